//! The Black Pill's devices behind the core's traits.
//!
//! - [`Encoder`]: a timer in encoder mode (the HAL's [`Qei`]) as a
//!   [`QuadratureCounter`].
//! - [`RfidPump`] + [`RfidUart`]: USART2 as a non-blocking
//!   [`embedded_io::Read`] + [`embedded_io::ReadReady`] (embedded-io 0.7)
//!   for the core's `RfidReader`.
//!
//! # Why the UART needs a pump
//! The receiver is USART2 by register (`setup::RfidRx`: the HAL's serial
//! set-up needs the HAL's clock set-up, which has panic paths), and the
//! core reads embedded-io 0.7 `Read + ReadReady`, so an adapter is needed
//! anyway. More importantly, the F411's USART has no receive FIFO: its data register
//! holds one byte, and at 9600 Bd the next byte arrives 1.04 ms later. A
//! reader polled once per 10 ms control tick would keep one byte in ten and
//! count the rest as overruns. So the receiver is split in two halves over
//! a lock-free single-producer single-consumer ring ([`heapless::spsc`]):
//!
//! - [`RfidPump`] owns the receiver and moves each received byte into the
//!   ring. The control loop calls [`RfidPump::pump`] continuously while it
//!   waits for the next tick, i.e. for the whole idle part of every period.
//! - [`RfidUart`] owns the ring's consumer and is what the core's
//!   `RfidReader` reads, inside `Robot::tick`, without ever blocking.
//!
//! Line errors (overrun, framing, noise, parity) and bytes dropped because
//! the ring was full are counted per kind in a shared [`LineErrors`] (a
//! `Cell`: everything runs in one thread, no interrupt touches it), and each
//! one is also reported once through [`ReadReady::read_ready`], so the core's
//! `RfidCounters::read_errors` counts them too. An overrun can only happen if
//! one tick's work (between two pumps) exceeds one byte time, 1.04 ms.

use core::cell::Cell;
use core::convert::Infallible;

use core::ops::Deref;
use embedded_io::{ErrorKind, ErrorType, Read, ReadReady};
use heapless::spsc::{Consumer, Producer};
use stm32f4xx_hal::pac;
use stm32f4xx_hal::pac::tim3::ccmr1_input::ICFILTER;
use stm32f4xx_hal::qei::{self, Qei};
use wmr_core::devices::QuadratureCounter;

use super::setup::{LineError, RfidRx};

/// A wheel encoder: a timer in quadrature encoder mode (both edges of both
/// channels, x4), read as the core's [`QuadratureCounter`].
///
/// The raw 16-bit counter is returned as is (the pilot is configured with
/// `encoder_bits: 16` and unwraps it). An encoder mounted mirror-image, like
/// its motor, counts down when its wheel drives the robot forward; such an
/// encoder is built with `reversed: true` and its count is complemented
/// (`!count`, which wraps like the counter itself), so that forward is
/// counting up on both wheels. Swapping its A and B wires does the same.
///
/// The HAL sets the timer up in encoder mode ([`Qei`]); [`Encoder::new`]
/// then takes the timer back and sets its inputs' digital filter
/// (`CCMR1.IC1F/IC2F`, which the HAL leaves at "none";
/// [`super::ENCODER_INPUT_FILTER`]), and reads the counter register itself.
pub struct Encoder<TIM: qei::Instance> {
    tim: TIM,
    reversed: bool,
}

impl<TIM> Encoder<TIM>
where
    TIM: qei::Instance + Deref<Target = pac::tim3::RegisterBlock>,
{
    /// Takes a timer configured in encoder mode by the HAL and sets both
    /// inputs' filter to `input_filter` (see
    /// [`super::ENCODER_INPUT_FILTER`]). The counter keeps running; the A
    /// and B pins stay in their timer alternate function (their type
    /// tokens are dropped, their configuration is in the GPIO registers).
    pub fn new(qei: Qei<TIM>, reversed: bool, input_filter: ICFILTER) -> Self {
        let (tim, _pins) = qei.release();
        tim.ccmr1_input()
            .modify(|_, w| w.ic1f().variant(input_filter).ic2f().variant(input_filter));
        Self { tim, reversed }
    }
}

impl<TIM> QuadratureCounter for Encoder<TIM>
where
    TIM: qei::Instance + Deref<Target = pac::tim3::RegisterBlock>,
{
    /// Reading a timer's counter register cannot fail.
    type Error = Infallible;

    fn raw_count(&mut self) -> Result<u32, Infallible> {
        let count = self.tim.cnt().read().cnt().bits();
        Ok(u32::from(if self.reversed { !count } else { count }))
    }
}

/// Receive-side faults of the RFID UART, by kind (all counters saturate).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, defmt::Format)]
pub struct LineErrors {
    /// A byte arrived before the previous one was read (ORE): at least one
    /// byte lost.
    pub overrun: u32,
    /// Stop bit not found (FE): wrong baud rate, noise or a line break.
    pub framing: u32,
    /// Noise detected during a bit (NF).
    pub noise: u32,
    /// Parity error (PE; not expected at 8N1).
    pub parity: u32,
    /// Bytes received while the ring was full (the reader fell behind).
    pub ring_full: u32,
}

impl LineErrors {
    /// All faults of all kinds.
    pub fn total(&self) -> u32 {
        self.overrun
            .saturating_add(self.framing)
            .saturating_add(self.noise)
            .saturating_add(self.parity)
            .saturating_add(self.ring_full)
    }
}

/// Adds one to the counter `which` selects.
fn count(errors: &Cell<LineErrors>, which: impl FnOnce(&mut LineErrors) -> &mut u32) {
    let mut e = errors.get();
    let counter = which(&mut e);
    *counter = counter.saturating_add(1);
    errors.set(e);
}

/// The hardware half of the RFID UART: moves received bytes from USART2
/// into the ring. See the module documentation.
pub struct RfidPump<'a> {
    rx: RfidRx,
    ring: Producer<'a, u8>,
    errors: &'a Cell<LineErrors>,
}

impl<'a> RfidPump<'a> {
    /// Takes the receiver, the ring's producer and the shared error counters.
    pub fn new(rx: RfidRx, ring: Producer<'a, u8>, errors: &'a Cell<LineErrors>) -> Self {
        Self { rx, ring, errors }
    }

    /// Moves the received byte, if any, into the ring, or counts the line
    /// error the USART flags. Never blocks: one status-register read, and
    /// one data-register read when a byte or an error is pending (which is
    /// also what clears the error flags).
    pub fn pump(&mut self) {
        match self.rx.read() {
            Ok(Some(byte)) => {
                if self.ring.enqueue(byte).is_err() {
                    count(self.errors, |e| &mut e.ring_full);
                }
            }
            Ok(None) => {}
            Err(error) => count(self.errors, |e| match error {
                LineError::Overrun => &mut e.overrun,
                LineError::Framing => &mut e.framing,
                LineError::Noise => &mut e.noise,
                LineError::Parity => &mut e.parity,
            }),
        }
    }
}

/// The reader half of the RFID UART: the ring's consumer, as embedded-io
/// 0.7 `Read + ReadReady` for the core's `RfidReader`. See the module
/// documentation.
///
/// Never blocks: [`Read::read`] returns what the ring holds, up to the
/// buffer's length, and at least one byte whenever [`ReadReady::read_ready`]
/// said `true`. Called on an empty ring (which `RfidReader` never does: it
/// asks `read_ready` first) it returns `Ok(0)` instead of waiting, since in
/// this single-threaded firmware nothing would fill the ring while it
/// waited.
pub struct RfidUart<'a> {
    ring: Consumer<'a, u8>,
    errors: &'a Cell<LineErrors>,
    /// How many of `errors.total()` were already reported.
    reported: u32,
}

impl<'a> RfidUart<'a> {
    /// Takes the ring's consumer and the shared error counters.
    pub fn new(ring: Consumer<'a, u8>, errors: &'a Cell<LineErrors>) -> Self {
        Self {
            ring,
            errors,
            reported: errors.get().total(),
        }
    }
}

impl ErrorType for RfidUart<'_> {
    /// [`ErrorKind::InvalidData`]: bytes were lost or corrupted on the
    /// line; the per-kind detail is in [`LineErrors`].
    type Error = ErrorKind;
}

impl ReadReady for RfidUart<'_> {
    /// `true` while the ring holds bytes. Once it is empty, each line error
    /// not yet reported is returned as one `Err` (after the bytes, so that
    /// good data is never held back); the reader counts it and ends its poll.
    fn read_ready(&mut self) -> Result<bool, ErrorKind> {
        if self.ring.ready() {
            return Ok(true);
        }
        if self.reported < self.errors.get().total() {
            self.reported = self.reported.saturating_add(1);
            return Err(ErrorKind::InvalidData);
        }
        Ok(false)
    }
}

impl Read for RfidUart<'_> {
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, ErrorKind> {
        let mut n = 0;
        for slot in buf.iter_mut() {
            let Some(byte) = self.ring.dequeue() else {
                break;
            };
            *slot = byte;
            n += 1;
        }
        Ok(n)
    }
}
