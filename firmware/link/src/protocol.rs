//! The numbers both sides of the link share: the protocol's version, its
//! limits, its timeouts and the QEMU board's link files.

/// The link's version: the shape of every message, as this crate defines
/// it (bumped when one changes); both sides refuse a mismatch. What each
/// version changed: `CHANGELOG.md`, "HIL link protocol versions".
pub const PROTOCOL_VERSION: u16 = 18;

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
///
/// [`MapChunk`]: crate::MapChunk
/// [`HostMessage`]: crate::HostMessage
pub const MAP_CHUNK_TAGS: usize = 14;

/// Waypoints one [`RouteChunk`] carries at most: the most whose chunk is
/// no larger in RAM than `Configure` (a waypoint is 32 B), so that
/// [`HostMessage`] does not grow and the firmware's receive path needs no
/// more stack; its largest frame (every waypoint a stop facing a heading,
/// with a speed limit) is 175 of the [`MAX_FRAME_BYTES`]
/// (`a_full_route_chunk_fits_a_frame`). A route of
/// `ROUTE_CAPACITY` (64) waypoints crosses in 10 chunks.
///
/// [`RouteChunk`]: crate::RouteChunk
/// [`HostMessage`]: crate::HostMessage
pub const ROUTE_CHUNK_WAYPOINTS: usize = 7;

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

/// UART bytes the host can hand over in one tick. At 115 200 Bd a 10 ms
/// tick carries at most 116 bytes.
pub const MAX_UART_BYTES_PER_TICK: usize = 160;

/// MAVLink bytes one [`MavlinkChunk`] carries at most, either way: its
/// largest frame (a full chunk, every varint at its longest) is well
/// within the [`MAX_FRAME_BYTES`] (`a_full_mavlink_chunk_fits_a_frame`),
/// and [`HostMessage`] does not grow (it is smaller than `Configure`).
///
/// [`MavlinkChunk`]: crate::MavlinkChunk
/// [`HostMessage`]: crate::HostMessage
pub const MAVLINK_CHUNK_BYTES: usize = 192;
