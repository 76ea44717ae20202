//! `firmware-sim`: run a scenario, list or print the embedded ones.

use std::io::IsTerminal as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use firmware_sim::hil::{HilOptions, LinkFaultSpec, run_hil};
use firmware_sim::output::{format_summary, write_all};
use firmware_sim::scenario::{EMBEDDED, Scenario, embedded_source};
use firmware_sim::slip::{self, Estimator, SlipScenario};
use firmware_sim::sweep::output::{
    SweepFiles, format_sweep_summary, markdown_table, scenario_dir, write_sweep,
};
use firmware_sim::sweep::shard::{MANIFEST, Shard, ShardManifest, merge_shards, write_shard};
use firmware_sim::sweep::{
    SweepOptions, SweepSummary, plan_of, run_sweep, run_sweep_shard, run_variation,
};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// Host simulator of the wmr-core robot controller.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run a scenario and write run.csv, summary.json and run.png.
    Run {
        /// Scenario file (TOML) or the name of an embedded scenario;
        /// default: the embedded `figure_eight_rfid` (paper 001, §6.3.2).
        scenario: Option<String>,
        /// Output directory (default: out/<scenario name>).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Override the scenario's duration, s (a transient that no longer
        /// fits is set to 0).
        #[arg(long)]
        duration_s: Option<f64>,
        /// Override the start of the error statistics window, s.
        #[arg(long)]
        transient_s: Option<f64>,
        /// Do not render run.png.
        #[arg(long)]
        no_plot: bool,
        /// Print the summary as JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Run a diff-drive + RFID-reader scenario with the control tick in the
    /// real firmware under QEMU (lock-step hardware-in-the-loop); writes the
    /// same files as `run`, plus the firmware's defmt log.
    Hil {
        /// Scenario file or embedded name; default:
        /// `figure_eight_rfid_full_stack_fusion_ekf` (the firmware's default
        /// estimator; `figure_eight_rfid_full_stack` runs paper 001's).
        scenario: Option<String>,
        /// Output directory (default: out/<scenario name>-hil).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Firmware ELF (default: build the QEMU-board firmware with cargo).
        #[arg(long)]
        firmware: Option<PathBuf>,
        /// Inject seeded faults on the link during the ticks, both ways:
        /// 1 % of bytes corrupted, 0.5 % of frames each dropped, duplicated
        /// and delayed by a frame, and an outage past the firmware's link
        /// timeout before 0.1 % of ticks (the faulty-link soak). Prints what was
        /// injected against what each side counted.
        #[arg(long, value_name = "SEED")]
        link_faults: Option<u64>,
        /// Override the scenario's duration, s.
        #[arg(long)]
        duration_s: Option<f64>,
        /// Longest wait for any answer of the firmware, s.
        #[arg(long, default_value_t = 10.0)]
        timeout_s: f64,
        /// Do not render run.png.
        #[arg(long)]
        no_plot: bool,
        /// A telemetry record on the firmware's log every N ticks (0:
        /// none); `firmware-sim plot OUT/firmware.log` reads them back.
        /// Default: the scenario's `telemetry.every_ticks` (its robot
        /// file's, when it names one), else 1 (every tick).
        #[arg(long, value_name = "N")]
        telemetry_every: Option<u16>,
        /// Also copy the decoded firmware log (OUT/firmware.log) to FILE.
        #[arg(long, value_name = "FILE")]
        firmware_log: Option<PathBuf>,
    },
    /// Turn a firmware's telemetry log (`firmware-sim hil`'s
    /// OUT/firmware.log, or what `probe-rs run` printed for the Black
    /// Pill) into run.csv, summary.json and run.png. A log has no ground
    /// truth: the plant's columns are empty and no error statistics are
    /// computed; a decimated log gives a decimated run.csv.
    Plot {
        /// The decoded log (text); with `--elf`, the raw defmt bytes.
        log: PathBuf,
        /// Output directory (default: out/<log file stem>-plot).
        #[arg(long)]
        out: Option<PathBuf>,
        /// The firmware ELF: LOG is raw defmt (e.g. OUT/firmware.defmt),
        /// decoded with its format table first.
        #[arg(long)]
        elf: Option<PathBuf>,
        /// Do not render run.png.
        #[arg(long)]
        no_plot: bool,
    },
    /// Monte Carlo sweep: run seeded variations of a scenario (what its
    /// `[sweep]` table names; without one, starts within 10 m of the
    /// reference's start with any heading) in parallel and write runs.csv,
    /// summary.json, table.md, error_hist.png and error_vs_distance.png;
    /// print the markdown table. With several scenarios, each gets
    /// DIR/<name>/ and DIR/table.md has a row per scenario. With
    /// `--shard K/N`, runs only that share of the runs, for `sweep-merge`.
    Sweep {
        /// Scenario files or embedded names (default: `figure_eight_rfid`).
        scenarios: Vec<String>,
        /// Number of runs.
        #[arg(long, default_value_t = 100)]
        runs: u64,
        /// Seed `S`: run `i` draws from ChaCha8 seeded with `S`, stream `i`.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Output directory (default: out/sweep-<scenario name>).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Worker threads (default: one per CPU); results do not depend on it.
        #[arg(long, default_value_t = 0)]
        threads: usize,
        /// Override the scenario's duration, s.
        #[arg(long)]
        duration_s: Option<f64>,
        /// Reproduce run INDEX of the sweep with `--seed`, with the full
        /// output of `run` (run.csv, summary.json, run.png) and its
        /// concrete scenario.toml.
        #[arg(long, value_name = "INDEX")]
        rerun: Option<u64>,
        /// Run only shard K of N, K counted from 0 (0 ≤ K < N, as Slurm's
        /// SLURM_ARRAY_TASK_ID and Kubernetes' JOB_COMPLETION_INDEX): the
        /// run indices ⌊K·runs/N⌋ up to ⌊(K+1)·runs/N⌋ (excluded). Writes
        /// runs.csv and shard.json only (no summary.json, table.md or PNGs:
        /// a shard is not the sweep); `sweep-merge` makes the sweep's files
        /// of all N shards. Default output: out/sweep-<scenario
        /// name>-shard-K-of-N.
        #[arg(long, value_name = "K/N", conflicts_with = "rerun")]
        shard: Option<Shard>,
        /// Do not render the PNGs.
        #[arg(long)]
        no_plot: bool,
    },
    /// Merge the N shards of a sweep (`sweep … --shard K/N`, one directory
    /// each, in any order) into runs.csv, summary.json, table.md and the
    /// PNGs: byte for byte what the unsharded sweep writes. Refuses shards
    /// of different sweeps (scenario, seed, runs, duration, N), missing or
    /// duplicated shards, naming the directory.
    SweepMerge {
        /// The shards' directories (each with its shard.json).
        #[arg(required = true, value_name = "DIR")]
        dirs: Vec<PathBuf>,
        /// Output directory (default: out/sweep-<scenario name>, or
        /// out/sweep with several scenarios, as `sweep`).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Do not render the PNGs.
        #[arg(long)]
        no_plot: bool,
    },
    /// Paper 004's tracked robot under slip: run a slip scenario (embedded
    /// `paper_004_velocity` or `paper_004_torque`, or a file) and write
    /// run.csv, summary.json, scenario.toml, errors.png, slip.png and
    /// trajectory.png.
    Slip {
        /// Slip scenario file (TOML) or embedded name.
        scenario: String,
        /// Override the estimator: exact, ekf, ukf or particle_filter.
        #[arg(long)]
        estimator: Option<Estimator>,
        /// Override the noise seed.
        #[arg(long)]
        seed: Option<u64>,
        /// Override the particle filter's particle count: 100 (the
        /// paper's), 300 or 1000 (`filter.particle_filter.particles`).
        #[arg(long)]
        particles: Option<usize>,
        /// Override the duration, s.
        #[arg(long)]
        duration_s: Option<f64>,
        /// Output directory (default: out/<name>-<estimator>-seed<seed>).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Do not render the PNGs.
        #[arg(long)]
        no_plot: bool,
        /// Print the summary as JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// List the embedded scenarios (the tracking ones, then paper 004's
    /// slip scenarios).
    Scenarios,
    /// Print an embedded scenario's TOML (a template for your own).
    #[command(alias = "scenario-template")]
    Show {
        /// Embedded scenario name (see `scenarios`).
        name: String,
    },
    /// List every key of a scenario file, then of a robot file: when it
    /// applies, its type or allowed values, default, unit and meaning
    /// (generated from the types that parse the files, so it cannot
    /// drift). `--json` prints the scenario's JSON Schema instead, for
    /// editors that check TOML against one (`--json --robot`: the robot
    /// file's).
    Schema {
        /// The JSON Schema (draft 2020-12) instead of the table.
        #[arg(long)]
        json: bool,
        /// With `--json`: the robot file's schema.
        #[arg(long)]
        robot: bool,
    },
    /// Validate a robot file as every simulation of it is validated (the
    /// core's constructors included) and write its flash image, what
    /// `cargo xtask firmware --robot FILE` builds into the Black Pill
    /// firmware.
    RobotImage {
        /// The robot file (TOML).
        robot: PathBuf,
        /// Where to write the image.
        #[arg(long)]
        out: PathBuf,
    },
}

/// Standard output was closed by its reader (`firmware-sim … | head`):
/// not an error, the program ends quietly, as Unix filters do.
#[derive(Debug)]
struct OutputClosed;

impl std::fmt::Display for OutputClosed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("standard output closed")
    }
}

impl std::error::Error for OutputClosed {}

/// Writes to standard output; a closed pipe becomes [`OutputClosed`], any
/// other write error an error of its own.
fn write_stdout(args: std::fmt::Arguments<'_>, newline: bool) -> anyhow::Result<()> {
    use std::io::Write as _;
    let mut stdout = std::io::stdout().lock();
    let written = stdout
        .write_fmt(args)
        .and_then(|()| {
            if newline {
                stdout.write_all(b"\n")
            } else {
                Ok(())
            }
        })
        .and_then(|()| stdout.flush());
    match written {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Err(OutputClosed.into()),
        Err(e) => Err(anyhow::Error::new(e).context("writing to standard output")),
    }
}

/// `print!` that returns [`OutputClosed`] instead of panicking.
macro_rules! out {
    ($($arg:tt)*) => {
        write_stdout(format_args!($($arg)*), false)?
    };
}

/// `println!` that returns [`OutputClosed`] instead of panicking.
macro_rules! outln {
    ($($arg:tt)*) => {
        write_stdout(format_args!($($arg)*), true)?
    };
}

fn main() -> ExitCode {
    match real_main() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if e.is::<OutputClosed>() => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn real_main() -> anyhow::Result<()> {
    match Cli::parse().command {
        Command::Scenarios => {
            for (name, text) in EMBEDDED {
                let s = Scenario::from_toml_str(text)?;
                outln!("{name:<30} {:>6} s  {}", s.duration_s, s.description);
            }
            outln!("\n(first = default; `firmware-sim show NAME` prints one)");
            outln!("\nslip scenarios (paper 004; `firmware-sim slip NAME`):");
            for (name, text) in slip::EMBEDDED_SLIP {
                let s = SlipScenario::from_toml_str(text)?;
                outln!("{name:<30} {:>6} s  {}", s.duration_s, s.description);
            }
            Ok(())
        }
        Command::Schema { json, robot } => {
            use firmware_sim::scenario::keys;
            if json {
                let schema = if robot {
                    keys::robot_schema()
                } else {
                    keys::scenario_schema()
                };
                outln!("{}", serde_json::to_string_pretty(&schema)?);
            } else {
                out!("{}", keys::markdown(&keys::scenario_keys()));
                outln!(
                    "\nRobot file (`robot = \"FILE\"` in a scenario, or its `[robot]` table; \
                     `cargo xtask firmware --robot FILE`):\n"
                );
                out!("{}", keys::markdown(&keys::robot_keys()));
            }
            Ok(())
        }
        Command::RobotImage { robot, out } => {
            use firmware_sim::scenario::robot::{FlashFloor, Robot};
            let image = Robot::from_file(&robot)?.flash_image()?;
            std::fs::write(&out, &image.bytes)
                .map_err(|e| anyhow::anyhow!("writing {}: {e}", out.display()))?;
            let floor = match &image.floor {
                FlashFloor::Grid(g) => format!(
                    "tag grid {} × {} at {} m from ({}, {}) m",
                    g.columns, g.rows, g.spacing_m, g.origin_m[0], g.origin_m[1]
                ),
                FlashFloor::Map(tags) => format!("tag map of {} tags", tags.len()),
            };
            outln!(
                "{}: {} B image ({floor}, telemetry every {} ticks) -> {}",
                robot.display(),
                image.bytes.len(),
                image.telemetry_every_ticks,
                out.display()
            );
            // Read by `cargo xtask firmware --robot`.
            outln!(
                "firmware features: {}",
                firmware_sim::hil::firmware_features(&image.pilot).join(",")
            );
            Ok(())
        }
        Command::Show { name } => {
            let text = embedded_source(&name)
                .or_else(|| slip::embedded_slip_source(&name))
                .ok_or_else(|| {
                    let names: Vec<&str> = EMBEDDED
                        .iter()
                        .chain(slip::EMBEDDED_SLIP)
                        .map(|(n, _)| *n)
                        .collect();
                    anyhow::anyhow!("no embedded scenario `{name}` (have: {})", names.join(", "))
                })?;
            out!("{text}");
            Ok(())
        }
        Command::Hil {
            scenario,
            out,
            firmware,
            duration_s,
            timeout_s,
            link_faults,
            no_plot,
            telemetry_every,
            firmware_log,
        } => {
            let mut scenario = match scenario {
                None => Scenario::embedded("figure_eight_rfid_full_stack_fusion_ekf")?,
                Some(arg) => load(&arg)?,
            };
            if let Some(d) = duration_s {
                scenario.duration_s = d;
                if scenario.transient_s >= d {
                    scenario.transient_s = 0.0;
                }
            }
            anyhow::ensure!(
                timeout_s.is_finite() && timeout_s > 0.0,
                "--timeout-s must be positive"
            );
            let out =
                out.unwrap_or_else(|| PathBuf::from("out").join(format!("{}-hil", scenario.name)));
            std::fs::create_dir_all(&out)?;
            let options = HilOptions {
                firmware,
                log: Some(out.join("firmware.defmt")),
                answer_timeout: std::time::Duration::from_secs_f64(timeout_s),
                faults: link_faults.map(LinkFaultSpec::soak),
                telemetry_every_ticks: match telemetry_every {
                    Some(n) => n,
                    None => firmware_sim::hil::default_telemetry_every_ticks(&scenario)?,
                },
            };
            let bar = progress_bar(&scenario, 0.0)?;
            let run = run_hil(&scenario, &options, |done, _| bar.set_position(done));
            bar.finish_and_clear();
            let run = run?;
            let files = write_all(&out, &run.result, !no_plot)?;
            if let Some(copy) = &firmware_log {
                std::fs::copy(out.join("firmware.log"), copy).map_err(|e| {
                    anyhow::anyhow!("copying the firmware log to {}: {e}", copy.display())
                })?;
            }
            out!("{}", format_summary(&run.result.summary));
            outln!(
                "firmware      {} (log: {})",
                run.firmware.display(),
                firmware_log
                    .as_deref()
                    .unwrap_or(&out.join("firmware.log"))
                    .display()
            );
            outln!(
                "wrote         {}, {}{}",
                files.csv.display(),
                files.summary.display(),
                files
                    .plot
                    .map(|p| format!(", {}", p.display()))
                    .unwrap_or_default()
            );
            Ok(())
        }
        Command::Plot {
            log,
            out,
            elf,
            no_plot,
        } => {
            let text = match &elf {
                Some(elf) => firmware_sim::hil::decode_defmt_log(elf, &log)?,
                None => std::fs::read_to_string(&log)
                    .map_err(|e| anyhow::anyhow!("reading {}: {e}", log.display()))?,
            };
            let run = firmware_sim::telemetry::read_log(&text, &log)?;
            let out = out.unwrap_or_else(|| {
                let stem = log
                    .file_stem()
                    .map_or_else(|| "log".into(), |s| s.to_string_lossy());
                PathBuf::from("out").join(format!("{stem}-plot"))
            });
            let files = firmware_sim::telemetry::write_log_run(&out, &run, !no_plot)?;
            out!(
                "{}",
                firmware_sim::telemetry::format_log_summary(&run.summary)
            );
            outln!(
                "wrote         {}",
                files
                    .iter()
                    .map(|p| p.display().to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            );
            Ok(())
        }
        Command::Sweep {
            scenarios,
            runs,
            seed,
            out,
            threads,
            duration_s,
            rerun,
            shard,
            no_plot,
        } => {
            let mut loaded = Vec::new();
            for arg in if scenarios.is_empty() {
                vec![EMBEDDED[0].0.to_owned()]
            } else {
                scenarios
            } {
                let mut scenario = load(&arg)?;
                if let Some(d) = duration_s {
                    override_duration(&mut scenario, d);
                }
                loaded.push(scenario);
            }
            match rerun {
                Some(index) => {
                    let [scenario] = loaded.as_slice() else {
                        anyhow::bail!("--rerun reproduces a run of one scenario; give exactly one");
                    };
                    let out = out.unwrap_or_else(|| {
                        PathBuf::from("out")
                            .join(format!("sweep-{}-seed{seed}-run{index}", scenario.name))
                    });
                    rerun_one(scenario, seed, index, &out, !no_plot)
                }
                None => {
                    let options = SweepOptions {
                        runs,
                        seed,
                        threads,
                    };
                    match shard {
                        None => sweep_all(&loaded, &options, out, !no_plot),
                        Some(shard) => sweep_shard(&loaded, &options, shard, duration_s, out),
                    }
                }
            }
        }
        Command::SweepMerge { dirs, out, no_plot } => merge(&dirs, out, !no_plot),
        Command::Slip {
            scenario,
            estimator,
            seed,
            particles,
            duration_s,
            out,
            no_plot,
            json,
        } => {
            let mut scenario = SlipScenario::load(&scenario)?;
            if let Some(e) = estimator {
                scenario.estimator = e;
            }
            if let Some(s) = seed {
                scenario.seed = s;
            }
            if let Some(p) = particles {
                scenario.filter.particle_filter.particles = p;
            }
            if let Some(d) = duration_s {
                scenario.duration_s = d;
            }
            scenario.validate()?;
            let out = out.unwrap_or_else(|| {
                PathBuf::from("out").join(format!(
                    "{}-{}-seed{}",
                    scenario.name,
                    scenario.estimator.name(),
                    scenario.seed
                ))
            });
            let result = slip::run(&scenario)?;
            let files = slip::write_outputs(&out, &scenario, &result, !no_plot)?;
            if json {
                outln!("{}", serde_json::to_string_pretty(&result.summary)?);
            } else {
                out!("{}", slip::format_slip_summary(&result.summary));
                outln!(
                    "wrote         {}, {}, {}{}",
                    files.csv.display(),
                    files.summary.display(),
                    files.scenario.display(),
                    files
                        .plots
                        .iter()
                        .map(|p| format!(", {}", p.display()))
                        .collect::<String>()
                );
            }
            Ok(())
        }
        Command::Run {
            scenario,
            out,
            duration_s,
            transient_s,
            no_plot,
            json,
        } => {
            let mut scenario = match scenario {
                None => Scenario::default_scenario(),
                Some(arg) => load(&arg)?,
            };
            if let Some(d) = duration_s {
                scenario.duration_s = d;
                if scenario.transient_s >= d && transient_s.is_none() {
                    eprintln!(
                        "note: transient_s {} s does not fit in {d} s; statistics from t = 0",
                        scenario.transient_s
                    );
                    scenario.transient_s = 0.0;
                }
            }
            if let Some(t) = transient_s {
                scenario.transient_s = t;
            }
            scenario.validate()?;
            let out = out.unwrap_or_else(|| PathBuf::from("out").join(&scenario.name));
            let result = run_with_progress(&scenario)?;
            let files = write_all(&out, &result, !no_plot)?;
            if json {
                outln!("{}", serde_json::to_string_pretty(&result.summary)?);
            } else {
                out!("{}", format_summary(&result.summary));
                outln!(
                    "wrote         {}, {}{}",
                    files.csv.display(),
                    files.summary.display(),
                    files
                        .plot
                        .map(|p| format!(", {}", p.display()))
                        .unwrap_or_default()
                );
            }
            Ok(())
        }
    }
}

/// Sets the duration; a transient that no longer fits is set to 0.
fn override_duration(scenario: &mut Scenario, duration_s: f64) {
    scenario.duration_s = duration_s;
    if scenario.transient_s >= duration_s {
        eprintln!(
            "note: transient_s {} s does not fit in {duration_s} s; statistics from t = 0",
            scenario.transient_s
        );
        scenario.transient_s = 0.0;
    }
}

/// Sweeps each scenario, writes its files, and prints the summaries and
/// the markdown table (also written to table.md).
fn sweep_all(
    scenarios: &[Scenario],
    options: &SweepOptions,
    out: Option<PathBuf>,
    plot: bool,
) -> anyhow::Result<()> {
    let names: Vec<&str> = scenarios.iter().map(|s| s.name.as_str()).collect();
    let root = out.unwrap_or_else(|| default_sweep_dir(&names, ""));
    let mut summaries = Vec::new();
    for scenario in scenarios {
        let dir = scenario_dir(&root, scenarios.len(), &scenario.name);
        let bar = runs_bar(&scenario.name, options.runs)?;
        let wall = std::time::Instant::now();
        let result = run_sweep(scenario, options, &|| bar.inc(1));
        bar.finish_and_clear();
        let result = result?;
        let wall_s = wall.elapsed().as_secs_f64();
        let files = write_sweep(&dir, &result, plot)?;
        out!("{}", format_sweep_summary(&result.summary));
        outln!(
            "wall time     {wall_s:.2} s ({:.3} s per run)",
            wall_s / options.runs.max(1) as f64
        );
        outln!("{}", wrote_sweep(&files));
        summaries.push(result.summary);
    }
    let table = write_table(&root, &summaries)?;
    out!("{table}");
    Ok(())
}

/// `out/sweep-<name><suffix>` for one scenario, `out/sweep<suffix>` for
/// several.
fn default_sweep_dir(names: &[&str], suffix: &str) -> PathBuf {
    PathBuf::from("out").join(match names {
        [name] => format!("sweep-{name}{suffix}"),
        _ => format!("sweep{suffix}"),
    })
}

/// A progress bar of `runs` runs on stderr (hidden when stderr is not a
/// terminal).
fn runs_bar(name: &str, runs: u64) -> anyhow::Result<ProgressBar> {
    Ok(if std::io::stderr().is_terminal() {
        let bar = ProgressBar::with_draw_target(Some(runs), ProgressDrawTarget::stderr());
        bar.set_style(
            ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} runs ({eta})")
                .map_err(|e| anyhow::anyhow!("{e}"))?
                .progress_chars("=> "),
        );
        bar.set_message(name.to_owned());
        bar
    } else {
        ProgressBar::hidden()
    })
}

/// The "wrote" line (and a blank line) of a sweep's files.
fn wrote_sweep(files: &SweepFiles) -> String {
    format!(
        "wrote         {}, {}, {}{}\n",
        files.runs_csv.display(),
        files.summary.display(),
        files.table.display(),
        files
            .error_hist
            .iter()
            .chain(&files.error_vs_distance)
            .map(|p| format!(", {}", p.display()))
            .collect::<String>()
    )
}

/// The markdown table of `summaries`, written to `root/table.md` with
/// several scenarios (each scenario's directory has its own table of one
/// row).
fn write_table(root: &Path, summaries: &[SweepSummary]) -> anyhow::Result<String> {
    let table = markdown_table(summaries);
    if summaries.len() != 1 {
        std::fs::create_dir_all(root)?;
        std::fs::write(root.join("table.md"), &table)?;
    }
    Ok(table)
}

/// Runs shard `shard` of each scenario's sweep and writes the shard's
/// runs.csv files and shard.json (see `firmware_sim::sweep::shard`).
fn sweep_shard(
    scenarios: &[Scenario],
    options: &SweepOptions,
    shard: Shard,
    duration_s: Option<f64>,
    out: Option<PathBuf>,
) -> anyhow::Result<()> {
    for (i, s) in scenarios.iter().enumerate() {
        anyhow::ensure!(
            !scenarios[..i].iter().any(|t| t.name == s.name),
            "two scenarios are named `{}`: a sharded sweep keeps each scenario's runs in \
             DIR/<name>/, so the names must differ",
            s.name
        );
    }
    let names: Vec<&str> = scenarios.iter().map(|s| s.name.as_str()).collect();
    let root = out.unwrap_or_else(|| {
        default_sweep_dir(
            &names,
            &format!("-shard-{}-of-{}", shard.index(), shard.count()),
        )
    });
    let manifest = ShardManifest::new(scenarios, shard, options.runs, options.seed, duration_s)?;
    let indices = shard.indices(options.runs);
    let mut results = Vec::new();
    let mut walls = Vec::new();
    for scenario in scenarios {
        let bar = runs_bar(&scenario.name, indices.end - indices.start)?;
        let wall = std::time::Instant::now();
        let result = run_sweep_shard(scenario, options, shard, &|| bar.inc(1));
        bar.finish_and_clear();
        results.push(result?);
        walls.push(wall.elapsed().as_secs_f64());
    }
    // Written before anything is printed: a reader that stops reading
    // early (`| head`) does not stop the shard being written.
    let files = write_shard(&root, &manifest, &results)?;
    for (result, wall_s) in results.iter().zip(walls) {
        outln!(
            "shard         {shard}: run indices {}..{} of {} (these runs only: merge all {} \
             shards with `firmware-sim sweep-merge`)",
            indices.start,
            indices.end,
            options.runs,
            shard.count()
        );
        out!("{}", format_sweep_summary(&result.summary));
        outln!(
            "wall time     {wall_s:.2} s ({:.3} s per run)\n",
            wall_s / (indices.end - indices.start).max(1) as f64
        );
    }
    outln!(
        "wrote         {}, {}",
        files
            .runs_csv
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", "),
        files.manifest.display()
    );
    Ok(())
}

/// Merges the shards in `dirs` and writes the sweep's files as
/// [`sweep_all`] does, printing the same summaries and table.
fn merge(dirs: &[PathBuf], out: Option<PathBuf>, plot: bool) -> anyhow::Result<()> {
    let merged = merge_shards(dirs)?;
    let names: Vec<&str> = merged
        .results
        .iter()
        .map(|r| r.summary.scenario.as_str())
        .collect();
    let root = out.unwrap_or_else(|| default_sweep_dir(&names, ""));
    anyhow::ensure!(
        !root.join(MANIFEST).exists(),
        "{} holds a {MANIFEST}: it is a shard's directory, and the merged sweep would overwrite \
         or be taken for a shard; merge into another directory (--out)",
        root.display()
    );
    // Every file is written before anything is printed (see
    // `sweep_shard`).
    let count = merged.results.len();
    let mut written = Vec::new();
    for result in merged.results {
        let dir = scenario_dir(&root, count, &result.summary.scenario);
        written.push((write_sweep(&dir, &result, plot)?, result.summary));
    }
    let summaries: Vec<SweepSummary> = written.iter().map(|(_, s)| s.clone()).collect();
    let table = write_table(&root, &summaries)?;
    for (files, summary) in &written {
        out!("{}", format_sweep_summary(summary));
        outln!(
            "merged        {} shards: {}",
            merged.shards.len(),
            merged
                .shards
                .iter()
                .map(|d| d.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        );
        outln!("{}", wrote_sweep(files));
    }
    out!("{table}");
    Ok(())
}

/// Reproduces one run of a sweep with the full output of `run`.
fn rerun_one(
    scenario: &Scenario,
    seed: u64,
    index: u64,
    out: &Path,
    plot: bool,
) -> anyhow::Result<()> {
    let (_, plan) = plan_of(scenario)?;
    let (concrete, result, row) = run_variation(scenario, &plan, seed, index)?;
    let files = write_all(out, &result, plot)?;
    let toml_path = out.join("scenario.toml");
    std::fs::write(&toml_path, concrete.to_toml_string()?)?;
    out!("{}", format_summary(&result.summary));
    outln!(
        "sweep run     index {index}, seed {seed}: start ({:.3}, {:.3}) m, heading {:.4} rad, \
         {:.3} m from the reference; {}",
        row.start_x_m,
        row.start_y_m,
        row.heading_rad,
        row.initial_distance_m,
        match row.time_to_converge_s {
            Some(t) => format!("converged at {t:.2} s"),
            None => format!(
                "NOT converged (error < {} m held ≥ {} s)",
                plan.converge_threshold_m, plan.converge_hold_s
            ),
        }
    );
    outln!(
        "wrote         {}, {}, {}{}",
        files.csv.display(),
        files.summary.display(),
        toml_path.display(),
        files
            .plot
            .map(|p| format!(", {}", p.display()))
            .unwrap_or_default()
    );
    Ok(())
}

/// A scenario file, or an embedded scenario by name.
fn load(arg: &str) -> anyhow::Result<Scenario> {
    let path = PathBuf::from(arg);
    let scenario = if !path.exists() && embedded_source(arg).is_some() {
        Scenario::embedded(arg)?
    } else {
        Scenario::from_file(&path)?
    };
    for warning in scenario.warnings() {
        eprintln!("warning: {arg}: {warning}");
    }
    Ok(scenario)
}

/// Runs with a progress bar on stderr (hidden when stderr is not a
/// terminal, and for runs under 20 000 ticks).
fn run_with_progress(scenario: &Scenario) -> anyhow::Result<firmware_sim::RunResult> {
    let bar = progress_bar(scenario, 20_000.0)?;
    let result = firmware_sim::run(scenario, |done, _| bar.set_position(done));
    bar.finish_and_clear();
    Ok(result?)
}

/// A progress bar on stderr for runs of at least `min_ticks` (hidden when
/// stderr is not a terminal).
fn progress_bar(scenario: &Scenario, min_ticks: f64) -> anyhow::Result<ProgressBar> {
    let ticks = (scenario.duration_s / scenario.period_s).round();
    Ok(if std::io::stderr().is_terminal() && ticks >= min_ticks {
        let bar = ProgressBar::with_draw_target(Some(ticks as u64), ProgressDrawTarget::stderr());
        bar.set_style(
            ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} ticks ({eta})")
                .map_err(|e| anyhow::anyhow!("{e}"))?
                .progress_chars("=> "),
        );
        bar.set_message(scenario.name.clone());
        bar
    } else {
        ProgressBar::hidden()
    })
}
