//! What the endpoint says unasked: the heartbeat, `SYS_STATUS`, the
//! position and attitude telemetry (frames mapped as in [`crate::geo`]),
//! and the robot's counters ([`Counts`], as `NAMED_VALUE_INT`).

use mavlink::MessageData;
use mavlink::dialects::common as c;
use wmr_core::devices::RfidCounters;
use wmr_core::pilot::tracker::TrackerCounters;

use crate::endpoint::{MavlinkEndpoint, RobotMode, RobotView, due};
use crate::geo;
use crate::wire::{self, TxBuffer};

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

/// [`COUNTER_NAMES`] as `NAMED_VALUE_INT`'s `name` carries them:
/// NUL-padded to 10 bytes, made at build time. The firmware links this
/// table alone, not the names' string addresses and lengths; a name past
/// 10 characters fails the build.
const COUNTER_IDS: [[u8; 10]; COUNTERS] = {
    let mut out = [[0; 10]; COUNTERS];
    let mut i = 0;
    while i < COUNTERS {
        out[i] = wire::nul_padded(COUNTER_NAMES[i]);
        i += 1;
    }
    out
};

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
        let (Some(&value), Some(name)) = (counts.0.get(i), COUNTER_IDS.get(i)) else {
            return;
        };
        let mut payload = [0u8; 18];
        let [t0, t1, t2, t3] = now_ms.to_le_bytes();
        let [v0, v1, v2, v3] = value.to_le_bytes();
        payload[..8].copy_from_slice(&[t0, t1, t2, t3, v0, v1, v2, v3]);
        payload[8..].copy_from_slice(name);
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
        let words = sys_status_words(&self.counters);
        self.send_words(
            tx,
            c::SYS_STATUS_DATA::ID,
            c::SYS_STATUS_DATA::EXTRA_CRC,
            &words,
        );
    }

    pub(crate) fn heartbeat(&mut self, view: &RobotView, tx: &mut TxBuffer<'_>) {
        let words = heartbeat_words(view, self.link_lost);
        self.send_words(
            tx,
            c::HEARTBEAT_DATA::ID,
            c::HEARTBEAT_DATA::EXTRA_CRC,
            &words,
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
        // LOCAL_POSITION_NED: time_boot_ms, x, y, z, vx, vy, vz.
        self.send_words(
            tx,
            c::LOCAL_POSITION_NED_DATA::ID,
            c::LOCAL_POSITION_NED_DATA::EXTRA_CRC,
            &[
                now_ms,
                north.to_bits(),
                east.to_bits(),
                0,
                vn.to_bits(),
                ve.to_bits(),
                0,
            ],
        );
        let yaw = geo::heading_to_yaw(e.heading_rad);
        // ATTITUDE: time_boot_ms, roll, pitch, yaw, rollspeed,
        // pitchspeed, yawspeed (clockwise from above in NED: minus the
        // floor's rate).
        self.send_words(
            tx,
            c::ATTITUDE_DATA::ID,
            c::ATTITUDE_DATA::EXTRA_CRC,
            &[
                now_ms,
                0,
                0,
                yaw.to_bits(),
                0,
                0,
                (-e.turn_rate_rad_s).to_bits(),
            ],
        );
        if let Some(origin) = self.config.origin {
            let (lat, lon) = origin.to_global(e.x_m, e.y_m);
            let words = global_position_words(now_ms, (lat, lon), (vn, ve), yaw);
            self.send_words(
                tx,
                c::GLOBAL_POSITION_INT_DATA::ID,
                c::GLOBAL_POSITION_INT_DATA::EXTRA_CRC,
                &words,
            );
        }
    }
}

/// Two 16-bit fields as the 32-bit little-endian word they fill, `low`
/// first on the wire.
fn pair(low: u16, high: u16) -> u32 {
    u32::from(low) | (u32::from(high) << 16)
}

/// `HEARTBEAT`'s payload as little-endian words: `custom_mode` u32, then
/// `type`, `autopilot`, `base_mode`, `system_status`, then
/// `mavlink_version`.
fn heartbeat_words(view: &RobotView, link_lost: bool) -> [u32; 3] {
    let mut base_mode = c::MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED.bits();
    if view.armed {
        base_mode |= c::MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED.bits();
    }
    if matches!(view.mode, RobotMode::Running | RobotMode::Paused) {
        base_mode |= c::MavModeFlag::MAV_MODE_FLAG_AUTO_ENABLED.bits();
    }
    let system_status = if view.mode == RobotMode::Stopped {
        c::MavState::MAV_STATE_EMERGENCY
    } else if link_lost {
        c::MavState::MAV_STATE_CRITICAL
    } else if view.armed {
        c::MavState::MAV_STATE_ACTIVE
    } else {
        c::MavState::MAV_STATE_STANDBY
    };
    let kinds = u32::from_le_bytes([
        c::MavType::MAV_TYPE_GROUND_ROVER as u8,
        c::MavAutopilot::MAV_AUTOPILOT_GENERIC as u8,
        base_mode,
        system_status as u8,
    ]);
    [view.mode as u32, kinds, 3]
}

/// `SYS_STATUS`'s payload as little-endian words: the three sensor
/// bitmaps (none), `load` 0, `voltage_battery` unknown (`u16::MAX`),
/// `current_battery` unknown (−1), `drop_rate_comm` 0, `errors_comm`,
/// `errors_count1..4`, `battery_remaining` unknown (−1); the extension
/// fields 0.
fn sys_status_words(n: &crate::endpoint::Counters) -> [u32; 8] {
    let sat = |v: u32| u16::try_from(v).unwrap_or(u16::MAX);
    [
        0,
        0,
        0,
        pair(0, u16::MAX),
        pair(u16::MAX, 0),
        pair(sat(n.rx.crc_errors), sat(n.mission_refusals)),
        pair(sat(n.command_refusals), sat(n.param_refusals)),
        pair(sat(n.tx_dropped), 0x00FF),
    ]
}

/// `GLOBAL_POSITION_INT`'s payload as little-endian words:
/// `time_boot_ms`, `lat`, `lon` (1e-7 degrees), `alt` and
/// `relative_alt` 0, then `vx`, `vy` (cm/s, north and east), `vz` 0 and
/// `hdg` (centidegrees in [0, 36000), from `yaw` in radians).
fn global_position_words(
    now_ms: u32,
    (lat, lon): (i32, i32),
    (vn, ve): (f32, f32),
    yaw: f32,
) -> [u32; 7] {
    let yaw_deg = yaw * (180.0 / wmr_core::math::PI);
    let hdg = libm::roundf(
        if yaw_deg < 0.0 {
            yaw_deg + 360.0
        } else {
            yaw_deg
        } * 100.0,
    );
    [
        now_ms,
        lat as u32,
        lon as u32,
        0,
        0,
        pair((vn * 100.0) as i16 as u16, (ve * 100.0) as i16 as u16),
        pair(0, (hdg as u16) % 36_000),
    ]
}

#[cfg(test)]
mod tests {
    use mavlink::MessageData;
    use mavlink::dialects::common as c;

    use super::{global_position_words, heartbeat_words, sys_status_words};
    use crate::endpoint::{Counters, RobotMode, RobotView};

    /// `words` as the bytes `send_words` writes, and the library's
    /// encoding of `msg`: equal over the library's whole length (the
    /// bytes past ours zero, as MAVLink 2 cuts them).
    fn assert_same<D: MessageData + core::fmt::Debug>(words: &[u32], msg: &D) {
        let mut ours = [0u8; 255];
        for (bytes, word) in ours.chunks_exact_mut(4).zip(words) {
            bytes.copy_from_slice(&word.to_le_bytes());
        }
        let mut lib = [0u8; 255];
        let n = msg.ser(mavlink::MavlinkVersion::V2, &mut lib);
        assert!(n <= 4 * words.len());
        assert_eq!(ours, lib, "{msg:?}");
    }

    #[test]
    fn heartbeats_are_the_librarys_encoding() {
        let modes = [
            RobotMode::Idle,
            RobotMode::Running,
            RobotMode::Paused,
            RobotMode::Done,
            RobotMode::Stopped,
        ];
        for mode in modes {
            for armed in [false, true] {
                for link_lost in [false, true] {
                    let view = RobotView {
                        armed,
                        mode,
                        ..RobotView::default()
                    };
                    let mut base_mode = c::MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED;
                    if armed {
                        base_mode |= c::MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED;
                    }
                    if matches!(mode, RobotMode::Running | RobotMode::Paused) {
                        base_mode |= c::MavModeFlag::MAV_MODE_FLAG_AUTO_ENABLED;
                    }
                    let system_status = match (mode, link_lost, armed) {
                        (RobotMode::Stopped, _, _) => c::MavState::MAV_STATE_EMERGENCY,
                        (_, true, _) => c::MavState::MAV_STATE_CRITICAL,
                        (_, _, true) => c::MavState::MAV_STATE_ACTIVE,
                        _ => c::MavState::MAV_STATE_STANDBY,
                    };
                    assert_same(
                        &heartbeat_words(&view, link_lost),
                        &c::HEARTBEAT_DATA {
                            custom_mode: mode as u32,
                            mavtype: c::MavType::MAV_TYPE_GROUND_ROVER,
                            autopilot: c::MavAutopilot::MAV_AUTOPILOT_GENERIC,
                            base_mode,
                            system_status,
                            mavlink_version: 3,
                        },
                    );
                }
            }
        }
    }

    #[test]
    fn sys_status_is_the_librarys_encoding() {
        let counts = [
            [0, 0, 0, 0, 0],
            [1, 2, 3, 4, 5],
            [65_534, 65_535, 65_536, 70_000, u32::MAX],
            [0x1234, 0xABCD, 7, 0x0100, 0x00FF],
        ];
        for [crc, mission, command, param, dropped] in counts {
            let mut n = Counters {
                mission_refusals: mission,
                command_refusals: command,
                param_refusals: param,
                tx_dropped: dropped,
                ..Counters::default()
            };
            n.rx.crc_errors = crc;
            let sat = |v: u32| u16::try_from(v).unwrap_or(u16::MAX);
            assert_same(
                &sys_status_words(&n),
                &c::SYS_STATUS_DATA {
                    onboard_control_sensors_present: c::MavSysStatusSensor::empty(),
                    onboard_control_sensors_enabled: c::MavSysStatusSensor::empty(),
                    onboard_control_sensors_health: c::MavSysStatusSensor::empty(),
                    load: 0,
                    voltage_battery: u16::MAX,
                    current_battery: -1,
                    drop_rate_comm: 0,
                    errors_comm: sat(crc),
                    errors_count1: sat(mission),
                    errors_count2: sat(command),
                    errors_count3: sat(param),
                    errors_count4: sat(dropped),
                    battery_remaining: -1,
                },
            );
        }
    }

    #[test]
    fn position_and_attitude_are_the_librarys_encoding() {
        let cases = [
            (0_u32, [0.0_f32, 0.0, 0.0, 0.0, 0.0], (0_i32, 0_i32)),
            (
                123_456,
                [1.25, -3.5, 0.75, -0.2, 2.5],
                (473_977_420, 85_455_940),
            ),
            (
                u32::MAX,
                [-1e4, 1e4, -3.0, 4.0, -0.001],
                (-900_000_000, -1_800_000_000),
            ),
            (7, [f32::NAN, 0.5, 3.1, -4.0, 0.0], (1, -1)),
        ];
        for (now_ms, [north, east, vn, ve, yaw], (lat, lon)) in cases {
            assert_same(
                &[
                    now_ms,
                    north.to_bits(),
                    east.to_bits(),
                    0,
                    vn.to_bits(),
                    ve.to_bits(),
                    0,
                ],
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
            assert_same(
                &[now_ms, 0, 0, yaw.to_bits(), 0, 0, (-vn).to_bits()],
                &c::ATTITUDE_DATA {
                    time_boot_ms: now_ms,
                    roll: 0.0,
                    pitch: 0.0,
                    yaw,
                    rollspeed: 0.0,
                    pitchspeed: 0.0,
                    yawspeed: -vn,
                },
            );
            let yaw_deg = yaw * (180.0 / wmr_core::math::PI);
            let hdg = libm::roundf(
                if yaw_deg < 0.0 {
                    yaw_deg + 360.0
                } else {
                    yaw_deg
                } * 100.0,
            );
            assert_same(
                &global_position_words(now_ms, (lat, lon), (vn, ve), yaw),
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
