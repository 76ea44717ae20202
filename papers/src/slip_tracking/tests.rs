use nalgebra::Vector2;
use wmr_core::geometry::{BodyVelocity, Pose, Vec2, WheelSpeeds};

use super::*;

#[test]
fn slip_factor_and_kinematics() {
    assert_eq!(slip_factor(0.0), Some(1.0));
    assert!((slip_factor(0.25).unwrap() - 4.0 / 3.0).abs() < 1e-6);
    assert_eq!(slip_factor(1.0), None);
    assert_eq!(slip_factor(-0.1), None);
    let robot = TrackedRobot::PAPER;
    let body = BodyVelocity {
        v_m_s: 0.5,
        omega_rad_s: -0.4,
    };
    let p = 4.0 / 3.0;
    let back = robot.body_velocity(robot.wheels_for(body, p), p);
    assert!((back.v_m_s - 0.5).abs() < 1e-6 && (back.omega_rad_s + 0.4).abs() < 1e-6);
    // Underestimating the slip slows the robot by p̂/p.
    let slow = robot.body_velocity(robot.wheels_for(body, 1.0), p);
    assert!((slow.v_m_s - 0.5 * 0.75).abs() < 1e-6);
    // (8) inverts (2) when p̂ = p.
    let u = Vector2::new(1.5, -0.5);
    let a = robot.wheel_acceleration(robot.torque_for(u, p), p);
    assert!((a - u).amax() < 1e-5, "{a}");
    assert!(TrackedRobot::new(0.35, 0.0, 0.8, 0.06).is_err());
}

#[test]
fn paper_reference_is_continuous_and_exact() {
    let reference = PiecewiseReference::<4>::paper().unwrap();
    let at = |t: f32| reference.sample(t);
    // 15 s straight at 0.5 m/s.
    let p = at(15.0).pose;
    assert!((p.position.x - 7.5).abs() < 1e-5 && p.position.y.abs() < 1e-6);
    // Continuous across each switch.
    for t in [15.0_f32, 33.0, 51.0] {
        let (a, b) = (at(t - 1e-3).pose, at(t).pose);
        assert!((a.position - b.position).norm() < 1e-3, "{t}");
    }
    // A full circle of radius 0.5/0.4 m at −0.4 rad/s from 15 s comes
    // back to (7.5, 0) after 2π/0.4 s.
    let back = at(15.0 + core::f32::consts::TAU / 0.4).pose;
    assert!(
        (back.position - Vec2::new(7.5, 0.0)).norm() < 1e-3,
        "{back:?}"
    );
    assert_eq!(at(40.0).velocity.omega_rad_s, 0.4);
    assert!(
        PiecewiseReference::new(
            Pose::new(0.0, 0.0, 0.0),
            [ReferenceSegment {
                start_s: 1.0,
                v_m_s: 0.5,
                omega_rad_s: 0.0
            }]
        )
        .is_err()
    );
}

#[test]
fn tracking_error_is_in_the_robot_frame() {
    let pose = Pose::new(1.0, 1.0, core::f32::consts::FRAC_PI_2);
    // Reference 2 m ahead of the robot (along +y), heading π.
    let e = tracking_error(&pose, &Pose::new(1.0, 3.0, core::f32::consts::PI));
    assert!((e[0] - 2.0).abs() < 1e-6 && e[1].abs() < 1e-6);
    assert!((e[2] - core::f32::consts::FRAC_PI_2).abs() < 1e-6);
}

#[test]
fn controller_validates_and_rejects_bad_poses() {
    let robot = TrackedRobot::PAPER;
    assert_eq!(
        AdaptiveVelocityController::new(robot, SlipGains::PAPER, 0.0, 1.0),
        Err(SlipTrackingError::Period)
    );
    assert_eq!(
        AdaptiveVelocityController::new(robot, SlipGains::PAPER, 0.005, 0.5),
        Err(SlipTrackingError::SlipEstimate)
    );
    assert_eq!(
        SlipGains::new(6.0, 8.0, 6.0, 4.0, 4.0, f32::NAN),
        Err(SlipTrackingError::Gain)
    );
    let mut c = AdaptiveVelocityController::new(robot, SlipGains::PAPER, 0.005, 1.0).unwrap();
    let reference = PiecewiseReference::<4>::paper().unwrap().sample(1.0);
    let out = c.step(&reference, &Pose::new(f32::NAN, 0.0, 0.0));
    assert_eq!(out.wheels, WheelSpeeds::default());
    assert_eq!(c.rejected_poses(), 1);
    assert_eq!(c.slip_estimate(), 1.0);
    // Far behind the reference, p̂ moves but stays in [1, P_MAX].
    for _ in 0..10_000 {
        let out = c.step(&reference, &Pose::new(-100.0, 50.0, 3.0));
        assert!((1.0..=P_MAX).contains(&out.slip_estimate));
    }
}
