//! Hardware-in-the-loop: the release firmware (QEMU board) under
//! `qemu-system-arm -M netduinoplus2`, in lock-step with the simulator.
//!
//! Needs `qemu-system-arm` (the README's test command installs it) and the
//! firmware ELF: `WMR_FIRMWARE_ELF` if set (absolute, or relative to the
//! workspace root; `cargo xtask ci` builds it first), else it is built here into `target/hil-firmware` (a separate
//! target directory, so that the nested cargo never waits on this test's
//! own build lock).

use std::path::PathBuf;
use std::sync::OnceLock;
use std::time::Duration;

use firmware_sim::hil::{
    HilOptions, LinkFaultSpec, QemuTarget, hil_test_firmware, run_hil, workspace_root,
};
use firmware_sim::{Record, Scenario, Summary, run};
use wmr_core::builds::{self, OptionalBuild};
use wmr_core::control::saturated::GainError;
use wmr_core::estimation::spec::{EstimatorSpec, FusionFilterSpec, FusionSpec};
use wmr_core::pilot::spec::SpecError;
use wmr_link::{HostMessage, Refusal, TargetMessage, TickInput};

/// The default QEMU-board firmware (`hil_test_firmware`).
fn firmware() -> PathBuf {
    static ELF: OnceLock<PathBuf> = OnceLock::new();
    ELF.get_or_init(|| hil_test_firmware(None).expect("the QEMU-board firmware"))
        .clone()
}

/// The QEMU-board firmware of an optional build (`wmr_core::builds`: one
/// feature more than the default), found or built once
/// (`hil_test_firmware`).
fn variant_firmware(elf: &'static OnceLock<PathBuf>, build: OptionalBuild) -> PathBuf {
    elf.get_or_init(|| {
        hil_test_firmware(Some(build))
            .unwrap_or_else(|e| panic!("the QEMU-board firmware with {}: {e:#}", build.feature))
    })
    .clone()
}

/// The QEMU-board firmware with the fusion estimator's UKF.
fn fusion_firmware() -> PathBuf {
    static ELF: OnceLock<PathBuf> = OnceLock::new();
    variant_firmware(&ELF, builds::FUSION_UKF)
}

/// The QEMU-board firmware with paper 003's wheel-speed observer.
fn speed_observer_firmware() -> PathBuf {
    static ELF: OnceLock<PathBuf> = OnceLock::new();
    variant_firmware(&ELF, builds::WHEEL_SPEED_OBSERVER)
}

/// The QEMU-board firmware with the fusion estimator's particle filter.
fn particle_filter_firmware() -> PathBuf {
    static ELF: OnceLock<PathBuf> = OnceLock::new();
    variant_firmware(&ELF, builds::FUSION_PARTICLE_FILTER)
}

/// The default firmware, built without the feature `scenario` needs,
/// refuses its configuration over the link as not in this build.
fn the_default_firmware_lacks(scenario: &Scenario) {
    let mut plain = QemuTarget::start(&firmware(), &options()).unwrap();
    let configure =
        firmware_sim::simulation::hil_configuration(&scenario.validate().unwrap()).unwrap();
    assert_eq!(
        plain.exchange(&HostMessage::Configure(configure)).unwrap(),
        TargetMessage::Refused(Refusal::Spec(SpecError::NotInThisBuild))
    );
}

fn options() -> HilOptions {
    HilOptions {
        firmware: Some(firmware()),
        log: None,
        answer_timeout: Duration::from_secs(20),
        faults: None,
        telemetry_every_ticks: firmware_sim::hil::DEFAULT_TELEMETRY_EVERY_TICKS,
        mavlink: None,
    }
}

/// The full device stack with the fusion estimator on paper 004's UKF
/// (wheel noise 3e-5 m²/m), 120 s.
fn fusion_ukf_scenario() -> Scenario {
    let mut scenario = Scenario::embedded("figure_eight_rfid_full_stack").unwrap();
    scenario.duration_s = 120.0;
    scenario.estimator = EstimatorSpec::Fusion(FusionSpec {
        filter: FusionFilterSpec::Ukf,
        wheel_variance_per_m: 3e-5,
        ..FusionSpec::default()
    });
    scenario
}

/// The fusion estimator's UKF in the firmware (built with `fusion-ukf`),
/// configured over the link: the same records as the host run, bit for
/// bit, over 120 s of the figure-eight. The default firmware, built
/// without the feature, refuses that configuration.
#[test]
fn fusion_ukf_in_the_firmware_runs_exactly_as_on_the_host() {
    let scenario = fusion_ukf_scenario();
    let fusion_options = HilOptions {
        firmware: Some(fusion_firmware()),
        ..options()
    };
    let summary = runs_exactly_as_on_the_host("fusion UKF", &scenario, &fusion_options);
    peak_stack_within_budget("fusion_ukf", &summary);

    the_default_firmware_lacks(&scenario);
}

/// The fusion estimator's particle filter in the firmware (built with
/// `fusion-particle-filter`: 100 particles, each nearest-tag read as the
/// particles' cell likelihood, roughening on resampling), configured over
/// the link with `host-tests/tests/fusion_ekf.rs`'s tuning (wheel noise
/// 2e-7 m²/m, seed 1): 120 s of the full-stack figure-eight give the host
/// run's records bit for bit, the particles' random draws included. The
/// default firmware, built without the feature, refuses it.
#[test]
fn the_fusion_particle_filter_in_the_firmware_runs_exactly_as_on_the_host() {
    let mut scenario = Scenario::embedded("figure_eight_rfid_full_stack").unwrap();
    scenario.duration_s = 120.0;
    scenario.estimator = EstimatorSpec::Fusion(FusionSpec {
        filter: FusionFilterSpec::ParticleFilter,
        wheel_variance_per_m: 2e-7,
        ..FusionSpec::default()
    });
    let pf_options = HilOptions {
        firmware: Some(particle_filter_firmware()),
        ..options()
    };
    let summary = runs_exactly_as_on_the_host("fusion particle filter", &scenario, &pf_options);
    let tracker = summary.tracker.expect("tracker report");
    assert_eq!(tracker.failsafe_entries, 0, "{tracker:?}");
    assert!(tracker.fixes_used > 0, "{tracker:?}");
    peak_stack_within_budget("fusion_particle_filter", &summary);

    the_default_firmware_lacks(&scenario);
}

/// Paper 003's wheel-speed observer on the speed loops, configured over
/// the link (which carries it in the drive's spec): 30 s of the
/// full-stack figure-eight give the host run's records, bit for bit. The
/// default firmware, built without the feature, refuses it.
#[test]
fn the_wheel_speed_observer_in_the_firmware_runs_exactly_as_on_the_host() {
    let mut scenario = Scenario::embedded("figure_eight_rfid_full_stack").unwrap();
    scenario.duration_s = 30.0;
    scenario.transient_s = 0.0;
    let mut drive = scenario.drive.unwrap_or_default();
    drive.speed_observer = Some(firmware_sim::scenario::SpeedObserverSpec {
        mass_kg: 4.0,
        yaw_inertia_kg_m2: 0.08,
        wheel_inertia_kg_m2: 0.0,
        stall_torque_nm: 0.6,
        lambda_per_s: 5.0,
        friction_gain: 0.01,
        disturbance_gain: 0.1,
    });
    scenario.drive = Some(drive);
    let observer_options = HilOptions {
        firmware: Some(speed_observer_firmware()),
        ..options()
    };
    runs_exactly_as_on_the_host("wheel-speed observer", &scenario, &observer_options);

    // The link's configuration carries the observer.
    let configure =
        firmware_sim::simulation::hil_configuration(&scenario.validate().unwrap()).unwrap();
    assert!(configure.pilot.drive.speed_observer.is_some());
    the_default_firmware_lacks(&scenario);
}

/// A robot whose floor is a tag map (`robots/circle_surveyed.toml`: 364
/// surveyed tags with arbitrary 40-bit ids), its map sent over the link
/// after `Configure` (in `MapChunk`s): 5 s of its circle give the
/// host run's records, bit for bit, on fixes the firmware resolved in the
/// map it loaded (every id read known to it).
#[test]
fn a_tag_map_robot_runs_exactly_as_on_the_host() {
    let path = workspace_root().join("robots").join("circle_surveyed.toml");
    let mut scenario = Scenario::from_file(&path).unwrap();
    assert_eq!(scenario.floor_tags.len(), 364);
    scenario.duration_s = 5.0;
    scenario.transient_s = 0.0;
    let s = runs_exactly_as_on_the_host("tag map", &scenario, &options());
    assert_eq!(s.floor_tags, Some(364));
    let rfid = s.rfid.expect("rfid counters");
    let tracker = s.tracker.expect("tracker counters");
    println!("tag map under HIL: rfid {rfid:?}; tracker {tracker:?}");
    assert!(rfid.frames_ok > 0, "no tag read: {rfid:?}");
    assert_eq!(rfid.unknown_tags, 0, "an id the firmware's map lacks");
    assert!(tracker.fixes_used > 0, "no fix used: {tracker:?}");
}

/// A route (the `route` template: three stops, one of them facing a
/// heading, a pivot; 3,329 ticks on a 10 cm tag grid) sent over the link
/// after `Configure` (`Route`, then `RouteChunk`s): the firmware follows
/// it with `Pilot::step_route` and gives the host run's records, bit for
/// bit, up to the same last tick (`settle_s` after the route is done);
/// its route counters (`Finished`) are the host's, and it reports the
/// route done.
#[test]
fn a_route_crosses_the_link_and_runs_exactly_as_on_the_host() {
    let scenario = Scenario::embedded("route").unwrap();
    let host = run(&scenario, |_, _| {}).unwrap();
    let hil = run_hil(&scenario, &options(), |_, _| {}).unwrap();
    let (h, f) = (&host.records, &hil.result.records);
    assert_eq!(first_difference(h, f), None, "records differ");
    // The run ended on the route, not at the scenario's duration.
    assert!(h.len() < scenario_ticks(&scenario) as usize, "{}", h.len());
    assert_eq!(hil.report.firmware_ticks as usize, f.len());
    assert_eq!(hil.report.firmware_link.corrupt_frames, 0);
    let host_route = host.summary.route.expect("the host's route report");
    let hil_route = hil
        .result
        .summary
        .route
        .expect("the HIL run's route report");
    println!(
        "route under HIL: {} ticks; firmware's counters {:?}; peak stack {} B",
        f.len(),
        hil_route.counters,
        hil.report.peak_stack_bytes
    );
    // The HIL report's counters are the firmware's (`Finished`).
    assert_eq!(hil_route.counters, host_route.counters);
    assert_eq!(host_route.counters.stops_reached, 3);
    assert_eq!(host_route.counters.routes_done, 1);
    assert!(host_route.done && hil_route.done && hil.report.route_done);
    assert_eq!(hil_route.done_at_s, host_route.done_at_s);
}

/// The fusion EKF on the same tag-map robot (range reader, 1 m blind
/// distance: the core's `FusionSettings::on_tag_map`), as the firmware
/// runs it: 10 s of the circle give the host run's records, bit for bit.
#[test]
fn the_fusion_estimator_on_a_tag_map_runs_exactly_as_on_the_host() {
    let path = workspace_root().join("robots").join("circle_surveyed.toml");
    let mut scenario = Scenario::from_file(&path).unwrap();
    scenario.estimator = EstimatorSpec::Fusion(FusionSpec {
        max_blind_distance_m: Some(1.0),
        ..FusionSpec::default()
    });
    scenario.duration_s = 10.0;
    scenario.transient_s = 0.0;
    let s = runs_exactly_as_on_the_host("fusion on a tag map", &scenario, &options());
    let tracker = s.tracker.expect("tracker counters");
    println!("fusion EKF on a tag map under HIL: tracker {tracker:?}");
    assert!(tracker.fixes_used > 10, "{tracker:?}");
    assert_eq!(tracker.failsafe_entries, 0, "{tracker:?}");
}

/// The firmware refuses a bad tag map, naming the tag and why (here a
/// duplicate id, which the core's `TagMap` refuses), and a map larger than
/// it holds; the run is then not configured, and the same map without the
/// duplicate loads.
#[test]
fn the_firmware_refuses_a_bad_tag_map_naming_the_tag() {
    use wmr_link::{FloorSpec, MAP_CAPACITY, MapChunk, MapRefusal, MapTag};
    let mut target = QemuTarget::start(&firmware(), &options()).unwrap();
    let tags: Vec<MapTag> = (0..3)
        .map(|i| MapTag {
            id: 0x33_0000_0000 + i,
            position_m: [0.1 * i as f32, 0.0],
        })
        .collect();
    let announce = |tags: u16| {
        HostMessage::Configure(wmr_link::Configure {
            floor: FloorSpec::Map { tags },
            ..configure()
        })
    };
    let chunk = |tags: &[MapTag]| {
        HostMessage::MapChunk(MapChunk {
            first: 0,
            tags: heapless::Vec::from_slice(tags).unwrap(),
        })
    };
    let capacity = u16::try_from(MAP_CAPACITY).unwrap();
    assert_eq!(
        target.exchange(&announce(capacity + 1)).unwrap(),
        TargetMessage::Refused(Refusal::Map(MapRefusal::Size {
            tags: capacity + 1,
            capacity
        }))
    );
    assert_eq!(
        target.exchange(&announce(3)).unwrap(),
        TargetMessage::MapLoaded { tags: 0 }
    );
    assert_eq!(
        target
            .exchange(&chunk(&[tags[0], tags[1], tags[1]]))
            .unwrap(),
        TargetMessage::Refused(Refusal::Map(MapRefusal::Tag {
            index: 2,
            why: wmr_core::devices::TagMapError::DuplicateId
        }))
    );
    assert_eq!(
        target.exchange(&tick(0, 0)).unwrap(),
        TargetMessage::Refused(Refusal::NotConfigured)
    );
    assert_eq!(
        target.exchange(&announce(3)).unwrap(),
        TargetMessage::MapLoaded { tags: 0 }
    );
    assert_eq!(
        target.exchange(&chunk(&tags)).unwrap(),
        TargetMessage::Configured
    );
    let TargetMessage::Finished(finished) = target.exchange(&HostMessage::Finish).unwrap() else {
        panic!("no report")
    };
    assert!(
        finished.counters.link.unexpected_messages >= 3,
        "refusals counted"
    );
}

/// The firmware's default scenario (`figure_eight_rfid_full_stack_fusion_ekf`:
/// the fusion EKF, which every board carries, selected
/// over the link): 120 s of the full-stack figure-eight, the same records
/// as the host run, bit for bit, within the stack budget. (The whole 480 s
/// run, by `firmware-sim hil`: 0.0068 / 0.0017 m max / mean after 100 s,
/// against paper 001's estimator's 0.0266 / 0.0042 m.)
#[test]
fn fusion_ekf_in_the_default_firmware_runs_exactly_as_on_the_host() {
    let mut scenario = Scenario::embedded("figure_eight_rfid_full_stack_fusion_ekf").unwrap();
    assert_eq!(
        scenario.estimator,
        EstimatorSpec::Fusion(FusionSpec {
            filter: FusionFilterSpec::Ekf,
            ..FusionSpec::default()
        })
    );
    scenario.duration_s = 120.0;
    let s = runs_exactly_as_on_the_host("fusion EKF", &scenario, &options());
    // The fusion estimator's targets on the RFID figure-eight
    // (host-tests/tests/fusion_ekf.rs: ≤ 0.02 / ≤ 0.005 m).
    assert!(s.max_error_m <= 0.02 && s.mean_error_m <= 0.005, "{s:?}");
    peak_stack_within_budget("fusion_ekf", &s);
}

/// Section 6.3.2's figure-eight through the full device stack, with the
/// tick in the firmware: the same records as the host run, bit for bit.
#[test]
fn firmware_under_qemu_tracks_the_figure_eight_exactly_as_the_host_run() {
    let scenario = Scenario::embedded("figure_eight_rfid_full_stack").unwrap();
    let host = run(&scenario, |_, _| {}).unwrap();
    let hil = run_hil(&scenario, &options(), |_, _| {}).unwrap();
    let (h, f) = (&host.records, &hil.result.records);
    let first_difference = first_difference(h, f);
    let max_position_diff = h
        .iter()
        .zip(f)
        .map(|(a, b)| (a.x_m - b.x_m).hypot(a.y_m - b.y_m))
        .fold(0.0_f64, f64::max);
    let s = &hil.result.summary;
    let report = s.hil.expect("hil report");
    println!(
        "HIL {} ticks: max |Δposition| host vs firmware {max_position_diff:e} m, \
         first differing record: {first_difference:?}; firmware error after {} s: \
         max {:.4} mean {:.4} rms {:.4} m; peak stack {} B; link {:?}",
        f.len(),
        s.transient_s,
        s.max_error_m,
        s.mean_error_m,
        s.rms_error_m,
        report.peak_stack_bytes,
        report.firmware_link
    );
    // Same f32 code (libm in software, IEEE single-precision add/mul/div/
    // sqrt on both the x86-64 SSE unit and the Cortex-M4 FPU, no fused
    // multiply-add contraction in Rust) on the same inputs: identical.
    assert_eq!(first_difference, None, "records differ");
    assert_eq!(max_position_diff, 0.0);
    // The paper's bounds (section 6.3.2) hold on the firmware too.
    assert!(s.max_error_m <= 0.05 && s.mean_error_m <= 0.01);
    assert_eq!(report.firmware_ticks, scenario_ticks(&scenario));
    assert_eq!(report.firmware_link.corrupt_frames, 0);
    assert_eq!(report.firmware_link.sequence_gaps, 0);
    assert_eq!(report.host_link.corrupt_frames, 0);
    assert_eq!(report.uart_overruns, 0);
    peak_stack_within_budget("heading_observer", s);
}

/// The RFID line at the most the link carries: 160,000 Bd (160 bytes per
/// 10 ms tick, the link's `MAX_UART_BYTES_PER_TICK`), a range-mode reader
/// repeating its tag back to back (11 frames a tick). The firmware's reader
/// empties the UART ring every tick, so every fix it uses arrived that tick
/// (no poll stopped at its bound, no stale fix), nothing overran, and the
/// frames a later one replaced are counted.
#[test]
fn reader_traffic_at_the_links_maximum_is_drained_every_tick() {
    let source = firmware_sim::scenario::embedded_source("figure_eight_rfid_full_stack").unwrap();
    let start = source.find("[position]").unwrap();
    let end = start + source[start..].find("\n\n").unwrap();
    let flood = "[position]\nkind = \"reader\"\nmode = \"range\"\nspacing_m = 0.1\n\
                 offset_m = [0.0, 0.0]\nread_radius_m = 0.08\nrepeat_interval_s = 0.0001\n\
                 baud = 160000";
    let mut scenario =
        Scenario::from_toml_str(&format!("{}{flood}{}", &source[..start], &source[end..])).unwrap();
    // 10 s: a flooded tick costs the lock-step link about 30 times a normal
    // one (the proxy UART takes its bytes one at a time).
    scenario.duration_s = 10.0;
    scenario.transient_s = 5.0;
    let host = run(&scenario, |_, _| {}).unwrap();
    let hil = run_hil(&scenario, &options(), |_, _| {}).unwrap();
    let (h, f) = (&host.records, &hil.result.records);
    let first_difference = first_difference(h, f);
    let s = &hil.result.summary;
    let report = s.hil.expect("hil report");
    let rfid = s.rfid.expect("rfid counters");
    let tracker = s.tracker.expect("tracker counters");
    println!(
        "flooded line, {} ticks: rfid {rfid:?}; tracker {tracker:?}; uart overruns {}; \
         error after {} s: max {:.4} mean {:.4} m",
        f.len(),
        report.uart_overruns,
        s.transient_s,
        s.max_error_m,
        s.mean_error_m
    );
    assert_eq!(first_difference, None, "records differ");
    let ticks = scenario_ticks(&scenario);
    // The line was full: more than 10 frames a tick, every one read but
    // those still on the line or in the ring when the run ended (at most a
    // tick's: 160 bytes, 12 frames).
    assert!(rfid.reader.frames_sent > 10 * u64::from(ticks), "{rfid:?}");
    assert!(rfid.reader.frames_sent - u64::from(rfid.frames_ok) <= 12);
    // Every poll emptied the ring: nothing overran and no poll stopped at
    // its bound, so every tag was read in the tick it arrived (age 0) ...
    assert_eq!(report.uart_overruns, 0);
    assert_eq!(rfid.backlogged_polls, 0);
    assert_eq!(tracker.stale_fixes, 0);
    // ... one a tick was used (from the second: the first tick's frame is
    // still on the line), the others replaced and counted.
    assert_eq!(tracker.fixes_used, ticks - 1);
    assert_eq!(rfid.superseded + tracker.fixes_used, rfid.frames_ok);
}

/// A faulty link, 20 s of the full-stack figure-eight: 1 % of
/// bytes corrupted and 0.5 % of frames each dropped, duplicated and
/// delayed, both ways, and outages past the firmware's link timeout before
/// 0.5 % of ticks. The host resends a tick until its answer comes; the
/// firmware answers a resent tick from its cache. So the records equal the
/// host run's, bit for bit; every fault is counted by the side that saw it,
/// exactly as replayed from what was injected (so no corrupt frame was
/// accepted and no stale one used); and every silence past the timeout was
/// reported with both motors at duty 0. (The hour-long soak: `firmware-sim
/// hil figure_eight_rfid_full_stack --link-faults 1`, docs/hil.md, "A faulty link".)
#[test]
fn a_faulty_link_loses_no_tick_and_every_fault_is_counted() {
    let mut scenario = Scenario::embedded("figure_eight_rfid_full_stack").unwrap();
    scenario.duration_s = 20.0;
    scenario.transient_s = 10.0;
    let faulty = HilOptions {
        faults: Some(LinkFaultSpec {
            outage_probability: 0.005,
            ..LinkFaultSpec::soak(16)
        }),
        ..options()
    };
    let host = run(&scenario, |_, _| {}).unwrap();
    let hil = run_hil(&scenario, &faulty, |_, _| {}).unwrap();
    assert_eq!(
        first_difference(&host.records, &hil.result.records),
        None,
        "records differ"
    );
    let report = hil.report;
    let faults = report.link_faults.expect("fault report");
    println!("faulty link: {report:?}");
    for injected in [faults.to_firmware, faults.to_host] {
        assert!(injected.corrupted > 100, "{injected:?}");
        assert!(injected.dropped > 0 && injected.duplicated > 0 && injected.delayed > 0);
    }
    assert!(
        faults.firmware_expected.agrees_with(&report.firmware_link),
        "firmware counted {:?}, injected {:?}",
        report.firmware_link,
        faults.firmware_expected
    );
    assert!(
        faults.host_expected.agrees_with(&report.host_link),
        "host counted {:?}, injected {:?}",
        report.host_link,
        faults.host_expected
    );
    // Each tick ran once: every resend answered from the cache.
    assert_eq!(report.firmware_ticks, scenario_ticks(&scenario));
    assert!(report.repeated_ticks > 100);
    assert!(faults.outages > 0);
    // Every timeout was reported (motors at 0, checked on receipt) or its
    // report was lost on the way, and counted.
    assert!(report.firmware_link.timeouts >= faults.outages);
    assert_eq!(
        report.firmware_link.timeouts,
        faults.silence_reports + faults.silence_reports_lost
    );
}

/// Telemetry: a HIL run's own firmware log, read back
/// by `firmware-sim plot`'s reader, gives that run's estimate, reference,
/// command, mode, fix and time columns of `run.csv` exactly, cell for
/// cell, every tick (20 s, a record every tick); decimated by 7, every
/// seventh row of them; nothing skipped or missing. The duties are the
/// pilot's, before the PWM's quantization: within one step of the
/// driver's.
#[test]
fn the_firmware_log_gives_the_hil_runs_columns_exactly() {
    let mut scenario = Scenario::embedded("figure_eight_rfid_full_stack").unwrap();
    scenario.duration_s = 20.0;
    scenario.transient_s = 0.0;
    let dir = workspace_root()
        .join("target")
        .join(format!("hil-telemetry-{}", std::process::id()));
    let pwm_max_duty = firmware_sim::simulation::hil_configuration(&scenario.validate().unwrap())
        .unwrap()
        .pwm_max_duty;
    for every in [1_u16, 7] {
        let raw = dir.join(format!("firmware-{every}.defmt"));
        std::fs::create_dir_all(&dir).unwrap();
        let hil = run_hil(
            &scenario,
            &HilOptions {
                log: Some(raw.clone()),
                telemetry_every_ticks: every,
                ..options()
            },
            |_, _| {},
        )
        .unwrap();
        let text = std::fs::read_to_string(raw.with_extension("log")).unwrap();
        let log = firmware_sim::telemetry::read_log(&text, &raw).unwrap();
        let s = &log.summary;
        println!("telemetry every {every}: {s:?}");
        assert_eq!(s.every_ticks, every);
        assert_eq!(
            (s.skipped_lines, s.missing_records, s.out_of_order_records),
            (0, 0, 0)
        );
        assert_eq!((s.malformed_defmt_frames, s.earlier_runs), (0, 0));
        assert!(!s.ground_truth);
        // Both as run.csv writes them.
        let out = dir.join(format!("plot-{every}"));
        firmware_sim::telemetry::write_log_run(&out, &log, false).unwrap();
        let hil_dir = dir.join(format!("hil-{every}"));
        firmware_sim::output::write_all(&hil_dir, &hil.result, false).unwrap();
        // Numbers, booleans and mode names: no quoted cells.
        let read = |path: std::path::PathBuf| {
            let text = std::fs::read_to_string(path).unwrap();
            let mut lines = text
                .lines()
                .map(|l| l.split(',').map(str::to_owned).collect::<Vec<String>>());
            let header = lines.next().unwrap();
            (header, lines.collect::<Vec<_>>())
        };
        let (plot_header, plot_rows) = read(out.join("run.csv"));
        let (hil_header, hil_rows) = read(hil_dir.join("run.csv"));
        assert_eq!(plot_header, hil_header, "the same columns");
        let hil_rows: Vec<_> = hil_rows.into_iter().step_by(usize::from(every)).collect();
        assert_eq!(plot_rows.len(), hil_rows.len());
        assert_eq!(
            plot_rows.len(),
            scenario_ticks(&scenario).div_ceil(u32::from(every)) as usize
        );
        let column = |name: &str| plot_header.iter().position(|h| h == name).unwrap();
        let exact = [
            "tick",
            "t_s",
            "ref_x_m",
            "ref_y_m",
            "est_x_m",
            "est_y_m",
            "est_cos",
            "est_sin",
            "est_theta_rad",
            "v_cmd_m_s",
            "omega_cmd_rad_s",
            "fix",
            "mode",
        ];
        let truth = ["x_m", "y_m", "theta_rad", "heading_error_rad", "error_m"];
        let step = 1.0 / f64::from(pwm_max_duty);
        for (p, h) in plot_rows.iter().zip(&hil_rows) {
            for name in exact {
                let i = column(name);
                assert_eq!(p[i], h[i], "{name} at tick {}", h[0]);
            }
            for name in truth {
                assert_eq!(p[column(name)], "", "{name}: a log has no truth");
            }
            for name in ["left_duty", "right_duty"] {
                let i = column(name);
                let (a, b): (f64, f64) = (p[i].parse().unwrap(), h[i].parse().unwrap());
                assert!((a - b).abs() <= step, "{name} at tick {}: {a} vs {b}", h[0]);
            }
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The tick of the first record where a host run and a firmware run
/// differ (`None`: identical), after checking they have as many records.
fn first_difference(host: &[Record], firmware: &[Record]) -> Option<u32> {
    assert_eq!(host.len(), firmware.len());
    host.iter()
        .zip(firmware)
        .find(|(a, b)| format!("{a:?}") != format!("{b:?}"))
        .map(|(a, _)| a.tick)
}

/// `scenario` on the host and through the firmware of `options`: the same
/// records, bit for bit, every tick run by the firmware, no corrupt frame.
/// Prints the firmware's figures under `label`; returns its summary.
fn runs_exactly_as_on_the_host(label: &str, scenario: &Scenario, options: &HilOptions) -> Summary {
    let host = run(scenario, |_, _| {}).unwrap();
    let hil = run_hil(scenario, options, |_, _| {}).unwrap();
    let (h, f) = (&host.records, &hil.result.records);
    let first_difference = first_difference(h, f);
    let s = hil.result.summary;
    let report = s.hil.expect("hil report");
    println!(
        "HIL {label} {} ticks: first differing record {first_difference:?}; firmware \
         error after {} s: max {:.4} mean {:.4} m; peak stack {} B",
        f.len(),
        s.transient_s,
        s.max_error_m,
        s.mean_error_m,
        report.peak_stack_bytes
    );
    assert_eq!(first_difference, None, "records differ");
    assert_eq!(report.firmware_ticks, scenario_ticks(scenario));
    assert_eq!(report.firmware_link.corrupt_frames, 0);
    s
}

/// The firmware's peak stack over a HIL run (`summary`) against its budget
/// `[hil_peak_stack_bytes] name` in `firmware/budgets.toml` (over by more
/// than the file's `tolerance` or `min_slack` fails, as xtask's budgets do)
/// and its hard limit `[hil_peak_stack_limit_bytes] name`, if it has one.
fn peak_stack_within_budget(name: &str, summary: &Summary) {
    let peak = f64::from(summary.hil.expect("hil report").peak_stack_bytes);
    let path = workspace_root().join("firmware").join("budgets.toml");
    let text = std::fs::read_to_string(&path).expect("read firmware/budgets.toml");
    let budgets: toml::Table = text.parse().expect("parse firmware/budgets.toml");
    let number = |v: &toml::Value| v.as_integer().map(|i| i as f64).or_else(|| v.as_float());
    let entry = |table: &str| {
        budgets
            .get(table)
            .and_then(|t| t.get(name))
            .and_then(number)
    };
    let budget = entry("hil_peak_stack_bytes")
        .unwrap_or_else(|| panic!("firmware/budgets.toml has no [hil_peak_stack_bytes] {name}"));
    let tolerance = budgets
        .get("tolerance")
        .and_then(number)
        .expect("tolerance");
    let min_slack = budgets
        .get("min_slack")
        .and_then(number)
        .expect("min_slack");
    println!("HIL peak stack {name}: {peak} B, budget {budget} B");
    assert!(peak > 0.0, "the stack was not painted");
    assert!(
        peak <= budget + (budget * tolerance).max(min_slack),
        "HIL peak stack {name}: {peak} B, over its budget of {budget} B"
    );
    if let Some(limit) = entry("hil_peak_stack_limit_bytes") {
        assert!(
            peak <= limit,
            "HIL peak stack {name}: {peak} B, over its limit of {limit} B"
        );
    }
}

fn scenario_ticks(s: &Scenario) -> u32 {
    (s.duration_s / s.period_s).round() as u32
}

fn configure() -> wmr_link::Configure {
    let scenario = Scenario::embedded("figure_eight_rfid_full_stack").unwrap();
    firmware_sim::simulation::hil_configuration(&scenario.validate().unwrap()).unwrap()
}

fn tick(k: u32, counts: u32) -> HostMessage {
    // A valid frame for the grid tag nearest the figure-eight's start.
    let frame = wmr_core::devices::encode_frame(wmr_core::devices::TagGrid::id(1, 60));
    HostMessage::Tick(TickInput {
        tick: k,
        left_count: Some(counts),
        right_count: Some(counts),
        uart: heapless::Vec::from_slice(&frame).unwrap(),
    })
}

/// A configured firmware left silent past its timeout reports it
/// (`LinkSilent`, motors stopped), as it does when a loaded machine keeps
/// the host from its next configuration step; the host checks the report
/// and takes the answer after it, so the next configuration succeeds.
#[test]
fn a_silence_report_between_configuration_steps_is_checked_and_passed_over() {
    let mut target = QemuTarget::start(&firmware(), &options()).unwrap();
    target.configure(configure(), &[], &[]).unwrap();
    std::thread::sleep(Duration::from_millis(
        3 * u64::from(wmr_link::LINK_TIMEOUT_MS),
    ));
    target.configure(configure(), &[], &[]).unwrap();
    let TargetMessage::Finished(finished) = target.exchange(&HostMessage::Finish).unwrap() else {
        panic!("no report")
    };
    assert!(
        finished.counters.link.timeouts >= 1,
        "{:?}",
        finished.counters.link
    );
}

/// The firmware refuses what the core refuses, and ticks before a
/// configuration; it counts corrupt frames and carries on; a silent link
/// stops the motors.
#[test]
fn firmware_reacts_to_bad_configuration_corrupt_frames_and_silence() {
    let mut target = QemuTarget::start(&firmware(), &options()).unwrap();

    assert_eq!(
        target.exchange(&tick(0, 0)).unwrap(),
        TargetMessage::Refused(Refusal::NotConfigured)
    );
    let mut bad = configure();
    bad.pilot.tracker.gains[2] = f32::NAN;
    assert_eq!(
        target.exchange(&HostMessage::Configure(bad)).unwrap(),
        TargetMessage::Refused(Refusal::Spec(SpecError::Gains(GainError::K3)))
    );
    let mut old = configure();
    old.protocol = wmr_link::PROTOCOL_VERSION + 1;
    assert_eq!(
        target.exchange(&HostMessage::Configure(old)).unwrap(),
        TargetMessage::Refused(Refusal::Protocol(wmr_link::PROTOCOL_VERSION))
    );
    assert_eq!(
        target
            .exchange(&HostMessage::Configure(configure()))
            .unwrap(),
        TargetMessage::Configured
    );

    // Garbage, then a frame with a flipped byte: both dropped and counted,
    // and the next good frame is answered.
    target.send_raw(&[0x13, 0x37, 0xFF, 0x00]).unwrap();
    let mut out = [0_u8; wmr_link::MAX_FRAME_BYTES];
    let mut damaged = wmr_link::Sender::default()
        .frame(tick(0, 0), &mut out)
        .unwrap()
        .to_vec();
    damaged[5] ^= 0x40;
    target.send_raw(&damaged).unwrap();
    // Each answered with a Nack (the host would resend its last message).
    for _ in 0..2 {
        assert_eq!(target.receive().unwrap(), TargetMessage::Nack);
    }

    // Drive for a while: the robot starts behind its reference and moves.
    let mut driven = false;
    let mut early_silences = 0;
    for k in 0..100 {
        target.send(&tick(k, k * 3)).unwrap();
        loop {
            match target.receive().unwrap() {
                TargetMessage::Ticked(out) => {
                    assert_eq!(out.tick, k);
                    driven |= out.left.duty > 0 || out.right.duty > 0;
                    break;
                }
                // This test's own pauses on a loaded machine.
                TargetMessage::LinkSilent { .. } => early_silences += 1,
                other => panic!("tick {k}: {other:?}"),
            }
        }
    }
    assert!(driven, "the robot never drove");

    // Silence well past the firmware's 50 ms link timeout: the motors
    // stop, and the firmware says so once.
    std::thread::sleep(Duration::from_millis(400));
    match target.receive().unwrap() {
        TargetMessage::LinkSilent { motors, silent_ms } => {
            // At the first poll past the timeout (later only if QEMU was
            // not scheduled then), and during the silence.
            println!("motors stopped after {silent_ms} ms of silence");
            assert!(
                (wmr_link::LINK_TIMEOUT_MS..400).contains(&silent_ms),
                "stopped after {silent_ms} ms"
            );
            assert!(motors.iter().all(|m| m.duty == 0), "{motors:?}");
        }
        other => panic!("expected LinkSilent, got {other:?}"),
    }
    let finished = match target.exchange(&HostMessage::Finish).unwrap() {
        TargetMessage::Finished(f) => f,
        other => panic!("{other:?}"),
    };
    println!("firmware after the fault drill: {finished:?}");
    let link = finished.counters.link;
    assert_eq!(link.corrupt_frames, 2, "garbage + damaged frame");
    assert_eq!(
        link.timeouts,
        1 + early_silences,
        "every silence noticed once"
    );
    assert!(link.unexpected_messages >= 3, "the refusals are counted");
    assert_eq!(finished.motors[0].duty, 0, "left motor still driven");
    assert_eq!(finished.motors[1].duty, 0, "right motor still driven");
    assert_eq!(finished.ticks, 100);
}

/// The firmware under QEMU, configured for the embedded `route` scenario
/// (its tag grid and its route sent over the link).
fn configured_for_the_route() -> QemuTarget {
    let setup = Scenario::embedded("route").unwrap().validate().unwrap();
    let mut target = QemuTarget::start(&firmware(), &options()).unwrap();
    target
        .configure(
            firmware_sim::simulation::hil_configuration(&setup).unwrap(),
            &firmware_sim::simulation::hil_map_chunks(&setup).unwrap(),
            &firmware_sim::simulation::hil_route_messages(&setup),
        )
        .unwrap();
    target
}

/// A MAVLink 2 frame from a ground station (system 255, component 190),
/// written by the endpoint's own encoder.
fn mavlink_frame(seq: u8, msg_id: u32, extra: u8, payload: &[u8]) -> Vec<u8> {
    let mut buf = [0_u8; 300];
    let mut tx = wmr_mavlink::TxBuffer::new(&mut buf);
    assert!(tx.frame([seq, 255, 190], msg_id, extra, payload));
    tx.as_slice().to_vec()
}

/// The frames (message id, payload) in a MAVLink 2 byte stream.
fn mavlink_frames(bytes: &[u8]) -> Vec<(u32, Vec<u8>)> {
    let mut frames = Vec::new();
    let mut i = 0;
    while i + 12 <= bytes.len() {
        assert_eq!(bytes[i], 0xFD, "a frame starts at {i}");
        let len = usize::from(bytes[i + 1]);
        let id = u32::from_le_bytes([bytes[i + 7], bytes[i + 8], bytes[i + 9], 0]);
        frames.push((id, bytes[i + 10..i + 10 + len].to_vec()));
        i += 12 + len;
    }
    assert_eq!(i, bytes.len(), "whole frames");
    frames
}

/// The firmware under QEMU answers a ground station over the link's
/// MAVLink channel (protocol 17) on a route run: heartbeats and
/// telemetry out while the route runs, and a pause (`COMMAND_LONG`
/// `MAV_CMD_DO_PAUSE_CONTINUE`, 0) acknowledged accepted and applied at
/// the next tick (the follower replaced by a fresh one, which holds:
/// no route running at the end). Prints the run's peak stack.
#[test]
fn the_firmware_answers_a_ground_station_over_the_link() {
    use wmr_link::{MavlinkChunk, MavlinkIn};
    let mut target = configured_for_the_route();
    let mut seq = 0_u32;
    // Sends `bytes` over the channel and asks until nothing is pending.
    let mut exchange = |target: &mut QemuTarget, bytes: &[u8]| {
        let mut got = Vec::new();
        let mut rest = bytes;
        loop {
            let chunk = MavlinkChunk::from_slice(rest);
            rest = &rest[chunk.len()..];
            let m = HostMessage::Mavlink(MavlinkIn { seq, bytes: chunk });
            seq += 1;
            let TargetMessage::Mavlink(out) = target.exchange(&m).unwrap() else {
                panic!("not a MAVLink answer")
            };
            assert_eq!(out.counters.rx_dropped_bytes, 0);
            got.extend_from_slice(out.bytes.as_slice());
            if rest.is_empty() && out.pending == 0 {
                return got;
            }
        }
    };
    let tick = |target: &mut QemuTarget, k: u32| {
        let input = TickInput {
            tick: k,
            left_count: Some(0),
            right_count: Some(0),
            uart: heapless::Vec::new(),
        };
        let TargetMessage::Ticked(_) = target.exchange(&HostMessage::Tick(input)).unwrap() else {
            panic!("not ticked")
        };
    };
    let mut sent = Vec::new();
    for k in 0..120 {
        tick(&mut target, k);
        sent.extend(exchange(&mut target, &[]));
    }
    let ids: Vec<u32> = mavlink_frames(&sent).iter().map(|(id, _)| *id).collect();
    // HEARTBEAT (0) at 1 Hz: ticks 0 and 100 of 10 ms.
    assert_eq!(ids.iter().filter(|&&id| id == 0).count(), 2, "{ids:?}");
    let gcs_heartbeat = mavlink_frame(0, 0, 50, &[0, 0, 0, 0, 6, 8, 0, 4, 3]);
    let mut pause = Vec::new();
    pause.extend_from_slice(&0.0_f32.to_le_bytes());
    pause.extend_from_slice(&[0; 24]);
    pause.extend_from_slice(&193_u16.to_le_bytes());
    pause.extend_from_slice(&[1, 1, 0]);
    let mut bytes = gcs_heartbeat;
    bytes.extend(mavlink_frame(1, 76, 152, &pause));
    assert!(
        exchange(&mut target, &bytes).is_empty(),
        "answered at the next tick"
    );
    tick(&mut target, 120);
    let answer = mavlink_frames(&exchange(&mut target, &[]));
    let ack = answer
        .iter()
        .find(|(id, _)| *id == 77)
        .unwrap_or_else(|| panic!("no COMMAND_ACK: {answer:?}"));
    // COMMAND_ACK: command (u16), result (0: accepted).
    assert_eq!(&ack.1[..2], &193_u16.to_le_bytes());
    assert_eq!(ack.1.get(2).copied().unwrap_or(0), 0, "accepted");
    for k in 121..150 {
        tick(&mut target, k);
        exchange(&mut target, &[]);
    }
    let finished = target.end().unwrap();
    println!(
        "MAVLink over the link: {} frames before the pause; peak stack {} B",
        ids.len(),
        finished.peak_stack_bytes
    );
    assert!(!finished.route_done);
    assert_eq!(
        finished.counters.route.routes_started, 0,
        "the fresh follower holds"
    );
}

/// A mission uploaded over the link's MAVLink channel while the route
/// runs (`MISSION_COUNT`, each `MISSION_ITEM_INT` the firmware asks for
/// with `MISSION_REQUEST_INT`) is accepted (`MISSION_ACK` 0) and loaded
/// into the running follower; prints the run's peak stack, the upload's
/// path being the endpoint's deepest.
#[test]
fn the_firmware_takes_a_mission_over_the_link() {
    use wmr_link::{MavlinkChunk, MavlinkIn};
    let mut target = configured_for_the_route();
    let mut seq = 0_u32;
    let mut k = 0_u32;
    // Sends `bytes`, runs a tick, and returns what the endpoint wrote.
    let mut step = |target: &mut QemuTarget, bytes: &[u8]| {
        let mut got = Vec::new();
        let mut rest = bytes;
        let mut ticked = false;
        loop {
            let chunk = MavlinkChunk::from_slice(rest);
            rest = &rest[chunk.len()..];
            let m = HostMessage::Mavlink(MavlinkIn { seq, bytes: chunk });
            seq += 1;
            let TargetMessage::Mavlink(out) = target.exchange(&m).unwrap() else {
                panic!("not a MAVLink answer")
            };
            got.extend_from_slice(out.bytes.as_slice());
            if rest.is_empty() && out.pending == 0 {
                if ticked {
                    return mavlink_frames(&got);
                }
                let input = TickInput {
                    tick: k,
                    left_count: Some(0),
                    right_count: Some(0),
                    uart: heapless::Vec::new(),
                };
                k += 1;
                let TargetMessage::Ticked(_) = target.exchange(&HostMessage::Tick(input)).unwrap()
                else {
                    panic!("not ticked")
                };
                ticked = true;
            }
        }
    };
    for _ in 0..10 {
        step(&mut target, &[]);
    }
    // Two waypoints, local NED (x north, y east, 1e-4 m).
    let items = [(0_i32, 0_i32), (5_000, 0)];
    let mut count = Vec::new();
    count.extend_from_slice(&(items.len() as u16).to_le_bytes());
    count.extend_from_slice(&[1, 1, 0]);
    let mut gcs_seq = 0_u8;
    let mut frames = step(&mut target, &mavlink_frame(gcs_seq, 44, 221, &count));
    let mut ack = None;
    for _ in 0..10 {
        if let Some((_, p)) = frames.iter().find(|(id, _)| *id == 47) {
            ack = Some(p.clone());
            break;
        }
        let Some((_, request)) = frames.iter().find(|(id, _)| *id == 51) else {
            panic!("no item asked for: {frames:?}")
        };
        // MISSION_REQUEST_INT: seq (u16) first.
        let i = usize::from(u16::from_le_bytes([
            request[0],
            request.get(1).copied().unwrap_or(0),
        ]));
        let (x, y) = items[i];
        let mut item = Vec::new();
        item.extend_from_slice(&0.0_f32.to_le_bytes()); // hold
        item.extend_from_slice(&0.0_f32.to_le_bytes());
        item.extend_from_slice(&0.0_f32.to_le_bytes());
        item.extend_from_slice(&f32::NAN.to_le_bytes()); // yaw: none
        item.extend_from_slice(&x.to_le_bytes());
        item.extend_from_slice(&y.to_le_bytes());
        item.extend_from_slice(&0.0_f32.to_le_bytes());
        item.extend_from_slice(&(i as u16).to_le_bytes());
        item.extend_from_slice(&16_u16.to_le_bytes()); // NAV_WAYPOINT
        item.extend_from_slice(&[1, 1, 1, 0, 1, 0]); // targets, LOCAL_NED, current, autocontinue, type
        gcs_seq = gcs_seq.wrapping_add(1);
        frames = step(&mut target, &mavlink_frame(gcs_seq, 73, 38, &item));
    }
    let ack = ack.expect("MISSION_ACK");
    // MISSION_ACK: target system, component, result (0: accepted).
    assert_eq!(ack.get(2).copied().unwrap_or(0), 0, "accepted: {ack:?}");
    for _ in 0..10 {
        step(&mut target, &[]);
    }
    let finished = target.end().unwrap();
    println!(
        "a mission over the link: peak stack {} B",
        finished.peak_stack_bytes
    );
}
