//! STM32F411 "Black Pill" robot board (STM32F411CEU6, 25 MHz crystal): the
//! core's `Robot` on real peripherals, one control tick per period of a
//! hardware timer.
//!
//! # Pinout
//!
//! | Function                           | Pin        | Peripheral     | AF  |
//! |------------------------------------|------------|----------------|-----|
//! | Left wheel encoder A               | PB4        | TIM3_CH1       | AF2 |
//! | Left wheel encoder B               | PB5        | TIM3_CH2       | AF2 |
//! | Right wheel encoder A              | PB6        | TIM4_CH1       | AF2 |
//! | Right wheel encoder B              | PB7        | TIM4_CH2       | AF2 |
//! | Left motor PWM (magnitude)         | PA8        | TIM1_CH1       | AF1 |
//! | Right motor PWM (magnitude)        | PA9        | TIM1_CH2       | AF1 |
//! | Left motor DIR                     | PB12       | GPIO push-pull | —   |
//! | Right motor DIR                    | PB13       | GPIO push-pull | —   |
//! | RFID reader TX → MCU RX            | PA3        | USART2_RX      | AF7 |
//! | MCU TX → RFID reader (unused)      | PA2        | USART2_TX      | AF7 |
//! | MAVLink peer TX → MCU RX           | PA10       | USART1_RX      | AF7 |
//! | MCU TX → MAVLink peer              | PA15       | USART1_TX      | AF7 |
//! | Heartbeat LED (on board, low = on) | PC13       | GPIO push-pull | —   |
//! | Debug probe (SWD)                  | PA13, PA14 | SWDIO, SWCLK   | AF0 |
//!
//! Internal: TIM5 is the control tick, the IWDG (on the ~32 kHz LSI) the
//! watchdog, the DWT cycle counter times each tick. The encoder inputs get
//! the internal pull-ups (for open-collector encoders). The PWM and DIR
//! lines need **external pull-downs** on the driver side: from reset until
//! they are configured, and after a watchdog reset, they float.
//!
//! The motor drivers are PWM + DIR, sign-magnitude (DRV8871/MC33926/Cytron
//! MDD class): PWM duty is the voltage magnitude, DIR high is forward for
//! the left motor; the right motor is mounted mirror-image, so its DIR is
//! inverted (`MotorWiring { reversed: true }`) and so is its encoder count.
//! The RFID reader is an RDM6300-style 125 kHz module sending 14-byte ASCII
//! frames at 9600 Bd 8N1; it runs on 5 V, so put a divider or level shifter
//! on its TX line unless PA3 is confirmed 5 V tolerant for the package used.
//!
//! The MAVLink port (a telemetry radio or a companion computer, 3.3 V,
//! 115 200 Bd 8N1) is USART1 on PA10/PA15: USART1's other pins are taken
//! (PA9 is the right motor's PWM, PB6/PB7 its encoder), USART6's PA11/PA12
//! are the USB connector's D−/D+ (kept free for a USB CDC port), and PB3,
//! USART1_RX's other pin, is the SWO trace output. PA15 is JTDI after
//! reset, unused with SWD. Built with a robot image that has a route
//! (`cargo xtask firmware --robot FILE`), the board runs the MAVLink
//! endpoint and mission runner of `wmr-mavlink` on this port, as the QEMU
//! board's route runs do (the glue is `wmr_link::mavlink_run`, shared):
//! each tick, before the robot's, the receive ring is emptied into the
//! endpoint and its frames are queued on the port's transmit ring, which
//! USART1's transmit interrupt empties (`blackpill::devices`, "Why the
//! MAVLink port transmits by interrupt"); after the robot's tick the
//! mission runner reads the route follower. The runner starts armed and
//! running the image's route, so without a ground station the robot
//! drives it from power-on (or waits disarmed: the robot file's
//! `[mavlink] power_on = "wait"`, which the image's route carries with the
//! endpoint's settings); a ground station heard and then
//! silent for the link timeout (3 s by default) stops the robot where it is
//! (`LinkLost`, a `STATUSTEXT` says so). Without a route (the
//! compiled-in [`PILOT`], or an image without one) the port's bytes are
//! counted and dropped.
//!
//! # Clock tree
//!
//! ```text
//! HSE 25 MHz ─► PLL  /M 25 = 1 MHz, ×N 384 = VCO 384 MHz
//!                    /P 4 ─► SYSCLK 96 MHz   (/Q 8 = 48 MHz, unused)
//! SYSCLK ─► AHB /1 = HCLK 96 MHz: core, DWT, flash (3 wait states, caches on)
//!        ├► APB1 /2 = 48 MHz: USART2 (BRR 5000: 9600 Bd exactly)
//!        │          timers ×2 = 96 MHz: TIM3, TIM4 (encoders),
//!        │                              TIM5 (PSC 95 → 1 MHz, ARR 9999 → 100 Hz tick)
//!        └► APB2 /1 = 96 MHz: TIM1 (PSC 0, ARR 4799 → 20 kHz PWM, 4800 duty steps)
//!                             USART1 (BRR 833: 115 246 Bd, +0.04 %)
//! LSI ~32 kHz ─► IWDG (/8, reload ~200 → 50 ms)
//! ```
//!
//! # Timing
//!
//! - **Control tick**: TIM5 counts microseconds and sets its update flag
//!   every [`TICK_US`] = the pilot spec's `period_s` (10 ms, 100 Hz). The
//!   loop polls the flag. A tick that finds the flag already set has
//!   overrun its period: it is counted, logged (once per status interval) and
//!   runs at once, so the schedule stays on the timer's grid.
//! - **UARTs**: the RFID reader's USART2 and the MAVLink port's USART1 are
//!   received by their RX interrupts into rings (the USART has no FIFO;
//!   see `blackpill::devices`), which the tick empties: the RFID ring
//!   through the core's `RfidReader`, the MAVLink ring into the MAVLink
//!   endpoint (a route run) or a byte count. The MAVLink port transmits
//!   from a 1 KiB ring by its transmit interrupt: the tick only copies
//!   the endpoint's frames into the ring (16 bytes per critical section).
//!   Both rings hold at least [`RING_WINDOW_US`] (40 ms, four 10 ms
//!   periods) of their line at full rate, so a tick late by up to 30 ms
//!   loses no byte; bytes lost anyway (ring full, hardware overrun,
//!   framing, noise, parity) are counted per kind and logged every second.
//! - **Tick work**: `Robot::tick` (encoders, RFID poll, tag lookup, pilot,
//!   motors), then the watchdog is fed, then events and status are logged.
//!   The tick's work is measured with the DWT cycle counter and its
//!   maximum logged every second.
//! - **Watchdog**: the IWDG resets the MCU if it is not fed for
//!   [`WATCHDOG_MS`] = 50 ms (five periods; 34 to 94 ms over the LSI's
//!   17–47 kHz tolerance). It is started first thing, so a hang anywhere,
//!   including a dead crystal during clock setup, ends in a reset.
//! - **Logs**: defmt over RTT: a status line and the fault counters every
//!   [`LOG_EVERY_TICKS`] ticks (1 s), the stack high-water mark once at
//!   [`STACK_LOG_AT_TICK`] (10 s), tracker mode changes, encoder halts,
//!   overruns; a telemetry record every [`TELEMETRY_EVERY_TICKS`] ticks
//!   (a robot image's `telemetry.every_ticks`; `crate::telemetry`,
//!   docs/firmware.md "Telemetry"). The heartbeat LED
//!   toggles every 0.5 s while the loop runs.
//!
//! # Faults
//!
//! - **Device faults** during a tick are the core's business (`Robot::tick`
//!   counts them and the pilot reacts: missing encoder reads bridged then
//!   motors stopped, unknown tags ignored, lost fixes → failsafe
//!   deceleration). The counters are logged every second.
//! - **Configuration refused** (the compiled-in [`PILOT`] spec, or the
//!   TIM1, USART2, USART1 or TIM5 set-up): the motors are held at duty 0
//!   (unpowered if TIM1 itself was refused), the error is logged every 5 s, the LED
//!   blinks fast (5 Hz) and the watchdog keeps being fed, until the board
//!   is reflashed. Never a panic.
//! - **Peripherals already taken** (impossible after a reset): an error is
//!   logged and the core sleeps; nothing is configured, so the motor lines
//!   float (external pull-downs).
//! - **Panic**: none can happen. `cargo xtask panic-free` proves at link
//!   time that the release firmware has no panic path (docs/firmware.md,
//!   "Panic freedom"); the clocks, TIM1, TIM5, USART1 and USART2 are set
//!   up by register for that (`blackpill::setup`). Were one to appear (a debug
//!   build, say), `panic-probe` prints the message over defmt and faults
//!   the core; the watchdog then resets
//!   the MCU within 50 ms, during which the PWM keeps its last duty. Under a
//!   debugger, a halted core (breakpoint, panic) freezes the IWDG and TIM5
//!   and **disables the TIM1 PWM outputs** (DBGMCU freeze bits), so the
//!   motors stop while the core is halted.
//!
//! # Flash and run
//!
//! With a debug probe (ST-Link, CMSIS-DAP, J-Link) on the SWD header and
//! [probe-rs](https://probe.rs) installed (`cargo install probe-rs-tools`),
//! from the workspace root:
//!
//! ```text
//! DEFMT_LOG=info cargo run -p wmr-firmware --release \
//!     --config 'profile.release.package.wmr-firmware.opt-level="z"' \
//!     --target thumbv7em-none-eabihf --no-default-features --features board-blackpill
//! ```
//!
//! The `--config` builds this crate for size, as every Black Pill build of
//! `cargo xtask` does (`size`, `firmware`, `flash`, `panic-free`; docs/budgets.md,
//! "Flash and static RAM"): the image that was measured and proved panic-free.
//!
//! The runner in `.cargo/config.toml` (`probe-rs run --chip STM32F411CEUx`)
//! flashes the ELF, resets the board and prints the decoded defmt log until
//! Ctrl-C. Without `DEFMT_LOG`, defmt keeps only `error` messages (it is
//! not set in `.cargo/config.toml` because `[env]` would change the QEMU
//! board's image too).
//!
//! The pilot runs from power-on: it commands zero until the first valid tag
//! fix (tracker `AwaitingFix`), then tracks the reference.

mod devices;
mod setup;
mod tags;

use core::cell::RefCell;

use cortex_m::peripheral::{DWT, NVIC};
use critical_section::Mutex;
use embedded_io::Read;
#[cfg(not(feature = "panic-never"))]
use panic_probe as _;
use stm32f4xx_hal::gpio::{Output, PB12, PB13, PC13, PinState, PushPull};
use stm32f4xx_hal::pac;
use stm32f4xx_hal::pac::interrupt;
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::watchdog::IndependentWatchdog;
use wmr_core::devices::{MotorDriver, MotorWiring, RfidReader};
use wmr_core::drive::spec::DriveSpec;
use wmr_core::estimation::heading_observer::HeadingObserverConfig;
use wmr_core::pilot::robot::Robot;
use wmr_core::pilot::robot::RobotTick;
use wmr_core::pilot::spec::{PilotSpec, SpecError, TrackerSpec};
use wmr_core::pilot::tracker::{TrackerConfig, TrackerMode};
use wmr_core::pilot::{Pilot, PilotConfig};
use wmr_core::reference::TrajectorySpec;
use wmr_link::telemetry::{self, Start};

use devices::{Encoder, Port, PortReader, SharedPort};
use embedded_hal::pwm::SetDutyCycle;
use setup::{MotorPwm, PwmChannel, SetupError, TickTimer, UartRx};
#[cfg(not(wmr_robot_image))]
use tags::{FlashTagTable, SITE_TAGS};
use wmr_link::rx_ring::{RxCounters, bytes_in_window};

/// Where the board finds its tags: the compiled-in [`SITE_TAGS`], or (built
/// with `cargo xtask firmware --robot FILE`) the robot image's floor.
#[cfg(not(wmr_robot_image))]
type BoardTags = FlashTagTable;
/// Where the board finds its tags: the robot image's floor.
#[cfg(wmr_robot_image)]
type BoardTags = wmr_link::image::ImageFloor<'static>;

/// The robot image of `cargo xtask firmware --robot FILE` (`firmware-sim
/// robot-image`, [`wmr_link::image`]), in flash: it replaces [`PILOT`]
/// and [`SITE_TAGS`].
#[cfg(wmr_robot_image)]
static ROBOT_IMAGE: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/robot.bin"));

/// The robot image's pilot, floor, control period (µs), checked for
/// this board as [`TICK_US`] is at compile time, and telemetry decimation
/// (the robot file's `telemetry.every_ticks`, in place of
/// [`TELEMETRY_EVERY_TICKS`]).
#[cfg(wmr_robot_image)]
#[allow(clippy::type_complexity)]
fn image_config() -> Result<
    (
        PilotSpec,
        BoardTags,
        u32,
        u16,
        Option<wmr_link::image::ImageRoute<'static>>,
    ),
    wmr_link::image::ImageError,
> {
    let image = wmr_link::image::decode(ROBOT_IMAGE)?;
    // Saturating: a negative or huge period becomes 0 or u32::MAX, refused.
    let tick_us = (image.pilot.tracker.period_s * 1.0e6 + 0.5) as u32;
    if !(1_000..=100_000).contains(&tick_us)
        || WATCHDOG_MS * 1_000 * 2 / 3 < tick_us.saturating_mul(3)
    {
        return Err(wmr_link::image::ImageError::Period);
    }
    Ok((
        image.pilot,
        image.floor,
        tick_us,
        image.telemetry_every_ticks,
        image.route,
    ))
}

/// Tags the board knows (for the start-up log).
#[cfg(wmr_robot_image)]
fn tag_count(tags: &BoardTags) -> usize {
    match tags {
        wmr_link::image::ImageFloor::Grid(grid) => {
            usize::from(grid.rows()) * usize::from(grid.columns())
        }
        wmr_link::image::ImageFloor::Map(map) => map.len(),
    }
}

/// The pilot, compiled in: paper 001's figure-eight (`h1` 5 m, `h2`
/// 0.02 rad/s, phase −π/2) with the simulator's
/// `figure_eight_rfid_full_stack` scenario for everything else (its TOML
/// file and `firmware-sim`'s scenario defaults), so that the robot runs the
/// configuration the simulator validated.
#[cfg_attr(wmr_robot_image, allow(dead_code))]
pub const PILOT: PilotSpec = PilotSpec {
    tracker: TrackerSpec {
        period_s: 0.01,
        trajectory: TrajectorySpec::FigureEight {
            h1_m: 5.0,
            h2_rad_s: 0.02,
            phase_rad: -core::f32::consts::FRAC_PI_2,
        },
        gains: [0.11, 0.11, 0.1],
        observer_gain_per_m: 0.6,
        observer_min_speed_m_s: HeadingObserverConfig::DEFAULT_MIN_SPEED_M_S,
        // failsafe.fix_timeout_s = 0.5 s at 10 ms.
        fix_timeout_ticks: 50,
        failsafe_decel_m_s2: TrackerConfig::DEFAULT_FAILSAFE_DECEL_M_S2,
        max_fix_age_ticks: TrackerConfig::DEFAULT_MAX_FIX_AGE_TICKS,
        estimator: wmr_core::estimation::spec::EstimatorSpec::HeadingObserver,
        law: wmr_core::control::spec::LawSpec::Saturated,
        sensors: wmr_core::estimation::spec::SensorSpec {
            track_width_m: 0.2,
            // Count quantum q = 2π·0.03 m / 2048: q²/12. No tag grid: the site's
            // tags are a map, which the fusion estimator (refusing a zero
            // spacing) cannot use.
            wheel_variance_floor_m2: 7.06e-10,
            tag_spacing_m: 0.0,
            read_radius_m: 0.0,
            // The reader's antenna at the axle midpoint.
            antenna_offset_m: [0.0; 2],
        },
    },
    drive: DriveSpec {
        wheel_radius_m: 0.03,
        track_width_m: 0.2,
        encoder_counts_per_rev: 2048,
        max_wheel_speed_rad_s: 18.0,
        max_wheel_accel_rad_s2: 50.0,
        // 1 / (20 rad/s wheel speed at full duty).
        feedforward_duty_per_rad_s: 0.05,
        kp_duty_per_rad_s: 0.02,
        ki_duty_per_rad: 0.5,
        speed_observer: None,
    },
    // TIM3 and TIM4 are 16-bit.
    encoder_bits: 16,
    max_encoder_fault_ticks: PilotConfig::DEFAULT_MAX_ENCODER_FAULT_TICKS,
};

/// Control period, µs: the pilot's `period_s`, rounded.
pub const TICK_US: u32 = (PILOT.tracker.period_s * 1.0e6 + 0.5) as u32;

/// Digital input filter of both encoder timers' inputs (TIM3/TIM4 `CCMR1`
/// `IC1F`/`IC2F`, RM0383 §13.4.7): an edge counts only after its new level
/// was sampled `N` times in a row at `f_SAMPLING`, so a noise spike shorter
/// than `N / f_SAMPLING` (a motor's commutation and PWM noise on the encoder
/// lines) is no edge. The timers run at 96 MHz with `CKD = 00` (`f_DTS` =
/// 96 MHz). The choices (the PAC's names): `NoFilter`; `FckIntN2`, `N4`,
/// `N8` (`f_CK_INT`); `FdtsDiv2N6`, `N8`; `FdtsDiv4N6`, `N8`; `FdtsDiv8N6`,
/// `N8`; `FdtsDiv16N5`, `N6`, `N8`; `FdtsDiv32N5`, `N6`, `N8`.
///
/// Default `FdtsDiv16N8`: spikes under 1.33 µs are rejected, and
/// edges up to about 750 kHz pass, against 5.9 kHz at the drive's top
/// wheel speed (18 rad/s, 2048 counts a turn). Lower it for a faster
/// encoder (the edge period must stay above the filter's `N / f_SAMPLING`);
/// raise it for a noisier motor. Glitches that still get through and
/// exceed what the wheel can turn in a tick are rejected by the pilot as
/// implausible jumps (`PilotCounters::implausible_encoder_reads`).
pub const ENCODER_INPUT_FILTER: pac::tim3::ccmr1_input::ICFILTER =
    pac::tim3::ccmr1_input::ICFILTER::FdtsDiv16N8;

/// Watchdog timeout, ms (nominal: the LSI runs at 17–47 kHz).
pub const WATCHDOG_MS: u32 = 50;

/// Ticks between two status logs (1 s).
pub const LOG_EVERY_TICKS: u32 = 100;

/// A telemetry record on the RTT log every this many ticks (10: 10 Hz at
/// the 10 ms tick, about 0.6 KB/s of RTT; 0: none). `crate::telemetry`
/// and docs/firmware.md, "Telemetry". Built with `cargo xtask firmware
/// --robot FILE`, the robot file's `telemetry.every_ticks` (in the image)
/// replaces it.
#[cfg_attr(wmr_robot_image, allow(dead_code))]
pub const TELEMETRY_EVERY_TICKS: u16 = 10;

/// The tick at which the stack high-water mark is logged, once (10 s in,
/// when every code path of the tick has run). Finding it scans the unused
/// stack (most of the 128 KiB RAM, over a millisecond, within the rings'
/// [`RING_WINDOW_US`]). Once, not periodically: it makes that tick late.
pub const STACK_LOG_AT_TICK: u32 = 1_000;

/// Ticks between two heartbeat LED toggles (0.5 s).
const HEARTBEAT_TICKS: u32 = 50;

/// Periods between two LED toggles while halted on a fault (0.1 s).
const FAULT_BLINK_PERIODS: u32 = 10;

/// Periods between two repetitions of the fault log while halted (5 s).
const FAULT_LOG_PERIODS: u32 = 500;

const _: () = {
    assert!(
        TICK_US >= 1_000 && TICK_US <= 100_000,
        "control period out of 1..=100 ms"
    );
    // At the LSI's fastest (47 kHz) the timeout shrinks to 68 %.
    assert!(
        WATCHDOG_MS * 1_000 * 2 / 3 >= 3 * TICK_US,
        "the watchdog must outlast three control periods"
    );
};

/// The Black Pill's crystal, Hz.
const HSE_HZ: u32 = 25_000_000;
/// System clock, Hz (96 MHz: the PLL's 48 MHz output is exact, for USB).
const SYSCLK_HZ: u32 = 96_000_000;
/// APB1 clock, Hz (its maximum is 50 MHz).
const PCLK1_HZ: u32 = 48_000_000;
/// APB2 clock, Hz.
const PCLK2_HZ: u32 = 96_000_000;
/// Motor PWM frequency, Hz (above hearing, within the drivers' range).
const PWM_HZ: u32 = 20_000;
/// RFID reader line speed, Bd (8N1).
const RFID_BAUD: u32 = 9_600;
/// Bytes of the RFID receive ring: 133 ms of reader output at 9600 Bd.
const RFID_RING_BYTES: usize = 128;
/// MAVLink port line speed, Bd (8N1): the usual telemetry radio rate.
const MAVLINK_BAUD: u32 = 115_200;
/// Bytes of the MAVLink receive ring: 44 ms of line at 115 200 Bd.
const MAVLINK_RING_BYTES: usize = 512;
/// Bytes of the MAVLink transmit ring: 89 ms of line at 115 200 Bd, the
/// endpoint's room for a tick's frames (a full `PARAM_VALUE` burst at a
/// `PARAM_REQUEST_LIST`; the default 5 Hz telemetry without a geodetic
/// origin is about 4 B a tick, 10 Hz about 8.6 B).
const MAVLINK_TX_RING_BYTES: usize = 1_024;
/// The longest time between two reads of a ring that loses no byte, at
/// each line's full rate: 40 ms, four control periods of 10 ms (a tick
/// late by three), checked against both rings' capacities at compile time
/// with [`bytes_in_window`] (whose sizing `wmr_link::rx_ring`'s tests
/// check against a simulated line and tick). A tick that stalls past the
/// watchdog's 50 ms resets the MCU anyway.
const RING_WINDOW_US: u32 = 40_000;
/// Most ring reads per tick when emptying the MAVLink ring: enough to
/// empty it full (512 / 16 bytes a read), plus the bytes that arrive
/// meanwhile.
const MAVLINK_READS_PER_TICK: u32 = 40;

const _: () = {
    assert!(RFID_RING_BYTES >= bytes_in_window(RFID_BAUD, RING_WINDOW_US));
    assert!(MAVLINK_RING_BYTES >= bytes_in_window(MAVLINK_BAUD, RING_WINDOW_US));
};

/// The RFID reader's USART2 and its ring, shared with [`USART2`].
static RFID_PORT: SharedPort<pac::USART2, RFID_RING_BYTES, 1> =
    Mutex::new(RefCell::new(Port::new()));
/// The MAVLink port's USART1 and its rings, shared with [`USART1`].
static MAVLINK_PORT: SharedPort<pac::USART1, MAVLINK_RING_BYTES, MAVLINK_TX_RING_BYTES> =
    Mutex::new(RefCell::new(Port::new()));

/// USART2's receive interrupt: the RFID reader's byte into its ring.
#[interrupt]
fn USART2() {
    devices::on_interrupt(&RFID_PORT);
}

/// USART1's interrupt: the MAVLink port's byte received into its ring,
/// the next byte to send out of its transmit ring.
#[interrupt]
fn USART1() {
    devices::on_interrupt(&MAVLINK_PORT);
}

/// The RFID reader's UART as the core reads it.
type RfidUart = PortReader<pac::USART2, RFID_RING_BYTES, 1>;
/// The MAVLink port's UART as the tick reads it.
type MavlinkUart = PortReader<pac::USART1, MAVLINK_RING_BYTES, MAVLINK_TX_RING_BYTES>;

/// Left motor: TIM1_CH1 (PA8) + DIR on PB12.
type LeftMotor<'a> = MotorDriver<PwmChannel<'a, 1>, PB12<Output<PushPull>>>;
/// Right motor: TIM1_CH2 (PA9) + DIR on PB13.
type RightMotor<'a> = MotorDriver<PwmChannel<'a, 2>, PB13<Output<PushPull>>>;
/// The on-board LED (active low).
type Led = PC13<Output<PushPull>>;
/// The robot on this board's devices.
type BoardRobot<'a> = Robot<
    Encoder<pac::TIM3>,
    Encoder<pac::TIM4>,
    LeftMotor<'a>,
    RightMotor<'a>,
    RfidUart,
    BoardTags,
>;

/// Why the firmware is not driving.
#[derive(Debug, Clone, Copy, defmt::Format)]
enum Fault {
    /// The compiled-in pilot spec (or the robot image's) was refused.
    Pilot(SpecError),
    /// The robot image is malformed or does not suit the board.
    #[cfg(wmr_robot_image)]
    Image(wmr_link::image::ImageError),
    /// The core refused the robot image's route (its count, a limit, an
    /// option, or a waypoint: by its index and key).
    #[cfg(wmr_robot_image)]
    Route(wmr_link::RouteRefusal),
    /// TIM1 (motor PWM), USART2 (RFID), USART1 (MAVLink) or TIM5 (tick)
    /// refused its configuration.
    Peripheral(SetupError),
}

/// The firmware: set the board up, then run the control loop forever.
pub fn run() -> ! {
    let (Some(dp), Some(mut cp)) = (pac::Peripherals::take(), cortex_m::Peripherals::take()) else {
        // Only possible if something took them before `main`.
        defmt::error!("peripherals already taken: nothing configured, motors unpowered");
        loop {
            cortex_m::asm::wfi();
        }
    };

    // While the core is halted by a debugger: freeze the watchdog and the
    // tick, and disable TIM1's outputs (advanced timers do that when frozen).
    dp.DBGMCU
        .apb1_fz()
        .modify(|_, w| w.dbg_iwdg_stop().set_bit().dbg_tim5_stop().set_bit());
    dp.DBGMCU
        .apb2_fz()
        .modify(|_, w| w.dbg_tim1_stop().set_bit());
    // First, so that a hang in the setup (a dead crystal) ends in a reset.
    let mut watchdog = IndependentWatchdog::new(dp.IWDG);
    watchdog.start(WATCHDOG_MS.millis());

    // The clock tree by register (`setup`: the HAL's `freeze` has panic
    // paths); the HAL's `Rcc` then only enables the GPIO ports and the
    // encoder timers, which need no clock figures.
    setup::clocks(&dp.RCC, &dp.FLASH);
    let sysclk_hz = SYSCLK_HZ;
    let mut rcc = dp.RCC.constrain();
    cp.DCB.enable_trace();
    cp.DWT.enable_cycle_counter();

    let gpioa = dp.GPIOA.split(&mut rcc);
    let gpiob = dp.GPIOB.split(&mut rcc);
    let gpioc = dp.GPIOC.split(&mut rcc);
    let mut led: Led = gpioc.pc13.into_push_pull_output_in_state(PinState::High);

    // Motors first, at duty 0: everything after this can fail, and the
    // fault path holds them stopped.
    let pwm = match MotorPwm::new(dp.TIM1, &rcc, PWM_HZ) {
        Ok(pwm) => pwm,
        // TIM1 never started: its outputs stay off, the motors unpowered.
        Err(e) => halt(Fault::Peripheral(e), watchdog, None, led, sysclk_hz),
    };
    let _left_pwm_pin = gpioa.pa8.into_alternate::<1>();
    let _right_pwm_pin = gpioa.pa9.into_alternate::<1>();
    let (mut left_pwm, mut right_pwm) = pwm.channels();
    let _ = left_pwm.set_duty_cycle(0);
    let _ = right_pwm.set_duty_cycle(0);
    left_pwm.enable();
    right_pwm.enable();
    let mut left_motor: LeftMotor<'_> = MotorDriver::new(
        left_pwm,
        gpiob.pb12.into_push_pull_output_in_state(PinState::Low),
        MotorWiring { reversed: false },
    );
    let mut right_motor: RightMotor<'_> = MotorDriver::new(
        right_pwm,
        gpiob.pb13.into_push_pull_output_in_state(PinState::Low),
        MotorWiring { reversed: true },
    );
    stop_motors(&mut left_motor, &mut right_motor);

    let left_encoder = Encoder::new(
        dp.TIM3.qei(
            (
                gpiob.pb4.into_alternate::<2>().internal_pull_up(true),
                gpiob.pb5.into_alternate::<2>().internal_pull_up(true),
            ),
            &mut rcc,
        ),
        false,
        ENCODER_INPUT_FILTER,
    );
    let right_encoder = Encoder::new(
        dp.TIM4.qei(
            (
                gpiob.pb6.into_alternate::<2>().internal_pull_up(true),
                gpiob.pb7.into_alternate::<2>().internal_pull_up(true),
            ),
            &mut rcc,
        ),
        true,
        ENCODER_INPUT_FILTER,
    );

    // The reader only talks; its TX pin stays configured, idle high.
    let _rfid_tx_pin = gpioa.pa2.into_alternate::<7>();
    let _rfid_rx_pin = gpioa.pa3.into_alternate::<7>();
    let rfid_rx = match UartRx::usart2(dp.USART2, &rcc, RFID_BAUD) {
        Ok(rx) => rx,
        Err(e) => halt(
            Fault::Peripheral(e),
            watchdog,
            Some((left_motor, right_motor)),
            led,
            sysclk_hz,
        ),
    };
    let _mavlink_tx_pin = gpioa.pa15.into_alternate::<7>();
    let _mavlink_rx_pin = gpioa.pa10.into_alternate::<7>();
    let mavlink_rx = match UartRx::usart1(dp.USART1, &rcc, MAVLINK_BAUD) {
        Ok(rx) => rx,
        Err(e) => halt(
            Fault::Peripheral(e),
            watchdog,
            Some((left_motor, right_motor)),
            led,
            sysclk_hz,
        ),
    };
    // The receivers go to their handlers' ports before the interrupts are
    // unmasked, so a handler never finds its port empty.
    devices::attach(&RFID_PORT, rfid_rx);
    devices::attach(&MAVLINK_PORT, mavlink_rx);
    // SAFETY: unmasking breaks no critical section: the firmware's critical
    // sections (cortex-m's single-core `critical-section`, the logger's)
    // mask every interrupt through PRIMASK, none relies on these two NVIC
    // lines staying masked; the handlers touch only their ports, through
    // `critical_section::with`.
    #[allow(unsafe_code)]
    unsafe {
        NVIC::unmask(pac::Interrupt::USART2);
        NVIC::unmask(pac::Interrupt::USART1);
    }
    let rfid = RfidReader::new(RfidUart::new(&RFID_PORT));
    let mut mavlink = MavlinkUart::new(&MAVLINK_PORT);

    #[cfg(not(wmr_robot_image))]
    let (spec, tags, tick_us, telemetry_every) = (PILOT, SITE_TAGS, TICK_US, TELEMETRY_EVERY_TICKS);
    #[cfg(wmr_robot_image)]
    let (spec, tags, tick_us, telemetry_every, image_route) = match image_config() {
        Ok(config) => config,
        Err(e) => halt(
            Fault::Image(e),
            watchdog,
            Some((left_motor, right_motor)),
            led,
            sysclk_hz,
        ),
    };
    #[cfg(not(wmr_robot_image))]
    let tag_count = tags.len();
    #[cfg(wmr_robot_image)]
    let tag_count = tag_count(&tags);
    let pilot = match spec
        .build()
        .and_then(|config| Pilot::new(config).map_err(SpecError::Pilot))
    {
        Ok(pilot) => pilot,
        Err(e) => halt(
            Fault::Pilot(e),
            watchdog,
            Some((left_motor, right_motor)),
            led,
            sysclk_hz,
        ),
    };
    let mut tick_timer = match TickTimer::start(dp.TIM5, &rcc, tick_us) {
        Ok(timer) => timer,
        Err(e) => halt(
            Fault::Peripheral(e),
            watchdog,
            Some((left_motor, right_motor)),
            led,
            sysclk_hz,
        ),
    };
    // The image's route, loaded through the core's checks into a static
    // (`RouteStore`: 24 KB, in `.bss`, never on the stack), and with it
    // the MAVLink endpoint and mission runner (`MavlinkPort`, a static
    // too), running that route.
    #[cfg(wmr_robot_image)]
    let mut mav: Option<&'static mut MavlinkPort> = None;
    #[cfg(wmr_robot_image)]
    let mut route: Option<&'static mut wmr_link::session::RouteStore> = match image_route {
        None => None,
        Some(image_route) => {
            let Some(store) = cortex_m::singleton!(
                : wmr_link::session::RouteStore = wmr_link::session::RouteStore::new()
            ) else {
                defmt::error!("route storage already taken");
                loop {
                    cortex_m::asm::wfi();
                }
            };
            let period_s = pilot.tracker().config().clock().period_s();
            match image_route.load_into(store, period_s) {
                Ok(limits) => {
                    // Checked by the load: configured.
                    let config = image_route.spec.mavlink.config().ok();
                    mav = config.and_then(|_| mavlink_port());
                    if mav.is_none() {
                        defmt::error!(
                            "no MAVLink endpoint: the route runs without a ground station link (its bytes counted and dropped)"
                        );
                    }
                    if let (Some(mav), Some(config)) = (mav.as_deref_mut(), config) {
                        mav.run.activate(
                            store,
                            image_route.spec.start,
                            limits,
                            period_s,
                            config,
                            image_route.spec.mavlink.power_on,
                        );
                        // The pilot's own tuning: built by the same checks.
                        let _ = mav.run.set_tuning(&pilot.config().tuning());
                    }
                    Some(store)
                }
                Err(e) => halt(
                    Fault::Route(e),
                    watchdog,
                    Some((left_motor, right_motor)),
                    led,
                    sysclk_hz,
                ),
            }
        }
    };
    let mut robot: BoardRobot<'_> = Robot::new(
        pilot,
        (left_encoder, right_encoder),
        (left_motor, right_motor),
        rfid,
        tags,
    );

    defmt::info!(
        "wmr-firmware (Black Pill): SYSCLK {=u32} Hz, tick {=u32} us, watchdog {=u32} ms, {=usize} tags",
        sysclk_hz,
        tick_us,
        WATCHDOG_MS,
        tag_count
    );

    let cycles_per_us = (sysclk_hz / 1_000_000).max(1);
    let mut stats = LoopStats::default();
    // The MAVLink endpoint's clock: control periods by the cycle counter,
    // so that its link-loss timeout and telemetry rates follow wall time
    // while ticks overrun (a loop pass may fold several periods).
    #[cfg(wmr_robot_image)]
    let mut mavlink_clock = wmr_link::period_clock::PeriodClock::new(
        cycles_per_us.saturating_mul(tick_us),
        DWT::cycle_count(),
    );
    if telemetry_every != 0 {
        crate::telemetry::start(Start {
            every_ticks: telemetry_every,
            period_s: robot.pilot().tracker().config().clock().period_s(),
        });
    }
    loop {
        let overrun = wait_for_tick(&mut tick_timer);
        let started = DWT::cycle_count();
        #[cfg(wmr_robot_image)]
        let periods = mavlink_clock
            .as_mut()
            .map_or(stats.ticks, |clock| clock.advance(started));
        // A route run talks MAVLink around the robot's tick (`MavlinkPort`);
        // otherwise the MAVLink port's bytes are counted and dropped.
        // (One call of the robot's tick: a call in each arm of a match
        // doubled its code, 1.7 KB.)
        #[cfg(wmr_robot_image)]
        let read = match (route.as_deref_mut(), mav.as_deref_mut()) {
            (Some(store), Some(mav)) => mav.before_tick(store, &mut mavlink, periods),
            _ => drain(&mut mavlink),
        };
        // Gains or failsafe times a ground station set: from this tick on.
        #[cfg(wmr_robot_image)]
        if let Some(tuning) = mav.as_deref_mut().and_then(|m| m.run.take_tuning()) {
            robot.retune(&tuning);
        }
        #[cfg(wmr_robot_image)]
        let step = robot.tick_on(
            route
                .as_deref_mut()
                .and_then(wmr_link::session::RouteStore::follower_mut),
        );
        #[cfg(wmr_robot_image)]
        {
            stats.mavlink_bytes = stats.mavlink_bytes.wrapping_add(read);
            if let (Some(store), Some(mav)) = (route.as_deref(), mav.as_deref_mut()) {
                mav.after_tick(store, &step);
                mav.run.set_counts(wmr_mavlink::Counts::of(
                    &robot.pilot().tracker().counters(),
                    &robot.rfid_counters(),
                    robot.counters().unknown_tags,
                ));
            }
        }
        #[cfg(not(wmr_robot_image))]
        let step = robot.tick();
        #[cfg(not(wmr_robot_image))]
        {
            stats.mavlink_bytes = stats.mavlink_bytes.wrapping_add(drain(&mut mavlink));
        }
        watchdog.feed();
        if telemetry::is_emitted(step.pilot.tracker.tick, telemetry_every) {
            crate::telemetry::record(&telemetry::Record::of(
                &step,
                robot.counters(),
                robot.pilot().tracker().counters(),
            ));
        }

        stats.ticks = stats.ticks.wrapping_add(1);
        if overrun {
            stats.overruns = stats.overruns.saturating_add(1);
            if !stats.overrun_logged {
                defmt::warn!(
                    "tick {=u32} overran its {=u32} us period (total {=u32})",
                    stats.ticks,
                    tick_us,
                    stats.overruns
                );
                stats.overrun_logged = true;
            }
        }
        stats.log_events(&step);
        if stats.ticks.is_multiple_of(HEARTBEAT_TICKS) {
            led.toggle();
        }
        if stats.ticks.is_multiple_of(LOG_EVERY_TICKS) {
            log_status(
                &robot,
                &step,
                &stats,
                [devices::counters(&RFID_PORT), mavlink.counters()],
                cycles_per_us,
            );
            #[cfg(wmr_robot_image)]
            if let Some(mav) = mav.as_deref() {
                mav.log_status();
            }
            stats.max_work_cycles = 0;
            stats.overrun_logged = false;
        }
        // Everything between two waits for the tick, logging included (a
        // status tick's own time counts in the next interval).
        let work_cycles = DWT::cycle_count().wrapping_sub(started);
        stats.max_work_cycles = stats.max_work_cycles.max(work_cycles);
    }
}

/// Waits for the next control tick (the UARTs' interrupts fill their
/// rings meanwhile). Returns whether the tick was already due on arrival
/// (an overrun).
fn wait_for_tick(timer: &mut TickTimer) -> bool {
    if timer.due() {
        return true;
    }
    while !timer.due() {}
    false
}

/// Empties the MAVLink ring (at most [`MAVLINK_READS_PER_TICK`] reads) and
/// returns the bytes taken out, dropped: a firmware without a route has
/// no MAVLink endpoint (`MavlinkPort`), as the QEMU board's runs without
/// a route have none.
// Out of line: inlined, it took a second copy of the ring's read.
#[inline(never)]
fn drain(uart: &mut MavlinkUart) -> u32 {
    let mut buf = [0_u8; 16];
    let mut bytes: u32 = 0;
    for _ in 0..MAVLINK_READS_PER_TICK {
        match uart.read(&mut buf) {
            Ok(0) | Err(_) => break,
            Ok(n) => bytes = bytes.wrapping_add(n as u32),
        }
    }
    bytes
}

/// The MAVLink side of a route run (`wmr_link::mavlink_run`, shared with
/// the QEMU board's session): the endpoint and mission runner, the bytes
/// taken out of the receive ring for the tick, the endpoint's output
/// before it goes to the transmit ring, and the last tick's estimate.
/// About 11 KB, in a static ([`mavlink_port`]).
#[cfg(wmr_robot_image)]
struct MavlinkPort {
    run: wmr_link::mavlink_run::MavlinkRun,
    rx: [u8; MAVLINK_RING_BYTES],
    tx: [u8; MAVLINK_TX_RING_BYTES],
    /// The last tick's estimate, reported by the endpoint.
    estimate: Option<wmr_mavlink::Estimate>,
}

#[cfg(wmr_robot_image)]
impl MavlinkPort {
    /// Not active, every byte zero ([`mavlink_port`]).
    const BLANK: Self = Self {
        run: wmr_link::mavlink_run::MavlinkRun::BLANK,
        rx: [0; MAVLINK_RING_BYTES],
        tx: [0; MAVLINK_TX_RING_BYTES],
        estimate: None,
    };

    /// Before the robot's tick, `tick` control periods after the loop
    /// started (by the cycle counter: `wmr_link::period_clock`): the receive ring
    /// emptied into the endpoint, its output queued on the transmit ring
    /// (the endpoint gets the ring's free room as its buffer: a frame
    /// that does not fit is dropped whole and counted by it), its events
    /// applied to the runner and `store`'s follower. Returns the bytes
    /// read. Not inlined: its buffers' moves stay out of the loop's frame.
    #[inline(never)]
    fn before_tick(
        &mut self,
        store: &mut wmr_link::session::RouteStore,
        uart: &mut MavlinkUart,
        tick: u32,
    ) -> u32 {
        let mut n = 0;
        for _ in 0..MAVLINK_READS_PER_TICK {
            match self.rx.get_mut(n..).map(|free| uart.read(free)) {
                Some(Ok(k)) if k > 0 => n += k,
                _ => break,
            }
        }
        let room = devices::tx_room(&MAVLINK_PORT).min(self.tx.len());
        let rx = self.rx.get(..n).unwrap_or(&[]);
        let (written, _dropped) = match self.tx.get_mut(..room) {
            Some(room) => self.run.before_tick(store, tick, self.estimate, rx, room),
            None => (0, 0),
        };
        devices::queue_tx(&MAVLINK_PORT, self.tx.get(..written).unwrap_or(&[]));
        // At most the ring's 512 bytes.
        u32::try_from(n).unwrap_or(u32::MAX)
    }

    /// After the robot's tick: the runner reads the follower, and the
    /// tick's estimate is kept for the next.
    fn after_tick(&mut self, store: &wmr_link::session::RouteStore, step: &RobotTick) {
        let t = &step.pilot.tracker;
        self.run.after_tick(store, t.reference.position);
        self.estimate = Some(wmr_link::mavlink_run::estimate(
            [t.position.x, t.position.y],
            [t.heading.cos_theta, t.heading.sin_theta],
            [t.command.v_m_s, t.command.omega_rad_s],
        ));
    }

    /// The once-a-second MAVLink status: the runner's mode (the heartbeat's
    /// `custom_mode`), armed, the link, and the endpoint's and transmit
    /// ring's counters.
    fn log_status(&self) {
        let runner = self.run.runner();
        let c = self.run.endpoint().counters();
        defmt::info!(
            "mavlink mode {=u8} armed {=bool} link lost {=bool} ({=u32} losses) | frames {=u32} crc errors {=u32} garbage {=u32} unknown {=u32} | refused: mission {=u32} command {=u32} param {=u32} | tx frames dropped {=u32}, ring {}",
            runner.mode() as u8,
            runner.armed(),
            self.run.endpoint().link_lost(),
            c.link_losses,
            c.rx.frames,
            c.rx.crc_errors,
            c.rx.garbage_bytes,
            c.rx.unknown_messages,
            c.mission_refusals,
            c.command_refusals,
            c.param_refusals,
            c.tx_dropped,
            devices::tx_counters(&MAVLINK_PORT)
        );
    }
}

/// The MAVLink side of a route run, in a static, blank (every byte
/// zero: building it clears memory, and the static is in `.bss`) and not
/// active until its run is activated (`MavlinkRun::activate`, with the
/// robot image's route, limits and `[mavlink]`). `None`: the static
/// already taken.
#[cfg(wmr_robot_image)]
fn mavlink_port() -> Option<&'static mut MavlinkPort> {
    cortex_m::singleton!(: MavlinkPort = MavlinkPort::BLANK)
}

/// Sets both motors' duty to 0. The PWM and GPIO writes cannot fail
/// (`Infallible`), so there is no error to handle.
fn stop_motors(left: &mut LeftMotor<'_>, right: &mut RightMotor<'_>) {
    let _ = left.stop();
    let _ = right.stop();
}

/// The fault path: motors held stopped (`None`: never powered, TIM1 was
/// refused), error logged every 5 s, LED blinking fast, watchdog fed,
/// forever. Timed by busy-waiting one control period, so that it does not
/// depend on the tick timer.
fn halt(
    fault: Fault,
    mut watchdog: IndependentWatchdog,
    mut motors: Option<(LeftMotor<'_>, RightMotor<'_>)>,
    mut led: Led,
    sysclk_hz: u32,
) -> ! {
    let period_cycles = sysclk_hz / 1_000_000 * TICK_US;
    let mut periods: u32 = 0;
    loop {
        if let Some((left, right)) = &mut motors {
            stop_motors(left, right);
        }
        watchdog.feed();
        if periods.is_multiple_of(FAULT_LOG_PERIODS) {
            defmt::error!("halted, motors stopped: {}", fault);
        }
        if periods.is_multiple_of(FAULT_BLINK_PERIODS) {
            led.toggle();
        }
        periods = periods.wrapping_add(1);
        cortex_m::asm::delay(period_cycles);
    }
}

/// What the loop tracks between two status logs.
#[derive(Default)]
struct LoopStats {
    /// Ticks run.
    ticks: u32,
    /// Ticks that found their period already over.
    overruns: u32,
    /// Bytes taken out of the MAVLink ring (wrapping).
    mavlink_bytes: u32,
    /// An overrun was logged in this status interval.
    overrun_logged: bool,
    /// Longest tick in this status interval, CPU cycles.
    max_work_cycles: u32,
    /// Tracker mode of the previous tick.
    mode: Option<TrackerMode>,
    /// Motors were stopped for encoder faults on the previous tick.
    encoder_halt: bool,
}

impl LoopStats {
    /// Logs what changed this tick: the tracker's mode, the encoder halt,
    /// a motor fault.
    fn log_events(&mut self, step: &RobotTick) {
        let mode = step.pilot.tracker.mode;
        if self.mode != Some(mode) {
            defmt::info!("tick {=u32}: tracker {}", self.ticks, mode);
            self.mode = Some(mode);
        }
        if step.pilot.encoder_halt != self.encoder_halt {
            if step.pilot.encoder_halt {
                defmt::warn!(
                    "tick {=u32}: encoder reads failing, motors stopped",
                    self.ticks
                );
            } else {
                defmt::info!("tick {=u32}: encoder reads back", self.ticks);
            }
            self.encoder_halt = step.pilot.encoder_halt;
        }
        if let Some(fault) = step.motor_fault {
            defmt::warn!("tick {=u32}: motor fault {}", self.ticks, fault);
        }
    }
}

/// The once-a-second status: mode, position, reference, duties, timing and
/// counters; at [`STACK_LOG_AT_TICK`], the stack high-water mark.
fn log_status(
    robot: &BoardRobot<'_>,
    step: &RobotTick,
    stats: &LoopStats,
    [rfid_uart, mavlink_uart]: [RxCounters; 2],
    cycles_per_us: u32,
) {
    let tracker = &step.pilot.tracker;
    defmt::info!(
        "tick {=u32} {} pos ({=f32}, {=f32}) m ref ({=f32}, {=f32}) m duty L {=f32} R {=f32} | tick max {=u32} us, overruns {=u32}",
        stats.ticks,
        tracker.mode,
        tracker.position.x,
        tracker.position.y,
        tracker.reference.position.x,
        tracker.reference.position.y,
        step.pilot.left.signed(),
        step.pilot.right.signed(),
        stats.max_work_cycles / cycles_per_us,
        stats.overruns
    );
    defmt::info!(
        "counters: robot {} rfid {} pilot {} rfid uart {}",
        robot.counters(),
        robot.rfid_counters(),
        robot.pilot().counters(),
        rfid_uart
    );
    defmt::info!(
        "mavlink uart {} bytes read {=u32}",
        mavlink_uart,
        stats.mavlink_bytes
    );
    if stats.ticks == STACK_LOG_AT_TICK {
        defmt::info!("peak stack {=u32} B", crate::stack::peak_bytes());
    }
}
