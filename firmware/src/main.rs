//! The robot firmware: the core's `Pilot` (through its `Robot`) as the only
//! control logic, on one of two boards chosen by a cargo feature:
//!
//! - `board-qemu` (default): QEMU's `netduinoplus2` (STM32F405). The devices
//!   are proxies over the HIL link (host files through semihosting) and
//!   the host simulator plays the hardware in
//!   lock-step (`firmware-sim hil`); see [`board::qemu`].
//! - `board-blackpill`: an STM32F411 "Black Pill" robot board; see
//!   [`board::blackpill`] for the pinout and how to flash it.
//!
//! Build with `cargo xtask firmware` (both boards) or
//! `cargo build -p wmr-firmware --release --target thumbv7em-none-eabihf
//! [--no-default-features --features board-blackpill]`.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod board;
#[cfg(target_os = "none")]
mod logger;
#[cfg(target_os = "none")]
mod stack;
#[cfg(target_os = "none")]
mod telemetry;

#[cfg(all(
    target_os = "none",
    feature = "board-qemu",
    feature = "board-blackpill"
))]
compile_error!("choose one board: `board-qemu` or `board-blackpill`");
#[cfg(all(
    target_os = "none",
    not(feature = "board-qemu"),
    not(feature = "board-blackpill")
))]
compile_error!("choose a board feature: `board-qemu` or `board-blackpill`");

/// The link-time proof of panic freedom (`cargo xtask panic-free`): this
/// panic handler calls a function that no object file defines. LTO and the
/// linker's section garbage collection drop the handler unless some code
/// path can still reach it, so the release build links if, and only if, no
/// panic path is left; otherwise the link fails with an undefined
/// reference to `wmr_firmware_has_a_panic_path`. The usual handlers (the
/// QEMU board's semihosting exit, the Black Pill's `panic-probe`) are left
/// out of this build.
#[cfg(all(target_os = "none", feature = "panic-never"))]
mod panic_never {
    #[panic_handler]
    fn panic(_info: &core::panic::PanicInfo) -> ! {
        // Defined nowhere, on purpose: see the module's documentation.
        #[allow(unsafe_code)]
        unsafe extern "Rust" {
            safe fn wmr_firmware_has_a_panic_path() -> !;
        }
        wmr_firmware_has_a_panic_path()
    }
}

#[cfg(target_os = "none")]
#[cortex_m_rt::entry]
fn main() -> ! {
    board::run()
}

/// On the host this crate is a stub, so that workspace-wide host commands
/// pass over it.
#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!(
        "wmr-firmware runs on a microcontroller: build it with `cargo xtask firmware` \
         (thumbv7em-none-eabihf) and run it under QEMU with `firmware-sim hil`"
    );
    std::process::exit(2);
}
