//! Paper 003 (Romero & Ortega), Proposition 2: the observer with dynamic
//! scaling on the 2-D spider crane of section 6.3, factored with the
//! standard Cholesky factor of `M⁻¹` (non-commuting columns, so `J ≠ 0`,
//! Remark 6.1). Simulations in `host_tests::paper_003::scaled`; plots with
//! `cargo run --release -p host-tests --example paper_003_figures`.
//!
//! Each assertion is a bound a little weaker than the figure measured
//! (given next to it).

use host_tests::paper_003::scaled::*;

/// The transformed model (5)–(7) with `J_jk = −𝐩ᵀ[T_j, T_k]` matches the
/// independent Lagrangian plant, and the gyroscopic force is large: the
/// printed `−pᵀ[T_j, T_k]` would leave a residual the size of `|J p|`.
#[test]
fn transformed_model_matches_the_plant() {
    let (residual, gyroscopic) = transformed_model_residual();
    println!("largest |ṗ − model| {residual:.2e}, largest |J(q,p)p| {gyroscopic:.2e}");
    // Measured 6.0e-5 (f32 rounding of the model terms) against 23.4.
    assert!(gyroscopic > 10.0, "{gyroscopic}");
    assert!(residual < 1e-4 * gyroscopic, "{residual}");
}

const INITIAL: [([f32; 3], [f32; 3]); 3] = [
    ([0.0; 3], [0.0; 3]),
    ([2.0, -1.0, 1.0], [1.0, -1.0, 0.5]),
    ([-3.0, 2.0, -2.0], [-0.5, 1.0, -1.0]),
];

fn run(momenta_0: [f32; 3], disturbance_0: [f32; 3], scaling_0: f32) -> ScaledCraneErrors {
    scaled_crane_run(&ScaledCraneRun {
        kappa: 1.0,
        disturbance_gain: 1.0,
        momenta_0,
        disturbance_0,
        scaling_0,
        period_s: 1e-3,
        duration_s: 60.0,
    })
}

/// From several initial estimates and scaling factors the momenta and
/// disturbance errors fall (the paper's inputs are exciting), the scaling
/// factor stays `≥ 1` and returns to 1, and no sample is rejected.
#[test]
fn converges_from_several_initial_conditions() {
    for (p0, d0) in INITIAL {
        for r0 in [1.0_f32, 5.0] {
            let e = run(p0, d0, r0);
            let (p_start, d_start) = (e.momenta.abs_at(0.0), e.disturbance.abs_at(0.0));
            let (p_late, d_late) = (
                e.momenta.max_abs_over(40.0, 60.0),
                e.disturbance.max_abs_over(40.0, 60.0),
            );
            let lowest = e
                .scaling
                .points
                .iter()
                .map(|p| p.1)
                .fold(f64::INFINITY, f64::min);
            println!(
                "p̂0 {p0:?}, d̂0 {d0:?}, r0 {r0}: |p̃| {p_start:.2} → {p_late:.1e}, \
                 |d̃| {d_start:.2} → {d_late:.1e} (largest over 40–60 s); r max {:.4}, \
                 min {lowest:.6}, r(60 s) {:.6}; |J p| up to {:.1}",
                e.scaling.max_abs_over(0.0, 60.0),
                e.scaling.abs_at(60.0),
                e.gyroscopic.max_abs_over(0.0, 60.0),
            );
            // Measured over all six runs: |p̃| ≤ 8.5e-3, |d̃| ≤ 6.1e-2 over
            // 40–60 s (|d̃| still falling, about 3× per 20 s); r(60 s) − 1 =
            // 3.0e-5. Past ~80 s the errors grow again: the crane drifts
            // under the constant d (no friction on q1, q2), to ~240 m at
            // 60 s, and the f32 resolution of q over a 1 ms step dominates.
            assert!(p_late < 1.2e-2, "{p_late}");
            assert!(d_late < 8e-2, "{d_late}");
            assert!(lowest >= 1.0);
            assert!(e.scaling.abs_at(60.0) < 1.001);
            assert_eq!(e.rejected_updates, 0);
        }
    }
}

/// The scaling dynamics (46): started at `r(0) = 5` it decays as
/// `1 + 4e^{−ψt/4}` while the filter errors are small, and started at 1 it
/// is pushed up by the mismatch terms `Δ_q, Δ_p` while the estimates are
/// poor.
#[test]
fn scaling_factor_dynamics() {
    let e = run(INITIAL[1].0, INITIAL[1].1, 5.0);
    let psi = 4.0 * (1.0 + 1.0);
    let predicted = 4.0 * (-psi * 2.0 / 4.0_f64).exp();
    let measured = e.scaling.abs_at(2.0) - 1.0;
    println!("r0 = 5: r(2 s) − 1 = {measured:.4} (pure decay: {predicted:.4})");
    // Measured 0.0743 against 0.0733: the Δ terms add 1.4 %.
    assert!(measured >= predicted && measured < 1.05 * predicted);
    let pushed = run(INITIAL[1].0, INITIAL[1].1, 1.0);
    let peak = pushed.scaling.max_abs_over(0.0, 60.0);
    println!("r0 = 1: r peaks at {peak:.4}");
    // Measured 1.053.
    assert!(peak > 1.02, "{peak}");
}
