//! The MAVLink channel beside the devices (the crate docs, "MAVLink"):
//! the bytes a ground station sent, to the firmware, and the bytes its
//! endpoint answered, to the host, in bounded chunks; and the firmware's
//! queues between those chunks and its endpoint's tick.

use serde::de::{self, SeqAccess, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::MAVLINK_CHUNK_BYTES;

/// Up to [`MAVLINK_CHUNK_BYTES`] bytes of a MAVLink byte stream (frames
/// need not start or end in a chunk). `Copy`, encoded as postcard bytes
/// (a length, then the bytes); a longer chunk is refused by the decoder.
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct MavlinkChunk {
    len: u8,
    bytes: [u8; MAVLINK_CHUNK_BYTES],
}

impl Default for MavlinkChunk {
    fn default() -> Self {
        Self::new()
    }
}

impl core::fmt::Debug for MavlinkChunk {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_list().entries(self.as_slice()).finish()
    }
}

#[cfg(feature = "defmt")]
impl defmt::Format for MavlinkChunk {
    fn format(&self, f: defmt::Formatter<'_>) {
        defmt::write!(f, "{=[u8]}", self.as_slice());
    }
}

impl MavlinkChunk {
    /// No bytes.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            len: 0,
            bytes: [0; MAVLINK_CHUNK_BYTES],
        }
    }

    /// The first bytes of `bytes` that fit (at most
    /// [`MAVLINK_CHUNK_BYTES`]); the rest go in the next chunk.
    #[must_use]
    pub fn from_slice(bytes: &[u8]) -> Self {
        let mut chunk = Self::new();
        // Element by element: no length check that could panic.
        let n = copy_into(&mut chunk.bytes, bytes);
        // At most `MAVLINK_CHUNK_BYTES`, which fits a `u8`.
        chunk.len = u8::try_from(n).unwrap_or(u8::MAX);
        chunk
    }

    /// The bytes.
    #[must_use]
    pub fn as_slice(&self) -> &[u8] {
        self.bytes.get(..usize::from(self.len)).unwrap_or(&[])
    }

    /// How many bytes.
    #[must_use]
    pub fn len(&self) -> usize {
        usize::from(self.len)
    }

    /// No bytes.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

impl Serialize for MavlinkChunk {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_bytes(self.as_slice())
    }
}

impl<'de> Deserialize<'de> for MavlinkChunk {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        deserializer.deserialize_bytes(ChunkVisitor)
    }
}

struct ChunkVisitor;

impl<'de> Visitor<'de> for ChunkVisitor {
    type Value = MavlinkChunk;

    fn expecting(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("at most MAVLINK_CHUNK_BYTES bytes")
    }

    fn visit_bytes<E: de::Error>(self, v: &[u8]) -> Result<Self::Value, E> {
        if v.len() > MAVLINK_CHUNK_BYTES {
            return Err(E::invalid_length(v.len(), &self));
        }
        Ok(MavlinkChunk::from_slice(v))
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Self::Value, A::Error> {
        let mut chunk = MavlinkChunk::new();
        while let Some(b) = seq.next_element::<u8>()? {
            let n = chunk.len();
            let Some(slot) = chunk.bytes.get_mut(n) else {
                return Err(de::Error::invalid_length(n.saturating_add(1), &self));
            };
            *slot = b;
            chunk.len = chunk.len.saturating_add(1);
        }
        Ok(chunk)
    }
}

/// Copies what fits of `from` to the start of `to`; returns how many
/// bytes.
fn copy_into(to: &mut [u8], from: &[u8]) -> usize {
    let mut n = 0;
    for (d, s) in to.iter_mut().zip(from) {
        *d = *s;
        n += 1;
    }
    n
}

/// The host's MAVLink message: bytes from the ground station, and a
/// request for the firmware's next chunk.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MavlinkIn {
    /// Counts the host's MAVLink messages from 0 (wrapping): one sent
    /// again (its answer lost) has the same number and is answered again
    /// from the firmware's cache, its bytes not queued twice.
    pub seq: u32,
    /// Bytes from the ground station, for the endpoint's next tick.
    pub bytes: MavlinkChunk,
}

/// The firmware's answer to a [`MavlinkIn`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MavlinkOut {
    /// The [`MavlinkIn::seq`] this answers.
    pub seq: u32,
    /// The endpoint's next output bytes, in order.
    pub bytes: MavlinkChunk,
    /// Output bytes still queued after these (the host asks again, with
    /// no bytes, until 0).
    pub pending: u16,
    /// The channel's counters now.
    pub counters: MavlinkCounters,
}

/// What the firmware's side of the channel could not carry.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MavlinkCounters {
    /// Bytes from the host that found no room in the receive queue (it
    /// holds [`MAVLINK_RX_QUEUE_BYTES`] between two ticks), or that came
    /// in a run without an endpoint (no route): dropped.
    pub rx_dropped_bytes: u32,
    /// Frames the endpoint wrote that found no room in the send queue
    /// ([`MAVLINK_TX_QUEUE_BYTES`]; the host drains it after each tick):
    /// dropped whole.
    pub tx_dropped_frames: u32,
    /// Messages answered again from the cache (sent again by the host).
    pub repeated: u32,
}

/// Bytes the firmware holds from the host between two ticks.
pub const MAVLINK_RX_QUEUE_BYTES: usize = 4 * MAVLINK_CHUNK_BYTES;

/// Bytes of endpoint output the firmware holds until the host takes them.
pub const MAVLINK_TX_QUEUE_BYTES: usize = 1024;

/// The firmware's side of the channel: what the host sent since the
/// last tick, what the endpoint wrote and the host has not taken, and
/// the last answer (for a message sent again).
#[derive(Debug, Clone)]
pub struct MavlinkQueues {
    rx: [u8; MAVLINK_RX_QUEUE_BYTES],
    rx_len: usize,
    tx: [u8; MAVLINK_TX_QUEUE_BYTES],
    tx_start: usize,
    tx_end: usize,
    last: Option<MavlinkOut>,
    counters: MavlinkCounters,
}

impl Default for MavlinkQueues {
    fn default() -> Self {
        Self::new()
    }
}

impl MavlinkQueues {
    /// Empty.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            rx: [0; MAVLINK_RX_QUEUE_BYTES],
            rx_len: 0,
            tx: [0; MAVLINK_TX_QUEUE_BYTES],
            tx_start: 0,
            tx_end: 0,
            last: None,
            counters: MavlinkCounters {
                rx_dropped_bytes: 0,
                tx_dropped_frames: 0,
                repeated: 0,
            },
        }
    }

    /// Empties both queues and the cache, and zeroes the counters (a new
    /// run).
    pub fn reset(&mut self) {
        self.rx_len = 0;
        self.tx_start = 0;
        self.tx_end = 0;
        self.last = None;
        self.counters = MavlinkCounters::default();
    }

    /// The counters.
    #[must_use]
    pub fn counters(&self) -> MavlinkCounters {
        self.counters
    }

    /// Handles the host's message: queues its bytes if `accept` (else
    /// counts them dropped, as those past the queue's room) and answers
    /// with the next chunk of output. A message with the last one's
    /// `seq` is answered again, nothing queued.
    pub fn exchange(&mut self, message: &MavlinkIn, accept: bool) -> MavlinkOut {
        if let Some(last) = self.last
            && last.seq == message.seq
        {
            self.counters.repeated = self.counters.repeated.wrapping_add(1);
            return MavlinkOut {
                counters: self.counters,
                ..last
            };
        }
        let bytes = message.bytes.as_slice();
        let taken = if accept { self.push_rx(bytes) } else { 0 };
        let lost = u32::try_from(bytes.len().saturating_sub(taken)).unwrap_or(u32::MAX);
        self.counters.rx_dropped_bytes = self.counters.rx_dropped_bytes.wrapping_add(lost);
        let chunk =
            MavlinkChunk::from_slice(self.tx.get(self.tx_start..self.tx_end).unwrap_or(&[]));
        self.tx_start = self.tx_start.saturating_add(chunk.len()).min(self.tx_end);
        let answer = MavlinkOut {
            seq: message.seq,
            bytes: chunk,
            pending: u16::try_from(self.tx_end.saturating_sub(self.tx_start)).unwrap_or(u16::MAX),
            counters: self.counters,
        };
        self.last = Some(answer);
        answer
    }

    fn push_rx(&mut self, bytes: &[u8]) -> usize {
        let n = match self.rx.get_mut(self.rx_len..) {
            Some(room) => copy_into(room, bytes),
            None => 0,
        };
        self.rx_len = self.rx_len.saturating_add(n);
        n
    }

    /// Lends the bytes received since the last tick and the send queue's
    /// free room to `f` (the endpoint's tick), which returns how many
    /// bytes it wrote at the room's start and how many frames it dropped;
    /// then empties the receive queue. The queued output is moved to the
    /// start first, so the room is all that is free.
    pub fn tick<F>(&mut self, f: F)
    where
        F: FnOnce(&[u8], &mut [u8]) -> (usize, u32),
    {
        if self.tx_start > 0 {
            // Element by element, front to back (the source is behind the
            // destination): no range check that could panic.
            for (to, from) in (self.tx_start..self.tx_end).enumerate() {
                if let Some(b) = self.tx.get(from).copied()
                    && let Some(d) = self.tx.get_mut(to)
                {
                    *d = b;
                }
            }
            self.tx_end = self.tx_end.saturating_sub(self.tx_start);
            self.tx_start = 0;
        }
        let (rx, tx) = (&self.rx, &mut self.tx);
        let (written, dropped) = match (rx.get(..self.rx_len), tx.get_mut(self.tx_end..)) {
            (Some(rx), Some(room)) => {
                let room_len = room.len();
                let (written, dropped) = f(rx, room);
                (written.min(room_len), dropped)
            }
            _ => (0, 0),
        };
        self.tx_end = self.tx_end.saturating_add(written);
        self.counters.tx_dropped_frames = self.counters.tx_dropped_frames.wrapping_add(dropped);
        self.rx_len = 0;
    }

    /// Output bytes queued for the host.
    #[must_use]
    pub fn pending(&self) -> usize {
        self.tx_end.saturating_sub(self.tx_start)
    }
}
