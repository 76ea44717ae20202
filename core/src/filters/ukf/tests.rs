//! Unit tests of the UKF.

use super::filter::*;
use super::sigma_points::*;
use super::*;
use crate::math;
use nalgebra::{SMatrix, SVector};
use proptest::prelude::*;

type V3 = SVector<f32, 3>;
type M3 = SMatrix<f32, 3, 3>;

/// Paper 004's scenario-1 kinematics, full-state measurement, angle
/// hooks on ψ.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Unicycle;

const PSI: [usize; 1] = [2];

impl UkfModel<3, 3> for Unicycle {
    type Input = [f32; 2];
    fn input_is_finite(&self, u: &[f32; 2]) -> bool {
        u.iter().all(|v| v.is_finite())
    }
    fn transition(&self, x: &V3, u: &[f32; 2], dt: f32) -> V3 {
        let [v, w] = *u;
        V3::new(
            x[0] + dt * v * math::cos(x[2]),
            x[1] + dt * v * math::sin(x[2]),
            x[2] + dt * w,
        )
    }
    fn measure(&self, x: &V3) -> V3 {
        *x
    }
    fn angles(&self) -> AngleComponents<3, 3> {
        AngleComponents::from_indices(&PSI, &PSI)
    }
}

fn unicycle_filter(alpha: f32) -> UnscentedKalmanFilter<Unicycle, 3, 3, 7> {
    UnscentedKalmanFilter::new(
        Unicycle,
        MerweScaledSigmaPoints::new(alpha, 2.0, 0.0).unwrap(),
        V3::new(0.0, 0.0, 0.5),
        M3::from_diagonal(&V3::new(1.0, 1.0, 0.2)),
        M3::identity() * 1e-4,
        M3::from_diagonal(&V3::new(0.1, 0.1, 0.2)),
    )
    .unwrap()
}

/// A linear system `x⁺ = A x + B u`, `z = H x`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Linear {
    a: SMatrix<f32, 2, 2>,
    b: SVector<f32, 2>,
    h: SMatrix<f32, 1, 2>,
}

impl UkfModel<2, 1> for Linear {
    type Input = f32;
    fn input_is_finite(&self, u: &f32) -> bool {
        u.is_finite()
    }
    fn transition(&self, x: &SVector<f32, 2>, u: &f32, _dt: f32) -> SVector<f32, 2> {
        self.a * x + self.b * *u
    }
    fn measure(&self, x: &SVector<f32, 2>) -> SVector<f32, 1> {
        self.h * x
    }
}

fn spd() -> M3 {
    M3::new(0.3, 0.1, 0.02, 0.1, 0.25, -0.03, 0.02, -0.03, 0.1)
}

/// `S = 2N + 1` is a compile-time check (the `compile_fail` doctest of
/// [`MerweScaledSigmaPoints`]); the right counts build.
#[test]
fn sigma_point_count_is_checked() {
    assert!(MerweScaledSigmaPoints::<3, 7>::new(0.5, 2.0, 0.0).is_ok());
    assert!(MerweScaledSigmaPoints::<1, 3>::paper().is_ok());
}

#[test]
fn parameters_are_validated() {
    type P = MerweScaledSigmaPoints<3, 7>;
    assert_eq!(P::new(0.0, 2.0, 0.0), Err(UkfError::Alpha));
    assert_eq!(P::new(f32::NAN, 2.0, 0.0), Err(UkfError::Alpha));
    assert_eq!(P::new(0.5, f32::INFINITY, 0.0), Err(UkfError::Beta));
    assert_eq!(P::new(0.5, 2.0, -3.0), Err(UkfError::Kappa));
    assert_eq!(P::new(0.5, 2.0, f32::NAN), Err(UkfError::Kappa));
    assert_eq!(P::new(1e-30, 2.0, 0.0), Err(UkfError::Spread));
    let points = P::new(0.5, 2.0, 0.0).unwrap();
    let bad_p0 = M3::new(1.0, 2.0, 0.0, 2.0, 1.0, 0.0, 0.0, 0.0, 1.0);
    let new = |x0: V3, p0: M3, q: M3, r: M3| {
        UnscentedKalmanFilter::new(Unicycle, points, x0, p0, q, r).map(|_| ())
    };
    let i = M3::identity();
    assert_eq!(
        new(V3::new(f32::NAN, 0.0, 0.0), i, i, i),
        Err(UkfError::InitialState)
    );
    use CovarianceDefect::*;
    assert_eq!(
        new(V3::zeros(), bad_p0, i, i),
        Err(UkfError::InitialCovariance(NotPositiveDefinite))
    );
    assert_eq!(
        new(V3::zeros(), M3::zeros(), i, i),
        Err(UkfError::InitialCovariance(NotPositiveDefinite))
    );
    let mut nan = i;
    nan[(1, 1)] = f32::NAN;
    assert_eq!(
        new(V3::zeros(), nan, i, i),
        Err(UkfError::InitialCovariance(NotFinite))
    );
    assert_eq!(
        new(V3::zeros(), i, -i, i),
        Err(UkfError::ProcessNoise(NotPositiveSemiDefinite))
    );
    let mut skew = i;
    skew[(0, 1)] = 0.5;
    assert_eq!(
        new(V3::zeros(), i, skew, i),
        Err(UkfError::ProcessNoise(NotSymmetric))
    );
    assert_eq!(
        new(V3::zeros(), i, i, bad_p0),
        Err(UkfError::MeasurementNoise(NotPositiveDefinite))
    );
    // Q = 0 is allowed (semi-definite); R must be positive definite: zero,
    // singular or merely semi-definite, it is refused by name and why.
    assert_eq!(new(V3::zeros(), i, M3::zeros(), i), Ok(()));
    let singular = M3::from_diagonal(&V3::new(1.0, 0.0, 1.0));
    for r in [M3::zeros(), singular] {
        assert_eq!(
            new(V3::zeros(), i, M3::zeros(), r),
            Err(UkfError::MeasurementNoise(NotPositiveDefinite))
        );
    }
    assert_eq!(
        UkfError::MeasurementNoise(NotPositiveDefinite).to_string(),
        "the measurement noise R is not positive definite"
    );
    let mut ukf = unicycle_filter(0.5);
    assert_eq!(
        ukf.set_measurement_noise(singular),
        Err(UkfError::MeasurementNoise(NotPositiveDefinite))
    );
    assert_eq!(
        ukf.measurement_noise(),
        unicycle_filter(0.5).measurement_noise()
    );
    // Per call, a zero R skips the update and is counted.
    assert_eq!(ukf.predict(&[1.0, 0.1], 0.1), StepOutcome::Applied);
    assert_eq!(
        ukf.update_with_noise(&V3::zeros(), &M3::zeros()),
        StepOutcome::RejectedInput
    );
    assert_eq!(
        ukf.update_component(0, 0.0, 0.0),
        StepOutcome::RejectedInput
    );
    assert_eq!(ukf.counters().rejected_inputs, 2);
}

/// The mean weights sum to one; the values are FilterPy's.
#[test]
fn weights() {
    for (alpha, kappa) in [
        (0.01_f32, 0.0_f32),
        (0.001, 0.0),
        (0.5, 0.0),
        (1.0, 0.0),
        (0.3, 1.0),
    ] {
        let points = MerweScaledSigmaPoints::<3, 7>::new(alpha, 2.0, kappa).unwrap();
        let wm = points.mean_weights();
        let wc = points.covariance_weights();
        let sum: f64 = wm.iter().map(|&w| f64::from(w)).sum();
        let size: f64 = wm.iter().map(|&w| f64::from(w).abs()).sum();
        assert!(
            (sum - 1.0).abs() <= size * f64::from(f32::EPSILON),
            "α {alpha}: Σ Wm − 1 = {:e}",
            sum - 1.0
        );
        let (a, k) = (f64::from(alpha), f64::from(kappa));
        let lambda = a * a * (3.0 + k) - 3.0;
        let expect_w0 = lambda / (3.0 + lambda);
        let expect_wi = 0.5 / (3.0 + lambda);
        let close =
            |got: f32, want: f64| (f64::from(got) - want).abs() <= 1e-6 * want.abs().max(1.0);
        assert!(close(wm[0], expect_w0), "{} {}", wm[0], expect_w0);
        assert!(close(wc[0], expect_w0 + 1.0 - a * a + 2.0));
        for k in 1..7 {
            assert!(close(wm[k], expect_wi) && wm[k] == wc[k]);
        }
        assert!(close(points.lambda(), lambda));
        assert!(close(points.gamma(), (3.0 + lambda).sqrt()));
    }
    // The paper's: W0 = −9999, Wi = 1666.67.
    let paper = MerweScaledSigmaPoints::<3, 7>::paper().unwrap();
    assert!((paper.mean_weights()[0] + 9999.0).abs() < 1e-2);
    assert!((paper.mean_weights()[1] - 1666.6667).abs() < 1e-3);
}

/// The points are FilterPy's (rows of scipy's upper factor = columns of
/// the lower one, `+` half first) and their unscented transform
/// reproduces `x` and `P`.
#[test]
fn sigma_points_reproduce_mean_and_covariance() {
    let x = V3::new(1.0, -2.0, 0.5);
    let p = spd();
    for (alpha, tol) in [(1.0_f32, 1e-6_f32), (0.5, 1e-6), (0.01, 1e-3)] {
        let points = MerweScaledSigmaPoints::<3, 7>::new(alpha, 2.0, 0.0).unwrap();
        let sigmas = points.sigma_points(&x, &p).unwrap();
        let l = (p * points.spread).cholesky().unwrap().l();
        for k in 0..3 {
            assert_eq!(sigmas.column(0), x);
            assert_eq!(sigmas.column(k + 1), x + l.column(k));
            assert_eq!(sigmas.column(k + 4), x - l.column(k));
        }
        // The points are x ± Lₖ rounded to f32 (ε|x|/2 each); the mean
        // weighs that rounding by Σ|Wᵢ| (1e4 for α = 0.01).
        let spread: f32 = points.mean_weights().iter().skip(1).map(|w| w.abs()).sum();
        let mean = unscented_mean(&sigmas, &points.mean_weights());
        let mean_tol = spread * f32::EPSILON * x.amax();
        assert!((mean - x).amax() < mean_tol, "α {alpha}: {mean}");
        let mut cov = M3::zeros();
        for (s, &w) in sigmas.column_iter().zip(points.covariance_weights().iter()) {
            let d = s - mean;
            cov += d * d.transpose() * w;
        }
        let err = (cov - p).amax() / p.amax();
        assert!(err < tol, "α {alpha}: relative error {err:e}");
    }
}

/// On a linear system the UKF is the Kalman filter, with FilterPy
/// 1.4.5's twist: the update's `S` and `Pxy` come from the propagated
/// points, which do not carry `Q` (module docs). With `Q = 0` that is
/// the Kalman filter exactly; with `Q ≠ 0` it is the Kalman filter
/// whose `S = H(P⁻ − Q)Hᵀ + R` and `Pxy = (P⁻ − Q)Hᵀ`.
#[test]
fn linear_system_is_the_kalman_filter() {
    let model = Linear {
        a: SMatrix::<f32, 2, 2>::new(1.0, 0.1, 0.0, 0.95),
        b: SVector::<f32, 2>::new(0.005, 0.1),
        h: SMatrix::<f32, 1, 2>::new(1.0, 0.0),
    };
    let r = SMatrix::<f32, 1, 1>::new(0.04);
    let x0 = SVector::<f32, 2>::new(0.5, -0.2);
    let p0 = SMatrix::<f32, 2, 2>::new(1.0, 0.3, 0.3, 0.5);
    let noisy = SMatrix::<f32, 2, 2>::new(1e-3, 2e-4, 2e-4, 2e-3);
    for q in [SMatrix::<f32, 2, 2>::zeros(), noisy] {
        for alpha in [0.01_f32, 0.5, 1.0] {
            let points = MerweScaledSigmaPoints::<2, 5>::new(alpha, 2.0, 0.0).unwrap();
            // The f32 rounding of the points (|x| ≤ 1), amplified by
            // Σ|Wᵢ| (1e4 for α = 0.01: module docs), and some growth
            // over the run; 1e-5 otherwise.
            let spread: f32 = points.mean_weights().iter().skip(1).map(|w| w.abs()).sum();
            let tol = (5.0 * spread * f32::EPSILON).max(1e-5);
            let mut ukf = UnscentedKalmanFilter::new(model, points, x0, p0, q, r).unwrap();
            let (mut x, mut p) = (x0, p0);
            let mut worst = (0.0_f32, 0.0_f32);
            for k in 0..50_u8 {
                let u = 0.3 * f32::from(k % 7) - 0.8;
                let z = SVector::<f32, 1>::new(0.02 * f32::from(k) - 0.5 * f32::from(k % 3));
                assert_eq!(ukf.predict(&u, 0.1), StepOutcome::Applied);
                x = model.a * x + model.b * u;
                let without_q = model.a * p * model.a.transpose();
                p = without_q + q;
                assert_eq!(ukf.update(&z), StepOutcome::Applied);
                let s = model.h * without_q * model.h.transpose() + r;
                let k_gain = without_q * model.h.transpose() * s.try_inverse().unwrap();
                x += k_gain * (z - model.h * x);
                p -= k_gain * s * k_gain.transpose();
                worst.0 = worst.0.max((ukf.state() - x).amax());
                worst.1 = worst.1.max((ukf.covariance() - p).amax() / p.amax());
                assert!((ukf.innovation_covariance() - s).amax() < tol * s.amax());
            }
            println!(
                "α {alpha}, |Q| {}: worst |Δx| {:.1e}, |ΔP|/|P| {:.1e} (tolerance {tol:.1e})",
                q.amax(),
                worst.0,
                worst.1
            );
            assert!(
                worst.0 < tol && worst.1 < tol,
                "α {alpha}, Q {q}: {worst:?} ≥ {tol}"
            );
            assert_eq!(ukf.counters(), UkfCounters::default());
        }
    }
}

/// A linear system measured in full (`h = I`).
#[derive(Debug, Clone, Copy, PartialEq)]
struct FullyMeasured(SMatrix<f32, 2, 2>);

impl UkfModel<2, 2> for FullyMeasured {
    type Input = f32;
    fn input_is_finite(&self, u: &f32) -> bool {
        u.is_finite()
    }
    fn transition(&self, x: &SVector<f32, 2>, u: &f32, _dt: f32) -> SVector<f32, 2> {
        self.0 * x + SVector::<f32, 2>::new(0.0, *u)
    }
    fn measure(&self, x: &SVector<f32, 2>) -> SVector<f32, 2> {
        *x
    }
}

/// With the update's points redrawn from `(x⁻, P⁻)`, one-component
/// updates of a linear system are the scalar Kalman filter, `Q` and
/// all (where the reused points leave `Q` out); the innovation, its
/// covariance and the gain are reported in full shape, zero outside the
/// component; a bad index or variance is refused and counted.
#[test]
fn component_updates_are_the_scalar_kalman_filter() {
    let a = SMatrix::<f32, 2, 2>::new(1.0, 0.1, 0.0, 0.95);
    let q = SMatrix::<f32, 2, 2>::new(1e-3, 2e-4, 2e-4, 2e-3);
    let (x0, p0) = (
        SVector::<f32, 2>::new(0.5, -0.2),
        SMatrix::<f32, 2, 2>::new(1.0, 0.3, 0.3, 0.5),
    );
    let points = MerweScaledSigmaPoints::<2, 5>::new(1.0, 2.0, 0.0).unwrap();
    let mut ukf =
        UnscentedKalmanFilter::new(FullyMeasured(a), points, x0, p0, q, SMatrix::identity())
            .unwrap()
            .with_redrawn_update_points();
    let (mut x, mut p) = (x0, p0);
    let mut worst = 0.0_f32;
    for k in 0..40_u8 {
        let u = 0.2 * f32::from(k % 5) - 0.4;
        assert_eq!(ukf.predict(&u, 0.1), StepOutcome::Applied);
        x = a * x + SVector::<f32, 2>::new(0.0, u);
        p = a * p * a.transpose() + q;
        let index = usize::from(k % 2);
        let (z, r) = (0.05 * f32::from(k) - 0.3, 0.01 + 0.01 * f32::from(k % 3));
        assert_eq!(ukf.update_component(index, z, r), StepOutcome::Applied);
        let s = p[(index, index)] + r;
        let gain = p.column(index) / s;
        let innovation = z - x[index];
        x += gain * innovation;
        p -= gain * gain.transpose() * s;
        worst = worst
            .max((ukf.state() - x).amax())
            .max((ukf.covariance() - p).amax());
        let other = 1 - index;
        assert!((ukf.innovation()[index] - innovation).abs() < 1e-4);
        assert_eq!(ukf.innovation()[other], 0.0);
        assert!((ukf.innovation_covariance()[(index, index)] - s).abs() < 1e-4);
        assert_eq!(ukf.gain().column(other).amax(), 0.0);
    }
    assert!(worst < 1e-5, "{worst}");
    for (index, z, r) in [(2, 0.0, 1.0), (0, f32::NAN, 1.0), (0, 0.0, -1.0)] {
        assert_eq!(
            ukf.update_component(index, z, r),
            StepOutcome::RejectedInput
        );
    }
    assert_eq!(ukf.counters().rejected_inputs, 3);
}

/// A `P` that is not positive definite: a rounding-sized defect is
/// repaired by the jitter; a real one resets `P` to `P0` and skips.
#[test]
fn cholesky_failure_repairs_or_resets() {
    let mut ukf = unicycle_filter(0.5);
    // Singular (semi-definite) P: the jitter repairs it.
    ukf.p = M3::new(1.0, 1.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.1);
    assert_eq!(ukf.predict(&[1.0, 0.1], 0.1), StepOutcome::Repaired);
    assert_eq!(ukf.counters().covariance_repairs, 1);
    assert!(ukf.covariance().iter().all(|v| v.is_finite()));
    // Indefinite P: reset and skipped.
    let x = *ukf.state();
    ukf.p = M3::new(1.0, 2.0, 0.0, 2.0, 1.0, 0.0, 0.0, 0.0, 1.0);
    assert_eq!(ukf.predict(&[1.0, 0.1], 0.1), StepOutcome::CovarianceReset);
    assert_eq!(ukf.counters().covariance_resets, 1);
    assert_eq!(ukf.covariance(), ukf.initial_covariance());
    assert_eq!(*ukf.state(), x);
    assert!(ukf.propagated_sigma_points().is_none());
    // And the filter goes on from there.
    assert_eq!(ukf.predict(&[1.0, 0.1], 0.1), StepOutcome::Applied);
    // An update with no fresh points draws them, and resets the same way.
    ukf.p = -M3::identity();
    assert_eq!(ukf.update(&V3::zeros()), StepOutcome::Applied);
    ukf.p = -M3::identity();
    assert_eq!(ukf.update(&V3::zeros()), StepOutcome::CovarianceReset);
    assert_eq!(ukf.counters().covariance_resets, 2);
}

#[test]
fn bad_input_is_skipped_and_counted() {
    let mut ukf = unicycle_filter(0.01);
    assert_eq!(ukf.predict(&[0.5, 0.2], 0.005), StepOutcome::Applied);
    let (x, p) = (*ukf.state(), *ukf.covariance());
    assert_eq!(
        ukf.update(&V3::new(f32::NAN, 0.0, 0.0)),
        StepOutcome::RejectedInput
    );
    assert_eq!(
        ukf.update_with_noise(&V3::zeros(), &(M3::identity() * f32::INFINITY)),
        StepOutcome::RejectedInput
    );
    assert_eq!(
        ukf.predict(&[f32::NAN, 0.2], 0.005),
        StepOutcome::RejectedInput
    );
    assert_eq!(
        ukf.predict(&[0.5, 0.2], f32::NAN),
        StepOutcome::RejectedInput
    );
    assert_eq!(ukf.predict(&[0.5, 0.2], -0.005), StepOutcome::RejectedInput);
    // Finite input, non-finite result (overflow in f).
    assert_eq!(ukf.predict(&[3e38, 0.2], 1e3), StepOutcome::NonFiniteResult);
    assert_eq!(ukf.counters().rejected_inputs, 5);
    assert_eq!(ukf.counters().non_finite_results, 1);
    assert_eq!((*ukf.state(), *ukf.covariance()), (x, p));
    // Still works afterwards.
    assert_eq!(ukf.predict(&[0.5, 0.2], 0.005), StepOutcome::Applied);
    assert_eq!(ukf.update(&V3::new(0.0, 0.0, 0.5)), StepOutcome::Applied);
}

/// A measurement that carries no information and no noise: `S = 0`. A
/// zero `R` is refused at construction and per call, so it is set here
/// behind the checks, to reach the defence that remains against an `S`
/// that rounding leaves singular.
#[test]
fn singular_innovation_is_skipped() {
    let model = Linear {
        a: SMatrix::<f32, 2, 2>::identity(),
        b: SVector::<f32, 2>::zeros(),
        h: SMatrix::<f32, 1, 2>::zeros(),
    };
    let points = MerweScaledSigmaPoints::<2, 5>::new(0.5, 2.0, 0.0).unwrap();
    let mut ukf = UnscentedKalmanFilter::new(
        model,
        points,
        SVector::zeros(),
        SMatrix::identity(),
        SMatrix::zeros(),
        SMatrix::identity(),
    )
    .unwrap();
    ukf.r = SMatrix::zeros();
    assert_eq!(ukf.predict(&0.0, 0.1), StepOutcome::Applied);
    let x = *ukf.state();
    assert_eq!(
        ukf.update(&SVector::<f32, 1>::new(1.0)),
        StepOutcome::SingularInnovation
    );
    assert_eq!(ukf.counters().singular_innovations, 1);
    assert_eq!(*ukf.state(), x);
    // The points are still those of the predict.
    assert!(ukf.propagated_sigma_points().is_some());
}

/// The update reuses σf: after a predict, the update's cross covariance
/// comes from the propagated points, not from points redrawn at x⁻.
#[test]
fn update_reuses_the_propagated_points() {
    let mut a = unicycle_filter(0.5);
    let mut b = a;
    let z = V3::new(0.1, 0.2, 0.4);
    a.predict(&[2.0, 3.0], 0.2);
    b.predict(&[2.0, 3.0], 0.2);
    let kept = *a.propagated_sigma_points().unwrap();
    assert_eq!(a.update(&z), StepOutcome::Applied);
    assert!(a.propagated_sigma_points().is_none());
    // Redrawn from (x⁻, P⁻): not the same update (f is nonlinear).
    b.sigmas_f_fresh = false;
    assert_eq!(b.update(&z), StepOutcome::Applied);
    assert!((a.state() - b.state()).amax() > 1e-5);
    // The propagated points are 7 distinct images of the prior's.
    assert!(kept.column(1) != kept.column(4));
}

#[test]
fn angles_wrap_through_pi() {
    let points = MerweScaledSigmaPoints::<1, 3>::new(1.0, 2.0, 0.0).unwrap();
    let w = points.mean_weights();
    let sigmas = SMatrix::<f32, 1, 3>::new(3.1, -3.1, 3.0);
    let mean = unscented_mean_with_angles(&sigmas, &w, &[0, 7]);
    let sum_sin: f32 = sigmas
        .iter()
        .zip(w.iter())
        .map(|(&a, &w)| w * a.sin())
        .sum();
    let sum_cos: f32 = sigmas
        .iter()
        .zip(w.iter())
        .map(|(&a, &w)| w * a.cos())
        .sum();
    assert!((mean[0] - sum_sin.atan2(sum_cos)).abs() < 1e-5, "{mean}");
    let d = residual_with_angles(
        &SVector::<f32, 2>::new(3.1, 3.1),
        &SVector::<f32, 2>::new(-3.1, -3.1),
        &[1, 9],
    );
    assert!((d[0] - 6.2).abs() < 1e-6 && (d[1] - (6.2 - math::TAU)).abs() < 1e-5);
    // The filter crosses π without a jump.
    let mut ukf = unicycle_filter(0.01);
    ukf.reset(V3::new(0.0, 0.0, 3.1), M3::identity() * 0.01)
        .unwrap();
    for _ in 0..20 {
        ukf.predict(&[0.5, 1.0], 0.01);
        ukf.update(&V3::new(0.0, 0.0, -3.1));
    }
    let psi = ukf.state()[2];
    assert!(math::wrap_angle(psi + 3.1).abs() < 0.2, "{}", ukf.state());
    assert_eq!(ukf.counters(), UkfCounters::default());
}

proptest! {
    /// The array-based `unscented_mean` gives, bit for bit, what the
    /// column-view formula gives (`σ₀ + Σ Wᵢ(σᵢ − σ₀)` through
    /// `column_iter`), for any finite points and weights.
    #[test]
    fn unscented_mean_is_bitwise_the_column_view_formula(
        points in proptest::collection::vec(-1e3_f32..1e3, 3 * 7),
        weights in proptest::collection::vec(-1e4_f32..1e4, 7),
    ) {
        let sigmas = SMatrix::<f32, 3, 7>::from_column_slice(&points);
        let weights = SVector::<f32, 7>::from_column_slice(&weights);
        let mut columns = sigmas.column_iter();
        let centre = columns.next().unwrap();
        let mut offset = SVector::<f32, 3>::zeros();
        for (column, &w) in columns.zip(weights.iter().skip(1)) {
            offset += (column - centre) * w;
        }
        let before = centre + offset;
        let now = unscented_mean(&sigmas, &weights);
        for (a, b) in now.iter().zip(before.iter()) {
            prop_assert_eq!(a.to_bits(), b.to_bits());
        }
    }

    /// Finite inputs and measurements never give a non-finite estimate.
    #[test]
    fn finite_in_finite_out(
        steps in proptest::collection::vec(
            (proptest::array::uniform2(-5f32..5.0), proptest::array::uniform3(-10f32..10.0)),
            1..30),
        alpha in prop_oneof![Just(0.01f32), Just(0.5), Just(1.0)],
    ) {
        let mut ukf = unicycle_filter(alpha);
        for (u, z) in &steps {
            ukf.predict(u, 0.05);
            ukf.update(&V3::from(*z));
            prop_assert!(ukf.state().iter().all(|v| v.is_finite()));
            prop_assert!(ukf.covariance().iter().all(|v| v.is_finite()));
        }
    }
}

/// A filter in `form` on the linear model, with FilterPy's reuse of the
/// predict's points or with points redrawn for the update.
fn linear_filter(
    model: Linear,
    alpha: f32,
    (x0, p0, q, r): (
        SVector<f32, 2>,
        SMatrix<f32, 2, 2>,
        SMatrix<f32, 2, 2>,
        SMatrix<f32, 1, 1>,
    ),
    form: UkfForm,
) -> UnscentedKalmanFilter<Linear, 2, 1, 5> {
    let points = MerweScaledSigmaPoints::<2, 5>::new(alpha, 2.0, 0.0).unwrap();
    UnscentedKalmanFilter::new(model, points, x0, p0, q, r)
        .unwrap()
        .with_form(form)
        .unwrap()
}

const FORMS: [UkfForm; 2] = [UkfForm::Covariance, UkfForm::SquareRoot];

/// A sharp measurement: `P0 = [[100, 0.05], [0.05, 1e-4]]`, identity
/// dynamics, `Q = 0`, the second state measured with `R = 1e-12`. The
/// exact posterior `P₂₂` is `1e-4·1e-12/(1e-4 + 1e-12) ≈ 1e-12`; FilterPy's
/// `P⁻ − K S Kᵀ` gives −2.9e-11 in `f32`, which needs a repair. Both forms
/// keep it at 1e-12 and need no repair.
/// The state starts at zero: at `α = 0.01` the sigma points of a variance
/// of 1e-12 are `x ± 1.4e-8`, below the `f32` resolution of an `x` of 0.5
/// (6e-8), where they round onto `x` and the next predict's `P₂₂` is 0 in
/// either form (module docs, "`f32` and small `α`").
#[test]
fn a_sharp_measurement_keeps_the_covariance_positive() {
    let model = Linear {
        a: SMatrix::<f32, 2, 2>::identity(),
        b: SVector::<f32, 2>::zeros(),
        h: SMatrix::<f32, 1, 2>::new(0.0, 1.0),
    };
    let p0 = SMatrix::<f32, 2, 2>::new(100.0, 0.05, 0.05, 1e-4);
    let setup = (
        SVector::<f32, 2>::zeros(),
        p0,
        SMatrix::<f32, 2, 2>::zeros(),
        SMatrix::<f32, 1, 1>::new(1e-12),
    );
    let exact_p22 = 1e-4_f64 * 1e-12 / (1e-4 + 1e-12);
    for form in FORMS {
        for alpha in [0.01_f32, 0.1, 1.0] {
            let mut ukf = linear_filter(model, alpha, setup, form);
            assert_eq!(ukf.predict(&0.0, 0.1), StepOutcome::Applied);
            assert_eq!(
                ukf.update(&SVector::<f32, 1>::new(1e-6)),
                StepOutcome::Applied
            );
            let after_update = ukf.covariance()[(1, 1)];
            assert_eq!(ukf.predict(&0.0, 0.1), StepOutcome::Applied);
            let after_predict = ukf.covariance()[(1, 1)];
            println!(
                "{form:?}, α {alpha}: P₂₂ {after_update:e} after the update, \
                 {after_predict:e} after the next predict"
            );
            for p22 in [after_update, after_predict] {
                let relative = (f64::from(p22) - exact_p22).abs() / exact_p22;
                assert!(relative < 1e-3, "{form:?}, α {alpha}: P₂₂ = {p22:e}");
            }
            assert_eq!(
                ukf.counters(),
                UkfCounters::default(),
                "{form:?}, α {alpha}"
            );
            // The factor of the square-root form is P's.
            if form == UkfForm::SquareRoot {
                let l = ukf.factor;
                let p = *ukf.covariance();
                assert!((l * l.transpose() - p).amax() <= 1e-6 * p.amax());
            }
        }
    }
}

/// Over 1,000 steps of a linear system with the update's points redrawn,
/// both forms are the Kalman filter (in `f64`) to `f32` rounding, at the
/// paper's `α = 0.01` as at `α = 0.1`. The bound is the rounding of the
/// sigma points amplified by the weights (module docs, "`f32` and small
/// `α`"): the state offsets `γ√P` are stored on top of `x` and rounded at
/// `ε|x|`, and each propagated point's rounding enters the mean with
/// weight `Wᵢ = 1/(2γ²)`, so `P` carries a relative `Σ|Wᵢ| ε` per step
/// (1e4 ε at `α = 0.01`, 100 ε at `α = 0.1`). `Q` here keeps `P` well above
/// that floor; with `Q` near zero the rounding dominates whatever the form
/// (module docs).
#[test]
fn both_forms_are_the_kalman_filter_over_1000_steps() {
    let model = Linear {
        a: SMatrix::<f32, 2, 2>::new(1.0, 0.1, 0.0, 0.95),
        b: SVector::<f32, 2>::new(0.005, 0.1),
        h: SMatrix::<f32, 1, 2>::new(1.0, 0.0),
    };
    let q = SMatrix::<f32, 2, 2>::new(1e-3, 2e-4, 2e-4, 2e-3);
    let setup = (
        SVector::<f32, 2>::new(0.5, -0.2),
        SMatrix::<f32, 2, 2>::new(1.0, 0.3, 0.3, 0.5),
        q,
        SMatrix::<f32, 1, 1>::new(0.04),
    );
    let to64 = |m: &SMatrix<f32, 2, 2>| m.map(f64::from);
    for form in FORMS {
        for alpha in [0.01_f32, 0.1] {
            let mut ukf = linear_filter(model, alpha, setup, form).with_redrawn_update_points();
            let points = *ukf.sigma_point_weights();
            let spread: f32 = points.mean_weights().iter().skip(1).map(|w| w.abs()).sum();
            let tol = f64::from(5.0 * spread * f32::EPSILON).max(1e-5);
            let (a, b, h) = (
                to64(&model.a),
                model.b.map(f64::from),
                model.h.map(f64::from),
            );
            let (q, r) = (to64(&q), 0.04_f64);
            let (mut x, mut p) = (setup.0.map(f64::from), to64(&setup.1));
            let mut worst = (0.0_f64, 0.0_f64);
            for k in 0..1000_u32 {
                let u = 0.3 * f64::from(k % 7) - 0.8;
                let z = 0.02 * f64::from(k % 50) - 0.5 * f64::from(k % 3);
                assert_eq!(ukf.predict(&(u as f32), 0.1), StepOutcome::Applied);
                x = a * x + b * u;
                p = a * p * a.transpose() + q;
                assert_eq!(
                    ukf.update(&SVector::<f32, 1>::new(z as f32)),
                    StepOutcome::Applied
                );
                let s = (h * p * h.transpose())[(0, 0)] + r;
                let gain = p * h.transpose() / s;
                x += gain * (z - (h * x)[(0, 0)]);
                p -= gain * gain.transpose() * s;
                let dx = (ukf.state().map(f64::from) - x).amax();
                let dp = (ukf.covariance().map(f64::from) - p).amax() / p.amax();
                worst = (worst.0.max(dx), worst.1.max(dp));
            }
            println!(
                "{form:?}, α {alpha}: worst |Δx| {:.1e}, |ΔP|/|P| {:.1e} over 1,000 steps \
                 (bound {tol:.1e})",
                worst.0, worst.1
            );
            assert!(
                worst.0 < tol && worst.1 < tol,
                "{form:?}, α {alpha}: {worst:?}"
            );
            assert_eq!(ukf.counters(), UkfCounters::default());
        }
    }
}

/// The square-root form needs `β ≥ α²`; the form is kept.
#[test]
fn the_square_root_form_is_validated() {
    let points = MerweScaledSigmaPoints::<3, 7>::new(1.0, 0.5, 0.0).unwrap();
    let i = M3::identity();
    let ukf = UnscentedKalmanFilter::new(Unicycle, points, V3::zeros(), i, i, i).unwrap();
    assert_eq!(ukf.form(), UkfForm::Covariance);
    assert_eq!(
        ukf.with_form(UkfForm::SquareRoot).err(),
        Some(UkfError::SquareRootBeta)
    );
    assert_eq!(
        unicycle_filter(0.5)
            .with_form(UkfForm::SquareRoot)
            .map(|f| f.form()),
        Ok(UkfForm::SquareRoot)
    );
}

/// On the nonlinear unicycle the two forms give the same estimate to
/// rounding, with the predict's points reused and redrawn, for full and
/// one-component updates.
#[test]
fn the_forms_agree_on_a_nonlinear_model() {
    for redraw in [false, true] {
        let mut a = unicycle_filter(0.5);
        if redraw {
            a = a.with_redrawn_update_points();
        }
        let mut b = a.with_form(UkfForm::SquareRoot).unwrap();
        let mut worst = (0.0_f32, 0.0_f32);
        for k in 0..200_u16 {
            let t = f32::from(k) * 0.05;
            let u = [0.5 + 0.2 * math::sin(t), 0.3 * math::cos(0.7 * t)];
            let z = V3::new(0.4 * math::sin(t), 0.3 * t, 0.5 + 0.1 * t);
            assert_eq!(a.predict(&u, 0.05), b.predict(&u, 0.05));
            if k % 3 == 0 {
                let (i, zi) = (usize::from(k % 2), z[usize::from(k % 2)]);
                assert_eq!(a.update_component(i, zi, 0.05), StepOutcome::Applied);
                assert_eq!(b.update_component(i, zi, 0.05), StepOutcome::Applied);
            } else {
                assert_eq!(a.update(&z), StepOutcome::Applied);
                assert_eq!(b.update(&z), StepOutcome::Applied);
            }
            worst.0 = worst.0.max((a.state() - b.state()).amax());
            worst.1 = worst
                .1
                .max((a.covariance() - b.covariance()).amax() / a.covariance().amax());
        }
        println!(
            "redraw {redraw}: worst |Δx| {:.1e}, |ΔP|/|P| {:.1e}",
            worst.0, worst.1
        );
        assert!(worst.0 < 1e-4 && worst.1 < 1e-4, "{worst:?}");
        assert_eq!(b.counters(), UkfCounters::default());
    }
}

/// The ratio of the UKF's `P₁₁` to the exact (`f64`) Kalman filter's
/// after 2,000 steps of a constant-velocity system with `Q = 0` (`x⁺ =
/// [[1, 0.1], [0, 1]] x`, position measured with `R = 0.04`, the truth
/// moving at 0.01 per step from `offset`), and the RMS distance of the two
/// position estimates over the last 200 steps, for weights `(α, β)`.
fn q_zero_drift(alpha: f32, beta: f32, offset: f64, form: UkfForm) -> (f64, f64) {
    let model = Linear {
        a: SMatrix::<f32, 2, 2>::new(1.0, 0.1, 0.0, 1.0),
        b: SVector::<f32, 2>::zeros(),
        h: SMatrix::<f32, 1, 2>::new(1.0, 0.0),
    };
    let r = 0.04_f64;
    let x0 = SVector::<f32, 2>::new(offset as f32, 0.0);
    let points = MerweScaledSigmaPoints::<2, 5>::new(alpha, beta, 0.0).unwrap();
    let mut ukf = UnscentedKalmanFilter::new(
        model,
        points,
        x0,
        SMatrix::identity(),
        SMatrix::zeros(),
        SMatrix::<f32, 1, 1>::new(r as f32),
    )
    .unwrap()
    .with_form(form)
    .unwrap();
    let a = model.a.map(f64::from);
    let (mut x, mut p) = (x0.map(f64::from), nalgebra::Matrix2::<f64>::identity());
    let mut truth = SVector::<f64, 2>::new(offset + 0.3, 0.01);
    // A uniform noise of variance R from a fixed linear congruential
    // sequence (Knuth's MMIX constants).
    let mut seed = 12345_u64;
    let mut noise = || {
        seed = seed
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((seed >> 11) as f64 / (1_u64 << 53) as f64 - 0.5) * (12.0 * r).sqrt()
    };
    let (steps, tail) = (2000_u32, 200_u32);
    let mut distance2 = 0.0_f64;
    for k in 0..steps {
        truth = a * truth;
        let z = truth[0] + noise();
        assert_eq!(ukf.predict(&0.0, 0.1), StepOutcome::Applied);
        x = a * x;
        p = a * p * a.transpose();
        assert_eq!(
            ukf.update(&SVector::<f32, 1>::new(z as f32)),
            StepOutcome::Applied
        );
        let s = p[(0, 0)] + r;
        let gain = p.column(0) / s;
        x += gain * (z - x[0]);
        p -= gain * gain.transpose() * s;
        if k >= steps - tail {
            distance2 += (f64::from(ukf.state()[0]) - x[0]).powi(2);
        }
    }
    assert_eq!(ukf.counters(), UkfCounters::default());
    (
        f64::from(ukf.covariance()[(0, 0)]) / p[(0, 0)],
        (distance2 / f64::from(tail)).sqrt(),
    )
}

/// With `Q = 0` and the paper's `α = 0.01` the covariance drifts above
/// the Kalman filter's, in both forms, by a factor that grows with `|x|`:
/// `f32` rounding of the sigma points (module docs, "`f32` and small
/// `α`"). The figures of the module docs, pinned: after 2,000 steps `P₁₁`
/// is within 3 % of the Kalman filter's at `α = 1` (|x| ≤ 100) and within
/// 10 % at `α = 0.1` (|x| ≤ 10); at `α = 0.01` it is 2.8–3.7× at |x| ≤ 1
/// and 11–12× at |x| = 10, and the estimates part by about the Kalman
/// filter's own σ (8.9e-3). With `β` at `α²` (which zeroes the centre
/// term) the same run at |x| ≤ 1 ends within 1.35×: the excess enters
/// `P` through the centre term `(β − α²) m mᵀ`, with `m` the predict's
/// rounding-sized mean shift.
#[test]
fn q_zero_drift_is_f32_rounding_at_small_alpha() {
    for form in FORMS {
        for offset in [0.0, 1.0, 10.0, 100.0] {
            let (ratio, distance) = q_zero_drift(1.0, 2.0, offset, form);
            println!("{form:?} |x| {offset}, α 1: P ratio {ratio:.2}, distance {distance:.1e}");
            assert!((0.97..1.03).contains(&ratio), "{form:?} {offset}: {ratio}");
            assert!(distance < 1e-4, "{form:?} {offset}: {distance}");
        }
        for offset in [0.0, 1.0, 10.0] {
            let (ratio, distance) = q_zero_drift(0.1, 2.0, offset, form);
            println!("{form:?} |x| {offset}, α 0.1: P ratio {ratio:.2}, distance {distance:.1e}");
            assert!((0.97..1.1).contains(&ratio), "{form:?} {offset}: {ratio}");
            assert!(distance < 1e-3, "{form:?} {offset}: {distance}");
        }
        let mut ratios = [0.0; 3];
        for (offset, ratio) in [0.0, 1.0, 10.0].into_iter().zip(ratios.iter_mut()) {
            let distance;
            (*ratio, distance) = q_zero_drift(0.01, 2.0, offset, form);
            println!("{form:?} |x| {offset}, α 0.01: P ratio {ratio:.2}, distance {distance:.1e}");
        }
        assert!(
            ratios[..2].iter().all(|r| (2.5..4.0).contains(r)),
            "{form:?}: {ratios:?}"
        );
        assert!((10.0..13.0).contains(&ratios[2]), "{form:?}: {ratios:?}");
        for offset in [0.0, 1.0] {
            let (ratio, _) = q_zero_drift(0.01, 1e-4, offset, form);
            println!("{form:?} |x| {offset}, α 0.01, β = α²: P ratio {ratio:.2}");
            assert!((0.8..1.35).contains(&ratio), "{form:?} {offset}: {ratio}");
        }
    }
}

/// A prior that is positive definite in exact arithmetic but rounds to a
/// singular `f32` matrix: `P = 2¹³ [[1, 1], [1, 1]] + diag(0, 2.5e-6)`
/// (two states that differ by a tiny independent offset; `8192 + 2.5e-6`
/// is `8192` in `f32`; `α` such that `(n + λ)P` is exact, so that its
/// Cholesky pivot is exactly 0). The predict repairs it, raising each
/// diagonal entry by at most `N·S·ε` of itself (module docs, "Bad input
/// and failures"), the size of the rounding it repairs. After the first
/// state is measured (`R` = 1e-8), the second state's variance (exact:
/// 2.5e-6 + 1e-8, from an `f64` Kalman filter) is off by what the jitter
/// added, within a few ulps of a matrix of scale 8192 (ulp 9.8e-4): the
/// `f32` resolution of that prior.
#[test]
fn a_repair_is_rounding_sized() {
    let model = Linear {
        a: SMatrix::<f32, 2, 2>::identity(),
        b: SVector::<f32, 2>::zeros(),
        h: SMatrix::<f32, 1, 2>::new(1.0, 0.0),
    };
    let r = 1e-8_f64;
    let scale = 8192.0_f64;
    let exact_p = nalgebra::Matrix2::<f64>::new(scale, scale, scale, scale + 2.5e-6);
    let rounded = exact_p.map(|v| v as f32);
    let s = exact_p[(0, 0)] + r;
    let exact_p22 = exact_p[(1, 1)] - exact_p[(1, 0)] * exact_p[(0, 1)] / s;
    let eps = f64::from(f32::EPSILON);
    for alpha in [0.0078125_f32, 0.5, 1.0] {
        let setup = (
            SVector::<f32, 2>::new(0.0, 0.0),
            SMatrix::<f32, 2, 2>::identity(),
            SMatrix::<f32, 2, 2>::zeros(),
            SMatrix::<f32, 1, 1>::new(r as f32),
        );
        let mut ukf = linear_filter(model, alpha, setup, UkfForm::Covariance);
        assert!(lower_factor(&(rounded * ukf.points.spread)).is_none());
        ukf.p = rounded;
        assert_eq!(ukf.predict(&0.0, 0.1), StepOutcome::Repaired);
        let added = (ukf.covariance() - rounded)
            .map(f64::from)
            .diagonal()
            .amax();
        assert_eq!(
            ukf.update(&SVector::<f32, 1>::new(1.0)),
            StepOutcome::Applied
        );
        let p22 = f64::from(ukf.covariance()[(1, 1)]);
        println!(
            "α {alpha}: the repair added {added:.2e} to the diagonal; \
             P₂₂ after the update {p22:.2e}, exact {exact_p22:.2e}"
        );
        assert!(added <= (2 * 5) as f64 * eps * scale, "{added:e}");
        assert!(
            (p22 - exact_p22).abs() <= 4.0 * (2 * 5) as f64 * eps * scale,
            "{p22:e}"
        );
        assert_eq!(ukf.counters().covariance_repairs, 1);
    }
}

/// With the centre mean the prior mean is `f(x, u)` exactly and `P⁻` the
/// points' spread about it plus `Q`, in both forms; on the unicycle with
/// a wide heading the means differ by the unscented mean's shift `m`,
/// and `P⁻` is the unscented one less its centre term `(β − α²) m mᵀ`
/// (module docs, "Square-root form"); on a linear model the filter is the
/// default one to rounding.
#[test]
fn the_centre_mean_is_the_centre_points_image() {
    let u = [1.0_f32, 0.2];
    for form in FORMS {
        let mut ukf = unicycle_filter(1.0).with_form(form).unwrap();
        ukf.reset(
            V3::new(0.5, -0.3, 0.4),
            M3::from_diagonal(&V3::new(0.01, 0.01, 0.5)),
        )
        .unwrap();
        let mut centre = ukf.with_centre_mean();
        let x0 = *ukf.state();
        assert_eq!(ukf.predict(&u, 0.5), StepOutcome::Applied);
        assert_eq!(centre.predict(&u, 0.5), StepOutcome::Applied);
        assert_eq!(*centre.state(), Unicycle.transition(&x0, &u, 0.5));
        let sigmas = centre.propagated_sigma_points().unwrap();
        let mut spread = *centre.process_noise();
        for (sigma, w) in sigmas
            .column_iter()
            .zip(centre.points.covariance_weights().iter())
        {
            let d = Unicycle
                .angles()
                .state_residual(&sigma.into_owned(), centre.state());
            spread += d * d.transpose() * *w;
        }
        assert!((centre.covariance() - spread).amax() < 1e-5, "{form:?}");
        let shift = centre.state() - ukf.state();
        assert!(shift.norm() > 0.02, "{form:?}: {shift}");
        let beta_less_alpha2 = 2.0 - 1.0;
        let excess =
            centre.covariance() - ukf.covariance() + shift * shift.transpose() * beta_less_alpha2;
        assert!(excess.amax() < 1e-5, "{form:?}: {excess}");
    }
    let model = Linear {
        a: SMatrix::<f32, 2, 2>::new(1.0, 0.1, 0.0, 0.95),
        b: SVector::<f32, 2>::new(0.005, 0.1),
        h: SMatrix::<f32, 1, 2>::new(1.0, 0.0),
    };
    let setup = (
        SVector::<f32, 2>::new(0.5, -0.2),
        SMatrix::<f32, 2, 2>::new(1.0, 0.3, 0.3, 0.5),
        SMatrix::<f32, 2, 2>::new(1e-3, 2e-4, 2e-4, 2e-3),
        SMatrix::<f32, 1, 1>::new(0.04),
    );
    for form in FORMS {
        let mut a = linear_filter(model, 1.0, setup, form);
        let mut b = a.with_centre_mean();
        for k in 0..100_u8 {
            let u = 0.3 * f32::from(k % 7) - 0.8;
            let z = SVector::<f32, 1>::new(0.02 * f32::from(k) - 0.5 * f32::from(k % 3));
            assert_eq!(a.predict(&u, 0.1), b.predict(&u, 0.1));
            assert_eq!(a.update(&z), b.update(&z));
            assert!((a.state() - b.state()).amax() < 1e-5, "{form:?}");
            assert!((a.covariance() - b.covariance()).amax() < 1e-5, "{form:?}");
        }
    }
}
