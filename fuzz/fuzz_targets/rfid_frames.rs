//! Arbitrary bytes into the RFID frame parser and into `RfidReader` (over a
//! fake UART that serves them in arbitrary chunks and fails on demand),
//! judged by an oracle written here from the frame format of the module's
//! docs, not from the parser: a frame is `0x02`, 12 ASCII hex characters
//! (either case: 10 for the 40-bit id, most significant first, 2 for the
//! XOR of its 5 bytes), `0x03`; any `0x02` starts a new frame.
//!
//! Input: byte 0 drives the UART's chunk sizes and the bytes' arrival,
//! byte 1 its faults; the rest is the stream. Each tag's age must bound
//! the polls since its frame arrived from above, through every poll
//! outcome (bytes read, a backlog, a read of 0 bytes while bytes wait, a
//! ready or read error).

#![no_main]

use std::cell::Cell;

use embedded_io::{ErrorKind, ErrorType, Read, ReadReady};
use libfuzzer_sys::fuzz_target;
use wmr_core::devices::{FrameParser, RfidCounters, RfidReader, TagId};

const STX: u8 = 0x02;
const ETX: u8 = 0x03;

fn hex(c: u8) -> Option<u8> {
    (c as char).to_digit(16).map(|d| d as u8)
}

/// What the oracle reads in a stream.
#[derive(Debug, Default)]
struct Oracle {
    /// Valid frames: (index of their ETX, tag id).
    valid: Vec<(usize, u64)>,
    /// Well-formed frames with a wrong checksum.
    bad_checksum: u32,
    /// Frames begun and aborted.
    malformed: u32,
    /// Bytes outside any frame.
    outside: u32,
    /// A frame is still open at the end.
    open: bool,
}

/// Window by window: from each STX, the frame takes up to 13 more bytes;
/// it is well-formed if those are 12 hex characters and an ETX. Otherwise
/// it ends at the first byte that does not fit (consumed, unless it is an
/// STX, which opens the next frame) or, if the stream ends first, is open.
fn oracle(s: &[u8]) -> Oracle {
    let mut o = Oracle::default();
    let mut i = 0;
    while i < s.len() {
        if s[i] != STX {
            o.outside += 1;
            i += 1;
            continue;
        }
        // A frame starts at i.
        let body = &s[i + 1..];
        let hex_run = body
            .iter()
            .take(12)
            .take_while(|&&c| hex(c).is_some())
            .count();
        if hex_run == body.len() {
            // The stream ended inside the frame (at most 12 hex characters).
            o.open = true;
            break;
        }
        let next = body[hex_run];
        if hex_run == 12 && next == ETX {
            let digits: Vec<u8> = body[..12].iter().map(|&c| hex(c).unwrap_or(0)).collect();
            let bytes: Vec<u8> = digits.chunks(2).map(|p| p[0] << 4 | p[1]).collect();
            let xor = bytes[..5].iter().fold(0, |a, b| a ^ b);
            if xor == bytes[5] {
                let id = bytes[..5].iter().fold(0_u64, |a, &b| a << 8 | u64::from(b));
                o.valid.push((i + 13, id));
            } else {
                o.bad_checksum += 1;
            }
            i += 14;
        } else {
            o.malformed += 1;
            // The byte that did not fit: an STX opens the next frame,
            // anything else is consumed by the aborted one.
            i += 1 + hex_run + usize::from(next != STX);
        }
    }
    o
}

/// A UART over the stream whose bytes arrive over time: `available` of
/// them have arrived (the harness moves it on before each poll), ready
/// while some of those wait; each read returns a chunk of 1..=16 bytes
/// (sizes from a generator seeded by the input); on the schedule
/// `failures` sets, a ready check or a read fails, or a read returns 0
/// bytes although bytes wait. Its position and fault counts are shared
/// with the harness, which watches them while the reader owns the UART.
struct FakeUart<'a> {
    data: &'a [u8],
    pos: &'a Cell<usize>,
    available: &'a Cell<usize>,
    injected: &'a Cell<u32>,
    zero_reads: &'a Cell<u32>,
    rng: &'a Cell<u32>,
    failures: u8,
}

/// xorshift32
fn next(rng: &Cell<u32>) -> u32 {
    let mut x = rng.get();
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    rng.set(x);
    x
}

impl FakeUart<'_> {
    /// Whether this call goes wrong: never if `failures` is 0, else about
    /// one call in `failures + 1`.
    fn fault(&mut self) -> bool {
        let f = u32::from(self.failures);
        f != 0 && next(self.rng).is_multiple_of(f + 1)
    }

    fn fail(&mut self) -> Result<(), ErrorKind> {
        self.injected.set(self.injected.get() + 1);
        Err(ErrorKind::Other)
    }
}

impl ErrorType for FakeUart<'_> {
    type Error = ErrorKind;
}

impl ReadReady for FakeUart<'_> {
    fn read_ready(&mut self) -> Result<bool, ErrorKind> {
        if self.fault() {
            self.fail()?;
        }
        Ok(self.pos.get() < self.available.get())
    }
}

impl Read for FakeUart<'_> {
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, ErrorKind> {
        if self.fault() {
            // Half the faults are errors, half reads of nothing.
            if next(self.rng) & 1 == 0 {
                self.fail()?;
            }
            self.zero_reads.set(self.zero_reads.get() + 1);
            return Ok(0);
        }
        let chunk = 1 + (next(self.rng) % 16) as usize;
        let pos = self.pos.get();
        let rest = &self.data[pos..self.available.get()];
        let n = rest.len().min(buf.len()).min(chunk);
        buf[..n].copy_from_slice(&rest[..n]);
        self.pos.set(pos + n);
        Ok(n)
    }
}

fuzz_target!(|data: &[u8]| {
    let [seed, failures, stream @ ..] = data else {
        return;
    };
    let want = oracle(stream);

    // The parser, byte by byte.
    let mut parser = FrameParser::new();
    let mut tags = Vec::new();
    for (i, &b) in stream.iter().enumerate() {
        if let Some(tag) = parser.push(b) {
            tags.push((i, tag.0));
        }
    }
    assert_eq!(tags, want.valid, "tags (index of ETX, id)");
    assert!(tags.iter().all(|&(_, id)| id <= TagId::MASK));
    let c = parser.counters();
    assert_eq!(c.frames_ok as usize, want.valid.len());
    assert_eq!(c.bad_checksum, want.bad_checksum);
    assert_eq!(c.malformed, want.malformed);
    assert_eq!(c.bytes_outside_frames, want.outside);
    assert_eq!((c.read_errors, c.superseded, c.backlogged_polls), (0, 0, 0));
    assert_eq!(parser.in_frame(), want.open);

    // The reader, poll by poll, while the bytes arrive: each poll returns
    // the last valid frame whose ETX it read, and counts the earlier ones
    // as superseded.
    let (pos, available, injected, zero_reads) =
        (Cell::new(0), Cell::new(0), Cell::new(0), Cell::new(0));
    let rng = Cell::new((u32::from(*seed) * 0x0101_0101) | 1);
    let mut reader = RfidReader::new(FakeUart {
        data: stream,
        pos: &pos,
        available: &available,
        injected: &injected,
        zero_reads: &zero_reads,
        rng: &rng,
        failures: *failures,
    });
    let max = RfidReader::<FakeUart>::MAX_BYTES_PER_POLL;
    // The poll before which each byte had arrived.
    let mut arrival = vec![0_u32; stream.len()];
    let mut superseded = 0;
    let mut backlogged_polls = 0;
    // Polls in a row that ended without seeing the UART empty.
    let mut unclean_run = 0;
    let mut polls = 0_u32;
    while pos.get() < stream.len() {
        // Bytes arrive between polls: a few, or (one time in four) a burst
        // that may exceed one poll's bound.
        let burst = if next(&rng) % 4 == 0 { 1200 } else { 40 };
        let arrived = (available.get() + (next(&rng) % burst) as usize).min(stream.len());
        arrival[available.get()..arrived].fill(polls);
        available.set(arrived);
        polls += 1;
        // Each poll reads at least one byte unless bytes are still to
        // arrive or the UART faults, which it does for about one call in
        // `failures + 1`.
        assert!(
            polls as usize <= 256 * (stream.len() + 1),
            "the reader does not progress"
        );
        let before = pos.get();
        let faults_before = injected.get() + zero_reads.get();
        let backlogged_before = reader.counters().backlogged_polls;
        let got = reader.poll_read();
        let after = pos.get();
        assert!(
            after - before <= max,
            "one poll read {} > {max} bytes",
            after - before
        );
        // A backlogged poll read the whole bound and left bytes waiting.
        let backlogged = reader.counters().backlogged_polls - backlogged_before;
        assert!(backlogged <= 1);
        if backlogged == 1 {
            assert!(after - before == max && after < available.get());
            backlogged_polls += 1;
        }
        let faulted = injected.get() + zero_reads.get() > faults_before;
        let completed: Vec<(usize, u64)> = want
            .valid
            .iter()
            .filter(|(etx, _)| (before..after).contains(etx))
            .copied()
            .collect();
        if let Some(read) = got {
            // An upper bound on the polls since the frame's last byte
            // arrived, whatever the polls in between met (a backlog, an
            // error, a read of nothing)...
            let (etx, _) = completed.last().copied().expect("a tag read this poll");
            let age = polls - 1 - arrival[etx];
            assert!(read.age_ticks >= age, "{read:?} arrived {age} polls ago");
            // ...and no looser than the polls in a row that ended without
            // seeing the UART empty.
            assert!(read.age_ticks <= unclean_run, "{read:?}: {unclean_run}");
        }
        assert_eq!(
            got.map(|read| read.id.0),
            completed.last().map(|&(_, id)| id),
            "poll of bytes {before}..{after}"
        );
        superseded += completed.len().saturating_sub(1);
        unclean_run = if faulted || backlogged == 1 {
            unclean_run + 1
        } else {
            0
        };
    }
    // The same bytes through the reader: the same counts as the parser's,
    // plus the UART's failures and the superseded tags.
    let r = reader.counters();
    assert_eq!(
        r,
        RfidCounters {
            read_errors: injected.get(),
            superseded: superseded as u32,
            backlogged_polls,
            ..c
        }
    );
});
