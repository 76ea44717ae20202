//! Short runs of every embedded scenario and of the other code paths.

use firmware_sim::output::{format_summary, write_all};
use firmware_sim::report::Mode;
use firmware_sim::{EMBEDDED, RunResult, Scenario, run};

fn short(mut s: Scenario, duration_s: f64) -> RunResult {
    s.duration_s = duration_s;
    s.transient_s = s.transient_s.min(duration_s / 2.0);
    let mut calls = 0;
    let r = run(&s, |done, total| {
        calls += 1;
        assert!(done <= total);
    })
    .unwrap_or_else(|e| panic!("{}: {e}", s.name));
    assert!(calls >= 1);
    r
}

fn assert_sane(r: &RunResult) {
    let s = &r.summary;
    assert_eq!(r.records.len(), s.ticks as usize);
    assert_eq!(s.non_finite_ticks, 0, "{}", format_summary(s));
    assert!(s.max_error_m.is_finite() && s.mean_error_m <= s.max_error_m);
    assert!(s.rms_error_m >= s.mean_error_m - 1e-12);
    for (k, rec) in r.records.iter().enumerate() {
        assert_eq!(rec.tick as usize, k);
        assert!((rec.t_s - k as f64 * r.setup.period_s).abs() < 1e-9);
    }
}

#[test]
fn every_embedded_scenario_runs_20_s_without_nan() {
    for (name, _) in EMBEDDED {
        let r = short(Scenario::embedded(name).unwrap(), 20.0);
        assert_sane(&r);
        // A route starts on its first waypoint (tests/routes.rs).
        if r.setup.route.is_some() {
            continue;
        }
        // Starting 1 m off, every other scenario closes in on the reference.
        let first = r.records[0].error_m;
        assert!((first - 1.0).abs() < 1e-3, "{name}: {first}");
        assert!(r.summary.final_error_m < first, "{name}");
    }
}

#[test]
fn full_stack_goes_through_the_robot_and_its_devices() {
    let r = short(
        Scenario::embedded("figure_eight_rfid_full_stack").unwrap(),
        20.0,
    );
    let s = &r.summary;
    assert_eq!(s.code_path, "robot");
    let rfid = s.rfid.unwrap();
    // 115200 Bd: every tick's frame arrives by the next tick.
    assert_eq!(rfid.reader.frames_sent, 2000);
    assert_eq!(rfid.frames_ok, 1999);
    assert_eq!(rfid.unknown_tags, 0);
    let pilot = s.pilot.unwrap();
    assert_eq!(pilot.reversals_under_drive, 0);
    assert_eq!(pilot.out_of_range_pwm_writes, 0);
    assert!(pilot.max_abs_duty > 0.1 && pilot.max_abs_duty <= 1.0);
    assert_eq!(r.records[0].mode, Mode::AwaitingFix);
    assert_eq!(r.records[1].mode, Mode::Tracking);
    assert!(r.records.iter().all(|x| x.left_duty.is_some()));
}

#[test]
fn default_scenario_matches_the_paper_within_its_figures() {
    // The full 480 s default run is 48 000 ticks of a few µs each.
    let r = run(&Scenario::default_scenario(), |_, _| {}).unwrap();
    let s = &r.summary;
    assert_sane(&r);
    assert_eq!(s.samples, 38_000);
    // Paper 001, §6.3.2: after 100 s, max 0.05 m, mean 0.01 m.
    assert!(s.max_error_m < 0.05, "{}", format_summary(s));
    assert!(s.mean_error_m < 0.01, "{}", format_summary(s));
    assert!(!s.gain_bound.satisfied);
}

const BASE: &str = r#"
name = "t"
duration_s = 15.0
transient_s = 5.0
[reference]
kind = "figure_eight"
[initial]
y_m = -5.5
heading_rad = 0.0
"#;

fn scenario(extra: &str) -> Scenario {
    Scenario::from_toml_str(&format!("{BASE}{extra}")).unwrap()
}

/// Range mode: the robot starts with its antenna over tag (0.1, −5.5)
/// (it does not move before its first fix: from anywhere else it would
/// wait forever).
#[test]
fn reader_in_range_mode_with_faults_on_the_unicycle() {
    let r = short(
        scenario(
            r#"
[position]
kind = "reader"
mode = "range"
read_radius_m = 0.04
antenna_offset_m = 0.1
baud = 9600
repeat_interval_s = 0.05
corrupt_byte_probability = 0.01
drop_frame_probability = 0.05
seed = 3
"#,
        ),
        15.0,
    );
    assert_sane(&r);
    let s = &r.summary;
    assert_eq!(s.code_path, "tracker");
    let rfid = s.rfid.unwrap();
    assert!(rfid.reader.frames_sent > 10, "{rfid:?}");
    assert!(rfid.reader.bytes_corrupted + rfid.reader.frames_dropped > 0);
    let t = s.tracker.unwrap();
    assert!(t.dead_reckoned_steps > t.fixes_used, "{t:?}");
}

#[test]
fn diff_drive_with_exact_and_nearest_tag_positions_runs_the_pilot() {
    for position in ["kind = \"exact\"", "kind = \"nearest_tag\""] {
        let r = short(
            scenario(&format!(
                "[plant]\nkind = \"diff_drive\"\n[position]\n{position}\n"
            )),
            15.0,
        );
        assert_sane(&r);
        assert_eq!(r.summary.code_path, "pilot");
        assert!(r.summary.pilot.is_some());
        assert_eq!(r.summary.tracker.unwrap().fixes_used, 1500);
    }
}

#[test]
fn losing_every_frame_ends_in_the_failsafe_standing_still() {
    let r = short(
        scenario(
            r#"
[plant]
kind = "diff_drive"
[position]
kind = "reader"
drop_frame_probability = 1.0
"#,
        ),
        5.0,
    );
    assert_sane(&r);
    // No fix ever: the robot never moves.
    assert!(r.records.iter().all(|x| x.mode == Mode::AwaitingFix));
    let last = r.records.last().unwrap();
    assert!((last.x_m).abs() < 1e-9 && (last.y_m + 5.5).abs() < 1e-9);
}

#[test]
fn circle_and_line_references() {
    for reference in [
        "kind = \"circle\"\ncenter_m = [0.0, 0.0]\nradius_m = 2.0\nrate_rad_s = 0.1\nphase_rad = -1.5707963",
        "kind = \"line\"\nstart_m = [0.0, -5.0]\nheading_rad = 0.0\nspeed_m_s = 0.2",
    ] {
        let text = BASE.replace("kind = \"figure_eight\"", reference)
            + "[position]\nkind = \"nearest_tag\"\n";
        let r = short(Scenario::from_toml_str(&text).unwrap(), 15.0);
        assert_sane(&r);
        assert!(r.summary.gain_bound.gamma.is_some());
    }
}

#[test]
fn outputs_are_written() {
    let r = short(
        Scenario::embedded("figure_eight_rfid_full_stack").unwrap(),
        10.0,
    );
    let dir = tempfile::tempdir().unwrap();
    let files = write_all(dir.path(), &r, true).unwrap();
    let csv = std::fs::read_to_string(&files.csv).unwrap();
    let mut lines = csv.lines();
    let header = lines.next().unwrap();
    assert!(header.starts_with("tick,t_s,x_m,y_m,theta_rad"));
    assert!(header.contains("error_m") && header.contains("left_duty"));
    assert_eq!(lines.count(), r.records.len());
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&files.summary).unwrap()).unwrap();
    assert_eq!(json["scenario"], "figure_eight_rfid_full_stack");
    assert!(json["max_error_m"].is_number());
    assert!(json["rfid"]["frames_ok"].as_u64().unwrap() > 900);
    let png = std::fs::read(files.plot.unwrap()).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    // Two panels with curves, grids and text: far from a blank image.
    assert!(png.len() > 50_000, "{}", png.len());
}
