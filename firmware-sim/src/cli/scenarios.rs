//! `firmware-sim scenarios` and `show`: the embedded scenarios.

use firmware_sim::scenario::{EMBEDDED, Scenario, embedded_source};
use firmware_sim::slip::{self, SlipScenario};

/// `scenarios`: lists the embedded scenarios, the tracking ones, then paper
/// 004's slip scenarios.
pub fn scenarios() -> anyhow::Result<()> {
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

/// The arguments of `show`.
#[derive(Debug, clap::Args)]
pub struct ShowArgs {
    /// Embedded scenario name (see `scenarios`).
    name: String,
}

impl ShowArgs {
    /// Runs the subcommand.
    pub fn run(self) -> anyhow::Result<()> {
        let Self { name } = self;
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
}
