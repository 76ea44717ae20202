//! The cascaded controller of Panteley et al. (paper 002, Jakubiak,
//! Nijmeijer & Lefeber, section 3, eqs. (31)–(32)) on the robot-frame error
//! (30) of [`crate::control::robot_frame`].
//!
//! # Controller (31)
//! `v = v_r + c2 x_e`, `ω = ω_r + c1 θ_e`, giving the closed loop (32). It is
//! globally K-exponentially stable when `ω_r` is persistently exciting
//! (Panteley et al.; paper 002 cites it as \[9\]). No discretization: the
//! law is static, evaluated once per tick on that tick's error.
//!
//! # Angle convention
//! `θ_e` comes wrapped to (−π, π] from [`RobotFrameError`](crate::control::robot_frame::RobotFrameError)
//! (see there why), so (31) steers the short way round.

use crate::control::interface::{LawCommand, TrackingCommand, TrackingLaw};
use crate::control::robot_frame::{UnicycleReference, estimated_error};
use crate::geometry::HeadingEstimate;
use crate::geometry::{BodyVelocity, Vec2};
use crate::plausible::GAIN;
use crate::reference::ReferenceSample;

/// Why [`CascadedGains`] were refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum CascadedGainsError {
    /// `c1` (heading, 1/s) outside [`GAIN`].
    C1,
    /// `c2` (along-track, 1/s) outside [`GAIN`].
    C2,
}

impl core::fmt::Display for CascadedGainsError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::C1 => write!(f, "c1_per_s must be in {GAIN} 1/s"),
            Self::C2 => write!(f, "c2_per_s must be in {GAIN} 1/s"),
        }
    }
}

impl core::error::Error for CascadedGainsError {}

/// Gains of the cascaded controller (31).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CascadedGains {
    c1_per_s: f32,
    c2_per_s: f32,
}

impl CascadedGains {
    /// `c1` (heading error, 1/s) and `c2` (along-track error, 1/s).
    ///
    /// # Errors
    /// The first gain outside [`GAIN`].
    pub fn new(c1_per_s: f32, c2_per_s: f32) -> Result<Self, CascadedGainsError> {
        if !GAIN.contains(c1_per_s) {
            return Err(CascadedGainsError::C1);
        }
        if !GAIN.contains(c2_per_s) {
            return Err(CascadedGainsError::C2);
        }
        Ok(Self { c1_per_s, c2_per_s })
    }

    /// `c1`, 1/s.
    #[must_use]
    pub fn c1_per_s(&self) -> f32 {
        self.c1_per_s
    }

    /// `c2`, 1/s.
    #[must_use]
    pub fn c2_per_s(&self) -> f32 {
        self.c2_per_s
    }
}

/// The controller (31) of Panteley et al.: `v = v_r + c2 x_e`,
/// `ω = ω_r + c1 θ_e`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CascadedController {
    gains: CascadedGains,
}

impl CascadedController {
    /// A controller with these gains.
    #[must_use]
    pub fn new(gains: CascadedGains) -> Self {
        Self { gains }
    }

    /// The gains.
    #[must_use]
    pub fn gains(&self) -> &CascadedGains {
        &self.gains
    }

    /// The command (31); `x_e_m` may be an estimate (Proposition 6, (50)).
    #[must_use]
    pub fn command(
        &self,
        reference: &UnicycleReference,
        x_e_m: f32,
        theta_e_rad: f32,
    ) -> BodyVelocity {
        BodyVelocity {
            v_m_s: reference.v_m_s + self.gains.c2_per_s * x_e_m,
            omega_rad_s: reference.omega_rad_s + self.gains.c1_per_s * theta_e_rad,
        }
    }
}

impl TrackingLaw for CascadedController {
    /// (31) on the error (30) from the estimated heading
    /// ([`estimated_error`]).
    fn command(
        &mut self,
        reference: &ReferenceSample,
        position: Vec2,
        heading: HeadingEstimate,
        _driven: BodyVelocity,
    ) -> LawCommand {
        match estimated_error(reference, position, heading) {
            Some((r, e)) => LawCommand::Drive(TrackingCommand {
                body: CascadedController::command(self, &r, e.x_e_m, e.theta_e_rad),
                ..TrackingCommand::default()
            }),
            None => LawCommand::ReferenceStandstill,
        }
    }

    /// Memoryless: nothing to forget.
    fn restart(&mut self) {}

    fn rejected_updates(&self) -> u32 {
        0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::robot_frame::RobotFrameError;
    use crate::geometry::Pose;
    use crate::reference::{Circle, Trajectory};

    /// The closed loop (32) under (31) converges on a circle (ω_r PE).
    #[test]
    fn closed_loop_converges_on_a_circle() {
        let h = 0.01;
        let ctrl = CascadedController::new(CascadedGains::new(1.0, 1.0).unwrap());
        let circle: Trajectory = Circle::new(Vec2::ZERO, 1.0, 1.0, 0.0).unwrap().into();
        let mut robot = Pose::new(3.0, -2.0, 2.0);
        for k in 0..3000u16 {
            let r = UnicycleReference::from_sample(&circle.sample(f32::from(k) * h)).unwrap();
            let e = RobotFrameError::new(r.pose(), robot);
            let cmd = ctrl.command(&r, e.x_e_m, e.theta_e_rad);
            robot = robot.advance_arc(cmd.v_m_s * h, cmd.omega_rad_s * h);
        }
        let r = UnicycleReference::from_sample(&circle.sample(30.0)).unwrap();
        let e = RobotFrameError::new(r.pose(), robot);
        assert!(e.distance_m() < 1e-3 && e.theta_e_rad.abs() < 1e-3, "{e:?}");
    }
}
