//! The filter of the module docs of [`super`]: its state, construction,
//! settings and accessors. Its steps are `predict`'s and `update`'s.

use nalgebra::{SMatrix, SVector};

use super::conditioning::{all_finite, check_covariance, symmetrize};
use super::factor::semidefinite_factor;
use super::sigma_points::lower_factor;
use super::{CovarianceDefect, MerweScaledSigmaPoints, UkfCounters, UkfError, UkfForm, UkfModel};

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
    /// The predict's mean is the centre point's image `f(x)`, and `P⁻`
    /// the points' spread about it ([`Self::with_centre_mean`]).
    pub(super) centre_mean: bool,
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
    /// (not finite, symmetric and positive semi-definite) or
    /// [`UkfError::MeasurementNoise`] (not finite, symmetric and positive
    /// definite), each with the [`CovarianceDefect`] found.
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
        check_covariance(&p0, true).map_err(UkfError::InitialCovariance)?;
        check_covariance(&q, false).map_err(UkfError::ProcessNoise)?;
        check_covariance(&r, true).map_err(UkfError::MeasurementNoise)?;
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
            centre_mean: false,
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
                    lower_factor(&self.p).ok_or(UkfError::InitialCovariance(
                        CovarianceDefect::NotPositiveDefinite,
                    ))?,
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

    /// The predict takes the centre point's image `f(x, u)` as the prior
    /// mean `x⁻` (the extended Kalman filter's mean) instead of the
    /// weighted mean of the propagated points, and `P⁻` as the points'
    /// spread about it, `Σᵢ Wᵢᶜ r(σfᵢ, x⁻) r(σfᵢ, x⁻)ᵀ + Q` (module docs,
    /// "Centre mean"). For a linear model it is the same filter.
    #[must_use]
    pub fn with_centre_mean(self) -> Self {
        Self {
            centre_mean: true,
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
        check_covariance(&q, false).map_err(UkfError::ProcessNoise)?;
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
    /// definite); `R` is unchanged.
    pub fn set_measurement_noise(&mut self, r: SMatrix<f32, M, M>) -> Result<(), UkfError> {
        check_covariance(&r, true).map_err(UkfError::MeasurementNoise)?;
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
        check_covariance(&p, true).map_err(UkfError::InitialCovariance)?;
        let factor = lower_factor(&p).ok_or(UkfError::InitialCovariance(
            CovarianceDefect::NotPositiveDefinite,
        ))?;
        self.x = x;
        self.p = p;
        if self.form == UkfForm::SquareRoot {
            self.factor = factor;
        }
        self.sigmas_f_fresh = false;
        Ok(())
    }
}
