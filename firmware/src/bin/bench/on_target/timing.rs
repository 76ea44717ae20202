//! Counting instructions: SysTick read around a call ([`timed`]), and its
//! calibration against loops and `nop`s of known length (items 1 and 2 of
//! the bench's documentation, `main.rs`).

use core::hint::black_box;

use cortex_m::peripheral::SYST;
use cortex_m_semihosting::hprintln;

use super::fail;

/// Timed calls per stage (`stage::Stage` holds this many).
pub(super) const SAMPLES: usize = 200;

/// The machine: QEMU's `netduinoplus2` (STM32F405, Cortex-M4F) for
/// `thumbv7em-none-eabihf`, its `microbit` (nRF51822, Cortex-M0) for
/// `thumbv6m-none-eabi` (`wmr-bench-m0`).
pub(super) const MACHINE: &str = if cfg!(target_abi = "eabihf") {
    "netduinoplus2"
} else {
    "microbit"
};
/// Core clock of the machine, Hz: 168 MHz, 16 MHz.
const CORE_CLOCK_HZ: f32 = if cfg!(target_abi = "eabihf") {
    168.0e6
} else {
    16.0e6
};
/// Virtual nanoseconds per instruction, `2^shift` of QEMU's `-icount
/// shift`: 0 on the M4F (0.168 counts per instruction), 6 on the M0 (64
/// ns: 1.024 counts per instruction, where shift 0 would quantize a
/// sample to 62 instructions).
const NS_PER_INSTRUCTION: f32 = if cfg!(target_abi = "eabihf") {
    1.0
} else {
    64.0
};
/// SysTick counts per instruction.
const EXPECTED_COUNTS_PER_INSTRUCTION: f32 = CORE_CLOCK_HZ * NS_PER_INSTRUCTION * 1.0e-9;
/// SysTick is a 24-bit down-counter.
pub(super) const SYSTICK_MASK: u32 = 0x00FF_FFFF;

/// Instructions in the `nop` block of the cross-check.
const NOP_BLOCK: u32 = 4000;

/// `f(input)` and the SysTick counts it took (the counter runs down and
/// wraps every 2^24 counts, ≈ 100 ms of virtual time: far longer than
/// any call).
///
/// `black_box` pins the work between the two reads: `input` is complete
/// before the first read and opaque to `f`, and the result is taken
/// before the second read. Inside the window are only the call, the
/// function, and one `black_box` each way (counted in the empty
/// measurement).
#[inline(always)]
pub(super) fn timed<I, R>(input: &I, f: impl FnOnce(&I) -> R) -> (u32, R) {
    let input = black_box(input);
    let start = SYST::get_current();
    let result = black_box(f(black_box(input)));
    let end = SYST::get_current();
    (start.wrapping_sub(end) & SYSTICK_MASK, result)
}

/// `iterations` (≥ 1) turns of a `subs`/`bne` loop: 2 instructions each.
#[inline(never)]
fn spin(iterations: u32) {
    let iterations = iterations.max(1);
    // SAFETY: a countdown in one register; it touches no memory, no
    // stack and no other register, and ends (iterations ≥ 1).
    #[allow(unsafe_code)]
    unsafe {
        core::arch::asm!(
            "2:",
            "subs {n}, {n}, #1",
            "bne 2b",
            n = inout(reg) iterations => _,
            options(nomem, nostack),
        );
    }
}

/// Exactly [`NOP_BLOCK`] `nop`s.
#[inline(never)]
fn nops() {
    // SAFETY: `nop`s only.
    #[allow(unsafe_code)]
    unsafe {
        core::arch::asm!(
            ".rept {n}",
            "nop",
            ".endr",
            n = const NOP_BLOCK,
            options(nomem, nostack, preserves_flags),
        );
    }
}

/// Mean of SysTick counts over `n` runs of `f`.
fn mean_counts(n: u32, mut f: impl FnMut() -> u32) -> f32 {
    let total: u64 = (0..n).map(|_| u64::from(f())).sum();
    total as f32 / n as f32
}

/// Counts → instructions.
#[derive(Clone, Copy)]
pub(super) struct Calibration {
    counts_per_instruction: f32,
    overhead_instructions: f32,
}

impl Calibration {
    pub(super) fn instructions(self, counts: f32) -> f32 {
        counts / self.counts_per_instruction - self.overhead_instructions
    }
}

pub(super) fn calibrate() -> Calibration {
    const SHORT: u32 = 1_000;
    const LONG: u32 = 101_000;
    let short = mean_counts(4, || timed(&SHORT, |&n| spin(n)).0);
    let long = mean_counts(4, || timed(&LONG, |&n| spin(n)).0);
    let loop_counts_per_iteration = (long - short) / (LONG - SHORT) as f32;
    // The loop's two instructions per iteration, checked against a
    // block of single instructions.
    let counts_per_instruction = 0.5 * loop_counts_per_iteration;
    let empty = mean_counts(SAMPLES as u32, || timed(&0_u32, |_| ()).0);
    let nop_block = mean_counts(SAMPLES as u32, || timed(&0_u32, |_| nops()).0);
    let nop_counts_per_instruction = (nop_block - empty) / NOP_BLOCK as f32;
    let cal = Calibration {
        counts_per_instruction,
        overhead_instructions: empty / counts_per_instruction,
    };
    hprintln!(
        "calibration counts_per_instruction={:.5} loop_counts_per_iteration={:.5} \
         nop_counts_per_instruction={:.4} overhead_instructions={:.1}",
        counts_per_instruction,
        loop_counts_per_iteration,
        nop_counts_per_instruction,
        cal.overhead_instructions
    );
    let off = |x: f32| (x / EXPECTED_COUNTS_PER_INSTRUCTION - 1.0).abs() > 0.01;
    if off(counts_per_instruction) || off(nop_counts_per_instruction) {
        fail(
            "SysTick does not count the expected counts per instruction: run QEMU \
             with `-icount shift=0` (netduinoplus2, 168 MHz) or `-icount shift=6` \
             (microbit, 16 MHz)",
        );
    }
    cal
}
