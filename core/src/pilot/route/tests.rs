//! A route followed in closed loop by a unicycle (the odometry is the
//! command, driven exactly): stops, pivots, the end, paper 001's observer,
//! a replacement's continuity, the start from the first fix, refusals.

use super::*;
use crate::control::LawChoice;
use crate::control::saturated::TrackingGains;
use crate::estimation::EstimatorChoice;
use crate::estimation::heading_observer::HeadingObserverConfig;
use crate::estimation::pose_observer::PoseObserverConfig;
use crate::geometry::Pose;
use crate::odometry::OdometryStep;
use crate::pilot::tracker::{
    OutputFeedbackTracker, TagFix, TrackerConfig, TrackerMode, TrackerOutput,
};
use crate::reference::StraightLine;
use crate::reference::route::{RouteLimitsSpec, Waypoint};
use core::f32::consts::FRAC_PI_2;
use std::vec::Vec;

pub(super) const H: f32 = 0.01;

pub(super) fn limits() -> RouteLimits {
    RouteLimits::new(&RouteLimitsSpec {
        max_speed_m_s: 0.3,
        max_tangential_accel_m_s2: 0.5,
        max_lateral_accel_m_s2: 0.8,
        blend_deviation_m: 0.05,
        pivot_threshold_rad: 0.5,
        pivot_rate_rad_s: 1.0,
        pivot_accel_rad_s2: 2.0,
    })
    .unwrap()
}

pub(super) fn tracker(
    estimator: EstimatorChoice,
    initial: HeadingEstimate,
) -> OutputFeedbackTracker {
    // The trajectory is not used on a route: any valid one.
    let line = StraightLine::new(Vec2::ZERO, 0.0, 0.2).unwrap();
    let config = TrackerConfig::new(
        estimator,
        LawChoice::Saturated(TrackingGains::new(0.5, 0.5, 2.0).unwrap()),
        line.into(),
        10,
    )
    .unwrap();
    OutputFeedbackTracker::with_initial_heading(config, initial).unwrap()
}

pub(super) fn pose_observer() -> EstimatorChoice {
    EstimatorChoice::PoseObserver(PoseObserverConfig::new(5.0, 5.0, 20.0, 20.0, H).unwrap())
}

pub(super) fn observer_001() -> EstimatorChoice {
    EstimatorChoice::HeadingObserver(HeadingObserverConfig::new(5.0, H).unwrap())
}

pub(super) const EAST: HeadingEstimate = HeadingEstimate {
    cos_theta: 1.0,
    sin_theta: 0.0,
};

/// A 1 m square from the origin, counter-clockwise: three stops (each a
/// 90° pivot to the next leg, then 0.5 s at rest), back at the origin
/// facing north (another 90° pivot).
fn square() -> Waypoints {
    Waypoints::from_slice(&[
        Waypoint::stop(0.0, 0.0, 0.0),
        Waypoint::stop(1.0, 0.0, 0.5),
        Waypoint::stop(1.0, 1.0, 0.5),
        Waypoint::stop(0.0, 1.0, 0.5),
        Waypoint::stop(0.0, 0.0, 0.5).facing(FRAC_PI_2),
    ])
    .unwrap()
}

/// One tick's record.
#[derive(Clone, Copy)]
pub(super) struct Tick {
    pub(super) out: TrackerOutput,
    /// The robot after driving this tick's command.
    pub(super) robot: Pose,
    pub(super) status: RouteStatus,
}

/// A closed loop: the tracker on `route`, a fix each tick (`fix_of` the
/// true position; `None`: no fix), the unicycle driving the command
/// exactly. `each` may load a route before a tick.
/// The robot drives `drive_scale` times the commanded speed (1: exactly;
/// the odometry measures what it drove).
pub(super) struct Run {
    pub(super) tracker: OutputFeedbackTracker,
    pub(super) route: RouteFollower,
    pub(super) robot: Pose,
    odometry: OdometryStep,
    pub(super) drive_scale: f32,
}

impl Run {
    pub(super) fn new(tracker: OutputFeedbackTracker, robot: Pose) -> Self {
        Self {
            tracker,
            route: RouteFollower::new(RouteOptions::default()),
            robot,
            odometry: OdometryStep::default(),
            drive_scale: 1.0,
        }
    }

    pub(super) fn tick(&mut self, fix: Option<Vec2>) -> Tick {
        let fix = fix.map(|position| TagFix {
            position,
            age_ticks: 0,
        });
        let out = self
            .tracker
            .step_route(&self.odometry, fix, &mut self.route);
        let c = BodyVelocity {
            v_m_s: out.command.v_m_s * self.drive_scale,
            omega_rad_s: out.command.omega_rad_s,
        };
        self.odometry = OdometryStep {
            ds_m: c.v_m_s * H,
            dtheta_rad: c.omega_rad_s * H,
            body: c,
            ..OdometryStep::default()
        };
        self.robot = self.robot.advance_arc(c.v_m_s * H, c.omega_rad_s * H);
        Tick {
            out,
            robot: self.robot,
            status: self.route.status(),
        }
    }

    /// Ticks until the route is done (and `extra` more), at most `max`.
    pub(super) fn until_done(&mut self, quantum_m: f32, max: usize, extra: usize) -> Vec<Tick> {
        let mut ticks = Vec::new();
        let mut after = 0;
        for _ in 0..max {
            let fix = quantized(self.robot.position, quantum_m);
            let t = self.tick(Some(fix));
            ticks.push(t);
            if t.status.done {
                after += 1;
                if after > extra {
                    break;
                }
            }
        }
        ticks
    }
}

pub(super) fn quantized(p: Vec2, quantum_m: f32) -> Vec2 {
    if quantum_m == 0.0 {
        return p;
    }
    Vec2::new(
        (p.x / quantum_m).round() * quantum_m,
        (p.y / quantum_m).round() * quantum_m,
    )
}

fn wrap(a: f32) -> f32 {
    crate::math::wrap_angle(a)
}

/// What a run of the square says: each stop's true errors at its settle,
/// whether the command was exactly zero at every settled tick.
struct Square {
    ticks: Vec<Tick>,
    counters: RouteCounters,
    /// True position error (m) and heading error from the held heading
    /// (rad) at each stop's first settled tick after the last pivot.
    settled: Vec<(f32, f32)>,
    /// The tracker's counters at the end.
    tracker: crate::pilot::tracker::TrackerCounters,
}

fn run_square(estimator: EstimatorChoice, initial: HeadingEstimate, quantum_m: f32) -> Square {
    let mut run = Run::new(tracker(estimator, initial), Pose::new(0.0, 0.0, 0.0));
    run.route.load(&square(), &limits(), RouteStart::AsGiven);
    let ticks = run.until_done(quantum_m, 20_000, 100);
    let counters = run.route.counters();
    let tracker = run.tracker.counters();
    let mut settled = Vec::new();
    for pair in ticks.windows(2) {
        let [before, now] = [pair[0], pair[1]];
        // The first tick of a stop's settled hold: the command turns
        // exactly zero while the reference rests holding a heading.
        let Some(RouteMode::Stopped {
            hold_heading_rad: Some(hold),
        }) = now.status.mode
        else {
            continue;
        };
        if now.out.command == BodyVelocity::ZERO && before.out.command != BodyVelocity::ZERO {
            let p = (now.robot.position - now.out.reference.position).norm();
            settled.push((p, wrap(now.robot.heading_rad - hold).abs()));
        }
    }
    Square {
        ticks,
        counters,
        settled,
        tracker,
    }
}

/// The command is exactly zero on every tick from a settle in a stop to
/// the reference moving again, and the route ends done, held at zero.
fn assert_held(square: &Square) {
    let mut holding = false;
    for t in &square.ticks {
        match t.status.mode {
            Some(RouteMode::Stopped { .. }) => {
                if t.out.command == BodyVelocity::ZERO {
                    holding = true;
                }
                if holding {
                    assert_eq!(t.out.command, BodyVelocity::ZERO, "creeping at a stop");
                }
            }
            _ => holding = false,
        }
    }
    let last = square.ticks.last().unwrap();
    assert!(last.status.done && !last.status.pending);
    assert_eq!(last.out.command, BodyVelocity::ZERO);
    assert_eq!(last.out.mode, TrackerMode::Tracking);
    assert_eq!(last.out.reference.position, Vec2::ZERO);
}

fn report(label: &str, square: &Square) {
    std::println!("{label}: tracker {:?}", square.tracker);
    let worst_p = square.settled.iter().map(|s| s.0).fold(0.0, f32::max);
    let worst_h = square.settled.iter().map(|s| s.1).fold(0.0, f32::max);
    std::println!(
        "{label}: {} ticks, {:?}, worst true stop error {worst_p:.5} m, {:.4}°",
        square.ticks.len(),
        square.counters,
        worst_h.to_degrees()
    );
}

/// Paper 002's pose observer, its heading known at the start, with an
/// exact fix every tick and with fixes on a 1 cm grid: four stops reached
/// within 1 cm and 1° of the truth, four pivots, motors exactly zero
/// during the dwells once settled, the route done with the robot stopped.
#[test]
fn a_square_with_stops_and_pivots_is_driven_to_its_end() {
    for quantum_m in [0.0, 0.01] {
        let square = run_square(pose_observer(), EAST, quantum_m);
        report(
            &std::format!("pose observer, fix grid {quantum_m} m"),
            &square,
        );
        let c = square.counters;
        assert_eq!(c.stops_reached, 4, "{c:?}");
        assert_eq!(c.pivots, 4, "{c:?}");
        assert_eq!(c.routes_started, 1, "{c:?}");
        assert_eq!(c.routes_done, 1, "{c:?}");
        assert_eq!(c.open_loop_pivot_ticks, 0, "{c:?}");
        assert_eq!(c.stop_errors, 0, "{c:?}");
        assert_eq!(square.settled.len(), 4);
        for (position_m, heading_rad) in &square.settled {
            assert!(*position_m <= 0.01, "{:?}", square.settled);
            assert!(heading_rad.to_degrees() <= 1.0, "{:?}", square.settled);
        }
        assert_held(&square);
        let last = square.ticks.last().unwrap();
        assert!(wrap(last.robot.heading_rad - FRAC_PI_2).abs() < 1.0_f32.to_radians());
    }
}

/// Paper 001's observer (5) learns the heading only while driving. From an
/// unknown heading `(0, 0)` it converges on the first leg; at the stops
/// and through the pivots its estimate is only turned by the encoders'
/// rotation (its error is kept, not corrected: `StandstillHeading::
/// EncoderRotated`), so the square is driven as with a known heading.
#[test]
fn paper_001_observer_pivots_on_the_encoder_rotated_heading() {
    assert_eq!(
        observer_001().heading_at_standstill(),
        crate::estimation::StandstillHeading::EncoderRotated
    );
    for quantum_m in [0.0, 0.01] {
        let square = run_square(observer_001(), HeadingEstimate::default(), quantum_m);
        report(
            &std::format!("observer 001, fix grid {quantum_m} m"),
            &square,
        );
        let c = square.counters;
        assert_eq!(
            (c.stops_reached, c.pivots, c.routes_done),
            (4, 4, 1),
            "{c:?}"
        );
        assert_eq!(c.open_loop_pivot_ticks, 0, "{c:?}");
        for (position_m, heading_rad) in &square.settled {
            assert!(*position_m <= 0.01, "{:?}", square.settled);
            assert!(heading_rad.to_degrees() <= 1.0, "{:?}", square.settled);
        }
        assert_held(&square);
    }
}

/// At standstill paper 001's observer turns its estimate with the
/// encoders and nothing else: a heading error it has when the robot stops
/// is the same after a pivot (here 0.2 rad, put in at the start with the
/// robot standing: it never drives, so nothing corrects it).
#[test]
fn paper_001_observer_keeps_its_heading_error_through_a_pivot() {
    let wrong = HeadingEstimate {
        cos_theta: 0.2_f32.cos(),
        sin_theta: 0.2_f32.sin(),
    };
    let mut run = Run::new(tracker(observer_001(), wrong), Pose::new(0.0, 0.0, 0.0));
    // A stop at the start, facing east, then north: a 90° pivot first.
    let route = Waypoints::from_slice(&[
        Waypoint::stop(0.0, 0.0, 0.2).facing(0.0),
        Waypoint::stop(0.0, 0.5, 0.0),
    ])
    .unwrap();
    run.route.load(&route, &limits(), RouteStart::AsGiven);
    let mut worst_change = 0.0_f32;
    let mut last = None;
    loop {
        // The estimate after this tick's step covers the odometry up to
        // the last tick: the robot before this tick's command.
        let before = run.robot;
        let t = run.tick(Some(run.robot.position));
        if matches!(t.status.mode, Some(RouteMode::Moving { .. })) {
            break;
        }
        let error = wrap(t.out.heading.heading_rad() - before.heading_rad);
        worst_change = worst_change.max((error - 0.2).abs());
        assert!(t.out.command.v_m_s == 0.0);
        assert!(t.status.elapsed_ticks < 1000);
        last = Some(t);
    }
    assert_eq!(run.route.counters().pivots, 1);
    // The robot turned to the estimate's north, 0.2 rad short of true
    // north, and the estimate's error is what it was.
    let robot = last.unwrap().robot;
    std::println!(
        "observer 001 through a pivot: error changed by {worst_change:e} rad, robot at {:.4} rad",
        robot.heading_rad
    );
    assert!(worst_change < 1e-4, "{worst_change}");
    assert!(
        wrap(robot.heading_rad - (FRAC_PI_2 - 0.2)).abs() < 1.0_f32.to_radians(),
        "{}",
        robot.heading_rad
    );
}

/// Before it has driven, paper 001's observer has no heading (`(0, 0)`):
/// a pivot at the first waypoint runs open loop (`ω = ω_r`), counted, and
/// on an exact plant still ends within 1° of its target.
#[test]
fn a_pivot_without_a_heading_estimate_is_open_loop() {
    let mut run = Run::new(
        tracker(observer_001(), HeadingEstimate::default()),
        Pose::new(0.0, 0.0, 0.0),
    );
    let route = Waypoints::from_slice(&[
        Waypoint::stop(0.0, 0.0, 0.0).facing(0.0),
        Waypoint::stop(0.0, 0.5, 0.0),
    ])
    .unwrap();
    run.route.load(&route, &limits(), RouteStart::AsGiven);
    let mut robot = run.robot;
    loop {
        let t = run.tick(Some(run.robot.position));
        if matches!(t.status.mode, Some(RouteMode::Moving { .. })) {
            break;
        }
        assert!(t.status.elapsed_ticks < 1000);
        robot = t.robot;
    }
    let c = run.route.counters();
    assert!(c.open_loop_pivot_ticks > 100 && c.pivots == 1, "{c:?}");
    let miss = wrap(robot.heading_rad - FRAC_PI_2).abs();
    std::println!("open-loop pivot: {:.4}° off", miss.to_degrees());
    assert!(miss < 1.0_f32.to_radians(), "{miss}");
}

/// A route loaded while another is moving: the running one goes on to its
/// next rest, and the new one starts there. Reference position and
/// velocity are continuous across the switch (no jump larger than one
/// tick's worth of the limits anywhere).
#[test]
fn a_replacement_waits_for_a_rest_and_starts_there() {
    let mut run = Run::new(tracker(pose_observer(), EAST), Pose::new(0.0, 0.0, 0.0));
    let first = Waypoints::from_slice(&[
        Waypoint::stop(0.0, 0.0, 0.0),
        Waypoint::stop(1.0, 0.0, 0.3),
        Waypoint::stop(2.0, 0.0, 0.0),
    ])
    .unwrap();
    // Its first position is replaced by the rest point.
    let second = Waypoints::from_slice(&[
        Waypoint::stop(9.0, 9.0, 0.0),
        Waypoint::pass(1.5, 0.5),
        Waypoint::stop(1.5, 1.0, 0.0),
    ])
    .unwrap();
    run.route.load(&first, &limits(), RouteStart::AsGiven);
    let mut ticks = Vec::new();
    for _ in 0..150 {
        ticks.push(run.tick(Some(run.robot.position)));
    }
    assert!(matches!(
        run.route.status().mode,
        Some(RouteMode::Moving { .. })
    ));
    run.route.load(&second, &limits(), RouteStart::AsGiven);
    ticks.extend(run.until_done(0.0, 20_000, 10));
    let c = run.route.counters();
    assert_eq!((c.routes_started, c.routes_done), (2, 1), "{c:?}");
    // The switch: the first route's stop at (1, 0), then the second's.
    let switch = ticks
        .windows(2)
        .position(|w| w[1].status.elapsed_ticks < w[0].status.elapsed_ticks)
        .unwrap();
    assert_eq!(ticks[switch].out.reference.position, Vec2::new(1.0, 0.0));
    assert_eq!(
        ticks[switch + 1].out.reference.position,
        Vec2::new(1.0, 0.0)
    );
    assert_eq!(ticks[switch + 1].out.reference.velocity, Vec2::ZERO);
    let (mut dp, mut dv) = (0.0_f32, 0.0_f32);
    for w in ticks.windows(2) {
        let (a, b) = (w[0].out.reference, w[1].out.reference);
        dp = dp.max((b.position - a.position).norm());
        dv = dv.max((b.velocity - a.velocity).norm());
    }
    // One tick at 0.3 m/s is 3 mm; at 0.8 m/s² (the larger acceleration
    // limit, lateral) 8 mm/s.
    assert!(dp <= 0.3 * H * 1.001, "{dp}");
    assert!(dv <= 0.8 * H * 1.01, "{dv}");
    // The first route's last stop was never driven to.
    assert!(
        ticks
            .iter()
            .all(|t| t.out.reference.position.x <= 1.5 + 1e-4)
    );
    let last = ticks.last().unwrap();
    assert!((last.robot.position - Vec2::new(1.5, 1.0)).norm() < 0.01);
}

/// `RouteStart::FromFirstFix`: nothing moves before the first fix; the
/// route then starts exactly at the estimated position and is driven from
/// there to its end.
#[test]
fn a_route_may_start_from_the_first_fix() {
    let start = Pose::new(0.3, -0.2, 0.0);
    let mut run = Run::new(tracker(pose_observer(), EAST), start);
    let route = Waypoints::from_slice(&[
        Waypoint::stop(0.0, 0.0, 0.0),
        Waypoint::stop(1.0, -0.2, 0.0),
    ])
    .unwrap();
    run.route.load(&route, &limits(), RouteStart::FromFirstFix);
    for _ in 0..20 {
        let t = run.tick(None);
        assert_eq!(t.out.mode, TrackerMode::AwaitingFix);
        assert_eq!(t.out.command, BodyVelocity::ZERO);
        assert!(t.status.pending && !t.status.running);
    }
    let first = run.tick(Some(start.position));
    assert!(first.status.running && !first.status.pending);
    assert_eq!(first.out.reference.position, start.position);
    let ticks = run.until_done(0.0, 20_000, 0);
    let last = ticks.last().unwrap();
    assert!((last.robot.position - Vec2::new(1.0, -0.2)).norm() < 0.01);
    // The start's stop of 0 s is shorter than a tick: only the end's.
    let c = run.route.counters();
    assert_eq!((c.stops_reached, c.routes_done), (1, 1), "{c:?}");
}

/// A route the planner refuses is reported and counted; the robot is held
/// where it is (never sent to the empty plan's origin). A good route
/// loaded after it starts from there.
#[test]
fn a_refused_route_holds_the_robot_where_it_is() {
    let at = Pose::new(0.4, 0.4, 0.0);
    let mut run = Run::new(tracker(pose_observer(), EAST), at);
    let one = Waypoints::from_slice(&[Waypoint::stop(0.0, 0.0, 0.0)]).unwrap();
    run.route.load(&one, &limits(), RouteStart::AsGiven);
    for _ in 0..50 {
        let t = run.tick(Some(at.position));
        assert_eq!(t.out.command, BodyVelocity::ZERO);
        assert_eq!(t.out.reference.position, at.position);
        assert!(t.status.refused.is_some() && !t.status.running);
    }
    assert_eq!(run.route.counters().routes_refused, 1);
    let good =
        Waypoints::from_slice(&[Waypoint::stop(0.0, 0.0, 0.0), Waypoint::stop(1.0, 0.4, 0.0)])
            .unwrap();
    run.route.load(&good, &limits(), RouteStart::FromFirstFix);
    let ticks = run.until_done(0.0, 20_000, 0);
    assert_eq!(ticks[0].out.reference.position, at.position);
    let last = ticks.last().unwrap();
    assert!(last.status.refused.is_none() && last.status.done);
    assert!((last.robot.position - Vec2::new(1.0, 0.4)).norm() < 0.01);
}

/// While the fix is lost the route's clock stands (the failsafe ramps the
/// robot down); it resumes with the fixes.
#[test]
fn the_route_waits_while_the_fix_is_lost() {
    let mut run = Run::new(tracker(pose_observer(), EAST), Pose::new(0.0, 0.0, 0.0));
    let route =
        Waypoints::from_slice(&[Waypoint::stop(0.0, 0.0, 0.0), Waypoint::stop(3.0, 0.0, 0.0)])
            .unwrap();
    run.route.load(&route, &limits(), RouteStart::AsGiven);
    for _ in 0..200 {
        run.tick(Some(run.robot.position));
    }
    for _ in 0..20 {
        run.tick(None);
    }
    let lost = run.route.status().elapsed_ticks;
    for _ in 0..300 {
        let t = run.tick(None);
        assert_eq!(t.out.mode, TrackerMode::FixLost);
        assert_eq!(t.status.elapsed_ticks, lost);
    }
    assert_eq!(run.tick(None).out.command, BodyVelocity::ZERO);
    let back = run.tick(Some(run.robot.position));
    assert_eq!(back.out.mode, TrackerMode::Tracking);
    assert_eq!(back.status.elapsed_ticks, lost + 1);
}

/// Options outside their ranges are refused by name.
#[test]
fn options_are_validated() {
    let good = RouteOptions::default().spec();
    assert!(good.build().is_ok());
    let with = |f: &dyn Fn(&mut RouteOptionsSpec)| {
        let mut spec = good;
        f(&mut spec);
        RouteOptions::new(&spec)
    };
    for k in [0.0, -1.0, f32::NAN, 1e4] {
        assert_eq!(
            with(&|s| s.pivot_gain_per_s = k),
            Err(RouteOptionsError::PivotGain)
        );
    }
    for (p, h) in [(0.0, 0.01), (0.01, f32::INFINITY), (f32::NAN, 0.01)] {
        assert_eq!(
            with(&|s| {
                s.position_tolerance_m = p;
                s.heading_tolerance_rad = h;
            }),
            Err(RouteOptionsError::Tolerance)
        );
    }
    for lag in [0.0, -0.1, f32::NAN, f32::INFINITY] {
        let e = with(&|s| s.max_lag_m = lag);
        assert_eq!(e, Err(RouteOptionsError::MaxLag));
        assert_eq!(e.unwrap_err().field(), "max_lag_m");
    }
    for v in [0.0, -0.1, 1.5, f32::NAN] {
        assert_eq!(
            with(&|s| s.approach_speed_m_s = v),
            Err(RouteOptionsError::ApproachSpeed)
        );
    }
    for t in [-1.0, f32::NAN, f32::INFINITY] {
        assert_eq!(
            with(&|s| s.approach_timeout_s = t),
            Err(RouteOptionsError::ApproachTimeout)
        );
    }
    assert!(with(&|s| s.approach_timeout_s = 0.0).is_ok());
}

/// The fusion EKF (its heading turned by the odometry at the stops, its
/// variance grown): the square with an exact fix, with fixes on a 1 cm
/// grid and on nearest-tag fixes of its own 10 cm grid, every stop within
/// 1 cm and 1° of the truth (measured on the 10 cm grid: 1.4 mm, 0.15°).
#[cfg(feature = "fusion-ekf")]
#[test]
fn the_fusion_ekf_drives_the_square() {
    use crate::estimation::fusion::{FusionSettings, PoseFilterConfig};
    let filter = PoseFilterConfig::new(0.2, 1e-3, 1e-9, 3.0).unwrap();
    let estimator = EstimatorChoice::Fusion {
        settings: FusionSettings::new(filter, 0.1, 0.0).unwrap(),
        guide: HeadingObserverConfig::new(5.0, H).unwrap(),
    };
    assert_eq!(
        estimator.heading_at_standstill(),
        crate::estimation::StandstillHeading::EncoderRotatedFiltered
    );
    for quantum_m in [0.0, 0.01, 0.1] {
        let square = run_square(estimator, EAST, quantum_m);
        report(&std::format!("fusion EKF, fix grid {quantum_m} m"), &square);
        let c = square.counters;
        assert_eq!(
            (c.stops_reached, c.pivots, c.routes_done),
            (4, 4, 1),
            "{c:?}"
        );
        assert_eq!(c.stop_errors, 0, "{c:?}");
        for (position_m, heading_rad) in &square.settled {
            assert!(*position_m <= 0.01, "{:?}", square.settled);
            assert!(heading_rad.to_degrees() <= 1.0, "{:?}", square.settled);
        }
        assert_held(&square);
    }
}

/// Through the whole pilot (encoders, tracker, drive), on ideal wheels
/// that turn at the drive's targets: once settled at a stop the motors'
/// duties are exactly zero for the rest of the dwell (no speed loop
/// holding a duty from its integral), and the route ends done with the
/// motors at zero. The pilot's pose observer starts from `(0, 0)` and
/// after the 0.5 m first leg its estimate is still short (measured
/// `(0.41, 0)`, below [`MIN_HEADING_NORM`]), so the pivot runs open loop;
/// through the drive's acceleration limits it overshoots (measured 4.2°),
/// which the stop's heading error reports.
#[test]
fn the_pilot_zeroes_the_motors_once_settled() {
    use crate::drive::{DriveConfig, SpeedLoopGains};
    use crate::geometry::DiffDriveGeometry;
    use crate::pilot::{Measurement, Pilot, PilotConfig};
    let geometry = DiffDriveGeometry::new(0.03, 0.2, 2048).unwrap();
    let drive = DriveConfig::new(
        geometry,
        H,
        20.0,
        100.0,
        SpeedLoopGains {
            feedforward_duty_per_rad_s: 0.05,
            kp_duty_per_rad_s: 0.02,
            ki_duty_per_rad: 0.1,
        },
    )
    .unwrap();
    let tracker = *tracker(pose_observer(), EAST).config();
    let mut pilot = Pilot::new(PilotConfig::new(tracker, drive, 16).unwrap()).unwrap();
    let mut follower = RouteFollower::new(RouteOptions::default());
    let route = Waypoints::from_slice(&[
        Waypoint::stop(0.0, 0.0, 0.0),
        Waypoint::stop(0.5, 0.0, 1.0),
        Waypoint::stop(0.5, 0.5, 0.5),
    ])
    .unwrap();
    follower.load(&route, &limits(), RouteStart::AsGiven);
    let mut robot = Pose::new(0.0, 0.0, 0.0);
    let (mut left, mut right) = (0.0_f64, 0.0_f64);
    let per_count = f64::from(geometry.rad_per_count());
    let mut held_ticks = 0;
    let mut motors_stopped = false;
    let mut done = false;
    for _ in 0..10_000 {
        let out = pilot.step_route(
            &Measurement {
                left_count: Some((left / per_count).floor() as i64 as u32),
                right_count: Some((right / per_count).floor() as i64 as u32),
                fix: Some(TagFix {
                    position: robot.position,
                    age_ticks: 0,
                }),
            },
            &mut follower,
        );
        let status = follower.status();
        let zero = out.left.duty == 0.0 && out.right.duty == 0.0;
        if !status.holding {
            motors_stopped = false;
        } else if motors_stopped || zero {
            // Once the drive's targets have ramped down, zero to the end
            // of the hold.
            motors_stopped = true;
            held_ticks += 1;
            assert_eq!((out.drive.left_duty, out.drive.right_duty), (0.0, 0.0));
            assert!(zero, "{out:?}");
        }
        let wheels = out.drive.wheel_targets;
        left += f64::from(wheels.left_rad_s * H);
        right += f64::from(wheels.right_rad_s * H);
        let body = geometry.body_from_wheels(wheels);
        robot = robot.advance_arc(body.v_m_s * H, body.omega_rad_s * H);
        if status.done {
            done = true;
            break;
        }
    }
    let c = follower.counters();
    std::println!("pilot: {held_ticks} ticks held, {c:?}, robot {robot:?}");
    assert!(done, "{c:?}");
    assert_eq!(
        (c.stops_reached, c.pivots, c.stop_errors),
        (2, 1, 1),
        "{c:?}"
    );
    assert!(c.open_loop_pivot_ticks > 100, "{c:?}");
    assert!(held_ticks > 50, "{held_ticks}");
    assert!(
        (robot.position - Vec2::new(0.5, 0.5)).norm() < 0.01,
        "{robot:?}"
    );
}

/// What a route costs in RAM, where the caller keeps it: the follower is
/// the plan, a pending route's waypoints and some bookkeeping; the
/// tracker and the pilot are no larger for routes.
#[test]
fn a_follower_is_a_plan_and_a_pending_route() {
    use core::mem::size_of;
    let follower = size_of::<RouteFollower>();
    let (plan, waypoints) = (size_of::<RoutePlan>(), size_of::<Waypoints>());
    std::println!(
        "RouteFollower {follower} B = RoutePlan {plan} B + Waypoints {waypoints} B + {} B",
        follower - plan - waypoints
    );
    assert!(follower <= plan + waypoints + 256, "{follower}");
}

/// Garbage in, no garbage out: non-finite fixes and odometry through a
/// route's moving legs, stops and pivots never make a non-finite command
/// (the tracker's own checks and the estimators' guards hold; a pivot
/// without a finite heading runs open loop).
#[test]
fn non_finite_input_never_reaches_the_command() {
    for estimator in [pose_observer(), observer_001()] {
        let mut run = Run::new(tracker(estimator, EAST), Pose::new(0.0, 0.0, 0.0));
        run.route.load(&square(), &limits(), RouteStart::AsGiven);
        for k in 0..4000_u32 {
            let fix = match k % 7 {
                0 => Some(Vec2::new(f32::NAN, 0.0)),
                1 => Some(Vec2::new(0.0, f32::INFINITY)),
                _ => Some(run.robot.position),
            };
            if k % 11 == 0 {
                run.odometry.body.v_m_s = f32::NAN;
                run.odometry.ds_m = f32::NAN;
            }
            if k % 13 == 0 {
                run.odometry.body.omega_rad_s = f32::INFINITY;
                run.odometry.dtheta_rad = f32::NEG_INFINITY;
            }
            let t = run.tick(fix);
            assert!(t.out.command.is_finite(), "{k}: {:?}", t.out);
            assert!(t.out.reference.position.is_finite(), "{k}: {:?}", t.out);
        }
        assert!(run.tracker.counters().invalid_fixes > 1000);
        assert!(
            run.route.counters().pivots > 0,
            "{:?}",
            run.route.counters()
        );
    }
}
