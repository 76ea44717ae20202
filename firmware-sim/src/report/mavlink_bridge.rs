//! What a HIL run with a ground station bridged to it (`firmware-sim hil
//! --mavlink`, `crate::hil`) reports: the summary's `hil.mavlink`.

use wmr_link::MavlinkCounters;

use crate::udp::LinkCounters;

/// What the bridge did (in the summary's `hil.mavlink`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct MavlinkBridgeReport {
    /// Times real time asked for.
    pub speedup: f64,
    /// Simulated time over wall time from the first tick to the last.
    pub speedup_achieved: f64,
    /// The UDP side: datagrams and bytes in, frames out and unsent.
    pub udp: LinkCounters,
    /// Datagrams dropped whole for want of room in the backlog.
    pub dropped_datagrams: u64,
    /// Their bytes.
    pub dropped_bytes: u64,
    /// The most bytes the backlog held before a tick.
    pub largest_backlog_bytes: u64,
    /// Bytes left in the backlog when the run ended (never sent: every
    /// byte received is sent to the firmware, dropped or left here).
    pub left_in_backlog_bytes: u64,
    /// Bytes sent to the firmware.
    pub bytes_to_firmware: u64,
    /// Bytes the firmware's endpoint wrote, sent on.
    pub bytes_from_firmware: u64,
    /// `HostMessage::Mavlink` messages sent.
    pub messages: u64,
    /// The firmware's side of the channel (its last answer's counters).
    pub firmware: MavlinkCounters,
    /// Answers of the host's copy of the session compared with the
    /// firmware's.
    pub copy_compared: u64,
    /// Those that differ (0: the host's copy, and with it the run's route
    /// status, followed the firmware).
    pub copy_mismatches: u32,
    /// The tick before which the first differing answer came.
    pub first_mismatch_tick: Option<u32>,
    /// The run was ended by Ctrl-C before its duration.
    pub interrupted: bool,
    /// Times the firmware reported the link silent past its 50 ms
    /// timeout and stopped its motors (the host late with a tick, e.g. a
    /// loaded machine; the paced run waits up to 25 ms between ticks:
    /// stops the simulated plant does not see, as it moves by the ticks'
    /// outputs).
    pub link_silences: u32,
}
