//! The robot's MAVLink 2 endpoint: `no_std`, no heap, no `unsafe`, no
//! panic on any input, `f32` only.
//!
//! A [`MavlinkEndpoint`] takes the bytes received from a ground station
//! (QGroundControl, MAVProxy, pymavlink, MAVSDK, mavros) and answers in
//! MAVLink 2 frames written into a caller's buffer ([`TxBuffer`]). It talks
//! to the robot through plain values: each [`MavlinkEndpoint::handle`] call
//! is given what the robot reports ([`RobotView`]: armed, mode, estimate,
//! current and reached waypoints) and returns what the robot must do
//! ([`Events`]: load a route, arm, start, pause, stop, link lost, …). A
//! mission is a route of the core ([`wmr_core::reference::route`]).
//!
//! # Protocol
//!
//! * In: MAVLink 1 and 2 frames (parser in [`wire`]: garbage skipped, CRC
//!   errors counted, a frame after garbage found again; signed frames
//!   dropped). Out: MAVLink 2, sequence numbered.
//! * `HEARTBEAT` at 1 Hz (and on a mode change): `MAV_TYPE_GROUND_ROVER`,
//!   `MAV_AUTOPILOT_GENERIC`, `custom_mode` = [`RobotMode`] number,
//!   `SAFETY_ARMED` when armed, `AUTO_ENABLED` while running or paused.
//!   A ground station's or companion computer's heartbeat (`MAV_TYPE_GCS`,
//!   `MAV_TYPE_ONBOARD_CONTROLLER`) starts the link watch:
//!   none for the link timeout → [`Event::LinkLost`] once and a
//!   `STATUSTEXT`; a heartbeat again → "link regained".
//! * The mission microservice ([`upload`] module), items as in
//!   [`mission`]; frames mapped as in [`geo`].
//! * Commands ([`command`] module), answered with `COMMAND_ACK`.
//! * Parameters ([`params`] module): the route limits, the link timeout,
//!   the telemetry and counters periods, law (27)–(28)'s gains and the
//!   failsafe times, each checked by its constructor.
//! * Telemetry ([`telemetry`] module) at the configured period: `LOCAL_POSITION_NED`,
//!   `ATTITUDE`, and `GLOBAL_POSITION_INT` with a geodetic origin;
//!   `SYS_STATUS` with the endpoint's counters at 1 Hz; the tracker's and
//!   RFID reader's counters as `NAMED_VALUE_INT`, round-robin.
//!
//! The tables of messages, commands and results are in docs/mavlink.md.
//!
//! # The library: `mavlink` 0.21 rather than `mavio` 0.5
//!
//! Both generate the `common` dialect from its XML at build time. Measured
//! with the same harness (a `no_std` binary for `thumbv7em-none-eabihf`,
//! fat LTO) that decodes HEARTBEAT, MISSION_ITEM_INT, COMMAND_LONG,
//! MISSION_COUNT and serialises HEARTBEAT, MISSION_ITEM_INT, COMMAND_ACK,
//! MISSION_COUNT, LOCAL_POSITION_NED: `mavlink` (no default features,
//! `dialect-common`, `embedded`) 7,890 B of `.text` + 512 B `.rodata` at
//! opt-level `s` (9,332 + 512 B at 3); `mavio` (`dlct-common`) 10,464 +
//! 519 B (13,314 + 519 B at 3). `mavlink`'s per-message `MessageData`
//! (`ser`, `ID`, `EXTRA_CRC`) lets the linker keep only the messages used
//! (no dialect-wide enum match is called), with neither trait objects nor
//! a 255-byte payload copy per message as `mavio`'s `&dyn Message` frame
//! builder has. This crate uses its serialisers, constants and CRC; its
//! readers (pull-based over `Read`) are not used, and fields are read by
//! their wire layout because its decoder refuses an enum value it does
//! not know (an unknown command must still be answered).
//!
//! The whole endpoint adds 18,924 B of flash at opt-level 3 (the
//! firmware's release profile: over the 16 KiB goal by 2.5 KiB)
//! and 13,702 B at opt-level `s`, measured by difference with
//! `firmware/mavlink/size`; 3,544 B of RAM (on the host). Details in
//! docs/mavlink.md.
//!
//! # Robustness
//!
//! Every byte sequence is accepted: checked indexing only, counters
//! wrap, and a message's fields are read from its wire layout
//! zero-extended to 255 bytes. Every refusal is answered (the
//! `MAV_MISSION_RESULT` or `MAV_RESULT`) and counted in [`Counters`].
#![no_std]
#![forbid(unsafe_code)]

pub mod command;
pub mod config;
pub mod endpoint;
pub mod geo;
pub mod mission;
pub mod params;
pub mod progress;
pub mod runner;
pub mod telemetry;
pub mod upload;
pub mod wire;

pub use config::{ConfigError, ConfigKey, EndpointConfig, EndpointSpec};
pub use endpoint::{
    Counters, EVENT_CAPACITY, Estimate, Event, Events, MavlinkEndpoint, RobotMode, RobotView,
};
pub use mission::{Item, Mission};
pub use progress::Progress;
pub use runner::{Applied, FollowerAction, MissionRunner, Note};
pub use telemetry::{COUNTER_NAMES, COUNTERS, Counts};
pub use wire::{RxCounters, TxBuffer};
