//! Global trajectory-tracking laws of paper 001 (Yan & Ma): state feedback
//! (14) with its gain bound (15), Theorem 2, and output feedback (27)–(28),
//! Theorem 3.
//!
//! # The law, as derived from the proofs
//! With position errors `ζ1 = x − x_r`, `ζ2 = y − y_r` (13) and
//! `f_i = k_i·atan(ζ_i)`:
//!
//! ```text
//! u = (ẋ_r − f1, ẏ_r − f2),   v = |u|,   θ* = atan2(u_y, u_x)        (14)
//! ḟ_i = k_i·ζ̇_i / (1 + ζ_i²),  ζ̇ = v·(cos θ, sin θ) − (ẋ_r, ẏ_r)
//! θ̇* = (u_x·u̇_y − u_y·u̇_x)/v²,  u̇ = (ẍ_r − ḟ1, ÿ_r − ḟ2)
//! e  = wrap(θ − θ*) ∈ (−π, π]
//! ω  = θ̇* − k3·e − v·ζ1·g1 − v·ζ2·g2
//! g1 = −sin(θ* + e/2)·sinc(e/2),  g2 = cos(θ* + e/2)·sinc(e/2)
//! ```
//!
//! so that `v(cos θ − cos θ*) = v·e·g1`, `v(sin θ − sin θ*) = v·e·g2` and
//! `V = ½(ζ1² + ζ2² + e²)` has `V̇ = −ζ1 f1 − ζ2 f2 − k3 e²` (25).
//! Where this differs from the printed text (papers' README, slips 2–5):
//! * `θ̇*` is the derivative of `atan2(u_y, u_x)`: its first bracket takes
//!   the reference *accelerations* `ẍ_r, ÿ_r` (printed: velocities).
//! * `ḟ_i` is the full derivative `k_i (ẋ_i − ẋ_{r,i})/(1+ζ_i²)`; (28)
//!   printed only the `v·ẑ` part.
//! * `e` is wrapped and `g1, g2` are evaluated at the wrapped difference
//!   (the `(cos a − cos b)/(a − b)` form is the same function for `a − b`
//!   in (−π, π], and has no 2π jump when `θ*` crosses ±π).
//! * Output feedback (27)–(28): `cos θ, sin θ, θ` are replaced by the
//!   observer's `ẑ3, ẑ4` and `θ̂ = atan2(ẑ4, ẑ3)`; the printed `k3·ẑ3`
//!   means `k3·(θ̂ − θ*)` (slip 4).
//!
//! # Computed with one `atan2` for `e`
//! `e = wrap(θ − θ*)` is the angle from the unit vector `d* = u/v` to the
//! heading vector `z = (cos θ, sin θ)` (or `(ẑ3, ẑ4)`, whose length does
//! not matter), so `e = atan2(d* × z, d* · z)` with `d* × z = d*_x z_y −
//! d*_y z_x` and `d* · z = d*_x z_x + d*_y z_y`: one `atan2` already in
//! (−π, π], instead of `atan2(ẑ4, ẑ3)`, `atan2(u_y, u_x)`, a subtraction
//! and a wrap. At `z = (±0, ±0)` (the observer's "heading unknown") it
//! takes `z = (±1, 0)` with the sign of `ẑ3`, which is what `θ̂ = atan2(±0,
//! ±0)` gives. `θ* = atan2(u_y, u_x)` is still computed once, for its
//! output and the held value; `(sin, cos)(θ* + e/2)` is one `sincos`, and
//! `sinc(e/2)` a series for |e| ≤ 0.2 rad ([`math::sinc`]).
//!
//! Half-angle identities could replace that `sincos`: with `ẑ = z/|z|`,
//! `d* + ẑ = 2 cos(e/2)·(cos, sin)(θ* + e/2)` (for |e| ≤ π/2) and `ẑ − d* =
//! 2 sin(e/2)·(−sin, cos)(θ* + e/2)` (above), and `sin(e/2)` is `d*` cross
//! the normalized bisector. Measured (`cargo xtask bench-target`,
//! Cortex-M4F), the law takes 564 instructions with them against 510 with
//! the `sincos`, because the two normalizations cost two `sqrt`s, and
//! `sqrtf` is a 67-instruction software routine here (stable `no_std` Rust
//! has no `VSQRT` without `unsafe`), against 100 for the `sincos`. So the
//! law keeps the `sincos`.
//!
//! # Gain bound (15)
//! `k1² + k2² ≤ γ²·(4/π²)·v_rm²` with `0 < γ < 1` guarantees
//! `v_m = (1 − γ)·v_rm ≤ v ≤ v_rM + γ·v_rm = v_M` (21)–(22). The paper's own
//! gains break it for its figure-eight (slip 6): [`TrackingGains::check_bound`]
//! reports that instead of refusing the gains.
//!
//! # Near `v = 0`
//! When the bound does not hold, `u` can pass through 0 and `θ*` is then
//! undefined. Below [`TrackingController::SINGULAR_SPEED_M_S`] the law holds
//! the last well-defined `θ*` and sets `θ̇* = 0`: the robot turns toward the
//! last desired heading at rate `k3` while `v` is (nearly) zero, and the law
//! is continuous again once `|u|` grows. Every output is finite for finite
//! input (no division by `v` below that threshold).

pub use crate::control::interface::TrackingCommand;

use crate::control::interface::{LawCommand, TrackingLaw};
use crate::geometry::HeadingEstimate;
use crate::geometry::{BodyVelocity, Pose, Vec2};
use crate::math;
use crate::plausible::GAIN;
use crate::reference::{ReferenceSample, SpeedBounds};

/// Why tracking gains were refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum GainError {
    /// `k1` outside [`GAIN`].
    K1,
    /// `k2` outside [`GAIN`].
    K2,
    /// `k3` outside [`GAIN`].
    K3,
}

impl core::fmt::Display for GainError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::K1 => write!(f, "gains[0] (k1) must be in {GAIN} m/s"),
            Self::K2 => write!(f, "gains[1] (k2) must be in {GAIN} m/s"),
            Self::K3 => write!(f, "gains[2] (k3) must be in {GAIN} 1/s"),
        }
    }
}

impl core::error::Error for GainError {}

/// What the gain bound (15) says about a set of gains and a reference.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum GainBound {
    /// (15) holds with this `γ < 1`: `v_m ≤ v ≤ v_M` is guaranteed (21)–(22).
    Satisfied {
        /// Smallest `γ` for which (15) holds.
        gamma: f32,
        /// Guaranteed lower bound `v_m = (1 − γ) v_rm` on the commanded speed, m/s.
        min_speed_m_s: f32,
        /// Guaranteed upper bound `v_M = v_rM + γ v_rm` on the commanded speed, m/s.
        max_speed_m_s: f32,
    },
    /// (15) fails (`γ ≥ 1`): the law still runs, but `v > 0` is not guaranteed
    /// and the paper's convergence proof does not apply.
    Violated {
        /// The `γ` these gains would need (≥ 1).
        gamma: f32,
    },
    /// The reference can stop (`v_rm = 0`): Assumption 1 fails for any gains.
    ReferenceNotExciting,
}

impl GainBound {
    /// Whether the guarantee of (21)–(22) applies.
    #[must_use]
    pub fn is_satisfied(&self) -> bool {
        matches!(self, Self::Satisfied { .. })
    }
}

/// Gains `k1, k2` (m/s per rad of `atan(ζ)`, i.e. the largest speed the
/// position-error feedback may add on each axis is `k_i·π/2`) and `k3` (1/s,
/// heading-error rate).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TrackingGains {
    k1: f32,
    k2: f32,
    k3: f32,
}

impl TrackingGains {
    /// Validates `k_i > 0` (15), finite.
    ///
    /// # Errors
    /// The first gain out of range.
    pub fn new(k1: f32, k2: f32, k3: f32) -> Result<Self, GainError> {
        let ok = |k: f32| GAIN.contains(k);
        if !ok(k1) {
            return Err(GainError::K1);
        }
        if !ok(k2) {
            return Err(GainError::K2);
        }
        if !ok(k3) {
            return Err(GainError::K3);
        }
        Ok(Self { k1, k2, k3 })
    }

    /// `k1`.
    #[must_use]
    pub fn k1(&self) -> f32 {
        self.k1
    }
    /// `k2`.
    #[must_use]
    pub fn k2(&self) -> f32 {
        self.k2
    }
    /// `k3`.
    #[must_use]
    pub fn k3(&self) -> f32 {
        self.k3
    }

    /// Checks the gain bound (15) against the reference's speed bounds (2).
    #[must_use]
    // Always inlined so that a compiled-in spec's validation folds away: see `LawSpec::build`.
    #[inline(always)]
    pub fn check_bound(&self, reference: SpeedBounds) -> GainBound {
        if !(reference.min_m_s.is_finite() && reference.min_m_s > 0.0) {
            return GainBound::ReferenceNotExciting;
        }
        // (15) ⇔ √(k1² + k2²)·π/2 ≤ γ·v_rm.
        let gamma = math::hypot(self.k1, self.k2) * 0.5 * math::PI / reference.min_m_s;
        if gamma < 1.0 {
            GainBound::Satisfied {
                gamma,
                min_speed_m_s: (1.0 - gamma) * reference.min_m_s,
                max_speed_m_s: reference.max_m_s + gamma * reference.min_m_s,
            }
        } else {
            GainBound::Violated { gamma }
        }
    }
}

/// The heading the law is given: the true one (state feedback) or the
/// observer's (output feedback).
#[derive(Debug, Clone, Copy, PartialEq)]
struct HeadingInput {
    /// `cos θ` or `ẑ3`.
    cos_theta: f32,
    /// `sin θ` or `ẑ4`.
    sin_theta: f32,
}

/// The tracking controller of paper 001.
///
/// Holds the gains and one piece of state: the last well-defined `θ*` (and
/// its unit vector), used while `|u|` is below [`Self::SINGULAR_SPEED_M_S`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TrackingController {
    gains: TrackingGains,
    held_desired_heading_rad: f32,
    held_desired_direction: Vec2,
}

impl TrackingController {
    /// Below this `|u|` (m/s) `θ*` is held and `θ̇* = 0`.
    pub const SINGULAR_SPEED_M_S: f32 = 1.0e-4;

    /// A controller with these gains.
    #[must_use]
    pub fn new(gains: TrackingGains) -> Self {
        Self {
            gains,
            held_desired_heading_rad: 0.0,
            held_desired_direction: Vec2::new(1.0, 0.0),
        }
    }

    /// The gains.
    #[must_use]
    pub fn gains(&self) -> &TrackingGains {
        &self.gains
    }

    /// Swaps gains without touching the state (bumpless).
    pub fn set_gains(&mut self, gains: TrackingGains) {
        self.gains = gains;
    }

    /// State feedback (14): the true pose is known.
    pub fn state_feedback(&mut self, reference: &ReferenceSample, pose: Pose) -> TrackingCommand {
        let (sin_theta, cos_theta) = math::sincos(pose.heading_rad);
        let heading = HeadingInput {
            cos_theta,
            sin_theta,
        };
        self.law(reference, pose.position, heading)
    }

    /// Output feedback (27)–(28): position measured, heading from the observer.
    pub fn output_feedback(
        &mut self,
        reference: &ReferenceSample,
        position: Vec2,
        estimate: HeadingEstimate,
    ) -> TrackingCommand {
        let heading = HeadingInput {
            cos_theta: estimate.cos_theta,
            sin_theta: estimate.sin_theta,
        };
        self.law(reference, position, heading)
    }

    fn law(
        &mut self,
        reference: &ReferenceSample,
        position: Vec2,
        heading: HeadingInput,
    ) -> TrackingCommand {
        let TrackingGains { k1, k2, k3 } = self.gains;
        let error = position - reference.position;
        let (f1, f2) = (k1 * math::atan(error.x), k2 * math::atan(error.y));
        let u = Vec2::new(reference.velocity.x - f1, reference.velocity.y - f2);
        let v = u.norm();

        // Time derivative of f_i along the robot's motion (slip 3).
        let error_rate = Vec2::new(
            v * heading.cos_theta - reference.velocity.x,
            v * heading.sin_theta - reference.velocity.y,
        );
        let f1_rate = k1 * error_rate.x / (1.0 + error.x * error.x);
        let f2_rate = k2 * error_rate.y / (1.0 + error.y * error.y);
        let u_rate = Vec2::new(
            reference.acceleration.x - f1_rate,
            reference.acceleration.y - f2_rate,
        );

        let (desired_heading_rad, desired_heading_rate_rad_s, desired) =
            if v > Self::SINGULAR_SPEED_M_S && v.is_finite() {
                // θ̇* = (u_x u̇_y − u_y u̇_x)/v², written as (cos θ*·u̇_y − sin θ*·u̇_x)/v
                // so that no intermediate overflows before the division (slip 2).
                let (cos_d, sin_d) = (u.x / v, u.y / v);
                let rate = (cos_d * u_rate.y - sin_d * u_rate.x) / v;
                let theta_d = math::atan2(u.y, u.x);
                let direction = Vec2::new(cos_d, sin_d);
                self.held_desired_heading_rad = theta_d;
                self.held_desired_direction = direction;
                (theta_d, rate, direction)
            } else {
                (
                    self.held_desired_heading_rad,
                    0.0,
                    self.held_desired_direction,
                )
            };

        // Slip 5: one wrapped difference feeds both the k3 term and g1, g2;
        // e = atan2(d* × z, d* · z) (module docs), with atan2(±0, ±0)'s
        // convention for an unknown heading.
        let z = if heading.cos_theta == 0.0 && heading.sin_theta == 0.0 {
            Vec2::new(1.0_f32.copysign(heading.cos_theta), 0.0)
        } else {
            Vec2::new(heading.cos_theta, heading.sin_theta)
        };
        let e = math::atan2(
            desired.x * z.y - desired.y * z.x,
            desired.x * z.x + desired.y * z.y,
        );
        let half = 0.5 * e;
        let sc = math::sinc(half);
        let mid = desired_heading_rad + half;
        let (sin_mid, cos_mid) = math::sincos(mid);
        let g1 = -sin_mid * sc;
        let g2 = cos_mid * sc;
        let omega = desired_heading_rate_rad_s - k3 * e - v * error.x * g1 - v * error.y * g2;

        TrackingCommand {
            body: BodyVelocity {
                v_m_s: v,
                omega_rad_s: omega,
            },
            position_error: error,
            desired_heading_rad,
            desired_heading_rate_rad_s,
            heading_error_rad: e,
        }
    }
}

impl TrackingLaw for TrackingController {
    /// Output feedback (27)–(28) ([`TrackingController::output_feedback`]).
    fn command(
        &mut self,
        reference: &ReferenceSample,
        position: Vec2,
        heading: HeadingEstimate,
        _driven: BodyVelocity,
    ) -> LawCommand {
        LawCommand::Drive(self.output_feedback(reference, position, heading))
    }

    /// The held `θ*` (module docs, "Near `v = 0`") stays: it is the last
    /// well-defined desired heading, whatever happened since.
    fn restart(&mut self) {}

    fn rejected_updates(&self) -> u32 {
        0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::{FigureEight, Trajectory};
    use proptest::prelude::*;

    #[test]
    fn paper_gains_break_the_bound_for_the_figure_eight() {
        let bounds = Trajectory::from(FigureEight::paper_001()).speed_bounds();
        let paper = TrackingGains::new(0.11, 0.11, 1.0).unwrap();
        match paper.check_bound(bounds) {
            GainBound::Violated { gamma } => assert!(gamma > 3.0 && gamma < 4.0, "{gamma}"),
            other => panic!("expected a violation, got {other:?}"),
        }
        let safe = TrackingGains::new(0.02, 0.02, 1.0).unwrap();
        assert!(safe.check_bound(bounds).is_satisfied());
    }

    #[test]
    fn gains_are_validated() {
        assert_eq!(TrackingGains::new(0.0, 1.0, 1.0), Err(GainError::K1));
        assert_eq!(TrackingGains::new(1.0, f32::NAN, 1.0), Err(GainError::K2));
        assert_eq!(TrackingGains::new(1.0, 1.0, -1.0), Err(GainError::K3));
    }

    #[test]
    fn singular_point_holds_the_desired_heading() {
        let mut c = TrackingController::new(TrackingGains::new(0.5, 0.5, 1.0).unwrap());
        // Reference moving +x at exactly the speed the position error cancels.
        let r = ReferenceSample {
            position: Vec2::ZERO,
            velocity: Vec2::new(0.5 * math::atan(1.0), 0.0),
            acceleration: Vec2::ZERO,
        };
        let first = c.state_feedback(&r, Pose::new(0.0, 0.0, 0.3));
        let cmd = c.state_feedback(&r, Pose::new(1.0, 0.0, 0.3));
        assert!(cmd.body.v_m_s < TrackingController::SINGULAR_SPEED_M_S);
        assert_eq!(cmd.desired_heading_rad, first.desired_heading_rad);
        assert!(cmd.body.is_finite());
    }

    /// Lyapunov decrease (25): along the exact closed loop, V̇ equals
    /// −ζ1 f1 − ζ2 f2 − k3 e² to within finite-difference accuracy.
    #[test]
    fn lyapunov_derivative_matches_25() {
        let traj = Trajectory::from(FigureEight::paper_001());
        let gains = TrackingGains::new(0.11, 0.11, 1.0).unwrap();
        let mut c = TrackingController::new(gains);
        let mut pose = Pose::new(0.3, -6.0, 2.0);
        let h = 1e-3_f32;
        for k in 0..2000 {
            let t = k as f32 * h;
            let r = traj.sample(t);
            let cmd = c.state_feedback(&r, pose);
            let v_now = 0.5
                * (cmd.position_error.x.powi(2)
                    + cmd.position_error.y.powi(2)
                    + cmd.heading_error_rad.powi(2));
            let predicted = -cmd.position_error.x * 0.11 * libm::atanf(cmd.position_error.x)
                - cmd.position_error.y * 0.11 * libm::atanf(cmd.position_error.y)
                - cmd.heading_error_rad.powi(2);
            let next = pose.advance_arc(cmd.body.v_m_s * h, cmd.body.omega_rad_s * h);
            let r_next = traj.sample(t + h);
            let cmd_next = TrackingController::new(gains).state_feedback(&r_next, next);
            let v_next = 0.5
                * (cmd_next.position_error.x.powi(2)
                    + cmd_next.position_error.y.powi(2)
                    + cmd_next.heading_error_rad.powi(2));
            let measured = (v_next - v_now) / h;
            assert!(
                (measured - predicted).abs() < 0.02 * predicted.abs() + 2e-3,
                "k={k}: V̇ {measured} vs (25) {predicted}"
            );
            pose = next;
        }
    }

    proptest! {
        /// Finite inputs never give a non-finite command.
        #[test]
        fn finite_in_finite_out(
            k in (1e-3_f32..10.0, 1e-3_f32..10.0, 1e-3_f32..10.0),
            p in (-1e4_f32..1e4, -1e4_f32..1e4),
            z in (-5.0_f32..5.0, -5.0_f32..5.0),
            rv in (-5.0_f32..5.0, -5.0_f32..5.0),
            ra in (-5.0_f32..5.0, -5.0_f32..5.0),
            rp in (-1e4_f32..1e4, -1e4_f32..1e4),
        ) {
            let mut c = TrackingController::new(TrackingGains::new(k.0, k.1, k.2).unwrap());
            let r = ReferenceSample {
                position: Vec2::new(rp.0, rp.1),
                velocity: Vec2::new(rv.0, rv.1),
                acceleration: Vec2::new(ra.0, ra.1),
            };
            let cmd = c.output_feedback(&r, Vec2::new(p.0, p.1),
                HeadingEstimate { cos_theta: z.0, sin_theta: z.1 });
            prop_assert!(cmd.body.is_finite(), "{:?}", cmd);
            let cmd = c.state_feedback(&r, Pose::new(p.0, p.1, z.0));
            prop_assert!(cmd.body.is_finite(), "{:?}", cmd);
        }

        /// With gains satisfying (15), v_m ≤ v ≤ v_M (21)–(22) for any pose.
        #[test]
        fn speed_stays_within_21_22(
            t in 0.0_f32..400.0,
            p in (-1e3_f32..1e3, -1e3_f32..1e3),
            theta in -4.0_f32..4.0,
            scale in 0.05_f32..0.99,
        ) {
            let traj = Trajectory::from(FigureEight::paper_001());
            let bounds = traj.speed_bounds();
            // Pick gains on the bound's γ = scale.
            let k = scale * 2.0 / math::PI * bounds.min_m_s / core::f32::consts::SQRT_2;
            let gains = TrackingGains::new(k, k, 1.0).unwrap();
            let GainBound::Satisfied { min_speed_m_s, max_speed_m_s, .. } = gains.check_bound(bounds) else {
                return Err(TestCaseError::fail("bound should hold"));
            };
            let mut c = TrackingController::new(gains);
            let cmd = c.state_feedback(&traj.sample(t), Pose::new(p.0, p.1, theta));
            prop_assert!(cmd.body.v_m_s >= min_speed_m_s * (1.0 - 1e-4), "{} < {}", cmd.body.v_m_s, min_speed_m_s);
            prop_assert!(cmd.body.v_m_s <= max_speed_m_s * (1.0 + 1e-4), "{} > {}", cmd.body.v_m_s, max_speed_m_s);
        }
    }
}
