//! The pose filters' parameters, validated once ([`PoseFilterConfig`]), and
//! the gate thresholds they imply (see [`crate::estimation::fusion::gate`]).

use crate::plausible::{READ_RADIUS_M, TAG_SPACING_M, TRACK_WIDTH_M};

/// Why a [`PoseFilterConfig`] was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum PoseFilterError {
    /// Track width outside [`TRACK_WIDTH_M`].
    TrackWidth,
    /// A wheel-noise parameter negative or not finite.
    WheelNoise,
    /// Gate not finite, or below 1 σ.
    Gate,
    /// An initial variance negative or not finite.
    InitialVariance,
    /// The wheel-scale random walk negative or not finite.
    ScaleWalk,
    /// Tag spacing outside [`TAG_SPACING_M`].
    TagSpacing,
    /// Reader range outside [`READ_RADIUS_M`] (and 0 on a tag map).
    ReadRadius,
    /// Blind-distance limit negative or not finite.
    BlindDistance,
    /// The fix's age negative, not finite, or more than
    /// [`crate::estimation::fusion::MAX_FIX_AGE_TICKS`] control periods.
    FixAge,
    /// A floor without a grid (a tag map) with a nearest-tag reader: the
    /// cell measurements need the grid's spacing, so a tag map needs a
    /// range reader (read radius > 0).
    TagMapReader,
    /// A floor without a grid (a tag map) and no blind-distance limit
    /// given: its default is derived from the grid's spacing.
    TagMapBlindDistance,
}

impl core::fmt::Display for PoseFilterError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let s = match self {
            Self::TrackWidth => return write!(f, "track_width_m must be in {TRACK_WIDTH_M} m"),
            Self::WheelNoise => {
                "wheel_variance_per_m must be finite and ≥ 0 m²/m, and so must the count \
                 quantization's variance (from the wheel radius and encoder counts per revolution)"
            }
            Self::Gate => "gate_sigma must be finite and ≥ 1",
            Self::InitialVariance => {
                "each initial variance (and scale_prior) must be finite and ≥ 0"
            }
            Self::ScaleWalk => "the wheel-scale random walk must be finite and ≥ 0 per m",
            Self::TagSpacing => return write!(f, "tag_spacing_m must be in {TAG_SPACING_M} m"),
            Self::ReadRadius => {
                return write!(
                    f,
                    "read_radius_m must be in {READ_RADIUS_M} m (and > 0 on a tag map)"
                );
            }
            Self::BlindDistance => "max_blind_distance_m must be finite and ≥ 0 m",
            Self::FixAge => {
                return write!(
                    f,
                    "fix_latency_s must be finite, ≥ 0 s and at most {} control periods",
                    crate::estimation::fusion::MAX_FIX_AGE_TICKS
                );
            }
            Self::TagMapReader => {
                "a tag map (no grid spacing) needs a range reader, read_radius_m > 0 m: \
                 the nearest-tag reader's cell measurements need a grid's tag_spacing_m"
            }
            Self::TagMapBlindDistance => {
                "max_blind_distance_m must be given on a tag map (its default, 4 s²/r, \
                 needs a grid's tag spacing s): the distance the robot may drive between \
                 two tags of its route, or 0 to keep the fix timeout"
            }
        };
        f.write_str(s)
    }
}

impl core::error::Error for PoseFilterError {}

/// Validated parameters of a pose filter ([`crate::estimation::fusion::PoseFilter`]).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PoseFilterConfig {
    pub(crate) track_width_m: f32,
    pub(crate) variance_per_m: f32,
    pub(crate) variance_floor_m2: f32,
    pub(crate) gate_sigma: f32,
    pub(crate) gate_one_dof: f32,
    pub(crate) gate_two_dof: f32,
    pub(crate) scale_walk_per_m: f32,
    pub(crate) recover_after: u32,
    pub(crate) particle_seed: u64,
}

impl PoseFilterConfig {
    /// Track width `b` (m); each wheel's travel variance per metre driven
    /// `α` (m²/m) and its floor `σ₀²` (m², e.g. `(r·2π/counts)²/12`); the
    /// gate in standard deviations `n ≥ 1` (module docs; 3 is usual).
    ///
    /// # Errors
    /// The first parameter out of range.
    pub fn new(
        track_width_m: f32,
        variance_per_m: f32,
        variance_floor_m2: f32,
        gate_sigma: f32,
    ) -> Result<Self, PoseFilterError> {
        if !TRACK_WIDTH_M.contains(track_width_m) {
            return Err(PoseFilterError::TrackWidth);
        }
        let non_negative = |x: f32| x.is_finite() && x >= 0.0;
        if !(non_negative(variance_per_m) && non_negative(variance_floor_m2)) {
            return Err(PoseFilterError::WheelNoise);
        }
        if !(gate_sigma.is_finite() && gate_sigma >= 1.0) {
            return Err(PoseFilterError::Gate);
        }
        Ok(Self {
            track_width_m,
            variance_per_m,
            variance_floor_m2,
            gate_sigma,
            gate_one_dof: gate_sigma * gate_sigma,
            gate_two_dof: -2.0 * ln_erfc_over_sqrt2(gate_sigma),
            scale_walk_per_m: 1e-8,
            recover_after: 3,
            particle_seed: 1,
        })
    }

    /// After this many consecutive gated measurements the filter takes
    /// itself to be lost rather than the fixes to be wrong: it widens its
    /// position covariance to cover the innovation and uses the fix
    /// (default 3; 0 never recovers).
    #[must_use]
    pub fn with_recovery_after(self, gated_fixes: u32) -> Self {
        Self {
            recover_after: gated_fixes,
            ..self
        }
    }

    /// The variance the wheel scale errors `ε` gain per metre driven
    /// (default 1e-8: `ε` may wander by 1e-4 per √m).
    ///
    /// # Errors
    /// [`PoseFilterError::ScaleWalk`].
    pub fn with_scale_walk(self, variance_per_m: f32) -> Result<Self, PoseFilterError> {
        if !(variance_per_m.is_finite() && variance_per_m >= 0.0) {
            return Err(PoseFilterError::ScaleWalk);
        }
        Ok(Self {
            scale_walk_per_m: variance_per_m,
            ..self
        })
    }

    /// The gate's chi-square thresholds `(1 dof, 2 dof)`.
    #[must_use]
    pub fn gate_thresholds(&self) -> (f32, f32) {
        (self.gate_one_dof, self.gate_two_dof)
    }

    /// The gate in standard deviations.
    #[must_use]
    pub fn gate_sigma(&self) -> f32 {
        self.gate_sigma
    }

    /// The seed of the particle filter's generator
    /// ([`crate::estimation::fusion::particle`]; default 1; the EKF and UKF draw
    /// nothing).
    #[must_use]
    pub fn with_particle_seed(self, seed: u64) -> Self {
        Self {
            particle_seed: seed,
            ..self
        }
    }

    /// The particle filter's seed.
    #[must_use]
    pub fn particle_seed(&self) -> u64 {
        self.particle_seed
    }

    /// The track width `b`, m.
    #[must_use]
    pub fn track_width_m(&self) -> f32 {
        self.track_width_m
    }
}

/// `ln(erfc(n/√2))` for `n ≥ 1` (Abramowitz & Stegun 7.1.26, relative
/// error of `erfc` below 1e-6 there; no cancellation: the polynomial
/// multiplies `e^{−n²/2}`, whose log is taken exactly). Computed once, at
/// construction, so always with libm's `f32` `logf` (the default backend's
/// `ln`): the `micromath` backend's `ln` would put the 2-dof gate 0.4 % off
/// (11.881 for 11.829 at 3σ) for no speed that matters here.
fn ln_erfc_over_sqrt2(n: f32) -> f32 {
    let x = n * core::f32::consts::FRAC_1_SQRT_2;
    let t = 1.0 / (1.0 + 0.327_591_1 * x);
    let poly = t
        * (0.254_829_6
            + t * (-0.284_496_74 + t * (1.421_413_7 + t * (-1.453_152_1 + t * 1.061_405_4))));
    libm::logf(poly) - x * x
}
