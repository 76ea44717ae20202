//! An extended Kalman filter of the pose `(x, y, θ)` that propagates with
//! the encoder odometry every tick and corrects with RFID tag fixes when
//! they arrive, gating each fix on its Mahalanobis distance (issue 5's
//! fusion estimator; the filter machinery follows paper 004's EKF, Joseph
//! form and all).
//!
//! The gate, the counters, re-localisation and heading resets are
//! [`PoseFilter`]'s, around a filter core ([`PoseFilterCore`]): this
//! module's EKF ([`EkfCore`], [`PoseEkf`]), paper 004's UKF
//! ([`crate::estimation::fusion::ukf`]) or its particle filter
//! ([`crate::estimation::fusion::particle`]), which share the state, the odometry
//! noise model and the measurements described here. [`FusionEstimator`]
//! runs the one [`FusionSettings::with_filter`] chooses.
//!
//! # State
//! `(x, y, θ, ε_R, ε_L)`: the pose and each wheel's scale error, the
//! wheel's true travel being `(1 + ε)` times what the encoder and the
//! nominal radius say. A wheel radius off by a fraction of a percent (tyre
//! wear, load, a different floor) makes `θ` drift by `v Δε / b`, faster
//! than tags a metre apart can correct a 3-state filter (the tests show it
//! losing the heading); with `ε` in the state the filter learns it from
//! the tags. `ε` starts at 0 with a prior variance and follows a random
//! walk; a prior variance of 0 turns it off.
//!
//! # Prediction (every tick)
//! The odometry step, with the wheel travels scaled by `(1 + ε̂)`, gives
//! `(Δs, Δθ)` and moves the pose along an exact arc,
//! `p⁺ = p + Δs sinc(Δθ/2) (cos m, sin m)`, `θ⁺ = θ + Δθ`, `m = θ + Δθ/2`
//! (as [`crate::geometry::Pose::advance_arc`]), with Jacobian
//! `F = I + [[0, 0, −c sin m], [0, 0, c cos m], [0, 0, 0]]`,
//! `c = Δs sinc(Δθ/2)`. Each wheel's travel `s_R, s_L` carries independent
//! noise of variance `α|s| + σ₀²` (slip and wheel-radius error grow with the
//! distance driven; `σ₀` is the count quantization), mapped into the state
//! through `∂(p, θ)/∂(s_R, s_L)`: `P⁺ = F P Fᵀ + G Σ Gᵀ`, where `F` also
//! carries `∂(p, θ)/∂ε` and `ε`'s own random walk adds its variance per
//! metre driven.
//!
//! # Correction (when a fix arrives)
//! A position measurement `z = H x + v`, `v ~ N(0, R)` with `H` selecting
//! one or both position axes. Innovation `y = z − H x̂`, `S = H P Hᵀ + R`,
//! Mahalanobis distance `d² = yᵀ S⁻¹ y`. Under the model `d²` is
//! chi-square distributed with `k` (= 1 or 2) degrees of freedom; the fix
//! is rejected (and counted) when `d²` exceeds the quantile of the gate
//! probability: the configuration gives the gate as `n σ` (the probability
//! of a 1-D Gaussian within `n σ`, e.g. 3σ → 0.9973), and the thresholds
//! are `χ²₁ = n²` and `χ²₂ = −2 ln(1 − erf(n/√2))` (the 2-dof chi-square
//! CDF is `1 − e^{−x/2}`), 9.0 and 11.83 for 3σ. Accepted fixes update with
//! `K = P Hᵀ S⁻¹`, `x̂⁺ = x̂ + K y`, and the Joseph form
//! `P⁺ = (I − KH) P (I − KH)ᵀ + K R Kᵀ`, symmetrised, which stays positive
//! semi-definite in `f32` where `(I − KH)P` need not.
//!
//! # Tag fixes as measurements ([`TagCellTracker`])
//! The nearest tag of a grid is not white noise: a robot at 0.1 m/s keeps
//! reading the same tag for a second, and an EKF fed each read as
//! independent would collapse onto the tag's centre. What does carry
//! information is the moment the nearest tag changes: the robot has just
//! crossed the boundary halfway between the two tags, along the axis that
//! changed, within the distance it drove during that tick. So the first
//! fix is a weak 2-D measurement (the uniform cell, variance `s²/12` per
//! axis) and each later change of tag is a sharp 1-D measurement of the
//! crossed axis. Reads of the same tag say the robot is still inside that
//! cell; by default they are skipped, and optionally
//! ([`TagCellTracker::with_edge_constraint`]) they pull an estimate that
//! has drifted out back to the cell's edge (variance `(s/10)²`).
//!
//! # Angle convention
//! `θ̂` is kept wrapped to (−π, π] after each step; its Jacobians use only
//! sines and cosines, so the wrap never enters a difference.
//!
//! # Bad input
//! A non-finite odometry step or fix is counted and ignored; a prediction
//! or update whose result is not finite (or whose `S` cannot be inverted)
//! leaves the state unchanged and is counted.

pub mod particle;
pub mod ukf;

use nalgebra::{Matrix2, Matrix3x2, SMatrix, SVector, Vector2};

use crate::estimation::heading_observer::HeadingObserver;
use crate::geometry::{Pose, Vec2};

/// The filter's state size: `(x, y, θ, ε_R, ε_L)`.
const STATES: usize = 5;
type Row = SMatrix<f32, 1, STATES>;
use crate::math;
use crate::odometry::OdometryStep;

/// Why a [`PoseFilterConfig`] was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum PoseFilterError {
    /// Track width not finite and positive.
    TrackWidth,
    /// A wheel-noise parameter negative or not finite.
    WheelNoise,
    /// Gate not finite, or below 1 σ.
    Gate,
    /// An initial variance negative or not finite.
    InitialVariance,
    /// The wheel-scale random walk negative or not finite.
    ScaleWalk,
    /// Tag spacing not finite and positive.
    TagSpacing,
    /// Reader range negative or not finite.
    ReadRadius,
    /// Blind-distance limit negative or not finite.
    BlindDistance,
}

/// Validated parameters of a [`PoseEkf`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PoseFilterConfig {
    track_width_m: f32,
    variance_per_m: f32,
    variance_floor_m2: f32,
    gate_sigma: f32,
    gate_one_dof: f32,
    gate_two_dof: f32,
    scale_walk_per_m: f32,
    recover_after: u32,
    particle_seed: u64,
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
        if !(track_width_m.is_finite() && track_width_m > 0.0) {
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
/// multiplies `e^{−n²/2}`, whose log is taken exactly).
fn ln_erfc_over_sqrt2(n: f32) -> f32 {
    let x = n * core::f32::consts::FRAC_1_SQRT_2;
    let t = 1.0 / (1.0 + 0.327_591_1 * x);
    let poly = t
        * (0.254_829_6
            + t * (-0.284_496_74 + t * (1.421_413_7 + t * (-1.453_152_1 + t * 1.061_405_4))));
    math::ln(poly) - x * x
}

/// A position measurement: one axis or both.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PositionMeasurement {
    /// Both coordinates, with per-axis variances (m²).
    Point {
        /// Measured position, m.
        position: Vec2,
        /// Variances of `x` and `y`, m².
        variance_m2: [f32; 2],
    },
    /// `x` only.
    X {
        /// Measured `x`, m.
        value_m: f32,
        /// Its variance, m².
        variance_m2: f32,
    },
    /// `y` only.
    Y {
        /// Measured `y`, m.
        value_m: f32,
        /// Its variance, m².
        variance_m2: f32,
    },
    /// Both coordinates with correlated noise: e.g. a range reader's entry
    /// point, sharp along the heading and wide across it.
    Ellipse {
        /// Measured position, m.
        position: Vec2,
        /// The noise covariance `[σx², σxy, σy²]`, m² (positive definite).
        covariance_m2: [f32; 3],
    },
}

impl PositionMeasurement {
    /// The measured position and its noise covariance, for the 2-D kinds.
    #[must_use]
    pub fn position_and_covariance(&self) -> Option<(Vec2, Matrix2<f32>)> {
        match *self {
            Self::Point {
                position,
                variance_m2,
            } => Some((
                position,
                Matrix2::from_diagonal(&Vector2::from(variance_m2)),
            )),
            Self::Ellipse {
                position,
                covariance_m2: [xx, xy, yy],
            } => Some((position, Matrix2::new(xx, xy, xy, yy))),
            Self::X { .. } | Self::Y { .. } => None,
        }
    }

    fn is_finite(&self) -> bool {
        match *self {
            Self::Ellipse {
                position,
                covariance_m2: [xx, xy, yy],
            } => {
                position.is_finite()
                    && [xx, xy, yy].iter().all(|v| v.is_finite())
                    && xx > 0.0
                    && yy > 0.0
                    && xx * yy - xy * xy > 0.0
            }
            Self::Point {
                position,
                variance_m2,
            } => position.is_finite() && variance_m2.iter().all(|v| v.is_finite() && *v > 0.0),
            Self::X {
                value_m,
                variance_m2,
            }
            | Self::Y {
                value_m,
                variance_m2,
            } => value_m.is_finite() && variance_m2.is_finite() && variance_m2 > 0.0,
        }
    }
}

/// What happened to a measurement.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FixOutcome {
    /// Used to correct the estimate.
    Used,
    /// Rejected by the gate.
    Gated,
    /// Not finite, or the update failed numerically.
    Invalid,
}

/// Counters of a [`PoseFilter`]: nothing is dropped silently.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct PoseFilterCounters {
    /// Predictions done.
    pub predictions: u32,
    /// Odometry steps refused (non-finite input or result).
    pub rejected_predictions: u32,
    /// Measurements used.
    pub fixes_used: u32,
    /// Measurements rejected by the Mahalanobis gate.
    pub fixes_gated: u32,
    /// Measurements refused as non-finite or numerically unusable.
    pub fixes_invalid: u32,
    /// Times the filter took itself to be lost and re-localised on a fix
    /// after consecutive gated ones (those fixes count as used).
    pub relocalisations: u32,
}

/// The mean `(x, y, θ, ε_R, ε_L)` of a pose filter.
pub type PoseState = SVector<f32, STATES>;
/// Its covariance.
pub type PoseCovariance = SMatrix<f32, STATES, STATES>;

/// The filter inside a [`PoseFilter`]: how it predicts with odometry and
/// applies a position measurement. The gate, the counters, re-localisation
/// and heading resets are the same for every filter and live in
/// [`PoseFilter`], which works on [`Self::mean`] and [`Self::covariance`].
pub trait PoseFilterCore: Sized {
    /// A filter at `mean` (finite) with `covariance` (finite, symmetric,
    /// positive semi-definite); `None` if it cannot start there.
    fn start(
        config: &PoseFilterConfig,
        mean: &PoseState,
        covariance: &PoseCovariance,
    ) -> Option<Self>;

    /// Propagates with a finite odometry step; `false` (and nothing
    /// changed) if the result would not be finite.
    fn predict(&mut self, config: &PoseFilterConfig, odometry: &OdometryStep) -> bool;

    /// The mean (heading in any turn; [`PoseFilter::pose`] wraps it).
    fn mean(&self) -> PoseState;

    /// The covariance of the mean.
    fn covariance(&self) -> PoseCovariance;

    /// Applies a finite measurement, ungated; `false` (and nothing
    /// changed) if it cannot be used numerically.
    fn update(&mut self, measurement: &PositionMeasurement) -> bool;

    /// Restarts at `mean` with `covariance` (as for [`Self::start`]);
    /// `false` (and nothing changed) if it cannot.
    fn reset(&mut self, mean: &PoseState, covariance: &PoseCovariance) -> bool;
}

/// A pose filter on odometry and position fixes (module docs): the filter
/// `Core` ([`EkfCore`], or the UKF and particle filter of
/// [`crate::estimation::fusion::ukf`] and [`crate::estimation::fusion::particle`]) behind the
/// Mahalanobis gate, with re-localisation and counters.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseFilter<Core> {
    config: PoseFilterConfig,
    core: Core,
    counters: PoseFilterCounters,
    /// Consecutive gated measurements of `x` and of `y` (a fix along one
    /// axis says nothing of the other's lock).
    consecutive_gated: [u32; 2],
}

/// The pose EKF.
pub type PoseEkf = PoseFilter<EkfCore>;

impl<Core: PoseFilterCore> PoseFilter<Core> {
    /// A filter at `initial` with variances `[σx², σy², σθ², σε²]` (m², m²,
    /// rad², and the prior of each wheel's scale error; 0 turns the scale
    /// estimation off). An unknown heading is `σθ ~ π`.
    ///
    /// # Errors
    /// [`PoseFilterError::InitialVariance`].
    pub fn new(
        config: PoseFilterConfig,
        initial: Pose,
        variances: [f32; 4],
    ) -> Result<Self, PoseFilterError> {
        if !(initial.position.is_finite()
            && initial.heading_rad.is_finite()
            && variances.iter().all(|v| v.is_finite() && *v >= 0.0))
        {
            return Err(PoseFilterError::InitialVariance);
        }
        let [vx, vy, vt, ve] = variances;
        let mean = PoseState::from([
            initial.position.x,
            initial.position.y,
            math::wrap_angle(initial.heading_rad),
            0.0,
            0.0,
        ]);
        let covariance = PoseCovariance::from_diagonal(&PoseState::from([vx, vy, vt, ve, ve]));
        let core =
            Core::start(&config, &mean, &covariance).ok_or(PoseFilterError::InitialVariance)?;
        Ok(Self {
            config,
            core,
            counters: PoseFilterCounters::default(),
            consecutive_gated: [0; 2],
        })
    }

    /// Replaces the heading estimate (wrapped) with variance `variance_rad2`
    /// and no correlation with the rest of the state; false (and nothing
    /// changed) if either is not finite or the filter cannot take it.
    pub fn reset_heading(&mut self, heading_rad: f32, variance_rad2: f32) -> bool {
        if !(heading_rad.is_finite() && variance_rad2.is_finite() && variance_rad2 >= 0.0) {
            return false;
        }
        let mut mean = self.core.mean();
        mean.z = math::wrap_angle(heading_rad);
        let mut covariance = self.core.covariance();
        covariance.fixed_view_mut::<1, 5>(2, 0).fill(0.0);
        covariance.fixed_view_mut::<5, 1>(0, 2).fill(0.0);
        covariance.fixed_view_mut::<1, 1>(2, 2).fill(variance_rad2);
        self.core.reset(&mean, &covariance)
    }

    /// The estimated wheel scale errors `(ε_R, ε_L)`.
    #[must_use]
    pub fn wheel_scale_errors(&self) -> [f32; 2] {
        let mean = self.core.mean();
        [mean.w, mean.a]
    }

    /// The estimated pose (heading wrapped to (−π, π]).
    #[must_use]
    pub fn pose(&self) -> Pose {
        let mean = self.core.mean();
        Pose::new(mean.x, mean.y, math::wrap_angle(mean.z))
    }

    /// The covariance of `(x, y, θ, ε_R, ε_L)`.
    #[must_use]
    pub fn covariance(&self) -> PoseCovariance {
        self.core.covariance()
    }

    /// The filter inside.
    #[must_use]
    pub fn core(&self) -> &Core {
        &self.core
    }

    /// The counters.
    #[must_use]
    pub fn counters(&self) -> PoseFilterCounters {
        self.counters
    }

    /// The configuration.
    #[must_use]
    pub fn config(&self) -> &PoseFilterConfig {
        &self.config
    }

    /// Propagates with one odometry step (module docs); a non-finite step,
    /// or one the filter cannot take, is counted and ignored.
    pub fn predict(&mut self, odometry: &OdometryStep) {
        let applied = odometry.ds_m.is_finite()
            && odometry.dtheta_rad.is_finite()
            && self.core.predict(&self.config, odometry);
        let c = &mut self.counters;
        if applied {
            c.predictions = c.predictions.saturating_add(1);
        } else {
            c.rejected_predictions = c.rejected_predictions.saturating_add(1);
        }
    }

    /// Corrects with a position measurement (module docs); counts and
    /// reports what happened to it.
    pub fn correct(&mut self, measurement: &PositionMeasurement) -> FixOutcome {
        let mut outcome = self.correct_once(measurement, true);
        let axes = match measurement {
            PositionMeasurement::Point { .. } | PositionMeasurement::Ellipse { .. } => [true, true],
            PositionMeasurement::X { .. } => [true, false],
            PositionMeasurement::Y { .. } => [false, true],
        };
        let counts = self
            .consecutive_gated
            .iter_mut()
            .zip(axes)
            .filter_map(|(count, measured)| measured.then_some(count));
        if outcome == FixOutcome::Gated {
            let mut longest = 0;
            for count in counts {
                *count = count.saturating_add(1);
                longest = longest.max(*count);
            }
            let recover = self.config.recover_after;
            if recover > 0 && longest >= recover {
                self.widen_to(measurement);
                outcome = self.correct_once(measurement, false);
                if outcome == FixOutcome::Used {
                    self.counters.relocalisations = self.counters.relocalisations.saturating_add(1);
                }
            }
        }
        if outcome == FixOutcome::Used {
            for (count, measured) in self.consecutive_gated.iter_mut().zip(axes) {
                if measured {
                    *count = 0;
                }
            }
        }
        let c = &mut self.counters;
        match outcome {
            FixOutcome::Used => c.fixes_used = c.fixes_used.saturating_add(1),
            FixOutcome::Gated => c.fixes_gated = c.fixes_gated.saturating_add(1),
            FixOutcome::Invalid => c.fixes_invalid = c.fixes_invalid.saturating_add(1),
        }
        outcome
    }

    /// Re-localisation: the filter is lost, so its pose covariance is
    /// reset to what it can still claim. Each position axis gets its
    /// variance plus the squared innovation of `measurement` on that axis,
    /// the heading a variance of at least `(π/2)²` (a filter that lost its
    /// position may hold a mirrored heading: x-only fixes cannot tell `θ`
    /// from `−θ`), and the pose's cross-covariances are cleared.
    fn widen_to(&mut self, measurement: &PositionMeasurement) {
        let mean = self.core.mean();
        let (dx2, dy2) = match *measurement {
            PositionMeasurement::Point { position, .. }
            | PositionMeasurement::Ellipse { position, .. } => (
                (position.x - mean.x) * (position.x - mean.x),
                (position.y - mean.y) * (position.y - mean.y),
            ),
            PositionMeasurement::X { value_m, .. } => {
                ((value_m - mean.x) * (value_m - mean.x), 0.0)
            }
            PositionMeasurement::Y { value_m, .. } => {
                (0.0, (value_m - mean.y) * (value_m - mean.y))
            }
        };
        let mut covariance = self.core.covariance();
        let diagonal = SVector::<f32, 3>::new(
            covariance.m11 + dx2,
            covariance.m22 + dy2,
            covariance.m33.max(0.25 * PI_SQUARED),
        );
        if diagonal.iter().all(|x| x.is_finite()) {
            covariance.fixed_view_mut::<3, 5>(0, 0).fill(0.0);
            covariance.fixed_view_mut::<5, 3>(0, 0).fill(0.0);
            covariance
                .fixed_view_mut::<3, 3>(0, 0)
                .copy_from(&SMatrix::<f32, 3, 3>::from_diagonal(&diagonal));
            // A core that cannot take it keeps its belief; the ungated
            // correction that follows still re-localises it.
            let _ = self.core.reset(&mean, &covariance);
        }
    }

    /// The gate on the Mahalanobis distance of the innovation (module
    /// docs), computed from the core's mean and covariance (exact for every
    /// filter here: the measurement is linear), then the core's update.
    fn correct_once(&mut self, measurement: &PositionMeasurement, gate: bool) -> FixOutcome {
        if !measurement.is_finite() {
            return FixOutcome::Invalid;
        }
        let Some((distance2, dof)) =
            mahalanobis(&self.core.mean(), &self.core.covariance(), measurement)
        else {
            return FixOutcome::Invalid;
        };
        let threshold = if dof == 1 {
            self.config.gate_one_dof
        } else {
            self.config.gate_two_dof
        };
        if gate && distance2 > threshold {
            return FixOutcome::Gated;
        }
        if self.core.update(measurement) {
            FixOutcome::Used
        } else {
            FixOutcome::Invalid
        }
    }
}

/// The squared Mahalanobis distance `yᵀ S⁻¹ y` of a finite measurement's
/// innovation under a belief `(mean, covariance)`, `S = H P Hᵀ + R`, and
/// its degrees of freedom; `None` if `S` cannot be inverted or `d²` is not
/// finite.
fn mahalanobis(
    mean: &PoseState,
    covariance: &PoseCovariance,
    measurement: &PositionMeasurement,
) -> Option<(f32, u8)> {
    let (distance2, dof) = match *measurement {
        PositionMeasurement::Point { .. } | PositionMeasurement::Ellipse { .. } => {
            let (position, r) = measurement.position_and_covariance()?;
            let innovation = Vector2::new(position.x - mean.x, position.y - mean.y);
            let s = covariance.fixed_view::<2, 2>(0, 0).into_owned() + r;
            let s_inv = s.try_inverse()?;
            ((innovation.transpose() * s_inv * innovation).x, 2)
        }
        PositionMeasurement::X {
            value_m,
            variance_m2,
        } => axis_distance2(value_m - mean.x, covariance.m11 + variance_m2)?,
        PositionMeasurement::Y {
            value_m,
            variance_m2,
        } => axis_distance2(value_m - mean.y, covariance.m22 + variance_m2)?,
    };
    distance2.is_finite().then_some((distance2, dof))
}

fn axis_distance2(innovation: f32, s: f32) -> Option<(f32, u8)> {
    (s.is_finite() && s > 0.0).then(|| (innovation * innovation / s, 1))
}

/// The odometry step through the wheel-scale estimate, and its
/// linearisation at a state (module docs, "Prediction").
pub(crate) struct OdometryLinearisation {
    /// The state after the step.
    pub(crate) state: PoseState,
    /// `F = ∂x⁺/∂x`.
    pub(crate) jacobian: PoseCovariance,
    /// `G Σ Gᵀ` plus the scale errors' random walk.
    pub(crate) process_noise: PoseCovariance,
}

/// Each wheel's travel `(s_R, s_L)` for an odometry step `(Δs, Δθ)` on a
/// track `b`: `Δs ± Δθ b/2`.
pub(crate) fn wheel_travels(ds_m: f32, dtheta_rad: f32, track_width_m: f32) -> (f32, f32) {
    (
        ds_m + 0.5 * dtheta_rad * track_width_m,
        ds_m - 0.5 * dtheta_rad * track_width_m,
    )
}

/// The pose `(x, y, θ)` of `state` moved along the exact arc of wheel
/// travels `(right, left)` (m) on a track `b`; the scale errors kept.
pub(crate) fn drive_wheels(
    state: &PoseState,
    right: f32,
    left: f32,
    track_width_m: f32,
) -> PoseState {
    let (ds, dth) = (0.5 * (right + left), (right - left) / track_width_m);
    let mid = state.z + 0.5 * dth;
    let chord = ds * math::sinc(0.5 * dth);
    let mut next = *state;
    next.x += chord * math::cos(mid);
    next.y += chord * math::sin(mid);
    next.z = math::wrap_angle(state.z + dth);
    next
}

/// The state after an odometry step, each wheel's nominal travel scaled
/// by its `(1 + ε)` and driven along the exact arc (the transition of the
/// UKF's sigma points and of the particle filter's noiseless particle; the
/// EKF computes the same move in [`linearise_odometry`], sharing its sines
/// with the Jacobian).
pub(crate) fn odometry_transition(
    state: &PoseState,
    odometry: &OdometryStep,
    track_width_m: f32,
) -> PoseState {
    let (right, left) = wheel_travels(odometry.ds_m, odometry.dtheta_rad, track_width_m);
    drive_wheels(
        state,
        right * (1.0 + state.w),
        left * (1.0 + state.a),
        track_width_m,
    )
}

/// The variance of a wheel's travel `s`: `α|s| + σ₀²`.
pub(crate) fn wheel_variance(config: &PoseFilterConfig, travel_m: f32) -> f32 {
    config.variance_per_m * travel_m.abs() + config.variance_floor_m2
}

/// The variance the scale error of a wheel that travelled `s` gains.
pub(crate) fn scale_walk_variance(config: &PoseFilterConfig, travel_m: f32) -> f32 {
    config.scale_walk_per_m * travel_m.abs()
}

/// The odometry step at `state`: the moved state, `F` and `G Σ Gᵀ` (module
/// docs, "Prediction").
pub(crate) fn linearise_odometry(
    config: &PoseFilterConfig,
    state: &PoseState,
    odometry: &OdometryStep,
) -> OdometryLinearisation {
    let b = config.track_width_m;
    let (theta, eps_r, eps_l) = (state.z, state.w, state.a);
    // Nominal wheel travels, then scaled by the estimated errors.
    let (nominal_r, nominal_l) = wheel_travels(odometry.ds_m, odometry.dtheta_rad, b);
    let (right, left) = (nominal_r * (1.0 + eps_r), nominal_l * (1.0 + eps_l));
    let (ds, dth) = (0.5 * (right + left), (right - left) / b);
    let mid = theta + 0.5 * dth;
    let (sin_m, cos_m) = (math::sin(mid), math::cos(mid));
    let chord = ds * math::sinc(0.5 * dth);
    let mut next = *state;
    next.x += chord * cos_m;
    next.y += chord * sin_m;
    next.z = math::wrap_angle(theta + dth);
    // ∂(x, y, θ)/∂(Δs, Δθ), then ∂(Δs, Δθ)/∂(s_R, s_L).
    let by_step = Matrix3x2::new(
        cos_m,
        -0.5 * chord * sin_m,
        sin_m,
        0.5 * chord * cos_m,
        0.0,
        1.0,
    );
    let by_wheels = by_step * Matrix2::new(0.5, 0.5, 1.0 / b, -1.0 / b);
    let mut jacobian = PoseCovariance::identity();
    jacobian
        .fixed_view_mut::<2, 1>(0, 2)
        .copy_from(&Vector2::new(-chord * sin_m, chord * cos_m));
    // ∂(x, y, θ)/∂ε = ∂/∂(s_R, s_L) · diag(nominal_r, nominal_l).
    let by_scale = by_wheels * Matrix2::new(nominal_r, 0.0, 0.0, nominal_l);
    jacobian.fixed_view_mut::<3, 2>(0, 3).copy_from(&by_scale);
    let noise = Matrix2::from_diagonal(&Vector2::new(
        wheel_variance(config, right),
        wheel_variance(config, left),
    ));
    let mut process_noise = PoseCovariance::zeros();
    process_noise
        .fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(by_wheels * noise * by_wheels.transpose()));
    process_noise
        .fixed_view_mut::<2, 2>(3, 3)
        .copy_from(&Matrix2::from_diagonal(&Vector2::new(
            scale_walk_variance(config, right),
            scale_walk_variance(config, left),
        )));
    OdometryLinearisation {
        state: next,
        jacobian,
        process_noise,
    }
}

/// The EKF of the module docs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EkfCore {
    state: PoseState,
    covariance: PoseCovariance,
}

impl PoseFilterCore for EkfCore {
    fn start(
        _config: &PoseFilterConfig,
        mean: &PoseState,
        covariance: &PoseCovariance,
    ) -> Option<Self> {
        let mut core = Self {
            state: PoseState::zeros(),
            covariance: PoseCovariance::zeros(),
        };
        core.reset(mean, covariance).then_some(core)
    }

    fn predict(&mut self, config: &PoseFilterConfig, odometry: &OdometryStep) -> bool {
        let step = linearise_odometry(config, &self.state, odometry);
        let covariance = symmetric(
            step.jacobian * self.covariance * step.jacobian.transpose() + step.process_noise,
        );
        let finite =
            step.state.iter().all(|x| x.is_finite()) && covariance.iter().all(|x| x.is_finite());
        if finite {
            self.state = step.state;
            self.covariance = covariance;
        }
        finite
    }

    fn mean(&self) -> PoseState {
        self.state
    }

    fn covariance(&self) -> PoseCovariance {
        self.covariance
    }

    fn update(&mut self, measurement: &PositionMeasurement) -> bool {
        match *measurement {
            PositionMeasurement::Point { .. } | PositionMeasurement::Ellipse { .. } => measurement
                .position_and_covariance()
                .is_some_and(|(position, r)| self.update_point(position, r)),
            PositionMeasurement::X {
                value_m,
                variance_m2,
            } => self.update_axis(
                Row::from_row_slice(&[1.0, 0.0, 0.0, 0.0, 0.0]),
                value_m,
                variance_m2,
            ),
            PositionMeasurement::Y {
                value_m,
                variance_m2,
            } => self.update_axis(
                Row::from_row_slice(&[0.0, 1.0, 0.0, 0.0, 0.0]),
                value_m,
                variance_m2,
            ),
        }
    }

    fn reset(&mut self, mean: &PoseState, covariance: &PoseCovariance) -> bool {
        let finite = mean.iter().all(|x| x.is_finite()) && covariance.iter().all(|x| x.is_finite());
        if finite {
            self.state = *mean;
            self.state.z = math::wrap_angle(mean.z);
            self.covariance = symmetric(*covariance);
        }
        finite
    }
}

impl EkfCore {
    fn update_point(&mut self, position: Vec2, r: Matrix2<f32>) -> bool {
        let h = SMatrix::<f32, 2, STATES>::from_row_slice(&[
            1.0, 0.0, 0.0, 0.0, 0.0, //
            0.0, 1.0, 0.0, 0.0, 0.0,
        ]);
        let innovation = Vector2::new(position.x - self.state.x, position.y - self.state.y);
        let s = h * self.covariance * h.transpose() + r;
        let Some(s_inv) = s.try_inverse() else {
            return false;
        };
        let gain = self.covariance * h.transpose() * s_inv;
        self.apply(gain * innovation, gain * h, gain * r * gain.transpose())
    }

    fn update_axis(&mut self, h: Row, value: f32, variance: f32) -> bool {
        let innovation = value - (h * self.state).x;
        let s = (h * self.covariance * h.transpose()).x + variance;
        if !(s.is_finite() && s > 0.0) {
            return false;
        }
        let gain = self.covariance * h.transpose() / s;
        self.apply(
            gain * innovation,
            gain * h,
            gain * gain.transpose() * variance,
        )
    }

    /// `x̂ += Δx`, Joseph-form covariance with `KH` and `KRKᵀ`.
    fn apply(
        &mut self,
        correction: PoseState,
        gain_h: PoseCovariance,
        gain_r_gain: PoseCovariance,
    ) -> bool {
        let mut state = self.state + correction;
        state.z = math::wrap_angle(state.z);
        let keep = PoseCovariance::identity() - gain_h;
        let covariance = symmetric(keep * self.covariance * keep.transpose() + gain_r_gain);
        let finite =
            state.iter().all(|x| x.is_finite()) && covariance.iter().all(|x| x.is_finite());
        if finite {
            self.state = state;
            self.covariance = covariance;
        }
        finite
    }
}

pub(crate) fn symmetric(m: PoseCovariance) -> PoseCovariance {
    (m + m.transpose()) * 0.5
}

/// Turns nearest-tag fixes on a square grid into the measurements they
/// carry (module docs): the first fix as the uniform cell, then each change
/// of tag as the crossing of the boundary between the two tags.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TagCellTracker {
    spacing_m: f32,
    last_tag: Option<Vec2>,
    same_tag_reads: u32,
    edge_corrections: u32,
    edges: bool,
}

/// At most two measurements from one fix (both axes crossed at once).
pub type CellMeasurements = heapless::Vec<PositionMeasurement, 2>;

impl TagCellTracker {
    /// For a grid of this spacing (m); `None` unless finite and positive.
    #[must_use]
    pub fn new(spacing_m: f32) -> Option<Self> {
        (spacing_m.is_finite() && spacing_m > 0.0).then_some(Self {
            spacing_m,
            last_tag: None,
            same_tag_reads: 0,
            edge_corrections: 0,
            edges: false,
        })
    }

    /// Whether reads of an unchanged tag pull an estimate that has left its
    /// cell back to the edge (default off: on the figure-eight it halves the
    /// worst error under wheel slip but triples it without, because the
    /// edge "measurement" is made from the estimate itself and its
    /// correlation leaks into the heading).
    #[must_use]
    pub fn with_edge_constraint(self, edges: bool) -> Self {
        Self { edges, ..self }
    }

    /// Reads of an unchanged tag (they carry information only when the
    /// estimate has left the tag's cell).
    #[must_use]
    pub fn same_tag_reads(&self) -> u32 {
        self.same_tag_reads
    }

    /// Edge measurements made because the estimate had left the cell of the
    /// tag still being read.
    #[must_use]
    pub fn edge_corrections(&self) -> u32 {
        self.edge_corrections
    }

    /// Forgets the last tag (after a gap in the reads, when a change of tag
    /// no longer means one boundary crossed during the last tick).
    pub fn restart(&mut self) {
        self.last_tag = None;
    }

    /// The measurement of a read of `tag` by a reader of range `radius_m`
    /// ([`FusionSettings::with_read_radius`]) on a robot heading `heading`
    /// (rad), `travel_m` driven since the last read: the first read of each
    /// pass (a different tag, or the same one after more than `2r` driven:
    /// a range reader repeats its read while the tag stays in range, so a
    /// gap in the reads alone does not end a pass) is where the antenna
    /// entered the disc around the tag.
    /// At a lateral offset `d` (uniform in `[−r, r]`) that is `√(r² − d²)`
    /// short of the tag along the heading: mean `πr/4` short, lateral
    /// variance `r²/3`, along-track variance `(2/3 − π²/16) r² ≈ 0.05 r²`.
    /// The measurement is the tag moved back by `πr/4` along the heading,
    /// with those variances along and across the heading
    /// ([`PositionMeasurement::Ellipse`]). Repeats within a pass give
    /// nothing (counted).
    pub fn range_measurement(
        &mut self,
        tag: Vec2,
        heading: f32,
        travel_m: f32,
        radius_m: f32,
    ) -> Option<PositionMeasurement> {
        if !(tag.is_finite() && heading.is_finite()) {
            return None;
        }
        if self.last_tag.replace(tag) == Some(tag) && travel_m <= 2.0 * radius_m {
            self.same_tag_reads = self.same_tag_reads.saturating_add(1);
            return None;
        }
        let back = core::f32::consts::FRAC_PI_4 * radius_m;
        let r2 = radius_m * radius_m;
        let (along, across) = (ENTRY_ALONG_VARIANCE * r2, r2 / 3.0);
        let (c, s) = (math::cos(heading), math::sin(heading));
        Some(PositionMeasurement::Ellipse {
            position: Vec2::new(tag.x - back * c, tag.y - back * s),
            // R(θ) diag(along, across) R(θ)ᵀ.
            covariance_m2: [
                along * c * c + across * s * s,
                (along - across) * c * s,
                along * s * s + across * c * c,
            ],
        })
    }

    /// The measurements of a fix at `tag`, given the displacement `(Δx, Δy)`
    /// the robot made during the last tick (from odometry and the current
    /// heading estimate) and the current position estimate.
    pub fn measurements(&mut self, tag: Vec2, last_step: Vec2, estimate: Vec2) -> CellMeasurements {
        let mut out = CellMeasurements::new();
        if !(tag.is_finite() && last_step.is_finite() && estimate.is_finite()) {
            return out;
        }
        let s = self.spacing_m;
        let cell = s * s / 12.0;
        let Some(last) = self.last_tag.replace(tag) else {
            // Capacity 2: the first push cannot fail.
            let _ = out.push(PositionMeasurement::Point {
                position: tag,
                variance_m2: [cell, cell],
            });
            return out;
        };
        let (dx, dy) = (tag.x - last.x, tag.y - last.y);
        let crossed = |d: f32| d.abs() > 0.5 * s;
        let adjacent = |d: f32| d.abs() < 1.5 * s;
        if !crossed(dx) && !crossed(dy) {
            // Still in the same cell: if the estimate has left it, the
            // cell's edge is where the robot at most is.
            self.same_tag_reads = self.same_tag_reads.saturating_add(1);
            if !self.edges {
                return out;
            }
            let edge = |estimate: f32, centre: f32| {
                let offset = estimate - centre;
                (offset.abs() > 0.5 * s).then(|| centre + 0.5 * s * offset.signum())
            };
            let edge_variance = s * s / 100.0;
            if let Some(value_m) = edge(estimate.x, tag.x) {
                let _ = out.push(PositionMeasurement::X {
                    value_m,
                    variance_m2: edge_variance,
                });
                self.edge_corrections = self.edge_corrections.saturating_add(1);
            }
            if let Some(value_m) = edge(estimate.y, tag.y) {
                let _ = out.push(PositionMeasurement::Y {
                    value_m,
                    variance_m2: edge_variance,
                });
                self.edge_corrections = self.edge_corrections.saturating_add(1);
            }
            return out;
        }
        if !(adjacent(dx) && adjacent(dy)) {
            // A jump past a neighbour: not one boundary crossed; weak fix.
            let _ = out.push(PositionMeasurement::Point {
                position: tag,
                variance_m2: [cell, cell],
            });
            return out;
        }
        // The robot crossed the boundary during the last tick and is now
        // beyond it by a uniform fraction of that tick's travel.
        let crossing = |from: f32, to: f32, step: f32| {
            let boundary = 0.5 * (from + to);
            let travel = step.abs().min(s);
            let value = boundary + (to - from).signum() * 0.5 * travel;
            // Travel²/12, plus 1 mm² for the reader's own position error.
            (value, travel * travel / 12.0 + 1e-6)
        };
        if crossed(dx) {
            let (value_m, variance_m2) = crossing(last.x, tag.x, last_step.x);
            let _ = out.push(PositionMeasurement::X {
                value_m,
                variance_m2,
            });
        }
        if crossed(dy) {
            let (value_m, variance_m2) = crossing(last.y, tag.y, last_step.y);
            let _ = out.push(PositionMeasurement::Y {
                value_m,
                variance_m2,
            });
        }
        out
    }
}

/// Which filter the fusion estimator runs. The EKF is always built; the
/// others need their cargo features (`fusion-ukf`,
/// `fusion-particle-filter`), for their flash and, for the particle
/// filter, RAM and time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FusionFilter {
    /// The EKF of this module.
    #[default]
    Ekf,
    /// The UKF ([`crate::estimation::fusion::ukf`]).
    #[cfg(feature = "fusion-ukf")]
    Ukf,
    /// The particle filter ([`crate::estimation::fusion::particle`]) with
    /// [`crate::estimation::fusion::particle::FUSION_PARTICLES`] particles; its
    /// generator is seeded with the filter configuration's
    /// [`PoseFilterConfig::particle_seed`].
    #[cfg(feature = "fusion-particle-filter")]
    ParticleFilter,
}

/// Validated settings of the tracker's fusion estimator
/// (`TrackerConfig::with_fusion`, cargo feature `fusion-ekf`).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FusionSettings {
    filter: PoseFilterConfig,
    kind: FusionFilter,
    tag_spacing_m: f32,
    scale_prior: f32,
    read_radius_m: f32,
    max_blind_distance_m: f32,
    edge_constraint: bool,
}

impl FusionSettings {
    /// The filter, the spacing of the square tag grid (m) and the prior
    /// variance of each wheel's scale error (0: the wheels are taken as
    /// calibrated; 4e-4 for a 2 % prior).
    ///
    /// # Errors
    /// [`PoseFilterError::TagSpacing`] or [`PoseFilterError::InitialVariance`].
    pub fn new(
        filter: PoseFilterConfig,
        tag_spacing_m: f32,
        scale_prior: f32,
    ) -> Result<Self, PoseFilterError> {
        if !(tag_spacing_m.is_finite() && tag_spacing_m > 0.0) {
            return Err(PoseFilterError::TagSpacing);
        }
        if !(scale_prior.is_finite() && scale_prior >= 0.0) {
            return Err(PoseFilterError::InitialVariance);
        }
        Ok(Self {
            filter,
            kind: FusionFilter::Ekf,
            tag_spacing_m,
            scale_prior,
            read_radius_m: 0.0,
            max_blind_distance_m: 0.0,
            edge_constraint: false,
        })
    }

    /// Reads of an unchanged tag pull an estimate that has left the tag's
    /// cell back to its edge ([`TagCellTracker::with_edge_constraint`];
    /// nearest-tag reader only; default off). Under random wheel slip,
    /// with a wheel-noise model near the slip's, it is what lets the
    /// filter see the lateral drift along a row of tags (README figures).
    #[must_use]
    pub fn with_edge_constraint(self, edge_constraint: bool) -> Self {
        Self {
            edge_constraint,
            ..self
        }
    }

    /// The failsafe on distance instead of time: the tracker takes the fix
    /// as lost when the robot has driven more than `max_blind_distance_m`
    /// (m, by odometry) since the last fix, instead of after the
    /// configuration's fix timeout. A reader that reports tags only in
    /// range of the antenna needs it: gaps between tags are normal there
    /// and last as long as the robot takes to reach the next tag, so a
    /// timeout short enough to be safe stops the robot between tags, where
    /// it never reads another; a stopped robot drives no distance, so
    /// waiting for a fix never counts against it. 0 (the default) keeps
    /// the timeout.
    ///
    /// # Errors
    /// [`PoseFilterError::BlindDistance`] unless finite and ≥ 0.
    pub fn with_max_blind_distance(
        self,
        max_blind_distance_m: f32,
    ) -> Result<Self, PoseFilterError> {
        if !(max_blind_distance_m.is_finite() && max_blind_distance_m >= 0.0) {
            return Err(PoseFilterError::BlindDistance);
        }
        Ok(Self {
            max_blind_distance_m,
            ..self
        })
    }

    /// The failsafe's distance limit, m (0: off).
    #[must_use]
    pub fn max_blind_distance_m(&self) -> f32 {
        self.max_blind_distance_m
    }

    /// Runs `kind` instead of the EKF.
    #[must_use]
    pub fn with_filter(self, kind: FusionFilter) -> Self {
        Self { kind, ..self }
    }

    /// The filter it runs.
    #[must_use]
    pub fn kind(&self) -> FusionFilter {
        self.kind
    }

    /// A reader that reports a tag only while the antenna is within
    /// `read_radius_m` of it (m; 0, the default, is the paper's nearest-tag
    /// reader). Each pass over a tag is then one measurement, where the
    /// antenna entered the disc around the tag
    /// ([`TagCellTracker::range_measurement`]); repeated reads within a
    /// pass are skipped (they are not independent) and counted as same-tag
    /// reads.
    ///
    /// # Errors
    /// [`PoseFilterError::ReadRadius`] unless finite and ≥ 0.
    pub fn with_read_radius(self, read_radius_m: f32) -> Result<Self, PoseFilterError> {
        if !(read_radius_m.is_finite() && read_radius_m >= 0.0) {
            return Err(PoseFilterError::ReadRadius);
        }
        Ok(Self {
            read_radius_m,
            ..self
        })
    }

    /// The filter's configuration.
    #[must_use]
    pub fn filter(&self) -> &PoseFilterConfig {
        &self.filter
    }
}

/// The fusion estimator as the tracker runs it: the filter (from the first
/// fix on; the EKF unless [`FusionSettings::with_filter`] chose another),
/// the tag-cell bookkeeping, and paper 001's observer (5) as a guide for
/// the heading.
///
/// An EKF that starts with an unknown heading can lock onto a wrong one:
/// fixes along one axis cannot tell `θ` from `−θ`, and a filter that
/// believes it faces backwards explains the tags with a mirrored track (the
/// Monte Carlo sweep found this in 0.7 % of starts up to 10 m away). Paper
/// 001's observer converges from any heading, and its error is bounded by
/// `b = e^{−L s}` after `s` metres driven (Theorem 1, (10)), so its heading
/// is within `asin b`. Once `b < 0.5` the guide is trusted: if the filter's
/// heading differs from it by more than `asin b + 0.3` rad for a second, or
/// when the filter re-localises, the filter's heading is reset to the
/// guide's with a variance of 0.1² (counted in [`Self::heading_resets`]).
#[derive(Debug, Clone, PartialEq)]
pub struct FusionEstimator {
    settings: FusionSettings,
    filter: Option<RunningFilter>,
    cells: TagCellTracker,
    guide: HeadingObserver,
    guide_position: Option<Vec2>,
    distance_m: f32,
    distance_since_fix_m: f32,
    disagreeing_ticks: u32,
    heading_resets: u32,
}

impl FusionEstimator {
    /// Waiting for its first fix; `guide` is paper 001's observer (5) that
    /// runs beside the filter (see the type's docs).
    #[must_use]
    pub fn new(settings: FusionSettings, guide: HeadingObserver) -> Self {
        Self {
            settings,
            filter: None,
            guide,
            guide_position: None,
            distance_m: 0.0,
            distance_since_fix_m: 0.0,
            disagreeing_ticks: 0,
            heading_resets: 0,
            // The spacing is validated by `FusionSettings::new`.
            cells: TagCellTracker {
                spacing_m: settings.tag_spacing_m,
                last_tag: None,
                same_tag_reads: 0,
                edge_corrections: 0,
                edges: settings.edge_constraint,
            },
        }
    }

    /// The filter, once started.
    #[must_use]
    pub fn filter(&self) -> Option<&RunningFilter> {
        self.filter.as_ref()
    }

    /// The estimated pose, once started.
    #[must_use]
    pub fn pose(&self) -> Option<Pose> {
        self.filter.as_ref().map(RunningFilter::pose)
    }

    /// One tick: predict with the odometry of the last period, then correct
    /// with this tick's fix (`after_gap`: fixes were missing before it, so
    /// a change of tag is no single boundary crossing). Returns the
    /// estimated pose, `None` before the first fix.
    pub fn step(
        &mut self,
        odometry: &OdometryStep,
        fix: Option<Vec2>,
        after_gap: bool,
    ) -> Option<Pose> {
        if let Some(filter) = self.filter.as_mut() {
            filter.predict(odometry);
        }
        if odometry.ds_m.is_finite() {
            self.distance_since_fix_m += odometry.ds_m.abs();
        }
        if let Some(tag) = fix {
            // Driven since the last read: what tells a range reader's
            // repeated read from a new pass over the same tag.
            let travel_m = core::mem::take(&mut self.distance_since_fix_m);
            if after_gap && self.settings.read_radius_m <= 0.0 {
                self.cells.restart();
            }
            let filter = match self.filter.as_mut() {
                Some(filter) => filter,
                None => {
                    // Start at the first tag, heading unknown; the first
                    // measurement (the uniform cell) sets the position.
                    let variances = [1.0, 1.0, PI_SQUARED, self.settings.scale_prior];
                    let start = Pose::new(tag.x, tag.y, 0.0);
                    let filter = RunningFilter::new(&self.settings, start, variances)?;
                    self.filter.insert(filter)
                }
            };
            let pose = filter.pose();
            let relocalisations = filter.counters().relocalisations;
            let radius = self.settings.read_radius_m;
            if radius > 0.0 {
                if let Some(measurement) =
                    self.cells
                        .range_measurement(tag, pose.heading_rad, travel_m, radius)
                {
                    filter.correct(&measurement);
                }
            } else {
                let last_step = Vec2::new(
                    odometry.ds_m * math::cos(pose.heading_rad),
                    odometry.ds_m * math::sin(pose.heading_rad),
                );
                for measurement in self.cells.measurements(tag, last_step, pose.position) {
                    filter.correct(&measurement);
                }
            }
            let relocalised = filter.counters().relocalisations != relocalisations;
            self.follow_guide(odometry, Some(tag), relocalised);
        } else {
            self.follow_guide(odometry, None, false);
        }
        self.pose()
    }

    /// Updates the guide observer from the fixes (dead-reckoned on its own
    /// heading between them, as the tracker does for observer (5)) and
    /// resets the filter's heading to it where the type's docs say.
    fn follow_guide(&mut self, odometry: &OdometryStep, tag: Option<Vec2>, relocalised: bool) {
        let guide_heading = self.guide.estimate().heading_rad();
        let now = match (tag, self.guide_position) {
            (Some(tag), _) => Some(tag),
            (None, Some(p)) => {
                let next = Pose {
                    position: p,
                    heading_rad: guide_heading,
                }
                .advance_arc(odometry.ds_m, odometry.dtheta_rad)
                .position;
                Some(if next.is_finite() { next } else { p })
            }
            (None, None) => None,
        };
        if let (Some(previous), Some(now)) = (self.guide_position, now) {
            self.guide.update(odometry.body, now - previous);
            if odometry.ds_m.is_finite() {
                self.distance_m += odometry.ds_m.abs();
            }
        }
        self.guide_position = now;
        // |z̃| ≤ e^{−L s}: the guide's heading is within asin of that.
        let bound = math::exp(-self.distance_m * self.guide.config().gain_per_m());
        let Some(filter) = self.filter.as_mut() else {
            return;
        };
        if bound.is_nan() || bound >= GUIDE_TRUST_BOUND {
            return;
        }
        let guide_error = math::atan(bound / math::sqrt(1.0 - bound * bound));
        let guide_heading = self.guide.estimate().heading_rad();
        let difference = math::wrap_angle(filter.pose().heading_rad - guide_heading).abs();
        self.disagreeing_ticks = if difference > guide_error + GUIDE_MARGIN_RAD {
            self.disagreeing_ticks.saturating_add(1)
        } else {
            0
        };
        if relocalised || self.disagreeing_ticks >= GUIDE_PATIENCE_TICKS {
            if filter.reset_heading(guide_heading, 0.01) {
                self.heading_resets = self.heading_resets.saturating_add(1);
            }
            self.disagreeing_ticks = 0;
        }
    }

    /// The distance driven (by odometry) since the last fix, m.
    #[must_use]
    pub fn distance_since_fix_m(&self) -> f32 {
        self.distance_since_fix_m
    }

    /// Whether the distance failsafe
    /// ([`FusionSettings::with_max_blind_distance`]) takes the fix as
    /// lost: `None` if it is off (the tracker's timeout decides),
    /// otherwise whether the robot drove more than the limit since the
    /// last fix.
    #[must_use]
    pub fn blind_distance_lost(&self) -> Option<bool> {
        let limit = self.settings.max_blind_distance_m;
        (limit > 0.0).then_some(self.distance_since_fix_m > limit)
    }

    /// Times the filter's heading was reset to the guide's.
    #[must_use]
    pub fn heading_resets(&self) -> u32 {
        self.heading_resets
    }

    /// The filter's counters (zero before the first fix).
    #[must_use]
    pub fn counters(&self) -> PoseFilterCounters {
        self.filter
            .as_ref()
            .map(RunningFilter::counters)
            .unwrap_or_default()
    }
}

// nalgebra's matrices have no `defmt::Format`: log what matters.
#[cfg(feature = "defmt")]
impl defmt::Format for FusionEstimator {
    fn format(&self, f: defmt::Formatter) {
        defmt::write!(
            f,
            "FusionEstimator {{ pose: {}, counters: {}, heading_resets: {} }}",
            self.pose(),
            self.counters(),
            self.heading_resets
        );
    }
}

/// The filter a [`FusionEstimator`] runs ([`FusionFilter`]).
#[derive(Debug, Clone, PartialEq)]
// The variants differ in size by the particles; there is no heap to box
// them into, and only one is built per robot.
#[allow(clippy::large_enum_variant)]
pub enum RunningFilter {
    /// The EKF.
    Ekf(PoseEkf),
    /// The UKF.
    #[cfg(feature = "fusion-ukf")]
    Ukf(crate::estimation::fusion::ukf::PoseUkf),
    /// The particle filter.
    #[cfg(feature = "fusion-particle-filter")]
    ParticleFilter(crate::estimation::fusion::particle::PoseParticleFilter),
}

/// `$body` with `$f` bound to the running [`PoseFilter`], whatever its core.
macro_rules! with_filter {
    ($running:expr, $f:ident => $body:expr) => {
        match $running {
            RunningFilter::Ekf($f) => $body,
            #[cfg(feature = "fusion-ukf")]
            RunningFilter::Ukf($f) => $body,
            #[cfg(feature = "fusion-particle-filter")]
            RunningFilter::ParticleFilter($f) => $body,
        }
    };
}

impl RunningFilter {
    /// The filter `settings` choose, at `start` with `variances` (as
    /// [`PoseFilter::new`]); `None` if it cannot start there.
    pub fn new(settings: &FusionSettings, start: Pose, variances: [f32; 4]) -> Option<Self> {
        let config = settings.filter;
        Some(match settings.kind {
            FusionFilter::Ekf => Self::Ekf(PoseFilter::new(config, start, variances).ok()?),
            #[cfg(feature = "fusion-ukf")]
            FusionFilter::Ukf => Self::Ukf(PoseFilter::new(config, start, variances).ok()?),
            #[cfg(feature = "fusion-particle-filter")]
            FusionFilter::ParticleFilter => {
                Self::ParticleFilter(PoseFilter::new(config, start, variances).ok()?)
            }
        })
    }

    /// [`PoseFilter::predict`].
    pub fn predict(&mut self, odometry: &OdometryStep) {
        with_filter!(self, f => f.predict(odometry));
    }

    /// [`PoseFilter::correct`].
    pub fn correct(&mut self, measurement: &PositionMeasurement) -> FixOutcome {
        with_filter!(self, f => f.correct(measurement))
    }

    /// [`PoseFilter::pose`].
    #[must_use]
    pub fn pose(&self) -> Pose {
        with_filter!(self, f => f.pose())
    }

    /// [`PoseFilter::covariance`].
    #[must_use]
    pub fn covariance(&self) -> PoseCovariance {
        with_filter!(self, f => f.covariance())
    }

    /// [`PoseFilter::wheel_scale_errors`].
    #[must_use]
    pub fn wheel_scale_errors(&self) -> [f32; 2] {
        with_filter!(self, f => f.wheel_scale_errors())
    }

    /// [`PoseFilter::counters`].
    #[must_use]
    pub fn counters(&self) -> PoseFilterCounters {
        with_filter!(self, f => f.counters())
    }

    /// [`PoseFilter::reset_heading`].
    pub fn reset_heading(&mut self, heading_rad: f32, variance_rad2: f32) -> bool {
        with_filter!(self, f => f.reset_heading(heading_rad, variance_rad2))
    }
}

const PI_SQUARED: f32 = core::f32::consts::PI * core::f32::consts::PI;

/// The variance of a range reader's entry point along the heading, in
/// units of `r²`: `2/3 − π²/16` (module docs of
/// [`TagCellTracker::range_measurement`]).
const ENTRY_ALONG_VARIANCE: f32 = 2.0 / 3.0 - PI_SQUARED / 16.0;

/// Ticks of disagreement with a trusted guide before the heading is reset
/// (a second at 100 Hz).
const GUIDE_PATIENCE_TICKS: u32 = 100;
/// The guide is trusted once its error bound `e^{−L s}` is below this
/// (its heading then within 30°).
const GUIDE_TRUST_BOUND: f32 = 0.5;
/// How far beyond the guide's own error bound the filter's heading may
/// stray before it counts as disagreeing, rad.
const GUIDE_MARGIN_RAD: f32 = 0.3;

/// What the pose filters' property tests share.
#[cfg(test)]
pub(crate) mod test_support {
    use super::*;

    /// Measurement kind `kind % 5` at `(x, y)`: a point, an axis, an
    /// ellipse, or a non-finite one.
    pub(crate) fn measurement(x: f32, y: f32, kind: u8) -> PositionMeasurement {
        match kind % 5 {
            0 => PositionMeasurement::Point {
                position: Vec2::new(x, y),
                variance_m2: [1e-4, 1e-4],
            },
            1 => PositionMeasurement::X {
                value_m: x,
                variance_m2: 1e-6,
            },
            2 => PositionMeasurement::Y {
                value_m: y,
                variance_m2: 1e-6,
            },
            3 => PositionMeasurement::Ellipse {
                position: Vec2::new(x, y),
                covariance_m2: [1e-4, 5e-5, 1e-4],
            },
            _ => PositionMeasurement::X {
                value_m: f32::INFINITY,
                variance_m2: 1e-6,
            },
        }
    }

    /// Feeds `filter` odometry steps `(Δs, Δθ, Δs is NaN)` and, cycling,
    /// fixes `(x, y, kind)`; `true` if its pose and covariance stayed
    /// finite throughout.
    pub(crate) fn stays_finite<Core: PoseFilterCore>(
        filter: &mut PoseFilter<Core>,
        steps: &[(f32, f32, bool)],
        fixes: &[(f32, f32, u8)],
    ) -> bool {
        steps
            .iter()
            .zip(fixes.iter().cycle())
            .all(|(&(ds, dth, nan), &(x, y, kind))| {
                filter.predict(&OdometryStep {
                    ds_m: if nan { f32::NAN } else { ds },
                    dtheta_rad: dth,
                    ..OdometryStep::default()
                });
                filter.correct(&measurement(x, y, kind));
                let p = filter.pose();
                p.position.is_finite()
                    && p.heading_rad.is_finite()
                    && filter.covariance().iter().all(|v| v.is_finite())
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn config() -> PoseFilterConfig {
        PoseFilterConfig::new(0.2, 1e-4, 1e-8, 3.0).unwrap()
    }

    #[test]
    fn gate_thresholds_are_chi_square_quantiles() {
        let (one, two) = config().gate_thresholds();
        assert!((one - 9.0).abs() < 1e-6);
        // χ²₂ quantile at 0.9973 = −2 ln(0.0026998) = 11.829.
        assert!((two - 11.829).abs() < 2e-3, "{two}");
        assert_eq!(
            PoseFilterConfig::new(0.2, 1e-4, 0.0, 0.5),
            Err(PoseFilterError::Gate)
        );
        assert_eq!(
            PoseFilterConfig::new(0.0, 1e-4, 0.0, 3.0),
            Err(PoseFilterError::TrackWidth)
        );
        assert_eq!(
            PoseFilterConfig::new(0.2, -1.0, 0.0, 3.0),
            Err(PoseFilterError::WheelNoise)
        );
    }

    #[test]
    fn outliers_are_gated_and_counted() {
        let mut ekf =
            PoseEkf::new(config(), Pose::new(0.0, 0.0, 0.0), [1e-4, 1e-4, 1e-2, 0.0]).unwrap();
        let far = PositionMeasurement::Point {
            position: Vec2::new(1.0, 0.0),
            variance_m2: [1e-4, 1e-4],
        };
        assert_eq!(ekf.correct(&far), FixOutcome::Gated);
        let near = PositionMeasurement::X {
            value_m: 0.01,
            variance_m2: 1e-4,
        };
        assert_eq!(ekf.correct(&near), FixOutcome::Used);
        let nan = PositionMeasurement::Y {
            value_m: f32::NAN,
            variance_m2: 1e-4,
        };
        assert_eq!(ekf.correct(&nan), FixOutcome::Invalid);
        let c = ekf.counters();
        assert_eq!((c.fixes_used, c.fixes_gated, c.fixes_invalid), (1, 1, 1));
        assert!(ekf.pose().position.x > 0.0 && ekf.pose().position.x < 0.01);
    }

    #[test]
    fn driving_straight_moves_the_estimate_and_grows_the_variance() {
        let mut ekf = PoseEkf::new(config(), Pose::new(0.0, 0.0, 0.5), [0.0; 4]).unwrap();
        let step = OdometryStep {
            ds_m: 0.01,
            ..OdometryStep::default()
        };
        for _ in 0..100 {
            ekf.predict(&step);
        }
        let p = ekf.pose();
        assert!((p.position.x - math::cos(0.5)).abs() < 1e-4, "{p:?}");
        assert!((p.position.y - math::sin(0.5)).abs() < 1e-4, "{p:?}");
        let c = ekf.covariance();
        assert!(c[(0, 0)] > 0.0 && c[(2, 2)] > 0.0);
        ekf.predict(&OdometryStep {
            ds_m: f32::NAN,
            ..OdometryStep::default()
        });
        assert_eq!(ekf.counters().rejected_predictions, 1);
    }

    #[test]
    fn tag_changes_become_boundary_crossings() {
        let mut cells = TagCellTracker::new(0.1).unwrap().with_edge_constraint(true);
        let first = cells.measurements(Vec2::new(0.0, 0.0), Vec2::new(0.001, 0.0), Vec2::ZERO);
        assert!(matches!(
            first.first(),
            Some(PositionMeasurement::Point { .. })
        ));
        assert!(
            cells
                .measurements(Vec2::new(0.0, 0.0), Vec2::new(0.001, 0.0), Vec2::ZERO)
                .is_empty()
        );
        assert_eq!(cells.same_tag_reads(), 1);
        let crossing = cells.measurements(Vec2::new(0.1, 0.0), Vec2::new(0.002, 0.0), Vec2::ZERO);
        match crossing.first() {
            Some(PositionMeasurement::X {
                value_m,
                variance_m2,
            }) => {
                assert!((value_m - 0.051).abs() < 1e-6, "{value_m}");
                assert!(*variance_m2 < 1e-5);
            }
            other => panic!("{other:?}"),
        }
        // A jump of two cells is not a crossing.
        let jump = cells.measurements(Vec2::new(0.3, 0.0), Vec2::new(0.002, 0.0), Vec2::ZERO);
        assert!(matches!(
            jump.first(),
            Some(PositionMeasurement::Point { .. })
        ));
    }

    proptest! {
        /// Finite input keeps the state finite and the covariance symmetric
        /// with a non-negative diagonal.
        #[test]
        fn finite_in_finite_out(
            steps in proptest::collection::vec((-0.05f32..0.05, -0.1f32..0.1), 1..50),
            fixes in proptest::collection::vec((-10.0f32..10.0, -10.0f32..10.0), 1..10),
            theta in -10.0f32..10.0,
        ) {
            let mut ekf = PoseEkf::new(config(), Pose::new(0.0, 0.0, theta), [1.0, 1.0, 10.0, 1e-4]).unwrap();
            for (i, &(ds, dth)) in steps.iter().enumerate() {
                ekf.predict(&OdometryStep { ds_m: ds, dtheta_rad: dth, ..OdometryStep::default() });
                if let Some(&(x, y)) = fixes.get(i) {
                    ekf.correct(&PositionMeasurement::Point {
                        position: Vec2::new(x, y),
                        variance_m2: [1e-3, 1e-3],
                    });
                }
                let p = ekf.pose();
                prop_assert!(p.position.is_finite() && p.heading_rad.is_finite());
                let c = ekf.covariance();
                prop_assert!((c - c.transpose()).amax() <= 1e-6 * (1.0 + c.amax()));
                prop_assert!((0..5).all(|i| c[(i, i)] >= 0.0));
            }
        }
    }

    #[test]
    fn range_reads_are_one_measurement_per_pass() {
        let mut cells = TagCellTracker::new(0.3).unwrap();
        let tag = Vec2::new(1.0, 2.0);
        // Heading +x: the entry point is π r/4 short of the tag along x.
        let Some(PositionMeasurement::Ellipse {
            position,
            covariance_m2: [xx, xy, yy],
        }) = cells.range_measurement(tag, 0.0, 0.0, 0.05)
        else {
            panic!("first read");
        };
        assert!((position.x - (1.0 - core::f32::consts::FRAC_PI_4 * 0.05)).abs() < 1e-6);
        assert!((position.y - 2.0).abs() < 1e-6);
        // Sharp along the heading (x), wide across it.
        let r2 = 0.05 * 0.05;
        assert!((xx - (2.0 / 3.0 - PI_SQUARED / 16.0) * r2).abs() < 1e-9);
        assert!((yy - r2 / 3.0).abs() < 1e-9 && xy.abs() < 1e-9);
        // Heading +y: the ellipse turns with it.
        let mut turned = TagCellTracker::new(0.3).unwrap();
        let Some(PositionMeasurement::Ellipse {
            covariance_m2: [txx, _, tyy],
            ..
        }) = turned.range_measurement(tag, core::f32::consts::FRAC_PI_2, 0.0, 0.05)
        else {
            panic!("first read");
        };
        assert!((txx - yy).abs() < 1e-8 && (tyy - xx).abs() < 1e-8);
        // Repeats while in range: nothing, counted.
        assert!(cells.range_measurement(tag, 0.0, 0.02, 0.05).is_none());
        assert_eq!(cells.same_tag_reads(), 1);
        // The same tag after driving more than 2r: a new pass.
        assert!(cells.range_measurement(tag, 0.0, 0.2, 0.05).is_some());
        assert!(
            cells
                .range_measurement(Vec2::new(f32::NAN, 0.0), 0.0, 1.0, 0.05)
                .is_none()
        );
    }
}
