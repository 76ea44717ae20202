//! Trapezoidal profiles in time: of the speed along a moving segment, of
//! the angular rate of a pivot.
//!
//! A segment of length `L` (m, or rad for a pivot) is driven from the
//! speed `v0` to `v1` under the cap `v_c` with the acceleration `a`:
//! accelerate at `a` to the peak `v_p = min(v_c, √(aL + (v0² + v1²)/2))`,
//! cruise at `v_p`, decelerate at `a` to `v1`. The planner's forward and
//! backward passes choose `v0, v1` so that `|v1² − v0²| ≤ 2aL`, which
//! makes `v_p ≥ max(v0, v1)`.

use crate::math;

/// One segment's profile: the three phases' durations and speeds.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Trapezoid {
    /// Speed at the start, m/s (rad/s).
    pub v0: f32,
    /// Peak (cruise) speed.
    pub peak: f32,
    /// Speed at the end.
    pub v1: f32,
    /// Acceleration magnitude, m/s² (rad/s²).
    pub accel: f32,
    /// Duration of the acceleration, s.
    pub t_accel_s: f32,
    /// Duration of the cruise, s.
    pub t_cruise_s: f32,
    /// Duration of the deceleration, s.
    pub t_decel_s: f32,
    /// Length, m (rad): the distance is clamped to it.
    pub length: f32,
}

impl Trapezoid {
    /// The profile over `length` from `v0` to `v1` (both `≤ cap`, reachable
    /// from each other within `length` at `accel`) under `cap`.
    #[must_use]
    pub fn new(length: f32, v0: f32, v1: f32, cap: f32, accel: f32) -> Self {
        let peak_sq = accel * length + 0.5 * (v0 * v0 + v1 * v1);
        // At the cap (the common case on long segments) without a root.
        let peak = if peak_sq >= cap * cap {
            cap
        } else {
            math::sqrt(peak_sq)
        }
        .max(v0)
        .max(v1);
        let t_accel_s = (peak - v0) / accel;
        let t_decel_s = (peak - v1) / accel;
        let d_accel = 0.5 * (v0 + peak) * t_accel_s;
        let d_decel = 0.5 * (v1 + peak) * t_decel_s;
        let cruise = (length - d_accel - d_decel).max(0.0);
        let t_cruise_s = if peak > 0.0 { cruise / peak } else { 0.0 };
        Self {
            v0,
            peak,
            v1,
            accel,
            t_accel_s,
            t_cruise_s,
            t_decel_s,
            length,
        }
    }

    /// Total duration, s.
    #[must_use]
    pub fn duration_s(&self) -> f32 {
        self.t_accel_s + self.t_cruise_s + self.t_decel_s
    }

    /// Distance, speed and acceleration at `t_s` from the segment's start
    /// (clamped to the segment): the distance in `[0, length]`, the speed
    /// exactly `v1` from the end of the deceleration on.
    #[must_use]
    pub fn at(&self, t_s: f32) -> (f32, f32, f32) {
        let t = t_s.max(0.0);
        let (distance, speed, accel) = if t < self.t_accel_s {
            (
                t * (self.v0 + 0.5 * self.accel * t),
                self.v0 + self.accel * t,
                self.accel,
            )
        } else {
            let d_accel = 0.5 * (self.v0 + self.peak) * self.t_accel_s;
            let t = t - self.t_accel_s;
            if t < self.t_cruise_s {
                (d_accel + self.peak * t, self.peak, 0.0)
            } else {
                let d = d_accel + self.peak * self.t_cruise_s;
                let t = t - self.t_cruise_s;
                if t < self.t_decel_s {
                    (
                        d + t * (self.peak - 0.5 * self.accel * t),
                        self.peak - self.accel * t,
                        -self.accel,
                    )
                } else {
                    (self.length, self.v1, 0.0)
                }
            }
        };
        (
            math::clamp_or(distance, 0.0, self.length, 0.0),
            speed,
            accel,
        )
    }
}
