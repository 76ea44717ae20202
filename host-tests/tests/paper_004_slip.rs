//! Paper 004 (Iossaqui, Camino & Zampieri): the tracked robot under slip
//! (i = 0.25 during 22.5–45 s) with the adaptive velocity-based controller
//! (scenario 1) and the torque-based one (scenario 2), fed by the EKF, the
//! UKF and the particle filter on measurements with the paper's noise
//! (`host_tests::paper_004`, over the simulator's `firmware_sim::slip` and
//! its embedded scenarios `paper_004_velocity`, `paper_004_torque`). Every
//! filter run is repeated for noise seeds 1 to 5 and the bounds hold for
//! the worst; each is a little weaker than the worst figure measured (given
//! next to it).

use host_tests::paper_004::*;

const SEEDS: std::ops::RangeInclusive<u64> = 1..=5;
const SLIP_P: f64 = 4.0 / 3.0;

/// Worst over the seeds of each figure.
#[derive(Debug, Default)]
struct Worst {
    before: f64,
    during: f64,
    after: f64,
    slip_gap: f64,
    slip_estimate_error: f64,
    slip_estimate_after: f64,
    estimate_error: f64,
}

fn worst(scenario: Scenario, estimator: Estimator) -> Worst {
    let mut w = Worst {
        slip_gap: f64::INFINITY,
        ..Worst::default()
    };
    for seed in SEEDS {
        let r = slip_run(scenario, estimator, seed);
        let (during_p, after_p) = (
            r.mean_slip_estimate(35.0, 45.0),
            r.mean_slip_estimate(55.0, 60.0),
        );
        let estimate = r.estimate_error.points.iter().map(|p| p.1).sum::<f64>()
            / r.estimate_error.points.len() as f64;
        w.before = w.before.max(r.position_error_rms(15.0, 22.5));
        w.during = w.during.max(r.position_error_rms(25.0, 45.0));
        w.after = w.after.max(r.position_error_rms(50.0, 60.0));
        w.slip_gap = w.slip_gap.min(during_p - after_p);
        w.slip_estimate_error = w.slip_estimate_error.max((during_p - SLIP_P).abs());
        w.slip_estimate_after = w.slip_estimate_after.max(after_p);
        w.estimate_error = w.estimate_error.max(estimate);
    }
    println!("{scenario:?}, {estimator:?}, worst of seeds {SEEDS:?}: {w:.3?}");
    w
}

/// The controllers on the true state: the errors converge before the slip,
/// stay small during it and after; `p̂` goes to `1/(1 − 0.25)` during the
/// slip and back towards 1 after.
#[test]
fn controllers_on_the_true_state() {
    for scenario in [Scenario::Velocity, Scenario::Torque] {
        let r = slip_run(scenario, Estimator::Exact, 0);
        let (during, after) = (
            r.mean_slip_estimate(35.0, 45.0),
            r.mean_slip_estimate(55.0, 60.0),
        );
        println!(
            "{scenario:?}, exact: position error RMS {:.3} / {:.3} / {:.3} m (before / during / \
             after the slip), p̂ {during:.3} during, {after:.3} after",
            r.position_error_rms(15.0, 22.5),
            r.position_error_rms(25.0, 45.0),
            r.position_error_rms(50.0, 60.0)
        );
        // Measured: velocity 0.033 / 0.005 / 0.013 m, p̂ 1.379, 1.065;
        // torque 0.024 / 0.001 / 0.011 m, p̂ 1.328, 1.057.
        assert!(r.position_error_rms(15.0, 22.5) < 0.04);
        assert!(r.position_error_rms(25.0, 45.0) < 0.01);
        assert!(r.position_error_rms(50.0, 60.0) < 0.02);
        assert!((during - SLIP_P).abs() < 0.05 * SLIP_P, "{during}");
        assert!(after < 1.08, "{after}");
    }
}

/// Scenario 1 with the EKF and the UKF (they agree to a few %): the
/// tracking error falls from 1.5 m to about 0.15 m RMS before the slip,
/// stays below 0.1 m during it and after; `p̂` is higher during the slip
/// than after it. Before the slip `p̂` is already high (1.7–2.1): the
/// initial error drives (7) up whatever the estimator (1.66 on the true
/// state).
#[test]
fn scenario_1_gaussian_filters() {
    for estimator in [Estimator::Ekf, Estimator::Ukf] {
        let w = worst(Scenario::Velocity, estimator);
        // Measured (EKF / UKF): 0.184 / 0.178, 0.081 / 0.079, 0.101 /
        // 0.097 m; p̂ gap ≥ 0.32 / 0.32, after ≤ 1.134 / 1.144; estimate
        // error ≤ 0.090 / 0.085 m.
        assert!(w.before < 0.22 && w.during < 0.1 && w.after < 0.12, "{w:?}");
        assert!(w.slip_gap > 0.25 && w.slip_estimate_after < 1.2, "{w:?}");
        assert!(w.estimate_error < 0.1, "{w:?}");
    }
}

/// Scenario 2 with the EKF and the UKF: errors converge before the slip,
/// stay bounded during it, converge again after; `p̂` reaches 1/(1 − 0.25)
/// during the slip and falls back after.
#[test]
fn scenario_2_gaussian_filters() {
    for estimator in [Estimator::Ekf, Estimator::Ukf] {
        let w = worst(Scenario::Torque, estimator);
        // Measured (EKF / UKF): 0.147 / 0.146, 0.055 / 0.058, 0.082 /
        // 0.081 m; |p̂ − 4/3| during ≤ 0.110 / 0.123, after ≤ 1.100 / 1.107;
        // estimate error ≤ 0.075 / 0.074 m.
        assert!(w.before < 0.18 && w.during < 0.07 && w.after < 0.1, "{w:?}");
        assert!(
            w.slip_estimate_error < 0.15 && w.slip_estimate_after < 1.15,
            "{w:?}"
        );
        assert!(w.estimate_error < 0.09, "{w:?}");
    }
}

/// The particle filter (100 particles, regularized, the optimal proposal)
/// in scenario 1: it tracks the robot about as the EKF does.
/// Its noisier estimates push `p̂` up through law (7) a little more than
/// the EKF's (worst seed of 1–5: 0.46 above 4/3 during the slip, the
/// EKF's 0.25).
#[test]
fn scenario_1_particle_filter() {
    let w = worst(Scenario::Velocity, Estimator::ParticleFilter);
    // Measured: 0.167, 0.087, 0.097 m; estimate error ≤ 0.087 m (the
    // prior proposal with σ_q = (0.01, 0.01, 0.02): 0.122, 0.094, 0.134 m;
    // 0.074 m; unregularized: 0.182, 0.174, 0.264 m; 0.196 m).
    assert!(w.before < 0.2 && w.during < 0.2 && w.after < 0.3, "{w:?}");
    assert!(w.estimate_error < 0.22, "{w:?}");
}

/// The particle filter (as in scenario 1) in scenario 2, within the EKF's
/// tracking bounds of [`scenario_2_gaussian_filters`]: with the optimal
/// proposal it tracks as the Gaussian filters do, and `p̂` reaches
/// 1/(1 − 0.25) (its worst seed 0.152 away during the slip, the EKF's
/// 0.110; the mean over seeds 1–20 is in [`the_particle_filter_matches_the_ekf`]).
#[test]
fn scenario_2_particle_filter() {
    let w = worst(Scenario::Torque, Estimator::ParticleFilter);
    // Measured: 0.115, 0.046, 0.076 m; |p̂ − 4/3| during ≤ 0.152, after
    // ≤ 1.146; estimate error ≤ 0.064 m (with the prior proposal, 4 of
    // seeds 1–5 diverge unregularized; regularized, its mean RMS before the
    // slip over seeds 1–20 is 0.50 m).
    assert!(w.before < 0.18 && w.during < 0.07 && w.after < 0.1, "{w:?}");
    assert!(
        w.slip_estimate_error < 0.17 && w.slip_estimate_after < 1.15,
        "{w:?}"
    );
    assert!(w.estimate_error < 0.09, "{w:?}");
}

/// The particle filter's runs are reproducible from the seed.
#[test]
fn particle_filter_runs_repeat_from_the_seed() {
    let a = slip_run(Scenario::Velocity, Estimator::ParticleFilter, 3);
    let b = slip_run(Scenario::Velocity, Estimator::ParticleFilter, 3);
    let c = slip_run(Scenario::Velocity, Estimator::ParticleFilter, 4);
    assert_eq!(a, b);
    assert_ne!(a.error[0].points, c.error[0].points);
}

/// A diverged run is flagged in the summary (`diverged`, also in
/// `summary.json`), exactly when its tracking error passes
/// [`firmware_sim::slip::DIVERGED_TRACKING_ERROR_M`] (or a record is not
/// finite). The paper's own particle filter (the prior as proposal, no
/// regularization) diverges in scenario 2: tracking errors of 39–57 m over
/// seeds 1–5 (`firmware-sim slip` with `proposal = "prior"` and
/// `regularization = 0.0`), so the flag's branch runs; the scenario files'
/// filter (optimal proposal, regularized), the EKF and the UKF stay within
/// 1.6 m of either scenario's reference, far from the threshold.
///
/// Which seeds of the paper's filter diverge depends on the last bit of
/// every transcendental the particles draw through, so the test asserts
/// the flag against the error and that most of the five diverge, not a
/// list of seeds.
#[test]
fn diverged_runs_are_flagged() {
    let run = |s: &firmware_sim::slip::SlipScenario| {
        let s = firmware_sim::slip::run(s)
            .expect("the embedded scenario runs")
            .summary;
        (s.diverged, s.tracking_error_max_m)
    };
    let flagged_exactly_beyond_the_threshold = |runs: &[(bool, f64)]| {
        for &(flag, worst) in runs {
            assert_eq!(
                flag,
                !worst.is_finite() || worst > firmware_sim::slip::DIVERGED_TRACKING_ERROR_M,
                "{runs:?}"
            );
        }
    };
    let papers_filter: Vec<(bool, f64)> = (1..=5)
        .map(|seed| {
            let mut s = slip_scenario(Scenario::Torque, Estimator::ParticleFilter, seed);
            let pf = &mut s.filter.particle_filter;
            pf.proposal = firmware_sim::slip::ProposalSpec::Prior;
            pf.regularization = 0.0;
            run(&s)
        })
        .collect();
    flagged_exactly_beyond_the_threshold(&papers_filter);
    let diverged = papers_filter.iter().filter(|f| f.0).count();
    assert!(diverged >= 3, "{papers_filter:?}");

    let scenario_files: Vec<(bool, f64)> = (1..=5)
        .map(|seed| {
            run(&slip_scenario(
                Scenario::Torque,
                Estimator::ParticleFilter,
                seed,
            ))
        })
        .collect();
    flagged_exactly_beyond_the_threshold(&scenario_files);
    assert!(
        scenario_files
            .iter()
            .all(|&(flag, worst)| !flag && worst < 2.0),
        "{scenario_files:?}"
    );
    for scenario in [Scenario::Velocity, Scenario::Torque] {
        for estimator in [Estimator::Ekf, Estimator::Ukf] {
            for seed in 1..=5 {
                let (flag, worst) = run(&slip_scenario(scenario, estimator, seed));
                assert!(
                    !flag && worst < 1.6,
                    "{scenario:?} {estimator:?} {seed}: {worst}"
                );
            }
        }
    }
}

/// The particle filter with the paper's N = 100, the
/// optimal proposal and the scenario files' process noise, against the
/// EKF over seeds 1–20 of both scenarios: no run diverges, the position
/// RMS is within 1.5× the EKF's in every window of every seed, and the
/// mean `p̂` during the slip is within 0.15 of 4/3 in scenario 2. In
/// scenario 1 the EKF's own `p̂` is 0.21 above 4/3 (law (7) under the
/// paper's measurement noise), so there the particle filter's is asserted
/// within 0.15 of the EKF's.
///
/// Measured (`python3 tools/slip_pf_table.py paper_004_{velocity,torque}
/// --particles 100 --seeds 1 20`): worst ratio 1.35 and 1.24, mean `p̂`
/// 1.641 (EKF 1.547) and 1.427 (EKF 1.388). With the prior proposal (the
/// paper's) and the same noise, scenario 2's worst ratio is 53.3; with its
/// old noise 16.5 (docs/paper-004.md).
#[test]
fn the_particle_filter_matches_the_ekf() {
    for scenario in [Scenario::Velocity, Scenario::Torque] {
        let (mut worst_ratio, mut pf_p, mut ekf_p) = (0.0_f64, 0.0_f64, 0.0_f64);
        for seed in 1..=20 {
            let summary = |estimator| {
                firmware_sim::slip::run(&host_tests::paper_004::slip_scenario(
                    scenario, estimator, seed,
                ))
                .expect("the embedded scenario runs")
                .summary
            };
            let (pf, ekf) = (summary(Estimator::ParticleFilter), summary(Estimator::Ekf));
            assert!(
                !pf.diverged && pf.non_finite_records == 0 && pf.tracking_error_max_m < 2.0,
                "{scenario:?} seed {seed}: {pf:?}"
            );
            assert!(!ekf.diverged, "{scenario:?} seed {seed}: {ekf:?}");
            for (p, e) in pf.tracking.iter().zip(ekf.tracking.iter()) {
                let (p, e) = (
                    p.position_error_rms_m.expect("a window with samples"),
                    e.position_error_rms_m.expect("a window with samples"),
                );
                worst_ratio = worst_ratio.max(p / e);
            }
            let during = |s: &firmware_sim::slip::SlipSummary| {
                s.slip_estimate[0]
                    .mean_slip_estimate
                    .expect("a window with samples")
            };
            pf_p += during(&pf) / 20.0;
            ekf_p += during(&ekf) / 20.0;
        }
        println!(
            "{scenario:?}, seeds 1-20: worst PF/EKF position RMS ratio {worst_ratio:.3}, mean p̂ \
             during the slip {pf_p:.3} (EKF {ekf_p:.3})"
        );
        assert!(worst_ratio <= 1.5, "{scenario:?}: {worst_ratio}");
        match scenario {
            Scenario::Torque => assert!((pf_p - SLIP_P).abs() <= 0.15, "{pf_p}"),
            Scenario::Velocity => assert!((pf_p - ekf_p).abs() <= 0.15, "{pf_p} {ekf_p}"),
        }
    }
}
