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
pub mod proxy;
pub mod session;
pub mod telemetry;

use serde::{Deserialize, Serialize};
use wmr_core::devices::tag_grid::TagGridSpec;
use wmr_core::devices::{RfidCounters, TagMapError};
use wmr_core::pilot::PilotCounters;
use wmr_core::pilot::robot::RobotCounters;
use wmr_core::pilot::spec::{PilotSpec, SpecError};
use wmr_core::pilot::tracker::{TrackerCounters, TrackerMode};

/// The link's version: bump when a message changes shape; both sides
/// refuse a mismatch. What each version changed: `CHANGELOG.md`, "HIL
/// link protocol versions".
pub const PROTOCOL_VERSION: u16 = 13;

/// Most tags the firmware's tag map holds under HIL (the QEMU board's
/// static table: 16 B a tag, 64 KiB of its 128 KiB of RAM): the robot
/// file's own cap (`firmware-sim`'s `scenario::robot::MAX_MAPPED_TAGS`, the
/// Black Pill's flash table), so that every robot file runs under HIL.
pub const MAP_CAPACITY: usize = 4096;

/// Tags one [`MapChunk`] carries at most: the most whose chunk is no
/// larger in RAM than `Configure` (14 × 16 B + its length: 240 of 248 B),
/// so that [`HostMessage`] does not grow and the firmware's receive path
/// needs no more stack; its largest frame (every id at its longest
/// varint, 10 B) is 268 of the [`MAX_FRAME_BYTES`]
/// (`a_full_map_chunk_fits_a_frame`).
pub const MAP_CHUNK_TAGS: usize = 14;

/// Silence on the link, while configured, after which the firmware stops
/// the motors, ms (five 10 ms control periods).
pub const LINK_TIMEOUT_MS: u32 = 50;

/// The QEMU board's link, host to firmware: a regular file the host
/// appends its frames to and the firmware reads through semihosting, from
/// QEMU's working directory (`firmware/src/board/qemu.rs`).
pub const HIL_TO_TARGET_FILE: &core::ffi::CStr = c"wmr-link-to-target";

/// The QEMU board's link, firmware to host: a named pipe the firmware
/// writes its frames to through semihosting and the host reads, in QEMU's
/// working directory.
pub const HIL_TO_HOST_PIPE: &core::ffi::CStr = c"wmr-link-to-host";

/// A frame at most this many sequence numbers behind the next expected one
/// is stale (a duplicate, or overtaken by a newer frame) and dropped;
/// further behind, it is taken as a restart of the peer and accepted.
pub const STALE_WINDOW: u32 = 64;

/// Largest encoded frame, bytes, including COBS overhead and the `0x00`.
pub const MAX_FRAME_BYTES: usize = 512;

/// Largest postcard payload plus CRC before COBS (COBS adds 1 byte per 254).
const MAX_RAW_BYTES: usize = MAX_FRAME_BYTES - MAX_FRAME_BYTES / 254 - 2;

/// UART bytes the host can hand over in one tick. At 115 200 Bd a 10 ms
/// tick carries at most 116 bytes.
pub const MAX_UART_BYTES_PER_TICK: usize = 160;

/// What the host sends.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum HostMessage {
    /// Build the pilot and the floor (the firmware validates them with
    /// the core's constructors, as the simulator does).
    Configure(Configure),
    /// The next tags of the tag map `Configure` announced.
    MapChunk(MapChunk),
    /// One control tick's device readings.
    Tick(TickInput),
    /// End of run: report and stop.
    Finish,
}

/// Configuration of a run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Configure {
    /// [`PROTOCOL_VERSION`] of the host.
    pub protocol: u16,
    /// The pilot.
    pub pilot: PilotSpec,
    /// The floor the robot looks its tag ids up in.
    pub floor: FloorSpec,
    /// Full-scale PWM duty the motor proxies report in, steps.
    pub pwm_max_duty: u16,
    /// A telemetry record on the firmware's defmt log every this many
    /// ticks (`tick % n == 0`; 0: none): [`telemetry`].
    pub telemetry_every_ticks: u16,
}

/// The floor of a run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FloorSpec {
    /// A regular grid, ids in the core's grid encoding: all of it here.
    Grid(TagGridSpec),
    /// A tag map of `tags` tags (1 to [`MAP_CAPACITY`]), sent next in
    /// [`MapChunk`]s.
    Map {
        /// Tags in the map.
        tags: u16,
    },
}

/// One tag of a tag map.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MapTag {
    /// The tag's id (as the reader reports it).
    pub id: u64,
    /// The tag's position, m, world frame.
    pub position_m: [f32; 2],
}

/// Consecutive tags of a tag map, in increasing id order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MapChunk {
    /// Index of the chunk's first tag in the map (the tags loaded before).
    pub first: u16,
    /// The tags.
    pub tags: heapless::Vec<MapTag, MAP_CHUNK_TAGS>,
}

/// Why the firmware refused a tag map.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MapRefusal {
    /// `Configure` announced `tags` tags: none, or more than the firmware
    /// holds.
    Size {
        /// Tags announced.
        tags: u16,
        /// Most the firmware holds ([`MAP_CAPACITY`]).
        capacity: u16,
    },
    /// A chunk arrived while no tag map was being loaded.
    NotLoading,
    /// A chunk did not start at the next tag to load.
    OutOfOrder {
        /// Index of the next tag to load.
        expected: u16,
        /// The chunk's first index.
        first: u16,
    },
    /// A chunk went past the tags `Configure` announced.
    TooMany {
        /// Tags announced.
        announced: u16,
    },
    /// The core's `TagMap` refused a tag (`TagMap::push`).
    Tag {
        /// Index of the tag in the map (the host knows its id).
        index: u16,
        /// Why: a non-finite position, an id not above the one before
        /// (a duplicate, or out of order), the map full.
        why: TagMapError,
    },
}

impl core::fmt::Display for MapRefusal {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::Size { tags, capacity } => write!(
                f,
                "Configure announced {tags} tags; the firmware holds 1 to {capacity}"
            ),
            Self::NotLoading => f.write_str("a map chunk arrived while no tag map was announced"),
            Self::OutOfOrder { expected, first } => write!(
                f,
                "a map chunk starting at tag {first} arrived; tag {expected} was next"
            ),
            Self::TooMany { announced } => {
                write!(f, "map chunks went past the {announced} tags announced")
            }
            Self::Tag { index, why } => write!(f, "tag {index}: {why}"),
        }
    }
}

impl core::error::Error for MapRefusal {}

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
    /// One tick done.
    Ticked(TickOutput),
    /// Answer to [`HostMessage::Finish`].
    Finished(Finished),
    /// A corrupt frame arrived (and was dropped): the host should resend
    /// its last message.
    Nack,
    /// The link was silent for [`LINK_TIMEOUT_MS`] while configured: the
    /// motors are stopped (as shown) until the next tick.
    LinkSilent {
        /// The motors after stopping them.
        motors: [MotorOutput; 2],
        /// Milliseconds of silence when they were stopped.
        silent_ms: u32,
    },
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

/// Every counter of the firmware, cumulative since configuration.
///
/// Serialized flat ([`Diagnostics::flat`], in field order, nested structs
/// in place), which in postcard is byte for byte what the derived
/// serializer writes, and what the derived deserializer reads: one
/// varint loop in the firmware's flash instead of one inlined encoder per
/// counter (about 1 KB on the QEMU board).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Diagnostics {
    /// The RFID frame parser.
    pub rfid: RfidCounters,
    /// Device faults of the robot.
    pub robot: RobotCounters,
    /// Encoder fault handling of the pilot.
    pub pilot: PilotCounters,
    /// Fix handling of the tracker.
    pub tracker: TrackerCounters,
    /// Observer updates skipped for non-finite input.
    pub observer_rejected_updates: u32,
    /// The link itself.
    pub link: LinkCounters,
    /// UART bytes the proxy could not buffer (overrun), lost.
    pub uart_overruns: u32,
    /// Ticks received again after their answer (the host resent them
    /// because the answer was lost): answered again, not run again.
    pub repeated_ticks: u32,
    /// Ticks older than the last one answered: refused, never run.
    pub stale_ticks: u32,
}

/// Counters in [`Diagnostics`], all `u32`.
pub const DIAGNOSTIC_COUNTERS: usize = 34;

impl Diagnostics {
    /// Every counter, in the order of the fields (nested structs' fields
    /// in place): the wire form.
    #[must_use]
    pub fn flat(&self) -> [u32; DIAGNOSTIC_COUNTERS] {
        // Destructured to the last field, so that a counter added anywhere
        // fails to compile here until it has its place on the wire.
        let Self {
            rfid:
                RfidCounters {
                    frames_ok: rfid_frames_ok,
                    bad_checksum,
                    malformed,
                    bytes_outside_frames,
                    read_errors,
                    superseded,
                    backlogged_polls,
                },
            robot:
                RobotCounters {
                    left_encoder_errors,
                    right_encoder_errors,
                    unknown_tags,
                    motor_faults,
                },
            pilot:
                PilotCounters {
                    encoder_fault_ticks,
                    implausible_encoder_reads,
                    encoder_halt_ticks,
                },
            tracker:
                TrackerCounters {
                    fixes_used,
                    invalid_fixes,
                    stale_fixes,
                    dead_reckoned_steps,
                    failsafe_entries,
                    non_finite_commands,
                    reference_standstill_ticks,
                    fixes_gated,
                    relocalisations,
                    heading_resets,
                },
            observer_rejected_updates,
            link:
                LinkCounters {
                    frames_ok: link_frames_ok,
                    corrupt_frames,
                    sequence_gaps,
                    stale_frames,
                    timeouts,
                    unexpected_messages,
                },
            uart_overruns,
            repeated_ticks,
            stale_ticks,
        } = *self;
        [
            rfid_frames_ok,
            bad_checksum,
            malformed,
            bytes_outside_frames,
            read_errors,
            superseded,
            backlogged_polls,
            left_encoder_errors,
            right_encoder_errors,
            unknown_tags,
            motor_faults,
            encoder_fault_ticks,
            implausible_encoder_reads,
            encoder_halt_ticks,
            fixes_used,
            invalid_fixes,
            stale_fixes,
            dead_reckoned_steps,
            failsafe_entries,
            non_finite_commands,
            reference_standstill_ticks,
            fixes_gated,
            relocalisations,
            heading_resets,
            observer_rejected_updates,
            link_frames_ok,
            corrupt_frames,
            sequence_gaps,
            stale_frames,
            timeouts,
            unexpected_messages,
            uart_overruns,
            repeated_ticks,
            stale_ticks,
        ]
    }
}

impl Serialize for Diagnostics {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeTuple as _;
        let mut tuple = serializer.serialize_tuple(DIAGNOSTIC_COUNTERS)?;
        for counter in self.flat() {
            tuple.serialize_element(&counter)?;
        }
        tuple.end()
    }
}

/// Faults of the link, as one side saw them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LinkCounters {
    /// Frames received and accepted.
    pub frames_ok: u32,
    /// Frames dropped: bad COBS, bad CRC, undecodable, or too long.
    pub corrupt_frames: u32,
    /// Frames missing between two accepted ones (by sequence number).
    pub sequence_gaps: u32,
    /// Intact frames dropped because their sequence number was behind the
    /// next expected one (duplicates, or overtaken by a newer frame).
    pub stale_frames: u32,
    /// Times the link was silent past the timeout (motors stopped).
    pub timeouts: u32,
    /// Messages that made no sense in the current state (e.g. a tick
    /// before the configuration), answered with a refusal.
    pub unexpected_messages: u32,
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
}

/// A message with its sequence number.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Frame<M> {
    /// Sender's frame count, from 0, wrapping.
    pub seq: u32,
    /// The message.
    pub body: M,
}

/// Why a frame could not be encoded or decoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LinkError {
    /// The message does not fit in [`MAX_FRAME_BYTES`] (encoding), or the
    /// received frame was longer (decoding).
    TooLong,
    /// Not valid COBS.
    Cobs,
    /// Shorter than a CRC.
    TooShort,
    /// CRC mismatch.
    Crc,
    /// postcard could not decode the payload as the expected message.
    Decode,
    /// An intact frame behind the next expected sequence number (a
    /// duplicate, or overtaken by a newer frame): dropped, not corrupt.
    Stale,
}

impl core::fmt::Display for LinkError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::TooLong => "frame longer than MAX_FRAME_BYTES",
            Self::Cobs => "frame is not valid COBS",
            Self::TooShort => "frame shorter than its CRC",
            Self::Crc => "frame CRC mismatch",
            Self::Decode => "frame payload does not decode as the expected message",
            Self::Stale => "stale frame: behind the next expected sequence number",
        })
    }
}

impl core::error::Error for LinkError {}

/// CRC-32 (ISO HDLC), computed bit by bit: the byte-wise table would cost
/// 1 KiB of the QEMU board's flash, which it needs for the fusion
/// estimator; a frame of about 100 bytes then takes a few thousand
/// instructions more, against the lock-step exchange's milliseconds.
const CRC: crc::Crc<u32, crc::NoTable> = crc::Crc::<u32, crc::NoTable>::new(&crc::CRC_32_ISO_HDLC);

/// Encodes `frame` into `out`; returns the frame's bytes (ending in `0x00`).
///
/// # Errors
/// [`LinkError::TooLong`] if the frame does not fit.
pub fn encode<'a, M: Serialize>(
    frame: &Frame<M>,
    out: &'a mut [u8; MAX_FRAME_BYTES],
) -> Result<&'a [u8], LinkError> {
    let mut raw = [0_u8; MAX_RAW_BYTES];
    let payload_len = postcard::to_slice(frame, &mut raw)
        .map_err(|_| LinkError::TooLong)?
        .len();
    let crc = CRC.checksum(raw.get(..payload_len).ok_or(LinkError::TooLong)?);
    raw.get_mut(payload_len..payload_len + 4)
        .ok_or(LinkError::TooLong)?
        .copy_from_slice(&crc.to_le_bytes());
    let raw = raw.get(..payload_len + 4).ok_or(LinkError::TooLong)?;
    // Leave the last byte for the terminator.
    let (body, _) = out.split_at_mut(MAX_FRAME_BYTES - 1);
    let n = cobs::try_encode(raw, body).map_err(|_| LinkError::TooLong)?;
    let terminator = out.get_mut(n).ok_or(LinkError::TooLong)?;
    *terminator = 0;
    out.get(..=n).ok_or(LinkError::TooLong)
}

/// Decodes one frame's COBS bytes (without the `0x00`), in place.
///
/// # Errors
/// Which check failed.
pub fn decode<'de, M: Deserialize<'de>>(cobs_bytes: &'de mut [u8]) -> Result<Frame<M>, LinkError> {
    let n = cobs_decode_in_place(cobs_bytes)?;
    let raw = cobs_bytes.get(..n).ok_or(LinkError::Cobs)?;
    let payload_len = n.checked_sub(4).ok_or(LinkError::TooShort)?;
    let (payload, crc_bytes) = raw
        .split_at_checked(payload_len)
        .ok_or(LinkError::TooShort)?;
    let crc: [u8; 4] = crc_bytes.try_into().map_err(|_| LinkError::TooShort)?;
    if CRC.checksum(payload) != u32::from_le_bytes(crc) {
        return Err(LinkError::Crc);
    }
    postcard::from_bytes(payload).map_err(|_| LinkError::Decode)
}

/// COBS-decodes `buf` in place up to its first `0x00` (or its end) and
/// returns the decoded length: the decoding of `cobs::decode_in_place`
/// (0.5), the same result and the same frames refused, with every access
/// checked. The crate's own decoder indexes its buffer (`buf[i]`), two
/// bounds checks that LTO cannot remove and so two panic paths in the
/// firmware's control loop; this one has none (`cargo xtask panic-free`).
///
/// # Errors
/// [`LinkError::Cobs`]: empty, or a code byte pointing past the end.
fn cobs_decode_in_place(buf: &mut [u8]) -> Result<usize, LinkError> {
    if buf.is_empty() {
        return Err(LinkError::Cobs);
    }
    let end = buf.iter().position(|&b| b == 0).unwrap_or(buf.len());
    let mut read = 0;
    let mut write = 0;
    while read < end {
        // Non-zero: `end` is the first zero.
        let code = usize::from(*buf.get(read).ok_or(LinkError::Cobs)?);
        // The next code byte, or the end, must come no later than `end`
        // (a code of 1 is a lone zero, always in range).
        if read + code > end && code != 1 {
            return Err(LinkError::Cobs);
        }
        read += 1;
        for _ in 1..code {
            let byte = *buf.get(read).ok_or(LinkError::Cobs)?;
            // `write < read` throughout: the output trails the input.
            *buf.get_mut(write).ok_or(LinkError::Cobs)? = byte;
            read += 1;
            write += 1;
        }
        // A block shorter than 254 data bytes stood for a zero, unless it
        // was the last.
        if code != 0xFF && read < end {
            *buf.get_mut(write).ok_or(LinkError::Cobs)? = 0;
            write += 1;
        }
    }
    Ok(write)
}

/// Collects received bytes into frames (split at `0x00`).
///
/// Feed bytes with [`Self::push`]; a complete frame comes back as
/// `Some(Ok(frame))` or `Some(Err(why))`. Too-long frames are discarded up
/// to the next `0x00` and reported once, as [`LinkError::TooLong`].
#[derive(Debug)]
pub struct Receiver {
    buf: [u8; MAX_FRAME_BYTES],
    len: usize,
    overflowed: bool,
    next_seq: Option<u32>,
    counters: LinkCounters,
}

impl Default for Receiver {
    fn default() -> Self {
        Self::new()
    }
}

impl Receiver {
    /// An empty receiver.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            buf: [0; MAX_FRAME_BYTES],
            len: 0,
            overflowed: false,
            next_seq: None,
            counters: LinkCounters {
                frames_ok: 0,
                corrupt_frames: 0,
                sequence_gaps: 0,
                stale_frames: 0,
                timeouts: 0,
                unexpected_messages: 0,
            },
        }
    }

    /// Takes one byte; returns a message when a frame ends. Corrupt frames
    /// and sequence gaps are counted here ([`Self::counters`]).
    pub fn push<M: for<'de> Deserialize<'de>>(&mut self, byte: u8) -> Option<Result<M, LinkError>> {
        if byte != 0 {
            match self.buf.get_mut(self.len) {
                Some(slot) => {
                    *slot = byte;
                    self.len += 1;
                }
                None => self.overflowed = true,
            }
            return None;
        }
        let len = core::mem::take(&mut self.len);
        if core::mem::take(&mut self.overflowed) {
            self.counters.corrupt_frames = self.counters.corrupt_frames.saturating_add(1);
            return Some(Err(LinkError::TooLong));
        }
        if len == 0 {
            // Back-to-back terminators: an empty frame, used to flush a line.
            return None;
        }
        let result = self
            .buf
            .get_mut(..len)
            .ok_or(LinkError::TooLong)
            .and_then(decode::<M>);
        Some(match result {
            Ok(frame) => {
                if let Some(expected) = self.next_seq {
                    let behind = expected.wrapping_sub(frame.seq);
                    if (1..=STALE_WINDOW).contains(&behind) {
                        // A duplicate or an overtaken frame: never used.
                        self.counters.stale_frames = self.counters.stale_frames.saturating_add(1);
                        return Some(Err(LinkError::Stale));
                    }
                    let gap = frame.seq.wrapping_sub(expected);
                    // Far behind: a restart of the peer; one gap.
                    let gap = if gap > u32::MAX / 2 { 1 } else { gap };
                    self.counters.sequence_gaps = self.counters.sequence_gaps.saturating_add(gap);
                }
                self.counters.frames_ok = self.counters.frames_ok.saturating_add(1);
                self.next_seq = Some(frame.seq.wrapping_add(1));
                Ok(frame.body)
            }
            Err(e) => {
                self.counters.corrupt_frames = self.counters.corrupt_frames.saturating_add(1);
                Err(e)
            }
        })
    }

    /// Counts a silent-link timeout.
    pub fn note_timeout(&mut self) {
        self.counters.timeouts = self.counters.timeouts.saturating_add(1);
    }

    /// Counts a message that made no sense in the current state.
    pub fn note_unexpected(&mut self) {
        self.counters.unexpected_messages = self.counters.unexpected_messages.saturating_add(1);
    }

    /// The counters.
    #[must_use]
    pub fn counters(&self) -> LinkCounters {
        self.counters
    }
}

/// Numbers outgoing frames.
#[derive(Debug, Default, Clone, Copy)]
pub struct Sender {
    seq: u32,
}

impl Sender {
    /// The sequence number the next frame will carry.
    #[must_use]
    pub fn next_seq(&self) -> u32 {
        self.seq
    }

    /// Encodes the next frame into `out`.
    ///
    /// # Errors
    /// [`LinkError::TooLong`].
    pub fn frame<'a, M: Serialize>(
        &mut self,
        body: M,
        out: &'a mut [u8; MAX_FRAME_BYTES],
    ) -> Result<&'a [u8], LinkError> {
        let bytes = encode(
            &Frame {
                seq: self.seq,
                body,
            },
            out,
        )?;
        self.seq = self.seq.wrapping_add(1);
        Ok(bytes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bit-by-bit CRC is CRC-32/ISO-HDLC: its check value, and the
    /// table-driven one on every length of a pseudo-random buffer.
    #[test]
    fn crc_is_crc32_iso_hdlc() {
        assert_eq!(CRC.checksum(b"123456789"), 0xCBF4_3926);
        let table = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);
        let bytes: std::vec::Vec<u8> = (0..300_u32)
            .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
            .collect();
        for n in 0..bytes.len() {
            assert_eq!(CRC.checksum(&bytes[..n]), table.checksum(&bytes[..n]));
        }
    }
    use proptest::prelude::*;
    use wmr_core::drive::spec::DriveSpec;
    use wmr_core::pilot::spec::TrackerSpec;
    use wmr_core::reference::TrajectorySpec;

    pub(crate) fn configure() -> HostMessage {
        HostMessage::Configure(Configure {
            protocol: PROTOCOL_VERSION,
            pilot: PilotSpec {
                tracker: TrackerSpec {
                    period_s: 0.01,
                    trajectory: TrajectorySpec::FigureEight {
                        h1_m: 5.0,
                        h2_rad_s: 0.02,
                        phase_rad: -core::f32::consts::FRAC_PI_2,
                    },
                    gains: [0.5, 0.5, 1.0],
                    observer_gain_per_m: 10.0,
                    observer_min_speed_m_s: 1e-3,
                    fix_timeout_ticks: 50,
                    failsafe_decel_m_s2: 0.5,
                    max_fix_age_ticks: 2,
                    estimator: wmr_core::estimation::spec::EstimatorSpec::HeadingObserver,
                    law: wmr_core::control::spec::LawSpec::Saturated,
                    sensors: wmr_core::estimation::spec::SensorSpec {
                        track_width_m: 0.3,
                        // Count quantum q = 2π·0.05 m / 2048: q²/12.
                        wheel_variance_floor_m2: 1.96e-9,
                        tag_spacing_m: 0.1,
                        read_radius_m: 0.0,
                        antenna_offset_m: [0.0; 2],
                    },
                },
                drive: DriveSpec {
                    wheel_radius_m: 0.05,
                    track_width_m: 0.3,
                    encoder_counts_per_rev: 2048,
                    max_wheel_speed_rad_s: 20.0,
                    max_wheel_accel_rad_s2: 40.0,
                    feedforward_duty_per_rad_s: 0.05,
                    kp_duty_per_rad_s: 0.05,
                    ki_duty_per_rad: 0.5,
                    speed_observer: None,
                },
                encoder_bits: 16,
                max_encoder_fault_ticks: 5,
            },
            floor: FloorSpec::Grid(TagGridSpec {
                origin_m: [-6.0, -6.0],
                spacing_m: 0.1,
                rows: 130,
                columns: 130,
            }),
            pwm_max_duty: 1000,
            telemetry_every_ticks: 1,
        })
    }

    fn full_tick() -> HostMessage {
        let mut uart = heapless::Vec::new();
        for i in 0..MAX_UART_BYTES_PER_TICK {
            let _ = uart.push(u8::try_from(i % 251).unwrap_or(0));
        }
        HostMessage::Tick(TickInput {
            tick: u32::MAX,
            left_count: Some(u32::MAX),
            right_count: None,
            uart,
        })
    }

    fn feed<M: for<'de> Deserialize<'de>>(
        rx: &mut Receiver,
        bytes: &[u8],
    ) -> Vec<Result<M, LinkError>> {
        bytes.iter().filter_map(|&b| rx.push(b)).collect()
    }

    #[test]
    fn messages_round_trip_and_fit() {
        let mut tx = Sender::default();
        let mut rx = Receiver::new();
        let mut out = [0; MAX_FRAME_BYTES];
        let chunk = HostMessage::MapChunk(MapChunk {
            first: 16,
            tags: heapless::Vec::from_slice(&[MapTag {
                id: 0x12_3456_789A,
                position_m: [1.5, -0.25],
            }])
            .unwrap(),
        });
        for msg in [configure(), chunk, full_tick(), HostMessage::Finish] {
            let bytes = tx.frame(msg.clone(), &mut out).unwrap().to_vec();
            assert_eq!(bytes.last(), Some(&0));
            assert!(!bytes[..bytes.len() - 1].contains(&0));
            assert_eq!(feed::<HostMessage>(&mut rx, &bytes), vec![Ok(msg)]);
        }
        assert_eq!(rx.counters().frames_ok, 4);
        assert_eq!(rx.counters().sequence_gaps, 0);
    }

    /// The largest chunk (every id and index at its longest varint,
    /// positions that do not compress) is one frame, and decodes back;
    /// in RAM it is no larger than `Configure`, the largest message
    /// before it, so the firmware's receive path needs no more stack.
    #[test]
    fn a_full_map_chunk_fits_a_frame() {
        let tags = (0..MAP_CHUNK_TAGS)
            .map(|i| MapTag {
                id: u64::MAX - i as u64,
                position_m: [f32::MIN_POSITIVE, -f32::MAX],
            })
            .collect();
        let chunk = HostMessage::MapChunk(MapChunk {
            first: u16::MAX,
            tags,
        });
        let mut out = [0; MAX_FRAME_BYTES];
        let mut tx = Sender { seq: u32::MAX };
        let bytes = tx.frame(chunk.clone(), &mut out).unwrap().to_vec();
        println!("largest map chunk: {} B of {MAX_FRAME_BYTES}", bytes.len());
        let mut rx = Receiver::new();
        assert_eq!(feed::<HostMessage>(&mut rx, &bytes), vec![Ok(chunk)]);
        assert!(core::mem::size_of::<MapChunk>() <= core::mem::size_of::<Configure>());
        // The capacity and every index fit the messages' u16.
        assert!(u16::try_from(MAP_CAPACITY).is_ok());
    }

    /// Every refusal of a map says which tag and why, in words.
    #[test]
    fn map_refusals_name_the_tag_and_why() {
        let said = |r: MapRefusal| Refusal::Map(r).to_string();
        assert_eq!(
            said(MapRefusal::Tag {
                index: 7,
                why: TagMapError::DuplicateId
            }),
            "the tag map was refused: tag 7: tag id already in the map"
        );
        assert_eq!(
            said(MapRefusal::Size {
                tags: 5000,
                capacity: 4096
            }),
            "the tag map was refused: Configure announced 5000 tags; the firmware holds 1 to 4096"
        );
        assert!(
            said(MapRefusal::Tag {
                index: 3,
                why: TagMapError::Unsorted
            })
            .contains("ids must increase")
        );
        assert!(
            said(MapRefusal::OutOfOrder {
                expected: 16,
                first: 32
            })
            .contains("starting at tag 32 arrived; tag 16 was next")
        );
    }

    /// The flat serializer of `Diagnostics` writes what the derived
    /// deserializer reads (postcard: a struct is its fields in order), in
    /// field order: every counter distinct, round trip exact.
    #[test]
    fn diagnostics_serialize_flat_in_field_order() {
        let values: [u32; DIAGNOSTIC_COUNTERS] =
            core::array::from_fn(|i| 1000 * u32::try_from(i).unwrap() + 1);
        // A postcard tuple is its elements' encodings in a row.
        let mut wire = Vec::new();
        for v in values {
            let mut buf = [0_u8; 8];
            wire.extend_from_slice(postcard::to_slice(&v, &mut buf).unwrap());
        }
        let diagnostics: Diagnostics = postcard::from_bytes(&wire).unwrap();
        assert_eq!(diagnostics.flat(), values);
        assert_eq!(diagnostics.rfid.frames_ok, 1);
        assert_eq!(diagnostics.link.timeouts, 29_001);
        assert_eq!(diagnostics.stale_ticks, 33_001);
        let mut again = [0_u8; 256];
        assert_eq!(
            postcard::to_slice(&diagnostics, &mut again).unwrap(),
            &wire[..]
        );
    }

    #[test]
    fn a_flipped_bit_is_caught_and_the_next_frame_still_decodes() {
        let mut tx = Sender::default();
        let mut rx = Receiver::new();
        let mut out = [0; MAX_FRAME_BYTES];
        let good = tx.frame(configure(), &mut out).unwrap().to_vec();
        let mut bad = good.clone();
        bad[10] ^= 0x04;
        let next = tx.frame(HostMessage::Finish, &mut out).unwrap().to_vec();
        let got = feed::<HostMessage>(&mut rx, &[bad, next].concat());
        assert_eq!(got.len(), 2);
        assert!(got[0].is_err());
        assert_eq!(got[1], Ok(HostMessage::Finish));
        assert_eq!(rx.counters().corrupt_frames, 1);
        // The corrupt frame still used a sequence number.
        assert_eq!(rx.counters().sequence_gaps, 0);
    }

    #[test]
    fn sequence_gaps_are_counted() {
        let mut tx = Sender::default();
        let mut rx = Receiver::new();
        let mut out = [0; MAX_FRAME_BYTES];
        let first = tx.frame(HostMessage::Finish, &mut out).unwrap().to_vec();
        for _ in 0..3 {
            tx.frame(HostMessage::Finish, &mut out).unwrap();
        }
        let fifth = tx.frame(HostMessage::Finish, &mut out).unwrap().to_vec();
        let got = feed::<HostMessage>(&mut rx, &[first, fifth].concat());
        assert_eq!(got.len(), 2);
        assert_eq!(rx.counters().sequence_gaps, 3);
    }

    #[test]
    fn duplicates_and_overtaken_frames_are_dropped_as_stale() {
        let mut tx = Sender::default();
        let mut rx = Receiver::new();
        let mut out = [0; MAX_FRAME_BYTES];
        let frames: Vec<Vec<u8>> = (0..3)
            .map(|_| tx.frame(HostMessage::Finish, &mut out).unwrap().to_vec())
            .collect();
        // 0, 0 again (a duplicate), 2 (overtakes 1), then the late 1.
        let stream = [&frames[0], &frames[0], &frames[2], &frames[1]].map(|f| f.as_slice());
        let got = feed::<HostMessage>(&mut rx, &stream.concat());
        assert_eq!(
            got,
            vec![
                Ok(HostMessage::Finish),
                Err(LinkError::Stale),
                Ok(HostMessage::Finish),
                Err(LinkError::Stale)
            ]
        );
        let c = rx.counters();
        assert_eq!((c.frames_ok, c.stale_frames), (2, 2));
        // 1 was missing when 2 came; it came late and was not used.
        assert_eq!((c.sequence_gaps, c.corrupt_frames), (1, 0));
    }

    #[test]
    fn a_peer_far_behind_has_restarted_and_is_accepted() {
        let mut tx = Sender::default();
        let mut rx = Receiver::new();
        let mut out = [0; MAX_FRAME_BYTES];
        for _ in 0..=STALE_WINDOW + 1 {
            let bytes = tx.frame(HostMessage::Finish, &mut out).unwrap().to_vec();
            assert_eq!(
                feed::<HostMessage>(&mut rx, &bytes),
                vec![Ok(HostMessage::Finish)]
            );
        }
        // The peer restarts its numbering from 0: more than the window
        // behind, so accepted (one gap), not stale.
        let restarted = Sender::default()
            .frame(HostMessage::Finish, &mut out)
            .unwrap()
            .to_vec();
        assert_eq!(
            feed::<HostMessage>(&mut rx, &restarted),
            vec![Ok(HostMessage::Finish)]
        );
        let c = rx.counters();
        assert_eq!((c.stale_frames, c.sequence_gaps), (0, 1));
    }

    #[test]
    fn an_overlong_frame_is_dropped_whole() {
        let mut rx = Receiver::new();
        let junk = vec![0x55_u8; MAX_FRAME_BYTES * 2];
        let got = feed::<HostMessage>(&mut rx, &[junk.as_slice(), &[0]].concat());
        assert_eq!(got, vec![Err(LinkError::TooLong)]);
        let mut out = [0; MAX_FRAME_BYTES];
        let ok = Sender::default()
            .frame(HostMessage::Finish, &mut out)
            .unwrap()
            .to_vec();
        assert_eq!(
            feed::<HostMessage>(&mut rx, &ok),
            vec![Ok(HostMessage::Finish)]
        );
    }

    proptest! {
        #[test]
        fn garbage_never_panics_and_rarely_passes(bytes in proptest::collection::vec(any::<u8>(), 0..2048)) {
            let mut rx = Receiver::new();
            let got = feed::<HostMessage>(&mut rx, &bytes);
            let c = rx.counters();
            prop_assert_eq!(got.len() as u32, c.frames_ok + c.corrupt_frames);
        }

        #[test]
        fn the_checked_cobs_decoder_agrees_with_the_crate(bytes in proptest::collection::vec(any::<u8>(), 0..700)) {
            let mut ours = bytes.clone();
            let mut theirs = bytes.clone();
            let got = cobs_decode_in_place(&mut ours);
            match cobs::decode_in_place(&mut theirs) {
                Ok(n) => {
                    prop_assert_eq!(got, Ok(n));
                    prop_assert_eq!(&ours[..n], &theirs[..n]);
                }
                Err(_) => prop_assert_eq!(got, Err(LinkError::Cobs)),
            }
        }

        #[test]
        fn the_checked_cobs_decoder_inverts_the_encoder(data in proptest::collection::vec(any::<u8>(), 0..700)) {
            let mut encoded = vec![0_u8; cobs::max_encoding_length(data.len())];
            let n = cobs::encode(&data, &mut encoded);
            encoded.truncate(n);
            prop_assert_eq!(cobs_decode_in_place(&mut encoded), Ok(data.len()));
            prop_assert_eq!(&encoded[..data.len()], data.as_slice());
        }

        #[test]
        fn any_single_byte_corruption_is_rejected(pos in 0_usize..400, flip in 1_u8..=255) {
            let mut out = [0; MAX_FRAME_BYTES];
            let good = Sender::default().frame(configure(), &mut out).unwrap().to_vec();
            let pos = pos % (good.len() - 1);
            let mut bad = good.clone();
            bad[pos] ^= flip;
            let mut rx = Receiver::new();
            let got = feed::<HostMessage>(&mut rx, &bad);
            // A corrupted byte may become 0x00 and split the frame; no piece
            // may decode as a message.
            prop_assert!(got.iter().all(Result::is_err), "{:?}", got);
        }
    }
}
