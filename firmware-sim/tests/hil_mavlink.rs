//! `firmware-sim hil --mavlink`: a ground station on loopback UDP talks
//! to the release firmware under QEMU through the link's MAVLink channel
//! (docs/hil.md, "A ground station on the firmware under QEMU"): an
//! in-process one (the `mavlink` library) against `run_hil` in a thread,
//! and the real one, `tools/gcs/gcs_check.py --hil` (pymavlink), against
//! this test build's `firmware-sim hil route --mavlink`; each against the
//! default firmware and against the one built with the fusion particle
//! filter; and `[mavlink] power_on` at the firmware's power-on.
//!
//! Needs `qemu-system-arm` and the firmware ELFs, found as
//! `host-tests/tests/hil.rs` finds them: `WMR_FIRMWARE_ELF` and
//! `WMR_FIRMWARE_ELF_FUSION_PARTICLE_FILTER` if set (relative paths from
//! the workspace root; `cargo xtask ci` builds both), else built here
//! into `target/hil-firmware` and
//! `target/hil-firmware-fusion-particle-filter`. The pymavlink check's
//! Python as in `tests/sitl.rs` (`gcs`).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, deprecated)]

mod gcs;

use std::net::UdpSocket;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

use firmware_sim::Scenario;
use firmware_sim::hil::{
    BACKLOG_BYTES, HilOptions, HilRun, MavlinkBridgeSpec, hil_test_firmware, run_hil,
    workspace_root,
};
use firmware_sim::scenario::mavlink::{MavlinkSpec, PowerOnSpec};
use firmware_sim::udp::MavlinkAddress;
use gcs::station::{Gcs, WALL_CAP};
use mavlink::dialects::common::*;
use wmr_core::builds;
use wmr_core::estimation::spec::{EstimatorSpec, FusionFilterSpec};

/// The default QEMU-board firmware (`hil_test_firmware`).
fn firmware() -> PathBuf {
    static ELF: OnceLock<PathBuf> = OnceLock::new();
    ELF.get_or_init(|| hil_test_firmware(None).expect("the QEMU-board firmware"))
        .clone()
}

/// The QEMU-board firmware with the fusion estimator's particle filter
/// (`hil_test_firmware`).
fn particle_filter_firmware() -> PathBuf {
    static ELF: OnceLock<PathBuf> = OnceLock::new();
    ELF.get_or_init(|| {
        hil_test_firmware(Some(builds::FUSION_PARTICLE_FILTER))
            .expect("the QEMU-board firmware with the fusion particle filter")
    })
    .clone()
}

/// `[hil_peak_stack_limit_bytes] name` in `firmware/budgets.toml`: the
/// hard limit of the firmware's peak stack over a HIL run.
fn peak_stack_limit(name: &str) -> u32 {
    let path = workspace_root().join("firmware").join("budgets.toml");
    let text = std::fs::read_to_string(&path).expect("read firmware/budgets.toml");
    let budgets: toml::Table = text.parse().expect("parse firmware/budgets.toml");
    budgets
        .get("hil_peak_stack_limit_bytes")
        .and_then(|t| t.get(name))
        .and_then(toml::Value::as_integer)
        .and_then(|v| u32::try_from(v).ok())
        .unwrap_or_else(|| {
            panic!("firmware/budgets.toml has no [hil_peak_stack_limit_bytes] {name}")
        })
}

/// The in-process ground station, sending a heartbeat every 20 ms of
/// wall time once the robot has spoken.
fn ground_station() -> Gcs {
    let mut gcs = Gcs::new(Duration::from_millis(20));
    gcs.heartbeats = true;
    gcs
}

/// `run_hil` in its thread. Ended through the stop flag, as Ctrl-C ends
/// it, also when an assertion fails first: the firmware is then finished
/// and QEMU exits, instead of running on after this process is gone.
struct Run {
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<anyhow::Result<HilRun>>>,
}

impl Run {
    /// Sets the stop flag and waits for the run's end.
    fn end(mut self) -> anyhow::Result<HilRun> {
        self.stop.store(true, Ordering::Relaxed);
        let thread = self.thread.take().expect("not ended yet");
        thread.join().expect("the run's thread panicked")
    }
}

impl Drop for Run {
    fn drop(&mut self) {
        if let Some(thread) = self.thread.take() {
            self.stop.store(true, Ordering::Relaxed);
            let _ = thread.join();
        }
    }
}

/// The firmware under QEMU answers a ground station on UDP through
/// `run_hil` with a bridge: its heartbeat says it runs the scenario's
/// route (mode 1) armed; a parameter read gives the route's speed limit;
/// a pause is acknowledged accepted and the heartbeat says paused. A
/// flood of garbage past the host's backlog is counted, every datagram
/// sent read by the bridge or counted as dropped by the kernel, every
/// byte read accounted for (sent to the firmware, dropped whole by
/// datagram, or left at the end), none dropped by the firmware's queues (the host
/// never sends more than they hold between two ticks), and the endpoint
/// still answers after it. The stop flag (Ctrl-C) ends the run cleanly:
/// the firmware finished, the host's copy of the session gave every
/// answer the firmware gave, and no route report is made.
#[test]
fn a_ground_station_on_udp_talks_to_the_firmware_under_qemu() {
    let mut gcs = ground_station();
    let mut scenario = Scenario::embedded("route").unwrap();
    scenario.duration_s = 60.0;
    let limit = scenario
        .validate()
        .unwrap()
        .route
        .unwrap()
        .limits_spec
        .max_speed_m_s;
    let run = start(&gcs, scenario, firmware());

    let h = first_heartbeat(&mut gcs);
    assert_eq!(h.mavtype, MavType::MAV_TYPE_GROUND_ROVER);
    assert_eq!(h.custom_mode, 1, "running the scenario's route");
    assert!(armed(&h), "armed");
    assert_eq!(gcs.read_max_speed(), limit);

    pause(&mut gcs);

    // A flood: three times the backlog in datagrams of 1,000 garbage
    // bytes, sent as fast as the socket takes them.
    let garbage = [0x55_u8; 1000];
    for _ in 0..3 * BACKLOG_BYTES / garbage.len() {
        gcs.send_raw(&garbage);
    }
    assert_eq!(gcs.read_max_speed(), limit, "answering after it");
    gcs.last_datagram();

    let run = run.end().expect("the HIL run");
    let report = run.report.mavlink.expect("the bridge's report");
    println!("{report:#?}");
    assert!(report.interrupted);
    assert!(
        run.result.records.len() < 6000,
        "ended by the flag, not at 60 s"
    );
    assert_eq!(report.copy_mismatches, 0, "{report:?}");
    assert!(report.copy_compared >= run.result.records.len() as u64);
    assert!(
        report.dropped_datagrams > 0,
        "the flood overflowed the backlog"
    );
    assert_eq!(report.dropped_bytes, 1000 * report.dropped_datagrams);
    assert_eq!(
        report.udp.datagrams_in + report.udp.kernel_dropped_datagrams.unwrap(),
        gcs.sent,
        "every datagram sent read by the bridge or dropped by the kernel, counted"
    );
    assert_eq!(
        report.udp.bytes_in,
        report.bytes_to_firmware + report.dropped_bytes + report.left_in_backlog_bytes,
        "every byte received accounted for"
    );
    assert_eq!(report.firmware.rx_dropped_bytes, 0);
    assert_eq!(report.firmware.tx_dropped_frames, 0);
    assert!(report.udp.frames_out > 0 && report.udp.frames_unsent == 0);
    assert!(run.result.summary.route.is_none(), "no route report");
}

/// `run_hil` of `scenario` on `firmware` in a thread, bridged at 5x real
/// time to `gcs`'s socket, no telemetry on the firmware's log.
fn start(gcs: &Gcs, scenario: Scenario, firmware: PathBuf) -> Run {
    let port = gcs.port();
    let stop = Arc::new(AtomicBool::new(false));
    let options = HilOptions {
        firmware: Some(firmware),
        answer_timeout: Duration::from_secs(20),
        telemetry_every_ticks: 0,
        mavlink: Some(MavlinkBridgeSpec {
            address: MavlinkAddress::parse(&format!("udp:127.0.0.1:{port}"), false).unwrap(),
            speedup: 5.0,
            stop: Some(Arc::clone(&stop)),
            // No signal handler here: Ctrl-C on `cargo test` ends QEMU
            // with the test.
            stops_on_signals: false,
            announce: None,
        }),
        ..HilOptions::default()
    };
    Run {
        stop,
        thread: Some(std::thread::spawn(move || {
            run_hil(&scenario, &options, |_, _| {})
        })),
    }
}

/// The robot's estimated distance east (the floor's x) in a
/// `LOCAL_POSITION_NED` past `east_m`.
fn east_of(m: &MavMessage, east_m: f32) -> bool {
    matches!(m, MavMessage::LOCAL_POSITION_NED(p) if p.y > east_m)
}

/// The robot's first heartbeat, within 5 s of the ground station's wall
/// time.
fn first_heartbeat(gcs: &mut Gcs) -> HEARTBEAT_DATA {
    let MavMessage::HEARTBEAT(h) = gcs.wait("the robot's heartbeat", 5000, |m| {
        matches!(m, MavMessage::HEARTBEAT(_))
    }) else {
        unreachable!()
    };
    h
}

/// A pause sent, acknowledged accepted, and a heartbeat saying paused
/// (custom mode 2) within 5 s.
fn pause(gcs: &mut Gcs) {
    assert_eq!(
        gcs.command(MavCmd::MAV_CMD_DO_PAUSE_CONTINUE, 0.0),
        MavResult::MAV_RESULT_ACCEPTED
    );
    gcs.wait(
        "paused",
        5000,
        |m| matches!(m, MavMessage::HEARTBEAT(h) if h.custom_mode == 2),
    );
}

/// Whether a heartbeat says the robot is armed.
fn armed(h: &HEARTBEAT_DATA) -> bool {
    h.base_mode
        .contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED)
}

/// The run ends on the route's first leg: past 0.25 m east, within 5 cm
/// of its line.
fn assert_on_first_leg(records: &[firmware_sim::Record]) {
    let last = records.last().unwrap();
    assert!(
        last.x_m > 0.25 && last.y_m.abs() < 0.05,
        "on the first leg: ({:.3}, {:.3})",
        last.x_m,
        last.y_m
    );
}

/// The first record whose motor duty or command is not zero.
fn first_driven(records: &[firmware_sim::Record]) -> Option<&firmware_sim::Record> {
    records.iter().find(|r| {
        r.v_cmd_m_s != 0.0
            || r.omega_cmd_rad_s != 0.0
            || r.left_duty.is_some_and(|d| d != 0.0)
            || r.right_duty.is_some_and(|d| d != 0.0)
    })
}

/// The `route` scenario for 60 s with its robot file's `[mavlink]
/// power_on`; the number of its route's waypoints.
fn route_with_power_on(power_on: PowerOnSpec) -> (Scenario, usize) {
    let mut scenario = Scenario::embedded("route").unwrap();
    scenario.duration_s = 60.0;
    scenario.mavlink = Some(MavlinkSpec {
        power_on,
        ..MavlinkSpec::default()
    });
    let waypoints = scenario
        .validate()
        .unwrap()
        .route
        .unwrap()
        .waypoints
        .as_slice()
        .len();
    (scenario, waypoints)
}

/// The firmware built with the fusion particle filter has the MAVLink
/// endpoint too: on the `route` scenario with the particle filter as its
/// fusion estimator (wheel noise 2e-7 m²/m, as `host-tests/tests/hil.rs`
/// tunes it), a ground station sees it run the route armed and drive
/// past its first station,
/// reads a parameter, pauses it (acknowledged, then reported) and
/// uploads a mission (accepted, read back). The
/// filter used the tags' fixes; the host's copy of the session gave every
/// answer the firmware gave and no byte was dropped; the firmware's peak
/// stack, the endpoint's and the filter's paths both run, is within the
/// particle filter's hard limit (`[hil_peak_stack_limit_bytes]`).
#[test]
fn a_ground_station_talks_to_the_particle_filter_firmware_under_qemu() {
    let mut gcs = ground_station();
    let mut scenario = Scenario::embedded("route").unwrap();
    scenario.duration_s = 60.0;
    let EstimatorSpec::Fusion(fusion) = &mut scenario.estimator else {
        panic!("the route scenario's estimator is the fusion estimator")
    };
    fusion.filter = FusionFilterSpec::ParticleFilter;
    fusion.wheel_variance_per_m = 2e-7;
    let limit = scenario
        .validate()
        .unwrap()
        .route
        .unwrap()
        .limits_spec
        .max_speed_m_s;
    let run = start(&gcs, scenario, particle_filter_firmware());

    let h = first_heartbeat(&mut gcs);
    assert_eq!(h.custom_mode, 1, "running the scenario's route");
    assert!(armed(&h), "armed");
    // Past station A (1 m east, a stop of 2 s).
    gcs.wait("driving 1.5 m east", 20_000, |m| east_of(m, 1.5));
    assert_eq!(gcs.read_max_speed(), limit);
    pause(&mut gcs);
    // A mission uploaded (the endpoint's deepest path) and read back.
    let mission = [(0.0, 0.0, 0.0), (0.5, 0.0, 0.0), (0.5, 0.4, 0.5)];
    assert_eq!(gcs.upload(&mission), MavMissionResult::MAV_MISSION_ACCEPTED);
    assert_eq!(usize::from(gcs.mission_count()), mission.len());
    gcs.last_datagram();

    let run = run.end().expect("the HIL run");
    let report = run.report.mavlink.expect("the bridge's report");
    let tracker = run.result.summary.tracker.expect("tracker report");
    println!(
        "particle filter firmware with a ground station: {} ticks, {} fixes used, \
         peak stack {} B",
        run.result.records.len(),
        tracker.fixes_used,
        run.report.peak_stack_bytes
    );
    assert!(tracker.fixes_used > 0, "{tracker:?}");
    assert_eq!(report.copy_mismatches, 0, "{report:?}");
    assert!(report.copy_compared >= run.result.records.len() as u64);
    assert_eq!(report.firmware.rx_dropped_bytes, 0);
    assert_eq!(report.firmware.tx_dropped_frames, 0);
    assert!(report.udp.frames_out > 0 && report.udp.frames_unsent == 0);
    let peak = run.report.peak_stack_bytes;
    assert!(peak > 0, "the stack was not painted");
    let limit = peak_stack_limit("fusion_particle_filter");
    assert!(
        peak <= limit,
        "peak stack {peak} B, over its limit of {limit} B"
    );
}

/// `[mavlink] power_on = "wait"` reaches the firmware under QEMU with the
/// route's announcement: it stays disarmed and idle, with the scenario's
/// route as its mission, refusing to start disarmed, its motors at zero
/// and the robot where it was put, for the 2 s of the robot's time the
/// ground station waits; armed and started (the route loaded at power-on,
/// no upload), it runs and drives the route's first leg (east).
#[test]
fn with_power_on_wait_the_firmware_under_qemu_waits_until_armed_and_started() {
    let mut gcs = ground_station();
    let (scenario, waypoints) = route_with_power_on(PowerOnSpec::Wait);
    let run = start(&gcs, scenario, firmware());

    let h = first_heartbeat(&mut gcs);
    assert_eq!(h.custom_mode, 0, "idle");
    assert!(!armed(&h), "disarmed");
    assert_eq!(
        usize::from(gcs.mission_count()),
        waypoints,
        "the route is the mission"
    );
    gcs.wait(
        "2 s of the robot's time",
        5000,
        |m| matches!(m, MavMessage::LOCAL_POSITION_NED(p) if p.time_boot_ms >= 2000),
    );
    assert_eq!(
        gcs.command(MavCmd::MAV_CMD_MISSION_START, 0.0),
        MavResult::MAV_RESULT_DENIED,
        "disarmed"
    );
    assert_eq!(
        gcs.command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, 1.0),
        MavResult::MAV_RESULT_ACCEPTED
    );
    // The robot's time the start is sent after (its telemetry's latest).
    let started_after_ms = gcs.sim_ms;
    assert_eq!(
        gcs.command(MavCmd::MAV_CMD_MISSION_START, 0.0),
        MavResult::MAV_RESULT_ACCEPTED
    );
    let MavMessage::HEARTBEAT(h) = gcs.wait(
        "running",
        5000,
        |m| matches!(m, MavMessage::HEARTBEAT(h) if h.custom_mode == 1),
    ) else {
        unreachable!()
    };
    assert!(armed(&h), "armed");
    gcs.wait("driving 0.3 m east", 10_000, |m| east_of(m, 0.3));

    let run = run.end().expect("the HIL run");
    let records = &run.result.records;
    let driven = first_driven(records).expect("driven after the start");
    println!(
        "power_on = wait: started after {started_after_ms} ms of the robot's time, \
         first driven at {:.2} s",
        driven.t_s
    );
    assert!(
        driven.t_s * 1000.0 >= f64::from(started_after_ms),
        "driven at {:.2} s, before the start (after {started_after_ms} ms)",
        driven.t_s
    );
    let rest = &records[0];
    for r in records.iter().take_while(|r| r.t_s < driven.t_s) {
        assert!(
            (r.x_m - rest.x_m).hypot(r.y_m - rest.y_m) < 1e-6,
            "moved while waiting, at {:.2} s",
            r.t_s
        );
    }
    assert_on_first_leg(records);
    let report = run.report.mavlink.expect("the bridge's report");
    assert_eq!(report.copy_mismatches, 0, "{report:?}");
}

/// `[mavlink] power_on = "run"` (as without a `[mavlink]` table): the
/// firmware under QEMU is armed and runs the scenario's route (its
/// mission) from power-on, driving from its first ticks, no ground
/// station's command needed.
#[test]
fn with_power_on_run_the_firmware_under_qemu_drives_from_power_on() {
    let mut gcs = ground_station();
    let (scenario, waypoints) = route_with_power_on(PowerOnSpec::Run);
    let run = start(&gcs, scenario, firmware());

    let h = first_heartbeat(&mut gcs);
    assert_eq!(h.custom_mode, 1, "running the scenario's route");
    assert!(armed(&h), "armed");
    assert_eq!(
        usize::from(gcs.mission_count()),
        waypoints,
        "the route is the mission"
    );
    gcs.wait("driving 0.3 m east", 10_000, |m| east_of(m, 0.3));

    let run = run.end().expect("the HIL run");
    let records = &run.result.records;
    let driven = first_driven(records).expect("driven");
    println!("power_on = run: first driven at {:.2} s", driven.t_s);
    assert!(driven.t_s < 0.1, "first driven at {:.2} s", driven.t_s);
    assert_on_first_leg(records);
}

/// The pymavlink ground station (`tools/gcs/gcs_check.py --hil`) against
/// this build's `firmware-sim hil route --mavlink`, at 20x real time:
/// every check of the SITL's list passes, the global-frame mission too
/// (the origin reaches the firmware with the route's announcement).
#[test]
fn pymavlink_ground_station_against_the_firmware_under_qemu() {
    let elf = firmware();
    let (passed, skipped) = gcs::gcs_check(&[
        "--hil",
        "--firmware",
        elf.to_str().unwrap(),
        "--speedup",
        "20",
    ]);
    assert!(passed >= 34, "only {passed} checks ran");
    assert_eq!(
        skipped, 0,
        "the firmware has every feature the script checks"
    );
}

/// The same pymavlink ground station against the firmware built with the
/// fusion particle filter, on the route with that filter
/// (`--particle-filter`): every check passes, and the filter used the
/// tags' fixes (one check more).
#[test]
fn pymavlink_ground_station_against_the_particle_filter_firmware_under_qemu() {
    let elf = particle_filter_firmware();
    let (passed, skipped) = gcs::gcs_check(&[
        "--hil",
        "--firmware",
        elf.to_str().unwrap(),
        "--speedup",
        "20",
        "--particle-filter",
    ]);
    assert!(passed >= 35, "only {passed} checks ran");
    assert_eq!(
        skipped, 0,
        "the firmware has every feature the script checks"
    );
}

/// The ground station's address is bound before QEMU boots: an address
/// in use is the run's first error (a file that is no firmware would
/// otherwise fail first, after QEMU's start).
#[test]
fn the_ground_stations_port_is_bound_before_qemu_boots() {
    let taken = UdpSocket::bind("127.0.0.1:0").unwrap();
    let port = taken.local_addr().unwrap().port();
    let options = HilOptions {
        firmware: Some(workspace_root().join("Cargo.toml")),
        answer_timeout: Duration::from_secs(20),
        telemetry_every_ticks: 0,
        mavlink: Some(MavlinkBridgeSpec {
            address: MavlinkAddress::parse(&format!("udpin:127.0.0.1:{port}"), false).unwrap(),
            speedup: 5.0,
            stop: None,
            stops_on_signals: false,
            announce: None,
        }),
        ..HilOptions::default()
    };
    let started = Instant::now();
    let Err(e) = run_hil(&Scenario::embedded("route").unwrap(), &options, |_, _| {}) else {
        panic!("a run on a port in use")
    };
    assert!(format!("{e:#}").contains("binding"), "{e:#}");
    assert!(
        started.elapsed() < Duration::from_secs(5),
        "QEMU was waited on"
    );
}

/// QEMU does not outlive a `firmware-sim hil` killed with SIGKILL (no
/// clean-up runs): started through `setpriv --pdeathsig KILL` where
/// util-linux has it, the kernel kills it with its parent.
#[cfg(target_os = "linux")]
#[test]
fn qemu_dies_with_a_killed_firmware_sim() {
    if std::process::Command::new("setpriv")
        .arg("--version")
        .output()
        .is_err()
    {
        eprintln!("skipped: no setpriv (util-linux) on this machine");
        return;
    }
    let elf = firmware();
    let out = tempfile::tempdir().unwrap();
    let mut sim = std::process::Command::new(env!("CARGO_BIN_EXE_firmware-sim"))
        .args(["hil", "route", "--duration-s", "600", "--no-plot"])
        .args(["--telemetry-every", "0", "--mavlink", "udpin:127.0.0.1:0"])
        .arg("--firmware")
        .arg(&elf)
        .arg("--out")
        .arg(out.path())
        .stdin(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    // QEMU: the child of firmware-sim (`/proc/PID/stat`: pid (comm) state ppid).
    let stat = |pid: &str| std::fs::read_to_string(format!("/proc/{pid}/stat")).ok();
    let parent_and_state = |text: &str| {
        let rest = text.rsplit_once(") ")?.1;
        let mut fields = rest.split_whitespace();
        let state = fields.next()?.to_owned();
        Some((fields.next()?.parse::<u32>().ok()?, state))
    };
    let started = Instant::now();
    let qemu = loop {
        let found = std::fs::read_dir("/proc").unwrap().find_map(|entry| {
            let name = entry.ok()?.file_name().into_string().ok()?;
            let text = stat(&name)?;
            let (ppid, _) = parent_and_state(&text)?;
            (ppid == sim.id() && text.contains("(qemu-system-arm)")).then_some(name)
        });
        if let Some(pid) = found {
            break pid;
        }
        assert!(started.elapsed() < WALL_CAP, "no QEMU under firmware-sim");
        std::thread::sleep(Duration::from_millis(20));
    };
    sim.kill().unwrap();
    sim.wait().unwrap();
    let killed = Instant::now();
    // Gone, or a zombie not yet reaped by its new parent.
    while let Some((_, state)) = stat(&qemu).as_deref().and_then(parent_and_state) {
        if state == "Z" || state == "X" {
            break;
        }
        assert!(
            killed.elapsed() < Duration::from_secs(10),
            "QEMU {qemu} still running 10 s after firmware-sim was killed"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}
