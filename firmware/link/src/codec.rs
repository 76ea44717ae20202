//! One frame on the wire: postcard, CRC-32 and COBS (the crate docs,
//! "Framing"), encoded and decoded.

use serde::{Deserialize, Serialize};

use crate::MAX_FRAME_BYTES;

/// Largest postcard payload plus CRC before COBS (COBS adds 1 byte per 254).
const MAX_RAW_BYTES: usize = MAX_FRAME_BYTES - MAX_FRAME_BYTES / 254 - 2;

/// A message with its sequence number.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Frame<M> {
    /// Sender's frame count, from 0, wrapping.
    pub seq: u32,
    /// The message.
    pub body: M,
}

/// Why a frame could not be encoded or decoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LinkError {
    /// The message does not fit in [`MAX_FRAME_BYTES`] (encoding), or the
    /// received frame was longer (decoding).
    TooLong,
    /// Not valid COBS.
    Cobs,
    /// Shorter than a CRC.
    TooShort,
    /// CRC mismatch.
    Crc,
    /// postcard could not decode the payload as the expected message.
    Decode,
    /// An intact frame behind the next expected sequence number (a
    /// duplicate, or overtaken by a newer frame): dropped, not corrupt.
    Stale,
}

impl core::fmt::Display for LinkError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::TooLong => "frame longer than MAX_FRAME_BYTES",
            Self::Cobs => "frame is not valid COBS",
            Self::TooShort => "frame shorter than its CRC",
            Self::Crc => "frame CRC mismatch",
            Self::Decode => "frame payload does not decode as the expected message",
            Self::Stale => "stale frame: behind the next expected sequence number",
        })
    }
}

impl core::error::Error for LinkError {}

/// CRC-32 (ISO HDLC), computed bit by bit: the byte-wise table would cost
/// 1 KiB of the QEMU board's flash, which it needs for the fusion
/// estimator; a frame of about 100 bytes then takes a few thousand
/// instructions more, against the lock-step exchange's milliseconds.
pub(crate) const CRC: crc::Crc<u32, crc::NoTable> =
    crc::Crc::<u32, crc::NoTable>::new(&crc::CRC_32_ISO_HDLC);

/// Encodes `frame` into `out`; returns the frame's bytes (ending in `0x00`).
///
/// # Errors
/// [`LinkError::TooLong`] if the frame does not fit.
pub fn encode<'a, M: Serialize>(
    frame: &Frame<M>,
    out: &'a mut [u8; MAX_FRAME_BYTES],
) -> Result<&'a [u8], LinkError> {
    let mut raw = [0_u8; MAX_RAW_BYTES];
    let payload_len = postcard::to_slice(frame, &mut raw)
        .map_err(|_| LinkError::TooLong)?
        .len();
    let crc = CRC.checksum(raw.get(..payload_len).ok_or(LinkError::TooLong)?);
    raw.get_mut(payload_len..payload_len + 4)
        .ok_or(LinkError::TooLong)?
        .copy_from_slice(&crc.to_le_bytes());
    let raw = raw.get(..payload_len + 4).ok_or(LinkError::TooLong)?;
    // Leave the last byte for the terminator.
    let (body, _) = out.split_at_mut(MAX_FRAME_BYTES - 1);
    let n = cobs::try_encode(raw, body).map_err(|_| LinkError::TooLong)?;
    let terminator = out.get_mut(n).ok_or(LinkError::TooLong)?;
    *terminator = 0;
    out.get(..=n).ok_or(LinkError::TooLong)
}

/// Decodes one frame's COBS bytes (without the `0x00`), in place.
///
/// # Errors
/// Which check failed.
pub fn decode<'de, M: Deserialize<'de>>(cobs_bytes: &'de mut [u8]) -> Result<Frame<M>, LinkError> {
    let n = cobs_decode_in_place(cobs_bytes)?;
    let raw = cobs_bytes.get(..n).ok_or(LinkError::Cobs)?;
    let payload_len = n.checked_sub(4).ok_or(LinkError::TooShort)?;
    let (payload, crc_bytes) = raw
        .split_at_checked(payload_len)
        .ok_or(LinkError::TooShort)?;
    let crc: [u8; 4] = crc_bytes.try_into().map_err(|_| LinkError::TooShort)?;
    if CRC.checksum(payload) != u32::from_le_bytes(crc) {
        return Err(LinkError::Crc);
    }
    postcard::from_bytes(payload).map_err(|_| LinkError::Decode)
}

/// COBS-decodes `buf` in place up to its first `0x00` (or its end) and
/// returns the decoded length: the decoding of `cobs::decode_in_place`
/// (0.5), the same result and the same frames refused, with every access
/// checked. The crate's own decoder indexes its buffer (`buf[i]`), two
/// bounds checks that LTO cannot remove and so two panic paths in the
/// firmware's control loop; this one has none (`cargo xtask panic-free`).
///
/// # Errors
/// [`LinkError::Cobs`]: empty, or a code byte pointing past the end.
pub(crate) fn cobs_decode_in_place(buf: &mut [u8]) -> Result<usize, LinkError> {
    if buf.is_empty() {
        return Err(LinkError::Cobs);
    }
    let end = buf.iter().position(|&b| b == 0).unwrap_or(buf.len());
    let mut read = 0;
    let mut write = 0;
    while read < end {
        // Non-zero: `end` is the first zero.
        let code = usize::from(*buf.get(read).ok_or(LinkError::Cobs)?);
        // The next code byte, or the end, must come no later than `end`
        // (a code of 1 is a lone zero, always in range).
        if read + code > end && code != 1 {
            return Err(LinkError::Cobs);
        }
        read += 1;
        for _ in 1..code {
            let byte = *buf.get(read).ok_or(LinkError::Cobs)?;
            // `write < read` throughout: the output trails the input.
            *buf.get_mut(write).ok_or(LinkError::Cobs)? = byte;
            read += 1;
            write += 1;
        }
        // A block shorter than 254 data bytes stood for a zero, unless it
        // was the last.
        if code != 0xFF && read < end {
            *buf.get_mut(write).ok_or(LinkError::Cobs)? = 0;
            write += 1;
        }
    }
    Ok(write)
}
