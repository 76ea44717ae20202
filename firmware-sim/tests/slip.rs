//! Paper 004's slip scenarios: the schema, its errors, the `slip`
//! subcommand.

mod common;
use common::{sim, stdout_of_success};

use firmware_sim::ScenarioError;
use firmware_sim::slip::{self, Controller, EMBEDDED_SLIP, Estimator, SlipScenario};

#[test]
fn embedded_slip_scenarios_parse_and_validate() {
    assert_eq!(EMBEDDED_SLIP.len(), 2);
    for ((name, _), controller) in EMBEDDED_SLIP
        .iter()
        .zip([Controller::Velocity, Controller::Torque])
    {
        let s = SlipScenario::embedded(name).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(s.name, *name);
        assert_eq!(s.controller, controller);
        assert_eq!(s.estimator, Estimator::Ekf);
        s.validate().unwrap();
        // Every estimator validates on the paper's settings.
        for estimator in Estimator::ALL {
            let mut s = s.clone();
            s.estimator = estimator;
            s.validate()
                .unwrap_or_else(|e| panic!("{name}, {estimator:?}: {e}"));
        }
        // The file form round-trips.
        let text = s.to_toml_string().unwrap();
        assert_eq!(SlipScenario::from_toml_str(&text).unwrap(), s, "{text}");
    }
    let e = SlipScenario::embedded("paper_004_nope").unwrap_err();
    assert_eq!(e.field(), Some("name"));
    assert!(e.to_string().contains("paper_004_torque"), "{e}");
}

/// The embedded velocity scenario's text with `old` replaced by `new`.
fn edited(old: &str, new: &str) -> String {
    let text = slip::embedded_slip_source("paper_004_velocity").unwrap();
    assert!(text.contains(old), "{old}");
    text.replacen(old, new, 1)
}

fn invalid_field(text: &str) -> (String, String) {
    match SlipScenario::from_toml_str(text) {
        Err(e @ ScenarioError::Invalid { .. }) => (e.field().unwrap().to_owned(), e.to_string()),
        other => panic!("expected a field error, got {other:?}"),
    }
}

#[test]
fn bad_values_are_refused_with_the_field_named() {
    let (field, msg) = invalid_field(&edited("slip_ratio = 0.25", "slip_ratio = 1.0"));
    assert_eq!(field, "slip[0].slip_ratio", "{msg}");
    assert!(msg.contains("[0, 1)"), "{msg}");

    let (field, msg) = invalid_field(&edited("start_s = 45.0", "start_s = 20.0"));
    assert_eq!(field, "slip[1].start_s", "{msg}");
    assert!(msg.contains("increasing"), "{msg}");

    let (field, msg) = invalid_field(&edited("particles = 100", "particles = 50"));
    assert_eq!(field, "filter.particle_filter.particles", "{msg}");
    assert!(msg.contains("100") && msg.contains("50"), "{msg}");

    let (field, msg) = invalid_field(&edited(
        "{ start_s = 33.0, v_m_s = 0.5",
        "{ start_s = 10.0, v_m_s = 0.5",
    ));
    assert_eq!(field, "reference.segments[2].start_s", "{msg}");

    let (field, msg) = invalid_field(&edited(
        "variance = [0.1, 0.1, 0.2,",
        "variance = [0.1, 0.1, -0.2,",
    ));
    assert_eq!(field, "measurement.variance[2]", "{msg}");

    let (field, msg) = invalid_field(&edited("\nalpha = 0.01", "\nalpha = 0.0"));
    assert_eq!(field, "filter.ukf.alpha", "{msg}");

    let (field, msg) = invalid_field(&edited(
        "initial_slip_estimate = 1.0",
        "initial_slip_estimate = 0.5",
    ));
    assert_eq!(field, "gains.initial_slip_estimate", "{msg}");

    // Unknown keys are schema errors naming the key.
    for (old, new, key) in [
        ("seed = 1", "seed = 1\nsede = 2", "sede"),
        ("rho = 3.0", "rho = 3.0\nk6 = 1.0", "k6"),
        (
            "slip_ratio = 0.25",
            "slip_ratio = 0.25\nend_s = 30.0",
            "end_s",
        ),
    ] {
        match SlipScenario::from_toml_str(&edited(old, new)) {
            Err(ScenarioError::Parse(m)) => assert!(m.contains(key), "{m}"),
            other => panic!("{key}: expected a parse error, got {other:?}"),
        }
    }
    match SlipScenario::from_toml_str(&edited("controller = \"velocity\"", "controller = \"pid\""))
    {
        Err(ScenarioError::Parse(m)) => assert!(m.contains("velocity") && m.contains("torque")),
        other => panic!("expected a parse error, got {other:?}"),
    }
}

#[test]
fn the_cli_refuses_a_bad_file_naming_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.toml");
    std::fs::write(&path, edited("particles = 100", "particles = 50")).unwrap();
    let out = sim()
        .arg("slip")
        .arg(&path)
        .arg("--out")
        .arg(dir.path().join("out"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("filter.particle_filter.particles"), "{err}");

    let out = sim()
        .args(["slip", "paper_004_velocity", "--estimator", "kalman"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("particle_filter"), "{err}");
}

/// A short run: the windows past its end have no samples (null).
#[test]
fn a_cut_run_leaves_the_later_windows_empty() {
    let mut s = SlipScenario::embedded("paper_004_torque").unwrap();
    s.duration_s = 5.0;
    s.estimator = Estimator::Ukf;
    let r = slip::run(&s).unwrap();
    assert_eq!(r.records.len(), 100);
    assert_eq!(r.summary.non_finite_records, 0);
    assert!(r.records.iter().all(|x| x.torque_left_nm.is_some()));
    assert!(r.summary.tracking.iter().all(|w| w.samples == 0
        && w.position_error_rms_m.is_none()
        && w.heading_error_rms_rad.is_none()));
    let first = &r.records[0];
    assert_eq!((first.x_m, first.y_m), (0.0, -1.0));
    // The robot closes in on the reference from 1 m off.
    let last = r.records.last().unwrap();
    assert!(last.e1_m.hypot(last.e2_m) < 0.5, "{last:?}");
}

#[test]
fn the_cli_runs_a_scenario_and_writes_its_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let out = sim()
        .args([
            "slip",
            "paper_004_velocity",
            "--estimator",
            "ekf",
            "--seed",
            "2",
            "--out",
        ])
        .arg(dir.path())
        .output()
        .unwrap();
    let text = stdout_of_success(&out);
    assert!(
        text.contains("paper_004_velocity") && text.contains("during slip"),
        "{text}"
    );
    for file in [
        "run.csv",
        "summary.json",
        "scenario.toml",
        "errors.png",
        "slip.png",
        "trajectory.png",
    ] {
        let path = dir.path().join(file);
        assert!(
            std::fs::metadata(&path).is_ok_and(|m| m.len() > 0),
            "{}",
            path.display()
        );
    }

    // The CSV: a header and a row every 50 ms.
    let csv = std::fs::read_to_string(dir.path().join("run.csv")).unwrap();
    let mut lines = csv.lines();
    let header = lines.next().unwrap();
    for column in [
        "t_s",
        "est_x_m",
        "ref_x_m",
        "e1_m",
        "e3_rad",
        "slip_estimate",
        "slip_ratio",
        "left_rad_s",
        "left_desired_rad_s",
        "torque_left_nm",
    ] {
        assert!(header.split(',').any(|c| c == column), "{column}: {header}");
    }
    assert_eq!(lines.count(), 1200);

    // The summary is the library's for the same scenario.
    let mut s = SlipScenario::embedded("paper_004_velocity").unwrap();
    s.seed = 2;
    let expected = serde_json::to_value(slip::run(&s).unwrap().summary).unwrap();
    let written: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("summary.json")).unwrap())
            .unwrap();
    assert_eq!(written, expected);
    assert_eq!(written["estimator"], "ekf");
    assert_eq!(written["seed"], 2);
    let windows = written["tracking"].as_array().unwrap();
    assert_eq!(windows.len(), 3);
    assert!(windows[1]["position_error_rms_m"].as_f64().unwrap() < 0.1);

    // scenario.toml is the scenario as run, overrides included.
    let as_run = SlipScenario::from_file(&dir.path().join("scenario.toml")).unwrap();
    assert_eq!(as_run, s);
}
