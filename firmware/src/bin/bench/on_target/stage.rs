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
