//! The figures of a run, from its records and what the rig counted.

use wmr_core::pilot::route::{RouteFollower, RouteStart, RouteStatus};
use wmr_core::reference::route::RouteMode;

use crate::plant::wrap_angle;
use crate::report::{
    Mode, ModeTicks, Record, RouteReport, SetupLabels, StopReport, Summary, TrackerReport,
};
use crate::scenario::{RouteSetup, Scenario, Setup, route_path};

use super::rig::Rig;
use super::sources::rfid_report;

/// Error statistics over the records with `t ≥ from_s`:
/// `(samples, max, mean, rms)`.
#[must_use]
pub fn error_stats(records: &[Record], from_s: f64) -> (u64, f64, f64, f64) {
    let mut n = 0_u64;
    let (mut max, mut sum, mut sum_sq) = (0.0_f64, 0.0, 0.0);
    for r in records.iter().filter(|r| r.t_s >= from_s - 1e-9) {
        n += 1;
        max = max.max(r.error_m);
        sum += r.error_m;
        sum_sq += r.error_m * r.error_m;
    }
    if n == 0 {
        return (0, f64::NAN, f64::NAN, f64::NAN);
    }
    let nf = n as f64;
    (n, max, sum / nf, (sum_sq / nf).sqrt())
}

pub(super) fn summarize(
    scenario: &Scenario,
    setup: &Setup,
    records: &[Record],
    route_ticks: &[RouteStatus],
    rig: &Rig<'_>,
    wall_s: f64,
) -> Summary {
    let (samples, max, mean, rms) = error_stats(records, setup.transient_s);
    let mut modes = ModeTicks::default();
    for r in records {
        match r.mode {
            Mode::AwaitingFix => modes.awaiting_fix += 1,
            Mode::Tracking => modes.tracking += 1,
            Mode::FixLost => modes.fix_lost += 1,
            Mode::StateFeedback => modes.state_feedback += 1,
        }
    }
    let max_heading_error_rad = records
        .iter()
        .filter(|r| r.t_s >= setup.transient_s - 1e-9)
        .filter_map(|r| r.heading_error_rad)
        .map(f64::abs)
        .reduce(f64::max);
    let (tracker, rfid, pilot, floor_tags) = match rig {
        Rig::Tracker {
            tracker, source, ..
        } => (
            Some(TrackerReport::of(tracker)),
            source.report(),
            None,
            source.floor_tags(),
        ),
        Rig::Controller { source, .. } => (None, source.report(), None, source.floor_tags()),
        Rig::Robot {
            hw,
            robot,
            reader,
            floor,
            ..
        } => (
            Some(TrackerReport::of(robot.pilot().tracker())),
            Some(rfid_report(
                robot.rfid_counters(),
                robot.counters().unknown_tags,
                reader.counters(),
            )),
            Some(hw.report(robot.pilot().counters(), robot.counters().motor_faults)),
            Some(floor.len()),
        ),
        Rig::Remote {
            hw,
            reader,
            floor,
            last,
            pwm_refusals,
            ..
        } => (
            Some(TrackerReport::from_counters(
                last.tracker,
                last.observer_rejected_updates,
            )),
            Some(rfid_report(
                last.rfid,
                last.robot.unknown_tags,
                reader.counters(),
            )),
            Some(hw.report(last.pilot, last.robot.motor_faults + *pwm_refusals)),
            Some(floor.len()),
        ),
        Rig::Pilot {
            hw,
            pilot,
            source,
            motor_faults,
            ..
        } => (
            Some(TrackerReport::of(pilot.tracker())),
            source.report(),
            Some(hw.report(pilot.counters(), *motor_faults)),
            source.floor_tags(),
        ),
    };
    // The scenario's gains k1, k2, k3 against the bound (15), whichever
    // law runs (the core evaluates it for law (27)–(28) only).
    // A route's own bounds (it stops: `v_rm = 0`), not its stand-in's.
    let speed_bounds = setup.route.as_ref().map_or_else(
        || setup.trajectory.speed_bounds(),
        |r| r.plan.speed_bounds(),
    );
    let gain_bound = setup.gains.check_bound(speed_bounds);
    let labels = SetupLabels::of(setup);
    Summary {
        scenario: scenario.name.clone(),
        plant: labels.plant,
        controller: labels.controller,
        position_source: labels.position_source,
        code_path: rig.code_path(),
        // A route run may end before `setup.ticks` (`RouteSpec::settle_s`).
        ticks: records.len() as u32,
        period_s: setup.period_s,
        duration_s: records.len() as f64 * setup.period_s,
        transient_s: setup.transient_s,
        samples,
        max_error_m: max,
        mean_error_m: mean,
        rms_error_m: rms,
        final_error_m: records.last().map_or(f64::NAN, |r| r.error_m),
        max_heading_error_rad,
        non_finite_ticks: records.iter().filter(|r| !r.is_finite()).count() as u64,
        gain_bound: gain_bound.into(),
        mode_ticks: modes,
        tracker,
        rfid,
        pilot,
        floor_tags,
        measurement: match rig {
            Rig::Tracker { source, .. }
            | Rig::Controller { source, .. }
            | Rig::Pilot { source, .. } => source.measurement_report(),
            Rig::Robot { .. } | Rig::Remote { .. } => None,
        },
        wall_time_s: wall_s,
        hil: None,
        route: match (&setup.route, rig.route()) {
            (Some(route), Some(follower)) => {
                let mut report =
                    route_report(route, follower, records, route_ticks, setup.period_s);
                // A HIL run reports the firmware's own counters.
                if let Rig::Remote { last, .. } = rig {
                    report.counters = last.route;
                }
                Some(report)
            }
            _ => None,
        },
    }
}

/// The window of the planned path searched for the point nearest the
/// robot, either side of the route's clock, ticks (3 s at 100 Hz): the
/// robot is near the reference, and a path that comes back near itself
/// (a loop) is not matched to its other pass.
const CROSS_TRACK_WINDOW_TICKS: usize = 300;

/// A route run's figures (ground truth, [`RouteReport`]).
///
/// * A stop's error is taken at the robot's last *settle* there (the tick
///   its command became a settled, exactly zero hold, after arrival and
///   again after a pivot): the true position's distance from the stop and,
///   where the stop faces a heading, the true heading's. The stop is the
///   waypoint the reference rests on (matched in order).
/// * The cross-track error is the true position's distance from the
///   planned path (the plan's reference position at every tick, joined by
///   straight segments, searched within [`CROSS_TRACK_WINDOW_TICKS`] of the
///   route's clock), over the ticks where the reference moves: the
///   distance from the path, not from the reference point (which also
///   holds the along-track lag).
fn route_report(
    route: &RouteSetup,
    follower: &RouteFollower,
    records: &[Record],
    route_ticks: &[RouteStatus],
    period_s: f64,
) -> RouteReport {
    let plan = follower.plan();
    // The path as far as the run can have followed it (a plan may last
    // far longer than the run): its ticks plus the search window.
    let reach = u32::try_from(records.len() + CROSS_TRACK_WINDOW_TICKS).unwrap_or(u32::MAX);
    let path = route_path(plan, reach);
    let started = route_ticks.iter().position(|s| s.running);
    let done = route_ticks.iter().position(|s| s.done);
    let planned_duration_s = f64::from(plan.duration_ticks()) * period_s;
    let time_taken_s = match (started, done) {
        (Some(a), Some(b)) => Some((b - a) as f64 * period_s),
        _ => None,
    };

    // The stops after the first waypoint, in order.
    let mut stops: Vec<StopReport> = route
        .stops()
        .filter(|(i, _)| *i > 0)
        .map(|(i, w)| StopReport {
            waypoint: i + 1,
            x_m: f64::from(w.position_m.x),
            y_m: f64::from(w.position_m.y),
            face_heading_deg: w
                .stop
                .and_then(|s| s.face_heading_rad)
                .map(|h| f64::from(h.to_degrees())),
            settled_at_s: None,
            position_error_m: None,
            heading_error_deg: None,
        })
        .collect();
    let mut next_stop = 0;
    let (mut max_ct, mut sum_sq, mut moving) = (0.0_f64, 0.0_f64, 0_u64);
    for (k, (status, record)) in route_ticks.iter().zip(records).enumerate() {
        let was_holding = k > 0 && route_ticks.get(k - 1).is_some_and(|s| s.holding);
        match status.mode {
            Some(RouteMode::Stopped { .. }) if status.holding && !was_holding => {
                let rest = [record.ref_x_m, record.ref_y_m];
                let at = |s: &StopReport| (s.x_m - rest[0]).hypot(s.y_m - rest[1]) < 1e-3;
                if let Some(j) = stops.iter().skip(next_stop).position(at) {
                    next_stop += j;
                    if let Some(stop) = stops.get_mut(next_stop) {
                        stop.settled_at_s = Some(record.t_s);
                        stop.position_error_m =
                            Some((record.x_m - stop.x_m).hypot(record.y_m - stop.y_m));
                        stop.heading_error_deg = stop.face_heading_deg.map(|face| {
                            wrap_angle(record.theta_rad - face.to_radians())
                                .abs()
                                .to_degrees()
                        });
                    }
                }
            }
            Some(RouteMode::Moving { .. }) => {
                let e = status.elapsed_ticks as usize;
                let lo = e.saturating_sub(CROSS_TRACK_WINDOW_TICKS);
                let hi = (e + CROSS_TRACK_WINDOW_TICKS).min(path.len().saturating_sub(1));
                let d = path.get(lo..=hi).map_or(f64::NAN, |w| {
                    distance_to_polyline([record.x_m, record.y_m], w)
                });
                if d.is_finite() {
                    max_ct = max_ct.max(d);
                    sum_sq += d * d;
                    moving += 1;
                }
            }
            _ => {}
        }
    }
    let max_of = |f: fn(&StopReport) -> Option<f64>| stops.iter().filter_map(f).reduce(f64::max);
    RouteReport {
        done: done.is_some(),
        start: match route.start {
            RouteStart::FromFirstFix => "from_first_fix",
            RouteStart::AsGivenHeadingKnown => "as_given_heading_known",
            _ => "as_given",
        },
        planned_duration_s,
        time_taken_s,
        time_ratio: time_taken_s
            .filter(|_| planned_duration_s > 0.0)
            .map(|t| t / planned_duration_s),
        started_at_s: started.map(|k| k as f64 * period_s),
        done_at_s: done.map(|k| k as f64 * period_s),
        max_stop_position_error_m: max_of(|s| s.position_error_m),
        max_stop_heading_error_deg: max_of(|s| s.heading_error_deg),
        stops_missed: stops.iter().filter(|s| s.settled_at_s.is_none()).count(),
        stops,
        max_cross_track_error_m: (moving > 0).then_some(max_ct),
        rms_cross_track_error_m: (moving > 0).then(|| (sum_sq / moving as f64).sqrt()),
        moving_ticks: moving,
        counters: follower.counters(),
        refused: follower.status().refused.map(|e| e.to_string()),
        path_m: path,
    }
}

/// Distance from `p` to the polyline through `points`, m.
fn distance_to_polyline(p: [f64; 2], points: &[[f64; 2]]) -> f64 {
    let segment = |a: [f64; 2], b: [f64; 2]| {
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let len2 = dx * dx + dy * dy;
        let t = if len2 > 0.0 {
            (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (p[0] - a[0] - t * dx).hypot(p[1] - a[1] - t * dy)
    };
    match points {
        [only] => (p[0] - only[0]).hypot(p[1] - only[1]),
        _ => points
            .windows(2)
            .map(|w| segment(w[0], w[1]))
            .fold(f64::INFINITY, f64::min),
    }
}
