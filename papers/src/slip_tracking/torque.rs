//! The adaptive torque-based controller (8)–(10), around the
//! velocity-based one (module docs of [`super`], "Adaptive torque-based
//! control (8)–(10)").

use nalgebra::Vector2;

use wmr_core::geometry::{Pose, WheelSpeeds};

use super::reference::ReferenceState;
use super::velocity::{AdaptiveVelocityController, VelocityControl};

/// What the torque-based controller did this step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TorqueControl {
    /// `(τ_L, τ_R)` (8), N·m.
    pub torque: [f32; 2],
    /// The velocity part: `ξ_d` (10), `(v, ω)`, the error, `p̂`.
    pub velocity: VelocityControl,
}

/// The adaptive torque-based controller (8)–(10).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AdaptiveTorqueController {
    velocity: AdaptiveVelocityController,
    last_desired: Option<WheelSpeeds>,
}

impl AdaptiveTorqueController {
    /// Around a velocity controller (its gains hold `k4, k5`).
    #[must_use]
    pub fn new(velocity: AdaptiveVelocityController) -> Self {
        Self {
            velocity,
            last_desired: None,
        }
    }

    /// `p̂`.
    #[must_use]
    pub fn slip_estimate(&self) -> f32 {
        self.velocity.slip_estimate
    }

    /// One step from the reference, the (estimated) pose and wheel speeds.
    pub fn step(
        &mut self,
        reference: &ReferenceState,
        pose: &Pose,
        wheels: WheelSpeeds,
    ) -> TorqueControl {
        let p_hat = self.velocity.slip_estimate;
        let velocity = self.velocity.step(reference, pose);
        let desired = velocity.wheels;
        let h = self.velocity.period_s;
        let g = self.velocity.gains;
        let robot = self.velocity.robot;
        let rate = self.last_desired.map_or(Vector2::zeros(), |last| {
            Vector2::new(
                (desired.left_rad_s - last.left_rad_s) / h,
                (desired.right_rad_s - last.right_rad_s) / h,
            )
        });
        let u = rate
            + Vector2::new(
                g.k4 * (desired.left_rad_s - wheels.left_rad_s),
                g.k5 * (desired.right_rad_s - wheels.right_rad_s),
            );
        let torque = robot.torque_for(u, p_hat);
        if !(torque.iter().all(|x| x.is_finite()) && velocity.body.is_finite()) {
            self.velocity.rejected_poses = self.velocity.rejected_poses.saturating_add(1);
            self.last_desired = None;
            return TorqueControl {
                torque: [0.0; 2],
                velocity,
            };
        }
        self.last_desired = Some(desired);
        TorqueControl {
            torque: [torque.x, torque.y],
            velocity,
        }
    }
}
