//! Writing a run to disk: `run.csv`, `summary.json`, `run.png`, and the
//! human-readable summary the CLI prints.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context as _;
use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use crate::report::{Record, RunResult, Summary};

/// Paths of the files [`write_all`] wrote.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct OutputFiles {
    /// One row per tick.
    pub csv: PathBuf,
    /// The summary, pretty JSON.
    pub summary: PathBuf,
    /// Trajectory and error plot, if plotting was asked for.
    pub plot: Option<PathBuf>,
}

/// Writes `run.csv`, `summary.json` and (if `plot`) `run.png` into `dir`,
/// creating it.
///
/// # Errors
/// Any I/O or rendering error, with the file it concerns.
pub fn write_all(dir: &Path, result: &RunResult, plot: bool) -> anyhow::Result<OutputFiles> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let files = OutputFiles {
        csv: dir.join("run.csv"),
        summary: dir.join("summary.json"),
        plot: plot.then(|| dir.join("run.png")),
    };
    write_csv(&files.csv, &result.records)?;
    write_summary(&files.summary, &result.summary)?;
    if let Some(png) = &files.plot {
        plot_png(png, result)?;
    }
    Ok(files)
}

/// Writes the records as CSV with a header row (empty cells for values a
/// run does not have, e.g. duties on the unicycle).
///
/// # Errors
/// I/O or serialization errors.
pub fn write_csv(path: &Path, records: &[Record]) -> anyhow::Result<()> {
    let mut w =
        csv::Writer::from_path(path).with_context(|| format!("creating {}", path.display()))?;
    for r in records {
        w.serialize(r)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    w.flush()
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// Writes the summary as pretty JSON.
///
/// # Errors
/// I/O or serialization errors.
pub fn write_summary(path: &Path, summary: &Summary) -> anyhow::Result<()> {
    let text = serde_json::to_string_pretty(summary)?;
    std::fs::write(path, text + "\n").with_context(|| format!("writing {}", path.display()))
}

/// A route run's lines of the summary (ground truth).
fn format_route(o: &mut String, r: &crate::report::RouteReport) {
    let opt = |v: Option<f64>, digits: usize| {
        v.map_or_else(|| "-".to_owned(), |v| format!("{v:.digits$}"))
    };
    let _ = writeln!(
        o,
        "route         {} (start {}): planned {:.2} s, taken {} s (ratio {}){}",
        if r.done { "done" } else { "NOT DONE" },
        r.start,
        r.planned_duration_s,
        opt(r.time_taken_s, 2),
        opt(r.time_ratio, 4),
        r.refused
            .as_ref()
            .map(|e| format!("; REFUSED: {e}"))
            .unwrap_or_default()
    );
    for stop in &r.stops {
        let _ = writeln!(
            o,
            "  stop {:<7} ({:.3}, {:.3}) m: true error {} m{}",
            format!("#{}", stop.waypoint),
            stop.x_m,
            stop.y_m,
            opt(stop.position_error_m, 4),
            stop.heading_error_deg
                .map(|h| format!(", heading {h:.3}°"))
                .unwrap_or_default()
        );
    }
    let _ = writeln!(
        o,
        "cross-track   max {} m  rms {} m over {} moving ticks (true distance from the planned path)",
        opt(r.max_cross_track_error_m, 4),
        opt(r.rms_cross_track_error_m, 4),
        r.moving_ticks
    );
    let c = &r.counters;
    let _ = writeln!(
        o,
        "route counts  stops reached {}  stop errors {}  pivots {}  open-loop pivot ticks {}  started {}  refused {}  done {}",
        c.stops_reached,
        c.stop_errors,
        c.pivots,
        c.open_loop_pivot_ticks,
        c.routes_started,
        c.routes_refused,
        c.routes_done
    );
    let _ = writeln!(
        o,
        "route clock   waited {} ticks for a lagging robot  approach {} ticks  approach timeouts {}",
        c.clock_wait_ticks, c.approach_ticks, c.approach_timeouts
    );
}

/// The summary as text for a terminal.
#[must_use]
pub fn format_summary(s: &Summary) -> String {
    let mut o = String::new();
    let _ = writeln!(o, "scenario      {}", s.scenario);
    let _ = writeln!(
        o,
        "setup         {} plant, {}, position {}, core path: {}",
        s.plant, s.controller, s.position_source, s.code_path
    );
    let _ = writeln!(
        o,
        "run           {} ticks of {} s = {} s simulated in {:.2} s wall ({:.0}× real time)",
        s.ticks,
        s.period_s,
        s.duration_s,
        s.wall_time_s,
        s.duration_s / s.wall_time_s.max(1e-9)
    );
    let _ = writeln!(
        o,
        "error t≥{:<5} max {:.4} m   mean {:.4} m   rms {:.4} m   ({} ticks)",
        format!("{}s", s.transient_s),
        s.max_error_m,
        s.mean_error_m,
        s.rms_error_m,
        s.samples
    );
    let _ = writeln!(o, "final error   {:.4} m", s.final_error_m);
    if let Some(h) = s.max_heading_error_rad {
        let _ = writeln!(o, "heading est.  max |θ̂ − θ| after transient {h:.4} rad");
    }
    let g = &s.gain_bound;
    let _ = match (g.satisfied, g.gamma) {
        (true, Some(gamma)) => writeln!(
            o,
            "gain bound    (15) holds, γ = {gamma:.3}: {:.4} ≤ v ≤ {:.4} m/s guaranteed",
            g.min_speed_m_s.unwrap_or(f64::NAN),
            g.max_speed_m_s.unwrap_or(f64::NAN)
        ),
        (false, Some(gamma)) => writeln!(
            o,
            "gain bound    (15) VIOLATED: these gains need γ = {gamma:.3} ≥ 1 (no speed guarantee)"
        ),
        _ => writeln!(o, "gain bound    reference can stop: (15) cannot hold"),
    };
    let m = &s.mode_ticks;
    let _ = writeln!(
        o,
        "modes         awaiting_fix {}  tracking {}  fix_lost {}  state_feedback {}",
        m.awaiting_fix, m.tracking, m.fix_lost, m.state_feedback
    );
    if let Some(t) = &s.tracker {
        let _ = writeln!(
            o,
            "tracker       fixes used {}  invalid {}  stale {}  gated {}  relocalised {}  heading resets {}  dead-reckoned {}  failsafe entries {}  non-finite cmds {}  reference standstill {}  observer rejects {}",
            t.fixes_used,
            t.invalid_fixes,
            t.stale_fixes,
            t.fixes_gated,
            t.relocalisations,
            t.heading_resets,
            t.dead_reckoned_steps,
            t.failsafe_entries,
            t.non_finite_commands,
            t.reference_standstill_ticks,
            t.observer_rejected_updates
        );
    }
    if let Some(r) = &s.rfid {
        let _ = writeln!(
            o,
            "rfid          frames ok {}  bad checksum {}  malformed {}  outside {}  read errors {}  superseded {}  backlogged polls {}  unknown tags {}",
            r.frames_ok,
            r.bad_checksum,
            r.malformed,
            r.bytes_outside_frames,
            r.read_errors,
            r.superseded,
            r.backlogged_polls,
            r.unknown_tags
        );
        let _ = writeln!(
            o,
            "reader model  sent {}  skipped (line busy) {}  dropped {}  corrupted bytes {}",
            r.reader.frames_sent,
            r.reader.skipped_line_busy,
            r.reader.frames_dropped,
            r.reader.bytes_corrupted
        );
    }
    if let Some(p) = &s.pilot {
        let _ = writeln!(
            o,
            "drive         speed-limited {}  accel-limited {} ticks  max |duty| {:.3}  encoder faults {}  implausible {}  halts {}  motor faults {}  reversals under drive {}  bad PWM writes {}",
            p.speed_limited_ticks,
            p.accel_limited_ticks,
            p.max_abs_duty,
            p.encoder_fault_ticks,
            p.implausible_encoder_reads,
            p.encoder_halt_ticks,
            p.motor_faults,
            p.reversals_under_drive,
            p.out_of_range_pwm_writes
        );
    }
    if let Some(r) = &s.route {
        format_route(&mut o, r);
    }
    if let Some(h) = &s.hil {
        let (f, l) = (&h.firmware_link, &h.host_link);
        let _ = writeln!(
            o,
            "firmware      {} ticks under QEMU  peak stack {} B  UART overruns {}",
            h.firmware_ticks, h.peak_stack_bytes, h.uart_overruns
        );
        let _ = writeln!(
            o,
            "link          firmware saw: ok {} corrupt {} gaps {} stale {} timeouts {} unexpected {} repeated ticks {};  host saw: ok {} corrupt {} gaps {} stale {}",
            f.frames_ok,
            f.corrupt_frames,
            f.sequence_gaps,
            f.stale_frames,
            f.timeouts,
            f.unexpected_messages,
            h.repeated_ticks,
            l.frames_ok,
            l.corrupt_frames,
            l.sequence_gaps,
            l.stale_frames
        );
        if let Some(r) = &h.link_faults {
            let verdict = |expected: &crate::report::link_faults::ExpectedCounters, seen| {
                if expected.agrees_with(seen) {
                    "agree".to_owned()
                } else {
                    format!(
                        "DISAGREE (expected ok {} corrupt {} gaps {} stale {})",
                        expected.frames_ok,
                        expected.corrupt_frames,
                        expected.sequence_gaps,
                        expected.stale_frames
                    )
                }
            };
            for (way, i) in [("to firmware", &r.to_firmware), ("to host", &r.to_host)] {
                let _ = writeln!(
                    o,
                    "faults        {way}: {} frames, dropped {} duplicated {} delayed {} corrupted {} ({} bytes)",
                    i.frames, i.dropped, i.duplicated, i.delayed, i.corrupted, i.bytes_corrupted
                );
            }
            let _ = writeln!(
                o,
                "faults        counts: firmware {}, host {}; outages {} timeouts {} silence reports {} (+{} lost, motors stopped after at most {} ms) resent ticks {} nacks {} stale answers {}",
                verdict(&r.firmware_expected, f),
                verdict(&r.host_expected, l),
                r.outages,
                f.timeouts,
                r.silence_reports,
                r.silence_reports_lost,
                r.longest_silence_before_stop_ms,
                r.resent_ticks,
                r.nacks,
                r.stale_answers
            );
        }
        if let Some(m) = &h.mavlink {
            format_mavlink_bridge(&mut o, m);
        }
    }
    if let Some(n) = s.floor_tags {
        let _ = writeln!(o, "floor         {n} tags");
    }
    if let Some(m) = &s.measurement {
        let _ = writeln!(
            o,
            "fix faults    noise std {} m per axis  miss probability {}  missed fixes {}",
            m.noise_std_m, m.miss_probability, m.missed_fixes
        );
    }
    if s.non_finite_ticks > 0 {
        let _ = writeln!(
            o,
            "WARNING       {} ticks with non-finite values",
            s.non_finite_ticks
        );
    }
    o
}

/// Image size, px (of every two-panel plot of the crate).
pub(crate) const SIZE: (u32, u32) = (1800, 820);
/// The plots' font family (shared by every plot of the crate).
pub(crate) const FONT: &str = "sans-serif";

/// Renders the trajectory vs the reference (left, equal axes) and the
/// tracking error vs time on a log axis with the transient window shaded
/// (right).
///
/// # Errors
/// Rendering or file errors.
pub fn plot_png(path: &Path, result: &RunResult) -> anyhow::Result<()> {
    let root = BitMapBackend::new(path, SIZE).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    let (left, right) = root.split_horizontally(SIZE.1 + 20);
    trajectory_panel(&left, result)?;
    error_panel(&right, result)?;
    root.present()
        .map_err(plot_err)
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// Draws a chart's series legend at `position` in the style of every plot
/// of the crate (white box, black border, [`FONT`] at `font_size` px).
pub(crate) fn draw_legend<'a, DB, CT>(
    chart: &mut ChartContext<'a, DB, CT>,
    position: SeriesLabelPosition,
    font_size: u32,
) -> anyhow::Result<()>
where
    DB: DrawingBackend + 'a,
    CT: CoordTranslate,
{
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font((FONT, font_size))
        .draw()
        .map_err(plot_err)
}

/// A plotters error as an `anyhow` error (shared by every plot of the crate).
pub(crate) fn plot_err<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow::anyhow!("plot: {e:?}")
}

/// Axis ranges with equal metres per pixel both ways, centred on the data
/// ranges `xs`, `ys` (already padded) in a plotting area of `pw × ph`
/// pixels.
pub(crate) fn equal_axes(
    xs: (f64, f64),
    ys: (f64, f64),
    pw: f64,
    ph: f64,
) -> (std::ops::Range<f64>, std::ops::Range<f64>) {
    let scale = ((xs.1 - xs.0) / pw).max((ys.1 - ys.0) / ph);
    let (cx, cy) = (0.5 * (xs.0 + xs.1), 0.5 * (ys.0 + ys.1));
    let (hx, hy) = (0.5 * scale * pw, 0.5 * scale * ph);
    (cx - hx..cx + hx, cy - hy..cy + hy)
}

/// A plan-view chart on `area`, x and y in metres with equal axes, framing
/// the finite ones of `points` with a 5 % margin (or the square ±1 m if
/// none is finite), its mesh drawn.
pub(crate) fn plan_chart<'a, 'b>(
    area: &'a DrawingArea<BitMapBackend<'b>, Shift>,
    points: impl IntoIterator<Item = (f64, f64)>,
) -> anyhow::Result<ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>>
{
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for (x, y) in points {
        if x.is_finite() && y.is_finite() {
            lo = [lo[0].min(x), lo[1].min(y)];
            hi = [hi[0].max(x), hi[1].max(y)];
        }
    }
    if !(lo[0].is_finite() && lo[1].is_finite()) {
        lo = [-1.0; 2];
        hi = [1.0; 2];
    }
    // Equal axes: metres per pixel the same both ways.
    let (margin, x_label, y_label) = (15_u32, 45_u32, 60_u32);
    let (w, h) = area.dim_in_pixel();
    let pw = f64::from(w.saturating_sub(2 * margin + y_label).max(1));
    let ph = f64::from(h.saturating_sub(2 * margin + x_label).max(1));
    let pad = 0.05 * (hi[0] - lo[0]).max(hi[1] - lo[1]).max(0.1);
    let (x_axis, y_axis) = equal_axes(
        (lo[0] - pad, hi[0] + pad),
        (lo[1] - pad, hi[1] + pad),
        pw,
        ph,
    );
    let mut chart = ChartBuilder::on(area)
        .margin(margin)
        .x_label_area_size(x_label)
        .y_label_area_size(y_label)
        .build_cartesian_2d(x_axis, y_axis)
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .x_desc("x [m]")
        .y_desc("y [m]")
        .label_style((FONT, 16))
        .axis_desc_style((FONT, 18))
        .draw()
        .map_err(plot_err)?;
    Ok(chart)
}

/// Draws `points` as a line of `color`, `width` px wide, with `label` in
/// the legend (a 2 px stroke of the same colour).
pub(crate) fn draw_line<'a, DB, X, Y>(
    chart: &mut ChartContext<'a, DB, Cartesian2d<X, Y>>,
    points: impl IntoIterator<Item = (f64, f64)>,
    color: RGBColor,
    width: u32,
    label: impl Into<String>,
) -> anyhow::Result<()>
where
    DB: DrawingBackend + 'a,
    X: Ranged<ValueType = f64>,
    Y: Ranged<ValueType = f64>,
{
    chart
        .draw_series(LineSeries::new(
            points,
            ShapeStyle::from(&color).stroke_width(width),
        ))
        .map_err(plot_err)?
        .label(label)
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
    Ok(())
}

fn trajectory_panel(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    result: &RunResult,
) -> anyhow::Result<()> {
    let records = &result.records;
    let area = area
        .titled(
            &format!("{}: trajectory", result.summary.scenario),
            (FONT, 24),
        )
        .map_err(plot_err)?;
    let mut chart = plan_chart(
        &area,
        records
            .iter()
            .flat_map(|r| [(r.x_m, r.y_m), (r.ref_x_m, r.ref_y_m)]),
    )?;
    let step = (records.len() / 20_000).max(1);
    if let Some(route) = &result.summary.route {
        // The route's planned path, under the rest, and its stops.
        let path_step = (route.path_m.len() / 20_000).max(1);
        draw_line(
            &mut chart,
            route.path_m.iter().step_by(path_step).map(|p| (p[0], p[1])),
            GREEN,
            4,
            "route (planned path)",
        )?;
        chart
            .draw_series(
                route
                    .stops
                    .iter()
                    .map(|stop| TriangleMarker::new((stop.x_m, stop.y_m), 8, MAGENTA.filled())),
            )
            .map_err(plot_err)?
            .label("stops")
            .legend(|(x, y)| TriangleMarker::new((x + 10, y), 6, MAGENTA.filled()));
    }
    draw_line(
        &mut chart,
        records.iter().step_by(step).map(|r| (r.ref_x_m, r.ref_y_m)),
        RED,
        2,
        "reference",
    )?;
    draw_line(
        &mut chart,
        records.iter().step_by(step).map(|r| (r.x_m, r.y_m)),
        BLUE,
        1,
        "robot (true)",
    )?;
    if let (Some(first), Some(last)) = (records.first(), records.last()) {
        chart
            .draw_series([
                Circle::new((first.x_m, first.y_m), 5, BLUE.filled()),
                Circle::new((first.ref_x_m, first.ref_y_m), 5, RED.filled()),
                Circle::new((last.x_m, last.y_m), 5, BLACK.filled()),
            ])
            .map_err(plot_err)?;
    }
    draw_legend(&mut chart, SeriesLabelPosition::UpperRight, 16)?;
    Ok(())
}

fn error_panel(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    result: &RunResult,
) -> anyhow::Result<()> {
    let s = &result.summary;
    let records = &result.records;
    let area = area
        .titled(
            &format!(
                "tracking error |p - p_ref|; after {} s: max {:.4} m, mean {:.4} m, rms {:.4} m",
                s.transient_s, s.max_error_m, s.mean_error_m, s.rms_error_m
            ),
            (FONT, 22),
        )
        .map_err(plot_err)?;
    let t_end = records.last().map_or(1.0, |r| r.t_s).max(1e-3);
    let positive = records
        .iter()
        .map(|r| r.error_m)
        .filter(|e| e.is_finite() && *e > 0.0);
    let (e_min, e_max) = positive.fold((f64::INFINITY, 0.0_f64), |(lo, hi), e| {
        (lo.min(e), hi.max(e))
    });
    let floor = if e_min.is_finite() {
        (e_min * 0.5).max(1e-6)
    } else {
        1e-6
    };
    let ceil = (e_max * 2.0).max(floor * 10.0);

    let mut chart = ChartBuilder::on(&area)
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(80)
        .build_cartesian_2d(0.0..t_end, (floor..ceil).log_scale())
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .x_desc("t [s]")
        .y_desc("error [m] (log)")
        .x_label_formatter(&|v| format!("{v:.0}"))
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .label_style((FONT, 16))
        .axis_desc_style((FONT, 18))
        .draw()
        .map_err(plot_err)?;
    if s.transient_s > 0.0 {
        chart
            .draw_series([Rectangle::new(
                [(0.0, floor), (s.transient_s.min(t_end), ceil)],
                RGBColor(200, 200, 200).mix(0.35).filled(),
            )])
            .map_err(plot_err)?
            .label(format!(
                "transient (t < {} s, not in the statistics)",
                s.transient_s
            ))
            .legend(|(x, y)| {
                Rectangle::new(
                    [(x, y - 6), (x + 20, y + 6)],
                    RGBColor(200, 200, 200).filled(),
                )
            });
    }
    let step = (records.len() / 20_000).max(1);
    draw_line(
        &mut chart,
        records
            .iter()
            .step_by(step)
            .map(|r| (r.t_s, r.error_m.clamp(floor, ceil))),
        BLUE,
        1,
        "tracking error",
    )?;
    if s.max_error_m.is_finite() && s.max_error_m > 0.0 {
        let t0 = s.transient_s.min(t_end);
        draw_line(
            &mut chart,
            [(t0, s.max_error_m), (t_end, s.max_error_m)],
            RED,
            1,
            format!("max after transient {:.4} m", s.max_error_m),
        )?;
        draw_line(
            &mut chart,
            [(t0, s.mean_error_m), (t_end, s.mean_error_m)],
            GREEN,
            1,
            format!("mean after transient {:.4} m", s.mean_error_m),
        )?;
    }
    draw_legend(&mut chart, SeriesLabelPosition::UpperRight, 16)?;
    Ok(())
}

/// The lines of a run with a ground station (`firmware-sim hil
/// --mavlink`).
fn format_mavlink_bridge(o: &mut String, m: &crate::report::mavlink_bridge::MavlinkBridgeReport) {
    let _ = writeln!(
        o,
        "mavlink       {:.1}x real time (asked {}x){}; udp in {} datagrams {} B ({} dropped by the kernel), out {} frames ({} unsent); backlog dropped {} datagrams {} B (largest {} B, {} B left at the end); firmware reported the link silent {} times",
        m.speedup_achieved,
        m.speedup,
        if m.interrupted {
            ", ended by Ctrl-C"
        } else {
            ""
        },
        m.udp.datagrams_in,
        m.udp.bytes_in,
        m.udp
            .kernel_dropped_datagrams
            .map_or_else(|| "unknown".to_owned(), |n| n.to_string()),
        m.udp.frames_out,
        m.udp.frames_unsent,
        m.dropped_datagrams,
        m.dropped_bytes,
        m.largest_backlog_bytes,
        m.left_in_backlog_bytes,
        m.link_silences
    );
    let _ = writeln!(
        o,
        "mavlink       channel: {} messages, {} B to the firmware, {} B back; firmware dropped {} B in, {} frames out",
        m.messages,
        m.bytes_to_firmware,
        m.bytes_from_firmware,
        m.firmware.rx_dropped_bytes,
        m.firmware.tx_dropped_frames
    );
    let copy = if m.copy_mismatches == 0 {
        format!(
            "all {} answers equal: the run's route status is the firmware's",
            m.copy_compared
        )
    } else {
        format!(
            "DIFFERS: {} of {} answers, the first before tick {}: the run's route status is the host copy's, not the firmware's",
            m.copy_mismatches,
            m.copy_compared,
            m.first_mismatch_tick
                .map_or_else(|| "?".to_owned(), |t| t.to_string())
        )
    };
    let _ = writeln!(o, "mavlink       host copy of the session: {copy}");
    let _ = writeln!(
        o,
        "route         no route report: a ground station steers the route (its missions, pauses and stops)"
    );
}
