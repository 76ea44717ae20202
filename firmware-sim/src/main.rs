//! `firmware-sim`: run a scenario, list or print the embedded ones.

use std::io::IsTerminal as _;
use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use firmware_sim::output::{format_summary, write_all};
use firmware_sim::scenario::{EMBEDDED, Scenario, embedded_source};
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
    /// List the embedded scenarios.
    Scenarios,
    /// Print an embedded scenario's TOML (a template for your own).
    #[command(alias = "scenario-template")]
    Show {
        /// Embedded scenario name (see `scenarios`).
        name: String,
    },
}

fn main() -> ExitCode {
    match real_main() {
        Ok(()) => ExitCode::SUCCESS,
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
                println!("{name:<30} {:>6} s  {}", s.duration_s, s.description);
            }
            println!("\n(first = default; `firmware-sim show NAME` prints one)");
            Ok(())
        }
        Command::Show { name } => {
            let text = embedded_source(&name).ok_or_else(|| {
                let names: Vec<&str> = EMBEDDED.iter().map(|(n, _)| *n).collect();
                anyhow::anyhow!("no embedded scenario `{name}` (have: {})", names.join(", "))
            })?;
            print!("{text}");
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
                Some(arg) => {
                    let path = PathBuf::from(&arg);
                    if !path.exists() && embedded_source(&arg).is_some() {
                        Scenario::embedded(&arg)?
                    } else {
                        Scenario::from_file(&path)?
                    }
                }
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
                println!("{}", serde_json::to_string_pretty(&result.summary)?);
            } else {
                print!("{}", format_summary(&result.summary));
                println!(
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

/// Runs with a progress bar on stderr (hidden when stderr is not a
/// terminal, and for runs under 20 000 ticks).
fn run_with_progress(scenario: &Scenario) -> anyhow::Result<firmware_sim::RunResult> {
    let ticks = (scenario.duration_s / scenario.period_s).round();
    let bar = if std::io::stderr().is_terminal() && ticks >= 20_000.0 {
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
    };
    let result = firmware_sim::run(scenario, |done, _| bar.set_position(done));
    bar.finish_and_clear();
    Ok(result?)
}
