//! The messages: what the host sends ([`HostMessage`]) and what the
//! firmware answers ([`TargetMessage`]), and their parts.

use serde::{Deserialize, Serialize};
use wmr_core::pilot::spec::{PilotSpec, SpecError};
use wmr_core::pilot::tracker::TrackerMode;

use crate::{
    Diagnostics, FloorSpec, MAX_UART_BYTES_PER_TICK, MapChunk, MapRefusal, MavlinkIn, MavlinkOut,
    RouteChunk, RouteRefusal, RouteSpec,
};

/// What the host sends.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum HostMessage {
    /// Build the pilot and the floor (the firmware validates them with
    /// the core's constructors, as the simulator does).
    Configure(Configure),
    /// The next tags of the tag map `Configure` announced.
    MapChunk(MapChunk),
    /// A route for the run just configured (before its first tick): the
    /// run follows it instead of the pilot's trajectory.
    Route(RouteSpec),
    /// The next waypoints of the route `Route` announced.
    RouteChunk(RouteChunk),
    /// One control tick's device readings.
    Tick(TickInput),
    /// End of run: report and stop.
    Finish,
    /// MAVLink bytes from the ground station, and a request for the
    /// firmware's next output chunk (the crate docs, "MAVLink"). Appended
    /// last: the other variants keep their encoding.
    Mavlink(MavlinkIn),
}

/// Configuration of a run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Configure {
    /// [`PROTOCOL_VERSION`] of the host.
    ///
    /// [`PROTOCOL_VERSION`]: crate::PROTOCOL_VERSION
    pub protocol: u16,
    /// The pilot.
    pub pilot: PilotSpec,
    /// The floor the robot looks its tag ids up in.
    pub floor: FloorSpec,
    /// Full-scale PWM duty the motor proxies report in, steps.
    pub pwm_max_duty: u16,
    /// A telemetry record on the firmware's defmt log every this many
    /// ticks (`tick % n == 0`; 0: none): [`telemetry`].
    ///
    /// [`telemetry`]: crate::telemetry
    pub telemetry_every_ticks: u16,
}

/// What the devices show at one control tick.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TickInput {
    /// Tick index `k` (`t = k·h`), from 0.
    pub tick: u32,
    /// Raw left encoder counter; `None` models a failed read.
    pub left_count: Option<u32>,
    /// Raw right encoder counter; `None` models a failed read.
    pub right_count: Option<u32>,
    /// Bytes the RFID reader's UART received since the last tick.
    pub uart: heapless::Vec<u8, MAX_UART_BYTES_PER_TICK>,
}

/// What the firmware sends.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TargetMessage {
    /// Sent once after reset.
    Hello {
        /// [`PROTOCOL_VERSION`] of the firmware.
        ///
        /// [`PROTOCOL_VERSION`]: crate::PROTOCOL_VERSION
        protocol: u16,
    },
    /// The configuration was accepted.
    Configured,
    /// The configuration was refused (or its protocol version differs).
    Refused(Refusal),
    /// The tag map `Configure` announced is being loaded: send the tags
    /// from this index on (0 after `Configure`; the last chunk is
    /// answered [`Self::Configured`] instead).
    MapLoaded {
        /// Tags loaded so far.
        tags: u16,
    },
    /// The route `Route` announced is being loaded: send the waypoints
    /// from this index on (0 after `Route`; the last chunk is answered
    /// [`Self::Configured`] instead).
    RouteLoaded {
        /// Waypoints loaded so far.
        waypoints: u8,
    },
    /// One tick done.
    Ticked(TickOutput),
    /// Answer to [`HostMessage::Finish`].
    Finished(Finished),
    /// A corrupt frame arrived (and was dropped): the host should resend
    /// its last message.
    Nack,
    /// The link was silent for [`LINK_TIMEOUT_MS`] while configured: the
    /// motors are stopped (as shown) until the next tick.
    ///
    /// [`LINK_TIMEOUT_MS`]: crate::LINK_TIMEOUT_MS
    LinkSilent {
        /// The motors after stopping them.
        motors: [MotorOutput; 2],
        /// Milliseconds of silence when they were stopped.
        silent_ms: u32,
    },
    /// Answer to [`HostMessage::Mavlink`]: the endpoint's next output
    /// bytes.
    Mavlink(MavlinkOut),
}

/// Why a configuration was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Refusal {
    /// The host speaks another protocol version (the firmware's).
    Protocol(u16),
    /// The core refused the spec.
    Spec(SpecError),
    /// The tag map was refused (the run is not configured).
    Map(MapRefusal),
    /// The route was refused (the run is not configured, except for
    /// [`RouteRefusal::NotExpected`] and [`RouteRefusal::NotLoading`],
    /// which change nothing).
    Route(RouteRefusal),
    /// A tick arrived before any configuration.
    NotConfigured,
    /// A tick older than the last one answered (never run late).
    StaleTick {
        /// The tick last answered.
        last_answered: u32,
    },
}

impl core::fmt::Display for Refusal {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Protocol(v) => write!(f, "the firmware speaks link protocol {v}"),
            Self::Spec(e) => write!(f, "the core refused the spec: {e}"),
            Self::Map(e) => write!(f, "the tag map was refused: {e}"),
            Self::Route(e) => write!(f, "the route was refused: {e}"),
            Self::NotConfigured => f.write_str("a tick arrived before any configuration"),
            Self::StaleTick { last_answered } => {
                write!(
                    f,
                    "a tick older than tick {last_answered}, already answered"
                )
            }
        }
    }
}

impl core::error::Error for Refusal {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            Self::Spec(e) => Some(e),
            Self::Map(e) => Some(e),
            Self::Route(e) => Some(e),
            _ => None,
        }
    }
}

/// One motor as the firmware drove it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MotorOutput {
    /// PWM duty, steps of [`Configure::pwm_max_duty`].
    pub duty: u16,
    /// Direction pin high.
    pub direction_high: bool,
}

/// What the firmware did at one tick.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TickOutput {
    /// The tick index this answers.
    pub tick: u32,
    /// Left motor.
    pub left: MotorOutput,
    /// Right motor.
    pub right: MotorOutput,
    /// Tracker mode after the tick.
    pub mode: TrackerMode,
    /// Reference position, m.
    pub reference_m: [f32; 2],
    /// Position used by the law (fix or dead-reckoned), m.
    pub position_m: [f32; 2],
    /// Heading estimate `(cos θ̂, sin θ̂)`.
    pub heading: [f32; 2],
    /// Body command `(v m/s, ω rad/s)`.
    pub command: [f32; 2],
    /// A tag fix passed the tracker's checks this tick and went to the
    /// estimator (`TrackerOutput::fix_used`).
    pub fix: bool,
    /// The drive's wheel-speed limit scaled the command this tick.
    pub speed_limited: bool,
    /// The drive's acceleration limit acted this tick.
    pub accel_limited: bool,
}

/// The end-of-run report.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Finished {
    /// Ticks run.
    pub ticks: u32,
    /// Deepest stack use since reset, bytes (stack painting).
    pub peak_stack_bytes: u32,
    /// The motors as they are now (stopped if the link went silent since
    /// the last tick).
    pub motors: [MotorOutput; 2],
    /// Final counters.
    pub counters: Diagnostics,
    /// The run's route is done: at rest on its last waypoint, settled
    /// (`RouteStatus::done`; false for a run without a route).
    pub route_done: bool,
}
