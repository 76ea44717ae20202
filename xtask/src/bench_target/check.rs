//! The default backend's figures (and the M0 run's) against the budgets of
//! `firmware/budgets.toml`.

use super::benches::BACKENDS;
use super::report::Report;

/// Budget and target names of the M0 run carry this prefix
/// (`m0.robot_tick`).
const M0_PREFIX: &str = "m0.";

/// The default backend's figures against `firmware/budgets.toml`: the
/// table (budgets, then issue 15's targets) and the verdict.
/// A name prefixed `m0.` is the M0 run's figure.
pub(super) fn check_budgets(
    reports: &[Report],
    m0: &Report,
) -> Result<(String, crate::Result), String> {
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
