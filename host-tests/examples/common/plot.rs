//! The plotting shared by the figure examples (`#[path]`-included).

use std::path::Path;

use host_tests::paper_002::Series;
use plotters::prelude::*;

const SIZE: (u32, u32) = (900, 560);
const FONT: &str = "sans-serif";
/// Values below this are drawn at it on log axes (below the runs' f32 floors).
const FLOOR: f64 = 1e-12;
const COLOURS: [RGBColor; 4] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
];

/// One plot: `log` draws `|value|` on a log axis, otherwise values as they are.
pub fn plot(
    title: &str,
    series: &[&Series],
    log: bool,
    path: &Path,
) -> Result<(), Box<dyn std::error::Error>> {
    let value = |v: f64| if log { v.abs().max(FLOOR) } else { v };
    let (lo, hi) = series
        .iter()
        .flat_map(|s| s.points.iter().map(|&(_, v)| value(v)))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    let t_end = series
        .iter()
        .filter_map(|s| s.points.last().map(|p| p.0))
        .fold(1.0_f64, f64::max);
    let root = BitMapBackend::new(path, SIZE).into_drawing_area();
    root.fill(&WHITE)?;
    let mut builder = ChartBuilder::on(&root);
    builder
        .caption(title, (FONT, 20))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(80);
    macro_rules! draw {
        ($chart:expr) => {{
            let mut chart = $chart;
            chart
                .configure_mesh()
                .x_desc("t (s)")
                .y_label_formatter(&|v: &f64| {
                    if log {
                        format!("{v:.0e}")
                    } else {
                        format!("{v:.3}")
                    }
                })
                .label_style((FONT, 16))
                .draw()?;
            for (i, s) in series.iter().enumerate() {
                let colour = COLOURS[i % COLOURS.len()];
                chart
                    .draw_series(LineSeries::new(
                        s.points.iter().map(|&(t, v)| (t, value(v))),
                        colour.stroke_width(2),
                    ))?
                    .label(s.label.clone())
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
        }};
    }
    if log {
        draw!(builder.build_cartesian_2d(0.0..t_end, (lo * 0.5..hi * 2.0).log_scale())?);
    } else {
        let pad = 0.05 * (hi - lo).max(1e-9);
        draw!(builder.build_cartesian_2d(0.0..t_end, lo - pad..hi + pad)?);
    }
    root.present()?;
    Ok(())
}
