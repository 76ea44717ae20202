//! `firmware-sim run`: one scenario, its run.csv, summary.json and run.png.

use super::{load, run_with_progress};
use std::path::PathBuf;

use firmware_sim::output::{format_summary, write_all};
use firmware_sim::scenario::Scenario;

/// The arguments of `run`.
#[derive(Debug, clap::Args)]
pub struct RunArgs {
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
}

impl RunArgs {
    /// Runs the subcommand.
    pub fn run(self) -> anyhow::Result<()> {
        let Self {
            scenario,
            out,
            duration_s,
            transient_s,
            no_plot,
            json,
        } = self;
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
