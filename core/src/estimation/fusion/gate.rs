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
//! The gate, the counters, re-localisation and heading resets are the same
//! for every filter and live in [`PoseFilter`], around a filter core
//! ([`PoseFilterCore`]): [`crate::estimation::fusion::ekf`],
//! [`crate::estimation::fusion::ukf`] or
//! [`crate::estimation::fusion::particle`].

use nalgebra::{Matrix2, SMatrix, SVector, Vector2};

use crate::estimation::fusion::config::{PoseFilterConfig, PoseFilterError};
use crate::geometry::{Pose, Vec2};
use crate::math;
use crate::odometry::OdometryStep;

/// The filter's state size: `(x, y, θ, ε_R, ε_L)`.
pub(crate) const STATES: usize = 5;

/// `π²`, rad².
pub(crate) const PI_SQUARED: f32 = core::f32::consts::PI * core::f32::consts::PI;

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

    /// Finite, with positive variances (and a positive definite ellipse).
    pub(crate) fn is_finite(&self) -> bool {
        let (values, positive) = match *self {
            Self::Ellipse {
                position,
                covariance_m2: [xx, xy, yy],
            } => (
                [position.x, position.y, xx, xy, yy],
                xx > 0.0 && yy > 0.0 && xx * yy - xy * xy > 0.0,
            ),
            Self::Point {
                position,
                variance_m2: [vx, vy],
            } => ([position.x, position.y, vx, vy, 0.0], vx > 0.0 && vy > 0.0),
            Self::X {
                value_m,
                variance_m2,
            }
            | Self::Y {
                value_m,
                variance_m2,
            } => ([value_m, variance_m2, 0.0, 0.0, 0.0], variance_m2 > 0.0),
        };
        positive && all_finite(&values)
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

    /// Re-localisation ([`PoseFilter`]'s, after consecutive gated
    /// measurements, before the ungated correction with `measurement`):
    /// `mean` and `covariance` are the belief the filter can still claim
    /// (its position widened to the measurement, its heading to at least
    /// `(π/2)²`, cross-covariances cleared); `false` (and nothing changed)
    /// if the core cannot take it. By default a restart there
    /// ([`Self::reset`]); the particle filter overrides it to keep what its
    /// particles know.
    fn relocalise(
        &mut self,
        mean: &PoseState,
        covariance: &PoseCovariance,
        measurement: &PositionMeasurement,
    ) -> bool {
        let _ = measurement;
        self.reset(mean, covariance)
    }

    /// [`Self::start`] in place: this core becomes the one `start` would
    /// return; `false` (and nothing changed) if it cannot start there.
    /// Built and moved in by default; a large core (the particle filter's
    /// 5 KB) overrides it to start where it lives, without a second core
    /// on the stack.
    fn start_in_place(
        &mut self,
        config: &PoseFilterConfig,
        mean: &PoseState,
        covariance: &PoseCovariance,
    ) -> bool {
        match Self::start(config, mean, covariance) {
            Some(core) => {
                *self = core;
                true
            }
            None => false,
        }
    }

    /// The configuration changed (the wheel noise adapted,
    /// [`crate::estimation::fusion::noise_adaptation`]). Nothing by default: the EKF and the UKF take it at each
    /// [`Self::predict`]; the particle filter's motion model keeps a copy.
    fn reconfigure(&mut self, config: &PoseFilterConfig) {
        let _ = config;
    }
}

/// A pose filter on odometry and position fixes (module docs): the filter
/// `Core` ([`EkfCore`](crate::estimation::fusion::ekf::EkfCore), or the UKF and particle filter of
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
        let (mean, covariance) = initial_belief(initial, variances)?;
        let core =
            Core::start(&config, &mean, &covariance).ok_or(PoseFilterError::InitialVariance)?;
        Ok(Self::with_core(config, core))
    }

    /// [`Self::new`] in place: this filter becomes the one `new` would
    /// return (counters zeroed), its core started where it lives
    /// ([`PoseFilterCore::start_in_place`]).
    ///
    /// # Errors
    /// As [`Self::new`]; the filter is then unchanged.
    pub fn restart(
        &mut self,
        config: PoseFilterConfig,
        initial: Pose,
        variances: [f32; 4],
    ) -> Result<(), PoseFilterError> {
        let (mean, covariance) = initial_belief(initial, variances)?;
        if !self.core.start_in_place(&config, &mean, &covariance) {
            return Err(PoseFilterError::InitialVariance);
        }
        self.config = config;
        self.counters = PoseFilterCounters::default();
        self.consecutive_gated = [0; 2];
        Ok(())
    }

    /// A filter around `core` as it is, counters zeroed.
    #[inline(always)]
    pub(crate) fn with_core(config: PoseFilterConfig, core: Core) -> Self {
        Self {
            config,
            core,
            counters: PoseFilterCounters::default(),
            consecutive_gated: [0; 2],
        }
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

    /// The normalised innovation squared `d² = y²/S` of a measurement of
    /// one axis against the belief now (the gate's, module docs); `None`
    /// for a 2-D measurement or if it cannot be formed.
    #[must_use]
    pub fn axis_innovation(&self, measurement: &PositionMeasurement) -> Option<f32> {
        match measurement {
            PositionMeasurement::X { .. } | PositionMeasurement::Y { .. } => {
                mahalanobis(&self.core.mean(), &self.core.covariance(), measurement)
                    .map(|(d2, _)| d2)
            }
            PositionMeasurement::Point { .. } | PositionMeasurement::Ellipse { .. } => None,
        }
    }

    /// Sets the wheel noise per metre the predictions use from now on
    /// (m²/m, finite and ≥ 0; anything else is ignored).
    pub(crate) fn set_wheel_variance_per_m(&mut self, variance_per_m: f32) {
        if variance_per_m.is_finite() && variance_per_m >= 0.0 {
            self.config.variance_per_m = variance_per_m;
            self.core.reconfigure(&self.config);
        }
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
        self.correct_with(measurement, |core| core.update(measurement))
    }

    /// [`Self::correct`] with the core's update made by `update` instead of
    /// [`PoseFilterCore::update`]: the gate, the re-localisation and the
    /// counters work on `measurement` (a Gaussian), the correction on what
    /// `update` applies (e.g. the exact likelihood of a tag's cell, whose
    /// moments `measurement` carries; `false`: it could not be used).
    pub fn correct_with(
        &mut self,
        measurement: &PositionMeasurement,
        mut update: impl FnMut(&mut Core) -> bool,
    ) -> FixOutcome {
        let mut outcome = self.correct_once(measurement, true, &mut update);
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
                outcome = self.correct_once(measurement, false, &mut update);
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
            let _ = self.core.relocalise(&mean, &covariance, measurement);
        }
    }

    /// The gate on the Mahalanobis distance of the innovation (module
    /// docs), computed from the core's mean and covariance (exact for every
    /// filter here: the measurement is linear), then the core's update.
    fn correct_once(
        &mut self,
        measurement: &PositionMeasurement,
        gate: bool,
        update: &mut impl FnMut(&mut Core) -> bool,
    ) -> FixOutcome {
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
        if update(&mut self.core) {
            FixOutcome::Used
        } else {
            FixOutcome::Invalid
        }
    }
}

/// The mean and covariance [`PoseFilter::new`] starts from (its docs);
/// [`PoseFilterError::InitialVariance`] for a pose or variance that is not
/// finite, or a negative variance.
fn initial_belief(
    initial: Pose,
    variances: [f32; 4],
) -> Result<(PoseState, PoseCovariance), PoseFilterError> {
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
    Ok((mean, covariance))
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
            let [y0, y1] = [position.x - mean.x, position.y - mean.y];
            // S = H P Hᵀ + R: P's x/y block plus R; S⁻¹ in closed form.
            let c = covariance;
            let [[i00, i01], [i10, i11]] = inverse_2x2([
                [c.m11 + r.m11, c.m12 + r.m12],
                [c.m21 + r.m21, c.m22 + r.m22],
            ])?;
            // (ỹᵀ S⁻¹) ỹ, in the order of the dense matrix product.
            let (row0, row1) = (y0 * i00 + y1 * i10, y0 * i01 + y1 * i11);
            (row0 * y0 + row1 * y1, 2)
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

/// The inverse of the 2×2 matrix of rows `s` by its closed form,
/// `[[s11, −s01], [−s10, s00]] / det` (`None` if `det = 0`): the 2-D
/// innovation covariance `S` of a fix needs no general inverse. The same
/// arithmetic as nalgebra's `try_inverse` for 2×2.
pub(crate) fn inverse_2x2(s: [[f32; 2]; 2]) -> Option<[[f32; 2]; 2]> {
    let [[s00, s01], [s10, s11]] = s;
    let determinant = s00 * s11 - s10 * s01;
    (determinant != 0.0).then(|| {
        [
            [s11 / determinant, -s01 / determinant],
            [-s10 / determinant, s00 / determinant],
        ]
    })
}

/// Whether every value is finite, by one float sum: `v − v` is 0 for a
/// finite `v` and NaN for an infinite or NaN one, and a NaN stays in the
/// sum (smaller code than a bit test per value).
// `v − v` is the point here.
#[allow(clippy::eq_op)]
pub(crate) fn all_finite(values: &[f32]) -> bool {
    values.iter().fold(0.0, |sum, v| sum + (v - v)) == 0.0
}
