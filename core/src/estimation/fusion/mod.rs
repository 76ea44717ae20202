//! An extended Kalman filter of the pose `(x, y, θ)` that propagates with
//! the encoder odometry every tick and corrects with RFID tag fixes when
//! they arrive, gating each fix on its Mahalanobis distance (the fusion
//! estimator; the filter machinery follows paper 004's EKF, Joseph form
//! and all).
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
//! # Where each part lives
//! * [`config`]: the filter's parameters ([`PoseFilterConfig`]).
//! * [`odometry_noise`]: the prediction (every tick): the odometry arc
//!   through the wheel-scale estimate, its Jacobian and its noise.
//! * [`gate`]: the correction (when a fix arrives): measurements, the
//!   Mahalanobis gate, counters and re-localisation around any filter core
//!   ([`PoseFilter`], [`PoseFilterCore`]).
//! * [`tag_cells`]: tag fixes as the measurements they carry
//!   ([`TagCellTracker`]).
//! * [`truncation`]: a Gaussian estimate truncated to a tag's cell, as a
//!   measurement (a stray estimate's correction).
//! * [`noise_adaptation`]: the filters' wheel noise raised when the
//!   crossings' innovations say the configured one is too small
//!   ([`WheelNoiseAdaptation`]).
//! * [`ekf`], [`ukf`], [`particle`]: the three filter cores.
//! * This module: the estimator the tracker runs ([`FusionSettings`],
//!   [`FusionEstimator`]) and its choice of filter ([`FusionFilter`]).
//!
//! # Angle convention
//! `θ̂` is kept wrapped to (−π, π] after each step; its Jacobians use only
//! sines and cosines, so the wrap never enters a difference.
//!
//! # Bad input
//! A non-finite odometry step or fix is counted and ignored; a prediction
//! or update whose result is not finite (or whose `S` cannot be inverted)
//! leaves the state unchanged and is counted.

pub mod config;
pub mod ekf;
pub mod gate;
pub mod noise_adaptation;
pub mod odometry_noise;
pub mod particle;
pub mod tag_cells;
pub mod truncation;
pub mod ukf;

pub use config::{PoseFilterConfig, PoseFilterError};
pub use ekf::{EkfCore, PoseEkf};
pub use gate::{
    FixOutcome, PoseCovariance, PoseFilter, PoseFilterCore, PoseFilterCounters, PoseState,
    PositionMeasurement,
};
pub use noise_adaptation::{InnovationTest, WheelNoiseAdaptation};
pub use tag_cells::{CellMeasurements, CellReading, TagCellTracker};

use crate::estimation::fusion::gate::PI_SQUARED;
use crate::estimation::heading_observer::HeadingObserver;
use crate::estimation::interface::{EstimatorCounters, PoseEstimator};
use crate::geometry::HeadingEstimate;
use crate::geometry::{Pose, Vec2};
use crate::math;
use crate::odometry::OdometryStep;
use crate::plausible::{READ_RADIUS_M, TAG_SPACING_M};

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

impl FusionFilter {
    /// What the filter's crossings are judged by when its wheel noise is
    /// adapted ([`noise_adaptation`]): the mean `d²` for the EKF and the
    /// UKF, the share beyond two standard deviations for the particle
    /// filter.
    #[must_use]
    pub const fn innovation_test(self) -> InnovationTest {
        match self {
            #[cfg(feature = "fusion-particle-filter")]
            Self::ParticleFilter => InnovationTest::ShareBeyondTwoSigma,
            _ => InnovationTest::MeanNis,
        }
    }

    /// The filter's name in reports: `fusion EKF`, `fusion UKF` or
    /// `fusion particle filter`.
    #[must_use]
    pub fn label(self) -> &'static str {
        match self {
            Self::Ekf => "fusion EKF",
            #[cfg(feature = "fusion-ukf")]
            Self::Ukf => "fusion UKF",
            #[cfg(feature = "fusion-particle-filter")]
            Self::ParticleFilter => "fusion particle filter",
        }
    }
}

/// Validated settings of the tracker's fusion estimator
/// (`EstimatorChoice::Fusion`, cargo feature `fusion-ekf`).
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
    fix_age_ticks: f32,
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
        if !TAG_SPACING_M.contains(tag_spacing_m) {
            return Err(PoseFilterError::TagSpacing);
        }
        Self::on_floor(filter, tag_spacing_m, 0.0, scale_prior)
    }

    /// The filter on a floor whose tags lie anywhere (a surveyed tag map,
    /// no grid) and a reader that reports a tag only while the antenna is
    /// within `read_radius_m` of it (m, > 0), with the prior variance of
    /// each wheel's scale error. Each pass over a tag is one measurement
    /// of where the antenna entered the tag's disc
    /// ([`TagCellTracker::range_measurement`]), which needs no grid; the
    /// nearest-tag reader's cell measurements do, so it is refused here.
    /// The failsafe keeps the fix timeout until
    /// [`Self::with_max_blind_distance`] sets a distance, which a floor
    /// with gaps between its tags needs (see there).
    ///
    /// # Errors
    /// [`PoseFilterError::TagMapReader`] unless `read_radius_m` is > 0,
    /// [`PoseFilterError::ReadRadius`] outside [`READ_RADIUS_M`],
    /// [`PoseFilterError::InitialVariance`].
    pub fn on_tag_map(
        filter: PoseFilterConfig,
        read_radius_m: f32,
        scale_prior: f32,
    ) -> Result<Self, PoseFilterError> {
        if read_radius_m.is_nan() || read_radius_m <= 0.0 {
            return Err(PoseFilterError::TagMapReader);
        }
        if !READ_RADIUS_M.contains(read_radius_m) {
            return Err(PoseFilterError::ReadRadius);
        }
        Self::on_floor(filter, 0.0, read_radius_m, scale_prior)
    }

    /// [`Self::new`] and [`Self::on_tag_map`] after their floor's checks:
    /// the EKF, no blind distance, no edge constraint.
    fn on_floor(
        filter: PoseFilterConfig,
        tag_spacing_m: f32,
        read_radius_m: f32,
        scale_prior: f32,
    ) -> Result<Self, PoseFilterError> {
        if !(scale_prior.is_finite() && scale_prior >= 0.0) {
            return Err(PoseFilterError::InitialVariance);
        }
        Ok(Self {
            filter,
            kind: FusionFilter::Ekf,
            tag_spacing_m,
            scale_prior,
            read_radius_m,
            max_blind_distance_m: 0.0,
            edge_constraint: false,
            fix_age_ticks: 0.0,
        })
    }

    /// Whether the floor is a grid (built by [`Self::new`]) rather than a
    /// tag map ([`Self::on_tag_map`]).
    #[must_use]
    pub fn on_grid(&self) -> bool {
        self.tag_spacing_m > 0.0
    }

    /// Reads of an unchanged tag pull an estimate that has left the tag's
    /// cell back to its edge ([`TagCellTracker::with_edge_constraint`];
    /// nearest-tag reader only; default off). Under random wheel slip,
    /// with a wheel-noise model near the slip's, it is what lets the
    /// filter see the lateral drift along a row of tags (figures in docs/fusion.md).
    #[must_use]
    pub fn with_edge_constraint(self, edge_constraint: bool) -> Self {
        Self {
            edge_constraint,
            ..self
        }
    }

    /// The age of each fix when the tick that uses it runs, in control
    /// periods: from the reader's read to the tick's poll (its processing,
    /// the frame's time on the UART, the wait for the poll). Each
    /// measurement is moved that many ticks of the last tick's travel on
    /// ([`TagCellTracker::with_fix_age_ticks`], "The fix's age" in
    /// [`tag_cells`]). Default 0: the fix is of the tick's own position.
    ///
    /// # Errors
    /// [`PoseFilterError::FixAge`] unless finite and in
    /// `[0, MAX_FIX_AGE_TICKS]` ([`MAX_FIX_AGE_TICKS`]).
    pub fn with_fix_age_ticks(self, fix_age_ticks: f32) -> Result<Self, PoseFilterError> {
        if !(fix_age_ticks.is_finite() && (0.0..=MAX_FIX_AGE_TICKS).contains(&fix_age_ticks)) {
            return Err(PoseFilterError::FixAge);
        }
        Ok(Self {
            fix_age_ticks,
            ..self
        })
    }

    /// The fix's age, control periods.
    #[must_use]
    pub fn fix_age_ticks(&self) -> f32 {
        self.fix_age_ticks
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
    /// [`PoseFilterError::ReadRadius`] unless finite and ≥ 0;
    /// [`PoseFilterError::TagMapReader`] for 0 on a tag map
    /// ([`Self::on_tag_map`]).
    pub fn with_read_radius(self, read_radius_m: f32) -> Result<Self, PoseFilterError> {
        if !READ_RADIUS_M.contains(read_radius_m) {
            return Err(PoseFilterError::ReadRadius);
        }
        if read_radius_m == 0.0 && !self.on_grid() {
            return Err(PoseFilterError::TagMapReader);
        }
        Ok(Self {
            read_radius_m,
            ..self
        })
    }

    /// The position variance per axis the filter starts with at the first
    /// fix, m²: 1 for the EKF and the UKF (the first measurement, the
    /// uniform cell, then sets it), the cell's own `s²/12` for the particle
    /// filter (its particles start in the cell rather than spread over a
    /// metre, where a 10 cm cell would hold none of 100).
    fn start_position_variance(&self) -> f32 {
        #[cfg(feature = "fusion-particle-filter")]
        if self.kind == FusionFilter::ParticleFilter && self.read_radius_m <= 0.0 {
            return self.tag_spacing_m * self.tag_spacing_m / 12.0;
        }
        1.0
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
    /// The filter: [`RunningFilter::Waiting`], or the particle filter not
    /// yet started, until the first fix (`started`).
    filter: RunningFilter,
    /// Whether `filter` started (at the first fix).
    started: bool,
    cells: TagCellTracker,
    guide: HeadingObserver,
    guide_position: Option<Vec2>,
    distance_m: f32,
    distance_since_fix_m: f32,
    disagreeing_ticks: u32,
    heading_resets: u32,
    /// The wheel noise's scale from the crossings ([`noise_adaptation`]).
    noise: WheelNoiseAdaptation,
    /// A heading known from outside before the first fix
    /// ([`PoseEstimator::assume_heading`]): the filter starts with it.
    start_heading_rad: Option<f32>,
}

impl FusionEstimator {
    /// Waiting for its first fix; `guide` is paper 001's observer (5) that
    /// runs beside the filter (see the type's docs).
    #[must_use]
    pub fn new(settings: FusionSettings, guide: HeadingObserver) -> Self {
        Self {
            settings,
            filter: RunningFilter::Waiting,
            started: false,
            guide,
            guide_position: None,
            distance_m: 0.0,
            distance_since_fix_m: 0.0,
            disagreeing_ticks: 0,
            heading_resets: 0,
            noise: WheelNoiseAdaptation::new(settings.kind().innovation_test()),
            start_heading_rad: None,
            // The spacing is validated by `FusionSettings::new`.
            cells: TagCellTracker::with_validated(
                settings.tag_spacing_m,
                settings.edge_constraint,
                settings.fix_age_ticks,
            ),
        }
    }

    /// The filter, once started.
    #[must_use]
    pub fn filter(&self) -> Option<&RunningFilter> {
        self.started.then_some(&self.filter)
    }

    /// The filter, once started.
    fn filter_mut(&mut self) -> Option<&mut RunningFilter> {
        self.started.then_some(&mut self.filter)
    }

    /// The estimated pose, once started.
    #[must_use]
    pub fn pose(&self) -> Option<Pose> {
        self.filter().map(RunningFilter::pose)
    }

    /// One tick: predict with the odometry of the last period, then correct
    /// with this tick's fix (`after_gap`: fixes were missing before it, so
    /// a change of tag is no single boundary crossing). Returns the
    /// estimated pose, `None` before the first fix.
    // Not inlined: one copy, out of the caller's tick.
    #[inline(never)]
    pub fn step(
        &mut self,
        odometry: &OdometryStep,
        fix: Option<Vec2>,
        after_gap: bool,
    ) -> Option<Pose> {
        if let Some(filter) = self.filter_mut() {
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
            if !self.started {
                // Start at the first tag, heading unknown; the first
                // measurement (the uniform cell) sets the position.
                let (heading_rad, heading_variance) = self
                    .start_heading_rad
                    .map_or((0.0, PI_SQUARED), |h| (h, ASSUMED_HEADING_VARIANCE_RAD2));
                let variances = [
                    self.settings.start_position_variance(),
                    self.settings.start_position_variance(),
                    heading_variance,
                    self.settings.scale_prior,
                ];
                let start = Pose::new(tag.x, tag.y, heading_rad);
                self.started = self.filter.start(&self.settings, start, variances);
            }
            let filter = self.started.then_some(&mut self.filter)?;
            let pose = filter.pose();
            let relocalisations = filter.counters().relocalisations;
            let radius = self.settings.read_radius_m;
            if radius > 0.0 {
                if let Some(measurement) = self.cells.range_measurement(
                    tag,
                    pose.heading_rad,
                    travel_m,
                    radius,
                    odometry.ds_m,
                ) {
                    // The particle filter takes the read as its disc; the
                    // others the entry point.
                    let disc = filter.correct_disc(
                        tag,
                        radius,
                        pose.heading_rad,
                        odometry.ds_m,
                        self.settings.fix_age_ticks,
                        &measurement,
                    );
                    if disc.is_none() {
                        filter.correct(&measurement);
                    }
                }
            } else {
                let (sin_theta, cos_theta) = math::sincos(pose.heading_rad);
                let last_step = Vec2::new(odometry.ds_m * cos_theta, odometry.ds_m * sin_theta);
                let configured_per_m = self.settings.filter.variance_per_m;
                // Crossings adapt the wheel noise, once the pose is acquired
                // (`noise_adaptation`).
                let guide_trusted =
                    || guide_error_bound(&self.guide, self.distance_m) < GUIDE_TRUST_BOUND;
                if filter.is_particle_filter() {
                    // The particle filter takes every read as its cell, and
                    // the crossing it would be for its noise.
                    if let Some(crossing) = self.cells.crossing(tag, last_step)
                        && guide_trusted()
                    {
                        for measurement in &crossing {
                            adapt_to_crossing(
                                &mut self.noise,
                                configured_per_m,
                                filter,
                                measurement,
                            );
                        }
                    }
                    let _ = filter.correct_cell(&mut self.cells, tag, last_step);
                } else {
                    // The others take the tracker's measurements.
                    let measurements =
                        self.cells.measurements(tag, last_step, pose.position, || {
                            let covariance = filter.covariance();
                            [covariance.m11, covariance.m22]
                        });
                    let adapt = measurements.reading() == CellReading::Crossing && guide_trusted();
                    for measurement in &measurements {
                        if adapt {
                            adapt_to_crossing(
                                &mut self.noise,
                                configured_per_m,
                                filter,
                                measurement,
                            );
                        }
                        filter.correct(measurement);
                    }
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
        let bound = guide_error_bound(&self.guide, self.distance_m);
        let Some(filter) = self.started.then_some(&mut self.filter) else {
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

    /// The wheel noise's adaptation to the crossings
    /// ([`noise_adaptation`]): its scale now and its changes.
    #[must_use]
    pub fn wheel_noise(&self) -> &WheelNoiseAdaptation {
        &self.noise
    }

    /// Times the filter's heading was reset to the guide's.
    #[must_use]
    pub fn heading_resets(&self) -> u32 {
        self.heading_resets
    }

    /// The filter's counters (zero before the first fix).
    #[must_use]
    pub fn counters(&self) -> PoseFilterCounters {
        self.filter()
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

impl PoseEstimator for FusionEstimator {
    /// [`FusionEstimator::step`]; the position of its pose (the filter
    /// keeps its own, so `last_position` is not needed).
    fn step(
        &mut self,
        odometry: &OdometryStep,
        fix: Option<Vec2>,
        _last_position: Option<Vec2>,
        after_gap: bool,
    ) -> Option<Vec2> {
        FusionEstimator::step(self, odometry, fix, after_gap).map(|pose| pose.position)
    }

    /// The filter's heading as `(cos θ̂, sin θ̂)`; `(0, 0)` before the first fix.
    fn heading(&self) -> HeadingEstimate {
        self.pose().map_or(HeadingEstimate::default(), |pose| {
            let (sin_theta, cos_theta) = math::sincos(pose.heading_rad);
            HeadingEstimate {
                cos_theta,
                sin_theta,
            }
        })
    }

    /// Odometry steps refused and fixes refused as non-finite.
    fn rejected_updates(&self) -> u32 {
        let c = FusionEstimator::counters(self);
        c.rejected_predictions.saturating_add(c.fixes_invalid)
    }

    fn counters(&self) -> EstimatorCounters {
        let filter = FusionEstimator::counters(self);
        EstimatorCounters {
            fixes_gated: filter.fixes_gated,
            relocalisations: filter.relocalisations,
            heading_resets: self.heading_resets(),
        }
    }

    fn blind_distance_lost(&self) -> Option<bool> {
        FusionEstimator::blind_distance_lost(self)
    }

    /// The filter's heading set to `heading_rad` with the variance
    /// [`ASSUMED_HEADING_VARIANCE_RAD2`] (its position kept); before the
    /// first fix, the filter starts with it. The guide observer is not
    /// told: it keeps its own convergence bound, and still corrects a
    /// filter told a wrong heading (the type's docs).
    fn assume_heading(&mut self, heading_rad: f32) {
        if !heading_rad.is_finite() {
            return;
        }
        match self.filter_mut() {
            Some(filter) => {
                filter.reset_heading(heading_rad, ASSUMED_HEADING_VARIANCE_RAD2);
            }
            None => self.start_heading_rad = Some(heading_rad),
        }
    }
}

/// The filter a [`FusionEstimator`] runs ([`FusionFilter`]).
#[derive(Debug, Clone, PartialEq)]
// The variants differ in size by the particles; there is no heap to box
// them into, and only one is built per robot.
#[allow(clippy::large_enum_variant)]
pub enum RunningFilter {
    /// No filter yet (before the first fix); never returned by
    /// [`FusionEstimator::filter`]. Its pose, covariance and
    /// counters are zero, and it takes no step.
    Waiting,
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
    ($running:expr, $f:ident => $body:expr, $waiting:expr) => {
        match $running {
            RunningFilter::Waiting => $waiting,
            RunningFilter::Ekf($f) => $body,
            #[cfg(feature = "fusion-ukf")]
            RunningFilter::Ukf($f) => $body,
            #[cfg(feature = "fusion-particle-filter")]
            RunningFilter::ParticleFilter($f) => $body,
        }
    };
}

impl RunningFilter {
    /// Starts the filter `settings` choose at `start` with `variances`
    /// (as [`PoseFilter::new`]) in this place: the EKF and the UKF built
    /// and moved in (a few hundred bytes); the particle filter (5 KB)
    /// entered as a blank ([`Self::enter_particle_filter`]) and started
    /// where it lives ([`PoseFilter::restart`]). `false` if it cannot
    /// start there (the EKF and the UKF then leave this unchanged).
    fn start(&mut self, settings: &FusionSettings, start: Pose, variances: [f32; 4]) -> bool {
        let config = settings.filter;
        match settings.kind {
            FusionFilter::Ekf => match PoseFilter::new(config, start, variances) {
                Ok(filter) => *self = Self::Ekf(filter),
                Err(_) => return false,
            },
            #[cfg(feature = "fusion-ukf")]
            FusionFilter::Ukf => match PoseFilter::new(config, start, variances) {
                Ok(filter) => *self = Self::Ukf(filter),
                Err(_) => return false,
            },
            #[cfg(feature = "fusion-particle-filter")]
            FusionFilter::ParticleFilter => {
                if !matches!(self, Self::ParticleFilter(_)) {
                    self.enter_particle_filter();
                }
                return match self {
                    Self::ParticleFilter(filter) => {
                        filter.restart(config, start, variances).is_ok()
                    }
                    _ => false,
                };
            }
        }
        true
    }

    /// Becomes the particle filter not yet started (every particle at the
    /// origin: [`PoseParticleFilter::blank`]). A function of its own, not
    /// inlined: the blank passes through a 5 KB temporary on the stack
    /// (the compiler builds a returned value in place only in a
    /// destination it knows writable, a local or a return slot, not behind
    /// a `&mut`), which this frame holds only while it runs, once per
    /// estimator, rather than in [`FusionEstimator::step`]'s every tick.
    /// The estimator is built with [`Self::Waiting`] rather than the blank
    /// so that its moves through the robot's construction copy a few
    /// bytes, not 5 KB each.
    ///
    /// [`PoseParticleFilter::blank`]: crate::estimation::fusion::particle::PoseParticleFilter
    #[cfg(feature = "fusion-particle-filter")]
    #[inline(never)]
    fn enter_particle_filter(&mut self) {
        *self =
            Self::ParticleFilter(crate::estimation::fusion::particle::PoseParticleFilter::blank());
    }

    /// [`PoseFilter::predict`].
    pub fn predict(&mut self, odometry: &OdometryStep) {
        with_filter!(self, f => f.predict(odometry), ());
    }

    /// [`PoseFilter::axis_innovation`]: the normalised innovation squared
    /// `y²/S` of a crossing against the belief now.
    pub fn crossing_innovation(&self, measurement: &PositionMeasurement) -> Option<f32> {
        with_filter!(self, f => f.axis_innovation(measurement), None)
    }

    /// [`PoseFilter`]'s wheel noise per metre from now on
    /// ([`noise_adaptation`]).
    fn set_wheel_variance_per_m(&mut self, variance_per_m: f32) {
        with_filter!(self, f => f.set_wheel_variance_per_m(variance_per_m), ());
    }

    /// Whether this is the particle filter.
    fn is_particle_filter(&self) -> bool {
        #[cfg(feature = "fusion-particle-filter")]
        if let Self::ParticleFilter(_) = self {
            return true;
        }
        false
    }

    /// [`PoseFilter::correct`].
    pub fn correct(&mut self, measurement: &PositionMeasurement) -> FixOutcome {
        with_filter!(self, f => f.correct(measurement), FixOutcome::Invalid)
    }

    /// The particle filter: corrects with a read of `tag` as its cell
    /// ([`TagCellTracker::cell`], the robot having moved by `last_step`
    /// during the tick) and
    /// returns what happened to it; the other filters: `None`, nothing
    /// done (they take the tracker's [`TagCellTracker::measurements`]).
    pub fn correct_cell(
        &mut self,
        cells: &mut TagCellTracker,
        tag: Vec2,
        last_step: Vec2,
    ) -> Option<FixOutcome> {
        #[cfg(feature = "fusion-particle-filter")]
        if let Self::ParticleFilter(f) = self {
            return Some(match cells.cell(tag, last_step) {
                Some(cell) => f.correct_cell(&cell),
                None => FixOutcome::Invalid,
            });
        }
        let _ = (cells, tag, last_step);
        None
    }

    /// The particle filter: corrects with a range reader's read of `tag`
    /// as its disc of radius `radius_m`, the robot having driven `lag_m`
    /// along `heading_rad` since the read
    /// ([`crate::estimation::fusion::particle::TagDisc`]), and returns what
    /// happened to it; the other filters: `None`, nothing done (they take
    /// the entry point, [`TagCellTracker::range_measurement`]).
    pub fn correct_disc(
        &mut self,
        tag: Vec2,
        radius_m: f32,
        heading_rad: f32,
        step_m: f32,
        fix_age_ticks: f32,
        entry: &PositionMeasurement,
    ) -> Option<FixOutcome> {
        #[cfg(feature = "fusion-particle-filter")]
        if let Self::ParticleFilter(f) = self {
            let (sin_theta, cos_theta) = math::sincos(heading_rad);
            let sweep = Vec2::new(cos_theta, sin_theta).scaled(step_m);
            let disc = crate::estimation::fusion::particle::TagDisc {
                centre: tag,
                radius_m,
                lag: sweep.scaled(fix_age_ticks),
                sweep,
                edge_std_m: crate::estimation::fusion::particle::DISC_EDGE_STD_M,
            };
            return Some(f.correct_disc(&disc, entry));
        }
        let _ = (tag, radius_m, heading_rad, step_m, fix_age_ticks, entry);
        None
    }

    /// [`PoseFilter::pose`].
    #[must_use]
    pub fn pose(&self) -> Pose {
        with_filter!(self, f => f.pose(), Pose::default())
    }

    /// [`PoseFilter::covariance`].
    #[must_use]
    pub fn covariance(&self) -> PoseCovariance {
        with_filter!(self, f => f.covariance(), PoseCovariance::zeros())
    }

    /// [`PoseFilter::wheel_scale_errors`].
    #[must_use]
    pub fn wheel_scale_errors(&self) -> [f32; 2] {
        with_filter!(self, f => f.wheel_scale_errors(), [0.0; 2])
    }

    /// [`PoseFilter::counters`].
    #[must_use]
    pub fn counters(&self) -> PoseFilterCounters {
        with_filter!(self, f => f.counters(), PoseFilterCounters::default())
    }

    /// [`PoseFilter::reset_heading`].
    pub fn reset_heading(&mut self, heading_rad: f32, variance_rad2: f32) -> bool {
        with_filter!(self, f => f.reset_heading(heading_rad, variance_rad2), false)
    }
}

/// The largest fix age [`FusionSettings::with_fix_age_ticks`] takes, control
/// periods (a second at 100 Hz: older fixes are not fixes of where the
/// robot is).
pub const MAX_FIX_AGE_TICKS: f32 = 100.0;

/// The variance of a heading known from outside
/// ([`PoseEstimator::assume_heading`]), rad²: a standard deviation of
/// 0.05 rad (2.9°), a robot parked at a station by hand or by a dock.
pub const ASSUMED_HEADING_VARIANCE_RAD2: f32 = 0.05 * 0.05;

/// Ticks of disagreement with a trusted guide before the heading is reset
/// (a second at 100 Hz).
const GUIDE_PATIENCE_TICKS: u32 = 100;
/// The guide is trusted once its error bound `e^{−L s}` is below this
/// (its heading then within 30°).
const GUIDE_TRUST_BOUND: f32 = 0.5;

/// How far beyond the guide's own error bound the filter's heading may
/// stray before it counts as disagreeing, rad.
const GUIDE_MARGIN_RAD: f32 = 0.3;

/// The guide observer's error bound `b = e^{−L s}` after `distance_m`
/// driven with fixes (paper 001, Theorem 1, (10)): its heading is within
/// `asin b`.
fn guide_error_bound(guide: &HeadingObserver, distance_m: f32) -> f32 {
    math::exp(-distance_m * guide.config().gain_per_m())
}

/// Takes a crossing's normalised innovation against `filter`'s belief
/// (before the filter takes the crossing) into `noise`, and sets the
/// filter's wheel noise to `configured_per_m` times the scale if it
/// changed ([`noise_adaptation`]).
fn adapt_to_crossing(
    noise: &mut WheelNoiseAdaptation,
    configured_per_m: f32,
    filter: &mut RunningFilter,
    crossing: &PositionMeasurement,
) {
    if let Some(nis) = filter.crossing_innovation(crossing)
        && let Some(scale) = noise.observe(nis)
    {
        filter.set_wheel_variance_per_m(configured_per_m * scale);
    }
}

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

    /// Drives 6 m along x over a 10 cm grid on wheels that travel 3 %
    /// more than the odometry says (the scale prior 0: not learnt), and
    /// returns the `kind` filter's wheel noise adaptation.
    fn drive_on_long_wheels(kind: FusionFilter, wheel_variance_per_m: f32) -> WheelNoiseAdaptation {
        use crate::estimation::heading_observer::HeadingObserverConfig;
        let filter = PoseFilterConfig::new(0.2, wheel_variance_per_m, 1e-9, 3.0).unwrap();
        let settings = FusionSettings::new(filter, 0.1, 0.0)
            .unwrap()
            .with_filter(kind);
        let guide = HeadingObserver::new(HeadingObserverConfig::new(1.0, 0.01).unwrap());
        let mut estimator = FusionEstimator::new(settings, guide);
        estimator.assume_heading(0.0);
        // The nearest tag on the x axis (x > 0 here).
        let nearest = |x: f32| Vec2::new(((x / 0.1 + 0.5) as i32) as f32 * 0.1, 0.0);
        let odometry = OdometryStep {
            ds_m: 0.002,
            ..OdometryStep::default()
        };
        let mut x = 0.02_f32;
        for _ in 0..3000 {
            x += 1.03 * odometry.ds_m;
            let _ = estimator.step(&odometry, Some(nearest(x)), false);
        }
        *estimator.wheel_noise()
    }

    /// Tuned far below its wheels' error, the EKF and the particle filter
    /// raise their wheel noise from the crossings (module
    /// [`noise_adaptation`]); tuned above it, they keep the configured
    /// noise. The UKF takes the same path but is not raised on this drive:
    /// its predicted spread already covers the 3 % (its average `d²` ends
    /// at 0.07); it is raised on the slipping wheels of docs/fusion.md's
    /// grid.
    #[test]
    fn a_wheel_noise_too_small_is_raised_from_the_crossings() {
        let kinds = [
            FusionFilter::Ekf,
            #[cfg(feature = "fusion-particle-filter")]
            FusionFilter::ParticleFilter,
        ];
        for kind in kinds {
            let low = drive_on_long_wheels(kind, 1e-7);
            assert!(low.scale() > 1.0, "{kind:?}: {low:?}");
            assert!(low.changes().0 > 0, "{kind:?}: {low:?}");
            let high = drive_on_long_wheels(kind, 1e-3);
            assert_eq!(high.scale(), 1.0, "{kind:?}: {high:?}");
            assert_eq!(high.changes(), (0, 0), "{kind:?}");
        }
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
        let first = cells.measurements(
            Vec2::new(0.0, 0.0),
            Vec2::new(0.001, 0.0),
            Vec2::ZERO,
            || [1e-4; 2],
        );
        assert_eq!(first.reading(), CellReading::First);
        assert!(matches!(
            first.as_slice().first(),
            Some(PositionMeasurement::Point { .. })
        ));
        let same = cells.measurements(
            Vec2::new(0.0, 0.0),
            Vec2::new(0.001, 0.0),
            Vec2::ZERO,
            || [1e-4; 2],
        );
        assert_eq!(same.reading(), CellReading::SameTag);
        assert!(same.as_slice().is_empty());
        assert_eq!(cells.same_tag_reads(), 1);
        // A non-finite read gives nothing and leaves the tracker as it was.
        let before = cells;
        let invalid = cells.measurements(
            Vec2::new(f32::NAN, 0.0),
            Vec2::new(0.001, 0.0),
            Vec2::ZERO,
            || [1e-4; 2],
        );
        assert_eq!(invalid.reading(), CellReading::Invalid);
        assert!(invalid.as_slice().is_empty());
        assert_eq!(cells, before);
        // Asked without taking the read, the tracker names the same
        // crossing and stays as it was; an unchanged tag is none.
        let before = cells;
        let probe = cells.crossing(Vec2::new(0.1, 0.0), Vec2::new(0.002, 0.0));
        assert_eq!(cells, before);
        assert_eq!(
            cells.crossing(Vec2::new(0.0, 0.0), Vec2::new(0.002, 0.0)),
            None
        );
        let crossing = cells.measurements(
            Vec2::new(0.1, 0.0),
            Vec2::new(0.002, 0.0),
            Vec2::ZERO,
            || [1e-4; 2],
        );
        assert_eq!(probe.as_ref(), Some(&crossing));
        assert_eq!(crossing.reading(), CellReading::Crossing);
        match crossing.as_slice().first() {
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
        let jump = cells.measurements(
            Vec2::new(0.3, 0.0),
            Vec2::new(0.002, 0.0),
            Vec2::ZERO,
            || [1e-4; 2],
        );
        assert_eq!(jump.reading(), CellReading::Jump);
        assert!(matches!(
            jump.as_slice().first(),
            Some(PositionMeasurement::Point { .. })
        ));
    }

    /// Reads of an unchanged tag leave an estimate within 2 cm of the
    /// tag's cell alone and truncate one beyond it to the cell (the
    /// truncation's Kalman update lands inside); the edge constraint
    /// instead pulls any estimate outside to the edge.
    #[test]
    fn a_stray_estimate_is_truncated_to_its_cell() {
        let tag = Vec2::new(0.0, 0.0);
        let step = Vec2::new(0.001, 0.0);
        let variance = 4e-4_f32;
        let read = |cells: &mut TagCellTracker, estimate: Vec2| {
            let _ = cells.measurements(tag, step, Vec2::ZERO, || [variance; 2]);
            cells.measurements(tag, step, estimate, || [variance; 2])
        };
        let mut cells = TagCellTracker::new(0.1).unwrap();
        // 1.5 cm beyond the edge at x = 0.05, inside the cell in y.
        assert!(
            read(&mut cells, Vec2::new(0.065, 0.0))
                .as_slice()
                .is_empty()
        );
        assert_eq!(cells.edge_corrections(), 0);
        // 3 cm beyond the edge in x, 2.5 cm below the cell in y.
        let mut cells = TagCellTracker::new(0.1).unwrap();
        let estimate = Vec2::new(0.08, -0.075);
        let pulled = read(&mut cells, estimate);
        assert_eq!(pulled.as_slice().len(), 2);
        assert_eq!(cells.edge_corrections(), 2);
        for m in &pulled {
            let (mean, value_m, variance_m2) = match *m {
                PositionMeasurement::X {
                    value_m,
                    variance_m2,
                } => (estimate.x, value_m, variance_m2),
                PositionMeasurement::Y {
                    value_m,
                    variance_m2,
                } => (estimate.y, value_m, variance_m2),
                other => panic!("{other:?}"),
            };
            let updated = mean + variance / (variance + variance_m2) * (value_m - mean);
            assert!(updated.abs() < 0.05, "{m:?}: {updated}");
            assert!((updated.abs() - 0.05).abs() < 0.02, "{m:?}: {updated}");
        }
        // The edge constraint: to the edge, at variance (s/10)².
        let mut cells = TagCellTracker::new(0.1).unwrap().with_edge_constraint(true);
        match read(&mut cells, Vec2::new(0.055, 0.0)).as_slice().first() {
            Some(PositionMeasurement::X {
                value_m,
                variance_m2,
            }) => {
                assert_eq!((*value_m, *variance_m2), (0.05, 0.1 * 0.1 / 100.0));
            }
            other => panic!("{other:?}"),
        }
        // A fix two ticks old: the cell has moved on by two steps (1 cm),
        // so 2.5 cm past its edge at the read is 1.5 cm past it now.
        let mut cells = TagCellTracker::new(0.1)
            .unwrap()
            .with_fix_age_ticks(2.0)
            .unwrap();
        let step = Vec2::new(0.005, 0.0);
        let _ = cells.measurements(tag, step, Vec2::ZERO, || [variance; 2]);
        assert!(
            cells
                .measurements(tag, step, Vec2::new(0.075, 0.0), || [variance; 2])
                .as_slice()
                .is_empty()
        );
        assert_eq!(
            cells
                .measurements(tag, step, Vec2::new(0.082, 0.0), || [variance; 2])
                .as_slice()
                .len(),
            1
        );
        // No variance, no truncation.
        assert!(
            cells
                .measurements(tag, step, Vec2::new(0.2, 0.0), || [f32::NAN; 2])
                .as_slice()
                .is_empty()
        );
    }

    /// A fix one tick old (the simulator's reader over its UART): a
    /// crossing is placed a tick and a half of travel past the boundary,
    /// a cell and a range reader's entry point a tick of travel on; 0 keeps
    /// the tick's own position.
    #[test]
    fn a_fix_s_age_moves_its_measurements_on_by_the_travel_since_the_read() {
        let step = Vec2::new(0.004, -0.002);
        let aged = |ticks| {
            TagCellTracker::new(0.1)
                .unwrap()
                .with_fix_age_ticks(ticks)
                .unwrap()
        };
        for (ticks, beyond) in [(0.0, 0.5), (1.0, 1.5), (2.5, 3.0)] {
            let mut cells = aged(ticks);
            let _ = cells.measurements(Vec2::new(0.0, 0.0), step, Vec2::ZERO, || [1e-4; 2]);
            let crossing = cells.measurements(Vec2::new(0.1, 0.0), step, Vec2::ZERO, || [1e-4; 2]);
            assert_eq!(crossing.reading(), CellReading::Crossing);
            match crossing.as_slice().first() {
                Some(PositionMeasurement::X { value_m, .. }) => {
                    let expected = 0.05 + beyond * step.x;
                    assert!((value_m - expected).abs() < 1e-7, "{ticks}: {value_m}");
                }
                other => panic!("{ticks}: {other:?}"),
            }
            let cell = cells.cell(Vec2::new(0.1, 0.0), step).unwrap();
            assert_eq!(cell.lag, step.scaled(ticks));
            // A robot whose span during the read's tick, moved on by the
            // lag, just reaches the cell's near edge is in it; a millimetre
            // (the edge's softening) short of it is not.
            let edge = 0.05 + cell.lag.x;
            assert!(cell.distance_sq(edge, 0.0) < 1e-6);
            assert!(cell.distance_sq(edge - 0.001 - 1e-6, 0.0) > 0.9);
            let mut range = aged(ticks);
            let Some(PositionMeasurement::Ellipse { position, .. }) =
                range.range_measurement(Vec2::new(1.0, 1.0), 0.0, 0.0, 0.05, step.x)
            else {
                panic!("{ticks}: no entry point");
            };
            let back = core::f32::consts::FRAC_PI_4 * 0.05;
            assert!((position.x - (1.0 - back + ticks * step.x)).abs() < 1e-6);
            // Heading 0: the step is along x only.
            assert!((position.y - 1.0).abs() < 1e-6);
        }
        assert!(
            TagCellTracker::new(0.1)
                .unwrap()
                .with_fix_age_ticks(-1.0)
                .is_none()
        );
        assert!(
            TagCellTracker::new(0.1)
                .unwrap()
                .with_fix_age_ticks(f32::NAN)
                .is_none()
        );
    }

    #[test]
    fn a_fix_age_beyond_its_range_is_refused() {
        let settings = FusionSettings::new(config(), 0.1, 0.0).unwrap();
        for ticks in [-0.5, f32::NAN, f32::INFINITY, MAX_FIX_AGE_TICKS + 1.0] {
            assert_eq!(
                settings.with_fix_age_ticks(ticks),
                Err(PoseFilterError::FixAge),
                "{ticks}"
            );
        }
        for ticks in [0.0, 1.0, MAX_FIX_AGE_TICKS] {
            assert_eq!(
                settings
                    .with_fix_age_ticks(ticks)
                    .map(|s| s.fix_age_ticks()),
                Ok(ticks)
            );
        }
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

    /// A read as its cell: 0 inside, a Gaussian tail of the softening
    /// outside, the tick's sweep behind the position forgiven, NaN for a
    /// non-finite position; every read gives one, a same-tag read counted.
    #[test]
    fn reads_become_cells() {
        let mut cells = TagCellTracker::new(0.1).unwrap();
        let cell = cells
            .cell(Vec2::new(0.0, 0.0), Vec2::new(0.0015, 0.0))
            .unwrap();
        assert_eq!(cell.half_width_m, 0.05);
        assert_eq!(cell.distance_sq(0.03, -0.04), 0.0);
        // 1 mm past the leading edge: within the sweep (read up to a tick
        // ago); 3 mm past it, 1.5 mm beyond the sweep: (1.5/1)².
        assert_eq!(cell.distance_sq(0.051, 0.0), 0.0);
        assert!((cell.distance_sq(0.053, 0.0) - 2.25).abs() < 1e-2);
        // Behind the trailing edge and beside the cell: no sweep.
        assert!((cell.distance_sq(-0.052, 0.0) - 4.0).abs() < 1e-2);
        assert!((cell.distance_sq(0.0, 0.052) - 4.0).abs() < 1e-2);
        assert!(cell.distance_sq(f32::NAN, 0.0).is_nan());
        assert!(cell.distance_sq(0.0, f32::INFINITY) > 1e30);
        assert!(
            cells
                .cell(Vec2::new(0.0, 0.0), Vec2::new(0.001, 0.0))
                .is_some()
        );
        assert_eq!(cells.same_tag_reads(), 1);
        assert!(cells.cell(Vec2::new(0.1, 0.0), Vec2::ZERO).is_some());
        assert_eq!(cells.same_tag_reads(), 1);
        assert!(cells.cell(Vec2::new(f32::NAN, 0.0), Vec2::ZERO).is_none());
        assert!(cells.cell(Vec2::ZERO, Vec2::new(0.0, f32::NAN)).is_none());
        // A sweep longer than the spacing is clamped to it.
        let long = cells.cell(Vec2::ZERO, Vec2::new(5.0, -5.0)).unwrap();
        assert_eq!(long.sweep, Vec2::new(0.1, -0.1));
    }

    #[test]
    fn range_reads_are_one_measurement_per_pass() {
        let mut cells = TagCellTracker::new(0.3).unwrap();
        let tag = Vec2::new(1.0, 2.0);
        // Heading +x: the entry point is π r/4 short of the tag along x.
        let Some(PositionMeasurement::Ellipse {
            position,
            covariance_m2: [xx, xy, yy],
        }) = cells.range_measurement(tag, 0.0, 0.0, 0.05, 0.0)
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
        }) = turned.range_measurement(tag, core::f32::consts::FRAC_PI_2, 0.0, 0.05, 0.0)
        else {
            panic!("first read");
        };
        assert!((txx - yy).abs() < 1e-8 && (tyy - xx).abs() < 1e-8);
        // Repeats while in range: nothing, counted.
        assert!(cells.range_measurement(tag, 0.0, 0.02, 0.05, 0.0).is_none());
        assert_eq!(cells.same_tag_reads(), 1);
        // The same tag after driving more than 2r: a new pass.
        assert!(cells.range_measurement(tag, 0.0, 0.2, 0.05, 0.0).is_some());
        assert!(
            cells
                .range_measurement(Vec2::new(f32::NAN, 0.0), 0.0, 1.0, 0.05, 0.0)
                .is_none()
        );
    }
}
