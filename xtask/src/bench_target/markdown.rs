//! The report's tables: one column per backend, and the Cortex-M0 run's.

use std::fmt::Write as _;

use crate::target::{grouped, qemu_version, rustc_version};

use super::benches::{FILTERS, FUSION_STACKS, MATH, STAGES};
use super::report::{Report, Stat};
use super::run::{M0_ICOUNT_SHIFT, M0_MACHINE, M0_TARGET};

/// `mean (min–max)`.
fn cell(stat: Option<&Stat>) -> String {
    stat.map_or_else(
        || "–".into(),
        |s| {
            format!(
                "{} ({}–{})",
                grouped(s.mean.round().max(0.0) as u64),
                grouped(s.min.max(0) as u64),
                grouped(s.max.max(0) as u64)
            )
        },
    )
}

/// The report's markdown (one column per backend).
pub fn markdown(reports: &[Report]) -> String {
    let mut md = String::new();
    let header = |md: &mut String, first: &str| backend_header(md, first, reports);
    let samples = reports.first().map_or(0, |r| r.samples);
    let opt_level = std::env::var("CARGO_PROFILE_RELEASE_OPT_LEVEL")
        .map(|l| format!(", `CARGO_PROFILE_RELEASE_OPT_LEVEL={l}`"))
        .unwrap_or_default();
    let _ = writeln!(
        md,
        "Instructions per call on the target: `wmr-bench` (release{opt_level}, \
         thumbv7em-none-eabihf, {}) under {} `netduinoplus2` (STM32F405, \
         Cortex-M4F) with `-icount shift=0`. Mean over {samples} calls along paper \
         001's figure-eight, min–max in parentheses (±6: one SysTick count); the \
         call and the loading of its arguments included. Instructions are a proxy \
         for Cortex-M4 cycles, not cycles: QEMU models no flash wait states, \
         pipeline or FPU latencies (`vdiv.f32`, `vsqrt.f32`: 14 cycles each). \
         Regenerate with `cargo xtask bench-target --write`.\n",
        rustc_version(),
        qemu_version()
    );
    header(&mut md, "stage");
    for (name, label) in STAGES {
        let _ = write!(md, "| {label} |");
        for r in reports {
            let _ = write!(md, " {} |", cell(r.stat(name)));
        }
        md.push('\n');
    }
    let _ = write!(md, "| tick peak stack (below the caller's SP) |");
    for r in reports {
        let _ = write!(md, " {} B |", grouped(r.tick_stack_bytes));
    }
    md.push('\n');
    for (name, estimator) in FUSION_STACKS {
        let _ = write!(
            md,
            "| tick peak stack, {estimator} estimator (below the caller's SP) |"
        );
        for r in reports {
            let stack = r.stack(name);
            let _ = write!(
                md,
                " {} |",
                stack.map_or("–".into(), |b| format!("{} B", grouped(b)))
            );
        }
        md.push('\n');
    }
    md.push_str("\nThe math backend alone, per call:\n\n");
    header(&mut md, "function");
    for (name, label) in MATH {
        let _ = write!(md, "| {label} |");
        for r in reports {
            let _ = write!(md, " {} |", cell(r.stat(name)));
        }
        md.push('\n');
    }
    filters_markdown(&mut md, reports, samples);
    md.push_str(
        "\n`wmr-bench` itself (a binary of its own: the firmware's size is `cargo xtask size`'s):",
    );
    for r in reports {
        if let Some((flash, ram)) = r.elf_flash_ram {
            let _ = write!(
                md,
                " {} {} B flash, {} B static RAM;",
                r.backend,
                grouped(flash),
                grouped(ram)
            );
        }
    }
    md.pop();
    md.push_str(".\n");
    md.push_str("\nCalibration:");
    for r in reports {
        let _ = write!(
            md,
            " {} {:.5} SysTick counts per instruction (expected 0.168), {:.1} \
             instructions of measurement overhead subtracted;",
            r.backend, r.counts_per_instruction, r.overhead_instructions
        );
    }
    md.pop();
    md.push_str(".\n");
    md
}

/// The Cortex-M0 run's tables: the tick's stages, the tick's stack, the
/// math, the bench's own size.
pub fn m0_markdown(m0: &Report) -> String {
    let mut md = String::new();
    let _ = writeln!(
        md,
        "On a Cortex-M0 (no FPU: every `f32` operation is a call into \
         compiler-builtins' soft float): `wmr-bench-m0` (the same source, \
         {M0_TARGET}, backend {}) under QEMU `{M0_MACHINE}` (nRF51822, 16 MHz) \
         with `-icount shift={M0_ICOUNT_SHIFT}` ({:.5} SysTick counts per \
         instruction, expected 1.024). Mean (min–max) over {} calls; both \
         whole ticks, each robot in a function of its own (paper 001's \
         estimator, and the fusion EKF with a tag frame every other tick); \
         paper 004's filters and the route are not run (their states and \
         stacks, and a route plan's 20 KB, do not fit beside the bench in 16 KiB \
         of RAM).\n",
        m0.backend, m0.counts_per_instruction, m0.samples
    );
    md.push_str("| stage or function | Cortex-M0 |\n| --- | ---: |\n");
    for (name, label) in STAGES.iter().chain(MATH.iter()) {
        if let Some(stat) = m0.stat(name) {
            let _ = writeln!(md, "| {label} | {} |", cell(Some(stat)));
        }
    }
    let _ = writeln!(
        md,
        "| tick peak stack (below the caller's SP) | {} B |",
        grouped(m0.tick_stack_bytes)
    );
    if let Some(bytes) = m0.stack("robot_tick_fusion") {
        let _ = writeln!(
            md,
            "| tick peak stack, fusion EKF estimator (below the caller's SP) | {} B |",
            grouped(bytes)
        );
    }
    if let Some((flash, ram)) = m0.elf_flash_ram {
        let _ = writeln!(
            md,
            "\n`wmr-bench-m0` itself: {} B flash, {} B static RAM (the core's ticks \
             with both estimators, the HIL link's proxies and the math benches; no \
             firmware is built for the M0).",
            grouped(flash),
            grouped(ram)
        );
    }
    md
}

/// A table header: `first`, then one right-aligned column per backend.
fn backend_header(md: &mut String, first: &str, reports: &[Report]) {
    let _ = write!(md, "| {first} |");
    for r in reports {
        let _ = write!(md, " {} |", r.backend);
    }
    md.push_str("\n| --- |");
    for _ in reports {
        md.push_str(" ---: |");
    }
    md.push('\n');
}

/// Paper 004's filters: instructions per step, then memory and tracking.
fn filters_markdown(md: &mut String, reports: &[Report], samples: u32) {
    let _ = writeln!(
        md,
        "\nPaper 004's nonlinear filters, per call: the EKF (`ExtendedKalmanFilter`), \
         the UKF (`UnscentedKalmanFilter`, `MerweScaledSigmaPoints::paper()`) and the \
         particle filter (`ParticleFilter`, 100 particles, systematic resampling below \
         an effective sample size of 50) on `wmr_papers::slip_tracking::PoseModel` (scenario 1) \
         and `PoseWheelModel` (scenario 2), set up as in `host-tests/src/paper_004.rs`. \
         Paper 004's tracked robot drives an arc at 0.5 m/s and 0.25 rad/s, its whole \
         state measured with deterministic uniform noise of `R`'s variances; a predict \
         (h = 5 ms) then an update each step (the UKF's update reuses the predict's \
         sigma points). Mean over {samples} steps after 2 s (the particle filters \
         converge from `P0` in about 1 s), min–max in parentheses. The fusion \
         estimator's filters (`fusion::{{ekf, ukf, particle}}`: the pose \
         and both wheel scales, wheel noise 3e-5 m²/m) drive the same arc on exact \
         odometry and correct with the true position as a 1 cm fix every step (the \
         tracker corrects only when the tag changes): their RMS error is near 0 by \
         construction, and a gated fix fails the bench.\n"
    );
    backend_header(md, "filter step", reports);
    for (name, label) in FILTERS {
        for step in ["predict", "update"] {
            let _ = write!(md, "| {label}: {step} |");
            for r in reports {
                let _ = write!(md, " {} |", cell(r.stat(&format!("{name}_{step}"))));
            }
            md.push('\n');
        }
    }
    let _ = write!(
        md,
        "\nTheir memory and tracking: state = `size_of` the filter on the target \
         (wherever it is kept: static RAM, or the stack of the function that owns it); \
         stack = one call's peak below its caller's stack pointer; RMS position error \
         over the sampled steps (of the measurements: 0.45 m), and the particle \
         filters' resamplings over the whole run.\n\n| filter | state |"
    );
    for r in reports {
        let _ = write!(md, " stack, predict / update: {} |", r.backend);
    }
    for r in reports {
        let _ = write!(md, " RMS position error: {} |", r.backend);
    }
    md.push_str("\n| --- | ---: |");
    for _ in 0..2 * reports.len() {
        md.push_str(" ---: |");
    }
    md.push('\n');
    let bytes = |b: Option<u64>| b.map_or_else(|| "–".into(), |b| format!("{} B", grouped(b)));
    for (name, label) in FILTERS {
        let state = reports
            .iter()
            .find_map(|r| r.filter(name))
            .map(|f| f.state_bytes);
        let _ = write!(md, "| {label} | {} |", bytes(state));
        for r in reports {
            let _ = write!(
                md,
                " {} / {} |",
                bytes(r.stack(&format!("{name}_predict"))),
                bytes(r.stack(&format!("{name}_update")))
            );
        }
        for r in reports {
            match r.filter(name) {
                Some(f) if f.resamplings > 0 => {
                    let _ = write!(
                        md,
                        " {:.3} m ({} resamplings in {} updates) |",
                        f.position_rms_error_m, f.resamplings, f.steps
                    );
                }
                Some(f) => {
                    let _ = write!(md, " {:.3} m |", f.position_rms_error_m);
                }
                None => md.push_str(" – |"),
            }
        }
        md.push('\n');
    }
}
