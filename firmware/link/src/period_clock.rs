//! Control periods counted from a free-running cycle counter, for the
//! clocks that must follow wall time when ticks overrun.
//!
//! A board's loop runs one control tick per period of its tick timer; a
//! tick that overruns its period folds the periods it missed into one
//! (the timer's update flag says only "at least one ended"), so a count
//! of loop passes runs slow while ticks overrun. The MAVLink endpoint's
//! link-loss timeout and telemetry rates must not stretch with it (a
//! robot whose ticks all overrun by half would stop on link loss after
//! 4.5 s instead of 3 s), so they take their time from [`PeriodClock`]:
//! the whole periods elapsed on a cycle counter (the Cortex-M's `DWT`
//! `CYCCNT`, 96 MHz on the Black Pill, wrapping every 44.7 s), the
//! remainder carried to the next reading.
//!
//! Readings must come less than one counter wrap apart (2³² cycles; the
//! loop reads once a tick). Arithmetic is `u32` only (no `u64` division
//! on the target), with no panic path: a zero period is refused at
//! construction.

use core::num::NonZeroU32;

/// Whole control periods elapsed on a wrapping `u32` cycle counter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PeriodClock {
    cycles_per_period: NonZeroU32,
    last_reading: u32,
    remainder_cycles: u32,
    periods: u32,
}

impl PeriodClock {
    /// A clock of periods of `cycles_per_period` cycles, starting at 0 at
    /// the counter's reading `now`. `None` if `cycles_per_period` is 0.
    #[must_use]
    pub const fn new(cycles_per_period: u32, now: u32) -> Option<Self> {
        let Some(cycles_per_period) = NonZeroU32::new(cycles_per_period) else {
            return None;
        };
        Some(Self {
            cycles_per_period,
            last_reading: now,
            remainder_cycles: 0,
            periods: 0,
        })
    }

    /// Takes the counter's reading `now` and returns the periods elapsed
    /// since the clock started (wrapping at 2³²). The cycles since the
    /// last reading are the wrapping difference, so the counter's own
    /// wrap is harmless.
    pub fn advance(&mut self, now: u32) -> u32 {
        let elapsed = now.wrapping_sub(self.last_reading);
        self.last_reading = now;
        // Whole periods of the elapsed cycles first, then of what is left
        // with the carried remainder. Both `left` and the remainder are
        // below the period, so `carried` is in 1..=period, `left − carried`
        // is taken only when not negative, and `remainder + left` only when
        // below the period: the wrapping operations never wrap.
        let whole = elapsed / self.cycles_per_period;
        let left = elapsed % self.cycles_per_period;
        let carried = self
            .cycles_per_period
            .get()
            .wrapping_sub(self.remainder_cycles);
        let (extra, remainder) = if left >= carried {
            (1, left.wrapping_sub(carried))
        } else {
            (0, self.remainder_cycles.wrapping_add(left))
        };
        self.remainder_cycles = remainder;
        self.periods = self.periods.wrapping_add(whole).wrapping_add(extra);
        self.periods
    }

    /// The periods elapsed at the last [`PeriodClock::advance`].
    #[must_use]
    pub const fn periods(&self) -> u32 {
        self.periods
    }
}

#[cfg(test)]
mod tests {
    use super::PeriodClock;
    use proptest::prelude::*;

    /// 10 ms at 96 MHz.
    const PERIOD: u32 = 960_000;

    #[test]
    fn a_zero_period_is_refused() {
        assert_eq!(PeriodClock::new(0, 0), None);
    }

    #[test]
    fn ticks_on_time_count_one_period_each() {
        let mut clock = PeriodClock::new(PERIOD, 5).unwrap();
        for k in 1..=1000_u32 {
            assert_eq!(clock.advance(5_u32.wrapping_add(k.wrapping_mul(PERIOD))), k);
        }
    }

    /// Ticks that all overrun by half a period: the loop makes 2 passes
    /// per 3 periods, the clock counts the 3.
    #[test]
    fn overrunning_ticks_count_the_periods_they_folded() {
        let mut clock = PeriodClock::new(PERIOD, 0).unwrap();
        let mut now = 0_u32;
        for _ in 0..200 {
            now = now.wrapping_add(PERIOD + PERIOD / 2);
            clock.advance(now);
        }
        assert_eq!(clock.periods(), 300);
    }

    #[test]
    fn the_cycle_counters_wrap_is_harmless() {
        let start = u32::MAX - PERIOD / 3;
        let mut clock = PeriodClock::new(PERIOD, start).unwrap();
        assert_eq!(clock.advance(start.wrapping_add(PERIOD)), 1);
        assert_eq!(clock.advance(start.wrapping_add(3 * PERIOD + 7)), 3);
    }

    proptest! {
        /// Over any readings less than a wrap apart, the periods counted
        /// are the whole periods of the total cycles elapsed, exactly.
        #[test]
        fn the_count_is_the_total_over_the_period(
            period in 1_u32..10_000_000,
            start in any::<u32>(),
            steps in proptest::collection::vec(0_u32..50_000_000, 1..200),
        ) {
            let mut clock = PeriodClock::new(period, start).unwrap();
            let mut now = start;
            let mut total = 0_u64;
            for step in steps {
                now = now.wrapping_add(step);
                total += u64::from(step);
                let counted = clock.advance(now);
                prop_assert_eq!(u64::from(counted), total / u64::from(period));
            }
        }
    }
}
