//! The Black Pill's devices behind the core's traits.
//!
//! - [`Encoder`]: a timer in encoder mode (the HAL's [`Qei`]) as a
//!   [`QuadratureCounter`].
//! - [`Port`] + [`PortReader`]: a USART received by its interrupt into a
//!   ring ([`wmr_link::rx_ring`]), read by the tick as a non-blocking
//!   [`embedded_io::Read`] + [`embedded_io::ReadReady`] (embedded-io 0.7):
//!   the RFID reader's USART2 for the core's `RfidReader`, and the MAVLink
//!   port's USART1, which also transmits by interrupt from the port's
//!   transmit ring ([`queue_tx`]).
//!
//! # Why the MAVLink port transmits by interrupt
//! The endpoint writes its frames at the tick (a few hundred bytes at
//! most: a telemetry burst, a mission item, a parameter); at 115 200 Bd
//! each byte takes 87 µs on the line, so writing them by polling `TXE`
//! would hold the tick for tens of milliseconds. The tick copies them
//! into the transmit ring ([`queue_tx`], [`rx_ring::TX_CHUNK`] bytes per critical
//! section) and turns the transmit interrupt on; the interrupt moves one
//! byte per "data register empty" and turns itself off when the ring is
//! empty. DMA (DMA2 stream 7, channel 4) would save the interrupt per
//! byte (about 11,500 a second at the line's full rate, of about 40
//! instructions each on the send path, `mavlink_usart_interrupt` of
//! `cargo xtask bench-target`: under 1 % of the core), at the price of
//! `unsafe` buffer addresses handed to the DMA controller; the interrupt
//! is safe code and cheap enough. The endpoint is given the ring's free room as its buffer, so
//! a frame that does not fit is dropped whole and counted by it, never
//! cut.
//!
//! # Why the UARTs are received by interrupt
//! The F411's USART has no receive FIFO: its data register holds one byte,
//! and the next arrives one byte time later (1.04 ms at 9600 Bd, 87 µs at
//! 115 200 Bd). Read only by the control tick, a UART would keep one byte a
//! tick and overrun the rest. So each USART's receive interrupt (`RXNEIE`:
//! a byte, or an overrun) moves the byte into the port's ring
//! ([`on_interrupt`], [`rx_ring::service_rx`]), whatever the tick
//! is doing, and the tick reads the ring ([`PortReader`]) as the core's
//! `RfidReader` reads any UART, so the core is unchanged. The rings are
//! sized so that a tick late by several periods loses nothing
//! (`super::RING_WINDOW_US`).
//!
//! Producer and consumer share each port as a `static`
//! `critical_section::Mutex<RefCell<Port>>` ([`SharedPort`]): no `unsafe`,
//! and each access a short critical section (one byte pushed, or at most
//! [`rx_ring::READ_CHUNK`] bytes popped). Line errors (overrun, framing, noise,
//! parity) and bytes dropped because a ring was full are counted per kind
//! in the ring's [`RxCounters`], and each one is also reported once through
//! [`ReadReady::read_ready`], so the core's `RfidCounters::read_errors`
//! counts the RFID reader's too.

use core::convert::Infallible;
use core::ops::Deref;

use embedded_io::{ErrorKind, ErrorType, Read, ReadReady};
use stm32f4xx_hal::pac;
use stm32f4xx_hal::pac::tim3::ccmr1_input::ICFILTER;
use stm32f4xx_hal::qei::{self, Qei};
use wmr_core::devices::QuadratureCounter;

pub use wmr_link::rx_ring::Port;
use wmr_link::rx_ring::{self, RxCounters, TxCounters, Usart};

use super::setup::UartRx;

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

/// A USART's receiver and its receive ring of `N` bytes, and its
/// transmit ring of `T` bytes (1 for a port that sends nothing), shared
/// between the USART's interrupt handler (the producer of received
/// bytes, the consumer of bytes to send) and the control tick: the
/// shared [`rx_ring::Port`] on the board's [`UartRx`]. See the module
/// documentation.
pub type SharedPort<U, const N: usize, const T: usize> = rx_ring::SharedPort<UartRx<U>, N, T>;

/// The USART's registers as the shared handler ([`rx_ring::on_interrupt`])
/// reads and writes them: the status register, the data register (its
/// read clears `RXNE` and the error flags) and `CR1.TXEIE`.
impl<U: Deref<Target = pac::usart1::RegisterBlock>> Usart for UartRx<U> {
    fn status(&self) -> u32 {
        u32::from(self.usart.sr().read().bits())
    }

    fn read_data(&mut self) -> u8 {
        self.usart.dr().read().dr().bits().to_le_bytes()[0]
    }

    fn write_data(&mut self, byte: u8) {
        self.usart.dr().write(|w| w.dr().set(u16::from(byte)));
    }

    fn tx_interrupt_enabled(&self) -> bool {
        self.usart.cr1().read().txeie().bit_is_set()
    }

    fn set_tx_interrupt(&mut self, on: bool) {
        self.usart.cr1().modify(|_, w| w.txeie().bit(on));
    }
}

/// Hands the receiver to its port, for the interrupt handler. Call before
/// unmasking the UART's interrupt: until then the handler finds no
/// receiver and does nothing.
pub fn attach<U, const N: usize, const T: usize>(port: &SharedPort<U, N, T>, rx: UartRx<U>) {
    rx_ring::attach(port, rx);
}

/// The UART interrupt handler's body ([`rx_ring::on_interrupt`], the code
/// `wmr-bench` counts): the received byte, or the error, into the port's
/// ring; then, if the transmitter is waiting for one, the next byte to
/// send.
#[inline(always)]
pub fn on_interrupt<U, const N: usize, const T: usize>(port: &SharedPort<U, N, T>)
where
    U: Deref<Target = pac::usart1::RegisterBlock>,
{
    rx_ring::on_interrupt(port);
}

/// Free room of `port`'s transmit ring, bytes.
#[cfg_attr(not(wmr_robot_image), allow(dead_code))]
pub fn tx_room<U, const N: usize, const T: usize>(port: &SharedPort<U, N, T>) -> usize {
    rx_ring::tx_room(port)
}

/// Queues `bytes` on `port`'s transmit ring ([`rx_ring::TX_CHUNK`] bytes
/// per critical section) and turns the transmit interrupt on; returns the
/// bytes queued (the rest are counted in the ring's
/// [`TxCounters::ring_full`]).
#[cfg_attr(not(wmr_robot_image), allow(dead_code))]
pub fn queue_tx<U, const N: usize, const T: usize>(
    port: &SharedPort<U, N, T>,
    bytes: &[u8],
) -> usize
where
    U: Deref<Target = pac::usart1::RegisterBlock>,
{
    rx_ring::queue_tx(port, bytes)
}

/// The counters of `port`'s transmit ring.
#[cfg_attr(not(wmr_robot_image), allow(dead_code))]
pub fn tx_counters<U, const N: usize, const T: usize>(port: &SharedPort<U, N, T>) -> TxCounters {
    rx_ring::tx_counters(port)
}

/// The counters of `port`'s ring (all zero in the impossible case of a
/// port already borrowed).
pub fn counters<U, const N: usize, const T: usize>(port: &SharedPort<U, N, T>) -> RxCounters {
    rx_ring::rx_counters(port)
}

/// The tick's side of a [`Port`]: its ring as embedded-io 0.7
/// `Read + ReadReady`, for the core's `RfidReader` (and the MAVLink
/// byte path). See the module documentation.
///
/// Never blocks: [`Read::read`] returns what the ring holds, up to
/// [`rx_ring::READ_CHUNK`] bytes, and at least one byte whenever
/// [`ReadReady::read_ready`] said `true` (the interrupt only adds bytes).
/// Called on an empty ring (which `RfidReader` never does: it asks
/// `read_ready` first) it returns `Ok(0)` instead of waiting.
pub struct PortReader<U: 'static, const N: usize, const T: usize> {
    port: &'static SharedPort<U, N, T>,
    /// How many of the ring's faults were already reported.
    reported: u32,
}

impl<U, const N: usize, const T: usize> PortReader<U, N, T> {
    /// The reader of `port`; faults already counted are not reported.
    pub fn new(port: &'static SharedPort<U, N, T>) -> Self {
        let mut reader = Self { port, reported: 0 };
        reader.reported = reader.counters().faults();
        reader
    }

    /// The ring's counters.
    pub fn counters(&self) -> RxCounters {
        counters(self.port)
    }

    /// Bytes waiting and faults counted, in one critical section.
    fn state(&self) -> (bool, u32) {
        rx_ring::rx_state(self.port).unwrap_or((false, self.reported))
    }
}

impl<U, const N: usize, const T: usize> ErrorType for PortReader<U, N, T> {
    /// [`ErrorKind::InvalidData`]: bytes were lost or corrupted on the
    /// line; the per-kind detail is in [`RxCounters`].
    type Error = ErrorKind;
}

impl<U, const N: usize, const T: usize> ReadReady for PortReader<U, N, T> {
    /// `true` while the ring holds bytes. Once it is empty, each fault not
    /// yet reported is returned as one `Err` (after the bytes, so that good
    /// data is never held back); the RFID reader counts it and ends its poll.
    fn read_ready(&mut self) -> Result<bool, ErrorKind> {
        let (ready, faults) = self.state();
        if ready {
            return Ok(true);
        }
        if self.reported < faults {
            self.reported = self.reported.saturating_add(1);
            return Err(ErrorKind::InvalidData);
        }
        Ok(false)
    }
}

impl<U, const N: usize, const T: usize> Read for PortReader<U, N, T> {
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, ErrorKind> {
        Ok(rx_ring::read(self.port, buf))
    }
}
