//! Generic state estimators, sized by const generics, that know nothing of
//! robots: the extended Kalman filter ([`ekf`]), the unscented Kalman filter
//! ([`ukf`]) and the particle filter ([`particle_filter`]) of paper 004.
//!
//! A model implements the filter's trait (transition, measurement and, for
//! the Gaussian filters, Jacobians or angle hooks); the robot's estimators in
//! [`crate::estimation`] are such models.

pub mod ekf;
pub mod particle_filter;
pub mod ukf;

/// What a filter's predict or update did: the one outcome type of the
/// [`ekf::ExtendedKalmanFilter`] and the [`ukf::UnscentedKalmanFilter`]
/// (their module docs, "Bad input"). The EKF never repairs or resets, so
/// it returns neither [`Self::Repaired`] nor [`Self::CovarianceReset`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum StepOutcome {
    /// The step was applied.
    Applied,
    /// The step was applied after `(λ + n)P` was symmetrised and jittered
    /// to factor.
    Repaired,
    /// Skipped: non-finite input, step, measurement or per-call noise.
    RejectedInput,
    /// Skipped: `(λ + n)P` did not factor even jittered; `P` was reset to
    /// the initial covariance, `x` kept.
    CovarianceReset,
    /// Skipped: the innovation covariance `S` is not invertible.
    SingularInnovation,
    /// Skipped: the result was not finite; the estimate is unchanged.
    NonFiniteResult,
}

impl StepOutcome {
    /// Whether the step changed the estimate as the filter equations say
    /// ([`Self::Applied`] or [`Self::Repaired`]).
    #[must_use]
    pub fn is_applied(self) -> bool {
        matches!(self, Self::Applied | Self::Repaired)
    }
}
