//! Files of the host through ARM semihosting (`SYS_OPEN`, `SYS_READ`,
//! `SYS_WRITE`; QEMU with `-semihosting-config enable=on,target=native`):
//! the transport of the QEMU board's lock-step link.
//!
//! Why not USART1: QEMU 7.2's STM32 USART model moves each byte with a
//! cross-thread wake-up (a 1-byte socket read or write per byte, and an
//! event-loop notification on every status-register read), about 1.5 ms a
//! lock-step tick on an idle machine. A semihosting call is one trap into
//! QEMU and one host system call for a whole buffer.
//!
//! The raw calls are `unsafe` (they hand QEMU pointers into guest memory);
//! this module alone holds them, behind [`HostFile`]'s safe methods.

#![allow(unsafe_code)]

use cortex_m_semihosting::syscall;

/// `SYS_OPEN` mode `"rb"`.
pub const READ_BINARY: usize = cortex_m_semihosting::nr::open::R_BINARY;
/// `SYS_OPEN` mode `"wb"` (on a named pipe the truncation does nothing).
pub const WRITE_BINARY: usize = cortex_m_semihosting::nr::open::W_TRUNC_BINARY;

/// A host file opened through semihosting.
pub struct HostFile {
    handle: usize,
}

impl HostFile {
    /// Opens the host file `name` (NUL-terminated; relative to QEMU's
    /// working directory) with a `SYS_OPEN` `mode`; `None` if the host
    /// refuses or `name` has no NUL.
    pub fn open(name: &[u8], mode: usize) -> Option<Self> {
        let len = name.iter().position(|&b| b == 0)?;
        // SAFETY: `SYS_OPEN` reads its three-word argument block (built by
        // the macro, alive across the call) and the NUL-terminated string
        // `name` points to (checked above: a NUL at `len`); it writes no
        // guest memory.
        let handle = unsafe { syscall!(OPEN, name.as_ptr(), mode, len) };
        // -1 is the failure value.
        (handle != usize::MAX).then_some(Self { handle })
    }

    /// Reads what the file has now, up to `buf.len()` bytes, without
    /// waiting on a regular file (0 at its end); the number of bytes read
    /// (0 on an error).
    pub fn read(&mut self, buf: &mut [u8]) -> usize {
        // SAFETY: `SYS_READ` writes at most `buf.len()` bytes from
        // `buf.as_mut_ptr()`: memory borrowed exclusively for the call.
        let not_read = unsafe { syscall!(READ, self.handle, buf.as_mut_ptr(), buf.len()) };
        // `SYS_READ` returns the bytes not read (all of them on an error).
        buf.len().saturating_sub(not_read)
    }

    /// Writes all of `bytes`; `false` if the host stopped taking them.
    pub fn write_all(&mut self, mut bytes: &[u8]) -> bool {
        while !bytes.is_empty() {
            // SAFETY: `SYS_WRITE` reads at most `bytes.len()` bytes from
            // `bytes.as_ptr()`: memory borrowed for the call.
            let not_written = unsafe { syscall!(WRITE, self.handle, bytes.as_ptr(), bytes.len()) };
            // `SYS_WRITE` returns the bytes not written; all of them (or
            // more: -1) means an error.
            if not_written >= bytes.len() {
                return false;
            }
            bytes = bytes.get(bytes.len() - not_written..).unwrap_or_default();
        }
        true
    }
}
