//! QEMU running the firmware ([`QemuTarget`]), how it is run
//! ([`HilOptions`]), and the lock-step link to its USART1.

use std::io::{Read, Write};
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::{Context, bail, ensure};
use wmr_link::{
    Diagnostics, Finished, HostMessage, MAX_FRAME_BYTES, PROTOCOL_VERSION, Receiver, Refusal,
    Sender, TargetMessage, TickInput, TickOutput,
};

use crate::simulation::TargetLink;

/// The QEMU binary looked for on `PATH`.
pub const QEMU: &str = "qemu-system-arm";

/// How to run the firmware.
#[derive(Debug, Clone)]
pub struct HilOptions {
    /// Firmware ELF; `None` builds it with cargo (`board-qemu`, release).
    pub firmware: Option<PathBuf>,
    /// Where QEMU's stdout (the defmt log) goes; `None` discards it.
    pub log: Option<PathBuf>,
    /// Longest wait for any answer of the firmware.
    pub answer_timeout: Duration,
}

impl Default for HilOptions {
    fn default() -> Self {
        Self {
            firmware: None,
            log: None,
            answer_timeout: Duration::from_secs(10),
        }
    }
}

/// QEMU running the firmware, and the socket to its USART1.
pub struct QemuTarget {
    child: Child,
    stream: UnixStream,
    pub(super) rx: Receiver,
    tx: Sender,
    timeout: Duration,
    /// Bytes read from the socket and not yet given to `rx`.
    pending: Vec<u8>,
    pending_at: usize,
    /// The firmware's end-of-run report, once received.
    pub(super) finished: Option<Finished>,
    // Keeps the socket's directory alive.
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
            .context("creating a directory for the link socket")?;
        let socket = dir.path().join("usart1.sock");
        let stdout = match &options.log {
            Some(path) => Stdio::from(
                std::fs::File::create(path)
                    .with_context(|| format!("creating {}", path.display()))?,
            ),
            None => Stdio::null(),
        };
        let mut child = Command::new(QEMU)
            .args([
                "-M",
                "netduinoplus2",
                "-display",
                "none",
                "-monitor",
                "none",
            ])
            .args(["-semihosting-config", "enable=on,target=native"])
            .arg("-serial")
            .arg(format!("unix:{},server=on,wait=on", socket.display()))
            .arg("-kernel")
            .arg(firmware)
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
        let deadline = Instant::now() + options.answer_timeout;
        let stream = loop {
            if let Ok(s) = UnixStream::connect(&socket) {
                break s;
            }
            if let Ok(Some(status)) = child.try_wait() {
                let mut err = String::new();
                if let Some(mut e) = child.stderr.take() {
                    let _ = e.read_to_string(&mut err);
                }
                bail!("{QEMU} exited at start ({status}): {}", err.trim());
            }
            if Instant::now() > deadline {
                let _ = child.kill();
                bail!(
                    "{QEMU} did not open its serial socket within {:?}",
                    options.answer_timeout
                );
            }
            std::thread::sleep(Duration::from_millis(10));
        };
        let mut target = Self {
            child,
            stream,
            rx: Receiver::new(),
            tx: Sender::default(),
            timeout: options.answer_timeout,
            pending: Vec::with_capacity(4096),
            pending_at: 0,
            finished: None,
            _dir: dir,
        };
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
        self.stream
            .write_all(bytes)
            .context("writing to the firmware's USART1")
    }

    /// Sends one message, without waiting.
    ///
    /// # Errors
    /// The socket failed.
    pub fn send(&mut self, message: &HostMessage) -> anyhow::Result<()> {
        let mut out = [0_u8; MAX_FRAME_BYTES];
        let bytes = self
            .tx
            .frame(message, &mut out)
            .map_err(|e| anyhow::anyhow!("message too long for the link: {e:?}"))?
            .to_vec();
        self.send_raw(&bytes)
    }

    /// Waits for the next message from the firmware.
    ///
    /// # Errors
    /// Timeout, a closed socket, or a corrupt frame (the link is a local
    /// socket: corruption means a firmware bug, so it is not retried).
    pub fn receive(&mut self) -> anyhow::Result<TargetMessage> {
        let deadline = Instant::now() + self.timeout;
        loop {
            while let Some(&byte) = self.pending.get(self.pending_at) {
                self.pending_at += 1;
                if let Some(frame) = self.rx.push::<TargetMessage>(byte) {
                    return frame
                        .map_err(|e| anyhow::anyhow!("corrupt frame from the firmware: {e:?}"));
                }
            }
            let left = deadline.saturating_duration_since(Instant::now());
            ensure!(
                !left.is_zero(),
                "the firmware did not answer within {:?}",
                self.timeout
            );
            self.stream.set_read_timeout(Some(left))?;
            self.pending.resize(4096, 0);
            self.pending_at = 0;
            match self.stream.read(&mut self.pending) {
                Ok(0) => bail!("the firmware closed the link (QEMU exited?)"),
                Ok(n) => self.pending.truncate(n),
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                    ) =>
                {
                    self.pending.clear();
                }
                Err(e) => {
                    return Err(anyhow::Error::new(e).context("reading the firmware's USART1"));
                }
            }
        }
    }

    /// Sends a message and waits for the answer.
    ///
    /// # Errors
    /// As [`Self::send`] and [`Self::receive`].
    pub fn exchange(&mut self, message: &HostMessage) -> anyhow::Result<TargetMessage> {
        self.send(message)?;
        self.receive()
    }

    /// Ends the run: `Finish`, the firmware's report, QEMU's exit.
    ///
    /// # Errors
    /// A wrong answer, or QEMU not exiting cleanly.
    pub fn end(&mut self) -> anyhow::Result<Finished> {
        let finished = match self.exchange(&HostMessage::Finish)? {
            TargetMessage::Finished(f) => f,
            other => bail!("unexpected answer to Finish: {other:?}"),
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
        match self.exchange(&HostMessage::Tick(input.clone()))? {
            TargetMessage::Ticked(out) => Ok(out),
            TargetMessage::Refused(Refusal::NotConfigured) => {
                bail!("the firmware was not configured (did it reset?)")
            }
            other => bail!("unexpected answer to tick {}: {other:?}", input.tick),
        }
    }

    fn finish(&mut self) -> anyhow::Result<Diagnostics> {
        Ok(self.end()?.counters)
    }
}
