//! The encoder + tag fusion EKF (`wmr_core::pose_ekf`) against paper 001's
//! position-only loop on the figure-eight with the nearest 10 cm tag every
//! tick (simulation in `host_tests::fusion`). Each assertion is a bound a
//! little weaker than the figure measured (given next to it); errors are
//! `|p − p_r|` after 100 s, m.

use host_tests::fusion::*;

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
        Estimator::Paper001,
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
    let paper = run(Estimator::Paper001, wheels, FusionTuning::FIXED_WHEELS);
    let fixed = run(Estimator::FusionEkf, wheels, FusionTuning::FIXED_WHEELS);
    let learnt = run(Estimator::FusionEkf, wheels, FusionTuning::LEARN_WHEELS);
    // Measured: 001 0.113 / 0.083; fixed wheels 0.149 / 0.042; learnt
    // 0.020 / 0.0038.
    assert!(paper.tracking.mean_m > 0.05 && fixed.tracking.mean_m > 0.03);
    assert!(learnt.tracking.max_m < 0.03 && learnt.tracking.mean_m < 0.005);
}
