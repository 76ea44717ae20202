//! The small dense linear algebra of the square-root form
//! ([`super::UkfForm::SquareRoot`]): a rank-one Cholesky update by Givens
//! rotations, from which the QR triangularisation of Van der Merwe & Wan
//! (2001) is built, and a square root of a semi-definite noise matrix.
//!
//! Written here rather than taken from nalgebra: its `QR` and
//! `Cholesky::rank_one_update` index with bounds checks that the link-time
//! panic-free proof (`cargo xtask panic-free`) need not see through; these
//! loops walk the column-major arrays with iterators and `get`, so every
//! access is total.

use nalgebra::{SMatrix, SVector};

use crate::math;

/// `L ← L'` with `L' L'ᵀ = L Lᵀ + a aᵀ`, for a lower-triangular `L`
/// (Van der Merwe & Wan 2001, `cholupdate(S, u, +ν)`): column `k` of `L`
/// and `a` are rotated by the Givens rotation that zeroes `aₖ`, `k = 0 …
/// n−1`. Each rotation is orthogonal, so `L Lᵀ + a aᵀ` is kept to
/// rounding and the diagonal stays ≥ 0; a zero pair `(Lₖₖ, aₖ)` is left
/// as it is (a semi-definite `L` stays so).
pub(super) fn rank_one_update<const N: usize>(l: &mut SMatrix<f32, N, N>, a: &SVector<f32, N>) {
    let mut a = *a;
    for (k, column) in l.data.0.iter_mut().enumerate() {
        let (Some(&diagonal), Some(&ak)) = (column.get(k), a.get(k)) else {
            continue;
        };
        let r = math::hypot(diagonal, ak);
        if r.partial_cmp(&0.0) != Some(core::cmp::Ordering::Greater) {
            continue;
        }
        let (c, s) = (diagonal / r, ak / r);
        for (lk, ai) in column.iter_mut().zip(a.iter_mut()).skip(k + 1) {
            let (lv, av) = (*lk, *ai);
            *lk = c * lv + s * av;
            *ai = c * av - s * lv;
        }
        if let Some(d) = column.get_mut(k) {
            *d = r;
        }
    }
}

/// Adds the columns of `a`, each scaled by `scale`, to the factor `l`
/// (`L Lᵀ + scale² A Aᵀ`): from `l = 0`, the QR triangularisation
/// `qr([scale·A]ᵀ)ᵀ` of the paper, one Givens rotation per entry.
pub(super) fn add_columns<const N: usize, const C: usize>(
    l: &mut SMatrix<f32, N, N>,
    a: &SMatrix<f32, N, C>,
    scale: f32,
) {
    for column in &a.data.0 {
        rank_one_update(l, &(SVector::from(*column) * scale));
    }
}

/// A lower-triangular `L` with `L Lᵀ = A` for a symmetric positive
/// semi-definite `A` (lower triangle read): Cholesky, except that a pivot
/// at or below `n ε` times the largest diagonal entry (a direction `A`
/// does not excite, to rounding) gives a zero column. Used for `√Q` and
/// `√R`, which may be singular (`Q = 0` is allowed).
pub(super) fn semidefinite_factor<const K: usize>(a: &SMatrix<f32, K, K>) -> SMatrix<f32, K, K> {
    let mut l = SMatrix::<f32, K, K>::zeros();
    let tiny = (K as f32) * f32::EPSILON * a.diagonal().amax();
    let at = |m: &SMatrix<f32, K, K>, i: usize, j: usize| m.get((i, j)).copied().unwrap_or(0.0);
    for j in 0..K {
        let mut d = at(a, j, j);
        for k in 0..j {
            let v = at(&l, j, k);
            d -= v * v;
        }
        if d.partial_cmp(&tiny) != Some(core::cmp::Ordering::Greater) {
            continue;
        }
        let root = math::sqrt(d);
        if let Some(v) = l.get_mut((j, j)) {
            *v = root;
        }
        for i in j + 1..K {
            let mut v = at(a, i, j);
            for k in 0..j {
                v -= at(&l, i, k) * at(&l, j, k);
            }
            if let Some(entry) = l.get_mut((i, j)) {
                *entry = v / root;
            }
        }
    }
    l
}

/// `L Lᵀ`, symmetrised.
pub(super) fn outer<const N: usize>(l: &SMatrix<f32, N, N>) -> SMatrix<f32, N, N> {
    let p = l * l.transpose();
    (p + p.transpose()) * 0.5
}

#[cfg(test)]
mod tests {
    use super::*;

    type M3 = SMatrix<f32, 3, 3>;

    /// The triangularisation keeps `L Lᵀ` and gives a lower-triangular
    /// factor with a non-negative diagonal; the semi-definite factor
    /// reproduces `Q = 0`, a rank-one matrix and nalgebra's Cholesky.
    #[test]
    fn factors_keep_the_product() {
        let a = SMatrix::<f32, 3, 5>::from_row_slice(&[
            1.0, -0.5, 0.2, 0.0, 3.0, //
            0.3, 0.8, -1.0, 0.1, 0.0, //
            0.0, 0.4, 0.5, -0.7, 0.2,
        ]);
        let mut l = M3::zeros();
        add_columns(&mut l, &a, 0.5);
        let want = a * a.transpose() * 0.25;
        assert!((outer(&l) - want).amax() < 1e-5 * want.amax(), "{l}");
        for i in 0..3 {
            assert!(l[(i, i)] >= 0.0);
            for j in i + 1..3 {
                assert_eq!(l[(i, j)], 0.0);
            }
        }
        assert_eq!(semidefinite_factor(&M3::zeros()), M3::zeros());
        let v = SVector::<f32, 3>::new(1.0, 2.0, -1.0);
        let rank_one = v * v.transpose();
        let f = semidefinite_factor(&rank_one);
        assert!((outer(&f) - rank_one).amax() < 1e-5, "{f}");
        let spd = M3::new(4.0, 1.0, 0.5, 1.0, 3.0, -0.2, 0.5, -0.2, 2.0);
        let f = semidefinite_factor(&spd);
        assert!((f - spd.cholesky().unwrap().l()).amax() < 1e-6);
    }
}
