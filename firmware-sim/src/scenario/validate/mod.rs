//! Validation: [`Scenario::validate`] checks every value and builds the
//! [`Setup`], the core's own validated configurations plus the
//! simulator's plant, floor and reader models. By table: the reference
//! (`reference`), the estimator, law and sensors (`estimator`), the plant
//! and drive (`plant`), the position source and its noise (`position`),
//! the sweep (`sweep`); a core refusal named by the file's key
//! (`refusal`); this file checks the top-level keys, the controller,
//! observer and failsafe, and puts the [`Setup`] together.

use wmr_core::control::saturated::TrackingGains;
use wmr_core::geometry::HeadingEstimate;
use wmr_core::pilot::PilotConfig;
use wmr_core::pilot::spec::{PilotSpec, TrackerSpec};
use wmr_core::pilot::tracker::TrackerConfig;
use wmr_core::reference::Trajectory;

use crate::devices::{EncoderGlitches, ReaderConfig};
use crate::plant::{DiffDriveParams, PlantPose, WheelErrors};

use crate::tags::{Floor, FloorTags};

use super::error::{ScenarioError, finite, in_range, non_negative, positive};
use super::route::{ReferenceSpec, RouteSetup};
use super::schema::Scenario;
use super::sweep_spec::SweepPlan;
use super::tables::{ControllerKind, MeasurementSpec, PositionSpec, ReaderModeSpec};
use wmr_core::plausible::{COORDINATE_M, DECEL_M_S2, GAIN, MIN_SPEED_M_S, PERIOD_S};

mod estimator;
mod plant;
mod position;
mod reference;
mod refusal;
mod sweep;

pub use reference::{reference_bounds, route_bounds, route_path};
use refusal::spec_refusal;

/// The validated plant.
// One per run: the size difference between the variants does not matter.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PlantSetup {
    /// Kinematic unicycle.
    Unicycle,
    /// Differential drive with motors, PWM and encoders.
    DiffDrive {
        /// Plant parameters.
        params: DiffDriveParams,
        /// Encoder counts per wheel revolution.
        encoder_counts_per_rev: u32,
        /// Encoder counter width, bits.
        encoder_bits: u32,
        /// PWM full scale, steps.
        pwm_max_duty: u16,
        /// Spurious encoder edges (none by default).
        encoder_glitches: EncoderGlitches,
        /// The core's pilot configuration (tracker + drive + encoder width).
        pilot: PilotConfig,
        /// The spec it was built from (what the HIL link sends the firmware).
        pilot_spec: PilotSpec,
    },
}

/// The validated position source.
#[derive(Debug, Clone, PartialEq)]
pub enum PositionSetup {
    /// True position every tick.
    Exact,
    /// Nearest tag every tick, no reader.
    NearestTag(FloorTags),
    /// Virtual reader + UART + the core's parser and tag grid or map.
    Reader(Floor, ReaderConfig),
}

/// A validated scenario: the core's configurations and the simulator's models.
#[derive(Debug, Clone, PartialEq)]
pub struct Setup {
    /// Control ticks to run.
    pub ticks: u32,
    /// Control period, s.
    pub period_s: f64,
    /// Statistics start at this time, s.
    pub transient_s: f64,
    /// Which law.
    pub controller: ControllerKind,
    /// The reference (for a route, its stand-in,
    /// [`RouteSetup::stand_in`], which a run does not sample).
    pub trajectory: Trajectory,
    /// The route, when the reference is one (`kind = "route"`).
    pub route: Option<RouteSetup>,
    /// The gains.
    pub gains: TrackingGains,
    /// The output-feedback tracker's configuration (also built for state
    /// feedback, for its gain-bound report).
    pub tracker: TrackerConfig,
    /// The observer's initial estimate.
    pub initial_estimate: HeadingEstimate,
    /// The robot's initial pose.
    pub initial_pose: PlantPose,
    /// The plant.
    pub plant: PlantSetup,
    /// The position source.
    pub position: PositionSetup,
    /// Noise and misses on the fix (validated; clean for the reader).
    pub measurement: MeasurementSpec,
    /// The plant's realistic wheels (`[plant.wheels]`), if any.
    pub wheels: Option<WheelErrors>,
    /// The validated `[sweep]` section, if the scenario has one.
    pub sweep: Option<SweepPlan>,
}

/// A point `[x, y]` on the floor, each coordinate in the core's
/// [`COORDINATE_M`], in the core's precision.
pub(super) fn floor_point(field: &str, [x, y]: [f64; 2]) -> Result<[f32; 2], ScenarioError> {
    Ok([
        f(in_range(field, x, COORDINATE_M, "m")?),
        f(in_range(field, y, COORDINATE_M, "m")?),
    ])
}

/// `f32` of a validated `f64` (the core's precision).
pub(super) fn f(v: f64) -> f32 {
    v as f32
}

impl Scenario {
    /// The keys that do not apply to this setup (the setup ignores
    /// them), each with why: `(key, reason)`. A key here is a warning
    /// where a file gives it ([`Self::warnings`]), and is left out of the
    /// resolved file ([`Self::to_toml_string`]).
    #[must_use]
    pub fn ignored_keys(&self) -> Vec<(&'static str, &'static str)> {
        const NO_OBSERVER: &str = "ignored with controller.kind = \"state_feedback\" (the heading is measured, no observer runs)";
        let mut keys = Vec::new();
        if self.controller.kind == ControllerKind::StateFeedback {
            keys.extend([
                ("observer.gain_per_m", NO_OBSERVER),
                ("observer.min_speed_m_s", NO_OBSERVER),
                ("initial.estimate_cos", "ignored with controller.kind = \"state_feedback\" (no observer runs)"),
                ("initial.estimate_sin", "ignored with controller.kind = \"state_feedback\" (no observer runs)"),
                ("controller.law", "ignored with controller.kind = \"state_feedback\" (it chooses the output-feedback law)"),
            ]);
        }
        if let PositionSpec::Reader {
            mode: ReaderModeSpec::Paper,
            ..
        } = self.position
        {
            keys.extend([
                ("position.read_radius_m", "ignored with position.mode = \"paper\" (the nearest tag is read every tick); it applies to mode = \"range\""),
                ("position.repeat_interval_s", "ignored with position.mode = \"paper\"; it applies to mode = \"range\""),
            ]);
        }
        if !matches!(self.reference, ReferenceSpec::Route(_)) {
            keys.push((
                "mavlink",
                "ignored without a route (reference.kind = \"route\"): the MAVLink endpoint \
                 runs on route runs only",
            ));
        }
        keys
    }

    /// The keys the scenario's file gave where they do not apply to this
    /// setup (ignored, so probably a mistake), whatever their value: one
    /// line each, naming the key and why. `firmware-sim` prints them as
    /// warnings; `firmware-sim schema` says when each key applies.
    #[must_use]
    pub fn warnings(&self) -> Vec<String> {
        let mut warnings: Vec<String> = self
            .ignored_keys()
            .into_iter()
            .filter(|(key, _)| self.given.contains(key))
            .map(|(key, why)| format!("{key}: {why}"))
            .collect();
        // The robot's keys, named as its file names them.
        if let Some((path, keys)) = self.given.robot() {
            warnings.extend(self.ignored_keys().into_iter().filter_map(|(key, why)| {
                let robot_key = super::robot::Robot::key_of(key)?;
                keys.contains(&robot_key).then(|| {
                    let why = why.replace("position.mode", "reader.mode");
                    format!("robot file {path}: {robot_key}: {why}")
                })
            }));
        }
        warnings
    }

    /// Checks every value and builds the core's configurations.
    ///
    /// # Errors
    /// [`ScenarioError::Invalid`] naming the first bad field.
    pub fn validate(&self) -> Result<Setup, ScenarioError> {
        if self.name.trim().is_empty() {
            return Err(ScenarioError::invalid("name", "must not be empty"));
        }
        let period_s = in_range("period_s", self.period_s, PERIOD_S, "s")?;
        let duration_s = positive("duration_s", self.duration_s)?;
        let transient_s = non_negative("transient_s", self.transient_s)?;
        if transient_s >= duration_s {
            return Err(ScenarioError::invalid(
                "transient_s",
                format!(
                    "must be less than duration_s ({duration_s} s), or no error statistics remain"
                ),
            ));
        }
        let ticks = (duration_s / period_s).round();
        if ticks < 1.0 || ticks >= f64::from(u32::MAX) {
            return Err(ScenarioError::invalid(
                "duration_s",
                format!("gives {ticks} ticks of {period_s} s; need 1 ..= 2^32 − 2"),
            ));
        }
        let ticks = ticks as u32;
        if let Some(telemetry) = &self.telemetry {
            telemetry.every_ticks()?;
        }

        // Checked whether a route uses it or not (a robot file's table is
        // refused where it is wrong, not only where it runs).
        let mavlink = self.mavlink.map(|m| m.settings()).transpose()?;
        let (trajectory_spec, route) = match &self.reference {
            ReferenceSpec::Trajectory(t) => (reference::checked(t)?, None),
            ReferenceSpec::Route(r) => {
                let mut route = r.validate(period_s)?;
                route.mavlink = mavlink.unwrap_or_default();
                (route.stand_in(), Some(route))
            }
        };
        let trajectory = trajectory_spec.build().map_err(|e| {
            ScenarioError::invalid("reference", format!("refused by the core: {e}"))
        })?;
        // The gains, the observer and the failsafe deceleration are checked
        // by the core (`spec_refusal` names their keys); the timeout is
        // checked here, where it becomes a tick count.
        let c = &self.controller;
        let gains = [
            f(in_range("controller.k1", c.k1, GAIN, "m/s")?),
            f(in_range("controller.k2", c.k2, GAIN, "m/s")?),
            f(in_range("controller.k3", c.k3, GAIN, "1/s")?),
        ];
        let timeout_s = positive("failsafe.fix_timeout_s", self.failsafe.fix_timeout_s)?;
        let fix_timeout_ticks = (timeout_s / period_s - 1e-9).ceil().max(1.0);
        if fix_timeout_ticks >= f64::from(u32::MAX) {
            return Err(ScenarioError::invalid(
                "failsafe.fix_timeout_s",
                "too long for a u32 tick count",
            ));
        }
        let tracker_spec = TrackerSpec {
            period_s: f(period_s),
            trajectory: trajectory_spec,
            gains,
            observer_gain_per_m: f(in_range(
                "observer.gain_per_m",
                self.observer.gain_per_m,
                GAIN,
                "1/m",
            )?),
            observer_min_speed_m_s: f(in_range(
                "observer.min_speed_m_s",
                self.observer.min_speed_m_s,
                MIN_SPEED_M_S,
                "m/s",
            )?),
            fix_timeout_ticks: fix_timeout_ticks as u32,
            failsafe_decel_m_s2: f(in_range(
                "failsafe.decel_m_s2",
                self.failsafe.decel_m_s2,
                DECEL_M_S2,
                "m/s²",
            )?),
            max_fix_age_ticks: TrackerConfig::DEFAULT_MAX_FIX_AGE_TICKS,
            estimator: self.estimator_spec()?,
            law: self.law_spec()?,
            sensors: self.sensor_spec(),
        };
        let tracker = tracker_spec.build().map_err(|e| spec_refusal(e, self))?;
        let gains = TrackingGains::new(gains[0], gains[1], gains[2])
            .map_err(|e| ScenarioError::invalid("controller", format!("{e}")))?;

        let i = &self.initial;
        let initial_pose = PlantPose::new(
            finite("initial.x_m", i.x_m)?,
            finite("initial.y_m", i.y_m)?,
            finite("initial.heading_rad", i.heading_rad)?,
        );
        let initial_estimate = HeadingEstimate {
            cos_theta: f(finite("initial.estimate_cos", i.estimate_cos)?),
            sin_theta: f(finite("initial.estimate_sin", i.estimate_sin)?),
        };

        let plant = self.plant_setup(tracker_spec)?;
        let wheels = self.wheels_setup()?;
        let position = self.position_setup(&trajectory, route.as_ref(), duration_s, period_s)?;

        if matches!(plant, PlantSetup::DiffDrive { .. })
            && initial_estimate != HeadingEstimate::default()
        {
            return Err(ScenarioError::invalid(
                "initial.estimate_cos",
                "the diff_drive plant runs the core's Pilot, whose observer always starts at (0, 0)",
            ));
        }
        if route.is_some() && self.controller.kind == ControllerKind::StateFeedback {
            return Err(ScenarioError::invalid(
                "controller.kind",
                "a route (reference.kind = \"route\") runs on the output-feedback tracker: \
                 use \"output_feedback\"",
            ));
        }
        match (self.controller.kind, &plant, &position) {
            (ControllerKind::StateFeedback, PlantSetup::DiffDrive { .. }, _) => {
                return Err(ScenarioError::invalid(
                    "controller.kind",
                    "state_feedback runs on the unicycle plant only (the robot's pilot is output feedback)",
                ));
            }
            (ControllerKind::StateFeedback, _, PositionSetup::Reader(..)) => {
                return Err(ScenarioError::invalid(
                    "position.kind",
                    "state_feedback needs a position every tick: use exact or nearest_tag",
                ));
            }
            _ => {}
        }
        let measurement = self.measurement_setup(&position)?;

        let mut setup = Setup {
            ticks,
            period_s,
            transient_s,
            controller: self.controller.kind,
            trajectory,
            route,
            gains,
            tracker,
            initial_estimate,
            initial_pose,
            plant,
            position,
            measurement,
            wheels,
            sweep: None,
        };
        if let Some(spec) = &self.sweep {
            setup.sweep = Some(SweepPlan::new(spec, self, &setup)?);
        }
        Ok(setup)
    }
}
