//! `cargo xtask opt-levels`: firmware size and on-target instruction counts
//! for each release opt-level (set through `CARGO_PROFILE_RELEASE_OPT_LEVEL`,
//! which applies to every crate of the build), to choose the profile.
//!
//! Every level rebuilds all dependencies (in `target/xtask`), so this takes
//! a few minutes; it is a measurement to repeat when the profile or the
//! toolchain changes, not a CI check.

use std::fmt::Write as _;

use crate::bench_target::{BACKENDS, Report, run_backend};
use crate::size::{Sizes, build_firmware, bytes_kib};
use crate::target::{grouped, rustc_version, write_report};

/// Where the report is written (relative to the workspace root).
const REPORT: &str = "target/opt-levels.md";

/// The levels compared.
const LEVELS: [&str; 4] = ["3", "2", "s", "z"];

/// The task.
pub fn opt_levels() -> crate::Result {
    let mut rows: Vec<(&str, Sizes, Vec<Report>)> = Vec::new();
    for level in LEVELS {
        let env = [("CARGO_PROFILE_RELEASE_OPT_LEVEL", level)];
        eprintln!("\n==> opt-level {level}: wmr-firmware (board-qemu)");
        let sizes = build_firmware("board-qemu", true, &env, &format!("opt-{level}/firmware"))?;
        let mut reports = Vec::new();
        for (backend, features) in BACKENDS {
            eprintln!("\n==> opt-level {level}: wmr-bench, {backend}");
            reports.push(run_backend(
                backend,
                features,
                &env,
                &format!("opt-{level}/bench-{backend}"),
            )?);
        }
        rows.push((level, sizes, reports));
    }

    let mut md = String::new();
    let _ = writeln!(
        md,
        "Release opt-level for every crate (`CARGO_PROFILE_RELEASE_OPT_LEVEL`; fat \
         LTO, one codegen unit), {}. Firmware: `wmr-firmware`, board-qemu. Tick: mean \
         instructions per call of `wmr-bench` under QEMU `-icount shift=0` (see \
         `cargo xtask bench-target`). Regenerate with `cargo xtask opt-levels`.\n",
        rustc_version()
    );
    md.push_str("| opt-level | flash | static RAM |");
    for (backend, _) in BACKENDS {
        let _ = write!(md, " `Robot::tick`, {backend} | `Pilot::step`, {backend} |");
    }
    let _ = write!(md, " tick stack, {} |", BACKENDS[0].0);
    md.push_str("\n| --- | ---: | ---: |");
    for _ in BACKENDS {
        md.push_str(" ---: | ---: |");
    }
    md.push_str(" ---: |\n");
    for (level, sizes, reports) in &rows {
        let _ = write!(
            md,
            "| `{level}` | {} | {} |",
            bytes_kib(sizes.flash),
            bytes_kib(sizes.ram)
        );
        for r in reports {
            for stage in ["robot_tick", "pilot_step"] {
                let mean = r.stat(stage).map_or(0, |s| s.mean.round().max(0.0) as u64);
                let _ = write!(md, " {} |", grouped(mean));
            }
        }
        let stack = reports.first().map_or(0, |r| r.tick_stack_bytes);
        let _ = writeln!(md, " {} B |", grouped(stack));
    }
    print!("\n{md}");
    let path = write_report(REPORT, &md)?;
    eprintln!("\nwritten to {}", path.display());
    Ok(())
}
