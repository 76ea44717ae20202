//! Plain-data descriptions of a pilot, validated into its configuration.
//!
//! A [`PilotSpec`] holds the numbers a robot integrator writes down (wheel
//! radius, gains, limits, the reference), in SI units, with no invariants of
//! its own. [`PilotSpec::build`] passes each of them through the validating
//! constructor of the core type it belongs to and returns the
//! [`PilotConfig`], or the first refusal as a small `Copy` [`SpecError`].
//!
//! Why a separate plain type: the validated configurations keep their
//! fields private, so nothing can bypass their checks. A spec is what can be
//! compiled into a firmware image as a `const`, written in a scenario file,
//! or sent over the hardware-in-the-loop link (behind the `serde` feature),
//! and every one of those paths ends in the same constructors, so the
//! simulator and the firmware build bit-identical configurations from the
//! same spec.

use crate::control::LawChoice;
use crate::control::cascaded::{CascadedGains, CascadedGainsError};
use crate::control::heading_error_sine::{HeadingErrorSineConfig, HeadingErrorSineConfigError};
use crate::control::saturated::{GainError, TrackingGains};
use crate::devices::{TagGrid, TagGridError};
use crate::drive::{DriveConfig, DriveConfigError, SpeedLoopGains};
use crate::estimation::EstimatorChoice;
use crate::estimation::fusion::PoseFilterError;
#[cfg(feature = "fusion-ekf")]
use crate::estimation::fusion::{FusionFilter, FusionSettings, PoseFilterConfig};
use crate::estimation::heading_observer::{HeadingObserverConfig, ObserverConfigError};
use crate::estimation::pose_observer::{PoseObserverConfig, PoseObserverConfigError};
use crate::geometry::{DiffDriveGeometry, GeometryError, Vec2};
use crate::pilot::tracker::{TrackerConfig, TrackerConfigError};
use crate::pilot::{PilotConfig, PilotConfigError};
use crate::reference::{Circle, FigureEight, ReferenceError, StraightLine, Trajectory};

/// Why a spec was refused: the part, and that part's own error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum SpecError {
    /// The reference trajectory.
    Trajectory(ReferenceError),
    /// The tracking gains `k1, k2, k3`.
    Gains(GainError),
    /// The heading observer.
    Observer(ObserverConfigError),
    /// The tracker (fix timeout, failsafe deceleration, period).
    Tracker(TrackerConfigError),
    /// The robot's geometry.
    Geometry(GeometryError),
    /// The drive (limits, speed loop).
    Drive(DriveConfigError),
    /// The pilot (encoder counter width, periods).
    Pilot(PilotConfigError),
    /// The floor-tag grid.
    TagGrid(TagGridError),
    /// Paper 002's pose observer (Proposition 4).
    PoseObserver(PoseObserverConfigError),
    /// The fusion estimator.
    Fusion(PoseFilterError),
    /// A part this build of the core was compiled without (the fusion
    /// estimator needs the cargo feature `fusion-ekf`, its UKF
    /// `fusion-ukf`, its particle filter `fusion-particle-filter`).
    NotInThisBuild,
    /// Paper 002's cascaded controller (31).
    CascadedLaw(CascadedGainsError),
    /// Paper 002's Proposition 7 observer and controller.
    HeadingErrorSineLaw(HeadingErrorSineConfigError),
}

impl SpecError {
    /// The part of the spec the error is about, as a dotted path of
    /// [`PilotSpec`]'s fields: `""` where the field stands at its top
    /// (`encoder_bits`, [`Self::Pilot`]) and for [`Self::NotInThisBuild`].
    #[must_use]
    pub fn section(&self) -> &'static str {
        match self {
            Self::Trajectory(_) => "tracker.trajectory",
            Self::Gains(_) | Self::Observer(_) | Self::Tracker(_) => "tracker",
            Self::PoseObserver(_) => "tracker.estimator.pose_observer",
            Self::Fusion(_) => "tracker.estimator.fusion",
            Self::CascadedLaw(_) => "tracker.law.cascaded",
            Self::HeadingErrorSineLaw(_) => "tracker.law.heading_error_sine",
            Self::Geometry(_) | Self::Drive(_) => "drive",
            Self::Pilot(_) => "",
            Self::TagGrid(_) => "tag_grid",
            Self::NotInThisBuild => "",
        }
    }

    /// The part's own error.
    fn inner(&self) -> Option<&(dyn core::error::Error + 'static)> {
        Some(match self {
            Self::Trajectory(e) => e,
            Self::Gains(e) => e,
            Self::Observer(e) => e,
            Self::Tracker(e) => e,
            Self::Geometry(e) => e,
            Self::Drive(e) => e,
            Self::Pilot(e) => e,
            Self::TagGrid(e) => e,
            Self::PoseObserver(e) => e,
            Self::Fusion(e) => e,
            Self::CascadedLaw(e) => e,
            Self::HeadingErrorSineLaw(e) => e,
            Self::NotInThisBuild => return None,
        })
    }
}

/// `section: what is wrong`, e.g. `drive: max_wheel_speed_rad_s must be
/// finite and > 0 rad/s`.
impl core::fmt::Display for SpecError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self.inner() {
            Some(e) if self.section().is_empty() => write!(f, "{e}"),
            Some(e) => write!(f, "{}: {e}", self.section()),
            None => f.write_str(
                "this build of the core lacks the selected part (the fusion estimator needs \
                 the cargo feature fusion-ekf, its UKF fusion-ukf, its particle filter \
                 fusion-particle-filter)",
            ),
        }
    }
}

impl core::error::Error for SpecError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        self.inner()
    }
}

/// The tracker's heading estimator.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum EstimatorSpec {
    /// Paper 001's heading observer (5), gain `observer_gain_per_m`.
    #[default]
    HeadingObserver,
    /// Paper 002's Proposition 4 observer of `x, y, cos θ, sin θ`.
    PoseObserver {
        /// `[a1, a2]` (1/s) and `[a3, a4]` (1/m²) of (37).
        gains: [f32; 4],
    },
    /// The encoder + tag fusion estimator ([`crate::estimation::fusion`]) on the
    /// filter `filter`.
    Fusion {
        /// Which filter.
        filter: FusionFilterSpec,
        /// Track width, m.
        track_width_m: f32,
        /// Each wheel's travel variance per metre driven, m²/m.
        wheel_variance_per_m: f32,
        /// Its floor (count quantization), m².
        wheel_variance_floor_m2: f32,
        /// Mahalanobis gate, standard deviations (≥ 1).
        gate_sigma: f32,
        /// Tag grid spacing, m.
        tag_spacing_m: f32,
        /// Prior variance of each wheel's scale error (0: not estimated).
        scale_prior: f32,
        /// Reader range, m (0: the nearest tag is read every tick).
        read_radius_m: f32,
        /// The failsafe's limit on the distance driven since the last fix,
        /// m (0: the tracker's fix timeout decides instead).
        max_blind_distance_m: f32,
        /// Reads of an unchanged tag pull an estimate that left the cell
        /// back to its edge.
        edge_constraint: bool,
    },
}

/// The fusion estimator's filter.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum FusionFilterSpec {
    /// The EKF.
    #[default]
    Ekf,
    /// Paper 004's UKF ([`crate::estimation::fusion::ukf`]; cargo feature `fusion-ukf`).
    Ukf,
    /// Paper 004's particle filter ([`crate::estimation::fusion::particle`]; cargo
    /// feature `fusion-particle-filter`).
    ParticleFilter {
        /// The generator's seed.
        seed: u64,
    },
}

/// The tracker's law.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum LawSpec {
    /// Paper 001's saturated output-feedback law (27)–(28), gains `gains`.
    #[default]
    Saturated,
    /// Paper 002's cascaded controller (31).
    Cascaded {
        /// `c1`, 1/s (heading error).
        c1_per_s: f32,
        /// `c2`, 1/s (along-track error).
        c2_per_s: f32,
    },
    /// Paper 002's Proposition 7: observer of `sin θ_e` and controller (64).
    HeadingErrorSine {
        /// Observer gain `a`, s/m².
        a_s_per_m2: f32,
        /// `c2`, 1/s.
        c2_per_s: f32,
        /// `γ ∈ (0, 1)`.
        gamma: f32,
    },
}

/// A reference trajectory by its parameters (SI units, radians).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum TrajectorySpec {
    /// [`FigureEight::new`]: half-width `h1_m`, rate `h2_rad_s`, phase.
    FigureEight {
        /// `h1`, m.
        h1_m: f32,
        /// `h2`, rad/s.
        h2_rad_s: f32,
        /// Phase `φ`, rad.
        phase_rad: f32,
    },
    /// [`Circle::new`].
    Circle {
        /// Centre, m.
        center_m: [f32; 2],
        /// Radius, m.
        radius_m: f32,
        /// Angular rate, rad/s (sign gives the sense).
        rate_rad_s: f32,
        /// Phase at `t = 0`, rad.
        phase_rad: f32,
    },
    /// [`StraightLine::new`].
    Line {
        /// Start point, m.
        start_m: [f32; 2],
        /// Direction, rad.
        heading_rad: f32,
        /// Speed, m/s.
        speed_m_s: f32,
    },
}

impl TrajectorySpec {
    /// The validated trajectory.
    ///
    /// # Errors
    /// The constructor's refusal.
    pub fn build(&self) -> Result<Trajectory, ReferenceError> {
        Ok(match *self {
            Self::FigureEight {
                h1_m,
                h2_rad_s,
                phase_rad,
            } => FigureEight::new(h1_m, h2_rad_s, phase_rad)?.into(),
            Self::Circle {
                center_m: [cx, cy],
                radius_m,
                rate_rad_s,
                phase_rad,
            } => Circle::new(Vec2::new(cx, cy), radius_m, rate_rad_s, phase_rad)?.into(),
            Self::Line {
                start_m: [x, y],
                heading_rad,
                speed_m_s,
            } => StraightLine::new(Vec2::new(x, y), heading_rad, speed_m_s)?.into(),
        })
    }
}

/// The output-feedback tracker of paper 001: period, reference, gains,
/// observer and failsafe.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct TrackerSpec {
    /// Control period `h`, s.
    pub period_s: f32,
    /// The reference.
    pub trajectory: TrajectorySpec,
    /// Gains `[k1, k2, k3]` of the law (27)–(28).
    pub gains: [f32; 3],
    /// Observer gain `L`, 1/m.
    pub observer_gain_per_m: f32,
    /// Speed below which the observer only rotates its estimate, m/s.
    pub observer_min_speed_m_s: f32,
    /// Ticks without a valid fix before the failsafe engages.
    pub fix_timeout_ticks: u32,
    /// Failsafe deceleration, m/s².
    pub failsafe_decel_m_s2: f32,
    /// Age beyond which a fix is stale, ticks.
    pub max_fix_age_ticks: u32,
    /// The heading estimator (paper 001's observer by default).
    pub estimator: EstimatorSpec,
    /// The law (paper 001's by default).
    pub law: LawSpec,
}

impl TrackerSpec {
    /// The validated tracker configuration.
    ///
    /// # Errors
    /// The first part refused.
    pub fn build(&self) -> Result<TrackerConfig, SpecError> {
        let trajectory = self.trajectory.build().map_err(SpecError::Trajectory)?;
        let [k1, k2, k3] = self.gains;
        let gains = TrackingGains::new(k1, k2, k3).map_err(SpecError::Gains)?;
        let observer = HeadingObserverConfig::new(self.observer_gain_per_m, self.period_s)
            .and_then(|o| o.with_min_speed(self.observer_min_speed_m_s))
            .map_err(SpecError::Observer)?;
        let config = TrackerConfig::new(observer, gains, trajectory, self.fix_timeout_ticks)
            .and_then(|t| t.with_failsafe_decel(self.failsafe_decel_m_s2))
            .map(|t| t.with_max_fix_age(self.max_fix_age_ticks))
            .map_err(SpecError::Tracker)?;
        let estimator = match self.estimator {
            EstimatorSpec::HeadingObserver => EstimatorChoice::HeadingObserver,
            EstimatorSpec::PoseObserver {
                gains: [a1, a2, a3, a4],
            } => EstimatorChoice::PoseObserver(
                PoseObserverConfig::new(a1, a2, a3, a4, self.period_s)
                    .map_err(SpecError::PoseObserver)?,
            ),
            #[cfg(feature = "fusion-ekf")]
            EstimatorSpec::Fusion {
                filter,
                track_width_m,
                wheel_variance_per_m,
                wheel_variance_floor_m2,
                gate_sigma,
                tag_spacing_m,
                scale_prior,
                read_radius_m,
                max_blind_distance_m,
                edge_constraint,
            } => {
                let (kind, seed) = match filter {
                    FusionFilterSpec::Ekf => (FusionFilter::Ekf, 1),
                    #[cfg(feature = "fusion-ukf")]
                    FusionFilterSpec::Ukf => (FusionFilter::Ukf, 1),
                    #[cfg(feature = "fusion-particle-filter")]
                    FusionFilterSpec::ParticleFilter { seed } => {
                        (FusionFilter::ParticleFilter, seed)
                    }
                    #[allow(unreachable_patterns)]
                    _ => return Err(SpecError::NotInThisBuild),
                };
                let settings = PoseFilterConfig::new(
                    track_width_m,
                    wheel_variance_per_m,
                    wheel_variance_floor_m2,
                    gate_sigma,
                )
                .map(|filter| filter.with_particle_seed(seed))
                .and_then(|filter| FusionSettings::new(filter, tag_spacing_m, scale_prior))
                .and_then(|settings| settings.with_read_radius(read_radius_m))
                .and_then(|settings| settings.with_max_blind_distance(max_blind_distance_m))
                .map_err(SpecError::Fusion)?
                .with_filter(kind)
                .with_edge_constraint(edge_constraint);
                EstimatorChoice::Fusion(settings)
            }
            #[cfg(not(feature = "fusion-ekf"))]
            EstimatorSpec::Fusion { .. } => return Err(SpecError::NotInThisBuild),
        };
        let law = match self.law {
            LawSpec::Saturated => LawChoice::Saturated,
            LawSpec::Cascaded { c1_per_s, c2_per_s } => LawChoice::Cascaded(
                CascadedGains::new(c1_per_s, c2_per_s).map_err(SpecError::CascadedLaw)?,
            ),
            LawSpec::HeadingErrorSine {
                a_s_per_m2,
                c2_per_s,
                gamma,
            } => LawChoice::HeadingErrorSine(
                HeadingErrorSineConfig::new(a_s_per_m2, c2_per_s, gamma, self.period_s)
                    .map_err(SpecError::HeadingErrorSineLaw)?,
            ),
        };
        config
            .with_estimator(estimator)
            .and_then(|config| config.with_law(law))
            .map_err(SpecError::Tracker)
    }
}

/// The drive: geometry, wheel limits and the speed loop.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct DriveSpec {
    /// Wheel radius, m.
    pub wheel_radius_m: f32,
    /// Distance between the wheels' contact points, m.
    pub track_width_m: f32,
    /// Encoder counts per wheel revolution (after quadrature decoding).
    pub encoder_counts_per_rev: u32,
    /// Wheel speed limit, rad/s.
    pub max_wheel_speed_rad_s: f32,
    /// Wheel acceleration limit, rad/s².
    pub max_wheel_accel_rad_s2: f32,
    /// Feed-forward duty per rad/s.
    pub feedforward_duty_per_rad_s: f32,
    /// Proportional gain, duty per rad/s.
    pub kp_duty_per_rad_s: f32,
    /// Integral gain, duty per rad.
    pub ki_duty_per_rad: f32,
}

impl DriveSpec {
    /// The validated drive configuration for control period `period_s`.
    ///
    /// # Errors
    /// The first part refused.
    pub fn build(&self, period_s: f32) -> Result<DriveConfig, SpecError> {
        let geometry = DiffDriveGeometry::new(
            self.wheel_radius_m,
            self.track_width_m,
            self.encoder_counts_per_rev,
        )
        .map_err(SpecError::Geometry)?;
        DriveConfig::new(
            geometry,
            period_s,
            self.max_wheel_speed_rad_s,
            self.max_wheel_accel_rad_s2,
            SpeedLoopGains {
                feedforward_duty_per_rad_s: self.feedforward_duty_per_rad_s,
                kp_duty_per_rad_s: self.kp_duty_per_rad_s,
                ki_duty_per_rad: self.ki_duty_per_rad,
            },
        )
        .map_err(SpecError::Drive)
    }
}

/// Everything a [`crate::pilot::Pilot`] needs.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct PilotSpec {
    /// Tracker (its period is the control period).
    pub tracker: TrackerSpec,
    /// Drive.
    pub drive: DriveSpec,
    /// Width of the hardware encoder counters, bits (16 on most STM32 timers).
    pub encoder_bits: u32,
    /// Consecutive encoder fault ticks bridged before the motors stop.
    pub max_encoder_fault_ticks: u32,
}

impl PilotSpec {
    /// The validated pilot configuration.
    ///
    /// # Errors
    /// The first part refused.
    pub fn build(&self) -> Result<PilotConfig, SpecError> {
        let tracker = self.tracker.build()?;
        let drive = self.drive.build(self.tracker.period_s)?;
        PilotConfig::new(tracker, drive, self.encoder_bits)
            .map(|p| p.with_max_encoder_fault_ticks(self.max_encoder_fault_ticks))
            .map_err(SpecError::Pilot)
    }
}

/// A regular floor-tag grid ([`TagGrid::new`]).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct TagGridSpec {
    /// Position of tag (row 0, column 0), m.
    pub origin_m: [f32; 2],
    /// Spacing between neighbours, m.
    pub spacing_m: f32,
    /// Rows (along y).
    pub rows: u16,
    /// Columns (along x).
    pub columns: u16,
}

impl TagGridSpec {
    /// The validated grid.
    ///
    /// # Errors
    /// [`SpecError::TagGrid`].
    pub fn build(&self) -> Result<TagGrid, SpecError> {
        let [x, y] = self.origin_m;
        TagGrid::new(Vec2::new(x, y), self.spacing_m, self.rows, self.columns)
            .map_err(SpecError::TagGrid)
    }

    /// The spec of a grid (inverse of [`Self::build`]).
    #[must_use]
    pub fn of(grid: &TagGrid) -> Self {
        let origin = grid.origin();
        Self {
            origin_m: [origin.x, origin.y],
            spacing_m: grid.spacing_m(),
            rows: grid.rows(),
            columns: grid.columns(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pilot::Pilot;

    fn paper_spec() -> PilotSpec {
        PilotSpec {
            tracker: TrackerSpec {
                period_s: 0.01,
                trajectory: TrajectorySpec::FigureEight {
                    h1_m: 5.0,
                    h2_rad_s: 0.02,
                    phase_rad: -core::f32::consts::FRAC_PI_2,
                },
                gains: [0.5, 0.5, 1.0],
                observer_gain_per_m: 10.0,
                observer_min_speed_m_s: 1e-3,
                fix_timeout_ticks: 50,
                failsafe_decel_m_s2: 0.5,
                max_fix_age_ticks: 2,
                estimator: crate::pilot::spec::EstimatorSpec::HeadingObserver,
                law: crate::pilot::spec::LawSpec::Saturated,
            },
            drive: DriveSpec {
                wheel_radius_m: 0.05,
                track_width_m: 0.3,
                encoder_counts_per_rev: 2048,
                max_wheel_speed_rad_s: 20.0,
                max_wheel_accel_rad_s2: 40.0,
                feedforward_duty_per_rad_s: 0.05,
                kp_duty_per_rad_s: 0.05,
                ki_duty_per_rad: 0.5,
            },
            encoder_bits: 16,
            max_encoder_fault_ticks: 5,
        }
    }

    /// Errors name the spec field and the rule, in the spec's words.
    #[test]
    fn errors_say_which_field_and_why() {
        extern crate std;
        use std::string::ToString;
        let mut s = paper_spec();
        s.drive.max_wheel_speed_rad_s = -1.0;
        let e = s.build().unwrap_err();
        assert_eq!(
            e.to_string(),
            "drive: max_wheel_speed_rad_s must be finite and > 0 rad/s"
        );
        assert!(core::error::Error::source(&e).is_some());
        let mut s = paper_spec();
        s.tracker.gains[1] = f32::NAN;
        assert_eq!(
            s.build().unwrap_err().to_string(),
            "tracker: gains[1] (k2) must be finite and > 0 m/s"
        );
        let mut s = paper_spec();
        s.encoder_bits = 40;
        assert_eq!(
            s.build().unwrap_err().to_string(),
            "encoder_bits must be 2..=32"
        );
        let mut s = paper_spec();
        s.tracker.fix_timeout_ticks = 0;
        assert_eq!(
            s.build().unwrap_err().to_string(),
            "tracker: fix_timeout_ticks must be ≥ 1"
        );
    }

    #[test]
    fn paper_spec_builds_the_same_as_the_constructors() {
        let spec = paper_spec();
        let config = spec.build().unwrap();
        assert_eq!(config.tracker().clock().period_s(), 0.01);
        assert_eq!(
            *config.tracker().trajectory(),
            Trajectory::from(FigureEight::paper_001())
        );
        assert_eq!(config.tracker().fix_timeout_ticks(), 50);
        assert_eq!(config.drive().geometry().counts_per_revolution(), 2048);
        assert!(Pilot::new(config).is_ok());
    }

    #[test]
    fn each_refusal_names_its_part() {
        let mut s = paper_spec();
        s.tracker.gains[1] = f32::NAN;
        assert_eq!(s.build(), Err(SpecError::Gains(GainError::K2)));
        let mut s = paper_spec();
        s.tracker.trajectory = TrajectorySpec::Line {
            start_m: [0.0, 0.0],
            heading_rad: 0.0,
            speed_m_s: -1.0,
        };
        assert_eq!(s.build(), Err(SpecError::Trajectory(ReferenceError::Rate)));
        let mut s = paper_spec();
        s.tracker.observer_gain_per_m = 0.0;
        assert_eq!(
            s.build(),
            Err(SpecError::Observer(ObserverConfigError::Gain))
        );
        let mut s = paper_spec();
        s.tracker.fix_timeout_ticks = 0;
        assert_eq!(
            s.build(),
            Err(SpecError::Tracker(TrackerConfigError::FixTimeout))
        );
        let mut s = paper_spec();
        s.drive.track_width_m = f32::INFINITY;
        assert_eq!(
            s.build(),
            Err(SpecError::Geometry(GeometryError::TrackWidth))
        );
        let mut s = paper_spec();
        s.drive.ki_duty_per_rad = -1.0;
        assert_eq!(
            s.build(),
            Err(SpecError::Drive(DriveConfigError::SpeedLoopGain))
        );
        let mut s = paper_spec();
        s.tracker.estimator = EstimatorSpec::Fusion {
            filter: FusionFilterSpec::Ekf,
            track_width_m: 0.2,
            wheel_variance_per_m: 1e-3,
            wheel_variance_floor_m2: 1e-9,
            gate_sigma: 3.0,
            tag_spacing_m: 0.0,
            scale_prior: 0.0,
            read_radius_m: 0.0,
            max_blind_distance_m: 0.0,
            edge_constraint: false,
        };
        let expected = if cfg!(feature = "fusion-ekf") {
            SpecError::Fusion(crate::estimation::fusion::PoseFilterError::TagSpacing)
        } else {
            SpecError::NotInThisBuild
        };
        assert_eq!(s.build(), Err(expected));
        let mut s = paper_spec();
        s.encoder_bits = 33;
        assert_eq!(
            s.build(),
            Err(SpecError::Pilot(PilotConfigError::EncoderBits))
        );
    }

    #[test]
    fn grid_spec_round_trips() {
        let spec = TagGridSpec {
            origin_m: [-6.0, -6.5],
            spacing_m: 0.1,
            rows: 130,
            columns: 120,
        };
        let grid = spec.build().unwrap();
        assert_eq!(TagGridSpec::of(&grid), spec);
        let bad = TagGridSpec { rows: 0, ..spec };
        assert_eq!(bad.build(), Err(SpecError::TagGrid(TagGridError::Size)));
    }
}
