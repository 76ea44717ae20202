//! The measurement update (module docs of [`super`], "Measurement
//! update"): the update's points and their measurement deviations, the
//! correction checked and kept, and the covariance form's correction (the
//! square-root form's is `square_root`'s).

use nalgebra::{SMatrix, SVector};

use super::conditioning::{all_finite, check_covariance, kalman_gain, symmetrize};
use super::factor::semidefinite_factor;
use super::filter::UnscentedKalmanFilter;
use super::{StepOutcome, UkfForm, UkfModel, bump};

/// Either form's measurement correction, before it is checked and kept:
/// the posterior `x, P`, the factor of `P` (the square-root form's; the
/// covariance form passes the filter's unchanged), the gain and `S`, for
/// `K` measured components; or the outcome of a failure. A tuple behind an
/// alias rather than a struct: a struct costs the three-state update
/// 7-10 % more instructions on the Cortex-M4 (measured at d197056).
pub(super) type Corrected<const N: usize, const K: usize> = Result<
    (
        SVector<f32, N>,
        SMatrix<f32, N, N>,
        SMatrix<f32, N, N>,
        SMatrix<f32, N, K>,
        SMatrix<f32, K, K>,
    ),
    StepOutcome,
>;

impl<Model, const N: usize, const M: usize, const S: usize> UnscentedKalmanFilter<Model, N, M, S>
where
    Model: UkfModel<N, M>,
{
    /// The measurement update with `z` and the filter's `R`: FilterPy's
    /// `update(z)` (module docs), on the last predict's `σf`.
    pub fn update(&mut self, z: &SVector<f32, M>) -> StepOutcome {
        let (r, r_factor) = (self.r, self.r_factor);
        self.update_with(z, &r, Some(&r_factor))
    }

    /// The measurement update with `z` and, for this call only, the
    /// measurement noise `r` (FilterPy's `update(z, R)`; an `r` that is not
    /// finite, symmetric and positive definite rejects the update, as
    /// [`UkfError::MeasurementNoise`](super::UkfError::MeasurementNoise)
    /// refuses it at construction).
    pub fn update_with_noise(
        &mut self,
        z: &SVector<f32, M>,
        r: &SMatrix<f32, M, M>,
    ) -> StepOutcome {
        if check_covariance(r, true).is_err() {
            bump(&mut self.counters.rejected_inputs);
            return StepOutcome::RejectedInput;
        }
        // Its factor only if the square-root form needs it (`correct`):
        // the covariance form does not, and a 2×2 factor per fix would be
        // half the fusion UKF's update cost.
        let r = symmetrize(r);
        self.update_with(z, &r, None)
    }

    /// The measurement update with component `index` (`< M`) of the
    /// measurement only, `z` with variance `r`: for a sensor that reported
    /// only part of the measurement vector this tick. It is the update of
    /// the scalar measurement `h_i(x)` (row `index` of the model's
    /// `measure`, its residual and mean), with the same sigma points,
    /// checks and outcomes as [`Self::update`]. Afterwards
    /// [`Self::innovation`], [`Self::innovation_covariance`] and
    /// [`Self::gain`] hold it in full-measurement shape, zero outside
    /// component `index` (as a full update with infinite variance on the
    /// other components would leave them). An `index ≥ M`, or an `r` that
    /// is not finite and > 0, rejects the update.
    pub fn update_component(&mut self, index: usize, z: f32, r: f32) -> StepOutcome {
        if !(index < M && z.is_finite() && r.is_finite() && r > 0.0) {
            bump(&mut self.counters.rejected_inputs);
            return StepOutcome::RejectedInput;
        }
        let (sigmas_f, repaired, reused, sigmas_h, z_mean) = match self.measurement_sigmas() {
            Ok(drawn) => drawn,
            Err(outcome) => return outcome,
        };
        let dz = self.measurement_deviations(&sigmas_h, &z_mean, |d| {
            SVector::<f32, 1>::new(d.get(index).copied().unwrap_or(f32::NAN))
        });
        let mut full_z = z_mean;
        if let Some(component) = full_z.get_mut(index) {
            *component = z;
        }
        let innovation = self
            .model
            .angles()
            .measurement_residual(&full_z, &z_mean)
            .get(index)
            .copied()
            .unwrap_or(f32::NAN);
        let innovation = SVector::<f32, 1>::new(innovation);
        let r_factor = SMatrix::<f32, 1, 1>::new(crate::math::sqrt(r));
        let r = SMatrix::<f32, 1, 1>::new(r);
        match self.correct(&sigmas_f, reused, &dz, &innovation, (&r, Some(&r_factor))) {
            Ok((gain, s)) => {
                self.innovation = SVector::zeros();
                self.innovation_covariance = SMatrix::zeros();
                self.gain = SMatrix::zeros();
                if let Some(v) = self.innovation.get_mut(index) {
                    *v = innovation.x;
                }
                if let Some(v) = self.innovation_covariance.get_mut((index, index)) {
                    *v = s.x;
                }
                if let Some(mut column) = self.gain.columns_mut(index, 1).column_iter_mut().next() {
                    column.copy_from(&gain);
                }
                Self::outcome(repaired)
            }
            Err(outcome) => outcome,
        }
    }

    fn update_with(
        &mut self,
        z: &SVector<f32, M>,
        r: &SMatrix<f32, M, M>,
        r_factor: Option<&SMatrix<f32, M, M>>,
    ) -> StepOutcome {
        if !all_finite(z) {
            bump(&mut self.counters.rejected_inputs);
            return StepOutcome::RejectedInput;
        }
        let (sigmas_f, repaired, reused, sigmas_h, z_mean) = match self.measurement_sigmas() {
            Ok(drawn) => drawn,
            Err(outcome) => return outcome,
        };
        let dz = self.measurement_deviations(&sigmas_h, &z_mean, |d| d);
        let innovation = self.model.angles().measurement_residual(z, &z_mean);
        match self.correct(&sigmas_f, reused, &dz, &innovation, (r, r_factor)) {
            Ok((gain, s)) => {
                self.innovation = innovation;
                self.innovation_covariance = s;
                self.gain = gain;
                Self::outcome(repaired)
            }
            Err(outcome) => outcome,
        }
    }

    /// The measurement deviations of the points (columns, `pick`ed to the
    /// `K` measured components): in the covariance form `rz(σhᵢ, ŷ)`; in
    /// the square-root form centred on the first point, `rz(ŷ, σh₀)` in
    /// column 0 and `rz(σhᵢ, σh₀)` in the others (module docs).
    fn measurement_deviations<const K: usize>(
        &self,
        sigmas_h: &SMatrix<f32, M, S>,
        z_mean: &SVector<f32, M>,
        pick: impl Fn(SVector<f32, M>) -> SVector<f32, K>,
    ) -> SMatrix<f32, K, S> {
        let mut dz = SMatrix::<f32, K, S>::zeros();
        match self.form {
            UkfForm::Covariance => {
                for (sigma_h, d) in sigmas_h.data.0.iter().zip(dz.data.0.iter_mut()) {
                    let residual = self
                        .model
                        .angles()
                        .measurement_residual(&SVector::from(*sigma_h), z_mean);
                    let [column] = pick(residual).data.0;
                    *d = column;
                }
            }
            UkfForm::SquareRoot => {
                let Some(centre) = sigmas_h.data.0.first().map(|c| SVector::from(*c)) else {
                    return dz;
                };
                for (i, (sigma_h, d)) in
                    sigmas_h.data.0.iter().zip(dz.data.0.iter_mut()).enumerate()
                {
                    let residual = if i == 0 {
                        self.model.angles().measurement_residual(z_mean, &centre)
                    } else {
                        self.model
                            .angles()
                            .measurement_residual(&SVector::from(*sigma_h), &centre)
                    };
                    let [column] = pick(residual).data.0;
                    *d = column;
                }
            }
        }
        dz
    }

    fn outcome(repaired: bool) -> StepOutcome {
        if repaired {
            StepOutcome::Repaired
        } else {
            StepOutcome::Applied
        }
    }

    /// The update's points: the last predict's `σf` if still fresh (else
    /// drawn from `(x, P)`), whether they were repaired, whether they are
    /// the predict's (which leave out `Q`), their images under `h` and
    /// the mean of those.
    #[allow(clippy::type_complexity)]
    fn measurement_sigmas(
        &mut self,
    ) -> Result<
        (
            SMatrix<f32, N, S>,
            bool,
            bool,
            SMatrix<f32, M, S>,
            SVector<f32, M>,
        ),
        StepOutcome,
    > {
        let reused = self.sigmas_f_fresh && !self.redraw_for_update;
        let (sigmas_f, repaired) = if reused {
            (self.sigmas_f, false)
        } else {
            self.draw_sigma_points()?
        };
        let mut sigmas_h = SMatrix::<f32, M, S>::zeros();
        for (sigma, mut measured) in sigmas_f.column_iter().zip(sigmas_h.column_iter_mut()) {
            measured.copy_from(&self.model.measure(&sigma.into_owned()));
        }
        let z_mean = self
            .model
            .angles()
            .measurement_mean(&sigmas_h, &self.points.mean_weights());
        Ok((sigmas_f, repaired, reused, sigmas_h, z_mean))
    }

    /// The correction from the measurement deviations `dz`
    /// ([`Self::measurement_deviations`]) of the points `sigmas_f`
    /// (columns) and the innovation, with noise `r` and its factor if known
    /// (`K` measured components; the square-root form factors `r` when it
    /// is not given, the covariance form never needs it): `S`, `P_xz`, the gain, and `x, P` updated in
    /// the filter's form. `reused`: the points are the predict's, whose
    /// covariance lacks `Q`. Returns the gain and `S`, or the outcome of a
    /// failure (counted).
    fn correct<const K: usize>(
        &mut self,
        sigmas_f: &SMatrix<f32, N, S>,
        reused: bool,
        dz: &SMatrix<f32, K, S>,
        innovation: &SVector<f32, K>,
        (r, r_factor): (&SMatrix<f32, K, K>, Option<&SMatrix<f32, K, K>>),
    ) -> Result<(SMatrix<f32, N, K>, SMatrix<f32, K, K>), StepOutcome> {
        let corrected = match self.form {
            UkfForm::Covariance => self.correct_covariance(sigmas_f, reused, dz, innovation, r),
            UkfForm::SquareRoot => {
                let r_factor = r_factor.copied().unwrap_or_else(|| semidefinite_factor(r));
                self.correct_square_root(sigmas_f, reused, dz, innovation, &r_factor)
            }
        };
        let (x, p, factor, gain, s) = match corrected {
            Ok(corrected) => corrected,
            Err(outcome) => {
                bump(match outcome {
                    StepOutcome::SingularInnovation => &mut self.counters.singular_innovations,
                    _ => &mut self.counters.non_finite_results,
                });
                return Err(outcome);
            }
        };
        if !(all_finite(&x)
            && all_finite(&p)
            && all_finite(&factor)
            && all_finite(&gain)
            && all_finite(innovation))
        {
            bump(&mut self.counters.non_finite_results);
            return Err(StepOutcome::NonFiniteResult);
        }
        self.x = x;
        self.p = p;
        self.factor = factor;
        self.sigmas_f_fresh = false;
        Ok((gain, s))
    }

    /// The covariance form's correction (module docs, "Measurement
    /// update"): FilterPy's `S`, `P_xz` and gain, and the Joseph-type
    /// `P = Σᵢ Wᵢᶜ eᵢ eᵢᵀ + K R Kᵀ (+ Q)`, `eᵢ = r(σfᵢ, x⁻) − K dzᵢ`.
    fn correct_covariance<const K: usize>(
        &self,
        sigmas_f: &SMatrix<f32, N, S>,
        reused: bool,
        dz: &SMatrix<f32, K, S>,
        innovation: &SVector<f32, K>,
        r: &SMatrix<f32, K, K>,
    ) -> Corrected<N, K> {
        let mut s = *r;
        let mut cross = SMatrix::<f32, N, K>::zeros();
        let mut dx = SMatrix::<f32, N, S>::zeros();
        for (((sigma_f, d), &w), dx) in sigmas_f
            .data
            .0
            .iter()
            .zip(dz.data.0.iter())
            .zip(self.points.covariance_weights().iter())
            .zip(dx.data.0.iter_mut())
        {
            let d = SVector::<f32, K>::from(*d);
            let residual = self
                .model
                .angles()
                .state_residual(&SVector::from(*sigma_f), &self.x);
            s += d * d.transpose() * w;
            cross += residual * d.transpose() * w;
            let [column] = residual.data.0;
            *dx = column;
        }
        if !(all_finite(&s) && all_finite(&cross)) {
            return Err(StepOutcome::NonFiniteResult);
        }
        let gain = kalman_gain(&cross, &s).ok_or(StepOutcome::SingularInnovation)?;
        let x = self.x + gain * innovation;
        let mut p = gain * r * gain.transpose();
        if reused {
            p += self.q;
        }
        let deviations = dx - gain * dz;
        for (e, &w) in deviations
            .data
            .0
            .iter()
            .zip(self.points.covariance_weights().iter())
        {
            let e = SVector::<f32, N>::from(*e);
            p += e * e.transpose() * w;
        }
        Ok((x, symmetrize(&p), self.factor, gain, s))
    }
}
