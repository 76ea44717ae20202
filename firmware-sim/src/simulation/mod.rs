//! Running a scenario: the simulation loop, per-tick records and the summary
//! (whose types are [`crate::report`]'s).
//!
//! One control tick `k` (time `t_k = k·h`, computed from `k`, never summed):
//!
//! 1. the position source looks at the plant's pose at `t_k` (exact
//!    position, nearest tag, or the virtual reader putting a frame on the
//!    line);
//! 2. the controller runs: the core's [`OutputFeedbackTracker`] or
//!    [`TrackingController`] directly (unicycle plant), or the core's
//!    [`Robot`] (diff-drive plant with the reader: encoders, UART, tag
//!    grid, pilot, motor drivers, exactly the firmware's tick) or its
//!    [`Pilot`] with the virtual encoders and motor drivers (diff-drive plant
//!    with an exact or nearest-tag position, which no device delivers);
//! 3. the tick is recorded (true pose at `t_k`, what the controller knew and
//!    commanded);
//! 4. the plant advances one period with what was commanded (unicycle: the
//!    `(v, ω)`; diff drive: the duties on the virtual PWM pins, held).
//!
//! By job, each file using only those above it: `target` (the
//! [`TargetLink`] a remote tick runs on, [`hil_configuration`]),
//! `sources` (the position sources and their faults), `hardware` (the
//! diff-drive body and its virtual devices), `rig` (the ways a tick runs,
//! the record of a tick), `summary` (the figures, [`error_stats`]),
//! `stepper` (a local rig ticked by another module: the SITL); this
//! file runs the loop ([`run`], [`run_with_target`]).
//!
//! [`OutputFeedbackTracker`]: wmr_core::pilot::tracker::OutputFeedbackTracker
//! [`TrackingController`]: wmr_core::control::saturated::TrackingController
//! [`Robot`]: wmr_core::pilot::robot::Robot
//! [`Pilot`]: wmr_core::pilot::Pilot

use std::time::Instant;

use crate::report::RunResult;
use crate::scenario::{Scenario, ScenarioError, Setup};

mod hardware;
mod rig;
mod sources;
mod stepper;
mod summary;
mod target;

pub use summary::error_stats;
pub use target::{MavlinkLog, TargetLink, hil_configuration, hil_map_chunks, hil_route_messages};

use rig::Rig;
pub(crate) use stepper::Stepper;
use summary::summarize;

/// Ticks between two progress callbacks.
const PROGRESS_EVERY: u32 = 1000;

/// Validates and runs a scenario. `progress(done, total)` is called every
/// 1000 ticks and at the end.
///
/// # Errors
/// The scenario's validation error.
pub fn run(
    scenario: &Scenario,
    progress: impl FnMut(u64, u64),
) -> Result<RunResult, ScenarioError> {
    let setup = scenario.validate()?;
    let rig = Rig::new(&setup);
    simulate(scenario, setup, rig, progress).map_err(|e| {
        // Local rigs never fail a tick.
        ScenarioError::invalid("(run)", e.to_string())
    })
}

/// Runs a diff-drive + reader scenario with the control tick on `target`
/// (already configured with [`hil_configuration`]); the plant, encoders and
/// RFID reader are the same as in [`run`].
///
/// # Errors
/// A scenario this cannot run remotely, or a link failure.
pub fn run_with_target(
    scenario: &Scenario,
    target: &mut dyn TargetLink,
    progress: impl FnMut(u64, u64),
) -> anyhow::Result<RunResult> {
    let setup = scenario.validate()?;
    let mut storage = target::ShadowStorage::new(target.mavlink_log().is_some())?;
    let shadow = target::RouteShadow::new(&setup, &mut storage)?;
    let rig = Rig::remote(&setup, target, shadow)?;
    simulate(scenario, setup, rig, progress)
}

fn simulate(
    scenario: &Scenario,
    setup: Setup,
    mut rig: Rig<'_>,
    progress: impl FnMut(u64, u64),
) -> anyhow::Result<RunResult> {
    let wall = Instant::now();
    let mut records = Vec::with_capacity(setup.ticks as usize);
    let mut progress = progress;
    let total = u64::from(setup.ticks);
    // A route run ends `settle_s` after the route is done, or at the
    // scenario's duration (a route not done by then is reported so).
    let settle_ticks = setup
        .route
        .as_ref()
        .map(|r| (r.settle_s / setup.period_s).round() as u64);
    let mut route_ticks = Vec::new();
    let mut done_at: Option<u32> = None;
    for k in 0..setup.ticks {
        if rig.stop_requested() {
            break;
        }
        let t = f64::from(k) * setup.period_s;
        let mut record = rig.tick(k, t)?;
        if let Some(status) = rig.route().map(|f| f.status()) {
            // Before the route starts (no fix yet) the core's reference is
            // a default sample at the origin: the record shows the first
            // waypoint, where the route will start, instead.
            if !status.running
                && let Some(first) = setup
                    .route
                    .as_ref()
                    .and_then(|r| r.waypoints.as_slice().first())
            {
                record.ref_x_m = f64::from(first.position_m.x);
                record.ref_y_m = f64::from(first.position_m.y);
                record.error_m = (record.x_m - record.ref_x_m).hypot(record.y_m - record.ref_y_m);
            }
            route_ticks.push(status);
            if status.done && done_at.is_none() {
                done_at = Some(k);
            }
        }
        records.push(record);
        rig.advance(setup.period_s);
        if (k + 1) % PROGRESS_EVERY == 0 {
            progress(u64::from(k) + 1, total);
        }
        if let (Some(done), Some(settle)) = (done_at, settle_ticks)
            && u64::from(k - done) >= settle
        {
            break;
        }
    }
    progress(total, total);
    if let Rig::Remote { target, last, .. } = &mut rig {
        *last = target.finish()?;
    }
    let summary = summarize(
        scenario,
        &setup,
        &records,
        &route_ticks,
        &rig,
        wall.elapsed().as_secs_f64(),
    );
    Ok(RunResult {
        scenario: scenario.clone(),
        setup,
        records,
        summary,
    })
}
