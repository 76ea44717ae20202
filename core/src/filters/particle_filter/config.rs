//! The noise levels and thresholds of a [`ParticleFilter`]
//! ([`ParticleFilterConfig`]), each validated when it is set, and why a
//! configuration or a filter is refused ([`ParticleFilterError`]).
//!
//! [`ParticleFilter`]: super::ParticleFilter

use nalgebra::SVector;

use super::Proposal;
use super::vector::non_negative;

/// Default resampling threshold as a fraction of `P`: resample when the
/// effective sample size falls below `P/2`.
pub const DEFAULT_RESAMPLE_FRACTION: f32 = 0.5;

/// Default collapse gate on the squared normalised distance
/// `Σ_j (r_j/σ_r,j)²` of the measurement to the *closest* particle:
/// `−2 ln(f32::MIN_POSITIVE) ≈ 174.67`, where `exp(−d²/2)` (the paper's
/// linear-space likelihood) underflows `f32`'s normal range for every
/// particle (module docs).
pub const DEFAULT_COLLAPSE_GATE: f32 = 174.673_1;

/// Why a [`ParticleFilterConfig`] or a [`ParticleFilter`] was refused.
///
/// [`ParticleFilter`]: super::ParticleFilter
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum ParticleFilterError {
    /// A process-noise standard deviation is negative or not finite.
    ProcessStd,
    /// A measurement-noise standard deviation is not finite and positive
    /// (or so small that its inverse overflows).
    MeasurementStd,
    /// The resampling threshold is not a fraction in [0, 1].
    ResampleThreshold,
    /// A recovery standard deviation is negative or not finite.
    RecoveryStd,
    /// The collapse gate is NaN or not positive.
    CollapseGate,
    /// The regularization bandwidth scale is not in [0, 1/h_opt] (finite,
    /// `≥ 0`, and the kernel's bandwidth `h` at most 1).
    Regularization,
    /// The prior mean is not finite.
    PriorMean,
    /// A prior standard deviation is negative or not finite.
    PriorStd,
    /// `P = 0`: a filter needs at least one particle.
    NoParticles,
    /// [`Proposal::Optimal`] for a model that does not measure its state
    /// ([`ParticleModel::measures_state`], `M = N`).
    ///
    /// [`ParticleModel::measures_state`]: super::ParticleModel::measures_state
    Proposal,
    /// A model with modes ([`ParticleModel::MODES`] > 0) in a filter whose
    /// mode slots `K` are not `P`, or with [`Proposal::Optimal`] (whose
    /// closed-form draw knows `σ_q` only).
    ///
    /// [`ParticleModel::MODES`]: super::ParticleModel::MODES
    Modes,
}

impl core::fmt::Display for ParticleFilterError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::ProcessStd => "each process-noise standard deviation must be finite and ≥ 0",
            Self::MeasurementStd => "each measurement-noise standard deviation must be finite and > 0 (and its inverse finite)",
            Self::ResampleThreshold => "the resampling threshold must be a fraction in [0, 1]",
            Self::RecoveryStd => "each recovery standard deviation must be finite and ≥ 0",
            Self::CollapseGate => "the collapse gate must be > 0 (not NaN)",
            Self::Regularization => "the regularization bandwidth scale must be finite and ≥ 0, and the kernel bandwidth h at most 1",
            Self::PriorMean => "the prior mean must be finite",
            Self::PriorStd => "each prior standard deviation must be finite and ≥ 0",
            Self::NoParticles => "the particle count P must be ≥ 1",
            Self::Proposal => "the optimal proposal needs a model whose measurement is its state (ParticleModel::measures_state, M = N)",
            Self::Modes => "a model with modes (ParticleModel::MODES > 0) needs K = P mode slots and the prior proposal",
        })
    }
}

impl core::error::Error for ParticleFilterError {}

/// Validated noise levels and thresholds of a [`ParticleFilter`] with `N`
/// states and `M` measurements.
///
/// [`ParticleFilter`]: super::ParticleFilter
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParticleFilterConfig<const N: usize, const M: usize> {
    pub(super) process_std: SVector<f32, N>,
    pub(super) measurement_std: SVector<f32, M>,
    pub(super) inverse_measurement_std: SVector<f32, M>,
    pub(super) resample_fraction: f32,
    pub(super) recovery_std: Option<SVector<f32, N>>,
    pub(super) collapse_gate: f32,
    pub(super) regularization: f32,
    pub(super) roughening: f32,
    pub(super) proposal: Proposal,
}

impl<const N: usize, const M: usize> ParticleFilterConfig<N, M> {
    /// The process noise `σ_q` (per component, per *step*, in the state's
    /// units: the paper's discrete `Q = diag(σ_q²)`; scale it yourself if
    /// the step varies) and the measurement noise `σ_r` (per component, in
    /// the measurement's units: `R = diag(σ_r²)`). A zero `σ_q` leaves that
    /// component without noise. Resampling below `P/2`, the prior's spread
    /// for recovery and the default collapse gate until changed.
    ///
    /// # Errors
    /// [`ParticleFilterError::ProcessStd`] for a negative or non-finite
    /// `σ_q`, [`ParticleFilterError::MeasurementStd`] for a `σ_r` that is
    /// not finite and positive.
    pub fn new(
        process_std: SVector<f32, N>,
        measurement_std: SVector<f32, M>,
    ) -> Result<Self, ParticleFilterError> {
        if !non_negative(&process_std) {
            return Err(ParticleFilterError::ProcessStd);
        }
        let inverse_measurement_std = measurement_std.map(|s| 1.0 / s);
        let positive = measurement_std.iter().all(|&s| s.is_finite() && s > 0.0)
            && inverse_measurement_std.iter().all(|s| s.is_finite());
        if !positive {
            return Err(ParticleFilterError::MeasurementStd);
        }
        Ok(Self {
            process_std,
            measurement_std,
            inverse_measurement_std,
            resample_fraction: DEFAULT_RESAMPLE_FRACTION,
            recovery_std: None,
            collapse_gate: DEFAULT_COLLAPSE_GATE,
            regularization: 0.0,
            roughening: 0.0,
            proposal: Proposal::Prior,
        })
    }

    /// Resample when the effective sample size `1/Σw̃²` drops below
    /// `fraction·P` (default ½; 1: at nearly every update, as in the paper;
    /// 0: never).
    ///
    /// # Errors
    /// [`ParticleFilterError::ResampleThreshold`] unless `fraction` is in
    /// [0, 1].
    pub fn with_resample_threshold(self, fraction: f32) -> Result<Self, ParticleFilterError> {
        if !(0.0..=1.0).contains(&fraction) {
            return Err(ParticleFilterError::ResampleThreshold);
        }
        Ok(Self {
            resample_fraction: fraction,
            ..self
        })
    }

    /// The spread (per component, state units) the particles are redrawn
    /// with around the estimate after a collapse (default: the prior's).
    ///
    /// # Errors
    /// [`ParticleFilterError::RecoveryStd`] for a negative or non-finite
    /// entry.
    pub fn with_recovery_std(
        self,
        recovery_std: SVector<f32, N>,
    ) -> Result<Self, ParticleFilterError> {
        if !non_negative(&recovery_std) {
            return Err(ParticleFilterError::RecoveryStd);
        }
        Ok(Self {
            recovery_std: Some(recovery_std),
            ..self
        })
    }

    /// The collapse gate on `min_i Σ_j (r_j⁽ⁱ⁾/σ_r,j)²` (dimensionless;
    /// default [`DEFAULT_COLLAPSE_GATE`]); `f32::INFINITY` collapses only
    /// when no particle keeps a weight, so that a far-off measurement pulls
    /// all the weight onto the closest particles instead.
    ///
    /// # Errors
    /// [`ParticleFilterError::CollapseGate`] for NaN or a gate that is not
    /// positive.
    pub fn with_collapse_gate(self, gate: f32) -> Result<Self, ParticleFilterError> {
        if gate.is_nan() || gate <= 0.0 {
            return Err(ParticleFilterError::CollapseGate);
        }
        Ok(Self {
            collapse_gate: gate,
            ..self
        })
    }

    /// Regularizes after every resampling (module docs, "Regularization"):
    /// each resampled particle is shrunk towards the mean and jittered by
    /// a Gaussian kernel of bandwidth `h = scale · h_opt` (Musso, Oudjane &
    /// Le Gland 2001; `h_opt` their optimal bandwidth for `N` states and
    /// `P` particles; shrinkage after Liu & West 2001, so that the cloud's
    /// mean and covariance are kept). `scale = 0` (the default) turns it
    /// off; `1` is the optimal bandwidth for a Gaussian posterior, smaller
    /// values for a multimodal one.
    ///
    /// # Errors
    /// [`ParticleFilterError::Regularization`] for a negative or
    /// non-finite scale; [`ParticleFilter::new`] refuses one whose `h`
    /// exceeds 1 for its `N` and `P`.
    ///
    /// [`ParticleFilter::new`]: super::ParticleFilter::new
    pub fn with_regularization(self, scale: f32) -> Result<Self, ParticleFilterError> {
        if !(scale.is_finite() && scale >= 0.0) {
            return Err(ParticleFilterError::Regularization);
        }
        Ok(Self {
            regularization: scale,
            ..self
        })
    }

    /// Roughening after every resampling (module docs, "Roughening";
    /// Gordon, Salmond & Smith 1993): each component of each particle
    /// jittered by `N(0, (K E_k P^{−1/d})²)`, `E_k` the component's range
    /// over the resampled particles and `d` the number of components with
    /// a non-zero range. `K = 0` (the default) turns it off.
    ///
    /// # Errors
    /// [`ParticleFilterError::Regularization`] for a negative or
    /// non-finite `K`.
    pub fn with_roughening(self, k: f32) -> Result<Self, ParticleFilterError> {
        if !(k.is_finite() && k >= 0.0) {
            return Err(ParticleFilterError::Regularization);
        }
        Ok(Self {
            roughening: k,
            ..self
        })
    }

    /// The roughening constant `K` (0: off).
    #[must_use]
    pub fn roughening(&self) -> f32 {
        self.roughening
    }

    /// Draws the particles from `proposal` (default [`Proposal::Prior`];
    /// module docs, "The optimal proposal"). [`ParticleFilter::new`]
    /// refuses [`Proposal::Optimal`] for a model that does not measure its
    /// state.
    ///
    /// [`ParticleFilter::new`]: super::ParticleFilter::new
    #[must_use]
    pub fn with_proposal(self, proposal: Proposal) -> Self {
        Self { proposal, ..self }
    }

    /// How the particles are drawn.
    #[must_use]
    pub fn proposal(&self) -> Proposal {
        self.proposal
    }

    /// The regularization bandwidth as a multiple of the optimal one (0:
    /// off).
    #[must_use]
    pub fn regularization(&self) -> f32 {
        self.regularization
    }

    /// `σ_q`, per component and step, state units.
    #[must_use]
    pub fn process_std(&self) -> &SVector<f32, N> {
        &self.process_std
    }

    /// `σ_r`, per component, measurement units.
    #[must_use]
    pub fn measurement_std(&self) -> &SVector<f32, M> {
        &self.measurement_std
    }

    /// The resampling threshold as a fraction of `P`.
    #[must_use]
    pub fn resample_fraction(&self) -> f32 {
        self.resample_fraction
    }

    /// The configured recovery spread (`None`: the prior's).
    #[must_use]
    pub fn recovery_std(&self) -> Option<&SVector<f32, N>> {
        self.recovery_std.as_ref()
    }

    /// The collapse gate (squared normalised distance).
    #[must_use]
    pub fn collapse_gate(&self) -> f32 {
        self.collapse_gate
    }
}
