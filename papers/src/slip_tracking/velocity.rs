//! The adaptive velocity-based controller (5)–(7) and the gains both
//! controllers take (module docs of [`super`], "Adaptive velocity-based
//! control (5)–(7)").

use wmr_core::geometry::{BodyVelocity, Pose, WheelSpeeds};
use wmr_core::math;

use super::error::{SlipTrackingError, positive};
use super::reference::{ReferenceState, tracking_error};
use super::robot::TrackedRobot;

/// Largest slip factor the adaptation may reach (`i = 0.95`).
pub const P_MAX: f32 = 20.0;

/// Gains of (5)–(7) and (9).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SlipGains {
    k1: f32,
    k2: f32,
    k3: f32,
    pub(super) k4: f32,
    pub(super) k5: f32,
    rho: f32,
}

impl SlipGains {
    /// The paper's: `k1 = k3 = 6, k2 = 8, k4 = k5 = 4, ρ = 3`.
    pub const PAPER: Self = Self {
        k1: 6.0,
        k2: 8.0,
        k3: 6.0,
        k4: 4.0,
        k5: 4.0,
        rho: 3.0,
    };

    /// `k1, k2, k3` of (6), `k4, k5` of (9) (1/s), `ρ` of (7).
    ///
    /// # Errors
    /// [`SlipTrackingError::Gain`] unless all are finite and positive.
    pub fn new(
        k1: f32,
        k2: f32,
        k3: f32,
        k4: f32,
        k5: f32,
        rho: f32,
    ) -> Result<Self, SlipTrackingError> {
        if [k1, k2, k3, k4, k5, rho].iter().all(|&x| positive(x)) {
            Ok(Self {
                k1,
                k2,
                k3,
                k4,
                k5,
                rho,
            })
        } else {
            Err(SlipTrackingError::Gain)
        }
    }
}

/// What the velocity-based controller did this step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct VelocityControl {
    /// `ξ` (5), rad/s.
    pub wheels: WheelSpeeds,
    /// The auxiliary `(v, ω)` (6).
    pub body: BodyVelocity,
    /// `(e1, e2, e3)` (4) from the pose used.
    pub error: [f32; 3],
    /// `p̂` after this step's update (7).
    pub slip_estimate: f32,
}

/// The adaptive velocity-based controller (5)–(7).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AdaptiveVelocityController {
    pub(super) robot: TrackedRobot,
    pub(super) gains: SlipGains,
    pub(super) period_s: f32,
    pub(super) slip_estimate: f32,
    pub(super) rejected_poses: u32,
}

impl AdaptiveVelocityController {
    /// With step `period_s` (s) and `p̂(0)` (paper: 1).
    ///
    /// # Errors
    /// [`SlipTrackingError::Period`] or [`SlipTrackingError::SlipEstimate`].
    pub fn new(
        robot: TrackedRobot,
        gains: SlipGains,
        period_s: f32,
        slip_estimate: f32,
    ) -> Result<Self, SlipTrackingError> {
        if !positive(period_s) {
            return Err(SlipTrackingError::Period);
        }
        if !(slip_estimate.is_finite() && (1.0..=P_MAX).contains(&slip_estimate)) {
            return Err(SlipTrackingError::SlipEstimate);
        }
        Ok(Self {
            robot,
            gains,
            period_s,
            slip_estimate,
            rejected_poses: 0,
        })
    }

    /// `p̂`.
    #[must_use]
    pub fn slip_estimate(&self) -> f32 {
        self.slip_estimate
    }

    /// Steps given a non-finite pose or reference (they command a stop and
    /// leave `p̂` unchanged).
    #[must_use]
    pub fn rejected_poses(&self) -> u32 {
        self.rejected_poses
    }

    /// One step from the reference and the (estimated) pose.
    pub fn step(&mut self, reference: &ReferenceState, pose: &Pose) -> VelocityControl {
        let g = self.gains;
        let error = tracking_error(pose, &reference.pose);
        let [e1, e2, e3] = error;
        let (v_r, w_r) = (reference.velocity.v_m_s, reference.velocity.omega_rad_s);
        let body = BodyVelocity {
            v_m_s: v_r * math::cos(e3) + g.k1 * e1,
            omega_rad_s: w_r + v_r * g.k2 * e2 + g.k3 * math::sin(e3),
        };
        let rate = g.rho * (body.v_m_s * e1 + body.omega_rad_s * math::sin(e3) / g.k2);
        let next = (self.slip_estimate + self.period_s * rate).clamp(1.0, P_MAX);
        if !(body.is_finite() && next.is_finite()) {
            self.rejected_poses = self.rejected_poses.saturating_add(1);
            return VelocityControl {
                slip_estimate: self.slip_estimate,
                ..VelocityControl::default()
            };
        }
        let wheels = self.robot.wheels_for(body, self.slip_estimate);
        self.slip_estimate = next;
        VelocityControl {
            wheels,
            body,
            error,
            slip_estimate: next,
        }
    }
}
