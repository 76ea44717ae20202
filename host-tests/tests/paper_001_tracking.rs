//! Paper 001, sections 6.2, 6.3.1 and 6.3.2 (Figs. 2–7), and the §6.3.2 run
//! through the full device stack.
//!
//! Each test runs one of the simulator's embedded scenarios (the same files
//! `firmware-sim run` takes, in `firmware-sim/scenarios/`, with the paper's
//! parameters and where they come from) and asserts the paper's outcome:
//!
//! | section | paper's outcome | asserted |
//! |---|---|---|
//! | 6.2 state feedback, `k = [0.11, 0.11, 1]`, 80 s | error → 0 (Fig. 3) | `< 1e-3 m` at 80 s |
//! | 6.3.1 output feedback, exact position, `k3 = 0.01, L = 4`, 480 s | error → 0 (Fig. 5) | `< 1e-3 m` over the last 80 s |
//! | 6.3.2 nearest 10 cm tag, `k3 = 0.1, L = 0.6`, 480 s | after 100 s: max 0.05 m, mean 0.01 m | `≤ 0.05`, `≤ 0.01` |
//! | 6.3.2 through PWM, motors, encoders, RFID frames on a UART | — | same bounds |
//!
//! The figures each run reaches are printed (`cargo test -p host-tests
//! --test paper_001_tracking -- --nocapture`) and reported in the README.

use firmware_sim::{RunResult, Scenario, run};

fn run_embedded(name: &str) -> RunResult {
    let scenario = Scenario::embedded(name).expect("embedded scenario is valid");
    let result = run(&scenario, |_, _| {}).expect("scenario runs");
    let s = &result.summary;
    println!(
        "{name}: after {:.0} s max {:.4} m, mean {:.5} m, RMS {:.5} m; final {:.2e} m; \
         gain bound (15) satisfied: {} (γ = {:?})",
        s.transient_s,
        s.max_error_m,
        s.mean_error_m,
        s.rms_error_m,
        s.final_error_m,
        s.gain_bound.satisfied,
        s.gain_bound.gamma
    );
    assert_eq!(s.non_finite_ticks, 0, "{name}: non-finite state");
    result
}

/// Largest tracking error over `t ≥ from_s`.
fn max_error_after(result: &RunResult, from_s: f64) -> f64 {
    result
        .records
        .iter()
        .filter(|r| r.t_s >= from_s)
        .map(|r| r.error_m)
        .fold(0.0, f64::max)
}

#[test]
fn section_6_2_state_feedback_converges_by_80_s() {
    let result = run_embedded("figure_eight_state_feedback");
    // The paper's gains break (15) for this reference (papers' README, slip 6).
    assert!(!result.summary.gain_bound.satisfied);
    assert!(
        result.summary.final_error_m < 1e-3,
        "{}",
        result.summary.final_error_m
    );
}

#[test]
fn section_6_3_1_noise_free_output_feedback_converges_by_480_s() {
    let result = run_embedded("figure_eight_exact");
    let tail = max_error_after(&result, 400.0);
    println!("figure_eight_exact: max error over 400–480 s {tail:.2e} m");
    assert!(result.summary.final_error_m < 1e-3);
    assert!(tail < 1e-3, "{tail}");
}

#[test]
fn section_6_3_2_rfid_tags_every_10_cm_meet_the_papers_figures() {
    let result = run_embedded("figure_eight_rfid");
    let s = &result.summary;
    assert!(s.transient_s >= 100.0);
    assert!(s.max_error_m <= 0.05, "max {}", s.max_error_m);
    assert!(s.mean_error_m <= 0.01, "mean {}", s.mean_error_m);
    let tracker = s
        .tracker
        .as_ref()
        .expect("output feedback reports its tracker");
    assert_eq!(tracker.failsafe_entries, 0);
    assert_eq!(u64::from(tracker.fixes_used), u64::from(s.ticks));
}

#[test]
fn section_6_3_2_through_the_full_device_stack() {
    let result = run_embedded("figure_eight_rfid_full_stack");
    let s = &result.summary;
    assert!(s.max_error_m <= 0.05, "max {}", s.max_error_m);
    assert!(s.mean_error_m <= 0.01, "mean {}", s.mean_error_m);
    let rfid = s.rfid.as_ref().expect("the full stack reads frames");
    assert!(rfid.frames_ok > 0);
    assert_eq!(rfid.bad_checksum + rfid.malformed + rfid.unknown_tags, 0);
    let pilot = s.pilot.as_ref().expect("the full stack runs the pilot");
    assert_eq!(
        pilot.encoder_fault_ticks + pilot.implausible_encoder_reads,
        0
    );
    assert_eq!(pilot.motor_faults, 0);
    let tracker = s.tracker.as_ref().expect("tracker report");
    assert_eq!(tracker.failsafe_entries, 0);
}
