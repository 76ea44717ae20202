//! The tables a scenario file holds, which a robot file shares: the serde
//! types of `[reference]`, `[initial]`, `[controller]`, `[observer]`,
//! `[plant]`, `[drive]`, `[position]`, `[failsafe]`, `[measurement]`,
//! `[telemetry]` and `[[floor_tags]]`, with their units in the key names,
//! their defaults (see `defaults`) and the plausible range of the core's
//! quantities. Checking the values is `validate`'s job.

use serde::{Deserialize, Serialize};
use wmr_core::control::spec::LawSpec;
use wmr_core::plausible;

use super::defaults;

/// The firmware's telemetry record stream (`[telemetry]`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TelemetrySpec {
    /// A telemetry record every this many control ticks, 1 to 65535 (the
    /// Black Pill's default, `TELEMETRY_EVERY_TICKS`: 10, 10 Hz at 10 ms).
    #[serde(default = "defaults::telemetry_every_ticks")]
    #[schemars(range(min = 1, max = 65535))]
    pub every_ticks: u64,
}

impl Default for TelemetrySpec {
    fn default() -> Self {
        Self {
            every_ticks: defaults::telemetry_every_ticks(),
        }
    }
}

impl TelemetrySpec {
    /// The decimation, checked: 1 to 65535 (the link's and the image's
    /// `u16`; 0 would be no telemetry).
    ///
    /// # Errors
    /// [`super::ScenarioError::Invalid`] naming `telemetry.every_ticks`.
    pub fn every_ticks(&self) -> Result<u16, super::ScenarioError> {
        u16::try_from(self.every_ticks)
            .ok()
            .filter(|n| *n >= 1)
            .ok_or_else(|| {
                super::ScenarioError::invalid(
                    "telemetry.every_ticks",
                    format!("must be 1 to 65535 ticks (got {})", self.every_ticks),
                )
            })
    }
}

/// One tag of a tag-map floor (`[[floor_tags]]`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FloorTagSpec {
    /// The id the reader reports (40 bits).
    pub id: u64,
    /// Position, m.
    pub x_m: f64,
    /// Position, m.
    pub y_m: f64,
}

/// Initial pose of the robot and of the observer's estimate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default, schemars::JsonSchema)]
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
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default, schemars::JsonSchema,
)]
#[serde(rename_all = "snake_case")]
pub enum ControllerKind {
    /// Observer (5) + law (27)–(28): position only (paper 001, Theorem 3).
    #[default]
    OutputFeedback,
    /// Law (14) with the true heading (paper 001, Theorem 2).
    StateFeedback,
}

/// Tracking law and gains.
///
/// (De)serialized by hand around the derived code (`remote = "Self"`), to
/// name the new key of a key that moved (see `legacy`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(remote = "Self", deny_unknown_fields)]
pub struct ControllerSpec {
    /// Which law.
    #[serde(default)]
    pub kind: ControllerKind,
    /// With `kind = "output_feedback"`: which position-only law, the core's
    /// own [`LawSpec`] (`law = "saturated"`, the default, also spelled
    /// `"paper_001"`; `[controller.law.cascaded]`;
    /// `[controller.law.heading_error_sine]`).
    #[serde(default)]
    pub law: LawSpec,
    /// `k1`, m/s.
    #[serde(default = "defaults::k12")]
    #[schemars(range(min = plausible::GAIN.min, max = plausible::GAIN.max))]
    pub k1: f64,
    /// `k2`, m/s.
    #[serde(default = "defaults::k12")]
    #[schemars(range(min = plausible::GAIN.min, max = plausible::GAIN.max))]
    pub k2: f64,
    /// `k3`, 1/s.
    #[serde(default = "defaults::k3")]
    #[schemars(range(min = plausible::GAIN.min, max = plausible::GAIN.max))]
    pub k3: f64,
}

impl Default for ControllerSpec {
    fn default() -> Self {
        Self {
            kind: ControllerKind::default(),
            law: LawSpec::default(),
            k1: defaults::k12(),
            k2: defaults::k12(),
            k3: defaults::k3(),
        }
    }
}

impl Serialize for ControllerSpec {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        // The derived serializer (inherent, from `remote = "Self"`).
        ControllerSpec::serialize(self, serializer)
    }
}

impl<'de> Deserialize<'de> for ControllerSpec {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        checked_table(
            deserializer,
            "controller",
            super::legacy::controller_key,
            ControllerSpec::deserialize,
        )
    }
}

/// The table `section` through its derived deserializer (inherent, from
/// `remote = "Self"`), unless `refuse` finds a reason in the raw table
/// first. An error inside names its key (`position.spacing_m`): the table
/// reaches the derived code as a value, without the positions that let the
/// TOML parser point at a key, and a tagged enum's fields are read from a
/// buffer that no path tracking sees; so the key is the first whose
/// removal changes the error.
fn checked_table<'de, D: serde::Deserializer<'de>, T>(
    deserializer: D,
    section: &str,
    refuse: impl Fn(&toml::Table) -> Option<String>,
    derived: impl Fn(toml::Value) -> Result<T, toml::de::Error>,
) -> Result<T, D::Error> {
    use serde::de::Error as _;
    let table = toml::Table::deserialize(deserializer)?;
    if let Some(reason) = refuse(&table) {
        return Err(D::Error::custom(reason));
    }
    // The derived deserializer's error text ends in a newline the outer
    // error adds again.
    let reason = |e: toml::de::Error| e.to_string().trim_end().to_owned();
    let error = match derived(toml::Value::Table(table.clone())) {
        Ok(value) => return Ok(value),
        Err(e) => reason(e),
    };
    let culprit = table.keys().filter(|key| *key != "kind").find(|key| {
        let mut without = table.clone();
        without.remove(*key);
        derived(toml::Value::Table(without)).map_or_else(|e| reason(e) != error, |_| true)
    });
    Err(D::Error::custom(match culprit {
        Some(key) => format!("`{section}.{key}`: {error}"),
        None => error,
    }))
}

/// Paper 001's heading observer (5).
///
/// (De)serialized by hand around the derived code (`remote = "Self"`), to
/// name the new key of a key that moved to `[estimator]` (see `legacy`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(remote = "Self", deny_unknown_fields)]
pub struct ObserverSpec {
    /// Observer gain `L`, 1/m.
    #[serde(default = "defaults::gain_per_m")]
    #[schemars(range(min = plausible::GAIN.min, max = plausible::GAIN.max))]
    pub gain_per_m: f64,
    /// Speed below which position changes are ignored, m/s.
    #[serde(default = "defaults::min_speed_m_s")]
    #[schemars(range(min = plausible::MIN_SPEED_M_S.min, max = plausible::MIN_SPEED_M_S.max))]
    pub min_speed_m_s: f64,
}

impl Default for ObserverSpec {
    fn default() -> Self {
        Self {
            gain_per_m: defaults::gain_per_m(),
            min_speed_m_s: defaults::min_speed_m_s(),
        }
    }
}

impl Serialize for ObserverSpec {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        // The derived serializer (inherent, from `remote = "Self"`).
        ObserverSpec::serialize(self, serializer)
    }
}

impl<'de> Deserialize<'de> for ObserverSpec {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        checked_table(
            deserializer,
            "observer",
            super::legacy::observer_key,
            ObserverSpec::deserialize,
        )
    }
}

/// The simulated robot body.
///
/// (De)serialized by hand around the derived code (`remote = "Self"`
/// makes the derives inherent `PlantSpec::serialize`/`deserialize`): serde
/// ignores keys beside a unit variant's tag, so a `[plant.dynamics]` table
/// under `kind = "unicycle"` would otherwise vanish silently.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(
    remote = "Self",
    tag = "kind",
    rename_all = "snake_case",
    deny_unknown_fields
)]
pub enum PlantSpec {
    /// Paper 001's kinematic unicycle (1): commands are velocities (what
    /// its odometry reports). The core's tracker (or controller) is called
    /// directly.
    Unicycle {
        /// Wheels that slip and are mis-scaled (`[plant.wheels]`); absent:
        /// the body moves exactly as commanded.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        wheels: Option<WheelErrorSpec>,
    },
    /// Two DC motors, PWM drivers, quadrature encoders: runs the core's
    /// `Robot` (or `Pilot`) against virtual devices.
    DiffDrive {
        /// Wheel radius, m.
        #[serde(default = "defaults::wheel_radius_m")]
        #[schemars(range(min = plausible::WHEEL_RADIUS_M.min, max = plausible::WHEEL_RADIUS_M.max))]
        wheel_radius_m: f64,
        /// Track width, m.
        #[serde(default = "defaults::track_width_m")]
        #[schemars(range(min = plausible::TRACK_WIDTH_M.min, max = plausible::TRACK_WIDTH_M.max))]
        track_width_m: f64,
        /// Motor + wheel time constant `τ`, s.
        #[serde(default = "defaults::motor_time_constant_s")]
        motor_time_constant_s: f64,
        /// Wheel speed at full duty, rad/s.
        #[serde(default = "defaults::wheel_speed_at_full_duty_rad_s")]
        wheel_speed_at_full_duty_rad_s: f64,
        /// Quadrature counts per wheel revolution.
        #[serde(default = "defaults::encoder_counts_per_rev")]
        #[schemars(range(min = 1, max = 16_777_216))]
        encoder_counts_per_rev: u32,
        /// Width of the hardware encoder counters, bits.
        #[serde(default = "defaults::encoder_bits")]
        #[schemars(range(min = 2, max = 32))]
        encoder_bits: u32,
        /// PWM full-scale duty, steps.
        #[serde(default = "defaults::pwm_max_duty")]
        #[schemars(range(min = 1))]
        pwm_max_duty: u16,
        /// RK4 substeps per control period.
        #[serde(default = "defaults::substeps")]
        #[schemars(range(min = 1))]
        substeps: u32,
        /// Rigid-body wheel dynamics (`[plant.dynamics]`); absent: each
        /// wheel is the first-order system of `motor_time_constant_s`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        dynamics: Option<DynamicsSpec>,
        /// Spurious encoder edges (`[plant.encoder_glitches]`); absent:
        /// clean encoder lines.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        encoder_glitches: Option<EncoderGlitchSpec>,
        /// Wheels that slip and are mis-scaled (`[plant.wheels]`); absent:
        /// the body moves as its wheels turn.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        wheels: Option<WheelErrorSpec>,
    },
}

impl Default for PlantSpec {
    fn default() -> Self {
        Self::Unicycle { wheels: None }
    }
}

/// Realistic wheels, the `[plant.wheels]` table (either plant): each
/// wheel's travel on the ground is `(1 + e)` times what its rotation
/// measured (what the odometry sees), plus a zero-mean Gaussian slip noise
/// whose variance grows with the distance rolled
/// ([`WheelErrors`](crate::plant::WheelErrors)). The noise is drawn from
/// the run's `measurement.seed` (on a stream of its own), so a sweep
/// varies it with each run's seed.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct WheelErrorSpec {
    /// Each wheel's slip-noise variance per metre it rolls, m²/m (in
    /// [0, 1]; 0: no noise). Compare the fusion filter's
    /// `estimator.fusion.wheel_variance_per_m`.
    #[serde(default)]
    #[schemars(range(min = 0.0, max = 1.0))]
    pub travel_variance_m2_per_m: f64,
    /// `[right, left]`: each wheel's scale error `e` (ground travel = `1 +
    /// e` times measured travel; each in [−0.5, 0.5]; 0: true scale).
    #[serde(default)]
    pub scale_error: [f64; 2],
}

/// Spurious edges on the encoder lines, the `[plant.encoder_glitches]`
/// table: on a read, with `probability_per_read`, a burst of `min_counts`
/// to `max_counts` extra counts (up or down, uniformly) lands in that
/// encoder's counter and stays there. The core rejects a burst larger than
/// twice the drive's top wheel speed allows in a tick (counted in
/// `pilot.implausible_encoder_reads`); a smaller one is odometry error (what
/// a timer's input filter is for).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct EncoderGlitchSpec {
    /// Probability of a burst, per read of one encoder (one read a tick).
    pub probability_per_read: f64,
    /// Smallest burst, counts (default 1).
    #[serde(default = "defaults::glitch_min_counts")]
    #[schemars(range(min = 1))]
    pub min_counts: u32,
    /// Largest burst, counts.
    #[schemars(range(min = 1))]
    pub max_counts: u32,
    /// RNG seed (left encoder; the right uses `seed + 1`).
    #[serde(default = "defaults::seed")]
    pub seed: u64,
}

impl Serialize for PlantSpec {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        // The derived serializer (inherent, from `remote = "Self"`).
        PlantSpec::serialize(self, serializer)
    }
}

impl<'de> Deserialize<'de> for PlantSpec {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let unicycle_dynamics = |table: &toml::Table| {
            (table.get("kind").and_then(toml::Value::as_str) == Some("unicycle")
                && table.contains_key("dynamics"))
            .then(|| {
                "`plant.dynamics` is only used with kind = \"diff_drive\" (the unicycle's \
                 commands are its velocities); remove the [plant.dynamics] table"
                    .to_string()
            })
        };
        // The unicycle takes `wheels` only; any other key is named.
        let unicycle_keys = |table: &toml::Table| {
            let keys = table
                .keys()
                .map(String::as_str)
                .filter(|key| *key != "wheels");
            only_kind_of(
                table.get("kind").and_then(toml::Value::as_str),
                keys,
                "plant",
                "unicycle",
            )
            .map(|m| m.replace("which takes no other key", "which takes only `wheels`"))
        };
        checked_table(
            deserializer,
            "plant",
            |table| unicycle_dynamics(table).or_else(|| unicycle_keys(table)),
            PlantSpec::deserialize,
        )
    }
}

/// A refusal of any of `keys` but `kind` in the table `section` when its
/// kind is `kind`, a variant without (other) keys: serde's tagged enums
/// pass over a unit variant's other keys, which would otherwise be
/// ignored in silence.
pub(super) fn only_kind_of<'a>(
    table_kind: Option<&str>,
    mut keys: impl Iterator<Item = &'a str>,
    section: &str,
    kind: &str,
) -> Option<String> {
    if table_kind != Some(kind) {
        return None;
    }
    keys.find(|key| *key != "kind").map(|key| {
        format!(
            "`{section}.{key}` does not apply to {section}.kind = \"{kind}\", which takes no \
             other key: remove it (`firmware-sim schema` says which keys each kind takes)"
        )
    })
}

/// Rigid-body wheel dynamics of the `diff_drive` plant, the
/// `[plant.dynamics]` table (see
/// [`WheelDynamics`](crate::plant::WheelDynamics)): the wheels carry the
/// robot's mass and yaw inertia, each motor gives `stall_torque_nm` at
/// full duty and zero speed less its back-EMF (no-load speed
/// `plant.wheel_speed_at_full_duty_rad_s`), and a slope load may start at
/// `load_start_s`. `plant.motor_time_constant_s` is then unused.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
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

/// Drive limits and per-wheel speed loops (`diff_drive` plant only): the
/// keys of the core's `wmr_core::drive::spec::DriveSpec` less the facts the
/// plant table states once (wheel radius, track, counts per revolution),
/// in `f64` so that each is checked and named before it becomes the
/// core's `f32` (a test holds the two to the same keys).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct DriveSpec {
    /// Wheel speed limit, rad/s.
    #[serde(default = "defaults::max_wheel_speed_rad_s")]
    #[schemars(range(min = plausible::WHEEL_SPEED_RAD_S.min, max = plausible::WHEEL_SPEED_RAD_S.max))]
    pub max_wheel_speed_rad_s: f64,
    /// Wheel acceleration limit, rad/s².
    #[serde(default = "defaults::max_wheel_accel_rad_s2")]
    #[schemars(range(min = plausible::WHEEL_ACCEL_RAD_S2.min, max = plausible::WHEEL_ACCEL_RAD_S2.max))]
    pub max_wheel_accel_rad_s2: f64,
    /// Feed-forward, duty per rad/s (default: 1 / wheel speed at full duty).
    #[serde(default)]
    #[schemars(range(min = plausible::SPEED_LOOP_GAIN.min, max = plausible::SPEED_LOOP_GAIN.max))]
    pub feedforward_duty_per_rad_s: Option<f64>,
    /// Proportional gain, duty per rad/s.
    #[serde(default = "defaults::kp_duty_per_rad_s")]
    #[schemars(range(min = plausible::SPEED_LOOP_GAIN.min, max = plausible::SPEED_LOOP_GAIN.max))]
    pub kp_duty_per_rad_s: f64,
    /// Integral gain, duty per rad.
    #[serde(default = "defaults::ki_duty_per_rad")]
    #[schemars(range(min = plausible::SPEED_LOOP_GAIN.min, max = plausible::SPEED_LOOP_GAIN.max))]
    pub ki_duty_per_rad: f64,
    /// Run the speed loops on paper 003's wheel-speed observer instead of
    /// the counts differenced over a tick (`[drive.speed_observer]`).
    #[serde(default)]
    pub speed_observer: Option<SpeedObserverSpec>,
}

/// The robot as the wheel-speed observer models it (paper 003, section
/// 6.1; see `wmr_core::drive::speed_observer`): the keys of the core's
/// `wmr_core::drive::spec::SpeedObserverSpec` less the motors' no-load
/// speed. The wheel radius, track and
/// the motors' no-load speed (`plant.wheel_speed_at_full_duty_rad_s`) come
/// from the plant table; these may differ from `[plant.dynamics]` to study
/// a mismatched model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SpeedObserverSpec {
    /// Robot mass, kg.
    #[schemars(range(min = plausible::MASS_KG.min, max = plausible::MASS_KG.max))]
    pub mass_kg: f64,
    /// Yaw inertia about the axle midpoint, kg m².
    #[schemars(range(min = plausible::YAW_INERTIA_KG_M2.min, max = plausible::YAW_INERTIA_KG_M2.max))]
    pub yaw_inertia_kg_m2: f64,
    /// Each wheel's drive-train inertia at the wheel, kg m² (default 0).
    #[serde(default)]
    #[schemars(range(min = plausible::WHEEL_INERTIA_KG_M2.min, max = plausible::WHEEL_INERTIA_KG_M2.max))]
    pub wheel_inertia_kg_m2: f64,
    /// Motor torque at the wheel at full duty and standstill, N·m.
    #[schemars(range(min = plausible::TORQUE_NM.min, max = plausible::TORQUE_NM.max))]
    pub stall_torque_nm: f64,
    /// `λ`, 1/s (default 5).
    #[serde(default = "defaults::observer_lambda_per_s")]
    #[schemars(range(min = plausible::GAIN.min, max = plausible::GAIN.max))]
    pub lambda_per_s: f64,
    /// Damping adaptation gain `γ_r` (default 0.01).
    #[serde(default = "defaults::observer_friction_gain")]
    #[schemars(range(min = plausible::GAIN.min, max = plausible::GAIN.max))]
    pub friction_gain: f64,
    /// Load adaptation gain `γ_d` (default 0.1).
    #[serde(default = "defaults::observer_disturbance_gain")]
    #[schemars(range(min = plausible::GAIN.min, max = plausible::GAIN.max))]
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
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default, schemars::JsonSchema,
)]
#[serde(rename_all = "snake_case")]
pub enum ReaderModeSpec {
    /// The nearest tag, every tick (paper 001, section 6.3.2).
    #[default]
    Paper,
    /// Tags within `read_radius_m`, on entry and every `repeat_interval_s`.
    Range,
}

/// Where the position measurement comes from. A key under `kind =
/// "exact"`, which serde's tagged enum would pass over, is refused by the
/// scenario's parser (on the file's keys).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default, schemars::JsonSchema)]
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
        #[schemars(range(min = plausible::TAG_SPACING_M.min, max = plausible::TAG_SPACING_M.max))]
        spacing_m: f64,
        /// A lattice point `[x, y]`, m.
        #[serde(default)]
        offset_m: [f64; 2],
        /// Margin around the reference and start when `extent_m` is not given, m.
        #[serde(default = "defaults::margin_m")]
        margin_m: f64,
        /// Covered rectangle `[x_min, y_min, x_max, y_max]`, m (default: automatic). The
        /// floor is at most 65,535 rows and 65,535 columns of tags (the grid id's
        /// 16-bit row and column); a larger one is refused.
        #[serde(default)]
        extent_m: Option<[f64; 4]>,
    },
    /// Frames from a virtual RFID reader over a virtual UART, parsed by the
    /// core's reader and looked up in the core's tag grid.
    Reader {
        /// Tag spacing, m.
        #[serde(default = "defaults::spacing_m")]
        #[schemars(range(min = plausible::TAG_SPACING_M.min, max = plausible::TAG_SPACING_M.max))]
        spacing_m: f64,
        /// A lattice point `[x, y]`, m.
        #[serde(default)]
        offset_m: [f64; 2],
        /// Margin around the reference and start when `extent_m` is not given, m.
        #[serde(default = "defaults::margin_m")]
        margin_m: f64,
        /// Covered rectangle `[x_min, y_min, x_max, y_max]`, m (default: automatic). The
        /// floor is at most 65,535 rows and 65,535 columns of tags (the grid id's
        /// 16-bit row and column); a larger one is refused.
        #[serde(default)]
        extent_m: Option<[f64; 4]>,
        /// `paper` (nearest tag every tick) or `range`.
        #[serde(default)]
        mode: ReaderModeSpec,
        /// Read radius around the antenna (`range` mode), m.
        #[serde(default = "defaults::read_radius_m")]
        #[schemars(range(min = plausible::READ_RADIUS_M.min, max = plausible::READ_RADIUS_M.max))]
        read_radius_m: f64,
        /// Antenna ahead of the axle midpoint, m (where the simulated reader
        /// reads; the estimators are told, unless
        /// `antenna_offset_compensated = false`).
        #[serde(default)]
        antenna_offset_m: f64,
        /// Whether the core is told the antenna offset (`tracker.sensors.
        /// antenna_offset_m`) and moves each fix back to the axle midpoint;
        /// `false` shows what ignoring it costs.
        #[serde(default = "defaults::yes")]
        antenna_offset_compensated: bool,
        /// Line speed, baud.
        #[serde(default = "defaults::baud")]
        #[schemars(range(min = 1))]
        baud: u32,
        /// Repeat interval while a tag stays in range (`range` mode), s.
        /// Shorter than the control period, the reader repeats between ticks
        /// too, as fast as the line carries frames.
        #[serde(default = "defaults::repeat_interval_s")]
        repeat_interval_s: f64,
        /// Probability that a byte arrives with a flipped bit (a fault
        /// key: a scenario naming a robot keeps it).
        #[serde(default)]
        corrupt_byte_probability: f64,
        /// Probability that a frame is lost (a fault key: a scenario
        /// naming a robot keeps it).
        #[serde(default)]
        drop_frame_probability: f64,
        /// Seed of the fault RNG (a fault key: a scenario naming a robot
        /// keeps it).
        #[serde(default = "defaults::seed")]
        seed: u64,
    },
}

impl PositionSpec {
    /// `kind = "reader"` with every other key at its default.
    #[must_use]
    pub fn reader_defaults() -> Self {
        Self::Reader {
            spacing_m: defaults::spacing_m(),
            offset_m: [0.0; 2],
            margin_m: defaults::margin_m(),
            extent_m: None,
            mode: ReaderModeSpec::default(),
            read_radius_m: defaults::read_radius_m(),
            antenna_offset_m: 0.0,
            antenna_offset_compensated: defaults::yes(),
            baud: defaults::baud(),
            repeat_interval_s: defaults::repeat_interval_s(),
            corrupt_byte_probability: 0.0,
            drop_frame_probability: 0.0,
            seed: defaults::seed(),
        }
    }
}

/// What the tracker does when fixes stop.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FailsafeSpec {
    /// Time without a valid fix before the failsafe engages, s.
    #[serde(default = "defaults::fix_timeout_s")]
    pub fix_timeout_s: f64,
    /// Failsafe deceleration, m/s².
    #[serde(default = "defaults::decel_m_s2")]
    #[schemars(range(min = plausible::DECEL_M_S2.min, max = plausible::DECEL_M_S2.max))]
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
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
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

    pub(super) fn is_default(&self) -> bool {
        *self == Self::default()
    }
}
