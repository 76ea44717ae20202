//! Paper 002 (Jakubiak, Nijmeijer & Lefeber, section 3.2), Proposition 7:
//! the observer (58) of `ψ = sin θ_e` from the robot-frame errors
//! `x_e, y_e`, with the output-feedback controller (64). (Propositions 5
//! and 6, the observers of one error from the other two, are reproduced in
//! the `wmr-papers` crate: no robot runs them.)
//!
//! The errors and their dynamics (30) are in [`crate::control::robot_frame`].
//! The observer is given, every step, the measured errors at the step's
//! end, the `(v, ω)` the robot drove over the step and the reference at the
//! step's start; it remembers the previous measurement itself.
//!
//! # Proposition 7: exact decay of `z`
//! With `z = ψ − a v_r y_e` and (30):
//! `ż = −a v_r² z + g + (ω_r − ω) cos θ_e`, `g = −a v̇_r y_e + a v_r ω x_e −
//! a² v_r³ y_e`, and the observer (58b) drops the unknown last term:
//! `ẑ⁺ = e^{−a v_r² h} ẑ + h φ(a v_r² h) g`, `ψ̂ = ẑ + a v_r y_e` (58a).
//! The error obeys `ψ̃̇ = (ω_r − ω) cos θ_e − a v_r² ψ̃`, which under (64)
//! is the second line of (61). Printed slips: (59) has `(ω − ω_r)` for
//! `(ω_r − ω)`; (65) drops the `a v_r ω x_e` term of (58b) and the minus
//! sign of `−a v_r² ẑ` (the text before (66) uses them).
//!
//! # Angle convention
//! `θ_e` as in [`crate::control::robot_frame::RobotFrameError`]: wrapped to (−π, π].
//! Proposition 7 needs `|θ_e(0)| < π` (the Lyapunov function (62) is
//! `1 − cos θ_e`), which the wrapping gives except exactly at π.

use crate::control::interface::{LawCommand, TrackingCommand, TrackingLaw};
use crate::control::robot_frame::{RobotFrameError, UnicycleReference, estimated_error};
use crate::geometry::HeadingEstimate;
use crate::geometry::{BodyVelocity, Vec2};
use crate::math;
use crate::plausible::{GAIN, PERIOD_S};
use crate::reference::ReferenceSample;

/// Why a [`HeadingErrorSineConfig`] was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum HeadingErrorSineConfigError {
    /// The observer gain `a` (s/m²) outside [`GAIN`].
    Gain,
    /// `c2` (1/s) outside [`GAIN`].
    C2,
    /// `γ` not in (0, 1).
    Gamma,
    /// Control period outside [`PERIOD_S`].
    Period,
}

impl core::fmt::Display for HeadingErrorSineConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Gain => write!(f, "a_s_per_m2 (the observer gain a) must be in {GAIN} s/m²"),
            Self::C2 => write!(f, "c2_per_s must be in {GAIN} 1/s"),
            Self::Gamma => f.write_str("gamma (γ) must be in (0, 1)"),
            Self::Period => write!(f, "period_s must be in {PERIOD_S} s"),
        }
    }
}

impl core::error::Error for HeadingErrorSineConfigError {}

/// A measurement of the errors at the start of the current step.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
struct Previous {
    error: RobotFrameError,
    reference: UnicycleReference,
}

/// Validated gains of Proposition 7's observer (65) and controller (64).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct HeadingErrorSineConfig {
    a_s_per_m2: f32,
    c2_per_s: f32,
    gamma: f32,
    period_s: f32,
}

impl HeadingErrorSineConfig {
    /// Observer gain `a` (s/m²), controller gains `c2` (1/s) and `γ ∈ (0, 1)`,
    /// step `h` (s). The paper's simulation: `a = 10, c2 = 2, γ = 0.9`.
    ///
    /// # Errors
    /// The first parameter outside its plausible range ([`crate::plausible`]).
    pub fn new(
        a_s_per_m2: f32,
        c2_per_s: f32,
        gamma: f32,
        period_s: f32,
    ) -> Result<Self, HeadingErrorSineConfigError> {
        if !GAIN.contains(a_s_per_m2) {
            return Err(HeadingErrorSineConfigError::Gain);
        }
        if !GAIN.contains(c2_per_s) {
            return Err(HeadingErrorSineConfigError::C2);
        }
        if !(gamma.is_finite() && gamma > 0.0 && gamma < 1.0) {
            return Err(HeadingErrorSineConfigError::Gamma);
        }
        if !PERIOD_S.contains(period_s) {
            return Err(HeadingErrorSineConfigError::Period);
        }
        Ok(Self {
            a_s_per_m2,
            c2_per_s,
            gamma,
            period_s,
        })
    }

    /// The step `h`, s.
    #[must_use]
    pub fn period_s(&self) -> f32 {
        self.period_s
    }
}

/// Proposition 7: the observer (58)/(65) of `ψ = sin θ_e` from `x_e, y_e`
/// and the output-feedback controller (64)
/// `v = v_r + c2 x_e`, `ω = ω_r + ½ γ a v_r² ψ̂`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct HeadingErrorSineTracker {
    config: HeadingErrorSineConfig,
    z: f32,
    psi_hat: f32,
    previous: Option<Previous>,
    rejected_updates: u32,
}

impl HeadingErrorSineTracker {
    /// A tracker whose first measurement sets `ẑ` so that `ψ̂ = psi_hat_0`
    /// (0: nothing known of the heading error).
    #[must_use]
    pub fn new(config: HeadingErrorSineConfig, psi_hat_0: f32) -> Self {
        Self {
            config,
            z: 0.0,
            psi_hat: if psi_hat_0.is_finite() {
                psi_hat_0
            } else {
                0.0
            },
            previous: None,
            rejected_updates: 0,
        }
    }

    /// `ψ̂`, the estimate of `sin θ_e`.
    #[must_use]
    pub fn psi_hat(&self) -> f32 {
        self.psi_hat
    }

    /// Updates skipped for non-finite input or result.
    #[must_use]
    pub fn rejected_updates(&self) -> u32 {
        self.rejected_updates
    }

    /// Forgets the previous measurement (after a gap in the updates, e.g.
    /// while the robot was stopped without position fixes): the next update
    /// re-anchors `ẑ` so that `ψ̂` keeps its value.
    pub fn restart(&mut self) {
        self.previous = None;
    }

    /// One step of the observer: the errors measured now (`θ_e` ignored),
    /// the `(v, ω)` driven over the step just ended, and the reference now
    /// (`v_r`, `v̇_r`).
    pub fn update(
        &mut self,
        measured: RobotFrameError,
        applied: BodyVelocity,
        reference: UnicycleReference,
    ) {
        if !(measured.is_finite() && applied.is_finite() && reference.is_finite()) {
            self.rejected_updates = self.rejected_updates.saturating_add(1);
            return;
        }
        let a = self.config.a_s_per_m2;
        let now = Previous {
            error: measured,
            reference,
        };
        let z = match self.previous.replace(now) {
            // First measurement: choose ẑ so that ψ̂ keeps its initial value.
            None => self.psi_hat - a * reference.v_m_s * measured.y_e_m,
            Some(prev) => {
                let h = self.config.period_s;
                let (vr, dvr) = (prev.reference.v_m_s, prev.reference.dv_m_s2);
                let (xe, ye) = (prev.error.x_e_m, prev.error.y_e_m);
                let g =
                    -a * dvr * ye + a * vr * applied.omega_rad_s * xe - a * a * vr * vr * vr * ye;
                let k = a * vr * vr * h;
                math::exp(-k) * self.z + h * math::one_minus_exp_neg_over_x(k) * g
            }
        };
        let psi_hat = z + a * reference.v_m_s * measured.y_e_m;
        if z.is_finite() && psi_hat.is_finite() {
            self.z = z;
            self.psi_hat = psi_hat;
        } else {
            self.rejected_updates = self.rejected_updates.saturating_add(1);
        }
    }

    /// The command (64) from the measured `x_e` and the current `ψ̂`.
    #[must_use]
    pub fn command(&self, reference: &UnicycleReference, x_e_m: f32) -> BodyVelocity {
        let c = &self.config;
        BodyVelocity {
            v_m_s: reference.v_m_s + c.c2_per_s * x_e_m,
            omega_rad_s: reference.omega_rad_s
                + 0.5 * c.gamma * c.a_s_per_m2 * reference.v_m_s * reference.v_m_s * self.psi_hat,
        }
    }
}

impl TrackingLaw for HeadingErrorSineTracker {
    /// The observer's step and (64) on the error (30) from the estimated
    /// heading ([`estimated_error`]).
    fn command(
        &mut self,
        reference: &ReferenceSample,
        position: Vec2,
        heading: HeadingEstimate,
        driven: BodyVelocity,
    ) -> LawCommand {
        match estimated_error(reference, position, heading) {
            Some((r, e)) => {
                self.update(e, driven, r);
                LawCommand::Drive(TrackingCommand {
                    body: HeadingErrorSineTracker::command(self, &r, e.x_e_m),
                    ..TrackingCommand::default()
                })
            }
            None => LawCommand::ReferenceStandstill,
        }
    }

    /// The observer's memory spans only tracked steps ([`Self::restart`]).
    fn restart(&mut self) {
        HeadingErrorSineTracker::restart(self);
    }

    fn rejected_updates(&self) -> u32 {
        HeadingErrorSineTracker::rejected_updates(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn sine_tracker_refuses_bad_gamma() {
        assert_eq!(
            HeadingErrorSineConfig::new(10.0, 2.0, 1.0, 0.01),
            Err(HeadingErrorSineConfigError::Gamma)
        );
    }

    proptest! {
        /// Finite input gives finite estimates and commands.
        #[test]
        fn finite_in_finite_out(
            xe in -1e3f32..1e3, ye in -1e3f32..1e3, th in -3.1f32..3.1,
            v in -10.0f32..10.0, w in -10.0f32..10.0, vr in -10.0f32..10.0,
        ) {
            let r = UnicycleReference { position: Vec2::ZERO, heading_rad: 0.0, v_m_s: vr, omega_rad_s: w, dv_m_s2: 1.0 };
            let e = RobotFrameError { x_e_m: xe, y_e_m: ye, theta_e_rad: th };
            let body = BodyVelocity { v_m_s: v, omega_rad_s: w };
            let mut sine = HeadingErrorSineTracker::new(HeadingErrorSineConfig::new(10.0, 2.0, 0.9, 0.01).unwrap(), 0.0);
            for _ in 0..5 {
                sine.update(e, body, r);
            }
            prop_assert!(sine.psi_hat().is_finite() && sine.command(&r, xe).is_finite());
        }
    }
}
