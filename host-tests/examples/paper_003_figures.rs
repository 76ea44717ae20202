//! Regenerates the plots of paper 003's simulations (PNG): the spider
//! crane's errors (figures 3–7 of the paper), Proposition 2's observer with
//! dynamic scaling on the same crane, and the robot's wheel speeds and load
//! torques from encoder angles:
//!
//! ```sh
//! cargo run --release -p host-tests --example paper_003_figures -- [OUT_DIR]
//! ```
//!
//! `OUT_DIR` defaults to `out/paper_003`. The data come from
//! `host_tests::paper_003`, the same simulations the tests assert on.

use std::path::PathBuf;

use host_tests::paper_002::Series;
use host_tests::paper_003::scaled::{ScaledCraneRun, scaled_crane_run};
use host_tests::paper_003::{CraneRun, WHEEL_GAINS, crane_run, wheel_run};

#[path = "common/plot.rs"]
mod common;
use common::plot;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out: PathBuf = std::env::args_os()
        .nth(1)
        .map_or_else(|| PathBuf::from("out/paper_003"), PathBuf::from);
    std::fs::create_dir_all(&out)?;
    let mut written = Vec::new();
    let mut save = |name: &str, title: &str, series: &[&Series], log: bool| {
        let path = out.join(format!("{name}.png"));
        let result = plot(title, series, log, &path);
        written.push((path, result.map_err(|e| e.to_string())));
    };
    let paper = crane_run(&CraneRun::paper([2.0, -1.0, 1.0], [1.0, -1.0, 0.5], 2.0));
    save(
        "fig3_4_crane_errors",
        "Figs. 3–4: spider crane, λ = 0.8: |p̃|, |d̃|, |r̃3|",
        &[&paper.momenta, &paper.disturbance, &paper.friction],
        true,
    );
    let runs: Vec<(f32, _)> = [0.2_f32, 0.8, 3.0]
        .into_iter()
        .map(|lambda| {
            let mut run = CraneRun::paper([2.0, -1.0, 1.0], [1.0, -1.0, 0.5], 2.0);
            run.lambda = lambda;
            let mut errors = crane_run(&run);
            errors.momenta.label = format!("|p̃|, λ = {lambda}");
            errors.disturbance.label = format!("|d̃|, λ = {lambda}");
            (lambda, errors)
        })
        .collect();
    save(
        "fig5_crane_momenta_vs_lambda",
        "Fig. 5: |p̃| for λ = 0.2, 0.8, 3",
        &runs.iter().map(|(_, e)| &e.momenta).collect::<Vec<_>>(),
        true,
    );
    save(
        "fig6_crane_disturbance_vs_lambda",
        "Fig. 6: |d̃| for λ = 0.2, 0.8, 3",
        &runs.iter().map(|(_, e)| &e.disturbance).collect::<Vec<_>>(),
        true,
    );
    let mut step = CraneRun::paper([0.0; 3], [0.0; 3], 0.0);
    step.d1_step = 0.5;
    step.d1_step_every_s = 30.0;
    step.duration_s = 120.0;
    let step = crane_run(&step);
    save(
        "fig7_crane_d1_steps",
        "Fig. 7: d1 stepping every 30 s and its estimate (N)",
        &[&step.d1, &step.d1_hat],
        false,
    );
    let scaled = scaled_crane_run(&ScaledCraneRun {
        kappa: 1.0,
        disturbance_gain: 1.0,
        momenta_0: [2.0, -1.0, 1.0],
        disturbance_0: [1.0, -1.0, 0.5],
        scaling_0: 5.0,
        period_s: 1e-3,
        duration_s: 60.0,
    });
    let mut scaling_excess = scaled.scaling.clone();
    scaling_excess.label = "r − 1".to_string();
    for point in &mut scaling_excess.points {
        point.1 -= 1.0;
    }
    save(
        "prop2_crane_errors",
        "Prop. 2 (dynamic scaling), Cholesky factor, κ = 1, r(0) = 5: |p̃|, |d̃|, r − 1",
        &[&scaled.momenta, &scaled.disturbance, &scaling_excess],
        true,
    );
    let wheels = wheel_run(WHEEL_GAINS, 120.0, 60.0);
    let [truth, observer, differencing] = &wheels.speeds;
    save(
        "wheel_speed_right",
        "Right wheel speed (rad/s): 1024-count encoder at 100 Hz",
        &[differencing, observer, truth],
        false,
    );
    save(
        "wheel_load_torque",
        "Load torque (N·m): 5 % slope from 60 s",
        &wheels.loads.iter().collect::<Vec<_>>(),
        false,
    );
    for (path, result) in written {
        result.map_err(|e| format!("{}: {e}", path.display()))?;
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}
