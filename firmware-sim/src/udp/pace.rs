//! Real time, or `N` times faster: tick `k` is not started before the
//! wall clock reaches `k·h / N` since the start; a machine that cannot
//! keep up runs flat out (the speed-up achieved is reported).

use std::time::{Duration, Instant};

/// The wall clock of a run.
#[derive(Debug, Clone, Copy)]
pub struct Pace {
    start: Instant,
    /// Wall seconds per simulated second (`1 / speedup`).
    wall_per_sim: f64,
}

impl Pace {
    /// Starts now at `speedup` × real time (finite, > 0).
    #[must_use]
    pub fn new(speedup: f64) -> Self {
        Self {
            start: Instant::now(),
            wall_per_sim: 1.0 / speedup,
        }
    }

    /// Sleeps until simulated time `t_s` is due.
    pub fn wait_for(&self, t_s: f64) {
        let due = Duration::from_secs_f64((t_s * self.wall_per_sim).max(0.0));
        let elapsed = self.start.elapsed();
        if let Some(rest) = due.checked_sub(elapsed) {
            std::thread::sleep(rest);
        }
    }

    /// Wall seconds since the start.
    #[must_use]
    pub fn elapsed_s(&self) -> f64 {
        self.start.elapsed().as_secs_f64()
    }
}
