//! Every counter of the firmware, and the link's own, as `Finished`
//! reports them.

use serde::{Deserialize, Serialize};
use wmr_core::devices::RfidCounters;
use wmr_core::pilot::PilotCounters;
use wmr_core::pilot::robot::RobotCounters;
use wmr_core::pilot::route::RouteCounters;
use wmr_core::pilot::tracker::TrackerCounters;

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
    /// The run's route follower (all zero for a run without a route).
    pub route: RouteCounters,
}

/// Counters in [`Diagnostics`], all `u32`.
pub const DIAGNOSTIC_COUNTERS: usize = 44;

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
            route:
                RouteCounters {
                    stops_reached,
                    stop_errors,
                    pivots,
                    open_loop_pivot_ticks,
                    routes_started,
                    routes_refused,
                    routes_done,
                    clock_wait_ticks,
                    approach_ticks,
                    approach_timeouts,
                },
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
            stops_reached,
            stop_errors,
            pivots,
            open_loop_pivot_ticks,
            routes_started,
            routes_refused,
            routes_done,
            clock_wait_ticks,
            approach_ticks,
            approach_timeouts,
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
