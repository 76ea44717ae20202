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

use core::ffi::CStr;

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
    /// Opens the host file `name` (relative to QEMU's working directory)
    /// with a `SYS_OPEN` `mode`; `None` if the host refuses.
    pub fn open(name: &CStr, mode: usize) -> Option<Self> {
        // SAFETY: `SYS_OPEN` reads its three-word argument block (built by
        // the macro, alive across the call) and the NUL-terminated string
        // `name` points to; it writes no guest memory.
        let handle = unsafe { syscall!(OPEN, name.as_ptr(), mode, name.count_bytes()) };
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

    /// Writes `bytes` in one call (to a pipe, a blocking write of a frame
    /// is whole); whether all of them went.
    pub fn write(&mut self, bytes: &[u8]) -> bool {
        // SAFETY: `SYS_WRITE` reads at most `bytes.len()` bytes from
        // `bytes.as_ptr()`: memory borrowed for the call.
        let not_written = unsafe { syscall!(WRITE, self.handle, bytes.as_ptr(), bytes.len()) };
        // `SYS_WRITE` returns the bytes not written (-1 on an error).
        not_written == 0
    }
}
