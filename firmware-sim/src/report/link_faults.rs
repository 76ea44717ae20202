//! The faults of a faulty-link HIL run as data: their rates
//! ([`LinkFaultSpec`]), what was injected each way ([`InjectedFaults`]),
//! what each receiver must count because of them ([`ExpectedCounters`],
//! replayed from the frames as they arrived) and the run's figures
//! ([`LinkFaultReport`]). The injector that draws the faults is
//! `crate::hil`'s.

use serde::Serialize;
use wmr_link::{LINK_TIMEOUT_MS, LinkCounters, STALE_WINDOW};

/// Fault rates of a faulty-link run (`firmware-sim hil --link-faults SEED`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LinkFaultSpec {
    /// Seed of the fault draws (ChaCha8; stream 0 host → firmware, 1 back).
    pub seed: u64,
    /// Probability that a content byte of a frame is corrupted.
    pub corrupt_byte_probability: f64,
    /// Probability that a frame is dropped.
    pub drop_probability: f64,
    /// Probability that a frame is sent twice.
    pub duplicate_probability: f64,
    /// Probability that a frame is held back and sent after the next one.
    pub delay_probability: f64,
    /// Probability, per tick, that the host is silent for
    /// [`OUTAGE_MS`] before sending it.
    pub outage_probability: f64,
}

/// How long an outage keeps the host silent, ms: twice the firmware's
/// timeout, so that the firmware must notice a silence not much longer
/// than its timeout.
pub const OUTAGE_MS: u64 = 2 * LINK_TIMEOUT_MS as u64;

impl LinkFaultSpec {
    /// The soak's rates: 1 % of bytes corrupted, and 0.5 % of frames each
    /// dropped, duplicated and delayed by a frame, both ways; an outage
    /// before 0.1 % of ticks.
    #[must_use]
    pub const fn soak(seed: u64) -> Self {
        Self {
            seed,
            corrupt_byte_probability: 0.01,
            drop_probability: 0.005,
            duplicate_probability: 0.005,
            delay_probability: 0.005,
            outage_probability: 0.001,
        }
    }

    /// Every probability in [0, 1], and the per-frame faults summing to at
    /// most 1.
    ///
    /// # Errors
    /// Which field is out of range.
    pub fn validate(&self) -> anyhow::Result<()> {
        for (name, p) in [
            ("corrupt_byte_probability", self.corrupt_byte_probability),
            ("drop_probability", self.drop_probability),
            ("duplicate_probability", self.duplicate_probability),
            ("delay_probability", self.delay_probability),
            ("outage_probability", self.outage_probability),
        ] {
            anyhow::ensure!(
                (0.0..=1.0).contains(&p),
                "link faults: {name} = {p} is not a probability"
            );
        }
        anyhow::ensure!(
            self.drop_probability + self.duplicate_probability + self.delay_probability <= 1.0,
            "link faults: drop, duplicate and delay probabilities sum above 1"
        );
        Ok(())
    }
}

/// What was done to one direction's frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub struct InjectedFaults {
    /// Frames offered to the link.
    pub frames: u32,
    /// Frames dropped.
    pub dropped: u32,
    /// Frames sent twice.
    pub duplicated: u32,
    /// Frames held back and sent after the next one.
    pub delayed: u32,
    /// Frames with at least one corrupted byte.
    pub corrupted: u32,
    /// Bytes corrupted.
    pub bytes_corrupted: u32,
}

/// What one direction's receiver must count, replayed from the frames as
/// they arrived.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub struct ExpectedCounters {
    /// Frames accepted.
    pub frames_ok: u32,
    /// Frames rejected as corrupt.
    pub corrupt_frames: u32,
    /// Frames missing between accepted ones.
    pub sequence_gaps: u32,
    /// Intact frames behind the next expected one, dropped.
    pub stale_frames: u32,
    #[serde(skip)]
    next_seq: Option<u32>,
}

impl ExpectedCounters {
    /// A frame with sequence number `seq` arrives, intact or not; whether
    /// the receiver must accept it.
    pub fn arrive(&mut self, seq: u32, intact: bool) -> bool {
        if !intact {
            self.corrupt_frames += 1;
            return false;
        }
        if let Some(next) = self.next_seq {
            if (1..=STALE_WINDOW).contains(&next.wrapping_sub(seq)) {
                self.stale_frames += 1;
                return false;
            }
            self.sequence_gaps += seq.wrapping_sub(next);
        }
        self.frames_ok += 1;
        self.next_seq = Some(seq.wrapping_add(1));
        true
    }

    /// Whether `seen` (a receiver's counters) agrees.
    #[must_use]
    pub fn agrees_with(&self, seen: &LinkCounters) -> bool {
        (
            seen.frames_ok,
            seen.corrupt_frames,
            seen.sequence_gaps,
            seen.stale_frames,
        ) == (
            self.frames_ok,
            self.corrupt_frames,
            self.sequence_gaps,
            self.stale_frames,
        )
    }
}

/// The faulty-link figures of a run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LinkFaultReport {
    /// The rates and seed.
    pub spec: LinkFaultSpec,
    /// Injected on the way to the firmware.
    pub to_firmware: InjectedFaults,
    /// Injected on the way back.
    pub to_host: InjectedFaults,
    /// What the firmware's receiver must have counted.
    pub firmware_expected: ExpectedCounters,
    /// What the host's receiver must have counted.
    pub host_expected: ExpectedCounters,
    /// Outages the host made.
    pub outages: u32,
    /// Ticks the host sent again (no answer, a `Nack`, or a corrupt one).
    pub resent_ticks: u32,
    /// `Nack`s received.
    pub nacks: u32,
    /// `LinkSilent` reports received, each with both motors at duty 0.
    pub silence_reports: u32,
    /// `LinkSilent` reports lost on the way back (dropped, corrupted, or
    /// delayed behind a newer frame).
    pub silence_reports_lost: u32,
    /// The longest silence after which a received `LinkSilent` report says
    /// the firmware stopped the motors, ms (at least the firmware's
    /// `LINK_TIMEOUT_MS`; more when QEMU was not scheduled when the
    /// timeout passed).
    pub longest_silence_before_stop_ms: u32,
    /// Answers to an earlier tick, or refusals of a stale tick, received
    /// (and not used).
    pub stale_answers: u32,
}
