//! Unit tests of the messages, the framing and the channel.

use super::codec::{CRC, cobs_decode_in_place};
use super::*;
use serde::Deserialize;
use wmr_core::devices::TagMapError;

/// The bit-by-bit CRC is CRC-32/ISO-HDLC: its check value, and the
/// table-driven one on every length of a pseudo-random buffer.
#[test]
fn crc_is_crc32_iso_hdlc() {
    assert_eq!(CRC.checksum(b"123456789"), 0xCBF4_3926);
    let table = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);
    let bytes: std::vec::Vec<u8> = (0..300_u32)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
        .collect();
    for n in 0..bytes.len() {
        assert_eq!(CRC.checksum(&bytes[..n]), table.checksum(&bytes[..n]));
    }
}
use proptest::prelude::*;
use wmr_core::devices::tag_grid::TagGridSpec;
use wmr_core::pilot::spec::PilotSpec;

pub(crate) fn configure() -> HostMessage {
    HostMessage::Configure(Configure {
        protocol: PROTOCOL_VERSION,
        pilot: PilotSpec::EXAMPLE,
        floor: FloorSpec::Grid(TagGridSpec {
            origin_m: [-6.0, -6.0],
            spacing_m: 0.1,
            rows: 130,
            columns: 130,
        }),
        pwm_max_duty: 1000,
        telemetry_every_ticks: 1,
    })
}

fn full_tick() -> HostMessage {
    let mut uart = heapless::Vec::new();
    for i in 0..MAX_UART_BYTES_PER_TICK {
        let _ = uart.push(u8::try_from(i % 251).unwrap_or(0));
    }
    HostMessage::Tick(TickInput {
        tick: u32::MAX,
        left_count: Some(u32::MAX),
        right_count: None,
        uart,
    })
}

fn feed<M: for<'de> Deserialize<'de>>(
    rx: &mut Receiver,
    bytes: &[u8],
) -> Vec<Result<M, LinkError>> {
    bytes.iter().filter_map(|&b| rx.push(b)).collect()
}

#[test]
fn messages_round_trip_and_fit() {
    let mut tx = Sender::default();
    let mut rx = Receiver::new();
    let mut out = [0; MAX_FRAME_BYTES];
    let chunk = HostMessage::MapChunk(MapChunk {
        first: 16,
        tags: heapless::Vec::from_slice(&[MapTag {
            id: 0x12_3456_789A,
            position_m: [1.5, -0.25],
        }])
        .unwrap(),
    });
    for msg in [configure(), chunk, full_tick(), HostMessage::Finish] {
        let bytes = tx.frame(msg.clone(), &mut out).unwrap().to_vec();
        assert_eq!(bytes.last(), Some(&0));
        assert!(!bytes[..bytes.len() - 1].contains(&0));
        assert_eq!(feed::<HostMessage>(&mut rx, &bytes), vec![Ok(msg)]);
    }
    assert_eq!(rx.counters().frames_ok, 4);
    assert_eq!(rx.counters().sequence_gaps, 0);
}

/// The largest chunk (every id and index at its longest varint,
/// positions that do not compress) is one frame, and decodes back;
/// in RAM it is no larger than `Configure`, the largest message
/// before it, so the firmware's receive path needs no more stack.
#[test]
fn a_full_map_chunk_fits_a_frame() {
    let tags = (0..MAP_CHUNK_TAGS)
        .map(|i| MapTag {
            id: u64::MAX - i as u64,
            position_m: [f32::MIN_POSITIVE, -f32::MAX],
        })
        .collect();
    let chunk = HostMessage::MapChunk(MapChunk {
        first: u16::MAX,
        tags,
    });
    let mut out = [0; MAX_FRAME_BYTES];
    let mut tx = Sender { seq: u32::MAX };
    let bytes = tx.frame(chunk.clone(), &mut out).unwrap().to_vec();
    println!("largest map chunk: {} B of {MAX_FRAME_BYTES}", bytes.len());
    let mut rx = Receiver::new();
    assert_eq!(feed::<HostMessage>(&mut rx, &bytes), vec![Ok(chunk)]);
    assert!(core::mem::size_of::<MapChunk>() <= core::mem::size_of::<Configure>());
    // The capacity and every index fit the messages' u16.
    assert!(u16::try_from(MAP_CAPACITY).is_ok());
}

/// A full MAVLink chunk (bytes that do not compress, every varint at its
/// longest) is one frame either way, decodes back, and a longer one is
/// refused by the decoder; in RAM the host's is no larger than
/// `Configure`, so the firmware's receive path needs no more stack.
#[test]
fn a_full_mavlink_chunk_fits_a_frame() {
    let bytes: std::vec::Vec<u8> = (0..MAVLINK_CHUNK_BYTES)
        .map(|i| (i % 255) as u8 + 1)
        .collect();
    let chunk = MavlinkChunk::from_slice(&bytes);
    assert_eq!(chunk.as_slice(), &bytes[..]);
    // A longer slice fills one chunk; the rest is the caller's.
    let mut longer = bytes.clone();
    longer.push(7);
    assert_eq!(MavlinkChunk::from_slice(&longer), chunk);
    let host = HostMessage::Mavlink(MavlinkIn {
        seq: u32::MAX,
        bytes: chunk,
    });
    let target = TargetMessage::Mavlink(MavlinkOut {
        seq: u32::MAX,
        bytes: chunk,
        pending: u16::MAX,
        counters: MavlinkCounters {
            rx_dropped_bytes: u32::MAX,
            tx_dropped_frames: u32::MAX,
            repeated: u32::MAX,
        },
    });
    let mut out = [0; MAX_FRAME_BYTES];
    let mut tx = Sender { seq: u32::MAX };
    let frame = tx.frame(host.clone(), &mut out).unwrap().to_vec();
    println!(
        "largest MAVLink chunk in: {} B of {MAX_FRAME_BYTES}",
        frame.len()
    );
    assert_eq!(
        feed::<HostMessage>(&mut Receiver::new(), &frame),
        vec![Ok(host)]
    );
    let frame = tx.frame(target, &mut out).unwrap().to_vec();
    println!(
        "largest MAVLink chunk out: {} B of {MAX_FRAME_BYTES}",
        frame.len()
    );
    assert_eq!(
        feed::<TargetMessage>(&mut Receiver::new(), &frame),
        vec![Ok(target)]
    );
    assert!(core::mem::size_of::<MavlinkIn>() <= core::mem::size_of::<Configure>());
    // A chunk over the limit on the wire is refused, not cut.
    let mut buf = [0_u8; 2 * MAVLINK_CHUNK_BYTES];
    let long = postcard::to_slice(&longer[..], &mut buf).unwrap();
    assert!(postcard::from_bytes::<MavlinkChunk>(long).is_err());
    let exact = postcard::to_slice(&bytes[..], &mut buf).unwrap();
    assert_eq!(postcard::from_bytes::<MavlinkChunk>(exact).unwrap(), chunk);
}

/// The firmware's queues: bytes queued up to their room and the rest
/// counted, output handed out in chunks in order, a message sent again
/// answered again without queueing twice.
#[test]
fn mavlink_queues_bound_count_and_answer_resends_again() {
    let mut q = MavlinkQueues::new();
    let full = MavlinkChunk::from_slice(&[9; MAVLINK_CHUNK_BYTES]);
    // Not accepted (no endpoint): all counted.
    let a = q.exchange(
        &MavlinkIn {
            seq: 0,
            bytes: full,
        },
        false,
    );
    assert_eq!((a.bytes.len(), a.pending), (0, 0));
    assert_eq!(a.counters.rx_dropped_bytes, MAVLINK_CHUNK_BYTES as u32);
    // Accepted up to the queue's room, the rest counted.
    let chunks = MAVLINK_RX_QUEUE_BYTES / MAVLINK_CHUNK_BYTES;
    for seq in 1..=chunks as u32 + 1 {
        q.exchange(&MavlinkIn { seq, bytes: full }, true);
    }
    assert_eq!(
        q.counters().rx_dropped_bytes,
        2 * MAVLINK_CHUNK_BYTES as u32
    );
    // Sent again: the same answer, nothing queued, counted as repeated.
    let again = q.exchange(
        &MavlinkIn {
            seq: chunks as u32 + 1,
            bytes: full,
        },
        true,
    );
    assert_eq!(
        again.counters.rx_dropped_bytes,
        2 * MAVLINK_CHUNK_BYTES as u32
    );
    assert_eq!(again.counters.repeated, 1);
    // The tick sees every queued byte and writes output; 3 frames dropped.
    let mut seen = 0;
    q.tick(|rx, room| {
        seen = rx.len();
        assert_eq!(room.len(), MAVLINK_TX_QUEUE_BYTES);
        for (i, b) in room.iter_mut().take(500).enumerate() {
            *b = (i % 251) as u8;
        }
        (500, 3)
    });
    assert_eq!(seen, MAVLINK_RX_QUEUE_BYTES);
    assert_eq!(q.counters().tx_dropped_frames, 3);
    // Output in order, chunk by chunk, until nothing is pending.
    let mut got = std::vec::Vec::new();
    let mut seq = 100;
    loop {
        let a = q.exchange(
            &MavlinkIn {
                seq,
                bytes: MavlinkChunk::new(),
            },
            true,
        );
        got.extend_from_slice(a.bytes.as_slice());
        seq += 1;
        if a.pending == 0 {
            break;
        }
    }
    assert_eq!(
        got,
        (0..500)
            .map(|i| (i % 251) as u8)
            .collect::<std::vec::Vec<_>>()
    );
    // The receive queue was emptied by the tick; output written after a
    // partial take goes after what is left.
    q.tick(|rx, room| {
        assert!(rx.is_empty());
        room[0] = 1;
        (1, 0)
    });
    assert_eq!(q.pending(), 1);
    // A writer claiming more than the room is held to the room.
    q.tick(|_, room| (room.len() + 10, 0));
    assert_eq!(q.pending(), MAVLINK_TX_QUEUE_BYTES);
}

/// A route chunk of [`ROUTE_CHUNK_WAYPOINTS`] waypoints at their longest
/// (each a stop facing a heading, with a speed limit) fits a frame; in
/// RAM it is no larger than `Configure`, so the firmware's receive path
/// needs no more stack; a route's capacity and every index fit the
/// messages' `u8`.
#[test]
fn a_full_route_chunk_fits_a_frame() {
    use wmr_core::reference::route::{ROUTE_CAPACITY, Waypoint};
    let waypoint = Waypoint::stop(-f32::MAX, f32::MIN_POSITIVE, f32::MAX)
        .facing(-f32::MAX)
        .with_speed_limit(f32::MAX);
    let chunk = HostMessage::RouteChunk(RouteChunk {
        first: u8::MAX,
        waypoints: heapless::Vec::from_slice(&[waypoint; ROUTE_CHUNK_WAYPOINTS]).unwrap(),
    });
    let mut out = [0; MAX_FRAME_BYTES];
    let mut tx = Sender { seq: u32::MAX };
    let bytes = tx.frame(chunk.clone(), &mut out).unwrap().to_vec();
    println!(
        "largest route chunk: {} B of {MAX_FRAME_BYTES}",
        bytes.len()
    );
    let mut rx = Receiver::new();
    assert_eq!(feed::<HostMessage>(&mut rx, &bytes), vec![Ok(chunk)]);
    assert!(core::mem::size_of::<RouteChunk>() <= core::mem::size_of::<Configure>());
    assert!(u8::try_from(ROUTE_CAPACITY).is_ok());
    // The announcement too.
    let announce = HostMessage::Route(RouteSpec {
        waypoints: u8::MAX,
        limits: wmr_core::reference::route::RouteLimitsSpec {
            max_speed_m_s: f32::MAX,
            max_tangential_accel_m_s2: f32::MAX,
            max_lateral_accel_m_s2: f32::MAX,
            blend_deviation_m: f32::MAX,
            pivot_threshold_rad: f32::MAX,
            pivot_rate_rad_s: f32::MAX,
            pivot_accel_rad_s2: f32::MAX,
        },
        options: RouteOptionsSpec {
            pivot_gain_per_s: f32::MAX,
            position_tolerance_m: f32::MAX,
            heading_tolerance_rad: f32::MAX,
            max_lag_m: f32::MAX,
            approach_speed_m_s: f32::MAX,
            approach_timeout_s: f32::MAX,
        },
        start: wmr_core::pilot::route::RouteStart::FromFirstFix,
        mavlink: crate::MavlinkSettings {
            system_id: u8::MAX,
            component_id: u8::MAX,
            link_timeout_ms: u32::MAX,
            item_timeout_ms: u32::MAX,
            item_retries: u8::MAX,
            telemetry_period_ms: u32::MAX,
            counters_period_ms: u32::MAX,
            origin_e7: Some([i32::MIN, i32::MIN]),
            power_on: crate::PowerOn::Wait,
        },
    });
    let bytes = tx.frame(announce.clone(), &mut out).unwrap().to_vec();
    assert_eq!(feed::<HostMessage>(&mut rx, &bytes), vec![Ok(announce)]);
}

/// Every refusal of a route says which and why, in words; the planner's
/// names the waypoint and its key.
#[test]
fn route_refusals_name_the_waypoint_and_why() {
    use wmr_core::reference::route::{LimitKey, RouteError, RouteLimitsError, WaypointKey};
    let said = |r: RouteRefusal| Refusal::Route(r).to_string();
    assert_eq!(
        said(RouteRefusal::Route(RouteError::NotFinite {
            index: 3,
            key: WaypointKey::Dwell
        })),
        "the route was refused: waypoint 3: stop.dwell_s must be finite"
    );
    assert_eq!(
        said(RouteRefusal::Limits(RouteLimitsError(LimitKey::MaxSpeed))),
        "the route was refused: limits: max_speed_m_s must be finite and > 0"
    );
    assert_eq!(
        said(RouteRefusal::Size {
            waypoints: 65,
            capacity: 64
        }),
        "the route was refused: the route announced 65 waypoints; the firmware holds 2 to 64"
    );
    assert_eq!(
        said(RouteRefusal::OutOfOrder {
            expected: 7,
            first: 14
        }),
        "the route was refused: a route chunk starting at waypoint 14 arrived; waypoint 7 was next"
    );
    assert_eq!(
        said(RouteRefusal::TooMany { announced: 4 }),
        "the route was refused: route chunks went past the 4 waypoints announced"
    );
    assert!(
        said(RouteRefusal::Options(
            wmr_core::pilot::route::RouteOptionsError::PivotGain
        ))
        .contains("pivot_gain_per_s")
    );
    // The MAVLink settings: the field by name, with its value.
    let bad = crate::MavlinkSettings {
        telemetry_period_ms: 5,
        ..crate::MavlinkSettings::default()
    };
    assert_eq!(
        said(bad.config().unwrap_err()),
        "the route was refused: mavlink: telemetry_period_ms = 5 must be in 0 or 20..=60000"
    );
    let bad = crate::MavlinkSettings {
        origin_e7: Some([900_000_000, 0]),
        ..crate::MavlinkSettings::default()
    };
    assert!(said(bad.config().unwrap_err()).contains("origin_e7.latitude = 900000000"));
}

/// Every refusal of a map says which tag and why, in words.
#[test]
fn map_refusals_name_the_tag_and_why() {
    let said = |r: MapRefusal| Refusal::Map(r).to_string();
    assert_eq!(
        said(MapRefusal::Tag {
            index: 7,
            why: TagMapError::DuplicateId
        }),
        "the tag map was refused: tag 7: tag id already in the map"
    );
    assert_eq!(
        said(MapRefusal::Size {
            tags: 5000,
            capacity: 4096
        }),
        "the tag map was refused: Configure announced 5000 tags; the firmware holds 1 to 4096"
    );
    assert!(
        said(MapRefusal::Tag {
            index: 3,
            why: TagMapError::Unsorted
        })
        .contains("ids must increase")
    );
    assert!(
        said(MapRefusal::OutOfOrder {
            expected: 16,
            first: 32
        })
        .contains("starting at tag 32 arrived; tag 16 was next")
    );
}

/// The flat serializer of `Diagnostics` writes what the derived
/// deserializer reads (postcard: a struct is its fields in order), in
/// field order: every counter distinct, round trip exact.
#[test]
fn diagnostics_serialize_flat_in_field_order() {
    let values: [u32; DIAGNOSTIC_COUNTERS] =
        core::array::from_fn(|i| 1000 * u32::try_from(i).unwrap() + 1);
    // A postcard tuple is its elements' encodings in a row.
    let mut wire = Vec::new();
    for v in values {
        let mut buf = [0_u8; 8];
        wire.extend_from_slice(postcard::to_slice(&v, &mut buf).unwrap());
    }
    let diagnostics: Diagnostics = postcard::from_bytes(&wire).unwrap();
    assert_eq!(diagnostics.flat(), values);
    assert_eq!(diagnostics.rfid.frames_ok, 1);
    assert_eq!(diagnostics.link.timeouts, 29_001);
    assert_eq!(diagnostics.stale_ticks, 33_001);
    let mut again = [0_u8; 256];
    assert_eq!(
        postcard::to_slice(&diagnostics, &mut again).unwrap(),
        &wire[..]
    );
}

#[test]
fn a_flipped_bit_is_caught_and_the_next_frame_still_decodes() {
    let mut tx = Sender::default();
    let mut rx = Receiver::new();
    let mut out = [0; MAX_FRAME_BYTES];
    let good = tx.frame(configure(), &mut out).unwrap().to_vec();
    let mut bad = good.clone();
    bad[10] ^= 0x04;
    let next = tx.frame(HostMessage::Finish, &mut out).unwrap().to_vec();
    let got = feed::<HostMessage>(&mut rx, &[bad, next].concat());
    assert_eq!(got.len(), 2);
    assert!(got[0].is_err());
    assert_eq!(got[1], Ok(HostMessage::Finish));
    assert_eq!(rx.counters().corrupt_frames, 1);
    // The corrupt frame still used a sequence number.
    assert_eq!(rx.counters().sequence_gaps, 0);
}

#[test]
fn sequence_gaps_are_counted() {
    let mut tx = Sender::default();
    let mut rx = Receiver::new();
    let mut out = [0; MAX_FRAME_BYTES];
    let first = tx.frame(HostMessage::Finish, &mut out).unwrap().to_vec();
    for _ in 0..3 {
        tx.frame(HostMessage::Finish, &mut out).unwrap();
    }
    let fifth = tx.frame(HostMessage::Finish, &mut out).unwrap().to_vec();
    let got = feed::<HostMessage>(&mut rx, &[first, fifth].concat());
    assert_eq!(got.len(), 2);
    assert_eq!(rx.counters().sequence_gaps, 3);
}

#[test]
fn duplicates_and_overtaken_frames_are_dropped_as_stale() {
    let mut tx = Sender::default();
    let mut rx = Receiver::new();
    let mut out = [0; MAX_FRAME_BYTES];
    let frames: Vec<Vec<u8>> = (0..3)
        .map(|_| tx.frame(HostMessage::Finish, &mut out).unwrap().to_vec())
        .collect();
    // 0, 0 again (a duplicate), 2 (overtakes 1), then the late 1.
    let stream = [&frames[0], &frames[0], &frames[2], &frames[1]].map(|f| f.as_slice());
    let got = feed::<HostMessage>(&mut rx, &stream.concat());
    assert_eq!(
        got,
        vec![
            Ok(HostMessage::Finish),
            Err(LinkError::Stale),
            Ok(HostMessage::Finish),
            Err(LinkError::Stale)
        ]
    );
    let c = rx.counters();
    assert_eq!((c.frames_ok, c.stale_frames), (2, 2));
    // 1 was missing when 2 came; it came late and was not used.
    assert_eq!((c.sequence_gaps, c.corrupt_frames), (1, 0));
}

#[test]
fn a_peer_far_behind_has_restarted_and_is_accepted() {
    let mut tx = Sender::default();
    let mut rx = Receiver::new();
    let mut out = [0; MAX_FRAME_BYTES];
    for _ in 0..=STALE_WINDOW + 1 {
        let bytes = tx.frame(HostMessage::Finish, &mut out).unwrap().to_vec();
        assert_eq!(
            feed::<HostMessage>(&mut rx, &bytes),
            vec![Ok(HostMessage::Finish)]
        );
    }
    // The peer restarts its numbering from 0: more than the window
    // behind, so accepted (one gap), not stale.
    let restarted = Sender::default()
        .frame(HostMessage::Finish, &mut out)
        .unwrap()
        .to_vec();
    assert_eq!(
        feed::<HostMessage>(&mut rx, &restarted),
        vec![Ok(HostMessage::Finish)]
    );
    let c = rx.counters();
    assert_eq!((c.stale_frames, c.sequence_gaps), (0, 1));
}

#[test]
fn an_overlong_frame_is_dropped_whole() {
    let mut rx = Receiver::new();
    let junk = vec![0x55_u8; MAX_FRAME_BYTES * 2];
    let got = feed::<HostMessage>(&mut rx, &[junk.as_slice(), &[0]].concat());
    assert_eq!(got, vec![Err(LinkError::TooLong)]);
    let mut out = [0; MAX_FRAME_BYTES];
    let ok = Sender::default()
        .frame(HostMessage::Finish, &mut out)
        .unwrap()
        .to_vec();
    assert_eq!(
        feed::<HostMessage>(&mut rx, &ok),
        vec![Ok(HostMessage::Finish)]
    );
}

proptest! {
    #[test]
    fn garbage_never_panics_and_rarely_passes(bytes in proptest::collection::vec(any::<u8>(), 0..2048)) {
        let mut rx = Receiver::new();
        let got = feed::<HostMessage>(&mut rx, &bytes);
        let c = rx.counters();
        prop_assert_eq!(got.len() as u32, c.frames_ok + c.corrupt_frames);
    }

    #[test]
    fn the_checked_cobs_decoder_agrees_with_the_crate(bytes in proptest::collection::vec(any::<u8>(), 0..700)) {
        let mut ours = bytes.clone();
        let mut theirs = bytes.clone();
        let got = cobs_decode_in_place(&mut ours);
        match cobs::decode_in_place(&mut theirs) {
            Ok(n) => {
                prop_assert_eq!(got, Ok(n));
                prop_assert_eq!(&ours[..n], &theirs[..n]);
            }
            Err(_) => prop_assert_eq!(got, Err(LinkError::Cobs)),
        }
    }

    #[test]
    fn the_checked_cobs_decoder_inverts_the_encoder(data in proptest::collection::vec(any::<u8>(), 0..700)) {
        let mut encoded = vec![0_u8; cobs::max_encoding_length(data.len())];
        let n = cobs::encode(&data, &mut encoded);
        encoded.truncate(n);
        prop_assert_eq!(cobs_decode_in_place(&mut encoded), Ok(data.len()));
        prop_assert_eq!(&encoded[..data.len()], data.as_slice());
    }

    #[test]
    fn any_single_byte_corruption_is_rejected(pos in 0_usize..400, flip in 1_u8..=255) {
        let mut out = [0; MAX_FRAME_BYTES];
        let good = Sender::default().frame(configure(), &mut out).unwrap().to_vec();
        let pos = pos % (good.len() - 1);
        let mut bad = good.clone();
        bad[pos] ^= flip;
        let mut rx = Receiver::new();
        let got = feed::<HostMessage>(&mut rx, &bad);
        // A corrupted byte may become 0x00 and split the frame; no piece
        // may decode as a message.
        prop_assert!(got.iter().all(Result::is_err), "{:?}", got);
    }
}
