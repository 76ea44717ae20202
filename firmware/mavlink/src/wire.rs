//! MAVLink frames on the wire: a push parser that survives garbage, and a
//! frame writer into a caller-provided byte buffer.
//!
//! The parser keeps up to one largest frame (280 bytes) and re-scans it
//! from the byte after a bad start (CRC error), so a frame that follows
//! garbage or a truncated frame is still found. Only the messages the
//! endpoint handles are checked ([`crc_extra`]): a frame of another id
//! cannot have its CRC checked (its `CRC_EXTRA` is not linked), so it is
//! skipped whole, by its declared length, and counted as unknown.

// The legacy mission messages are deprecated in the dialect but still
// sent by ground stations: accepted.
#![allow(deprecated)]

use mavlink::MessageData;
use mavlink::dialects::common as c;

/// Largest payload, bytes.
pub const MAX_PAYLOAD: usize = 255;
const V1_STX: u8 = 0xFE;
const V2_STX: u8 = 0xFD;
const V1_HEADER: usize = 6;
const V2_HEADER: usize = 10;
const SIGNATURE: usize = 13;
const IFLAG_SIGNED: u8 = 0x01;
/// Largest frame: a signed MAVLink 2 frame with a full payload.
const MAX_FRAME: usize = V2_HEADER + MAX_PAYLOAD + 2 + SIGNATURE;

/// Messages received, with their `CRC_EXTRA`: ids and extras as bytes
/// ([`pack`]: every id is below 256), 30 bytes of flash rather than 120.
const RECEIVED: [(u8, u8); 15] = pack([
    (c::HEARTBEAT_DATA::ID, c::HEARTBEAT_DATA::EXTRA_CRC),
    (c::MISSION_COUNT_DATA::ID, c::MISSION_COUNT_DATA::EXTRA_CRC),
    (
        c::MISSION_ITEM_INT_DATA::ID,
        c::MISSION_ITEM_INT_DATA::EXTRA_CRC,
    ),
    (c::MISSION_ITEM_DATA::ID, c::MISSION_ITEM_DATA::EXTRA_CRC),
    (
        c::MISSION_REQUEST_LIST_DATA::ID,
        c::MISSION_REQUEST_LIST_DATA::EXTRA_CRC,
    ),
    (
        c::MISSION_REQUEST_INT_DATA::ID,
        c::MISSION_REQUEST_INT_DATA::EXTRA_CRC,
    ),
    (
        c::MISSION_REQUEST_DATA::ID,
        c::MISSION_REQUEST_DATA::EXTRA_CRC,
    ),
    (c::MISSION_ACK_DATA::ID, c::MISSION_ACK_DATA::EXTRA_CRC),
    (
        c::MISSION_CLEAR_ALL_DATA::ID,
        c::MISSION_CLEAR_ALL_DATA::EXTRA_CRC,
    ),
    (
        c::MISSION_SET_CURRENT_DATA::ID,
        c::MISSION_SET_CURRENT_DATA::EXTRA_CRC,
    ),
    (c::COMMAND_LONG_DATA::ID, c::COMMAND_LONG_DATA::EXTRA_CRC),
    (c::COMMAND_INT_DATA::ID, c::COMMAND_INT_DATA::EXTRA_CRC),
    (
        c::PARAM_REQUEST_LIST_DATA::ID,
        c::PARAM_REQUEST_LIST_DATA::EXTRA_CRC,
    ),
    (
        c::PARAM_REQUEST_READ_DATA::ID,
        c::PARAM_REQUEST_READ_DATA::EXTRA_CRC,
    ),
    (c::PARAM_SET_DATA::ID, c::PARAM_SET_DATA::EXTRA_CRC),
]);

/// The received messages' table with each id as a byte; a message id
/// past 255 fails the build.
const fn pack<const N: usize>(full: [(u32, u8); N]) -> [(u8, u8); N] {
    let mut out = [(0, 0); N];
    let mut i = 0;
    while i < N {
        let (id, extra) = full[i];
        assert!(id <= 0xFF, "a received message id past 255: widen RECEIVED");
        out[i] = (id as u8, extra);
        i += 1;
    }
    out
}

/// `name` NUL-padded to `W` bytes, as MAVLink's fixed-width `char` fields
/// carry it (`PARAM_VALUE`'s `param_id`, `NAMED_VALUE_INT`'s `name`), for
/// tables made at build time; a name past `W` bytes fails the build.
pub(crate) const fn nul_padded<const W: usize>(name: &str) -> [u8; W] {
    let name = name.as_bytes();
    assert!(name.len() <= W, "a name past its field's width");
    let mut out = [0; W];
    let mut k = 0;
    while k < name.len() {
        out[k] = name[k];
        k += 1;
    }
    out
}

/// The `CRC_EXTRA` of a message the endpoint handles, `None` for others.
#[must_use]
pub fn crc_extra(msg_id: u32) -> Option<u8> {
    let msg_id = u8::try_from(msg_id).ok()?;
    // An opaque table: with its contents known, LLVM unrolls the search
    // into one comparison per message.
    core::hint::black_box(&RECEIVED[..])
        .iter()
        .find(|(id, _)| *id == msg_id)
        .map(|(_, extra)| *extra)
}

/// The MAVLink checksum (CRC-16/MCRF4XX, the X.25 CRC) of `data`
/// followed by the message's `extra` byte ([`crc_extra`]).
///
/// Computed a byte at a time without a table, as MAVLink's C library
/// (`crc_accumulate`) does: the library's table-driven CRC links a
/// 512-byte table for the few dozen bytes of a frame.
// Out of line: the parser's and the writer's copies of its loop cost
// flash.
#[must_use]
#[inline(never)]
pub fn crc(data: &[u8], extra: u8) -> u16 {
    let mut crc = 0xFFFF;
    for &byte in data {
        crc = crc_accumulate(crc, byte);
    }
    crc_accumulate(crc, extra)
}

/// One byte into the X.25 CRC (MAVLink's `crc_accumulate`).
fn crc_accumulate(crc: u16, byte: u8) -> u16 {
    let tmp = byte ^ (crc as u8);
    let tmp = tmp ^ (tmp << 4);
    let tmp = u16::from(tmp);
    (crc >> 8) ^ (tmp << 8) ^ (tmp << 3) ^ (tmp >> 4)
}

/// Counts of what the parser dropped.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RxCounters {
    /// Frames received whole with a good CRC.
    pub frames: u32,
    /// Bytes skipped while looking for a start byte.
    pub garbage_bytes: u32,
    /// Frame candidates whose CRC did not match.
    pub crc_errors: u32,
    /// Frames of a message id the endpoint does not handle (skipped whole).
    pub unknown_messages: u32,
    /// MAVLink 2 frames with incompatibility flags other than signing, or
    /// signed (signing is not supported: a signed frame is dropped).
    pub unsupported_frames: u32,
}

impl RxCounters {
    /// Every count 0.
    pub(crate) const ZERO: Self = Self {
        frames: 0,
        garbage_bytes: 0,
        crc_errors: 0,
        unknown_messages: 0,
        unsupported_frames: 0,
    };
}

/// A received frame, its payload zero-extended to [`MAX_PAYLOAD`] bytes
/// (MAVLink 2 drops trailing zeros on the wire).
#[derive(Debug, Clone, Copy)]
pub struct RxFrame {
    /// MAVLink 1 or 2.
    pub version: mavlink::MavlinkVersion,
    /// The message id.
    pub msg_id: u32,
    /// The sender's system id.
    pub sys_id: u8,
    /// The sender's component id.
    pub comp_id: u8,
    /// The payload, zero-extended.
    pub payload: [u8; MAX_PAYLOAD],
}

impl RxFrame {
    /// The payload byte at `offset` (0 past the end).
    #[must_use]
    pub fn byte(&self, offset: usize) -> u8 {
        self.payload.get(offset).copied().unwrap_or(0)
    }

    /// The little-endian `u16` at `offset`.
    #[must_use]
    pub fn u16_at(&self, offset: usize) -> u16 {
        u16::from_le_bytes([self.byte(offset), self.byte(offset + 1)])
    }
}

/// The push parser: bytes in, whole checked frames out.
#[derive(Debug, Clone)]
pub struct Parser {
    buf: [u8; MAX_FRAME],
    len: usize,
}

impl Default for Parser {
    fn default() -> Self {
        Self::new()
    }
}

impl Parser {
    /// An empty parser.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            buf: [0; MAX_FRAME],
            len: 0,
        }
    }

    /// Empties the parser, in place.
    pub fn reset(&mut self) {
        self.len = 0;
    }

    /// Appends a byte; call [`Parser::next_frame`] until `None` after each.
    pub fn push(&mut self, byte: u8, counters: &mut RxCounters) {
        if self.len >= MAX_FRAME {
            // Only reachable if `next_frame` was not drained: drop the
            // oldest byte so that the buffer never overflows.
            self.drop_front(1);
            counters.garbage_bytes = counters.garbage_bytes.wrapping_add(1);
        }
        if let Some(slot) = self.buf.get_mut(self.len) {
            *slot = byte;
            self.len += 1;
        }
    }

    // Out of line: inlined into `push` with `n = 1`, LLVM turns the loop
    // into a call of `memmove`, which links 1.5 KB of it into a firmware
    // that had none.
    #[inline(never)]
    fn drop_front(&mut self, n: usize) {
        let len = self.len.min(MAX_FRAME);
        let n = n.min(len);
        // A checked byte loop rather than `copy_within`, whose bounds
        // check links a panic path at opt-level `s` (at most 280 bytes).
        for i in n..len {
            let byte = self.at(i);
            if let Some(slot) = self.buf.get_mut(i - n) {
                *slot = byte;
            }
        }
        self.len = len - n;
    }

    fn at(&self, i: usize) -> u8 {
        self.buf.get(i).copied().unwrap_or(0)
    }

    /// The next whole frame with a good CRC in the buffer, if any.
    // Out of line: at opt-level 3 with fat LTO, inlined into its caller it
    // is unrolled and duplicated (docs/mavlink.md, Cost).
    #[inline(never)]
    pub fn next_frame(&mut self, counters: &mut RxCounters) -> Option<RxFrame> {
        loop {
            if self.len == 0 {
                return None;
            }
            let stx = self.at(0);
            if stx != V1_STX && stx != V2_STX {
                let skip = self
                    .buf
                    .get(1..self.len)
                    .and_then(|rest| rest.iter().position(|&b| b == V1_STX || b == V2_STX))
                    .map_or(self.len, |p| p + 1);
                counters.garbage_bytes = counters.garbage_bytes.wrapping_add(skip as u32);
                self.drop_front(skip);
                continue;
            }
            let v2 = stx == V2_STX;
            let header = if v2 { V2_HEADER } else { V1_HEADER };
            if self.len < header {
                return None;
            }
            let payload_len = usize::from(self.at(1));
            let flags = if v2 { self.at(2) } else { 0 };
            let signed = flags & IFLAG_SIGNED != 0;
            let frame_len = header + payload_len + 2 + if signed { SIGNATURE } else { 0 };
            if self.len < frame_len {
                return None;
            }
            let (msg_id, sys_id, comp_id) = if v2 {
                let id = u32::from_le_bytes([self.at(7), self.at(8), self.at(9), 0]);
                (id, self.at(5), self.at(6))
            } else {
                (u32::from(self.at(5)), self.at(3), self.at(4))
            };
            let Some(extra) = crc_extra(msg_id) else {
                counters.unknown_messages = counters.unknown_messages.wrapping_add(1);
                self.drop_front(frame_len);
                continue;
            };
            let body_end = header + payload_len;
            let body = self.buf.get(1..body_end).unwrap_or(&[]);
            let crc = crc(body, extra);
            let got = u16::from_le_bytes([self.at(body_end), self.at(body_end + 1)]);
            if crc != got {
                counters.crc_errors = counters.crc_errors.wrapping_add(1);
                self.drop_front(1);
                continue;
            }
            if flags & !IFLAG_SIGNED != 0 || signed {
                counters.unsupported_frames = counters.unsupported_frames.wrapping_add(1);
                self.drop_front(frame_len);
                continue;
            }
            let mut payload = [0u8; MAX_PAYLOAD];
            if let (Some(dst), Some(src)) = (
                payload.get_mut(..payload_len),
                self.buf.get(header..body_end),
            ) {
                dst.copy_from_slice(src);
            }
            self.drop_front(frame_len);
            counters.frames = counters.frames.wrapping_add(1);
            return Some(RxFrame {
                version: if v2 {
                    mavlink::MavlinkVersion::V2
                } else {
                    mavlink::MavlinkVersion::V1
                },
                msg_id,
                sys_id,
                comp_id,
                payload,
            });
        }
    }
}

/// Outgoing bytes: whole MAVLink 2 frames appended to a caller's buffer.
/// A frame that does not fit is dropped whole and counted.
#[derive(Debug)]
pub struct TxBuffer<'a> {
    buf: &'a mut [u8],
    len: usize,
    dropped: u32,
}

impl<'a> TxBuffer<'a> {
    /// Frames will be written into `buf` from its start.
    pub fn new(buf: &'a mut [u8]) -> Self {
        Self {
            buf,
            len: 0,
            dropped: 0,
        }
    }

    /// The bytes written so far.
    #[must_use]
    pub fn as_slice(&self) -> &[u8] {
        self.buf.get(..self.len).unwrap_or(&[])
    }

    /// How many bytes were written.
    #[must_use]
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether nothing was written.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Frames dropped for want of room.
    #[must_use]
    pub fn dropped(&self) -> u32 {
        self.dropped
    }

    /// Empties the buffer (after its bytes were sent).
    pub fn clear(&mut self) {
        self.len = 0;
    }

    /// Appends one MAVLink 2 frame (`header`: sequence, system id,
    /// component id) of message `msg_id`, its CRC seeded with the
    /// message's `extra` byte ([`crc_extra`]); `false` (and counted) if it
    /// does not fit. Public so that a test's ground station frames its
    /// messages with the endpoint's own encoder.
    // Out of line: called from many places; inlined at each (opt-level 3,
    // fat LTO) it cost flash (docs/mavlink.md, Cost).
    #[inline(never)]
    pub fn frame(&mut self, header: [u8; 3], msg_id: u32, extra: u8, payload: &[u8]) -> bool {
        // A MAVLink 2 payload keeps at least one byte after the trailing
        // zeros are cut.
        let n = payload.len().clamp(1, MAX_PAYLOAD);
        let total = V2_HEADER + n + 2;
        let Some(out) = self.buf.get_mut(self.len..self.len + total) else {
            self.dropped = self.dropped.wrapping_add(1);
            return false;
        };
        // Written in place: header, payload (a payload cut to nothing is
        // one zero byte), CRC.
        let id = msg_id.to_le_bytes();
        let head = [
            V2_STX, n as u8, 0, 0, header[0], header[1], header[2], id[0], id[1], id[2],
        ];
        if let Some(h) = out.get_mut(..V2_HEADER) {
            h.copy_from_slice(&head);
        }
        let copy = payload.len().min(n);
        if let (Some(d), Some(s)) = (
            out.get_mut(V2_HEADER..V2_HEADER + copy),
            payload.get(..copy),
        ) {
            d.copy_from_slice(s);
        }
        if let Some(z) = out.get_mut(V2_HEADER + copy..V2_HEADER + n) {
            z.fill(0);
        }
        let crc = crc(out.get(1..V2_HEADER + n).unwrap_or(&[]), extra);
        if let Some(c) = out.get_mut(V2_HEADER + n..total) {
            c.copy_from_slice(&crc.to_le_bytes());
        }
        self.len += total;
        true
    }
}

#[cfg(test)]
mod tests {
    use super::{RECEIVED, crc};

    /// The table-free CRC is the library's (`mavlink::calculate_crc`) on
    /// every length up to a full frame and every received message's
    /// extra byte.
    #[test]
    fn the_crc_is_the_librarys() {
        let mut data = [0u8; 300];
        for (i, b) in (0_u32..).zip(data.iter_mut()) {
            *b = (i.wrapping_mul(2_654_435_761) >> 13) as u8;
        }
        for len in 0..data.len() {
            for &(_, extra) in &RECEIVED {
                assert_eq!(
                    crc(&data[..len], extra),
                    mavlink::calculate_crc(&data[..len], extra),
                    "{len} bytes, extra {extra}"
                );
            }
        }
        assert_eq!(
            crc(b"123456789", 0),
            mavlink::calculate_crc(b"123456789", 0)
        );
    }
}
