//! 125 kHz RFID reader on a UART (RDM6300-style ASCII frames).
//!
//! Frame, 14 bytes: `0x02` (STX), 10 ASCII hex characters for the 5-byte tag
//! id (most significant byte first), 2 ASCII hex characters of checksum (the
//! XOR of the 5 id bytes), `0x03` (ETX). At 9600 Bd a frame takes ≈ 15 ms.
//!
//! [`FrameParser`] is a byte-at-a-time state machine that resynchronises on
//! any STX and counts, rather than reports, everything it throws away;
//! [`RfidReader`] drains a non-blocking [`embedded_io`] UART into it with a
//! bounded amount of work per control tick.

use embedded_io::{Read, ReadReady};

/// Start of a frame.
const STX: u8 = 0x02;
/// End of a frame.
const ETX: u8 = 0x03;
/// Hex characters between STX and ETX: 10 for the id, 2 for the checksum.
const HEX_CHARS: u8 = 12;
/// Bytes in a frame.
pub const FRAME_LEN: usize = 14;
/// Size of the stack buffer [`RfidReader::poll`] reads through.
const READ_CHUNK: usize = 16;

/// A 125 kHz (EM4100-family) tag id. Only the low 40 bits are used.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TagId(pub u64);

impl TagId {
    /// Bits of a tag id.
    pub const BITS: u32 = 40;
    /// Mask of the used bits.
    pub const MASK: u64 = (1 << Self::BITS) - 1;

    /// The id with the bits above [`Self::BITS`] cleared.
    #[must_use]
    pub const fn masked(self) -> Self {
        Self(self.0 & Self::MASK)
    }

    /// The 5 id bytes, most significant first (as sent in a frame).
    #[must_use]
    pub const fn to_be_bytes(self) -> [u8; 5] {
        let b = self.0.to_be_bytes();
        [b[3], b[4], b[5], b[6], b[7]]
    }

    /// The frame checksum: XOR of the 5 id bytes.
    #[must_use]
    pub fn checksum(self) -> u8 {
        self.to_be_bytes().iter().fold(0, |acc, b| acc ^ b)
    }
}

/// As printed on tags and in tag maps: 10 uppercase hex digits.
impl core::fmt::Display for TagId {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "{:010X}", self.masked().0)
    }
}

/// The reader's frame for `id` (uppercase hex; bits above 40 are ignored).
///
/// Used by the simulator's virtual reader and by tests.
#[must_use]
pub fn encode_frame(id: TagId) -> [u8; FRAME_LEN] {
    let mut frame = [0_u8; FRAME_LEN];
    let id = id.masked();
    // 12 nibbles: the 40-bit id then the 8-bit checksum, most significant first.
    let payload = (id.0 << 8) | u64::from(id.checksum());
    let mut chars = frame.iter_mut();
    if let Some(first) = chars.next() {
        *first = STX;
    }
    for (i, c) in chars.take(usize::from(HEX_CHARS)).enumerate() {
        let shift = 4 * (usize::from(HEX_CHARS) - 1 - i);
        *c = hex_digit(((payload >> shift) & 0xF) as u8);
    }
    if let Some(last) = frame.last_mut() {
        *last = ETX;
    }
    frame
}

/// Uppercase ASCII hex digit of a nibble (`n < 16`).
fn hex_digit(n: u8) -> u8 {
    if n < 10 { b'0' + n } else { b'A' + (n - 10) }
}

/// Value of an ASCII hex digit, either case.
fn hex_value(c: u8) -> Option<u8> {
    match c {
        b'0'..=b'9' => Some(c - b'0'),
        b'A'..=b'F' => Some(c - b'A' + 10),
        b'a'..=b'f' => Some(c - b'a' + 10),
        _ => None,
    }
}

/// What the reader has seen and thrown away. All counters saturate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct RfidCounters {
    /// Complete frames with a valid checksum.
    pub frames_ok: u32,
    /// Complete, well-formed frames whose checksum did not match.
    pub bad_checksum: u32,
    /// Frames aborted: a non-hex byte inside, a wrong terminator, or cut
    /// short by a new STX.
    pub malformed: u32,
    /// Bytes outside any frame (the CR/LF some readers append, line noise).
    /// Not an error.
    pub bytes_outside_frames: u32,
    /// UART read or ready-check errors ([`RfidReader`] only).
    pub read_errors: u32,
    /// Valid tags that a later valid tag in the same poll replaced
    /// ([`RfidReader`] only).
    pub superseded: u32,
    /// Polls that stopped at [`RfidReader::MAX_BYTES_PER_POLL`] with bytes
    /// still waiting: the reader fell behind the line ([`RfidReader`] only;
    /// the next poll's tags carry the age that implies, see
    /// [`RfidReader::poll_read`]).
    pub backlogged_polls: u32,
}

/// Parser state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
enum State {
    /// Waiting for STX.
    Idle,
    /// After STX, `received` hex characters so far, accumulated in `payload`.
    Hex { received: u8, payload: u64 },
    /// All 12 hex characters in, waiting for ETX.
    Etx { payload: u64 },
}

/// Byte-at-a-time RFID frame parser.
///
/// Resynchronisation: an STX anywhere starts a new frame (a frame it cuts
/// short counts as malformed); a non-hex byte inside a frame or a wrong
/// terminator aborts the frame (counted as malformed) and the parser waits
/// for the next STX; bytes outside a frame are counted, not errors.
#[derive(Debug, Clone, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FrameParser {
    state: State,
    counters: RfidCounters,
}

impl FrameParser {
    /// A parser waiting for its first STX, counters at zero.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            state: State::Idle,
            counters: RfidCounters {
                frames_ok: 0,
                bad_checksum: 0,
                malformed: 0,
                bytes_outside_frames: 0,
                read_errors: 0,
                superseded: 0,
                backlogged_polls: 0,
            },
        }
    }

    /// Feeds one byte; returns the tag when it completes a frame with a valid
    /// checksum.
    pub fn push(&mut self, byte: u8) -> Option<TagId> {
        let c = &mut self.counters;
        if byte == STX {
            if self.state != State::Idle {
                c.malformed = c.malformed.saturating_add(1);
            }
            self.state = State::Hex {
                received: 0,
                payload: 0,
            };
            return None;
        }
        let (next, tag) = match self.state {
            State::Idle => {
                c.bytes_outside_frames = c.bytes_outside_frames.saturating_add(1);
                (State::Idle, None)
            }
            State::Hex { received, payload } => match hex_value(byte) {
                Some(nibble) => {
                    let payload = (payload << 4) | u64::from(nibble);
                    let received = received + 1;
                    if received == HEX_CHARS {
                        (State::Etx { payload }, None)
                    } else {
                        (State::Hex { received, payload }, None)
                    }
                }
                None => {
                    c.malformed = c.malformed.saturating_add(1);
                    (State::Idle, None)
                }
            },
            State::Etx { payload } => {
                if byte != ETX {
                    c.malformed = c.malformed.saturating_add(1);
                    (State::Idle, None)
                } else {
                    let id = TagId(payload >> 8);
                    if id.checksum() == (payload & 0xFF) as u8 {
                        c.frames_ok = c.frames_ok.saturating_add(1);
                        (State::Idle, Some(id))
                    } else {
                        c.bad_checksum = c.bad_checksum.saturating_add(1);
                        (State::Idle, None)
                    }
                }
            }
        };
        self.state = next;
        tag
    }

    /// Whether a frame has started and not yet ended.
    #[must_use]
    pub fn in_frame(&self) -> bool {
        self.state != State::Idle
    }

    /// What the parser has seen so far.
    #[must_use]
    pub fn counters(&self) -> RfidCounters {
        self.counters
    }
}

impl Default for FrameParser {
    fn default() -> Self {
        Self::new()
    }
}

/// A tag read by [`RfidReader::poll_read`], with how old it may be.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TagRead {
    /// The tag.
    pub id: TagId,
    /// Upper bound on the polls (control ticks) since the frame's last
    /// byte arrived: 0 when the previous poll saw the UART empty (so the
    /// frame arrived since), `k` after `k` polls in a row that ended without
    /// seeing it empty: stopped at [`RfidReader::MAX_BYTES_PER_POLL`] with
    /// bytes still waiting, or ended by a ready or read error, or by a read
    /// of 0 bytes while the UART said it was ready.
    pub age_ticks: u32,
}

/// A non-blocking RFID reader on a UART.
///
/// [`Self::poll_read`] is meant to be called once per control tick: it
/// reads only what the UART already holds, and at most
/// [`Self::MAX_BYTES_PER_POLL`] bytes of it.
///
/// # Backlog and age
/// A poll reads until the UART is empty, so that a tag it returns arrived
/// since the previous poll (age 0), and the bound is large enough to empty
/// any UART buffer this project feeds it (the HIL link's 512-byte ring,
/// the Black Pill's ring) in one poll. Should a poll still stop at the
/// bound with bytes waiting, it counts [`RfidCounters::backlogged_polls`],
/// and the next poll's tag carries the age that implies
/// ([`TagRead::age_ticks`]): the tracker rejects a fix older than its
/// `max_fix_age_ticks`, so a backlog is never replayed as fresh. A poll
/// ended by a ready or read error, or by a read of 0 bytes while the UART
/// said it was ready, has not seen the UART empty either, and ages what it
/// left behind the same way (a UART that reports an overrun while bytes
/// are still buffered). Older tags of one poll are counted in
/// [`RfidCounters::superseded`]: only the latest is returned.
#[derive(Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RfidReader<R: Read + ReadReady> {
    uart: R,
    parser: FrameParser,
    /// Polls in a row that ended without seeing the UART empty.
    backlog_polls_in_a_row: u32,
}

impl<R: Read + ReadReady> RfidReader<R> {
    /// Most bytes one poll reads: bounds the control tick's work (the
    /// parser takes a few tens of instructions a byte) and is the size of
    /// the largest UART buffer in the project (the HIL link's ring), so that
    /// one poll drains it. A 9600 Bd reader sends under 10 bytes per 10 ms
    /// tick; the HIL link delivers at most 160.
    pub const MAX_BYTES_PER_POLL: usize = 512;

    /// Takes the UART (configured by the caller, typically 9600 8N1).
    #[must_use]
    pub fn new(uart: R) -> Self {
        Self {
            uart,
            parser: FrameParser::new(),
            backlog_polls_in_a_row: 0,
        }
    }

    /// [`Self::poll_read`] without the age (for callers that poll often
    /// enough to drain the UART every time).
    pub fn poll(&mut self) -> Option<TagId> {
        self.poll_read().map(|read| read.id)
    }

    /// Reads what the UART holds, without blocking, and returns the most
    /// recent valid tag completed during this poll, with its age bound
    /// (type docs, "Backlog and age").
    ///
    /// Reads while `read_ready()` says so, until [`Self::MAX_BYTES_PER_POLL`]
    /// bytes. Earlier valid tags of the same poll are counted in
    /// [`RfidCounters::superseded`]; a read or ready error is counted in
    /// [`RfidCounters::read_errors`] and ends the poll, as does a read of 0
    /// bytes. A frame split across polls is completed by a later poll.
    pub fn poll_read(&mut self) -> Option<TagRead> {
        let age_ticks = self.backlog_polls_in_a_row;
        let mut latest = None;
        let mut budget = Self::MAX_BYTES_PER_POLL;
        let mut buf = [0_u8; READ_CHUNK];
        loop {
            match self.uart.read_ready() {
                Ok(true) => {}
                Ok(false) => {
                    // Emptied: the next poll's bytes all arrive after this.
                    self.backlog_polls_in_a_row = 0;
                    break;
                }
                Err(_) => {
                    self.count_read_error();
                    self.left_bytes_unknown();
                    break;
                }
            }
            if budget == 0 {
                // Bytes waiting beyond the bound: behind the line.
                self.backlog_polls_in_a_row = self.backlog_polls_in_a_row.saturating_add(1);
                let c = &mut self.parser.counters;
                c.backlogged_polls = c.backlogged_polls.saturating_add(1);
                return latest.map(|id| TagRead { id, age_ticks });
            }
            let want = budget.min(buf.len());
            let Some(chunk) = buf.get_mut(..want) else {
                break;
            };
            let n = match self.uart.read(chunk) {
                Ok(0) => {
                    // Ready, yet nothing read: the UART may still hold bytes.
                    self.left_bytes_unknown();
                    break;
                }
                Ok(n) => n.min(want),
                Err(_) => {
                    self.count_read_error();
                    self.left_bytes_unknown();
                    break;
                }
            };
            budget -= n;
            for &byte in chunk.iter().take(n) {
                if let Some(tag) = self.parser.push(byte) {
                    if latest.is_some() {
                        let c = &mut self.parser.counters;
                        c.superseded = c.superseded.saturating_add(1);
                    }
                    latest = Some(tag);
                }
            }
        }
        latest.map(|id| TagRead { id, age_ticks })
    }

    /// What the reader has seen so far.
    #[must_use]
    pub fn counters(&self) -> RfidCounters {
        self.parser.counters
    }

    /// Gives the UART back.
    #[must_use]
    pub fn release(self) -> R {
        self.uart
    }

    /// The poll ended without seeing the UART empty (a ready or read
    /// error, or a 0-byte read while ready): whatever it left behind may
    /// have arrived before this poll, so the next poll's tag is one tick
    /// older at most, as after a backlogged poll.
    fn left_bytes_unknown(&mut self) {
        self.backlog_polls_in_a_row = self.backlog_polls_in_a_row.saturating_add(1);
    }

    fn count_read_error(&mut self) {
        let c = &mut self.parser.counters;
        c.read_errors = c.read_errors.saturating_add(1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::vec::Vec;

    fn parse_all(p: &mut FrameParser, bytes: &[u8]) -> Vec<TagId> {
        bytes.iter().filter_map(|&b| p.push(b)).collect()
    }

    /// A UART over a byte slice: `ready` while bytes remain; reads at most
    /// `chunk` bytes at a time; can be told to fail.
    struct FakeUart<'a> {
        data: &'a [u8],
        pos: usize,
        chunk: usize,
        fail_ready: bool,
        fail_read: bool,
        reads: usize,
    }

    impl<'a> FakeUart<'a> {
        fn new(data: &'a [u8]) -> Self {
            Self {
                data,
                pos: 0,
                chunk: usize::MAX,
                fail_ready: false,
                fail_read: false,
                reads: 0,
            }
        }
    }

    impl embedded_io::ErrorType for FakeUart<'_> {
        type Error = embedded_io::ErrorKind;
    }

    impl ReadReady for FakeUart<'_> {
        fn read_ready(&mut self) -> Result<bool, Self::Error> {
            if self.fail_ready {
                return Err(embedded_io::ErrorKind::Other);
            }
            Ok(self.pos < self.data.len())
        }
    }

    impl Read for FakeUart<'_> {
        fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
            self.reads += 1;
            if self.fail_read {
                return Err(embedded_io::ErrorKind::Other);
            }
            let rest = &self.data[self.pos..];
            assert!(!rest.is_empty(), "read would block");
            let n = rest.len().min(buf.len()).min(self.chunk);
            buf[..n].copy_from_slice(&rest[..n]);
            self.pos += n;
            Ok(n)
        }
    }

    #[test]
    fn known_frame() {
        // 0x0F00A1B2C3 → checksum 0F^00^A1^B2^C3 = 0xDF.
        let id = TagId(0x0F_00A1_B2C3);
        assert_eq!(id.checksum(), 0xDF);
        assert_eq!(&encode_frame(id), b"\x020F00A1B2C3DF\x03");
        assert_eq!(std::format!("{id}"), "0F00A1B2C3");
        let mut p = FrameParser::new();
        assert_eq!(parse_all(&mut p, b"\x020f00a1b2c3Df\x03"), [id]);
        assert_eq!(p.counters().frames_ok, 1);
    }

    #[test]
    fn high_bits_are_ignored_when_encoding() {
        assert_eq!(
            encode_frame(TagId(0xFFFF_0012_3456_789A)),
            encode_frame(TagId(0x12_3456_789A))
        );
    }

    #[test]
    fn resynchronises_after_garbage_and_counts_it() {
        let a = encode_frame(TagId(0x12_3456_789A));
        let b = encode_frame(TagId(0xAB_CDEF_0123));
        let mut bad = encode_frame(TagId(42));
        assert_eq!(bad[11..13], *b"2A");
        bad[12] = b'B'; // well-formed, wrong checksum
        let mut stream = Vec::new();
        stream.extend_from_slice(b"xy\r\n"); // 4 outside
        stream.extend_from_slice(&a[..7]); // cut short by the next STX: malformed
        stream.extend_from_slice(&a);
        stream.extend_from_slice(b"\r\n"); // 2 outside
        stream.extend_from_slice(b"\x0212G"); // non-hex inside: malformed
        stream.extend_from_slice(b"45"); // 2 outside
        stream.extend_from_slice(&bad); // bad checksum
        stream.extend_from_slice(&a[..13]);
        stream.push(b'!'); // wrong terminator: malformed
        stream.extend_from_slice(&b);
        let mut p = FrameParser::new();
        assert_eq!(
            parse_all(&mut p, &stream),
            [TagId(0x12_3456_789A), TagId(0xAB_CDEF_0123)]
        );
        assert_eq!(
            p.counters(),
            RfidCounters {
                frames_ok: 2,
                bad_checksum: 1,
                malformed: 3,
                bytes_outside_frames: 8,
                read_errors: 0,
                superseded: 0,
                backlogged_polls: 0,
            }
        );
        assert!(!p.in_frame());
    }

    #[test]
    fn short_frame_and_stray_etx() {
        let mut p = FrameParser::new();
        assert_eq!(parse_all(&mut p, b"\x03\x021234\x03"), []);
        let c = p.counters();
        assert_eq!((c.bytes_outside_frames, c.malformed), (1, 1));
    }

    #[test]
    fn poll_returns_latest_and_counts_superseded() {
        let stream: Vec<u8> = [1_u64, 2, 3]
            .iter()
            .flat_map(|&i| encode_frame(TagId(i)))
            .collect();
        let mut r = RfidReader::new(FakeUart::new(&stream));
        assert_eq!(r.poll(), Some(TagId(3)));
        assert_eq!(r.counters().superseded, 2);
        assert_eq!(r.counters().frames_ok, 3);
        assert_eq!(r.poll(), None);
    }

    #[test]
    fn frame_split_across_polls_is_found() {
        let frame = encode_frame(TagId(0x99_8877_6655));
        let mut r = RfidReader::new(FakeUart::new(&frame[..5]));
        assert_eq!(r.poll(), None);
        let parser = r.parser.clone();
        // Same parser state, the rest of the frame arrives on the next tick.
        let mut r = RfidReader {
            uart: FakeUart::new(&frame[5..]),
            parser,
            backlog_polls_in_a_row: 0,
        };
        assert_eq!(r.poll(), Some(TagId(0x99_8877_6655)));
    }

    /// A backlog beyond one poll's bound is read on the next poll, and its
    /// tag says it may be a tick old; an emptied UART resets the age.
    #[test]
    fn backlog_is_drained_and_aged() {
        // 50 frames = 700 bytes: 512 on the first poll (36 whole frames),
        // the rest on the second.
        let stream: Vec<u8> = (0..50_u64)
            .flat_map(|i| encode_frame(TagId(1000 + i)))
            .collect();
        let seven = encode_frame(TagId(7));
        let mut r = RfidReader::new(FakeUart::new(&stream));
        let first = r.poll_read();
        assert_eq!(
            first,
            Some(TagRead {
                id: TagId(1035),
                age_ticks: 0
            })
        );
        assert_eq!(r.counters().backlogged_polls, 1);
        assert_eq!(
            r.poll_read(),
            Some(TagRead {
                id: TagId(1049),
                age_ticks: 1
            })
        );
        assert_eq!(r.uart.pos, stream.len());
        assert_eq!(r.counters().backlogged_polls, 1);
        assert_eq!(r.counters().superseded, 48);
        assert_eq!(r.poll_read(), None);
        // Emptied: fresh again.
        r.uart = FakeUart::new(&seven);
        assert_eq!(
            r.poll_read(),
            Some(TagRead {
                id: TagId(7),
                age_ticks: 0
            })
        );
    }

    #[test]
    fn per_poll_budget_is_respected() {
        // 10 frames = 140 bytes; small chunks exercise partial reads.
        let stream: Vec<u8> = (0..10_u64)
            .flat_map(|i| encode_frame(TagId(1000 + i)))
            .collect();
        let mut uart = FakeUart::new(&stream);
        uart.chunk = 5;
        let mut r = RfidReader::new(uart);
        let max = RfidReader::<FakeUart>::MAX_BYTES_PER_POLL;
        let mut tags = Vec::new();
        let mut polls = 0;
        loop {
            let before = r.uart.pos;
            let tag = r.poll();
            let read = r.uart.pos - before;
            assert!(read <= max, "poll read {read} > {max}");
            if read == 0 {
                break;
            }
            polls += 1;
            tags.extend(tag);
        }
        assert_eq!(polls, stream.len().div_ceil(max));
        assert_eq!(r.uart.pos, stream.len());
        // Each poll returns the last frame it completed.
        assert_eq!(tags.last(), Some(&TagId(1009)));
        let c = r.counters();
        assert_eq!(c.frames_ok, 10);
        assert_eq!(c.superseded as usize + tags.len(), 10);
    }

    #[test]
    fn uart_errors_are_counted_and_end_the_poll() {
        let frame = encode_frame(TagId(7));
        let mut uart = FakeUart::new(&frame);
        uart.fail_ready = true;
        let mut r = RfidReader::new(uart);
        assert_eq!(r.poll(), None);
        assert_eq!(r.uart.reads, 0);
        r.uart.fail_ready = false;
        r.uart.fail_read = true;
        assert_eq!(r.poll(), None);
        assert_eq!(r.uart.reads, 1);
        assert_eq!(r.counters().read_errors, 2);
        r.uart.fail_read = false;
        assert_eq!(r.poll(), Some(TagId(7)));
        assert_eq!(r.release().pos, FRAME_LEN);
    }

    /// A frame already buffered when polls start to fail, read once they
    /// stop: each failed poll (ready error, read error, or a 0-byte read
    /// while ready) may have left it waiting, so it comes out as old as the
    /// failed polls before it, and the tracker's `max_fix_age_ticks` can
    /// reject it.
    #[test]
    fn a_frame_left_behind_by_failed_polls_is_aged() {
        struct Flaky<'a> {
            uart: FakeUart<'a>,
            zero_reads: usize,
        }
        impl embedded_io::ErrorType for Flaky<'_> {
            type Error = embedded_io::ErrorKind;
        }
        impl ReadReady for Flaky<'_> {
            fn read_ready(&mut self) -> Result<bool, Self::Error> {
                self.uart.read_ready()
            }
        }
        impl Read for Flaky<'_> {
            fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
                if self.zero_reads > 0 {
                    self.zero_reads -= 1;
                    return Ok(0);
                }
                self.uart.read(buf)
            }
        }
        let frame = encode_frame(TagId(7));
        let mut r = RfidReader::new(Flaky {
            uart: FakeUart::new(&frame),
            zero_reads: 1,
        });
        // Poll 0: a 0-byte read while ready. Poll 1: a ready error.
        // Poll 2: a read error. Poll 3 reads the frame, buffered since
        // before poll 0.
        assert_eq!(r.poll_read(), None);
        r.uart.uart.fail_ready = true;
        assert_eq!(r.poll_read(), None);
        r.uart.uart.fail_ready = false;
        r.uart.uart.fail_read = true;
        assert_eq!(r.poll_read(), None);
        r.uart.uart.fail_read = false;
        assert_eq!(
            r.poll_read(),
            Some(TagRead {
                id: TagId(7),
                age_ticks: 3
            })
        );
        let c = r.counters();
        assert_eq!((c.read_errors, c.backlogged_polls), (2, 0));
        // That poll saw the UART empty: the next frame is fresh.
        r.uart.uart = FakeUart::new(&frame);
        assert_eq!(r.poll_read().map(|read| read.age_ticks), Some(0));
    }

    /// A reader that claims data but returns 0 bytes (EOF) must not spin.
    #[test]
    fn zero_byte_read_ends_the_poll() {
        struct Eof(usize);
        impl embedded_io::ErrorType for Eof {
            type Error = core::convert::Infallible;
        }
        impl ReadReady for Eof {
            fn read_ready(&mut self) -> Result<bool, Self::Error> {
                Ok(true)
            }
        }
        impl Read for Eof {
            fn read(&mut self, _: &mut [u8]) -> Result<usize, Self::Error> {
                self.0 += 1;
                Ok(0)
            }
        }
        let mut r = RfidReader::new(Eof(0));
        assert_eq!(r.poll(), None);
        assert_eq!(r.release().0, 1);
    }

    /// Bytes that can never start or end a frame.
    fn garbage() -> impl Strategy<Value = Vec<u8>> {
        prop::collection::vec(any::<u8>().prop_filter("no STX", |&b| b != STX), 0..40)
    }

    proptest! {
        #[test]
        fn round_trip_any_40_bit_id(raw in 0_u64..=TagId::MASK, lower in any::<bool>()) {
            let mut frame = encode_frame(TagId(raw));
            if lower {
                frame.make_ascii_lowercase();
            }
            let mut p = FrameParser::new();
            prop_assert_eq!(parse_all(&mut p, &frame), [TagId(raw)]);
            prop_assert_eq!(p.counters(), RfidCounters { frames_ok: 1, ..RfidCounters::default() });
        }

        #[test]
        fn garbage_around_frames_does_not_hide_them(
            ids in prop::collection::vec(0_u64..=TagId::MASK, 1..5),
            gaps in prop::collection::vec(garbage(), 5),
        ) {
            let mut stream = Vec::new();
            for (id, gap) in ids.iter().zip(&gaps) {
                stream.extend_from_slice(gap);
                stream.extend_from_slice(&encode_frame(TagId(*id)));
            }
            let mut p = FrameParser::new();
            let found = parse_all(&mut p, &stream);
            let want: Vec<TagId> = ids.iter().map(|&i| TagId(i)).collect();
            prop_assert_eq!(found, want);
        }

        #[test]
        fn never_panics_and_counts_add_up(bytes in prop::collection::vec(any::<u8>(), 0..600)) {
            let mut p = FrameParser::new();
            let tags = parse_all(&mut p, &bytes);
            let c = p.counters();
            prop_assert_eq!(tags.len(), c.frames_ok as usize);
            // Every STX starts a frame; every frame ends exactly once (ok, bad
            // checksum, malformed) or is still open.
            let stx = bytes.iter().filter(|&&b| b == STX).count();
            let ended = (c.frames_ok + c.bad_checksum + c.malformed) as usize;
            prop_assert_eq!(stx, ended + usize::from(p.in_frame()));
            prop_assert!(c.bytes_outside_frames as usize <= bytes.len() - stx);
        }

        #[test]
        fn never_accepts_a_wrong_checksum(
            raw in 0_u64..=TagId::MASK,
            wrong in any::<u8>(),
            lower in any::<bool>(),
            before in garbage(),
            after in garbage(),
        ) {
            let id = TagId(raw);
            prop_assume!(wrong != id.checksum());
            let mut frame = encode_frame(id);
            frame[11] = hex_digit(wrong >> 4);
            frame[12] = hex_digit(wrong & 0xF);
            if lower {
                frame.make_ascii_lowercase();
            }
            // No STX in the garbage, so the only frame that can start is this one.
            let mut p = FrameParser::new();
            prop_assert_eq!(parse_all(&mut p, &before), []);
            let in_frame: Vec<TagId> = parse_all(&mut p, &frame);
            prop_assert_eq!(in_frame, []);
            prop_assert_eq!(parse_all(&mut p, &after), []);
            let c = p.counters();
            prop_assert_eq!((c.frames_ok, c.bad_checksum, c.malformed), (0, 1, 0));
        }

        #[test]
        fn reader_finds_every_frame_over_arbitrary_read_sizes(
            ids in prop::collection::vec(0_u64..=TagId::MASK, 1..8),
            chunk in 1_usize..20,
        ) {
            let stream: Vec<u8> = ids.iter().flat_map(|&i| encode_frame(TagId(i))).collect();
            let mut uart = FakeUart::new(&stream);
            uart.chunk = chunk;
            let mut r = RfidReader::new(uart);
            let mut last = None;
            while r.uart.pos < stream.len() {
                if let Some(t) = r.poll() {
                    last = Some(t);
                }
            }
            let c = r.counters();
            prop_assert_eq!(c.frames_ok as usize, ids.len());
            prop_assert_eq!(last, ids.last().map(|&i| TagId(i)));
        }
    }
}
