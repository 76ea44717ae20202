//! `firmware-sim slip`: paper 004's tracked robot under slip.

use std::path::PathBuf;

use firmware_sim::slip::{self, Estimator, SlipScenario};

/// The arguments of `slip`.
#[derive(Debug, clap::Args)]
pub struct SlipArgs {
    /// Slip scenario file (TOML; its keys: `firmware-sim schema --slip`)
    /// or embedded name.
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
}

impl SlipArgs {
    /// Runs the subcommand.
    pub fn run(self) -> anyhow::Result<()> {
        let Self {
            scenario,
            estimator,
            seed,
            particles,
            duration_s,
            out,
            no_plot,
            json,
        } = self;
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
}
