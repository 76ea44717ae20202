//! Scenarios: what to simulate, as TOML, validated into the core's configs.
//!
//! A scenario file names every quantity with its unit (`period_s`, `h1_m`);
//! everything but `name`, `duration_s` and the reference has a default (the
//! paper's section 6.3.2 values where the paper gives one). Unknown keys are
//! errors, and every validation error names the offending field; values the
//! core checks are refused in the core's words:
//!
//! ```text
//! scenario field `observer.gain_per_m`: refused by the core: observer_gain_per_m (L) must be in [0.000001, 10000] 1/m (got 0)
//! scenario field `plant.wheel_radius_m`: must be in [0.001, 2] m (got 0)
//! ```
//!
//! [`Scenario::validate`] turns a scenario into a [`Setup`]: the core's own
//! validated configurations
//! ([`TrackerConfig`](wmr_core::pilot::tracker::TrackerConfig),
//! [`PilotConfig`](wmr_core::pilot::PilotConfig), ...) plus the simulator's
//! plant, floor and reader models.
//!
//! By job, each file using only those above it:
//! * `error`: [`ScenarioError`] and the checks of single values
//!   (`positive`, `non_negative`, ...), which the slip scenarios share;
//! * `defaults`: the default values;
//! * `sweep_spec`: the `[sweep]` table ([`SweepSpec`]) and its validated
//!   [`SweepPlan`];
//! * `legacy`: the keys that moved, and the new key an error names;
//! * `tables`: the serde tables a scenario holds and a robot file shares
//!   (`[plant]`, `[drive]`, `[controller]`, ...); the estimator and the law
//!   are the core's own spec types ([`EstimatorSpec`], [`LawSpec`]), so the
//!   list of both is written once, in the core;
//! * `mavlink`: the `[mavlink]` table ([`mavlink::MavlinkSpec`]), the
//!   robot's MAVLink endpoint and power-on;
//! * `robot_file`: the robot file's schema ([`robot::RobotFile`]) and how a
//!   scenario names its robot ([`robot::RobotSource`]);
//! * `schema`: the scenario's top level ([`Scenario`]);
//! * `robot`: loading a robot file and how a scenario takes its tables
//!   ([`Scenario::resolve_robot`]), the flash image;
//! * `validate`: [`Scenario::validate`] and what it builds ([`Setup`],
//!   [`PlantSetup`], [`PositionSetup`]);
//! * this file: parsing, files and the embedded scenarios ([`EMBEDDED`]).

use std::path::Path;

mod defaults;
mod error;
pub mod keys;
mod legacy;
pub mod mavlink;
pub mod robot;
mod robot_file;
pub mod route;
mod schema;
mod sweep_spec;
mod tables;
mod validate;

#[cfg(test)]
mod tests;

pub use error::ScenarioError;
pub(crate) use error::{non_negative, positive};
pub use route::{ReferenceSpec, RouteSetup, RouteSpec, RouteStartSpec, WaypointSpec};
use schema::GivenKeys;
pub use schema::Scenario;
pub use sweep_spec::{
    DEFAULT_EXACT_THRESHOLD_M, DEFAULT_HOLD_FRACTION, DEFAULT_START_RADIUS_M,
    DEFAULT_THRESHOLD_SPACINGS, EncoderChoices, HeadingSweep, MAX_ENCODER_CHOICES, ObserverStart,
    SweepPlan, SweepSpec,
};
pub use tables::{
    ControllerKind, ControllerSpec, DriveSpec, DynamicsSpec, FailsafeSpec, FloorTagSpec,
    InitialSpec, MeasurementSpec, ObserverSpec, PlantSpec, PositionSpec, ReaderModeSpec,
    SpeedObserverSpec, WheelErrorSpec,
};
pub use validate::{PlantSetup, PositionSetup, Setup, reference_bounds, route_bounds, route_path};
pub use wmr_core::control::spec::LawSpec;
/// The core's estimator and law specs, which the scenario's `[estimator]`
/// table and `controller.law` key deserialize into.
pub use wmr_core::estimation::spec::{EstimatorSpec, FusionFilterSpec, FusionSpec};

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
        "figure_eight_rfid_full_stack_fusion_ekf",
        include_str!("../../scenarios/figure_eight_rfid_full_stack_fusion_ekf.toml"),
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
    ("circle", include_str!("../../scenarios/circle.toml")),
    ("line", include_str!("../../scenarios/line.toml")),
    ("route", include_str!("../../scenarios/route.toml")),
    (
        "warehouse_loop",
        include_str!("../../scenarios/warehouse_loop.toml"),
    ),
];

/// The TOML text of an embedded scenario, by file name (without `.toml`).
#[must_use]
pub fn embedded_source(name: &str) -> Option<&'static str> {
    let name = name.strip_suffix(".toml").unwrap_or(name);
    EMBEDDED.iter().find(|(n, _)| *n == name).map(|(_, s)| *s)
}

/// Reads `path` and parses it with `parse`, naming the file in parse
/// errors (shared by the scenario kinds of this crate).
pub(crate) fn read_file<T>(
    path: &Path,
    parse: impl FnOnce(&str) -> Result<T, ScenarioError>,
) -> Result<T, ScenarioError> {
    let text = std::fs::read_to_string(path)
        .map_err(|source| ScenarioError::io("scenario file", path, source))?;
    parse(&text).map_err(|e| match e {
        ScenarioError::Parse(m) => ScenarioError::Parse(format!("{}: {m}", path.display())),
        other => other,
    })
}

/// The parser's error `e` of the scenario `text`, naming the key when it
/// is inside `[position]`: a tagged enum's fields are read from a buffer,
/// so the parser can only point at the table's header. The key is the
/// first whose removal changes the table's own error.
fn name_position_key(text: &str, e: &toml::de::Error) -> String {
    use serde::Deserialize as _;
    let message = e.to_string();
    let Ok(raw) = text.parse::<toml::Table>() else {
        return message;
    };
    let Some(toml::Value::Table(position)) = raw.get("position") else {
        return message;
    };
    let error_of = |table: &toml::Table| {
        PositionSpec::deserialize(toml::Value::Table(table.clone()))
            .err()
            .map(|e| e.to_string())
    };
    let Some(error) = error_of(position) else {
        return message;
    };
    let culprit = position.keys().filter(|key| *key != "kind").find(|key| {
        let mut without = position.clone();
        without.remove(*key);
        error_of(&without).as_ref() != Some(&error)
    });
    match culprit {
        Some(key) => format!("`position.{key}`: {message}"),
        None => message,
    }
}

/// The keys a scenario file gives: its top level, and its `[position]`
/// table's kind and other keys.
#[derive(serde::Deserialize)]
struct FileKeys {
    position: Option<TaggedKeys>,
    #[serde(flatten)]
    top: std::collections::BTreeMap<String, serde::de::IgnoredAny>,
}

/// A tagged table's `kind` and its other keys.
#[derive(serde::Deserialize)]
struct TaggedKeys {
    kind: Option<String>,
    #[serde(flatten)]
    other: std::collections::BTreeMap<String, serde::de::IgnoredAny>,
}

impl FileKeys {
    /// Whether the file gives the top-level key `key`.
    fn given(&self, key: &str) -> bool {
        (key == "position" && self.position.is_some()) || self.top.contains_key(key)
    }
}

impl Scenario {
    /// Parses and validates a scenario from TOML text.
    ///
    /// # Errors
    /// [`ScenarioError::Parse`] for bad TOML or schema (unknown or missing
    /// keys, wrong types), [`ScenarioError::Invalid`] for bad values.
    pub fn from_toml_str(text: &str) -> Result<Self, ScenarioError> {
        Self::from_toml_str_in(text, None)
    }

    /// [`Self::from_toml_str`] for a scenario whose robot file (`robot =
    /// "FILE"`) is relative to `dir` (`None`: none is read, as
    /// [`Self::from_toml_str`] does, which refuses `robot = "FILE"`). The
    /// returned scenario holds the robot's tables in its own
    /// ([`Self::resolve_robot`]), so it is self-contained.
    ///
    /// # Errors
    /// As [`Self::from_toml_str`]; a refused robot key is a
    /// [`ScenarioError::Robot`] naming the robot file.
    pub fn from_toml_str_in(text: &str, dir: Option<&Path>) -> Result<Self, ScenarioError> {
        let parse_error = |e: toml::de::Error| ScenarioError::Parse(e.to_string());
        let mut scenario: Self =
            toml::from_str(text).map_err(|e| ScenarioError::Parse(name_position_key(text, &e)))?;
        // Which keys the file gives, not what they hold (a value is not
        // converted: a u64 seed beyond i64 is no TOML integer value).
        let keys: FileKeys = toml::from_str(text).map_err(parse_error)?;
        if let Some(position) = &keys.position {
            let given = position.other.keys().map(String::as_str);
            if let Some(reason) =
                tables::only_kind_of(position.kind.as_deref(), given, "position", "exact")
            {
                return Err(ScenarioError::Parse(reason));
            }
        }
        scenario.given = GivenKeys::of_toml(text).map_err(parse_error)?;
        if let ReferenceSpec::Route(route) = &mut scenario.reference {
            route.load_waypoints(dir)?;
        }
        let robot = scenario.resolve_robot(dir, |key| keys.given(key))?;
        scenario.validate().map_err(|e| match &robot {
            Some(robot) => robot.name_in(e),
            None => e,
        })?;
        Ok(scenario)
    }

    /// Reads, parses and validates a scenario file (its robot file
    /// relative to it).
    ///
    /// # Errors
    /// As [`Self::from_toml_str`], plus [`ScenarioError::Io`].
    pub fn from_file(path: &Path) -> Result<Self, ScenarioError> {
        read_file(path, |text| Self::from_toml_str_in(text, path.parent()))
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

    /// The scenario as TOML, resolved: every key that applies, at its
    /// value (defaults filled in), and none that this setup ignores
    /// ([`Self::ignored_keys`]), so that the file read back gives the same
    /// run and no warning. The values of the core's `f32` specs (the
    /// reference's, the estimator's and the law's tables) are written as their shortest
    /// decimal (`0.001`, not `0.0010000000474974513`), which reads back as
    /// the same `f32`.
    ///
    /// # Errors
    /// Never for a scenario that was parsed (all values representable).
    pub fn to_toml_string(&self) -> Result<String, toml::ser::Error> {
        // A toml::Value holds i64 integers: a u64 seed beyond them (a
        // sweep's drawn seeds) is written by the typed serializer as it is.
        let Ok(mut value) = toml::Value::try_from(self) else {
            return toml::to_string_pretty(self);
        };
        for (key, _) in self.ignored_keys() {
            remove_key(&mut value, key);
        }
        // The core's own specs (the reference's, the estimator's and the
        // law's tables) hold f32; the simulator's tables hold f64 and are
        // written as they are.
        for table in ["reference", "estimator"] {
            if let Some(spec) = value.get_mut(table) {
                shortest_f32_floats(spec);
            }
        }
        if let Some(law) = value.get_mut("controller").and_then(|c| c.get_mut("law")) {
            shortest_f32_floats(law);
        }
        toml::to_string_pretty(&value)
    }
}

/// Removes the dotted `key` from a TOML value, if there.
fn remove_key(value: &mut toml::Value, key: &str) {
    match key.split_once('.') {
        Some((table, rest)) => {
            if let Some(inner) = value.get_mut(table) {
                remove_key(inner, rest);
            }
        }
        None => {
            if let Some(table) = value.as_table_mut() {
                table.remove(key);
            }
        }
    }
}

/// Writes every float of a table of the core's `f32` specs as the `f64` of
/// its shortest `f32` decimal, which reads back as the same `f32`.
fn shortest_f32_floats(value: &mut toml::Value) {
    match value {
        toml::Value::Float(x) => {
            let single = *x as f32;
            if f64::from(single).to_bits() == x.to_bits()
                && let Ok(shortest) = single.to_string().parse::<f64>()
            {
                *x = shortest;
            }
        }
        toml::Value::Table(table) => table.iter_mut().for_each(|(_, v)| shortest_f32_floats(v)),
        toml::Value::Array(items) => items.iter_mut().for_each(shortest_f32_floats),
        _ => {}
    }
}
