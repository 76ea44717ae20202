//! Reduced-order heading observer of paper 001 (Yan & Ma), eq. (5), Theorem 1.
//!
//! # The law
//! With `z3 = cos θ`, `z4 = sin θ` and the measured position `(x, y)`, the
//! paper's observer (as corrected from its proof, slip 1 of the papers'
//! README) is
//!
//! ```text
//! ζ̇3 = −ẑ4·ω − L·v·ẑ3,   ẑ3 = ζ3 + L·x,
//! ζ̇4 =  ẑ3·ω − L·v·ẑ4,   ẑ4 = ζ4 + L·y,            (5)
//! ```
//!
//! i.e. `d/dt ẑ = J·ω·ẑ − L·v·ẑ + L·ṗ` with `J` the 90° rotation. The error
//! `e = z − ẑ` then obeys `ė = (J·ω − L·v)·e` (8): it rotates with the robot
//! and shrinks at rate `L·v`, so `V_o = ½|e|²` satisfies (9)
//! `V̇_o = −2·L·v·V_o` and (10) `|e(t)| ≤ |e(0)|·e^{−v_m L t}`. The heading
//! estimate is (11) `θ̂ = atan2(ẑ4, ẑ3)`, in (−π, π].
//!
//! # Discretization (exact under zero-order hold)
//! Over one step `h` the measured `v`, `ω` are constant and the unicycle
//! drives an exact arc, so the position increment is
//! `Δp = v·S·z(t)` with `S = h·sinc(ωh/2)·R(ωh/2)`. Integrating the linear
//! ODE for `ẑ` exactly and eliminating the unknown `z(t)` through `Δp`:
//!
//! ```text
//! ẑ⁺ = d·R(ωh)·ẑ + L·φ(L v h)/sinc(ωh/2) · R(ωh/2)·Δp,
//!      d = e^{−L v h},   φ(x) = (1 − e^{−x})/x,
//! ```
//!
//! which gives exactly `e⁺ = d·R(ωh)·e`: the rotation × decay of (8) with no
//! discretization error and no step-size stability limit (a forward-Euler
//! step would need `L·v·h < 2` and distort the rotation). `φ` keeps the gain
//! finite as `v → 0`; no division by `v` appears.
//!
//! # Beyond the paper's assumption `v ≥ v_m > 0` (Assumption 3)
//! * `v < 0` (reversing, e.g. while the drive brakes): the correction uses
//!   `|v|` for the decay and `sign(v)·Δp` for the innovation, which is the
//!   same observer for the robot driving its mirror image; `e` still decays
//!   as `e^{−L|v|h}`.
//! * `|v|` below [`HeadingObserverConfig::min_speed_m_s`]: a position change
//!   says nothing reliable about heading (it is quantization noise), so the
//!   estimate only rotates with `ω` (`d = 1`, no innovation) and `|e|` is
//!   kept, not grown.
//! * Non-finite `v`, `ω` or `Δp`: the update is skipped and counted in
//!   [`HeadingObserver::rejected_updates`].
//!
//! In every case `|e⁺| ≤ |e|`: the error never grows.

use crate::geometry::{BodyVelocity, HeadingEstimate, Vec2};
use crate::math;
use crate::plausible::{GAIN, MIN_SPEED_M_S, PERIOD_S};

/// Why a [`HeadingObserverConfig`] was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum ObserverConfigError {
    /// Observer gain `L` outside [`GAIN`].
    Gain,
    /// Control period outside [`PERIOD_S`].
    Period,
    /// Minimum speed for innovation outside [`MIN_SPEED_M_S`].
    MinSpeed,
    /// Initial estimate not finite.
    InitialEstimate,
}

impl core::fmt::Display for ObserverConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Gain => write!(f, "observer_gain_per_m (L) must be in {GAIN} 1/m"),
            Self::Period => write!(f, "period_s must be in {PERIOD_S} s"),
            Self::MinSpeed => write!(f, "observer_min_speed_m_s must be in {MIN_SPEED_M_S} m/s"),
            Self::InitialEstimate => f.write_str("the initial estimate (ĉ, ŝ) must be finite"),
        }
    }
}

impl core::error::Error for ObserverConfigError {}

/// Parameters of the heading observer (validated once).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct HeadingObserverConfig {
    gain_per_m: f32,
    period_s: f32,
    min_speed_m_s: f32,
}

impl HeadingObserverConfig {
    /// Default speed below which position changes are not used, m/s.
    pub const DEFAULT_MIN_SPEED_M_S: f32 = 1.0e-3;

    /// `L` (1/m: the error decays as `e^{−L·distance}`) and the step `h` (s).
    ///
    /// # Errors
    /// The first parameter outside its plausible range ([`crate::plausible`]).
    pub fn new(gain_per_m: f32, period_s: f32) -> Result<Self, ObserverConfigError> {
        if !GAIN.contains(gain_per_m) {
            return Err(ObserverConfigError::Gain);
        }
        if !PERIOD_S.contains(period_s) {
            return Err(ObserverConfigError::Period);
        }
        Ok(Self {
            gain_per_m,
            period_s,
            min_speed_m_s: Self::DEFAULT_MIN_SPEED_M_S,
        })
    }

    /// Sets the speed below which the observer only rotates its estimate.
    ///
    /// # Errors
    /// [`ObserverConfigError::MinSpeed`] outside [`MIN_SPEED_M_S`].
    pub fn with_min_speed(mut self, min_speed_m_s: f32) -> Result<Self, ObserverConfigError> {
        if !MIN_SPEED_M_S.contains(min_speed_m_s) {
            return Err(ObserverConfigError::MinSpeed);
        }
        self.min_speed_m_s = min_speed_m_s;
        Ok(self)
    }

    /// Observer gain `L`, 1/m.
    #[must_use]
    pub fn gain_per_m(&self) -> f32 {
        self.gain_per_m
    }

    /// Control period `h`, s.
    #[must_use]
    pub fn period_s(&self) -> f32 {
        self.period_s
    }

    /// Speed below which position changes are not used, m/s.
    #[must_use]
    pub fn min_speed_m_s(&self) -> f32 {
        self.min_speed_m_s
    }
}

/// The reduced-order heading observer (paper 001, (5)), exactly discretized.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct HeadingObserver {
    config: HeadingObserverConfig,
    estimate: HeadingEstimate,
    rejected_updates: u32,
}

impl HeadingObserver {
    /// An observer starting from `ẑ = (0, 0)` ("heading unknown", as in the
    /// paper's section 6.1).
    #[must_use]
    pub fn new(config: HeadingObserverConfig) -> Self {
        Self {
            config,
            estimate: HeadingEstimate::default(),
            rejected_updates: 0,
        }
    }

    /// An observer starting from a given `ẑ(0)`.
    ///
    /// # Errors
    /// [`ObserverConfigError::InitialEstimate`] if not finite.
    pub fn with_initial_estimate(
        config: HeadingObserverConfig,
        initial: HeadingEstimate,
    ) -> Result<Self, ObserverConfigError> {
        if !(initial.cos_theta.is_finite() && initial.sin_theta.is_finite()) {
            return Err(ObserverConfigError::InitialEstimate);
        }
        Ok(Self {
            estimate: initial,
            ..Self::new(config)
        })
    }

    /// The configuration.
    #[must_use]
    pub fn config(&self) -> &HeadingObserverConfig {
        &self.config
    }

    /// The current estimate `(ẑ3, ẑ4)`.
    #[must_use]
    pub fn estimate(&self) -> HeadingEstimate {
        self.estimate
    }

    /// Sets `ẑ = (cos θ, sin θ)` for a heading `θ` known from outside
    /// (rad, counter-clockwise from +x); a non-finite one is ignored.
    pub fn assume_heading(&mut self, heading_rad: f32) {
        if heading_rad.is_finite() {
            let (sin_theta, cos_theta) = crate::math::sincos(heading_rad);
            self.estimate = HeadingEstimate {
                cos_theta,
                sin_theta,
            };
        }
    }

    /// Updates skipped because an input was not finite.
    #[must_use]
    pub fn rejected_updates(&self) -> u32 {
        self.rejected_updates
    }

    /// One step: `body` is the measured (v, ω) held over the last step, and
    /// `delta_position` the measured position change over the same step (m).
    pub fn update(&mut self, body: BodyVelocity, delta_position: Vec2) {
        if !(body.is_finite() && delta_position.is_finite()) {
            self.rejected_updates = self.rejected_updates.saturating_add(1);
            return;
        }
        let h = self.config.period_s;
        // |ωh| ≤ π keeps sinc(ωh/2) ≥ 2/π > 0; a real robot turns far slower
        // (π rad per 10 ms tick is 314 rad/s), so this only bounds garbage.
        let turn = math::clamp_or(body.omega_rad_s * h, -math::PI, math::PI, 0.0);
        let (s, c) = math::unit_rotation(turn);
        let z = Vec2::new(self.estimate.cos_theta, self.estimate.sin_theta);
        let rotated = z.rotated(c, s);

        let speed = body.v_m_s.abs();
        let next = if speed < self.config.min_speed_m_s {
            rotated
        } else {
            let x = self.config.gain_per_m * speed * h;
            let decay = math::exp(-x);
            let sign = if body.v_m_s < 0.0 { -1.0 } else { 1.0 };
            let gain = sign * self.config.gain_per_m * math::one_minus_exp_neg_over_x(x)
                / math::sinc(0.5 * turn);
            let (sh, ch) = math::unit_rotation(0.5 * turn);
            rotated.scaled(decay) + delta_position.rotated(ch, sh).scaled(gain)
        };
        if next.is_finite() {
            self.estimate = HeadingEstimate {
                cos_theta: next.x,
                sin_theta: next.y,
            };
        } else {
            self.rejected_updates = self.rejected_updates.saturating_add(1);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Pose;
    use proptest::prelude::*;

    fn run(mut pose: Pose, obs: &mut HeadingObserver, v: f32, w: f32, steps: usize) -> (Pose, f32) {
        let h = obs.config().period_s();
        let mut v_o = 0.0;
        for _ in 0..steps {
            let next = pose.advance_arc(v * h, w * h);
            obs.update(
                BodyVelocity {
                    v_m_s: v,
                    omega_rad_s: w,
                },
                next.position - pose.position,
            );
            pose = next;
            v_o = obs.estimate().lyapunov(pose.heading_rad);
        }
        (pose, v_o)
    }

    #[test]
    fn exact_decay_rate_on_an_arc() {
        // V_o(t) = V_o(0)·e^{−2 L v t} exactly (up to f32 rounding).
        let cfg = HeadingObserverConfig::new(1.0, 0.01).unwrap();
        let mut obs = HeadingObserver::new(cfg);
        let pose = Pose::new(0.0, -5.0, 1.5 * math::PI);
        let v0 = obs.estimate().lyapunov(pose.heading_rad);
        let (_, v_o) = run(pose, &mut obs, 0.2, 0.1, 500);
        let expected = v0 * libm::expf(-2.0 * 1.0 * 0.2 * 5.0);
        assert!((v_o / expected - 1.0).abs() < 1e-3, "{v_o} vs {expected}");
    }

    #[test]
    fn standing_still_keeps_the_estimate() {
        let cfg = HeadingObserverConfig::new(4.0, 0.01).unwrap();
        let mut obs = HeadingObserver::with_initial_estimate(
            cfg,
            HeadingEstimate {
                cos_theta: 0.6,
                sin_theta: 0.8,
            },
        )
        .unwrap();
        // A quantization jump of the position while v = 0 is ignored.
        obs.update(BodyVelocity::ZERO, Vec2::new(0.1, 0.0));
        assert_eq!(obs.estimate().cos_theta, 0.6);
        assert_eq!(obs.estimate().sin_theta, 0.8);
    }

    #[test]
    fn non_finite_input_is_counted_not_used() {
        let cfg = HeadingObserverConfig::new(1.0, 0.01).unwrap();
        let mut obs = HeadingObserver::new(cfg);
        obs.update(
            BodyVelocity {
                v_m_s: f32::NAN,
                omega_rad_s: 0.0,
            },
            Vec2::ZERO,
        );
        obs.update(BodyVelocity::ZERO, Vec2::new(f32::INFINITY, 0.0));
        assert_eq!(obs.rejected_updates(), 2);
        assert_eq!(obs.estimate(), HeadingEstimate::default());
    }

    #[test]
    fn config_is_validated() {
        assert_eq!(
            HeadingObserverConfig::new(0.0, 0.01),
            Err(ObserverConfigError::Gain)
        );
        assert_eq!(
            HeadingObserverConfig::new(1.0, -0.01),
            Err(ObserverConfigError::Period)
        );
        assert_eq!(
            HeadingObserverConfig::new(1.0, 0.01)
                .unwrap()
                .with_min_speed(f32::NAN),
            Err(ObserverConfigError::MinSpeed)
        );
    }

    proptest! {
        /// The error never grows, forwards or backwards, turning or not.
        #[test]
        fn observer_error_never_grows(
            gain in 0.05_f32..10.0,
            theta0 in -10.0_f32..10.0,
            z0 in (-3.0_f32..3.0, -3.0_f32..3.0),
            inputs in prop::collection::vec((-2.0_f32..2.0, -3.0_f32..3.0), 1..100),
        ) {
            let cfg = HeadingObserverConfig::new(gain, 0.01).unwrap();
            let mut obs = HeadingObserver::with_initial_estimate(
                cfg, HeadingEstimate { cos_theta: z0.0, sin_theta: z0.1 }).unwrap();
            let mut pose = Pose::new(0.0, 0.0, theta0);
            let mut err = obs.estimate().lyapunov(pose.heading_rad).sqrt();
            for (v, w) in inputs {
                let (p, _) = run(pose, &mut obs, v, w, 1);
                pose = p;
                let next = obs.estimate().lyapunov(pose.heading_rad).sqrt();
                // f32: allow a few ulps of the state's size.
                prop_assert!(next <= err + 2e-6 * (1.0 + err), "{} -> {}", err, next);
                err = next;
            }
        }
    }
}
