//! The encoder + tag fusion EKF (`wmr_core::estimation::fusion`) against paper 001's
//! position-only loop on the figure-eight with the nearest 10 cm tag every
//! tick (simulation in `host_tests::fusion`). Each assertion is a bound a
//! little weaker than the figure measured (given next to it); errors are
//! `|p − p_r|` after 100 s, m.

use host_tests::fusion::*;
use wmr_core::estimation::spec::{EstimatorSpec, FusionFilterSpec, FusionSpec};

fn run(estimator: Estimator, wheels: WheelTruth, tuning: FusionTuning) -> FusionRun {
    let r = figure_eight_run(estimator, wheels, tuning);
    println!(
        "{estimator:?}, {wheels:?}: tracking max {:.4} mean {:.4} RMS {:.4}; \
         estimate max {:.4} mean {:.4}; heading ≤ {:.3} rad; {:?}; same-tag reads {}",
        r.tracking.max_m,
        r.tracking.mean_m,
        r.tracking.rms_m,
        r.estimation.max_m,
        r.estimation.mean_m,
        r.heading_error_max_rad,
        r.counters,
        r.same_tag_reads
    );
    r
}

/// The paper's setting (exact wheels, encoder quantization only): the
/// fusion EKF, with each change of tag taken as a boundary crossing, beats
/// paper 001's observer by 5× on the largest error and 7× on the mean.
#[test]
fn fusion_beats_paper_001_on_the_papers_run() {
    let paper = run(
        Estimator::HeadingObserver,
        WheelTruth::IDEAL,
        FusionTuning::FIXED_WHEELS,
    );
    let fusion = run(
        Estimator::FusionEkf,
        WheelTruth::IDEAL,
        FusionTuning::FIXED_WHEELS,
    );
    // Measured: 001 0.0263 / 0.0037; fusion 0.0047 / 0.0005 (issue target
    // ≤ 0.02 / ≤ 0.005).
    assert!(paper.tracking.max_m > 0.02);
    assert!(fusion.tracking.max_m < 0.01 && fusion.tracking.mean_m < 0.001);
    assert_eq!(fusion.counters.fixes_invalid, 0);
}

/// Wheel radii off by +0.5 % / −0.3 %: the heading from odometry drifts by
/// 4 mrad/s. Paper 001's loop lags by 8 cm on average; the EKF that learns
/// the wheel scales (and a drive that uses them) keeps 4 mm.
#[test]
fn learning_the_wheel_scales_removes_the_radius_error() {
    let wheels = WheelTruth {
        slip_std_per_sqrt_m: 0.0,
        ..WheelTruth::REALISTIC
    };
    let paper = run(
        Estimator::HeadingObserver,
        wheels,
        FusionTuning::FIXED_WHEELS,
    );
    let fixed = run(Estimator::FusionEkf, wheels, FusionTuning::FIXED_WHEELS);
    let learnt = run(Estimator::FusionEkf, wheels, FusionTuning::LEARN_WHEELS);
    // Measured: 001 0.113 / 0.083; fixed wheels 0.149 / 0.042; learnt
    // 0.020 / 0.0038.
    assert!(paper.tracking.mean_m > 0.05 && fixed.tracking.mean_m > 0.03);
    assert!(learnt.tracking.max_m < 0.03 && learnt.tracking.mean_m < 0.005);
}

/// Random wheel slip: with the EKF's default tuning (wheel noise 1e-3
/// m²/m, same-tag reads skipped) the worst error under 2 mm/√m of slip is
/// twice paper 001's, because the lateral position is not observed while
/// the robot drives along a row of tags. With a wheel-noise model near the
/// slip's (3e-5) and the cell-edge constraint on (reads of an unchanged
/// tag pull an estimate that left the cell back to its edge), the fusion
/// EKF beats paper 001's loop under slip and keeps the issue's target
/// (≤ 0.02 / ≤ 0.005 m) on exact wheels. The harness's plant, not the
/// simulator's, has slip and radius errors.
#[test]
fn random_slip_with_the_cell_edge_constraint() {
    let slip = |std| WheelTruth {
        right_radius_error: 0.0,
        left_radius_error: 0.0,
        slip_std_per_sqrt_m: std,
    };
    let robust = |base: FusionTuning| FusionTuning {
        variance_per_m: 3e-5,
        edges: true,
        ..base
    };
    // (wheels, tuning base, bound on the worst start's max, bound on the
    // median start's mean). Over 32 starts, fusion worst max / median
    // mean, m, with the f32 kernels and series [with libm's sinf/cosf]
    // (001, one run, max / mean): 2 mm/√m slip 0.0648 [0.0647] / 0.0100
    // [0.0101] (0.0590 / 0.0134); realistic (radii + 1 cm/√m, scales
    // learnt) 0.204 [0.275] / 0.0470 [0.0455] (0.291 / 0.0931); exact
    // wheels 0.0253 [0.0263] / 0.0012 [0.0014] (0.0263 / 0.0037); radii
    // only, learnt 0.0272 [0.0337] / 0.0009 [0.0011] (0.113 / 0.0834). The
    // worst error over starts is bimodal under slip (0.0525 or 0.065 m:
    // on par with paper 001's, not better), so the max is bounded over
    // every start and only the mean is compared with paper 001's. The
    // default tuning under 2 mm/√m, one run: 0.0614 / 0.0104.
    let cases = [
        (slip(0.002), FusionTuning::FIXED_WHEELS, 0.068, 0.012),
        (
            WheelTruth::REALISTIC,
            FusionTuning::LEARN_WHEELS,
            0.29,
            0.055,
        ),
        (WheelTruth::IDEAL, FusionTuning::FIXED_WHEELS, 0.028, 0.0015),
        (
            WheelTruth {
                slip_std_per_sqrt_m: 0.0,
                ..WheelTruth::REALISTIC
            },
            FusionTuning::LEARN_WHEELS,
            0.035,
            0.002,
        ),
    ];
    let mut failures = Vec::new();
    for (wheels, base, max_bound, mean_bound) in cases {
        let paper = run(
            Estimator::HeadingObserver,
            wheels,
            FusionTuning::FIXED_WHEELS,
        );
        // The ensemble of starts (`host_tests::ENSEMBLE_OFFSETS_M`): the
        // bounds hold for its median.
        let runs: Vec<FusionRun> = host_tests::ENSEMBLE_OFFSETS_M
            .iter()
            .map(|&offset| {
                figure_eight_run_from(Estimator::FusionEkf, wheels, robust(base), offset)
            })
            .collect();
        let errors = host_tests::EnsembleErrors::new(
            &format!("FusionEkf ensemble, {wheels:?}, tracking"),
            runs.iter().map(|r| (r.tracking.max_m, r.tracking.mean_m)),
        );
        // The worst start against the max bound, the median start against
        // the mean bound and paper 001's mean.
        let (worst, mean) = (errors.worst_max(), errors.median_mean());
        if !(worst < max_bound && mean < mean_bound) {
            failures.push(format!("{wheels:?}: worst max {worst}, median mean {mean}"));
        }
        if mean >= paper.tracking.mean_m {
            failures.push(format!("{wheels:?}: mean not below paper 001's"));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
    // The default tuning: a stray estimate is truncated to its cell, and
    // under slip its mean stays below paper 001's too.
    let default = run(
        Estimator::FusionEkf,
        slip(0.002),
        FusionTuning::FIXED_WHEELS,
    );
    let paper = run(
        Estimator::HeadingObserver,
        slip(0.002),
        FusionTuning::FIXED_WHEELS,
    );
    assert!(
        default.tracking.mean_m < paper.tracking.mean_m,
        "{:?} against {:?}",
        default.tracking,
        paper.tracking
    );
}

/// The same tuning in the `Pilot` (scenario keys `[estimator.fusion]`
/// `wheel_variance_per_m = 3e-5`, `edge_constraint = true`)
/// on the simulator's exact-odometry unicycle and on the full device
/// stack, whose plants have no slip. Medians over 32 starts
/// (`host_tests::ENSEMBLE_OFFSETS_M`), max / mean with the f32 kernels:
/// EKF 0.0216 / 0.0014 and 0.0222 / 0.0025 m, UKF 0.0171 / 0.0013 and
/// 0.0204 / 0.0023 m (docs/fusion.md). The EKF's spread is wide
/// (0.0108–0.0269 m on the unicycle): a single run can be one of its best
/// starts, so the test holds the ensemble's medians: each filter within
/// its bounds, and the UKF within 1.5× of the EKF's medians (the filters'
/// consistency goal of docs/fusion.md).
#[test]
fn the_slip_tuning_in_the_pilot() {
    // (scenario, EKF bounds, UKF bounds) on the median max / mean, m.
    let runs = [
        (
            "figure_eight_rfid_fusion_ekf",
            (0.025, 0.0016),
            (0.025, 0.0016),
        ),
        ("figure_eight_rfid_full_stack", (0.03, 0.003), (0.03, 0.003)),
    ];
    let mut failures = Vec::new();
    for (name, ekf_bounds, ukf_bounds) in runs {
        let medians = |kind| {
            // The ensemble of starts (`host_tests::ENSEMBLE_OFFSETS_M`):
            // the bounds hold for its median.
            let ensemble = host_tests::run_scenario_ensemble(name, |scenario| {
                scenario.estimator = EstimatorSpec::Fusion(FusionSpec {
                    filter: kind,
                    wheel_variance_per_m: 3e-5,
                    edge_constraint: true,
                    ..FusionSpec::default()
                });
            });
            let errors = host_tests::EnsembleErrors::new(
                &format!("{kind:?}, {name}"),
                ensemble.iter().map(|s| (s.max_error_m, s.mean_error_m)),
            );
            (errors.median_max(), errors.median_mean())
        };
        let ekf = medians(FusionFilterSpec::Ekf);
        let ukf = medians(FusionFilterSpec::Ukf);
        for (kind, (max, mean), (max_bound, mean_bound)) in [
            (FusionFilterSpec::Ekf, ekf, ekf_bounds),
            (FusionFilterSpec::Ukf, ukf, ukf_bounds),
        ] {
            if !(max < max_bound && mean < mean_bound) {
                failures.push(format!(
                    "{kind:?} {name}: median max {max}, median mean {mean}"
                ));
            }
        }
        if !(ukf.0 <= 1.5 * ekf.0 && ukf.1 <= 1.5 * ekf.1) {
            failures.push(format!(
                "{name}: UKF {ukf:?} not within 1.5x of EKF {ekf:?}"
            ));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// The template (`figure_eight_rfid_fusion_ekf`) with only `filter`
/// switched, over 32 starts (`host_tests::ENSEMBLE_OFFSETS_M`) on a
/// nearest-tag floor of `spacing_m`: each start's max and mean error.
fn template_ensemble(kind: FusionFilterSpec, spacing_m: f64) -> host_tests::EnsembleErrors {
    use firmware_sim::scenario::PositionSpec;
    let ensemble = host_tests::run_scenario_ensemble("figure_eight_rfid_fusion_ekf", |scenario| {
        if let EstimatorSpec::Fusion(fusion) = &mut scenario.estimator {
            fusion.filter = kind;
        }
        if let PositionSpec::NearestTag { spacing_m: s, .. } = &mut scenario.position {
            *s = spacing_m;
        }
    });
    assert!(ensemble.iter().all(|s| s.non_finite_ticks == 0));
    host_tests::EnsembleErrors::new(
        &format!("{kind:?}, template defaults, {spacing_m} m tags"),
        ensemble.iter().map(|s| (s.max_error_m, s.mean_error_m)),
    )
}

/// The UKF and the particle filter with the template's defaults
/// (`figure_eight_rfid_fusion_ekf`, `filter` switched, wheel noise 1e-3
/// m²/m on the simulator's exact wheels) on the 10, 20 and 30 cm
/// nearest-tag floors, medians over 32 starts against the EKF's.
///
/// The UKF: median max and mean at most 0.01 / 0.001 m on the template's
/// 10 cm floor and within 1.5× of the EKF's on each floor. Measured, max
/// / mean (m), UKF against EKF: 10 cm 0.0055 / 0.0005 against 0.0051 /
/// 0.0005; 20 cm 0.0124 / 0.0011 against 0.0140 / 0.0012; 30 cm 0.0124 /
/// 0.0012 against 0.0130 / 0.0013 (docs/fusion.md, "The UKF at the
/// default wheel noise").
///
/// The particle filter, whose noise levels (docs/fusion.md, "The particle
/// filter's noise levels") let it follow the odometry as the EKF does:
/// the template's own run (seed 1, its start) at most 0.01 / 0.001 m, as
/// the EKF's and the UKF's; the median max at most 0.01 m on 10 cm and
/// within 1.5× of the EKF's on each floor. Its median mean is 1.6–2.2×
/// the EKF's and is not held here. Measured: the run 0.0037 / 0.000998 m;
/// median max (worst start) against the EKF's: 10 cm 0.0039 (0.0075)
/// against 0.0051 (0.0072), 20 cm 0.0115 (0.0284) against 0.0140
/// (0.0173), 30 cm 0.0110 (0.0289) against 0.0130 (0.0138).
#[test]
fn the_ukf_and_the_particle_filter_at_the_template_defaults() {
    let mut failures = Vec::new();
    let template = host_tests::run_scenario_variant("figure_eight_rfid_fusion_ekf", |scenario| {
        if let EstimatorSpec::Fusion(fusion) = &mut scenario.estimator {
            fusion.filter = FusionFilterSpec::ParticleFilter;
        }
    });
    assert_eq!(template.non_finite_ticks, 0);
    if !(template.max_error_m <= 0.01 && template.mean_error_m <= 0.001) {
        failures.push(format!(
            "particle filter, template run: max {:.4}, mean {:.4} over 0.01 / 0.001 m",
            template.max_error_m, template.mean_error_m
        ));
    }
    for spacing in [0.1_f64, 0.2, 0.3] {
        let ekf = template_ensemble(FusionFilterSpec::Ekf, spacing);
        let ukf = template_ensemble(FusionFilterSpec::Ukf, spacing);
        let pf = template_ensemble(FusionFilterSpec::ParticleFilter, spacing);
        let ekf = (ekf.median_max(), ekf.median_mean());
        let ukf = (ukf.median_max(), ukf.median_mean());
        let pf_max = pf.median_max();
        if spacing == 0.1 && !(ukf.0 <= 0.01 && ukf.1 <= 0.001) {
            failures.push(format!("{spacing} m: UKF {ukf:?} over 0.01 / 0.001 m"));
        }
        if !(ukf.0 <= 1.5 * ekf.0 && ukf.1 <= 1.5 * ekf.1) {
            failures.push(format!(
                "{spacing} m: UKF {ukf:?} not within 1.5x of EKF {ekf:?}"
            ));
        }
        if spacing == 0.1 && pf_max > 0.01 {
            failures.push(format!(
                "{spacing} m: particle filter's median max {pf_max:.4} over 0.01 m"
            ));
        }
        if pf_max > 1.5 * ekf.0 {
            failures.push(format!(
                "{spacing} m: particle filter's median max {pf_max:.4} not within 1.5x of the EKF's {:.4}",
                ekf.0
            ));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// The fusion EKF chosen in a scenario file (`[estimator.fusion]`,
/// `filter = "ekf"`), through the simulator on the unicycle and through the
/// whole device stack (motors, 2048-count encoders, the RFID reader over
/// its UART, the `Pilot`).
#[test]
fn fusion_ekf_from_a_scenario_file_through_the_simulator_and_the_pilot() {
    // Measured: 0.0047 / 0.0005 m (unicycle), 0.0051 / 0.0016 m (stack).
    for (name, max_bound, mean_bound) in [
        ("figure_eight_rfid_fusion_ekf", 0.01, 0.001),
        ("figure_eight_rfid_full_stack", 0.01, 0.003),
    ] {
        // Every run of the ensemble of starts (`host_tests::ENSEMBLE_OFFSETS_M`).
        let ensemble = host_tests::run_scenario_ensemble(name, |scenario| {
            scenario.estimator = EstimatorSpec::fusion(FusionFilterSpec::Ekf);
        });
        // Printed for the docs; every run is held to the bounds below.
        let _ = host_tests::EnsembleErrors::new(
            &format!("fusion EKF, {name}"),
            ensemble.iter().map(|s| (s.max_error_m, s.mean_error_m)),
        );
        for s in &ensemble {
            assert_eq!(s.non_finite_ticks, 0);
            assert!(
                s.max_error_m < max_bound && s.mean_error_m < mean_bound,
                "{name}: {:.4} / {:.4}",
                s.max_error_m,
                s.mean_error_m
            );
        }
    }
}

/// From random starts up to 10 m away with any heading, every run of the
/// fusion EKF converges and tracks within 2 cm after 100 s: the guide
/// observer resets a heading the filter locked wrongly, and each axis
/// re-localises on its own after 3 gated fixes (without both, 7 of 1,000
/// runs did not converge).
#[test]
fn fusion_ekf_converges_from_random_starts() {
    use firmware_sim::Scenario;
    use firmware_sim::sweep::{SweepOptions, run_sweep};
    let scenario = Scenario::embedded("figure_eight_rfid_fusion_ekf").expect("embedded");
    let options = SweepOptions {
        runs: 100,
        seed: 1,
        threads: 0,
    };
    let result = run_sweep(&scenario, &options, &|| {}).expect("sweep runs");
    let s = &result.summary;
    println!(
        "100 runs: converged {}, slowest {:?}; max error p50 {:.4} p99 {:.4} max {:.4} m",
        s.converged, s.slowest, s.max_error_m.p50, s.max_error_m.p99, s.max_error_m.max
    );
    // Measured over 1,000 runs: all converge (slowest 75 s), max error
    // p50 0.0062, p99 0.0145, max 0.0194 m.
    assert!(s.not_converged.is_empty(), "{:?}", s.not_converged);
    assert!(s.max_error_m.max < 0.03, "{:?}", s.max_error_m);
}

/// Medians over an ensemble of starts, and the runs that lost the fix.
#[derive(Debug)]
struct Ensemble {
    max_m: f64,
    mean_m: f64,
    lost: usize,
}

/// The sparse reader: a tag is read only while the antenna is within 5 cm
/// of it (range mode: on entry, then every 0.1 s while in range), on the
/// full device stack, paper 001's observer against the fusion estimator on
/// floors of 10, 20 and 30 cm. The fusion estimator takes the first read of
/// each pass as the disc's entry point (`TagCellTracker::range_measurement`:
/// `πr/4` short of the tag, variance `0.05 r²` along the heading and
/// `r²/3` across it) and its failsafe counts the distance driven since the last fix (default
/// `4 s²/r`: 0.8, 3.2 and 7.2 m), not the time: with the default 0.5 s fix
/// timeout the robot stops between tags and never reads another (a
/// deadlock), so paper 001's observer, which has no such failsafe,
/// runs with the timeout raised to 30 s. The fusion filters run with the
/// EKF's default wheel noise (1e-3 m²/m) and with one near the truth
/// (3e-5). On the 10 cm floor they are on par with paper 001's observer.
///
/// Figures are medians over the ensemble of 32 starts
/// (`host_tests::ENSEMBLE_OFFSETS_M`). The EKF at its default wheel noise
/// loses the fix on the 20 cm floor in some of them (5 of 32 with the
/// core's f32 kernels, 6 of 32 with libm's `sinf`/`cosf`): that row is
/// held to its medians only, and every other row to no lost fix at all.
#[test]
fn sparse_reader_range_mode() {
    use firmware_sim::scenario::{PositionSpec, ReaderModeSpec};
    // Ensemble medians, max / mean (m), by spacing 10 / 20 / 30 cm, with the
    // f32 kernels (libm's sinf/cosf: the same to the digits shown except
    // where given in brackets):
    // 001 observer: 0.0271 / 0.0058, 0.0604 [0.0565] / 0.0306, 11.1 / 3.64
    //               (31 of 32 lost);
    // EKF, 1e-3:    0.0270 / 0.0068, 0.187 / 0.0379 [0.0396] (5 [6] of 32
    //               lost), 0.208 / 0.0625 [0.0664];
    // EKF, 3e-5:    0.0275 [0.0269] / 0.0064, 0.0492 [0.0495] / 0.0136,
    //               0.0993 / 0.0295 [0.0288];
    // UKF, 3e-5:    0.0301 / 0.0064 [0.0065], 0.0639 [0.0641] / 0.0163
    //               [0.0169], 0.104 [0.102] / 0.0262.
    let bounds = [
        (
            FusionFilterSpec::Ekf,
            1e-3,
            [(0.03, 0.0075), (0.21, 0.047), (0.23, 0.075)],
        ),
        (
            FusionFilterSpec::Ekf,
            3e-5,
            [(0.03, 0.007), (0.055, 0.015), (0.11, 0.032)],
        ),
        (
            FusionFilterSpec::Ukf,
            3e-5,
            [(0.036, 0.0072), (0.072, 0.019), (0.11, 0.028)],
        ),
    ];
    let mut failures = Vec::new();
    for (index, spacing) in [0.1_f64, 0.2, 0.3].into_iter().enumerate() {
        let run = |estimator: EstimatorSpec, timeout_s| {
            let s = host_tests::run_scenario_ensemble("figure_eight_rfid_full_stack", |scenario| {
                scenario.estimator = estimator;
                if let PositionSpec::Reader {
                    mode, spacing_m, ..
                } = &mut scenario.position
                {
                    *mode = ReaderModeSpec::Range;
                    *spacing_m = spacing;
                }
                scenario.failsafe.fix_timeout_s = timeout_s;
            });
            let label = match estimator {
                EstimatorSpec::Fusion(f) => {
                    format!(
                        "{:?}, wheel variance {:e}",
                        f.filter, f.wheel_variance_per_m
                    )
                }
                other => format!("{other:?}"),
            };
            let lost = s.iter().filter(|s| s.mode_ticks.fix_lost > 0).count();
            let errors = host_tests::EnsembleErrors::new(
                &format!(
                    "{spacing} m tags, {label}, {lost} of {} runs lost the fix",
                    s.len()
                ),
                s.iter().map(|s| (s.max_error_m, s.mean_error_m)),
            );
            assert!(s.iter().all(|s| s.non_finite_ticks == 0));
            Ensemble {
                max_m: errors.median_max(),
                mean_m: errors.median_mean(),
                lost,
            }
        };
        let paper = run(EstimatorSpec::HeadingObserver, 30.0);
        for (kind, variance, per_spacing) in bounds {
            let (max_bound, mean_bound) = per_spacing[index];
            // The default fix timeout: the distance failsafe decides.
            let s = run(
                EstimatorSpec::Fusion(FusionSpec {
                    filter: kind,
                    wheel_variance_per_m: variance,
                    ..FusionSpec::default()
                }),
                0.5,
            );
            let may_lose = kind == FusionFilterSpec::Ekf && variance >= 1e-3 && spacing >= 0.2;
            if !((s.lost == 0 || may_lose) && s.max_m < max_bound && s.mean_m < mean_bound) {
                failures.push(format!("{spacing} {kind:?} {variance}: {s:?}"));
            }
            // From 20 cm up, with the wheel noise near the truth: at most
            // 0.55 of paper 001's mean error (EKF 0.43, UKF 0.55 at 20 cm;
            // at 30 cm paper 001 loses the robot).
            if spacing >= 0.2 && variance < 1e-3 && s.mean_m >= 0.6 * paper.mean_m {
                failures.push(format!(
                    "{spacing} {kind:?} {variance}: not 0.6 of 001's mean"
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Paper 004's UKF and particle filter as the `Pilot`'s fusion estimator
/// (`[estimator.fusion]`, `filter = "ukf"` / `"particle_filter"`), with
/// the guide observer, on the unicycle and on the full device stack. The
/// UKF runs at 3e-5 m²/m here and at the template's 1e-3 in
/// `the_ukf_and_the_particle_filter_at_the_template_defaults`, as the
/// particle filter does; here the particle filter runs at
/// [`PF_WHEEL_VARIANCE`].
/// The particle filter's runs repeat from the seed.
#[test]
fn the_ukf_and_the_particle_filter_as_the_pilots_estimator() {
    // (kind, scenario, wheel variance, bounds on the ensemble's median max
    // / mean); medians over 32 starts, m, with the f32 kernels: UKF 0.0046
    // / 0.0004 and 0.0043 / 0.0016 (docs/fusion.md). The particle filter (every read as its tag's cell,
    // roughening; docs/fusion.md) is held to issue 17's target, 0.02 /
    // 0.005 m (the EKF, above: 0.0053 / 0.0005 and 0.0051 / 0.0016).
    let runs = [
        (
            FusionFilterSpec::Ukf,
            "figure_eight_rfid_fusion_ekf",
            3e-5,
            0.01,
            0.001,
        ),
        (
            FusionFilterSpec::Ukf,
            "figure_eight_rfid_full_stack",
            3e-5,
            0.01,
            0.0025,
        ),
        (
            FusionFilterSpec::ParticleFilter,
            "figure_eight_rfid_fusion_ekf",
            PF_WHEEL_VARIANCE,
            0.02,
            0.005,
        ),
        (
            FusionFilterSpec::ParticleFilter,
            "figure_eight_rfid_full_stack",
            PF_WHEEL_VARIANCE,
            0.02,
            0.005,
        ),
    ];
    let run = |kind, name, seed| {
        host_tests::run_scenario_variant(name, |scenario| {
            scenario.estimator = EstimatorSpec::Fusion(FusionSpec {
                filter: kind,
                wheel_variance_per_m: PF_WHEEL_VARIANCE,
                particle_seed: seed,
                ..FusionSpec::default()
            });
        })
    };
    let mut failures = Vec::new();
    for (kind, name, variance, max_bound, mean_bound) in runs {
        // The ensemble of starts (`host_tests::ENSEMBLE_OFFSETS_M`): the
        // bounds hold for its median.
        let ensemble = host_tests::run_scenario_ensemble(name, |scenario| {
            scenario.estimator = EstimatorSpec::Fusion(FusionSpec {
                filter: kind,
                wheel_variance_per_m: variance,
                ..FusionSpec::default()
            });
        });
        let errors = host_tests::EnsembleErrors::new(
            &format!("{kind:?} ensemble, {name}"),
            ensemble.iter().map(|s| (s.max_error_m, s.mean_error_m)),
        );
        assert!(ensemble.iter().all(|s| s.non_finite_ticks == 0));
        let (max, mean) = (errors.median_max(), errors.median_mean());
        if !(max < max_bound && mean < mean_bound) {
            failures.push(format!(
                "{kind:?} {name}: median max {max}, median mean {mean}"
            ));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
    let kind = FusionFilterSpec::ParticleFilter;
    let name = "figure_eight_rfid_fusion_ekf";
    let (first, again, other) = (run(kind, name, 1), run(kind, name, 1), run(kind, name, 2));
    // Everything but the wall time repeats.
    let figures = |s: &firmware_sim::Summary| {
        (
            s.max_error_m,
            s.mean_error_m,
            s.rms_error_m,
            s.final_error_m,
            s.tracker,
        )
    };
    assert_eq!(figures(&first), figures(&again));
    assert_ne!(first.max_error_m, other.max_error_m);
}

/// The fusion particle filter's wheel-noise tuning, m²/m: each wheel's
/// travel variance per metre (0.45 mm/√m), near the simulated plants'
/// exact wheels (2048-count encoders on the full stack).
const PF_WHEEL_VARIANCE: f32 = 2e-7;

/// The fusion particle filter (every nearest-tag read as its tag's cell,
/// roughening after resampling; docs/fusion.md) within issue 17's target,
/// 0.02 m max and 0.005 m mean after 100 s on the figure-eight, with the
/// unicycle and through the full device stack: one run each (seed 1, the
/// scenario's start), a few seconds in release. The ensembles of
/// `the_ukf_and_the_particle_filter_as_the_pilots_estimator` hold the same
/// bounds on their medians.
#[test]
fn the_particle_filter_meets_issue_17() {
    let mut failures = Vec::new();
    for name in [
        "figure_eight_rfid_fusion_ekf",
        "figure_eight_rfid_full_stack",
    ] {
        let s = host_tests::run_scenario_variant(name, |scenario| {
            scenario.estimator = EstimatorSpec::Fusion(FusionSpec {
                filter: FusionFilterSpec::ParticleFilter,
                wheel_variance_per_m: PF_WHEEL_VARIANCE,
                ..FusionSpec::default()
            });
        });
        assert_eq!(s.non_finite_ticks, 0);
        if !(s.max_error_m <= 0.02 && s.mean_error_m <= 0.005) {
            failures.push(format!(
                "{name}: max {:.4}, mean {:.4}",
                s.max_error_m, s.mean_error_m
            ));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
