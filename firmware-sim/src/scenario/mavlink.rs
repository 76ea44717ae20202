//! The `[mavlink]` table of a robot file (or a scenario): the robot's
//! MAVLink endpoint (`wmr_mavlink::EndpointSpec`), the floor's geodetic
//! origin, and what the robot does at power-on. One table for the SITL,
//! the firmware under QEMU (the HIL link's route announcement) and the
//! Black Pill (the robot image's route): `wmr_link::MavlinkSettings`.
//!
//! ```toml
//! [mavlink]
//! system_id = 1
//! telemetry_period_ms = 200
//! link_timeout_ms = 3000
//! power_on = "run"            # or "wait": disarmed until a ground station arms and starts it
//! [mavlink.origin]
//! latitude_deg = 47.397742
//! longitude_deg = 8.545594
//! ```
//!
//! Every value is checked once, by the endpoint's own constructor
//! (`EndpointConfig::new`), and refused naming the key and its value.

use serde::{Deserialize, Serialize};
use wmr_link::{MavlinkSettings, PowerOn};
use wmr_mavlink::{ConfigKey, EndpointSpec};

use super::error::ScenarioError;

fn system_id() -> u64 {
    u64::from(EndpointSpec::default().system_id)
}
fn component_id() -> u64 {
    u64::from(EndpointSpec::default().component_id)
}
fn link_timeout_ms() -> u64 {
    u64::from(EndpointSpec::default().link_timeout_ms)
}
fn item_timeout_ms() -> u64 {
    u64::from(EndpointSpec::default().item_timeout_ms)
}
fn item_retries() -> u64 {
    u64::from(EndpointSpec::default().item_retries)
}
fn telemetry_period_ms() -> u64 {
    u64::from(EndpointSpec::default().telemetry_period_ms)
}
fn counters_period_ms() -> u64 {
    u64::from(EndpointSpec::default().counters_period_ms)
}

/// The robot's MAVLink endpoint (`[mavlink]`): used by route runs (a
/// route reference), on the SITL, under QEMU and on the Black Pill.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MavlinkSpec {
    /// This robot's MAVLink system id, 1 to 255.
    #[serde(default = "system_id")]
    #[schemars(range(min = 1, max = 255))]
    pub system_id: u64,
    /// This robot's MAVLink component id, 1 to 255 (1: the autopilot).
    #[serde(default = "component_id")]
    #[schemars(range(min = 1, max = 255))]
    pub component_id: u64,
    /// No ground-station heartbeat for this long (after one was heard):
    /// the link is lost and the robot stops, 100 to 600000 ms.
    #[serde(default = "link_timeout_ms")]
    #[schemars(range(min = 100, max = 600_000))]
    pub link_timeout_ms: u64,
    /// A mission upload re-requests an item after this long without it,
    /// 50 to 60000 ms.
    #[serde(default = "item_timeout_ms")]
    #[schemars(range(min = 50, max = 60_000))]
    pub item_timeout_ms: u64,
    /// Re-requests of one item before an upload is cancelled, 0 to 20.
    #[serde(default = "item_retries")]
    #[schemars(range(min = 0, max = 20))]
    pub item_retries: u64,
    /// Position and attitude telemetry period, ms: 0 (off) or 20 to
    /// 60000.
    #[serde(default = "telemetry_period_ms")]
    #[schemars(range(min = 0, max = 60_000))]
    pub telemetry_period_ms: u64,
    /// Period in which the tracker's and RFID reader's counters are all
    /// sent once (`NAMED_VALUE_INT`, one counter at a time), ms: 0 (off)
    /// or 20 to 60000.
    #[serde(default = "counters_period_ms")]
    #[schemars(range(min = 0, max = 60_000))]
    pub counters_period_ms: u64,
    /// The floor's (0, 0) on the globe (WGS-84), for global-frame
    /// missions and `GLOBAL_POSITION_INT`; without it a global-frame
    /// mission is refused (`MAV_MISSION_UNSUPPORTED_FRAME`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub origin: Option<OriginSpec>,
    /// What the robot does when its route run begins, with or without a
    /// ground station: `run` (armed, driving the route) or `wait`
    /// (disarmed and idle, the route loaded as the mission, until a
    /// ground station arms and starts it).
    #[serde(default)]
    pub power_on: PowerOnSpec,
}

impl Default for MavlinkSpec {
    fn default() -> Self {
        Self {
            system_id: system_id(),
            component_id: component_id(),
            link_timeout_ms: link_timeout_ms(),
            item_timeout_ms: item_timeout_ms(),
            item_retries: item_retries(),
            telemetry_period_ms: telemetry_period_ms(),
            counters_period_ms: counters_period_ms(),
            origin: None,
            power_on: PowerOnSpec::default(),
        }
    }
}

/// The floor's geodetic origin (`[mavlink.origin]`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct OriginSpec {
    /// Latitude of the floor's (0, 0), degrees north, within ±85°.
    #[schemars(range(min = -85.0, max = 85.0))]
    pub latitude_deg: f64,
    /// Longitude of the floor's (0, 0), degrees east, within ±180°.
    #[schemars(range(min = -180.0, max = 180.0))]
    pub longitude_deg: f64,
}

/// What the robot does at power-on (`mavlink.power_on`).
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, schemars::JsonSchema,
)]
#[serde(rename_all = "snake_case")]
pub enum PowerOnSpec {
    /// Armed, running the route from power-on.
    #[default]
    Run,
    /// Disarmed and idle, the route loaded as the mission.
    Wait,
}

impl From<PowerOnSpec> for PowerOn {
    fn from(p: PowerOnSpec) -> Self {
        match p {
            PowerOnSpec::Run => Self::Run,
            PowerOnSpec::Wait => Self::Wait,
        }
    }
}

/// The key of the table a [`ConfigKey`] is.
fn key_of(key: ConfigKey) -> &'static str {
    match key {
        ConfigKey::SystemId => "mavlink.system_id",
        ConfigKey::ComponentId => "mavlink.component_id",
        ConfigKey::LinkTimeout => "mavlink.link_timeout_ms",
        ConfigKey::ItemTimeout => "mavlink.item_timeout_ms",
        ConfigKey::ItemRetries => "mavlink.item_retries",
        ConfigKey::TelemetryPeriod => "mavlink.telemetry_period_ms",
        ConfigKey::CountersPeriod => "mavlink.counters_period_ms",
        ConfigKey::OriginLatitude => "mavlink.origin.latitude_deg",
        ConfigKey::OriginLongitude => "mavlink.origin.longitude_deg",
    }
}

/// The accepted range of a key, in the table's units.
fn range_of(key: ConfigKey) -> &'static str {
    match key {
        ConfigKey::OriginLatitude => "-85 to 85 degrees",
        ConfigKey::OriginLongitude => "-180 to 180 degrees",
        other => other.range(),
    }
}

impl MavlinkSpec {
    /// The settings, checked by the endpoint's constructor
    /// (`EndpointConfig::new`).
    ///
    /// # Errors
    /// [`ScenarioError::Invalid`] naming the first refused key with its
    /// value.
    pub fn settings(&self) -> Result<MavlinkSettings, ScenarioError> {
        let refused = |key: ConfigKey, value: String| {
            ScenarioError::invalid(
                key_of(key),
                format!("must be {} (got {value})", range_of(key)),
            )
        };
        // Wider than the endpoint's fields: out of their type is out of
        // range too.
        let narrow_u8 = |key, v: u64| u8::try_from(v).map_err(|_| refused(key, v.to_string()));
        let narrow_u32 = |key, v: u64| u32::try_from(v).map_err(|_| refused(key, v.to_string()));
        let e7 = |key, deg: f64| {
            let v = (deg * 1e7).round();
            if deg.is_finite() && v.abs() <= f64::from(i32::MAX) {
                Ok(v as i32)
            } else {
                Err(refused(key, format!("{deg:?}")))
            }
        };
        let origin_e7 = match self.origin {
            None => None,
            Some(o) => Some((
                e7(ConfigKey::OriginLatitude, o.latitude_deg)?,
                e7(ConfigKey::OriginLongitude, o.longitude_deg)?,
            )),
        };
        let spec = EndpointSpec {
            system_id: narrow_u8(ConfigKey::SystemId, self.system_id)?,
            component_id: narrow_u8(ConfigKey::ComponentId, self.component_id)?,
            link_timeout_ms: narrow_u32(ConfigKey::LinkTimeout, self.link_timeout_ms)?,
            item_timeout_ms: narrow_u32(ConfigKey::ItemTimeout, self.item_timeout_ms)?,
            item_retries: narrow_u8(ConfigKey::ItemRetries, self.item_retries)?,
            telemetry_period_ms: narrow_u32(ConfigKey::TelemetryPeriod, self.telemetry_period_ms)?,
            counters_period_ms: narrow_u32(ConfigKey::CountersPeriod, self.counters_period_ms)?,
            origin_e7,
        };
        let settings = MavlinkSettings::of(&spec, self.power_on.into());
        settings.config().map_err(|e| {
            let key = e_key(&e);
            let value = match (key, self.origin) {
                (ConfigKey::OriginLatitude, Some(o)) => format!("{:?}", o.latitude_deg),
                (ConfigKey::OriginLongitude, Some(o)) => format!("{:?}", o.longitude_deg),
                _ => match e {
                    wmr_link::RouteRefusal::Endpoint(r) => r.value.to_string(),
                    _ => String::new(),
                },
            };
            refused(key, value)
        })?;
        Ok(settings)
    }
}

/// The key a refusal of [`MavlinkSettings::config`] names.
fn e_key(e: &wmr_link::RouteRefusal) -> ConfigKey {
    match e {
        wmr_link::RouteRefusal::Endpoint(r) => r.key(),
        _ => ConfigKey::SystemId,
    }
}

#[cfg(test)]
mod tests {
    use crate::scenario::robot::Robot;
    use crate::scenario::{ReferenceSpec, Scenario, ScenarioError};
    use wmr_link::PowerOn;

    /// The robot file `robots/route_loop.toml` with its own `[mavlink]`
    /// table replaced by `table`.
    fn robot_with(table: &str) -> Result<Robot, ScenarioError> {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots");
        let file = std::fs::read_to_string(dir.join("route_loop.toml")).unwrap();
        let own = file.find("\n[mavlink]").unwrap_or(file.len());
        let text = format!("{}\n{table}", &file[..own]);
        let file = tempfile::Builder::new()
            .suffix(".toml")
            .tempfile_in(&dir)
            .unwrap();
        std::fs::write(file.path(), text).unwrap();
        Robot::from_file(file.path())
    }

    /// The robot's route as a scenario validates it (what the SITL and
    /// the HIL link use, and the flash image holds).
    fn settings_of(robot: &Robot) -> Result<wmr_link::MavlinkSettings, ScenarioError> {
        let Some(reference @ ReferenceSpec::Route(_)) = robot.file.reference.clone() else {
            panic!("a route robot")
        };
        let setup = robot
            .scenario(reference, 10.0)
            .validate()
            .map_err(|e| robot.name_in(e))?;
        Ok(setup.route.unwrap().mavlink)
    }

    #[test]
    fn a_robot_files_mavlink_table_is_read_and_defaults_when_absent() {
        let plain = robot_with("").unwrap();
        assert_eq!(
            settings_of(&plain).unwrap(),
            wmr_link::MavlinkSettings::default()
        );
        let robot = robot_with(
            "\n[mavlink]\nsystem_id = 7\ncomponent_id = 2\nlink_timeout_ms = 5000\n\
             item_timeout_ms = 500\nitem_retries = 3\ntelemetry_period_ms = 100\n\
             power_on = \"wait\"\n[mavlink.origin]\nlatitude_deg = 47.397742\n\
             longitude_deg = -8.545594\n",
        )
        .unwrap();
        let s = settings_of(&robot).unwrap();
        assert_eq!(
            (
                s.system_id,
                s.component_id,
                s.link_timeout_ms,
                s.item_timeout_ms
            ),
            (7, 2, 5000, 500)
        );
        assert_eq!((s.item_retries, s.telemetry_period_ms), (3, 100));
        assert_eq!(s.origin_e7, Some([473_977_420, -85_455_940]));
        assert_eq!(s.power_on, PowerOn::Wait);
        // The flash image carries them with the route.
        let image = robot.flash_image().unwrap();
        let decoded = wmr_link::image::decode(&image.bytes).unwrap();
        assert_eq!(decoded.route.unwrap().spec.mavlink, s);
    }

    #[test]
    fn bad_mavlink_keys_and_values_are_refused_by_name() {
        // An unknown key: refused by the parser, named.
        let e = robot_with("\n[mavlink]\nsystem = 3\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("system"), "{e}");
        let e = robot_with(
            "\n[mavlink.origin]\nlatitude_deg = 1.0\nlongitude_deg = 2.0\naltitude_m = 3.0\n",
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("altitude_m"), "{e}");
        let e = robot_with("\n[mavlink]\npower_on = \"later\"\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("later"), "{e}");
        // Values out of range: named with the value, in the robot file.
        for (table, key, value) in [
            ("system_id = 0", "mavlink.system_id", "got 0"),
            ("system_id = 256", "mavlink.system_id", "got 256"),
            ("component_id = 0", "mavlink.component_id", "got 0"),
            ("link_timeout_ms = 99", "mavlink.link_timeout_ms", "got 99"),
            (
                "item_timeout_ms = 70000",
                "mavlink.item_timeout_ms",
                "got 70000",
            ),
            ("item_retries = 21", "mavlink.item_retries", "got 21"),
            (
                "telemetry_period_ms = 10",
                "mavlink.telemetry_period_ms",
                "got 10",
            ),
            (
                "telemetry_period_ms = 5000000000",
                "mavlink.telemetry_period_ms",
                "got 5000000000",
            ),
            (
                "counters_period_ms = 19",
                "mavlink.counters_period_ms",
                "got 19",
            ),
            (
                "counters_period_ms = 5000000000",
                "mavlink.counters_period_ms",
                "got 5000000000",
            ),
            (
                "origin = { latitude_deg = 86.0, longitude_deg = 0.0 }",
                "mavlink.origin.latitude_deg",
                "got 86",
            ),
            (
                "origin = { latitude_deg = 0.0, longitude_deg = -181.5 }",
                "mavlink.origin.longitude_deg",
                "got -181.5",
            ),
            (
                "origin = { latitude_deg = 1e300, longitude_deg = 0.0 }",
                "mavlink.origin.latitude_deg",
                "got 1e300",
            ),
        ] {
            let robot = robot_with(&format!("\n[mavlink]\n{table}\n")).unwrap();
            let e = settings_of(&robot).unwrap_err();
            let text = e.to_string();
            assert!(
                matches!(&e, ScenarioError::Robot { field, .. } if field == key),
                "{table}: {text}"
            );
            assert!(text.contains(value), "{table}: {text}");
            assert!(robot.flash_image().is_err(), "{table}: imaged");
        }
    }

    /// A scenario naming a robot cannot give `[mavlink]` (the robot's);
    /// a table where no route runs is a warning, naming it.
    #[test]
    fn a_scenario_naming_a_robot_takes_its_mavlink_table() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots");
        let e = Scenario::from_toml_str_in(
            "name = \"x\"\nduration_s = 1.0\nrobot = \"route_loop.toml\"\n\
             [reference]\nkind = \"circle\"\nradius_m = 1.0\nrate_rad_s = 0.05\n[mavlink]\nsystem_id = 2\n",
            Some(&dir),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("`mavlink`"), "{e}");
        let s = Scenario::from_toml_str(
            "name = \"x\"\nduration_s = 1.0\n[reference]\nkind = \"circle\"\nradius_m = 1.0\nrate_rad_s = 0.05\n\
             [mavlink]\nsystem_id = 2\n",
        )
        .unwrap();
        let warnings = s.warnings();
        assert!(
            warnings
                .iter()
                .any(|w| w.starts_with("mavlink: ignored without a route")),
            "{warnings:?}"
        );
    }
}
