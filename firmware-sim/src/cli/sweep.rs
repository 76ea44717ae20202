//! `firmware-sim sweep` and `sweep-merge`: Monte Carlo sweeps, whole or sharded, and the
//! merge of shards.

use super::{load, override_duration};
use std::io::IsTerminal as _;
use std::path::{Path, PathBuf};

use firmware_sim::output::{format_summary, write_all};
use firmware_sim::scenario::{EMBEDDED, Scenario};
use firmware_sim::sweep::output::{
    SweepFiles, format_sweep_summary, markdown_table, scenario_dir, write_sweep,
};
use firmware_sim::sweep::shard::{MANIFEST, Shard, ShardManifest, merge_shards, write_shard};
use firmware_sim::sweep::{
    SweepOptions, SweepSummary, plan_of, run_sweep, run_sweep_shard, run_variation,
};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// The arguments of `sweep`.
#[derive(Debug, clap::Args)]
pub struct SweepArgs {
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
}

impl SweepArgs {
    /// Runs the subcommand.
    pub fn run(self) -> anyhow::Result<()> {
        let Self {
            scenarios,
            runs,
            seed,
            out,
            threads,
            duration_s,
            rerun,
            shard,
            no_plot,
        } = self;
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
}

/// The arguments of `sweep-merge`.
#[derive(Debug, clap::Args)]
pub struct SweepMergeArgs {
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
}

impl SweepMergeArgs {
    /// Runs the subcommand.
    pub fn run(self) -> anyhow::Result<()> {
        let Self { dirs, out, no_plot } = self;
        merge(&dirs, out, !no_plot)
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
