//! The subcommands of `firmware-sim`, a file each, and what several of
//! them share.

pub mod hil;
pub mod plot;
pub mod robot_image;
pub mod run;
pub mod scenarios;
pub mod schema;
pub mod sitl;
pub mod slip;
pub mod sweep;

use std::io::IsTerminal as _;
use std::path::PathBuf;

use firmware_sim::scenario::{Scenario, embedded_source};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// Sets the duration; a transient that no longer fits is set to 0.
pub fn override_duration(scenario: &mut Scenario, duration_s: f64) {
    scenario.duration_s = duration_s;
    if scenario.transient_s >= duration_s {
        eprintln!(
            "note: transient_s {} s does not fit in {duration_s} s; statistics from t = 0",
            scenario.transient_s
        );
        scenario.transient_s = 0.0;
    }
}

/// A scenario file, or an embedded scenario by name.
pub fn load(arg: &str) -> anyhow::Result<Scenario> {
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
pub fn run_with_progress(scenario: &Scenario) -> anyhow::Result<firmware_sim::RunResult> {
    let bar = progress_bar(scenario, 20_000.0)?;
    let result = firmware_sim::run(scenario, |done, _| bar.set_position(done));
    bar.finish_and_clear();
    Ok(result?)
}

/// A progress bar on stderr for runs of at least `min_ticks` (hidden when
/// stderr is not a terminal).
pub fn progress_bar(scenario: &Scenario, min_ticks: f64) -> anyhow::Result<ProgressBar> {
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
