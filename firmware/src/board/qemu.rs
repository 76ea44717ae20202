//! QEMU `netduinoplus2` board (STM32F405 model): hardware-in-the-loop.
//!
//! QEMU models the F405's USARTs, timers and the Cortex-M4 core, but no
//! motors, encoders or RFID reader, and no RCC (clock setup is skipped: the
//! model runs at its fixed 168 MHz). So the robot's devices are proxies
//! (`wmr_link::proxy`) and two host files, read and written through
//! semihosting ([`host_file`]), carry the lock-step link to `firmware-sim
//! hil`: the host appends its frames to a regular file
//! ([`HIL_TO_TARGET_FILE`]), which the firmware polls (a read at its end
//! returns at once, so the firmware keeps its time), and the firmware
//! writes its frames to a named pipe ([`HIL_TO_HOST_PIPE`]), which the host
//! waits on. The frames are the link's (COBS, CRC-32), as on a serial line.
//! (USART1 carried the link before: QEMU's USART model moves each byte
//! with a cross-thread wake-up, about 1.5 ms a tick; see `host_file`.)
//!
//! - The **control tick** is the arrival of the host's `Tick` frame: in
//!   lock-step the simulator is the clock, which makes the run
//!   deterministic whatever QEMU's speed. (The real board's tick comes from
//!   a hardware timer; see `board::blackpill`.)
//! - **SysTick** (core clock, free-running: [`SilenceTimer`]) times the
//!   link: after [`LINK_TIMEOUT_MS`] without a valid frame while a run is
//!   configured,
//!   the firmware counts a timeout, stops the motors, as a robot must
//!   when its sensors go silent, and reports it (`LinkSilent`, with the
//!   motors). It drives again on the next tick frame.
//! - **Corrupt frames** (bad COBS/CRC/postcard, too long) are dropped,
//!   counted and answered with `Nack`, so that the host resends at once;
//!   the receiver resynchronises at the next `0x00`. Stale frames (a
//!   duplicate, or overtaken by a newer one) are dropped and counted, never
//!   used. A resent tick is answered again, not run twice (`Session`).
//! - **Logs** go out with defmt over semihosting (QEMU's stdout; decode with
//!   the firmware ELF), through the firmware's own logger (`crate::logger`),
//!   with a telemetry record every `Configure::telemetry_every_ticks` ticks
//!   (`crate::telemetry`). The run ends on the host's `Finish`: the firmware
//!   answers with its stack high-water mark and exits through semihosting.

mod host_file;

use core::cell::RefCell;

use cortex_m::peripheral::SYST;
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m_semihosting::debug::{self, EXIT_FAILURE, EXIT_SUCCESS};
use host_file::HostFile;
// The device crate's interrupt vectors (cortex-m-rt's `device` feature):
// this board uses no peripheral of it.
use stm32f4xx_hal as _;
use wmr_link::proxy::ProxyBus;
use wmr_link::session::{LinkTagMap, MavlinkStore, RouteStore, Session};
use wmr_link::{
    HIL_TO_HOST_PIPE, HIL_TO_TARGET_FILE, HostMessage, LINK_TIMEOUT_MS, LinkError, MAX_FRAME_BYTES,
    PROTOCOL_VERSION, Receiver, Sender, TargetMessage,
};

/// Core clock of the `netduinoplus2` model, Hz.
const CORE_CLOCK_HZ: u32 = 168_000_000;

/// Link faults logged one by one; after that, one line in [`LOG_EVERY`]
/// (a faulty link must not slow the firmware down with semihosting logs;
/// every fault is counted either way).
const LOG_FIRST: u32 = 8;
/// See [`LOG_FIRST`].
const LOG_EVERY: u32 = 1000;

/// Whether the `n`-th fault (from 1) of a kind is logged.
fn worth_logging(n: u32) -> bool {
    n <= LOG_FIRST || n.is_multiple_of(LOG_EVERY)
}

/// Bytes read from the host per semihosting call, at most (a tick frame
/// is about 31 B; one with a flooded RFID line takes a few reads).
const INBOX_BYTES: usize = 64;

/// The lock-step link's two host files, and the bytes read from the host
/// and not yet given to the receiver.
struct HostLink {
    from_host: HostFile,
    to_host: HostFile,
    inbox: &'static mut [u8; INBOX_BYTES],
    next: usize,
    end: usize,
}

impl HostLink {
    /// Opens both files (the host made them before starting QEMU); `None`
    /// if either is missing.
    fn open(inbox: &'static mut [u8; INBOX_BYTES]) -> Option<Self> {
        Some(Self {
            from_host: HostFile::open(HIL_TO_TARGET_FILE, host_file::READ_BINARY)?,
            to_host: HostFile::open(HIL_TO_HOST_PIPE, host_file::WRITE_BINARY)?,
            inbox,
            next: 0,
            end: 0,
        })
    }

    /// The next byte from the host, if it has sent one (one semihosting
    /// read per buffer, not per byte).
    fn read_byte(&mut self) -> Option<u8> {
        if self.next >= self.end {
            self.end = self.from_host.read(self.inbox.as_mut_slice());
            self.next = 0;
        }
        let byte = *self.inbox.get(self.next).filter(|_| self.next < self.end)?;
        self.next += 1;
        Some(byte)
    }

    /// Sends `bytes` to the host. A write the host does not take (its end
    /// of the pipe closed: it stopped) loses the frame, as a cut line
    /// would; a host still running resends or reports the silence.
    fn write(&mut self, bytes: &[u8]) {
        let _ = self.to_host.write(bytes);
    }
}

/// Milliseconds of link silence from SysTick, by differences of its 24-bit
/// down-counter at full reload (2^24 cycles, 99.9 ms at 168 MHz): a poll
/// of the link that comes late, because QEMU was not scheduled for a
/// while, still counts every millisecond that passed, as long as polls
/// are less than 99.9 ms apart. (Counting one millisecond per wrap flag,
/// at a 1 ms reload, missed every wrap but one in such a gap: a loaded
/// machine let 68 of 345 outages of 200 ms go unnoticed.) QEMU derives the
/// counter from the host clock.
struct SilenceTimer {
    /// The counter at the last restart or poll.
    last: u32,
    /// Cycles polled and not yet a whole millisecond.
    cycles: u32,
    /// Whole milliseconds since the last restart.
    ms: u32,
}

/// SysTick's reload: the counter's full 24 bits.
const SYST_RELOAD: u32 = 0x00FF_FFFF;
/// Core cycles per millisecond.
const CYCLES_PER_MS: u32 = CORE_CLOCK_HZ / 1000;

impl SilenceTimer {
    fn new(mut syst: SYST) -> Self {
        syst.set_clock_source(SystClkSource::Core);
        syst.set_reload(SYST_RELOAD);
        syst.clear_current();
        syst.enable_counter();
        Self {
            last: SYST::get_current(),
            cycles: 0,
            ms: 0,
        }
    }

    /// Starts counting from 0 ms (a valid frame arrived).
    fn restart(&mut self) {
        self.last = SYST::get_current();
        self.cycles = 0;
        self.ms = 0;
    }

    /// Milliseconds since the last restart, saturating.
    fn silent_ms(&mut self) -> u32 {
        let now = SYST::get_current();
        // A down-counter: the cycles since the last poll, modulo 2^24.
        let elapsed = self.last.wrapping_sub(now) & SYST_RELOAD;
        self.last = now;
        // At most 2^24 + CYCLES_PER_MS: no overflow.
        self.cycles += elapsed;
        let whole = self.cycles / CYCLES_PER_MS;
        self.cycles -= whole * CYCLES_PER_MS;
        self.ms = self.ms.saturating_add(whole);
        self.ms
    }
}

/// Encodes and sends one message (a frame that does not fit is a bug in
/// the message sizes, caught by the link's tests; it is logged and dropped).
/// By reference: a `TargetMessage` (184 B, its `Finished` the largest) is
/// not copied into each frame on the way out.
fn send(link: &mut HostLink, tx: &mut Sender, message: &TargetMessage) {
    let mut out = [0_u8; MAX_FRAME_BYTES];
    match tx.frame(message, &mut out) {
        Ok(bytes) => link.write(bytes),
        Err(e) => defmt::error!("answer not sent: {}", e),
    }
}

/// Ends QEMU with a failure: start-up found the hardware or the statics
/// already taken, which only a bug can cause, or the link's files missing.
/// (Not inlined: one copy of the exit for every start-up check, in flash.)
#[inline(never)]
fn fail() -> ! {
    debug::exit(EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}

/// The MAVLink endpoint and mission runner of route runs (about 11 KB
/// with the channel's queues and the upload check's route), in a static,
/// blank (`MavlinkStore::BLANK`: every byte zero, so building it clears
/// memory) and idle: each route run configures it with the settings its
/// route announcement carries (`RouteSpec::mavlink`, the robot file's
/// `[mavlink]`).
fn mavlink_store() -> Option<&'static mut MavlinkStore> {
    cortex_m::singleton!(: MavlinkStore = MavlinkStore::BLANK)
}

/// The firmware: serve the link until the host says `Finish`.
///
/// The long-lived state (the proxy bus, the session with its robot, the
/// link receiver: about 1.9 KB; the tag map a run may load,
/// `wmr_link::MAP_CAPACITY` tags, 64 KiB; the route a run may follow,
/// its `RouteStore`; the MAVLink endpoint of route runs, its
/// `MavlinkStore`) lives in statics
/// (`cortex_m::singleton!`, in `.bss`), not in this function's frame, so
/// the stack holds only what a message's handling needs (docs/budgets.md,
/// "Stack").
pub fn run() -> ! {
    // Built first, in a frame of its own that is gone before the run
    // loop's: the endpoint passes through the stack on its way to its
    // static, and stacked on the run loop's frame it would be the deepest
    // point of a run. In every build, the particle filter's included: that
    // filter is built in place, so its stack (8 KiB at most,
    // `[hil_peak_stack_limit_bytes]` in `firmware/budgets.toml`) leaves RAM
    // for the store.
    let Some(mav) = mavlink_store() else { fail() };
    serve(mav)
}

/// [`run`]'s loop, lent the MAVLink store.
#[inline(never)]
fn serve(mav: &'static mut MavlinkStore) -> ! {
    let Some(cp) = cortex_m::Peripherals::take() else {
        // Only possible if something took them before `main`.
        fail()
    };
    let Some(inbox) = cortex_m::singleton!(: [u8; INBOX_BYTES] = [0; INBOX_BYTES]) else {
        fail()
    };
    let Some(mut link) = HostLink::open(inbox) else {
        defmt::error!("the link's host files are missing (start it with `firmware-sim hil`)");
        fail()
    };
    let mut silence = SilenceTimer::new(cp.SYST);
    let Some(bus) = cortex_m::singleton!(: ProxyBus = ProxyBus::new()) else {
        fail()
    };
    let bus: &'static ProxyBus = bus;
    // Empty (its length 0): built in place, not on the stack (the HIL
    // tests' peak stack would show 64 KiB).
    let Some(map) = cortex_m::singleton!(: RefCell<LinkTagMap> = RefCell::new(LinkTagMap::new()))
    else {
        fail()
    };
    let map: &'static RefCell<LinkTagMap> = map;
    // The route's waypoints and its scratch plan or follower (24 KB), in
    // place for the same reason.
    let Some(route) = cortex_m::singleton!(: RouteStore = RouteStore::new()) else {
        fail()
    };
    let Some(session) = cortex_m::singleton!(: Session<'static> = Session::new(bus, map, route))
    else {
        fail()
    };
    session.lend_mavlink(mav);
    let Some(rx) = cortex_m::singleton!(: Receiver = Receiver::new()) else {
        fail()
    };
    let mut tx = Sender::default();
    defmt::info!(
        "wmr-firmware (QEMU board), link protocol {}",
        PROTOCOL_VERSION
    );
    send(
        &mut link,
        &mut tx,
        &TargetMessage::Hello {
            protocol: PROTOCOL_VERSION,
        },
    );

    let mut stopped_for_silence = false;
    loop {
        if let Some(byte) = link.read_byte() {
            match rx.push::<HostMessage>(byte) {
                None => {}
                // Counted by the receiver; the host gets the count.
                Some(Err(LinkError::Stale)) => {}
                Some(Err(e)) => {
                    let n = rx.counters().corrupt_frames;
                    if worth_logging(n) {
                        defmt::warn!("corrupt frame dropped ({} so far): {}", n, e);
                    }
                    send(&mut link, &mut tx, &TargetMessage::Nack);
                }
                Some(Ok(message)) => {
                    silence.restart();
                    if stopped_for_silence {
                        if worth_logging(rx.counters().timeouts) {
                            defmt::info!("link back");
                        }
                        stopped_for_silence = false;
                    }
                    let (answer, done) =
                        session.handle(&message, rx.counters(), crate::stack::peak_bytes);
                    match answer {
                        TargetMessage::Configured => defmt::info!("configured"),
                        // Why is in the answer, which the host prints
                        // (formatting `Refusal` here would cost 0.8 KB of
                        // flash).
                        TargetMessage::Refused(_) => {
                            rx.note_unexpected();
                            if worth_logging(rx.counters().unexpected_messages) {
                                defmt::warn!("refused (the host shows why)");
                            }
                        }
                        _ => {}
                    }
                    let configured = matches!(answer, TargetMessage::Configured);
                    send(&mut link, &mut tx, &answer);
                    // Telemetry after the answer: the host is not kept
                    // waiting for the log.
                    if let Some(record) = session.telemetry() {
                        crate::telemetry::record(record);
                    } else if let Some(start) = session.telemetry_start().filter(|_| configured) {
                        crate::telemetry::start(start);
                    }
                    if done {
                        defmt::info!("finished; peak stack {} B", crate::stack::peak_bytes());
                        debug::exit(EXIT_SUCCESS);
                    }
                }
            }
        } else if session.is_configured() && !stopped_for_silence {
            let silent_ms = silence.silent_ms();
            if silent_ms >= LINK_TIMEOUT_MS {
                rx.note_timeout();
                let report = session.link_silent(silent_ms);
                stopped_for_silence = true;
                if worth_logging(rx.counters().timeouts) {
                    defmt::warn!("link silent for {} ms: motors stopped", silent_ms);
                }
                send(&mut link, &mut tx, &report);
            }
        }
    }
}

/// A panic (none is possible: `cargo xtask panic-free` proves that no
/// panic path links) is logged and ends QEMU with a failure.
#[cfg(not(feature = "panic-never"))]
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    defmt::error!("panic: {}", defmt::Display2Format(info));
    debug::exit(EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}
