//! A generic extended Kalman filter (paper 004, Iossaqui, Camino &
//! Zampieri, "The EKF algorithm"): `N` states, `M` measurements, additive
//! noise (`B = D = I` in the paper's notation).
//!
//! ```text
//! predict:  x⁻ = f(x, u, h)            P⁻ = A P Aᵀ + Q,   A = ∂f/∂x at x
//! update:   S = C P⁻ Cᵀ + R            K = P⁻ Cᵀ S⁻¹,     C = ∂h/∂x at x⁻
//!           x = x⁻ + K ỹ,  ỹ = residual(y, h(x⁻))
//!           P = (I − K C) P⁻ (I − K C)ᵀ + K R Kᵀ          (Joseph form)
//! ```
//!
//! The paper prints `P = (I − KC)P⁻`; the Joseph form is algebraically the
//! same for the optimal gain and keeps `P` symmetric positive semi-definite
//! under `f32` rounding. `P` is symmetrised after every step.
//!
//! Angles: the model's [`EkfModel::measurement_residual`] wraps angle
//! components of the innovation and [`EkfModel::normalize`] wraps the state's
//! (both identity by default).
//!
//! # Bad input
//! Each of these skips the step, keeps the previous estimate, is counted
//! ([`EkfCounters`]) and is reported by the returned [`StepOutcome`], the
//! outcome type the UKF returns too:
//! * a non-finite or negative step `dt`, a non-finite measurement, or a
//!   per-call `R` ([`ExtendedKalmanFilter::update_with_noise`]) that is
//!   not finite, symmetric and positive definite:
//!   [`StepOutcome::RejectedInput`];
//! * an innovation covariance `S` that does not factor (not positive
//!   definite): [`StepOutcome::SingularInnovation`];
//! * a non-finite result: [`StepOutcome::NonFiniteResult`].
//!
//! `Q` and `R` can be replaced between steps
//! ([`ExtendedKalmanFilter::set_process_noise`],
//! [`ExtendedKalmanFilter::set_measurement_noise`]), checked as at
//! construction.

use nalgebra::{SMatrix, SVector};

pub use super::StepOutcome;

/// A system for the [`ExtendedKalmanFilter`].
pub trait EkfModel<const N: usize, const M: usize> {
    /// The input `u`.
    type Input: Copy;
    /// `f(x, u, h)`: the state after a step of `dt_s`.
    fn transition(&self, x: &SVector<f32, N>, u: &Self::Input, dt_s: f32) -> SVector<f32, N>;
    /// `A = ∂f/∂x` at `x`.
    fn transition_jacobian(
        &self,
        x: &SVector<f32, N>,
        u: &Self::Input,
        dt_s: f32,
    ) -> SMatrix<f32, N, N>;
    /// `(f(x, u, h), ∂f/∂x)` together, as the predict needs both (default:
    /// the two calls). Override it when they share work, e.g. the sine and
    /// cosine of a heading, which with `libm` cost a Cortex-M4 about 1,300
    /// instructions each.
    fn transition_with_jacobian(
        &self,
        x: &SVector<f32, N>,
        u: &Self::Input,
        dt_s: f32,
    ) -> (SVector<f32, N>, SMatrix<f32, N, N>) {
        (
            self.transition(x, u, dt_s),
            self.transition_jacobian(x, u, dt_s),
        )
    }
    /// `h(x)`: the expected measurement.
    fn measure(&self, x: &SVector<f32, N>) -> SVector<f32, M>;
    /// `C = ∂h/∂x` at `x`.
    fn measurement_jacobian(&self, x: &SVector<f32, N>) -> SMatrix<f32, M, N>;
    /// `z − ẑ`, with angle components wrapped (default: plain difference).
    fn measurement_residual(
        &self,
        z: &SVector<f32, M>,
        expected: &SVector<f32, M>,
    ) -> SVector<f32, M> {
        z - expected
    }
    /// Wraps the angle components of a state (default: unchanged).
    fn normalize(&self, x: SVector<f32, N>) -> SVector<f32, N> {
        x
    }
}

/// Why an [`ExtendedKalmanFilter`] was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum FilterConfigError {
    /// The initial covariance `P0` is not finite, symmetric and positive
    /// definite.
    InitialCovariance,
    /// The process noise `Q` is not finite, symmetric and positive
    /// semi-definite.
    ProcessNoise,
    /// The measurement noise `R` is not finite, symmetric and positive
    /// definite.
    MeasurementNoise,
    /// The initial state is not finite.
    InitialState,
}

impl core::fmt::Display for FilterConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::InitialCovariance => {
                "the initial covariance P0 must be finite, symmetric and positive definite"
            }
            Self::ProcessNoise => {
                "the process noise Q must be finite, symmetric and positive semi-definite"
            }
            Self::MeasurementNoise => {
                "the measurement noise R must be finite, symmetric and positive definite"
            }
            Self::InitialState => "the initial state must be finite",
        })
    }
}

impl core::error::Error for FilterConfigError {}

/// What the filter skipped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct EkfCounters {
    /// Predictions skipped for a bad step `dt` or a non-finite result.
    pub rejected_predictions: u32,
    /// Updates skipped for a non-finite measurement, a bad per-call `R` or
    /// a non-finite result.
    pub rejected_updates: u32,
    /// Updates skipped because `S` was not positive definite.
    pub singular_innovations: u32,
}

/// The filter's state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExtendedKalmanFilter<Model, const N: usize, const M: usize>
where
    Model: EkfModel<N, M>,
{
    model: Model,
    x: SVector<f32, N>,
    p: SMatrix<f32, N, N>,
    q: SMatrix<f32, N, N>,
    r: SMatrix<f32, M, M>,
    counters: EkfCounters,
}

/// `true` if `a` is finite and symmetric to `f32` rounding.
fn symmetric<const K: usize>(a: &SMatrix<f32, K, K>) -> bool {
    a.iter().all(|x| x.is_finite()) && (a - a.transpose()).amax() <= 1e-6 * a.amax().max(1e-30)
}

/// Finite, symmetric and positive definite.
fn definite<const K: usize>(a: &SMatrix<f32, K, K>) -> bool {
    symmetric(a) && a.cholesky().is_some()
}

/// Finite, symmetric and positive semi-definite (it factors once its
/// diagonal is raised by 1e-6 of its largest entry).
fn semidefinite<const K: usize>(a: &SMatrix<f32, K, K>) -> bool {
    symmetric(a)
        && (a + SMatrix::<f32, K, K>::identity() * (1e-6 * a.amax().max(1e-30)))
            .cholesky()
            .is_some()
}

fn bump(counter: &mut u32) {
    *counter = counter.saturating_add(1);
}

impl<Model, const N: usize, const M: usize> ExtendedKalmanFilter<Model, N, M>
where
    Model: EkfModel<N, M>,
{
    /// A filter at `x0` with covariance `p0`, process noise `q` (per step)
    /// and measurement noise `r`.
    ///
    /// # Errors
    /// [`FilterConfigError`]: a non-finite `x0`, or the first covariance
    /// (`P0`, `Q`, `R`) that is not symmetric positive (semi-)definite.
    pub fn new(
        model: Model,
        x0: SVector<f32, N>,
        p0: SMatrix<f32, N, N>,
        q: SMatrix<f32, N, N>,
        r: SMatrix<f32, M, M>,
    ) -> Result<Self, FilterConfigError> {
        if !x0.iter().all(|x| x.is_finite()) {
            return Err(FilterConfigError::InitialState);
        }
        if !definite(&p0) {
            return Err(FilterConfigError::InitialCovariance);
        }
        if !semidefinite(&q) {
            return Err(FilterConfigError::ProcessNoise);
        }
        if !definite(&r) {
            return Err(FilterConfigError::MeasurementNoise);
        }
        Ok(Self {
            x: model.normalize(x0),
            model,
            p: p0,
            q,
            r,
            counters: EkfCounters::default(),
        })
    }

    /// The estimate.
    #[must_use]
    pub fn state(&self) -> &SVector<f32, N> {
        &self.x
    }

    /// Its covariance.
    #[must_use]
    pub fn covariance(&self) -> &SMatrix<f32, N, N> {
        &self.p
    }

    /// What was skipped.
    #[must_use]
    pub fn counters(&self) -> EkfCounters {
        self.counters
    }

    /// The model.
    #[must_use]
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The process noise `Q` (per step).
    #[must_use]
    pub fn process_noise(&self) -> &SMatrix<f32, N, N> {
        &self.q
    }

    /// The measurement noise `R`.
    #[must_use]
    pub fn measurement_noise(&self) -> &SMatrix<f32, M, M> {
        &self.r
    }

    /// Sets `Q`.
    ///
    /// # Errors
    /// [`FilterConfigError::ProcessNoise`] (not finite, symmetric and
    /// positive semi-definite); `Q` is unchanged.
    pub fn set_process_noise(&mut self, q: SMatrix<f32, N, N>) -> Result<(), FilterConfigError> {
        if !semidefinite(&q) {
            return Err(FilterConfigError::ProcessNoise);
        }
        self.q = q;
        Ok(())
    }

    /// Sets `R`.
    ///
    /// # Errors
    /// [`FilterConfigError::MeasurementNoise`] (not finite, symmetric and
    /// positive definite); `R` is unchanged.
    pub fn set_measurement_noise(
        &mut self,
        r: SMatrix<f32, M, M>,
    ) -> Result<(), FilterConfigError> {
        if !definite(&r) {
            return Err(FilterConfigError::MeasurementNoise);
        }
        self.r = r;
        Ok(())
    }

    /// Time update over `dt_s` (finite, ≥ 0) with input `u` (module docs,
    /// "Bad input").
    pub fn predict(&mut self, u: &Model::Input, dt_s: f32) -> StepOutcome {
        if !(dt_s.is_finite() && dt_s >= 0.0) {
            bump(&mut self.counters.rejected_predictions);
            return StepOutcome::RejectedInput;
        }
        let (x, a) = self.model.transition_with_jacobian(&self.x, u, dt_s);
        let x = self.model.normalize(x);
        let p = a * self.p * a.transpose() + self.q;
        if x.iter().all(|v| v.is_finite()) && p.iter().all(|v| v.is_finite()) {
            self.x = x;
            self.p = (p + p.transpose()) * 0.5;
            StepOutcome::Applied
        } else {
            bump(&mut self.counters.rejected_predictions);
            StepOutcome::NonFiniteResult
        }
    }

    /// Measurement update with `z` and the filter's `R`.
    pub fn update(&mut self, z: &SVector<f32, M>) -> StepOutcome {
        let r = self.r;
        self.update_with(z, &r)
    }

    /// Measurement update with `z` and, for this call only, the
    /// measurement noise `r` (rejected unless finite, symmetric and
    /// positive definite).
    pub fn update_with_noise(
        &mut self,
        z: &SVector<f32, M>,
        r: &SMatrix<f32, M, M>,
    ) -> StepOutcome {
        if !definite(r) {
            bump(&mut self.counters.rejected_updates);
            return StepOutcome::RejectedInput;
        }
        self.update_with(z, r)
    }

    fn update_with(&mut self, z: &SVector<f32, M>, r: &SMatrix<f32, M, M>) -> StepOutcome {
        if !z.iter().all(|v| v.is_finite()) {
            bump(&mut self.counters.rejected_updates);
            return StepOutcome::RejectedInput;
        }
        let c = self.model.measurement_jacobian(&self.x);
        let innovation = self
            .model
            .measurement_residual(z, &self.model.measure(&self.x));
        let s = c * self.p * c.transpose() + r;
        let Some(s_chol) = s.cholesky() else {
            bump(&mut self.counters.singular_innovations);
            return StepOutcome::SingularInnovation;
        };
        // K = P Cᵀ S⁻¹, i.e. Kᵀ = S⁻¹ C P (S symmetric).
        let gain = s_chol.solve(&(c * self.p)).transpose();
        let x = self.model.normalize(self.x + gain * innovation);
        let i_kc = SMatrix::<f32, N, N>::identity() - gain * c;
        let p = i_kc * self.p * i_kc.transpose() + gain * r * gain.transpose();
        if x.iter().all(|v| v.is_finite()) && p.iter().all(|v| v.is_finite()) {
            self.x = x;
            self.p = (p + p.transpose()) * 0.5;
            StepOutcome::Applied
        } else {
            bump(&mut self.counters.rejected_updates);
            StepOutcome::NonFiniteResult
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A constant-velocity cart, position measured.
    #[derive(Debug, Clone, Copy)]
    struct Cart;

    impl EkfModel<2, 1> for Cart {
        type Input = ();
        fn transition(&self, x: &SVector<f32, 2>, _u: &(), dt: f32) -> SVector<f32, 2> {
            SVector::<f32, 2>::new(x.x + dt * x.y, x.y)
        }
        fn transition_jacobian(
            &self,
            _x: &SVector<f32, 2>,
            _u: &(),
            dt: f32,
        ) -> SMatrix<f32, 2, 2> {
            SMatrix::<f32, 2, 2>::new(1.0, dt, 0.0, 1.0)
        }
        fn measure(&self, x: &SVector<f32, 2>) -> SVector<f32, 1> {
            SVector::<f32, 1>::new(x.x)
        }
        fn measurement_jacobian(&self, _x: &SVector<f32, 2>) -> SMatrix<f32, 1, 2> {
            SMatrix::<f32, 1, 2>::new(1.0, 0.0)
        }
    }

    fn filter() -> ExtendedKalmanFilter<Cart, 2, 1> {
        ExtendedKalmanFilter::new(
            Cart,
            SVector::zeros(),
            SMatrix::<f32, 2, 2>::identity() * 10.0,
            SMatrix::<f32, 2, 2>::zeros(),
            SMatrix::<f32, 1, 1>::new(0.01),
        )
        .unwrap()
    }

    #[test]
    fn configuration_is_validated() {
        let bad = SMatrix::<f32, 2, 2>::new(1.0, 2.0, 2.0, 1.0);
        let r = SMatrix::<f32, 1, 1>::new(0.01);
        assert_eq!(
            ExtendedKalmanFilter::new(Cart, SVector::zeros(), bad, SMatrix::zeros(), r).err(),
            Some(FilterConfigError::InitialCovariance)
        );
        let nan = SVector::<f32, 2>::new(f32::NAN, 0.0);
        assert_eq!(
            ExtendedKalmanFilter::new(Cart, nan, SMatrix::identity(), SMatrix::zeros(), r).err(),
            Some(FilterConfigError::InitialState)
        );
    }

    /// On a linear system the EKF is the Kalman filter: the velocity of a
    /// cart is found from noiseless positions, and one update from
    /// `P = 10 I` matches the closed form.
    #[test]
    fn linear_system_is_the_kalman_filter() {
        let mut f = filter();
        assert_eq!(f.update(&SVector::<f32, 1>::new(1.0)), StepOutcome::Applied);
        // K = 10 / (10 + 0.01); x = K·1.
        let k = 10.0 / 10.01;
        assert!((f.state().x - k).abs() < 1e-6);
        assert!((f.covariance().m11 - 10.0 * 0.01 / 10.01).abs() < 1e-6);
        let mut f = filter();
        for step in 1..=200u16 {
            assert_eq!(f.predict(&(), 0.1), StepOutcome::Applied);
            let z = SVector::<f32, 1>::new(0.3 * f32::from(step) * 0.1);
            assert_eq!(f.update(&z), StepOutcome::Applied);
        }
        assert!((f.state().y - 0.3).abs() < 1e-3, "{}", f.state());
    }

    #[test]
    fn bad_measurements_are_skipped_and_counted() {
        let mut f = filter();
        let before = *f.state();
        assert_eq!(
            f.update(&SVector::<f32, 1>::new(f32::NAN)),
            StepOutcome::RejectedInput
        );
        assert_eq!(
            f.update_with_noise(
                &SVector::<f32, 1>::new(1.0),
                &SMatrix::<f32, 1, 1>::new(-1.0)
            ),
            StepOutcome::RejectedInput
        );
        assert_eq!(f.predict(&(), f32::NAN), StepOutcome::RejectedInput);
        assert_eq!(f.predict(&(), -0.1), StepOutcome::RejectedInput);
        assert_eq!(f.predict(&(), 1e30), StepOutcome::NonFiniteResult);
        assert_eq!(*f.state(), before);
        assert_eq!(f.counters().rejected_updates, 2);
        assert_eq!(f.counters().rejected_predictions, 3);
        // S = 0: a measurement with no noise and no uncertainty.
        let mut sharp = ExtendedKalmanFilter::new(
            Cart,
            SVector::zeros(),
            SMatrix::<f32, 2, 2>::new(1e-30, 0.0, 0.0, 1.0),
            SMatrix::zeros(),
            SMatrix::<f32, 1, 1>::new(1e-30),
        )
        .unwrap();
        assert!(
            sharp
                .set_measurement_noise(SMatrix::<f32, 1, 1>::new(0.0))
                .is_err()
        );
        let z = SVector::<f32, 1>::new(1.0);
        let zero_p = SMatrix::<f32, 2, 2>::new(0.0, 0.0, 0.0, 1.0);
        sharp.p = zero_p;
        sharp.r = SMatrix::zeros();
        assert_eq!(sharp.update(&z), StepOutcome::SingularInnovation);
        assert_eq!(sharp.counters().singular_innovations, 1);
    }

    /// A per-call `R` is the filter's `R` for that call; `Q` and `R` can be
    /// set, and are checked as at construction.
    #[test]
    fn per_call_and_settable_noise() {
        let z = SVector::<f32, 1>::new(1.0);
        let wide = SMatrix::<f32, 1, 1>::new(4.0);
        let mut a = filter();
        let mut b = filter();
        assert_eq!(a.update_with_noise(&z, &wide), StepOutcome::Applied);
        assert_eq!(b.set_measurement_noise(wide), Ok(()));
        assert_eq!(b.update(&z), StepOutcome::Applied);
        assert_eq!((a.state(), a.covariance()), (b.state(), b.covariance()));
        assert_eq!(*a.measurement_noise(), SMatrix::<f32, 1, 1>::new(0.01));
        let q = SMatrix::<f32, 2, 2>::new(1e-3, 0.0, 0.0, 2e-3);
        assert_eq!(a.set_process_noise(q), Ok(()));
        assert_eq!(*a.process_noise(), q);
        assert_eq!(
            a.set_process_noise(-q),
            Err(FilterConfigError::ProcessNoise)
        );
        assert_eq!(
            a.set_measurement_noise(SMatrix::<f32, 1, 1>::new(f32::NAN)),
            Err(FilterConfigError::MeasurementNoise)
        );
        assert_eq!(*a.process_noise(), q);
        let before = *a.covariance();
        assert_eq!(a.predict(&(), 0.1), StepOutcome::Applied);
        let f = SMatrix::<f32, 2, 2>::new(1.0, 0.1, 0.0, 1.0);
        assert!((a.covariance() - (f * before * f.transpose() + q)).amax() < 1e-5);
    }
}
