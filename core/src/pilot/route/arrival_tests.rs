//! The route's clock and arrivals: the clock waits for a robot lagging the
//! moving reference (and only for one lagging it), a stop reached short is
//! approached, a first route as given starts with an approach to its first
//! waypoint, an approach that cannot arrive times out, and a known start
//! heading reaches the estimator.

use super::tests::{EAST, Run, limits, observer_001, pose_observer, tracker};
use super::*;
use crate::geometry::Pose;
use crate::odometry::OdometryStep;
use crate::pilot::tracker::TagFix;
use core::f32::consts::FRAC_PI_2;

/// Two stops 1 m apart along +x.
fn leg() -> Waypoints {
    Waypoints::from_slice(&[Waypoint::stop(0.0, 0.0, 0.0), Waypoint::stop(1.0, 0.0, 0.0)]).unwrap()
}

fn fix(position: Vec2) -> Option<TagFix> {
    Some(TagFix {
        position,
        age_ticks: 0,
    })
}

/// A robot that does not move (its fix stays at the start) is waited for:
/// the reference leaves it and stops `max_lag_m` ahead, the clock counting
/// the ticks it waits. The same robot held 10 cm beside the first leg is
/// not waited for: a robot that keeps 10 cm beside the moving reference
/// is not waited for (waiting would not bring it closer).
#[test]
fn the_clock_waits_only_for_a_robot_that_lags() {
    let still = OdometryStep::default();
    let mut follower = RouteFollower::new(RouteOptions::default());
    let mut t = tracker(pose_observer(), EAST);
    follower.load(&leg(), &limits(), RouteStart::AsGiven);
    let mut ahead = 0.0_f32;
    for _ in 0..500 {
        let out = t.step_route(&still, fix(Vec2::ZERO), &mut follower);
        ahead = ahead.max(out.reference.position.x);
    }
    let max_lag = RouteOptions::DEFAULT_MAX_LAG_M;
    // Ahead by the lag and at most one tick's advance at the speed reached.
    assert!(ahead > max_lag && ahead < max_lag + 0.01, "{ahead}");
    let waited = follower.counters().clock_wait_ticks;
    assert!(waited > 400, "{waited}");
    assert!(follower.status().elapsed_ticks < 100);

    let mut follower = RouteFollower::new(RouteOptions::default());
    let mut t = tracker(pose_observer(), EAST);
    // Started on the first waypoint (no approach), then kept beside.
    follower.load(&leg(), &limits(), RouteStart::FromFirstFix);
    let mut reference = t
        .step_route(&still, fix(Vec2::ZERO), &mut follower)
        .reference;
    for _ in 0..300 {
        let beside = reference.position + Vec2::new(0.0, 0.1);
        reference = t.step_route(&still, fix(beside), &mut follower).reference;
    }
    assert_eq!(follower.counters().clock_wait_ticks, 0);
    assert_eq!(follower.status().elapsed_ticks, 301);
}

/// A robot that drives 10 % slower than commanded (and knows it only from
/// the fixes) reaches each stop of a leg short and is driven onto it: the
/// clock stands during the approach, and the robot settles within a
/// quarter of the 1 cm tolerance of the truth (exact fixes, no cross-track
/// error on a straight leg).
#[test]
fn a_stop_reached_short_is_approached() {
    let mut run = Run::new(tracker(pose_observer(), EAST), Pose::new(0.0, 0.0, 0.0));
    run.drive_scale = 0.9;
    run.route.load(&leg(), &limits(), RouteStart::AsGiven);
    let ticks = run.until_done(0.0, 5_000, 10);
    let last = ticks.last().unwrap();
    assert!(last.status.done);
    let c = run.route.counters();
    assert!(c.approach_ticks > 0 && c.approach_timeouts == 0, "{c:?}");
    let error = (last.robot.position - Vec2::new(1.0, 0.0)).norm();
    let bound = 0.25 * RouteOptions::DEFAULT_POSITION_TOLERANCE_M;
    assert!(error <= bound * 1.01, "{error}");
    assert_eq!(c.stop_errors, 0);
    // The clock stood while approaching: the route took longer than its plan.
    let planned = run.route.plan().duration_ticks() as usize;
    let done_at = ticks.iter().position(|t| t.status.done).unwrap();
    assert!(done_at > planned, "{done_at} {planned}");
}

/// A first route as given, the robot 15 cm from its first waypoint (facing
/// it sideways), is started by driving the robot onto the waypoint (it
/// backs onto it, the smaller turn): the route's clock stands at 0 until it
/// has arrived.
#[test]
fn a_first_route_as_given_starts_on_its_first_waypoint() {
    let mut run = Run::new(
        tracker(
            pose_observer(),
            HeadingEstimate {
                cos_theta: 0.0,
                sin_theta: 1.0,
            },
        ),
        Pose::new(-0.15, 0.05, FRAC_PI_2),
    );
    run.route.load(&leg(), &limits(), RouteStart::AsGiven);
    let mut arrived_at = None;
    for k in 0..2_000 {
        let t = run.tick(Some(run.robot.position));
        if t.status.elapsed_ticks > 0 {
            arrived_at = Some((k, run.robot.position));
            break;
        }
        assert!(t.out.command.v_m_s.abs() <= RouteOptions::DEFAULT_APPROACH_SPEED_M_S);
    }
    let (k, at) = arrived_at.expect("never arrived");
    assert!(k > 300, "an approach of 15 cm at 5 cm/s takes seconds: {k}");
    assert_eq!(run.route.counters().approach_timeouts, 0);
    let bound = (0.25_f32.hypot(0.5)) * RouteOptions::DEFAULT_POSITION_TOLERANCE_M;
    assert!(at.norm() <= bound, "{at:?}");
    let done = run.until_done(0.0, 5_000, 1);
    assert!(done.last().unwrap().status.done);
}

/// A robot that cannot move does not hold the route forever: its approach
/// ends at `approach_timeout_s`, counted, and the route goes on.
#[test]
fn an_approach_that_cannot_arrive_times_out() {
    let spec = RouteOptionsSpec {
        approach_timeout_s: 1.0,
        ..RouteOptions::default().spec()
    };
    let mut run = Run::new(tracker(pose_observer(), EAST), Pose::new(-0.2, 0.0, 0.0));
    run.route = RouteFollower::new(spec.build().unwrap());
    run.drive_scale = 0.0;
    run.route.load(&leg(), &limits(), RouteStart::AsGiven);
    let mut started = None;
    for k in 0..300 {
        let t = run.tick(Some(run.robot.position));
        if t.status.elapsed_ticks > 0 {
            started = Some(k);
            break;
        }
    }
    assert_eq!(started, Some(100), "1 s of approach at 100 Hz");
    assert_eq!(run.route.counters().approach_timeouts, 1);
}

/// With `AsGivenHeadingKnown` the estimator takes the heading the route
/// assumes at its first waypoint when the route starts: the first leg's
/// direction, or the first waypoint's heading to face. Paper 001's
/// observer starts at `(0, 0)` (no heading) and has it at the first tick.
#[test]
fn a_known_start_heading_reaches_the_estimator() {
    let north_leg =
        Waypoints::from_slice(&[Waypoint::stop(0.0, 0.0, 0.0), Waypoint::stop(0.0, 1.0, 0.0)])
            .unwrap();
    let facing_west = Waypoints::from_slice(&[
        Waypoint::stop(0.0, 0.0, 0.0).facing(core::f32::consts::PI),
        Waypoint::stop(0.0, 1.0, 0.0),
    ])
    .unwrap();
    for (waypoints, expected) in [(north_leg, FRAC_PI_2), (facing_west, core::f32::consts::PI)] {
        for start in [RouteStart::AsGiven, RouteStart::AsGivenHeadingKnown] {
            let mut follower = RouteFollower::new(RouteOptions::default());
            let mut t = tracker(observer_001(), HeadingEstimate::default());
            follower.load(&waypoints, &limits(), start);
            let out = t.step_route(&OdometryStep::default(), fix(Vec2::ZERO), &mut follower);
            let h = out.heading;
            if start == RouteStart::AsGiven {
                assert_eq!(h, HeadingEstimate::default(), "not told");
            } else {
                let error = crate::math::wrap_angle(h.heading_rad() - expected).abs();
                assert!(
                    error < 1e-6 && h.cos_theta.hypot(h.sin_theta) > 0.999,
                    "{h:?}"
                );
            }
        }
    }
}
