//! `firmware-sim hil --mavlink`: a ground station on UDP talks to the
//! firmware under QEMU through the link's MAVLink channel (docs/hil.md,
//! "A ground station on the firmware under QEMU").
//!
//! Before each tick `k` ([`Bridge::before_tick`]):
//!
//! 1. wait for the wall clock to reach `k·h / N` since the first tick
//!    (the SITL's [`Pace`]): the ground station's heartbeats and timeouts
//!    are wall time, the firmware's link watch counts ticks, so the run
//!    keeps to wall time (`--speedup N`; a machine that cannot keep up
//!    runs flat out, and the speed-up achieved is reported);
//! 2. read every datagram waiting (the SITL's [`UdpLink`]) into a backlog
//!    of at most [`BACKLOG_BYTES`]; a datagram that does not fit whole is
//!    dropped and counted;
//! 3. send the firmware up to [`MAVLINK_RX_QUEUE_BYTES`] of the backlog
//!    (what its queue holds between two ticks, so it drops none), in
//!    `HostMessage::Mavlink` chunks of [`MAVLINK_CHUNK_BYTES`], asking
//!    again with no bytes while it says output is pending; the rest of
//!    the backlog waits for the next tick;
//! 4. send what the firmware's endpoint wrote at the last tick to the
//!    ground station, a datagram per frame.
//!
//! Every exchange is logged ([`MavlinkLog`]): the host's copy of the
//! firmware's session is fed the same messages before the same tick and
//! its answers are compared with the firmware's.

use std::collections::VecDeque;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::{bail, ensure};
use wmr_link::{
    MAVLINK_CHUNK_BYTES, MAVLINK_RX_QUEUE_BYTES, MAVLINK_TX_QUEUE_BYTES, MavlinkChunk,
    MavlinkCounters, MavlinkIn, MavlinkOut,
};

use crate::report::mavlink_bridge::MavlinkBridgeReport;
use crate::simulation::MavlinkLog;
use crate::udp::{LinkCounters, MavlinkAddress, Pace, UdpLink};

/// Bytes from the ground station the host holds for the firmware: about
/// 85 ticks of the firmware's queue, far more than a ground station
/// sends (a mission upload is one item in flight at a time).
pub const BACKLOG_BYTES: usize = 65_536;

/// The longest wall time between two ticks, s: well inside the link's
/// 50 ms silence timeout (`wmr_link::LINK_TIMEOUT_MS`), after which the
/// firmware stops the motors on its own.
pub const MAX_WALL_PER_TICK_S: f64 = 0.025;

/// A ground station bridged to the run (`HilOptions::mavlink`).
#[derive(Debug, Clone)]
pub struct MavlinkBridgeSpec {
    /// Where the ground station is (the SITL's `--mavlink` address).
    pub address: MavlinkAddress,
    /// Times real time (finite, > 0, and a tick's wall time at most
    /// [`MAX_WALL_PER_TICK_S`]).
    pub speedup: f64,
    /// Set (by Ctrl-C): the run ends before its next tick, the firmware
    /// is finished and the run reported up to there.
    pub stop: Option<Arc<AtomicBool>>,
    /// The caller sets `stop` on SIGINT, SIGTERM and SIGHUP (the command
    /// line): QEMU then runs in a process group of its own, so that a
    /// terminal's Ctrl-C reaches the caller only and the run ends
    /// cleanly. `false` (a caller that handles no signal, such as a
    /// test): QEMU stays in the caller's group and dies with it.
    pub stops_on_signals: bool,
    /// Called once the socket is open, with a line naming its address
    /// and the ground station's (the command line prints it).
    pub announce: Option<fn(&str)>,
}

/// The bridge of a run: the UDP link, the wall clock, the backlog.
pub(super) struct Bridge {
    link: UdpLink,
    speedup: f64,
    period_s: f64,
    /// Started at the first tick.
    pace: Option<Pace>,
    backlog: VecDeque<u8>,
    seq: u32,
    stop: Option<Arc<AtomicBool>>,
    pub(super) log: MavlinkLog,
    report: MavlinkBridgeReport,
    ticks: u32,
}

impl Bridge {
    /// Opens the UDP socket of `spec` for a run ticking every `period_s`.
    ///
    /// # Errors
    /// A speed-up out of range, the socket's bind error.
    pub(super) fn open(spec: &MavlinkBridgeSpec, period_s: f64) -> anyhow::Result<Self> {
        ensure!(
            spec.speedup.is_finite() && spec.speedup > 0.0,
            "--speedup {}: must be finite and > 0",
            spec.speedup
        );
        ensure!(
            period_s / spec.speedup <= MAX_WALL_PER_TICK_S,
            "--speedup {}: a tick of {period_s} s would take {:.1} ms of wall time; at most \
             {:.0} ms (the link's silence timeout is {} ms): use --speedup {} or more",
            spec.speedup,
            period_s / spec.speedup * 1e3,
            MAX_WALL_PER_TICK_S * 1e3,
            wmr_link::LINK_TIMEOUT_MS,
            period_s / MAX_WALL_PER_TICK_S
        );
        let link = UdpLink::open(spec.address)?;
        if let Some(announce) = spec.announce {
            announce(&format!(
                "MAVLink on {}, {}x real time",
                link.describe(),
                spec.speedup
            ));
        }
        Ok(Self {
            link,
            speedup: spec.speedup,
            period_s,
            pace: None,
            backlog: VecDeque::with_capacity(BACKLOG_BYTES),
            seq: 0,
            stop: spec.stop.clone(),
            log: MavlinkLog::default(),
            report: MavlinkBridgeReport {
                speedup: spec.speedup,
                speedup_achieved: 0.0,
                udp: LinkCounters::default(),
                dropped_datagrams: 0,
                dropped_bytes: 0,
                largest_backlog_bytes: 0,
                left_in_backlog_bytes: 0,
                bytes_to_firmware: 0,
                bytes_from_firmware: 0,
                messages: 0,
                firmware: MavlinkCounters::default(),
                copy_compared: 0,
                copy_mismatches: 0,
                first_mismatch_tick: None,
                interrupted: false,
                link_silences: 0,
            },
            ticks: 0,
        })
    }

    /// Whether Ctrl-C asked the run to end.
    pub(super) fn stop_requested(&self) -> bool {
        self.stop
            .as_ref()
            .is_some_and(|stop| stop.load(Ordering::Relaxed))
    }

    /// The exchange before tick `tick` (module documentation), each
    /// message sent to the firmware by `exchange` (the target's
    /// `mavlink_exchange`), which returns its answer.
    ///
    /// # Errors
    /// A socket error, `exchange`'s error, or the firmware answering a
    /// message other than the one sent.
    pub(super) fn before_tick(
        &mut self,
        mut exchange: impl FnMut(&MavlinkIn) -> anyhow::Result<MavlinkOut>,
        tick: u32,
    ) -> anyhow::Result<()> {
        let pace = self.pace.get_or_insert_with(|| Pace::new(self.speedup));
        pace.wait_for(f64::from(tick) * self.period_s);
        self.ticks = tick.saturating_add(1);
        let (backlog, report) = (&mut self.backlog, &mut self.report);
        self.link.receive_datagrams(|datagram| {
            if backlog.len() + datagram.len() > BACKLOG_BYTES {
                report.dropped_datagrams += 1;
                report.dropped_bytes += datagram.len() as u64;
            } else {
                backlog.extend(datagram);
            }
        })?;
        report.largest_backlog_bytes = report.largest_backlog_bytes.max(backlog.len() as u64);
        // What the firmware's queues can pass in one tick, with room to
        // spare: more exchanges than that mean it never stops saying
        // output is pending.
        let most = (MAVLINK_RX_QUEUE_BYTES + MAVLINK_TX_QUEUE_BYTES) / MAVLINK_CHUNK_BYTES + 4;
        let mut budget = MAVLINK_RX_QUEUE_BYTES;
        let mut out = Vec::new();
        for _ in 0..most {
            let n = budget.min(self.backlog.len()).min(MAVLINK_CHUNK_BYTES);
            let bytes: Vec<u8> = self.backlog.drain(..n).collect();
            budget -= n;
            let (message, answer) = self.exchange_one(&bytes, &mut exchange)?;
            out.extend_from_slice(answer.bytes.as_slice());
            self.report.bytes_to_firmware += n as u64;
            self.log.exchanges.push((message, answer));
            if answer.pending == 0 && (budget == 0 || self.backlog.is_empty()) {
                self.link.send_frames(&out);
                return Ok(());
            }
        }
        bail!(
            "the firmware still had MAVLink output pending after {most} exchanges before tick {tick}"
        )
    }

    /// At the end of the run, after its last tick: fetches what the
    /// firmware's endpoint wrote at that tick (messages with no bytes,
    /// while it says output is pending) and sends it to the ground
    /// station. Not logged for the host's copy of the session, which
    /// compares exchanges before a tick.
    ///
    /// # Errors
    /// As [`Self::before_tick`].
    pub(super) fn flush(
        &mut self,
        mut exchange: impl FnMut(&MavlinkIn) -> anyhow::Result<MavlinkOut>,
    ) -> anyhow::Result<()> {
        let most = MAVLINK_TX_QUEUE_BYTES / MAVLINK_CHUNK_BYTES + 4;
        let mut out = Vec::new();
        for _ in 0..most {
            let (_, answer) = self.exchange_one(&[], &mut exchange)?;
            out.extend_from_slice(answer.bytes.as_slice());
            if answer.pending == 0 {
                self.link.send_frames(&out);
                return Ok(());
            }
        }
        bail!("the firmware still had MAVLink output pending after {most} exchanges at the end")
    }

    /// One message of `bytes` to the firmware and its answer, checked to
    /// answer that message; counted in the report (messages, bytes from
    /// the firmware, its latest counters).
    fn exchange_one(
        &mut self,
        bytes: &[u8],
        exchange: &mut impl FnMut(&MavlinkIn) -> anyhow::Result<MavlinkOut>,
    ) -> anyhow::Result<(MavlinkIn, MavlinkOut)> {
        let message = MavlinkIn {
            seq: self.seq,
            bytes: MavlinkChunk::from_slice(bytes),
        };
        self.seq = self.seq.wrapping_add(1);
        let answer = exchange(&message)?;
        ensure!(
            answer.seq == message.seq,
            "the firmware answered MAVLink message {} to message {}",
            answer.seq,
            message.seq
        );
        self.report.messages += 1;
        self.report.bytes_from_firmware += answer.bytes.len() as u64;
        self.report.firmware = answer.counters;
        Ok((message, answer))
    }

    /// The bridge's figures at the end of the run, with the firmware's
    /// `link_silences` reports.
    pub(super) fn report(&self, link_silences: u32) -> MavlinkBridgeReport {
        let wall_s = self.pace.as_ref().map_or(0.0, Pace::elapsed_s);
        let sim_s = f64::from(self.ticks) * self.period_s;
        MavlinkBridgeReport {
            speedup_achieved: if wall_s > 0.0 { sim_s / wall_s } else { 0.0 },
            udp: self.link.counters(),
            left_in_backlog_bytes: self.backlog.len() as u64,
            copy_compared: self.log.compared,
            copy_mismatches: self.log.mismatches,
            first_mismatch_tick: self.log.first_mismatch_tick,
            interrupted: self.stop_requested(),
            link_silences,
            ..self.report
        }
    }
}
