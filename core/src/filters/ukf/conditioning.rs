//! The covariance helpers both steps share: finiteness, symmetrising, the
//! check of a noise covariance and the gain's solve with `S` (module docs
//! of [`super`]).

use nalgebra::SMatrix;

use super::CovarianceDefect;
use super::sigma_points::lower_factor;

/// `K = Pxy S⁻¹` for a symmetric `S`: as `Kᵀ = S⁻¹ Pxyᵀ` by Cholesky when
/// `S` is positive definite (the normal case), else with nalgebra's inverse
/// (FilterPy always inverts, `np.linalg.inv`); `None` if `S` is singular
/// or `K` not finite. The Cholesky solve matters in `f32`: nalgebra's
/// closed-form 4 × 4 inverse of the landmark fixture's `S` put 3e-4 of
/// error into the first update's `P`.
pub(super) fn kalman_gain<const N: usize, const M: usize>(
    cross: &SMatrix<f32, N, M>,
    s: &SMatrix<f32, M, M>,
) -> Option<SMatrix<f32, N, M>> {
    let gain = match nalgebra::Cholesky::new(*s) {
        Some(factor) => factor.solve(&cross.transpose()).transpose(),
        None => cross * s.try_inverse()?,
    };
    all_finite(&gain).then_some(gain)
}

/// `(a + aᵀ)/2`.
pub(super) fn symmetrize<const K: usize>(a: &SMatrix<f32, K, K>) -> SMatrix<f32, K, K> {
    (a + a.transpose()) * 0.5
}

pub(super) fn all_finite<const R: usize, const C: usize>(a: &SMatrix<f32, R, C>) -> bool {
    a.iter().all(|v| v.is_finite())
}

/// `Ok` if `a` is finite, symmetric to `f32` rounding and positive
/// semi-definite (it factors once its diagonal is raised by 1e-6 of its
/// largest entry) or, with `definite`, positive definite (its Cholesky
/// factor exists and is finite); else the first defect found.
pub(super) fn check_covariance<const K: usize>(
    a: &SMatrix<f32, K, K>,
    definite: bool,
) -> Result<(), CovarianceDefect> {
    let scale = a.amax();
    if !all_finite(a) {
        return Err(CovarianceDefect::NotFinite);
    }
    if (a - a.transpose()).amax() > 1e-6 * scale {
        return Err(CovarianceDefect::NotSymmetric);
    }
    if definite {
        return lower_factor(a)
            .map(|_| ())
            .ok_or(CovarianceDefect::NotPositiveDefinite);
    }
    lower_factor(&(a + SMatrix::<f32, K, K>::identity() * (1e-6 * scale).max(f32::MIN_POSITIVE)))
        .map(|_| ())
        .ok_or(CovarianceDefect::NotPositiveSemiDefinite)
}
