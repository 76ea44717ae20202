//! Paper 004's two simulation scenarios (Iossaqui, Camino & Zampieri),
//! as the host tests use them: a thin wrapper over the simulator's
//! `firmware_sim::slip`, which holds the model, the documented choices the
//! paper leaves open (filter start, process noise, the particle filter's
//! spread and collapse gate) and what they did. Scenario 1 is the embedded
//! slip scenario `paper_004_velocity`, scenario 2 `paper_004_torque`
//! (`firmware-sim/scenarios/slip/`): the tracked robot under a slip ratio
//! that steps from 0 to 0.25 during 22.5–45 s, the adaptive velocity- or
//! torque-based controller on the estimates of a nonlinear filter fed with
//! noisy full-state measurements (`R` as in the paper), `h = 5 ms`, 60 s.
//! `firmware-sim slip paper_004_velocity --estimator ukf --seed 3 --out
//! DIR` runs one with CSV, summary and plots.

pub use firmware_sim::slip::{
    Controller as Scenario, DURATION_S, Estimator, PARTICLE_PROCESS_STD, PARTICLES, PERIOD_S,
    PROCESS_NOISE, SLIP_RATIO, SLIP_WINDOW_S, SlipRecord, SlipScenario, slip_ratio,
};

use crate::paper_002::Series;

/// A run's time series (every 50 ms) and summary.
#[derive(Debug, Clone, PartialEq)]
pub struct SlipRun {
    /// `e1, e2, e3` (4) of the true pose against the reference.
    pub error: [Series; 3],
    /// `p̂`.
    pub slip_estimate: Series,
    /// `|estimated − true position|`, m.
    pub estimate_error: Series,
    /// `ω_L − ω_Ld`, `ω_R − ω_Rd` of the true wheel speeds (scenario 1:
    /// the previous command against this one).
    pub wheel_error: [Series; 2],
    /// True path `(X, Y)`.
    pub path: Vec<(f64, f64)>,
    /// The simulator's records the series come from.
    pub records: Vec<SlipRecord>,
}

impl SlipRun {
    /// RMS of `|(e1, e2)|` over `[from, to)`, m (0 without samples).
    #[must_use]
    pub fn position_error_rms(&self, from: f64, to: f64) -> f64 {
        firmware_sim::slip::position_error_rms(&self.records, from, to).unwrap_or(0.0)
    }

    /// RMS of `e3` over `[from, to)`, rad (0 without samples).
    #[must_use]
    pub fn heading_error_rms(&self, from: f64, to: f64) -> f64 {
        firmware_sim::slip::heading_error_rms(&self.records, from, to).unwrap_or(0.0)
    }

    /// Mean `p̂` over `[from, to)` (0 without samples).
    #[must_use]
    pub fn mean_slip_estimate(&self, from: f64, to: f64) -> f64 {
        firmware_sim::slip::mean_slip_estimate(&self.records, from, to).unwrap_or(0.0)
    }
}

/// The paper's scenario for a controller (the simulator's embedded file)
/// with an estimator and a noise seed.
///
/// # Panics
/// If an embedded scenario does not validate (the simulator's tests catch
/// that).
#[must_use]
pub fn slip_scenario(scenario: Scenario, estimator: Estimator, seed: u64) -> SlipScenario {
    let name = match scenario {
        Scenario::Velocity => "paper_004_velocity",
        Scenario::Torque => "paper_004_torque",
    };
    let mut s = SlipScenario::embedded(name).expect("embedded slip scenario");
    s.estimator = estimator;
    s.seed = seed;
    s
}

/// Runs a scenario with an estimator and a noise seed.
///
/// # Panics
/// If the embedded scenario is refused.
#[must_use]
pub fn slip_run(scenario: Scenario, estimator: Estimator, seed: u64) -> SlipRun {
    let records = firmware_sim::slip::run(&slip_scenario(scenario, estimator, seed))
        .expect("the embedded scenario runs")
        .records;
    let series = |label: &str, value: fn(&SlipRecord) -> f64| Series {
        label: label.to_owned(),
        points: records.iter().map(|r| (r.t_s, value(r))).collect(),
    };
    SlipRun {
        error: [
            series("e1", |r| r.e1_m),
            series("e2", |r| r.e2_m),
            series("e3", |r| r.e3_rad),
        ],
        slip_estimate: series("p̂", |r| r.slip_estimate),
        estimate_error: series("|estimate − true position|", |r| r.estimate_error_m),
        wheel_error: [
            series("ω_L − ω_Ld", |r| r.left_rad_s - r.left_desired_rad_s),
            series("ω_R − ω_Rd", |r| r.right_rad_s - r.right_desired_rad_s),
        ],
        path: records.iter().map(|r| (r.x_m, r.y_m)).collect(),
        records,
    }
}
