//! The circle and line templates (`firmware-sim show circle`, `show line`)
//! track their references: paper 001's system, nearest 10 cm tag, after
//! the transient (measured: circle 0.0060 / 0.0026 m, line 0.0015 / 0.0006
//! m max / mean).

use firmware_sim::{Scenario, run};

fn tracks(name: &str) {
    let scenario = Scenario::embedded(name).unwrap();
    let s = run(&scenario, |_, _| {}).unwrap().summary;
    println!(
        "{name}: max {:.4} mean {:.4} m after {} s",
        s.max_error_m, s.mean_error_m, s.transient_s
    );
    // Within the tag spacing's quantization, as paper 001's figure-eight.
    assert!(
        s.max_error_m <= 0.02 && s.mean_error_m <= 0.005,
        "{name}: {s:?}"
    );
}

#[test]
fn the_circle_template_tracks() {
    tracks("circle");
}

#[test]
fn the_line_template_tracks() {
    tracks("line");
}
