//! Commands and their acks, the heartbeat.

mod common;

use common::*;
use mavlink::dialects::common::*;
use wmr_mavlink::{Event, RobotMode};

const FORCE: f32 = 21_196.0;

#[test]
fn arm_start_pause_continue_stop() {
    let mut rig = Rig::default_rig();
    let arm = MavCmd::MAV_CMD_COMPONENT_ARM_DISARM;
    let start = MavCmd::MAV_CMD_MISSION_START;
    let pause = MavCmd::MAV_CMD_DO_PAUSE_CONTINUE;

    // Start with no mission, then disarmed: denied.
    let (events, result) = rig.command(start, 0.0, 0.0);
    assert_eq!(
        (events, result),
        (vec![], Some(MavResult::MAV_RESULT_DENIED))
    );
    assert_eq!(
        rig.upload(&square()).0,
        MavMissionResult::MAV_MISSION_ACCEPTED
    );
    let (events, result) = rig.command(start, 0.0, 0.0);
    assert_eq!(
        (events, result),
        (vec![], Some(MavResult::MAV_RESULT_DENIED))
    );

    let (events, result) = rig.command(arm, 1.0, 0.0);
    assert_eq!(
        (events, result),
        (vec![Event::Arm], Some(MavResult::MAV_RESULT_ACCEPTED))
    );
    rig.view.armed = true;
    // Arming again: accepted, nothing to do.
    let (events, result) = rig.command(arm, 1.0, 0.0);
    assert_eq!(
        (events, result),
        (vec![], Some(MavResult::MAV_RESULT_ACCEPTED))
    );

    // Pause while idle: denied.
    let (events, result) = rig.command(pause, 0.0, 0.0);
    assert_eq!(
        (events, result),
        (vec![], Some(MavResult::MAV_RESULT_DENIED))
    );

    let (events, result) = rig.command(start, 0.0, 0.0);
    assert_eq!(
        (events, result),
        (vec![Event::Start], Some(MavResult::MAV_RESULT_ACCEPTED))
    );
    rig.view.mode = RobotMode::Running;
    // Start from item 2: set current, then start.
    let (events, result) = rig.command(start, 2.0, 0.0);
    assert_eq!(
        (events, result),
        (
            vec![Event::SetCurrent(2), Event::Start],
            Some(MavResult::MAV_RESULT_ACCEPTED)
        )
    );
    // Start from an item past the mission: denied.
    let (_, result) = rig.command(start, 7.0, 0.0);
    assert_eq!(result, Some(MavResult::MAV_RESULT_DENIED));

    let (events, result) = rig.command(pause, 0.0, 0.0);
    assert_eq!(
        (events, result),
        (vec![Event::Pause], Some(MavResult::MAV_RESULT_ACCEPTED))
    );
    rig.view.mode = RobotMode::Paused;
    let (events, result) = rig.command(pause, 1.0, 0.0);
    assert_eq!(
        (events, result),
        (vec![Event::Continue], Some(MavResult::MAV_RESULT_ACCEPTED))
    );
    rig.view.mode = RobotMode::Running;

    // Disarm while running: denied; forced: an emergency stop.
    let (events, result) = rig.command(arm, 0.0, 0.0);
    assert_eq!(
        (events, result),
        (vec![], Some(MavResult::MAV_RESULT_DENIED))
    );
    let (events, result) = rig.command(arm, 0.0, FORCE);
    assert_eq!(
        (events, result),
        (
            vec![Event::EmergencyStop],
            Some(MavResult::MAV_RESULT_ACCEPTED)
        )
    );
    rig.view.mode = RobotMode::Stopped;
    // Stopped: start denied until re-armed; disarm accepted.
    let (_, result) = rig.command(start, 0.0, 0.0);
    assert_eq!(result, Some(MavResult::MAV_RESULT_DENIED));
    let (events, result) = rig.command(arm, 0.0, 0.0);
    assert_eq!(
        (events, result),
        (vec![Event::Disarm], Some(MavResult::MAV_RESULT_ACCEPTED))
    );

    let (events, result) = rig.command(MavCmd::MAV_CMD_DO_FLIGHTTERMINATION, 1.0, 0.0);
    assert_eq!(
        (events, result),
        (
            vec![Event::EmergencyStop],
            Some(MavResult::MAV_RESULT_ACCEPTED)
        )
    );

    // A bad parameter: denied.
    let (events, result) = rig.command(arm, f32::NAN, 0.0);
    assert_eq!(
        (events, result),
        (vec![], Some(MavResult::MAV_RESULT_DENIED))
    );
    // Unsupported: answered so.
    let (events, result) = rig.command(MavCmd::MAV_CMD_NAV_TAKEOFF, 0.0, 0.0);
    assert_eq!(
        (events, result),
        (vec![], Some(MavResult::MAV_RESULT_UNSUPPORTED))
    );
    assert_eq!(rig.ep.counters().command_refusals, 8);
}

#[test]
fn an_unknown_command_number_is_acked_unsupported_with_its_number() {
    let mut rig = Rig::default_rig();
    // COMMAND_LONG with command 61234, by its layout.
    let mut payload = [0u8; 33];
    payload[28..30].copy_from_slice(&61_234u16.to_le_bytes());
    payload[30] = 1;
    payload[31] = 1;
    let frame = raw_v2(
        0,
        76,
        <COMMAND_LONG_DATA as mavlink::MessageData>::EXTRA_CRC,
        &payload,
    );
    // The library cannot decode the ack (no such MAV_CMD): read its bytes.
    let mut buf = vec![0u8; 4096];
    let mut tx = wmr_mavlink::TxBuffer::new(&mut buf);
    let events = rig
        .ep
        .handle(rig.now_ms, &frame, &rig.view, plan_check, &mut tx);
    assert!(events.as_slice().is_empty());
    let out = tx.as_slice();
    let ack = out
        .windows(13)
        .find(|w| w[0] == 0xFD && w[7] == 77 && w[8] == 0 && w[9] == 0)
        .expect("a COMMAND_ACK frame");
    assert_eq!(u16::from_le_bytes([ack[10], ack[11]]), 61_234);
    assert_eq!(ack[12], MavResult::MAV_RESULT_UNSUPPORTED as u8);
}

#[test]
fn command_int_and_targets() {
    let mut rig = Rig::default_rig();
    let (events, out) = rig.send(MavMessage::COMMAND_INT(COMMAND_INT_DATA {
        command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
        param1: 1.0,
        target_system: 1,
        target_component: 1,
        ..Default::default()
    }));
    assert_eq!(events, vec![Event::Arm]);
    assert_eq!(ack_of(&out, 400), Some(MavResult::MAV_RESULT_ACCEPTED));
    // Addressed to system 7: ignored, counted.
    let (events, out) = rig.send(MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
        param1: 1.0,
        target_system: 7,
        target_component: 1,
        ..Default::default()
    }));
    assert!(events.is_empty());
    assert_eq!(ack_of(&out, 400), None);
    assert_eq!(rig.ep.counters().not_for_us, 1);
}

#[test]
fn mavlink1_in_mavlink2_out() {
    let mut rig = Rig::default_rig();
    let bytes = rig.encode_v1(&MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
        param1: 1.0,
        target_system: 1,
        target_component: 1,
        ..Default::default()
    }));
    assert_eq!(bytes[0], 0xFE);
    let (events, out) = rig.feed(&bytes);
    assert_eq!(events, vec![Event::Arm]);
    assert_eq!(ack_of(&out, 400), Some(MavResult::MAV_RESULT_ACCEPTED));
}

#[test]
fn heartbeat_at_one_hertz_with_mode_and_armed() {
    let mut rig = Rig::default_rig();
    let mut beats = Vec::new();
    for _ in 0..300 {
        let (_, out) = rig.tick(10);
        beats.extend(out.into_iter().filter_map(|m| match m {
            MavMessage::HEARTBEAT(h) => Some(h),
            _ => None,
        }));
    }
    // 3 s at 10 ms: the first call and every 1,000 ms after it.
    assert_eq!(beats.len(), 3);
    let h = &beats[0];
    assert_eq!(h.mavtype, MavType::MAV_TYPE_GROUND_ROVER);
    assert_eq!(h.autopilot, MavAutopilot::MAV_AUTOPILOT_GENERIC);
    assert!(
        !h.base_mode
            .contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED)
    );
    assert_eq!(h.system_status, MavState::MAV_STATE_STANDBY);

    // A mode change is sent at once, with a STATUSTEXT.
    rig.view.armed = true;
    rig.view.mode = RobotMode::Running;
    let (_, out) = rig.tick(10);
    let h = out
        .iter()
        .find_map(|m| match m {
            MavMessage::HEARTBEAT(h) => Some(h.clone()),
            _ => None,
        })
        .expect("heartbeat on the change");
    assert!(
        h.base_mode
            .contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED)
    );
    assert!(
        h.base_mode
            .contains(MavModeFlag::MAV_MODE_FLAG_AUTO_ENABLED)
    );
    assert_eq!(h.custom_mode, RobotMode::Running as u32);
    assert_eq!(h.system_status, MavState::MAV_STATE_ACTIVE);
    assert!(out.iter().any(|m| matches!(m, MavMessage::STATUSTEXT(_))));
}
