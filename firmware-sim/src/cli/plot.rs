//! `firmware-sim plot`: a firmware telemetry log back into a run's files.

use std::path::PathBuf;

/// The arguments of `plot`.
#[derive(Debug, clap::Args)]
pub struct PlotArgs {
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
}

impl PlotArgs {
    /// Runs the subcommand.
    pub fn run(self) -> anyhow::Result<()> {
        let Self {
            log,
            out,
            elf,
            no_plot,
        } = self;
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
}
