//! QEMU running the firmware ([`QemuTarget`]), how it is run
//! ([`HilOptions`]), and the lock-step link to it.
//!
//! The link's frames travel through two files in QEMU's working directory
//! (a temporary directory), which the firmware reads and writes by
//! semihosting (`firmware/src/board/qemu.rs`): the host appends its frames
//! to a regular file ([`HIL_TO_TARGET_FILE`]) and reads the firmware's from
//! a named pipe ([`HIL_TO_HOST_PIPE`]), waiting on it with `poll`. A frame
//! is then one system call each side, where QEMU's USART model, the link
//! before, woke a thread per byte (1.5 ms a tick).

use std::collections::VecDeque;
use std::fs::File;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::{Context, bail, ensure};
use rustix::event::{PollFd, PollFlags, Timespec};
use rustix::fs::{Mode, OFlags};
use wmr_link::{
    Configure, Diagnostics, Finished, HIL_TO_HOST_PIPE, HIL_TO_TARGET_FILE, HostMessage, LinkError,
    MAX_FRAME_BYTES, MapChunk, MapRefusal, PROTOCOL_VERSION, Receiver, Refusal, Sender,
    TargetMessage, TickInput, TickOutput,
};

use super::faults::{Frame, Injector, LinkFaultReport, LinkFaultSpec, OUTAGE_MS};
use super::mavlink::{Bridge, MavlinkBridgeSpec};
use crate::simulation::{MavlinkLog, TargetLink};

/// How long the host waits for a tick's answer before sending the tick
/// again: well inside the firmware's link timeout, so that a lost frame
/// costs a resend, not a stop of the motors.
pub const RESEND_AFTER: Duration = Duration::from_millis(20);

/// The QEMU binary looked for on `PATH`.
pub const QEMU: &str = "qemu-system-arm";

/// util-linux's `setpriv`, which QEMU is started through where it is on
/// `PATH` (Linux): `--pdeathsig KILL` has the kernel kill QEMU when the
/// thread that started it ends, so that QEMU does not outlive a
/// `firmware-sim` killed with SIGKILL (which runs no clean-up). The
/// workspace has no `unsafe` code, which setting the signal in the child
/// between fork and exec needs (`CommandExt::pre_exec`); `setpriv` sets
/// it and then executes QEMU. Without it, QEMU is started directly and a
/// SIGKILL leaves it running (every other ending stops it: `Finish`, or
/// the kill in `Drop`).
pub const SETPRIV: &str = "setpriv";

/// The first `name` on `PATH` that is a file.
fn on_path(name: &str) -> Option<PathBuf> {
    std::env::split_paths(&std::env::var_os("PATH")?)
        .map(|dir| dir.join(name))
        .find(|path| path.is_file())
}

/// How to run the firmware.
#[derive(Debug, Clone)]
pub struct HilOptions {
    /// Firmware ELF; `None` builds it with cargo (`board-qemu`, release).
    pub firmware: Option<PathBuf>,
    /// Where QEMU's stdout (the defmt log) goes; `None` discards it.
    pub log: Option<PathBuf>,
    /// Longest wait for any answer of the firmware (for a tick: across its
    /// resends).
    pub answer_timeout: Duration,
    /// Seeded faults on the link during the ticks (`None`: a clean link).
    pub faults: Option<LinkFaultSpec>,
    /// A telemetry record on the firmware's log every this many ticks (0:
    /// none): `Configure::telemetry_every_ticks`.
    pub telemetry_every_ticks: u16,
    /// A ground station bridged to the link's MAVLink channel (`None`: the
    /// run sends no MAVLink message).
    pub mavlink: Option<MavlinkBridgeSpec>,
}

/// [`HilOptions::telemetry_every_ticks`] by default: every tick, so that
/// `firmware-sim plot` of a HIL run's log gives all its rows.
pub const DEFAULT_TELEMETRY_EVERY_TICKS: u16 = 1;

impl Default for HilOptions {
    fn default() -> Self {
        Self {
            firmware: None,
            log: None,
            answer_timeout: Duration::from_secs(10),
            faults: None,
            telemetry_every_ticks: DEFAULT_TELEMETRY_EVERY_TICKS,
            mavlink: None,
        }
    }
}

/// The faulty link's state: an injector each way, the bytes of the frame
/// from the firmware being assembled, and the host's figures.
struct FaultyLink {
    to_firmware: Injector,
    to_host: Injector,
    incoming: Vec<u8>,
    report: LinkFaultReport,
}

/// What one wait for the firmware gave.
// One at a time, on the host: a MAVLink answer's 192-byte chunk makes
// `Message` the large variant, which boxing would not make cheaper.
#[allow(clippy::large_enum_variant)]
enum Event {
    Message(TargetMessage),
    /// A corrupt frame (dropped and counted by the receiver).
    Corrupt,
    /// A stale frame (dropped and counted by the receiver).
    Stale,
    /// Nothing within the wait.
    Quiet,
}

/// How long one `poll` on the firmware's pipe waits at most before the
/// host checks that QEMU is still running.
const EXIT_CHECK: Duration = Duration::from_millis(100);

/// QEMU running the firmware, and the link's two files.
pub struct QemuTarget {
    child: Child,
    /// Host to firmware: the regular file the firmware reads.
    to_target: File,
    /// Firmware to host: the named pipe, opened non-blocking.
    from_target: File,
    pub(super) rx: Receiver,
    tx: Sender,
    timeout: Duration,
    /// Bytes off the link (after any faults) not yet given to `rx`.
    inbox: VecDeque<u8>,
    /// Faults, when the options ask for them; active during ticks only.
    faulty: Option<FaultyLink>,
    /// `LinkSilent` reports received: the firmware stopped its motors
    /// because the host was silent past its timeout.
    pub(super) link_silences: u32,
    /// The firmware's end-of-run report, once received.
    pub(super) finished: Option<Finished>,
    /// The ground station's bridge, when the run has one.
    pub(super) bridge: Option<Bridge>,
    // Keeps the link's directory alive.
    _dir: tempfile::TempDir,
}

impl Drop for QemuTarget {
    fn drop(&mut self) {
        // Normally QEMU has exited after `Finish`; on any error it is killed.
        if matches!(self.child.try_wait(), Ok(None)) {
            let _ = self.child.kill();
        }
        let _ = self.child.wait();
    }
}

impl QemuTarget {
    /// Starts QEMU with `firmware` and waits for its `Hello`.
    ///
    /// # Errors
    /// QEMU missing, failing to start, or the firmware not saying hello.
    pub fn start(firmware: &Path, options: &HilOptions) -> anyhow::Result<Self> {
        let dir = tempfile::Builder::new()
            .prefix("wmr-hil")
            .tempdir()
            .context("creating a directory for the link's files")?;
        let to_target = link_path(dir.path(), HIL_TO_TARGET_FILE)?;
        let to_target = File::create(&to_target)
            .with_context(|| format!("creating {}", to_target.display()))?;
        let pipe = link_path(dir.path(), HIL_TO_HOST_PIPE)?;
        rustix::fs::mkfifoat(rustix::fs::CWD, &pipe, Mode::RUSR | Mode::WUSR)
            .with_context(|| format!("creating the named pipe {}", pipe.display()))?;
        // Opened before QEMU starts, so that the firmware's open for
        // writing finds a reader; non-blocking, waited on with `poll`.
        let from_target = File::from(
            rustix::fs::open(&pipe, OFlags::RDONLY | OFlags::NONBLOCK, Mode::empty())
                .with_context(|| format!("opening {}", pipe.display()))?,
        );
        // QEMU runs in the link's directory: the firmware opens the files
        // by their names.
        let firmware = std::path::absolute(firmware)
            .with_context(|| format!("locating {}", firmware.display()))?;
        let stdout = match &options.log {
            Some(path) => Stdio::from(
                std::fs::File::create(path)
                    .with_context(|| format!("creating {}", path.display()))?,
            ),
            None => Stdio::null(),
        };
        let qemu = on_path(QEMU).ok_or_else(|| {
            anyhow::anyhow!(
                "`{QEMU}` not found: install it (Debian/Ubuntu: \
                 `apt-get install qemu-system-arm`), or run `cargo xtask ci`, which does"
            )
        })?;
        let mut command = match on_path(SETPRIV) {
            Some(setpriv) if cfg!(target_os = "linux") => {
                let mut command = Command::new(setpriv);
                command.args(["--pdeathsig", "KILL", "--"]).arg(&qemu);
                command
            }
            _ => Command::new(&qemu),
        };
        if options.mavlink.as_ref().is_some_and(|m| m.stops_on_signals) {
            // Its own process group: Ctrl-C in a terminal reaches this
            // process only, which ends the run and then QEMU through
            // `Finish` (QEMU would otherwise die with it, mid-run).
            std::os::unix::process::CommandExt::process_group(&mut command, 0);
        }
        let child = command
            .current_dir(dir.path())
            .args([
                "-M",
                "netduinoplus2",
                "-display",
                "none",
                "-monitor",
                "none",
                "-serial",
                "null",
            ])
            .args(["-semihosting-config", "enable=on,target=native"])
            .arg("-kernel")
            .arg(&firmware)
            .stdin(Stdio::null())
            .stdout(stdout)
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| {
                if e.kind() == std::io::ErrorKind::NotFound {
                    anyhow::anyhow!(
                        "`{QEMU}` not found: install it (Debian/Ubuntu: \
                         `apt-get install qemu-system-arm`), or run `cargo xtask ci`, which does"
                    )
                } else {
                    anyhow::Error::new(e).context(format!("starting {QEMU}"))
                }
            })?;
        let mut target = Self {
            child,
            to_target,
            from_target,
            rx: Receiver::new(),
            tx: Sender::default(),
            timeout: options.answer_timeout,
            inbox: VecDeque::with_capacity(4096),
            faulty: None,
            link_silences: 0,
            finished: None,
            bridge: None,
            _dir: dir,
        };
        if let Some(spec) = options.faults {
            spec.validate()?;
            target.faulty = Some(FaultyLink {
                to_firmware: Injector::new(spec, 0),
                to_host: Injector::new(spec, 1),
                incoming: Vec::new(),
                report: LinkFaultReport {
                    spec,
                    to_firmware: Default::default(),
                    to_host: Default::default(),
                    firmware_expected: Default::default(),
                    host_expected: Default::default(),
                    outages: 0,
                    resent_ticks: 0,
                    nacks: 0,
                    silence_reports: 0,
                    silence_reports_lost: 0,
                    longest_silence_before_stop_ms: 0,
                    stale_answers: 0,
                },
            });
        }
        match target.receive()? {
            TargetMessage::Hello { protocol } if protocol == PROTOCOL_VERSION => Ok(target),
            TargetMessage::Hello { protocol } => bail!(
                "the firmware speaks link protocol {protocol}, this simulator {PROTOCOL_VERSION}: rebuild one of them"
            ),
            other => bail!("expected Hello from the firmware, got {other:?}"),
        }
    }

    /// Sends raw bytes (tests of the firmware's reaction to garbage).
    ///
    /// # Errors
    /// The socket failed.
    pub fn send_raw(&mut self, bytes: &[u8]) -> anyhow::Result<()> {
        self.to_target
            .write_all(bytes)
            .context("writing to the firmware's link file")
    }

    /// Sends one message, without waiting.
    ///
    /// # Errors
    /// The socket failed.
    pub fn send(&mut self, message: &HostMessage) -> anyhow::Result<()> {
        self.send_through(message, false)
    }

    /// Sends one message, through the faults if `faulty`.
    fn send_through(&mut self, message: &HostMessage, faulty: bool) -> anyhow::Result<()> {
        let mut out = [0_u8; MAX_FRAME_BYTES];
        let seq = self.tx.next_seq();
        let bytes = self
            .tx
            .frame(message, &mut out)
            .map_err(|e| anyhow::anyhow!("message too long for the link: {e:?}"))?
            .to_vec();
        let wire = match self.faulty.as_mut() {
            Some(link) => link.to_firmware.deliver(
                Frame {
                    bytes,
                    seq,
                    silence_report: false,
                },
                faulty,
            ),
            None => bytes,
        };
        self.send_raw(&wire)
    }

    /// The faulty link's figures so far (`None` on a clean link).
    #[must_use]
    pub fn fault_report(&self) -> Option<LinkFaultReport> {
        self.faulty.as_ref().map(|link| {
            let mut r = link.report;
            r.to_firmware = link.to_firmware.injected;
            r.to_host = link.to_host.injected;
            r.firmware_expected = link.to_firmware.expected;
            r.host_expected = link.to_host.expected;
            r.silence_reports_lost = link.to_host.silence_reports_lost;
            r
        })
    }

    /// Counts a report of the faulty run (no-op on a clean link).
    fn count(&mut self, f: impl FnOnce(&mut LinkFaultReport)) {
        if let Some(link) = self.faulty.as_mut() {
            f(&mut link.report);
        }
    }

    /// A `LinkSilent` report: the motors must be stopped, and the
    /// firmware must have waited at least its timeout (it stops at the
    /// first poll of the link past it, so later only when QEMU was not
    /// scheduled then; the longest wait is reported).
    fn silence_reported(
        &mut self,
        motors: [wmr_link::MotorOutput; 2],
        silent_ms: u32,
    ) -> anyhow::Result<()> {
        ensure!(
            motors.iter().all(|m| m.duty == 0),
            "the firmware reported the link silent with its motors still driven: {motors:?}"
        );
        ensure!(
            silent_ms >= wmr_link::LINK_TIMEOUT_MS,
            "the firmware stopped the motors after {silent_ms} ms of silence, before its {} ms timeout",
            wmr_link::LINK_TIMEOUT_MS
        );
        self.link_silences = self.link_silences.saturating_add(1);
        self.count(|r| {
            r.silence_reports += 1;
            r.longest_silence_before_stop_ms = r.longest_silence_before_stop_ms.max(silent_ms);
        });
        Ok(())
    }

    /// An outage: the host silent for [`OUTAGE_MS`], past the firmware's
    /// timeout; what the firmware sends meanwhile is handled as during a
    /// tick.
    fn outage(&mut self) -> anyhow::Result<()> {
        self.count(|r| r.outages += 1);
        let end = Instant::now() + Duration::from_millis(OUTAGE_MS);
        loop {
            let left = end.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Ok(());
            }
            match self.wait(left, true)? {
                Event::Message(TargetMessage::LinkSilent { motors, silent_ms }) => {
                    self.silence_reported(motors, silent_ms)?;
                }
                Event::Message(TargetMessage::Nack) => self.count(|r| r.nacks += 1),
                Event::Message(TargetMessage::Ticked(_) | TargetMessage::Refused(_))
                | Event::Stale => self.count(|r| r.stale_answers += 1),
                Event::Message(other) => bail!("unexpected message during an outage: {other:?}"),
                Event::Corrupt | Event::Quiet => {}
            }
        }
    }

    /// One tick over the faulty link: sent again until its answer comes
    /// (after [`RESEND_AFTER`] without one, on a `Nack`, or on a corrupt
    /// frame back), within the answer timeout.
    fn faulty_tick(&mut self, input: &TickInput) -> anyhow::Result<TickOutput> {
        let outage = self
            .faulty
            .as_mut()
            .is_some_and(|link| link.to_firmware.outage());
        if outage {
            self.outage()?;
        }
        let message = HostMessage::Tick(input.clone());
        let deadline = Instant::now() + self.timeout;
        let mut resend = true;
        loop {
            ensure!(
                Instant::now() < deadline,
                "the firmware did not answer tick {} within {:?} over the faulty link",
                input.tick,
                self.timeout
            );
            if resend {
                self.send_through(&message, true)?;
                resend = false;
            }
            match self.wait(RESEND_AFTER, true)? {
                Event::Message(TargetMessage::Ticked(out)) if out.tick == input.tick => {
                    return Ok(out);
                }
                Event::Message(
                    TargetMessage::Ticked(_) | TargetMessage::Refused(Refusal::StaleTick { .. }),
                )
                | Event::Stale => self.count(|r| r.stale_answers += 1),
                Event::Message(TargetMessage::Nack) => {
                    self.count(|r| {
                        r.nacks += 1;
                        r.resent_ticks += 1;
                    });
                    resend = true;
                }
                Event::Message(TargetMessage::LinkSilent { motors, silent_ms }) => {
                    self.silence_reported(motors, silent_ms)?;
                }
                Event::Message(TargetMessage::Refused(Refusal::NotConfigured)) => {
                    bail!("the firmware was not configured (did it reset?)")
                }
                Event::Message(other) => {
                    bail!("unexpected answer to tick {}: {other:?}", input.tick)
                }
                Event::Corrupt | Event::Quiet => {
                    self.count(|r| r.resent_ticks += 1);
                    resend = true;
                }
            }
        }
    }

    /// Ends the faulty part of the run: the frame each injector still
    /// holds back goes out (late, so stale at its receiver).
    fn release_held(&mut self) -> anyhow::Result<()> {
        let Some(link) = self.faulty.as_mut() else {
            return Ok(());
        };
        let to_firmware = link.to_firmware.release_held();
        self.inbox.extend(link.to_host.release_held());
        self.send_raw(&to_firmware)
    }

    /// Waits for the next message from the firmware.
    ///
    /// # Errors
    /// Timeout, a closed socket, or a corrupt frame (outside the faulty
    /// ticks the link is a local socket: corruption means a firmware bug,
    /// so it is not retried).
    pub fn receive(&mut self) -> anyhow::Result<TargetMessage> {
        match self.wait(self.timeout, false)? {
            Event::Message(m) => Ok(m),
            Event::Corrupt => bail!("corrupt frame from the firmware"),
            Event::Stale => bail!("stale frame from the firmware"),
            Event::Quiet => bail!("the firmware did not answer within {:?}", self.timeout),
        }
    }

    /// Waits up to `wait` for the next frame from the firmware, through
    /// the faults if `faulty`.
    fn wait(&mut self, wait: Duration, faulty: bool) -> anyhow::Result<Event> {
        let deadline = Instant::now() + wait;
        loop {
            while let Some(byte) = self.inbox.pop_front() {
                match self.rx.push::<TargetMessage>(byte) {
                    None => {}
                    Some(Ok(m)) => return Ok(Event::Message(m)),
                    Some(Err(LinkError::Stale)) => return Ok(Event::Stale),
                    Some(Err(_)) => return Ok(Event::Corrupt),
                }
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Ok(Event::Quiet);
            }
            if !self.readable(left.min(EXIT_CHECK))? {
                self.check_running()?;
                continue;
            }
            let mut buf = [0_u8; 4096];
            match self.from_target.read(&mut buf) {
                Ok(0) => bail!("the firmware closed the link (QEMU exited?)"),
                Ok(n) => self.take_in(buf.get(..n).unwrap_or_default(), faulty)?,
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::Interrupted
                    ) => {}
                Err(e) => {
                    return Err(anyhow::Error::new(e).context("reading the firmware's link pipe"));
                }
            }
        }
    }

    /// Whether the firmware's pipe has bytes (or was closed) within `wait`.
    fn readable(&self, wait: Duration) -> anyhow::Result<bool> {
        let timeout = Timespec::try_from(wait).context("a poll timeout")?;
        let mut fds = [PollFd::new(&self.from_target, PollFlags::IN)];
        match rustix::event::poll(&mut fds, Some(&timeout)) {
            Ok(n) => Ok(n > 0),
            Err(rustix::io::Errno::INTR) => Ok(false),
            Err(e) => Err(anyhow::Error::new(e).context("waiting on the firmware's link pipe")),
        }
    }

    /// An error with QEMU's own message if it has exited.
    fn check_running(&mut self) -> anyhow::Result<()> {
        if let Some(status) = self.child.try_wait()? {
            let mut err = String::new();
            if let Some(mut e) = self.child.stderr.take() {
                let _ = e.read_to_string(&mut err);
            }
            bail!("{QEMU} exited ({status}): {}", err.trim());
        }
        Ok(())
    }

    /// Bytes read from the pipe into the inbox: as they are, or frame by
    /// frame through the faults.
    fn take_in(&mut self, bytes: &[u8], faulty: bool) -> anyhow::Result<()> {
        let Some(link) = self.faulty.as_mut() else {
            self.inbox.extend(bytes);
            return Ok(());
        };
        for &b in bytes {
            link.incoming.push(b);
            if b != 0 {
                continue;
            }
            let bytes = std::mem::take(&mut link.incoming);
            let mut copy = bytes.clone();
            let body = copy.len().saturating_sub(1);
            let frame = wmr_link::decode::<TargetMessage>(&mut copy[..body]).map_err(|e| {
                anyhow::anyhow!("the firmware sent a frame that does not decode: {e}")
            })?;
            let silence_report = matches!(frame.body, TargetMessage::LinkSilent { .. });
            self.inbox.extend(link.to_host.deliver(
                Frame {
                    bytes,
                    seq: frame.seq,
                    silence_report,
                },
                faulty,
            ));
        }
        Ok(())
    }

    /// Sends a message and waits for the answer.
    ///
    /// # Errors
    /// As [`Self::send`] and [`Self::receive`].
    pub fn exchange(&mut self, message: &HostMessage) -> anyhow::Result<TargetMessage> {
        self.send(message)?;
        self.receive()
    }

    /// [`Self::exchange`] for a step of the configuration: a `LinkSilent`
    /// report that comes first is checked and counted as during a tick
    /// (a loaded machine kept the host from its next step past the
    /// firmware's timeout: the motors are at rest before the run anyway)
    /// and the answer is awaited after it.
    fn configuration_step(&mut self, message: &HostMessage) -> anyhow::Result<TargetMessage> {
        let mut answer = self.exchange(message)?;
        while let TargetMessage::LinkSilent { motors, silent_ms } = answer {
            self.silence_reported(motors, silent_ms)?;
            answer = self.receive()?;
        }
        Ok(answer)
    }

    /// Configures the run: `configure`, then, if it announces a tag map,
    /// `map`'s chunks ([`crate::simulation::hil_map_chunks`]), each sent
    /// once the firmware has acknowledged the tags before it, then, for a
    /// route, `route`'s messages
    /// ([`crate::simulation::hil_route_messages`]), each sent once the
    /// firmware has acknowledged the waypoints before it; the last is
    /// answered `Configured`.
    ///
    /// # Errors
    /// The firmware refusing the configuration, its map or its route
    /// (saying why), or answering anything else.
    pub fn configure(
        &mut self,
        configure: Configure,
        map: &[MapChunk],
        route: &[HostMessage],
    ) -> anyhow::Result<()> {
        let mut answer = self.configuration_step(&HostMessage::Configure(configure))?;
        let mut asked = "Configure".to_owned();
        for chunk in map {
            match answer {
                TargetMessage::MapLoaded { tags } if tags == chunk.first => {}
                other => return not_configured(&asked, other, map),
            }
            answer = self.configuration_step(&HostMessage::MapChunk(chunk.clone()))?;
            asked = format!("the map chunk from tag {}", chunk.first);
        }
        for message in route {
            match (message, answer) {
                (HostMessage::Route(_), TargetMessage::Configured) => {}
                (HostMessage::RouteChunk(chunk), TargetMessage::RouteLoaded { waypoints })
                    if waypoints == chunk.first => {}
                (_, other) => return not_configured(&asked, other, map),
            }
            answer = self.configuration_step(message)?;
            asked = match message {
                HostMessage::RouteChunk(chunk) => {
                    format!("the route chunk from waypoint {}", chunk.first)
                }
                _ => "the route's announcement".to_owned(),
            };
        }
        match answer {
            TargetMessage::Configured => Ok(()),
            other => not_configured(&asked, other, map),
        }
    }

    /// One exchange on the MAVLink channel: `message`, then the
    /// firmware's answer (a `LinkSilent` report before it is checked and
    /// counted, as during a tick).
    ///
    /// # Errors
    /// The link failed, or the firmware answered anything else.
    pub fn mavlink_exchange(
        &mut self,
        message: &wmr_link::MavlinkIn,
    ) -> anyhow::Result<wmr_link::MavlinkOut> {
        match self.configuration_step(&HostMessage::Mavlink(*message))? {
            TargetMessage::Mavlink(out) => Ok(out),
            other => bail!("unexpected answer to a MAVLink message: {other:?}"),
        }
    }

    /// Bridges a ground station to the run from its next tick on
    /// (`super::mavlink`; the bridge opened before QEMU started).
    pub(super) fn attach_bridge(&mut self, bridge: Bridge) {
        self.bridge = Some(bridge);
    }

    /// Ends the run: `Finish`, the firmware's report, QEMU's exit.
    ///
    /// # Errors
    /// A wrong answer, or QEMU not exiting cleanly.
    pub fn end(&mut self) -> anyhow::Result<Finished> {
        self.release_held()?;
        self.send(&HostMessage::Finish)?;
        let finished = loop {
            match self.wait(self.timeout, false)? {
                Event::Message(TargetMessage::Finished(f)) => break f,
                // After a faulty run: late answers to resent ticks, and
                // the frames held back, are stale; a report of silence
                // may still come.
                Event::Message(
                    TargetMessage::Ticked(_) | TargetMessage::Refused(Refusal::StaleTick { .. }),
                )
                | Event::Stale
                    if self.faulty.is_some() =>
                {
                    self.count(|r| r.stale_answers += 1);
                }
                // The firmware's answer to a corrupt frame sent before
                // `Finish` (a duplicate, or the frame held back and
                // released above): `Finish` itself goes out clean, so
                // this is no reason to resend it.
                Event::Message(TargetMessage::Nack) if self.faulty.is_some() => {
                    self.count(|r| r.nacks += 1);
                }
                Event::Message(TargetMessage::LinkSilent { motors, silent_ms }) => {
                    self.silence_reported(motors, silent_ms)?;
                }
                Event::Message(other) => bail!("unexpected answer to Finish: {other:?}"),
                Event::Corrupt => bail!("corrupt frame from the firmware"),
                Event::Stale => bail!("stale frame from the firmware"),
                Event::Quiet => bail!(
                    "the firmware did not answer Finish within {:?}",
                    self.timeout
                ),
            }
        };
        let deadline = Instant::now() + self.timeout;
        loop {
            if let Some(status) = self.child.try_wait()? {
                ensure!(status.success(), "QEMU exited with {status} after Finish");
                self.finished = Some(finished);
                return Ok(finished);
            }
            ensure!(
                Instant::now() < deadline,
                "QEMU did not exit within {:?} after Finish",
                self.timeout
            );
            std::thread::sleep(Duration::from_millis(5));
        }
    }
}

impl TargetLink for QemuTarget {
    fn tick(&mut self, input: &TickInput) -> anyhow::Result<TickOutput> {
        if self.faulty.is_some() {
            return self.faulty_tick(input);
        }
        if let Some(mut bridge) = self.bridge.take() {
            let bridged = bridge.before_tick(|m| self.mavlink_exchange(m), input.tick);
            self.bridge = Some(bridge);
            bridged?;
        }
        self.send(&HostMessage::Tick(input.clone()))?;
        loop {
            match self.receive()? {
                TargetMessage::Ticked(out) => return Ok(out),
                // The host took longer than the link timeout since the
                // last tick (a loaded machine): the firmware stopped the
                // motors meanwhile, which simulated time does not see.
                TargetMessage::LinkSilent { motors, silent_ms } => {
                    self.silence_reported(motors, silent_ms)?;
                }
                TargetMessage::Refused(Refusal::NotConfigured) => {
                    bail!("the firmware was not configured (did it reset?)")
                }
                other => bail!("unexpected answer to tick {}: {other:?}", input.tick),
            }
        }
    }

    fn finish(&mut self) -> anyhow::Result<Diagnostics> {
        // The last tick's MAVLink output is still in the firmware's
        // queue (a bridge sends a tick's frames before the next tick):
        // fetched and sent before the firmware is finished.
        if let Some(mut bridge) = self.bridge.take() {
            let flushed = bridge.flush(|m| self.mavlink_exchange(m));
            self.bridge = Some(bridge);
            flushed?;
        }
        Ok(self.end()?.counters)
    }

    fn mavlink_log(&mut self) -> Option<&mut MavlinkLog> {
        self.bridge.as_mut().map(|b| &mut b.log)
    }

    fn stop_requested(&self) -> bool {
        self.bridge.as_ref().is_some_and(Bridge::stop_requested)
    }
}

/// The error for an answer to `asked` (a step of the configuration) that
/// is not the next one expected; a tag of `map` the firmware refused is
/// named by its id too.
fn not_configured(asked: &str, answer: TargetMessage, map: &[MapChunk]) -> anyhow::Result<()> {
    match answer {
        TargetMessage::Refused(why) => {
            let id = match why {
                Refusal::Map(MapRefusal::Tag { index, .. }) => map
                    .iter()
                    .flat_map(|c| &c.tags)
                    .nth(usize::from(index))
                    .map(|t| format!(" (tag id {:#x})", t.id)),
                _ => None,
            };
            bail!(
                "the firmware refused the configuration: {why}{} ({why:?})",
                id.unwrap_or_default()
            )
        }
        other => bail!("unexpected answer to {asked}: {other:?}"),
    }
}

/// The path of the link file `name` in `dir`.
fn link_path(dir: &Path, name: &std::ffi::CStr) -> anyhow::Result<PathBuf> {
    Ok(dir.join(name.to_str().context("a link file name")?))
}
