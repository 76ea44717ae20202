//! The scenario's parsing, defaults and validation.

use super::*;
use crate::plant::{DiffDriveParams, LoadTorque, WheelDynamics};

const MINIMAL: &str = r#"
    name = "t"
    duration_s = 10.0
    [reference]
    kind = "figure_eight"
"#;

fn err_of(text: &str) -> ScenarioError {
    Scenario::from_toml_str(text).unwrap_err()
}

#[test]
fn embedded_scenarios_parse_and_validate() {
    assert_eq!(EMBEDDED.len(), 11);
    for (name, text) in EMBEDDED {
        let s = Scenario::from_toml_str(text).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(&s.name, name);
        // Round trip through TOML.
        let again = Scenario::from_toml_str(&s.to_toml_string().unwrap()).unwrap();
        assert_eq!(again, s);
    }
    assert_eq!(Scenario::default_scenario().name, "figure_eight_rfid");
    assert!(embedded_source("figure_eight_exact.toml").is_some());
    assert_eq!(
        Scenario::embedded("nope").unwrap_err().field(),
        Some("name")
    );
}

/// The firmware's default scenario is paper 001's full-stack run with the
/// fusion EKF, and nothing else different (so that the two cannot drift
/// apart).
#[test]
fn firmware_default_scenario_is_the_full_stack_run_with_the_fusion_ekf() {
    let paper = Scenario::embedded("figure_eight_rfid_full_stack").unwrap();
    let mut fusion = Scenario::embedded("figure_eight_rfid_full_stack_fusion_ekf").unwrap();
    assert_eq!(
        fusion.estimator,
        EstimatorSpec::Fusion(FusionSpec {
            filter: FusionFilterSpec::Ekf,
            ..FusionSpec::default()
        })
    );
    assert_ne!(paper.estimator, fusion.estimator);
    fusion.name.clone_from(&paper.name);
    fusion.description.clone_from(&paper.description);
    fusion.estimator = paper.estimator;
    assert_eq!(fusion, paper);
}

/// A key given where it does not apply is a warning that names it; the
/// shipped scenarios have none.
#[test]
fn keys_that_do_not_apply_are_warned_about() {
    for (name, _) in EMBEDDED {
        assert_eq!(
            Scenario::embedded(name).unwrap().warnings(),
            Vec::<String>::new(),
            "{name}"
        );
    }
    let state = Scenario::from_toml_str(&format!(
        "{MINIMAL}\n[controller]\nkind = \"state_feedback\"\n[observer]\ngain_per_m = 2.0\n"
    ))
    .unwrap();
    let w = state.warnings();
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(w[0].starts_with("observer.gain_per_m: ignored"), "{w:?}");
    let paper_reader = Scenario::from_toml_str(&format!(
        "{MINIMAL}\n[plant]\nkind = \"diff_drive\"\n[position]\nkind = \"reader\"\nread_radius_m = 0.2\n"
    ))
    .unwrap();
    let w = paper_reader.warnings();
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(w[0].starts_with("position.read_radius_m: ignored"), "{w:?}");
}

/// A key that does not apply is warned about whatever its value, its
/// default included, and only where the file gives it.
#[test]
fn warnings_name_given_keys_whatever_their_value() {
    let default_gain = Scenario::from_toml_str(&format!(
        "{MINIMAL}\n[controller]\nkind = \"state_feedback\"\n[observer]\ngain_per_m = 0.6\n"
    ))
    .unwrap();
    assert_eq!(default_gain.observer.gain_per_m, 0.6);
    let w = default_gain.warnings();
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(w[0].starts_with("observer.gain_per_m: ignored"), "{w:?}");
    let default_radius = Scenario::from_toml_str(&format!(
        "{MINIMAL}\n[plant]\nkind = \"diff_drive\"\n[position]\nkind = \"reader\"\nread_radius_m = {}\nrepeat_interval_s = {}\n",
        super::defaults::read_radius_m(),
        super::defaults::repeat_interval_s(),
    ))
    .unwrap();
    let w = default_radius.warnings();
    assert_eq!(w.len(), 2, "{w:?}");
    assert!(w[0].starts_with("position.read_radius_m: ignored"), "{w:?}");
    assert!(
        w[1].starts_with("position.repeat_interval_s: ignored"),
        "{w:?}"
    );
    // The law at its default (another one is refused).
    let law = Scenario::from_toml_str(&format!(
        "{MINIMAL}\n[controller]\nkind = \"state_feedback\"\nlaw = \"saturated\"\n"
    ))
    .unwrap();
    assert_eq!(law.warnings().len(), 1, "{:?}", law.warnings());
}

/// The resolved file leaves out what the setup ignores (so it reads back
/// without a warning) and writes the core's `f32` values as short as they
/// were given.
#[test]
fn the_resolved_file_reads_back_the_same_without_warnings() {
    let state = Scenario::from_toml_str(&format!(
        "{MINIMAL}\n[controller]\nkind = \"state_feedback\"\n[observer]\ngain_per_m = 2.0\n"
    ))
    .unwrap();
    let resolved = state.to_toml_string().unwrap();
    assert!(!resolved.contains("gain_per_m"), "{resolved}");
    assert!(!resolved.contains("estimate_cos"), "{resolved}");
    let again = Scenario::from_toml_str(&resolved).unwrap();
    assert_eq!(again.warnings(), Vec::<String>::new());
    // The same run: only the unused observer's gain went back to its default.
    let (a, b) = (again.validate().unwrap(), state.validate().unwrap());
    assert_eq!(
        (
            a.ticks,
            a.controller,
            a.gains,
            a.trajectory,
            a.plant,
            a.position
        ),
        (
            b.ticks,
            b.controller,
            b.gains,
            b.trajectory,
            b.plant,
            b.position
        )
    );

    let fusion = Scenario::from_toml_str(&format!(
        "{MINIMAL}\n[position]\nkind = \"nearest_tag\"\n[estimator.fusion]\nwheel_variance_per_m = 1e-3\ngate_sigma = 3.3\n"
    ))
    .unwrap();
    let resolved = fusion.to_toml_string().unwrap();
    assert!(
        resolved.contains("wheel_variance_per_m = 0.001\n"),
        "{resolved}"
    );
    assert!(resolved.contains("gate_sigma = 3.3\n"), "{resolved}");
    assert!(resolved.contains("phase_rad = -1.5707964\n"), "{resolved}");
    let again = Scenario::from_toml_str(&resolved).unwrap();
    assert_eq!(again.estimator, fusion.estimator);
    // f64 keys keep their value, bit for bit.
    assert_eq!(again.period_s.to_bits(), fusion.period_s.to_bits());
}

#[test]
fn minimal_scenario_takes_the_paper_defaults() {
    let s = Scenario::from_toml_str(MINIMAL).unwrap();
    let setup = s.validate().unwrap();
    assert_eq!(setup.ticks, 1000);
    assert_eq!(s.controller.k1, 0.11);
    assert_eq!(s.observer.gain_per_m, 0.6);
    assert_eq!(setup.position, PositionSetup::Exact);
    assert_eq!(setup.plant, PlantSetup::Unicycle);
    let p = setup.trajectory.sample(0.0).position;
    assert!(p.x.abs() < 1e-5 && (p.y + 5.0).abs() < 1e-5);
    assert_eq!(setup.tracker.fix_timeout_ticks(), 50);
}

#[test]
fn unknown_keys_are_refused_with_their_name() {
    let e = err_of(&format!("{MINIMAL}\nperiod_ms = 10\n")).to_string();
    assert!(e.contains("period_ms"), "{e}");
    let e = err_of(&MINIMAL.replace("kind = \"figure_eight\"", "kind = \"figure_eight\"\nh1 = 3"))
        .to_string();
    assert!(e.contains("h1"), "{e}");
    let e = err_of(&format!(
        "{MINIMAL}\n[plant]\nkind = \"diff_drive\"\nradius_m = 0.1\n"
    ))
    .to_string();
    assert!(e.contains("radius_m"), "{e}");
    let e = err_of(&MINIMAL.replace("figure_eight", "spiral")).to_string();
    assert!(e.contains("spiral"), "{e}");
    let e = err_of("name = \"x\"\n[reference]\nkind = \"figure_eight\"\n").to_string();
    assert!(e.contains("duration_s"), "{e}");
}

#[test]
fn bad_values_name_their_field() {
    let cases = [
        ("[observer]\ngain_per_m = -1.0", "observer.gain_per_m"),
        ("[observer]\nmin_speed_m_s = -1.0", "observer.min_speed_m_s"),
        ("[controller]\nk3 = 0.0", "controller.k3"),
        (
            "[plant]\nkind = \"diff_drive\"\nwheel_radius_m = 0.0",
            "plant.wheel_radius_m",
        ),
        (
            "[plant]\nkind = \"diff_drive\"\nencoder_bits = 40",
            "plant.encoder_bits",
        ),
        ("[drive]\nkp_duty_per_rad_s = 0.1", "drive"),
        (
            "[plant]\nkind = \"diff_drive\"\n[drive]\nmax_wheel_speed_rad_s = 0.0",
            "drive.max_wheel_speed_rad_s",
        ),
        (
            "[position]\nkind = \"nearest_tag\"\nspacing_m = 0.0",
            "position.spacing_m",
        ),
        (
            "[position]\nkind = \"nearest_tag\"\nspacing_m = 1e-5",
            "position.spacing_m",
        ),
        (
            "[position]\nkind = \"nearest_tag\"\nspacing_m = 0.01\n\
             extent_m = [-5000.0, -5000.0, 5000.0, 5000.0]",
            "position.extent_m",
        ),
        ("[position]\nkind = \"reader\"\nbaud = 0", "position.baud"),
        (
            "[position]\nkind = \"reader\"\ndrop_frame_probability = 1.5",
            "position.drop_frame_probability",
        ),
        (
            "[position]\nkind = \"reader\"\n[controller]\nkind = \"state_feedback\"",
            "position.kind",
        ),
        (
            "[plant]\nkind = \"diff_drive\"\n[controller]\nkind = \"state_feedback\"",
            "controller.kind",
        ),
        ("[failsafe]\nfix_timeout_s = 0.0", "failsafe.fix_timeout_s"),
        ("[failsafe]\ndecel_m_s2 = -2.0", "failsafe.decel_m_s2"),
        ("[initial]\nx_m = nan", "initial.x_m"),
        (
            "[initial]\nestimate_cos = 1.0\n[plant]\nkind = \"diff_drive\"",
            "initial.estimate_cos",
        ),
        (
            "[measurement]\nnoise_std_m = -0.1",
            "measurement.noise_std_m",
        ),
        (
            "[measurement]\nmiss_probability = 1.5",
            "measurement.miss_probability",
        ),
        (
            "[position]\nkind = \"reader\"\n[measurement]\nnoise_std_m = 0.01",
            "measurement.noise_std_m",
        ),
        (
            "[controller]\nkind = \"state_feedback\"\n[measurement]\nmiss_probability = 0.1",
            "measurement.miss_probability",
        ),
        ("transient_s = 20.0", "transient_s"),
        ("period_s = -0.01", "period_s"),
    ];
    for (extra, field) in cases {
        // Top-level keys must come before the tables.
        let text = if extra.starts_with('[') {
            format!("{MINIMAL}\n{extra}\n")
        } else {
            format!("{extra}\n{MINIMAL}")
        };
        let e = err_of(&text);
        assert_eq!(e.field(), Some(field), "{extra}: {e}");
        assert!(e.to_string().contains(field));
    }
    let e = err_of(&MINIMAL.replace(
        "kind = \"figure_eight\"",
        "kind = \"figure_eight\"\nh2_rad_s = -0.1",
    ));
    assert_eq!(e.field(), Some("reference.h2_rad_s"));
}

const DIFF_DRIVE: &str = "[plant]\nkind = \"diff_drive\"\n";
const DYNAMICS: &str = "[plant.dynamics]\nmass_kg = 4.0\nyaw_inertia_kg_m2 = 0.08\n\
                        stall_torque_nm = 0.6\n";

fn dynamics_of(setup: &Setup) -> Option<WheelDynamics> {
    match setup.plant {
        PlantSetup::DiffDrive { params, .. } => params.dynamics,
        PlantSetup::Unicycle => panic!("diff_drive expected"),
    }
}

#[test]
fn plant_dynamics_table_gives_the_wheel_dynamics() {
    // Absent: the first-order wheels.
    let s = Scenario::from_toml_str(&format!("{MINIMAL}\n{DIFF_DRIVE}")).unwrap();
    assert_eq!(dynamics_of(&s.validate().unwrap()), None);
    let full = Scenario::embedded("figure_eight_rfid_full_stack").unwrap();
    assert_eq!(dynamics_of(&full.validate().unwrap()), None);
    assert!(!full.to_toml_string().unwrap().contains("dynamics"));

    // The required keys only: the others default to 0 (no load).
    let s = Scenario::from_toml_str(&format!("{MINIMAL}\n{DIFF_DRIVE}{DYNAMICS}")).unwrap();
    let expected = WheelDynamics {
        mass_kg: 4.0,
        yaw_inertia_kg_m2: 0.08,
        wheel_inertia_kg_m2: 0.0,
        viscous_friction_nm_s_per_rad: 0.0,
        stall_torque_nm: 0.6,
        load: LoadTorque::NONE,
    };
    assert_eq!(dynamics_of(&s.validate().unwrap()), Some(expected));

    // Every key.
    let text = format!(
        "{MINIMAL}\n{DIFF_DRIVE}{DYNAMICS}wheel_inertia_kg_m2 = 2e-4\n\
         viscous_friction_nm_s_per_rad = 0.01\nload_start_s = 30.0\nload_ramp_s = 2.5\n\
         load_grade_percent = -5.0\n"
    );
    let s = Scenario::from_toml_str(&text).unwrap();
    let setup = s.validate().unwrap();
    assert_eq!(
        dynamics_of(&setup),
        Some(WheelDynamics {
            wheel_inertia_kg_m2: 2e-4,
            viscous_friction_nm_s_per_rad: 0.01,
            load: LoadTorque {
                start_s: 30.0,
                ramp_s: 2.5,
                grade_percent: -5.0,
            },
            ..expected
        })
    );
    // The rest of the plant is untouched.
    let PlantSetup::DiffDrive { params, .. } = setup.plant else {
        panic!("diff_drive expected");
    };
    assert_eq!(
        DiffDriveParams {
            dynamics: None,
            ..params
        },
        DiffDriveParams::default()
    );
    // Round trip through TOML.
    let again = Scenario::from_toml_str(&s.to_toml_string().unwrap()).unwrap();
    assert_eq!(again, s);
}

#[test]
fn bad_plant_dynamics_keys_name_their_field() {
    let cases = [
        ("mass_kg = 0.0", "mass_kg"),
        ("mass_kg = -4.0", "mass_kg"),
        ("yaw_inertia_kg_m2 = 0.0", "yaw_inertia_kg_m2"),
        ("yaw_inertia_kg_m2 = inf", "yaw_inertia_kg_m2"),
        ("wheel_inertia_kg_m2 = -1e-4", "wheel_inertia_kg_m2"),
        ("wheel_inertia_kg_m2 = nan", "wheel_inertia_kg_m2"),
        (
            "viscous_friction_nm_s_per_rad = -0.01",
            "viscous_friction_nm_s_per_rad",
        ),
        ("stall_torque_nm = 0.0", "stall_torque_nm"),
        ("stall_torque_nm = nan", "stall_torque_nm"),
        ("load_start_s = -1.0", "load_start_s"),
        ("load_ramp_s = -0.5", "load_ramp_s"),
        ("load_ramp_s = inf", "load_ramp_s"),
        ("load_grade_percent = 100.0", "load_grade_percent"),
        ("load_grade_percent = -100.0", "load_grade_percent"),
        ("load_grade_percent = nan", "load_grade_percent"),
    ];
    for (line, key) in cases {
        // TOML refuses a key given twice: drop the table's own line.
        let name = line.split(' ').next().unwrap();
        let table: String = DYNAMICS
            .lines()
            .filter(|l| !l.starts_with(name))
            .map(|l| format!("{l}\n"))
            .collect();
        let text = format!("{MINIMAL}\n{DIFF_DRIVE}{table}{line}\n");
        let e = err_of(&text);
        let field = format!("plant.dynamics.{key}");
        assert_eq!(e.field(), Some(field.as_str()), "{line}: {e}");
        assert!(e.to_string().contains(&field), "{e}");
    }
    // The extremes inside the range are accepted.
    for grade in ["99.9", "-99.9"] {
        let text = format!("{MINIMAL}\n{DIFF_DRIVE}{DYNAMICS}load_grade_percent = {grade}\n");
        assert!(Scenario::from_toml_str(&text).is_ok(), "{grade}");
    }
}

#[test]
fn speed_observer_table_is_validated() {
    let table = "[drive.speed_observer]\nmass_kg = 4.0\nyaw_inertia_kg_m2 = 0.08\n";
    let ok = format!("{MINIMAL}\n{DIFF_DRIVE}{DYNAMICS}{table}stall_torque_nm = 0.6\n");
    let setup = Scenario::from_toml_str(&ok).unwrap().validate().unwrap();
    let PlantSetup::DiffDrive { pilot, .. } = setup.plant else {
        panic!("diff drive");
    };
    assert!(pilot.drive().speed_observer().is_some());
    for (line, key) in [
        ("stall_torque_nm = 0.0", "stall_torque_nm"),
        ("stall_torque_nm = 0.6\nlambda_per_s = -1.0", "lambda_per_s"),
        (
            "stall_torque_nm = 0.6\nfriction_gain = nan",
            "friction_gain",
        ),
        (
            "stall_torque_nm = 0.6\ndisturbance_gain = 0.0",
            "disturbance_gain",
        ),
    ] {
        let text = format!("{MINIMAL}\n{DIFF_DRIVE}{DYNAMICS}{table}{line}\n");
        let e = err_of(&text);
        let field = format!("drive.speed_observer.{key}");
        assert_eq!(e.field(), Some(field.as_str()), "{line}: {e}");
    }
}

#[test]
fn plant_dynamics_table_is_refused_where_it_does_not_belong() {
    // With the unicycle (explicit kind).
    let text = format!("{MINIMAL}\n[plant]\nkind = \"unicycle\"\n{DYNAMICS}");
    let e = err_of(&text);
    assert!(matches!(e, ScenarioError::Parse(_)), "{e:?}");
    assert!(e.to_string().contains("plant.dynamics"), "{e}");
    assert!(e.to_string().contains("diff_drive"), "{e}");
    // Without a plant kind.
    let e = err_of(&format!("{MINIMAL}\n{DYNAMICS}")).to_string();
    assert!(e.contains("kind"), "{e}");
    // Unknown or missing keys in the table.
    let e = err_of(&format!(
        "{MINIMAL}\n{DIFF_DRIVE}{DYNAMICS}mass_g = 4000.0\n"
    ))
    .to_string();
    assert!(e.contains("mass_g"), "{e}");
    let e = err_of(&format!(
        "{MINIMAL}\n{DIFF_DRIVE}[plant.dynamics]\nmass_kg = 4.0\nyaw_inertia_kg_m2 = 0.08\n"
    ))
    .to_string();
    assert!(e.contains("stall_torque_nm"), "{e}");
    // The unicycle parses, with or without its table.
    let s = Scenario::from_toml_str(&format!("{MINIMAL}\n[plant]\nkind = \"unicycle\"\n")).unwrap();
    assert_eq!(s.plant, PlantSpec::Unicycle { wheels: None });
}

#[test]
fn floor_covers_the_reference_and_the_start() {
    let text = format!(
        "{MINIMAL}\n[initial]\ny_m = -6.0\n[position]\nkind = \"nearest_tag\"\nmargin_m = 0.5\n"
    );
    let setup = Scenario::from_toml_str(&text).unwrap().validate().unwrap();
    let PositionSetup::NearestTag(floor) = setup.position else {
        panic!("nearest tag expected");
    };
    let (lo, hi) = floor.bounds();
    // The start (0, −6) with its margin, and the reference's start (0, −5).
    assert!(lo[1] <= -6.5 + 1e-9 && hi[1] >= -4.5, "{lo:?} {hi:?}");
}

/// `[estimator]` and `controller.law` are the core's own spec types: their
/// defaults are the core's, their values are checked by the core, and the
/// error names the scenario key with the core's words for the rule.
#[test]
fn estimator_and_law_tables_are_the_cores_specs() {
    const TAGS: &str = "[position]\nkind = \"nearest_tag\"\n";
    let s = Scenario::from_toml_str(&format!("{MINIMAL}\n{TAGS}[estimator.fusion]\n")).unwrap();
    assert_eq!(s.estimator, EstimatorSpec::Fusion(FusionSpec::default()));
    assert!(s.validate().is_ok());
    let s = Scenario::from_toml_str(&format!(
        "estimator = \"heading_observer\"\n{MINIMAL}\n[controller]\nlaw = \"paper_001\"\n"
    ))
    .unwrap();
    assert_eq!(
        (s.estimator, s.controller.law),
        (EstimatorSpec::HeadingObserver, LawSpec::Saturated)
    );
    let s = Scenario::from_toml_str(&format!(
        "{MINIMAL}\n[estimator.pose_observer]\n[controller.law.heading_error_sine]\ngamma = 0.8\n"
    ))
    .unwrap();
    assert_eq!(s.estimator, EstimatorSpec::POSE_OBSERVER);
    assert_eq!(
        s.controller.law,
        LawSpec::HeadingErrorSine {
            a_s_per_m2: LawSpec::DEFAULT_SINE_A_S_PER_M2,
            c2_per_s: LawSpec::DEFAULT_C_PER_S,
            gamma: 0.8,
        }
    );

    let cases = [
        (
            format!("{TAGS}[estimator.fusion]\ngate_sigma = 0.5"),
            "estimator.fusion.gate_sigma",
            "gate_sigma must be finite and ≥ 1 (got 0.5)",
        ),
        (
            "[estimator.pose_observer]\ngains = [0.0, 1.5, 100.0, 100.0]".to_string(),
            "estimator.pose_observer.gains",
            "a1, the x injection) must be in [0.000001, 10000] 1/s (got [0.0, 1.5, 100.0, 100.0])",
        ),
        (
            "[controller.law.cascaded]\nc1_per_s = -1.0".to_string(),
            "controller.law.cascaded.c1_per_s",
            "c1_per_s must be in [0.000001, 10000] 1/s (got -1)",
        ),
        (
            "[controller.law.heading_error_sine]\ngamma = 1.5".to_string(),
            "controller.law.heading_error_sine.gamma",
            "γ) must be in (0, 1) (got 1.5)",
        ),
        (
            "[estimator.fusion]".to_string(),
            "estimator.fusion",
            "nearest_tag or reader",
        ),
        (
            "[estimator.pose_observer]\n[controller]\nkind = \"state_feedback\"".to_string(),
            "estimator",
            "no estimator runs",
        ),
    ];
    for (extra, field, reason) in cases {
        let e = err_of(&format!("{MINIMAL}\n{extra}\n"));
        assert_eq!(e.field(), Some(field), "{extra}: {e}");
        assert!(e.to_string().contains(reason), "{extra}: {e}");
    }
    let e = err_of(&format!(
        "{MINIMAL}\n[estimator.fusion]\nfusion_gate_sigma = 3.0\n"
    ));
    assert!(e.to_string().contains("fusion_gate_sigma"), "{e}");
}

/// Scenario files of the old layout fail with the new key's name.
#[test]
fn old_estimator_and_law_keys_name_their_new_keys() {
    for (old, new) in [
        (
            "[observer]\nkind = \"fusion_ekf\"",
            "[estimator.fusion] with filter = \"ekf\"",
        ),
        (
            "[observer]\nfusion_wheel_variance_per_m = 1e-3",
            "estimator.fusion.wheel_variance_per_m",
        ),
        (
            "[observer]\npose_gains = [1.5, 1.5, 100.0, 100.0]",
            "estimator.pose_observer.gains",
        ),
        (
            "[controller]\nlaw = \"cascaded\"\nc1 = 0.5",
            "[controller.law.cascaded]",
        ),
        (
            "[controller]\ngamma = 0.9",
            "controller.law.heading_error_sine.gamma",
        ),
    ] {
        let e = err_of(&format!("{MINIMAL}\n{old}\n")).to_string();
        assert!(e.contains(new), "{old}: {e}");
    }
}

/// `PositionSpec::reader_defaults` is what `kind = "reader"` alone reads as
/// (what a scenario naming a robot compares its `[position]` with).
#[test]
fn reader_defaults_are_the_readers_serde_defaults() {
    let parsed: PositionSpec = toml::from_str("kind = \"reader\"").unwrap();
    assert_eq!(parsed, PositionSpec::reader_defaults());
}

/// Values no robot has are refused at the front door, naming the key, the
/// plausible range and the value: a control period of 3.4e38 s (which would
/// put the reference at `t = inf` on the second tick), a 3e38 m tag
/// spacing, and gains the core refuses (the value looked up in the file).
#[test]
fn implausible_values_are_refused_naming_key_range_and_value() {
    let cases = [
        (
            "period_s = 3.4e38\n",
            "period_s",
            "must be in [0.0001, 1] s (got 3.4e38)",
        ),
        (
            "[position]\nkind = \"nearest_tag\"\nspacing_m = 3e38\n",
            "position.spacing_m",
            "must be in [0.01, 10] m (got 3e38)",
        ),
        (
            "[controller]\nk1 = 1e9\n",
            "controller.k1",
            "must be in [0.000001, 10000] m/s (got 1e9)",
        ),
        (
            "[observer]\ngain_per_m = 2e4\n",
            "observer.gain_per_m",
            "(got 20000)",
        ),
    ];
    for (extra, field, text) in cases {
        let (head, tail) = MINIMAL.split_at(MINIMAL.find("[reference]").unwrap());
        let e = err_of(&format!("{head}{extra}{tail}"));
        assert_eq!(e.field(), Some(field), "{e}");
        assert!(e.to_string().contains(text), "{e}");
    }
}

/// The fusion estimator's other fields are named with their value too
/// (the table's test above names the gate, the pose observer's gains and
/// the laws' gains).
#[test]
fn estimator_and_law_refusals_name_their_field_and_value() {
    let reader = "[position]\nkind = \"nearest_tag\"\n";
    let cases = [
        (
            format!("{reader}[estimator.fusion]\nwheel_variance_per_m = -1.0\n"),
            "estimator.fusion.wheel_variance_per_m",
            "(got -1)",
        ),
        (
            format!("{reader}[estimator.fusion]\nscale_prior = -1.0\n"),
            "estimator.fusion.scale_prior",
            "(got -1)",
        ),
        (
            format!("{reader}[estimator.fusion]\nmax_blind_distance_m = -1.0\n"),
            "estimator.fusion.max_blind_distance_m",
            "(got -1)",
        ),
    ];
    for (extra, field, text) in cases {
        let (head, tail) = MINIMAL.split_at(MINIMAL.find("[reference]").unwrap());
        let e = err_of(&format!("{head}{extra}{tail}"));
        assert_eq!(e.field(), Some(field), "{e}");
        assert!(e.to_string().contains(text), "{e}");
    }
}

/// A kind that takes no key refuses every other key of its table, by its
/// path (serde's tagged enums pass over a unit variant's keys).
#[test]
fn a_key_under_a_kind_that_takes_none_is_refused_by_its_path() {
    for (table, path) in [
        ("[plant]\nkind = \"unicycle\"\nfoo = 1", "`plant.foo`"),
        (
            "[plant]\nkind = \"unicycle\"\nwheel_radius_m = 0.03",
            "`plant.wheel_radius_m`",
        ),
        (
            "[plant]\nkind = \"unicycle\"\nsubsteps = 4",
            "`plant.substeps`",
        ),
        (
            "[position]\nkind = \"exact\"\nspacing_m = 0.1",
            "`position.spacing_m`",
        ),
    ] {
        let e = err_of(&format!("{MINIMAL}\n{table}\n"));
        assert!(matches!(e, ScenarioError::Parse(_)), "{e}");
        assert!(e.to_string().contains(path), "{table}: {e}");
    }
    // The kinds alone still parse.
    Scenario::from_toml_str(&format!("{MINIMAL}\n[plant]\nkind = \"unicycle\"\n")).unwrap();
    Scenario::from_toml_str(&format!("{MINIMAL}\n[position]\nkind = \"exact\"\n")).unwrap();
}

/// A value of the wrong type or length inside a table names its key, also
/// in the tables deserialized by hand (whose errors the parser could only
/// place at the table's header).
#[test]
fn a_type_error_names_its_key() {
    for (table, path) in [
        (
            "[position]\nkind = \"nearest_tag\"\nspacing_m = \"10 cm\"",
            "`position.spacing_m`",
        ),
        (
            "[position]\nkind = \"nearest_tag\"\noffset_m = [0.0]",
            "`position.offset_m`",
        ),
        (
            "[plant]\nkind = \"diff_drive\"\nwheel_radius_m = \"3 cm\"",
            "`plant.wheel_radius_m`",
        ),
        ("[controller]\nk1 = \"fast\"", "`controller.k1`"),
        ("[observer]\ngain_per_m = true", "`observer.gain_per_m`"),
    ] {
        let e = err_of(&format!("{MINIMAL}\n{table}\n"));
        assert!(matches!(e, ScenarioError::Parse(_)), "{e}");
        assert!(e.to_string().contains(path), "{table}: {e}");
    }
}

/// A floor is at most 65,535 rows and columns of tags, and its tags at
/// least 1 cm apart: beyond either it is refused, naming the key.
#[test]
fn floors_beyond_the_cap_are_refused() {
    let wide = Scenario::from_toml_str(&format!(
        "{MINIMAL}\n[position]\nkind = \"nearest_tag\"\nspacing_m = 0.01\nextent_m = [-400.0, -10.0, 400.0, 10.0]\n"
    ));
    let e = wide.unwrap_err().to_string();
    assert!(
        e.contains("position.extent_m") && e.contains("65535"),
        "{e}"
    );
    let dense = Scenario::from_toml_str(&format!(
        "{MINIMAL}\n[position]\nkind = \"nearest_tag\"\nspacing_m = 0.001\n"
    ));
    let e = dense.unwrap_err().to_string();
    assert!(
        e.contains("position.spacing_m") && e.contains("0.001"),
        "{e}"
    );
}

/// The `[drive]` and `[drive.speed_observer]` tables are the core's
/// `DriveSpec` and `SpeedObserverSpec` as a file writes them: the same
/// keys, less the facts the plant table states once (wheel radius, track,
/// counts per revolution, the motors' no-load speed). A key added to the
/// core's spec and not to the file, or renamed in one of them, fails here.
#[test]
fn the_drive_tables_are_the_cores_specs_less_the_plants_facts() {
    use std::collections::BTreeSet;
    use wmr_core::drive::spec as core;
    let keys =
        |v: toml::Value| -> BTreeSet<String> { v.as_table().unwrap().keys().cloned().collect() };
    let observer = core::SpeedObserverSpec {
        mass_kg: 1.0,
        yaw_inertia_kg_m2: 1.0,
        wheel_inertia_kg_m2: 0.0,
        stall_torque_nm: 1.0,
        no_load_speed_rad_s: 1.0,
        lambda_per_s: 1.0,
        friction_gain: 1.0,
        disturbance_gain: 1.0,
    };
    let drive = core::DriveSpec {
        wheel_radius_m: 0.03,
        track_width_m: 0.2,
        encoder_counts_per_rev: 2048,
        max_wheel_speed_rad_s: 20.0,
        max_wheel_accel_rad_s2: 40.0,
        feedforward_duty_per_rad_s: 0.05,
        kp_duty_per_rad_s: 0.05,
        ki_duty_per_rad: 0.5,
        speed_observer: Some(observer),
    };
    let file_observer = super::SpeedObserverSpec {
        mass_kg: 1.0,
        yaw_inertia_kg_m2: 1.0,
        wheel_inertia_kg_m2: 0.0,
        stall_torque_nm: 1.0,
        lambda_per_s: 1.0,
        friction_gain: 1.0,
        disturbance_gain: 1.0,
    };
    let file_drive = super::DriveSpec {
        feedforward_duty_per_rad_s: Some(0.05),
        speed_observer: Some(file_observer),
        ..super::DriveSpec::default()
    };
    let from_plant = |keys: &[&str]| {
        keys.iter()
            .map(|k| (*k).to_owned())
            .collect::<BTreeSet<_>>()
    };
    let core_drive = keys(toml::Value::try_from(drive).unwrap());
    let file = keys(toml::Value::try_from(file_drive).unwrap());
    let plant = from_plant(&["wheel_radius_m", "track_width_m", "encoder_counts_per_rev"]);
    assert_eq!(core_drive, &file | &plant);
    let core_observer = keys(toml::Value::try_from(observer).unwrap());
    let file = keys(toml::Value::try_from(file_observer).unwrap());
    assert_eq!(core_observer, &file | &from_plant(&["no_load_speed_rad_s"]));
}

/// `[plant.wheels]` on either plant: absent, no wheel errors; given, its
/// values with the run's `measurement.seed` (and the plant's track, the
/// default robot's on the unicycle); each bad key refused by name with its
/// value; an unknown key named.
#[test]
fn plant_wheels_table_is_validated() {
    let wheels = "[plant.wheels]\ntravel_variance_m2_per_m = 1e-4\nscale_error = [0.01, -0.02]\n\
                  [measurement]\nseed = 7\n";
    let setup = |text: &str| {
        Scenario::from_toml_str(text)
            .and_then(|s| s.validate())
            .unwrap_or_else(|e| panic!("{e}"))
    };
    assert_eq!(setup(MINIMAL).wheels, None);
    let unicycle = setup(&format!(
        "{MINIMAL}\n[plant]\nkind = \"unicycle\"\n{wheels}"
    ));
    assert_eq!(
        unicycle.wheels,
        Some(crate::plant::WheelErrors {
            travel_variance_m2_per_m: 1e-4,
            scale_error: [0.01, -0.02],
            track_width_m: 0.2,
            seed: 7,
        })
    );
    let diff_drive = setup(&format!(
        "{MINIMAL}\n[plant]\nkind = \"diff_drive\"\ntrack_width_m = 0.3\n{wheels}"
    ));
    assert_eq!(diff_drive.wheels.map(|w| w.track_width_m), Some(0.3));
    // The resolved file reads back the same.
    let s = Scenario::from_toml_str(&format!(
        "{MINIMAL}\n[plant]\nkind = \"unicycle\"\n{wheels}"
    ))
    .unwrap();
    assert_eq!(
        Scenario::from_toml_str(&s.to_toml_string().unwrap()).unwrap(),
        s
    );
    for (table, value) in [
        ("travel_variance_m2_per_m = -1e-4", "-0.0001"),
        ("travel_variance_m2_per_m = 2.0", "2"),
        ("travel_variance_m2_per_m = nan", "NaN"),
        ("scale_error = [0.0, 0.7]", "0.7"),
        ("scale_error = [-0.6, 0.0]", "-0.6"),
        ("scale_error = [inf, 0.0]", "inf"),
    ] {
        let key = format!(
            "plant.wheels.{}",
            table.split(' ').next().unwrap_or_default()
        );
        for kind in ["unicycle", "diff_drive"] {
            let e = Scenario::from_toml_str(&format!(
                "{MINIMAL}\n[plant]\nkind = \"{kind}\"\n[plant.wheels]\n{table}\n"
            ))
            .and_then(|s| s.validate())
            .unwrap_err();
            assert_eq!(e.field(), Some(key.as_str()), "{table}: {e}");
            assert!(e.to_string().contains(value), "{table}: {e}");
        }
    }
    let e = err_of(&format!(
        "{MINIMAL}\n[plant]\nkind = \"unicycle\"\n[plant.wheels]\nslip_variance = 1.0\n"
    ))
    .to_string();
    assert!(e.contains("slip_variance"), "{e}");
    // The unicycle takes `wheels` and nothing else.
    let e = err_of(&format!(
        "{MINIMAL}\n[plant]\nkind = \"unicycle\"\nwheel_radius_m = 0.03\n"
    ))
    .to_string();
    assert!(
        e.contains("plant.wheel_radius_m") && e.contains("wheels"),
        "{e}"
    );
}
