//! Link loss, corrupt and random bytes, a full output buffer, telemetry.

mod common;

use common::*;
use mavlink::dialects::common::*;
use wmr_mavlink::{EndpointSpec, Estimate, Event};

fn gcs_heartbeat() -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        mavtype: MavType::MAV_TYPE_GCS,
        autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
        mavlink_version: 3,
        ..Default::default()
    })
}

fn texts(out: &[MavMessage]) -> Vec<String> {
    out.iter()
        .filter_map(|m| match m {
            MavMessage::STATUSTEXT(t) => Some(
                String::from_utf8_lossy(&t.text[..])
                    .trim_end_matches('\0')
                    .to_string(),
            ),
            _ => None,
        })
        .collect()
}

/// A companion computer (mavros's default heartbeat type) keeps the link
/// as a ground station does: its silence stops the robot too.
#[test]
fn a_companion_computers_heartbeat_starts_the_link_watch() {
    let mut rig = Rig::new(EndpointSpec {
        link_timeout_ms: 1_000,
        telemetry_period_ms: 0,
        ..EndpointSpec::default()
    });
    rig.send(MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        mavtype: MavType::MAV_TYPE_ONBOARD_CONTROLLER,
        autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
        mavlink_version: 3,
        ..Default::default()
    }));
    let lost = (0..15)
        .map(|_| rig.tick(100).0)
        .position(|events| events.contains(&Event::LinkLost));
    assert_eq!(lost, Some(9), "lost 1 s after the heartbeat");
    assert!(rig.ep.link_lost());
}

#[test]
fn link_loss_once_after_the_timeout_then_regained() {
    let mut rig = Rig::new(EndpointSpec {
        link_timeout_ms: 2_000,
        telemetry_period_ms: 0,
        ..EndpointSpec::default()
    });
    // No ground station yet: no loss however long.
    for _ in 0..50 {
        assert!(rig.tick(100).0.is_empty());
    }
    rig.send(gcs_heartbeat());
    let t0 = rig.now_ms;
    // A vehicle's heartbeat (not a GCS) does not keep the link.
    rig.tick(1_000);
    rig.send(MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        mavtype: MavType::MAV_TYPE_QUADROTOR,
        ..Default::default()
    }));
    let mut lost_at = None;
    let mut lost_texts = Vec::new();
    for _ in 0..40 {
        let (events, out) = rig.tick(100);
        if events.contains(&Event::LinkLost) {
            assert!(lost_at.is_none(), "LinkLost twice");
            lost_at = Some(rig.now_ms - t0);
            lost_texts = texts(&out);
        }
    }
    assert_eq!(lost_at, Some(2_000));
    assert!(
        lost_texts.iter().any(|t| t.starts_with("link lost")),
        "{lost_texts:?}"
    );
    assert!(rig.ep.link_lost());
    let (_, out) = rig.send(gcs_heartbeat());
    assert!(texts(&out).iter().any(|t| t == "link regained"));
    assert!(!rig.ep.link_lost());
    // And lost again after another silence.
    let mut again = 0;
    for _ in 0..30 {
        again += rig
            .tick(100)
            .0
            .iter()
            .filter(|e| **e == Event::LinkLost)
            .count();
    }
    assert_eq!(again, 1);
    assert_eq!(rig.ep.counters().link_losses, 2);
}

fn arm_frame(rig: &mut Rig) -> Vec<u8> {
    rig.encode(&MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
        param1: 1.0,
        target_system: 1,
        target_component: 1,
        ..Default::default()
    }))
}

#[test]
fn corrupt_and_truncated_frames_are_counted_and_good_ones_still_found() {
    let mut rig = Rig::default_rig();
    // A flipped payload byte: a CRC error, no ack, no event.
    let mut bad = arm_frame(&mut rig);
    bad[12] ^= 0x40;
    let (events, out) = rig.feed(&bad);
    assert!(events.is_empty());
    assert_eq!(ack_of(&out, 400), None);
    assert!(rig.ep.counters().rx.crc_errors >= 1);

    // Garbage, then a truncated frame, then a good one: the good one is
    // found (the truncated frame's length swallows its start, its CRC
    // fails, and the parser re-scans).
    let good = arm_frame(&mut rig);
    let truncated = arm_frame(&mut rig);
    let mut bytes = vec![0x00, 0x13, 0x37, 0xFF, 0x42];
    bytes.extend_from_slice(&truncated[..truncated.len() - 9]);
    bytes.extend_from_slice(&good);
    let before = rig.ep.counters();
    let (events, out) = rig.feed(&bytes);
    assert_eq!(events, vec![Event::Arm]);
    assert_eq!(ack_of(&out, 400), Some(MavResult::MAV_RESULT_ACCEPTED));
    let after = rig.ep.counters();
    assert!(after.rx.garbage_bytes > before.rx.garbage_bytes);
    assert!(after.rx.crc_errors > before.rx.crc_errors);

    // A frame split across calls is assembled.
    let good = arm_frame(&mut rig);
    let (events, _) = rig.feed(&good[..7]);
    assert!(events.is_empty());
    let (events, _) = rig.feed(&good[7..]);
    assert_eq!(events, vec![Event::Arm]);

    // A message the endpoint does not handle: skipped whole, counted.
    let ping = rig.encode(&MavMessage::SYSTEM_TIME(SYSTEM_TIME_DATA::default()));
    let (events, _) = rig.feed(&ping);
    assert!(events.is_empty());
    assert_eq!(rig.ep.counters().rx.unknown_messages, 1);
}

/// xorshift32: a seeded, reproducible byte source.
struct Rng(u32);
impl Rng {
    fn next(&mut self) -> u32 {
        let mut x = self.0;
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        self.0 = x;
        x
    }
}

#[test]
fn random_bytes_never_panic_nor_command_anything() {
    let mut rig = Rig::new(EndpointSpec {
        origin_e7: Some((473_977_420, 85_455_940)),
        ..EndpointSpec::default()
    });
    rig.view.estimate = Some(Estimate::default());
    let mut rng = Rng(0x9E37_79B9);
    let good = arm_frame(&mut rig);
    let mut total = 0usize;
    for round in 0..3_000 {
        let len = (rng.next() % 700) as usize;
        let mut bytes: Vec<u8> = (0..len).map(|_| rng.next() as u8).collect();
        // Now and then, start bytes and MAVLink-looking headers.
        if round % 3 == 0 {
            for i in (0..bytes.len()).step_by(37) {
                bytes[i] = if rng.next().is_multiple_of(2) {
                    0xFD
                } else {
                    0xFE
                };
            }
        }
        total += bytes.len();
        let (events, _) = rig.feed(&bytes);
        assert!(events.is_empty(), "round {round}: {events:?}");
        rig.tick(7);
    }
    let c = rig.ep.counters();
    // Not one frame passed the CRC; the bytes were skipped as garbage, as
    // frames of unknown messages, or after a CRC failure.
    assert_eq!(c.rx.frames, 0, "{c:?}");
    assert!(c.rx.garbage_bytes > 0 && c.rx.unknown_messages > 0 && c.rx.crc_errors > 0);
    assert!(c.rx.garbage_bytes as usize <= total);
    // After all that, a good frame still works (once the parser has
    // dropped what is left of the last garbage).
    let mut tail = vec![0u8; 300];
    tail.extend_from_slice(&good);
    let (events, _) = rig.feed(&tail);
    assert_eq!(events, vec![Event::Arm]);
}

#[test]
fn random_mutations_of_good_frames_never_panic() {
    let mut rig = Rig::default_rig();
    let mut rng = Rng(12_345);
    let mut frames = vec![arm_frame(&mut rig)];
    for item in square() {
        frames.push(rig.encode(&item));
    }
    frames.push(rig.encode(&MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
        count: 3,
        target_system: 1,
        target_component: 1,
    })));
    for _ in 0..5_000 {
        let mut f = frames[(rng.next() as usize) % frames.len()].clone();
        let flips = 1 + rng.next() % 3;
        for _ in 0..flips {
            let i = (rng.next() as usize) % f.len();
            f[i] = rng.next() as u8;
        }
        let cut = (rng.next() as usize) % (f.len() + 1);
        rig.feed(&f[..cut]);
        rig.tick(1);
    }
}

#[test]
fn a_full_output_buffer_drops_whole_frames_and_counts_them() {
    let mut rig = Rig::default_rig();
    // Room for the heartbeat (21 bytes) but not for the SYS_STATUS after
    // it: one whole frame out, one dropped.
    rig.tx_capacity = 25;
    let (_, out) = rig.tick(10);
    assert_eq!(out.len(), 1);
    assert!(matches!(out[0], MavMessage::HEARTBEAT(_)));
    assert_eq!(rig.ep.counters().tx_dropped, 1);
    // No room at all: both dropped.
    rig.tx_capacity = 0;
    let (_, out) = rig.tick(1_000);
    assert!(out.is_empty());
    assert_eq!(rig.ep.counters().tx_dropped, 3);
}

#[test]
fn telemetry_at_its_period_in_ned_and_global() {
    let (lat0, lon0) = (473_977_420, 85_455_940);
    let mut rig = Rig::new(EndpointSpec {
        telemetry_period_ms: 100,
        origin_e7: Some((lat0, lon0)),
        ..EndpointSpec::default()
    });
    // Floor (3, 4), heading +x (east) at 0.5 m/s.
    rig.view.estimate = Some(Estimate {
        x_m: 3.0,
        y_m: 4.0,
        heading_rad: 0.0,
        speed_m_s: 0.5,
        turn_rate_rad_s: 0.1,
    });
    let mut positions = Vec::new();
    let mut last = None;
    for _ in 0..100 {
        let (_, out) = rig.tick(10);
        for m in out {
            match m {
                MavMessage::LOCAL_POSITION_NED(p) => positions.push(p),
                MavMessage::ATTITUDE(a) => {
                    // East is yaw +90°; a counter-clockwise turn is a
                    // negative yaw rate.
                    assert!((a.yaw - core::f32::consts::FRAC_PI_2).abs() < 1e-6);
                    assert!((a.yawspeed + 0.1).abs() < 1e-6);
                }
                MavMessage::GLOBAL_POSITION_INT(g) => last = Some(g),
                _ => {}
            }
        }
    }
    assert_eq!(positions.len(), 10);
    let p = &positions[0];
    assert_eq!((p.x, p.y, p.z), (4.0, 3.0, 0.0));
    assert!((p.vy - 0.5).abs() < 1e-6 && p.vx.abs() < 1e-6);
    let g = last.expect("GLOBAL_POSITION_INT");
    // 4 m north, 3 m east, by the WGS-84 radii in f64.
    let (a, e2) = (6_378_137.0f64, 6.694_379_990_14e-3f64);
    let phi = (f64::from(lat0) * 1e-7).to_radians();
    let w2 = 1.0 - e2 * phi.sin().powi(2);
    let per_e7 = 1e-7f64.to_radians();
    let dlat = 4.0 / (a * (1.0 - e2) / w2.powf(1.5) * per_e7);
    let dlon = 3.0 / (a / w2.sqrt() * phi.cos() * per_e7);
    assert!(
        (f64::from(g.lat - lat0) - dlat).abs() <= 1.0,
        "{} vs {dlat}",
        g.lat - lat0
    );
    assert!(
        (f64::from(g.lon - lon0) - dlon).abs() <= 1.0,
        "{} vs {dlon}",
        g.lon - lon0
    );
    assert_eq!(g.hdg, 9_000);
}

#[test]
fn sys_status_carries_the_counters_and_no_reached_without_a_mission() {
    let mut rig = Rig::default_rig();
    // Reached reported with no mission: nothing sent.
    rig.view.reached = Some(0);
    let (_, out) = rig.tick(10);
    assert!(
        !out.iter()
            .any(|m| matches!(m, MavMessage::MISSION_ITEM_REACHED(_)))
    );
    let mut bad = arm_frame(&mut rig);
    bad[12] ^= 1;
    rig.feed(&bad);
    rig.command(MavCmd::MAV_CMD_NAV_TAKEOFF, 0.0, 0.0);
    let (_, out) = rig.tick(1_000);
    let s = out
        .iter()
        .find_map(|m| match m {
            MavMessage::SYS_STATUS(s) => Some(s.clone()),
            _ => None,
        })
        .expect("SYS_STATUS at 1 Hz");
    assert_eq!((s.errors_comm, s.errors_count2), (1, 1));
    assert_eq!((s.voltage_battery, s.battery_remaining), (u16::MAX, -1));
}
