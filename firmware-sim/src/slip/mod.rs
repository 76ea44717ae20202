//! Paper 004 (Iossaqui, Camino & Zampieri): the tracked robot under
//! longitudinal slip, tracking a piecewise reference with the adaptive
//! velocity-based (scenario 1) or torque-based (scenario 2) controller of
//! `wmr_papers::slip_tracking` on the estimates of the core's EKF, UKF or
//! particle filter, fed with noisy full-state measurements.
//!
//! A [`SlipScenario`] (TOML, its own schema: `firmware-sim slip`, not
//! `run`; its keys listed by `firmware-sim schema --slip`, [`slip_keys`])
//! names the controller, the estimator, the noise seed, the slip
//! schedule, the reference segments, the robot, the gains, the measurement
//! noise and the filters' settings; every key but `name` and `controller`
//! has a default, the paper's value, and the defaults reproduce the paper's
//! two scenarios as [`EMBEDDED_SLIP`] holds them (`paper_004_velocity`,
//! `paper_004_torque`). Unknown keys are errors, and every validation error
//! names the offending field:
//!
//! ```text
//! scenario field `slip[0].slip_ratio`: must be in [0, 1) (got 1)
//! ```
//!
//! # The simulation
//! * the slip ratio `i(t)` steps from 0 to 0.25 during 22.5–45 s (the
//!   schedule is a list of `{start_s, slip_ratio}` steps, `i = 0` before
//!   the first), `p = 1/(1 − i)`;
//! * the plant is integrated in `f64` (RK4, 10 substeps per step, inputs
//!   held): scenario 1's wheel speeds are the commanded ones (no
//!   dynamics), scenario 2's follow `ξ̇ = p M₀⁻¹ τ` from the torques;
//! * the measurement is the full state (scenario 1: `(X, Y, ψ)`; 2: also
//!   `(ω_L, ω_R)`) plus Gaussian noise with the paper's
//!   `R = diag(0.1, 0.1, 0.2, 0.01, 0.01)`, drawn from ChaCha8 seeded with
//!   the scenario's seed (Box–Muller); the noise is drawn even for the
//!   `exact` estimator, so that a seed gives the same draws whatever runs;
//! * the reference (3) is `wmr_papers::slip_tracking::PiecewiseReference`
//!   (the paper's four segments: `v_r` 0.5 m/s until 51 s then 0.7, `ω_r`
//!   0 until 15 s, −0.4 rad/s until 33 s, +0.4 until 51 s, then 0);
//! * `h = 5 ms`, 60 s; the controllers and filters are the core's (`f32`).
//!
//! Choices the paper leaves open, each measured:
//! * the filters start at the known initial state (`x̂0 = E[x0] = q(0)`)
//!   with `P0 = 10 I` (the UKF's heading variance 1 rad²: its circular mean
//!   turns around above ~2 rad²); starting them at 0 made `p̂` jump to
//!   2.5 within 0.1 s on the initial estimate error;
//! * process noise [`PROCESS_NOISE`] (the paper's plant has none; with
//!   `Q = 0` the EKF stopped following the measurements and scenario 1
//!   diverged; 1e-4 and 1e-6 tracked worse);
//! * both scenarios' filters move the pose with the controller's `(v, ω)`
//!   of (6) (see `PoseWheelModel`);
//! * the particle filter's process noise is [`PARTICLE_PROCESS_STD`] (see
//!   there), and its collapse gate is off: from `P0 = 10 I` every particle
//!   is beyond its default 13σ of the first measurement in 5-D, and it
//!   would ignore measurements for ever.
//!
//! Law (7) integrates `k1 e1² + (k3/k2) sin² e3` terms whose mean is
//! positive under estimate noise, so noisier estimates push `p̂` up: the
//! particle filter's do (scenario 1: `p̂` 1.7–8.2), and in scenario 2 the
//! drift, through `p̂` in (8), made 3 of 5 seeded runs diverge.
//!
//! # Outputs
//! [`run()`] gives a [`SlipRecord`] every `record_every_steps` steps (50 ms
//! by default) and a [`SlipSummary`] (RMS tracking errors before, during
//! and after the slip, mean `p̂` during and after it, the estimate error),
//! computed over the records; [`write_outputs`] writes `run.csv`,
//! `summary.json`, `scenario.toml` (the scenario as run) and the plots
//! `errors.png`, `slip.png` and `trajectory.png`.
//!
//! # Files
//! By job, each using only those above it: `filter` (the estimator of a
//! run, [`PARTICLES`], [`PARTICLE_COUNTS`]), `scenario` (the paper's constants, the TOML tables
//! with their defaults, the embedded scenarios), `validate`
//! ([`SlipScenario::validate`] and what a run needs), `summary` (records
//! and statistics), `run` ([`run()`]), `output` ([`write_outputs`]: files
//! and plots); this file parses and loads scenarios. Of the rest of the
//! crate, slip uses only [`crate::scenario`]'s error type, value checks
//! and key tables ([`crate::scenario::keys`]) and [`crate::output`]'s plot
//! helpers.

use std::path::Path;

use crate::scenario::ScenarioError;

mod filter;
mod output;
mod run;
mod scenario;
mod summary;
mod validate;

#[cfg(test)]
mod tests;

pub use filter::{PARTICLE_COUNTS, PARTICLES};
pub use output::{SlipFiles, write_outputs};
pub use run::run;
pub use scenario::{
    Controller, DURATION_S, EMBEDDED_SLIP, Estimator, FilterSpec, GainsSpec, INITIAL_VARIANCE,
    InitialState, MAX_SEGMENTS, MEASUREMENT_VARIANCE, MeasurementSpec, PARTICLE_PROCESS_STD,
    PARTICLE_REGULARIZATION, PERIOD_S, PROCESS_NOISE, ParticleFilterSpec, ProposalSpec,
    ReferenceSpec, RobotSpec, SLIP_RATIO, SLIP_WINDOW_S, SegmentSpec, SlipScenario, SlipStep,
    UKF_INITIAL_VARIANCE, UkfFormSpec, UkfSpec, WindowsSpec, embedded_slip_source, slip_keys,
    slip_ratio, slip_schema,
};
pub use summary::{
    DIVERGED_TRACKING_ERROR_M, SlipEstimateWindow, SlipRecord, SlipResult, SlipSummary,
    TrackingWindow, format_slip_summary, heading_error_rms, mean_slip_estimate, position_error_rms,
};

impl SlipScenario {
    /// Parses and validates a scenario from TOML text.
    ///
    /// # Errors
    /// [`ScenarioError::Parse`] for bad TOML or schema (unknown or missing
    /// keys, wrong types), [`ScenarioError::Invalid`] for bad values.
    pub fn from_toml_str(text: &str) -> Result<Self, ScenarioError> {
        let scenario: Self =
            toml::from_str(text).map_err(|e| ScenarioError::Parse(e.to_string()))?;
        scenario.validate()?;
        Ok(scenario)
    }

    /// Reads, parses and validates a scenario file.
    ///
    /// # Errors
    /// As [`Self::from_toml_str`], plus [`ScenarioError::Io`].
    pub fn from_file(path: &Path) -> Result<Self, ScenarioError> {
        crate::scenario::read_file(path, Self::from_toml_str)
    }

    /// An embedded slip scenario by name (see [`EMBEDDED_SLIP`]).
    ///
    /// # Errors
    /// [`ScenarioError::Invalid`] (field `name`) for an unknown name.
    pub fn embedded(name: &str) -> Result<Self, ScenarioError> {
        let text = embedded_slip_source(name).ok_or_else(|| {
            let names: Vec<&str> = EMBEDDED_SLIP.iter().map(|(n, _)| *n).collect();
            ScenarioError::invalid(
                "name",
                format!(
                    "no embedded slip scenario `{name}` (have: {})",
                    names.join(", ")
                ),
            )
        })?;
        Self::from_toml_str(text)
    }

    /// A file if `arg` is an existing path, else an embedded scenario by
    /// name.
    ///
    /// # Errors
    /// As [`Self::from_file`] and [`Self::embedded`].
    pub fn load(arg: &str) -> Result<Self, ScenarioError> {
        let path = Path::new(arg);
        let a_name = embedded_slip_source(arg).is_some()
            || !(arg.ends_with(".toml") || arg.contains(std::path::MAIN_SEPARATOR));
        if !path.exists() && a_name {
            Self::embedded(arg)
        } else {
            Self::from_file(path)
        }
    }
}
