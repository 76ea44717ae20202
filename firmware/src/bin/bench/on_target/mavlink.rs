//! The MAVLink endpoint's part of a control tick, as both boards run it
//! (`wmr_link::mavlink_run::MavlinkRun`: `before_tick`, the endpoint's
//! parse, answers, periodic frames and events, then `after_tick`, the
//! runner reading the route follower): `mavlink_tick`, instructions per
//! tick on average over 2 s of 10 ms ticks with telemetry at 10 Hz
//! (`LOCAL_POSITION_NED` and `ATTITUDE` every 10th tick; no geodetic
//! origin, so no `GLOBAL_POSITION_INT`), the endpoint's `HEARTBEAT` and
//! `SYS_STATUS` at 1 Hz, the robot's counters (told after each tick, as
//! the boards do, and sent as `NAMED_VALUE_INT` at the default counters
//! period: one every 333 ms), and a ground station's `HEARTBEAT` arriving
//! once a second. The robot's own tick is not in it (the whole-tick rows
//! are).
//! The Black Pill's byte path is: the frames written are queued on a
//! 1 KiB `TxRing` in chunks of 16 bytes (`queue_tx`'s critical sections)
//! and taken out one byte at a time (its transmit interrupt's `pop`). The
//! interrupt's entry and exit, its critical section and its register
//! accesses are not (a bench has no USART to drive): the handler's send
//! path is about 65 instructions a byte in its disassembly, this `pop`
//! included.
//!
//! The run is `robots/route_loop.toml`'s route (5 waypoints, one
//! station), loaded into a `RouteStore` and a `MavlinkRun` in statics (24
//! and 9 KB) as the Black Pill keeps them. The bench checks what it
//! measured: every ground-station heartbeat parsed, no frame dropped, no
//! link loss, every byte written queued and sent, and the frames of the
//! timed ticks at their rates (20 `LOCAL_POSITION_NED` and `ATTITUDE`, 2
//! `HEARTBEAT` and `SYS_STATUS`, 6 `NAMED_VALUE_INT` in 2 s, each within
//! one).

use wmr_core::pilot::route::{RouteOptionsSpec, RouteStart};
use wmr_core::reference::route::{RouteLimitsSpec, Waypoint};
use wmr_link::RouteSpec;
use wmr_link::mavlink_run::{MavlinkRun, estimate};
use wmr_link::rx_ring::TxRing;
use wmr_link::session::RouteStore;
use wmr_mavlink::{COUNTERS, Counts, EndpointConfig, EndpointSpec, TxBuffer};

use super::fail;
use super::stage::Stage;
use super::timing::{Calibration, SAMPLES, timed};
use super::world::PERIOD_S;

/// `robots/route_loop.toml`'s route limits.
const LIMITS: RouteLimitsSpec = RouteLimitsSpec {
    max_speed_m_s: 0.2,
    max_tangential_accel_m_s2: 0.3,
    max_lateral_accel_m_s2: 0.3,
    blend_deviation_m: 0.05,
    ..super::route::LIMITS
};

/// Ticks run before the timed ones (the first tick sends every periodic
/// frame at once).
const WARM_UP_TICKS: u32 = 100;

/// A ground station's heartbeat arrives at ticks `k` with `k % 100 == 50`
/// (1 Hz at 10 ms).
const GCS_HEARTBEAT_EVERY: u32 = 100;

/// The Black Pill's transmit ring's capacity and the bytes queued per
/// critical section (`board::blackpill::devices::TX_CHUNK`).
const TX_RING_BYTES: usize = 1024;
const TX_CHUNK: usize = 16;

/// The telemetry period, ms (10 Hz), and the tick's, ms.
const TELEMETRY_PERIOD_MS: u32 = 100;
const PERIOD_MS: u32 = (PERIOD_S * 1000.0 + 0.5) as u32;

/// Counts the MAVLink 2 frames of `bytes` (whole frames, unsigned) by
/// message: `LOCAL_POSITION_NED` (32), `ATTITUDE` (30), `HEARTBEAT` (0),
/// `SYS_STATUS` (1), `NAMED_VALUE_INT` (252), in that order in `counts`.
fn count_frames(mut bytes: &[u8], counts: &mut [u32; 5]) {
    while let (Some(&len), Some(id)) = (bytes.get(1), bytes.get(7..10)) {
        let id = id.iter().rev().fold(0_u32, |a, &b| (a << 8) | u32::from(b));
        let slot = match id {
            32 => counts.get_mut(0),
            30 => counts.get_mut(1),
            0 => counts.get_mut(2),
            1 => counts.get_mut(3),
            252 => counts.get_mut(4),
            _ => None,
        };
        if let Some(c) = slot {
            *c += 1;
        }
        bytes = bytes.get(12 + usize::from(len)..).unwrap_or(&[]);
    }
}

/// Runs the ticks and reports `mavlink_tick`.
pub(super) fn bench_mavlink(cal: Calibration) {
    let spec = EndpointSpec {
        telemetry_period_ms: TELEMETRY_PERIOD_MS,
        ..EndpointSpec::default()
    };
    let Ok(config) = EndpointConfig::new(&spec) else {
        fail("endpoint configuration refused");
    };
    let route = RouteSpec {
        waypoints: 5,
        limits: LIMITS,
        options: RouteOptionsSpec::default(),
        start: RouteStart::AsGiven,
        mavlink: wmr_link::MavlinkSettings::of(&spec, wmr_link::PowerOn::Run),
    };
    let Some(store) = cortex_m::singleton!(: RouteStore = RouteStore::new()) else {
        fail("route store already taken");
    };
    let Ok(limits) = store.begin(&route) else {
        fail("bench route's limits refused");
    };
    let waypoints = [
        Waypoint::pass(0.0, 0.0),
        Waypoint::stop(1.0, 0.0, 2.0),
        Waypoint::pass(1.0, 0.5),
        Waypoint::pass(0.0, 0.5),
        Waypoint::pass(0.0, 0.0),
    ];
    for w in waypoints {
        if store.push(w).is_err() {
            fail("bench route too long");
        }
    }
    if store.finish(&limits, route.start, PERIOD_S).is_err() {
        fail("bench route refused");
    }
    let Some(run) = cortex_m::singleton!(: MavlinkRun = MavlinkRun::new(config, limits)) else {
        fail("MAVLink run already taken");
    };
    run.activate(
        store,
        route.start,
        limits,
        PERIOD_S,
        config,
        route.mavlink.power_on,
    );

    // A ground station's HEARTBEAT (MAV_TYPE_GCS), framed by the
    // endpoint's own encoder.
    let mut heartbeat = [0_u8; 32];
    let mut tx = TxBuffer::new(&mut heartbeat);
    if !tx.frame([0, 255, 190], 0, 50, &[0, 0, 0, 0, 6, 8, 0, 4, 3]) {
        fail("heartbeat frame");
    }
    let heartbeat_len = tx.len();
    let heartbeat = heartbeat.get(..heartbeat_len).unwrap_or(&[]);
    let mut room = [0_u8; TX_RING_BYTES];
    let Some(ring) = cortex_m::singleton!(: TxRing<TX_RING_BYTES> = TxRing::new()) else {
        fail("transmit ring already taken");
    };
    let mut sent = 0_usize;
    // Frames of the timed ticks: LOCAL_POSITION_NED, ATTITUDE, HEARTBEAT,
    // SYS_STATUS, NAMED_VALUE_INT.
    let mut frames = [0_u32; 5];
    let mut stage = Stage::new("mavlink_tick");
    let mut written = 0_usize;
    let mut dropped = 0_u32;
    let mut heartbeats = 0_u32;
    for k in 0..WARM_UP_TICKS + SAMPLES as u32 {
        let rx = if k % GCS_HEARTBEAT_EVERY == GCS_HEARTBEAT_EVERY / 2 {
            heartbeats += 1;
            heartbeat
        } else {
            &[]
        };
        let (counts, (n, d, s)) = timed(&k, |&k| mavlink_tick(run, store, k, rx, &mut room, ring));
        if k >= WARM_UP_TICKS {
            stage.record(counts);
            count_frames(room.get(..n).unwrap_or(&[]), &mut frames);
        }
        written += n;
        dropped += d;
        sent += s;
    }
    let c = run.endpoint().counters();
    if c.rx.frames != heartbeats || dropped != 0 || c.tx_dropped != 0 {
        fail("MAVLink bench: a heartbeat not parsed, or a frame dropped");
    }
    if run.endpoint().link_lost() || written == 0 {
        fail("MAVLink bench: link lost, or nothing sent");
    }
    if sent != written || ring.counters().ring_full != 0 {
        fail("MAVLink bench: a byte written not queued and sent");
    }
    let telemetry = SAMPLES as u32 * PERIOD_MS / TELEMETRY_PERIOD_MS;
    let status = SAMPLES as u32 * PERIOD_MS / 1_000;
    let counters = SAMPLES as u32 * PERIOD_MS / (spec.counters_period_ms / COUNTERS as u32);
    let near = |n: u32, expected: u32| n.abs_diff(expected) <= 1;
    if !(near(frames[0], telemetry)
        && near(frames[1], telemetry)
        && near(frames[2], status)
        && near(frames[3], status)
        && near(frames[4], counters))
    {
        fail("MAVLink bench: the timed ticks' frames are not at their rates");
    }
    stage.report(cal);
}

/// One tick's MAVLink handling: the endpoint before the robot's tick (a
/// robot at rest 1 m along x, facing +y), its frames queued on the
/// transmit ring and taken out byte by byte, the runner after the tick.
/// Returns the bytes written, the frames dropped and the bytes sent.
#[inline(never)]
fn mavlink_tick(
    run: &mut MavlinkRun,
    store: &mut RouteStore,
    tick: u32,
    rx: &[u8],
    room: &mut [u8],
    ring: &mut TxRing<TX_RING_BYTES>,
) -> (usize, u32, usize) {
    let at = estimate([1.0, 0.0], [0.0, 1.0], [0.0, 0.0]);
    let room_now = room.len().min(ring.room());
    let (written, dropped) = run.before_tick(
        store,
        tick,
        Some(at),
        rx,
        room.get_mut(..room_now).unwrap_or(&mut []),
    );
    for chunk in room.get(..written).unwrap_or(&[]).chunks(TX_CHUNK) {
        ring.push_slice(chunk);
    }
    let mut sent = 0;
    while ring.pop().is_some() {
        sent += 1;
    }
    run.after_tick(store, wmr_core::geometry::Vec2::new(1.0, 0.0));
    // The robot's counters, as a board tells them after its tick.
    run.set_counts(Counts::of(
        &wmr_core::pilot::tracker::TrackerCounters {
            fixes_used: tick,
            ..Default::default()
        },
        &wmr_core::devices::RfidCounters::default(),
        0,
    ));
    (written, dropped, sent)
}
