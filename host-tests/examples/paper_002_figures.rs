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

use std::path::{Path, PathBuf};

use host_tests::paper_002::{Figure, chained, unicycle};
use plotters::prelude::*;

const SIZE: (u32, u32) = (900, 560);
const FONT: &str = "sans-serif";
/// Values below this are drawn at it (f32 resolution floor of the runs).
const FLOOR: f64 = 1e-12;
const COLOURS: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
    RGBColor(23, 190, 207),
];

fn plot(figure: &Figure, path: &Path) -> Result<(), Box<dyn std::error::Error>> {
    let values = figure
        .series
        .iter()
        .flat_map(|s| s.points.iter().map(|&(_, v)| v.abs().max(FLOOR)));
    let (lo, hi) = values.fold((f64::INFINITY, 0.0_f64), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    let (lo, hi) = if lo.is_finite() && hi > 0.0 {
        (lo * 0.5, hi * 2.0)
    } else {
        (FLOOR, 1.0)
    };
    let t_end = figure
        .series
        .iter()
        .filter_map(|s| s.points.last().map(|p| p.0))
        .fold(1.0_f64, f64::max);
    let root = BitMapBackend::new(path, SIZE).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(&figure.title, (FONT, 20))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(80)
        .build_cartesian_2d(0.0..t_end, (lo..hi).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("t (s)")
        .y_desc("|error|")
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .label_style((FONT, 16))
        .draw()?;
    for (i, series) in figure.series.iter().enumerate() {
        let colour = COLOURS[i % COLOURS.len()];
        chart
            .draw_series(LineSeries::new(
                series.points.iter().map(|&(t, v)| (t, v.abs().max(FLOOR))),
                colour.stroke_width(2),
            ))?
            .label(series.label.clone())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
            });
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font((FONT, 15))
        .draw()?;
    root.present()?;
    Ok(())
}

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
        plot(figure, &path).map_err(|e| format!("{}: {e}", path.display()))?;
        eprintln!("wrote {}", path.display());
    }
    println!(
        "Figure-eight (paper 001 §6.3.2), nearest 10 cm tag every tick, 480 s, h = 10 ms; \
         position error after 100 s:\n\n{}",
        unicycle::comparison_markdown()
    );
    Ok(())
}
