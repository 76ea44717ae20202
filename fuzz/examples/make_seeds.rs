//! Writes the structured seeds of the committed corpus (`fuzz/corpus/`):
//! valid RFID streams, link frames of both sides and a ground station's
//! MAVLink frames. Run from `fuzz/`:
//! `cargo run --example make_seeds` (or `-- DIR` to write them under
//! `DIR` instead: `cargo xtask fuzz` does, and checks that the committed
//! seeds are the same, so that they follow the link protocol). The scenario seeds are the
//! simulator's embedded scenarios, copied; the seeds of the targets that
//! draw their input with `arbitrary` are random bytes.

use std::fs;
use std::path::PathBuf;

use wmr_core::devices::tag_grid::TagGridSpec;
use wmr_core::devices::{TagGrid, TagId, encode_frame};
use wmr_core::pilot::route::{RouteOptions, RouteStart};
use wmr_core::pilot::spec::{PilotSpec, TrackerSpec};
use wmr_core::reference::TrajectorySpec;
use wmr_core::reference::route::{RouteError, RouteLimitsSpec, Waypoint, WaypointKey, Waypoints};
use wmr_link::{
    Configure, Diagnostics, Finished, FloorSpec, HostMessage, MAX_FRAME_BYTES, MavlinkChunk,
    MavlinkCounters, MavlinkIn, MavlinkOut, MotorOutput, PROTOCOL_VERSION, Refusal, RouteRefusal,
    Sender, TargetMessage, TickInput, TickOutput, route_messages,
};

/// Where the seeds go: the first argument, or the committed corpus.
fn corpus_dir() -> PathBuf {
    std::env::args_os()
        .nth(1)
        .map_or_else(|| PathBuf::from("corpus"), PathBuf::from)
}

fn write(dir: &str, name: &str, bytes: &[u8]) {
    let dir = corpus_dir().join(dir);
    fs::create_dir_all(&dir).expect("corpus directory");
    fs::write(dir.join(name), bytes).expect("seed written");
}

fn frame<M: serde::Serialize>(tx: &mut Sender, m: M) -> Vec<u8> {
    let mut out = [0; MAX_FRAME_BYTES];
    tx.frame(m, &mut out).expect("fits").to_vec()
}

fn main() {
    // RFID: two control bytes (chunk sizes, failures), then the stream.
    let a = encode_frame(TagId(0x0F_00A1_B2C3));
    let b = encode_frame(TagGrid::id(10, 12));
    let mut lower = encode_frame(TagId(0xAB_CDEF_0123));
    lower.make_ascii_lowercase();
    let mut bad = encode_frame(TagId(42));
    bad[12] = b'B';
    let mut stream = vec![7, 0];
    stream.extend_from_slice(&a);
    write("rfid_frames", "one_frame", &stream);
    let mut stream = vec![3, 4];
    stream.extend_from_slice(b"xy\r\n");
    stream.extend_from_slice(&a[..7]);
    stream.extend_from_slice(&a);
    stream.extend_from_slice(b"\r\n\x0212G45");
    stream.extend_from_slice(&bad);
    stream.extend_from_slice(&lower);
    stream.extend_from_slice(&a[..13]);
    stream.push(b'!');
    stream.extend_from_slice(&b);
    write("rfid_frames", "mixed", &stream);
    let mut stream = vec![200, 9];
    for i in 0..10 {
        stream.extend_from_slice(&encode_frame(TagId(1000 + i)));
    }
    write("rfid_frames", "ten_frames", &stream);

    // Link: host and target messages, each framed.
    let pilot = PilotSpec {
        tracker: TrackerSpec {
            trajectory: TrajectorySpec::Line {
                start_m: [0.0, 0.0],
                heading_rad: 0.0,
                speed_m_s: 0.2,
            },
            ..PilotSpec::EXAMPLE.tracker
        },
        ..PilotSpec::EXAMPLE
    };
    let configure = HostMessage::Configure(Configure {
        protocol: PROTOCOL_VERSION,
        pilot,
        floor: FloorSpec::Grid(TagGridSpec {
            origin_m: [-1.0, -1.0],
            spacing_m: 0.1,
            rows: 21,
            columns: 21,
        }),
        pwm_max_duty: 1000,
        telemetry_every_ticks: 1,
    });
    let tick = HostMessage::Tick(TickInput {
        tick: 3,
        left_count: Some(100),
        right_count: None,
        uart: heapless::Vec::from_slice(&b).expect("fits"),
    });
    // A route of three waypoints: its announcement and its one chunk.
    let waypoints = Waypoints::from_slice(&[
        Waypoint::stop(0.0, 0.0, 0.0),
        Waypoint::pass(0.5, 0.1).with_speed_limit(0.2),
        Waypoint::stop(1.0, 0.0, 0.5).facing(1.5),
    ])
    .expect("fits");
    let limits = RouteLimitsSpec {
        max_speed_m_s: 0.3,
        max_tangential_accel_m_s2: 0.5,
        max_lateral_accel_m_s2: 0.5,
        blend_deviation_m: 0.02,
        pivot_threshold_rad: 0.5,
        pivot_rate_rad_s: 1.0,
        pivot_accel_rad_s2: 2.0,
    };
    let mut route = route_messages(
        &waypoints,
        limits,
        &RouteOptions::default(),
        RouteStart::AsGiven,
        wmr_link::MavlinkSettings::default(),
    );
    let (Some(announce), Some(chunk)) = (route.next(), route.next()) else {
        unreachable!("an announcement and a chunk")
    };
    let mut tx = Sender::default();
    let host = [
        ("configure", frame(&mut tx, configure)),
        ("route", frame(&mut tx, announce)),
        ("route_chunk", frame(&mut tx, chunk)),
        ("tick", frame(&mut tx, tick)),
        ("finish", frame(&mut tx, HostMessage::Finish)),
        (
            "mavlink_in",
            frame(
                &mut tx,
                HostMessage::Mavlink(MavlinkIn {
                    seq: 5,
                    bytes: MavlinkChunk::from_slice(&[0xFD, 9, 0, 0, 0, 255, 190, 0, 0, 0]),
                }),
            ),
        ),
    ];
    let ticked = TargetMessage::Ticked(TickOutput {
        tick: 3,
        left: MotorOutput {
            duty: 120,
            direction_high: true,
        },
        right: MotorOutput::default(),
        mode: wmr_core::pilot::tracker::TrackerMode::Tracking,
        reference_m: [0.1, 0.0],
        position_m: [0.2, 0.0],
        heading: [1.0, 0.0],
        command: [0.2, 0.01],
        fix: true,
        speed_limited: false,
        accel_limited: true,
    });
    let finished = TargetMessage::Finished(Finished {
        ticks: 3,
        peak_stack_bytes: 4096,
        motors: [MotorOutput::default(); 2],
        counters: Diagnostics::default(),
        route_done: true,
    });
    let mut tx = Sender::default();
    let target = [
        (
            "hello",
            frame(
                &mut tx,
                TargetMessage::Hello {
                    protocol: PROTOCOL_VERSION,
                },
            ),
        ),
        (
            "refused",
            frame(&mut tx, TargetMessage::Refused(Refusal::NotConfigured)),
        ),
        (
            "route_loaded",
            frame(&mut tx, TargetMessage::RouteLoaded { waypoints: 7 }),
        ),
        (
            "refused_route",
            frame(
                &mut tx,
                TargetMessage::Refused(Refusal::Route(RouteRefusal::Route(
                    RouteError::NotFinite {
                        index: 3,
                        key: WaypointKey::Dwell,
                    },
                ))),
            ),
        ),
        ("ticked", frame(&mut tx, ticked)),
        ("finished", frame(&mut tx, finished)),
        (
            "mavlink_out",
            frame(
                &mut tx,
                TargetMessage::Mavlink(MavlinkOut {
                    seq: 5,
                    bytes: MavlinkChunk::from_slice(&[0xFD, 9, 0, 0, 7, 1, 1, 0, 0, 0]),
                    pending: 21,
                    counters: MavlinkCounters::default(),
                }),
            ),
        ),
    ];
    let mut stream = Vec::new();
    for (name, bytes) in host.iter().chain(&target) {
        // One frame's COBS bytes, as `decode` takes them (no terminator).
        write("link_decode", name, &bytes[..bytes.len() - 1]);
        stream.extend_from_slice(bytes);
    }
    write("link_decode", "stream", &stream);
    mavlink_seeds();
}

/// MAVLink: three control bytes (chunk sizes, robot state, clock), then a
/// ground station's frames: a heartbeat, an arm command, a two-waypoint
/// upload, a download request and a start.
fn mavlink_seeds() {
    use mavlink::dialects::common::*;
    let mut seq = 0u8;
    let mut frame = |msg: MavMessage| {
        let mut buf = [0u8; 300];
        let header = mavlink::MavHeader {
            system_id: 255,
            component_id: 190,
            sequence: seq,
        };
        seq = seq.wrapping_add(1);
        let n = mavlink::write_v2_msg(&mut &mut buf[..], header, &msg).expect("fits");
        buf[..n].to_vec()
    };
    let item = |seq: u16, north_e4: i32| {
        MavMessage::MISSION_ITEM_INT(MISSION_ITEM_INT_DATA {
            param1: 1.0,
            param4: f32::NAN,
            x: north_e4,
            y: 0,
            seq,
            command: MavCmd::MAV_CMD_NAV_WAYPOINT,
            target_system: 1,
            target_component: 1,
            frame: MavFrame::MAV_FRAME_LOCAL_NED,
            autocontinue: 1,
            ..Default::default()
        })
    };
    let command = |command: MavCmd, param1: f32| {
        MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            command,
            param1,
            target_system: 1,
            target_component: 1,
            ..Default::default()
        })
    };
    let mut stream = vec![0x35, 0x04, 20];
    for msg in [
        MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            mavtype: MavType::MAV_TYPE_GCS,
            ..Default::default()
        }),
        command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, 1.0),
        MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
            count: 2,
            target_system: 1,
            target_component: 1,
        }),
        item(0, 0),
        item(1, 10_000),
        MavMessage::MISSION_REQUEST_LIST(MISSION_REQUEST_LIST_DATA {
            target_system: 1,
            target_component: 1,
        }),
        command(MavCmd::MAV_CMD_MISSION_START, 0.0),
    ] {
        stream.extend(frame(msg));
    }
    write("mavlink_rx", "arm_upload_start", &stream);
}
