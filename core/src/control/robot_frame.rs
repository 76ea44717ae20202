//! The tracking error in the robot's frame (paper 002, Jakubiak, Nijmeijer
//! & Lefeber, section 3, eq. (30)) and the reference as a unicycle, shared
//! by the laws that work on that error ([`crate::control::cascaded`],
//! [`crate::control::heading_error_sine`]).
//!
//! # Error (30)
//! ```text
//! [x_e]   [ cos θ  sin θ  0] [x_r − x]
//! [y_e] = [−sin θ  cos θ  0] [y_r − y]
//! [θ_e]   [   0      0    1] [θ_r − θ]
//! ẋ_e = ω y_e + v_r cos θ_e − v,  ẏ_e = −ω x_e + v_r sin θ_e,  θ̇_e = ω_r − ω
//! ```
//! `x_e` is the reference ahead of the robot, `y_e` to its left.
//!
//! # Angle convention
//! `θ_e` is wrapped to (−π, π]: the reference's and the robot's headings
//! are integrated angles with arbitrary turns, and (31) must steer the short
//! way round. The paper's closed loop (32) has `θ̇_e = −c1 θ_e` for the unwrapped
//! difference; the wrapped one obeys the same equation between wraps, and a
//! wrap only happens at `|θ_e| = π`, where `−c1 θ_e` points inward from both
//! sides.
//!
//! # The reference as unicycle inputs
//! A [`ReferenceSample`] gives position, velocity and acceleration; the
//! unicycle that follows it has `θ_r = atan2(ẏ_r, ẋ_r)`, `v_r = |ṗ_r|`,
//! `ω_r = (ẋ_r ÿ_r − ẏ_r ẍ_r)/v_r²` and `v̇_r = (ẋ_r ẍ_r + ẏ_r ÿ_r)/v_r`,
//! defined while `v_r > 0` ([`UnicycleReference::from_sample`]).

use crate::geometry::HeadingEstimate;
use crate::geometry::{Pose, Vec2};
use crate::math;
use crate::reference::ReferenceSample;

/// The reference as a unicycle: pose and inputs at one time.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct UnicycleReference {
    /// `(x_r, y_r)`, m.
    pub position: Vec2,
    /// `θ_r`, rad (any value; differences are wrapped where used).
    pub heading_rad: f32,
    /// `v_r`, m/s.
    pub v_m_s: f32,
    /// `ω_r`, rad/s.
    pub omega_rad_s: f32,
    /// `v̇_r`, m/s² (needed by the observer of Proposition 7).
    pub dv_m_s2: f32,
}

impl UnicycleReference {
    /// Below this reference speed (m/s) the heading and `ω_r` of a
    /// position-only reference are undefined.
    pub const MIN_SPEED_M_S: f32 = 1.0e-6;

    /// The unicycle inputs of a reference sample; `None` where the
    /// reference stands still (its heading is undefined there).
    #[must_use]
    pub fn from_sample(sample: &ReferenceSample) -> Option<Self> {
        let (vel, acc) = (sample.velocity, sample.acceleration);
        let speed = vel.norm();
        if !(speed.is_finite() && speed > Self::MIN_SPEED_M_S && acc.is_finite()) {
            return None;
        }
        Some(Self {
            position: sample.position,
            heading_rad: math::atan2(vel.y, vel.x),
            v_m_s: speed,
            omega_rad_s: (vel.x * acc.y - vel.y * acc.x) / (speed * speed),
            dv_m_s2: (vel.x * acc.x + vel.y * acc.y) / speed,
        })
    }

    /// The reference pose.
    #[must_use]
    pub fn pose(&self) -> Pose {
        Pose {
            position: self.position,
            heading_rad: self.heading_rad,
        }
    }

    /// All fields finite.
    #[must_use]
    pub fn is_finite(&self) -> bool {
        self.position.is_finite()
            && self.heading_rad.is_finite()
            && self.v_m_s.is_finite()
            && self.omega_rad_s.is_finite()
            && self.dv_m_s2.is_finite()
    }
}

/// The tracking error (30) in the robot's frame.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RobotFrameError {
    /// `x_e`, m: the reference ahead of the robot.
    pub x_e_m: f32,
    /// `y_e`, m: the reference to the robot's left.
    pub y_e_m: f32,
    /// `θ_e = θ_r − θ` wrapped to (−π, π], rad.
    pub theta_e_rad: f32,
}

impl RobotFrameError {
    /// The error (30) of `robot` against `reference`.
    #[must_use]
    pub fn new(reference: Pose, robot: Pose) -> Self {
        let (s, c) = math::sincos(robot.heading_rad);
        Self::with_heading(reference, robot.position, c, s, robot.heading_rad)
    }

    /// The error (30) with the robot's heading given as `(cos θ, sin θ)`
    /// and angle `θ` (e.g. an observer's estimate).
    #[must_use]
    pub fn with_heading(
        reference: Pose,
        position: Vec2,
        cos_theta: f32,
        sin_theta: f32,
        theta_rad: f32,
    ) -> Self {
        let d = reference.position - position;
        Self {
            x_e_m: cos_theta * d.x + sin_theta * d.y,
            y_e_m: -sin_theta * d.x + cos_theta * d.y,
            theta_e_rad: math::wrap_angle(reference.heading_rad - theta_rad),
        }
    }

    /// `|(x_e, y_e)|`, m: the position error (frame-independent).
    #[must_use]
    pub fn distance_m(&self) -> f32 {
        math::hypot(self.x_e_m, self.y_e_m)
    }

    /// All fields finite.
    #[must_use]
    pub fn is_finite(&self) -> bool {
        self.x_e_m.is_finite() && self.y_e_m.is_finite() && self.theta_e_rad.is_finite()
    }
}

/// The reference as a unicycle and the error (30) from an estimated heading
/// `(ĉ, ŝ)` (normalised; `θ̂ = 0` while the estimate is still `(0, 0)`),
/// as paper 002's laws use them on a robot that does not measure its
/// heading; `None` where the reference stands still (its heading is
/// undefined).
#[must_use]
pub fn estimated_error(
    reference: &ReferenceSample,
    position: Vec2,
    heading: HeadingEstimate,
) -> Option<(UnicycleReference, RobotFrameError)> {
    let r = UnicycleReference::from_sample(reference)?;
    let norm = math::hypot(heading.cos_theta, heading.sin_theta);
    let (c, s) = if norm > 1.0e-6 {
        (heading.cos_theta / norm, heading.sin_theta / norm)
    } else {
        (1.0, 0.0)
    };
    let theta = math::atan2(s, c);
    Some((
        r,
        RobotFrameError::with_heading(r.pose(), position, c, s, theta),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::{Circle, Trajectory};
    use proptest::prelude::*;

    #[test]
    fn reference_inputs_of_a_circle() {
        // Radius 2 m at 0.5 rad/s: v_r = 1 m/s, ω_r = 0.5 rad/s, v̇_r = 0.
        let circle: Trajectory = Circle::new(Vec2::ZERO, 2.0, 0.5, 0.0).unwrap().into();
        let r = UnicycleReference::from_sample(&circle.sample(1.0)).unwrap();
        assert!((r.v_m_s - 1.0).abs() < 1e-5);
        assert!((r.omega_rad_s - 0.5).abs() < 1e-5);
        assert!(r.dv_m_s2.abs() < 1e-5);
        assert!(
            UnicycleReference::from_sample(&ReferenceSample::default()).is_none(),
            "a standing reference has no heading"
        );
    }

    #[test]
    fn error_is_in_the_robot_frame() {
        // Robot at the origin facing +y; reference 1 m ahead, heading +y.
        let robot = Pose::new(0.0, 0.0, 0.5 * math::PI);
        let reference = Pose::new(0.0, 1.0, 0.5 * math::PI + 2.0 * math::TAU);
        let e = RobotFrameError::new(reference, robot);
        assert!(
            (e.x_e_m - 1.0).abs() < 1e-6 && e.y_e_m.abs() < 1e-6,
            "{e:?}"
        );
        assert!(e.theta_e_rad.abs() < 1e-5, "turns are wrapped away: {e:?}");
    }

    proptest! {
        /// `|(x_e, y_e)|` is the world-frame distance, whatever the heading.
        #[test]
        fn rotation_keeps_the_distance(
            x in -100.0f32..100.0, y in -100.0f32..100.0, th in -10.0f32..10.0,
            xr in -100.0f32..100.0, yr in -100.0f32..100.0, thr in -10.0f32..10.0,
        ) {
            let e = RobotFrameError::new(Pose::new(xr, yr, thr), Pose::new(x, y, th));
            let d = math::hypot(xr - x, yr - y);
            prop_assert!((e.distance_m() - d).abs() <= 1e-4 * (1.0 + d));
            prop_assert!(e.theta_e_rad > -math::PI - 1e-6 && e.theta_e_rad <= math::PI + 1e-6);
        }
    }
}
