//! Reduced-order observers of the robot-frame tracking error (paper 002,
//! Jakubiak, Nijmeijer & Lefeber, section 3.2): of `y_e` from `x_e, θ_e`
//! (Proposition 5, (43)–(48)); of `x_e` from `y_e, θ_e` with the controller
//! (50) (Proposition 6, (49)–(50)). Proposition 7, which a robot can run,
//! is `wmr_core::control::heading_error_sine`.
//!
//! The errors and their dynamics (30) are in `wmr_core::control::robot_frame`.
//! Each observer is given, every step, the measured errors at the step's
//! end, the `(v, ω)` the robot drove over the step and the reference at the
//! step's start; it remembers the previous measurement itself.
//!
//! # Propositions 5 and 6: innovation form
//! The paper writes these observers with `z = y_e + b(t) x_e` and
//! `b = −c_y ω` (resp. `z = x_e + b y_e`, `b = c_e ω`), which needs `ḃ` and
//! so `ω̇`. A sampled observer can use the measured change of the known
//! error directly, which is what the `z` construction stands in for: for
//! Proposition 5, with `Δx_e` measured over the step,
//!
//! ```text
//! ν   = Δx_e − h (ω ŷ_e + v_r cos θ_e − v)          (= h ω ỹ_e + O(h²))
//! ŷ_e⁺ = ŷ_e + h (−ω x_e + v_r sin θ_e) + L ν,   L = c_y ω φ(c_y ω² h)
//! ```
//!
//! with `φ(x) = (1 − e^{−x})/x`, so `ỹ_e⁺ = e^{−c_y ω² h} ỹ_e` up to the
//! `O(h²)` of the Euler prediction: exactly the decay (48),
//! `ỹ_e(t) = ỹ_e(0) e^{−c_y ∫ω²}`. Proposition 6 is the same with the roles
//! of `x_e` and `y_e` swapped (`ν = Δy_e − h(−ω x̂_e + v_r sin θ_e) = −h ω
//! x̃_e`), giving `x̃_e⁺ = e^{−c_e ω² h} x̃_e`.
//!
//! Printed slips: Proposition 5 writes `ŷ_e = ẑ_e − b(t) x` for
//! `ŷ_e = ẑ − b x_e`; (47) writes `ỹ_e(0)` for the initial estimation
//! error. In Proposition 6, (49)–(50) give `x̃̇_e = −(c2 + c_e ω²) x̃_e`, but
//! that uses the state-feedback closed loop `ẋ_e = … − c2 x_e`: with the
//! controller of (50), `v = v_r + c2 x̂_e`, the `−c2 x̂_e` term is known to
//! the observer and cancels, leaving `x̃̇_e = −c_e ω² x̃_e`. Without
//! excitation (`ω ≡ 0`) `x_e` is indeed unobservable from `y_e, θ_e`, which
//! the printed rate would contradict. The proof of Proposition 6 only needs
//! `x̃_e` to decay exponentially, which `ω_r` persistently exciting gives.
//!
//! # Angle convention
//! `θ_e` as in `wmr_core::control::robot_frame::RobotFrameError`: wrapped
//! to (−π, π].

use wmr_core::control::robot_frame::{RobotFrameError, UnicycleReference};
use wmr_core::geometry::BodyVelocity;
use wmr_core::math;

/// Why a Proposition 5 or 6 observer configuration was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum ErrorObserverConfigError {
    /// The observer gain (`c_y`, `c_e`, s) not finite and positive.
    Gain,
    /// Control period not finite and positive.
    Period,
}

impl core::fmt::Display for ErrorObserverConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::Gain => "the observer gain (c_y or c_e) must be finite and > 0 s",
            Self::Period => "period_s must be finite and > 0 s",
        })
    }
}

impl core::error::Error for ErrorObserverConfigError {}

fn positive(x: f32) -> bool {
    x.is_finite() && x > 0.0
}

/// A measurement of the errors at the start of the current step.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
struct Previous {
    error: RobotFrameError,
    reference: UnicycleReference,
}

/// Which error a [`SingleErrorObserver`] estimates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
enum Estimated {
    /// `y_e` from `x_e, θ_e` (Proposition 5).
    Lateral,
    /// `x_e` from `y_e, θ_e` (Proposition 6).
    Longitudinal,
}

/// The shared machinery of Propositions 5 and 6 (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
struct SingleErrorObserver {
    which: Estimated,
    gain_s: f32,
    period_s: f32,
    estimate_m: f32,
    previous: Option<Previous>,
    rejected_updates: u32,
}

impl SingleErrorObserver {
    fn new(
        which: Estimated,
        gain_s: f32,
        period_s: f32,
        initial_m: f32,
    ) -> Result<Self, ErrorObserverConfigError> {
        if !positive(gain_s) {
            return Err(ErrorObserverConfigError::Gain);
        }
        if !positive(period_s) {
            return Err(ErrorObserverConfigError::Period);
        }
        Ok(Self {
            which,
            gain_s,
            period_s,
            estimate_m: if initial_m.is_finite() {
                initial_m
            } else {
                0.0
            },
            previous: None,
            rejected_updates: 0,
        })
    }

    fn update(
        &mut self,
        measured: RobotFrameError,
        applied: BodyVelocity,
        reference: UnicycleReference,
    ) {
        if !(measured.is_finite() && applied.is_finite() && reference.is_finite()) {
            self.rejected_updates = self.rejected_updates.saturating_add(1);
            return;
        }
        let now = Previous {
            error: measured,
            reference,
        };
        let Some(prev) = self.previous.replace(now) else {
            return;
        };
        let h = self.period_s;
        let (w, v, vr) = (applied.omega_rad_s, applied.v_m_s, prev.reference.v_m_s);
        let e = prev.error;
        let (sin_e, cos_e) = (math::sin(e.theta_e_rad), math::cos(e.theta_e_rad));
        let k = self.gain_s * w * w * h;
        let gain = self.gain_s * w * math::one_minus_exp_neg_over_x(k);
        let next = match self.which {
            Estimated::Lateral => {
                let innovation =
                    (measured.x_e_m - e.x_e_m) - h * (w * self.estimate_m + vr * cos_e - v);
                self.estimate_m + h * (-w * e.x_e_m + vr * sin_e) + gain * innovation
            }
            Estimated::Longitudinal => {
                let innovation =
                    (measured.y_e_m - e.y_e_m) - h * (-w * self.estimate_m + vr * sin_e);
                self.estimate_m + h * (w * e.y_e_m + vr * cos_e - v) - gain * innovation
            }
        };
        if next.is_finite() {
            self.estimate_m = next;
        } else {
            self.rejected_updates = self.rejected_updates.saturating_add(1);
        }
    }
}

/// Proposition 5: the observer of `y_e` from `x_e` and `θ_e`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LateralErrorObserver(SingleErrorObserver);

impl LateralErrorObserver {
    /// Gain `c_y` (s; `b = −c_y ω`), step `h` (s), initial estimate `ŷ_e(0)` (m).
    ///
    /// # Errors
    /// [`ErrorObserverConfigError::Gain`] or [`ErrorObserverConfigError::Period`].
    pub fn new(
        c_y_s: f32,
        period_s: f32,
        initial_m: f32,
    ) -> Result<Self, ErrorObserverConfigError> {
        SingleErrorObserver::new(Estimated::Lateral, c_y_s, period_s, initial_m).map(Self)
    }

    /// One step: the errors measured now (its `y_e` is ignored), the
    /// `(v, ω)` driven over the step just ended, and the reference now.
    pub fn update(
        &mut self,
        measured: RobotFrameError,
        applied: BodyVelocity,
        reference: UnicycleReference,
    ) {
        self.0.update(measured, applied, reference);
    }

    /// `ŷ_e`, m.
    #[must_use]
    pub fn estimate_m(&self) -> f32 {
        self.0.estimate_m
    }

    /// Updates skipped for non-finite input or result.
    #[must_use]
    pub fn rejected_updates(&self) -> u32 {
        self.0.rejected_updates
    }
}

/// Proposition 6: the observer of `x_e` from `y_e` and `θ_e`; use its
/// estimate in (31) as `v = v_r + c2 x̂_e` (50).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LongitudinalErrorObserver(SingleErrorObserver);

impl LongitudinalErrorObserver {
    /// Gain `c_e` (s; `b = c_e ω`), step `h` (s), initial estimate `x̂_e(0)` (m).
    ///
    /// # Errors
    /// [`ErrorObserverConfigError::Gain`] or [`ErrorObserverConfigError::Period`].
    pub fn new(
        c_e_s: f32,
        period_s: f32,
        initial_m: f32,
    ) -> Result<Self, ErrorObserverConfigError> {
        SingleErrorObserver::new(Estimated::Longitudinal, c_e_s, period_s, initial_m).map(Self)
    }

    /// One step: the errors measured now (its `x_e` is ignored), the
    /// `(v, ω)` driven over the step just ended, and the reference now.
    pub fn update(
        &mut self,
        measured: RobotFrameError,
        applied: BodyVelocity,
        reference: UnicycleReference,
    ) {
        self.0.update(measured, applied, reference);
    }

    /// `x̂_e`, m.
    #[must_use]
    pub fn estimate_m(&self) -> f32 {
        self.0.estimate_m
    }

    /// Updates skipped for non-finite input or result.
    #[must_use]
    pub fn rejected_updates(&self) -> u32 {
        self.0.rejected_updates
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use wmr_core::control::cascaded::{CascadedController, CascadedGains};
    use wmr_core::geometry::{Pose, Vec2};

    /// A reference unicycle with constant inputs, integrated exactly.
    fn reference_at(v: f32, w: f32, t: f32) -> UnicycleReference {
        let start = Pose::new(0.0, 0.0, 0.0);
        let p = start.advance_arc(v * t, w * t);
        UnicycleReference {
            position: p.position,
            heading_rad: p.heading_rad,
            v_m_s: v,
            omega_rad_s: w,
            dv_m_s2: 0.0,
        }
    }

    #[test]
    fn lateral_observer_converges_under_the_cascaded_controller() {
        let h = 0.001;
        let ctrl = CascadedController::new(CascadedGains::new(1.0, 1.0).unwrap());
        let mut obs = LateralErrorObserver::new(1.0, h, 0.0).unwrap();
        let mut robot = Pose::new(-1.0, -2.0, 0.3);
        let mut applied = BodyVelocity::ZERO;
        let mut last = 0.0;
        for k in 0..10_000u16 {
            let r = reference_at(1.0, 1.0, f32::from(k) * h);
            let e = RobotFrameError::new(r.pose(), robot);
            obs.update(e, applied, r);
            last = (e.y_e_m - obs.estimate_m()).abs();
            applied = ctrl.command(&r, e.x_e_m, e.theta_e_rad);
            robot = robot.advance_arc(applied.v_m_s * h, applied.omega_rad_s * h);
        }
        assert!(last < 1e-3, "|ỹ_e| after 10 s: {last}");
    }

    #[test]
    fn observers_refuse_bad_gains() {
        assert_eq!(
            LongitudinalErrorObserver::new(0.0, 0.01, 0.0),
            Err(ErrorObserverConfigError::Gain)
        );
    }

    proptest! {
        /// Finite input gives finite estimates.
        #[test]
        fn finite_in_finite_out(
            xe in -1e3f32..1e3, ye in -1e3f32..1e3, th in -3.1f32..3.1,
            v in -10.0f32..10.0, w in -10.0f32..10.0, vr in -10.0f32..10.0,
        ) {
            let r = UnicycleReference { position: Vec2::ZERO, heading_rad: 0.0, v_m_s: vr, omega_rad_s: w, dv_m_s2: 1.0 };
            let e = RobotFrameError { x_e_m: xe, y_e_m: ye, theta_e_rad: th };
            let body = BodyVelocity { v_m_s: v, omega_rad_s: w };
            let mut lat = LateralErrorObserver::new(1.0, 0.01, 0.0).unwrap();
            let mut lon = LongitudinalErrorObserver::new(1.0, 0.01, 0.0).unwrap();
            for _ in 0..5 {
                lat.update(e, body, r);
                lon.update(e, body, r);
            }
            prop_assert!(lat.estimate_m().is_finite() && lon.estimate_m().is_finite());
        }
    }
}
