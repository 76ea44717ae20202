//! The filter of the module docs of [`super`].

use nalgebra::{SMatrix, SVector};

use super::factor::{outer, semidefinite_factor};
use super::sigma_points::{lower_factor, points_from_factor};
use super::{
    COVARIANCE_JITTER, MerweScaledSigmaPoints, StepOutcome, UkfCounters, UkfError, UkfForm,
    UkfModel, bump,
};

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

/// Finite, symmetric to `f32` rounding and positive semi-definite (it
/// factors once its diagonal is raised by 1e-6 of its largest entry).
pub(super) fn is_noise_covariance<const K: usize>(a: &SMatrix<f32, K, K>) -> bool {
    let scale = a.amax();
    all_finite(a)
        && (a - a.transpose()).amax() <= 1e-6 * scale
        && lower_factor(
            &(a + SMatrix::<f32, K, K>::identity() * (1e-6 * scale).max(f32::MIN_POSITIVE)),
        )
        .is_some()
}

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

/// The unscented Kalman filter of the module docs for a model with `N`
/// states and `M` measurements; `S` must be `2N + 1` (checked by
/// [`MerweScaledSigmaPoints::new`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UnscentedKalmanFilter<Model, const N: usize, const M: usize, const S: usize>
where
    Model: UkfModel<N, M>,
{
    pub(super) model: Model,
    pub(super) points: MerweScaledSigmaPoints<N, S>,
    pub(super) x: SVector<f32, N>,
    pub(super) p: SMatrix<f32, N, N>,
    pub(super) initial_covariance: SMatrix<f32, N, N>,
    pub(super) q: SMatrix<f32, N, N>,
    pub(super) r: SMatrix<f32, M, M>,
    /// FilterPy's `sigmas_f`: the last predict's propagated points.
    pub(super) sigmas_f: SMatrix<f32, N, S>,
    /// `sigmas_f` belong to the current `(x, P)` (a predict, and no update
    /// or reset, since).
    pub(super) sigmas_f_fresh: bool,
    /// Draw the update's points from `(x⁻, P⁻)` rather than reuse `σf`.
    pub(super) redraw_for_update: bool,
    pub(super) innovation: SVector<f32, M>,
    pub(super) innovation_covariance: SMatrix<f32, M, M>,
    pub(super) gain: SMatrix<f32, N, M>,
    pub(super) counters: UkfCounters,
    /// Which covariance is propagated.
    pub(super) form: UkfForm,
    /// The square-root form's lower factor `L` of `P` (`P = L Lᵀ`); zero
    /// in the covariance form.
    pub(super) factor: SMatrix<f32, N, N>,
    /// `√Q` (lower, [`semidefinite_factor`]); zero in the covariance form.
    pub(super) q_factor: SMatrix<f32, N, N>,
    /// `√R`; zero in the covariance form.
    pub(super) r_factor: SMatrix<f32, M, M>,
}

impl<Model, const N: usize, const M: usize, const S: usize> UnscentedKalmanFilter<Model, N, M, S>
where
    Model: UkfModel<N, M>,
{
    /// A filter at `x0` with covariance `p0` (also the covariance a failed
    /// factorisation resets to), process noise `q` (added once per
    /// predict, whatever `dt`, as in FilterPy) and measurement noise `r`.
    ///
    /// # Errors
    /// [`UkfError::InitialState`], [`UkfError::InitialCovariance`] (not
    /// finite, symmetric and positive definite), [`UkfError::ProcessNoise`]
    /// or [`UkfError::MeasurementNoise`] (not finite, symmetric and
    /// positive semi-definite).
    pub fn new(
        model: Model,
        points: MerweScaledSigmaPoints<N, S>,
        x0: SVector<f32, N>,
        p0: SMatrix<f32, N, N>,
        q: SMatrix<f32, N, N>,
        r: SMatrix<f32, M, M>,
    ) -> Result<Self, UkfError> {
        if !all_finite(&x0) {
            return Err(UkfError::InitialState);
        }
        if !(is_noise_covariance(&p0) && lower_factor(&p0).is_some()) {
            return Err(UkfError::InitialCovariance);
        }
        if !is_noise_covariance(&q) {
            return Err(UkfError::ProcessNoise);
        }
        if !is_noise_covariance(&r) {
            return Err(UkfError::MeasurementNoise);
        }
        let p0 = symmetrize(&p0);
        Ok(Self {
            model,
            points,
            x: x0,
            p: p0,
            initial_covariance: p0,
            q: symmetrize(&q),
            r: symmetrize(&r),
            sigmas_f: SMatrix::zeros(),
            sigmas_f_fresh: false,
            redraw_for_update: false,
            innovation: SVector::zeros(),
            innovation_covariance: SMatrix::zeros(),
            gain: SMatrix::zeros(),
            counters: UkfCounters::default(),
            form: UkfForm::Covariance,
            factor: SMatrix::zeros(),
            // Only the square-root form uses them (`with_form`).
            q_factor: SMatrix::zeros(),
            r_factor: SMatrix::zeros(),
        })
    }

    /// The filter in `form` ([`UkfForm`]; a new filter is in the
    /// covariance form).
    ///
    /// # Errors
    /// [`UkfError::SquareRootBeta`]: the square-root form needs `β ≥ α²`
    /// (module docs, "Square-root form"); the filter is not built.
    pub fn with_form(self, form: UkfForm) -> Result<Self, UkfError> {
        let (factor, q_factor, r_factor) = match form {
            UkfForm::Covariance => (SMatrix::zeros(), SMatrix::zeros(), SMatrix::zeros()),
            UkfForm::SquareRoot => {
                if self.points.centre_term().is_none() {
                    return Err(UkfError::SquareRootBeta);
                }
                (
                    lower_factor(&self.p).ok_or(UkfError::InitialCovariance)?,
                    semidefinite_factor(&self.q),
                    semidefinite_factor(&self.r),
                )
            }
        };
        Ok(Self {
            form,
            factor,
            q_factor,
            r_factor,
            ..self
        })
    }

    /// The form the filter propagates.
    #[must_use]
    pub fn form(&self) -> UkfForm {
        self.form
    }

    /// Updates draw their sigma points from the prior `(x⁻, P⁻)`, which
    /// includes `Q`, instead of reusing the last predict's `σf` (module
    /// docs, "Measurement update": FilterPy after 1.4.5).
    #[must_use]
    pub fn with_redrawn_update_points(self) -> Self {
        Self {
            redraw_for_update: true,
            ..self
        }
    }

    /// The model.
    #[must_use]
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The sigma points' parameters and weights.
    #[must_use]
    pub fn sigma_point_weights(&self) -> &MerweScaledSigmaPoints<N, S> {
        &self.points
    }

    /// The state estimate `x` (the prior `x⁻` after a predict, the
    /// posterior after an update).
    #[must_use]
    pub fn state(&self) -> &SVector<f32, N> {
        &self.x
    }

    /// Its covariance `P`.
    #[must_use]
    pub fn covariance(&self) -> &SMatrix<f32, N, N> {
        &self.p
    }

    /// The initial covariance, which a failed factorisation resets `P` to.
    #[must_use]
    pub fn initial_covariance(&self) -> &SMatrix<f32, N, N> {
        &self.initial_covariance
    }

    /// The process noise `Q`.
    #[must_use]
    pub fn process_noise(&self) -> &SMatrix<f32, N, N> {
        &self.q
    }

    /// The measurement noise `R`.
    #[must_use]
    pub fn measurement_noise(&self) -> &SMatrix<f32, M, M> {
        &self.r
    }

    /// The innovation `ỹ = rz(y, ŷ)` of the last applied update (zeros
    /// before the first).
    #[must_use]
    pub fn innovation(&self) -> &SVector<f32, M> {
        &self.innovation
    }

    /// Its covariance `S = Pyy` (with `R`) of the last applied update.
    #[must_use]
    pub fn innovation_covariance(&self) -> &SMatrix<f32, M, M> {
        &self.innovation_covariance
    }

    /// The gain `K` of the last applied update.
    #[must_use]
    pub fn gain(&self) -> &SMatrix<f32, N, M> {
        &self.gain
    }

    /// The propagated sigma points `σf` (columns) of the last predict, if
    /// the next update will use them (no update or reset since).
    #[must_use]
    pub fn propagated_sigma_points(&self) -> Option<&SMatrix<f32, N, S>> {
        self.sigmas_f_fresh.then_some(&self.sigmas_f)
    }

    /// What was skipped or repaired so far.
    #[must_use]
    pub fn counters(&self) -> UkfCounters {
        self.counters
    }

    /// Sets `Q`.
    ///
    /// # Errors
    /// [`UkfError::ProcessNoise`] (not finite, symmetric and positive
    /// semi-definite); `Q` is unchanged.
    pub fn set_process_noise(&mut self, q: SMatrix<f32, N, N>) -> Result<(), UkfError> {
        if !is_noise_covariance(&q) {
            return Err(UkfError::ProcessNoise);
        }
        self.q = symmetrize(&q);
        // The covariance form never reads √Q: a 5×5 factor per step would
        // be 15 % of the fusion UKF's predict.
        if self.form == UkfForm::SquareRoot {
            self.q_factor = semidefinite_factor(&self.q);
        }
        Ok(())
    }

    /// Sets `R`.
    ///
    /// # Errors
    /// [`UkfError::MeasurementNoise`] (not finite, symmetric and positive
    /// semi-definite); `R` is unchanged.
    pub fn set_measurement_noise(&mut self, r: SMatrix<f32, M, M>) -> Result<(), UkfError> {
        if !is_noise_covariance(&r) {
            return Err(UkfError::MeasurementNoise);
        }
        self.r = symmetrize(&r);
        if self.form == UkfForm::SquareRoot {
            self.r_factor = semidefinite_factor(&self.r);
        }
        Ok(())
    }

    /// Restarts from `x` with covariance `p` (the counters and the initial
    /// covariance are kept; the next update draws its points from here).
    ///
    /// # Errors
    /// [`UkfError::InitialState`] or [`UkfError::InitialCovariance`]; the
    /// filter is unchanged.
    pub fn reset(&mut self, x: SVector<f32, N>, p: SMatrix<f32, N, N>) -> Result<(), UkfError> {
        if !all_finite(&x) {
            return Err(UkfError::InitialState);
        }
        let p = symmetrize(&p);
        let Some(factor) = lower_factor(&p).filter(|_| is_noise_covariance(&p)) else {
            return Err(UkfError::InitialCovariance);
        };
        self.x = x;
        self.p = p;
        if self.form == UkfForm::SquareRoot {
            self.factor = factor;
        }
        self.sigmas_f_fresh = false;
        Ok(())
    }

    /// The sigma points of the current `(x, P)`, with the repair and reset
    /// of the module docs: `Ok((points, repaired))`, or `Err` after a reset.
    fn draw_sigma_points(&mut self) -> Result<(SMatrix<f32, N, S>, bool), StepOutcome> {
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
        // swamped by the largest.
        let mut jittered = scaled;
        for v in jittered.iter_mut().step_by(N + 1).take(N) {
            *v += (COVARIANCE_JITTER * v.abs()).max(f32::MIN_POSITIVE);
        }
        if let Some(l) = lower_factor(&jittered) {
            bump(&mut self.counters.covariance_repairs);
            return Ok((points_from_factor(&self.x, &l), true));
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
        let x = self
            .model
            .angles()
            .state_mean(&sigmas_f, &self.points.mean_weights());
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

    /// The measurement update with `z` and the filter's `R`: FilterPy's
    /// `update(z)` (module docs), on the last predict's `σf`.
    pub fn update(&mut self, z: &SVector<f32, M>) -> StepOutcome {
        let (r, r_factor) = (self.r, self.r_factor);
        self.update_with(z, &r, Some(&r_factor))
    }

    /// The measurement update with `z` and, for this call only, the
    /// measurement noise `r` (FilterPy's `update(z, R)`; an `r` that is not
    /// finite, symmetric and positive semi-definite rejects the update).
    pub fn update_with_noise(
        &mut self,
        z: &SVector<f32, M>,
        r: &SMatrix<f32, M, M>,
    ) -> StepOutcome {
        if !is_noise_covariance(r) {
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
    /// is not finite and ≥ 0, rejects the update.
    pub fn update_component(&mut self, index: usize, z: f32, r: f32) -> StepOutcome {
        if !(index < M && z.is_finite() && r.is_finite() && r >= 0.0) {
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
