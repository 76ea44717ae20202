//! Devices whose other side is the link: what the firmware's robot talks to
//! when the host simulator plays the hardware.
//!
//! Each proxy implements the same embedded-hal / embedded-io trait as the
//! real peripheral (and as the simulator's virtual device), so the core's
//! [`wmr_core::pilot::robot::Robot`] runs unchanged on top of them. They share one
//! [`ProxyBus`] through `Cell`s: the session writes a tick's readings into
//! the bus, the robot reads and writes the proxies, the session reads the
//! motor outputs back. Single-threaded (one control loop), no `unsafe`.
//! The UART ring is the one `RefCell`: it is borrowed with `try_borrow` /
//! `try_borrow_mut` only, never held across a call into another proxy, so
//! a borrow cannot fail, and if it ever did the access would see an empty
//! or full buffer instead of panicking (no panic path in the control loop:
//! `cargo xtask panic-free`).

use core::cell::{Cell, RefCell};
use core::convert::Infallible;

use embedded_hal::digital::{self, OutputPin};
use embedded_hal::pwm::{self, SetDutyCycle};
use wmr_core::devices::QuadratureCounter;

use crate::{MotorOutput, TickInput};

/// Bytes the proxy UART buffers (a real UART driver's receive ring).
pub const UART_BUFFER_BYTES: usize = 512;

/// The shared state of all proxies.
#[derive(Debug)]
pub struct ProxyBus {
    counts: [Cell<Option<u32>>; 2],
    uart: RefCell<heapless::Deque<u8, UART_BUFFER_BYTES>>,
    uart_overruns: Cell<u32>,
    motors: [Cell<MotorOutput>; 2],
    pwm_max_duty: Cell<u16>,
}

impl Default for ProxyBus {
    fn default() -> Self {
        Self::new()
    }
}

/// A wheel side.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    /// Left wheel.
    Left = 0,
    /// Right wheel.
    Right = 1,
}

impl ProxyBus {
    /// Empty bus: encoders unread (a read fails), motors stopped.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            counts: [Cell::new(None), Cell::new(None)],
            uart: RefCell::new(heapless::Deque::new()),
            uart_overruns: Cell::new(0),
            motors: [
                Cell::new(MotorOutput {
                    duty: 0,
                    direction_high: false,
                }),
                Cell::new(MotorOutput {
                    duty: 0,
                    direction_high: false,
                }),
            ],
            pwm_max_duty: Cell::new(1),
        }
    }

    /// Sets the PWM full scale (`≥ 1`) and stops both motors.
    pub fn reset(&self, pwm_max_duty: u16) {
        self.pwm_max_duty.set(pwm_max_duty.max(1));
        self.stop_motors();
        for c in &self.counts {
            c.set(None);
        }
        if let Ok(mut fifo) = self.uart.try_borrow_mut() {
            fifo.clear();
        }
    }

    /// Loads one tick's readings: encoder counters, and the UART bytes
    /// appended to the receive buffer (bytes beyond its capacity are lost
    /// and counted, as a UART overrun).
    pub fn load(&self, input: &TickInput) {
        let [left, right] = &self.counts;
        left.set(input.left_count);
        right.set(input.right_count);
        let mut fifo = self.uart.try_borrow_mut();
        for &byte in &input.uart {
            // A byte the ring cannot take (full, or, impossibly, borrowed)
            // is lost and counted, as a UART overrun.
            if !fifo.as_mut().is_ok_and(|f| f.push_back(byte).is_ok()) {
                self.uart_overruns
                    .set(self.uart_overruns.get().saturating_add(1));
            }
        }
    }

    /// Stops both motors (duty 0, direction kept).
    pub fn stop_motors(&self) {
        for m in &self.motors {
            m.set(MotorOutput { duty: 0, ..m.get() });
        }
    }

    /// What a motor was last driven with.
    #[must_use]
    pub fn motor(&self, side: Side) -> MotorOutput {
        self.motor_cell(side).get()
    }

    /// UART bytes lost to a full buffer.
    #[must_use]
    pub fn uart_overruns(&self) -> u32 {
        self.uart_overruns.get()
    }

    fn motor_cell(&self, side: Side) -> &Cell<MotorOutput> {
        let [left, right] = &self.motors;
        match side {
            Side::Left => left,
            Side::Right => right,
        }
    }

    /// The encoder proxy of one wheel.
    #[must_use]
    pub fn encoder(&self, side: Side) -> ProxyEncoder<'_> {
        ProxyEncoder { bus: self, side }
    }

    /// The PWM proxy of one motor.
    #[must_use]
    pub fn pwm(&self, side: Side) -> ProxyPwm<'_> {
        ProxyPwm { bus: self, side }
    }

    /// The direction-pin proxy of one motor.
    #[must_use]
    pub fn direction_pin(&self, side: Side) -> ProxyPin<'_> {
        ProxyPin { bus: self, side }
    }

    /// The RFID reader's UART proxy.
    #[must_use]
    pub fn uart(&self) -> ProxyUart<'_> {
        ProxyUart { bus: self }
    }
}

/// Failed encoder read (the host sent none for this tick).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct NoReading;

/// An encoder counter as the host reported it.
#[derive(Debug, Clone, Copy)]
pub struct ProxyEncoder<'a> {
    bus: &'a ProxyBus,
    side: Side,
}

impl QuadratureCounter for ProxyEncoder<'_> {
    type Error = NoReading;

    fn raw_count(&mut self) -> Result<u32, NoReading> {
        let [left, right] = &self.bus.counts;
        match self.side {
            Side::Left => left,
            Side::Right => right,
        }
        .get()
        .ok_or(NoReading)
    }
}

/// A PWM channel whose duty goes back to the host.
#[derive(Debug, Clone, Copy)]
pub struct ProxyPwm<'a> {
    bus: &'a ProxyBus,
    side: Side,
}

impl pwm::ErrorType for ProxyPwm<'_> {
    type Error = Infallible;
}

impl SetDutyCycle for ProxyPwm<'_> {
    fn max_duty_cycle(&self) -> u16 {
        self.bus.pwm_max_duty.get()
    }

    fn set_duty_cycle(&mut self, duty: u16) -> Result<(), Infallible> {
        let cell = self.bus.motor_cell(self.side);
        cell.set(MotorOutput {
            duty: duty.min(self.bus.pwm_max_duty.get()),
            ..cell.get()
        });
        Ok(())
    }
}

/// A direction pin whose level goes back to the host.
#[derive(Debug, Clone, Copy)]
pub struct ProxyPin<'a> {
    bus: &'a ProxyBus,
    side: Side,
}

impl digital::ErrorType for ProxyPin<'_> {
    type Error = Infallible;
}

impl OutputPin for ProxyPin<'_> {
    fn set_low(&mut self) -> Result<(), Infallible> {
        self.set(false);
        Ok(())
    }

    fn set_high(&mut self) -> Result<(), Infallible> {
        self.set(true);
        Ok(())
    }
}

impl ProxyPin<'_> {
    fn set(&self, high: bool) {
        let cell = self.bus.motor_cell(self.side);
        cell.set(MotorOutput {
            direction_high: high,
            ..cell.get()
        });
    }
}

/// The RFID reader's UART: serves the bytes the host forwarded, in order.
#[derive(Debug, Clone, Copy)]
pub struct ProxyUart<'a> {
    bus: &'a ProxyBus,
}

impl embedded_io::ErrorType for ProxyUart<'_> {
    type Error = Infallible;
}

impl embedded_io::ReadReady for ProxyUart<'_> {
    fn read_ready(&mut self) -> Result<bool, Infallible> {
        Ok(self.bus.uart.try_borrow().is_ok_and(|f| !f.is_empty()))
    }
}

impl embedded_io::Read for ProxyUart<'_> {
    /// Never blocks: `Ok(0)` when nothing is buffered (the core reads only
    /// after `read_ready`).
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Infallible> {
        let Ok(mut fifo) = self.bus.uart.try_borrow_mut() else {
            return Ok(0);
        };
        let mut n = 0;
        for slot in buf.iter_mut() {
            match fifo.pop_front() {
                Some(byte) => {
                    *slot = byte;
                    n += 1;
                }
                None => break,
            }
        }
        Ok(n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use embedded_io::{Read, ReadReady};

    #[test]
    fn proxies_carry_readings_in_and_drives_out() {
        let bus = ProxyBus::new();
        bus.reset(1000);
        let mut left = bus.encoder(Side::Left);
        assert_eq!(left.raw_count(), Err(NoReading));
        let mut uart_bytes = heapless::Vec::new();
        uart_bytes.extend_from_slice(b"\x02ABC").unwrap();
        bus.load(&TickInput {
            tick: 0,
            left_count: Some(65_535),
            right_count: None,
            uart: uart_bytes,
        });
        assert_eq!(left.raw_count(), Ok(65_535));
        assert_eq!(bus.encoder(Side::Right).raw_count(), Err(NoReading));
        let mut uart = bus.uart();
        assert_eq!(uart.read_ready(), Ok(true));
        let mut buf = [0; 2];
        assert_eq!(uart.read(&mut buf), Ok(2));
        assert_eq!(&buf, b"\x02A");
        let mut buf = [0; 8];
        assert_eq!(uart.read(&mut buf), Ok(2));
        assert_eq!(uart.read_ready(), Ok(false));

        let mut pwm = bus.pwm(Side::Right);
        assert_eq!(pwm.max_duty_cycle(), 1000);
        pwm.set_duty_cycle(2000).unwrap();
        bus.direction_pin(Side::Right).set_high().unwrap();
        assert_eq!(
            bus.motor(Side::Right),
            MotorOutput {
                duty: 1000,
                direction_high: true
            }
        );
        bus.stop_motors();
        assert_eq!(bus.motor(Side::Right).duty, 0);
    }

    #[test]
    fn the_uart_ring_keeps_byte_order_across_its_wrap() {
        let bus = ProxyBus::new();
        let mut uart = bus.uart();
        let mut next_in: u8 = 0;
        let mut next_out: u8 = 0;
        // Loads of 160 bytes and reads of 150: the ring holds up to 450
        // bytes (290 left over and a load) while 4,800 pass, wrapping round
        // its 512 bytes 9 times, and no byte is lost or reordered.
        for _ in 0..30 {
            let mut bytes = heapless::Vec::new();
            while !bytes.is_full() {
                bytes.push(next_in).unwrap();
                next_in = next_in.wrapping_add(1);
            }
            bus.load(&TickInput {
                tick: 0,
                left_count: None,
                right_count: None,
                uart: bytes,
            });
            let mut buf = [0; 150];
            let n = uart.read(&mut buf).unwrap();
            assert_eq!(n, buf.len());
            for &b in &buf[..n] {
                assert_eq!(b, next_out);
                next_out = next_out.wrapping_add(1);
            }
        }
        assert_eq!(bus.uart_overruns(), 0);
        bus.reset(1);
        assert_eq!(uart.read_ready(), Ok(false));
    }

    #[test]
    fn a_full_uart_buffer_counts_lost_bytes() {
        let bus = ProxyBus::new();
        let mut uart = heapless::Vec::new();
        uart.resize(crate::MAX_UART_BYTES_PER_TICK, 0x30).unwrap();
        let input = TickInput {
            tick: 0,
            left_count: None,
            right_count: None,
            uart,
        };
        for _ in 0..4 {
            bus.load(&input);
        }
        assert_eq!(
            bus.uart_overruns() as usize,
            4 * crate::MAX_UART_BYTES_PER_TICK - UART_BUFFER_BYTES
        );
    }
}
