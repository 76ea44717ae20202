//! Paper 003 (Romero & Ortega), Proposition 1: the adaptive momenta
//! observer on the 2-D spider crane of section 6.3 and on the differential
//! drive in its wheel angles (section 6.1). Simulations in
//! `host_tests::paper_003` (plots: `cargo run --release -p host-tests
//! --example paper_003_figures`).
//!
//! Each assertion is a bound a little weaker than the figure measured
//! (given next to it).

use host_tests::paper_002::log_decay_rate;
use host_tests::paper_003::*;

const INITIAL: [([f32; 3], [f32; 3], f32); 3] = [
    ([0.0; 3], [0.0; 3], 0.0),
    ([2.0, -1.0, 1.0], [1.0, -1.0, 0.5], 2.0),
    ([-3.0, 2.0, -2.0], [-0.5, 1.0, -1.0], -1.0),
];

/// Figures 3 and 4: with `λ = 0.8`, from several initial `p̂, d̂, r̂3`,
/// `p̃ → 0` and (the inputs being exciting) `d̃ → 0`, `r̃3 → 0`; the
/// Lyapunov function (25) never grows by more than the discretization's
/// `O(h²)`.
#[test]
fn figures_3_4_crane_errors_converge() {
    for (p0, d0, r0) in INITIAL {
        let e = crane_run(&CraneRun::paper(p0, d0, r0));
        let v0 = e.lyapunov.points[0].1;
        let growth = e
            .lyapunov
            .points
            .windows(2)
            .map(|w| w[1].1 - w[0].1)
            .fold(f64::MIN, f64::max);
        let (p, d, r) = (
            e.momenta.max_abs_over(40.0, 60.0),
            e.disturbance.max_abs_over(40.0, 60.0),
            e.friction.max_abs_over(40.0, 60.0),
        );
        println!(
            "p̂0 {p0:?}, d̂0 {d0:?}, r̂0 {r0}: V(0) = {v0:.3}; largest over 40–60 s: \
             |p̃| {p:.1e}, |d̃| {d:.1e}, |r̃3| {r:.1e}; largest 10 ms rise of V {growth:.1e}"
        );
        // Measured (all three starts): |p̃| ≤ 4.1e-3, |d̃| ≤ 6.3e-3,
        // |r̃3| ≤ 4.1e-3 (the O(h) floor of the step); V rises by ≤ 8.7e-7.
        assert!(p < 5e-3 && d < 1e-2 && r < 1e-2, "{p} {d} {r}");
        assert!(growth < 1e-5, "{growth}");
        assert!(e.lyapunov.abs_at(60.0) < 1e-3 * v0.max(0.1));
    }
}

/// Figures 5 and 6: `λ` sets how fast `p̃` falls; the parameters follow
/// more slowly, whatever `λ`.
#[test]
fn figures_5_6_effect_of_lambda() {
    let mut early = Vec::new();
    for lambda in [0.2_f32, 0.8, 3.0] {
        let mut run = CraneRun::paper(INITIAL[1].0, INITIAL[1].1, INITIAL[1].2);
        run.lambda = lambda;
        let e = crane_run(&run);
        let rate = log_decay_rate(&e.momenta.points, 0.0, 5.0, 1e-12).expect("samples");
        println!(
            "λ = {lambda}: |p̃| rate over 0–5 s {rate:.2} /s; |p̃(5 s)| {:.2e}, |d̃(20 s)| {:.2e}, \
             |r̃3(20 s)| {:.2e}, |p̃(60 s)| {:.1e}",
            e.momenta.abs_at(5.0),
            e.disturbance.abs_at(20.0),
            e.friction.abs_at(20.0),
            e.momenta.abs_at(60.0)
        );
        early.push(e.momenta.abs_at(5.0));
    }
    // Measured |p̃(5 s)|: 1.35, 0.352, 0.207.
    assert!(
        early[0] > 2.0 * early[1] && early[1] > early[2],
        "{early:?}"
    );
}

/// Figure 7: step changes of `d1` (0.1 → 0.6 → 0.1 N every 30 s) are
/// tracked.
#[test]
fn figure_7_step_in_d1_is_tracked() {
    let mut run = CraneRun::paper([0.0; 3], [0.0; 3], 0.0);
    run.d1_step = 0.5;
    run.d1_step_every_s = 30.0;
    run.duration_s = 120.0;
    let e = crane_run(&run);
    for (from, to, truth) in [(40.0, 60.0, 0.6), (70.0, 90.0, 0.1), (100.0, 120.0, 0.6)] {
        let worst = e
            .d1_hat
            .points
            .iter()
            .filter(|p| p.0 >= from && p.0 < to)
            .map(|p| (p.1 - truth).abs())
            .fold(0.0, f64::max);
        println!("d1 = {truth}: largest |d̂1 − d1| over {from}–{to} s {worst:.1e}");
        // Measured ≤ 2.9e-3, 6.3e-3, 4.7e-3 (from 10 s after each step).
        assert!(worst < 1e-2, "{worst}");
    }
}

/// Section 6.1 on the robot: 1024-count encoders at 100 Hz. The observer's
/// wheel speeds against differencing the counts, the load torque after the
/// robot drives onto a 5 % slope, and the wheel friction.
#[test]
fn wheel_speeds_load_and_friction_from_encoder_angles() {
    let w = wheel_run(WHEEL_GAINS, 120.0, 60.0);
    println!(
        "wheel speed RMS error: observer {:.4} rad/s, differencing {:.4} rad/s ({:.1}× better)",
        w.observer_speed_rms,
        w.differencing_speed_rms,
        w.differencing_speed_rms / w.observer_speed_rms
    );
    println!(
        "load torque: before the step {:.4?} N·m (truth 0), last 20 s {:.4?} (truth {:.4}), \
         90 % after {:?} s; friction {:.5?} N·m·s/rad (truth {})",
        w.pre_step_load_torque,
        w.final_load_torque,
        w.true_load_torque,
        w.load_rise_s,
        w.final_friction,
        w.true_friction
    );
    // Measured: 0.053 vs 0.251 rad/s; loads −0.0359, −0.0363 N·m (truth
    // −0.0343; −0.006 before the step), 90 % after 1.23 s; friction 0.0090
    // (truth 0.01): the quantization noise biases the quadratic update.
    assert!(w.observer_speed_rms < 0.25 * w.differencing_speed_rms);
    for i in 0..2 {
        let load_error = (w.final_load_torque[i] - w.true_load_torque).abs();
        assert!(load_error < 0.25 * w.true_load_torque.abs(), "{w:?}");
        let friction_error = (w.final_friction[i] - w.true_friction).abs();
        assert!(friction_error < 0.2 * w.true_friction, "{w:?}");
    }
    assert!(
        w.load_rise_s.is_some_and(|t| t < 10.0),
        "{:?}",
        w.load_rise_s
    );
}
