//! Regenerates the semilog plots of paper 002's simulations (PNG, one per
//! figure of the paper, plus the position-only comparison on paper 001's
//! figure-eight) and prints the comparison table:
//!
//! ```sh
//! cargo run --release -p host-tests --example paper_002_figures -- [OUT_DIR]
//! ```
//!
//! `OUT_DIR` defaults to `out/paper_002`. The data come from
//! `host_tests::paper_002`, the same simulations the tests assert on.

use std::path::PathBuf;

use host_tests::paper_002::{Figure, chained, comparison, unicycle};

#[path = "common/plot.rs"]
mod common;
use common::plot;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out: PathBuf = std::env::args_os()
        .nth(1)
        .map_or_else(|| PathBuf::from("out/paper_002"), PathBuf::from);
    std::fs::create_dir_all(&out)?;
    let figures: Vec<Figure> = chained::figures()
        .into_iter()
        .chain(unicycle::figures())
        .collect();
    for figure in &figures {
        let path = out.join(format!("{}.png", figure.name));
        plot(
            &figure.title,
            &figure.series.iter().collect::<Vec<_>>(),
            true,
            &path,
        )
        .map_err(|e| format!("{}: {e}", path.display()))?;
        eprintln!("wrote {}", path.display());
    }
    println!(
        "Figure-eight (paper 001 §6.3.2), nearest 10 cm tag every tick, 480 s, h = 10 ms; \
         position error after 100 s:\n\n{}",
        comparison::comparison_markdown()
    );
    Ok(())
}
