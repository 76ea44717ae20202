//! Scenarios: what to simulate, as TOML, validated into the core's configs.
//!
//! A scenario file names every quantity with its unit (`period_s`, `h1_m`);
//! everything but `name`, `duration_s` and the reference has a default (the
//! paper's section 6.3.2 values where the paper gives one). Unknown keys are
//! errors, and every validation error names the offending field:
//!
//! ```text
//! scenario field `observer.gain_per_m`: must be finite and > 0 (got -1)
//! ```
//!
//! [`Scenario::validate`] turns a scenario into a [`Setup`]: the core's own
//! validated configurations ([`TrackerConfig`], [`PilotConfig`], ...) plus the
//! simulator's plant, floor and reader models.

use std::f64::consts::FRAC_PI_2;
use std::path::Path;

use serde::{Deserialize, Serialize};
use wmr_core::control::saturated::TrackingGains;
use wmr_core::drive::momenta_observer::WheelInertia;
use wmr_core::drive::speed_observer::WheelSpeedObserverConfig;
use wmr_core::estimation::heading_observer::HeadingEstimate;
use wmr_core::pilot::PilotConfig;
use wmr_core::pilot::spec::{
    self as core_spec, EstimatorSpec, FusionFilterSpec, LawSpec, PilotSpec, SpecError, TrackerSpec,
    TrajectorySpec,
};
use wmr_core::pilot::tracker::TrackerConfig;
use wmr_core::reference::Trajectory;

use crate::devices::{LinkFaults, ReaderConfig, ReaderMode};
use crate::plant::{DiffDriveParams, LoadTorque, PlantPose, WheelDynamics};
use crate::tags::FloorTags;

mod sweep_spec;

pub use sweep_spec::{
    DEFAULT_EXACT_THRESHOLD_M, DEFAULT_HOLD_FRACTION, DEFAULT_START_RADIUS_M,
    DEFAULT_THRESHOLD_SPACINGS, EncoderChoices, HeadingSweep, MAX_ENCODER_CHOICES, ObserverStart,
    SweepPlan, SweepSpec,
};

/// Why a scenario was refused.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// The file could not be read.
    #[error("cannot read scenario file {path}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// Not valid TOML, or not the scenario schema (the message names the
    /// key and the line).
    #[error("scenario is not valid: {0}")]
    Parse(String),
    /// A value out of range or inconsistent with another.
    #[error("scenario field `{field}`: {reason}")]
    Invalid {
        /// Dotted path of the field, e.g. `plant.wheel_radius_m`.
        field: String,
        /// What is wrong with it.
        reason: String,
    },
}

impl ScenarioError {
    pub(crate) fn invalid(field: &str, reason: impl Into<String>) -> Self {
        Self::Invalid {
            field: field.to_owned(),
            reason: reason.into(),
        }
    }

    /// The offending field's dotted path, for [`Self::Invalid`].
    #[must_use]
    pub fn field(&self) -> Option<&str> {
        match self {
            Self::Invalid { field, .. } => Some(field),
            _ => None,
        }
    }
}

/// A simulation scenario (the TOML file's top level).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Short name (used for the default output directory).
    pub name: String,
    /// Free text.
    #[serde(default)]
    pub description: String,
    /// Simulated time, s.
    pub duration_s: f64,
    /// Control period `h`, s.
    #[serde(default = "defaults::period_s")]
    pub period_s: f64,
    /// Error statistics are taken over `t ≥ transient_s`, s.
    #[serde(default)]
    pub transient_s: f64,
    /// The reference trajectory.
    pub reference: ReferenceSpec,
    /// Initial pose and observer estimate.
    #[serde(default)]
    pub initial: InitialSpec,
    /// Tracking law and gains.
    #[serde(default)]
    pub controller: ControllerSpec,
    /// Heading observer (output feedback only).
    #[serde(default)]
    pub observer: ObserverSpec,
    /// The simulated robot body.
    #[serde(default)]
    pub plant: PlantSpec,
    /// Drive limits and speed loops (`diff_drive` plant only).
    #[serde(default)]
    pub drive: Option<DriveSpec>,
    /// Where the position measurement comes from.
    #[serde(default)]
    pub position: PositionSpec,
    /// What the tracker does when fixes stop.
    #[serde(default)]
    pub failsafe: FailsafeSpec,
    /// Noise and misses on the position fix (`exact` and `nearest_tag`
    /// sources).
    #[serde(default, skip_serializing_if = "MeasurementSpec::is_default")]
    pub measurement: MeasurementSpec,
    /// What `firmware-sim sweep` varies (ignored by `run`, but validated).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sweep: Option<SweepSpec>,
}

/// The reference trajectory.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ReferenceSpec {
    /// Paper 001's figure-eight, `x = h1 sin 2s`, `y = h1 sin s`, `s = h2 t + φ`.
    FigureEight {
        /// Half-width `h1`, m.
        #[serde(default = "defaults::h1_m")]
        h1_m: f64,
        /// Rate `h2`, rad/s.
        #[serde(default = "defaults::h2_rad_s")]
        h2_rad_s: f64,
        /// Phase `φ`, rad (−π/2 starts at (0, −h1), as the paper's runs).
        #[serde(default = "defaults::phase_rad")]
        phase_rad: f64,
    },
    /// A circle.
    Circle {
        /// Centre `[x, y]`, m.
        #[serde(default)]
        center_m: [f64; 2],
        /// Radius, m.
        radius_m: f64,
        /// Angular rate, rad/s (negative: clockwise).
        rate_rad_s: f64,
        /// Polar angle of the start point, rad.
        #[serde(default)]
        phase_rad: f64,
    },
    /// A straight line at constant speed.
    Line {
        /// Start `[x, y]`, m.
        #[serde(default)]
        start_m: [f64; 2],
        /// Direction, rad.
        #[serde(default)]
        heading_rad: f64,
        /// Speed, m/s.
        speed_m_s: f64,
    },
}

/// Initial pose of the robot and of the observer's estimate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct InitialSpec {
    /// x, m.
    #[serde(default)]
    pub x_m: f64,
    /// y, m.
    #[serde(default)]
    pub y_m: f64,
    /// Heading θ(0), rad.
    #[serde(default)]
    pub heading_rad: f64,
    /// Observer's initial `ẑ3` (estimate of cos θ); 0 = heading unknown.
    #[serde(default)]
    pub estimate_cos: f64,
    /// Observer's initial `ẑ4` (estimate of sin θ).
    #[serde(default)]
    pub estimate_sin: f64,
}

/// Which tracking law.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum ControllerKind {
    /// Observer (5) + law (27)–(28): position only (paper 001, Theorem 3).
    #[default]
    OutputFeedback,
    /// Law (14) with the true heading (paper 001, Theorem 2).
    StateFeedback,
}

/// Which position-only law the output-feedback tracker runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum LawKind {
    /// Paper 001's law (27)–(28), gains `k1, k2, k3`.
    #[default]
    Paper001,
    /// Paper 002's cascaded controller (31), gains `c1, c2`, on the error
    /// (30) from the estimated heading.
    Cascaded,
    /// Paper 002's Proposition 7: observer of `sin θ_e` (gain `a`) and
    /// controller (64) (gains `c2`, `gamma`).
    HeadingErrorSine,
}

/// Tracking law and gains.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControllerSpec {
    /// Which law.
    #[serde(default)]
    pub kind: ControllerKind,
    /// With `kind = "output_feedback"`: which position-only law.
    #[serde(default)]
    pub law: LawKind,
    /// `c1` of (31), 1/s.
    #[serde(default = "defaults::c1")]
    pub c1: f64,
    /// `c2` of (31) and (64), 1/s.
    #[serde(default = "defaults::c2")]
    pub c2: f64,
    /// Observer gain `a` of Proposition 7, s/m².
    #[serde(default = "defaults::sine_a")]
    pub a: f64,
    /// `γ ∈ (0, 1)` of (64).
    #[serde(default = "defaults::gamma")]
    pub gamma: f64,
    /// `k1`, m/s.
    #[serde(default = "defaults::k12")]
    pub k1: f64,
    /// `k2`, m/s.
    #[serde(default = "defaults::k12")]
    pub k2: f64,
    /// `k3`, 1/s.
    #[serde(default = "defaults::k3")]
    pub k3: f64,
}

impl Default for ControllerSpec {
    fn default() -> Self {
        Self {
            kind: ControllerKind::default(),
            law: LawKind::default(),
            c1: defaults::c1(),
            c2: defaults::c2(),
            a: defaults::sine_a(),
            gamma: defaults::gamma(),
            k1: defaults::k12(),
            k2: defaults::k12(),
            k3: defaults::k3(),
        }
    }
}

/// Which heading estimator the output-feedback tracker runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum ObserverKind {
    /// Paper 001's observer (5), gain `gain_per_m`.
    #[default]
    Paper001,
    /// Paper 002's Proposition 4 observer of `x, y, cos θ, sin θ`, gains
    /// `pose_gains = [a1, a2, a3, a4]`.
    Pose,
    /// The encoder + tag fusion EKF (`wmr_core::estimation::fusion`), tuned by the
    /// `fusion_*` keys; needs grid tags (`nearest_tag`, or `reader` in
    /// `paper` or `range` mode) without added noise.
    FusionEkf,
    /// The same estimator on paper 004's UKF (`wmr_core::estimation::fusion::ukf`).
    FusionUkf,
    /// The same estimator on paper 004's particle filter
    /// (`wmr_core::estimation::fusion::particle`, 100 particles), its generator
    /// seeded with `fusion_particle_seed`.
    FusionParticleFilter,
}

/// Heading observer parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObserverSpec {
    /// Which estimator.
    #[serde(default)]
    pub kind: ObserverKind,
    /// `[a1, a2]` (1/s), `[a3, a4]` (1/m²) of paper 002's (37).
    #[serde(default = "defaults::pose_gains")]
    pub pose_gains: [f64; 4],
    /// Fusion EKF: each wheel's travel variance per metre driven, m²/m.
    #[serde(default = "defaults::fusion_wheel_variance_per_m")]
    pub fusion_wheel_variance_per_m: f64,
    /// Fusion EKF: Mahalanobis gate, standard deviations.
    #[serde(default = "defaults::fusion_gate_sigma")]
    pub fusion_gate_sigma: f64,
    /// Fusion EKF: prior variance of each wheel's scale error (0: the
    /// wheels are taken as calibrated; 4e-4 learns them from a 2 % prior).
    #[serde(default)]
    pub fusion_scale_prior: f64,
    /// Fusion estimator: the failsafe's limit on the distance driven since
    /// the last fix, m, which then replaces the fix timeout (0: the timeout
    /// decides). Default with a `range` reader, where gaps between tags are
    /// normal: `4 s²/r` for spacing `s` and range `r` (1.6 m for the 20 cm
    /// grid and 5 cm range; `defaults::fusion_range_max_blind_distance_m`);
    /// 0 otherwise.
    #[serde(default)]
    pub fusion_max_blind_distance_m: Option<f64>,
    /// Fusion estimator: reads of an unchanged tag pull an estimate that
    /// left the tag's cell back to its edge (nearest-tag reader; default
    /// off; with `fusion_wheel_variance_per_m` near the real wheel noise
    /// it is the tuning for wheels that slip).
    #[serde(default)]
    pub fusion_edge_constraint: bool,
    /// Fusion particle filter: its generator's seed (default 1).
    #[serde(default = "defaults::fusion_particle_seed")]
    pub fusion_particle_seed: u64,
    /// Observer gain `L`, 1/m.
    #[serde(default = "defaults::gain_per_m")]
    pub gain_per_m: f64,
    /// Speed below which position changes are ignored, m/s.
    #[serde(default = "defaults::min_speed_m_s")]
    pub min_speed_m_s: f64,
}

impl Default for ObserverSpec {
    fn default() -> Self {
        Self {
            kind: ObserverKind::default(),
            pose_gains: defaults::pose_gains(),
            fusion_wheel_variance_per_m: defaults::fusion_wheel_variance_per_m(),
            fusion_gate_sigma: defaults::fusion_gate_sigma(),
            fusion_scale_prior: 0.0,
            fusion_particle_seed: defaults::fusion_particle_seed(),
            fusion_max_blind_distance_m: None,
            fusion_edge_constraint: false,
            gain_per_m: defaults::gain_per_m(),
            min_speed_m_s: defaults::min_speed_m_s(),
        }
    }
}

/// The simulated robot body.
///
/// (De)serialized by hand around the derived code (`remote = "Self"`
/// makes the derives inherent `PlantSpec::serialize`/`deserialize`): serde
/// ignores keys beside a unit variant's tag, so a `[plant.dynamics]` table
/// under `kind = "unicycle"` would otherwise vanish silently.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
#[serde(
    remote = "Self",
    tag = "kind",
    rename_all = "snake_case",
    deny_unknown_fields
)]
pub enum PlantSpec {
    /// Paper 001's kinematic unicycle (1): commands are velocities. The
    /// core's tracker (or controller) is called directly.
    #[default]
    Unicycle,
    /// Two DC motors, PWM drivers, quadrature encoders: runs the core's
    /// `Robot` (or `Pilot`) against virtual devices.
    DiffDrive {
        /// Wheel radius, m.
        #[serde(default = "defaults::wheel_radius_m")]
        wheel_radius_m: f64,
        /// Track width, m.
        #[serde(default = "defaults::track_width_m")]
        track_width_m: f64,
        /// Motor + wheel time constant `τ`, s.
        #[serde(default = "defaults::motor_time_constant_s")]
        motor_time_constant_s: f64,
        /// Wheel speed at full duty, rad/s.
        #[serde(default = "defaults::wheel_speed_at_full_duty_rad_s")]
        wheel_speed_at_full_duty_rad_s: f64,
        /// Quadrature counts per wheel revolution.
        #[serde(default = "defaults::encoder_counts_per_rev")]
        encoder_counts_per_rev: u32,
        /// Width of the hardware encoder counters, bits.
        #[serde(default = "defaults::encoder_bits")]
        encoder_bits: u32,
        /// PWM full-scale duty, steps.
        #[serde(default = "defaults::pwm_max_duty")]
        pwm_max_duty: u16,
        /// RK4 substeps per control period.
        #[serde(default = "defaults::substeps")]
        substeps: u32,
        /// Rigid-body wheel dynamics (`[plant.dynamics]`); absent: each
        /// wheel is the first-order system of `motor_time_constant_s`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        dynamics: Option<DynamicsSpec>,
    },
}

impl Serialize for PlantSpec {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        // The derived serializer (inherent, from `remote = "Self"`).
        PlantSpec::serialize(self, serializer)
    }
}

impl<'de> Deserialize<'de> for PlantSpec {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        use serde::de::Error as _;
        let table = toml::Table::deserialize(deserializer)?;
        if table.get("kind").and_then(toml::Value::as_str) == Some("unicycle")
            && table.contains_key("dynamics")
        {
            return Err(D::Error::custom(
                "`plant.dynamics` is only used with kind = \"diff_drive\" (the unicycle's \
                 commands are its velocities); remove the [plant.dynamics] table",
            ));
        }
        // The derived deserializer (inherent, from `remote = "Self"`); its
        // error's text ends in a newline the outer error adds again.
        PlantSpec::deserialize(toml::Value::Table(table))
            .map_err(|e| D::Error::custom(e.to_string().trim_end()))
    }
}

/// Rigid-body wheel dynamics of the `diff_drive` plant, the
/// `[plant.dynamics]` table (see [`WheelDynamics`]): the wheels carry the
/// robot's mass and yaw inertia, each motor gives `stall_torque_nm` at
/// full duty and zero speed less its back-EMF (no-load speed
/// `plant.wheel_speed_at_full_duty_rad_s`), and a slope load may start at
/// `load_start_s`. `plant.motor_time_constant_s` is then unused.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DynamicsSpec {
    /// Robot mass, kg.
    pub mass_kg: f64,
    /// Yaw inertia about the axle midpoint, kg m².
    pub yaw_inertia_kg_m2: f64,
    /// Each wheel's inertia with its motor and gearbox reflected to the
    /// wheel, kg m².
    #[serde(default)]
    pub wheel_inertia_kg_m2: f64,
    /// Viscous friction of each wheel's drive train, N·m·s/rad.
    #[serde(default)]
    pub viscous_friction_nm_s_per_rad: f64,
    /// Motor torque at the wheel at full duty and zero speed, N·m.
    pub stall_torque_nm: f64,
    /// When the robot starts onto the slope, s of scenario time.
    #[serde(default)]
    pub load_start_s: f64,
    /// Time the slope angle takes to reach its final value (linear in the
    /// angle), s; 0 = step.
    #[serde(default)]
    pub load_ramp_s: f64,
    /// Final grade driven uphill, percent (rise per 100 of run; negative:
    /// downhill; 0: no load).
    #[serde(default)]
    pub load_grade_percent: f64,
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

/// Drive limits and per-wheel speed loops (`diff_drive` plant only).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DriveSpec {
    /// Wheel speed limit, rad/s.
    #[serde(default = "defaults::max_wheel_speed_rad_s")]
    pub max_wheel_speed_rad_s: f64,
    /// Wheel acceleration limit, rad/s².
    #[serde(default = "defaults::max_wheel_accel_rad_s2")]
    pub max_wheel_accel_rad_s2: f64,
    /// Feed-forward, duty per rad/s (default: 1 / wheel speed at full duty).
    #[serde(default)]
    pub feedforward_duty_per_rad_s: Option<f64>,
    /// Proportional gain, duty per rad/s.
    #[serde(default = "defaults::kp_duty_per_rad_s")]
    pub kp_duty_per_rad_s: f64,
    /// Integral gain, duty per rad.
    #[serde(default = "defaults::ki_duty_per_rad")]
    pub ki_duty_per_rad: f64,
    /// Run the speed loops on paper 003's wheel-speed observer instead of
    /// the counts differenced over a tick (`[drive.speed_observer]`).
    #[serde(default)]
    pub speed_observer: Option<SpeedObserverSpec>,
}

/// The robot as the wheel-speed observer models it (paper 003, section
/// 6.1; see `wmr_core::drive::speed_observer`). The wheel radius, track and
/// the motors' no-load speed (`plant.wheel_speed_at_full_duty_rad_s`) come
/// from the plant table; these may differ from `[plant.dynamics]` to study
/// a mismatched model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpeedObserverSpec {
    /// Robot mass, kg.
    pub mass_kg: f64,
    /// Yaw inertia about the axle midpoint, kg m².
    pub yaw_inertia_kg_m2: f64,
    /// Each wheel's drive-train inertia at the wheel, kg m² (default 0).
    #[serde(default)]
    pub wheel_inertia_kg_m2: f64,
    /// Motor torque at the wheel at full duty and standstill, N·m.
    pub stall_torque_nm: f64,
    /// `λ`, 1/s (default 5).
    #[serde(default = "defaults::observer_lambda_per_s")]
    pub lambda_per_s: f64,
    /// Damping adaptation gain `γ_r` (default 0.01).
    #[serde(default = "defaults::observer_friction_gain")]
    pub friction_gain: f64,
    /// Load adaptation gain `γ_d` (default 0.1).
    #[serde(default = "defaults::observer_disturbance_gain")]
    pub disturbance_gain: f64,
}

impl Default for DriveSpec {
    fn default() -> Self {
        Self {
            max_wheel_speed_rad_s: defaults::max_wheel_speed_rad_s(),
            max_wheel_accel_rad_s2: defaults::max_wheel_accel_rad_s2(),
            feedforward_duty_per_rad_s: None,
            kp_duty_per_rad_s: defaults::kp_duty_per_rad_s(),
            ki_duty_per_rad: defaults::ki_duty_per_rad(),
            speed_observer: None,
        }
    }
}

/// When the virtual reader reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum ReaderModeSpec {
    /// The nearest tag, every tick (paper 001, section 6.3.2).
    #[default]
    Paper,
    /// Tags within `read_radius_m`, on entry and every `repeat_interval_s`.
    Range,
}

/// Where the position measurement comes from.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum PositionSpec {
    /// The true position, every tick.
    #[default]
    Exact,
    /// The nearest tag's position, every tick, with no reader or UART in
    /// between (paper 001, section 6.3.2).
    NearestTag {
        /// Tag spacing, m.
        #[serde(default = "defaults::spacing_m")]
        spacing_m: f64,
        /// A lattice point `[x, y]`, m.
        #[serde(default)]
        offset_m: [f64; 2],
        /// Margin around the reference and start when `extent_m` is not given, m.
        #[serde(default = "defaults::margin_m")]
        margin_m: f64,
        /// Covered rectangle `[x_min, y_min, x_max, y_max]`, m (default: automatic).
        #[serde(default)]
        extent_m: Option<[f64; 4]>,
    },
    /// Frames from a virtual RFID reader over a virtual UART, parsed by the
    /// core's reader and looked up in the core's tag grid.
    Reader {
        /// Tag spacing, m.
        #[serde(default = "defaults::spacing_m")]
        spacing_m: f64,
        /// A lattice point `[x, y]`, m.
        #[serde(default)]
        offset_m: [f64; 2],
        /// Margin around the reference and start when `extent_m` is not given, m.
        #[serde(default = "defaults::margin_m")]
        margin_m: f64,
        /// Covered rectangle `[x_min, y_min, x_max, y_max]`, m (default: automatic).
        #[serde(default)]
        extent_m: Option<[f64; 4]>,
        /// `paper` (nearest tag every tick) or `range`.
        #[serde(default)]
        mode: ReaderModeSpec,
        /// Read radius around the antenna (`range` mode), m.
        #[serde(default = "defaults::read_radius_m")]
        read_radius_m: f64,
        /// Antenna ahead of the axle midpoint, m.
        #[serde(default)]
        antenna_offset_m: f64,
        /// Line speed, baud.
        #[serde(default = "defaults::baud")]
        baud: u32,
        /// Repeat interval while a tag stays in range (`range` mode), s.
        #[serde(default = "defaults::repeat_interval_s")]
        repeat_interval_s: f64,
        /// Probability that a byte arrives with a flipped bit.
        #[serde(default)]
        corrupt_byte_probability: f64,
        /// Probability that a frame is lost.
        #[serde(default)]
        drop_frame_probability: f64,
        /// Seed of the fault RNG.
        #[serde(default = "defaults::seed")]
        seed: u64,
    },
}

/// What the tracker does when fixes stop.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FailsafeSpec {
    /// Time without a valid fix before the failsafe engages, s.
    #[serde(default = "defaults::fix_timeout_s")]
    pub fix_timeout_s: f64,
    /// Failsafe deceleration, m/s².
    #[serde(default = "defaults::decel_m_s2")]
    pub decel_m_s2: f64,
}

impl Default for FailsafeSpec {
    fn default() -> Self {
        Self {
            fix_timeout_s: defaults::fix_timeout_s(),
            decel_m_s2: defaults::decel_m_s2(),
        }
    }
}

/// Faults on the position fix of the `exact` and `nearest_tag` sources
/// (the `reader` source has its own link faults,
/// `position.drop_frame_probability` and `position.corrupt_byte_probability`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeasurementSpec {
    /// Standard deviation of the zero-mean Gaussian noise added to each
    /// axis of every fix, m.
    #[serde(default)]
    pub noise_std_m: f64,
    /// Probability that a tick has no fix (the tracker dead-reckons).
    #[serde(default)]
    pub miss_probability: f64,
    /// Seed of the noise and miss RNG.
    #[serde(default = "defaults::seed")]
    pub seed: u64,
}

impl Default for MeasurementSpec {
    fn default() -> Self {
        Self {
            noise_std_m: 0.0,
            miss_probability: 0.0,
            seed: defaults::seed(),
        }
    }
}

impl MeasurementSpec {
    /// Whether the fix is passed through untouched.
    #[must_use]
    pub fn is_clean(&self) -> bool {
        self.noise_std_m == 0.0 && self.miss_probability == 0.0
    }

    fn is_default(&self) -> bool {
        *self == Self::default()
    }
}

/// Default values (serde needs functions).
mod defaults {
    pub fn period_s() -> f64 {
        0.01
    }
    pub fn h1_m() -> f64 {
        5.0
    }
    pub fn h2_rad_s() -> f64 {
        0.02
    }
    pub fn phase_rad() -> f64 {
        -super::FRAC_PI_2
    }
    pub fn k12() -> f64 {
        0.11
    }
    pub fn k3() -> f64 {
        0.1
    }
    pub fn c1() -> f64 {
        0.5
    }
    pub fn c2() -> f64 {
        0.5
    }
    pub fn sine_a() -> f64 {
        100.0
    }
    pub fn gamma() -> f64 {
        0.9
    }
    pub fn pose_gains() -> [f64; 4] {
        [1.5, 1.5, 100.0, 100.0]
    }
    pub fn gain_per_m() -> f64 {
        0.6
    }
    pub fn fusion_wheel_variance_per_m() -> f64 {
        1e-3
    }
    /// The fusion estimator's blind-distance limit with a range reader of
    /// radius `r` on a grid of spacing `s`, m: `4 s²/r`, eight times
    /// `s²/2r`, the mean distance a straight line runs between read discs
    /// of the grid (the figure-eight's longest gaps on 20 and 30 cm floors
    /// stopped the robot at 2 m, none at this).
    pub fn fusion_range_max_blind_distance_m(spacing_m: f64, read_radius_m: f64) -> f64 {
        4.0 * spacing_m * spacing_m / read_radius_m
    }
    pub fn fusion_particle_seed() -> u64 {
        1
    }
    pub fn fusion_gate_sigma() -> f64 {
        3.0
    }
    pub fn min_speed_m_s() -> f64 {
        f64::from(
            wmr_core::estimation::heading_observer::HeadingObserverConfig::DEFAULT_MIN_SPEED_M_S,
        )
    }
    pub fn wheel_radius_m() -> f64 {
        0.03
    }
    pub fn track_width_m() -> f64 {
        0.2
    }
    pub fn motor_time_constant_s() -> f64 {
        0.05
    }
    pub fn wheel_speed_at_full_duty_rad_s() -> f64 {
        20.0
    }
    pub fn encoder_counts_per_rev() -> u32 {
        2048
    }
    pub fn encoder_bits() -> u32 {
        16
    }
    pub fn pwm_max_duty() -> u16 {
        1000
    }
    pub fn substeps() -> u32 {
        10
    }
    pub fn max_wheel_speed_rad_s() -> f64 {
        18.0
    }
    pub fn max_wheel_accel_rad_s2() -> f64 {
        50.0
    }
    pub fn kp_duty_per_rad_s() -> f64 {
        0.02
    }
    pub fn ki_duty_per_rad() -> f64 {
        0.5
    }
    pub fn observer_lambda_per_s() -> f64 {
        f64::from(wmr_core::drive::speed_observer::WheelSpeedObserverConfig::DEFAULT_LAMBDA_PER_S)
    }
    pub fn observer_friction_gain() -> f64 {
        f64::from(wmr_core::drive::speed_observer::WheelSpeedObserverConfig::DEFAULT_FRICTION_GAIN)
    }
    pub fn observer_disturbance_gain() -> f64 {
        f64::from(
            wmr_core::drive::speed_observer::WheelSpeedObserverConfig::DEFAULT_DISTURBANCE_GAIN,
        )
    }
    pub fn spacing_m() -> f64 {
        0.1
    }
    pub fn margin_m() -> f64 {
        1.0
    }
    pub fn read_radius_m() -> f64 {
        0.05
    }
    pub fn baud() -> u32 {
        115_200
    }
    pub fn repeat_interval_s() -> f64 {
        0.1
    }
    pub fn seed() -> u64 {
        1
    }
    pub fn fix_timeout_s() -> f64 {
        0.5
    }
    pub fn decel_m_s2() -> f64 {
        f64::from(wmr_core::pilot::tracker::TrackerConfig::DEFAULT_FAILSAFE_DECEL_M_S2)
    }
}

/// The scenarios shipped with the simulator, as `(file name, TOML text)`.
/// The first is the default.
pub const EMBEDDED: &[(&str, &str)] = &[
    (
        "figure_eight_rfid",
        include_str!("../../scenarios/figure_eight_rfid.toml"),
    ),
    (
        "figure_eight_rfid_full_stack",
        include_str!("../../scenarios/figure_eight_rfid_full_stack.toml"),
    ),
    (
        "figure_eight_rfid_pose_observer",
        include_str!("../../scenarios/figure_eight_rfid_pose_observer.toml"),
    ),
    (
        "figure_eight_rfid_fusion_ekf",
        include_str!("../../scenarios/figure_eight_rfid_fusion_ekf.toml"),
    ),
    (
        "figure_eight_exact",
        include_str!("../../scenarios/figure_eight_exact.toml"),
    ),
    (
        "figure_eight_state_feedback",
        include_str!("../../scenarios/figure_eight_state_feedback.toml"),
    ),
];

/// The TOML text of an embedded scenario, by file name (without `.toml`).
#[must_use]
pub fn embedded_source(name: &str) -> Option<&'static str> {
    let name = name.strip_suffix(".toml").unwrap_or(name);
    EMBEDDED.iter().find(|(n, _)| *n == name).map(|(_, s)| *s)
}

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
        /// The core's pilot configuration (tracker + drive + encoder width).
        pilot: PilotConfig,
        /// The spec it was built from (what the HIL link sends the firmware).
        pilot_spec: PilotSpec,
    },
}

/// The validated position source.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PositionSetup {
    /// True position every tick.
    Exact,
    /// Nearest tag every tick, no reader.
    NearestTag(FloorTags),
    /// Virtual reader + UART + the core's parser and tag grid.
    Reader(FloorTags, ReaderConfig),
}

/// A validated scenario: the core's configurations and the simulator's models.
#[derive(Debug, Clone, Copy, PartialEq)]
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

pub(crate) fn positive(field: &str, v: f64) -> Result<f64, ScenarioError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(ScenarioError::invalid(
            field,
            format!("must be finite and > 0 (got {v})"),
        ))
    }
}

pub(crate) fn non_negative(field: &str, v: f64) -> Result<f64, ScenarioError> {
    if v.is_finite() && v >= 0.0 {
        Ok(v)
    } else {
        Err(ScenarioError::invalid(
            field,
            format!("must be finite and ≥ 0 (got {v})"),
        ))
    }
}

fn finite(field: &str, v: f64) -> Result<f64, ScenarioError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(ScenarioError::invalid(
            field,
            format!("must be finite (got {v})"),
        ))
    }
}

pub(crate) fn probability(field: &str, v: f64) -> Result<f64, ScenarioError> {
    if (0.0..=1.0).contains(&v) {
        Ok(v)
    } else {
        Err(ScenarioError::invalid(
            field,
            format!("must be a probability in [0, 1] (got {v})"),
        ))
    }
}

/// A refusal of the core's spec builder, named by the scenario table it
/// came from.
/// Reads `path` and parses it with `parse`, naming the file in parse
/// errors (shared by the scenario kinds of this crate).
pub(crate) fn read_file<T>(
    path: &Path,
    parse: impl FnOnce(&str) -> Result<T, ScenarioError>,
) -> Result<T, ScenarioError> {
    let text = std::fs::read_to_string(path).map_err(|source| ScenarioError::Io {
        path: path.display().to_string(),
        source,
    })?;
    parse(&text).map_err(|e| match e {
        ScenarioError::Parse(m) => ScenarioError::Parse(format!("{}: {m}", path.display())),
        other => other,
    })
}

/// `config` with its speed loops on the wheel-speed observer `o`.
fn with_speed_observer(
    config: &PilotConfig,
    o: &SpeedObserverSpec,
    params: &DiffDriveParams,
    encoder_bits: u32,
) -> Result<PilotConfig, ScenarioError> {
    let field = |key: &str| format!("drive.speed_observer.{key}");
    let inertia = WheelInertia::new(
        f(positive(&field("mass_kg"), o.mass_kg)?),
        f(positive(&field("yaw_inertia_kg_m2"), o.yaw_inertia_kg_m2)?),
        f(params.wheel_radius_m),
        f(params.track_width_m),
        f(non_negative(
            &field("wheel_inertia_kg_m2"),
            o.wheel_inertia_kg_m2,
        )?),
    )
    .map_err(|e| ScenarioError::invalid("drive.speed_observer", format!("{e:?}")))?;
    let stall = f(positive(&field("stall_torque_nm"), o.stall_torque_nm)?);
    let gains = (
        f(positive(&field("lambda_per_s"), o.lambda_per_s)?),
        f(positive(&field("friction_gain"), o.friction_gain)?),
        f(positive(&field("disturbance_gain"), o.disturbance_gain)?),
    );
    let observer = WheelSpeedObserverConfig::new(
        inertia,
        stall,
        f(params.wheel_speed_at_full_duty_rad_s),
        config.drive().period_s(),
    )
    .and_then(|c| c.with_gains(gains.0, gains.1, gains.2))
    .map_err(|e| ScenarioError::invalid("drive.speed_observer", format!("{e:?}")))?;
    let drive = config
        .drive()
        .with_speed_observer(observer)
        .map_err(|e| ScenarioError::invalid("drive.speed_observer", format!("{e:?}")))?;
    PilotConfig::new(*config.tracker(), drive, encoder_bits)
        .map(|c| c.with_max_encoder_fault_ticks(PilotConfig::DEFAULT_MAX_ENCODER_FAULT_TICKS))
        .map_err(|e| ScenarioError::invalid("drive.speed_observer", format!("{e:?}")))
}

fn spec_refusal(e: SpecError) -> ScenarioError {
    let field = match e {
        SpecError::Trajectory(_) => "reference",
        SpecError::Gains(_) => "controller",
        SpecError::Observer(_) => "observer",
        SpecError::Tracker(_) => "failsafe",
        SpecError::Geometry(_) | SpecError::Pilot(_) => "plant",
        SpecError::Drive(_) => "drive",
        SpecError::TagGrid(_) => "position",
        SpecError::PoseObserver(_) => "observer.pose_gains",
        SpecError::Fusion(_) | SpecError::NotInThisBuild => "observer",
        SpecError::CascadedLaw(_) | SpecError::HeadingErrorSineLaw(_) => "controller",
    };
    ScenarioError::invalid(field, format!("refused by the core: {e:?}"))
}

/// `f32` of a validated `f64` (the core's precision).
fn f(v: f64) -> f32 {
    v as f32
}

impl Scenario {
    /// The core's estimator choice; paper 002's only with output feedback.
    fn estimator_spec(&self) -> Result<EstimatorSpec, ScenarioError> {
        match (self.observer.kind, self.controller.kind) {
            (ObserverKind::Paper001, _) => Ok(EstimatorSpec::HeadingObserver),
            (ObserverKind::Pose, ControllerKind::OutputFeedback) => {
                let g = self.observer.pose_gains;
                Ok(EstimatorSpec::PoseObserver {
                    gains: [
                        f(positive("observer.pose_gains[0]", g[0])?),
                        f(positive("observer.pose_gains[1]", g[1])?),
                        f(positive("observer.pose_gains[2]", g[2])?),
                        f(positive("observer.pose_gains[3]", g[3])?),
                    ],
                })
            }
            (
                ObserverKind::FusionEkf
                | ObserverKind::FusionUkf
                | ObserverKind::FusionParticleFilter,
                ControllerKind::OutputFeedback,
            ) => self.fusion_spec(),
            (
                ObserverKind::FusionEkf
                | ObserverKind::FusionUkf
                | ObserverKind::FusionParticleFilter,
                ControllerKind::StateFeedback,
            ) => Err(ScenarioError::invalid(
                "observer.kind",
                "state feedback measures the heading: no estimator runs",
            )),
            (ObserverKind::Pose, ControllerKind::StateFeedback) => Err(ScenarioError::invalid(
                "observer.kind",
                "state feedback measures the heading: no observer runs",
            )),
        }
    }

    /// The fusion EKF's spec: its tag model needs a grid read nearest-first
    /// without added noise; the wheel geometry comes from the plant.
    fn fusion_spec(&self) -> Result<EstimatorSpec, ScenarioError> {
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
            PositionSpec::Exact => {
                return Err(ScenarioError::invalid(
                    "observer.kind",
                    "the fusion EKF models tag reads: use position nearest_tag or reader",
                ));
            }
        };
        if self.measurement.noise_std_m > 0.0 {
            return Err(ScenarioError::invalid(
                "measurement.noise_std_m",
                "the fusion EKF's tag model needs fixes on the tag grid (no added noise)",
            ));
        }
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
        let o = &self.observer;
        let non_negative = |field: &'static str, v: f64| {
            if v.is_finite() && v >= 0.0 {
                Ok(v)
            } else {
                Err(ScenarioError::invalid(
                    field,
                    format!("must be ≥ 0 (got {v})"),
                ))
            }
        };
        let range_default = if read_radius_m > 0.0 {
            defaults::fusion_range_max_blind_distance_m(spacing_m, read_radius_m)
        } else {
            0.0
        };
        let max_blind_distance_m = non_negative(
            "observer.fusion_max_blind_distance_m",
            o.fusion_max_blind_distance_m.unwrap_or(range_default),
        )?;
        let filter = match o.kind {
            ObserverKind::FusionUkf => FusionFilterSpec::Ukf,
            ObserverKind::FusionParticleFilter => FusionFilterSpec::ParticleFilter {
                seed: o.fusion_particle_seed,
            },
            _ => FusionFilterSpec::Ekf,
        };
        Ok(EstimatorSpec::Fusion {
            filter,
            max_blind_distance_m: f(max_blind_distance_m),
            edge_constraint: o.fusion_edge_constraint,
            track_width_m: f(track_width_m),
            wheel_variance_per_m: f(non_negative(
                "observer.fusion_wheel_variance_per_m",
                o.fusion_wheel_variance_per_m,
            )?),
            wheel_variance_floor_m2: f(floor_m2),
            gate_sigma: f(positive("observer.fusion_gate_sigma", o.fusion_gate_sigma)?),
            tag_spacing_m: f(spacing_m),
            read_radius_m: f(read_radius_m),
            scale_prior: f(non_negative(
                "observer.fusion_scale_prior",
                o.fusion_scale_prior,
            )?),
        })
    }

    /// The core's law choice; paper 002's only with output feedback.
    fn law_spec(&self) -> Result<LawSpec, ScenarioError> {
        let c = &self.controller;
        match (c.law, c.kind) {
            (LawKind::Paper001, _) => Ok(LawSpec::Saturated),
            (_, ControllerKind::StateFeedback) => Err(ScenarioError::invalid(
                "controller.law",
                "selects the output-feedback law: use it with kind = \"output_feedback\"",
            )),
            (LawKind::Cascaded, ControllerKind::OutputFeedback) => Ok(LawSpec::Cascaded {
                c1_per_s: f(positive("controller.c1", c.c1)?),
                c2_per_s: f(positive("controller.c2", c.c2)?),
            }),
            (LawKind::HeadingErrorSine, ControllerKind::OutputFeedback) => {
                if !(c.gamma > 0.0 && c.gamma < 1.0) {
                    return Err(ScenarioError::invalid(
                        "controller.gamma",
                        format!("must be in (0, 1) (got {})", c.gamma),
                    ));
                }
                Ok(LawSpec::HeadingErrorSine {
                    a_s_per_m2: f(positive("controller.a", c.a)?),
                    c2_per_s: f(positive("controller.c2", c.c2)?),
                    gamma: f(c.gamma),
                })
            }
        }
    }

    /// Parses and validates a scenario from TOML text.
    ///
    /// # Errors
    /// [`ScenarioError::Parse`] for bad TOML or schema (unknown or missing
    /// keys, wrong types), [`ScenarioError::Invalid`] for bad values.
    pub fn from_toml_str(text: &str) -> Result<Self, ScenarioError> {
        let scenario: Self =
            toml::from_str(text).map_err(|e| ScenarioError::Parse(e.to_string()))?;
        scenario.validate()?;
        Ok(scenario)
    }

    /// Reads, parses and validates a scenario file.
    ///
    /// # Errors
    /// As [`Self::from_toml_str`], plus [`ScenarioError::Io`].
    pub fn from_file(path: &Path) -> Result<Self, ScenarioError> {
        read_file(path, Self::from_toml_str)
    }

    /// An embedded scenario by name (see [`EMBEDDED`]).
    ///
    /// # Errors
    /// [`ScenarioError::Invalid`] (field `name`) for an unknown name; an
    /// embedded scenario that does not parse is a bug, caught by the tests.
    pub fn embedded(name: &str) -> Result<Self, ScenarioError> {
        let text = embedded_source(name).ok_or_else(|| {
            let names: Vec<&str> = EMBEDDED.iter().map(|(n, _)| *n).collect();
            ScenarioError::invalid(
                "name",
                format!("no embedded scenario `{name}` (have: {})", names.join(", ")),
            )
        })?;
        Self::from_toml_str(text)
    }

    /// The default scenario: paper 001, section 6.3.2 (figure-eight, nearest
    /// RFID tag every tick, unicycle).
    #[must_use]
    pub fn default_scenario() -> Self {
        // The embedded scenarios are checked by the tests.
        #[allow(clippy::expect_used)]
        Self::embedded(EMBEDDED[0].0).expect("embedded default scenario is valid")
    }

    /// The scenario as TOML.
    ///
    /// # Errors
    /// Never for a scenario that was parsed (all values representable).
    pub fn to_toml_string(&self) -> Result<String, toml::ser::Error> {
        toml::to_string_pretty(self)
    }

    /// Checks every value and builds the core's configurations.
    ///
    /// # Errors
    /// [`ScenarioError::Invalid`] naming the first bad field.
    pub fn validate(&self) -> Result<Setup, ScenarioError> {
        if self.name.trim().is_empty() {
            return Err(ScenarioError::invalid("name", "must not be empty"));
        }
        let period_s = positive("period_s", self.period_s)?;
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

        let trajectory_spec = self.reference.spec()?;
        let trajectory = trajectory_spec.build().map_err(|e| {
            ScenarioError::invalid("reference", format!("refused by the core: {e:?}"))
        })?;
        let c = &self.controller;
        let gains = [
            f(positive("controller.k1", c.k1)?),
            f(positive("controller.k2", c.k2)?),
            f(positive("controller.k3", c.k3)?),
        ];
        let gain_per_m = positive("observer.gain_per_m", self.observer.gain_per_m)?;
        let min_speed = non_negative("observer.min_speed_m_s", self.observer.min_speed_m_s)?;
        let timeout_s = positive("failsafe.fix_timeout_s", self.failsafe.fix_timeout_s)?;
        let decel = positive("failsafe.decel_m_s2", self.failsafe.decel_m_s2)?;
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
            observer_gain_per_m: f(gain_per_m),
            observer_min_speed_m_s: f(min_speed),
            fix_timeout_ticks: fix_timeout_ticks as u32,
            failsafe_decel_m_s2: f(decel),
            max_fix_age_ticks: TrackerConfig::DEFAULT_MAX_FIX_AGE_TICKS,
            estimator: self.estimator_spec()?,
            law: self.law_spec()?,
        };
        let tracker = tracker_spec.build().map_err(spec_refusal)?;
        let gains = TrackingGains::new(gains[0], gains[1], gains[2])
            .map_err(|e| ScenarioError::invalid("controller", format!("{e:?}")))?;

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
            } => {
                let params = DiffDriveParams {
                    wheel_radius_m: positive("plant.wheel_radius_m", wheel_radius_m)?,
                    track_width_m: positive("plant.track_width_m", track_width_m)?,
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
                    Some(v) => non_negative("drive.feedforward_duty_per_rad_s", v)?,
                    None => 1.0 / params.wheel_speed_at_full_duty_rad_s,
                };
                let pilot_spec = PilotSpec {
                    tracker,
                    drive: core_spec::DriveSpec {
                        wheel_radius_m: f(params.wheel_radius_m),
                        track_width_m: f(params.track_width_m),
                        encoder_counts_per_rev,
                        max_wheel_speed_rad_s: f(positive(
                            "drive.max_wheel_speed_rad_s",
                            d.max_wheel_speed_rad_s,
                        )?),
                        max_wheel_accel_rad_s2: f(positive(
                            "drive.max_wheel_accel_rad_s2",
                            d.max_wheel_accel_rad_s2,
                        )?),
                        feedforward_duty_per_rad_s: f(feedforward),
                        kp_duty_per_rad_s: f(non_negative(
                            "drive.kp_duty_per_rad_s",
                            d.kp_duty_per_rad_s,
                        )?),
                        ki_duty_per_rad: f(non_negative(
                            "drive.ki_duty_per_rad",
                            d.ki_duty_per_rad,
                        )?),
                    },
                    encoder_bits,
                    max_encoder_fault_ticks: PilotConfig::DEFAULT_MAX_ENCODER_FAULT_TICKS,
                };
                let mut pilot = pilot_spec.build().map_err(spec_refusal)?;
                if let Some(o) = d.speed_observer {
                    pilot = with_speed_observer(&pilot, &o, &params, encoder_bits)?;
                }
                Ok(PlantSetup::DiffDrive {
                    params,
                    encoder_counts_per_rev,
                    encoder_bits,
                    pwm_max_duty,
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
                let spacing_m = positive("position.spacing_m", spacing_m)?;
                finite("position.offset_m", offset_m[0])?;
                finite("position.offset_m", offset_m[1])?;
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
                baud,
                repeat_interval_s,
                corrupt_byte_probability,
                drop_frame_probability,
                seed,
            } => {
                let floor = floor(spacing_m, offset_m, margin_m, extent_m)?;
                let mode = match mode {
                    ReaderModeSpec::Paper => ReaderMode::Paper,
                    ReaderModeSpec::Range => ReaderMode::Range {
                        read_radius_m: positive("position.read_radius_m", read_radius_m)?,
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
                    },
                ))
            }
        }
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
            .map_err(|e| ScenarioError::invalid("reference", format!("refused by the core: {e:?}")))
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
                h1_m: f(positive("reference.h1_m", h1_m)?),
                h2_rad_s: f(positive("reference.h2_rad_s", h2_rad_s)?),
                phase_rad: f(finite("reference.phase_rad", phase_rad)?),
            },
            Self::Circle {
                center_m,
                radius_m,
                rate_rad_s,
                phase_rad,
            } => {
                let rate = finite("reference.rate_rad_s", rate_rad_s)?;
                if rate == 0.0 {
                    return Err(ScenarioError::invalid(
                        "reference.rate_rad_s",
                        "must not be 0",
                    ));
                }
                TrajectorySpec::Circle {
                    center_m: [
                        f(finite("reference.center_m", center_m[0])?),
                        f(finite("reference.center_m", center_m[1])?),
                    ],
                    radius_m: f(positive("reference.radius_m", radius_m)?),
                    rate_rad_s: f(rate),
                    phase_rad: f(finite("reference.phase_rad", phase_rad)?),
                }
            }
            Self::Line {
                start_m,
                heading_rad,
                speed_m_s,
            } => TrajectorySpec::Line {
                start_m: [
                    f(finite("reference.start_m", start_m[0])?),
                    f(finite("reference.start_m", start_m[1])?),
                ],
                heading_rad: f(finite("reference.heading_rad", heading_rad)?),
                speed_m_s: f(positive("reference.speed_m_s", speed_m_s)?),
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

#[cfg(test)]
mod tests {
    use super::*;

    const MINIMAL: &str = r#"
        name = "t"
        duration_s = 10.0
        [reference]
        kind = "figure_eight"
    "#;

    fn err_of(text: &str) -> ScenarioError {
        Scenario::from_toml_str(text).unwrap_err()
    }

    #[test]
    fn embedded_scenarios_parse_and_validate() {
        assert_eq!(EMBEDDED.len(), 6);
        for (name, text) in EMBEDDED {
            let s = Scenario::from_toml_str(text).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(&s.name, name);
            // Round trip through TOML.
            let again = Scenario::from_toml_str(&s.to_toml_string().unwrap()).unwrap();
            assert_eq!(again, s);
        }
        assert_eq!(Scenario::default_scenario().name, "figure_eight_rfid");
        assert!(embedded_source("figure_eight_exact.toml").is_some());
        assert_eq!(
            Scenario::embedded("nope").unwrap_err().field(),
            Some("name")
        );
    }

    #[test]
    fn minimal_scenario_takes_the_paper_defaults() {
        let s = Scenario::from_toml_str(MINIMAL).unwrap();
        let setup = s.validate().unwrap();
        assert_eq!(setup.ticks, 1000);
        assert_eq!(s.controller.k1, 0.11);
        assert_eq!(s.observer.gain_per_m, 0.6);
        assert_eq!(setup.position, PositionSetup::Exact);
        assert_eq!(setup.plant, PlantSetup::Unicycle);
        let p = setup.trajectory.sample(0.0).position;
        assert!(p.x.abs() < 1e-5 && (p.y + 5.0).abs() < 1e-5);
        assert_eq!(setup.tracker.fix_timeout_ticks(), 50);
    }

    #[test]
    fn unknown_keys_are_refused_with_their_name() {
        let e = err_of(&format!("{MINIMAL}\nperiod_ms = 10\n")).to_string();
        assert!(e.contains("period_ms"), "{e}");
        let e =
            err_of(&MINIMAL.replace("kind = \"figure_eight\"", "kind = \"figure_eight\"\nh1 = 3"))
                .to_string();
        assert!(e.contains("h1"), "{e}");
        let e = err_of(&format!(
            "{MINIMAL}\n[plant]\nkind = \"diff_drive\"\nradius_m = 0.1\n"
        ))
        .to_string();
        assert!(e.contains("radius_m"), "{e}");
        let e = err_of(&MINIMAL.replace("figure_eight", "spiral")).to_string();
        assert!(e.contains("spiral"), "{e}");
        let e = err_of("name = \"x\"\n[reference]\nkind = \"figure_eight\"\n").to_string();
        assert!(e.contains("duration_s"), "{e}");
    }

    #[test]
    fn bad_values_name_their_field() {
        let cases = [
            ("[observer]\ngain_per_m = -1.0", "observer.gain_per_m"),
            ("[observer]\nmin_speed_m_s = -1.0", "observer.min_speed_m_s"),
            ("[controller]\nk3 = 0.0", "controller.k3"),
            (
                "[plant]\nkind = \"diff_drive\"\nwheel_radius_m = 0.0",
                "plant.wheel_radius_m",
            ),
            (
                "[plant]\nkind = \"diff_drive\"\nencoder_bits = 40",
                "plant.encoder_bits",
            ),
            ("[drive]\nkp_duty_per_rad_s = 0.1", "drive"),
            (
                "[plant]\nkind = \"diff_drive\"\n[drive]\nmax_wheel_speed_rad_s = 0.0",
                "drive.max_wheel_speed_rad_s",
            ),
            (
                "[position]\nkind = \"nearest_tag\"\nspacing_m = 0.0",
                "position.spacing_m",
            ),
            (
                "[position]\nkind = \"nearest_tag\"\nspacing_m = 1e-5",
                "position.extent_m",
            ),
            ("[position]\nkind = \"reader\"\nbaud = 0", "position.baud"),
            (
                "[position]\nkind = \"reader\"\ndrop_frame_probability = 1.5",
                "position.drop_frame_probability",
            ),
            (
                "[position]\nkind = \"reader\"\n[controller]\nkind = \"state_feedback\"",
                "position.kind",
            ),
            (
                "[plant]\nkind = \"diff_drive\"\n[controller]\nkind = \"state_feedback\"",
                "controller.kind",
            ),
            ("[failsafe]\nfix_timeout_s = 0.0", "failsafe.fix_timeout_s"),
            ("[failsafe]\ndecel_m_s2 = -2.0", "failsafe.decel_m_s2"),
            ("[initial]\nx_m = nan", "initial.x_m"),
            (
                "[initial]\nestimate_cos = 1.0\n[plant]\nkind = \"diff_drive\"",
                "initial.estimate_cos",
            ),
            (
                "[measurement]\nnoise_std_m = -0.1",
                "measurement.noise_std_m",
            ),
            (
                "[measurement]\nmiss_probability = 1.5",
                "measurement.miss_probability",
            ),
            (
                "[position]\nkind = \"reader\"\n[measurement]\nnoise_std_m = 0.01",
                "measurement.noise_std_m",
            ),
            (
                "[controller]\nkind = \"state_feedback\"\n[measurement]\nmiss_probability = 0.1",
                "measurement.miss_probability",
            ),
            ("transient_s = 20.0", "transient_s"),
            ("period_s = -0.01", "period_s"),
        ];
        for (extra, field) in cases {
            // Top-level keys must come before the tables.
            let text = if extra.starts_with('[') {
                format!("{MINIMAL}\n{extra}\n")
            } else {
                format!("{extra}\n{MINIMAL}")
            };
            let e = err_of(&text);
            assert_eq!(e.field(), Some(field), "{extra}: {e}");
            assert!(e.to_string().contains(field));
        }
        let e = err_of(&MINIMAL.replace(
            "kind = \"figure_eight\"",
            "kind = \"figure_eight\"\nh2_rad_s = -0.1",
        ));
        assert_eq!(e.field(), Some("reference.h2_rad_s"));
    }

    const DIFF_DRIVE: &str = "[plant]\nkind = \"diff_drive\"\n";
    const DYNAMICS: &str = "[plant.dynamics]\nmass_kg = 4.0\nyaw_inertia_kg_m2 = 0.08\n\
                            stall_torque_nm = 0.6\n";

    fn dynamics_of(setup: &Setup) -> Option<WheelDynamics> {
        match setup.plant {
            PlantSetup::DiffDrive { params, .. } => params.dynamics,
            PlantSetup::Unicycle => panic!("diff_drive expected"),
        }
    }

    #[test]
    fn plant_dynamics_table_gives_the_wheel_dynamics() {
        // Absent: the first-order wheels, as before.
        let s = Scenario::from_toml_str(&format!("{MINIMAL}\n{DIFF_DRIVE}")).unwrap();
        assert_eq!(dynamics_of(&s.validate().unwrap()), None);
        let full = Scenario::embedded("figure_eight_rfid_full_stack").unwrap();
        assert_eq!(dynamics_of(&full.validate().unwrap()), None);
        assert!(!full.to_toml_string().unwrap().contains("dynamics"));

        // The required keys only: the others default to 0 (no load).
        let s = Scenario::from_toml_str(&format!("{MINIMAL}\n{DIFF_DRIVE}{DYNAMICS}")).unwrap();
        let expected = WheelDynamics {
            mass_kg: 4.0,
            yaw_inertia_kg_m2: 0.08,
            wheel_inertia_kg_m2: 0.0,
            viscous_friction_nm_s_per_rad: 0.0,
            stall_torque_nm: 0.6,
            load: LoadTorque::NONE,
        };
        assert_eq!(dynamics_of(&s.validate().unwrap()), Some(expected));

        // Every key.
        let text = format!(
            "{MINIMAL}\n{DIFF_DRIVE}{DYNAMICS}wheel_inertia_kg_m2 = 2e-4\n\
             viscous_friction_nm_s_per_rad = 0.01\nload_start_s = 30.0\nload_ramp_s = 2.5\n\
             load_grade_percent = -5.0\n"
        );
        let s = Scenario::from_toml_str(&text).unwrap();
        let setup = s.validate().unwrap();
        assert_eq!(
            dynamics_of(&setup),
            Some(WheelDynamics {
                wheel_inertia_kg_m2: 2e-4,
                viscous_friction_nm_s_per_rad: 0.01,
                load: LoadTorque {
                    start_s: 30.0,
                    ramp_s: 2.5,
                    grade_percent: -5.0,
                },
                ..expected
            })
        );
        // The rest of the plant is untouched.
        let PlantSetup::DiffDrive { params, .. } = setup.plant else {
            panic!("diff_drive expected");
        };
        assert_eq!(
            DiffDriveParams {
                dynamics: None,
                ..params
            },
            DiffDriveParams::default()
        );
        // Round trip through TOML.
        let again = Scenario::from_toml_str(&s.to_toml_string().unwrap()).unwrap();
        assert_eq!(again, s);
    }

    #[test]
    fn bad_plant_dynamics_keys_name_their_field() {
        let cases = [
            ("mass_kg = 0.0", "mass_kg"),
            ("mass_kg = -4.0", "mass_kg"),
            ("yaw_inertia_kg_m2 = 0.0", "yaw_inertia_kg_m2"),
            ("yaw_inertia_kg_m2 = inf", "yaw_inertia_kg_m2"),
            ("wheel_inertia_kg_m2 = -1e-4", "wheel_inertia_kg_m2"),
            ("wheel_inertia_kg_m2 = nan", "wheel_inertia_kg_m2"),
            (
                "viscous_friction_nm_s_per_rad = -0.01",
                "viscous_friction_nm_s_per_rad",
            ),
            ("stall_torque_nm = 0.0", "stall_torque_nm"),
            ("stall_torque_nm = nan", "stall_torque_nm"),
            ("load_start_s = -1.0", "load_start_s"),
            ("load_ramp_s = -0.5", "load_ramp_s"),
            ("load_ramp_s = inf", "load_ramp_s"),
            ("load_grade_percent = 100.0", "load_grade_percent"),
            ("load_grade_percent = -100.0", "load_grade_percent"),
            ("load_grade_percent = nan", "load_grade_percent"),
        ];
        for (line, key) in cases {
            // TOML refuses a key given twice: drop the table's own line.
            let name = line.split(' ').next().unwrap();
            let table: String = DYNAMICS
                .lines()
                .filter(|l| !l.starts_with(name))
                .map(|l| format!("{l}\n"))
                .collect();
            let text = format!("{MINIMAL}\n{DIFF_DRIVE}{table}{line}\n");
            let e = err_of(&text);
            let field = format!("plant.dynamics.{key}");
            assert_eq!(e.field(), Some(field.as_str()), "{line}: {e}");
            assert!(e.to_string().contains(&field), "{e}");
        }
        // The extremes inside the range are accepted.
        for grade in ["99.9", "-99.9"] {
            let text = format!("{MINIMAL}\n{DIFF_DRIVE}{DYNAMICS}load_grade_percent = {grade}\n");
            assert!(Scenario::from_toml_str(&text).is_ok(), "{grade}");
        }
    }

    #[test]
    fn speed_observer_table_is_validated_and_refused_for_hil() {
        let table = "[drive.speed_observer]\nmass_kg = 4.0\nyaw_inertia_kg_m2 = 0.08\n";
        let ok = format!("{MINIMAL}\n{DIFF_DRIVE}{DYNAMICS}{table}stall_torque_nm = 0.6\n");
        let setup = Scenario::from_toml_str(&ok).unwrap().validate().unwrap();
        let PlantSetup::DiffDrive { pilot, .. } = setup.plant else {
            panic!("diff drive");
        };
        assert!(pilot.drive().speed_observer().is_some());
        // The link does not carry it: a HIL run is refused, not run without it.
        let mut full = Scenario::embedded("figure_eight_rfid_full_stack").unwrap();
        assert!(crate::run::hil_configuration(&full.validate().unwrap()).is_ok());
        let mut drive = full.drive.unwrap_or_default();
        drive.speed_observer = Some(SpeedObserverSpec {
            mass_kg: 4.0,
            yaw_inertia_kg_m2: 0.08,
            wheel_inertia_kg_m2: 0.0,
            stall_torque_nm: 0.6,
            lambda_per_s: 5.0,
            friction_gain: 0.01,
            disturbance_gain: 0.1,
        });
        full.drive = Some(drive);
        let e = crate::run::hil_configuration(&full.validate().unwrap()).unwrap_err();
        assert!(e.to_string().contains("speed_observer"), "{e}");
        for (line, key) in [
            ("stall_torque_nm = 0.0", "stall_torque_nm"),
            ("stall_torque_nm = 0.6\nlambda_per_s = -1.0", "lambda_per_s"),
            (
                "stall_torque_nm = 0.6\nfriction_gain = nan",
                "friction_gain",
            ),
            (
                "stall_torque_nm = 0.6\ndisturbance_gain = 0.0",
                "disturbance_gain",
            ),
        ] {
            let text = format!("{MINIMAL}\n{DIFF_DRIVE}{DYNAMICS}{table}{line}\n");
            let e = err_of(&text);
            let field = format!("drive.speed_observer.{key}");
            assert_eq!(e.field(), Some(field.as_str()), "{line}: {e}");
        }
    }

    #[test]
    fn plant_dynamics_table_is_refused_where_it_does_not_belong() {
        // With the unicycle (explicit kind).
        let text = format!("{MINIMAL}\n[plant]\nkind = \"unicycle\"\n{DYNAMICS}");
        let e = err_of(&text);
        assert!(matches!(e, ScenarioError::Parse(_)), "{e:?}");
        assert!(e.to_string().contains("plant.dynamics"), "{e}");
        assert!(e.to_string().contains("diff_drive"), "{e}");
        // Without a plant kind.
        let e = err_of(&format!("{MINIMAL}\n{DYNAMICS}")).to_string();
        assert!(e.contains("kind"), "{e}");
        // Unknown or missing keys in the table.
        let e = err_of(&format!(
            "{MINIMAL}\n{DIFF_DRIVE}{DYNAMICS}mass_g = 4000.0\n"
        ))
        .to_string();
        assert!(e.contains("mass_g"), "{e}");
        let e = err_of(&format!(
            "{MINIMAL}\n{DIFF_DRIVE}[plant.dynamics]\nmass_kg = 4.0\nyaw_inertia_kg_m2 = 0.08\n"
        ))
        .to_string();
        assert!(e.contains("stall_torque_nm"), "{e}");
        // The unicycle still parses as before, with or without its table.
        let s =
            Scenario::from_toml_str(&format!("{MINIMAL}\n[plant]\nkind = \"unicycle\"\n")).unwrap();
        assert_eq!(s.plant, PlantSpec::Unicycle);
    }

    #[test]
    fn floor_covers_the_reference_and_the_start() {
        let text = format!(
            "{MINIMAL}\n[initial]\ny_m = -6.0\n[position]\nkind = \"nearest_tag\"\nmargin_m = 0.5\n"
        );
        let setup = Scenario::from_toml_str(&text).unwrap().validate().unwrap();
        let PositionSetup::NearestTag(floor) = setup.position else {
            panic!("nearest tag expected");
        };
        let (lo, hi) = floor.bounds();
        // The start (0, −6) with its margin, and the reference's start (0, −5).
        assert!(lo[1] <= -6.5 + 1e-9 && hi[1] >= -4.5, "{lo:?} {hi:?}");
    }
}
