//! The MAVLink endpoint's part of a control tick as the Black Pill runs
//! it, and the MAVLink USART's interrupts that tick brings, over 2 s of
//! 10 ms ticks with telemetry at 10 Hz (`LOCAL_POSITION_NED` and
//! `ATTITUDE` every 10th tick; no geodetic origin, so no
//! `GLOBAL_POSITION_INT`), the endpoint's `HEARTBEAT` and `SYS_STATUS` at
//! 1 Hz, the robot's counters (told after each tick, as the boards do,
//! and sent as `NAMED_VALUE_INT` at the default counters period: one
//! every 333 ms), and a ground station's `HEARTBEAT` arriving once a
//! second. The robot's own tick is not in it (the whole-tick rows are).
//!
//! - `mavlink_tick`, instructions per tick: the Black Pill's
//!   `MavlinkPort::before_tick` and `after_tick` (`board/blackpill.rs`)
//!   over the shared port of `wmr_link::rx_ring`: the receive ring
//!   emptied ([`rx_ring::read`], a critical section per 16 bytes), the
//!   transmit ring's room asked, `wmr_link::mavlink_run::MavlinkRun`'s
//!   `before_tick` (the endpoint's parse, answers, periodic frames and
//!   events), its output queued ([`rx_ring::queue_tx`], a critical
//!   section per 16 bytes, the transmit interrupt turned on), then
//!   `after_tick` (the runner reading the route follower) and the
//!   counters told;
//! - `mavlink_usart_interrupt`, instructions per interrupt: the USART's
//!   handler, [`rx_ring::on_interrupt`], the code the Black Pill's
//!   `USART1` runs (its critical section, the port's borrow, the receive
//!   path's status read and, for a byte, data read and push; the
//!   transmit path's `TXEIE` and status reads and a byte popped and
//!   written, or the interrupt turned off once the ring is empty), once
//!   for each byte received (before the tick that reads it) and for each
//!   byte sent, plus the one that finds the transmit ring empty;
//! - `mavlink_tick_with_interrupts`, instructions per tick: a tick and
//!   the interrupts of the bytes it read and sent, summed (its goal,
//!   1,500 on average, is `[targets]` in `firmware/budgets.toml`).
//!
//! The USART's registers are words in RAM ([`RamUsart`]: a `static` at a
//! fixed address, read and written as the handler reads and writes the
//! USART's, one load or store each): the bench plays the hardware,
//! setting `RXNE` and the data register before a receive interrupt and
//! `TXE` before a transmit one, outside the measured windows. It calls
//! the handler as a function: the call (one `bl`) stands for the
//! exception entry, which on the Cortex-M4 stacks eight registers in
//! hardware (about 12 cycles in and 10 out, no instruction) and is not
//! counted; these are instruction counts, not cycles (QEMU models no bus
//! wait states for the USART's registers). QEMU 7.2's STM32 USART model
//! cannot drive the handler itself: it raises its interrupt for a
//! received byte only, from a character device read asynchronously (no
//! fixed byte schedule), and never for `TXE`.
//!
//! The run is `robots/route_loop.toml`'s route (5 waypoints, one
//! station), loaded into a `RouteStore` and a `MavlinkRun` in statics (24
//! and 9 KB) as the Black Pill keeps them. The bench checks what it
//! measured: every ground-station heartbeat received and parsed, no frame
//! dropped, no link loss, every byte written queued and sent through the
//! handler in order, and the frames of the timed ticks at their rates (20
//! `LOCAL_POSITION_NED` and `ATTITUDE`, 2 `HEARTBEAT` and `SYS_STATUS`, 6
//! `NAMED_VALUE_INT` in 2 s, each within one).

use core::cell::RefCell;
use core::sync::atomic::{AtomicU32, Ordering};

use critical_section::Mutex;
use wmr_core::pilot::route::{RouteOptionsSpec, RouteStart};
use wmr_core::reference::route::{RouteLimitsSpec, Waypoint};
use wmr_link::RouteSpec;
use wmr_link::mavlink_run::{MavlinkRun, estimate};
use wmr_link::rx_ring::{self, Port, SharedPort, Usart, status};
use wmr_link::session::RouteStore;
use wmr_mavlink::{COUNTERS, Counts, EndpointConfig, EndpointSpec, TxBuffer};

use super::fail;
use super::stage::{Histogram, Stage, Sums};
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

/// The Black Pill's MAVLink receive and transmit rings' capacities
/// (`MAVLINK_RING_BYTES`, `MAVLINK_TX_RING_BYTES`), and its reads of the
/// receive ring per tick at most (`MAVLINK_READS_PER_TICK`).
const RX_RING_BYTES: usize = 512;
const TX_RING_BYTES: usize = 1024;
const READS_PER_TICK: u32 = 40;

/// `CR1.TXEIE`: the transmit interrupt on.
const TXEIE: u32 = 1 << 7;
/// `SR.TC`: transmission complete (set with `TXE` on an idle line).
const TC: u32 = 1 << 6;

/// The bench's USART registers: status, data, control 1.
static SR: AtomicU32 = AtomicU32::new(0);
static DR: AtomicU32 = AtomicU32::new(0);
static CR1: AtomicU32 = AtomicU32::new(0);

/// A USART whose registers are [`SR`], [`DR`] and [`CR1`] in RAM: each
/// access one load or store at a fixed address, as the Black Pill's
/// (`board::blackpill::devices`, `impl Usart for UartRx`) is one volatile
/// access of a register at a fixed address.
struct RamUsart;

impl Usart for RamUsart {
    fn status(&self) -> u32 {
        SR.load(Ordering::Relaxed)
    }

    fn read_data(&mut self) -> u8 {
        DR.load(Ordering::Relaxed).to_le_bytes()[0]
    }

    fn write_data(&mut self, byte: u8) {
        DR.store(u32::from(byte), Ordering::Relaxed);
    }

    fn tx_interrupt_enabled(&self) -> bool {
        CR1.load(Ordering::Relaxed) & TXEIE != 0
    }

    fn set_tx_interrupt(&mut self, on: bool) {
        let cr1 = CR1.load(Ordering::Relaxed);
        CR1.store(
            if on { cr1 | TXEIE } else { cr1 & !TXEIE },
            Ordering::Relaxed,
        );
    }
}

/// The MAVLink port, as the Black Pill's `MAVLINK_PORT`.
static PORT: SharedPort<RamUsart, RX_RING_BYTES, TX_RING_BYTES> =
    Mutex::new(RefCell::new(Port::new()));

/// The USART's interrupt handler, as the Black Pill's `USART1`.
#[inline(never)]
fn usart_interrupt() {
    rx_ring::on_interrupt(&PORT);
}

/// One interrupt, timed: its instructions (the measurement's own
/// subtracted), recorded in `per_interrupt`.
fn interrupt(cal: Calibration, per_interrupt: &mut Histogram<64>) -> f32 {
    let (counts, ()) = timed(&(), |_| usart_interrupt());
    per_interrupt.record(counts);
    cal.instructions(counts as f32)
}

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

/// Runs the ticks and reports `mavlink_tick`, `mavlink_usart_interrupt`
/// and `mavlink_tick_with_interrupts`.
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
    let Some(run) = cortex_m::singleton!(: MavlinkRun = MavlinkRun::BLANK) else {
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
    rx_ring::attach(&PORT, RamUsart);
    // The line idle, the transmitter empty.
    SR.store(status::TXE | TC, Ordering::Relaxed);
    let Some(bufs) = cortex_m::singleton!(: Buffers = Buffers {
        rx: [0; RX_RING_BYTES],
        tx: [0; TX_RING_BYTES],
    }) else {
        fail("MAVLink buffers already taken");
    };
    // Frames of the timed ticks: LOCAL_POSITION_NED, ATTITUDE, HEARTBEAT,
    // SYS_STATUS, NAMED_VALUE_INT.
    let mut frames = [0_u32; 5];
    let mut tick_stage = Stage::new("mavlink_tick");
    let mut per_interrupt = Histogram::<64>::new("mavlink_usart_interrupt");
    let mut whole = Sums::new("mavlink_tick_with_interrupts");
    let mut written = 0_usize;
    let mut sent = 0_usize;
    let mut out_of_order = false;
    let mut dropped = 0_u32;
    let mut heartbeats = 0_u32;
    let mut received = 0_usize;
    for k in 0..WARM_UP_TICKS + SAMPLES as u32 {
        let timed_tick = k >= WARM_UP_TICKS;
        // Untimed ticks count no interrupt: a scratch histogram.
        let mut scratch = Histogram::<64>::new("");
        let hist = if timed_tick {
            &mut per_interrupt
        } else {
            &mut scratch
        };
        let mut isr = 0.0_f32;
        // The bytes received since the last tick, each by its interrupt.
        if k % GCS_HEARTBEAT_EVERY == GCS_HEARTBEAT_EVERY / 2 {
            heartbeats += 1;
            for &byte in heartbeat {
                SR.store(status::RXNE | status::TXE | TC, Ordering::Relaxed);
                DR.store(u32::from(byte), Ordering::Relaxed);
                isr += interrupt(cal, hist);
            }
            SR.store(status::TXE | TC, Ordering::Relaxed);
        }
        let (counts, (r, n, d)) = timed(&k, |&k| mavlink_tick(run, store, k, bufs));
        // The bytes written, each sent by its interrupt ("data register
        // empty") until the handler finds the ring empty and turns the
        // transmit interrupt off; each checked against what was written.
        let mut k_sent = 0;
        while CR1.load(Ordering::Relaxed) & TXEIE != 0 && k_sent <= n {
            DR.store(u32::MAX, Ordering::Relaxed);
            SR.store(status::TXE | TC, Ordering::Relaxed);
            isr += interrupt(cal, hist);
            let out = DR.load(Ordering::Relaxed);
            if out != u32::MAX {
                out_of_order |= bufs.tx.get(k_sent).map(|&b| u32::from(b)) != Some(out);
                k_sent += 1;
            }
        }
        if timed_tick {
            tick_stage.record(counts);
            whole.record(cal.instructions(counts as f32) + isr);
            count_frames(bufs.tx.get(..n).unwrap_or(&[]), &mut frames);
        }
        received += r;
        written += n;
        sent += k_sent;
        dropped += d;
    }
    let c = run.endpoint().counters();
    if c.rx.frames != heartbeats
        || received != heartbeats as usize * heartbeat_len
        || dropped != 0
        || c.tx_dropped != 0
    {
        fail("MAVLink bench: a heartbeat not received or parsed, or a frame dropped");
    }
    if run.endpoint().link_lost() || written == 0 {
        fail("MAVLink bench: link lost, or nothing sent");
    }
    let tx = rx_ring::tx_counters(&PORT);
    let rx = rx_ring::rx_counters(&PORT);
    if sent != written
        || out_of_order
        || tx.ring_full != 0
        || tx.sent as usize != written
        || rx.faults() != 0
    {
        fail("MAVLink bench: a byte written not queued and sent in order");
    }
    // Every timed tick's bytes took an interrupt each, and each tick that
    // sent one more (the one that turns the transmit interrupt off).
    if per_interrupt.calls() < SAMPLES as u32 {
        fail("MAVLink bench: fewer interrupts than ticks");
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
    tick_stage.report(cal);
    per_interrupt.report(cal);
    whole.report();
}

/// The Black Pill's MAVLink buffers (`MavlinkPort`'s): the bytes read
/// for the tick, the endpoint's output before it is queued.
struct Buffers {
    rx: [u8; RX_RING_BYTES],
    tx: [u8; TX_RING_BYTES],
}

/// One tick's MAVLink handling as the Black Pill's `MavlinkPort` does it:
/// the receive ring emptied into the endpoint before the robot's tick (a
/// robot at rest 1 m along x, facing +y), its output queued on the
/// transmit ring (the interrupt sends it), the runner after the tick, and
/// the robot's counters told. Returns the bytes read, the bytes written
/// and the frames dropped.
#[inline(never)]
fn mavlink_tick(
    run: &mut MavlinkRun,
    store: &mut RouteStore,
    tick: u32,
    bufs: &mut Buffers,
) -> (usize, usize, u32) {
    let mut read = 0;
    for _ in 0..READS_PER_TICK {
        match bufs
            .rx
            .get_mut(read..)
            .map(|free| rx_ring::read(&PORT, free))
        {
            Some(k) if k > 0 => read += k,
            _ => break,
        }
    }
    let at = estimate([1.0, 0.0], [0.0, 1.0], [0.0, 0.0]);
    let room = rx_ring::tx_room(&PORT).min(bufs.tx.len());
    let rx = bufs.rx.get(..read).unwrap_or(&[]);
    let (written, dropped) = match bufs.tx.get_mut(..room) {
        Some(room) => run.before_tick(store, tick, Some(at), rx, room),
        None => (0, 0),
    };
    rx_ring::queue_tx(&PORT, bufs.tx.get(..written).unwrap_or(&[]));
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
    (read, written, dropped)
}
