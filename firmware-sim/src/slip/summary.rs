//! What a slip run reports: its records ([`SlipRecord`]), the statistics
//! over them ([`SlipSummary`]) and the summary as text.

use std::fmt::Write as _;

use serde::Serialize;

use super::scenario::{Controller, Estimator, SlipScenario};

/// One sample of a run (a CSV row). Wheel speeds and torques of scenario 1
/// are the commanded ones, and its estimate has no wheel speeds (empty
/// cells).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SlipRecord {
    /// Time, s.
    pub t_s: f64,
    /// True `X`, m.
    pub x_m: f64,
    /// True `Y`, m.
    pub y_m: f64,
    /// True `ψ`, rad.
    pub heading_rad: f64,
    /// Estimated `X`, m.
    pub est_x_m: f64,
    /// Estimated `Y`, m.
    pub est_y_m: f64,
    /// Estimated `ψ`, rad.
    pub est_heading_rad: f64,
    /// Estimated `ω_L`, rad/s (scenario 2).
    pub est_left_rad_s: Option<f64>,
    /// Estimated `ω_R`, rad/s (scenario 2).
    pub est_right_rad_s: Option<f64>,
    /// Reference `X_r`, m.
    pub ref_x_m: f64,
    /// Reference `Y_r`, m.
    pub ref_y_m: f64,
    /// Reference `ψ_r`, rad.
    pub ref_heading_rad: f64,
    /// `v_r`, m/s.
    pub ref_v_m_s: f64,
    /// `ω_r`, rad/s.
    pub ref_omega_rad_s: f64,
    /// `e1` (4) of the true pose, m.
    pub e1_m: f64,
    /// `e2`, m.
    pub e2_m: f64,
    /// `e3`, rad.
    pub e3_rad: f64,
    /// `p̂` after this step's update.
    pub slip_estimate: f64,
    /// The true slip ratio `i` over this step.
    pub slip_ratio: f64,
    /// The true `p = 1/(1 − i)`.
    pub slip_factor: f64,
    /// True `ω_L` at `t` (scenario 1: the previous command), rad/s.
    pub left_rad_s: f64,
    /// True `ω_R` at `t`, rad/s.
    pub right_rad_s: f64,
    /// `ω_Ld` (5), rad/s.
    pub left_desired_rad_s: f64,
    /// `ω_Rd`, rad/s.
    pub right_desired_rad_s: f64,
    /// `τ_L` (8), N·m (scenario 2).
    pub torque_left_nm: Option<f64>,
    /// `τ_R`, N·m (scenario 2).
    pub torque_right_nm: Option<f64>,
    /// `|estimated − true position|`, m.
    pub estimate_error_m: f64,
}

/// Tracking errors over a window.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TrackingWindow {
    /// `before_slip`, `during_slip` or `after_slip`.
    pub window: String,
    /// s.
    pub from_s: f64,
    /// s (excluded).
    pub to_s: f64,
    /// Records in the window.
    pub samples: usize,
    /// RMS of `|(e1, e2)|`, m (null: no samples).
    pub position_error_rms_m: Option<f64>,
    /// RMS of `e3`, rad.
    pub heading_error_rms_rad: Option<f64>,
}

/// `p̂` over a window.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SlipEstimateWindow {
    /// `during_slip` or `after_slip`.
    pub window: String,
    /// s.
    pub from_s: f64,
    /// s (excluded).
    pub to_s: f64,
    /// Records in the window.
    pub samples: usize,
    /// Mean `p̂` (null: no samples).
    pub mean_slip_estimate: Option<f64>,
    /// Mean true `p`.
    pub mean_slip_factor: Option<f64>,
}

/// What a run did (`summary.json`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SlipSummary {
    /// Scenario name.
    pub scenario: String,
    /// `velocity` or `torque`.
    pub controller: Controller,
    /// The estimator.
    pub estimator: Estimator,
    /// Noise seed.
    pub seed: u64,
    /// s.
    pub duration_s: f64,
    /// s.
    pub period_s: f64,
    /// Records (one every `record_every_steps` steps).
    pub records: usize,
    /// Tracking errors of the true pose before, during and after the slip.
    pub tracking: Vec<TrackingWindow>,
    /// `p̂` during and after the slip.
    pub slip_estimate: Vec<SlipEstimateWindow>,
    /// `p̂` at the end.
    pub final_slip_estimate: f64,
    /// Mean `|estimated − true position|` over the records, m.
    pub estimate_error_mean_m: f64,
    /// Largest `|estimated − true position|`, m.
    pub estimate_error_max_m: f64,
    /// Records with a non-finite value (a diverged run).
    pub non_finite_records: usize,
    /// Largest tracking error `|(e1, e2)|` of the true pose over the run, m.
    pub tracking_error_max_m: f64,
    /// The run diverged: a non-finite record, or a tracking error above
    /// [`DIVERGED_TRACKING_ERROR_M`] (the paper's runs stay within a few
    /// decimetres; a diverged one stays finite but leaves by tens of
    /// metres, with `p̂` pinned at its bound).
    pub diverged: bool,
}

/// A tracking error above this marks a slip run as diverged, m: ten times
/// the worst error of any converging run of either scenario (the particle
/// filter's, about 1 m RMS after the slip in scenario 2), far below the
/// 60–400 m that diverged runs reach.
pub const DIVERGED_TRACKING_ERROR_M: f64 = 10.0;

/// A run: its records and summary.
#[derive(Debug, Clone, PartialEq)]
pub struct SlipResult {
    /// One every `record_every_steps` steps.
    pub records: Vec<SlipRecord>,
    /// The statistics.
    pub summary: SlipSummary,
}

/// `(RMS, samples)` of `value` over the records with `from ≤ t < to`
/// (RMS `None` without samples).
fn rms_over(
    records: &[SlipRecord],
    from: f64,
    to: f64,
    value: impl Fn(&SlipRecord) -> f64,
) -> (Option<f64>, usize) {
    let (sum, n) = records
        .iter()
        .filter(|r| r.t_s >= from && r.t_s < to)
        .fold((0.0, 0_u32), |(s, n), r| (s + value(r), n + 1));
    ((n > 0).then(|| (sum / f64::from(n)).sqrt()), n as usize)
}

/// RMS of `|(e1, e2)|` over `[from, to)`, m; `None` without records there.
#[must_use]
pub fn position_error_rms(records: &[SlipRecord], from: f64, to: f64) -> Option<f64> {
    rms_over(records, from, to, |r| r.e1_m * r.e1_m + r.e2_m * r.e2_m).0
}

/// RMS of `e3` over `[from, to)`, rad; `None` without records there.
#[must_use]
pub fn heading_error_rms(records: &[SlipRecord], from: f64, to: f64) -> Option<f64> {
    rms_over(records, from, to, |r| r.e3_rad * r.e3_rad).0
}

/// Mean of `value` over `[from, to)`; `None` without records there.
fn mean_over(
    records: &[SlipRecord],
    from: f64,
    to: f64,
    value: impl Fn(&SlipRecord) -> f64,
) -> (Option<f64>, usize) {
    let (sum, n) = records
        .iter()
        .filter(|r| r.t_s >= from && r.t_s < to)
        .fold((0.0, 0_u32), |(s, n), r| (s + value(r), n + 1));
    ((n > 0).then(|| sum / f64::from(n)), n as usize)
}

/// Mean `p̂` over `[from, to)`; `None` without records there.
#[must_use]
pub fn mean_slip_estimate(records: &[SlipRecord], from: f64, to: f64) -> Option<f64> {
    mean_over(records, from, to, |r| r.slip_estimate).0
}

pub(super) fn summarize(scenario: &SlipScenario, records: &[SlipRecord]) -> SlipSummary {
    let w = &scenario.windows;
    let tracking = [
        ("before_slip", w.before_slip_s),
        ("during_slip", w.during_slip_s),
        ("after_slip", w.after_slip_s),
    ]
    .into_iter()
    .map(|(name, [from, to])| {
        let (position, samples) =
            rms_over(records, from, to, |r| r.e1_m * r.e1_m + r.e2_m * r.e2_m);
        TrackingWindow {
            window: name.to_owned(),
            from_s: from,
            to_s: to,
            samples,
            position_error_rms_m: position,
            heading_error_rms_rad: heading_error_rms(records, from, to),
        }
    })
    .collect();
    let slip_estimate = [
        ("during_slip", w.slip_estimate_during_s),
        ("after_slip", w.slip_estimate_after_s),
    ]
    .into_iter()
    .map(|(name, [from, to])| {
        let (mean, samples) = mean_over(records, from, to, |r| r.slip_estimate);
        SlipEstimateWindow {
            window: name.to_owned(),
            from_s: from,
            to_s: to,
            samples,
            mean_slip_estimate: mean,
            mean_slip_factor: mean_over(records, from, to, |r| r.slip_factor).0,
        }
    })
    .collect();
    let errors = records.iter().map(|r| r.estimate_error_m);
    let count = records.len().max(1) as f64;
    let non_finite_records = records.iter().filter(|r| !record_finite(r)).count();
    // NaN-propagating max: a non-finite error makes it non-finite.
    let tracking_error_max_m = records.iter().fold(0.0_f64, |worst, r| {
        let e = r.e1_m.hypot(r.e2_m);
        if e.is_nan() { f64::NAN } else { worst.max(e) }
    });
    SlipSummary {
        scenario: scenario.name.clone(),
        controller: scenario.controller,
        estimator: scenario.estimator,
        seed: scenario.seed,
        duration_s: scenario.duration_s,
        period_s: scenario.period_s,
        records: records.len(),
        tracking,
        slip_estimate,
        final_slip_estimate: records.last().map_or(f64::NAN, |r| r.slip_estimate),
        estimate_error_mean_m: errors.clone().sum::<f64>() / count,
        estimate_error_max_m: errors.fold(0.0, f64::max),
        non_finite_records,
        tracking_error_max_m,
        diverged: non_finite_records > 0
            || tracking_error_max_m.is_nan()
            || tracking_error_max_m > DIVERGED_TRACKING_ERROR_M,
    }
}

fn record_finite(r: &SlipRecord) -> bool {
    [
        r.x_m,
        r.y_m,
        r.heading_rad,
        r.est_x_m,
        r.est_y_m,
        r.est_heading_rad,
        r.e1_m,
        r.e2_m,
        r.e3_rad,
        r.slip_estimate,
        r.left_rad_s,
        r.right_rad_s,
        r.left_desired_rad_s,
        r.right_desired_rad_s,
        r.torque_left_nm.unwrap_or(0.0),
        r.torque_right_nm.unwrap_or(0.0),
    ]
    .iter()
    .all(|v| v.is_finite())
}

/// The summary as text for a terminal.
#[must_use]
pub fn format_slip_summary(s: &SlipSummary) -> String {
    let opt =
        |v: Option<f64>, digits: usize| v.map_or("–".to_owned(), |v| format!("{v:.digits$}"));
    let mut o = String::new();
    let _ = writeln!(o, "scenario      {}", s.scenario);
    let _ = writeln!(
        o,
        "setup         {} control, estimator {}, seed {}, {} s at {} s ({} records)",
        s.controller.name(),
        s.estimator.name(),
        s.seed,
        s.duration_s,
        s.period_s,
        s.records
    );
    for w in &s.tracking {
        let _ = writeln!(
            o,
            "{:<13} {}–{} s: position RMS {} m, heading RMS {} rad",
            w.window.replace('_', " "),
            w.from_s,
            w.to_s,
            opt(w.position_error_rms_m, 4),
            opt(w.heading_error_rms_rad, 4)
        );
    }
    for w in &s.slip_estimate {
        let _ = writeln!(
            o,
            "p̂ {:<11} {}–{} s: mean {} (true p {})",
            w.window.replace('_', " "),
            w.from_s,
            w.to_s,
            opt(w.mean_slip_estimate, 3),
            opt(w.mean_slip_factor, 3)
        );
    }
    let _ = writeln!(
        o,
        "estimate      |x̂ − x| mean {:.4} m, max {:.4} m; final p̂ {:.3}",
        s.estimate_error_mean_m, s.estimate_error_max_m, s.final_slip_estimate
    );
    if s.non_finite_records > 0 {
        let _ = writeln!(
            o,
            "WARNING       {} records with non-finite values (diverged)",
            s.non_finite_records
        );
    } else if s.diverged {
        let _ = writeln!(
            o,
            "WARNING       diverged: tracking error up to {:.1} m (> {} m)",
            s.tracking_error_max_m, DIVERGED_TRACKING_ERROR_M
        );
    }
    o
}
