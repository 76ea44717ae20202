//! The files of a slip run: `run.csv`, `summary.json`, `scenario.toml`
//! and the plots.

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::output::{FONT, draw_legend, equal_axes, plot_err};

use super::scenario::SlipScenario;
use super::summary::{SlipRecord, SlipResult};

/// Paths of the files [`write_outputs`] wrote.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SlipFiles {
    /// One row per record.
    pub csv: PathBuf,
    /// The summary, pretty JSON.
    pub summary: PathBuf,
    /// The scenario as run (with any command-line overrides).
    pub scenario: PathBuf,
    /// `errors.png`, `slip.png`, `trajectory.png`, if plotting was asked
    /// for.
    pub plots: Vec<PathBuf>,
}

/// Writes `run.csv`, `summary.json`, `scenario.toml` and (if `plot`)
/// `errors.png`, `slip.png` and `trajectory.png` into `dir`, creating it.
///
/// # Errors
/// Any I/O or rendering error, with the file it concerns.
pub fn write_outputs(
    dir: &Path,
    scenario: &SlipScenario,
    result: &SlipResult,
    plot: bool,
) -> anyhow::Result<SlipFiles> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let files = SlipFiles {
        csv: dir.join("run.csv"),
        summary: dir.join("summary.json"),
        scenario: dir.join("scenario.toml"),
        plots: if plot {
            ["errors.png", "slip.png", "trajectory.png"]
                .iter()
                .map(|f| dir.join(f))
                .collect()
        } else {
            Vec::new()
        },
    };
    let mut w = csv::Writer::from_path(&files.csv)
        .with_context(|| format!("creating {}", files.csv.display()))?;
    for r in &result.records {
        w.serialize(r)
            .with_context(|| format!("writing {}", files.csv.display()))?;
    }
    w.flush()
        .with_context(|| format!("writing {}", files.csv.display()))?;
    let text = serde_json::to_string_pretty(&result.summary)?;
    std::fs::write(&files.summary, text + "\n")
        .with_context(|| format!("writing {}", files.summary.display()))?;
    std::fs::write(&files.scenario, scenario.to_toml_string()?)
        .with_context(|| format!("writing {}", files.scenario.display()))?;
    if let [errors, slip, trajectory] = files.plots.as_slice() {
        let intervals = slip_intervals(scenario);
        plot_errors(errors, result, &intervals)?;
        plot_slip(slip, result, &intervals)?;
        plot_trajectory(trajectory, result)?;
    }
    Ok(files)
}

/// Image size of a time plot, px.
const SIZE: (u32, u32) = (1400, 1000);
/// Shade of the slip intervals.
const SLIP_SHADE: RGBColor = RGBColor(255, 200, 120);

/// `[from, to)` intervals where the slip ratio is above 0, cut at the
/// duration.
fn slip_intervals(scenario: &SlipScenario) -> Vec<(f64, f64)> {
    let end = scenario.duration_s;
    let mut out: Vec<(f64, f64)> = Vec::new();
    for (k, step) in scenario.slip.iter().enumerate() {
        let to = scenario.slip.get(k + 1).map_or(end, |s| s.start_s).min(end);
        if step.slip_ratio > 0.0 && step.start_s < to {
            out.push((step.start_s, to));
        }
    }
    out
}

/// Finite `(lo, hi)` of the values, padded; `(-1, 1)` if none.
fn value_range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if !(lo.is_finite() && hi.is_finite()) {
        return (-1.0, 1.0);
    }
    let pad = 0.05 * (hi - lo).max(1e-3);
    (lo - pad, hi + pad)
}

type Curve<'a> = (&'a str, RGBColor, Vec<(f64, f64)>);

/// One time panel: the curves, the slip intervals shaded.
fn time_panel(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    title: &str,
    y_desc: &str,
    t_end: f64,
    curves: &[Curve<'_>],
    intervals: &[(f64, f64)],
) -> anyhow::Result<()> {
    let (lo, hi) = value_range(curves.iter().flat_map(|c| c.2.iter().map(|p| p.1)));
    let mut chart = ChartBuilder::on(area)
        .caption(title, (FONT, 22))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..t_end, lo..hi)
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .x_desc("t [s]")
        .y_desc(y_desc)
        .label_style((FONT, 15))
        .axis_desc_style((FONT, 17))
        .draw()
        .map_err(plot_err)?;
    if !intervals.is_empty() {
        chart
            .draw_series(
                intervals.iter().map(|&(a, b)| {
                    Rectangle::new([(a, lo), (b, hi)], SLIP_SHADE.mix(0.35).filled())
                }),
            )
            .map_err(plot_err)?
            .label("slip")
            .legend(|(x, y)| Rectangle::new([(x, y - 6), (x + 20, y + 6)], SLIP_SHADE.filled()));
    }
    for (label, color, points) in curves {
        let color = *color;
        chart
            .draw_series(LineSeries::new(
                points
                    .iter()
                    .filter(|p| p.1.is_finite())
                    .map(|&(t, v)| (t, v.clamp(lo, hi))),
                ShapeStyle::from(&color).stroke_width(2),
            ))
            .map_err(plot_err)?
            .label(*label)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
    }
    draw_legend(&mut chart, SeriesLabelPosition::UpperRight, 15)?;
    Ok(())
}

fn t_end(result: &SlipResult) -> f64 {
    result.records.last().map_or(1.0, |r| r.t_s).max(1e-3)
}

fn series(result: &SlipResult, value: impl Fn(&SlipRecord) -> f64) -> Vec<(f64, f64)> {
    result.records.iter().map(|r| (r.t_s, value(r))).collect()
}

/// Label, axis description, colour and value of an error panel.
type ErrorPanel = (&'static str, &'static str, RGBColor, fn(&SlipRecord) -> f64);

/// `e1`, `e2` and `e3` of the true pose against time, one panel each.
fn plot_errors(path: &Path, result: &SlipResult, intervals: &[(f64, f64)]) -> anyhow::Result<()> {
    let root = BitMapBackend::new(path, SIZE).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    let s = &result.summary;
    let root = root
        .titled(
            &format!(
                "{}: tracking errors ({} control, {}, seed {})",
                s.scenario,
                s.controller.name(),
                s.estimator.name(),
                s.seed
            ),
            (FONT, 24),
        )
        .map_err(plot_err)?;
    let panels = root.split_evenly((3, 1));
    let t_end = t_end(result);
    let specs: [ErrorPanel; 3] = [
        ("e1", "e1 [m]", BLUE, |r| r.e1_m),
        ("e2", "e2 [m]", RED, |r| r.e2_m),
        ("e3", "e3 [rad]", GREEN, |r| r.e3_rad),
    ];
    for (area, (label, desc, color, value)) in panels.iter().zip(specs) {
        time_panel(
            area,
            label,
            desc,
            t_end,
            &[(label, color, series(result, value))],
            intervals,
        )?;
    }
    root.present()
        .map_err(plot_err)
        .with_context(|| format!("writing {}", path.display()))
}

/// `p̂` with the true `p`.
fn plot_slip(path: &Path, result: &SlipResult, intervals: &[(f64, f64)]) -> anyhow::Result<()> {
    let root = BitMapBackend::new(path, (SIZE.0, SIZE.1 / 2)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    let s = &result.summary;
    time_panel(
        &root,
        &format!(
            "{}: slip factor estimate ({}, seed {})",
            s.scenario,
            s.estimator.name(),
            s.seed
        ),
        "p = 1/(1 - i)",
        t_end(result),
        &[
            ("true p", BLACK, series(result, |r| r.slip_factor)),
            ("estimate p_hat", BLUE, series(result, |r| r.slip_estimate)),
        ],
        intervals,
    )?;
    root.present()
        .map_err(plot_err)
        .with_context(|| format!("writing {}", path.display()))
}

/// The true and estimated paths against the reference, equal axes.
fn plot_trajectory(path: &Path, result: &SlipResult) -> anyhow::Result<()> {
    let size = (1400_u32, 900_u32);
    let root = BitMapBackend::new(path, size).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    let records = &result.records;
    let (xs, ys) = (
        value_range(records.iter().flat_map(|r| [r.x_m, r.ref_x_m])),
        value_range(records.iter().flat_map(|r| [r.y_m, r.ref_y_m])),
    );
    let (margin, x_label, y_label, caption) = (15_u32, 45_u32, 60_u32, 40_u32);
    let pw = f64::from(size.0 - 2 * margin - y_label);
    let ph = f64::from(size.1 - 2 * margin - x_label - caption);
    let (x_axis, y_axis) = equal_axes(xs, ys, pw, ph);
    let s = &result.summary;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!(
                "{}: trajectory ({} control, {}, seed {})",
                s.scenario,
                s.controller.name(),
                s.estimator.name(),
                s.seed
            ),
            (FONT, 22),
        )
        .margin(margin)
        .x_label_area_size(x_label)
        .y_label_area_size(y_label)
        .build_cartesian_2d(x_axis.clone(), y_axis.clone())
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .x_desc("X [m]")
        .y_desc("Y [m]")
        .label_style((FONT, 15))
        .axis_desc_style((FONT, 17))
        .draw()
        .map_err(plot_err)?;
    let inside = |p: &(f64, f64)| {
        p.0.is_finite()
            && p.1.is_finite()
            && (x_axis.start..=x_axis.end).contains(&p.0)
            && (y_axis.start..=y_axis.end).contains(&p.1)
    };
    let estimate_color = RGBColor(120, 160, 255);
    let xy = |f: fn(&SlipRecord) -> (f64, f64)| records.iter().map(f).collect::<Vec<_>>();
    let curves = [
        (
            "estimate",
            estimate_color,
            1,
            xy(|r| (r.est_x_m, r.est_y_m)),
        ),
        ("reference", RED, 2, xy(|r| (r.ref_x_m, r.ref_y_m))),
        ("robot (true)", BLUE, 2, xy(|r| (r.x_m, r.y_m))),
    ];
    for (label, color, width, points) in curves {
        chart
            .draw_series(LineSeries::new(
                points.into_iter().filter(|p| inside(p)),
                ShapeStyle::from(&color).stroke_width(width),
            ))
            .map_err(plot_err)?
            .label(label)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
    }
    if let Some(first) = records.first() {
        chart
            .draw_series(
                [
                    ((first.x_m, first.y_m), BLUE),
                    ((first.ref_x_m, first.ref_y_m), RED),
                ]
                .into_iter()
                .filter(|(p, _)| inside(p))
                .map(|(p, c)| Circle::new(p, 5, c.filled())),
            )
            .map_err(plot_err)?;
    }
    draw_legend(&mut chart, SeriesLabelPosition::UpperLeft, 15)?;
    root.present()
        .map_err(plot_err)
        .with_context(|| format!("writing {}", path.display()))
}
