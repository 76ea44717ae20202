//! The lock-step hardware-in-the-loop link between the firmware and the
//! host simulator, defined once for both sides.
//!
//! # Protocol
//! The firmware runs its board's devices as proxies over one byte stream
//! (QEMU's `netduinoplus2`: two host files through semihosting, see
//! [`HIL_TO_TARGET_FILE`]; a serial port would do as well). The host is the world: it plays the
//! motors, encoders and RFID reader.
//!
//! ```text
//! firmware                                   host (firmware-sim hil)
//!    │ ── Hello ─────────────────────────────────► │  after reset
//!    │ ◄──────────────── Configure{pilot, floor} ─ │
//!    │ ── Configured | Refused(SpecError) ───────► │  floor: Grid(spec)
//!    │ ── MapLoaded{0} | Refused(Map(..)) ───────► │  floor: Map{tags: n}
//!    │ ◄──── MapChunk{first, ≤ MAP_CHUNK_TAGS tags} │  ─┐ ids increasing,
//!    │ ── MapLoaded{tags so far} | Refused(Map) ─► │   │ until n are
//!    │      ... (the last chunk: Configured) ...   │  ─┘ loaded
//!    │ ◄──── Route{n, limits, options, start} ───── │  optional: a route
//!    │ ── RouteLoaded{0} | Refused(Route(..)) ───► │
//!    │ ◄── RouteChunk{first, ≤ ROUTE_CHUNK_WAYPOINTS} ─┐ in route order,
//!    │ ── RouteLoaded{so far} | Refused(Route) ──► │   │ until n are
//!    │      ... (the last chunk: Configured) ...   │  ─┘ loaded
//!    │ ◄───────── Tick{k, encoder counters, UART bytes}
//!    │ ── Ticked{k, duties, directions, estimate, drive limits}
//!    │                 ... once per control tick ...
//!    │ ◄──────────────────────────────── Finish ─ │
//!    │ ── Finished{ticks, stack, all counters} ──► │  then exits (semihosting)
//! ```
//!
//! Each side sends the next message only after the answer to the last, so
//! the run is deterministic whatever the speed of QEMU or of the host.
//!
//! # The floor
//! A tag grid travels in `Configure` ([`FloorSpec::Grid`]). A tag map
//! (surveyed tags with arbitrary ids, a robot file's `floor.kind =
//! "tag_map"`) does not fit one frame: `Configure` announces its size
//! ([`FloorSpec::Map`]), the firmware answers [`TargetMessage::MapLoaded`]
//! with 0 tags, and the map follows in [`MapChunk`]s of at most
//! [`MAP_CHUNK_TAGS`] tags in increasing id order, each acknowledged with
//! the tags loaded so far; the last is answered `Configured`. The firmware
//! loads the tags into the core's `TagMap` of [`MAP_CAPACITY`] tags, in
//! place, with its own checks (`TagMap::push`: finite positions, ids
//! increasing, so unique, capacity), and refuses a size it cannot hold, a
//! chunk out of order, a tag past the announced count, or a tag the core
//! refuses, naming which and why ([`MapRefusal`]); a refused map leaves it
//! unconfigured with its motors stopped. A chunk when no map is loading is
//! refused and changes nothing (a running robot runs on). A chunk sent again (its answer lost) is answered again,
//! not loaded twice. The configuration goes over a clean link (the
//! fault injector acts on the ticks only).
//!
//! # The route
//! A run may follow a route (the core's `reference::route`, through
//! `Pilot::step_route`) instead of the pilot's trajectory. Once the run
//! is `Configured` (its map, if any, loaded) and before its first tick,
//! [`HostMessage::Route`] announces it ([`RouteSpec`]: the waypoint count,
//! the `RouteLimitsSpec`, the follower's options, the start); the
//! firmware checks the count (2 to `ROUTE_CAPACITY`), the limits
//! (`RouteLimits::new`) and the options (`RouteOptions::new`) and answers
//! [`TargetMessage::RouteLoaded`] with 0 waypoints. The waypoints follow
//! in [`RouteChunk`]s of at most [`ROUTE_CHUNK_WAYPOINTS`], in route
//! order, loaded in place into the core's `Waypoints` and acknowledged
//! with the count so far; after the last, the firmware plans the route
//! with the core (`RoutePlan::replan`, into a scratch plan: a refusal
//! names the waypoint and its key), hands it to its `RouteFollower` and
//! answers `Configured`. A count, limit, option, chunk out of order, a
//! waypoint past the count or a route the planner refuses is refused,
//! naming which and why ([`RouteRefusal`]), and leaves the firmware
//! unconfigured with its motors stopped. A route announced outside that
//! window, or a chunk when none is loading, is refused and changes
//! nothing. A chunk sent again (its answer lost) is answered again, not
//! loaded twice. [`route_messages`] gives a host the messages to send.
//! With `RouteStart::FromFirstFix` the first waypoint is replaced by the
//! robot's position when the route starts, so the planner's verdict then
//! may differ: the follower counts such a refusal
//! (`RouteCounters::routes_refused`, in [`Finished`]) and holds the robot
//! still.
//!
//! # MAVLink
//! A ground station's MAVLink bytes cross the link as a channel beside
//! the devices, outside the lock-step of the ticks, so a run without a
//! ground station sends exactly the frames it sent before the channel
//! existed. [`HostMessage::Mavlink`] ([`MavlinkIn`]) carries up to
//! [`MAVLINK_CHUNK_BYTES`] bytes received from the ground station; the
//! firmware queues them for its endpoint's next tick and answers
//! [`TargetMessage::Mavlink`] ([`MavlinkOut`]) with the next chunk of
//! the bytes its endpoint wrote and how many are still queued; the host
//! asks again with no bytes until none are. The firmware's queues are
//! bounded ([`MavlinkQueues`]): bytes or frames that do not fit are
//! dropped and counted ([`MavlinkCounters`], in every answer). A message
//! sent again (its answer lost) carries the same `seq` and is answered
//! again from a cache, its bytes not queued twice.
//!
//! ```text
//!    │ ◄──── Mavlink{seq, ≤ MAVLINK_CHUNK_BYTES from the GCS} ─ │  any time
//!    │ ── Mavlink{seq, next output chunk, pending, counters} ─► │  configured
//! ```
//!
//! Between those queues and the robot, the endpoint, the mission runner
//! and the follower actions are [`mavlink_run`]'s, which the Black Pill
//! runs on its MAVLink UART too.
//!
//! # Faults
//! A frame that arrives corrupt is dropped and counted, and the firmware
//! answers it with [`TargetMessage::Nack`], so that the host resends its
//! last message at once instead of waiting for a timeout. The host resends
//! a tick whose answer does not come (lost either way); the firmware
//! answers a tick it already ran again from its cached answer, without
//! running it twice ([`Diagnostics::repeated_ticks`]). A frame whose
//! sequence number is behind the last accepted one (a duplicate, or one
//! overtaken by a newer frame) is dropped and counted
//! ([`LinkCounters::stale_frames`]): stale data is never used as fresh.
//! After [`LINK_TIMEOUT_MS`] without a valid frame the firmware stops the
//! motors and says so ([`TargetMessage::LinkSilent`]).
//!
//! # Framing
//! One frame is `COBS(postcard(Frame{seq, body}) ‖ CRC-32(…) as LE u32) ‖ 0x00`.
//! - **postcard** (serde) encodes the message compactly (varints).
//! - **CRC-32** (ISO-HDLC, the Ethernet/zlib polynomial) over the postcard
//!   bytes catches corruption that still decodes; COBS alone does not.
//! - **COBS** removes every zero byte, so `0x00` marks the end of a frame and
//!   a receiver resynchronises at the next `0x00` after any garbage.
//! - **`seq`** counts each side's frames from 0 (wrapping); a receiver
//!   counts gaps (lost frames) and drops stale frames (at most
//!   [`STALE_WINDOW`] behind; further behind is a restart of the peer).
//!
//! Nothing allocates; buffers are sized by [`MAX_FRAME_BYTES`].

#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::indexing_slicing
    )
)]

pub mod image;
pub mod mavlink_run;
pub mod period_clock;
pub mod proxy;
pub mod route_store;
pub mod rx_ring;
pub mod session;
pub mod telemetry;

mod channel;
mod codec;
mod diagnostics;
mod floor;
mod mavlink;
mod message;
mod protocol;
mod route;
#[cfg(test)]
mod tests;

pub use channel::{Receiver, Sender};
pub use codec::{Frame, LinkError, decode, encode};
pub use diagnostics::{DIAGNOSTIC_COUNTERS, Diagnostics, LinkCounters};
pub use floor::{FloorSpec, MapChunk, MapRefusal, MapTag};
pub use mavlink::{
    MAVLINK_RX_QUEUE_BYTES, MAVLINK_TX_QUEUE_BYTES, MavlinkChunk, MavlinkCounters, MavlinkIn,
    MavlinkOut, MavlinkQueues,
};
pub use message::{
    Configure, Finished, HostMessage, MotorOutput, Refusal, TargetMessage, TickInput, TickOutput,
};
pub use protocol::{
    HIL_TO_HOST_PIPE, HIL_TO_TARGET_FILE, LINK_TIMEOUT_MS, MAP_CAPACITY, MAP_CHUNK_TAGS,
    MAVLINK_CHUNK_BYTES, MAX_FRAME_BYTES, MAX_UART_BYTES_PER_TICK, PROTOCOL_VERSION,
    ROUTE_CHUNK_WAYPOINTS, STALE_WINDOW,
};
pub use route::{
    EndpointRefusal, MavlinkSettings, PowerOn, RouteChunk, RouteRefusal, RouteSpec, route_messages,
};
pub use wmr_core::pilot::route::RouteOptionsSpec;
