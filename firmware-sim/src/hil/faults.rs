//! Seeded faults on the lock-step link, both ways, and what each receiver
//! should count because of them (the faulty-link soak).
//!
//! Each frame, in each direction, meets at most one fault, drawn from the
//! run's seed: dropped, sent twice, delayed (held back and sent after the
//! next frame of that direction), or corrupted. Corruption flips bytes of
//! the frame's content, each with [`LinkFaultSpec::corrupt_byte_probability`],
//! to another non-zero value: a corrupted byte never becomes or replaces
//! the `0x00` delimiter, so one corrupted frame is exactly one corrupt frame
//! at the receiver (what delimiter loss does, resynchronisation at the next
//! `0x00`, is covered by the link's unit tests and fuzz targets). On top, an
//! outage keeps the host silent for longer than the firmware's
//! [`LINK_TIMEOUT_MS`](wmr_link::LINK_TIMEOUT_MS) before a tick.
//!
//! [`ExpectedCounters`] replays each direction's frames in the order they
//! arrive, from what was injected (a frame's sequence number and whether
//! it arrived intact), and derives what the receiver must count: frames
//! accepted, corrupt, stale and missing. A receiver's counters equal it
//! only if it rejected every corrupted frame (no bad CRC accepted) and
//! used no stale frame.

use rand::rngs::ChaCha8Rng;
use rand::{RngExt as _, SeedableRng as _};

pub use crate::report::link_faults::{
    ExpectedCounters, InjectedFaults, LinkFaultReport, LinkFaultSpec, OUTAGE_MS,
};

/// A frame on its way: bytes (with the `0x00`), sequence number, and what
/// it carries (for counting lost reports).
#[derive(Debug, Clone)]
pub struct Frame {
    /// The encoded frame.
    pub bytes: Vec<u8>,
    /// Its sequence number.
    pub seq: u32,
    /// Whether it carries a `LinkSilent` report.
    pub silence_report: bool,
}

/// One direction's fault injector.
#[derive(Debug)]
pub struct Injector {
    spec: LinkFaultSpec,
    rng: ChaCha8Rng,
    held: Option<Frame>,
    /// What was injected.
    pub injected: InjectedFaults,
    /// What the receiver must count.
    pub expected: ExpectedCounters,
    /// `LinkSilent` reports lost: dropped, corrupted, or delayed behind a
    /// newer frame (stale).
    pub silence_reports_lost: u32,
}

impl Injector {
    /// The injector of direction `stream` (0 host → firmware, 1 back).
    #[must_use]
    pub fn new(spec: LinkFaultSpec, stream: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(spec.seed);
        rng.set_stream(stream);
        Self {
            spec,
            rng,
            held: None,
            injected: InjectedFaults::default(),
            expected: ExpectedCounters::default(),
            silence_reports_lost: 0,
        }
    }

    /// The bytes that go on the wire for `frame` (none, it, it twice, or it
    /// followed by the frame held back before it).
    pub fn pass(&mut self, frame: Frame) -> Vec<u8> {
        self.injected.frames += 1;
        let s = self.spec;
        let u: f64 = self.rng.random();
        let mut wire = Vec::new();
        if u < s.drop_probability {
            self.injected.dropped += 1;
            self.count_lost(&frame, false);
        } else if u < s.drop_probability + s.duplicate_probability {
            self.injected.duplicated += 1;
            // A report arrives if either copy is accepted (the second is
            // then stale).
            let first = self.expected.arrive(frame.seq, true);
            let second = self.expected.arrive(frame.seq, true);
            self.count_lost(&frame, first || second);
            wire.extend_from_slice(&frame.bytes);
            wire.extend_from_slice(&frame.bytes);
        } else if u < s.drop_probability + s.duplicate_probability + s.delay_probability
            && self.held.is_none()
        {
            self.injected.delayed += 1;
            self.held = Some(frame);
            return wire;
        } else {
            let mut bytes = frame.bytes.clone();
            let content = bytes.len().saturating_sub(1);
            let mut hit = 0;
            for b in bytes.iter_mut().take(content) {
                if self.rng.random::<f64>() < s.corrupt_byte_probability {
                    // Any other non-zero value.
                    let mut v: u8 = self.rng.random_range(1..=254);
                    if v >= *b {
                        v += 1;
                    }
                    *b = v;
                    hit += 1;
                }
            }
            if hit > 0 {
                self.injected.corrupted += 1;
                self.injected.bytes_corrupted += hit;
            }
            self.arrive(&frame, hit == 0);
            wire.extend_from_slice(&bytes);
        }
        if let Some(late) = self.held.take() {
            self.arrive(&late, true);
            wire.extend_from_slice(&late.bytes);
        }
        wire
    }

    /// `frame` through the faults if `inject`, else as it is (but counted
    /// as arriving, for [`ExpectedCounters`]).
    pub fn deliver(&mut self, frame: Frame, inject: bool) -> Vec<u8> {
        if inject {
            return self.pass(frame);
        }
        self.arrive(&frame, true);
        frame.bytes
    }

    /// `frame` reaches its receiver once, intact or not: counted for the
    /// replay, and as a lost report if it carries a silence report the
    /// receiver will not accept.
    fn arrive(&mut self, frame: &Frame, intact: bool) {
        let accepted = self.expected.arrive(frame.seq, intact);
        self.count_lost(frame, accepted);
    }

    /// A silence report in `frame` is lost unless it was `accepted`.
    fn count_lost(&mut self, frame: &Frame, accepted: bool) {
        if frame.silence_report && !accepted {
            self.silence_reports_lost += 1;
        }
    }

    /// The frame held back, if any, now (counted as arriving).
    pub fn release_held(&mut self) -> Vec<u8> {
        match self.held.take() {
            Some(late) => {
                self.arrive(&late, true);
                late.bytes
            }
            None => Vec::new(),
        }
    }

    /// Whether the host stays silent before the next tick.
    pub fn outage(&mut self) -> bool {
        self.rng.random::<f64>() < self.spec.outage_probability
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use wmr_link::{HostMessage, MAX_FRAME_BYTES, Receiver, Sender};

    /// The receiver's counters equal the replay's on a long stream with
    /// every fault at a high rate.
    #[test]
    fn the_receiver_counts_what_was_injected() {
        let spec = LinkFaultSpec {
            seed: 7,
            corrupt_byte_probability: 0.02,
            drop_probability: 0.05,
            duplicate_probability: 0.05,
            delay_probability: 0.05,
            outage_probability: 0.0,
        };
        let mut injector = Injector::new(spec, 0);
        let (mut tx, mut rx) = (Sender::default(), Receiver::new());
        let mut out = [0_u8; MAX_FRAME_BYTES];
        for seq in 0..20_000_u32 {
            let bytes = tx.frame(HostMessage::Finish, &mut out).unwrap().to_vec();
            let wire = injector.pass(Frame {
                bytes,
                seq,
                silence_report: false,
            });
            for b in wire {
                let _ = rx.push::<HostMessage>(b);
            }
        }
        let i = injector.injected;
        assert!(i.dropped > 800 && i.duplicated > 800 && i.delayed > 800 && i.corrupted > 800);
        assert!(
            injector.expected.agrees_with(&rx.counters()),
            "{:?} vs {:?}",
            injector.expected,
            rx.counters()
        );
    }

    /// A duplicated silence report arrives once and is not also counted
    /// as lost (the hour-long soak counted one report more than timeouts
    /// before); a dropped one is lost.
    #[test]
    fn a_duplicated_report_is_received_not_lost() {
        let report = |seq| Frame {
            bytes: vec![1, 0],
            seq,
            silence_report: true,
        };
        let twice = LinkFaultSpec {
            duplicate_probability: 1.0,
            corrupt_byte_probability: 0.0,
            drop_probability: 0.0,
            delay_probability: 0.0,
            ..LinkFaultSpec::soak(3)
        };
        let mut injector = Injector::new(twice, 1);
        assert_eq!(injector.pass(report(0)), vec![1, 0, 1, 0]);
        assert_eq!(injector.silence_reports_lost, 0);
        assert_eq!(injector.expected.frames_ok, 1);
        assert_eq!(injector.expected.stale_frames, 1);
        let mut dropping = Injector::new(
            LinkFaultSpec {
                drop_probability: 1.0,
                duplicate_probability: 0.0,
                ..twice
            },
            1,
        );
        assert!(dropping.pass(report(0)).is_empty());
        assert_eq!(dropping.silence_reports_lost, 1);
    }

    #[test]
    fn rates_are_validated() {
        assert!(LinkFaultSpec::soak(1).validate().is_ok());
        let bad = LinkFaultSpec {
            drop_probability: 1.5,
            ..LinkFaultSpec::soak(1)
        };
        assert!(
            bad.validate()
                .unwrap_err()
                .to_string()
                .contains("drop_probability")
        );
    }
}
