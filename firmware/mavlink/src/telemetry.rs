//! What the endpoint says unasked: the heartbeat, `SYS_STATUS`, the
//! position and attitude telemetry (frames mapped as in [`crate::geo`]),
//! and the robot's counters ([`Counts`], as `NAMED_VALUE_INT`).

use mavlink::MessageData;
use mavlink::dialects::common as c;
use wmr_core::devices::RfidCounters;
use wmr_core::pilot::tracker::TrackerCounters;

use crate::endpoint::{MavlinkEndpoint, RobotMode, RobotView, due};
use crate::geo;
use crate::wire::TxBuffer;

/// How many counters [`Counts`] holds.
pub const COUNTERS: usize = 15;

/// The counters' `NAMED_VALUE_INT` names (≤ 10 characters), in the order
/// of [`Counts`] and of sending: the tracker's
/// (`wmr_core::pilot::tracker::TrackerCounters`), then the RFID reader's
/// (`wmr_core::devices::RfidCounters`, and the robot's unknown tags).
pub const COUNTER_NAMES: [&str; COUNTERS] = [
    "TRK_FIXES",  // fixes_used
    "TRK_INVAL",  // invalid_fixes
    "TRK_STALE",  // stale_fixes
    "TRK_GATED",  // fixes_gated
    "TRK_RELOC",  // relocalisations
    "TRK_HDGRST", // heading_resets
    "TRK_FSAFE",  // failsafe_entries
    "TRK_DEADRK", // dead_reckoned_steps
    "RF_FRAMES",  // frames_ok
    "RF_CRC",     // bad_checksum
    "RF_MALFORM", // malformed
    "RF_UNKNOWN", // RobotCounters::unknown_tags
    "RF_BACKLOG", // backlogged_polls
    "RF_RDERR",   // read_errors
    "RF_SUPERSD", // superseded
];

/// The robot's counters a ground station is sent, in the order of
/// [`COUNTER_NAMES`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Counts(pub [u32; COUNTERS]);

impl Counts {
    /// The tracker's counters, the RFID reader's and the robot's count of
    /// tags not in its map (zeros for a robot without a reader).
    #[must_use]
    pub fn of(tracker: &TrackerCounters, rfid: &RfidCounters, unknown_tags: u32) -> Self {
        let t = tracker;
        Self([
            t.fixes_used,
            t.invalid_fixes,
            t.stale_fixes,
            t.fixes_gated,
            t.relocalisations,
            t.heading_resets,
            t.failsafe_entries,
            t.dead_reckoned_steps,
            rfid.frames_ok,
            rfid.bad_checksum,
            rfid.malformed,
            unknown_tags,
            rfid.backlogged_polls,
            rfid.read_errors,
            rfid.superseded,
        ])
    }
}

impl MavlinkEndpoint {
    /// The next counter as a `NAMED_VALUE_INT` when one is due: the
    /// counters one after another, one every `counters_period_ms /`
    /// [`COUNTERS`] (so each once a period), none before the robot told
    /// them. Written by layout: `time_boot_ms` u32, `value` i32 (the count
    /// modulo 2³², as two's complement), `name` 10 bytes.
    // Out of line: at opt-level 3 with fat LTO, inlined into its caller it
    // is unrolled and duplicated (docs/mavlink.md, Cost).
    #[inline(never)]
    pub(crate) fn send_count(&mut self, now_ms: u32, tx: &mut TxBuffer<'_>) {
        let period = self.config.counters_period_ms;
        let Some(counts) = self.counts else { return };
        if period == 0 || !due(now_ms, self.last_count_ms, period / COUNTERS as u32) {
            return;
        }
        self.last_count_ms = Some(now_ms);
        let i = usize::from(self.next_count) % COUNTERS;
        self.next_count = ((i + 1) % COUNTERS) as u8;
        let (Some(&value), Some(name)) = (counts.0.get(i), COUNTER_NAMES.get(i)) else {
            return;
        };
        let mut payload = [0u8; 18];
        let [t0, t1, t2, t3] = now_ms.to_le_bytes();
        let [v0, v1, v2, v3] = value.to_le_bytes();
        payload[..8].copy_from_slice(&[t0, t1, t2, t3, v0, v1, v2, v3]);
        for (slot, b) in payload[8..].iter_mut().zip(name.bytes()) {
            *slot = b;
        }
        self.send_raw(
            tx,
            c::NAMED_VALUE_INT_DATA::ID,
            c::NAMED_VALUE_INT_DATA::EXTRA_CRC,
            &payload,
        );
    }

    // Out of line: at opt-level 3 with fat LTO, inlined into its caller it
    // is unrolled and duplicated (docs/mavlink.md, Cost).
    #[inline(never)]
    /// `SYS_STATUS` at 1 Hz: no sensors declared, battery unknown, and the
    /// endpoint's counters (each saturated to `u16`): `errors_comm` = CRC
    /// errors, `errors_count1..4` = mission, command and parameter
    /// refusals and frames dropped for want of room.
    pub(crate) fn sys_status(&mut self, tx: &mut TxBuffer<'_>) {
        let sat = |v: u32| u16::try_from(v).unwrap_or(u16::MAX);
        let n = self.counters;
        self.send(
            tx,
            &c::SYS_STATUS_DATA {
                onboard_control_sensors_present: c::MavSysStatusSensor::empty(),
                onboard_control_sensors_enabled: c::MavSysStatusSensor::empty(),
                onboard_control_sensors_health: c::MavSysStatusSensor::empty(),
                load: 0,
                voltage_battery: u16::MAX,
                current_battery: -1,
                drop_rate_comm: 0,
                errors_comm: sat(n.rx.crc_errors),
                errors_count1: sat(n.mission_refusals),
                errors_count2: sat(n.command_refusals),
                errors_count3: sat(n.param_refusals),
                errors_count4: sat(n.tx_dropped),
                battery_remaining: -1,
            },
        );
    }

    pub(crate) fn heartbeat(&mut self, view: &RobotView, tx: &mut TxBuffer<'_>) {
        let mut base_mode = c::MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED;
        if view.armed {
            base_mode |= c::MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED;
        }
        if matches!(view.mode, RobotMode::Running | RobotMode::Paused) {
            base_mode |= c::MavModeFlag::MAV_MODE_FLAG_AUTO_ENABLED;
        }
        let system_status = if view.mode == RobotMode::Stopped {
            c::MavState::MAV_STATE_EMERGENCY
        } else if self.link_lost {
            c::MavState::MAV_STATE_CRITICAL
        } else if view.armed {
            c::MavState::MAV_STATE_ACTIVE
        } else {
            c::MavState::MAV_STATE_STANDBY
        };
        self.send(
            tx,
            &c::HEARTBEAT_DATA {
                custom_mode: view.mode as u32,
                mavtype: c::MavType::MAV_TYPE_GROUND_ROVER,
                autopilot: c::MavAutopilot::MAV_AUTOPILOT_GENERIC,
                base_mode,
                system_status,
                mavlink_version: 3,
            },
        );
    }

    // Out of line: at opt-level 3 with fat LTO, inlined into its caller it
    // is unrolled and duplicated (docs/mavlink.md, Cost).
    #[inline(never)]
    pub(crate) fn telemetry(&mut self, now_ms: u32, view: &RobotView, tx: &mut TxBuffer<'_>) {
        let period = self.config.telemetry_period_ms;
        let Some(e) = view.estimate else { return };
        if period == 0 || !due(now_ms, self.last_telemetry_ms, period) {
            return;
        }
        self.last_telemetry_ms = Some(now_ms);
        let (north, east) = geo::floor_to_ned(e.x_m, e.y_m);
        let (cos, sin) = (
            wmr_core::math::cos(e.heading_rad),
            wmr_core::math::sin(e.heading_rad),
        );
        let (vn, ve) = geo::floor_to_ned(e.speed_m_s * cos, e.speed_m_s * sin);
        self.send(
            tx,
            &c::LOCAL_POSITION_NED_DATA {
                time_boot_ms: now_ms,
                x: north,
                y: east,
                z: 0.0,
                vx: vn,
                vy: ve,
                vz: 0.0,
            },
        );
        let yaw = geo::heading_to_yaw(e.heading_rad);
        self.send(
            tx,
            &c::ATTITUDE_DATA {
                time_boot_ms: now_ms,
                roll: 0.0,
                pitch: 0.0,
                yaw,
                rollspeed: 0.0,
                pitchspeed: 0.0,
                // Clockwise from above in NED: minus the floor's rate.
                yawspeed: -e.turn_rate_rad_s,
            },
        );
        if let Some(origin) = self.config.origin {
            let (lat, lon) = origin.to_global(e.x_m, e.y_m);
            let yaw_deg = yaw * (180.0 / wmr_core::math::PI);
            let hdg = libm::roundf(
                if yaw_deg < 0.0 {
                    yaw_deg + 360.0
                } else {
                    yaw_deg
                } * 100.0,
            );
            self.send(
                tx,
                &c::GLOBAL_POSITION_INT_DATA {
                    time_boot_ms: now_ms,
                    lat,
                    lon,
                    alt: 0,
                    relative_alt: 0,
                    vx: (vn * 100.0) as i16,
                    vy: (ve * 100.0) as i16,
                    vz: 0,
                    hdg: (hdg as u16) % 36_000,
                },
            );
        }
    }
}
