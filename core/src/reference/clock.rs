//! The time at which a trajectory is sampled, from integer ticks, reduced
//! modulo whole periods of a periodic reference (module documentation of
//! [`crate::reference`], "Time on long runs").

use super::{TickClock, Trajectory};

/// Turns of a periodic reference in one epoch: its time is reduced
/// modulo this many periods (module documentation).
pub const EPOCH_TURNS: u32 = 5;

/// `2⁶⁸ / (10π)`, rounded to the nearest integer (64 significant bits;
/// computed in exact rational arithmetic from Machin's formula for π).
const INV_EPOCH_RAD_Q68: u64 = 0x8261_35F1_D836_7755;

/// `2³²` as `f32` (exact).
const TWO_POW_32: f32 = 4_294_967_296.0;

/// `2⁻⁶⁴` as `f32` (exact).
const TWO_POW_MINUS_64: f32 = 1.0 / (TWO_POW_32 * TWO_POW_32);

/// How a trajectory's time is formed from integer ticks: `t = k·h` for a
/// line; for a periodic reference the tick count reduced modulo
/// [`EPOCH_TURNS`] periods, in integer arithmetic, before any `f32` time
/// is formed. Built once ([`Self::new`]); the tracker advances a
/// [`ReferenceTime`] with it every tick ([`Self::next`]).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ReferenceClock {
    /// The control period `h`, s.
    period_s: f32,
    /// Epochs per tick `q = |ω|·h / 10π`, as its fraction in units of
    /// `2⁻⁶⁴` epoch (whole epochs per tick do not move the phase); 0 for
    /// a line.
    epochs_per_tick: u64,
    /// At least one whole epoch per tick (`|ω|·h ≥ 10π`): every tick
    /// starts an epoch.
    every_tick_wraps: bool,
    /// Ticks per `2⁻⁶⁴` epoch, `1/q` from the rounded `q` (whole epochs
    /// included), for the offset of an epoch's first tick; 0 for a line.
    ticks_per_unit: f32,
}

/// A trajectory's time at one tick, from its clock ([`ReferenceClock`]):
/// the ticks since the trajectory started, reduced modulo its epoch.
/// [`Self::default`] is tick 0.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ReferenceTime {
    /// Where the tick is in its epoch, in units of `2⁻⁶⁴` epoch: `k·q`
    /// modulo `2⁶⁴` (exact modular arithmetic).
    epoch_phase: u64,
    /// Whole ticks since the epoch's first tick (since the start in the
    /// first epoch, and for a line).
    ticks: u64,
    /// Ticks from the epoch's start to its first tick, in `[0, 1)` (0 in
    /// the first epoch).
    offset_ticks: f32,
}

impl ReferenceClock {
    /// The clock of `trajectory` sampled every `clock.period_s()`: the
    /// figure-eight's period is `2π/h2`, a circle's `2π/|ω|`; a line has
    /// none.
    #[must_use]
    pub fn new(clock: &TickClock, trajectory: &Trajectory) -> Self {
        let period_s = clock.period_s();
        let Some(rate) = trajectory.rate_rad_s() else {
            return Self {
                period_s,
                epochs_per_tick: 0,
                every_tick_wraps: false,
                ticks_per_unit: 0.0,
            };
        };
        let rate = rate.abs();
        // |ω|·h = m·2^e exactly (two 24-bit mantissas); the epochs per
        // tick, in units of 2⁻⁶⁴ epoch, are m·2^e·2⁶⁴/10π
        // = m·INV·2^(e − 4), INV = 2⁶⁸/10π.
        let (m_rate, e_rate) = mantissa_exponent(rate);
        let (m_period, e_period) = mantissa_exponent(period_s);
        let product = widening_mul(m_rate * m_period, INV_EPOCH_RAD_Q68);
        let e = e_rate + e_period - 4;
        let units = if e >= 0 {
            // Whole epochs per tick (outside the plausible ranges): only
            // the fraction, the low 64 bits, moves the phase.
            u32::try_from(e)
                .ok()
                .and_then(|e| product.checked_shl(e))
                .unwrap_or(0)
        } else {
            let shift = e.unsigned_abs();
            if shift >= 128 {
                0
            } else {
                (product + (1_u128 << (shift - 1))) >> shift
            }
        };
        let whole = (units >> 64) as u64;
        let units_f32 = u64_to_f32(whole) * TWO_POW_32 * TWO_POW_32 + u64_to_f32(units as u64);
        Self {
            period_s,
            // The fraction of an epoch per tick (truncation keeps it).
            epochs_per_tick: units as u64,
            every_tick_wraps: e >= 0 || whole != 0,
            ticks_per_unit: if units_f32 > 0.0 {
                1.0 / units_f32
            } else {
                0.0
            },
        }
    }

    /// The control period `h`, s.
    #[must_use]
    pub fn period_s(&self) -> f32 {
        self.period_s
    }

    /// The epoch, in ticks (`10π / (|ω|·h)`, as the rounded `q` gives
    /// it, `2⁶⁴/q`, in `f32`), if the reference is periodic.
    #[must_use]
    pub fn epoch_ticks(&self) -> Option<f32> {
        (self.ticks_per_unit > 0.0).then(|| self.ticks_per_unit / TWO_POW_MINUS_64)
    }

    /// The time of tick 0.
    #[must_use]
    pub fn start(&self) -> ReferenceTime {
        ReferenceTime::default()
    }

    /// The time one tick after `time`: exact integer arithmetic, no
    /// accumulated rounding, no end (the whole ticks of a line saturate
    /// after `2⁶⁴` ticks).
    #[must_use]
    pub fn next(&self, time: ReferenceTime) -> ReferenceTime {
        let (epoch_phase, carried) = time.epoch_phase.overflowing_add(self.epochs_per_tick);
        if carried || self.every_tick_wraps {
            // A new epoch began during this tick, `epoch_phase` (in units
            // of 2⁻⁶⁴ epoch, less than one tick's) before it.
            ReferenceTime {
                epoch_phase,
                ticks: 0,
                offset_ticks: u64_to_f32(epoch_phase) * self.ticks_per_unit,
            }
        } else {
            ReferenceTime {
                epoch_phase,
                ticks: time.ticks.saturating_add(1),
                offset_ticks: time.offset_ticks,
            }
        }
    }

    /// The time of tick `tick` since the start, as [`Self::next`] would
    /// reach it from [`Self::start`] (bit for bit), without stepping
    /// there.
    #[must_use]
    pub fn at_tick(&self, tick: u64) -> ReferenceTime {
        let product = widening_mul(tick, self.epochs_per_tick);
        let epoch_phase = product as u64;
        let wrapped = (self.every_tick_wraps && tick > 0) || (product >> 64) != 0;
        if !wrapped {
            return ReferenceTime {
                epoch_phase,
                ticks: tick,
                offset_ticks: 0.0,
            };
        }
        // The epoch began `w` ticks ago, the largest `w` with
        // `w·q ≤ phase`: the phase at its first tick, `phase − w·q`, is
        // below one tick's `q`.
        let ticks = if self.every_tick_wraps {
            0
        } else {
            epoch_phase.checked_div(self.epochs_per_tick).unwrap_or(0)
        };
        let at_first = epoch_phase.wrapping_sub(ticks.wrapping_mul(self.epochs_per_tick));
        ReferenceTime {
            epoch_phase,
            ticks,
            offset_ticks: u64_to_f32(at_first) * self.ticks_per_unit,
        }
    }

    /// The time, s, at which the trajectory is sampled at `time`: the
    /// ticks since its epoch started times `h`, `(w + δ)·h`; in the first
    /// epoch (and for a line) `k·h` exactly as [`TickClock::time_s`].
    #[must_use]
    pub fn time_s(&self, time: ReferenceTime) -> f32 {
        (u64_to_f32(time.ticks) + time.offset_ticks) * self.period_s
    }
}

impl Trajectory {
    /// The reference at `time` of `clock` ([`ReferenceClock::time_s`]).
    #[must_use]
    pub fn sample_at(&self, clock: &ReferenceClock, time: ReferenceTime) -> super::ReferenceSample {
        self.sample(clock.time_s(time))
    }
}

/// `x = m·2^e` for a finite `f32` of either sign (`m < 2²⁴`, exact).
fn mantissa_exponent(x: f32) -> (u64, i32) {
    let bits = x.to_bits();
    let biased = ((bits >> 23) & 0xFF) as i32;
    let fraction = u64::from(bits & 0x7F_FFFF);
    if biased == 0 {
        (fraction, -149)
    } else {
        (fraction | 0x80_0000, biased - 150)
    }
}

/// The exact 128-bit product of two `u64`, from four 32-bit products (the
/// target's `UMULL`; no 128-bit multiplication routine).
fn widening_mul(a: u64, b: u64) -> u128 {
    let (a1, a0) = (a >> 32, a & 0xFFFF_FFFF);
    let (b1, b0) = (b >> 32, b & 0xFFFF_FFFF);
    (u128::from(a1 * b1) << 64)
        + (u128::from(a1 * b0) << 32)
        + (u128::from(a0 * b1) << 32)
        + u128::from(a0 * b0)
}

/// `x` in `f32`: one rounding below `2³²` (the FPU's `u32` conversion,
/// the same as `x as u32 as f32`), two beyond (still within `2⁻²³`
/// relative), without a software `u64` conversion routine.
fn u64_to_f32(x: u64) -> f32 {
    match u32::try_from(x) {
        Ok(x) => x as f32,
        Err(_) => ((x >> 32) as u32 as f32) * TWO_POW_32 + (x as u32) as f32,
    }
}
