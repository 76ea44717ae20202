//! The scenario file's top level ([`Scenario`]): its own keys and the
//! tables it holds (`tables`, shared with the robot file), with their units
//! in the key names and their defaults (see `defaults`). Checking the
//! values is `validate`'s job.

use serde::{Deserialize, Serialize};
use wmr_core::estimation::spec::EstimatorSpec;
use wmr_core::plausible;

use super::defaults;
use super::mavlink::MavlinkSpec;
use super::robot_file::RobotSource;
use super::route::ReferenceSpec;
use super::sweep_spec::SweepSpec;
use super::tables::{
    ControllerSpec, DriveSpec, FailsafeSpec, FloorTagSpec, InitialSpec, MeasurementSpec,
    ObserverSpec, PlantSpec, PositionSpec, TelemetrySpec,
};

/// A simulation scenario (the TOML file's top level).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
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
    #[schemars(range(min = plausible::PERIOD_S.min, max = plausible::PERIOD_S.max))]
    pub period_s: f64,
    /// Error statistics are taken over `t ≥ transient_s`, s.
    #[serde(default)]
    pub transient_s: f64,
    /// The reference: an analytic trajectory of the core, or a route
    /// (`kind = "route"`).
    pub reference: ReferenceSpec,
    /// Initial pose and observer estimate.
    #[serde(default)]
    pub initial: InitialSpec,
    /// Tracking law and gains.
    #[serde(default)]
    pub controller: ControllerSpec,
    /// Paper 001's heading observer (5), which runs under every estimator
    /// (the fusion filter's heading guide).
    #[serde(default)]
    pub observer: ObserverSpec,
    /// The output-feedback tracker's estimator: the core's own
    /// [`EstimatorSpec`] (`estimator = "heading_observer"`, the default;
    /// `[estimator.pose_observer]`; `[estimator.fusion]`).
    #[serde(default)]
    pub estimator: EstimatorSpec,
    /// The simulated robot body.
    #[serde(default)]
    pub plant: PlantSpec,
    /// Drive limits and speed loops (`diff_drive` plant only).
    #[serde(default)]
    pub drive: Option<DriveSpec>,
    /// Where the position measurement comes from.
    #[serde(default)]
    pub position: PositionSpec,
    /// The floor of a robot whose floor is a tag map (`floor.kind =
    /// "tag_map"`), as `[[floor_tags]]` rows `id`, `x_m`, `y_m`: filled in
    /// from the robot's map when the scenario names the robot, so that the
    /// resolved scenario (a sweep run's `scenario.toml`, a shard's
    /// manifest) is self-contained. Given, the reader
    /// (`position.kind = "reader"` only) reads these tags and the robot
    /// looks the ids up in them; `position`'s grid keys are not used.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub floor_tags: Vec<FloorTagSpec>,
    /// What the tracker does when fixes stop.
    #[serde(default)]
    pub failsafe: FailsafeSpec,
    /// The firmware's telemetry decimation: the default of `firmware-sim
    /// hil --telemetry-every` (without it, 1). Filled in from the robot
    /// file's `[telemetry]` when the scenario names a robot.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub telemetry: Option<TelemetrySpec>,
    /// The robot's MAVLink endpoint, the floor's geodetic origin and what
    /// the robot does at power-on, for a route run (`firmware-sim sitl`,
    /// `firmware-sim hil --mavlink`); default: `EndpointSpec::default()`,
    /// running from power-on. Filled in from the robot file's `[mavlink]`
    /// when the scenario names a robot.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mavlink: Option<MavlinkSpec>,
    /// Noise and misses on the position fix (`exact` and `nearest_tag`
    /// sources).
    #[serde(default, skip_serializing_if = "MeasurementSpec::is_default")]
    pub measurement: MeasurementSpec,
    /// What `firmware-sim sweep` varies (ignored by `run`, but validated).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sweep: Option<SweepSpec>,
    /// The robot: a robot file (`robot = "robots/example.toml"`, relative
    /// to the scenario file) or its tables embedded (`[robot]`; keys: the
    /// robot file's, `firmware-sim schema`). Its tables (`period_s`,
    /// `plant`, `drive`, `controller`, `observer`, `estimator`,
    /// `failsafe`, and `position` from its reader and floor) replace the
    /// scenario's, which must then be left out, except the reader's fault
    /// keys (the experiment's): `[position]` with `kind = "reader"` and
    /// only `corrupt_byte_probability`, `drop_frame_probability`, `seed`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot: Option<RobotSource>,
    /// The keys the file gave (not serialized): warnings name a key that
    /// does not apply only where the file wrote it.
    #[serde(skip)]
    #[schemars(skip)]
    pub(crate) given: GivenKeys,
}

/// The dotted keys a scenario file gave (`observer.gain_per_m`), tables
/// of tables included, arrays of tables as their key alone. Provenance, not
/// content: any two compare equal, so that a scenario and its re-read
/// resolved file are the same scenario.
#[derive(Debug, Clone, Default)]
pub struct GivenKeys {
    /// The file's own keys.
    keys: std::collections::BTreeSet<String>,
    /// The robot file whose tables the scenario holds (its path as errors
    /// name it, and its keys in its own names), when it names one.
    robot: Option<(String, Box<GivenKeys>)>,
}

impl GivenKeys {
    /// The keys of a TOML text (which has parsed as a scenario already).
    ///
    /// # Errors
    /// The TOML parser's, for a text that is not TOML.
    pub(crate) fn of_toml(text: &str) -> Result<Self, toml::de::Error> {
        toml::from_str::<KeyTree>(text).map(|tree| Self {
            keys: tree.0,
            robot: None,
        })
    }

    /// The keys under `table` (`robot` for an inline robot), in the
    /// table's own names.
    pub(crate) fn under(&self, table: &str) -> Self {
        let prefix = format!("{table}.");
        Self {
            keys: self
                .keys
                .iter()
                .filter_map(|k| k.strip_prefix(&prefix).map(str::to_owned))
                .collect(),
            robot: None,
        }
    }

    /// Records the keys of the robot file at `path` whose tables the
    /// scenario took.
    pub(crate) fn with_robot(mut self, path: String, robot: GivenKeys) -> Self {
        self.robot = Some((path, Box::new(robot)));
        self
    }

    /// Whether the file gave `key` (a table counts as given when the file
    /// wrote it or any key under it).
    #[must_use]
    pub fn contains(&self, key: &str) -> bool {
        self.keys.contains(key)
    }

    /// The robot file's path and keys, when the scenario took a robot's
    /// tables.
    #[must_use]
    pub fn robot(&self) -> Option<(&str, &GivenKeys)> {
        self.robot
            .as_ref()
            .map(|(path, keys)| (path.as_str(), &**keys))
    }
}

/// The dotted keys under a TOML value: its own keys and theirs for a
/// table, none for anything else (values are skipped, never converted).
struct KeyTree(std::collections::BTreeSet<String>);

impl<'de> Deserialize<'de> for KeyTree {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Keys;
        impl<'de> serde::de::Visitor<'de> for Keys {
            type Value = KeyTree;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("any TOML value")
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                mut map: A,
            ) -> Result<KeyTree, A::Error> {
                let mut keys = std::collections::BTreeSet::new();
                while let Some(key) = map.next_key::<String>()? {
                    let under: KeyTree = map.next_value()?;
                    keys.extend(under.0.into_iter().map(|k| format!("{key}.{k}")));
                    keys.insert(key);
                }
                Ok(KeyTree(keys))
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                mut seq: A,
            ) -> Result<KeyTree, A::Error> {
                while seq.next_element::<serde::de::IgnoredAny>()?.is_some() {}
                Ok(KeyTree(std::collections::BTreeSet::new()))
            }
            fn visit_bool<E>(self, _: bool) -> Result<KeyTree, E> {
                Ok(KeyTree(std::collections::BTreeSet::new()))
            }
            fn visit_i64<E>(self, _: i64) -> Result<KeyTree, E> {
                Ok(KeyTree(std::collections::BTreeSet::new()))
            }
            fn visit_u64<E>(self, _: u64) -> Result<KeyTree, E> {
                Ok(KeyTree(std::collections::BTreeSet::new()))
            }
            fn visit_f64<E>(self, _: f64) -> Result<KeyTree, E> {
                Ok(KeyTree(std::collections::BTreeSet::new()))
            }
            fn visit_str<E>(self, _: &str) -> Result<KeyTree, E> {
                Ok(KeyTree(std::collections::BTreeSet::new()))
            }
        }
        d.deserialize_any(Keys)
    }
}

impl PartialEq for GivenKeys {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}
