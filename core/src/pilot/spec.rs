//! Plain-data descriptions of a pilot, validated into its configuration.
//!
//! A [`PilotSpec`] holds the numbers a robot integrator writes down (wheel
//! radius, gains, limits, the reference), in SI units, with no invariants of
//! its own. [`PilotSpec::build`] passes each of them through the validating
//! constructor of the core type it belongs to and returns the
//! [`PilotConfig`], or the first refusal as a small `Copy` [`SpecError`]
//! whose [`SpecError::section`] says which part of the spec it is about.
//!
//! Each layer's spec lives beside its block and builds it with that
//! layer's own error: the reference's [`TrajectorySpec`]
//! ([`crate::reference`]), the estimators' [`EstimatorSpec`] and
//! [`SensorSpec`] ([`crate::estimation::spec`]), the laws' [`LawSpec`]
//! ([`crate::control::spec`]), the drive's [`DriveSpec`]
//! ([`crate::drive::spec`]) and the floor's
//! [`crate::devices::tag_grid::TagGridSpec`]. This module keeps the
//! tracker's and the pilot's own fields and composes the rest.
//!
//! Why a separate plain type: the validated configurations keep their
//! fields private, so nothing can bypass their checks. A spec is what can be
//! compiled into a firmware image as a `const`, written in a scenario file,
//! or sent over the hardware-in-the-loop link (behind the `serde` feature),
//! and every one of those paths ends in the same constructors, so the
//! simulator and the firmware build bit-identical configurations from the
//! same spec.

use crate::builds::OptionalBuild;
use crate::control::saturated::{GainError, TrackingGains};
use crate::control::spec::{LawSpec, LawSpecError};
use crate::devices::TagGridError;
use crate::drive::DriveConfigError;
use crate::drive::momenta_observer::MomentaObserverError;
use crate::drive::spec::{DriveSpec, DriveSpecError};

use crate::estimation::heading_observer::{HeadingObserverConfig, ObserverConfigError};
use crate::estimation::spec::{EstimatorSpec, EstimatorSpecError, SensorSpec};
use crate::geometry::{GeometryError, Vec2};
use crate::pilot::tracker::{TrackerConfig, TrackerConfigError};
use crate::pilot::{PilotConfig, PilotConfigError};
use crate::reference::{ReferenceError, TrajectorySpec};

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
    /// The estimator ([`EstimatorSpec`]; never its
    /// [`EstimatorSpecError::NotInThisBuild`], which is
    /// [`Self::NotInThisBuild`]).
    Estimator(EstimatorSpecError),
    /// A part this build of the core was compiled without (the fusion
    /// estimator needs the cargo feature `fusion-ekf`, its UKF
    /// `fusion-ukf`, its particle filter `fusion-particle-filter`; the
    /// wheel-speed observer `wheel-speed-observer`).
    NotInThisBuild,
    /// The law ([`LawSpec`]).
    Law(LawSpecError),
    /// The sensors' track width differs from the drive's.
    SensorTrackWidth,
    /// Paper 003's wheel-speed observer of the speed loops
    /// ([`crate::drive::spec::SpeedObserverSpec`]).
    SpeedObserver(MomentaObserverError),
}

impl SpecError {
    /// The part of the spec the error is about.
    #[must_use]
    pub fn section(&self) -> SpecSection {
        match self {
            Self::Trajectory(_) => SpecSection::Trajectory,
            Self::Tracker(TrackerConfigError::AntennaOffset) => SpecSection::Sensors,
            Self::Gains(_) | Self::Observer(_) | Self::Tracker(_) => SpecSection::Tracker,
            // Built by hand rather than through `From`: still the build's.
            Self::Estimator(EstimatorSpecError::NotInThisBuild) => SpecSection::Build,
            Self::Estimator(e) if e.is_about_sensors() => SpecSection::Sensors,
            Self::SensorTrackWidth => SpecSection::Sensors,
            Self::Estimator(e) => SpecSection::Estimator(e.estimator_key()),
            Self::Law(e) => SpecSection::Law(e.law_key()),
            Self::Geometry(_) | Self::Drive(_) => SpecSection::Drive,
            Self::SpeedObserver(_) => SpecSection::SpeedObserver,
            Self::Pilot(_) => SpecSection::Pilot,
            Self::TagGrid(_) => SpecSection::TagGrid,
            Self::NotInThisBuild => SpecSection::Build,
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
            Self::Estimator(e) => return core::error::Error::source(e),
            Self::Law(e) => return core::error::Error::source(e),
            Self::SpeedObserver(e) => e,
            Self::NotInThisBuild | Self::SensorTrackWidth => return None,
        })
    }
}

/// The part of a [`PilotSpec`] a [`SpecError`] is about; it displays as
/// a dotted path of [`PilotSpec`]'s fields (nothing for the pilot's own
/// fields and for [`Self::Build`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SpecSection {
    /// The pilot's own fields (`encoder_bits`, `max_encoder_fault_ticks`).
    Pilot,
    /// The tracker's own fields: period, gains `k1, k2, k3`, paper 001's
    /// observer, fix timeout and age, failsafe deceleration.
    Tracker,
    /// The reference trajectory ([`TrajectorySpec`]).
    Trajectory,
    /// The sensor facts ([`SensorSpec`]).
    Sensors,
    /// The estimator's own table, by its key in [`EstimatorSpec`]
    /// (`pose_observer`, `fusion`).
    Estimator(&'static str),
    /// The law's own table, by its key in [`LawSpec`] (`cascaded`,
    /// `heading_error_sine`).
    Law(&'static str),
    /// The drive ([`DriveSpec`]: geometry, limits, speed loop).
    Drive,
    /// Paper 003's wheel-speed observer
    /// ([`crate::drive::spec::SpeedObserverSpec`]).
    SpeedObserver,
    /// The floor-tag grid ([`crate::devices::tag_grid::TagGridSpec`]).
    TagGrid,
    /// A part this build of the core was compiled without.
    Build,
}

impl core::fmt::Display for SpecSection {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Pilot | Self::Build => Ok(()),
            Self::Tracker => f.write_str("tracker"),
            Self::Trajectory => f.write_str("tracker.trajectory"),
            Self::Sensors => f.write_str("tracker.sensors"),
            Self::Estimator(key) => write!(f, "tracker.estimator.{key}"),
            Self::Law(key) => write!(f, "tracker.law.{key}"),
            Self::Drive => f.write_str("drive"),
            Self::SpeedObserver => f.write_str("drive.speed_observer"),
            Self::TagGrid => f.write_str("tag_grid"),
        }
    }
}

impl From<EstimatorSpecError> for SpecError {
    fn from(e: EstimatorSpecError) -> Self {
        match e {
            EstimatorSpecError::NotInThisBuild => Self::NotInThisBuild,
            e => Self::Estimator(e),
        }
    }
}

impl From<LawSpecError> for SpecError {
    fn from(e: LawSpecError) -> Self {
        Self::Law(e)
    }
}

impl From<TagGridError> for SpecError {
    fn from(e: TagGridError) -> Self {
        Self::TagGrid(e)
    }
}

impl From<DriveSpecError> for SpecError {
    fn from(e: DriveSpecError) -> Self {
        match e {
            DriveSpecError::Geometry(e) => Self::Geometry(e),
            DriveSpecError::Drive(e) => Self::Drive(e),
            DriveSpecError::SpeedObserver(e) => Self::SpeedObserver(e),
            DriveSpecError::NotInThisBuild => Self::NotInThisBuild,
        }
    }
}

/// `section: what is wrong`, e.g. `drive: max_wheel_speed_rad_s must be
/// finite and > 0 rad/s`.
impl core::fmt::Display for SpecError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self.inner() {
            Some(e) if matches!(self.section(), SpecSection::Pilot | SpecSection::Build) => {
                write!(f, "{e}")
            }
            Some(e) => write!(f, "{}: {e}", self.section()),
            None if *self == Self::SensorTrackWidth => write!(
                f,
                "{}: track_width_m must equal drive.track_width_m",
                self.section()
            ),
            None => f.write_str(
                "this build of the core lacks the selected part (the fusion estimator needs \
                 the cargo feature fusion-ekf, its UKF fusion-ukf, its particle filter \
                 fusion-particle-filter; drive.speed_observer needs wheel-speed-observer)",
            ),
        }
    }
}

impl core::error::Error for SpecError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        self.inner()
    }
}

/// The output-feedback tracker of paper 001: period, reference, gains,
/// observer and failsafe.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct TrackerSpec {
    /// Control period `h`, s, in [`crate::plausible::PERIOD_S`].
    pub period_s: f32,
    /// The reference.
    #[cfg_attr(feature = "serde", serde(with = "crate::reference::TrajectoryWire"))]
    pub trajectory: TrajectorySpec,
    /// Gains `[k1, k2, k3]` of the law (27)–(28), each in [`crate::plausible::GAIN`].
    pub gains: [f32; 3],
    /// Observer gain `L`, 1/m, in [`crate::plausible::GAIN`].
    pub observer_gain_per_m: f32,
    /// Speed below which the observer only rotates its estimate, m/s, in
    /// [`crate::plausible::MIN_SPEED_M_S`].
    pub observer_min_speed_m_s: f32,
    /// Ticks without a valid fix before the failsafe engages.
    pub fix_timeout_ticks: u32,
    /// Failsafe deceleration, m/s², in [`crate::plausible::DECEL_M_S2`].
    pub failsafe_decel_m_s2: f32,
    /// Age beyond which a fix is stale, ticks.
    pub max_fix_age_ticks: u32,
    /// The estimator (paper 001's observer by default).
    pub estimator: EstimatorSpec,
    /// What the estimator knows of the robot's sensors.
    pub sensors: SensorSpec,
    /// The law (paper 001's by default).
    pub law: LawSpec,
}

impl TrackerSpec {
    /// The validated tracker configuration.
    ///
    /// # Errors
    /// The first part refused, in this order: the trajectory, the gains,
    /// paper 001's observer, the estimator, the law, then the tracker's
    /// own fields (fix timeout, estimator and law periods, failsafe
    /// deceleration, antenna offset).
    pub fn build(&self) -> Result<TrackerConfig, SpecError> {
        let trajectory = self.trajectory.build().map_err(SpecError::Trajectory)?;
        let [k1, k2, k3] = self.gains;
        let gains = TrackingGains::new(k1, k2, k3).map_err(SpecError::Gains)?;
        let observer = HeadingObserverConfig::new(self.observer_gain_per_m, self.period_s)
            .and_then(|o| o.with_min_speed(self.observer_min_speed_m_s))
            .map_err(SpecError::Observer)?;
        let estimator = self
            .estimator
            .build(self.period_s, &self.sensors, observer)?;
        let law = self.law.build(gains, self.period_s)?;
        TrackerConfig::new(estimator, law, trajectory, self.fix_timeout_ticks)
            .and_then(|t| t.with_failsafe_decel(self.failsafe_decel_m_s2))
            .map(|t| t.with_max_fix_age(self.max_fix_age_ticks))
            .and_then(|t| {
                let [ahead, left] = self.sensors.antenna_offset_m;
                t.with_antenna_offset(Vec2::new(ahead, left))
            })
            .map_err(SpecError::Tracker)
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
    /// A complete, valid spec to start from in tests, examples and fuzz
    /// seeds (`PilotSpec { drive: …, ..PilotSpec::EXAMPLE }`): paper 001's
    /// figure-eight (`h1` = 5 m, `h2` = 0.02 rad/s, from `(0, −5)` m)
    /// tracked at 100 Hz by paper 001's observer (gain 10 /m) and law
    /// (`k1, k2, k3` = 0.5, 0.5, 1), on a robot with 5 cm wheels, a 30 cm
    /// track and 2048-count encoders on 16-bit counters, over a 10 cm tag
    /// grid. Not a tuning for a robot: a robot file states its own.
    pub const EXAMPLE: Self = Self {
        tracker: TrackerSpec {
            period_s: 0.01,
            trajectory: TrajectorySpec::FigureEight {
                h1_m: TrajectorySpec::PAPER_H1_M,
                h2_rad_s: TrajectorySpec::PAPER_H2_RAD_S,
                phase_rad: TrajectorySpec::PAPER_PHASE_RAD,
            },
            gains: [0.5, 0.5, 1.0],
            observer_gain_per_m: 10.0,
            observer_min_speed_m_s: 1e-3,
            fix_timeout_ticks: 50,
            failsafe_decel_m_s2: 0.5,
            max_fix_age_ticks: 2,
            estimator: EstimatorSpec::HeadingObserver,
            law: LawSpec::Saturated,
            sensors: SensorSpec {
                track_width_m: 0.3,
                // Count quantum q = 2π·0.05 m / 2048: q²/12.
                wheel_variance_floor_m2: 1.96e-9,
                tag_spacing_m: 0.1,
                read_radius_m: 0.0,
                antenna_offset_m: [0.0; 2],
            },
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
            speed_observer: None,
        },
        encoder_bits: 16,
        max_encoder_fault_ticks: 5,
    };

    /// The optional builds ([`crate::builds`]) this spec needs beyond what
    /// both firmware boards carry (the fusion EKF): the fusion estimator's
    /// UKF or particle filter, the wheel-speed observer.
    pub fn required_builds(&self) -> impl Iterator<Item = OptionalBuild> {
        let observer = self.drive.required_build();
        observer
            .into_iter()
            .chain(self.tracker.estimator.required_build())
    }

    /// The validated pilot configuration.
    ///
    /// # Errors
    /// The first part refused.
    pub fn build(&self) -> Result<PilotConfig, SpecError> {
        let tracker = self.tracker.build()?;
        let drive = self.drive.build(self.tracker.period_s)?;
        if self.tracker.sensors.track_width_m.to_bits() != self.drive.track_width_m.to_bits() {
            return Err(SpecError::SensorTrackWidth);
        }
        PilotConfig::new(tracker, drive, self.encoder_bits)
            .map(|p| p.with_max_encoder_fault_ticks(self.max_encoder_fault_ticks))
            .map_err(SpecError::Pilot)
    }
}

/// A pilot drawn from a fuzzer's bytes, around a typical 2048-count,
/// 0.3 m robot at 100 Hz ([`crate::fuzzing`]); each part is drawn by its
/// own spec's `Arbitrary`.
#[cfg(feature = "arbitrary")]
impl<'a> arbitrary::Arbitrary<'a> for PilotSpec {
    fn arbitrary(u: &mut arbitrary::Unstructured<'a>) -> arbitrary::Result<Self> {
        use crate::fuzzing::{count, float};
        let period_s = float(u, 0.01)?;
        let drive: DriveSpec = u.arbitrary()?;
        // The sensors' track width must equal the drive's (bit for bit):
        // keep it so most of the time.
        let sensor_track_width_m = if u.ratio(7, 8)? {
            drive.track_width_m
        } else {
            float(u, 0.3)?
        };
        let tracker = TrackerSpec {
            period_s,
            trajectory: u.arbitrary()?,
            gains: [float(u, 0.5)?, float(u, 0.5)?, float(u, 1.0)?],
            observer_gain_per_m: float(u, 10.0)?,
            observer_min_speed_m_s: float(u, 1e-3)?,
            fix_timeout_ticks: count(u, 50)?,
            failsafe_decel_m_s2: float(u, 0.5)?,
            max_fix_age_ticks: count(u, 2)?,
            estimator: u.arbitrary()?,
            law: u.arbitrary()?,
            sensors: SensorSpec {
                track_width_m: sensor_track_width_m,
                wheel_variance_floor_m2: float(u, 1.96e-9)?,
                tag_spacing_m: float(u, 0.1)?,
                read_radius_m: float(u, 0.0)?,
                antenna_offset_m: [float(u, 0.1)?, float(u, 0.0)?],
            },
        };
        Ok(Self {
            tracker,
            drive,
            encoder_bits: count(u, 16)?,
            max_encoder_fault_ticks: count(u, 5)?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::drive::spec::SpeedObserverSpec;
    #[cfg(feature = "fusion-ekf")]
    use crate::estimation::fusion::{FusionSettings, PoseFilterConfig};
    use crate::estimation::spec::{FusionFilterSpec, FusionSpec};
    use crate::pilot::Pilot;
    use crate::reference::{FigureEight, Trajectory};

    /// Errors name the spec field and the rule, in the spec's words.
    #[test]
    fn errors_say_which_field_and_why() {
        extern crate std;
        use std::string::ToString;
        let mut s = PilotSpec::EXAMPLE;
        s.drive.max_wheel_speed_rad_s = -1.0;
        let e = s.build().unwrap_err();
        assert_eq!(
            e.to_string(),
            "drive: max_wheel_speed_rad_s must be in [0.001, 10000] rad/s"
        );
        assert!(core::error::Error::source(&e).is_some());
        let mut s = PilotSpec::EXAMPLE;
        s.tracker.gains[1] = f32::NAN;
        assert_eq!(
            s.build().unwrap_err().to_string(),
            "tracker: gains[1] (k2) must be in [0.000001, 10000] m/s"
        );
        let mut s = PilotSpec::EXAMPLE;
        s.encoder_bits = 40;
        assert_eq!(
            s.build().unwrap_err().to_string(),
            "encoder_bits must be 2..=32"
        );
        let mut s = PilotSpec::EXAMPLE;
        s.tracker.fix_timeout_ticks = 0;
        assert_eq!(
            s.build().unwrap_err().to_string(),
            "tracker: fix_timeout_ticks must be ≥ 1"
        );
        let mut s = PilotSpec::EXAMPLE;
        s.tracker.sensors.track_width_m = 0.31;
        assert_eq!(
            s.build().unwrap_err().to_string(),
            "tracker.sensors: track_width_m must equal drive.track_width_m"
        );
        if cfg!(feature = "fusion-ekf") {
            let mut s = PilotSpec::EXAMPLE;
            s.tracker.estimator = EstimatorSpec::Fusion(FusionSpec {
                gate_sigma: 0.5,
                ..FusionSpec::default()
            });
            assert_eq!(
                s.build().unwrap_err().to_string(),
                "tracker.estimator.fusion: gate_sigma must be finite and ≥ 1"
            );
            s.tracker.estimator = EstimatorSpec::Fusion(FusionSpec::default());
            s.tracker.sensors.read_radius_m = -1.0;
            assert_eq!(
                s.build().unwrap_err().to_string(),
                "tracker.sensors: read_radius_m must be in [0, 1] m (and > 0 on a tag map)"
            );
        }
    }

    /// A wheel-speed observer of a 2 kg robot, but for its mass and
    /// motors' stall torque.
    fn speed_observer(mass_kg: f32, stall_torque_nm: f32) -> SpeedObserverSpec {
        SpeedObserverSpec {
            mass_kg,
            yaw_inertia_kg_m2: 0.02,
            wheel_inertia_kg_m2: 0.0,
            stall_torque_nm,
            no_load_speed_rad_s: 20.0,
            lambda_per_s: 5.0,
            friction_gain: 0.01,
            disturbance_gain: 0.1,
        }
    }

    /// Every physical quantity of a spec at the ends of its plausible range
    /// builds, and one `f32` step beyond either end is refused naming the
    /// part and the key.
    #[test]
    fn every_range_holds_its_ends_and_refuses_beyond() {
        use crate::plausible::{self as p, Range};
        type Set = fn(&mut PilotSpec, f32);
        let cases: [(&str, Range, Set); 27] = [
            ("period_s", p::PERIOD_S, |s, v| {
                s.tracker.period_s = v;
            }),
            ("h1_m", p::REFERENCE_SIZE_M, |s, v| {
                s.tracker.trajectory = TrajectorySpec::FigureEight {
                    h1_m: v,
                    h2_rad_s: 0.02,
                    phase_rad: 0.0,
                };
            }),
            ("h2_rad_s", p::REFERENCE_RATE_RAD_S, |s, v| {
                s.tracker.trajectory = TrajectorySpec::FigureEight {
                    h1_m: 5.0,
                    h2_rad_s: v,
                    phase_rad: 0.0,
                };
            }),
            ("phase_rad", p::ANGLE_RAD, |s, v| {
                s.tracker.trajectory = TrajectorySpec::FigureEight {
                    h1_m: 5.0,
                    h2_rad_s: 0.02,
                    phase_rad: v,
                };
            }),
            ("radius_m", p::REFERENCE_SIZE_M, |s, v| {
                s.tracker.trajectory = TrajectorySpec::Circle {
                    center_m: [0.0; 2],
                    radius_m: v,
                    rate_rad_s: 0.05,
                    phase_rad: 0.0,
                };
            }),
            ("rate_rad_s", p::REFERENCE_RATE_RAD_S, |s, v| {
                s.tracker.trajectory = TrajectorySpec::Circle {
                    center_m: [0.0; 2],
                    radius_m: 2.0,
                    rate_rad_s: -v,
                    phase_rad: 0.0,
                };
            }),
            ("center_m", p::COORDINATE_M, |s, v| {
                s.tracker.trajectory = TrajectorySpec::Circle {
                    center_m: [0.0, v],
                    radius_m: 2.0,
                    rate_rad_s: 0.05,
                    phase_rad: 0.0,
                };
            }),
            ("speed_m_s", p::REFERENCE_SPEED_M_S, |s, v| {
                s.tracker.trajectory = TrajectorySpec::Line {
                    start_m: [0.0; 2],
                    heading_rad: 0.0,
                    speed_m_s: v,
                };
            }),
            ("start_m", p::COORDINATE_M, |s, v| {
                s.tracker.trajectory = TrajectorySpec::Line {
                    start_m: [v, 0.0],
                    heading_rad: 0.0,
                    speed_m_s: 0.1,
                };
            }),
            ("heading_rad", p::ANGLE_RAD, |s, v| {
                s.tracker.trajectory = TrajectorySpec::Line {
                    start_m: [0.0; 2],
                    heading_rad: v,
                    speed_m_s: 0.1,
                };
            }),
            ("(k1)", p::GAIN, |s, v| s.tracker.gains[0] = v),
            ("(k3)", p::GAIN, |s, v| s.tracker.gains[2] = v),
            ("observer_gain_per_m", p::GAIN, |s, v| {
                s.tracker.observer_gain_per_m = v;
            }),
            ("observer_min_speed_m_s", p::MIN_SPEED_M_S, |s, v| {
                s.tracker.observer_min_speed_m_s = v;
            }),
            ("failsafe_decel_m_s2", p::DECEL_M_S2, |s, v| {
                s.tracker.failsafe_decel_m_s2 = v;
            }),
            ("wheel_radius_m", p::WHEEL_RADIUS_M, |s, v| {
                s.drive.wheel_radius_m = v;
            }),
            ("track_width_m", p::TRACK_WIDTH_M, |s, v| {
                s.drive.track_width_m = v;
                s.tracker.sensors.track_width_m = v;
            }),
            ("max_wheel_speed_rad_s", p::WHEEL_SPEED_RAD_S, |s, v| {
                s.drive.max_wheel_speed_rad_s = v;
            }),
            ("max_wheel_accel_rad_s2", p::WHEEL_ACCEL_RAD_S2, |s, v| {
                s.drive.max_wheel_accel_rad_s2 = v;
            }),
            ("speed-loop gains", p::SPEED_LOOP_GAIN, |s, v| {
                s.drive.ki_duty_per_rad = v;
            }),
            ("c1_per_s", p::GAIN, |s, v| {
                s.tracker.law = LawSpec::Cascaded {
                    c1_per_s: v,
                    c2_per_s: 0.5,
                };
            }),
            ("a_s_per_m2", p::GAIN, |s, v| {
                s.tracker.law = LawSpec::HeadingErrorSine {
                    a_s_per_m2: v,
                    c2_per_s: 0.5,
                    gamma: 0.9,
                };
            }),
            ("(a3)", p::GAIN, |s, v| {
                s.tracker.estimator = EstimatorSpec::PoseObserver {
                    gains: [1.5, 1.5, v, 100.0],
                };
            }),
            ("tag_spacing_m", p::TAG_SPACING_M, |s, v| {
                s.tracker.estimator = EstimatorSpec::fusion(FusionFilterSpec::Ekf);
                s.tracker.sensors.tag_spacing_m = v;
            }),
            ("read_radius_m", p::READ_RADIUS_M, |s, v| {
                s.tracker.estimator = EstimatorSpec::fusion(FusionFilterSpec::Ekf);
                s.tracker.sensors.read_radius_m = v;
            }),
            ("mass_kg", p::MASS_KG, |s, v| {
                s.drive.speed_observer = Some(speed_observer(v, 0.5));
            }),
            ("stall_torque_nm", p::TORQUE_NM, |s, v| {
                s.drive.speed_observer = Some(speed_observer(2.0, v));
            }),
        ];
        for (key, range, set) in cases {
            for inside in [range.min, range.max] {
                let mut s = PilotSpec::EXAMPLE;
                set(&mut s, inside);
                let built = s.build();
                // The ends build, but for parts of this build that are
                // missing and for the step a paper 002 observer needs.
                assert!(
                    built.is_ok()
                        || built == Err(SpecError::NotInThisBuild)
                        || matches!(built, Err(SpecError::SpeedObserver(_)) if key != "mass_kg" && key != "stall_torque_nm"),
                    "{key} = {inside}: {built:?}"
                );
            }
            for outside in [range.min.next_down(), range.max.next_up(), f32::NAN] {
                let mut s = PilotSpec::EXAMPLE;
                set(&mut s, outside);
                match s.build() {
                    Err(SpecError::NotInThisBuild) => {}
                    Err(e) => {
                        let text = std::format!("{e}");
                        assert!(text.contains(key), "{key} = {outside}: {text}");
                        assert!(text.contains(&std::format!("{range}")), "{text}");
                    }
                    Ok(_) => panic!("{key} = {outside} accepted"),
                }
            }
        }
    }

    /// The blind-distance default follows the reader: `4 s²/r` for a range
    /// reader, none for the nearest-tag reader, and an explicit value wins.
    #[test]
    fn fusion_blind_distance_default_follows_the_reader() {
        let mut sensors = PilotSpec::EXAMPLE.tracker.sensors;
        let fusion = FusionSpec::default();
        assert_eq!(fusion.max_blind_distance_m(&sensors), 0.0);
        sensors.tag_spacing_m = 0.2;
        sensors.read_radius_m = 0.05;
        let limit = fusion.max_blind_distance_m(&sensors);
        assert!((limit - 3.2).abs() < 1e-6, "{limit}");
        let explicit = FusionSpec {
            max_blind_distance_m: Some(0.0),
            ..fusion
        };
        assert_eq!(explicit.max_blind_distance_m(&sensors), 0.0);
    }

    #[test]
    fn paper_spec_builds_the_same_as_the_constructors() {
        let spec = PilotSpec::EXAMPLE;
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
        let mut s = PilotSpec::EXAMPLE;
        s.tracker.gains[1] = f32::NAN;
        assert_eq!(s.build(), Err(SpecError::Gains(GainError::K2)));
        let mut s = PilotSpec::EXAMPLE;
        s.tracker.trajectory = TrajectorySpec::Line {
            start_m: [0.0, 0.0],
            heading_rad: 0.0,
            speed_m_s: -1.0,
        };
        assert_eq!(s.build(), Err(SpecError::Trajectory(ReferenceError::Rate)));
        let mut s = PilotSpec::EXAMPLE;
        s.tracker.observer_gain_per_m = 0.0;
        assert_eq!(
            s.build(),
            Err(SpecError::Observer(ObserverConfigError::Gain))
        );
        let mut s = PilotSpec::EXAMPLE;
        s.tracker.fix_timeout_ticks = 0;
        assert_eq!(
            s.build(),
            Err(SpecError::Tracker(TrackerConfigError::FixTimeout))
        );
        let mut s = PilotSpec::EXAMPLE;
        s.drive.track_width_m = f32::INFINITY;
        assert_eq!(
            s.build(),
            Err(SpecError::Geometry(GeometryError::TrackWidth))
        );
        let mut s = PilotSpec::EXAMPLE;
        s.drive.ki_duty_per_rad = -1.0;
        assert_eq!(
            s.build(),
            Err(SpecError::Drive(DriveConfigError::SpeedLoopGain))
        );
        let mut s = PilotSpec::EXAMPLE;
        s.tracker.estimator = EstimatorSpec::Fusion(FusionSpec::default());
        s.tracker.sensors.tag_spacing_m = -0.1;
        let expected = if cfg!(feature = "fusion-ekf") {
            SpecError::Estimator(EstimatorSpecError::Fusion(
                crate::estimation::fusion::PoseFilterError::TagSpacing,
            ))
        } else {
            SpecError::NotInThisBuild
        };
        assert_eq!(s.build(), Err(expected));
        let mut s = PilotSpec::EXAMPLE;
        s.tracker.sensors.track_width_m = 0.31;
        assert_eq!(s.build(), Err(SpecError::SensorTrackWidth));
        let mut s = PilotSpec::EXAMPLE;
        s.encoder_bits = 33;
        assert_eq!(
            s.build(),
            Err(SpecError::Pilot(PilotConfigError::EncoderBits))
        );
        // A build's refusal is the build's section however it is wrapped.
        let wrapped = SpecError::Estimator(EstimatorSpecError::NotInThisBuild);
        assert_eq!(wrapped.section(), SpecSection::Build);
        assert_eq!(wrapped.to_string(), SpecError::NotInThisBuild.to_string());
        assert_eq!(
            SpecError::from(EstimatorSpecError::NotInThisBuild),
            SpecError::NotInThisBuild
        );
    }

    /// The fix's latency is given in seconds and kept as control periods;
    /// a negative, non-finite or too old one is refused by its key.
    #[cfg(feature = "fusion-ekf")]
    #[test]
    fn the_fix_latency_becomes_periods_and_is_refused_by_its_key() {
        use crate::estimation::fusion::{MAX_FIX_AGE_TICKS, PoseFilterError};
        let mut s = PilotSpec::EXAMPLE;
        let fusion = |fix_latency_s| {
            EstimatorSpec::Fusion(FusionSpec {
                fix_latency_s,
                ..FusionSpec::default()
            })
        };
        s.tracker.estimator = fusion(2.0 * s.tracker.period_s);
        let EstimatorSpec::Fusion(spec) = s.tracker.estimator else {
            unreachable!()
        };
        let settings = spec.build(s.tracker.period_s, &s.tracker.sensors).unwrap();
        assert!((settings.fix_age_ticks() - 2.0).abs() < 1e-6);
        for bad in [
            -0.001,
            f32::NAN,
            f32::INFINITY,
            (MAX_FIX_AGE_TICKS + 1.0) * s.tracker.period_s,
        ] {
            s.tracker.estimator = fusion(bad);
            let refused = s.build().map(|_| ()).unwrap_err();
            assert_eq!(
                refused,
                SpecError::Estimator(EstimatorSpecError::Fusion(PoseFilterError::FixAge)),
                "{bad}"
            );
            let SpecError::Estimator(e) = refused else {
                unreachable!()
            };
            assert_eq!(e.field_key(), Some("fix_latency_s"));
        }
    }

    /// A floor without a grid (tag spacing 0: a tag map) takes the fusion
    /// estimator with a range reader and an explicit blind distance, and
    /// refuses it otherwise, saying which.
    #[cfg(feature = "fusion-ekf")]
    #[test]
    fn fusion_on_a_tag_map_needs_a_range_reader_and_a_blind_distance() {
        use crate::estimation::fusion::PoseFilterError;
        let mut s = PilotSpec::EXAMPLE;
        s.tracker.estimator = EstimatorSpec::Fusion(FusionSpec::default());
        s.tracker.sensors.tag_spacing_m = 0.0;
        // The nearest-tag reader's cells need a grid.
        assert_eq!(
            s.build().map(|_| ()),
            Err(SpecError::Estimator(EstimatorSpecError::Fusion(
                PoseFilterError::TagMapReader
            )))
        );
        s.tracker.sensors.read_radius_m = 0.05;
        assert_eq!(
            s.build().map(|_| ()),
            Err(SpecError::Estimator(EstimatorSpecError::Fusion(
                PoseFilterError::TagMapBlindDistance
            )))
        );
        for limit in [0.0, 3.0] {
            s.tracker.estimator = EstimatorSpec::Fusion(FusionSpec {
                max_blind_distance_m: Some(limit),
                ..FusionSpec::default()
            });
            let EstimatorSpec::Fusion(fusion) = s.tracker.estimator else {
                unreachable!()
            };
            let settings = fusion
                .build(s.tracker.period_s, &s.tracker.sensors)
                .unwrap();
            assert!(!settings.on_grid());
            assert_eq!(settings.max_blind_distance_m(), limit);
            assert!(s.build().is_ok());
        }
        // Settings on a map cannot be turned into a nearest-tag reader's.
        let filter = PoseFilterConfig::new(0.2, 1e-3, 1e-9, 3.0).unwrap();
        let on_map = FusionSettings::on_tag_map(filter, 0.05, 0.0).unwrap();
        assert_eq!(
            on_map.with_read_radius(0.0),
            Err(PoseFilterError::TagMapReader)
        );
        assert_eq!(
            FusionSettings::on_tag_map(filter, f32::NAN, 0.0),
            Err(PoseFilterError::TagMapReader)
        );
        assert!(FusionSettings::new(filter, 0.1, 0.0).unwrap().on_grid());
    }
}
