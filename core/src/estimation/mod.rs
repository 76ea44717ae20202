//! Estimators of the robot's pose from odometry and tag fixes, behind one
//! interface ([`PoseEstimator`]) and one list ([`EstimatorChoice`],
//! dispatched by [`Estimator`]):
//!
//! | choice | estimator | paper |
//! |---|---|---|
//! | [`EstimatorChoice::HeadingObserver`] | [`heading_observer`], with [`dead_reckoning`] | 001, observer (5) |
//! | [`EstimatorChoice::PoseObserver`] | [`pose_observer`], with [`dead_reckoning`] | 002, Proposition 4 |
//! | `EstimatorChoice::Fusion` (feature `fusion-ekf`) | [`fusion`]: EKF, UKF or particle filter of [`crate::filters`] | 004's filters on odometry + tags |
//!
//! The tracker ([`crate::pilot::tracker`]) hands the estimator each tick's
//! odometry and the tag fix it accepted (finite, fresh); the estimator
//! returns the position the law uses this tick and holds the heading.
//!
//! # Adding an estimator
//! Its own file, its arms in the lists here, and its spec beside it in
//! [`spec`]: nothing outside this module changes. The recipe, step by
//! step: `docs/architecture.md`, "Adding an estimator or a law".

pub mod dead_reckoning;
pub mod fusion;
pub mod heading_observer;
pub mod interface;
pub mod pose_observer;
pub mod spec;

pub use dead_reckoning::{DeadReckoning, PositionObserver};
pub use interface::{EstimatorCounters, PoseEstimator};

#[cfg(feature = "fusion-ekf")]
use crate::estimation::fusion::{FusionEstimator, FusionSettings};
use crate::estimation::heading_observer::{HeadingObserver, HeadingObserverConfig};
use crate::estimation::pose_observer::{PoseEstimate, PoseObserver, PoseObserverConfig};
use crate::geometry::HeadingEstimate;
use crate::geometry::Vec2;
use crate::odometry::OdometryStep;

/// Which estimator the tracker runs, with its configuration: the one list
/// of estimators. Each names itself ([`Self::label`]) and states its step
/// ([`Self::period_s`]), which is the tracker's control period.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum EstimatorChoice {
    /// Paper 001's heading observer (5), with dead reckoning between fixes.
    HeadingObserver(HeadingObserverConfig),
    /// Paper 002's Proposition 4 observer of `x, y, cos θ, sin θ`, fed the
    /// position (fix or dead-reckoned).
    PoseObserver(PoseObserverConfig),
    /// The encoder + tag fusion estimator ([`fusion`]) on the filter its
    /// settings choose: its pose is the law's position and heading, between
    /// fixes too (cargo feature `fusion-ekf`). Paper 001's observer (5)
    /// runs beside it as its heading guide (`guide`).
    #[cfg(feature = "fusion-ekf")]
    Fusion {
        /// The filter and its tuning.
        settings: FusionSettings,
        /// The heading guide's configuration.
        guide: HeadingObserverConfig,
    },
}

impl EstimatorChoice {
    /// The estimator's step, s: the tracker's control period.
    #[must_use]
    pub fn period_s(&self) -> f32 {
        match self {
            Self::HeadingObserver(config) => config.period_s(),
            Self::PoseObserver(config) => config.period_s(),
            #[cfg(feature = "fusion-ekf")]
            Self::Fusion { guide, .. } => guide.period_s(),
        }
    }

    /// The estimator's name in reports: `observer 001`, `pose observer`,
    /// `fusion EKF`, `fusion UKF` or `fusion particle filter`.
    #[must_use]
    pub fn label(&self) -> &'static str {
        match self {
            Self::HeadingObserver(_) => "observer 001",
            Self::PoseObserver(_) => "pose observer",
            #[cfg(feature = "fusion-ekf")]
            Self::Fusion { settings, .. } => settings.kind().label(),
        }
    }

    /// What the estimator's heading does while the robot stands or turns
    /// in place (`v = 0`), which a route's stops and pivots rely on: no
    /// estimator here observes the heading from position fixes at
    /// standstill (a position that does not change says nothing of the
    /// direction the robot faces), so each carries the heading it had on
    /// arrival, turned by the encoders' rotation.
    #[must_use]
    pub fn heading_at_standstill(&self) -> StandstillHeading {
        match self {
            Self::HeadingObserver(_) | Self::PoseObserver(_) => StandstillHeading::EncoderRotated,
            #[cfg(feature = "fusion-ekf")]
            Self::Fusion { .. } => StandstillHeading::EncoderRotatedFiltered,
        }
    }

    /// Paper 001's observer (5) where it runs: as the estimator, or as the
    /// fusion estimator's heading guide.
    #[must_use]
    pub fn heading_observer(&self) -> Option<HeadingObserverConfig> {
        match *self {
            Self::HeadingObserver(config) => Some(config),
            Self::PoseObserver(_) => None,
            #[cfg(feature = "fusion-ekf")]
            Self::Fusion { guide, .. } => Some(guide),
        }
    }
}

/// What an estimator's heading does while the robot stands or turns in
/// place ([`EstimatorChoice::heading_at_standstill`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum StandstillHeading {
    /// Not observed, not corrected: turned exactly by the encoders'
    /// rotation `ω·h` each tick, so its error on arrival is kept through a
    /// stop and a pivot (plus the encoders' own rotation error). Paper
    /// 001's observer (5): below `min_speed_m_s` its innovation is off and
    /// `ẑ⁺ = R(ωh)·ẑ`, `|e⁺| = |e|` (module `heading_observer`); paper
    /// 002's Proposition 4 observer: its injection into `(ĉ, ŝ)` is
    /// proportional to `v`, zero at standstill. Pivots on it are pivots by
    /// encoder rotation, as good as the heading was when the robot stopped;
    /// before the robot has driven, paper 001's estimate is `(0, 0)` (no
    /// heading at all) and a pivot is open loop (module
    /// `pilot::route`).
    EncoderRotated,
    /// As [`Self::EncoderRotated`], inside a filter: the odometry turns
    /// the heading and grows its variance; a fix at standstill corrects it
    /// only through the position–heading correlation the motion before the
    /// stop left in the covariance (the fusion estimators).
    EncoderRotatedFiltered,
}

/// The running estimator: [`EstimatorChoice`] built.
// No heap to box the filter into: the tracker holds its estimator inline,
// and the largest sets the size (the fusion EKF ~250 B, its particle
// filter ~4.5 KB when the feature `fusion-particle-filter` is on).
#[cfg_attr(feature = "fusion-ekf", allow(clippy::large_enum_variant))]
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Estimator {
    /// [`EstimatorChoice::HeadingObserver`].
    HeadingObserver(DeadReckoning<HeadingObserver>),
    /// [`EstimatorChoice::PoseObserver`].
    PoseObserver(DeadReckoning<PoseObserver>),
    /// `EstimatorChoice::Fusion`.
    #[cfg(feature = "fusion-ekf")]
    Fusion(FusionEstimator),
}

impl Estimator {
    /// The estimator `choice`, its heading starting at `initial` (paper
    /// 001's `ẑ(0)`; a non-finite one starts at `(0, 0)`, heading
    /// unknown), its position at the first fix.
    #[must_use]
    pub fn new(choice: EstimatorChoice, initial: HeadingEstimate) -> Self {
        let observer = |config| {
            HeadingObserver::with_initial_estimate(config, initial)
                .unwrap_or_else(|_| HeadingObserver::new(config))
        };
        match choice {
            EstimatorChoice::HeadingObserver(config) => {
                Self::HeadingObserver(DeadReckoning::new(observer(config)))
            }
            EstimatorChoice::PoseObserver(config) => {
                let start = if initial.cos_theta.is_finite() && initial.sin_theta.is_finite() {
                    initial
                } else {
                    HeadingEstimate::default()
                };
                Self::PoseObserver(DeadReckoning::new(PoseObserver::new(
                    config,
                    PoseEstimate {
                        position: Vec2::ZERO,
                        cos_theta: start.cos_theta,
                        sin_theta: start.sin_theta,
                    },
                )))
            }
            #[cfg(feature = "fusion-ekf")]
            EstimatorChoice::Fusion { settings, guide } => {
                Self::Fusion(FusionEstimator::new(settings, observer(guide)))
            }
        }
    }
}

macro_rules! dispatch {
    ($self:ident, $method:ident($($arg:expr),*)) => {
        match $self {
            Self::HeadingObserver(e) => PoseEstimator::$method(e, $($arg),*),
            Self::PoseObserver(e) => PoseEstimator::$method(e, $($arg),*),
            #[cfg(feature = "fusion-ekf")]
            Self::Fusion(e) => PoseEstimator::$method(e, $($arg),*),
        }
    };
}

impl PoseEstimator for Estimator {
    fn step(
        &mut self,
        odometry: &OdometryStep,
        fix: Option<Vec2>,
        last_position: Option<Vec2>,
        after_gap: bool,
    ) -> Option<Vec2> {
        dispatch!(self, step(odometry, fix, last_position, after_gap))
    }

    fn heading(&self) -> HeadingEstimate {
        dispatch!(self, heading())
    }

    fn rejected_updates(&self) -> u32 {
        dispatch!(self, rejected_updates())
    }

    fn counters(&self) -> EstimatorCounters {
        dispatch!(self, counters())
    }

    fn blind_distance_lost(&self) -> Option<bool> {
        dispatch!(self, blind_distance_lost())
    }

    fn assume_heading(&mut self, heading_rad: f32) {
        dispatch!(self, assume_heading(heading_rad));
    }
}
