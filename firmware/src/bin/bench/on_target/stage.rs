//! One stage's samples, and its `bench` line: mean, median, minimum and
//! maximum instructions per call.

use cortex_m_semihosting::hprintln;
use wmr_core::math;

use super::timing::{Calibration, SAMPLES};

/// Per-call SysTick counts of one stage.
pub(super) struct Stage {
    pub(super) name: &'static str,
    counts: [u32; SAMPLES],
    n: usize,
}

impl Stage {
    pub(super) const fn new(name: &'static str) -> Self {
        Self {
            name,
            counts: [0; SAMPLES],
            n: 0,
        }
    }

    pub(super) fn record(&mut self, counts: u32) {
        if let Some(slot) = self.counts.get_mut(self.n) {
            *slot = counts;
            self.n += 1;
        }
    }

    pub(super) fn report(&self, cal: Calibration) {
        let Some(samples) = self.counts.get(..self.n).filter(|s| !s.is_empty()) else {
            hprintln!("bench {} no-samples", self.name);
            return;
        };
        let mut sorted = [0_u32; SAMPLES];
        let sorted = &mut sorted[..samples.len()];
        sorted.copy_from_slice(samples);
        sorted.sort_unstable();
        let total: u64 = samples.iter().map(|&c| u64::from(c)).sum();
        let instr = |c: u32| nearest(cal.instructions(c as f32));
        hprintln!(
            "bench {} mean={:.1} median={} min={} max={} n={}",
            self.name,
            cal.instructions(total as f32 / samples.len() as f32),
            instr(sorted[sorted.len() / 2]),
            instr(sorted[0]),
            instr(sorted[sorted.len() - 1]),
            samples.len()
        );
    }
}

/// Nearest integer (of a value that fits an `i32`).
pub(super) fn nearest(x: f32) -> i32 {
    math::floor(x + 0.5) as i32
}

/// Per-sample instructions of a stage whose sample is several timed
/// windows (a tick and the interrupts it brings), each window's
/// SysTick counts turned into instructions (its own measurement
/// overhead subtracted) before they are summed.
pub(super) struct Sums {
    pub(super) name: &'static str,
    values: [f32; SAMPLES],
    n: usize,
}

impl Sums {
    pub(super) const fn new(name: &'static str) -> Self {
        Self {
            name,
            values: [0.0; SAMPLES],
            n: 0,
        }
    }

    pub(super) fn record(&mut self, instructions: f32) {
        if let Some(slot) = self.values.get_mut(self.n) {
            *slot = instructions;
            self.n += 1;
        }
    }

    pub(super) fn report(&self) {
        let Some(samples) = self.values.get(..self.n).filter(|s| !s.is_empty()) else {
            hprintln!("bench {} no-samples", self.name);
            return;
        };
        let mut sorted = [0.0_f32; SAMPLES];
        let sorted = &mut sorted[..samples.len()];
        sorted.copy_from_slice(samples);
        sorted.sort_unstable_by(f32::total_cmp);
        let total: f32 = samples.iter().sum();
        hprintln!(
            "bench {} mean={:.1} median={} min={} max={} n={}",
            self.name,
            total / samples.len() as f32,
            nearest(sorted[sorted.len() / 2]),
            nearest(sorted[0]),
            nearest(sorted[sorted.len() - 1]),
            samples.len()
        );
    }
}

/// Per-call SysTick counts of a short stage called more often than
/// [`SAMPLES`] times, as a histogram (a call of up to `B - 1` counts; a
/// longer one fails the bench).
pub(super) struct Histogram<const B: usize> {
    pub(super) name: &'static str,
    bins: [u32; B],
    n: u32,
}

impl<const B: usize> Histogram<B> {
    pub(super) const fn new(name: &'static str) -> Self {
        Self {
            name,
            bins: [0; B],
            n: 0,
        }
    }

    pub(super) fn record(&mut self, counts: u32) {
        let Some(bin) = usize::try_from(counts)
            .ok()
            .and_then(|c| self.bins.get_mut(c))
        else {
            super::fail("a call longer than its histogram");
        };
        *bin += 1;
        self.n += 1;
    }

    /// Calls recorded.
    pub(super) fn calls(&self) -> u32 {
        self.n
    }

    /// The counts of the call at rank `rank` (0: the shortest).
    fn at(&self, rank: u32) -> u32 {
        let mut seen = 0;
        for (counts, &k) in self.bins.iter().enumerate() {
            seen += k;
            if seen > rank {
                return counts as u32;
            }
        }
        0
    }

    pub(super) fn report(&self, cal: Calibration) {
        if self.n == 0 {
            hprintln!("bench {} no-samples", self.name);
            return;
        }
        let total: u64 = (0_u64..)
            .zip(&self.bins)
            .map(|(counts, &k)| counts * u64::from(k))
            .sum();
        let instr = |c: u32| nearest(cal.instructions(c as f32));
        hprintln!(
            "bench {} mean={:.1} median={} min={} max={} n={}",
            self.name,
            cal.instructions(total as f32 / self.n as f32),
            instr(self.at(self.n / 2)),
            instr(self.at(0)),
            instr(self.at(self.n - 1)),
            self.n
        );
    }
}
