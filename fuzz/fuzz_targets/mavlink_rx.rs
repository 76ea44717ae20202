//! Arbitrary bytes into the MAVLink endpoint's receive path
//! (`wmr_mavlink::MavlinkEndpoint::handle`), in arbitrary chunks, with an
//! arbitrary robot state, clock steps and route-check verdicts.
//!
//! Input: byte 0 drives the chunk sizes, byte 1 the robot's state and the
//! route check, byte 2 the clock's steps; the rest is the stream. Checked
//! at every call, besides the absence of panics and overflows:
//!
//! * what the endpoint sends is whole MAVLink 2 frames from system 1,
//!   component 1, each with a good CRC (read back by the `mavlink`
//!   library), and nothing else;
//! * an event that moves the robot (arm, start, continue) or loads a route
//!   comes only from a call in which a frame passed its CRC;
//! * the counters never go down.

#![no_main]

use libfuzzer_sys::fuzz_target;
use mavlink::dialects::common::MavMessage;
use mavlink::{MavlinkReader, MavlinkVersion};
use wmr_core::reference::route::{RouteError, RouteLimits, RouteLimitsSpec};
use wmr_mavlink::{
    Counters, EndpointConfig, EndpointSpec, Estimate, Event, MavlinkEndpoint, RobotMode, RobotView,
    TxBuffer,
};

/// Every byte of `out` is in a whole, CRC-valid MAVLink 2 frame of ours.
fn whole_frames(out: &[u8]) {
    let mut reader = MavlinkReader::new(out);
    let mut consumed = 0;
    while consumed < out.len() {
        let raw = reader
            .read_raw_message::<MavMessage>(MavlinkVersion::V2)
            .expect("the endpoint sends only good MAVLink 2 frames");
        assert_eq!((raw.system_id(), raw.component_id()), (1, 1));
        let mavlink::MAVLinkMessageRaw::V2(frame) = raw else {
            panic!("a MAVLink 1 frame out");
        };
        consumed += frame.raw_bytes().len();
    }
    assert_eq!(consumed, out.len());
}

fn not_less(before: &Counters, after: &Counters) {
    let b = [
        before.rx.frames,
        before.rx.garbage_bytes,
        before.rx.crc_errors,
        before.rx.unknown_messages,
        before.rx.unsupported_frames,
        before.not_for_us,
        before.mission_refusals,
        before.upload_timeouts,
        before.command_refusals,
        before.param_refusals,
        before.link_losses,
        before.tx_dropped,
    ];
    let a = [
        after.rx.frames,
        after.rx.garbage_bytes,
        after.rx.crc_errors,
        after.rx.unknown_messages,
        after.rx.unsupported_frames,
        after.not_for_us,
        after.mission_refusals,
        after.upload_timeouts,
        after.command_refusals,
        after.param_refusals,
        after.link_losses,
        after.tx_dropped,
    ];
    for (b, a) in b.iter().zip(&a) {
        assert!(a >= b, "a counter went down: {before:?} → {after:?}");
    }
}

fuzz_target!(|data: &[u8]| {
    let [chunks, state, clock, stream @ ..] = data else {
        return;
    };
    let spec = EndpointSpec {
        origin_e7: (state & 0x40 != 0).then_some((473_977_420, 85_455_940)),
        telemetry_period_ms: 50,
        ..EndpointSpec::default()
    };
    let config = EndpointConfig::new(&spec).expect("a valid configuration");
    let limits = RouteLimits::new(&RouteLimitsSpec {
        max_speed_m_s: 0.5,
        max_tangential_accel_m_s2: 0.5,
        max_lateral_accel_m_s2: 0.5,
        blend_deviation_m: 0.05,
        pivot_threshold_rad: 0.5,
        pivot_rate_rad_s: 1.0,
        pivot_accel_rad_s2: 2.0,
    })
    .expect("valid limits");
    let mut endpoint = MavlinkEndpoint::new(config, limits);
    let mode = match state & 3 {
        0 => RobotMode::Idle,
        1 => RobotMode::Running,
        2 => RobotMode::Paused,
        _ => RobotMode::Stopped,
    };
    let mut view = RobotView {
        armed: state & 4 != 0,
        mode,
        estimate: Some(Estimate {
            x_m: 1.5,
            y_m: -2.0,
            heading_rad: 0.3,
            speed_m_s: 0.2,
            turn_rate_rad_s: -0.1,
        }),
        current: 0,
        reached: None,
    };
    let refuse_routes = state & 8 != 0;
    let mut now_ms = 0u32;
    let mut rest = stream;
    let mut call = 0u32;
    let mut out = [0u8; 2048];
    while !rest.is_empty() {
        let size = 1 + usize::from(chunks.rotate_left(call % 8)) % 64;
        let (chunk, tail) = rest.split_at(size.min(rest.len()));
        rest = tail;
        now_ms = now_ms.wrapping_add(u32::from(*clock) * (call % 5 + 1));
        view.reached = (call % 3 == 0).then_some((call / 3) as u16);
        view.current = (call % 7) as u16;
        let before = endpoint.counters();
        let mut tx = TxBuffer::new(&mut out);
        let events = endpoint.handle(
            now_ms,
            chunk,
            &view,
            |_| {
                if refuse_routes {
                    Err(RouteError::TooLong)
                } else {
                    Ok(())
                }
            },
            &mut tx,
        );
        let after = endpoint.counters();
        whole_frames(tx.as_slice());
        not_less(&before, &after);
        let moved = events.as_slice().iter().any(|e| {
            matches!(
                e,
                Event::Arm | Event::Start | Event::Continue | Event::LoadRoute
            )
        });
        if moved {
            assert!(
                after.rx.frames > before.rx.frames,
                "{events:?} from no frame"
            );
        }
        // The route of an accepted mission is what the endpoint holds.
        if events.as_slice().contains(&Event::LoadRoute) {
            assert!(!refuse_routes);
            assert_eq!(
                usize::from(endpoint.mission().len()),
                endpoint.route().len()
            );
        }
        call += 1;
    }
});
