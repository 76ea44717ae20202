//! The mission microservice against a ground station of the `mavlink`
//! library: upload, read back, refusals keeping the running mission,
//! timeouts, clear, set current, items reached.
#![allow(deprecated)]

mod common;

use common::*;
use mavlink::dialects::common::*;
use wmr_mavlink::{EndpointSpec, Event};

fn item_fields(m: &MavMessage) -> (u16, u8, f32, u32, i32, i32, f32, u16) {
    match m {
        MavMessage::MISSION_ITEM_INT(i) => (
            i.seq,
            i.frame as u8,
            i.param1,
            i.param4.to_bits(),
            i.x,
            i.y,
            i.z,
            i.command as u16,
        ),
        other => panic!("not an item: {other:?}"),
    }
}

#[test]
fn upload_then_read_back_equal() {
    let mut rig = Rig::default_rig();
    let items = square();
    let (result, events) = rig.upload(&items);
    assert_eq!(result, MavMissionResult::MAV_MISSION_ACCEPTED);
    assert_eq!(events, vec![Event::LoadRoute]);
    let back = rig.download(true);
    assert_eq!(back.len(), items.len());
    for (sent, got) in items.iter().zip(&back) {
        assert_eq!(item_fields(sent), item_fields(got));
    }
    // The route: floor x = east, y = north; stops from hold time and yaw.
    let route = rig.ep.route();
    let w = route.as_slice();
    assert_eq!(w.len(), 4);
    assert_eq!((w[1].position_m.x, w[1].position_m.y), (1.0, 0.0));
    assert_eq!((w[2].position_m.x, w[2].position_m.y), (1.0, 1.0));
    assert!(w[0].stop.is_none() && w[2].stop.is_none());
    assert_eq!(w[1].stop.unwrap().dwell_s, 2.0);
    assert_eq!(w[1].stop.unwrap().face_heading_rad, None);
    // Yaw 0 (north) is the floor heading +π/2.
    let face = w[3].stop.unwrap().face_heading_rad.unwrap();
    assert!((face - core::f32::consts::FRAC_PI_2).abs() < 1e-6, "{face}");
    assert_eq!(rig.ep.counters().mission_refusals, 0);
}

#[test]
fn legacy_mission_item_upload_and_download() {
    let mut rig = Rig::default_rig();
    let legacy: Vec<MavMessage> = [(0.0f32, 0.0f32), (0.0, 2.0), (2.0, 2.0)]
        .iter()
        .enumerate()
        .map(|(i, &(n, e))| {
            MavMessage::MISSION_ITEM(MISSION_ITEM_DATA {
                x: n,
                y: e,
                seq: i as u16,
                command: MavCmd::MAV_CMD_NAV_WAYPOINT,
                target_system: 1,
                target_component: 1,
                frame: MavFrame::MAV_FRAME_LOCAL_NED,
                param4: f32::NAN,
                autocontinue: 1,
                ..Default::default()
            })
        })
        .collect();
    let (result, _) = rig.upload(&legacy);
    assert_eq!(result, MavMissionResult::MAV_MISSION_ACCEPTED);
    let back = rig.download(false);
    assert_eq!(back.len(), 3);
    for (sent, got) in legacy.iter().zip(&back) {
        let (MavMessage::MISSION_ITEM(s), MavMessage::MISSION_ITEM(g)) = (sent, got) else {
            panic!("legacy items expected");
        };
        assert_eq!((s.seq, s.x, s.y), (g.seq, g.x, g.y));
        assert!(g.param4.is_nan());
    }
    let w = rig.ep.route();
    assert_eq!(
        (w.as_slice()[2].position_m.x, w.as_slice()[2].position_m.y),
        (2.0, 2.0)
    );
}

/// WGS-84 local radii in f64, independently of the crate's f32.
fn expected_floor(lat0: i32, lon0: i32, lat: i32, lon: i32) -> (f64, f64) {
    let a = 6_378_137.0f64;
    let e2 = 6.694_379_990_14e-3f64;
    let phi = (f64::from(lat0) * 1e-7).to_radians();
    let w2 = 1.0 - e2 * phi.sin().powi(2);
    let m = a * (1.0 - e2) / w2.powf(1.5);
    let n = a / w2.sqrt();
    let mid = (f64::from(lat0 + lat) * 0.5e-7).to_radians();
    let north = (f64::from(lat - lat0) * 1e-7).to_radians() * m;
    let east = (f64::from(lon - lon0) * 1e-7).to_radians() * n * mid.cos();
    (east, north)
}

#[test]
fn global_frame_items_through_the_origin() {
    let (lat0, lon0) = (473_977_420, 85_455_940); // Zürich
    let mut rig = Rig::new(EndpointSpec {
        origin_e7: Some((lat0, lon0)),
        telemetry_period_ms: 0,
        ..EndpointSpec::default()
    });
    // About 0 m, 11 m north, then 11 m north and 7.5 m east, 60 m away.
    let points = [(0, 0), (100_000, 0), (100_000, 100_000), (500_000, 500_000)];
    let items: Vec<MavMessage> = points
        .iter()
        .enumerate()
        .map(|(i, &(dlat, dlon))| {
            MavMessage::MISSION_ITEM_INT(MISSION_ITEM_INT_DATA {
                x: lat0 + dlat,
                y: lon0 + dlon,
                z: 10.0,
                seq: i as u16,
                command: MavCmd::MAV_CMD_NAV_WAYPOINT,
                target_system: 1,
                target_component: 1,
                frame: MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                param4: f32::NAN,
                autocontinue: 1,
                ..Default::default()
            })
        })
        .collect();
    let (result, _) = rig.upload(&items);
    assert_eq!(result, MavMissionResult::MAV_MISSION_ACCEPTED);
    let route = rig.ep.route();
    for (w, &(dlat, dlon)) in route.as_slice().iter().zip(&points) {
        let (x, y) = expected_floor(lat0, lon0, lat0 + dlat, lon0 + dlon);
        let err = ((f64::from(w.position_m.x) - x).powi(2)
            + (f64::from(w.position_m.y) - y).powi(2))
        .sqrt();
        assert!(err < 1e-3, "error {err} m at ({x}, {y})");
    }
    let back = rig.download(true);
    for (sent, got) in items.iter().zip(&back) {
        assert_eq!(item_fields(sent), item_fields(got));
    }
}

/// Uploads a good mission, then `bad`: the result, with the running
/// mission and route kept and the refusal counted.
fn refused(bad: &[MavMessage], spec: EndpointSpec) -> MavMissionResult {
    let mut rig = Rig::new(spec);
    assert_eq!(
        rig.upload(&square()).0,
        MavMissionResult::MAV_MISSION_ACCEPTED
    );
    let route_before = rig.ep.route();
    let (result, events) = rig.upload(bad);
    assert!(events.is_empty(), "{events:?}");
    assert_eq!(rig.ep.route(), route_before);
    assert_eq!(rig.download(true).len(), 4);
    assert_eq!(rig.ep.counters().mission_refusals, 1);
    result
}

fn with(
    mut items: Vec<MavMessage>,
    seq: usize,
    f: impl FnOnce(&mut MISSION_ITEM_INT_DATA),
) -> Vec<MavMessage> {
    if let MavMessage::MISSION_ITEM_INT(i) = &mut items[seq] {
        f(i);
    }
    items
}

#[test]
fn bad_missions_get_their_result_and_keep_the_running_one() {
    let spec = EndpointSpec {
        telemetry_period_ms: 0,
        ..EndpointSpec::default()
    };
    let too_many: Vec<MavMessage> = (0..65)
        .map(|i| local_item(i, f32::from(i), 0.0, 0.0, f32::NAN))
        .collect();
    assert_eq!(
        refused(&too_many, spec),
        MavMissionResult::MAV_MISSION_NO_SPACE
    );

    let takeoff = with(square(), 2, |i| i.command = MavCmd::MAV_CMD_NAV_TAKEOFF);
    assert_eq!(
        refused(&takeoff, spec),
        MavMissionResult::MAV_MISSION_UNSUPPORTED
    );

    let enu = with(square(), 1, |i| i.frame = MavFrame::MAV_FRAME_LOCAL_ENU);
    assert_eq!(
        refused(&enu, spec),
        MavMissionResult::MAV_MISSION_UNSUPPORTED_FRAME
    );

    // A global frame without an origin configured.
    let global = with(square(), 0, |i| i.frame = MavFrame::MAV_FRAME_GLOBAL_INT);
    assert_eq!(
        refused(&global, spec),
        MavMissionResult::MAV_MISSION_UNSUPPORTED_FRAME
    );

    let hold = with(square(), 1, |i| i.param1 = -1.0);
    assert_eq!(
        refused(&hold, spec),
        MavMissionResult::MAV_MISSION_INVALID_PARAM1
    );

    let yaw = with(square(), 1, |i| i.param4 = f32::INFINITY);
    assert_eq!(
        refused(&yaw, spec),
        MavMissionResult::MAV_MISSION_INVALID_PARAM4
    );

    // Two equal consecutive positions: refused by the core's planner.
    let same = with(square(), 2, |i| {
        i.x = 0;
        i.y = 10_000;
    });
    assert_eq!(refused(&same, spec), MavMissionResult::MAV_MISSION_INVALID);

    // One waypoint is not a route.
    let one = vec![local_item(0, 1.0, 1.0, 0.0, f32::NAN)];
    assert_eq!(refused(&one, spec), MavMissionResult::MAV_MISSION_INVALID);

    // Out of the floor's ±1e4 m: refused by the core's waypoint check.
    let far = with(square(), 3, |i| i.x = 200_000_000);
    assert_eq!(
        refused(&far, spec),
        MavMissionResult::MAV_MISSION_INVALID_PARAM5_X
    );
}

#[test]
fn nan_coordinates_in_legacy_items_are_refused_by_axis() {
    let spec = EndpointSpec {
        telemetry_period_ms: 0,
        ..EndpointSpec::default()
    };
    for (nan_x, expected) in [
        (true, MavMissionResult::MAV_MISSION_INVALID_PARAM5_X),
        (false, MavMissionResult::MAV_MISSION_INVALID_PARAM6_Y),
    ] {
        let items: Vec<MavMessage> = (0..3)
            .map(|i| {
                let bad = i == 1;
                MavMessage::MISSION_ITEM(MISSION_ITEM_DATA {
                    x: if bad && nan_x { f32::NAN } else { f32::from(i) },
                    y: if bad && !nan_x { f32::NAN } else { 0.0 },
                    seq: i,
                    command: MavCmd::MAV_CMD_NAV_WAYPOINT,
                    target_system: 1,
                    target_component: 1,
                    frame: MavFrame::MAV_FRAME_LOCAL_NED,
                    ..Default::default()
                })
            })
            .collect();
        assert_eq!(refused(&items, spec), expected);
    }
}

#[test]
fn an_unknown_command_number_is_unsupported() {
    let mut rig = Rig::default_rig();
    assert_eq!(
        rig.upload(&square()).0,
        MavMissionResult::MAV_MISSION_ACCEPTED
    );
    let bytes = rig.encode(&MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
        count: 2,
        target_system: 1,
        target_component: 1,
    }));
    let (_, out) = rig.feed(&bytes);
    assert!(
        out.iter()
            .any(|m| matches!(m, MavMessage::MISSION_REQUEST_INT(r) if r.seq == 0))
    );
    // MISSION_ITEM_INT with command 60000 (no such MAV_CMD), by its layout.
    let mut payload = [0u8; 38];
    payload[12..16].copy_from_slice(&f32::NAN.to_le_bytes());
    payload[30..32].copy_from_slice(&60_000u16.to_le_bytes());
    payload[32] = 1;
    payload[33] = 1;
    payload[34] = MavFrame::MAV_FRAME_LOCAL_NED as u8;
    let frame = raw_v2(
        9,
        73,
        <MISSION_ITEM_INT_DATA as mavlink::MessageData>::EXTRA_CRC,
        &payload,
    );
    let (events, out) = rig.feed(&frame);
    assert!(events.is_empty());
    let ack = out.iter().find_map(|m| match m {
        MavMessage::MISSION_ACK(a) => Some(a.mavtype),
        _ => None,
    });
    assert_eq!(ack, Some(MavMissionResult::MAV_MISSION_UNSUPPORTED));
    assert_eq!(rig.ep.mission().len(), 4);
}

#[test]
fn upload_times_out_after_the_retries_and_keeps_the_mission() {
    let mut rig = Rig::new(EndpointSpec {
        item_timeout_ms: 500,
        item_retries: 2,
        telemetry_period_ms: 0,
        ..EndpointSpec::default()
    });
    assert_eq!(
        rig.upload(&square()).0,
        MavMissionResult::MAV_MISSION_ACCEPTED
    );
    rig.send(MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
        count: 3,
        target_system: 1,
        target_component: 1,
    }));
    let (_, out) = rig.send(local_item(0, 5.0, 5.0, 0.0, f32::NAN));
    assert!(
        out.iter()
            .any(|m| matches!(m, MavMessage::MISSION_REQUEST_INT(r) if r.seq == 1))
    );
    let mut requests = 0;
    let mut cancelled = false;
    for _ in 0..40 {
        let (_, out) = rig.tick(100);
        for m in out {
            match m {
                MavMessage::MISSION_REQUEST_INT(r) => {
                    assert_eq!(r.seq, 1);
                    requests += 1;
                }
                MavMessage::MISSION_ACK(a) => {
                    assert_eq!(a.mavtype, MavMissionResult::MAV_MISSION_OPERATION_CANCELLED);
                    cancelled = true;
                }
                _ => {}
            }
        }
    }
    assert_eq!(requests, 2);
    assert!(cancelled);
    assert_eq!(rig.ep.counters().upload_timeouts, 1);
    assert_eq!(rig.ep.mission().len(), 4);
}

#[test]
fn fence_uploads_are_unsupported() {
    let mut rig = Rig::default_rig();
    // MISSION_COUNT with mission_type FENCE (an extension field the
    // library build here does not carry), by its layout.
    let frame = raw_v2(
        0,
        44,
        <MISSION_COUNT_DATA as mavlink::MessageData>::EXTRA_CRC,
        &[3, 0, 1, 1, MavMissionType::MAV_MISSION_TYPE_FENCE as u8],
    );
    let mut buf = vec![0u8; 4096];
    let mut tx = wmr_mavlink::TxBuffer::new(&mut buf);
    let events = rig.ep.handle(0, &frame, &rig.view, plan_check, &mut tx);
    assert!(events.as_slice().is_empty());
    // The MISSION_ACK frame (id 47): result UNSUPPORTED, mission_type echoed.
    let out = tx.as_slice();
    let ack = out
        .windows(14)
        .find(|w| w[0] == 0xFD && w[7] == 47 && w[8] == 0 && w[9] == 0)
        .expect("a MISSION_ACK frame");
    assert_eq!(ack[1], 4);
    assert_eq!((ack[10], ack[11]), (GCS_SYS, GCS_COMP));
    assert_eq!(ack[12], MavMissionResult::MAV_MISSION_UNSUPPORTED as u8);
    assert_eq!(ack[13], MavMissionType::MAV_MISSION_TYPE_FENCE as u8);
    assert_eq!(rig.ep.counters().mission_refusals, 1);
}

#[test]
fn clear_set_current_and_items_reached() {
    let mut rig = Rig::default_rig();
    assert_eq!(
        rig.upload(&square()).0,
        MavMissionResult::MAV_MISSION_ACCEPTED
    );

    let (events, out) = rig.send(MavMessage::MISSION_SET_CURRENT(MISSION_SET_CURRENT_DATA {
        seq: 2,
        target_system: 1,
        target_component: 1,
    }));
    assert_eq!(events, vec![Event::SetCurrent(2)]);
    assert!(
        out.iter()
            .any(|m| matches!(m, MavMessage::MISSION_CURRENT(c) if c.seq == 2))
    );
    let (events, out) = rig.send(MavMessage::MISSION_SET_CURRENT(MISSION_SET_CURRENT_DATA {
        seq: 9,
        target_system: 1,
        target_component: 1,
    }));
    assert!(events.is_empty());
    assert!(out.iter().any(|m| matches!(m, MavMessage::STATUSTEXT(_))));
    assert_eq!(rig.ep.counters().mission_refusals, 1);

    // Reached 0 and 1 between two calls: both reported, once each.
    rig.view.reached = Some(1);
    let (_, out) = rig.tick(10);
    let reached: Vec<u16> = out
        .iter()
        .filter_map(|m| match m {
            MavMessage::MISSION_ITEM_REACHED(r) => Some(r.seq),
            _ => None,
        })
        .collect();
    assert_eq!(reached, vec![0, 1]);
    let (_, out) = rig.tick(10);
    assert!(
        !out.iter()
            .any(|m| matches!(m, MavMessage::MISSION_ITEM_REACHED(_)))
    );

    let (events, out) = rig.send(MavMessage::MISSION_CLEAR_ALL(MISSION_CLEAR_ALL_DATA {
        target_system: 1,
        target_component: 1,
    }));
    assert_eq!(events, vec![Event::ClearRoute]);
    assert!(out.iter().any(|m| matches!(m, MavMessage::MISSION_ACK(a) if a.mavtype == MavMissionResult::MAV_MISSION_ACCEPTED)));
    assert!(rig.download(true).is_empty());
}
