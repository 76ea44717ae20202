//! The firmware's defmt global logger: defmt frames over semihosting (QEMU
//! board) or an RTT up channel (Black Pill), as `defmt-semihosting` and
//! `defmt-rtt` send them, but without their panics.
//!
//! Why not those crates: both panic when the logger is taken while it is
//! already taken (`"defmt logger taken reentrantly"`) or released when it
//! is not (`"defmt release out of context"`), and neither has a feature
//! that turns those checks off (`defmt-rtt`'s `drop-on-contention` keeps
//! the re-entrancy panic). Those calls are panic paths in every function
//! that logs, and `cargo xtask panic-free` refuses them. Here a nested
//! frame (only possible from a fault handler while a frame is being
//! written: the firmware enables no interrupt, and the logger holds a
//! critical section from `acquire` to `release`) is dropped whole and the
//! outer frame goes on; an unmatched release does nothing.
//!
//! The byte stream is the same as those crates': defmt's own
//! [`defmt::Encoder`] (rzCOBS framing) for the frames; `defmt-print`,
//! `probe-rs` and `firmware-sim` decode it as they decode theirs.

#![allow(unsafe_code)]

use core::cell::UnsafeCell;
use core::sync::atomic::{AtomicU8, Ordering};

#[defmt::global_logger]
struct Logger;

/// The logger's state: one execution context at a time (see `depth`).
struct State {
    /// Nesting of `acquire` calls: 0 idle, 1 a frame in progress, more a
    /// nested frame being dropped.
    depth: AtomicU8,
    /// The critical section taken by the outermost `acquire`.
    restore: UnsafeCell<critical_section::RestoreState>,
    encoder: UnsafeCell<defmt::Encoder>,
    sink: UnsafeCell<sink::Sink>,
}

// SAFETY: `encoder`, `restore` and `sink` are touched only by the context
// that took the logger at depth 1, inside the critical section it holds
// (interrupts off on this single-core MCU); nested contexts only change
// `depth`, an atomic.
unsafe impl Sync for State {}

static STATE: State = State {
    depth: AtomicU8::new(0),
    restore: UnsafeCell::new(critical_section::RestoreState::invalid()),
    encoder: UnsafeCell::new(defmt::Encoder::new()),
    sink: UnsafeCell::new(sink::Sink::new()),
};

impl State {
    /// Runs `f` on the encoder and the sink, if this context owns the
    /// logger (depth 1).
    fn with_frame(&self, f: impl FnOnce(&mut defmt::Encoder, &mut sink::Sink)) {
        if self.depth.load(Ordering::Relaxed) == 1 {
            // SAFETY: depth 1 means the context that took the logger is the
            // one running (a nested context would have raised the depth),
            // inside its critical section: no other reference exists.
            let (encoder, sink) = unsafe { (&mut *self.encoder.get(), &mut *self.sink.get()) };
            f(encoder, sink);
        }
    }
}

// SAFETY (of the trait's contract): `acquire` takes a critical section
// and `release` gives it back; `write` and `flush` act only between the
// two, in the context that acquired.
unsafe impl defmt::Logger for Logger {
    fn acquire() {
        // SAFETY: released in `release` (outermost) or at once (nested).
        let restore = unsafe { critical_section::acquire() };
        let depth = STATE.depth.load(Ordering::Relaxed);
        if depth > 0 {
            // Nested (a fault handler logging mid-frame): this frame is
            // dropped. The outer critical section still holds, so giving
            // this one back changes nothing.
            STATE
                .depth
                .store(depth.saturating_add(1), Ordering::Relaxed);
            // SAFETY: the state `acquire` just returned, given back once.
            unsafe { critical_section::release(restore) };
            return;
        }
        STATE.depth.store(1, Ordering::Relaxed);
        // SAFETY: depth 1 and the critical section are ours.
        unsafe { STATE.restore.get().write(restore) };
        STATE.with_frame(|encoder, sink| encoder.start_frame(|b| sink.write(b)));
    }

    unsafe fn flush() {
        STATE.with_frame(|_, sink| sink.flush());
    }

    unsafe fn release() {
        match STATE.depth.load(Ordering::Relaxed) {
            // Not taken: nothing to release.
            0 => {}
            1 => {
                STATE.with_frame(|encoder, sink| {
                    encoder.end_frame(|b| sink.write(b));
                    sink.end_frame();
                });
                // SAFETY: written by the `acquire` that set depth 1.
                let restore = unsafe { STATE.restore.get().read() };
                STATE.depth.store(0, Ordering::Relaxed);
                // SAFETY: the outermost `acquire`'s state, given back once.
                unsafe { critical_section::release(restore) };
            }
            nested => STATE.depth.store(nested - 1, Ordering::Relaxed),
        }
    }

    unsafe fn write(bytes: &[u8]) {
        STATE.with_frame(|encoder, sink| encoder.write(bytes, |b| sink.write(b)));
    }
}

/// QEMU: the host's standard output through semihosting (QEMU's stdout).
#[cfg(feature = "board-qemu")]
mod sink {
    use cortex_m_semihosting::hio::{self, HostStream};

    /// Bytes gathered before one semihosting write (defmt's encoder hands
    /// over one byte at a time, and a semihosting call costs a trap to
    /// QEMU: unbuffered, a telemetry record of about 60 bytes would be 60
    /// calls).
    const BUF_SIZE: usize = 128;

    pub struct Sink {
        stdout: Option<HostStream>,
        buf: [u8; BUF_SIZE],
        len: usize,
    }

    impl Sink {
        pub const fn new() -> Self {
            Self {
                stdout: None,
                buf: [0; BUF_SIZE],
                len: 0,
            }
        }

        /// Buffers `bytes`, writing the buffer out whenever it fills.
        pub fn write(&mut self, bytes: &[u8]) {
            for &b in bytes {
                if let Some(slot) = self.buf.get_mut(self.len) {
                    *slot = b;
                    self.len += 1;
                }
                if self.len >= BUF_SIZE {
                    self.flush();
                }
            }
        }

        /// A frame is complete: out it goes (a log line is never held back).
        pub fn end_frame(&mut self) {
            self.flush();
        }

        /// Writes the buffer out; a failure to open or write loses it
        /// (there is nowhere to report it).
        pub fn flush(&mut self) {
            if self.stdout.is_none() {
                self.stdout = hio::hstdout().ok();
            }
            if let (Some(stdout), Some(bytes)) = (&mut self.stdout, self.buf.get(..self.len)) {
                let _ = stdout.write_all(bytes);
            }
            self.len = 0;
        }
    }
}

/// Black Pill: SEGGER RTT up channel 0 (`defmt`), read by the debug probe
/// (`probe-rs` finds the `_SEGGER_RTT` control block by its symbol). As
/// `defmt-rtt` 1.3 does: 1 KiB, non-blocking (old bytes are overwritten
/// when the host lags) until the host switches the channel to blocking.
#[cfg(feature = "board-blackpill")]
mod sink {
    use core::cell::UnsafeCell;
    use core::sync::atomic::{AtomicU32, Ordering};

    /// Bytes of the up channel's ring.
    const BUF_SIZE: usize = 1024;
    /// The channel's mode bits (flags, set by the host).
    const MODE_MASK: u32 = 0b11;
    /// Mode: wait while the ring is full (the host reads it).
    const MODE_BLOCK_IF_FULL: u32 = 2;
    /// Mode: overwrite unread bytes (the default: no host needed).
    const MODE_NON_BLOCKING_TRIM: u32 = 1;

    /// SEGGER's control block layout (one up channel, no down channel).
    #[repr(C)]
    pub struct Header {
        id: [u8; 16],
        max_up_channels: u32,
        max_down_channels: u32,
        up_channel: Channel,
    }

    #[repr(C)]
    struct Channel {
        name: *const u8,
        buffer: *mut u8,
        size: u32,
        write: AtomicU32,
        read: AtomicU32,
        flags: AtomicU32,
    }

    // SAFETY: the pointers are to statics and never change; the cursors
    // and flags are atomics shared with the host, which reads the buffer
    // only between `read` and `write` as the RTT protocol says.
    unsafe impl Sync for Header {}

    struct Buffer(UnsafeCell<[u8; BUF_SIZE]>);

    // SAFETY: written only by the logger inside its critical section.
    unsafe impl Sync for Buffer {}

    static BUFFER: Buffer = Buffer(UnsafeCell::new([0; BUF_SIZE]));
    static NAME: [u8; 6] = *b"defmt\0";

    #[unsafe(no_mangle)]
    static _SEGGER_RTT: Header = Header {
        id: *b"SEGGER RTT\0\0\0\0\0\0",
        max_up_channels: 1,
        max_down_channels: 0,
        up_channel: Channel {
            name: NAME.as_ptr(),
            buffer: BUFFER.0.get().cast(),
            size: BUF_SIZE as u32,
            write: AtomicU32::new(0),
            read: AtomicU32::new(0),
            flags: AtomicU32::new(MODE_NON_BLOCKING_TRIM),
        },
    };

    pub struct Sink;

    impl Sink {
        pub const fn new() -> Self {
            Self
        }

        fn channel() -> &'static Channel {
            &_SEGGER_RTT.up_channel
        }

        fn host_is_connected() -> bool {
            Self::channel().flags.load(Ordering::Relaxed) & MODE_MASK == MODE_BLOCK_IF_FULL
        }

        /// Free bytes between the write and the read cursor (one slot
        /// always stays empty).
        fn available(read: usize, write: usize) -> usize {
            if read > write {
                read - write - 1
            } else {
                (BUF_SIZE - 1 - write % BUF_SIZE) + read
            }
        }

        /// Writes `bytes`, waiting for the host in blocking mode,
        /// overwriting unread bytes otherwise.
        pub fn write(&mut self, mut bytes: &[u8]) {
            let channel = Self::channel();
            while !bytes.is_empty() {
                let write = channel.write.load(Ordering::Acquire) as usize % BUF_SIZE;
                let room = if Self::host_is_connected() {
                    let read = channel.read.load(Ordering::Relaxed) as usize % BUF_SIZE;
                    Self::available(read, write)
                } else {
                    BUF_SIZE
                };
                // Up to the end of the ring; the rest on the next pass.
                let n = bytes.len().min(room).min(BUF_SIZE - write);
                if n == 0 {
                    continue;
                }
                let (now, rest) = bytes.split_at_checked(n).unwrap_or((bytes, &[]));
                // SAFETY: only the logger writes the buffer, inside its
                // critical section; the host reads other bytes.
                let ring = unsafe { &mut *BUFFER.0.get() };
                if let Some(dst) = ring.get_mut(write..write + now.len()) {
                    for (d, s) in dst.iter_mut().zip(now) {
                        *d = *s;
                    }
                }
                channel
                    .write
                    .store(((write + now.len()) % BUF_SIZE) as u32, Ordering::Release);
                bytes = rest;
            }
        }

        /// Bytes go to the ring as they come: nothing to do.
        pub fn end_frame(&mut self) {}

        /// Waits until the host has read everything (blocking mode only).
        pub fn flush(&mut self) {
            let channel = Self::channel();
            if !Self::host_is_connected() {
                return;
            }
            while channel.read.load(Ordering::Relaxed) != channel.write.load(Ordering::Relaxed) {}
        }
    }
}
