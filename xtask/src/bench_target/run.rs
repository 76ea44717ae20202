//! Building `wmr-bench` (one math backend) or `wmr-bench-m0` (the
//! Cortex-M0) and running it under QEMU.

use std::time::Duration;

use crate::target::{Build, qemu, qemu_on};

use super::report::{Report, parse};

/// A whole run takes well under a second of host time.
const QEMU_TIMEOUT: Duration = Duration::from_secs(120);

/// Features every `wmr-bench` build adds to its backend's: the fusion EKF
/// estimator, for the whole-tick rows that run it.
const BENCH_FEATURES: [&str; 1] = ["fusion-ekf"];

/// Builds `wmr-bench` for one backend (`label` names the ELF's copy) and
/// runs it under QEMU.
pub fn run_backend(
    backend: &str,
    features: &[&str],
    env: &[(&str, &str)],
    label: &str,
) -> Result<Report, String> {
    let features: Vec<&str> = features.iter().chain(&BENCH_FEATURES).copied().collect();
    let elf = Build {
        bins: &["wmr-bench"],
        features: &features,
        env,
        ..Build::default()
    }
    .run(label)?;
    let elf = elf.first().ok_or("no ELF built")?;
    eprintln!("    running {} under QEMU (-icount shift=0)", elf.display());
    let sizes = crate::size::analyse(elf)?;
    let output = qemu(elf, QEMU_TIMEOUT)?;
    let mut report = parse(&output).map_err(|e| format!("{}: {e}", elf.display()))?;
    report.elf_flash_ram = Some((sizes.flash, sizes.ram));
    if report.backend != backend {
        return Err(format!(
            "{} says backend {}, expected {backend}",
            elf.display(),
            report.backend
        ));
    }
    Ok(report)
}

/// The Cortex-M0 target of `wmr-bench-m0`.
pub const M0_TARGET: &str = "thumbv6m-none-eabi";
/// QEMU's Cortex-M0 machine (nRF51822, 16 MHz).
pub(super) const M0_MACHINE: &str = "microbit";
/// `-icount shift` on the M0: 64 ns per instruction, 1.024 SysTick counts at
/// 16 MHz (shift 0 would make one count 62 instructions).
pub(super) const M0_ICOUNT_SHIFT: u32 = 6;

/// Builds `wmr-bench-m0` (the same bench source, default backend) for the
/// Cortex-M0 and runs it on QEMU's `microbit`.
pub fn run_m0() -> Result<Report, String> {
    let elfs = crate::target::build_release(
        "wmr-bench-m0",
        M0_TARGET,
        &["--features", "fusion-ekf"],
        &[],
        &["wmr-bench-m0"],
        "bench-m0",
    )?;
    let elf = elfs.first().ok_or("no ELF built")?;
    eprintln!(
        "    running {} under QEMU {M0_MACHINE} (-icount shift={M0_ICOUNT_SHIFT})",
        elf.display()
    );
    let sizes = crate::size::analyse(elf)?;
    let output = qemu_on(elf, M0_MACHINE, M0_ICOUNT_SHIFT, QEMU_TIMEOUT)?;
    let mut report = parse(&output).map_err(|e| format!("{}: {e}", elf.display()))?;
    report.elf_flash_ram = Some((sizes.flash, sizes.ram));
    if report.machine != M0_MACHINE {
        return Err(format!(
            "{} says machine {}, expected {M0_MACHINE}",
            elf.display(),
            report.machine
        ));
    }
    Ok(report)
}
