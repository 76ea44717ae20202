//! The time update (module docs of [`super`], "Time update"): the sigma
//! points of `(x, P)`, with the repair and reset of "Bad input and
//! failures", propagated through the model; and the points' deviations
//! about the centre point, which the square-root form's sums are taken
//! over.

use nalgebra::{SMatrix, SVector};

use super::conditioning::{all_finite, symmetrize};
use super::factor::outer;
use super::filter::UnscentedKalmanFilter;
use super::sigma_points::{lower_factor, points_from_factor};
use super::{StepOutcome, UkfForm, UkfModel, bump, repair_bound};

impl<Model, const N: usize, const M: usize, const S: usize> UnscentedKalmanFilter<Model, N, M, S>
where
    Model: UkfModel<N, M>,
{
    /// The sigma points of the current `(x, P)`, with the repair and reset
    /// of the module docs: `Ok((points, repaired))`, or `Err` after a reset.
    pub(super) fn draw_sigma_points(&mut self) -> Result<(SMatrix<f32, N, S>, bool), StepOutcome> {
        if self.form == UkfForm::SquareRoot {
            let l = self.factor * self.points.gamma();
            return Ok((points_from_factor(&self.x, &l), false));
        }
        if let Some(points) = self.points.sigma_points(&self.x, &self.p) {
            return Ok((points, false));
        }
        let scaled = symmetrize(&(self.p * self.points.spread));
        // Each diagonal entry raised by the jitter times itself (a floor
        // for a zero or negative one), so that a small variance is not
        // swamped by the largest; the jitter grows from ε by factors of 4
        // up to REPAIR_BOUND, and the first that factors is kept.
        let mut jitter = f32::EPSILON;
        let bound = repair_bound::<N, S>();
        while jitter <= bound {
            let mut jittered = scaled;
            for v in jittered.iter_mut().step_by(N + 1).take(N) {
                *v += (jitter * v.abs()).max(f32::MIN_POSITIVE);
            }
            if let Some(l) = lower_factor(&jittered) {
                bump(&mut self.counters.covariance_repairs);
                return Ok((points_from_factor(&self.x, &l), true));
            }
            jitter *= 4.0;
        }
        self.p = self.initial_covariance;
        self.sigmas_f_fresh = false;
        bump(&mut self.counters.covariance_resets);
        Err(StepOutcome::CovarianceReset)
    }

    /// The time update over `dt_s` seconds (≥ 0) with input `u`: FilterPy's
    /// `predict(dt, u=u)` (module docs). On return [`Self::state`] and
    /// [`Self::covariance`] are the prior `x⁻, P⁻`.
    pub fn predict(&mut self, u: &Model::Input, dt_s: f32) -> StepOutcome {
        if !(dt_s.is_finite() && dt_s >= 0.0 && self.model.input_is_finite(u)) {
            bump(&mut self.counters.rejected_inputs);
            return StepOutcome::RejectedInput;
        }
        let (sigmas, repaired) = match self.draw_sigma_points() {
            Ok(drawn) => drawn,
            Err(outcome) => return outcome,
        };
        let mut sigmas_f = SMatrix::<f32, N, S>::zeros();
        for (sigma, mut propagated) in sigmas.column_iter().zip(sigmas_f.column_iter_mut()) {
            propagated.copy_from(&self.model.transition(&sigma.into_owned(), u, dt_s));
        }
        let x = match (self.centre_mean, sigmas_f.data.0.first()) {
            (true, Some(centre)) => SVector::from(*centre),
            _ => self
                .model
                .angles()
                .state_mean(&sigmas_f, &self.points.mean_weights()),
        };
        let (p, factor) = match self.form {
            UkfForm::Covariance => {
                let mut p = self.q;
                for (sigma, &w) in sigmas_f
                    .column_iter()
                    .zip(self.points.covariance_weights().iter())
                {
                    let d = self.model.angles().state_residual(&sigma.into_owned(), &x);
                    p += d * d.transpose() * w;
                }
                (symmetrize(&p), self.factor)
            }
            UkfForm::SquareRoot => {
                let deviations = self.centred_state_deviations(&sigmas_f, &x);
                let factor = self.points.centred_factor(self.q_factor, &deviations);
                (outer(&factor), factor)
            }
        };
        if !(all_finite(&x) && all_finite(&p) && all_finite(&factor) && all_finite(&sigmas_f)) {
            bump(&mut self.counters.non_finite_results);
            self.sigmas_f_fresh = false;
            return StepOutcome::NonFiniteResult;
        }
        self.x = x;
        self.p = p;
        self.factor = factor;
        self.sigmas_f = sigmas_f;
        self.sigmas_f_fresh = true;
        if repaired {
            StepOutcome::Repaired
        } else {
            StepOutcome::Applied
        }
    }

    /// The state deviations of the points `sigmas` about the first one,
    /// `r(mean, σ₀)` in column 0 and `r(σᵢ, σ₀)` in the others (the
    /// square-root form's centred sums, module docs).
    pub(super) fn centred_state_deviations(
        &self,
        sigmas: &SMatrix<f32, N, S>,
        mean: &SVector<f32, N>,
    ) -> SMatrix<f32, N, S> {
        let mut d = SMatrix::<f32, N, S>::zeros();
        let Some(centre) = sigmas.data.0.first().map(|c| SVector::from(*c)) else {
            return d;
        };
        for (i, (sigma, out)) in sigmas.data.0.iter().zip(d.data.0.iter_mut()).enumerate() {
            let residual = if i == 0 {
                self.model.angles().state_residual(mean, &centre)
            } else {
                self.model
                    .angles()
                    .state_residual(&SVector::from(*sigma), &centre)
            };
            let [column] = residual.data.0;
            *out = column;
        }
        d
    }
}
