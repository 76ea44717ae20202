//! A receive ring for a UART: the bytes an interrupt handler takes off the
//! line, held until the control tick reads them, with every byte that
//! could not be held counted.
//!
//! [`RxRing`] is plain data with `&mut self` methods: one producer (the
//! UART's receive interrupt) pushes, one consumer (the tick) pops. A board
//! shares it between the two as a [`SharedPort`] (a
//! `critical_section::Mutex<RefCell<Port>>` holding the USART, its receive
//! ring and its [`TxRing`]) in a `static` (the Black Pill:
//! `firmware/src/board/blackpill/devices.rs`): no `unsafe`, no heap, and a
//! critical section of a few instructions per byte pushed or per chunk
//! popped. The interrupt handler's body ([`on_interrupt`]) is here, generic
//! over the USART's registers ([`Usart`]), so that the board runs it on
//! its USARTs and `wmr-bench` counts its instructions on registers in RAM. `heapless::spsc` would avoid the
//! critical section but needs `&'static mut` queue storage to split
//! (`unsafe` or a `singleton!`), and its producer would still have to reach
//! the interrupt handler through a `Mutex<RefCell<Option<…>>>`; with the
//! mutex there anyway, a [`heapless::Deque`] inside it is the simpler whole.
//!
//! # Guarantees
//! - Bytes come out in the order they went in, none duplicated.
//! - Lossless until full: a push into a full ring drops that byte and
//!   counts it in [`RxCounters::ring_full`]; a line error the producer
//!   reports (the USART's overrun, framing, noise, parity flags) is counted
//!   by kind. Nothing is dropped without a count.
//! - Sizing: a consumer that empties the ring at least every `W` µs loses
//!   nothing on a line of `B` baud if the capacity is at least
//!   [`bytes_in_window`]`(B, W)` (the bytes that can arrive in `W`, plus one
//!   for the byte the USART's data register may still hold). The tests
//!   check that bound against a simulated line and tick.
//!
//! Never panics: the deque's pushes and pops are checked, the counters
//! saturate (except [`RxCounters::received`], a traffic counter that wraps).

use heapless::Deque;

/// A receive-side fault the producer reports with [`RxRing::line_error`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LineError {
    /// A byte arrived before the previous one was read (the USART's ORE):
    /// at least one byte lost on the line.
    Overrun,
    /// Stop bit not found (FE): wrong baud rate, noise or a line break.
    Framing,
    /// Noise detected during a bit (NF).
    Noise,
    /// Parity error (PE).
    Parity,
}

/// What a ring has seen since it was made.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RxCounters {
    /// Bytes taken into the ring (wrapping: a traffic counter).
    pub received: u32,
    /// Bytes dropped because the ring was full (the consumer fell behind).
    pub ring_full: u32,
    /// Hardware overruns: bytes lost before they reached the ring.
    pub overrun: u32,
    /// Framing errors.
    pub framing: u32,
    /// Noise errors.
    pub noise: u32,
    /// Parity errors.
    pub parity: u32,
    /// The most bytes the ring has held at once: its margin on a real
    /// line is its capacity minus this.
    pub peak: u32,
}

impl RxCounters {
    /// Every fault of every kind (bytes lost or suspect), saturating.
    #[must_use]
    pub fn faults(&self) -> u32 {
        self.ring_full
            .saturating_add(self.overrun)
            .saturating_add(self.framing)
            .saturating_add(self.noise)
            .saturating_add(self.parity)
    }
}

/// A fixed-capacity receive ring of `N` bytes with its fault counters; see
/// the module documentation.
#[derive(Debug)]
pub struct RxRing<const N: usize> {
    bytes: Deque<u8, N>,
    counters: RxCounters,
}

impl<const N: usize> Default for RxRing<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> RxRing<N> {
    /// An empty ring (`const`: it can initialise a `static`).
    #[must_use]
    pub const fn new() -> Self {
        Self {
            bytes: Deque::new(),
            counters: RxCounters {
                received: 0,
                ring_full: 0,
                overrun: 0,
                framing: 0,
                noise: 0,
                parity: 0,
                peak: 0,
            },
        }
    }

    /// Bytes the ring holds at most.
    #[must_use]
    pub const fn capacity(&self) -> usize {
        N
    }

    /// Bytes waiting.
    #[must_use]
    pub fn len(&self) -> usize {
        self.bytes.len()
    }

    /// No byte waiting.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }

    /// Takes a received byte; `false` if the ring was full, in which case
    /// the byte is dropped and counted in [`RxCounters::ring_full`].
    pub fn push(&mut self, byte: u8) -> bool {
        if self.bytes.push_back(byte).is_ok() {
            let c = &mut self.counters;
            c.received = c.received.wrapping_add(1);
            c.peak = c
                .peak
                .max(u32::try_from(self.bytes.len()).unwrap_or(u32::MAX));
            true
        } else {
            self.counters.ring_full = self.counters.ring_full.saturating_add(1);
            false
        }
    }

    /// Counts a line error of the kind given.
    pub fn line_error(&mut self, error: LineError) {
        let c = &mut self.counters;
        let counter = match error {
            LineError::Overrun => &mut c.overrun,
            LineError::Framing => &mut c.framing,
            LineError::Noise => &mut c.noise,
            LineError::Parity => &mut c.parity,
        };
        *counter = counter.saturating_add(1);
    }

    /// The oldest byte waiting, taken out.
    pub fn pop(&mut self) -> Option<u8> {
        self.bytes.pop_front()
    }

    /// Moves the oldest waiting bytes into `buf`, as many as fit; returns
    /// how many (0 when the ring is empty or `buf` is).
    pub fn pop_into(&mut self, buf: &mut [u8]) -> usize {
        let mut n = 0;
        for slot in buf.iter_mut() {
            let Some(byte) = self.bytes.pop_front() else {
                break;
            };
            *slot = byte;
            n += 1;
        }
        n
    }

    /// What the ring has seen.
    #[must_use]
    pub fn counters(&self) -> RxCounters {
        self.counters
    }
}

/// What a transmit ring has seen since it was made.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TxCounters {
    /// Bytes handed to the UART (wrapping: a traffic counter).
    pub sent: u32,
    /// Bytes refused because the ring was full (the caller offered more
    /// than [`TxRing::room`]), saturating.
    pub ring_full: u32,
    /// The most bytes the ring has held at once.
    pub peak: u32,
}

/// A fixed-capacity transmit ring of `N` bytes (`N` a power of two): the
/// tick queues whole frames ([`TxRing::push_slice`], within
/// [`TxRing::room`]), the UART's transmit interrupt takes one byte at
/// each "data register empty" ([`TxRing::pop`]). Shared between the two
/// as [`RxRing`] is (module documentation). Never panics; a byte that
/// finds no room is refused and counted, never silently lost.
///
/// Its state is two free-running counts, the bytes ever queued and ever
/// sent (both wrapping): the bytes waiting are their difference, the
/// next byte in and out at each count modulo `N` (a mask, `N` dividing
/// 2^32), and [`TxCounters::sent`] is the sent count itself. The
/// interrupt's pop is then a compare, a masked load and an increment,
/// and a queued byte a masked store (a `heapless::Deque` keeps a
/// "full" flag besides its two indices, and wraps each index by a
/// compare).
#[derive(Debug)]
pub struct TxRing<const N: usize> {
    bytes: [u8; N],
    /// Bytes ever queued (wrapping).
    queued: u32,
    /// Bytes ever sent (wrapping).
    sent: u32,
    ring_full: u32,
    peak: u32,
}

impl<const N: usize> Default for TxRing<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> TxRing<N> {
    /// `N - 1`, the mask of an index; refuses, at compile time, an `N`
    /// that is not a power of two (or does not fit the counts).
    const MASK: u32 = {
        assert!(
            N.is_power_of_two() && N <= 1 << 31,
            "TxRing's N: a power of two"
        );
        (N - 1) as u32
    };

    /// An empty ring (`const`: it can initialise a `static`).
    #[must_use]
    pub const fn new() -> Self {
        let _ = Self::MASK;
        Self {
            bytes: [0; N],
            queued: 0,
            sent: 0,
            ring_full: 0,
            peak: 0,
        }
    }

    /// Bytes waiting to be sent.
    #[must_use]
    pub fn len(&self) -> usize {
        self.queued.wrapping_sub(self.sent) as usize
    }

    /// Nothing waiting.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.queued == self.sent
    }

    /// Bytes that can still be queued.
    #[must_use]
    pub fn room(&self) -> usize {
        N.saturating_sub(self.len())
    }

    /// Queues what fits of `bytes`, in order; returns how many. The rest
    /// is counted in [`TxCounters::ring_full`].
    pub fn push_slice(&mut self, bytes: &[u8]) -> usize {
        let n = bytes.len().min(self.room());
        let mut at = self.queued;
        for &b in bytes.iter().take(n) {
            if let Some(slot) = self.bytes.get_mut((at & Self::MASK) as usize) {
                *slot = b;
            }
            at = at.wrapping_add(1);
        }
        self.queued = at;
        let refused = u32::try_from(bytes.len().saturating_sub(n)).unwrap_or(u32::MAX);
        self.ring_full = self.ring_full.saturating_add(refused);
        self.peak = self.peak.max(u32::try_from(self.len()).unwrap_or(u32::MAX));
        n
    }

    /// The next byte to send, taken out (counted sent).
    pub fn pop(&mut self) -> Option<u8> {
        if self.queued == self.sent {
            return None;
        }
        let b = self.bytes.get((self.sent & Self::MASK) as usize).copied();
        self.sent = self.sent.wrapping_add(1);
        b
    }

    /// What the ring has seen.
    #[must_use]
    pub fn counters(&self) -> TxCounters {
        TxCounters {
            sent: self.sent,
            ring_full: self.ring_full,
            peak: self.peak,
        }
    }
}

/// Bits of the STM32F4 USART's status register (`USART_SR`, RM0383
/// §19.6.1) that [`service_rx`] and [`service_tx`] read.
pub mod status {
    /// Parity error.
    pub const PE: u32 = 1 << 0;
    /// Framing error.
    pub const FE: u32 = 1 << 1;
    /// Noise detected.
    pub const NF: u32 = 1 << 2;
    /// Overrun: a byte arrived before the held one was read.
    pub const ORE: u32 = 1 << 3;
    /// A received byte waits in the data register.
    pub const RXNE: u32 = 1 << 5;
    /// The transmit data register is empty.
    pub const TXE: u32 = 1 << 7;
}

/// A USART's registers as its interrupt handler uses them: the status
/// register, the data register read and written, and the transmit
/// interrupt's enable bit (`CR1.TXEIE`). The Black Pill implements it on
/// its USARTs' register blocks (`firmware/src/board/blackpill/devices.rs`);
/// `wmr-bench` on registers in RAM, so that it counts the handler's own
/// instructions ([`on_interrupt`]) as the board runs them.
pub trait Usart {
    /// The status register ([`status`]'s bits).
    fn status(&self) -> u32;
    /// The received byte (reading the data register clears `RXNE` and the
    /// error flags on the STM32).
    fn read_data(&mut self) -> u8;
    /// `byte` into the data register, to send (clears `TXE`).
    fn write_data(&mut self, byte: u8);
    /// Whether the transmit interrupt (`TXEIE`) is on.
    fn tx_interrupt_enabled(&self) -> bool;
    /// Turns the transmit interrupt on or off.
    fn set_tx_interrupt(&mut self, on: bool);
}

/// The receive interrupt's work: moves the byte `usart` holds, if any,
/// into `ring`, and counts the errors it flags. One status read, and one
/// data read whenever a byte or an error is pending (the data read is
/// what clears `RXNE` and the error flags, so the interrupt does not fire
/// again for the same byte).
///
/// An overrun (`ORE`) means a byte after the held one was lost; the held
/// one is valid (RM0383 §19.3.4) and goes into the ring. A byte with a
/// parity, framing or noise error is suspect and is dropped, counted by
/// its kind.
pub fn service_rx<U: Usart, const N: usize>(usart: &mut U, ring: &mut RxRing<N>) {
    let sr = usart.status();
    let suspect = sr & (status::PE | status::FE | status::NF);
    if sr & (status::RXNE | status::ORE) == 0 && suspect == 0 {
        return;
    }
    let byte = usart.read_data();
    // Each flag tested on its own, not in a loop over the kinds: the
    // Black Pill's firmware crate is built for size (opt-level "z"),
    // where such a loop stays a loop, an iterator's calls a flag.
    if sr & status::ORE != 0 {
        ring.line_error(LineError::Overrun);
    }
    if sr & status::PE != 0 {
        ring.line_error(LineError::Parity);
    }
    if sr & status::FE != 0 {
        ring.line_error(LineError::Framing);
    }
    if sr & status::NF != 0 {
        ring.line_error(LineError::Noise);
    }
    if suspect == 0 {
        ring.push(byte);
    }
}

/// The transmit interrupt's work: while the transmit interrupt is on
/// ([`Usart::set_tx_interrupt`]) and the data register is empty (`TXE`),
/// the next byte of `ring` into it (the write clears `TXE`); an empty
/// ring turns the interrupt off, so it does not fire again until bytes
/// are queued ([`queue_tx`]).
pub fn service_tx<U: Usart, const N: usize>(usart: &mut U, ring: &mut TxRing<N>) {
    if !usart.tx_interrupt_enabled() || usart.status() & status::TXE == 0 {
        return;
    }
    match ring.pop() {
        Some(byte) => usart.write_data(byte),
        None => usart.set_tx_interrupt(false),
    }
}

/// A USART `U`, its receive ring of `N` bytes and its transmit ring of
/// `T` bytes (1 for a port that sends nothing), shared between the
/// USART's interrupt handler (the producer of received bytes, the
/// consumer of bytes to send: [`on_interrupt`]) and the control tick in
/// a `static` [`SharedPort`]: no `unsafe`, and each access a short
/// critical section (one byte moved, or at most [`READ_CHUNK`] bytes
/// popped, or [`TX_CHUNK`] queued).
pub struct Port<U, const N: usize, const T: usize> {
    /// The USART, once [`attach`] has put it there.
    usart: Option<U>,
    rx: RxRing<N>,
    tx: TxRing<T>,
}

impl<U, const N: usize, const T: usize> Default for Port<U, N, T> {
    fn default() -> Self {
        Self::new()
    }
}

impl<U, const N: usize, const T: usize> Port<U, N, T> {
    /// No USART yet, empty rings (`const`: for a `static`).
    #[must_use]
    pub const fn new() -> Self {
        Self {
            usart: None,
            rx: RxRing::new(),
            tx: TxRing::new(),
        }
    }
}

/// A [`Port`] as a `static`: a critical section's mutex around it.
pub type SharedPort<U, const N: usize, const T: usize> =
    critical_section::Mutex<core::cell::RefCell<Port<U, N, T>>>;

/// Hands the USART to its port, for the interrupt handler. Call before
/// unmasking the USART's interrupt: until then the handler finds no
/// USART and does nothing.
pub fn attach<U, const N: usize, const T: usize>(port: &SharedPort<U, N, T>, usart: U) {
    critical_section::with(|cs| {
        if let Ok(mut port) = port.borrow(cs).try_borrow_mut() {
            port.usart = Some(usart);
        }
    });
}

/// The USART interrupt handler's body: the received byte, or the error,
/// into the port's receive ring ([`service_rx`]); then, if the
/// transmitter is waiting for one, the next byte to send
/// ([`service_tx`]). One critical section.
pub fn on_interrupt<U: Usart, const N: usize, const T: usize>(port: &SharedPort<U, N, T>) {
    critical_section::with(|cs| {
        // Never already borrowed: every borrow is inside a critical
        // section, and a single core runs one at a time.
        if let Ok(mut port) = port.borrow(cs).try_borrow_mut() {
            let Port { usart, rx, tx } = &mut *port;
            if let Some(usart) = usart {
                service_rx(usart, rx);
                // A port built with a one-byte transmit ring (the RFID
                // reader's: nothing is sent to it) never turns its
                // transmit interrupt on: its handler leaves the
                // transmit path out.
                if T > 1 {
                    service_tx(usart, tx);
                }
            }
        }
    });
}

/// Most bytes one critical section of [`queue_tx`] copies into a
/// transmit ring (interrupts masked for about as long as a
/// [`READ_CHUNK`] read).
pub const TX_CHUNK: usize = 16;

/// Most bytes one [`read`] takes out of a receive ring, in one critical
/// section (interrupts masked): 16 byte moves, against 87 µs between two
/// bytes at 115 200 Bd, so no receive interrupt waits long enough to
/// lose a byte.
pub const READ_CHUNK: usize = 16;

/// Free room of `port`'s transmit ring, bytes (0 in the impossible case
/// of a port already borrowed).
pub fn tx_room<U, const N: usize, const T: usize>(port: &SharedPort<U, N, T>) -> usize {
    critical_section::with(|cs| {
        port.borrow(cs)
            .try_borrow()
            .map(|port| port.tx.room())
            .unwrap_or(0)
    })
}

/// Queues `bytes` on `port`'s transmit ring, [`TX_CHUNK`] bytes per
/// critical section, and turns the transmit interrupt on; returns the
/// bytes queued (all of them when they fit [`tx_room`]; the rest are
/// counted in the ring's [`TxCounters::ring_full`]).
pub fn queue_tx<U: Usart, const N: usize, const T: usize>(
    port: &SharedPort<U, N, T>,
    bytes: &[u8],
) -> usize {
    let mut queued = 0;
    for chunk in bytes.chunks(TX_CHUNK) {
        queued += critical_section::with(|cs| {
            port.borrow(cs)
                .try_borrow_mut()
                .map(|mut port| {
                    let Port { usart, tx, .. } = &mut *port;
                    let n = tx.push_slice(chunk);
                    if let Some(usart) = usart.as_mut().filter(|_| n > 0) {
                        usart.set_tx_interrupt(true);
                    }
                    n
                })
                .unwrap_or(0)
        });
    }
    queued
}

/// The counters of `port`'s transmit ring.
pub fn tx_counters<U, const N: usize, const T: usize>(port: &SharedPort<U, N, T>) -> TxCounters {
    critical_section::with(|cs| {
        port.borrow(cs)
            .try_borrow()
            .map(|port| port.tx.counters())
            .unwrap_or_default()
    })
}

/// The counters of `port`'s receive ring (all zero in the impossible case
/// of a port already borrowed).
pub fn rx_counters<U, const N: usize, const T: usize>(port: &SharedPort<U, N, T>) -> RxCounters {
    critical_section::with(|cs| {
        port.borrow(cs)
            .try_borrow()
            .map(|port| port.rx.counters())
            .unwrap_or_default()
    })
}

/// Whether `port`'s receive ring holds bytes, and its faults counted, in
/// one critical section (`None` in the impossible case of a port already
/// borrowed).
pub fn rx_state<U, const N: usize, const T: usize>(
    port: &SharedPort<U, N, T>,
) -> Option<(bool, u32)> {
    critical_section::with(|cs| {
        port.borrow(cs)
            .try_borrow()
            .map(|port| (!port.rx.is_empty(), port.rx.counters().faults()))
            .ok()
    })
}

/// Moves the oldest bytes of `port`'s receive ring into `buf`, at most
/// [`READ_CHUNK`] in one critical section; returns how many (0 when the
/// ring is empty).
pub fn read<U, const N: usize, const T: usize>(
    port: &SharedPort<U, N, T>,
    buf: &mut [u8],
) -> usize {
    let len = buf.len().min(READ_CHUNK);
    let Some(chunk) = buf.get_mut(..len) else {
        return 0;
    };
    critical_section::with(|cs| {
        port.borrow(cs)
            .try_borrow_mut()
            .map(|mut port| port.rx.pop_into(chunk))
            .unwrap_or(0)
    })
}

/// The capacity a ring needs on a line of `baud` Bd, 8N1 (10 bits a byte),
/// emptied at least every `window_us` µs: the bytes that can arrive in the
/// window (rounded up), plus one that the USART's data register may hold
/// when the window starts. Saturates at `usize::MAX`.
#[must_use]
pub const fn bytes_in_window(baud: u32, window_us: u32) -> usize {
    // baud / 10 bytes a second; × window / 1e6, rounded up, in u64 (no overflow).
    let bits = baud as u64 * window_us as u64;
    let bytes = bits.div_ceil(10_000_000) + 1;
    if bytes > usize::MAX as u64 {
        usize::MAX
    } else {
        bytes as usize
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn bytes_come_out_in_order() {
        let mut ring = RxRing::<8>::new();
        for b in 1..=5 {
            assert!(ring.push(b));
        }
        assert_eq!(ring.len(), 5);
        assert_eq!(ring.pop(), Some(1));
        let mut buf = [0; 3];
        assert_eq!(ring.pop_into(&mut buf), 3);
        assert_eq!(buf, [2, 3, 4]);
        assert!(ring.push(6));
        let mut buf = [0; 8];
        assert_eq!(ring.pop_into(&mut buf), 2);
        assert_eq!(buf.get(..2), Some(&[5, 6][..]));
        assert!(ring.is_empty());
        assert_eq!(ring.pop(), None);
        assert_eq!(ring.pop_into(&mut buf), 0);
        assert_eq!(ring.counters().received, 6);
        assert_eq!(ring.counters().peak, 5);
        assert_eq!(ring.counters().faults(), 0);
    }

    #[test]
    fn a_full_ring_counts_each_dropped_byte_and_keeps_the_old_ones() {
        let mut ring = RxRing::<4>::new();
        for b in 0..4 {
            assert!(ring.push(b));
        }
        assert!(!ring.push(10));
        assert!(!ring.push(11));
        let c = ring.counters();
        assert_eq!((c.received, c.ring_full, c.faults()), (4, 2, 2));
        assert_eq!(c.peak, 4);
        let mut buf = [0; 8];
        assert_eq!(ring.pop_into(&mut buf), 4);
        assert_eq!(buf.get(..4), Some(&[0, 1, 2, 3][..]));
        // Room again: the next byte is taken.
        assert!(ring.push(12));
        assert_eq!(ring.pop(), Some(12));
        assert_eq!(ring.counters().ring_full, 2);
    }

    #[test]
    fn line_errors_are_counted_by_kind() {
        let mut ring = RxRing::<4>::new();
        ring.line_error(LineError::Overrun);
        ring.line_error(LineError::Overrun);
        ring.line_error(LineError::Framing);
        ring.line_error(LineError::Noise);
        ring.line_error(LineError::Parity);
        let c = ring.counters();
        assert_eq!(
            (c.overrun, c.framing, c.noise, c.parity, c.ring_full),
            (2, 1, 1, 1, 0)
        );
        assert_eq!(c.faults(), 5);
        assert!(ring.is_empty());
    }

    #[test]
    fn window_sizes() {
        // 9600 Bd: 960 B/s, 0.96 bytes a ms.
        assert_eq!(bytes_in_window(9_600, 5_000), 5 + 1);
        assert_eq!(bytes_in_window(9_600, 1_000), 1 + 1);
        // 115200 Bd: 11.52 bytes a ms.
        assert_eq!(bytes_in_window(115_200, 5_000), 58 + 1);
        assert_eq!(bytes_in_window(115_200, 0), 1);
        assert_eq!(bytes_in_window(u32::MAX, u32::MAX), 1_844_674_406_512 + 1);
    }

    /// What a simulated run saw.
    #[derive(Debug, PartialEq, Eq)]
    struct Run {
        sent: u32,
        read: u32,
        in_order: bool,
        ring_full: u32,
        max_len: usize,
        /// The ring's own [`RxCounters::peak`].
        peak: u32,
    }

    /// A UART line at `baud` (8N1, back-to-back bytes) into a ring of `N`,
    /// for `ticks` control ticks: tick `k` ends `period_us + late_us(k)`
    /// after tick `k - 1` (a late tick: the previous one overran) and
    /// empties the ring in reads of `chunk(k)` bytes, as the core's
    /// `RfidReader` does. The interrupt pushes a byte at each byte time.
    /// Time in ns, so that 115200 Bd's 86.8 µs byte time is kept exact
    /// enough (86,805 ns).
    fn simulate<const N: usize>(
        baud: u32,
        period_us: u32,
        ticks: usize,
        late_us: impl Fn(usize) -> u32,
        chunk: impl Fn(usize) -> usize,
    ) -> Run {
        let byte_ns = 10_000_000_000_u64 / u64::from(baud);
        let mut ring = RxRing::<N>::new();
        let mut next_byte_ns = 0_u64;
        let mut now_ns = 0_u64;
        let mut sent: u32 = 0;
        let mut expect: u32 = 0;
        let mut in_order = true;
        let mut max_len = 0;
        for k in 0..ticks {
            now_ns += u64::from(period_us + late_us(k)) * 1_000;
            while next_byte_ns <= now_ns {
                ring.push(sent.to_le_bytes()[0]);
                sent += 1;
                next_byte_ns += byte_ns;
            }
            max_len = max_len.max(ring.len());
            let mut buf = [0_u8; 64];
            let want = chunk(k).clamp(1, buf.len());
            loop {
                let n = ring.pop_into(&mut buf[..want]);
                if n == 0 {
                    break;
                }
                for &b in &buf[..n] {
                    in_order &= b == expect.to_le_bytes()[0];
                    expect += 1;
                }
            }
        }
        Run {
            sent,
            read: expect,
            in_order,
            ring_full: ring.counters().ring_full,
            max_len,
            peak: ring.counters().peak,
        }
    }

    /// The Black Pill's capacities (`firmware/src/board/blackpill.rs`:
    /// `RFID_RING_BYTES`, `MAVLINK_RING_BYTES`).
    const RFID_RING: usize = 128;
    const MAVLINK_RING: usize = 512;

    #[test]
    fn rfid_at_9600_bd_with_a_5_ms_tick_and_late_ticks_loses_nothing() {
        // Every 7th tick 8 ms late (a 13 ms gap), one 60 ms stall.
        let run = simulate::<RFID_RING>(
            9_600,
            5_000,
            2_000,
            |k| match k {
                1_000 => 60_000,
                k if k % 7 == 0 => 8_000,
                _ => 0,
            },
            |k| 1 + k % 16,
        );
        assert_eq!(run.ring_full, 0, "{run:?}");
        assert!(run.in_order, "{run:?}");
        assert_eq!(run.read, run.sent);
        // 2000 ticks ≈ 10 s + late time: about 10,800 bytes at 960 B/s.
        assert!(run.sent > 10_000, "{run:?}");
        // The stall filled the ring to about 63 bytes of its 128.
        assert!(run.max_len < RFID_RING, "{run:?}");
    }

    #[test]
    fn mavlink_at_115200_bd_with_a_5_ms_tick_and_late_ticks_loses_nothing() {
        // Every 5th tick 7 ms late (a 12 ms gap), one 35 ms stall.
        let run = simulate::<MAVLINK_RING>(
            115_200,
            5_000,
            2_000,
            |k| match k {
                1_500 => 35_000,
                k if k % 5 == 0 => 7_000,
                _ => 0,
            },
            |_| 16,
        );
        assert_eq!(run.ring_full, 0, "{run:?}");
        assert!(run.in_order, "{run:?}");
        assert_eq!(run.read, run.sent);
        assert!(run.sent > 110_000, "{run:?}");
        // A 40 ms gap at 11.52 bytes a ms: 461 bytes of 512.
        assert!(run.max_len > 400 && run.max_len < MAVLINK_RING, "{run:?}");
    }

    #[test]
    fn a_stall_longer_than_the_ring_counts_every_lost_byte() {
        // 115200 Bd into 64 bytes: a 20 ms gap brings 230 bytes.
        let run = simulate::<64>(
            115_200,
            5_000,
            100,
            |k| if k == 50 { 15_000 } else { 0 },
            |_| 16,
        );
        assert!(run.ring_full > 0);
        assert_eq!(run.peak, 64);
        // Lost bytes are exactly the ones counted: nothing silent.
        assert_eq!(run.read + run.ring_full, run.sent);
    }

    #[test]
    fn the_tx_ring_sends_in_order_and_counts_what_it_refuses() {
        let mut ring = TxRing::<4>::new();
        assert_eq!(ring.room(), 4);
        assert_eq!(ring.push_slice(&[1, 2, 3]), 3);
        assert_eq!(ring.room(), 1);
        assert_eq!(ring.push_slice(&[4, 5, 6]), 1);
        assert_eq!(ring.counters().ring_full, 2);
        assert_eq!(ring.counters().peak, 4);
        let out: Vec<u8> = core::iter::from_fn(|| ring.pop()).collect();
        assert_eq!(out, [1, 2, 3, 4]);
        assert!(ring.is_empty());
        assert_eq!(ring.counters().sent, 4);
        assert_eq!(ring.pop(), None);
    }

    /// The Black Pill's MAVLink transmit ring (`MAVLINK_TX_RING_BYTES`).
    const MAVLINK_TX_RING: usize = 1_024;

    /// A tick of `period_us` that queues `frame(k)` bytes (only when they
    /// fit the ring's room, as the board gives the endpoint the room as
    /// its buffer; a frame that does not fit is the endpoint's to count)
    /// into a [`TxRing`] that the transmit interrupt empties at one byte
    /// per byte time of a `baud` line. Returns the bytes queued, sent,
    /// whether in order, the frames that found no room, and the ring's
    /// counters.
    fn simulate_tx<const N: usize>(
        baud: u32,
        period_us: u32,
        ticks: usize,
        frame: impl Fn(usize) -> usize,
    ) -> (u32, u32, bool, u32, TxCounters) {
        let byte_ns = 10_000_000_000_u64 / u64::from(baud);
        let mut ring = TxRing::<N>::new();
        let (mut queued, mut sent, mut in_order, mut no_room) = (0_u32, 0_u32, true, 0_u32);
        let mut next_byte_ns = 0_u64;
        let mut now_ns = 0_u64;
        for k in 0..ticks {
            let tick_end = now_ns + u64::from(period_us) * 1_000;
            let n = frame(k);
            if n <= ring.room() {
                let bytes: Vec<u8> = (0..n)
                    .map(|i| (queued + i as u32).to_le_bytes()[0])
                    .collect();
                assert_eq!(ring.push_slice(&bytes), n);
                queued += n as u32;
            } else {
                no_room += 1;
            }
            // The line: a byte leaves at each byte time while the ring
            // holds one (the interrupt refills the data register).
            next_byte_ns = next_byte_ns.max(now_ns);
            while next_byte_ns + byte_ns <= tick_end {
                let Some(b) = ring.pop() else { break };
                in_order &= b == sent.to_le_bytes()[0];
                sent += 1;
                next_byte_ns += byte_ns;
            }
            now_ns = tick_end;
        }
        (queued, sent, in_order, no_room, ring.counters())
    }

    #[test]
    fn mavlink_telemetry_at_10_hz_goes_out_whole_at_115200_bd_with_a_5_ms_tick() {
        // The endpoint's output at 10 Hz telemetry with a geodetic origin
        // (the most it sends): LOCAL_POSITION_NED
        // (40 B), ATTITUDE (40 B) and GLOBAL_POSITION_INT (40 B) every
        // 20th tick of 5 ms, HEARTBEAT (21 B) and SYS_STATUS (43 B) every
        // 200th, and a mission download's MISSION_ITEM_INT (50 B) every
        // 3rd tick for a while: far under the line's 57.6 bytes a tick.
        let frame = |k: usize| {
            let mut n = 0;
            if k.is_multiple_of(20) {
                n += 120;
            }
            if k.is_multiple_of(200) {
                n += 64;
            }
            if (400..600).contains(&k) && k.is_multiple_of(3) {
                n += 50;
            }
            n
        };
        let (queued, sent, in_order, no_room, c) =
            simulate_tx::<MAVLINK_TX_RING>(115_200, 5_000, 4_000, frame);
        assert_eq!((no_room, c.ring_full), (0, 0), "{c:?}");
        assert!(in_order);
        // The last frames are queued at tick 3,980 and take about 10 ms
        // of line: every byte queued has left by the last tick.
        assert_eq!((sent, c.sent), (queued, queued));
        assert!(queued > 20_000);
        assert!((c.peak as usize) < MAVLINK_TX_RING / 4, "{c:?}");
    }

    /// A producer that queues only what fits the ring's room (as the
    /// board's endpoint writes into a buffer of the room: it counts the
    /// frames that do not fit, `frames_past_the_room_are_dropped_whole_and_counted`
    /// in `mavlink_run`) never overfills the ring, and what it queued goes
    /// out whole and in order, however far past the line's rate it
    /// produces.
    #[test]
    fn output_past_the_line_rate_never_overfills_a_ring_given_its_room() {
        // 100 bytes every 1 ms tick onto a 9600 Bd line (0.96 bytes a
        // ms): the ring fills, and every frame that then finds no room
        // is not queued; what was queued goes out in order.
        let (queued, sent, in_order, no_room, c) = simulate_tx::<256>(9_600, 1_000, 1_000, |_| 100);
        assert!(no_room > 900, "{no_room}");
        assert!(in_order);
        assert_eq!(c.sent, sent);
        assert!(queued >= sent && queued - sent <= 256);
        assert_eq!(c.ring_full, 0);
    }

    proptest! {
        /// At any line speed and tick period, with ticks late by any
        /// amount up to a bound and reads of any chunk size, a ring of
        /// `bytes_in_window(baud, longest gap)` or more loses nothing, and
        /// the bytes come out in order.
        #[test]
        fn capacity_of_the_longest_gap_loses_nothing(
            baud in 1_200_u32..=230_400,
            period_us in 1_000_u32..=20_000,
            max_late_us in 0_u32..=20_000,
            lates in proptest::collection::vec(0.0_f64..=1.0, 1..64),
            chunks in proptest::collection::vec(1_usize..=64, 1..16),
        ) {
            let gap_us = period_us + max_late_us;
            let needed = bytes_in_window(baud, gap_us);
            // The ring's capacity is a const: the smallest of these that fits.
            let late = |k: usize| {
                let f = lates.get(k % lates.len()).copied().unwrap_or(0.0);
                (f * f64::from(max_late_us)) as u32
            };
            let chunk = |k: usize| chunks.get(k % chunks.len()).copied().unwrap_or(1);
            let ticks = 300;
            let run = if needed <= 64 {
                simulate::<64>(baud, period_us, ticks, late, chunk)
            } else if needed <= 256 {
                simulate::<256>(baud, period_us, ticks, late, chunk)
            } else if needed <= 1_024 {
                simulate::<1_024>(baud, period_us, ticks, late, chunk)
            } else {
                simulate::<2_048>(baud, period_us, ticks, late, chunk)
            };
            prop_assert_eq!(run.ring_full, 0, "{:?}", run);
            prop_assert!(run.in_order);
            prop_assert_eq!(run.read, run.sent);
            // The bound is tight to within one byte: the fullest the ring
            // got never exceeds what the longest gap can bring.
            prop_assert!(run.max_len <= needed, "{:?} needed {}", run, needed);
            // The ring's peak is the fullest it got: just before a tick.
            prop_assert_eq!(run.peak as usize, run.max_len);
        }
    }

    /// A USART as registers in memory: what the handler read and wrote.
    #[derive(Debug, Default)]
    struct FakeUsart {
        sr: u32,
        dr: u8,
        txeie: bool,
        data_reads: u32,
        sent: std::vec::Vec<u8>,
    }

    impl Usart for FakeUsart {
        fn status(&self) -> u32 {
            self.sr
        }
        fn read_data(&mut self) -> u8 {
            self.data_reads += 1;
            // As the STM32: the read clears RXNE and the error flags.
            self.sr &= !(status::RXNE | status::ORE | status::PE | status::FE | status::NF);
            self.dr
        }
        fn write_data(&mut self, byte: u8) {
            self.sent.push(byte);
        }
        fn tx_interrupt_enabled(&self) -> bool {
            self.txeie
        }
        fn set_tx_interrupt(&mut self, on: bool) {
            self.txeie = on;
        }
    }

    fn shared<const N: usize, const T: usize>() -> SharedPort<FakeUsart, N, T> {
        let port = SharedPort::new(core::cell::RefCell::new(Port::new()));
        attach(&port, FakeUsart::default());
        port
    }

    /// Runs `f` on the port's USART and rings.
    fn with_port<const N: usize, const T: usize, R>(
        port: &SharedPort<FakeUsart, N, T>,
        f: impl FnOnce(&mut FakeUsart, &mut RxRing<N>, &mut TxRing<T>) -> R,
    ) -> R {
        critical_section::with(|cs| {
            let mut port = port.borrow(cs).borrow_mut();
            let Port { usart, rx, tx } = &mut *port;
            let usart = usart.as_mut().expect("attached");
            f(usart, rx, tx)
        })
    }

    #[test]
    fn the_handler_moves_a_received_byte_and_counts_each_line_error() {
        let port = shared::<8, 1>();
        // Nothing pending (TXE alone): the data register is not read. The
        // transmit interrupt on, as a fault would leave it: a port with a
        // one-byte transmit ring (the RFID reader's) never services it.
        with_port(&port, |u, _, _| {
            u.sr = status::TXE;
            u.txeie = true;
        });
        on_interrupt(&port);
        with_port(&port, |u, rx, _| {
            assert_eq!(u.data_reads, 0);
            assert!(rx.is_empty());
            u.sr = status::RXNE | status::TXE;
            u.dr = 0x41;
        });
        on_interrupt(&port);
        // An overrun: the held byte is good and kept, the lost one counted.
        with_port(&port, |u, _, _| {
            u.sr = status::RXNE | status::ORE;
            u.dr = 0x42;
        });
        on_interrupt(&port);
        // Framing and noise: the byte is suspect, dropped, both counted.
        with_port(&port, |u, _, _| {
            u.sr = status::RXNE | status::FE | status::NF;
            u.dr = 0x43;
        });
        on_interrupt(&port);
        with_port(&port, |u, _, _| {
            u.sr = status::RXNE | status::PE;
            u.dr = 0x44;
        });
        on_interrupt(&port);
        let mut buf = [0_u8; 8];
        assert_eq!(read(&port, &mut buf), 2);
        assert_eq!(buf.get(..2), Some(&[0x41, 0x42][..]));
        let c = rx_counters(&port);
        assert_eq!(
            (c.received, c.overrun, c.framing, c.noise, c.parity),
            (2, 1, 1, 1, 1)
        );
        assert_eq!(rx_state(&port), Some((false, 4)));
        with_port(&port, |u, _, _| {
            assert_eq!(u.data_reads, 4);
            // Its transmit path left out: nothing sent, the interrupt
            // not turned off (the transmit path would have, its ring
            // being empty).
            assert!(u.sent.is_empty());
            assert!(u.txeie);
        });
    }

    #[test]
    fn the_handler_sends_the_queued_bytes_one_an_interrupt_then_turns_itself_off() {
        let port = shared::<8, 64>();
        let frame: std::vec::Vec<u8> = (0..40).collect();
        assert_eq!(tx_room(&port), 64);
        assert_eq!(queue_tx(&port, &frame), 40);
        assert_eq!(tx_room(&port), 24);
        // The data register still busy: nothing moves.
        with_port(&port, |u, _, _| {
            assert!(u.txeie);
            u.sr = 0;
        });
        on_interrupt(&port);
        with_port(&port, |u, _, _| {
            assert!(u.sent.is_empty());
            u.sr = status::TXE;
        });
        let mut interrupts = 0;
        while with_port(&port, |u, _, _| u.txeie) && interrupts < 100 {
            on_interrupt(&port);
            interrupts += 1;
        }
        // One interrupt a byte, and one more that finds the ring empty.
        assert_eq!(interrupts, 41);
        with_port(&port, |u, _, _| assert_eq!(u.sent, frame));
        let c = tx_counters(&port);
        assert_eq!((c.sent, c.ring_full, c.peak), (40, 0, 40));
        // More than the room: what fits is queued, the rest counted.
        assert_eq!(queue_tx(&port, &[7; 70]), 64);
        assert_eq!(tx_counters(&port).ring_full, 6);
        // Nothing queued: the interrupt stays off.
        let idle = shared::<8, 64>();
        assert_eq!(queue_tx(&idle, &[]), 0);
        with_port(&idle, |u, _, _| assert!(!u.txeie));
    }

    #[test]
    fn a_read_takes_at_most_a_chunk() {
        let port = shared::<64, 1>();
        for b in 0..40 {
            with_port(&port, |u, _, _| {
                u.sr = status::RXNE;
                u.dr = b;
            });
            on_interrupt(&port);
        }
        let mut buf = [0_u8; 64];
        assert_eq!(read(&port, &mut buf), READ_CHUNK);
        assert_eq!(
            buf.get(..READ_CHUNK),
            (0..16).collect::<std::vec::Vec<u8>>().get(..)
        );
        assert_eq!(read(&port, &mut buf), READ_CHUNK);
        assert_eq!(read(&port, &mut buf), 8);
        assert_eq!(read(&port, &mut buf), 0);
        assert_eq!(rx_state(&port), Some((false, 0)));
    }
}
