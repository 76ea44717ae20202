//! `firmware-sim`: run a scenario, list or print the embedded ones.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

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
#[macro_export]
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::write_stdout(format_args!($($arg)*), false)?
    };
}

/// `println!` that returns [`OutputClosed`] instead of panicking.
#[macro_export]
macro_rules! outln {
    ($($arg:tt)*) => {
        $crate::write_stdout(format_args!($($arg)*), true)?
    };
}

mod cli;

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
    Run(cli::run::RunArgs),
    /// Run a diff-drive + RFID-reader scenario with the control tick in the
    /// real firmware under QEMU (lock-step hardware-in-the-loop); writes the
    /// same files as `run`, plus the firmware's defmt log.
    Hil(cli::hil::HilArgs),
    /// Turn a firmware's telemetry log (`firmware-sim hil`'s
    /// OUT/firmware.log, or what `probe-rs run` printed for the Black
    /// Pill) into run.csv, summary.json and run.png. A log has no ground
    /// truth: the plant's columns are empty and no error statistics are
    /// computed; a decimated log gives a decimated run.csv.
    Plot(cli::plot::PlotArgs),
    /// Monte Carlo sweep: run seeded variations of a scenario (what its
    /// `[sweep]` table names; without one, starts within 10 m of the
    /// reference's start with any heading) in parallel and write runs.csv,
    /// summary.json, table.md, error_hist.png and error_vs_distance.png;
    /// print the markdown table. With several scenarios, each gets
    /// DIR/<name>/ and DIR/table.md has a row per scenario. With
    /// `--shard K/N`, runs only that share of the runs, for `sweep-merge`.
    Sweep(cli::sweep::SweepArgs),
    /// Merge the N shards of a sweep (`sweep … --shard K/N`, one directory
    /// each, in any order) into runs.csv, summary.json, table.md and the
    /// PNGs: byte for byte what the unsharded sweep writes. Refuses shards
    /// of different sweeps (scenario, seed, runs, duration, N), missing or
    /// duplicated shards, naming the directory.
    SweepMerge(cli::sweep::SweepMergeArgs),
    /// Paper 004's tracked robot under slip: run a slip scenario (embedded
    /// `paper_004_velocity` or `paper_004_torque`, or a file) and write
    /// run.csv, summary.json, scenario.toml, errors.png, slip.png and
    /// trajectory.png. The file's keys: `firmware-sim schema --slip`.
    Slip(cli::slip::SlipArgs),
    /// The simulated robot (a route scenario or a robot file with a route:
    /// the same plant, devices and core as `run`) in real time, or
    /// `--speedup N` times faster, behind the robot's MAVLink endpoint on
    /// UDP, for QGroundControl, MAVProxy or pymavlink (docs/mavlink.md,
    /// "The SITL"). Starts disarmed, idle, with no mission.
    Sitl(cli::sitl::SitlArgs),
    /// List the embedded scenarios (the tracking ones, then paper 004's
    /// slip scenarios).
    Scenarios,
    /// Print an embedded scenario's TOML (a template for your own).
    #[command(alias = "scenario-template")]
    Show(cli::scenarios::ShowArgs),
    /// List every key of a scenario file, then of a robot file: when it
    /// applies, its type or allowed values, default, unit and meaning
    /// (generated from the types that parse the files, so it cannot
    /// drift). `--robot`: the robot file's keys only; `--slip`: the slip
    /// scenario file's (`firmware-sim slip FILE`). `--json` prints the
    /// file's JSON Schema instead, for editors that check TOML against one.
    Schema(cli::schema::SchemaArgs),
    /// Validate a robot file as every simulation of it is validated (the
    /// core's constructors included) and write its flash image, what
    /// `cargo xtask firmware --robot FILE` builds into the Black Pill
    /// firmware.
    RobotImage(cli::robot_image::RobotImageArgs),
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
        Command::Run(args) => args.run(),
        Command::Hil(args) => args.run(),
        Command::Plot(args) => args.run(),
        Command::Sweep(args) => args.run(),
        Command::SweepMerge(args) => args.run(),
        Command::Slip(args) => args.run(),
        Command::Sitl(args) => args.run(),
        Command::Scenarios => cli::scenarios::scenarios(),
        Command::Show(args) => args.run(),
        Command::Schema(args) => args.run(),
        Command::RobotImage(args) => args.run(),
    }
}
