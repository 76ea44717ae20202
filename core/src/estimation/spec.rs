//! The estimators' plain-data description ([`EstimatorSpec`], with the
//! fusion estimator's [`FusionSpec`] and the sensor facts of
//! [`SensorSpec`]), validated into an [`EstimatorChoice`] by each
//! estimator's own constructor; see [`crate::pilot::spec`] for why specs
//! are plain data.

use crate::builds::{self, OptionalBuild};
use crate::estimation::EstimatorChoice;
use crate::estimation::fusion::PoseFilterError;
#[cfg(feature = "fusion-ekf")]
use crate::estimation::fusion::{FusionFilter, FusionSettings, PoseFilterConfig};
use crate::estimation::heading_observer::HeadingObserverConfig;
use crate::estimation::pose_observer::{PoseObserverConfig, PoseObserverConfigError};

/// Why an [`EstimatorSpec`] was refused: the estimator, and its own error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[non_exhaustive]
pub enum EstimatorSpecError {
    /// Paper 002's pose observer (Proposition 4).
    PoseObserver(PoseObserverConfigError),
    /// The fusion estimator.
    Fusion(PoseFilterError),
    /// The fusion estimator, or its UKF or particle filter, in a build
    /// without its cargo feature (`fusion-ekf`, `fusion-ukf`,
    /// `fusion-particle-filter`).
    NotInThisBuild,
}

impl EstimatorSpecError {
    /// The estimator's key in [`EstimatorSpec`] (its `snake_case` tag:
    /// `pose_observer`, `fusion`; `""` for [`Self::NotInThisBuild`]).
    #[must_use]
    pub fn estimator_key(&self) -> &'static str {
        match self {
            Self::PoseObserver(_) => "pose_observer",
            Self::Fusion(_) => "fusion",
            Self::NotInThisBuild => "",
        }
    }

    /// The refused field's key in its estimator's spec (`gains` of
    /// [`EstimatorSpec::PoseObserver`], `wheel_variance_per_m` of
    /// [`FusionSpec`], …), or `None` when the refusal is not about one of
    /// the estimator's own fields (the sensors', the period, the build).
    #[must_use]
    pub fn field_key(&self) -> Option<&'static str> {
        match self {
            Self::PoseObserver(PoseObserverConfigError::Period) => None,
            Self::PoseObserver(_) => Some("gains"),
            Self::Fusion(PoseFilterError::WheelNoise) => Some("wheel_variance_per_m"),
            Self::Fusion(PoseFilterError::Gate) => Some("gate_sigma"),
            Self::Fusion(PoseFilterError::InitialVariance) => Some("scale_prior"),
            Self::Fusion(PoseFilterError::BlindDistance | PoseFilterError::TagMapBlindDistance) => {
                Some("max_blind_distance_m")
            }
            Self::Fusion(PoseFilterError::FixAge) => Some("fix_latency_s"),
            Self::Fusion(_) | Self::NotInThisBuild => None,
        }
    }

    /// Whether the refused value is a fact of the robot's sensors
    /// ([`SensorSpec`]) rather than the estimator's own tuning.
    #[must_use]
    pub fn is_about_sensors(&self) -> bool {
        matches!(
            self,
            Self::Fusion(
                PoseFilterError::TrackWidth
                    | PoseFilterError::TagSpacing
                    | PoseFilterError::ReadRadius
            )
        )
    }
}

impl core::fmt::Display for EstimatorSpecError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::PoseObserver(e) => core::fmt::Display::fmt(e, f),
            Self::Fusion(e) => core::fmt::Display::fmt(e, f),
            Self::NotInThisBuild => f.write_str(
                "this build of the core lacks the selected estimator (the fusion estimator \
                 needs the cargo feature fusion-ekf, its UKF fusion-ukf, its particle filter \
                 fusion-particle-filter)",
            ),
        }
    }
}

impl core::error::Error for EstimatorSpecError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            Self::PoseObserver(e) => Some(e),
            Self::Fusion(e) => Some(e),
            Self::NotInThisBuild => None,
        }
    }
}

/// The tracker's estimator: which one, and its own tuning.
///
/// What the estimator needs to know of the robot's sensors (track width,
/// count quantization, tag spacing, reader range) is not here but in
/// [`SensorSpec`], so that a scenario or robot file states those facts
/// once. With the `serde` feature this is the `[estimator]` table of a
/// scenario file, externally tagged in `snake_case`:
/// `estimator = "heading_observer"` (the default), `[estimator.pose_observer]`
/// or `[estimator.fusion]`, each field optional with the default documented
/// on it.
#[cfg_attr(feature = "schemars", derive(schemars::JsonSchema))]
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(rename_all = "snake_case", deny_unknown_fields)
)]
#[non_exhaustive]
pub enum EstimatorSpec {
    /// Paper 001's heading observer (5), gain
    /// [`crate::pilot::spec::TrackerSpec::observer_gain_per_m`], with dead reckoning between
    /// fixes.
    #[default]
    HeadingObserver,
    /// Paper 002's Proposition 4 observer of `x, y, cos θ, sin θ`.
    PoseObserver {
        /// `[a1, a2]` (1/s) and `[a3, a4]` (1/m²) of (37), each in
        /// [`crate::plausible::GAIN`]; default
        /// [`EstimatorSpec::DEFAULT_POSE_OBSERVER_GAINS`].
        #[cfg_attr(
            feature = "serde",
            serde(default = "EstimatorSpec::default_pose_observer_gains")
        )]
        gains: [f32; 4],
    },
    /// The encoder + tag fusion estimator ([`crate::estimation::fusion`]).
    Fusion(FusionSpec),
}

impl EstimatorSpec {
    /// Paper 002's Proposition 4 gains `[a1, a2, a3, a4]` the simulator
    /// reproduces the paper with.
    pub const DEFAULT_POSE_OBSERVER_GAINS: [f32; 4] = [1.5, 1.5, 100.0, 100.0];
    /// Paper 002's pose observer with [`Self::DEFAULT_POSE_OBSERVER_GAINS`].
    pub const POSE_OBSERVER: Self = Self::PoseObserver {
        gains: Self::DEFAULT_POSE_OBSERVER_GAINS,
    };

    /// The fusion estimator on `filter` with default tuning.
    #[must_use]
    pub fn fusion(filter: FusionFilterSpec) -> Self {
        Self::Fusion(FusionSpec {
            filter,
            ..FusionSpec::default()
        })
    }

    #[cfg(feature = "serde")]
    fn default_pose_observer_gains() -> [f32; 4] {
        Self::DEFAULT_POSE_OBSERVER_GAINS
    }
}

/// The fusion estimator's tuning (the `[estimator.fusion]` table).
#[cfg_attr(feature = "schemars", derive(schemars::JsonSchema))]
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(default, deny_unknown_fields)
)]
pub struct FusionSpec {
    /// Which filter (default the EKF).
    pub filter: FusionFilterSpec,
    /// Each wheel's travel variance per metre driven, m²/m (default 1e-3).
    /// A floor: on a grid of nearest-tag reads every filter raises it, up
    /// to 64×, while the tag crossings show it too small
    /// (`noise_adaptation`).
    pub wheel_variance_per_m: f32,
    /// Mahalanobis gate, standard deviations, ≥ 1 (default 3).
    pub gate_sigma: f32,
    /// Prior variance of each wheel's scale error (default 0: the wheels
    /// are taken as calibrated; 4e-4 learns them from a 2 % prior).
    pub scale_prior: f32,
    /// The failsafe's limit on the distance driven since the last fix, m,
    /// which then replaces the fix timeout; 0: the timeout decides. Not
    /// given (the default): `4 s²/r` for tag spacing `s` and a reader of
    /// range `r > 0` ([`SensorSpec`]), where gaps between tags are normal
    /// (eight times `s²/2r`, the mean distance a straight line runs
    /// between the grid's read discs; 3.2 m for a 20 cm grid and a 5 cm
    /// range), and 0 for a reader of the nearest tag. On a tag map
    /// (`SensorSpec::tag_spacing_m` 0) there is no default: it must be
    /// given ([`PoseFilterError::TagMapBlindDistance`]).
    pub max_blind_distance_m: Option<f32>,
    /// Reads of an unchanged tag pull any estimate that left the tag's cell
    /// back to its edge (default off: only an estimate more than 2 cm
    /// beyond the cell is truncated to it; with `wheel_variance_per_m` near
    /// the real wheel noise it is the tuning for wheels that slip).
    pub edge_constraint: bool,
    /// The particle filter's generator seed (default 1; the other filters
    /// ignore it).
    pub particle_seed: u64,
    /// The age of a tag fix when the tick that uses it runs, s: from the
    /// reader's read to the tick's poll (the reader's processing, the
    /// frame's time on its UART, the wait for the poll). The filters place
    /// each fix that far behind the robot along its motion
    /// (the core's `FusionSettings::with_fix_age_ticks`). Default 0: a fix of the
    /// tick's own position. The simulator's reader over its UART reads at
    /// a tick and its frame is polled at the next: one control period
    /// (`period_s`) when the frame is shorter than a period.
    pub fix_latency_s: f32,
}

impl FusionSpec {
    /// The default of [`Self::wheel_variance_per_m`], m²/m.
    pub const DEFAULT_WHEEL_VARIANCE_PER_M: f32 = 1e-3;
    /// The default of [`Self::gate_sigma`].
    pub const DEFAULT_GATE_SIGMA: f32 = 3.0;
    /// The default of [`Self::particle_seed`].
    pub const DEFAULT_PARTICLE_SEED: u64 = 1;

    /// The blind-distance limit this spec gives with `sensors`, m (see
    /// [`Self::max_blind_distance_m`]).
    #[must_use]
    pub fn max_blind_distance_m(&self, sensors: &SensorSpec) -> f32 {
        match self.max_blind_distance_m {
            Some(limit) => limit,
            None if sensors.read_radius_m > 0.0 => {
                4.0 * sensors.tag_spacing_m * sensors.tag_spacing_m / sensors.read_radius_m
            }
            None => 0.0,
        }
    }
}

#[cfg(feature = "fusion-ekf")]
impl FusionSpec {
    /// The validated settings with `sensors`, for control period
    /// `period_s` (s, validated by the caller: finite and > 0).
    ///
    /// # Errors
    /// [`EstimatorSpecError::Fusion`] for a value out of range,
    /// [`EstimatorSpecError::NotInThisBuild`] for a filter this build lacks.
    pub fn build(
        &self,
        period_s: f32,
        sensors: &SensorSpec,
    ) -> Result<FusionSettings, EstimatorSpecError> {
        // The particle filter's seed; the EKF and UKF draw nothing and keep
        // the configuration's default of 1.
        let (kind, seed) = match self.filter {
            FusionFilterSpec::Ekf => (FusionFilter::Ekf, Self::DEFAULT_PARTICLE_SEED),
            #[cfg(feature = "fusion-ukf")]
            FusionFilterSpec::Ukf => (FusionFilter::Ukf, Self::DEFAULT_PARTICLE_SEED),
            #[cfg(feature = "fusion-particle-filter")]
            FusionFilterSpec::ParticleFilter => (FusionFilter::ParticleFilter, self.particle_seed),
            #[allow(unreachable_patterns)]
            _ => return Err(EstimatorSpecError::NotInThisBuild),
        };
        PoseFilterConfig::new(
            sensors.track_width_m,
            self.wheel_variance_per_m,
            sensors.wheel_variance_floor_m2,
            self.gate_sigma,
        )
        .map(|filter| filter.with_particle_seed(seed))
        .and_then(|filter| {
            // A tag spacing of 0 is a floor without a grid (a tag map).
            if sensors.tag_spacing_m == 0.0 {
                if self.max_blind_distance_m.is_none() && sensors.read_radius_m > 0.0 {
                    return Err(PoseFilterError::TagMapBlindDistance);
                }
                FusionSettings::on_tag_map(filter, sensors.read_radius_m, self.scale_prior)
            } else {
                FusionSettings::new(filter, sensors.tag_spacing_m, self.scale_prior)
                    .and_then(|settings| settings.with_read_radius(sensors.read_radius_m))
            }
        })
        .and_then(|settings| settings.with_max_blind_distance(self.max_blind_distance_m(sensors)))
        .and_then(|settings| {
            // A NaN or infinite latency makes an age that is refused.
            settings.with_fix_age_ticks(self.fix_latency_s / period_s)
        })
        .map(|settings| {
            settings
                .with_filter(kind)
                .with_edge_constraint(self.edge_constraint)
        })
        .map_err(EstimatorSpecError::Fusion)
    }
}

impl Default for FusionSpec {
    fn default() -> Self {
        Self {
            filter: FusionFilterSpec::default(),
            wheel_variance_per_m: Self::DEFAULT_WHEEL_VARIANCE_PER_M,
            gate_sigma: Self::DEFAULT_GATE_SIGMA,
            scale_prior: 0.0,
            max_blind_distance_m: None,
            edge_constraint: false,
            particle_seed: Self::DEFAULT_PARTICLE_SEED,
            fix_latency_s: 0.0,
        }
    }
}

/// The fusion estimator's filter.
#[cfg_attr(feature = "schemars", derive(schemars::JsonSchema))]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(rename_all = "snake_case")
)]
#[non_exhaustive]
pub enum FusionFilterSpec {
    /// The EKF.
    #[default]
    Ekf,
    /// Paper 004's UKF ([`crate::estimation::fusion::ukf`]; cargo feature `fusion-ukf`).
    Ukf,
    /// Paper 004's particle filter ([`crate::estimation::fusion::particle`];
    /// cargo feature `fusion-particle-filter`), seeded with
    /// [`FusionSpec::particle_seed`].
    ParticleFilter,
}

/// What the estimators know of the robot's sensors: the odometry's track
/// width and count quantization, the floor's tag spacing and the reader's
/// range. Facts of the robot and its floor, stated once (only the fusion
/// estimator uses them); in a [`crate::pilot::spec::PilotSpec`] the
/// track width must equal the drive's.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct SensorSpec {
    /// Distance between the wheels' contact points, m, in
    /// [`crate::plausible::TRACK_WIDTH_M`].
    pub track_width_m: f32,
    /// Variance of one wheel's measured travel from the count quantization
    /// alone, m² (`q²/12` for a count quantum `q = 2π r / counts per
    /// revolution`).
    pub wheel_variance_floor_m2: f32,
    /// Spacing of the floor's tag grid, m, in [`crate::plausible::TAG_SPACING_M`]
    /// (0 on a tag map).
    pub tag_spacing_m: f32,
    /// Reader range around the antenna, m (0: the nearest tag is read
    /// every tick), in [`crate::plausible::READ_RADIUS_M`].
    pub read_radius_m: f32,
    /// Where the reader's antenna sits from the axle midpoint, m, in the
    /// robot's frame: `[ahead, to the left]` (default `[0, 0]`; at most
    /// [`crate::pilot::tracker::TrackerConfig::MAX_ANTENNA_OFFSET_M`] away). Every estimator gets
    /// its fixes moved back to the midpoint
    /// ([`crate::pilot::tracker::TrackerConfig::with_antenna_offset`]).
    pub antenna_offset_m: [f32; 2],
}

impl EstimatorSpec {
    /// The optional build ([`crate::builds`]) this estimator needs beyond
    /// the fusion EKF both firmware boards carry: the fusion estimator's
    /// UKF or particle filter.
    #[must_use]
    pub fn required_build(&self) -> Option<OptionalBuild> {
        match self {
            Self::Fusion(FusionSpec {
                filter: FusionFilterSpec::Ukf,
                ..
            }) => Some(builds::FUSION_UKF),
            Self::Fusion(FusionSpec {
                filter: FusionFilterSpec::ParticleFilter,
                ..
            }) => Some(builds::FUSION_PARTICLE_FILTER),
            Self::Fusion(FusionSpec {
                filter: FusionFilterSpec::Ekf,
                ..
            })
            | Self::HeadingObserver
            | Self::PoseObserver { .. } => None,
        }
    }

    /// The validated estimator for control period `period_s` and the
    /// robot's `sensors`; paper 001's observer (5) runs with
    /// `heading_observer`, as the estimator or as the fusion estimator's
    /// heading guide.
    ///
    /// # Errors
    /// The estimator's own refusal, or
    /// [`EstimatorSpecError::NotInThisBuild`].
    pub fn build(
        &self,
        period_s: f32,
        sensors: &SensorSpec,
        heading_observer: HeadingObserverConfig,
    ) -> Result<EstimatorChoice, EstimatorSpecError> {
        Ok(match *self {
            Self::HeadingObserver => EstimatorChoice::HeadingObserver(heading_observer),
            Self::PoseObserver {
                gains: [a1, a2, a3, a4],
            } => EstimatorChoice::PoseObserver(
                PoseObserverConfig::new(a1, a2, a3, a4, period_s)
                    .map_err(EstimatorSpecError::PoseObserver)?,
            ),
            #[cfg(feature = "fusion-ekf")]
            Self::Fusion(fusion) => EstimatorChoice::Fusion {
                settings: fusion.build(period_s, sensors)?,
                guide: heading_observer,
            },
            #[cfg(not(feature = "fusion-ekf"))]
            Self::Fusion(_) => {
                let _ = sensors;
                return Err(EstimatorSpecError::NotInThisBuild);
            }
        })
    }
}

/// An estimator drawn from a fuzzer's bytes, its tuning near the defaults
/// ([`crate::fuzzing`]), on any of the three filters.
#[cfg(feature = "arbitrary")]
impl<'a> arbitrary::Arbitrary<'a> for EstimatorSpec {
    fn arbitrary(u: &mut arbitrary::Unstructured<'a>) -> arbitrary::Result<Self> {
        use crate::fuzzing::float;
        Ok(match u.int_in_range(0_u8..=3)? {
            0 => Self::HeadingObserver,
            1 => {
                let [a1, a2, a3, a4] = Self::DEFAULT_POSE_OBSERVER_GAINS;
                Self::PoseObserver {
                    gains: [float(u, a1)?, float(u, a2)?, float(u, a3)?, float(u, a4)?],
                }
            }
            _ => {
                let d = FusionSpec::default();
                Self::Fusion(FusionSpec {
                    filter: *u.choose(&[
                        FusionFilterSpec::Ekf,
                        FusionFilterSpec::Ukf,
                        FusionFilterSpec::ParticleFilter,
                    ])?,
                    wheel_variance_per_m: float(u, d.wheel_variance_per_m)?,
                    gate_sigma: float(u, d.gate_sigma)?,
                    scale_prior: float(u, 4e-4)?,
                    max_blind_distance_m: if u.arbitrary()? {
                        Some(float(u, 3.2)?)
                    } else {
                        None
                    },
                    edge_constraint: u.arbitrary()?,
                    particle_seed: u.arbitrary()?,
                    fix_latency_s: float(u, 0.01)?,
                })
            }
        })
    }
}
