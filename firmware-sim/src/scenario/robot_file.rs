//! The robot file's schema: its top level ([`RobotFile`]), its reader and
//! floor tables, and how a scenario names its robot ([`RobotSource`]). The
//! tables it shares with a scenario are `tables`'; loading a robot file
//! and giving its tables to a scenario is `robot`'s job.

use serde::{Deserialize, Serialize};
use wmr_core::devices::TagId;
use wmr_core::estimation::spec::EstimatorSpec;

use super::defaults;
use super::mavlink::MavlinkSpec;
use super::route::ReferenceSpec;
use super::tables::{
    ControllerSpec, DriveSpec, FailsafeSpec, ObserverSpec, PlantSpec, ReaderModeSpec, TelemetrySpec,
};

/// A robot file's top level.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RobotFile {
    /// Short name (the flash image's and the firmware log's).
    pub name: String,
    /// Free text.
    #[serde(default)]
    pub description: String,
    /// Control period `h`, s.
    #[serde(default = "defaults::period_s")]
    pub period_s: f64,
    /// The trajectory the flashed firmware tracks (needed to flash; a
    /// scenario naming the robot tracks its own `[reference]`). A route
    /// (`kind = "route"`) is read and checked, but not flashed yet: the
    /// flash image and the HIL link carry analytic references only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference: Option<ReferenceSpec>,
    /// Geometry (wheel radius, track), encoders and motors:
    /// `kind = "diff_drive"` and its keys.
    pub plant: PlantSpec,
    /// Drive limits, speed loops and the wheel-speed observer.
    #[serde(default)]
    pub drive: DriveSpec,
    /// Tracking law and gains.
    #[serde(default)]
    pub controller: ControllerSpec,
    /// Paper 001's heading observer (5).
    #[serde(default)]
    pub observer: ObserverSpec,
    /// The estimator (the core's `EstimatorSpec`).
    #[serde(default)]
    pub estimator: EstimatorSpec,
    /// What the tracker does when fixes stop.
    #[serde(default)]
    pub failsafe: FailsafeSpec,
    /// The RFID reader.
    #[serde(default)]
    pub reader: ReaderSpec,
    /// The floor's tags.
    pub floor: FloorSpec,
    /// The firmware's telemetry records (`every_ticks`, default 10): the
    /// flashed Black Pill's decimation and `firmware-sim hil`'s default of
    /// `--telemetry-every`.
    #[serde(default)]
    pub telemetry: TelemetrySpec,
    /// The robot's MAVLink endpoint (system id, timeouts, telemetry
    /// period), the floor's geodetic origin and what the robot does at
    /// power-on (`run` or `wait`): its route runs' on the SITL, under QEMU
    /// and on the Black Pill (the flash image carries it with the route).
    /// Default: `EndpointSpec::default()`, no origin, running from
    /// power-on.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mavlink: Option<MavlinkSpec>,
}

/// The robot's RFID reader (the keys of a scenario's `position.kind =
/// "reader"` that describe the reader).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ReaderSpec {
    /// `paper` (nearest tag every tick) or `range`.
    #[serde(default)]
    pub mode: ReaderModeSpec,
    /// Read radius around the antenna (`range` mode), m.
    #[serde(default = "defaults::read_radius_m")]
    pub read_radius_m: f64,
    /// Antenna ahead of the axle midpoint, m (the estimators move each fix
    /// back to the midpoint).
    #[serde(default)]
    pub antenna_offset_m: f64,
    /// Line speed, baud.
    #[serde(default = "defaults::baud")]
    pub baud: u32,
    /// Repeat interval while a tag stays in range (`range` mode), s.
    #[serde(default = "defaults::repeat_interval_s")]
    pub repeat_interval_s: f64,
}

impl Default for ReaderSpec {
    fn default() -> Self {
        Self {
            mode: ReaderModeSpec::default(),
            read_radius_m: defaults::read_radius_m(),
            antenna_offset_m: 0.0,
            baud: defaults::baud(),
            repeat_interval_s: defaults::repeat_interval_s(),
        }
    }
}

/// The floor's tags.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum FloorSpec {
    /// A regular grid, ids in the core's grid encoding.
    Grid {
        /// Tag spacing, m.
        #[serde(default = "defaults::spacing_m")]
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
    /// Surveyed tags with arbitrary ids: a CSV file of `id,x_m,y_m` rows
    /// (a header row is allowed; ids decimal or `0x` hexadecimal, 40 bits).
    TagMap {
        /// The CSV file, relative to the robot file.
        file: String,
    },
}

/// One surveyed tag of a tag map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MappedTag {
    /// The id the reader reports (40 bits).
    pub id: TagId,
    /// Position, m.
    pub x_m: f64,
    /// Position, m.
    pub y_m: f64,
}

/// Where a scenario's robot comes from: `robot = "FILE"` or `[robot]`.
#[derive(Debug, Clone, PartialEq, Serialize, schemars::JsonSchema)]
#[serde(untagged)]
pub enum RobotSource {
    /// A robot file, relative to the scenario file.
    File(String),
    /// The robot's tables, embedded.
    Inline(Box<RobotFile>),
}

impl<'de> Deserialize<'de> for RobotSource {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        use serde::de::Error as _;
        match toml::Value::deserialize(deserializer)? {
            toml::Value::String(path) => Ok(Self::File(path)),
            table @ toml::Value::Table(_) => RobotFile::deserialize(table)
                .map(|r| Self::Inline(Box::new(r)))
                // The inner error ends in a newline the outer one adds again.
                .map_err(|e| D::Error::custom(e.to_string().trim_end())),
            other => Err(D::Error::custom(format!(
                "robot must be a file name or a [robot] table (got {})",
                other.type_str()
            ))),
        }
    }
}
