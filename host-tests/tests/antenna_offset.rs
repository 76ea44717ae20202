//! The RFID antenna 10 cm ahead of the axle midpoint:
//! the simulated reader reads the tag under the antenna; a core told of
//! the offset (`SensorSpec::antenna_offset_m`) moves each fix back to the
//! axle midpoint with its heading estimate. On paper 001's full-stack
//! figure-eight (480 s, error after 100 s), for every estimator: ignoring
//! the offset leaves a bias of about its length; modelling it restores the
//! figures of a robot whose antenna is at the midpoint.
//!
//! Measured (max / mean, m): paper 001's observer 0.0266 / 0.0042 at the
//! midpoint, 0.1066 / 0.0949 ignored, 0.0283 / 0.0042 modelled; paper
//! 002's pose observer 0.0434 / 0.0073, 0.1112 / 0.0975, 0.0493 / 0.0071;
//! the fusion EKF 0.0068 / 0.0017, 0.1061 / 0.0959, 0.0079 / 0.0019 (its
//! largest error not fully restored: the fix is moved with the heading
//! estimate, not through the filter's measurement model).

use firmware_sim::{Scenario, Summary, run};

/// The full-stack scenario `name` with the antenna `offset_m` ahead,
/// compensated by the core or not; its summary.
fn run_with_antenna(
    name: &str,
    estimator: Option<&str>,
    offset_m: f64,
    compensated: bool,
) -> Summary {
    let source = firmware_sim::scenario::embedded_source(name).unwrap();
    let mut text = source.replace(
        "antenna_offset_m = 0.0",
        &format!("antenna_offset_m = {offset_m:?}\nantenna_offset_compensated = {compensated}"),
    );
    assert_ne!(text, source, "{name} has no antenna_offset_m key");
    if let Some(table) = estimator {
        text.push_str(table);
    }
    let scenario = Scenario::from_toml_str(&text).unwrap();
    run(&scenario, |_, _| {}).unwrap().summary
}

/// Ignoring a 10 cm offset degrades `estimator`'s tracking to about the
/// offset; modelling it gives the midpoint antenna's mean error within
/// `mean_ratio` and its largest within `max_ratio`.
fn offset_matters_and_modelling_restores(
    label: &str,
    name: &str,
    estimator: Option<&str>,
    mean_ratio: f64,
    max_ratio: f64,
) -> Summary {
    let midpoint = run_with_antenna(name, estimator, 0.0, true);
    let ignored = run_with_antenna(name, estimator, 0.1, false);
    let modelled = run_with_antenna(name, estimator, 0.1, true);
    let figures = |s: &Summary| format!("{:.4} / {:.4}", s.max_error_m, s.mean_error_m);
    println!(
        "{label}: midpoint {}, ignored {}, modelled {} m (max / mean after {} s)",
        figures(&midpoint),
        figures(&ignored),
        figures(&modelled),
        midpoint.transient_s
    );
    // Ignored: the tracked point is the antenna, 10 cm off.
    assert!(
        ignored.mean_error_m > 0.08,
        "{label}: {}",
        figures(&ignored)
    );
    assert!(ignored.mean_error_m > 10.0 * midpoint.mean_error_m);
    // Modelled: back to the midpoint antenna's figures.
    assert!(
        modelled.mean_error_m <= mean_ratio * midpoint.mean_error_m,
        "{label}: modelled {} against {}",
        figures(&modelled),
        figures(&midpoint)
    );
    assert!(
        modelled.max_error_m <= max_ratio * midpoint.max_error_m,
        "{label}: modelled {} against {}",
        figures(&modelled),
        figures(&midpoint)
    );
    modelled
}

#[test]
fn paper_001_observer_with_the_antenna_ahead() {
    offset_matters_and_modelling_restores(
        "paper 001's observer",
        "figure_eight_rfid_full_stack",
        None,
        1.05,
        1.1,
    );
}

#[test]
fn paper_002_pose_observer_with_the_antenna_ahead() {
    offset_matters_and_modelling_restores(
        "paper 002's pose observer",
        "figure_eight_rfid_full_stack",
        Some("\n[estimator.pose_observer]\ngains = [1.5, 1.5, 100.0, 100.0]\n"),
        1.05,
        1.2,
    );
}

#[test]
fn fusion_ekf_with_the_antenna_ahead() {
    let modelled = offset_matters_and_modelling_restores(
        "fusion EKF",
        "figure_eight_rfid_full_stack_fusion_ekf",
        None,
        1.15,
        2.0,
    );
    // Still within the fusion estimator's targets on the RFID figure-eight.
    assert!(modelled.max_error_m <= 0.02 && modelled.mean_error_m <= 0.005);
}
