//! The square-root form's measurement correction (module docs of
//! [`super`], "Square-root form"; Van der Merwe & Wan 2001, Algorithm 3.1,
//! eqs. 22–27, with the posterior factor built by updates only).

use nalgebra::{SMatrix, SVector};

use super::factor::{add_columns, outer};
use super::filter::UnscentedKalmanFilter;
use super::update::Corrected;
use super::{StepOutcome, UkfModel};

impl<Model, const N: usize, const M: usize, const S: usize> UnscentedKalmanFilter<Model, N, M, S>
where
    Model: UkfModel<N, M>,
{
    /// `S_y = qr([√Wᵢ dzᵢ, √R])` with the centre term (eqs. 23–24),
    /// `P_xy` from the centred sums (eq. 26), `K = (P_xy / S_yᵀ) / S_y`
    /// (eq. 27) by two triangular solves, and the posterior factor
    /// `L = qr([√Wᵢ eᵢ, K √R (, √Q)])`, `eᵢ = dxᵢ − K dzᵢ`, with the centre
    /// term: `L Lᵀ = P⁻ − K S Kᵀ`, built by rank-one updates only (where
    /// the paper downdates `L⁻` by the columns of `K S_y`, eq. 27, which
    /// in `f32` fails when a variance falls by orders of magnitude).
    pub(super) fn correct_square_root<const K: usize>(
        &self,
        sigmas_f: &SMatrix<f32, N, S>,
        reused: bool,
        dz: &SMatrix<f32, K, S>,
        innovation: &SVector<f32, K>,
        r_factor: &SMatrix<f32, K, K>,
    ) -> Corrected<N, K> {
        let dx = self.centred_state_deviations(sigmas_f, &self.x);
        let s_factor = self.points.centred_factor(*r_factor, dz);
        let cross = self.points.centred_cross(&dx, dz);
        if !(s_factor.iter().all(|v| v.is_finite()) && cross.iter().all(|v| v.is_finite())) {
            return Err(StepOutcome::NonFiniteResult);
        }
        if !s_factor.diagonal().iter().all(|&d| d > 0.0) {
            return Err(StepOutcome::SingularInnovation);
        }
        // Kᵀ = S_y⁻ᵀ S_y⁻¹ P_xyᵀ: nalgebra's Cholesky solve on the factor
        // as it is (lower triangle read).
        let gain = nalgebra::Cholesky::pack_dirty(s_factor)
            .solve(&cross.transpose())
            .transpose();
        if !gain.iter().all(|v| v.is_finite()) {
            return Err(StepOutcome::SingularInnovation);
        }
        let x = self.x + gain * innovation;
        let base = if reused {
            self.q_factor
        } else {
            SMatrix::zeros()
        };
        let mut factor = self.points.centred_factor(base, &(dx - gain * dz));
        add_columns(&mut factor, &(gain * r_factor), 1.0);
        Ok((x, outer(&factor), factor, gain, outer(&s_factor)))
    }
}
