//! Paper 002 (Jakubiak, Nijmeijer & Lefeber), section 3: the mobile car.
//! Simulations in `host_tests::paper_002::unicycle` (plots:
//! `cargo run --release -p host-tests --example paper_002_figures`).
//!
//! Each assertion is a bound a little weaker than the figure measured
//! (given next to it) with the step `h = 1 ms` (section 3 figures) or
//! `h = 10 ms` (figure-eight comparison). Decay rates are least-squares
//! slopes of `ln|error|` (1/s).

use host_tests::paper_002::comparison::comparison_markdown;
use host_tests::paper_002::unicycle::*;
use host_tests::paper_002::{Series, log_decay_rate};

fn rate(s: &Series, from: f64, to: f64) -> f64 {
    log_decay_rate(&s.points, from, to, 1e-12).expect("enough samples")
}

fn last(s: &Series) -> f64 {
    s.points.last().expect("samples").1.abs()
}

/// Figure 4: with `v` persistently exciting (`v = 1`, `v = sin t`) every
/// error of the Proposition 4 observer decays exponentially from
/// `x̃ = 10, ỹ = 40, θ̃ = π/2` to the f32 floor.
#[test]
fn figure_4_pose_observer_converges_exponentially() {
    for (v, name) in [
        ((|_| 1.0) as fn(f64) -> f64, "v = 1"),
        (f64::sin as fn(f64) -> f64, "v = sin t"),
    ] {
        let [x, y, th] = pose_observer_run(v, 0.5, 20.0);
        let rates = [rate(&x, 0.0, 5.0), rate(&y, 0.0, 5.0), rate(&th, 0.0, 5.0)];
        println!(
            "fig 4, {name}: rates over 0–5 s {rates:.2?} /s; |θ̃(20 s)| = {:.1e}",
            last(&th)
        );
        // Measured: −3.55, −4.06, −3.08 (v = 1); −2.99, −3.81, −2.96 (sin t).
        assert!(rates.iter().all(|&r| r < -2.5), "{name}: {rates:?}");
        // Measured 2.8e-5 rad (v = 1), 1.6e-6 rad (sin t).
        assert!(last(&th) < 1e-4, "{name}: {}", last(&th));
    }
}

/// Figure 5: `v` not persistently exciting. With `∫v² < ∞` the heading
/// error does not go to zero (5(a): `v = e^{−t}`; 5(b): `v = 1/(1+t)`);
/// with `∫v² = ∞` (5(c): `v = 1/√(1+t)`) it does.
#[test]
fn figure_5_pose_observer_without_excitation() {
    let [_, _, th_exp] = pose_observer_run(|t| (-t).exp(), 0.5, 20.0);
    let stall = rate(&th_exp, 5.0, 20.0);
    println!(
        "fig 5(a) v = e^-t: |θ̃(20 s)| = {:.3} rad, rate 5–20 s {stall:.1e} /s",
        last(&th_exp)
    );
    // Measured 1.774 rad, rate −2e-6 /s: stuck.
    assert!(last(&th_exp) > 1.5 && stall > -1e-3);

    let [_, _, th_inv] = pose_observer_run(|t| 1.0 / (1.0 + t), 0.5, 20.0);
    println!(
        "fig 5(b) v = 1/(1+t): |θ̃(20 s)| = {:.3} rad, rate 15–20 s {:.3} /s",
        last(&th_inv),
        rate(&th_inv, 15.0, 20.0)
    );
    // Measured 0.025 rad (900× figure 4's), rate −0.03 /s and slowing.
    assert!(last(&th_inv) > 1e-2);
    assert!(rate(&th_inv, 15.0, 20.0) > -0.1);

    let [_, _, th_sqrt] = pose_observer_run(|t| 1.0 / (1.0 + t).sqrt(), 0.5, 20.0);
    println!(
        "fig 5(c) v = 1/√(1+t): |θ̃(20 s)| = {:.1e} rad",
        last(&th_sqrt)
    );
    // Measured 1.1e-5 rad: converges. At the paper's gains it reaches the
    // f32 floor within 5 s, before its decay visibly slows (the paper's
    // "not exponentially" shows over longer horizons or smaller gains).
    assert!(last(&th_sqrt) < 1e-4);
}

/// Figure 6: Proposition 7 with `v_r = ω_r = 1`, `c2 = 2, a = 10, γ = 0.9`
/// from `(x_e, y_e, θ_e) = (10, 20, π/2)`, `ψ̃ = 1`: all errors decay
/// exponentially.
#[test]
fn figure_6_sine_observer_controller_converges_exponentially() {
    let run = robot_frame_run(RobotFrameLoop::HeadingErrorSine, constant_inputs, 30.0);
    let rates = [
        rate(&run.position_error, 0.0, 15.0),
        rate(&run.heading_error, 0.0, 15.0),
        rate(&run.observer_error, 0.0, 15.0),
    ];
    println!(
        "fig 6: rates over 0–15 s {rates:.2?} /s; |(x_e, y_e)(30 s)| = {:.1e} m",
        last(&run.position_error)
    );
    // Measured −0.78, −0.80, −0.79 /s.
    assert!(rates.iter().all(|&r| r < -0.6), "{rates:?}");
    // Measured 6.3e-9 m.
    assert!(last(&run.position_error) < 1e-6);
}

/// Figure 7: `ω_r = 1/√(1+t)` is not persistently exciting: the position
/// error still decreases, but far from exponentially (the paper: only
/// asymptotically, since `∫ω_r² = ∞`).
#[test]
fn figure_7_without_turning_excitation_position_converges_slowly() {
    let pe = robot_frame_run(RobotFrameLoop::HeadingErrorSine, constant_inputs, 30.0);
    let run = robot_frame_run(RobotFrameLoop::HeadingErrorSine, fading_turn_inputs, 30.0);
    let slow = rate(&run.position_error, 15.0, 30.0);
    let fast = rate(&pe.position_error, 0.0, 15.0);
    println!(
        "fig 7: |(x_e, y_e)(30 s)| = {:.2} m, rate 15–30 s {slow:.3} /s (figure 6: {fast:.2} /s); |θ_e(30 s)| = {:.1e}",
        last(&run.position_error),
        last(&run.heading_error)
    );
    // Measured 1.90 m and −0.022 /s, against −0.76 /s with ω_r = 1.
    assert!(last(&run.position_error) > 1.0);
    assert!(slow < 0.0 && slow > -0.05);
    // The heading error is still driven to zero (measured 1.7e-4 rad).
    assert!(last(&run.heading_error) < 1e-3);
}

/// Figure 8: `v_r = e^{−t/2}` is not persistently exciting: the heading
/// error and the observer error stall away from zero. (The position error
/// goes to zero here because the reference stops.)
#[test]
fn figure_8_without_speed_excitation_heading_and_observer_stall() {
    let run = robot_frame_run(RobotFrameLoop::HeadingErrorSine, fading_speed_inputs, 30.0);
    println!(
        "fig 8: |θ_e(30 s)| = {:.4} rad, |ψ̃(30 s)| = {:.4}, rates 15–30 s {:.1e}, {:.1e} /s",
        last(&run.heading_error),
        last(&run.observer_error),
        rate(&run.heading_error, 15.0, 30.0),
        rate(&run.observer_error, 15.0, 30.0)
    );
    // Measured 0.0316 rad and 0.0153, rates ~1e-6 /s.
    assert!(last(&run.heading_error) > 0.02);
    assert!(last(&run.observer_error) > 0.01);
    assert!(rate(&run.heading_error, 15.0, 30.0).abs() < 1e-3);
}

/// Proposition 5: `ỹ_e` decays as `e^{−c_y ∫ω²}` (48): with `c_y = 1` and
/// `ω → ω_r = 1`, at 1 /s.
#[test]
fn proposition_5_lateral_observer_decays_at_c_y_omega_squared() {
    let run = robot_frame_run(RobotFrameLoop::LateralObserver, constant_inputs, 30.0);
    let r = rate(&run.observer_error, 5.0, 15.0);
    println!("prop 5: ỹ_e rate 5–15 s {r:.3} /s (expected −c_y ω_r² = −1)");
    // Measured −1.063 /s.
    assert!((-1.3..-0.8).contains(&r), "{r}");
}

/// Proposition 6: with the controller (50) the observer error decays at
/// `c_e ω²` = 1 /s, not at the printed `c2 + c_e ω²` = 3 /s (the `c2`
/// term cancels: see `wmr_core::control::heading_error_sine`), and the closed
/// loop converges.
#[test]
fn proposition_6_longitudinal_observer_and_controller_converge() {
    let run = robot_frame_run(RobotFrameLoop::LongitudinalObserver, constant_inputs, 30.0);
    let r = rate(&run.observer_error, 5.0, 15.0);
    println!(
        "prop 6: x̃_e rate 5–15 s {r:.3} /s; |(x_e, y_e)(30 s)| = {:.1e} m",
        last(&run.position_error)
    );
    // Measured −1.026 /s and 1.2e-7 m.
    assert!((-1.3..-0.8).contains(&r), "{r}");
    assert!(last(&run.position_error) < 1e-5);
}

/// Position-only pairings on paper 001's figure-eight with the nearest
/// 10 cm tag every tick (statistics after 100 s of 480 s).
#[test]
fn figure_eight_position_only_pairings() {
    println!("{}", comparison_markdown());
    let stats = |p| figure_eight_comparison(p).0;
    let paper_001 = stats(Pairing::HeadingObserverWithSaturatedLaw);
    // Same run as paper 001 §6.3.2's scenario: 0.0263 / 0.0037 m.
    assert!(
        paper_001.max_m < 0.03 && paper_001.mean_m < 0.005,
        "{paper_001:?}"
    );
    // Measured 0.0431 / 0.0066 m: the 4-state observer works with 001's
    // law but filters the tag quantization less well than observer (5).
    let prop4 = stats(Pairing::PoseObserverWithSaturatedLaw);
    assert!(prop4.max_m < 0.05 && prop4.mean_m < 0.008, "{prop4:?}");
    // Measured 0.416 / 0.099 m and 0.078 / 0.033 m (0.416 / 0.104 and
    // 0.218 / 0.107 with libm's sinf/cosf: Prop. 7 depends on the noise's
    // path, see the pairings test below): they track, coarsely;
    // the figure-eight's ω_r (≤ 0.03 rad/s) barely excites the y_e
    // dynamics these laws rely on (Remark 5).
    let cascaded = stats(Pairing::PoseObserverWithCascaded);
    assert!(
        cascaded.max_m < 0.5 && cascaded.mean_m < 0.15,
        "{cascaded:?}"
    );
    // Proposition 7 depends on the path of the quantization noise (a 1-ulp
    // change of one sin redraws it): the median of an ensemble of starts
    // (`host_tests::ENSEMBLE_OFFSETS_M`) is held to the bounds. Measured
    // over 32 starts: median 0.298 / 0.136 m (0.217–0.378 m) with the f32
    // kernels, 0.498 / 0.198 m (0.227–0.498 m) with libm's sinf/cosf; the
    // bound on the max, 0.55 m, sits just above libm's median.
    let prop7: Vec<ErrorStats> = host_tests::ENSEMBLE_OFFSETS_M
        .iter()
        .map(|&offset| figure_eight_comparison_from(Pairing::PoseObserverWithProp7, offset).0)
        .collect();
    let errors = host_tests::EnsembleErrors::new(
        "Prop. 7 ensemble",
        prop7.iter().map(|s| (s.max_m, s.mean_m)),
    );
    let (max, mean) = (errors.median_max(), errors.median_mean());
    assert!(max < 0.55 && mean < 0.22, "median {max} / {mean}");
}

/// The same pairings selected in a scenario file and run by the simulator
/// through the core's `OutputFeedbackTracker` (unicycle plant, nearest
/// 10 cm tag) and through the whole `Pilot` device stack (motors,
/// encoders, RFID frames). The first three give the harness's figures
/// within the stack's own effects; Proposition 7's depend on the path of
/// the quantization noise (see the bounds).
#[test]
fn pairings_selected_in_a_scenario_file_run_in_the_simulator_and_the_pilot() {
    use firmware_sim::scenario::{EstimatorSpec, LawSpec};
    let cases = [
        (
            EstimatorSpec::HeadingObserver,
            LawSpec::Saturated,
            0.03,
            0.005,
        ),
        // Measured (unicycle / full stack): 0.0430 / 0.0066 m, 0.0430 / 0.0073 m.
        (
            EstimatorSpec::POSE_OBSERVER,
            LawSpec::Saturated,
            0.05,
            0.008,
        ),
        // 0.4159 / 0.0953 m, 0.4514 / 0.1064 m.
        (EstimatorSpec::POSE_OBSERVER, LawSpec::CASCADED, 0.5, 0.12),
        // Proposition 7: the y_e feedthrough `a v_r y_e` of (58a) turns the
        // 5 cm tag quantization into ψ̂ noise (a v_r ≈ 8 /m), and the result
        // depends on the noise's path. Over 32 starts, median max / mean
        // (spread of the max), with the f32 kernels [libm's sinf/cosf]:
        // unicycle 0.455 [0.667] / 0.200 [0.250] (0.10–27.8 m [0.11–26.9]:
        // some starts lose the reference), full stack 2.19 [2.35] / 0.77
        // [1.03] (1.0–4.7 m [1.2–7.4], with the drive's limits). The
        // bounds, 0.75 / 0.3 and 3.0 / 1.1 m, sit just above libm's medians.
        (
            EstimatorSpec::POSE_OBSERVER,
            LawSpec::HEADING_ERROR_SINE,
            0.75,
            0.3,
        ),
    ];
    let mut failures = Vec::new();
    for name in ["figure_eight_rfid", "figure_eight_rfid_full_stack"] {
        for (estimator, law, max_bound, mean_bound) in cases {
            if law == LawSpec::HEADING_ERROR_SINE {
                // Noise-path dependent: the median of an ensemble of starts
                // (`host_tests::ENSEMBLE_OFFSETS_M`) is held to the bounds.
                let ensemble = host_tests::run_scenario_ensemble(name, |scenario| {
                    scenario.estimator = estimator;
                    scenario.controller.law = law;
                });
                let errors = host_tests::EnsembleErrors::new(
                    &format!("{name}, Prop. 7 ensemble"),
                    ensemble.iter().map(|s| (s.max_error_m, s.mean_error_m)),
                );
                assert!(ensemble.iter().all(|s| s.non_finite_ticks == 0));
                let (max, mean) = (errors.median_max(), errors.median_mean());
                // The full stack adds encoder and reader quantization.
                let (max_bound, mean_bound) = if name.ends_with("full_stack") {
                    (3.0, 1.1)
                } else {
                    (max_bound, mean_bound)
                };
                if !(max < max_bound && mean < mean_bound) {
                    failures.push(format!("{name} Prop. 7: median {max:.4} / {mean:.4}"));
                }
                continue;
            }
            let s = host_tests::run_scenario_variant(name, |scenario| {
                scenario.estimator = estimator;
                scenario.controller.law = law;
            });
            assert_eq!(s.non_finite_ticks, 0);
            if !(s.max_error_m < max_bound && s.mean_error_m < mean_bound) {
                failures.push(format!(
                    "{name} {estimator:?} {law:?}: {:.4} / {:.4}",
                    s.max_error_m, s.mean_error_m
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
