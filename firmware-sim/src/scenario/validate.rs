//! Validation: [`Scenario::validate`] checks every value and builds the
//! [`Setup`], the core's own validated configurations plus the
//! simulator's plant, floor and reader models.

use wmr_core::control::saturated::{GainError, TrackingGains};
use wmr_core::drive::DriveConfigError;
use wmr_core::estimation::heading_observer::ObserverConfigError;
use wmr_core::geometry::HeadingEstimate;
use wmr_core::pilot::PilotConfig;
use wmr_core::pilot::spec::{
    self as core_spec, EstimatorSpec, LawSpec, PilotSpec, SensorSpec, SpecError, TrackerSpec,
    TrajectorySpec,
};
use wmr_core::pilot::tracker::TrackerConfig;
use wmr_core::pilot::tracker::TrackerConfigError;
use wmr_core::reference::Trajectory;

use crate::devices::{EncoderGlitches, LinkFaults, ReaderConfig, ReaderMode};
use crate::plant::{DiffDriveParams, LoadTorque, PlantPose, WheelDynamics};
use std::sync::Arc;

use wmr_core::devices::TagId;

use crate::tags::{Floor, FloorTags, MapFloor};

use super::defaults;
use super::error::{ScenarioError, finite, in_range, non_negative, positive, probability, shown};
use super::schema::Scenario;
use super::sweep_spec::{
    DEFAULT_EXACT_THRESHOLD_M, DEFAULT_HOLD_FRACTION, DEFAULT_START_RADIUS_M,
    DEFAULT_THRESHOLD_SPACINGS, EncoderChoices, MAX_ENCODER_CHOICES, ObserverStart, SweepPlan,
    SweepSpec,
};
use super::tables::{
    ControllerKind, DynamicsSpec, MeasurementSpec, ObserverSpec, PlantSpec, PositionSpec,
    ReaderModeSpec, ReferenceSpec, SpeedObserverSpec,
};
use wmr_core::plausible::{
    ANGLE_RAD, COORDINATE_M, DECEL_M_S2, GAIN, MASS_KG, MIN_SPEED_M_S, PERIOD_S, READ_RADIUS_M,
    REFERENCE_RATE_RAD_S, REFERENCE_SIZE_M, REFERENCE_SPEED_M_S, SPEED_LOOP_GAIN, TAG_SPACING_M,
    TORQUE_NM, TRACK_WIDTH_M, WHEEL_ACCEL_RAD_S2, WHEEL_INERTIA_KG_M2, WHEEL_RADIUS_M,
    WHEEL_SPEED_RAD_S, YAW_INERTIA_KG_M2,
};

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
    /// The reference.
    pub trajectory: Trajectory,
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
    /// The validated `[sweep]` section, if the scenario has one.
    pub sweep: Option<SweepPlan>,
}

/// The core's spec of the wheel-speed observer `o` (its keys checked one
/// by one, to name the key; the core checks the whole when it builds it).
fn speed_observer_spec(
    o: &SpeedObserverSpec,
    params: &DiffDriveParams,
) -> Result<core_spec::SpeedObserverSpec, ScenarioError> {
    let field = |key: &str| format!("drive.speed_observer.{key}");
    Ok(core_spec::SpeedObserverSpec {
        mass_kg: f(in_range(&field("mass_kg"), o.mass_kg, MASS_KG, "kg")?),
        yaw_inertia_kg_m2: f(in_range(
            &field("yaw_inertia_kg_m2"),
            o.yaw_inertia_kg_m2,
            YAW_INERTIA_KG_M2,
            "kg m²",
        )?),
        wheel_inertia_kg_m2: f(in_range(
            &field("wheel_inertia_kg_m2"),
            o.wheel_inertia_kg_m2,
            WHEEL_INERTIA_KG_M2,
            "kg m²",
        )?),
        stall_torque_nm: f(in_range(
            &field("stall_torque_nm"),
            o.stall_torque_nm,
            TORQUE_NM,
            "N·m",
        )?),
        no_load_speed_rad_s: f(params.wheel_speed_at_full_duty_rad_s),
        lambda_per_s: f(in_range(
            &field("lambda_per_s"),
            o.lambda_per_s,
            GAIN,
            "1/s",
        )?),
        friction_gain: f(in_range(
            &field("friction_gain"),
            o.friction_gain,
            GAIN,
            "",
        )?),
        disturbance_gain: f(in_range(
            &field("disturbance_gain"),
            o.disturbance_gain,
            GAIN,
            "",
        )?),
    })
}

/// A refusal of the core's spec builder, named by the scenario key it came
/// from, in the core's own words (which name the field and the rule), with
/// the key's value in `scenario` where the key is a value rather than a
/// table.
fn spec_refusal(e: SpecError, scenario: &Scenario) -> ScenarioError {
    let field = match e.section() {
        "tracker.trajectory" => "reference",
        "tracker.estimator.pose_observer" => "estimator.pose_observer",
        "tracker.estimator.fusion" => "estimator.fusion",
        "tracker.law.cascaded" => "controller.law.cascaded",
        "tracker.law.heading_error_sine" => "controller.law.heading_error_sine",
        // The sensor facts come from the plant and the floor.
        "tracker.sensors" => "position",
        "drive" => "drive",
        "drive.speed_observer" => "drive.speed_observer",
        "tag_grid" => "position",
        _ => match e {
            SpecError::Gains(GainError::K1) => "controller.k1",
            SpecError::Gains(GainError::K2) => "controller.k2",
            SpecError::Gains(GainError::K3) => "controller.k3",
            SpecError::Observer(ObserverConfigError::Gain) => "observer.gain_per_m",
            SpecError::Observer(ObserverConfigError::MinSpeed) => "observer.min_speed_m_s",
            SpecError::Observer(_) => "observer",
            SpecError::Tracker(TrackerConfigError::FailsafeDecel) => "failsafe.decel_m_s2",
            SpecError::Tracker(TrackerConfigError::FixTimeout) => "failsafe.fix_timeout_s",
            SpecError::Tracker(TrackerConfigError::Period) => "period_s",
            SpecError::Tracker(_) => "failsafe",
            SpecError::Geometry(_) | SpecError::Pilot(_) => "plant",
            _ => "estimator",
        },
    };
    let field = match e {
        SpecError::Drive(DriveConfigError::MaxWheelSpeed) => "drive.max_wheel_speed_rad_s",
        SpecError::Drive(DriveConfigError::MaxWheelAccel) => "drive.max_wheel_accel_rad_s2",
        SpecError::Drive(DriveConfigError::Period)
        | SpecError::Observer(ObserverConfigError::Period)
        | SpecError::Tracker(TrackerConfigError::Period) => "period_s",
        _ => field,
    };
    let mut reason = match core::error::Error::source(&e) {
        Some(inner) => format!("refused by the core: {inner}"),
        None => format!("refused by the core: {e}"),
    };
    if let Some(value) = scenario.value_at(field) {
        let value = match value {
            toml::Value::Float(v) => shown(v),
            other => other.to_string(),
        };
        reason.push_str(&format!(" (got {value})"));
    }
    ScenarioError::invalid(field, reason)
}

/// A point `[x, y]` on the floor, each coordinate in the core's
/// [`COORDINATE_M`], in the core's precision.
fn floor_point(field: &str, [x, y]: [f64; 2]) -> Result<[f32; 2], ScenarioError> {
    Ok([
        f(in_range(field, x, COORDINATE_M, "m")?),
        f(in_range(field, y, COORDINATE_M, "m")?),
    ])
}

/// `f32` of a validated `f64` (the core's precision).
fn f(v: f64) -> f32 {
    v as f32
}

impl Scenario {
    /// The value of the dotted key `path` as this scenario holds it (its
    /// defaults filled in), unless the key is a table or absent.
    fn value_at(&self, path: &str) -> Option<toml::Value> {
        let mut value = toml::Value::try_from(self).ok()?;
        for key in path.split('.') {
            value = value.get(key)?.clone();
        }
        (!value.is_table()).then_some(value)
    }

    /// Keys given a value other than their default where they do not
    /// apply to this setup (ignored, so probably a mistake): one line
    /// each, naming the key and why. `firmware-sim` prints them as
    /// warnings; `firmware-sim schema` says when each key applies.
    #[must_use]
    pub fn warnings(&self) -> Vec<String> {
        let mut w = Vec::new();
        if self.controller.kind == ControllerKind::StateFeedback {
            let observer = ObserverSpec::default();
            if self.observer.gain_per_m.to_bits() != observer.gain_per_m.to_bits() {
                w.push("observer.gain_per_m: ignored with controller.kind = \"state_feedback\" (the heading is measured, no observer runs)".to_owned());
            }
            if self.observer.min_speed_m_s.to_bits() != observer.min_speed_m_s.to_bits() {
                w.push("observer.min_speed_m_s: ignored with controller.kind = \"state_feedback\" (the heading is measured, no observer runs)".to_owned());
            }
            if self.initial.estimate_cos != 0.0 || self.initial.estimate_sin != 0.0 {
                w.push("initial.estimate_cos/estimate_sin: ignored with controller.kind = \"state_feedback\" (no observer runs)".to_owned());
            }
            if self.controller.law != LawSpec::default() {
                w.push("controller.law: ignored with controller.kind = \"state_feedback\" (it chooses the output-feedback law)".to_owned());
            }
        }
        if let PositionSpec::Reader {
            mode: ReaderModeSpec::Paper,
            read_radius_m,
            repeat_interval_s,
            ..
        } = self.position
        {
            if read_radius_m.to_bits() != defaults::read_radius_m().to_bits() {
                w.push("position.read_radius_m: ignored with position.mode = \"paper\" (the nearest tag is read every tick); it applies to mode = \"range\"".to_owned());
            }
            if repeat_interval_s.to_bits() != defaults::repeat_interval_s().to_bits() {
                w.push("position.repeat_interval_s: ignored with position.mode = \"paper\"; it applies to mode = \"range\"".to_owned());
            }
        }
        w
    }

    /// The core's estimator spec, as the scenario chose it; paper 002's and
    /// the fusion estimator only with output feedback, the fusion
    /// estimator only on a tag grid read without added noise. The core
    /// checks its values.
    fn estimator_spec(&self) -> Result<EstimatorSpec, ScenarioError> {
        match (self.estimator, self.controller.kind) {
            (EstimatorSpec::HeadingObserver, _) => {}
            (_, ControllerKind::StateFeedback) => {
                return Err(ScenarioError::invalid(
                    "estimator",
                    "state feedback measures the heading: no estimator runs",
                ));
            }
            (EstimatorSpec::Fusion(_), ControllerKind::OutputFeedback) => {
                if matches!(self.position, PositionSpec::Exact) {
                    return Err(ScenarioError::invalid(
                        "estimator.fusion",
                        "the fusion estimator models tag reads: use position nearest_tag or reader",
                    ));
                }
                if self.measurement.noise_std_m > 0.0 {
                    return Err(ScenarioError::invalid(
                        "measurement.noise_std_m",
                        "the fusion estimator's tag model needs fixes on the tag grid (no added noise)",
                    ));
                }
            }
            // Any other estimator needs nothing of the simulator.
            (_, ControllerKind::OutputFeedback) => {}
        }
        Ok(self.estimator)
    }

    /// What the estimator knows of the sensors: the plant's track width and
    /// count quantization, the floor's spacing, the reader's range and
    /// where its antenna is (unless `antenna_offset_compensated = false`).
    fn sensor_spec(&self) -> SensorSpec {
        let antenna_ahead_m = match self.position {
            PositionSpec::Reader {
                antenna_offset_m,
                antenna_offset_compensated: true,
                ..
            } => antenna_offset_m,
            _ => 0.0,
        };
        let (spacing_m, read_radius_m) = match self.position {
            PositionSpec::NearestTag { spacing_m, .. } => (spacing_m, 0.0),
            PositionSpec::Reader {
                spacing_m,
                mode: ReaderModeSpec::Paper,
                ..
            } => (spacing_m, 0.0),
            PositionSpec::Reader {
                spacing_m,
                mode: ReaderModeSpec::Range,
                read_radius_m,
                ..
            } => (spacing_m, read_radius_m),
            // No tags: the fusion estimator is refused above.
            PositionSpec::Exact => (0.0, 0.0),
        };
        // A tag map has no grid spacing (as in the robot's flash image).
        let spacing_m = if self.floor_tags.is_empty() {
            spacing_m
        } else {
            0.0
        };
        let (track_width_m, floor_m2) = match self.plant {
            PlantSpec::DiffDrive {
                wheel_radius_m,
                track_width_m,
                encoder_counts_per_rev,
                ..
            } => {
                let quantum = wheel_radius_m * std::f64::consts::TAU
                    / f64::from(encoder_counts_per_rev.max(1));
                (track_width_m, quantum * quantum / 12.0)
            }
            // The unicycle's odometry is exact: only the noise model's
            // geometry matters, taken as the default robot's.
            PlantSpec::Unicycle => (defaults::track_width_m(), 1e-9),
        };
        SensorSpec {
            track_width_m: f(track_width_m),
            wheel_variance_floor_m2: f(floor_m2),
            tag_spacing_m: f(spacing_m),
            read_radius_m: f(read_radius_m),
            antenna_offset_m: [f(antenna_ahead_m), 0.0],
        }
    }

    /// The core's law spec; paper 002's only with output feedback. The
    /// core checks its values.
    fn law_spec(&self) -> Result<LawSpec, ScenarioError> {
        match (self.controller.law, self.controller.kind) {
            (LawSpec::Saturated, _) | (_, ControllerKind::OutputFeedback) => {
                Ok(self.controller.law)
            }
            (_, ControllerKind::StateFeedback) => Err(ScenarioError::invalid(
                "controller.law",
                "selects the output-feedback law: use it with kind = \"output_feedback\"",
            )),
        }
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

        let trajectory_spec = self.reference.spec()?;
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
        let position = self.position_setup(&trajectory, duration_s, period_s)?;

        if matches!(plant, PlantSetup::DiffDrive { .. })
            && initial_estimate != HeadingEstimate::default()
        {
            return Err(ScenarioError::invalid(
                "initial.estimate_cos",
                "the diff_drive plant runs the core's Pilot, whose observer always starts at (0, 0)",
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
            gains,
            tracker,
            initial_estimate,
            initial_pose,
            plant,
            position,
            measurement,
            sweep: None,
        };
        if let Some(spec) = &self.sweep {
            setup.sweep = Some(SweepPlan::new(spec, self, &setup)?);
        }
        Ok(setup)
    }

    fn measurement_setup(
        &self,
        position: &PositionSetup,
    ) -> Result<MeasurementSpec, ScenarioError> {
        let m = self.measurement;
        non_negative("measurement.noise_std_m", m.noise_std_m)?;
        probability("measurement.miss_probability", m.miss_probability)?;
        if matches!(position, PositionSetup::Reader(..)) && !m.is_clean() {
            return Err(ScenarioError::invalid(
                if m.noise_std_m == 0.0 {
                    "measurement.miss_probability"
                } else {
                    "measurement.noise_std_m"
                },
                "applies to the exact and nearest_tag sources only: the reader's fixes are tag ids \
                 looked up in the grid (for lost frames use position.drop_frame_probability)",
            ));
        }
        if self.controller.kind == ControllerKind::StateFeedback && m.miss_probability > 0.0 {
            return Err(ScenarioError::invalid(
                "measurement.miss_probability",
                "state_feedback needs a position every tick (only output feedback dead-reckons)",
            ));
        }
        Ok(m)
    }

    fn plant_setup(&self, tracker: TrackerSpec) -> Result<PlantSetup, ScenarioError> {
        match self.plant {
            PlantSpec::Unicycle => {
                if self.drive.is_some() {
                    return Err(ScenarioError::invalid(
                        "drive",
                        "only used with plant.kind = \"diff_drive\"; remove the [drive] table",
                    ));
                }
                Ok(PlantSetup::Unicycle)
            }
            PlantSpec::DiffDrive {
                wheel_radius_m,
                track_width_m,
                motor_time_constant_s,
                wheel_speed_at_full_duty_rad_s,
                encoder_counts_per_rev,
                encoder_bits,
                pwm_max_duty,
                substeps,
                dynamics,
                encoder_glitches,
            } => {
                let encoder_glitches = match encoder_glitches {
                    None => EncoderGlitches::default(),
                    Some(g) => {
                        if g.min_counts == 0 {
                            return Err(ScenarioError::invalid(
                                "plant.encoder_glitches.min_counts",
                                "must be ≥ 1",
                            ));
                        }
                        if g.max_counts < g.min_counts {
                            return Err(ScenarioError::invalid(
                                "plant.encoder_glitches.max_counts",
                                format!("must be ≥ min_counts ({})", g.min_counts),
                            ));
                        }
                        EncoderGlitches {
                            probability_per_read: probability(
                                "plant.encoder_glitches.probability_per_read",
                                g.probability_per_read,
                            )?,
                            min_counts: g.min_counts,
                            max_counts: g.max_counts,
                            seed: g.seed,
                        }
                    }
                };
                let params = DiffDriveParams {
                    wheel_radius_m: in_range(
                        "plant.wheel_radius_m",
                        wheel_radius_m,
                        WHEEL_RADIUS_M,
                        "m",
                    )?,
                    track_width_m: in_range(
                        "plant.track_width_m",
                        track_width_m,
                        TRACK_WIDTH_M,
                        "m",
                    )?,
                    motor_time_constant_s: positive(
                        "plant.motor_time_constant_s",
                        motor_time_constant_s,
                    )?,
                    wheel_speed_at_full_duty_rad_s: positive(
                        "plant.wheel_speed_at_full_duty_rad_s",
                        wheel_speed_at_full_duty_rad_s,
                    )?,
                    substeps,
                    dynamics: dynamics.as_ref().map(DynamicsSpec::build).transpose()?,
                };
                if substeps == 0 {
                    return Err(ScenarioError::invalid("plant.substeps", "must be ≥ 1"));
                }
                if encoder_counts_per_rev == 0 {
                    return Err(ScenarioError::invalid(
                        "plant.encoder_counts_per_rev",
                        "must be ≥ 1",
                    ));
                }
                if !(2..=32).contains(&encoder_bits) {
                    return Err(ScenarioError::invalid(
                        "plant.encoder_bits",
                        format!("must be in 2 ..= 32 (got {encoder_bits})"),
                    ));
                }
                if pwm_max_duty == 0 {
                    return Err(ScenarioError::invalid("plant.pwm_max_duty", "must be ≥ 1"));
                }
                let d = self.drive.unwrap_or_default();
                let feedforward = match d.feedforward_duty_per_rad_s {
                    Some(v) => v,
                    None => 1.0 / params.wheel_speed_at_full_duty_rad_s,
                };
                let pilot_spec = PilotSpec {
                    tracker,
                    drive: core_spec::DriveSpec {
                        wheel_radius_m: f(params.wheel_radius_m),
                        track_width_m: f(params.track_width_m),
                        encoder_counts_per_rev,
                        max_wheel_speed_rad_s: f(in_range(
                            "drive.max_wheel_speed_rad_s",
                            d.max_wheel_speed_rad_s,
                            WHEEL_SPEED_RAD_S,
                            "rad/s",
                        )?),
                        max_wheel_accel_rad_s2: f(in_range(
                            "drive.max_wheel_accel_rad_s2",
                            d.max_wheel_accel_rad_s2,
                            WHEEL_ACCEL_RAD_S2,
                            "rad/s²",
                        )?),
                        feedforward_duty_per_rad_s: f(in_range(
                            "drive.feedforward_duty_per_rad_s",
                            feedforward,
                            SPEED_LOOP_GAIN,
                            "duty/(rad/s)",
                        )?),
                        kp_duty_per_rad_s: f(in_range(
                            "drive.kp_duty_per_rad_s",
                            d.kp_duty_per_rad_s,
                            SPEED_LOOP_GAIN,
                            "duty/(rad/s)",
                        )?),
                        ki_duty_per_rad: f(in_range(
                            "drive.ki_duty_per_rad",
                            d.ki_duty_per_rad,
                            SPEED_LOOP_GAIN,
                            "duty/rad",
                        )?),
                        speed_observer: d
                            .speed_observer
                            .map(|o| speed_observer_spec(&o, &params))
                            .transpose()?,
                    },
                    encoder_bits,
                    max_encoder_fault_ticks: PilotConfig::DEFAULT_MAX_ENCODER_FAULT_TICKS,
                };
                let pilot = pilot_spec.build().map_err(|e| spec_refusal(e, self))?;
                Ok(PlantSetup::DiffDrive {
                    params,
                    encoder_counts_per_rev,
                    encoder_bits,
                    pwm_max_duty,
                    encoder_glitches,
                    pilot,
                    pilot_spec,
                })
            }
        }
    }

    fn position_setup(
        &self,
        trajectory: &Trajectory,
        duration_s: f64,
        period_s: f64,
    ) -> Result<PositionSetup, ScenarioError> {
        let floor =
            |spacing_m: f64, offset_m: [f64; 2], margin_m: f64, extent_m: Option<[f64; 4]>| {
                let spacing_m = in_range("position.spacing_m", spacing_m, TAG_SPACING_M, "m")?;
                floor_point("position.offset_m", offset_m)?;
                let (min, max) = match extent_m {
                    Some(e) => {
                        for v in e {
                            finite("position.extent_m", v)?;
                        }
                        ([e[0], e[1]], [e[2], e[3]])
                    }
                    None => {
                        let margin = non_negative("position.margin_m", margin_m)?;
                        let (mut lo, mut hi) = reference_bounds(trajectory, duration_s, period_s);
                        lo = [lo[0].min(self.initial.x_m), lo[1].min(self.initial.y_m)];
                        hi = [hi[0].max(self.initial.x_m), hi[1].max(self.initial.y_m)];
                        (
                            [lo[0] - margin, lo[1] - margin],
                            [hi[0] + margin, hi[1] + margin],
                        )
                    }
                };
                FloorTags::covering(spacing_m, offset_m, min, max)
                    .map_err(|e| ScenarioError::invalid("position.extent_m", e.to_string()))
            };
        if !self.floor_tags.is_empty() && !matches!(self.position, PositionSpec::Reader { .. }) {
            return Err(ScenarioError::invalid(
                "floor_tags",
                "a tag map is read by a reader: position.kind = \"reader\"",
            ));
        }
        match self.position {
            PositionSpec::Exact => Ok(PositionSetup::Exact),
            PositionSpec::NearestTag {
                spacing_m,
                offset_m,
                margin_m,
                extent_m,
            } => Ok(PositionSetup::NearestTag(floor(
                spacing_m, offset_m, margin_m, extent_m,
            )?)),
            PositionSpec::Reader {
                spacing_m,
                offset_m,
                margin_m,
                extent_m,
                mode,
                read_radius_m,
                antenna_offset_m,
                // The core's business (`sensor_spec`).
                antenna_offset_compensated: _,
                baud,
                repeat_interval_s,
                corrupt_byte_probability,
                drop_frame_probability,
                seed,
            } => {
                let floor = if self.floor_tags.is_empty() {
                    Floor::Grid(floor(spacing_m, offset_m, margin_m, extent_m)?)
                } else {
                    let tags: Vec<_> = self
                        .floor_tags
                        .iter()
                        .map(|t| (TagId(t.id), [t.x_m, t.y_m]))
                        .collect();
                    if let Some(t) = self.floor_tags.iter().find(|t| t.id > TagId::MASK) {
                        return Err(ScenarioError::invalid(
                            "floor_tags",
                            format!("id {:#x} is wider than the reader's 40 bits", t.id),
                        ));
                    }
                    let map = MapFloor::new(&tags)
                        .map_err(|e| {
                            ScenarioError::invalid(
                                "floor_tags",
                                format!("refused by the core's tag map: {e}"),
                            )
                        })?
                        .ok_or_else(|| ScenarioError::invalid("floor_tags", "no tags"))?;
                    Floor::Map(Arc::new(map))
                };
                let mode = match mode {
                    ReaderModeSpec::Paper => ReaderMode::Paper,
                    ReaderModeSpec::Range => ReaderMode::Range {
                        read_radius_m: in_range(
                            "position.read_radius_m",
                            positive("position.read_radius_m", read_radius_m)?,
                            READ_RADIUS_M,
                            "m",
                        )?,
                        repeat_interval_s: positive(
                            "position.repeat_interval_s",
                            repeat_interval_s,
                        )?,
                    },
                };
                if baud == 0 {
                    return Err(ScenarioError::invalid("position.baud", "must be ≥ 1"));
                }
                Ok(PositionSetup::Reader(
                    floor,
                    ReaderConfig {
                        mode,
                        antenna_offset_m: finite("position.antenna_offset_m", antenna_offset_m)?,
                        baud,
                        faults: LinkFaults {
                            corrupt_byte_probability: probability(
                                "position.corrupt_byte_probability",
                                corrupt_byte_probability,
                            )?,
                            drop_frame_probability: probability(
                                "position.drop_frame_probability",
                                drop_frame_probability,
                            )?,
                            seed,
                        },
                        update_period_s: Some(period_s),
                    },
                ))
            }
        }
    }
}

impl DynamicsSpec {
    /// The plant's wheel dynamics, checked key by key.
    ///
    /// # Errors
    /// [`ScenarioError::Invalid`] naming the first bad
    /// `plant.dynamics.*` key.
    pub fn build(&self) -> Result<WheelDynamics, ScenarioError> {
        let mass_kg = positive("plant.dynamics.mass_kg", self.mass_kg)?;
        let yaw_inertia_kg_m2 =
            positive("plant.dynamics.yaw_inertia_kg_m2", self.yaw_inertia_kg_m2)?;
        let wheel_inertia_kg_m2 = non_negative(
            "plant.dynamics.wheel_inertia_kg_m2",
            self.wheel_inertia_kg_m2,
        )?;
        let viscous_friction_nm_s_per_rad = non_negative(
            "plant.dynamics.viscous_friction_nm_s_per_rad",
            self.viscous_friction_nm_s_per_rad,
        )?;
        let stall_torque_nm = positive("plant.dynamics.stall_torque_nm", self.stall_torque_nm)?;
        let start_s = non_negative("plant.dynamics.load_start_s", self.load_start_s)?;
        let ramp_s = non_negative("plant.dynamics.load_ramp_s", self.load_ramp_s)?;
        let grade_percent = self.load_grade_percent;
        if !(grade_percent > -100.0 && grade_percent < 100.0) {
            return Err(ScenarioError::invalid(
                "plant.dynamics.load_grade_percent",
                format!("must be in (−100, 100) (got {grade_percent})"),
            ));
        }
        Ok(WheelDynamics {
            mass_kg,
            yaw_inertia_kg_m2,
            wheel_inertia_kg_m2,
            viscous_friction_nm_s_per_rad,
            stall_torque_nm,
            load: LoadTorque {
                start_s,
                ramp_s,
                grade_percent,
            },
        })
    }
}

impl ReferenceSpec {
    /// The core trajectory.
    ///
    /// # Errors
    /// [`ScenarioError::Invalid`] naming the bad `reference.*` field.
    pub fn build(&self) -> Result<Trajectory, ScenarioError> {
        self.spec()?
            .build()
            .map_err(|e| ScenarioError::invalid("reference", format!("refused by the core: {e}")))
    }

    /// The core's plain spec of the reference (checked field by field).
    ///
    /// # Errors
    /// [`ScenarioError::Invalid`] naming the bad `reference.*` field.
    pub fn spec(&self) -> Result<TrajectorySpec, ScenarioError> {
        Ok(match *self {
            Self::FigureEight {
                h1_m,
                h2_rad_s,
                phase_rad,
            } => TrajectorySpec::FigureEight {
                h1_m: f(in_range("reference.h1_m", h1_m, REFERENCE_SIZE_M, "m")?),
                h2_rad_s: f(in_range(
                    "reference.h2_rad_s",
                    h2_rad_s,
                    REFERENCE_RATE_RAD_S,
                    "rad/s",
                )?),
                phase_rad: f(in_range(
                    "reference.phase_rad",
                    phase_rad,
                    ANGLE_RAD,
                    "rad",
                )?),
            },
            Self::Circle {
                center_m,
                radius_m,
                rate_rad_s,
                phase_rad,
            } => {
                if !REFERENCE_RATE_RAD_S.contains_magnitude(rate_rad_s as f32) {
                    return Err(ScenarioError::invalid(
                        "reference.rate_rad_s",
                        format!(
                            "its magnitude must be in {REFERENCE_RATE_RAD_S} rad/s, the sign \
                             gives the sense (got {rate_rad_s})"
                        ),
                    ));
                }
                TrajectorySpec::Circle {
                    center_m: floor_point("reference.center_m", center_m)?,
                    radius_m: f(in_range(
                        "reference.radius_m",
                        radius_m,
                        REFERENCE_SIZE_M,
                        "m",
                    )?),
                    rate_rad_s: f(rate_rad_s),
                    phase_rad: f(in_range(
                        "reference.phase_rad",
                        phase_rad,
                        ANGLE_RAD,
                        "rad",
                    )?),
                }
            }
            Self::Line {
                start_m,
                heading_rad,
                speed_m_s,
            } => TrajectorySpec::Line {
                start_m: floor_point("reference.start_m", start_m)?,
                heading_rad: f(in_range(
                    "reference.heading_rad",
                    heading_rad,
                    ANGLE_RAD,
                    "rad",
                )?),
                speed_m_s: f(in_range(
                    "reference.speed_m_s",
                    speed_m_s,
                    REFERENCE_SPEED_M_S,
                    "m/s",
                )?),
            },
        })
    }
}

/// Bounding box of the reference over `[0, duration_s]`, sampled at
/// `max(period, 0.05 s)`, `([x_min, y_min], [x_max, y_max])`.
#[must_use]
pub fn reference_bounds(
    trajectory: &Trajectory,
    duration_s: f64,
    period_s: f64,
) -> ([f64; 2], [f64; 2]) {
    let step = period_s.max(0.05);
    let n = (duration_s / step).ceil() as u64;
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for k in 0..=n {
        let t = (k as f64 * step).min(duration_s);
        let p = trajectory.sample(t as f32).position;
        let (x, y) = (f64::from(p.x), f64::from(p.y));
        lo = [lo[0].min(x), lo[1].min(y)];
        hi = [hi[0].max(x), hi[1].max(y)];
    }
    (lo, hi)
}

fn range(field: &str, r: [f64; 2], max: Option<f64>) -> Result<[f64; 2], ScenarioError> {
    let lo = non_negative(field, r[0])?;
    let hi = non_negative(field, r[1])?;
    if lo > hi || max.is_some_and(|m| hi > m) {
        let bound = max.map(|m| format!(" ≤ {m}")).unwrap_or_default();
        return Err(ScenarioError::invalid(
            field,
            format!("must be [lo, hi] with 0 ≤ lo ≤ hi{bound} (got [{lo}, {hi}])"),
        ));
    }
    Ok([lo, hi])
}

impl SweepPlan {
    /// Validates `spec` against its scenario and the scenario's validated
    /// setup (called by [`Scenario::validate`]).
    ///
    /// # Errors
    /// [`ScenarioError::Invalid`] naming the `sweep.*` field that is out of
    /// range or cannot apply to this scenario.
    pub fn new(
        spec: &SweepSpec,
        scenario: &Scenario,
        setup: &Setup,
    ) -> Result<Self, ScenarioError> {
        let start = setup.trajectory.sample(0.0).position;
        let reference_start_m = [f64::from(start.x), f64::from(start.y)];
        let start_radius_m = range(
            "sweep.start_radius_m",
            spec.start_radius_m.unwrap_or(DEFAULT_START_RADIUS_M),
            None,
        )?;
        let output_feedback = setup.controller == ControllerKind::OutputFeedback;
        let diff_drive = matches!(setup.plant, PlantSetup::DiffDrive { .. });
        match spec.observer_start {
            ObserverStart::Scenario => {}
            _ if !output_feedback => {
                return Err(ScenarioError::invalid(
                    "sweep.observer_start",
                    "state_feedback runs no observer: remove it or use \"scenario\"",
                ));
            }
            ObserverStart::UnitDisc if diff_drive => {
                return Err(ScenarioError::invalid(
                    "sweep.observer_start",
                    "the diff_drive plant runs the core's Pilot, whose observer always starts at (0, 0)",
                ));
            }
            ObserverStart::Zero | ObserverStart::UnitDisc => {}
        }
        let spacing_m = match &setup.position {
            PositionSetup::Exact => None,
            PositionSetup::NearestTag(floor) => Some(floor.spacing_m()),
            PositionSetup::Reader(floor, _) => floor.spacing_m(),
        };
        let tag_offset_cell_m = match (spec.tag_offset, spacing_m) {
            (Some(true), None) => {
                return Err(ScenarioError::invalid(
                    "sweep.tag_offset",
                    "position.kind = \"exact\" and a tag-map floor have no tag grid to offset",
                ));
            }
            (Some(false), _) => None,
            (_, spacing) => spacing,
        };
        let encoder_counts_per_rev = match &spec.encoder_counts_per_rev {
            None => None,
            Some(_) if !diff_drive => {
                return Err(ScenarioError::invalid(
                    "sweep.encoder_counts_per_rev",
                    "only the diff_drive plant has encoders",
                ));
            }
            Some(list) => {
                if list.is_empty() || list.len() > MAX_ENCODER_CHOICES || list.contains(&0) {
                    return Err(ScenarioError::invalid(
                        "sweep.encoder_counts_per_rev",
                        format!(
                            "must list 1 to {MAX_ENCODER_CHOICES} resolutions, each ≥ 1 (got {list:?})"
                        ),
                    ));
                }
                let mut values = [0; MAX_ENCODER_CHOICES];
                values[..list.len()].copy_from_slice(list);
                Some(EncoderChoices {
                    values,
                    len: list.len(),
                })
            }
        };
        let position_noise_std_m = match spec.position_noise_std_m {
            None => None,
            Some(_) if matches!(setup.position, PositionSetup::Reader(..)) => {
                return Err(ScenarioError::invalid(
                    "sweep.position_noise_std_m",
                    "the reader's fixes are tag ids looked up in the grid: noise applies to the \
                     exact and nearest_tag sources only",
                ));
            }
            Some(r) => Some(range("sweep.position_noise_std_m", r, None)?),
        };
        let read_miss_probability = match spec.read_miss_probability {
            None => None,
            Some(_) if !output_feedback => {
                return Err(ScenarioError::invalid(
                    "sweep.read_miss_probability",
                    "state_feedback needs a position every tick (only output feedback dead-reckons)",
                ));
            }
            Some(r) => {
                let r = range("sweep.read_miss_probability", r, Some(1.0))?;
                probability("sweep.read_miss_probability", r[1])?;
                Some(r)
            }
        };
        let default_threshold = spacing_m.map_or(DEFAULT_EXACT_THRESHOLD_M, |s| {
            DEFAULT_THRESHOLD_SPACINGS * s
        }) + position_noise_std_m.map_or(0.0, |r| 3.0 * r[1]);
        // To the nanometre: 0.3, not 0.30000000000000004, in the outputs.
        let default_threshold = (default_threshold * 1e9).round() / 1e9;
        let converge_threshold_m = positive(
            "sweep.converge_threshold_m",
            spec.converge_threshold_m.unwrap_or(default_threshold),
        )?;
        let duration_s = f64::from(setup.ticks) * setup.period_s;
        let converge_hold_s = non_negative(
            "sweep.converge_hold_s",
            spec.converge_hold_s
                .unwrap_or(DEFAULT_HOLD_FRACTION * duration_s),
        )?;
        if converge_hold_s >= duration_s {
            return Err(ScenarioError::invalid(
                "sweep.converge_hold_s",
                format!("must be shorter than the run ({duration_s} s)"),
            ));
        }
        let plan = Self {
            reference_start_m,
            start_radius_m,
            initial_heading: spec.initial_heading,
            observer_start: spec.observer_start,
            tag_offset_cell_m,
            encoder_counts_per_rev,
            position_noise_std_m,
            read_miss_probability,
            converge_threshold_m,
            converge_hold_s,
        };
        plan.check_extreme_starts(scenario)?;
        Ok(plan)
    }

    /// Validates the scenario with the start at the annulus' extremes on
    /// each axis (the floor of tags must cover every start, and the floor
    /// is a rectangle, so these bound every run's).
    fn check_extreme_starts(&self, scenario: &Scenario) -> Result<(), ScenarioError> {
        let r = self.start_radius_m[1];
        let [x, y] = self.reference_start_m;
        for (dx, dy) in [(r, 0.0), (-r, 0.0), (0.0, r), (0.0, -r)] {
            let mut probe = scenario.clone();
            probe.sweep = None;
            probe.initial.x_m = x + dx;
            probe.initial.y_m = y + dy;
            probe.validate().map_err(|e| {
                ScenarioError::invalid(
                    "sweep.start_radius_m",
                    format!("a start {r} m from the reference's start is refused: {e}"),
                )
            })?;
        }
        Ok(())
    }
}
