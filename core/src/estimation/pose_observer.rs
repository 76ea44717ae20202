//! The four-dimensional observer of `x, y, cos θ, sin θ` from measured
//! position (paper 002, Jakubiak, Nijmeijer & Lefeber, section 3.1.1,
//! Proposition 4, eqs. (33)–(41)).
//!
//! # Continuous time
//! With `c = cos θ`, `s = sin θ` the unicycle (5) becomes (34):
//! `ẋ = v c, ẏ = v s, ṡ = ω c, ċ = −ω s`. The observer (37) is a copy with
//! output injection from the measured position:
//!
//! ```text
//! x̂' = v ĉ + a1 x̃        ŝ' =  ω ĉ + a3 v ỹ        x̃ = x − x̂
//! ŷ' = v ŝ + a2 ỹ        ĉ' = −ω ŝ + a4 v x̃        ỹ = y − ŷ
//! ```
//!
//! and `V = ½(a4 x̃² + a3 ỹ² + s̃² + c̃²)` (40) has `V̇ = −a1 a4 x̃² − a2 a3 ỹ²`
//! (41). The estimate converges when `v` stays away from zero (39), and
//! exponentially when `v` is persistently exciting (section 3.1.2).
//!
//! Printed slips: (37)'s first line lost its dot (`x̂` for `x̂'`), and
//! `ṡ = ω c, ċ = −ω s` in (34) is right but (36)'s fourth line reads
//! `ω s̃` for `−ω s̃`; (38) has it right.
//!
//! # Discretization
//! Per step of length `h`, with `(v, ω)` held (the odometry of the step) and
//! the position `p⁺` measured at its end, in three parts:
//!
//! 1. rotate `(ĉ, ŝ)` by `ωh/2` (exact, unit-normalised rotation);
//! 2. correct with an implicit (backward-Euler) step of the injection,
//!    using the exact-arc chord `σ = v h sinc(ωh/2)` for `v h`:
//!    `x̂⁺ = x̂ + σ ĉₘ' + h a1 (x⁺ − x̂⁺)`, `ĉₘ' = ĉₘ + σ a4 (x⁺ − x̂⁺)`, and
//!    the same for `(ŷ, ŝ)` with `a2, a3`;
//! 3. rotate by the other `ωh/2`.
//!
//! The true pose obeys `x⁺ = x + σ cₘ` exactly (exact-arc motion), so the
//! error obeys `(1 + h a1) x̃⁺ − σ c̃ₘ' = x̃`, `σ a4 x̃⁺ + c̃ₘ' = c̃ₘ`: the
//! matrix `M = [[1 + h a1, −σ], [σ a4, 1]]` maps the new error to the old
//! one, and `|M e|²_P − |e|²_P = a4 ((2 h a1 + h² a1² + σ² a4) x̃² − 2 h a1 σ
//! x̃ c̃ + σ² c̃²) ≥ 0` with `P = diag(a4, 1)` (its discriminant is
//! `−4σ²(2 h a1 + σ² a4) < 0`). So the discrete `V` never increases, for any
//! step, gain or sign of `v`, as in continuous time; the rotations leave
//! `s̃² + c̃²` unchanged. The denominators `1 + h a1 + σ² a_i` are ≥ 1.
//!
//! # Angle convention
//! The estimate is `(ĉ, ŝ)`, not an angle: no wrapping. `θ̂ = atan2(ŝ, ĉ)`
//! in [−π, π] when needed (the paper suggests `arctan(ŝ/ĉ)`).

use crate::geometry::HeadingEstimate;
use crate::geometry::{BodyVelocity, Vec2};
use crate::math;
use crate::plausible::{GAIN, PERIOD_S};

/// Why a [`PoseObserverConfig`] was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum PoseObserverConfigError {
    /// `a1` (x injection, 1/s) outside [`GAIN`].
    A1,
    /// `a2` (y injection, 1/s) outside [`GAIN`].
    A2,
    /// `a3` (`ŝ` injection from `ỹ`, 1/m²) outside [`GAIN`].
    A3,
    /// `a4` (`ĉ` injection from `x̃`, 1/m²) outside [`GAIN`].
    A4,
    /// Control period outside [`PERIOD_S`].
    Period,
}

impl core::fmt::Display for PoseObserverConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::A1 => write!(f, "gains[0] (a1, the x injection) must be in {GAIN} 1/s"),
            Self::A2 => write!(f, "gains[1] (a2, the y injection) must be in {GAIN} 1/s"),
            Self::A3 => write!(f, "gains[2] (a3) must be in {GAIN} 1/m²"),
            Self::A4 => write!(f, "gains[3] (a4) must be in {GAIN} 1/m²"),
            Self::Period => write!(f, "period_s must be in {PERIOD_S} s"),
        }
    }
}

impl core::error::Error for PoseObserverConfigError {}

/// Validated gains and step of a [`PoseObserver`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PoseObserverConfig {
    a1_per_s: f32,
    a2_per_s: f32,
    a3_per_m2: f32,
    a4_per_m2: f32,
    period_s: f32,
}

impl PoseObserverConfig {
    /// Gains `a1, a2` (1/s), `a3, a4` (1/m²) of (37) and the step `h` (s).
    ///
    /// # Errors
    /// The first parameter outside its plausible range ([`crate::plausible`]).
    pub fn new(
        a1_per_s: f32,
        a2_per_s: f32,
        a3_per_m2: f32,
        a4_per_m2: f32,
        period_s: f32,
    ) -> Result<Self, PoseObserverConfigError> {
        let ok = |x: f32| GAIN.contains(x);
        if !ok(a1_per_s) {
            return Err(PoseObserverConfigError::A1);
        }
        if !ok(a2_per_s) {
            return Err(PoseObserverConfigError::A2);
        }
        if !ok(a3_per_m2) {
            return Err(PoseObserverConfigError::A3);
        }
        if !ok(a4_per_m2) {
            return Err(PoseObserverConfigError::A4);
        }
        if !PERIOD_S.contains(period_s) {
            return Err(PoseObserverConfigError::Period);
        }
        Ok(Self {
            a1_per_s,
            a2_per_s,
            a3_per_m2,
            a4_per_m2,
            period_s,
        })
    }

    /// The step `h`, s.
    #[must_use]
    pub fn period_s(&self) -> f32 {
        self.period_s
    }

    /// `[a1, a2, a3, a4]`.
    #[must_use]
    pub fn gains(&self) -> [f32; 4] {
        [self.a1_per_s, self.a2_per_s, self.a3_per_m2, self.a4_per_m2]
    }
}

/// The observer's state `(x̂, ŷ, ĉ, ŝ)`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PoseEstimate {
    /// `(x̂, ŷ)`, m.
    pub position: Vec2,
    /// `ĉ`, estimate of `cos θ` (not constrained to the unit circle).
    pub cos_theta: f32,
    /// `ŝ`, estimate of `sin θ`.
    pub sin_theta: f32,
}

impl PoseEstimate {
    /// `(ĉ, ŝ)` as a heading estimate (for the laws that take one).
    #[must_use]
    pub fn heading(&self) -> HeadingEstimate {
        HeadingEstimate {
            cos_theta: self.cos_theta,
            sin_theta: self.sin_theta,
        }
    }

    /// `V` of (40) against a true pose (for tests and diagnostics).
    #[must_use]
    pub fn lyapunov(&self, config: &PoseObserverConfig, position: Vec2, heading_rad: f32) -> f32 {
        let ex = position.x - self.position.x;
        let ey = position.y - self.position.y;
        let (sin_theta, cos_theta) = math::sincos(heading_rad);
        let es = sin_theta - self.sin_theta;
        let ec = cos_theta - self.cos_theta;
        0.5 * (config.a4_per_m2 * ex * ex + config.a3_per_m2 * ey * ey + es * es + ec * ec)
    }
}

/// Paper 002's Proposition 4 observer, discretized as in the module docs.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PoseObserver {
    config: PoseObserverConfig,
    estimate: PoseEstimate,
    rejected_updates: u32,
}

impl PoseObserver {
    /// An observer starting from `initial` (e.g. the first measured position
    /// and `(ĉ, ŝ) = (0, 0)`: heading unknown).
    #[must_use]
    pub fn new(config: PoseObserverConfig, initial: PoseEstimate) -> Self {
        Self {
            config,
            estimate: initial,
            rejected_updates: 0,
        }
    }

    /// The configuration.
    #[must_use]
    pub fn config(&self) -> &PoseObserverConfig {
        &self.config
    }

    /// The current estimate.
    #[must_use]
    pub fn estimate(&self) -> PoseEstimate {
        self.estimate
    }

    /// Replaces the estimate (e.g. the position at the first fix).
    pub fn reset(&mut self, estimate: PoseEstimate) {
        self.estimate = estimate;
    }

    /// Updates skipped because an input or the result was not finite.
    #[must_use]
    pub fn rejected_updates(&self) -> u32 {
        self.rejected_updates
    }

    /// One step: `body` is the `(v, ω)` held over the step, `position` the
    /// position measured at its end (m). A non-finite input or result
    /// leaves the estimate unchanged and is counted.
    pub fn update(&mut self, body: BodyVelocity, position: Vec2) {
        if !(body.is_finite() && position.is_finite()) {
            self.rejected_updates = self.rejected_updates.saturating_add(1);
            return;
        }
        let h = self.config.period_s;
        // As in the heading observer: |ωh| ≤ π bounds garbage only.
        let half_turn = math::clamp_or(
            0.5 * body.omega_rad_s * h,
            -0.5 * math::PI,
            0.5 * math::PI,
            0.0,
        );
        let (s, c) = math::unit_rotation(half_turn);
        let e = self.estimate;
        let mid = Vec2::new(e.cos_theta, e.sin_theta).rotated(c, s);
        let chord = body.v_m_s * h * math::sinc(half_turn);
        let (x, cos_mid) = implicit_injection(
            e.position.x,
            mid.x,
            position.x,
            chord,
            self.config.a1_per_s * h,
            self.config.a4_per_m2,
        );
        let (y, sin_mid) = implicit_injection(
            e.position.y,
            mid.y,
            position.y,
            chord,
            self.config.a2_per_s * h,
            self.config.a3_per_m2,
        );
        let heading = Vec2::new(cos_mid, sin_mid).rotated(c, s);
        let next = PoseEstimate {
            position: Vec2::new(x, y),
            cos_theta: heading.x,
            sin_theta: heading.y,
        };
        if next.position.is_finite() && heading.is_finite() {
            self.estimate = next;
        } else {
            self.rejected_updates = self.rejected_updates.saturating_add(1);
        }
    }
}

/// The implicit step of one channel: solves `p̂⁺ = p̂ + σ q' + k (p − p̂⁺)`,
/// `q' = q + σ a (p − p̂⁺)` for `(p̂⁺, q')`, with `k = a_p h` and `a` the
/// heading injection gain. The denominator is ≥ 1.
fn implicit_injection(
    estimate: f32,
    heading_component: f32,
    measured: f32,
    chord: f32,
    k: f32,
    a: f32,
) -> (f32, f32) {
    let stiffness = k + chord * chord * a;
    let next = (estimate + chord * heading_component + stiffness * measured) / (1.0 + stiffness);
    (next, heading_component + chord * a * (measured - next))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Pose;
    use proptest::prelude::*;

    fn config(h: f32) -> PoseObserverConfig {
        PoseObserverConfig::new(10.0, 10.0, 100.0, 100.0, h).unwrap()
    }

    #[test]
    fn refuses_bad_gains() {
        assert_eq!(
            PoseObserverConfig::new(0.0, 1.0, 1.0, 1.0, 0.01),
            Err(PoseObserverConfigError::A1)
        );
        assert_eq!(
            PoseObserverConfig::new(1.0, 1.0, 1.0, f32::NAN, 0.01),
            Err(PoseObserverConfigError::A4)
        );
        assert_eq!(
            PoseObserverConfig::new(1.0, 1.0, 1.0, 1.0, -0.01),
            Err(PoseObserverConfigError::Period)
        );
    }

    #[test]
    fn converges_on_a_circle_from_the_paper_initial_errors() {
        // Section 3.1.2: θ̃ = π/2 (s̃ = 1, c̃ = 0), x̃ = 10, ỹ = 40; v = 1.
        let h = 0.001;
        let mut obs = PoseObserver::new(
            config(h),
            PoseEstimate {
                position: Vec2::new(-10.0, -40.0),
                cos_theta: 1.0,
                sin_theta: -1.0,
            },
        );
        let mut pose = Pose::new(0.0, 0.0, 0.0);
        let body = BodyVelocity {
            v_m_s: 1.0,
            omega_rad_s: 0.5,
        };
        for _ in 0..20_000 {
            pose = pose.advance_arc(body.v_m_s * h, body.omega_rad_s * h);
            obs.update(body, pose.position);
        }
        let v = obs
            .estimate()
            .lyapunov(obs.config(), pose.position, pose.heading_rad);
        assert!(v < 1e-8, "V after 20 s: {v}");
    }

    #[test]
    fn rejects_non_finite_input() {
        let mut obs = PoseObserver::new(config(0.01), PoseEstimate::default());
        obs.update(
            BodyVelocity {
                v_m_s: f32::NAN,
                omega_rad_s: 0.0,
            },
            Vec2::ZERO,
        );
        obs.update(BodyVelocity::ZERO, Vec2::new(f32::INFINITY, 0.0));
        assert_eq!(obs.rejected_updates(), 2);
        assert_eq!(obs.estimate(), PoseEstimate::default());
    }

    proptest! {
        /// The discrete V of (40) never increases (module docs), whatever
        /// the gains, speeds (either sign) and initial errors.
        #[test]
        fn lyapunov_never_increases(
            gains in proptest::array::uniform4(0.1f32..200.0),
            v in -2.0f32..2.0, w in -2.0f32..2.0,
            x0 in -20.0f32..20.0, y0 in -20.0f32..20.0, th in -3.1f32..3.1,
            c0 in -1.0f32..1.0, s0 in -1.0f32..1.0,
        ) {
            let h = 0.01;
            let cfg = PoseObserverConfig::new(gains[0], gains[1], gains[2], gains[3], h).unwrap();
            let mut obs = PoseObserver::new(cfg, PoseEstimate {
                position: Vec2::new(x0, y0), cos_theta: c0, sin_theta: s0,
            });
            // Truth in f64 would be better; f32 exact-arc is exact to rounding.
            let mut pose = Pose::new(0.0, 0.0, th);
            let body = BodyVelocity { v_m_s: v, omega_rad_s: w };
            let mut last = obs.estimate().lyapunov(&cfg, pose.position, pose.heading_rad);
            for _ in 0..200 {
                pose = pose.advance_arc(v * h, w * h);
                obs.update(body, pose.position);
                let now = obs.estimate().lyapunov(&cfg, pose.position, pose.heading_rad);
                prop_assert!(now <= last * (1.0 + 1e-4) + 1e-5, "{last} -> {now}");
                last = now;
            }
        }

        /// Finite input gives a finite estimate.
        #[test]
        fn finite_in_finite_out(
            v in -1e3f32..1e3, w in -1e3f32..1e3,
            x in -1e4f32..1e4, y in -1e4f32..1e4,
        ) {
            let mut obs = PoseObserver::new(config(0.01), PoseEstimate::default());
            for _ in 0..10 {
                obs.update(BodyVelocity { v_m_s: v, omega_rad_s: w }, Vec2::new(x, y));
            }
            let e = obs.estimate();
            prop_assert!(e.position.is_finite() && e.cos_theta.is_finite() && e.sin_theta.is_finite());
        }
    }
}
