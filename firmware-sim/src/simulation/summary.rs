//! The figures of a run, from its records and what the rig counted.

use crate::report::{Mode, ModeTicks, Record, SetupLabels, Summary, TrackerReport};
use crate::scenario::{Scenario, Setup};

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
    let gain_bound = setup.gains.check_bound(setup.trajectory.speed_bounds());
    let labels = SetupLabels::of(setup);
    Summary {
        scenario: scenario.name.clone(),
        plant: labels.plant,
        controller: labels.controller,
        position_source: labels.position_source,
        code_path: rig.code_path(),
        ticks: setup.ticks,
        period_s: setup.period_s,
        duration_s: f64::from(setup.ticks) * setup.period_s,
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
    }
}
