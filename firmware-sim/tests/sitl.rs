//! `firmware-sim sitl`: an in-process ground station (the `mavlink`
//! library over a loopback UDP socket) against the SITL loop running in a
//! thread, on the embedded `route` scenario's robot; the robot's modes
//! without a socket; and a real ground station, `tools/gcs/gcs_check.py`
//! (pymavlink), against this test build's `firmware-sim sitl route
//! --speedup 50` (docs/mavlink.md, "The SITL").
//!
//! The pymavlink check is run as `tests/hil_mavlink.rs` runs it against
//! the firmware under QEMU (`gcs`: its Python).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, deprecated)]

mod gcs;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use firmware_sim::Scenario;
use firmware_sim::scenario::Setup;
use firmware_sim::scenario::mavlink::{MavlinkSpec, PowerOnSpec};
use firmware_sim::sitl::{self, MavlinkAddress, SitlOptions, SitlReport};
use gcs::station::Gcs;
use mavlink::dialects::common::*;

/// The `route` scenario with `power_on` and a telemetry period of
/// `telemetry_period_ms`.
fn route_setup(power_on: PowerOnSpec, telemetry_period_ms: u64) -> Setup {
    let mut scenario = Scenario::embedded("route").unwrap();
    scenario.mavlink = Some(MavlinkSpec {
        power_on,
        telemetry_period_ms,
        ..MavlinkSpec::default()
    });
    scenario.validate().unwrap()
}

/// Runs the SITL on the `route` scenario's robot in a thread, waiting
/// disarmed at power-on; the ground station, the stop flag and the
/// thread.
fn start(speedup: f64) -> (Gcs, Arc<AtomicBool>, std::thread::JoinHandle<SitlReport>) {
    // Heartbeats (once turned on) every 5 ms of wall time.
    let gcs = Gcs::new(Duration::from_millis(5));
    let setup = route_setup(PowerOnSpec::Wait, 100);
    let options = SitlOptions {
        address: MavlinkAddress::parse(&format!("udp:127.0.0.1:{}", gcs.port()), false).unwrap(),
        speedup,
        duration_s: Some(600.0),
        keep_records: true,
    };
    let stop = Arc::new(AtomicBool::new(false));
    let flag = Arc::clone(&stop);
    let thread = std::thread::spawn(move || sitl::run(&setup, &options, &flag, |_| {}).unwrap());
    (gcs, stop, thread)
}

const MISSION: [(f32, f32, f32); 3] = [(0.0, 0.0, 0.0), (0.5, 0.0, 0.0), (0.5, 0.4, 0.5)];

/// A first leg of 2 m: still driving 3 s after it started.
const LONG_MISSION: [(f32, f32, f32); 3] = [(0.0, 0.0, 0.0), (2.0, 0.0, 0.0), (2.0, 1.0, 0.0)];

#[test]
fn an_uploaded_mission_is_driven_to_its_end() {
    // No ground-station heartbeat: no link watch, so any speed-up works.
    let (mut gcs, stop, thread) = start(100.0);
    gcs.wait("the robot's heartbeat", 5000, |m| {
        matches!(m, MavMessage::HEARTBEAT(_))
    });
    assert_eq!(gcs.upload(&MISSION), MavMissionResult::MAV_MISSION_ACCEPTED);
    assert_eq!(
        gcs.command(MavCmd::MAV_CMD_MISSION_START, 0.0),
        MavResult::MAV_RESULT_DENIED,
        "disarmed"
    );
    assert_eq!(
        gcs.command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, 1.0),
        MavResult::MAV_RESULT_ACCEPTED
    );
    assert_eq!(
        gcs.command(MavCmd::MAV_CMD_MISSION_START, 0.0),
        MavResult::MAV_RESULT_ACCEPTED
    );
    gcs.mode_is("running", 1, 2000);
    gcs.mode_is("done", 3, 60_000);
    gcs.wait("the last reached", 1000, |m| {
        matches!(m, MavMessage::LOCAL_POSITION_NED(_))
    });
    stop.store(true, Ordering::Relaxed);
    let report = thread.join().unwrap();
    assert_eq!(gcs.reached, vec![0, 1, 2]);
    assert_eq!(
        (report.routes_done, report.reached, report.mode),
        (1, Some(2), 3)
    );
    assert_eq!(report.link_losses, 0);
    // The robot itself (the plant's truth) on the last waypoint.
    let [x, y] = report.position_m.unwrap();
    assert!((x - 0.5).hypot(y - 0.4) < 0.02, "ended at ({x:.4}, {y:.4})");
    // The follower ran the uploaded route: it started once, stopped at
    // the last waypoint, the command held at exactly zero since.
    let last = report.records.last().unwrap();
    assert_eq!((last.v_cmd_m_s, last.omega_cmd_rad_s), (0.0, 0.0));
    assert!(
        report
            .log
            .iter()
            .any(|l| l.contains("mission of 3 items loaded")),
        "{:?}",
        report.log
    );
}

#[test]
fn a_lost_link_stops_the_robot_mid_leg() {
    // 5x real time: heartbeats every 5 ms of wall time are 25 ms of the
    // robot's, far inside the 3 s link timeout even on a loaded machine.
    let (mut gcs, stop, thread) = start(5.0);
    gcs.wait("the robot's heartbeat", 5000, |m| {
        matches!(m, MavMessage::HEARTBEAT(_))
    });
    gcs.heartbeats = true;
    assert_eq!(
        gcs.upload(&LONG_MISSION),
        MavMissionResult::MAV_MISSION_ACCEPTED
    );
    assert_eq!(
        gcs.command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, 1.0),
        MavResult::MAV_RESULT_ACCEPTED
    );
    assert_eq!(
        gcs.command(MavCmd::MAV_CMD_MISSION_START, 0.0),
        MavResult::MAV_RESULT_ACCEPTED
    );
    gcs.wait(
        "moving",
        30_000,
        |m| matches!(m, MavMessage::LOCAL_POSITION_NED(p) if p.vx.hypot(p.vy) > 0.1),
    );
    gcs.heartbeats = false;
    let silent_from_ms = gcs.sim_ms;
    gcs.wait(
        "link lost",
        10_000,
        |m| matches!(m, MavMessage::STATUSTEXT(s) if s.text.starts_with(b"link lost")),
    );
    gcs.mode_is("stopped", 4, 1000);
    let at = gcs.sim_ms;
    gcs.wait(
        "3 s after the loss",
        10_000,
        |m| matches!(m, MavMessage::LOCAL_POSITION_NED(p) if p.time_boot_ms >= at + 5000),
    );
    stop.store(true, Ordering::Relaxed);
    let report = thread.join().unwrap();
    assert_eq!(
        (report.link_losses, report.mode, report.routes_done),
        (1, 4, 0)
    );
    assert!(
        report.reached.is_none_or(|r| r < 2),
        "stopped before the end"
    );
    let lost_at = report
        .log
        .iter()
        .find_map(|l| {
            l.strip_suffix(" s: link lost: stopped (disarm, re-arm to restart)")
                .map(|t| t.parse::<f64>().unwrap())
        })
        .expect("the loss in the log");
    // The loss 3 s (the link timeout) after the last heartbeat: that went
    // out within a few ms of wall time of the position message that ended
    // the heartbeats; 0.5 s of the robot's time allowed either side for
    // the scheduling of two threads on a loaded machine.
    let silence = lost_at - f64::from(silent_from_ms) / 1000.0;
    assert!(
        (2.5..=3.5).contains(&silence),
        "lost {silence:.2} s after the heartbeats stopped"
    );
    // Stopped: from the loss on, the command ramps down to exactly zero
    // and stays there, the robot still.
    let h = 0.01;
    let after: Vec<_> = report
        .records
        .iter()
        .filter(|r| r.t_s >= lost_at - h / 2.0)
        .collect();
    assert!(after[0].v_cmd_m_s > 0.05, "moving when the link was lost");
    let settle = after
        .iter()
        .position(|r| r.v_cmd_m_s == 0.0 && r.omega_cmd_rad_s == 0.0)
        .expect("settled");
    assert!(
        after[settle..]
            .iter()
            .all(|r| r.v_cmd_m_s == 0.0 && r.omega_cmd_rad_s == 0.0)
    );
    assert!(
        settle as f64 * h < 2.0,
        "the ramp down took {} s",
        settle as f64 * h
    );
    let (rest, end) = (after[settle + 50], after.last().unwrap());
    assert!(end.t_s - rest.t_s > 2.0);
    assert!(
        (end.x_m - rest.x_m).hypot(end.y_m - rest.y_m) < 1e-3,
        "the robot moved at rest"
    );
}

/// The robot's modes without a socket: events applied at tick boundaries
/// as the SITL's loop applies the endpoint's.
#[test]
fn a_pause_holds_mid_leg_and_a_continue_finishes_the_mission() {
    use firmware_sim::sitl::SitlRobot;
    use wmr_core::reference::route::{Waypoint, Waypoints};
    use wmr_mavlink::{Event, RobotMode};

    let setup = route_setup(PowerOnSpec::Wait, 200);
    let limits = setup.route.as_ref().unwrap().limits;
    let mut robot = SitlRobot::new(&setup).unwrap();
    let mission = Waypoints::from_slice(&[
        Waypoint::pass(0.0, 0.0),
        Waypoint::pass(1.5, 0.0),
        Waypoint::stop(1.5, 0.5, 0.5),
    ])
    .unwrap();
    for event in [Event::LoadRoute, Event::Arm, Event::Start] {
        robot.apply(event, &mission, limits, None);
    }
    assert_eq!(robot.mode(), RobotMode::Running);
    // Mid-leg: past 0.6 m, moving.
    let mut moving_at = None;
    for _ in 0..3000 {
        let r = robot.step().unwrap();
        if r.x_m > 0.6 && r.v_cmd_m_s > 0.1 {
            moving_at = Some(r.x_m);
            break;
        }
    }
    assert!(moving_at.is_some(), "never mid-leg");
    robot.apply(Event::Pause, &mission, limits, None);
    assert_eq!(robot.mode(), RobotMode::Paused);
    let mut settled = None;
    for k in 0..300 {
        let r = robot.step().unwrap();
        if r.v_cmd_m_s == 0.0 && r.omega_cmd_rad_s == 0.0 {
            settled = Some((k, r.x_m, r.y_m));
            break;
        }
    }
    let (k, x, y) = settled.expect("at rest within 3 s");
    assert!(
        f64::from(k) * 0.01 < 2.0 && x < 1.4,
        "held mid-leg: {k} ticks, x {x:.3}"
    );
    for _ in 0..200 {
        let r = robot.step().unwrap();
        assert_eq!((r.v_cmd_m_s, r.omega_cmd_rad_s), (0.0, 0.0));
        assert!((r.x_m - x).hypot(r.y_m - y) < 1e-3, "moved while paused");
    }
    assert_eq!(robot.view().current, 1, "still driving to item 1");
    robot.apply(Event::Continue, &mission, limits, None);
    assert_eq!(robot.mode(), RobotMode::Running);
    for _ in 0..6000 {
        robot.step().unwrap();
        if robot.mode() == RobotMode::Done {
            break;
        }
    }
    assert_eq!(robot.mode(), RobotMode::Done);
    assert_eq!(robot.view().reached, Some(2));
    let last = robot.last().unwrap();
    assert!(
        (last.x_m - 1.5).hypot(last.y_m - 0.5) < 0.02,
        "ended at ({:.4}, {:.4})",
        last.x_m,
        last.y_m
    );
    // A disarm holds and idles.
    robot.apply(Event::Disarm, &mission, limits, None);
    assert_eq!((robot.mode(), robot.view().armed), (RobotMode::Idle, false));
}

#[test]
fn pymavlink_ground_station_against_the_sitl() {
    let (passed, skipped) = gcs::gcs_check(&["--speedup", "50"]);
    assert!(passed >= 31, "only {passed} checks ran");
    assert_eq!(skipped, 0, "the SITL has every feature the script checks");
}

/// A mission uploaded while the robot drives replaces the running route
/// at its next rest (the core's replacement), and is driven to its end.
#[test]
fn a_mission_uploaded_while_driving_replaces_the_route_at_its_next_rest() {
    use firmware_sim::sitl::SitlRobot;
    use wmr_core::reference::route::{Waypoint, Waypoints};
    use wmr_mavlink::{Event, RobotMode};

    let setup = route_setup(PowerOnSpec::Wait, 200);
    let limits = setup.route.as_ref().unwrap().limits;
    let mut robot = SitlRobot::new(&setup).unwrap();
    let first = Waypoints::from_slice(&[
        Waypoint::pass(0.0, 0.0),
        Waypoint::stop(1.0, 0.0, 0.5),
        Waypoint::stop(2.0, 0.0, 0.5),
    ])
    .unwrap();
    for event in [Event::LoadRoute, Event::Arm, Event::Start] {
        robot.apply(event, &first, limits, None);
    }
    for _ in 0..3000 {
        let r = robot.step().unwrap();
        if r.x_m > 0.5 {
            break;
        }
    }
    // The replacement's first waypoint is taken as the rest point where
    // the running route next rests: (1, 0).
    let second = Waypoints::from_slice(&[
        Waypoint::pass(1.0, 0.0),
        Waypoint::pass(1.0, 0.6),
        Waypoint::stop(0.4, 0.6, 0.0),
    ])
    .unwrap();
    robot.apply(Event::LoadRoute, &second, limits, None);
    assert_eq!(robot.mode(), RobotMode::Running);
    let mut max_x: f64 = 0.0;
    for _ in 0..6000 {
        let r = robot.step().unwrap();
        max_x = max_x.max(r.x_m);
        if robot.mode() == RobotMode::Done {
            break;
        }
    }
    assert_eq!(robot.mode(), RobotMode::Done);
    assert_eq!(robot.view().reached, Some(2));
    assert!(
        max_x < 1.1,
        "drove on toward the first mission's end: x {max_x:.3}"
    );
    let last = robot.last().unwrap();
    assert!(
        (last.x_m - 0.4).hypot(last.y_m - 0.6) < 0.02,
        "ended at ({:.4}, {:.4})",
        last.x_m,
        last.y_m
    );
}

/// Without a ground station the SITL's robot is the robot file's: with
/// `power_on = "run"` (the default, as the firmware starts) it drives the
/// scenario's route from power-on, tick for tick as `firmware-sim run`
/// does; with `"wait"` it holds, disarmed and idle, the route loaded as
/// the mission, until armed and started, then drives that route to its
/// end.
#[test]
fn at_power_on_the_sitl_runs_or_waits_as_the_robot_file_says() {
    use firmware_sim::sitl::SitlRobot;
    use wmr_core::reference::route::Waypoints;
    use wmr_mavlink::{Event, RobotMode};

    let scenario = Scenario::embedded("route").unwrap();
    let run = firmware_sim::run(&scenario, |_, _| {}).unwrap();
    let setup = route_setup(PowerOnSpec::Run, 200);
    let mut robot = SitlRobot::new(&setup).unwrap();
    assert_eq!(
        (robot.mode(), robot.view().armed),
        (RobotMode::Running, true)
    );
    assert!(run.records.len() > 1000, "{} ticks", run.records.len());
    for (k, expected) in run.records.iter().enumerate() {
        let got = robot.step().unwrap();
        assert_eq!(got, expected, "tick {k}");
    }
    assert_eq!(robot.mode(), RobotMode::Done, "the route's end reached");

    let setup = route_setup(PowerOnSpec::Wait, 200);
    let route = setup.route.as_ref().unwrap();
    let mut robot = SitlRobot::new(&setup).unwrap();
    assert_eq!((robot.mode(), robot.view().armed), (RobotMode::Idle, false));
    let start = *robot.step().unwrap();
    for _ in 0..500 {
        let r = robot.step().unwrap();
        assert_eq!((r.v_cmd_m_s, r.omega_cmd_rad_s), (0.0, 0.0));
        assert!((r.x_m - start.x_m).hypot(r.y_m - start.y_m) < 1e-6);
    }
    // Arm and start: the route loaded at power-on (no upload).
    let none = Waypoints::new();
    for event in [Event::Arm, Event::Start] {
        robot.apply(event, &none, route.limits, None);
    }
    assert_eq!(robot.mode(), RobotMode::Running);
    for _ in 0..run.records.len() * 2 {
        robot.step().unwrap();
        if robot.mode() == RobotMode::Done {
            break;
        }
    }
    assert_eq!(robot.mode(), RobotMode::Done);
    let last = route.waypoints.as_slice().last().unwrap().position_m;
    let end = robot.last().unwrap();
    assert!(
        (end.x_m - f64::from(last.x)).hypot(end.y_m - f64::from(last.y)) < 0.02,
        "ended at ({:.4}, {:.4})",
        end.x_m,
        end.y_m
    );
}

/// Sets a PARAM (REAL32) and returns the PARAM_VALUE answered for it and
/// whether a STATUSTEXT naming it came before that answer's next
/// heartbeat.
fn set_param(gcs: &mut Gcs, name: &str, value: f32) -> (f32, Option<String>) {
    let mut id = [0u8; 16];
    id[..name.len()].copy_from_slice(name.as_bytes());
    gcs.send(&MavMessage::PARAM_SET(PARAM_SET_DATA {
        param_value: value,
        target_system: 1,
        target_component: 1,
        param_id: id.into(),
        param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
    }));
    let answer = match gcs.wait(
        name,
        5000,
        |m| matches!(m, MavMessage::PARAM_VALUE(p) if p.param_id[..] == id[..]),
    ) {
        MavMessage::PARAM_VALUE(p) => p.param_value,
        _ => unreachable!(),
    };
    let mut text = None;
    gcs.wait("the next heartbeat", 5000, |m| match m {
        MavMessage::STATUSTEXT(t) => {
            text = Some(
                String::from_utf8_lossy(&t.text[..])
                    .trim_end_matches('\0')
                    .to_string(),
            );
            false
        }
        m => matches!(m, MavMessage::HEARTBEAT(_)),
    });
    (answer, text)
}

/// A ground station tunes the SITL's robot: a gain and a failsafe time
/// set are the robot's own after (its pilot's configuration), a bad gain
/// is refused by name with the old value, and the tracker's and RFID
/// reader's counters arrive as NAMED_VALUE_INT.
#[test]
fn gains_set_over_mavlink_are_the_robots_and_its_counters_arrive() {
    let (mut gcs, stop, thread) = start(100.0);
    gcs.wait("the robot's heartbeat", 5000, |m| {
        matches!(m, MavMessage::HEARTBEAT(_))
    });
    // The route scenario's k1 = 2, its fix timeout 0.5 s / 10 ms.
    assert_eq!(set_param(&mut gcs, "TRK_K1", 1.5), (1.5, None));
    assert_eq!(set_param(&mut gcs, "FS_DECEL", 0.8), (0.8, None));
    assert_eq!(
        set_param(&mut gcs, "TRK_K2", -2.0),
        (2.0, Some("refused: TRK_K2".to_string()))
    );
    // The counters: each of the default 5 s period's names, the RFID
    // reader's frames counted (the route scenario reads tags).
    let mut seen = std::collections::BTreeMap::new();
    gcs.wait("every counter", 20_000, |m| {
        if let MavMessage::NAMED_VALUE_INT(v) = m {
            let name = String::from_utf8_lossy(&v.name[..])
                .trim_end_matches('\0')
                .to_string();
            seen.insert(name, v.value);
        }
        seen.len() == wmr_mavlink::COUNTERS
    });
    stop.store(true, Ordering::Relaxed);
    let report = thread.join().unwrap();
    for name in wmr_mavlink::COUNTER_NAMES {
        assert!(seen.contains_key(name), "{name}: {seen:?}");
    }
    assert!(seen["RF_FRAMES"] > 0, "{seen:?}");
    let tuning = report.tuning.unwrap();
    assert_eq!(tuning.gains, Some([1.5, 2.0, 1.0]));
    assert_eq!(tuning.failsafe_decel_m_s2, 0.8);
    assert_eq!(tuning.fix_timeout_ticks, 50);
    assert_eq!(report.param_refusals, 1);
}

/// A gain set mid-leg changes the robot's command from the next tick
/// on, and only from then: the same mission run twice, one retuned.
#[test]
fn a_gain_set_mid_leg_changes_the_command_from_the_next_tick() {
    use firmware_sim::sitl::SitlRobot;
    use wmr_core::reference::route::{Waypoint, Waypoints};
    use wmr_mavlink::Event;

    // Waiting at power-on, so that the mission below is the only route.
    let setup = route_setup(PowerOnSpec::Wait, 100);
    let limits = setup.route.as_ref().unwrap().limits;
    let mission = Waypoints::from_slice(&[
        Waypoint::pass(0.0, 0.0),
        Waypoint::pass(1.5, 0.0),
        Waypoint::stop(1.5, 0.5, 0.5),
    ])
    .unwrap();
    let run = |retune_at: Option<u32>| {
        let mut robot = SitlRobot::new(&setup).unwrap();
        for event in [Event::LoadRoute, Event::Arm, Event::Start] {
            robot.apply(event, &mission, limits, None);
        }
        let mut tuning = robot.tuning().unwrap();
        tuning.gains = Some([0.3, 0.3, 0.2]);
        let tuning = tuning.build().unwrap();
        let mut commands = Vec::new();
        for k in 0..600 {
            if Some(k) == retune_at {
                robot.apply(Event::Tuning, &mission, limits, Some(tuning));
            }
            let r = robot.step().unwrap();
            commands.push((r.v_cmd_m_s, r.omega_cmd_rad_s));
        }
        (commands, robot.tuning().unwrap())
    };
    let (plain, before) = run(None);
    let (tuned, after) = run(Some(300));
    assert_eq!(before.gains, Some([2.0, 2.0, 1.0]));
    assert_eq!(after.gains, Some([0.3, 0.3, 0.2]));
    assert_eq!(plain[..300], tuned[..300], "the same before the set");
    assert!(plain[300].0 > 0.05, "mid-leg, moving");
    assert_ne!(plain[300], tuned[300], "the new gains from the next tick");
}
