//! `cargo xtask bench-target [--write]`: instructions per call on the
//! target, under QEMU, for each math backend (see
//! `firmware/src/bin/bench/main.rs`).
//!
//! By default it is a report: it prints the tables and writes
//! `target/bench-target.md`, nothing tracked (so `cargo xtask ci` can run
//! it on any checkout). With `--write` it also replaces the generated
//! section of `docs/budgets.md` (between its `bench-target` markers),
//! which is how the published tables are regenerated.
//!
//! # Files
//! By job, each using only those above it:
//! * `benches`: what is measured: the math backends ([`BACKENDS`]), each
//!   table's bench names and row labels, and the particle filter's own
//!   build;
//! * `report`: what one run reported ([`Report`]) and the parsing of the
//!   bench's output ([`parse`](report::parse));
//! * `run`: building `wmr-bench` (and `wmr-bench-m0`) and running it under
//!   QEMU ([`run_backend`], [`run_m0`]);
//! * `markdown`: the report's tables ([`markdown()`], [`m0_markdown`]);
//! * `check`: the default backend's figures against the budgets;
//! * this file: the task ([`bench_target`]): every run, the report, the
//!   docs page.

use crate::target::{marked_section, update_marked, write_report};

mod benches;
mod check;
mod markdown;
mod report;
mod run;

#[cfg(test)]
mod tests;

pub use benches::BACKENDS;
use benches::{PF_FEATURES, ROUTE_FEATURES};
use check::check_budgets;
pub use markdown::{m0_markdown, markdown};
pub use report::Report;
pub use run::{M0_TARGET, run_backend, run_m0};

/// The tracked page holding the published tables (relative to the
/// workspace root), written only with `--write`.
pub const DOCS_PAGE: &str = "docs/budgets.md";
/// Markers of the generated part of [`DOCS_PAGE`].
const DOCS_START: &str = "<!-- bench-target:start -->";
const DOCS_END: &str = "<!-- bench-target:end -->";

/// Where the table is always written (relative to the workspace root;
/// `target/` is not tracked).
pub const REPORT: &str = "target/bench-target.md";

/// The task. `write_docs` (`--write`) also updates the generated section of
/// [`DOCS_PAGE`]; without it nothing tracked is written.
pub fn bench_target(write_docs: bool) -> crate::Result {
    let mut reports = Vec::new();
    for (backend, features) in BACKENDS {
        eprintln!("\n==> wmr-bench, {backend}");
        let mut report = run_backend(backend, features, &[], &format!("bench-{backend}"))?;
        eprintln!("\n==> wmr-bench, {backend}, fusion particle filter");
        let with_pf: Vec<&str> = features.iter().chain(&PF_FEATURES).copied().collect();
        let pf = run_backend(backend, &with_pf, &[], &format!("bench-{backend}-pf"))?;
        report.take_pf_tick(&pf)?;
        eprintln!("\n==> wmr-bench, {backend}, route tick");
        let with_route: Vec<&str> = features.iter().chain(&ROUTE_FEATURES).copied().collect();
        let route = run_backend(backend, &with_route, &[], &format!("bench-{backend}-route"))?;
        report.take_route_tick(&route)?;
        reports.push(report);
    }
    eprintln!("\n==> wmr-bench-m0, f32 (Cortex-M0)");
    let m0 = run_m0()?;
    let table = format!("{}\n{}", markdown(&reports), m0_markdown(&m0));
    print!("\n{table}");
    let (budget_table, verdict) = check_budgets(&reports, &m0)?;
    print!("\n{budget_table}");
    let path = write_report(REPORT, &format!("{table}\n{budget_table}"))?;
    eprintln!("\nwritten to {}", path.display());
    if write_docs {
        let page = update_marked(DOCS_PAGE, DOCS_START, DOCS_END, &table)?;
        eprintln!(
            "{} updated between {DOCS_START} and {DOCS_END}",
            page.display()
        );
    } else if marked_section(DOCS_PAGE, DOCS_START, DOCS_END).is_some_and(|t| t != table) {
        eprintln!(
            "{DOCS_PAGE}'s tables differ from this run (not written: \
             `cargo xtask bench-target --write` updates them)"
        );
    }
    verdict
}
