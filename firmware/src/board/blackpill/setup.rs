//! Register-level set-up of the clock tree, the motor PWM timer (TIM1), the
//! control tick timer (TIM5) and the receivers of the RFID reader (USART2)
//! and the MAVLink port (USART1), through the PAC.
//!
//! Why not the HAL: stm32f4xx-hal's `Rcc::freeze` searches PLL settings
//! at run time (`MainPll::fast_setup`, `I2sPll::setup`: divisions,
//! `unwrap`s, `assert!`s), and its `pwm_hz` (`set_auto_reload(…).unwrap()`)
//! and `counter_us` (`FTimer::configure`: `assert!` and `unwrap`) compute
//! prescalers from the `Clocks` that only `freeze` can make (their fields
//! are private). LTO folds none of it away, so each is a panic path in the
//! release firmware, and `cargo xtask panic-free` refuses it. Here every
//! figure is derived at compile time from the clock tree below (checked by
//! `const` assertions, which cannot fail at run time), and what could be
//! refused (a divider out of range) is returned as an error that the board
//! hands to its "configuration refused" path (`blackpill::halt`).
//!
//! The registers are written as stm32f4xx-hal 0.23 wrote them for the same
//! configuration (`Config::hse(25 MHz).sysclk(96 MHz).pclk1(48 MHz)
//! .pclk2(96 MHz)`, `pwm_hz(20 kHz)`, `counter_us`, `serial` at 9600 Bd 8N1):
//! the same PLL factors, wait states, prescalers, reload values, modes and
//! order. The GPIO modes, the encoders (QEI) and the watchdog stay with the
//! HAL, which sets them up without a panic path.

use core::convert::Infallible;
use core::ops::Deref;

use embedded_hal::pwm::{ErrorType, SetDutyCycle};
use stm32f4xx_hal::pac;

/// The PLL input divider: HSE 25 MHz / 25 = 1 MHz (VCO input 1–2 MHz).
const PLL_M: u32 = 25;
/// The VCO multiplier: 1 MHz × 384 = 384 MHz (VCO output 100–432 MHz).
const PLL_N: u32 = 384;
/// The system clock divider: 384 MHz / 4 = 96 MHz.
const PLL_P: u32 = 4;
/// The 48 MHz domain's divider (USB, SDIO; unused): 384 MHz / 8.
const PLL_Q: u32 = 8;
/// APB1 prescaler (96 MHz / 2 = 48 MHz, at most 50 MHz).
const APB1_DIV: u32 = 2;
/// APB2 prescaler.
const APB2_DIV: u32 = 1;
/// Flash wait states at 96 MHz and 2.7–3.6 V (one per 30 MHz, RM0383 3.4).
const FLASH_WAIT_STATES: u32 = (super::SYSCLK_HZ - 1) / 30_000_000;

/// Timer clock of APB1 (TIM5): twice PCLK1 when APB1 is divided.
pub const TIMCLK1_HZ: u32 = if APB1_DIV == 1 {
    super::PCLK1_HZ
} else {
    2 * super::PCLK1_HZ
};
/// Timer clock of APB2 (TIM1).
pub const TIMCLK2_HZ: u32 = if APB2_DIV == 1 {
    super::PCLK2_HZ
} else {
    2 * super::PCLK2_HZ
};

const _: () = {
    let vco_in = super::HSE_HZ / PLL_M;
    assert!(vco_in * PLL_M == super::HSE_HZ && vco_in >= 1_000_000 && vco_in <= 2_000_000);
    let vco_out = vco_in * PLL_N;
    assert!(PLL_N >= 50 && PLL_N <= 432 && vco_out >= 100_000_000 && vco_out <= 432_000_000);
    assert!(vco_out / PLL_P == super::SYSCLK_HZ && vco_out.is_multiple_of(PLL_P));
    assert!(PLL_P == 2 || PLL_P == 4 || PLL_P == 6 || PLL_P == 8);
    assert!(PLL_Q >= 2 && PLL_Q <= 15 && vco_out / PLL_Q <= 48_000_000);
    // The STM32F411's limits: SYSCLK and HCLK 100 MHz, APB1 50 MHz.
    assert!(super::SYSCLK_HZ <= 100_000_000);
    assert!(super::SYSCLK_HZ / APB1_DIV == super::PCLK1_HZ && super::PCLK1_HZ <= 50_000_000);
    assert!(super::SYSCLK_HZ / APB2_DIV == super::PCLK2_HZ && super::PCLK2_HZ <= 100_000_000);
    assert!(FLASH_WAIT_STATES <= 15);
};

/// Switches the system clock to the PLL on the 25 MHz crystal (the clock
/// tree of `board::blackpill`). Waits for the crystal and the PLL; if
/// either never starts, the watchdog (started before) resets the MCU.
pub fn clocks(rcc: &pac::RCC, flash: &pac::FLASH) {
    flash.acr().modify(|_, w| {
        w.latency()
            .set(FLASH_WAIT_STATES as u8)
            .prften()
            .set_bit()
            .icen()
            .set_bit()
            .dcen()
            .set_bit()
    });
    rcc.cr().modify(|_, w| w.hseon().set_bit());
    while rcc.cr().read().hserdy().bit_is_clear() {}
    let pllcfgr = PLL_M | PLL_N << 6 | (PLL_P / 2 - 1) << 16 | 1 << 22 | PLL_Q << 24;
    // SAFETY: every field of the word is in its documented range (the
    // `const` assertions above); PLLSRC (bit 22) selects HSE.
    #[allow(unsafe_code)]
    rcc.pllcfgr().write(|w| unsafe { w.bits(pllcfgr) });
    rcc.cr().modify(|_, w| w.pllon().set_bit());
    while rcc.cr().read().pllrdy().bit_is_clear() {}
    rcc.cfgr()
        .modify(|_, w| w.ppre2().div1().ppre1().div2().hpre().div1());
    // "The clocks are divided with the new prescaler factor from 1 to 16
    // AHB cycles after write."
    cortex_m::asm::delay(16);
    rcc.cfgr().modify(|_, w| w.sw().pll());
}

/// Why a peripheral refused its configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum SetupError {
    /// The motor PWM frequency is out of TIM1's reach.
    PwmFrequency,
    /// The control period is out of TIM5's reach.
    TickPeriod,
    /// The RFID reader's baud rate is out of USART2's reach.
    BaudRate,
    /// The MAVLink port's baud rate is out of USART1's reach.
    MavlinkBaudRate,
}

impl core::fmt::Display for SetupError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::PwmFrequency => "the motor PWM frequency is out of TIM1's reach",
            Self::TickPeriod => "the control period is out of TIM5's reach",
            Self::BaudRate => "the RFID reader's baud rate is out of USART2's reach",
            Self::MavlinkBaudRate => "the MAVLink port's baud rate is out of USART1's reach",
        })
    }
}

impl core::error::Error for SetupError {}

/// TIM1 as the motors' PWM: edge-aligned, prescaler 1, `TIMCLK2 / freq`
/// steps per period, channels 1 and 2 in PWM mode 1 with preload, outputs
/// off and duty 0 until [`PwmChannel::enable`].
pub struct MotorPwm {
    tim: pac::TIM1,
}

impl MotorPwm {
    /// Starts TIM1 at `freq_hz`.
    ///
    /// # Errors
    /// [`SetupError::PwmFrequency`] unless `TIMCLK2 / freq_hz` is 2 to
    /// 65,536 steps (prescaler 1, as the HAL chose for 20 kHz).
    pub fn new(tim: pac::TIM1, rcc: &pac::RCC, freq_hz: u32) -> Result<Self, SetupError> {
        // Clock on, then reset, as the HAL does before setting a timer up.
        rcc.apb2enr().modify(|_, w| w.tim1en().set_bit());
        rcc.apb2rstr().modify(|_, w| w.tim1rst().set_bit());
        rcc.apb2rstr().modify(|_, w| w.tim1rst().clear_bit());
        let steps = TIMCLK2_HZ.checked_div(freq_hz).unwrap_or(0);
        let arr = u16::try_from(steps.wrapping_sub(1))
            .ok()
            .filter(|&arr| arr > 0)
            .ok_or(SetupError::PwmFrequency)?;
        tim.cr1().modify(|_, w| w.arpe().set_bit());
        tim.psc().write(|w| w.psc().set(0));
        tim.arr().write(|w| w.arr().set(arr));
        // Load the prescaler and reload now, without an update interrupt flag.
        tim.cr1().modify(|_, w| w.urs().set_bit());
        tim.egr().write(|w| w.ug().set_bit());
        tim.cr1().modify(|_, w| w.urs().clear_bit());
        // The outputs come on at the next update (automatic output enable).
        tim.bdtr().modify(|_, w| w.aoe().set_bit());
        tim.cr1().modify(|_, w| w.cen().set_bit());
        tim.ccmr1_output().modify(|_, w| {
            w.oc1pe()
                .set_bit()
                .oc1m()
                .pwm_mode1()
                .oc2pe()
                .set_bit()
                .oc2m()
                .pwm_mode1()
        });
        Ok(Self { tim })
    }

    /// The two channels.
    pub fn channels(&self) -> (PwmChannel<'_, 1>, PwmChannel<'_, 2>) {
        (PwmChannel { tim: &self.tim }, PwmChannel { tim: &self.tim })
    }
}

/// One channel of TIM1 (1 or 2; the pins are set to their alternate
/// function by the caller).
pub struct PwmChannel<'a, const C: u8> {
    tim: &'a pac::TIM1,
}

impl<const C: u8> PwmChannel<'_, C> {
    /// Turns the channel's output on (CCxE).
    pub fn enable(&mut self) {
        match C {
            1 => self.tim.ccer().modify(|_, w| w.cc1e().set_bit()),
            _ => self.tim.ccer().modify(|_, w| w.cc2e().set_bit()),
        };
    }
}

impl<const C: u8> ErrorType for PwmChannel<'_, C> {
    type Error = Infallible;
}

impl<const C: u8> SetDutyCycle for PwmChannel<'_, C> {
    /// Steps per period (ARR + 1), as the HAL's channels report it.
    fn max_duty_cycle(&self) -> u16 {
        self.tim.arr().read().arr().bits().wrapping_add(1)
    }

    fn set_duty_cycle(&mut self, duty: u16) -> Result<(), Infallible> {
        match C {
            1 => self.tim.ccr1().write(|w| w.ccr().set(duty)),
            _ => self.tim.ccr2().write(|w| w.ccr().set(duty)),
        };
        Ok(())
    }
}

/// TIM5 counting microseconds, its update flag set once per period.
pub struct TickTimer {
    tim: pac::TIM5,
}

impl TickTimer {
    /// Starts TIM5 with a period of `period_us` microseconds.
    ///
    /// # Errors
    /// [`SetupError::TickPeriod`] unless the timer clock is a whole number
    /// of MHz (at most 65,536) and the period 2 µs or more.
    pub fn start(tim: pac::TIM5, rcc: &pac::RCC, period_us: u32) -> Result<Self, SetupError> {
        rcc.apb1enr().modify(|_, w| w.tim5en().set_bit());
        rcc.apb1rstr().modify(|_, w| w.tim5rst().set_bit());
        rcc.apb1rstr().modify(|_, w| w.tim5rst().clear_bit());
        let psc = u16::try_from((TIMCLK1_HZ / 1_000_000).wrapping_sub(1))
            .ok()
            .filter(|_| TIMCLK1_HZ.is_multiple_of(1_000_000) && TIMCLK1_HZ >= 1_000_000)
            .ok_or(SetupError::TickPeriod)?;
        let arr = period_us
            .checked_sub(1)
            .filter(|&arr| arr > 0)
            .ok_or(SetupError::TickPeriod)?;
        tim.cr1().modify(|_, w| w.cen().clear_bit());
        tim.cnt().reset();
        tim.sr().write(|w| w.uif().clear_bit());
        tim.psc().write(|w| w.psc().set(psc));
        tim.arr().write(|w| w.arr().set(arr));
        tim.cr1().modify(|_, w| w.urs().set_bit());
        tim.egr().write(|w| w.ug().set_bit());
        tim.cr1().modify(|_, w| w.urs().clear_bit());
        tim.cr1().modify(|_, w| w.cen().set_bit());
        Ok(Self { tim })
    }

    /// Whether a period ended since the last call that said so (clears
    /// the update flag).
    pub fn due(&mut self) -> bool {
        if self.tim.sr().read().uif().bit_is_set() {
            self.tim.sr().write(|w| w.uif().clear_bit());
            true
        } else {
            false
        }
    }
}

/// A USART receiving at a fixed baud rate, 8N1 (transmitter on, idle
/// high), with its receive interrupt enabled (`RXNEIE`: a byte received,
/// or an overrun), and transmitting by interrupt (`TXEIE`, on while bytes
/// are queued: the MAVLink port's). USART1 and USART2 share one register
/// block type.
pub struct UartRx<U> {
    /// Its registers, for the interrupt handler's register access
    /// (`super::devices`, `wmr_link::rx_ring::Usart`).
    pub(super) usart: U,
}

impl UartRx<pac::USART2> {
    /// USART2 (APB1, [`super::PCLK1_HZ`]), the RFID reader's; see
    /// [`UartRx::configure`].
    ///
    /// # Errors
    /// [`SetupError::BaudRate`] unless `PCLK1 / baud` (rounded) is 16 to
    /// 65,535.
    pub fn usart2(usart: pac::USART2, rcc: &pac::RCC, baud: u32) -> Result<Self, SetupError> {
        rcc.apb1enr().modify(|_, w| w.usart2en().set_bit());
        rcc.apb1rstr().modify(|_, w| w.usart2rst().set_bit());
        rcc.apb1rstr().modify(|_, w| w.usart2rst().clear_bit());
        Self::configure(usart, super::PCLK1_HZ, baud).ok_or(SetupError::BaudRate)
    }
}

impl UartRx<pac::USART1> {
    /// USART1 (APB2, [`super::PCLK2_HZ`]), the MAVLink port's; see
    /// [`UartRx::configure`].
    ///
    /// # Errors
    /// [`SetupError::MavlinkBaudRate`] unless `PCLK2 / baud` (rounded) is
    /// 16 to 65,535.
    pub fn usart1(usart: pac::USART1, rcc: &pac::RCC, baud: u32) -> Result<Self, SetupError> {
        rcc.apb2enr().modify(|_, w| w.usart1en().set_bit());
        rcc.apb2rstr().modify(|_, w| w.usart1rst().set_bit());
        rcc.apb2rstr().modify(|_, w| w.usart1rst().clear_bit());
        Self::configure(usart, super::PCLK2_HZ, baud).ok_or(SetupError::MavlinkBaudRate)
    }
}

impl<U: Deref<Target = pac::usart1::RegisterBlock>> UartRx<U> {
    /// Sets the USART up at `baud` from its bus clock `pclk_hz`, 8 data
    /// bits, no parity, 1 stop bit, oversampling by 16, the receive
    /// interrupt enabled (the pins are set to AF7 by the caller; the NVIC
    /// line is the caller's to unmask). `None` unless `pclk_hz / baud`
    /// (rounded) is 16 to 65,535.
    fn configure(usart: U, pclk_hz: u32, baud: u32) -> Option<Self> {
        let brr = pclk_hz
            .checked_add(baud / 2)
            .and_then(|n| n.checked_div(baud))
            .and_then(|d| u16::try_from(d).ok())
            .filter(|&d| d >= 16)?;
        usart.cr3().reset();
        usart.cr2().modify(|_, w| w.stop().stop1());
        usart.brr().write(|w| {
            w.div_mantissa()
                .set(brr >> 4)
                .div_fraction()
                .set((brr & 0xF) as u8)
        });
        usart.cr1().write(|w| {
            w.ue()
                .set_bit()
                .te()
                .set_bit()
                .re()
                .set_bit()
                .m()
                .clear_bit()
                .pce()
                .clear_bit()
                .over8()
                .clear_bit()
                .rxneie()
                .set_bit()
        });
        Some(Self { usart })
    }
}
