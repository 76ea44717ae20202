//! A route over the link (the crate docs, "The route"): its announcement,
//! its waypoints in chunks, why the firmware refuses one, and the messages
//! a host sends for a route ([`route_messages`]).

use serde::{Deserialize, Serialize};
use wmr_core::pilot::route::{RouteOptions, RouteOptionsError, RouteOptionsSpec, RouteStart};
use wmr_core::reference::route::{
    ROUTE_CAPACITY, RouteError, RouteLimitsError, RouteLimitsSpec, Waypoint, Waypoints,
};

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
) -> impl Iterator<Item = HostMessage> + 'w {
    let all = waypoints.as_slice();
    let announce = HostMessage::Route(RouteSpec {
        waypoints: u8::try_from(all.len()).unwrap_or(u8::MAX),
        limits,
        options: options.spec(),
        start,
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
