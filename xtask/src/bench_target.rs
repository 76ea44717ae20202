//! `cargo xtask bench-target [--write]`: instructions per call on the
//! target, under QEMU, for each math backend (see
//! `firmware/src/bin/bench/main.rs`).
//!
//! By default it is a report: it prints the tables and writes
//! `target/bench-target.md`, nothing tracked (so `cargo xtask ci` can run
//! it on any checkout). With `--write` it also replaces the generated
//! section of `docs/budgets.md` (between its `bench-target` markers),
//! which is how the published tables are regenerated.

use std::fmt::Write as _;
use std::time::Duration;

use crate::target::{
    Build, grouped, marked_section, qemu, qemu_on, qemu_version, rustc_version, update_marked,
    write_report,
};

/// The math backends: name and the firmware features that select it.
/// `f32` is the default (the core's `f32`-native functions), `libm` every
/// function from the `libm` crate (its `sinf`/`cosf` in software `f64`).
pub const BACKENDS: [(&str, &[&str]); 3] = [
    ("f32", &[]),
    ("libm", &["libm"]),
    ("micromath", &["micromath"]),
];

/// The tracked page holding the published tables (relative to the
/// workspace root), written only with `--write`.
pub const DOCS_PAGE: &str = "docs/budgets.md";
/// Markers of the generated part of [`DOCS_PAGE`].
const DOCS_START: &str = "<!-- bench-target:start -->";
const DOCS_END: &str = "<!-- bench-target:end -->";

/// Where the table is always written (relative to the workspace root;
/// `target/` is not tracked).
pub const REPORT: &str = "target/bench-target.md";

/// A whole run takes well under a second of host time.
const QEMU_TIMEOUT: Duration = Duration::from_secs(120);

/// Stages of the main table: the bench's name and the row label.
const STAGES: [(&str, &str); 10] = [
    (
        "odometry",
        "odometry (2 counter deltas + `OdometryStep::from_counts`)",
    ),
    (
        "heading_observer",
        "heading observer (`HeadingObserver::update`)",
    ),
    (
        "output_feedback",
        "output-feedback law (`TrackingController::output_feedback`)",
    ),
    (
        "wheel_speed_loop",
        "wheel speed loop (`WheelSpeedLoop::update`, one wheel)",
    ),
    ("pilot_step", "`Pilot::step`"),
    (
        "robot_tick",
        "whole tick (`Robot::tick` over the HIL proxies, one RFID frame)",
    ),
    (
        "robot_tick_fusion_fix",
        "whole tick, fusion EKF estimator, tick with a tag fix (one RFID frame; corrections included)",
    ),
    (
        "robot_tick_fusion_dead_reckoned",
        "whole tick, fusion EKF estimator, dead-reckoned tick (no frame)",
    ),
    (
        "robot_tick_fusion_pf_fix",
        "whole tick, fusion particle filter (100 particles; a build with `fusion-particle-filter`), tick with a tag fix (the read tag's cell likelihood)",
    ),
    (
        "robot_tick_fusion_pf_dead_reckoned",
        "whole tick, fusion particle filter (100 particles; a build with `fusion-particle-filter`), dead-reckoned tick (no frame)",
    ),
];

/// Stack lines of the fusion estimator's whole ticks and the row label's
/// estimator.
const FUSION_STACKS: [(&str, &str); 2] = [
    ("robot_tick_fusion", "fusion EKF"),
    (PF_TICK[2], "fusion particle filter"),
];

/// Features every `wmr-bench` build adds to its backend's: the fusion EKF
/// estimator, for the whole-tick rows that run it.
const BENCH_FEATURES: [&str; 1] = ["fusion-ekf"];

/// The fusion particle filter's whole-tick stages and stack, measured by a
/// build of their own (each backend's, with [`PF_FEATURES`]) and reported in
/// that backend's column: compiled into the main build, the particle
/// filter's arm of the estimator would set the frame of every fusion tick
/// (the EKF's then takes 10 KB of stack, not 2.5 KB) and move the other
/// rows, which are what a firmware without it runs.
const PF_TICK: [&str; 3] = [
    "robot_tick_fusion_pf_fix",
    "robot_tick_fusion_pf_dead_reckoned",
    "robot_tick_fusion_pf",
];

/// Features of the particle filter's own build (added to the backend's).
const PF_FEATURES: [&str; 1] = [wmr_core::builds::FUSION_PARTICLE_FILTER.feature];

/// Math backend calls, per call.
const MATH: [(&str, &str); 7] = [
    ("math_sin", "`sin`"),
    ("math_cos", "`cos`"),
    ("math_sincos", "`sincos` (and one `f32` add of the pair)"),
    ("math_atan", "`atan`"),
    ("math_atan2", "`atan2`"),
    ("math_exp", "`exp`"),
    ("math_sqrt", "`sqrt`"),
];

/// Paper 004's filters: the bench's name and the row label. Each has the
/// stages `<name>_predict` and `<name>_update`.
const FILTERS: [(&str, &str); 13] = [
    ("ekf3", "EKF, N = M = 3 (`PoseModel`)"),
    ("ekf5", "EKF, N = M = 5 (`PoseWheelModel`)"),
    ("ukf3", "UKF, N = M = 3 (7 sigma points)"),
    ("ukf5", "UKF, N = M = 5 (11 sigma points)"),
    ("srukf3", "square-root UKF, N = M = 3"),
    ("srukf5", "square-root UKF, N = M = 5"),
    (
        "pf3",
        "particle filter, N = M = 3, 100 particles (prior proposal)",
    ),
    (
        "pf5",
        "particle filter, N = M = 5, 100 particles (prior proposal)",
    ),
    (
        "pf3o",
        "particle filter, N = M = 3, 100 particles (optimal proposal, regularized: the slip scenarios')",
    ),
    (
        "pf5o",
        "particle filter, N = M = 5, 100 particles (optimal proposal, regularized: the slip scenarios')",
    ),
    ("fusion_ekf", "fusion EKF (`PoseEkf`: odometry, 2-D fix)"),
    ("fusion_ukf", "fusion UKF (`PoseUkf`: odometry, 2-D fix)"),
    (
        "fusion_pf",
        "fusion particle filter (`PoseParticleFilter`, 100 particles)",
    ),
];

/// One stage's instruction counts.
#[derive(Debug, Clone, PartialEq)]
pub struct Stat {
    /// Bench name.
    pub name: String,
    /// Mean instructions per call.
    pub mean: f64,
    /// Median, instructions (±1 SysTick count).
    pub median: i64,
    /// Smallest sample, instructions.
    pub min: i64,
    /// Largest sample, instructions.
    pub max: i64,
}

/// One of paper 004's filters, as the bench left it.
#[derive(Debug, Clone, PartialEq)]
pub struct FilterRun {
    /// Bench name (`ekf3`, …).
    pub name: String,
    /// `size_of` the filter on the target, bytes.
    pub state_bytes: u64,
    /// RMS position error over the sampled steps, m.
    pub position_rms_error_m: f64,
    /// Particle-filter resamplings over the whole run.
    pub resamplings: u64,
    /// Steps (predict + update) of the whole run.
    pub steps: u64,
}

/// What one run of `wmr-bench` reported.
#[derive(Debug, Clone, PartialEq)]
pub struct Report {
    /// Math backend the binary was built with.
    pub backend: String,
    /// The QEMU machine it ran on (`netduinoplus2` when the output does not
    /// say).
    pub machine: String,
    /// Samples per stage.
    pub samples: u32,
    /// SysTick counts per instruction found by the calibration.
    pub counts_per_instruction: f64,
    /// The measurement's own instructions (subtracted).
    pub overhead_instructions: f64,
    /// Every `bench` line.
    pub stats: Vec<Stat>,
    /// Peak stack of one tick below its caller's stack pointer, bytes.
    pub tick_stack_bytes: u64,
    /// Peak stack of one call of each other measured stage (paper 004's
    /// filter steps), bytes.
    pub stacks: Vec<(String, u64)>,
    /// Every `filter` line.
    pub filters: Vec<FilterRun>,
    /// Flash and static RAM of the `wmr-bench` ELF, bytes (set by
    /// [`run_backend`], not by the output).
    pub elf_flash_ram: Option<(u64, u64)>,
}

impl Report {
    /// The stage called `name`.
    pub fn stat(&self, name: &str) -> Option<&Stat> {
        self.stats.iter().find(|s| s.name == name)
    }

    /// The stack of the stage called `name` (not the tick's).
    pub fn stack(&self, name: &str) -> Option<u64> {
        self.stacks.iter().find(|s| s.0 == name).map(|s| s.1)
    }

    /// Takes the particle filter's whole-tick stages and stack
    /// ([`PF_TICK`]) from `pf`, the same backend's run built with
    /// [`PF_FEATURES`] (whose other figures are not this build's).
    ///
    /// # Errors
    /// `pf` lacks one of them, or this run already has one.
    pub fn take_pf_tick(&mut self, pf: &Report) -> Result<(), String> {
        let [fix, dead_reckoned, stack] = PF_TICK;
        for name in [fix, dead_reckoned] {
            if self.stat(name).is_some() {
                return Err(format!("the {} build measured {name}", self.backend));
            }
            let stat = pf.stat(name).ok_or_else(|| {
                format!(
                    "the {} particle-filter build measured no {name}",
                    pf.backend
                )
            })?;
            self.stats.push(stat.clone());
        }
        let bytes = pf.stack(stack).ok_or_else(|| {
            format!(
                "the {} particle-filter build reported no stack {stack}",
                pf.backend
            )
        })?;
        self.stacks.push((stack.to_owned(), bytes));
        Ok(())
    }

    /// The filter called `name`.
    pub fn filter(&self, name: &str) -> Option<&FilterRun> {
        self.filters.iter().find(|f| f.name == name)
    }
}

/// `key=value` fields of a line.
fn field<T: std::str::FromStr>(line: &str, key: &str) -> Result<T, String> {
    line.split_whitespace()
        .find_map(|w| w.strip_prefix(key)?.strip_prefix('='))
        .ok_or_else(|| format!("no `{key}=` in `{line}`"))?
        .parse()
        .map_err(|_| format!("bad `{key}=` in `{line}`"))
}

/// Parses the bench's semihosting output.
pub fn parse(output: &str) -> Result<Report, String> {
    let mut report = Report {
        backend: String::new(),
        machine: "netduinoplus2".into(),
        samples: 0,
        counts_per_instruction: 0.0,
        overhead_instructions: 0.0,
        stats: Vec::new(),
        tick_stack_bytes: 0,
        stacks: Vec::new(),
        filters: Vec::new(),
        elf_flash_ram: None,
    };
    let (mut header, mut calibrated, mut stack, mut done) = (false, false, false, false);
    for line in output.lines().map(str::trim) {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("wmr-bench") => {
                report.backend = field(line, "backend")?;
                report.samples = field(line, "samples")?;
                if let Ok(machine) = field::<String>(line, "machine") {
                    report.machine = machine;
                }
                header = true;
            }
            Some("calibration") => {
                report.counts_per_instruction = field(line, "counts_per_instruction")?;
                report.overhead_instructions = field(line, "overhead_instructions")?;
                calibrated = true;
            }
            Some("bench") => {
                let name = words.next().ok_or_else(|| format!("no name in `{line}`"))?;
                report.stats.push(Stat {
                    name: name.to_string(),
                    mean: field(line, "mean")?,
                    median: field(line, "median")?,
                    min: field(line, "min")?,
                    max: field(line, "max")?,
                });
            }
            Some("stack") => {
                let name = words.next().ok_or_else(|| format!("no name in `{line}`"))?;
                let bytes = field(line, "bytes")?;
                if name == "robot_tick" {
                    report.tick_stack_bytes = bytes;
                    stack = true;
                } else {
                    report.stacks.push((name.to_string(), bytes));
                }
            }
            Some("filter") => {
                let name = words.next().ok_or_else(|| format!("no name in `{line}`"))?;
                report.filters.push(FilterRun {
                    name: name.to_string(),
                    state_bytes: field(line, "state_bytes")?,
                    position_rms_error_m: field(line, "position_rms_error_m")?,
                    resamplings: field(line, "resamplings")?,
                    steps: field(line, "steps")?,
                });
            }
            Some("error") => return Err(format!("the bench failed: {line}")),
            Some("done") => done = true,
            _ => {}
        }
    }
    match (header, calibrated, stack, done) {
        (true, true, true, true) => Ok(report),
        _ => Err(format!("incomplete bench output:\n{output}")),
    }
}

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
const M0_MACHINE: &str = "microbit";
/// `-icount shift` on the M0: 64 ns per instruction, 1.024 SysTick counts at
/// 16 MHz (shift 0 would make one count 62 instructions).
const M0_ICOUNT_SHIFT: u32 = 6;
/// Budget and target names of the M0 run carry this prefix
/// (`m0.robot_tick`).
const M0_PREFIX: &str = "m0.";

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

/// The task. `write_docs` (`--write`) also updates the generated section of
/// [`DOCS_PAGE`]; without it nothing tracked is written.
pub fn bench_target(write_docs: bool) -> crate::Result {
    let mut reports = Vec::new();
    for (backend, features) in BACKENDS {
        eprintln!("\n==> wmr-bench, {backend}");
        let mut report = run_backend(backend, features, &[], &format!("bench-{backend}"))?;
        eprintln!("\n==> wmr-bench, {backend}, fusion particle filter");
        let with_pf: Vec<&str> = features.iter().chain(&PF_FEATURES).copied().collect();
        let pf = run_backend(backend, &with_pf, &[], &format!("bench-{backend}-pf"))?;
        report.take_pf_tick(&pf)?;
        reports.push(report);
    }
    eprintln!("\n==> wmr-bench-m0, f32 (Cortex-M0)");
    let m0 = run_m0()?;
    let table = format!("{}\n{}", markdown(&reports), m0_markdown(&m0));
    print!("\n{table}");
    let (budget_table, verdict) = check_budgets(&reports, &m0)?;
    print!("\n{budget_table}");
    let path = write_report(REPORT, &format!("{table}\n{budget_table}"))?;
    eprintln!("\nwritten to {}", path.display());
    if write_docs {
        let page = update_marked(DOCS_PAGE, DOCS_START, DOCS_END, &table)?;
        eprintln!(
            "{} updated between {DOCS_START} and {DOCS_END}",
            page.display()
        );
    } else if marked_section(DOCS_PAGE, DOCS_START, DOCS_END).is_some_and(|t| t != table) {
        eprintln!(
            "{DOCS_PAGE}'s tables differ from this run (not written: \
             `cargo xtask bench-target --write` updates them)"
        );
    }
    verdict
}

/// The default backend's figures against `firmware/budgets.toml`: the
/// table (budgets, then issue 15's targets) and the verdict.
/// A name prefixed `m0.` is the M0 run's figure.
fn check_budgets(reports: &[Report], m0: &Report) -> Result<(String, crate::Result), String> {
    let budgets = crate::budgets::Budgets::load()?;
    let default = reports
        .iter()
        .find(|r| r.backend == BACKENDS[0].0)
        .ok_or("no run of the default backend")?;
    let run = |name: &str| match name.strip_prefix(M0_PREFIX) {
        Some(name) => (m0, name.to_owned()),
        None => (default, name.to_owned()),
    };
    let mean = |name: &str| {
        let (report, name) = run(name);
        report.stat(&name).map(|s| s.mean)
    };
    let mut verdicts = budgets.check("instructions", &budgets.instructions, mean)?;
    verdicts.extend(budgets.check("stack_bytes", &budgets.stack_bytes, |name| {
        let (report, name) = run(name);
        if name == "robot_tick" {
            Some(report.tick_stack_bytes as f64)
        } else {
            report.stack(&name).map(|b| b as f64)
        }
    })?);
    let (md, verdict) = crate::budgets::report(&verdicts, budgets.tolerance);
    let md = format!(
        "Budgets (`{}`, backend {}, tolerance {:.0} %):\n\n{md}\nIssue 15's targets (not enforced):\n\n{}",
        crate::budgets::FILE,
        default.backend,
        budgets.tolerance * 100.0,
        budgets.targets_report(mean)
    );
    Ok((md, verdict))
}

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
         paper 004's filters are not run (their states and stacks do not fit \
         beside the bench in 16 KiB of RAM).\n",
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

#[cfg(test)]
mod tests {
    use super::*;

    const OUTPUT: &str = "\
wmr-bench backend=libm samples=200
calibration counts_per_instruction=0.16800 loop_counts_per_iteration=0.33601 nop_counts_per_instruction=0.1683 overhead_instructions=2.0
bench odometry mean=73.7 median=75 min=69 max=75 n=200
bench robot_tick mean=10227.0 median=9266 min=9052 max=11432 n=200
bench pf3_predict mean=936441.6 median=936579 min=933347 max=938829 n=200
bench pf3_update mean=277137.9 median=276744 min=274988 max=283708 n=200
stack pf3_predict bytes=328
stack pf3_update bytes=352
filter pf3 state_bytes=2928 position_rms_error_m=0.0428 faults=0 repairs=0 resamplings=61 steps=601
stack robot_tick bytes=776
check frames_ok=230 unknown_tags=0 encoder_errors=0 mode=tracking
done
";

    #[test]
    fn parses_the_bench_output() {
        let r = parse(OUTPUT).unwrap();
        assert_eq!(r.backend, "libm");
        assert_eq!(r.samples, 200);
        assert_eq!(r.tick_stack_bytes, 776);
        let tick = r.stat("robot_tick").unwrap();
        assert_eq!((tick.min, tick.max), (9052, 11432));
        assert!((tick.mean - 10227.0).abs() < 1e-9);
        let md = markdown(&[r]);
        assert!(md.contains("| 10 227 (9 052–11 432) |"), "{md}");
        assert!(md.contains("| 776 B |"), "{md}");
    }

    #[test]
    fn reports_the_filters() {
        let r = parse(OUTPUT).unwrap();
        assert_eq!(r.stack("pf3_update"), Some(352));
        assert_eq!(r.filter("pf3").map(|f| f.state_bytes), Some(2928));
        let md = markdown(&[r]);
        assert!(
            md.contains(
                "| particle filter, N = M = 3, 100 particles (prior proposal): predict | 936 442 (933 347–938 829) |"
            ),
            "{md}"
        );
        assert!(
            md.contains("| particle filter, N = M = 3, 100 particles (prior proposal) | 2 928 B | 328 B / 352 B | 0.043 m (61 resamplings in 601 updates) |"),
            "{md}"
        );
        assert!(
            md.contains("| EKF, N = M = 3 (`PoseModel`): update | – |"),
            "{md}"
        );
    }

    /// The particle filter's own build gives its whole-tick rows and stack
    /// to its backend's column, nothing else; a build lacking them, or a
    /// main build that measured them itself, is an error.
    #[test]
    fn the_particle_filter_build_gives_its_tick_rows() {
        let pf_output = OUTPUT.replace(
            "stack robot_tick bytes=776\n",
            "stack robot_tick bytes=9999\n\
             bench robot_tick_fusion_pf_fix mean=268219.0 median=268000 min=248820 max=359407 n=100\n\
             bench robot_tick_fusion_pf_dead_reckoned mean=159212.0 median=159200 min=157673 max=159804 n=100\n\
             stack robot_tick_fusion_pf bytes=15296\n",
        );
        let pf = parse(&pf_output).unwrap();
        let mut r = parse(OUTPUT).unwrap();
        r.take_pf_tick(&pf).unwrap();
        assert_eq!(r.stack("robot_tick_fusion_pf"), Some(15296));
        assert_eq!(r.tick_stack_bytes, 776, "the main build's own tick");
        assert_eq!(
            r.stat("robot_tick_fusion_pf_fix").map(|s| s.max),
            Some(359_407)
        );
        let md = markdown(&[r.clone()]);
        assert!(
            md.contains(
                "tick with a tag fix (the read tag's cell likelihood) | 268 219 (248 820–359 407) |"
            ),
            "{md}"
        );
        assert!(md.contains("| tick peak stack, fusion particle filter estimator (below the caller's SP) | 15 296 B |"), "{md}");
        assert!(r.take_pf_tick(&pf).is_err(), "measured twice");
        assert!(
            parse(OUTPUT)
                .unwrap()
                .take_pf_tick(&parse(OUTPUT).unwrap())
                .is_err()
        );
    }

    #[test]
    fn the_docs_page_has_the_markers() {
        // `--write` fails without them; find out here, not after a bench run.
        assert!(marked_section(DOCS_PAGE, DOCS_START, DOCS_END).is_some());
    }

    #[test]
    fn refuses_incomplete_or_failed_runs() {
        assert!(parse(&OUTPUT.replace("done\n", "")).is_err());
        assert!(parse("wmr-bench backend=libm samples=1\nerror SysTick\n").is_err());
    }
}
