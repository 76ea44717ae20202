//! `firmware-sim plot LOG`: a firmware's telemetry log (the decoded defmt
//! text of `firmware-sim hil`'s `firmware.log`, or what `probe-rs run`
//! prints for the Black Pill) back into `run.csv`, `summary.json` and
//! `run.png`.
//!
//! The records are `wmr_link::telemetry`'s (what the firmware saw and
//! drove); `run.csv` has a simulated run's columns, in its order, with
//! the same values where the firmware knows them: the estimate, the
//! reference, the command, the mode, the fix flag, the time `t = k·h`. A
//! log has no ground truth, so the plant's columns (`x_m`, `y_m`,
//! `theta_rad`, `heading_error_rad`, `error_m`) are empty and the summary
//! says so instead of computing error statistics. The duties are the
//! pilot's (before the PWM's quantization to whole steps, which a
//! simulated run's driver inputs show). A decimated log gives a
//! decimated `run.csv`: one row per record, nothing interpolated.
//!
//! Lines without a telemetry tag are other logs, counted; a tagged line
//! that does not read (truncated, malformed, another format version) is
//! skipped, counted and reported with its line number, never dropped in
//! silence. Only the last run of the log (from its last start line) is
//! read; earlier runs (a reset) are counted.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context as _, bail};
use plotters::prelude::*;
use serde::Serialize;
use wmr_core::geometry::HeadingEstimate;
use wmr_link::telemetry::{
    FLAG_ACCEL_LIMITED, FLAG_FIX, FLAG_SPEED_LIMITED, FORMAT_VERSION, Line, Record, Start,
    mode_of_code, parse_line,
};

use crate::output::{FONT, SIZE, draw_legend, draw_line, plan_chart, plot_err};
use crate::report::{Mode, ModeTicks};

/// One row of a log's `run.csv`: a simulated run's columns
/// ([`crate::Record`]), in its order; the plant's truth is empty.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LogRecord {
    /// Tick index `k`.
    pub tick: u32,
    /// `t = k·h`, s.
    pub t_s: f64,
    /// No ground truth in a log: empty.
    pub x_m: Option<f64>,
    /// Empty.
    pub y_m: Option<f64>,
    /// Empty.
    pub theta_rad: Option<f64>,
    /// Reference x, m.
    pub ref_x_m: f64,
    /// Reference y, m.
    pub ref_y_m: f64,
    /// Position the law used, m; empty before the first fix.
    pub est_x_m: Option<f64>,
    /// Position the law used, y, m.
    pub est_y_m: Option<f64>,
    /// Heading estimate's cosine.
    pub est_cos: Option<f64>,
    /// Heading estimate's sine.
    pub est_sin: Option<f64>,
    /// `θ̂ = atan2(ẑ4, ẑ3)` (the core's), rad.
    pub est_theta_rad: Option<f64>,
    /// Empty (needs the true heading).
    pub heading_error_rad: Option<f64>,
    /// Commanded forward speed, m/s.
    pub v_cmd_m_s: f64,
    /// Commanded yaw rate, rad/s.
    pub omega_cmd_rad_s: f64,
    /// The pilot's signed left duty (before PWM quantization).
    pub left_duty: Option<f64>,
    /// The pilot's signed right duty.
    pub right_duty: Option<f64>,
    /// A tag fix was used this tick.
    pub fix: bool,
    /// Tracker mode after the tick.
    pub mode: Mode,
    /// Empty (needs the true position).
    pub error_m: Option<f64>,
}

/// A tagged line that was not read.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct SkippedLine {
    /// Line number in the log, from 1.
    pub line: usize,
    /// Why.
    pub reason: String,
}

/// Tagged lines reported one by one in the summary, at most.
pub const SKIPPED_LISTED: usize = 20;

/// What a log's summary says.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LogSummary {
    /// Always `telemetry log`: not a simulation.
    pub source: &'static str,
    /// The log read.
    pub log: PathBuf,
    /// [`FORMAT_VERSION`] read.
    pub format_version: u32,
    /// A record every this many ticks, as the firmware said.
    pub every_ticks: u16,
    /// Control period, s (as the firmware printed it).
    pub period_s: f64,
    /// Rows in run.csv: one per record read.
    pub records: u64,
    /// First and last tick read.
    pub first_tick: Option<u32>,
    /// Last tick read.
    pub last_tick: Option<u32>,
    /// `(last − first)·h`, s.
    pub duration_s: f64,
    /// Records the decimation says should be between the first and the
    /// last but are not in the log (lost on the way: an RTT ring
    /// overwritten, a skipped line).
    pub missing_records: u64,
    /// Records whose tick is not after the one before, or off the
    /// decimation's grid: dropped, counted.
    pub out_of_order_records: u64,
    /// Tagged lines that did not read.
    pub skipped_lines: u64,
    /// The first [`SKIPPED_LISTED`] of them.
    pub skipped: Vec<SkippedLine>,
    /// Frames the defmt decoder could not decode (its `malformed defmt
    /// frame` lines).
    pub malformed_defmt_frames: u64,
    /// Lines that are other logs.
    pub other_lines: u64,
    /// Runs before the last start line (a reset), not read.
    pub earlier_runs: u64,
    /// Whether the plant's truth is known: never for a log.
    pub ground_truth: bool,
    /// What a simulated run's summary has that a log cannot give.
    pub not_computed: &'static str,
    /// Records per mode (records, not ticks, when decimated).
    pub mode_records: ModeTicks,
    /// Records with a fix used.
    pub fix_records: u64,
    /// Records with the wheel-speed limit acting.
    pub speed_limited_records: u64,
    /// Records with the acceleration limit acting.
    pub accel_limited_records: u64,
    /// Records holding a non-finite number.
    pub non_finite_records: u64,
    /// The counters of the last record: fixes used.
    pub fixes_used: Option<u32>,
    /// Device faults (encoders, unknown tags, motors) at the last record.
    pub device_faults: Option<u32>,
}

/// A log read back.
#[derive(Debug, Clone)]
pub struct LogRun {
    /// One row per record.
    pub records: Vec<LogRecord>,
    /// What was read and how.
    pub summary: LogSummary,
}

/// Reads a decoded log's text (`path` only names it in the summary).
///
/// # Errors
/// No start line (the log began after the run had started, or telemetry
/// was off), or no record after it.
pub fn read_log(text: &str, path: &Path) -> anyhow::Result<LogRun> {
    let mut start: Option<(Start, usize)> = None;
    let mut earlier_runs = 0_u64;
    let mut records: Vec<(Record, usize)> = Vec::new();
    let mut skipped = Vec::new();
    let (mut other_lines, mut malformed_defmt_frames) = (0_u64, 0_u64);
    for (i, line) in text.lines().enumerate() {
        let number = i + 1;
        match parse_line(line) {
            None if line.contains("malformed defmt frame") => malformed_defmt_frames += 1,
            None => other_lines += 1,
            Some(Err(e)) => skipped.push(SkippedLine {
                line: number,
                reason: e.to_string(),
            }),
            Some(Ok(Line::Start(s))) => {
                if start.is_some() || !records.is_empty() {
                    earlier_runs += 1;
                }
                records.clear();
                start = Some((s, number));
            }
            Some(Ok(Line::Record(r))) => records.push((r, number)),
        }
    }
    let Some((start, _)) = start else {
        bail!(
            "{}: no `wmr-tlm-start` line ({} records, {} other lines): the log began after \
             the run had started, or the firmware's telemetry was off",
            path.display(),
            records.len(),
            other_lines
        );
    };
    if start.every_ticks == 0 {
        bail!("{}: the firmware's telemetry was off", path.display());
    }
    // The period as the firmware printed it (its shortest decimal), read
    // as f64: the scenario's `period_s`, which a simulated run's `t = k·h`
    // uses, when that is a short decimal such as 0.01.
    let period_s: f64 = start
        .period_s
        .to_string()
        .parse()
        .context("the start line's period")?;
    let every = u32::from(start.every_ticks);
    let mut rows = Vec::with_capacity(records.len());
    let mut out_of_order = 0_u64;
    let mut missing = 0_u64;
    let mut last: Option<u32> = None;
    let mut accepted = Vec::with_capacity(records.len());
    for (r, _line) in &records {
        let on_grid = r.tick.is_multiple_of(every);
        if !on_grid || last.is_some_and(|l| r.tick <= l) {
            out_of_order += 1;
            continue;
        }
        if let Some(l) = last {
            missing += u64::from((r.tick - l) / every - 1);
        }
        last = Some(r.tick);
        rows.push(row(r, period_s));
        accepted.push(*r);
    }
    if rows.is_empty() {
        bail!(
            "{}: a start line but no readable record after it ({} tagged lines skipped)",
            path.display(),
            skipped.len()
        );
    }
    let mut modes = ModeTicks::default();
    let (mut fixes, mut speed, mut accel, mut non_finite) = (0, 0, 0, 0);
    for r in &accepted {
        fixes += u64::from(r.flags & FLAG_FIX != 0);
        speed += u64::from(r.flags & FLAG_SPEED_LIMITED != 0);
        accel += u64::from(r.flags & FLAG_ACCEL_LIMITED != 0);
        let numbers = [r.reference_m, r.position_m, r.heading, r.command, r.duty];
        non_finite += u64::from(!numbers.iter().flatten().all(|v| v.is_finite()));
    }
    for row in &rows {
        match row.mode {
            Mode::AwaitingFix => modes.awaiting_fix += 1,
            Mode::Tracking => modes.tracking += 1,
            Mode::FixLost => modes.fix_lost += 1,
            Mode::StateFeedback => modes.state_feedback += 1,
        }
    }
    let (first, last_row) = (rows.first().map(|r| r.tick), rows.last().map(|r| r.tick));
    let last_record = accepted.last();
    let summary = LogSummary {
        source: "telemetry log",
        log: path.to_path_buf(),
        format_version: FORMAT_VERSION,
        every_ticks: start.every_ticks,
        period_s,
        records: u64::try_from(rows.len()).unwrap_or(u64::MAX),
        first_tick: first,
        last_tick: last_row,
        duration_s: match (first, last_row) {
            (Some(a), Some(b)) => f64::from(b - a) * period_s,
            _ => 0.0,
        },
        missing_records: missing,
        out_of_order_records: out_of_order,
        skipped_lines: u64::try_from(skipped.len()).unwrap_or(u64::MAX),
        skipped: skipped.into_iter().take(SKIPPED_LISTED).collect(),
        malformed_defmt_frames,
        other_lines,
        earlier_runs,
        ground_truth: false,
        not_computed: "a log has no ground truth: x_m, y_m, theta_rad, heading_error_rad and \
                       error_m are empty, and no tracking-error statistics are computed",
        mode_records: modes,
        fix_records: fixes,
        speed_limited_records: speed,
        accel_limited_records: accel,
        non_finite_records: non_finite,
        fixes_used: last_record.map(|r| r.fixes_used),
        device_faults: last_record.map(|r| r.device_faults),
    };
    Ok(LogRun {
        records: rows,
        summary,
    })
}

/// A record as a `run.csv` row, with a simulated run's conversions
/// (`f64::from` of each `f32`; `θ̂` by the core's `atan2`).
fn row(r: &Record, period_s: f64) -> LogRecord {
    let mode = mode_of_code(r.mode).map_or(Mode::AwaitingFix, Mode::from);
    let heading = HeadingEstimate {
        cos_theta: r.heading[0],
        sin_theta: r.heading[1],
    };
    // A simulated run leaves the position empty while awaiting a fix.
    let position = (mode != Mode::AwaitingFix).then_some(r.position_m);
    LogRecord {
        tick: r.tick,
        t_s: f64::from(r.tick) * period_s,
        x_m: None,
        y_m: None,
        theta_rad: None,
        ref_x_m: f64::from(r.reference_m[0]),
        ref_y_m: f64::from(r.reference_m[1]),
        est_x_m: position.map(|p| f64::from(p[0])),
        est_y_m: position.map(|p| f64::from(p[1])),
        est_cos: Some(f64::from(heading.cos_theta)),
        est_sin: Some(f64::from(heading.sin_theta)),
        est_theta_rad: Some(f64::from(heading.heading_rad())),
        heading_error_rad: None,
        v_cmd_m_s: f64::from(r.command[0]),
        omega_cmd_rad_s: f64::from(r.command[1]),
        left_duty: Some(f64::from(r.duty[0])),
        right_duty: Some(f64::from(r.duty[1])),
        fix: r.flags & FLAG_FIX != 0,
        mode,
        error_m: None,
    }
}

/// Writes `run.csv`, `summary.json` and (if `plot`) `run.png` into `dir`.
///
/// # Errors
/// I/O or rendering errors, naming the file.
pub fn write_log_run(dir: &Path, run: &LogRun, plot: bool) -> anyhow::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let csv_path = dir.join("run.csv");
    let mut w = csv::Writer::from_path(&csv_path)
        .with_context(|| format!("creating {}", csv_path.display()))?;
    for r in &run.records {
        w.serialize(r)
            .with_context(|| format!("writing {}", csv_path.display()))?;
    }
    w.flush()
        .with_context(|| format!("writing {}", csv_path.display()))?;
    let summary_path = dir.join("summary.json");
    let text = serde_json::to_string_pretty(&run.summary)?;
    std::fs::write(&summary_path, text + "\n")
        .with_context(|| format!("writing {}", summary_path.display()))?;
    let mut files = vec![csv_path, summary_path];
    if plot {
        let png = dir.join("run.png");
        plot_log(&png, run).with_context(|| format!("writing {}", png.display()))?;
        files.push(png);
    }
    Ok(files)
}

/// The summary as text for a terminal.
#[must_use]
pub fn format_log_summary(s: &LogSummary) -> String {
    let mut o = String::new();
    let _ = writeln!(
        o,
        "log           {} (telemetry format {}; no ground truth: no error statistics)",
        s.log.display(),
        s.format_version
    );
    let _ = writeln!(
        o,
        "records       {} (every {} ticks of {} s), ticks {}..={}, {} s; missing {}  out of order {}",
        s.records,
        s.every_ticks,
        s.period_s,
        s.first_tick.unwrap_or(0),
        s.last_tick.unwrap_or(0),
        s.duration_s,
        s.missing_records,
        s.out_of_order_records
    );
    let _ = writeln!(
        o,
        "lines         skipped {}  malformed defmt frames {}  other {}  earlier runs {}",
        s.skipped_lines, s.malformed_defmt_frames, s.other_lines, s.earlier_runs
    );
    for k in &s.skipped {
        let _ = writeln!(o, "  skipped line {}: {}", k.line, k.reason);
    }
    let m = &s.mode_records;
    let _ = writeln!(
        o,
        "modes         awaiting_fix {}  tracking {}  fix_lost {} (records)",
        m.awaiting_fix, m.tracking, m.fix_lost
    );
    let _ = writeln!(
        o,
        "records with  fix {}  speed-limited {}  accel-limited {}  non-finite {}",
        s.fix_records, s.speed_limited_records, s.accel_limited_records, s.non_finite_records
    );
    let _ = writeln!(
        o,
        "counters      fixes used {}  device faults {} (at the last record)",
        s.fixes_used.unwrap_or(0),
        s.device_faults.unwrap_or(0)
    );
    o
}

/// The estimate against the reference (left, equal axes) and the commands
/// over time (right).
fn plot_log(path: &Path, run: &LogRun) -> anyhow::Result<()> {
    let root = BitMapBackend::new(path, SIZE).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    let (left, right) = root.split_horizontally(SIZE.1 + 20);
    let records = &run.records;

    let left = left
        .titled("telemetry: estimate and reference", (FONT, 24))
        .map_err(plot_err)?;
    let mut chart = plan_chart(
        &left,
        records
            .iter()
            .flat_map(|r| [Some((r.ref_x_m, r.ref_y_m)), r.est_x_m.zip(r.est_y_m)])
            .flatten(),
    )?;
    draw_line(
        &mut chart,
        records.iter().map(|r| (r.ref_x_m, r.ref_y_m)),
        RED,
        2,
        "reference",
    )?;
    draw_line(
        &mut chart,
        records.iter().filter_map(|r| r.est_x_m.zip(r.est_y_m)),
        BLUE,
        1,
        "estimate (the firmware's; no ground truth in a log)",
    )?;
    draw_legend(&mut chart, SeriesLabelPosition::UpperRight, 16)?;

    let right = right
        .titled(
            &format!(
                "commands, one point per record (every {} ticks)",
                run.summary.every_ticks
            ),
            (FONT, 22),
        )
        .map_err(plot_err)?;
    let t_end = records.last().map_or(1.0, |r| r.t_s).max(1e-3);
    let (c_lo, c_hi) = records
        .iter()
        .flat_map(|r| [r.v_cmd_m_s, r.omega_cmd_rad_s])
        .filter(|v| v.is_finite())
        .fold((-0.1_f64, 0.1_f64), |(lo, hi), v| (lo.min(v), hi.max(v)));
    let mut chart = ChartBuilder::on(&right)
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(80)
        .build_cartesian_2d(0.0..t_end, c_lo * 1.1..c_hi * 1.1)
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .x_desc("t [s]")
        .y_desc("command")
        .label_style((FONT, 16))
        .axis_desc_style((FONT, 18))
        .draw()
        .map_err(plot_err)?;
    draw_line(
        &mut chart,
        records.iter().map(|r| (r.t_s, r.v_cmd_m_s)),
        BLUE,
        1,
        "v [m/s]",
    )?;
    draw_line(
        &mut chart,
        records.iter().map(|r| (r.t_s, r.omega_cmd_rad_s)),
        GREEN,
        1,
        "ω [rad/s]",
    )?;
    draw_legend(&mut chart, SeriesLabelPosition::UpperRight, 16)?;
    root.present().map_err(plot_err)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(tick: u32, mode: u8) -> String {
        format!("wmr-tlm 1 {tick} {mode} 1 0.5 -0.25 0.1 0.2 1.0 0.0 0.3 -0.1 0.2 0.25 0 {tick} 0")
    }

    #[test]
    fn a_decimated_log_gives_a_decimated_run_and_says_what_it_lost() {
        let text = [
            "INFO wmr-firmware (QEMU board), link protocol 11".to_owned(),
            "wmr-tlm-start 1 10 0.01".to_owned(),
            line(0, 0),
            line(10, 1),
            // Truncated, then a whole record is missing (tick 30).
            "wmr-tlm 1 20 1 1 0.5".to_owned(),
            line(40, 1),
            "(malformed defmt frame skipped)".to_owned(),
            // Off the decimation's grid.
            line(45, 1),
            line(50, 2),
        ]
        .join("\n");
        let run = read_log(&text, Path::new("firmware.log")).unwrap();
        let ticks: Vec<u32> = run.records.iter().map(|r| r.tick).collect();
        assert_eq!(ticks, [0, 10, 40, 50]);
        let s = &run.summary;
        assert_eq!((s.every_ticks, s.records), (10, 4));
        assert_eq!(s.missing_records, 2, "ticks 20 and 30");
        assert_eq!(s.out_of_order_records, 1);
        assert_eq!(s.skipped_lines, 1);
        assert_eq!(s.skipped[0].line, 5);
        assert!(s.skipped[0].reason.contains("truncated"), "{:?}", s.skipped);
        assert_eq!((s.malformed_defmt_frames, s.other_lines), (1, 1));
        assert!(!s.ground_truth);
        assert_eq!(s.duration_s, 0.5);
        assert_eq!(run.records[1].t_s, 10.0 * 0.01);
        // Awaiting a fix: no position, as in a simulated run.
        assert_eq!(run.records[0].est_x_m, None);
        assert_eq!(run.records[1].est_x_m, Some(f64::from(0.1_f32)));
        assert_eq!(run.records[0].x_m, None);
        assert_eq!(run.records[3].mode, Mode::FixLost);
    }

    #[test]
    fn a_log_without_a_start_is_refused_and_a_reset_starts_over() {
        let err = read_log(&line(0, 0), Path::new("x.log")).unwrap_err();
        assert!(err.to_string().contains("no `wmr-tlm-start`"), "{err}");
        let text = [
            "wmr-tlm-start 1 1 0.01".to_owned(),
            line(0, 0),
            line(1, 1),
            "wmr-tlm-start 1 1 0.01".to_owned(),
            line(0, 0),
        ]
        .join("\n");
        let run = read_log(&text, Path::new("x.log")).unwrap();
        assert_eq!(run.records.len(), 1);
        assert_eq!(run.summary.earlier_runs, 1);
    }

    /// The CSV header is a simulated run's, column for column.
    #[test]
    fn the_csv_columns_are_a_simulated_runs() {
        let dir = tempfile::tempdir().unwrap();
        let text = ["wmr-tlm-start 1 1 0.01".to_owned(), line(0, 1)].join("\n");
        let run = read_log(&text, Path::new("x.log")).unwrap();
        write_log_run(dir.path(), &run, false).unwrap();
        let ours = std::fs::read_to_string(dir.path().join("run.csv")).unwrap();
        let scenario = crate::Scenario::embedded("figure_eight_rfid_full_stack").unwrap();
        let mut short = scenario.clone();
        short.duration_s = 0.02;
        short.transient_s = 0.0;
        let sim = crate::run(&short, |_, _| {}).unwrap();
        crate::output::write_csv(&dir.path().join("sim.csv"), &sim.records).unwrap();
        let theirs = std::fs::read_to_string(dir.path().join("sim.csv")).unwrap();
        assert_eq!(ours.lines().next(), theirs.lines().next());
    }
}
