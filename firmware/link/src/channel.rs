//! Each side's end of the link: frames numbered going out ([`Sender`]),
//! bytes collected into frames coming in, their gaps, duplicates and
//! corruption counted ([`Receiver`]).

use serde::{Deserialize, Serialize};

use crate::{Frame, LinkCounters, LinkError, MAX_FRAME_BYTES, STALE_WINDOW, decode, encode};

/// Collects received bytes into frames (split at `0x00`).
///
/// Feed bytes with [`Self::push`]; a complete frame comes back as
/// `Some(Ok(frame))` or `Some(Err(why))`. Too-long frames are discarded up
/// to the next `0x00` and reported once, as [`LinkError::TooLong`].
#[derive(Debug)]
pub struct Receiver {
    buf: [u8; MAX_FRAME_BYTES],
    len: usize,
    overflowed: bool,
    next_seq: Option<u32>,
    counters: LinkCounters,
}

impl Default for Receiver {
    fn default() -> Self {
        Self::new()
    }
}

impl Receiver {
    /// An empty receiver.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            buf: [0; MAX_FRAME_BYTES],
            len: 0,
            overflowed: false,
            next_seq: None,
            counters: LinkCounters {
                frames_ok: 0,
                corrupt_frames: 0,
                sequence_gaps: 0,
                stale_frames: 0,
                timeouts: 0,
                unexpected_messages: 0,
            },
        }
    }

    /// Takes one byte; returns a message when a frame ends. Corrupt frames
    /// and sequence gaps are counted here ([`Self::counters`]).
    pub fn push<M: for<'de> Deserialize<'de>>(&mut self, byte: u8) -> Option<Result<M, LinkError>> {
        if byte != 0 {
            match self.buf.get_mut(self.len) {
                Some(slot) => {
                    *slot = byte;
                    self.len += 1;
                }
                None => self.overflowed = true,
            }
            return None;
        }
        let len = core::mem::take(&mut self.len);
        if core::mem::take(&mut self.overflowed) {
            self.counters.corrupt_frames = self.counters.corrupt_frames.saturating_add(1);
            return Some(Err(LinkError::TooLong));
        }
        if len == 0 {
            // Back-to-back terminators: an empty frame, used to flush a line.
            return None;
        }
        let result = self
            .buf
            .get_mut(..len)
            .ok_or(LinkError::TooLong)
            .and_then(decode::<M>);
        Some(match result {
            Ok(frame) => {
                if let Some(expected) = self.next_seq {
                    let behind = expected.wrapping_sub(frame.seq);
                    if (1..=STALE_WINDOW).contains(&behind) {
                        // A duplicate or an overtaken frame: never used.
                        self.counters.stale_frames = self.counters.stale_frames.saturating_add(1);
                        return Some(Err(LinkError::Stale));
                    }
                    let gap = frame.seq.wrapping_sub(expected);
                    // Far behind: a restart of the peer; one gap.
                    let gap = if gap > u32::MAX / 2 { 1 } else { gap };
                    self.counters.sequence_gaps = self.counters.sequence_gaps.saturating_add(gap);
                }
                self.counters.frames_ok = self.counters.frames_ok.saturating_add(1);
                self.next_seq = Some(frame.seq.wrapping_add(1));
                Ok(frame.body)
            }
            Err(e) => {
                self.counters.corrupt_frames = self.counters.corrupt_frames.saturating_add(1);
                Err(e)
            }
        })
    }

    /// Counts a silent-link timeout.
    pub fn note_timeout(&mut self) {
        self.counters.timeouts = self.counters.timeouts.saturating_add(1);
    }

    /// Counts a message that made no sense in the current state.
    pub fn note_unexpected(&mut self) {
        self.counters.unexpected_messages = self.counters.unexpected_messages.saturating_add(1);
    }

    /// The counters.
    #[must_use]
    pub fn counters(&self) -> LinkCounters {
        self.counters
    }
}

/// Numbers outgoing frames.
#[derive(Debug, Default, Clone, Copy)]
pub struct Sender {
    pub(crate) seq: u32,
}

impl Sender {
    /// The sequence number the next frame will carry.
    #[must_use]
    pub fn next_seq(&self) -> u32 {
        self.seq
    }

    /// Encodes the next frame into `out`.
    ///
    /// # Errors
    /// [`LinkError::TooLong`].
    pub fn frame<'a, M: Serialize>(
        &mut self,
        body: M,
        out: &'a mut [u8; MAX_FRAME_BYTES],
    ) -> Result<&'a [u8], LinkError> {
        let bytes = encode(
            &Frame {
                seq: self.seq,
                body,
            },
            out,
        )?;
        self.seq = self.seq.wrapping_add(1);
        Ok(bytes)
    }
}
