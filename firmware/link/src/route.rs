//! A route over the link (the crate docs, "The route"): its announcement,
//! its waypoints in chunks, why the firmware refuses one, and the messages
//! a host sends for a route ([`route_messages`]).

use serde::{Deserialize, Serialize};
use wmr_core::pilot::route::{RouteOptions, RouteOptionsError, RouteOptionsSpec, RouteStart};
use wmr_core::reference::route::{
    ROUTE_CAPACITY, RouteError, RouteLimitsError, RouteLimitsSpec, Waypoint, Waypoints,
};

use wmr_mavlink::{ConfigError, ConfigKey, EndpointConfig, EndpointSpec};

use crate::{HostMessage, ROUTE_CHUNK_WAYPOINTS};

/// A route announced after the configuration ([`HostMessage::Route`]): its
/// size, limits, how it is followed and where it starts; its waypoints
/// follow in [`RouteChunk`]s.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RouteSpec {
    /// Waypoints in the route, 2 to [`ROUTE_CAPACITY`].
    pub waypoints: u8,
    /// The limits the plan obeys (validated by `RouteLimits::new`).
    pub limits: RouteLimitsSpec,
    /// How the route is followed at rest.
    pub options: RouteOptionsSpec,
    /// Where the route starts.
    pub start: RouteStart,
    /// The MAVLink endpoint of the route run and what the robot does at
    /// power-on (a robot file's `[mavlink]`).
    pub mavlink: MavlinkSettings,
}

/// What a robot does when its route run begins (power-on on the Black
/// Pill, the run's first tick under QEMU and in the SITL), with or
/// without a ground station.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PowerOn {
    /// Armed, running the route from its start.
    #[default]
    Run,
    /// Disarmed, idle, holding where it stands, the route loaded as the
    /// mission: a ground station arms it and starts it (or uploads
    /// another mission).
    Wait,
}

/// A route run's MAVLink endpoint settings, as plain numbers
/// ([`EndpointSpec`]'s, checked by [`EndpointConfig::new`] when the route
/// is announced: [`RouteRefusal::Endpoint`]), and its [`PowerOn`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MavlinkSettings {
    /// MAVLink system id, 1 to 255.
    pub system_id: u8,
    /// MAVLink component id, 1 to 255.
    pub component_id: u8,
    /// No ground-station heartbeat for this long is a link loss, ms.
    pub link_timeout_ms: u32,
    /// Upload: re-request an item after this long, ms.
    pub item_timeout_ms: u32,
    /// Upload: re-requests of one item before it is cancelled.
    pub item_retries: u8,
    /// Position and attitude telemetry period, ms (0: off).
    pub telemetry_period_ms: u32,
    /// Tracker and RFID counter telemetry period (all counters once),
    /// ms (0: off).
    pub counters_period_ms: u32,
    /// The floor's geodetic origin, latitude and longitude in 1e-7
    /// degrees (`None`: global-frame missions are refused).
    pub origin_e7: Option<[i32; 2]>,
    /// What the robot does when the run begins.
    pub power_on: PowerOn,
}

impl Default for MavlinkSettings {
    /// `EndpointSpec::default()`'s settings, running from power-on.
    fn default() -> Self {
        Self::of(&EndpointSpec::default(), PowerOn::Run)
    }
}

impl MavlinkSettings {
    /// The settings of `spec`, with `power_on`.
    #[must_use]
    pub fn of(spec: &EndpointSpec, power_on: PowerOn) -> Self {
        Self {
            system_id: spec.system_id,
            component_id: spec.component_id,
            link_timeout_ms: spec.link_timeout_ms,
            item_timeout_ms: spec.item_timeout_ms,
            item_retries: spec.item_retries,
            telemetry_period_ms: spec.telemetry_period_ms,
            counters_period_ms: spec.counters_period_ms,
            origin_e7: spec.origin_e7.map(|(lat, lon)| [lat, lon]),
            power_on,
        }
    }

    /// The endpoint's settings.
    #[must_use]
    pub fn endpoint_spec(&self) -> EndpointSpec {
        EndpointSpec {
            system_id: self.system_id,
            component_id: self.component_id,
            link_timeout_ms: self.link_timeout_ms,
            item_timeout_ms: self.item_timeout_ms,
            item_retries: self.item_retries,
            telemetry_period_ms: self.telemetry_period_ms,
            counters_period_ms: self.counters_period_ms,
            origin_e7: self.origin_e7.map(|[lat, lon]| (lat, lon)),
        }
    }

    /// The endpoint's configuration, checked.
    ///
    /// # Errors
    /// [`RouteRefusal::Endpoint`] naming the field and its value.
    pub fn config(&self) -> Result<EndpointConfig, RouteRefusal> {
        EndpointConfig::new(&self.endpoint_spec()).map_err(|e| RouteRefusal::Endpoint(e.into()))
    }
}

/// A MAVLink endpoint setting the firmware refused: which
/// ([`ConfigKey`]'s order) and its value.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EndpointRefusal {
    /// The field: 0 system id, 1 component id, 2 link timeout, 3 item
    /// timeout, 4 item retries, 5 telemetry period, 6 origin latitude,
    /// 7 origin longitude, 8 counters period.
    pub field: u8,
    /// The value given.
    pub value: i64,
}

const CONFIG_KEYS: [ConfigKey; 9] = [
    ConfigKey::SystemId,
    ConfigKey::ComponentId,
    ConfigKey::LinkTimeout,
    ConfigKey::ItemTimeout,
    ConfigKey::ItemRetries,
    ConfigKey::TelemetryPeriod,
    ConfigKey::OriginLatitude,
    ConfigKey::OriginLongitude,
    ConfigKey::CountersPeriod,
];

impl From<ConfigError> for EndpointRefusal {
    fn from(e: ConfigError) -> Self {
        let field = CONFIG_KEYS.iter().position(|k| *k == e.key).unwrap_or(0);
        Self {
            // Nine keys: fits.
            field: u8::try_from(field).unwrap_or(0),
            value: e.value,
        }
    }
}

impl EndpointRefusal {
    /// The refused field.
    #[must_use]
    pub fn key(&self) -> ConfigKey {
        CONFIG_KEYS
            .get(usize::from(self.field))
            .copied()
            .unwrap_or(ConfigKey::SystemId)
    }
}

/// Consecutive waypoints of the announced route, in route order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RouteChunk {
    /// Index of the chunk's first waypoint in the route (the waypoints
    /// loaded before).
    pub first: u8,
    /// The waypoints.
    pub waypoints: heapless::Vec<Waypoint, ROUTE_CHUNK_WAYPOINTS>,
}

/// Why the firmware refused a route.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RouteRefusal {
    /// A route was announced while the firmware was not configured, or
    /// after its run had started ticking, or while a route was loading.
    NotExpected,
    /// The announcement's waypoint count: fewer than 2, or more than the
    /// firmware holds.
    Size {
        /// Waypoints announced.
        waypoints: u8,
        /// Most the firmware holds ([`ROUTE_CAPACITY`]).
        capacity: u8,
    },
    /// The core refused a limit (`RouteLimits::new`), named by its key.
    Limits(RouteLimitsError),
    /// The core refused the follower options (`RouteOptions::new`).
    Options(RouteOptionsError),
    /// A chunk arrived while no route was being loaded.
    NotLoading,
    /// A chunk did not start at the next waypoint to load.
    OutOfOrder {
        /// Index of the next waypoint to load.
        expected: u8,
        /// The chunk's first index.
        first: u8,
    },
    /// A chunk went past the waypoints announced.
    TooMany {
        /// Waypoints announced.
        announced: u8,
    },
    /// The core's planner refused the route (`RoutePlan::replan`), naming
    /// the waypoint and its key where it is one waypoint's fault.
    Route(RouteError),
    /// The MAVLink endpoint's settings (`EndpointConfig::new`), naming
    /// the field and its value. Appended last: the other variants keep
    /// their encoding.
    Endpoint(EndpointRefusal),
}

impl core::fmt::Display for RouteRefusal {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::NotExpected => f.write_str(
                "a route was announced outside a configured run that has not started ticking",
            ),
            Self::Size {
                waypoints,
                capacity,
            } => write!(
                f,
                "the route announced {waypoints} waypoints; the firmware holds 2 to {capacity}"
            ),
            Self::Limits(e) => write!(f, "limits: {e}"),
            Self::Options(e) => write!(f, "options: {e}"),
            Self::NotLoading => {
                f.write_str("a route chunk arrived while no route was being loaded")
            }
            Self::OutOfOrder { expected, first } => write!(
                f,
                "a route chunk starting at waypoint {first} arrived; waypoint {expected} was next"
            ),
            Self::TooMany { announced } => {
                write!(
                    f,
                    "route chunks went past the {announced} waypoints announced"
                )
            }
            Self::Route(e) => write!(f, "{e}"),
            Self::Endpoint(e) => write!(
                f,
                "mavlink: {}",
                ConfigError {
                    key: e.key(),
                    value: e.value,
                }
            ),
        }
    }
}

impl core::error::Error for RouteRefusal {}

/// [`ROUTE_CAPACITY`] as the messages' `u8` (it fits: the link's tests).
pub(crate) const CAPACITY_U8: u8 = if ROUTE_CAPACITY <= u8::MAX as usize {
    ROUTE_CAPACITY as u8
} else {
    u8::MAX
};

/// The messages a host sends, after a configuration is `Configured`, to
/// load `waypoints` as the run's route: the announcement, then the
/// waypoints in chunks of [`ROUTE_CHUNK_WAYPOINTS`]. Each is to be sent
/// after the answer to the one before (`RouteLoaded`, and `Configured`
/// for the last). A `Waypoints` holds at most [`ROUTE_CAPACITY`], which
/// fits the announcement's `u8`.
pub fn route_messages<'w>(
    waypoints: &'w Waypoints,
    limits: RouteLimitsSpec,
    options: &RouteOptions,
    start: RouteStart,
    mavlink: MavlinkSettings,
) -> impl Iterator<Item = HostMessage> + 'w {
    let all = waypoints.as_slice();
    let announce = HostMessage::Route(RouteSpec {
        waypoints: u8::try_from(all.len()).unwrap_or(u8::MAX),
        limits,
        options: options.spec(),
        start,
        mavlink,
    });
    let chunks = all
        .chunks(ROUTE_CHUNK_WAYPOINTS)
        .enumerate()
        .map(|(i, part)| {
            HostMessage::RouteChunk(RouteChunk {
                first: u8::try_from(i * ROUTE_CHUNK_WAYPOINTS).unwrap_or(u8::MAX),
                // At most `ROUTE_CHUNK_WAYPOINTS`: never empty.
                waypoints: heapless::Vec::from_slice(part).unwrap_or_default(),
            })
        });
    core::iter::once(announce).chain(chunks)
}

#[cfg(test)]
mod endpoint_refusal_tests {
    use super::EndpointRefusal;
    use wmr_mavlink::{ConfigError, ConfigKey};

    /// Every setting the endpoint can refuse crosses the link as itself,
    /// so that the host names the key the firmware refused.
    #[test]
    fn every_refused_key_crosses_the_link_as_itself() {
        for key in [
            ConfigKey::SystemId,
            ConfigKey::ComponentId,
            ConfigKey::LinkTimeout,
            ConfigKey::ItemTimeout,
            ConfigKey::ItemRetries,
            ConfigKey::TelemetryPeriod,
            ConfigKey::CountersPeriod,
            ConfigKey::OriginLatitude,
            ConfigKey::OriginLongitude,
        ] {
            let refusal = EndpointRefusal::from(ConfigError { key, value: 19 });
            assert_eq!((refusal.key(), refusal.value), (key, 19));
        }
    }
}
