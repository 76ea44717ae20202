//! Writing a sweep to disk: `runs.csv`, `summary.json`, `table.md`,
//! `error_hist.png`, `error_vs_distance.png`, and the text the CLI prints.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context as _;
use plotters::coord::Shift;
use plotters::prelude::*;

use super::{Percentiles, SweepResult, SweepRun, SweepSummary};
use crate::output::{FONT, draw_legend, plot_err};

/// Paths of the files [`write_sweep`] wrote.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SweepFiles {
    /// One row per run.
    pub runs_csv: PathBuf,
    /// The summary, pretty JSON.
    pub summary: PathBuf,
    /// The markdown table row of this sweep.
    pub table: PathBuf,
    /// Histograms of the per-run max and mean error, if plotting was asked for.
    pub error_hist: Option<PathBuf>,
    /// Final error vs initial distance, if plotting was asked for.
    pub error_vs_distance: Option<PathBuf>,
}

/// Where a sweep of `count` scenarios writes the files of scenario
/// `name`: `root` itself for one scenario, `root/<name>` for several (with
/// the combined `root/table.md`).
#[must_use]
pub fn scenario_dir(root: &Path, count: usize, name: &str) -> PathBuf {
    if count == 1 {
        root.to_path_buf()
    } else {
        root.join(name)
    }
}

/// Writes the sweep's files into `dir`, creating it.
///
/// # Errors
/// Any I/O or rendering error, with the file it concerns.
pub fn write_sweep(dir: &Path, result: &SweepResult, plot: bool) -> anyhow::Result<SweepFiles> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let files = SweepFiles {
        runs_csv: dir.join("runs.csv"),
        summary: dir.join("summary.json"),
        table: dir.join("table.md"),
        error_hist: plot.then(|| dir.join("error_hist.png")),
        error_vs_distance: plot.then(|| dir.join("error_vs_distance.png")),
    };
    let write = |path: &Path, bytes: &[u8]| {
        std::fs::write(path, bytes).with_context(|| format!("writing {}", path.display()))
    };
    write(&files.runs_csv, &runs_csv(&result.rows)?)?;
    write(
        &files.summary,
        (serde_json::to_string_pretty(&result.summary)? + "\n").as_bytes(),
    )?;
    write(
        &files.table,
        markdown_table(std::slice::from_ref(&result.summary)).as_bytes(),
    )?;
    if let Some(png) = &files.error_hist {
        plot_error_histograms(png, result)?;
    }
    if let Some(png) = &files.error_vs_distance {
        plot_error_vs_distance(png, result)?;
    }
    Ok(files)
}

/// `runs.csv` as bytes: a header and one row per run, in index order (the
/// header alone for no run: a shard of more shards than runs).
///
/// # Errors
/// Serialization errors.
pub fn runs_csv(rows: &[SweepRun]) -> anyhow::Result<Vec<u8>> {
    let mut w = csv::Writer::from_writer(Vec::new());
    for row in rows {
        w.serialize(row)?;
    }
    let bytes = w
        .into_inner()
        .map_err(|e| anyhow::anyhow!("runs.csv: {e}"))?;
    if !rows.is_empty() {
        return Ok(bytes);
    }
    // The writer takes its header from the first row it serializes.
    let with_one = runs_csv(&[SweepRun::default()])?;
    let header_end = with_one
        .iter()
        .position(|&b| b == b'\n')
        .map_or(with_one.len(), |at| at + 1);
    Ok(with_one[..header_end].to_vec())
}

/// A markdown table with one row per sweep: convergence and the
/// percentiles of the per-run max and mean error after each scenario's
/// transient. Sweeps of other estimators or laws add rows.
#[must_use]
pub fn markdown_table(summaries: &[SweepSummary]) -> String {
    let mut o = String::from(
        "| scenario | setup | runs | converged | window | max p50 (m) | max p90 | max p99 | max max | mean p50 (m) | mean p90 | mean p99 | mean max |\n\
         | --- | --- | ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n",
    );
    let p = |p: &Percentiles| {
        [p.p50, p.p90, p.p99, p.max]
            .map(|v| format!("{v:.4}"))
            .join(" | ")
    };
    for s in summaries {
        let _ = writeln!(
            o,
            "| `{}` | {} | {} | {} ({:.1} %) | t ≥ {} s | {} | {} |",
            s.scenario,
            s.setup,
            s.runs,
            s.converged,
            100.0 * s.converged_fraction,
            s.transient_s,
            p(&s.max_error_m),
            p(&s.mean_error_m)
        );
    }
    o
}

/// The sweep's figures as text for a terminal.
#[must_use]
pub fn format_sweep_summary(s: &SweepSummary) -> String {
    let mut o = String::new();
    let plan = &s.plan;
    let _ = writeln!(o, "scenario      {} ({})", s.scenario, s.setup);
    let _ = writeln!(
        o,
        "sweep         {} runs, seed {}, {} s each at h = {} s",
        s.runs, s.seed, s.duration_s, s.period_s
    );
    let _ = writeln!(
        o,
        "varied        start {}–{} m from the reference start, heading {:?}, observer {:?}{}{}{}{}",
        plan.start_radius_m[0],
        plan.start_radius_m[1],
        plan.initial_heading,
        plan.observer_start,
        plan.tag_offset_cell_m
            .map(|c| format!(", tag offset in a {c} m cell"))
            .unwrap_or_default(),
        plan.encoder_counts_per_rev
            .map(|c| format!(", encoder {:?} counts/rev", c.as_slice()))
            .unwrap_or_default(),
        plan.position_noise_std_m
            .map(|r| format!(", noise std {}–{} m", r[0], r[1]))
            .unwrap_or_default(),
        plan.read_miss_probability
            .map(|r| format!(", misses {}–{}", r[0], r[1]))
            .unwrap_or_default(),
    );
    let _ = writeln!(
        o,
        "converged     {}/{} ({:.1} %): error < {} m from t_c on, held ≥ {} s to the end",
        s.converged,
        s.runs,
        100.0 * s.converged_fraction,
        plan.converge_threshold_m,
        plan.converge_hold_s
    );
    if let Some(slow) = &s.slowest {
        let _ = writeln!(
            o,
            "slowest       run {} (seed {}): converged at {:.1} s from {:.2} m",
            slow.index, slow.seed, slow.time_to_converge_s, slow.initial_distance_m
        );
    }
    if !s.not_converged.is_empty() {
        let shown: Vec<String> = s
            .not_converged
            .iter()
            .take(20)
            .map(|r| r.index.to_string())
            .collect();
        let _ = writeln!(
            o,
            "NOT converged {} runs (seed {}): indices {}{}",
            s.not_converged.len(),
            s.seed,
            shown.join(", "),
            if s.not_converged.len() > 20 {
                ", …"
            } else {
                ""
            }
        );
    }
    let line = |name: &str, p: &Percentiles| {
        format!(
            "{name:<13} p50 {:.4}  p90 {:.4}  p99 {:.4}  max {:.4} m\n",
            p.p50, p.p90, p.p99, p.max
        )
    };
    o += &line(&format!("max t≥{}s", s.transient_s), &s.max_error_m);
    o += &line(&format!("mean t≥{}s", s.transient_s), &s.mean_error_m);
    o += &line("final error", &s.final_error_m);
    o += &line("start dist.", &s.initial_distance_m);
    if let Some(r) = &s.route {
        let worst = |w: &Option<crate::sweep::WorstRun>, unit: &str| {
            w.map_or_else(
                || "-".to_owned(),
                |w| format!("{:.4} {unit} (run {})", w.value, w.index),
            )
        };
        let _ = writeln!(
            o,
            "route         done {}/{}, stops missed {}; worst over all stops of all runs: \
             position {}, heading {}; worst cross-track {}; worst time ratio {}",
            r.runs_done,
            s.runs,
            r.stops_missed,
            worst(&r.worst_stop_position_error_m, "m"),
            worst(&r.worst_stop_heading_error_deg, "°"),
            worst(&r.worst_cross_track_error_m, "m"),
            worst(&r.worst_time_ratio, ""),
        );
        o += &line("stop pos.", &r.stop_position_error_m);
        o += &line("cross-track", &r.cross_track_error_m);
    }
    if s.non_finite_runs > 0 {
        let _ = writeln!(
            o,
            "WARNING       {} runs with non-finite values",
            s.non_finite_runs
        );
    }
    o
}

/// Image size, px.
const SIZE: (u32, u32) = (1600, 700);
/// Histogram bins (log-spaced).
const BINS: usize = 40;

/// Histograms of the per-run max error (left) and mean error (right) after
/// the transient, on log-spaced bins, with p50/p90/p99 marked.
///
/// # Errors
/// Rendering or file errors.
pub fn plot_error_histograms(path: &Path, result: &SweepResult) -> anyhow::Result<()> {
    let root = BitMapBackend::new(path, SIZE).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    let (left, right) = root.split_horizontally(SIZE.0 / 2);
    let s = &result.summary;
    histogram_panel(
        &left,
        &format!(
            "{}: max error after {} s, {} runs",
            s.scenario, s.transient_s, s.runs
        ),
        result.rows.iter().map(|r| r.max_error_m),
        &s.max_error_m,
    )?;
    histogram_panel(
        &right,
        &format!("mean error after {} s", s.transient_s),
        result.rows.iter().map(|r| r.mean_error_m),
        &s.mean_error_m,
    )?;
    root.present()
        .map_err(plot_err)
        .with_context(|| format!("writing {}", path.display()))
}

fn histogram_panel(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    title: &str,
    values: impl Iterator<Item = f64>,
    percentiles: &Percentiles,
) -> anyhow::Result<()> {
    let values: Vec<f64> = values.filter(|v| v.is_finite() && *v > 0.0).collect();
    let (mut lo, mut hi) = values
        .iter()
        .fold((f64::INFINITY, 0.0_f64), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        });
    if !lo.is_finite() {
        (lo, hi) = (1e-3, 1.0);
    }
    if hi <= lo * 1.01 {
        (lo, hi) = (lo / 1.5, hi * 1.5);
    }
    // The x axis is log10(error), labelled with the error.
    let (l0, l1) = (lo.log10(), hi.log10());
    let edge = |i: usize| l0 + (l1 - l0) * i as f64 / BINS as f64;
    let mut counts = [0_u32; BINS];
    for v in &values {
        let i = (((v.log10() - l0) / (l1 - l0)) * BINS as f64) as usize;
        counts[i.min(BINS - 1)] += 1;
    }
    let top = f64::from(counts.iter().copied().max().unwrap_or(1).max(1)) * 1.1;
    let area = area.titled(title, (FONT, 22)).map_err(plot_err)?;
    let mut chart = ChartBuilder::on(&area)
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d(l0..l1, 0.0..top)
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .x_desc("error [m] (log)")
        .y_desc("runs")
        .x_labels(8)
        .x_label_formatter(&|v| format!("{:.2e}", 10_f64.powf(*v)))
        .label_style((FONT, 16))
        .axis_desc_style((FONT, 18))
        .draw()
        .map_err(plot_err)?;
    chart
        .draw_series(counts.iter().enumerate().map(|(i, &c)| {
            Rectangle::new(
                [(edge(i), 0.0), (edge(i + 1), f64::from(c))],
                BLUE.mix(0.6).filled(),
            )
        }))
        .map_err(plot_err)?;
    for (name, v, color) in [
        ("p50", percentiles.p50, GREEN),
        ("p90", percentiles.p90, MAGENTA),
        ("p99", percentiles.p99, RED),
    ] {
        if v.is_finite() && v > 0.0 {
            chart
                .draw_series(LineSeries::new(
                    [
                        (v.log10().clamp(l0, l1), 0.0),
                        (v.log10().clamp(l0, l1), top),
                    ],
                    color.stroke_width(2),
                ))
                .map_err(plot_err)?
                .label(format!("{name} {v:.4} m"))
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                });
        }
    }
    draw_legend(&mut chart, SeriesLabelPosition::UpperRight, 16)?;
    Ok(())
}

/// Final error (log) vs initial distance to the reference, converged runs
/// in blue, the others in red, with the convergence threshold.
///
/// # Errors
/// Rendering or file errors.
pub fn plot_error_vs_distance(path: &Path, result: &SweepResult) -> anyhow::Result<()> {
    let s = &result.summary;
    let threshold = s.plan.converge_threshold_m;
    let root = BitMapBackend::new(path, SIZE).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    let area = root
        .titled(
            &format!(
                "{}: final error vs initial distance, {} runs, {} converged",
                s.scenario, s.runs, s.converged
            ),
            (FONT, 22),
        )
        .map_err(plot_err)?;
    let floor = 1e-7;
    let finite = |v: f64| {
        if v.is_finite() {
            v.max(floor)
        } else {
            f64::NAN
        }
    };
    let points: Vec<(f64, f64, bool)> = result
        .rows
        .iter()
        .map(|r| (r.initial_distance_m, finite(r.final_error_m), r.converged))
        .filter(|(d, e, _)| d.is_finite() && e.is_finite())
        .collect();
    let d_max = points.iter().map(|p| p.0).fold(1e-3, f64::max) * 1.05;
    let e_min = points.iter().map(|p| p.1).fold(threshold, f64::min) / 2.0;
    let e_max = points.iter().map(|p| p.1).fold(threshold, f64::max) * 2.0;
    let mut chart = ChartBuilder::on(&area)
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(80)
        .build_cartesian_2d(0.0..d_max, (e_min..e_max).log_scale())
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .x_desc("initial distance to the reference [m]")
        .y_desc("final error [m] (log)")
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .label_style((FONT, 16))
        .axis_desc_style((FONT, 18))
        .draw()
        .map_err(plot_err)?;
    chart
        .draw_series(LineSeries::new(
            [(0.0, threshold), (d_max, threshold)],
            BLACK.stroke_width(1),
        ))
        .map_err(plot_err)?
        .label(format!("convergence threshold {threshold} m"))
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(1)));
    chart
        .draw_series(
            points
                .iter()
                .filter(|p| p.2)
                .map(|&(d, e, _)| Circle::new((d, e), 3, BLUE.mix(0.6).filled())),
        )
        .map_err(plot_err)?
        .label("converged")
        .legend(|(x, y)| Circle::new((x + 10, y), 4, BLUE.filled()));
    chart
        .draw_series(
            points
                .iter()
                .filter(|p| !p.2)
                .map(|&(d, e, _)| Cross::new((d, e), 5, RED.stroke_width(2))),
        )
        .map_err(plot_err)?
        .label("not converged")
        .legend(|(x, y)| Cross::new((x + 10, y), 5, RED.stroke_width(2)));
    draw_legend(&mut chart, SeriesLabelPosition::UpperLeft, 16)?;
    root.present()
        .map_err(plot_err)
        .with_context(|| format!("writing {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A shard of more shards than runs holds no run: its `runs.csv` is the
    /// header alone, the line every other shard's starts with.
    #[test]
    fn an_empty_shard_writes_the_header() {
        let empty = runs_csv(&[]).unwrap();
        let one = runs_csv(&[SweepRun::default()]).unwrap();
        assert_eq!(empty.iter().filter(|&&b| b == b'\n').count(), 1);
        assert!(one.starts_with(&empty));
        assert!(empty.starts_with(b"index,seed,"));
    }
}
