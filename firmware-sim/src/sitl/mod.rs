//! `firmware-sim sitl`: the simulated robot in real time (or `N` times
//! faster) behind the robot's own MAVLink endpoint (`wmr-mavlink`), on a
//! UDP socket, as ArduPilot's and PX4's SITL are (docs/mavlink.md, "The
//! SITL").
//!
//! Each control tick `k` (simulated time `k·h`; the endpoint's clock is
//! that time in ms, so timeouts and telemetry rates are simulated time):
//!
//! 1. wait for the wall clock ([`pace`]);
//! 2. read every datagram waiting ([`link`]) and hand the bytes to the
//!    endpoint with what the robot reports ([`robot::SitlRobot::view`]);
//!    an uploaded mission is checked by the core's planner with the
//!    endpoint's route limits and the scenario's period;
//! 3. apply the endpoint's events to the robot at this tick boundary
//!    ([`robot`]);
//! 4. run the robot's tick (the same rig as `firmware-sim run`) and
//!    advance the plant; update the mission's progress
//!    ([`wmr_mavlink::progress`]);
//! 5. send what the endpoint wrote, a datagram per frame.
//!
//! The UDP side is [`crate::udp`]'s, shared with `firmware-sim hil
//! --mavlink` ([`address`]: the `--mavlink` address and the loopback
//! rule, [`link`]: the UDP socket, [`pace`]: the wall clock; re-exported
//! here). [`robot`]: the robot on the mission runner of `wmr-mavlink`;
//! this file runs the loop ([`run`]). Uses `udp`, `scenario`, `report`
//! and `simulation` of this crate.

pub use crate::udp::{address, link, pace};
pub mod robot;

use std::sync::atomic::{AtomicBool, Ordering};

use wmr_core::reference::route::RoutePlan;
use wmr_mavlink::{Counters, MavlinkEndpoint, RobotMode, TxBuffer};

use crate::report::Record;
use crate::scenario::Setup;

pub use address::MavlinkAddress;
pub use link::{LinkCounters, UdpLink};
pub use robot::SitlRobot;

/// Room for one tick's outgoing frames (a download answer, telemetry,
/// statustexts: a few frames of at most 280 bytes each).
const TX_BYTES: usize = 8192;

/// How a SITL run goes.
#[derive(Debug, Clone)]
pub struct SitlOptions {
    /// Where the ground station is.
    pub address: MavlinkAddress,
    /// Times real time (finite, > 0).
    pub speedup: f64,
    /// Simulated seconds to run; `None`: until stopped.
    pub duration_s: Option<f64>,
    /// Keep every tick's record (for `--out`).
    pub keep_records: bool,
}

/// What a SITL run did.
#[derive(Debug, Clone, serde::Serialize)]
pub struct SitlReport {
    /// Ticks run.
    pub ticks: u32,
    /// Simulated seconds.
    pub sim_s: f64,
    /// Wall seconds.
    pub wall_s: f64,
    /// `sim_s / wall_s`.
    pub speedup_achieved: f64,
    /// The mode at the end (`custom_mode`: 0 idle, 1 running, 2 paused,
    /// 3 done, 4 stopped).
    pub mode: u8,
    /// Armed at the end.
    pub armed: bool,
    /// Routes the robot finished.
    pub routes_done: u32,
    /// The last item reached.
    pub reached: Option<u16>,
    /// The estimate at the end, floor frame, m.
    pub estimate_m: Option<[f64; 2]>,
    /// The true position at the end, floor frame, m.
    pub position_m: Option<[f64; 2]>,
    /// The endpoint's counters: link losses, refusals, frames.
    pub link_losses: u32,
    /// Missions, items, set-currents and requests refused.
    pub mission_refusals: u32,
    /// Commands refused.
    pub command_refusals: u32,
    /// Parameter reads and sets refused.
    pub param_refusals: u32,
    /// CRC errors on the link.
    pub crc_errors: u32,
    /// The UDP link's counters.
    pub link: LinkCounters,
    /// The gains and failsafe times the robot ran with at the end (as set
    /// by `PARAM_SET`, or the scenario's).
    pub tuning: Option<SitlTuning>,
    /// What the robot did, a line each, with its simulated time.
    pub log: Vec<String>,
    /// Every tick's record, with `keep_records`.
    #[serde(skip)]
    pub records: Vec<Record>,
}

/// The gains and failsafe times of a [`SitlReport`]
/// (`wmr_core::pilot::tuning::TuningSpec`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct SitlTuning {
    /// Law (27)–(28)'s `[k1, k2, k3]` (`None` on another law).
    pub gains: Option<[f32; 3]>,
    /// Ticks without a valid fix before the failsafe engages.
    pub fix_timeout_ticks: u32,
    /// Age beyond which a fix is stale, ticks.
    pub max_fix_age_ticks: u32,
    /// Failsafe deceleration, m/s².
    pub failsafe_decel_m_s2: f32,
    /// Encoder fault ticks bridged before the motors stop.
    pub max_encoder_fault_ticks: u32,
}

/// Builds the endpoint for `setup`'s robot: configured by its
/// `[mavlink]` table (checked by the scenario's validation), the route
/// as its mission (`MavlinkEndpoint::load_route_mission`), as the
/// firmware builds it.
///
/// # Errors
/// No route; the endpoint configuration's error, by name and value.
pub fn endpoint(setup: &Setup) -> anyhow::Result<MavlinkEndpoint> {
    let route = setup.route.as_ref().ok_or_else(|| {
        anyhow::anyhow!("sitl needs a route scenario or a robot file with a route")
    })?;
    let config = route
        .mavlink
        .config()
        .map_err(|e| anyhow::anyhow!("MAVLink endpoint: {e}"))?;
    let mut endpoint = MavlinkEndpoint::new(config, route.limits);
    endpoint.load_route_mission(&route.waypoints);
    Ok(endpoint)
}

/// Runs the robot of `setup` behind MAVLink on `link` until the duration
/// is over or `stop` is set. `ready` is called once, before the first
/// tick, with the link (its address is then known).
///
/// # Errors
/// A scenario the SITL cannot run, the endpoint's configuration, a
/// socket error.
pub fn run(
    setup: &Setup,
    options: &SitlOptions,
    stop: &AtomicBool,
    ready: impl FnOnce(&UdpLink),
) -> anyhow::Result<SitlReport> {
    anyhow::ensure!(
        options.speedup.is_finite() && options.speedup > 0.0,
        "--speedup {}: must be finite and > 0",
        options.speedup
    );
    let mut robot = SitlRobot::new(setup)?;
    let mut endpoint = endpoint(setup)?;
    if let Some(tuning) = robot.tuning() {
        endpoint
            .set_tuning(&tuning)
            .map_err(|e| anyhow::anyhow!("the robot's tuning: {e}"))?;
    }
    let mut link = UdpLink::open(options.address)?;
    ready(&link);
    let period_s = robot.period_s();
    let ticks = options
        .duration_s
        .map(|d| (d / period_s).round().min(f64::from(u32::MAX)) as u32);
    let pace = pace::Pace::new(options.speedup);
    let mut plan = Box::new(RoutePlan::empty());
    let mut rx = Vec::new();
    let mut tx_buf = vec![0_u8; TX_BYTES];
    let mut log = Vec::new();
    let mut records = Vec::new();
    let mut routes_done = 0;
    while ticks.is_none_or(|n| robot.ticks() < n) && !stop.load(Ordering::Relaxed) {
        let t_s = f64::from(robot.ticks()) * period_s;
        pace.wait_for(t_s);
        rx.clear();
        link.receive(&mut rx)?;
        let now_ms = (t_s * 1000.0).round() as u64 as u32;
        let view = robot.view();
        let mut tx = TxBuffer::new(&mut tx_buf);
        let events = endpoint.handle(
            now_ms,
            &rx,
            &view,
            |route| plan.replan(route.as_slice(), &robot.limits(), period_s as f32),
            &mut tx,
        );
        let mission = endpoint.route();
        let limits = endpoint.route_limits();
        for &event in events.as_slice() {
            if let Some(line) = robot.apply(event, &mission, limits, endpoint.tuning()) {
                log.push(format!("{t_s:.2} s: {line}"));
            }
        }
        let mode_before = robot.mode();
        let record = *robot.step()?;
        if let Some(counts) = robot.counts() {
            endpoint.set_counts(counts);
        }
        if mode_before != RobotMode::Done && robot.mode() == RobotMode::Done {
            routes_done += 1;
            log.push(format!("{t_s:.2} s: mission done"));
        }
        link.send_frames(tx.as_slice());
        if options.keep_records {
            records.push(record);
        }
    }
    let wall_s = pace.elapsed_s();
    let sim_s = f64::from(robot.ticks()) * period_s;
    let counters: Counters = endpoint.counters();
    let view = robot.view();
    let last = robot.last();
    Ok(SitlReport {
        ticks: robot.ticks(),
        sim_s,
        wall_s,
        speedup_achieved: if wall_s > 0.0 { sim_s / wall_s } else { 0.0 },
        mode: view.mode as u8,
        armed: view.armed,
        routes_done,
        reached: view.reached,
        estimate_m: last.and_then(|r| Some([r.est_x_m?, r.est_y_m?])),
        position_m: last.map(|r| [r.x_m, r.y_m]),
        link_losses: counters.link_losses,
        mission_refusals: counters.mission_refusals,
        command_refusals: counters.command_refusals,
        param_refusals: counters.param_refusals,
        crc_errors: counters.rx.crc_errors,
        link: link.counters(),
        tuning: robot.tuning().map(|t| SitlTuning {
            gains: t.gains,
            fix_timeout_ticks: t.fix_timeout_ticks,
            max_fix_age_ticks: t.max_fix_age_ticks,
            failsafe_decel_m_s2: t.failsafe_decel_m_s2,
            max_encoder_fault_ticks: t.max_encoder_fault_ticks,
        }),
        log,
        records,
    })
}
