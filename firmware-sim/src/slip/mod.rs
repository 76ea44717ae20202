//! Paper 004 (Iossaqui, Camino & Zampieri): the tracked robot under
//! longitudinal slip, tracking a piecewise reference with the adaptive
//! velocity-based (scenario 1) or torque-based (scenario 2) controller of
//! `wmr_papers::slip_tracking` on the estimates of the core's EKF, UKF or
//! particle filter, fed with noisy full-state measurements.
//!
//! A [`SlipScenario`] (TOML, its own schema: `firmware-sim slip`, not
//! `run`) names the controller, the estimator, the noise seed, the slip
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
//! [`run`] gives a [`SlipRecord`] every `record_every_steps` steps (50 ms
//! by default) and a [`SlipSummary`] (RMS tracking errors before, during
//! and after the slip, mean `p̂` during and after it, the estimate error),
//! computed over the records; [`write_outputs`] writes `run.csv`,
//! `summary.json`, `scenario.toml` (the scenario as run) and the plots
//! `errors.png`, `slip.png` and `trajectory.png`.

use std::f64::consts::{FRAC_PI_4, FRAC_PI_6, PI, TAU};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context as _;
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::output::{FONT, draw_legend, equal_axes, plot_err};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt as _, SeedableRng as _};
use serde::{Deserialize, Serialize};
use wmr_core::filters::ekf::ExtendedKalmanFilter;
use wmr_core::filters::particle_filter::{
    ParticleFilter, ParticleFilterConfig, ParticleFilterError,
};
use wmr_core::filters::ukf::{MerweScaledSigmaPoints, UkfError, UnscentedKalmanFilter};
use wmr_core::geometry::{BodyVelocity, Pose, WheelSpeeds};
use wmr_papers::slip_tracking::{
    AdaptiveTorqueController, AdaptiveVelocityController, P_MAX, PiecewiseReference, PoseModel,
    PoseWheelModel, ReferenceSegment, ReferenceState, SlipGains, SlipTrackingError, TrackedRobot,
    tracking_error,
};

use crate::scenario::{ScenarioError, non_negative, positive};

/// Control and filter step of the paper, s.
pub const PERIOD_S: f64 = 0.005;
/// Simulated time of the paper, s.
pub const DURATION_S: f64 = 60.0;
/// When the paper's slip starts and ends, s.
pub const SLIP_WINDOW_S: (f64, f64) = (22.5, 45.0);
/// The paper's slip ratio during the window.
pub const SLIP_RATIO: f64 = 0.25;
/// Particles of the particle filter (paper: 100). A const generic of the
/// core's `ParticleFilter`: a scenario must ask for exactly this many.
pub const PARTICLES: usize = 100;
/// The filters' process noise per step (variances): position and heading,
/// and (scenario 2) wheel speeds. The paper does not give its `Q` (its
/// plant has none); with `Q = 0` the filters stop listening to the
/// measurements.
pub const PROCESS_NOISE: [f64; 5] = [1e-5, 1e-5, 1e-5, 1e-2, 1e-2];
/// The particle filter's process noise per step (standard deviations). The
/// EKF's `Q` (0.003 per step) leaves 100 particles too few distinct ones
/// after resampling (the cloud cannot follow a heading error back); of the
/// spreads tried (0.003–0.03) this one tracked best in scenario 1.
pub const PARTICLE_PROCESS_STD: [f32; 5] = [0.01, 0.01, 0.02, 0.5, 0.5];
/// The paper's measurement noise `R` (variances of `X, Y` in m², `ψ` in
/// rad², `ω_L, ω_R` in rad²/s²).
pub const MEASUREMENT_VARIANCE: [f64; 5] = [0.1, 0.1, 0.2, 0.01, 0.01];
/// The paper's `P0 = 10 I` (EKF; the particle filter's prior spread is its
/// square root).
pub const INITIAL_VARIANCE: [f64; 5] = [10.0; 5];
/// The UKF's `P0`: the heading's variance 1 rad², not the paper's 10 (the
/// unscented circular mean turns around above ~2 rad², core `ukf` docs).
pub const UKF_INITIAL_VARIANCE: [f64; 5] = [10.0, 10.0, 1.0, 10.0, 10.0];
/// Most reference segments a scenario may have.
pub const MAX_SEGMENTS: usize = 8;

/// The slip scenarios shipped with the simulator, as `(file name, TOML
/// text)`: the paper's scenarios 1 and 2.
pub const EMBEDDED_SLIP: &[(&str, &str)] = &[
    (
        "paper_004_velocity",
        include_str!("../../scenarios/slip/paper_004_velocity.toml"),
    ),
    (
        "paper_004_torque",
        include_str!("../../scenarios/slip/paper_004_torque.toml"),
    ),
];

/// The TOML text of an embedded slip scenario, by file name (without
/// `.toml`).
#[must_use]
pub fn embedded_slip_source(name: &str) -> Option<&'static str> {
    let name = name.strip_suffix(".toml").unwrap_or(name);
    EMBEDDED_SLIP
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, s)| *s)
}

/// The paper's slip ratio `i(t)`: [`SLIP_RATIO`] during [`SLIP_WINDOW_S`].
#[must_use]
pub fn slip_ratio(t: f64) -> f64 {
    ratio_at(&defaults::slip(), t)
}

/// Which adaptive controller (and so which plant and filter state).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Controller {
    /// Scenario 1: adaptive velocity-based control (5)–(7); the wheels
    /// turn at the commanded speeds; filter state `(X, Y, ψ)`.
    Velocity,
    /// Scenario 2: adaptive torque-based control (8)–(10); the wheels
    /// follow the torques; filter state `(X, Y, ψ, ω_L, ω_R)`.
    Torque,
}

impl Controller {
    /// The name used in the TOML file.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Velocity => "velocity",
            Self::Torque => "torque",
        }
    }

    /// Measured (and filtered) state components: 3 or 5.
    #[must_use]
    pub fn measured_states(self) -> usize {
        match self {
            Self::Velocity => 3,
            Self::Torque => 5,
        }
    }
}

/// How the controller gets its state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Estimator {
    /// The true state, no noise (the controllers' own behaviour).
    Exact,
    /// The core's EKF on noisy measurements.
    #[default]
    Ekf,
    /// The core's UKF (paper: α = 0.01, β = 2, κ = 0) on noisy
    /// measurements.
    Ukf,
    /// The core's particle filter ([`PARTICLES`] particles) on noisy
    /// measurements.
    ParticleFilter,
}

impl Estimator {
    /// Every estimator.
    pub const ALL: [Self; 4] = [Self::Exact, Self::Ekf, Self::Ukf, Self::ParticleFilter];

    /// The name used in the TOML file and on the command line.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Exact => "exact",
            Self::Ekf => "ekf",
            Self::Ukf => "ukf",
            Self::ParticleFilter => "particle_filter",
        }
    }
}

impl std::str::FromStr for Estimator {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|e| e.name() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = Self::ALL.iter().map(|e| e.name()).collect();
                format!("unknown estimator `{s}` (have: {})", names.join(", "))
            })
    }
}

/// A slip scenario (the TOML file's top level).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SlipScenario {
    /// Short name (used for the default output directory).
    pub name: String,
    /// Free text.
    #[serde(default)]
    pub description: String,
    /// `velocity` (scenario 1) or `torque` (scenario 2).
    pub controller: Controller,
    /// `exact`, `ekf` (default), `ukf` or `particle_filter`.
    #[serde(default)]
    pub estimator: Estimator,
    /// Seed of the measurement noise (and of the particle filter).
    #[serde(default = "defaults::seed")]
    pub seed: u64,
    /// Simulated time, s (default 60).
    #[serde(default = "defaults::duration_s")]
    pub duration_s: f64,
    /// Control and filter step `h`, s (default 0.005).
    #[serde(default = "defaults::period_s")]
    pub period_s: f64,
    /// RK4 substeps of the plant per step (default 10).
    #[serde(default = "defaults::plant_substeps")]
    pub plant_substeps: u32,
    /// A record (CSV row, and sample of the summary's statistics) every
    /// this many steps (default 10: 50 ms).
    #[serde(default = "defaults::record_every_steps")]
    pub record_every_steps: u32,
    /// Initial pose and wheel speeds; absent: the paper's for the
    /// controller (scenario 1 `(0, −1.5, π/4)`, 2 `(0, −1, π/6, 0, 0)`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub initial: Option<InitialState>,
    /// The slip ratio's steps (`[[slip]]`), in increasing time; 0 before
    /// the first. Default: 0.25 from 22.5 s, 0 from 45 s.
    #[serde(default = "defaults::slip")]
    pub slip: Vec<SlipStep>,
    /// The reference (3).
    #[serde(default)]
    pub reference: ReferenceSpec,
    /// The robot (default the paper's `TrackedRobot::PAPER`).
    #[serde(default)]
    pub robot: RobotSpec,
    /// Controller gains and `p̂(0)` (default `SlipGains::PAPER`, 1).
    #[serde(default)]
    pub gains: GainsSpec,
    /// Measurement noise (default the paper's `R`).
    #[serde(default)]
    pub measurement: MeasurementSpec,
    /// Filter settings.
    #[serde(default)]
    pub filter: FilterSpec,
    /// Windows of the summary's statistics.
    #[serde(default)]
    pub windows: WindowsSpec,
}

/// Initial pose and wheel speeds of the robot (and the filters' `x̂0`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct InitialState {
    /// `X`, m.
    #[serde(default)]
    pub x_m: f64,
    /// `Y`, m.
    #[serde(default)]
    pub y_m: f64,
    /// `ψ`, rad.
    #[serde(default)]
    pub heading_rad: f64,
    /// `ω_L`, rad/s (scenario 2; scenario 1's wheels start at the first
    /// command).
    #[serde(default)]
    pub left_rad_s: f64,
    /// `ω_R`, rad/s.
    #[serde(default)]
    pub right_rad_s: f64,
}

impl InitialState {
    /// The paper's initial state for a controller.
    #[must_use]
    pub fn paper(controller: Controller) -> Self {
        match controller {
            Controller::Velocity => Self {
                x_m: 0.0,
                y_m: -1.5,
                heading_rad: FRAC_PI_4,
                ..Self::default()
            },
            Controller::Torque => Self {
                x_m: 0.0,
                y_m: -1.0,
                heading_rad: FRAC_PI_6,
                ..Self::default()
            },
        }
    }

    fn state(&self) -> [f64; 5] {
        [
            self.x_m,
            self.y_m,
            self.heading_rad,
            self.left_rad_s,
            self.right_rad_s,
        ]
    }
}

/// From `start_s` on, the slip ratio is `slip_ratio`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SlipStep {
    /// s.
    pub start_s: f64,
    /// `i ∈ [0, 1)`.
    pub slip_ratio: f64,
}

/// The reference: a unicycle from a start pose driven by piecewise
/// constant `(v_r, ω_r)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReferenceSpec {
    /// Start `X`, m.
    #[serde(default)]
    pub x_m: f64,
    /// Start `Y`, m.
    #[serde(default)]
    pub y_m: f64,
    /// Start heading, rad.
    #[serde(default)]
    pub heading_rad: f64,
    /// 1 to [`MAX_SEGMENTS`] segments, the first at 0 s, in increasing
    /// time. Default: the paper's four.
    #[serde(default = "defaults::segments")]
    pub segments: Vec<SegmentSpec>,
}

impl Default for ReferenceSpec {
    fn default() -> Self {
        Self {
            x_m: 0.0,
            y_m: 0.0,
            heading_rad: 0.0,
            segments: defaults::segments(),
        }
    }
}

/// One constant-input piece of the reference.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SegmentSpec {
    /// Start time, s.
    pub start_s: f64,
    /// `v_r`, m/s.
    pub v_m_s: f64,
    /// `ω_r`, rad/s.
    pub omega_rad_s: f64,
}

/// The tracked robot (default: the paper's, `b = 0.65 m, r = 0.35 m,
/// m = 0.80 kg, J = 0.0608 kg m²`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotSpec {
    /// `r`, m.
    #[serde(default = "defaults::wheel_radius_m")]
    pub wheel_radius_m: f64,
    /// `b`, m.
    #[serde(default = "defaults::track_width_m")]
    pub track_width_m: f64,
    /// `m`, kg.
    #[serde(default = "defaults::mass_kg")]
    pub mass_kg: f64,
    /// `J`, kg m².
    #[serde(default = "defaults::yaw_inertia_kg_m2")]
    pub yaw_inertia_kg_m2: f64,
}

impl Default for RobotSpec {
    fn default() -> Self {
        Self {
            wheel_radius_m: defaults::wheel_radius_m(),
            track_width_m: defaults::track_width_m(),
            mass_kg: defaults::mass_kg(),
            yaw_inertia_kg_m2: defaults::yaw_inertia_kg_m2(),
        }
    }
}

/// Gains of (5)–(7) and (9) (default the paper's: `k1 = k3 = 6, k2 = 8,
/// k4 = k5 = 4, ρ = 3`) and `p̂(0)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GainsSpec {
    /// `k1`, 1/s.
    #[serde(default = "defaults::k1")]
    pub k1: f64,
    /// `k2`.
    #[serde(default = "defaults::k2")]
    pub k2: f64,
    /// `k3`, 1/s.
    #[serde(default = "defaults::k3")]
    pub k3: f64,
    /// `k4` of (9), 1/s.
    #[serde(default = "defaults::k45")]
    pub k4: f64,
    /// `k5` of (9), 1/s.
    #[serde(default = "defaults::k45")]
    pub k5: f64,
    /// `ρ` of (7).
    #[serde(default = "defaults::rho")]
    pub rho: f64,
    /// `p̂(0)`, in `[1, P_MAX]` (paper: 1).
    #[serde(default = "defaults::initial_slip_estimate")]
    pub initial_slip_estimate: f64,
}

impl Default for GainsSpec {
    fn default() -> Self {
        Self {
            k1: defaults::k1(),
            k2: defaults::k2(),
            k3: defaults::k3(),
            k4: defaults::k45(),
            k5: defaults::k45(),
            rho: defaults::rho(),
            initial_slip_estimate: defaults::initial_slip_estimate(),
        }
    }
}

/// Gaussian noise on the measured state.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeasurementSpec {
    /// Variances of `X, Y` (m²), `ψ` (rad²), `ω_L, ω_R` (rad²/s²): the
    /// noise drawn and the filters' `R` (scenario 1 uses the first three).
    #[serde(default = "defaults::measurement_variance")]
    pub variance: [f64; 5],
}

impl Default for MeasurementSpec {
    fn default() -> Self {
        Self {
            variance: MEASUREMENT_VARIANCE,
        }
    }
}

/// The filters' settings (scenario 1 uses the first three entries of each
/// array).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FilterSpec {
    /// EKF `P0` diagonal; the particle filter's prior spread is its square
    /// root (default 10 each).
    #[serde(default = "defaults::initial_variance")]
    pub initial_variance: [f64; 5],
    /// EKF and UKF process noise `Q` per step, diagonal (default
    /// [`PROCESS_NOISE`]).
    #[serde(default = "defaults::process_noise")]
    pub process_noise: [f64; 5],
    /// The UKF's own settings.
    #[serde(default)]
    pub ukf: UkfSpec,
    /// The particle filter's own settings.
    #[serde(default)]
    pub particle_filter: ParticleFilterSpec,
}

impl Default for FilterSpec {
    fn default() -> Self {
        Self {
            initial_variance: INITIAL_VARIANCE,
            process_noise: PROCESS_NOISE,
            ukf: UkfSpec::default(),
            particle_filter: ParticleFilterSpec::default(),
        }
    }
}

/// The UKF's sigma points and `P0`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UkfSpec {
    /// `α` (paper 0.01).
    #[serde(default = "defaults::alpha")]
    pub alpha: f64,
    /// `β` (paper 2).
    #[serde(default = "defaults::beta")]
    pub beta: f64,
    /// `κ` (paper 0).
    #[serde(default)]
    pub kappa: f64,
    /// `P0` diagonal (default [`UKF_INITIAL_VARIANCE`]).
    #[serde(default = "defaults::ukf_initial_variance")]
    pub initial_variance: [f64; 5],
}

impl Default for UkfSpec {
    fn default() -> Self {
        Self {
            alpha: defaults::alpha(),
            beta: defaults::beta(),
            kappa: 0.0,
            initial_variance: UKF_INITIAL_VARIANCE,
        }
    }
}

/// The particle filter's settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParticleFilterSpec {
    /// Must be [`PARTICLES`] (a const generic of the core's filter).
    #[serde(default = "defaults::particles")]
    pub particles: usize,
    /// Process noise per step, standard deviations (default
    /// [`PARTICLE_PROCESS_STD`]).
    #[serde(default = "defaults::particle_process_std")]
    pub process_std: [f64; 5],
    /// Collapse gate on the best particle's squared normalised residual
    /// (default `inf`: off).
    #[serde(default = "defaults::collapse_gate")]
    pub collapse_gate: f64,
}

impl Default for ParticleFilterSpec {
    fn default() -> Self {
        Self {
            particles: PARTICLES,
            process_std: defaults::particle_process_std(),
            collapse_gate: defaults::collapse_gate(),
        }
    }
}

/// The summary's windows, `[from, to)` in s.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WindowsSpec {
    /// Tracking errors before the slip (default 15–22.5 s).
    #[serde(default = "defaults::before_slip_s")]
    pub before_slip_s: [f64; 2],
    /// Tracking errors during the slip (default 25–45 s).
    #[serde(default = "defaults::during_slip_s")]
    pub during_slip_s: [f64; 2],
    /// Tracking errors after the slip (default 50–60 s).
    #[serde(default = "defaults::after_slip_s")]
    pub after_slip_s: [f64; 2],
    /// Mean `p̂` during the slip (default 35–45 s).
    #[serde(default = "defaults::slip_estimate_during_s")]
    pub slip_estimate_during_s: [f64; 2],
    /// Mean `p̂` after the slip (default 55–60 s).
    #[serde(default = "defaults::slip_estimate_after_s")]
    pub slip_estimate_after_s: [f64; 2],
}

impl Default for WindowsSpec {
    fn default() -> Self {
        Self {
            before_slip_s: defaults::before_slip_s(),
            during_slip_s: defaults::during_slip_s(),
            after_slip_s: defaults::after_slip_s(),
            slip_estimate_during_s: defaults::slip_estimate_during_s(),
            slip_estimate_after_s: defaults::slip_estimate_after_s(),
        }
    }
}

/// Serde defaults: the paper's values.
mod defaults {
    use super::{PARTICLES, SLIP_RATIO, SLIP_WINDOW_S, SegmentSpec, SlipStep};

    pub fn seed() -> u64 {
        1
    }
    pub fn duration_s() -> f64 {
        super::DURATION_S
    }
    pub fn period_s() -> f64 {
        super::PERIOD_S
    }
    pub fn plant_substeps() -> u32 {
        10
    }
    pub fn record_every_steps() -> u32 {
        10
    }
    pub fn slip() -> Vec<SlipStep> {
        vec![
            SlipStep {
                start_s: SLIP_WINDOW_S.0,
                slip_ratio: SLIP_RATIO,
            },
            SlipStep {
                start_s: SLIP_WINDOW_S.1,
                slip_ratio: 0.0,
            },
        ]
    }
    pub fn segments() -> Vec<SegmentSpec> {
        let segment = |start_s, v_m_s, omega_rad_s| SegmentSpec {
            start_s,
            v_m_s,
            omega_rad_s,
        };
        vec![
            segment(0.0, 0.5, 0.0),
            segment(15.0, 0.5, -0.4),
            segment(33.0, 0.5, 0.4),
            segment(51.0, 0.7, 0.0),
        ]
    }
    pub fn wheel_radius_m() -> f64 {
        0.35
    }
    pub fn track_width_m() -> f64 {
        0.65
    }
    pub fn mass_kg() -> f64 {
        0.80
    }
    pub fn yaw_inertia_kg_m2() -> f64 {
        0.0608
    }
    pub fn k1() -> f64 {
        6.0
    }
    pub fn k2() -> f64 {
        8.0
    }
    pub fn k3() -> f64 {
        6.0
    }
    pub fn k45() -> f64 {
        4.0
    }
    pub fn rho() -> f64 {
        3.0
    }
    pub fn initial_slip_estimate() -> f64 {
        1.0
    }
    pub fn measurement_variance() -> [f64; 5] {
        super::MEASUREMENT_VARIANCE
    }
    pub fn initial_variance() -> [f64; 5] {
        super::INITIAL_VARIANCE
    }
    pub fn process_noise() -> [f64; 5] {
        super::PROCESS_NOISE
    }
    pub fn alpha() -> f64 {
        0.01
    }
    pub fn beta() -> f64 {
        2.0
    }
    pub fn ukf_initial_variance() -> [f64; 5] {
        super::UKF_INITIAL_VARIANCE
    }
    pub fn particles() -> usize {
        PARTICLES
    }
    pub fn particle_process_std() -> [f64; 5] {
        // `PARTICLE_PROCESS_STD` as decimals, not `f64::from` of its `f32`s
        // (the file form prints them as written; a test checks that they
        // round to the constant).
        [0.01, 0.01, 0.02, 0.5, 0.5]
    }
    pub fn collapse_gate() -> f64 {
        f64::INFINITY
    }
    pub fn before_slip_s() -> [f64; 2] {
        [15.0, 22.5]
    }
    pub fn during_slip_s() -> [f64; 2] {
        [25.0, 45.0]
    }
    pub fn after_slip_s() -> [f64; 2] {
        [50.0, 60.0]
    }
    pub fn slip_estimate_during_s() -> [f64; 2] {
        [35.0, 45.0]
    }
    pub fn slip_estimate_after_s() -> [f64; 2] {
        [55.0, 60.0]
    }
}

/// The slip ratio of `steps` at `t`: the last step started at or before
/// `t`, 0 before the first.
fn ratio_at(steps: &[SlipStep], t: f64) -> f64 {
    steps
        .iter()
        .take_while(|s| s.start_s <= t)
        .last()
        .map_or(0.0, |s| s.slip_ratio)
}

fn finite(field: &str, v: f64) -> Result<f64, ScenarioError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(ScenarioError::invalid(
            field,
            format!("must be finite (got {v})"),
        ))
    }
}

fn positive_array<const N: usize>(
    field: &str,
    values: &[f64; N],
) -> Result<[f32; N], ScenarioError> {
    let mut out = [0.0; N];
    for (i, (o, &v)) in out.iter_mut().zip(values).enumerate() {
        *o = positive(&format!("{field}[{i}]"), v)? as f32;
    }
    Ok(out)
}

fn non_negative_array<const N: usize>(
    field: &str,
    values: &[f64; N],
) -> Result<[f32; N], ScenarioError> {
    let mut out = [0.0; N];
    for (i, (o, &v)) in out.iter_mut().zip(values).enumerate() {
        *o = non_negative(&format!("{field}[{i}]"), v)? as f32;
    }
    Ok(out)
}

fn window(field: &str, w: [f64; 2]) -> Result<(), ScenarioError> {
    let [from, to] = w;
    if !(from.is_finite() && to.is_finite() && from >= 0.0 && from < to) {
        return Err(ScenarioError::invalid(
            field,
            format!("must be [from, to] with 0 ≤ from < to, finite (got [{from}, {to}])"),
        ));
    }
    Ok(())
}

/// A diagonal matrix as nested arrays (column-major, as `nalgebra`'s
/// `From<[[T; R]; C]>` takes them).
fn diag<const N: usize>(d: [f32; N]) -> [[f32; N]; N] {
    let mut m = [[0.0; N]; N];
    for (i, row) in m.iter_mut().enumerate() {
        row[i] = d[i];
    }
    m
}

fn first<const N: usize>(a: [f32; 5]) -> [f32; N] {
    std::array::from_fn(|i| a[i])
}

/// The reference sampler: `PiecewiseReference<K>` for the scenario's `K`.
type Sampler = Box<dyn Fn(f32) -> ReferenceState + Send + Sync>;

fn sampler<const K: usize>(
    start: Pose,
    segments: &[ReferenceSegment],
) -> Result<Sampler, SlipTrackingError> {
    let segments: [ReferenceSegment; K] = segments
        .try_into()
        .map_err(|_| SlipTrackingError::Reference)?;
    let reference = PiecewiseReference::<K>::new(start, segments)?;
    Ok(Box::new(move |t| reference.sample(t)))
}

/// The state estimator of a run.
// One per run: the size difference between the variants does not matter.
#[allow(clippy::large_enum_variant)]
enum Filter {
    Exact,
    Ekf3(ExtendedKalmanFilter<PoseModel, 3, 3>),
    Ekf5(ExtendedKalmanFilter<PoseWheelModel, 5, 5>),
    Ukf3(UnscentedKalmanFilter<PoseModel, 3, 3, 7>),
    Ukf5(UnscentedKalmanFilter<PoseWheelModel, 5, 5, 11>),
    Pf3(Box<ParticleFilter<PoseModel, 3, 3, PARTICLES>>),
    Pf5(Box<ParticleFilter<PoseWheelModel, 5, 5, PARTICLES>>),
}

impl Filter {
    /// Updates on a measurement; the estimate (the truth for `Exact`;
    /// zero wheel speeds for the 3-state filters).
    fn update(&mut self, truth: &[f64; 5], z: &[f32; 5]) -> [f64; 5] {
        let three = |e: [f32; 3]| [f64::from(e[0]), f64::from(e[1]), f64::from(e[2]), 0.0, 0.0];
        let five = |e: [f32; 5]| e.map(f64::from);
        match self {
            Self::Exact => *truth,
            Self::Ekf3(f) => {
                f.update(&first::<3>(*z).into());
                let s = f.state();
                three([s[0], s[1], s[2]])
            }
            Self::Ekf5(f) => {
                f.update(&(*z).into());
                let s = f.state();
                five([s[0], s[1], s[2], s[3], s[4]])
            }
            Self::Ukf3(f) => {
                f.update(&first::<3>(*z).into());
                let s = f.state();
                three([s[0], s[1], s[2]])
            }
            Self::Ukf5(f) => {
                f.update(&(*z).into());
                let s = f.state();
                five([s[0], s[1], s[2], s[3], s[4]])
            }
            Self::Pf3(f) => {
                f.update(&first::<3>(*z).into());
                let s = f.estimate();
                three([s[0], s[1], s[2]])
            }
            Self::Pf5(f) => {
                f.update(&(*z).into());
                let s = f.estimate();
                five([s[0], s[1], s[2], s[3], s[4]])
            }
        }
    }

    fn predict(&mut self, u: &BodyVelocity, h: f32) {
        match self {
            Self::Exact => {}
            Self::Ekf3(f) => f.predict(u, h),
            Self::Ekf5(f) => f.predict(u, h),
            Self::Ukf3(f) => {
                f.predict(u, h);
            }
            Self::Ukf5(f) => {
                f.predict(u, h);
            }
            Self::Pf3(f) => f.predict(u, h),
            Self::Pf5(f) => f.predict(u, h),
        }
    }
}

fn ukf_field(e: UkfError) -> ScenarioError {
    let (field, what) = match e {
        UkfError::Alpha => ("filter.ukf.alpha", "must be finite and > 0"),
        UkfError::Beta => ("filter.ukf.beta", "must be finite"),
        UkfError::Kappa => ("filter.ukf.kappa", "must be finite with n + κ > 0"),
        UkfError::Spread => ("filter.ukf.alpha", "gives non-finite sigma-point weights"),
        UkfError::InitialCovariance => ("filter.ukf.initial_variance", "refused"),
        UkfError::ProcessNoise => ("filter.process_noise", "refused"),
        UkfError::MeasurementNoise => ("measurement.variance", "refused"),
        _ => ("filter.ukf", "refused"),
    };
    ScenarioError::invalid(field, format!("{what} (the core's UKF: {e:?})"))
}

fn pf_field(e: ParticleFilterError) -> ScenarioError {
    let field = match e {
        ParticleFilterError::ProcessStd => "filter.particle_filter.process_std",
        ParticleFilterError::MeasurementStd => "measurement.variance",
        ParticleFilterError::CollapseGate => "filter.particle_filter.collapse_gate",
        ParticleFilterError::PriorStd => "filter.initial_variance",
        ParticleFilterError::PriorMean => "initial",
        _ => "filter.particle_filter",
    };
    ScenarioError::invalid(
        field,
        format!("refused by the core's particle filter: {e:?}"),
    )
}

/// A validated scenario, ready to run.
struct Setup {
    robot: TrackedRobot,
    velocity: AdaptiveVelocityController,
    reference: Sampler,
    filter: Filter,
    initial: [f64; 5],
    steps: u32,
}

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

    /// The scenario as TOML.
    ///
    /// # Errors
    /// Never for a scenario that was parsed (all values representable).
    pub fn to_toml_string(&self) -> Result<String, toml::ser::Error> {
        toml::to_string_pretty(self)
    }

    /// The initial state (the paper's for the controller if not given).
    #[must_use]
    pub fn initial_state(&self) -> InitialState {
        self.initial
            .unwrap_or_else(|| InitialState::paper(self.controller))
    }

    /// Checks every value (the filters' settings too, whichever estimator
    /// runs).
    ///
    /// # Errors
    /// [`ScenarioError::Invalid`] naming the first bad field.
    pub fn validate(&self) -> Result<(), ScenarioError> {
        self.setup().map(|_| ())
    }

    fn setup(&self) -> Result<Setup, ScenarioError> {
        if self.name.trim().is_empty() {
            return Err(ScenarioError::invalid("name", "must not be empty"));
        }
        let duration_s = positive("duration_s", self.duration_s)?;
        let period_s = positive("period_s", self.period_s)?;
        let steps = (duration_s / period_s).round();
        if steps < 1.0 || steps >= f64::from(u32::MAX) {
            return Err(ScenarioError::invalid(
                "duration_s",
                format!("gives {steps} steps of {period_s} s; need 1 ..= 2^32 − 2"),
            ));
        }
        if self.plant_substeps == 0 {
            return Err(ScenarioError::invalid("plant_substeps", "must be ≥ 1"));
        }
        if self.record_every_steps == 0 {
            return Err(ScenarioError::invalid("record_every_steps", "must be ≥ 1"));
        }
        let initial = self.initial_state();
        for (key, v) in [
            ("x_m", initial.x_m),
            ("y_m", initial.y_m),
            ("heading_rad", initial.heading_rad),
            ("left_rad_s", initial.left_rad_s),
            ("right_rad_s", initial.right_rad_s),
        ] {
            finite(&format!("initial.{key}"), v)?;
        }
        let mut previous: Option<f64> = None;
        for (k, step) in self.slip.iter().enumerate() {
            let start = non_negative(&format!("slip[{k}].start_s"), step.start_s)?;
            if let Some(p) = previous.filter(|&p| start <= p) {
                return Err(ScenarioError::invalid(
                    &format!("slip[{k}].start_s"),
                    format!(
                        "must be later than slip[{}].start_s ({p} s): steps in increasing \
                         time (got {start})",
                        k - 1
                    ),
                ));
            }
            previous = Some(start);
            let i = step.slip_ratio;
            if !(i.is_finite() && (0.0..1.0).contains(&i)) {
                return Err(ScenarioError::invalid(
                    &format!("slip[{k}].slip_ratio"),
                    format!("must be in [0, 1) (got {i})"),
                ));
            }
        }
        let reference = self.reference_sampler()?;
        let r = &self.robot;
        let robot = TrackedRobot::new(
            positive("robot.wheel_radius_m", r.wheel_radius_m)? as f32,
            positive("robot.track_width_m", r.track_width_m)? as f32,
            positive("robot.mass_kg", r.mass_kg)? as f32,
            positive("robot.yaw_inertia_kg_m2", r.yaw_inertia_kg_m2)? as f32,
        )
        .map_err(|e| ScenarioError::invalid("robot", format!("refused by the core: {e:?}")))?;
        if robot.wheel_inertia().try_inverse().is_none() {
            return Err(ScenarioError::invalid(
                "robot",
                "the wheel inertia M0 is singular",
            ));
        }
        let g = &self.gains;
        let gains = SlipGains::new(
            positive("gains.k1", g.k1)? as f32,
            positive("gains.k2", g.k2)? as f32,
            positive("gains.k3", g.k3)? as f32,
            positive("gains.k4", g.k4)? as f32,
            positive("gains.k5", g.k5)? as f32,
            positive("gains.rho", g.rho)? as f32,
        )
        .map_err(|e| ScenarioError::invalid("gains", format!("refused by the core: {e:?}")))?;
        let p0 = g.initial_slip_estimate;
        if !(p0.is_finite() && (1.0..=f64::from(P_MAX)).contains(&p0)) {
            return Err(ScenarioError::invalid(
                "gains.initial_slip_estimate",
                format!("must be in [1, {P_MAX}] (got {p0})"),
            ));
        }
        let velocity = AdaptiveVelocityController::new(robot, gains, period_s as f32, p0 as f32)
            .map_err(|e| {
                ScenarioError::invalid("period_s", format!("refused by the core: {e:?}"))
            })?;
        let w = &self.windows;
        window("windows.before_slip_s", w.before_slip_s)?;
        window("windows.during_slip_s", w.during_slip_s)?;
        window("windows.after_slip_s", w.after_slip_s)?;
        window("windows.slip_estimate_during_s", w.slip_estimate_during_s)?;
        window("windows.slip_estimate_after_s", w.slip_estimate_after_s)?;
        let filter = self.filter(&initial.state())?;
        Ok(Setup {
            robot,
            velocity,
            reference,
            filter,
            initial: initial.state(),
            steps: steps as u32,
        })
    }

    fn reference_sampler(&self) -> Result<Sampler, ScenarioError> {
        let r = &self.reference;
        let start = Pose::new(
            finite("reference.x_m", r.x_m)? as f32,
            finite("reference.y_m", r.y_m)? as f32,
            finite("reference.heading_rad", r.heading_rad)? as f32,
        );
        let n = r.segments.len();
        if n == 0 || n > MAX_SEGMENTS {
            return Err(ScenarioError::invalid(
                "reference.segments",
                format!("must have 1 to {MAX_SEGMENTS} segments (got {n})"),
            ));
        }
        let mut segments = Vec::with_capacity(n);
        for (k, s) in r.segments.iter().enumerate() {
            let field = |key: &str| format!("reference.segments[{k}].{key}");
            let start_s = finite(&field("start_s"), s.start_s)?;
            if k == 0 && start_s != 0.0 {
                return Err(ScenarioError::invalid(
                    &field("start_s"),
                    format!("the first segment must start at 0 s (got {start_s})"),
                ));
            }
            if let Some(p) = k.checked_sub(1).and_then(|j| segments.get(j)) {
                let p: &ReferenceSegment = p;
                if start_s as f32 <= p.start_s {
                    return Err(ScenarioError::invalid(
                        &field("start_s"),
                        format!(
                            "must be later than segment {}'s ({} s) (got {start_s})",
                            k - 1,
                            p.start_s
                        ),
                    ));
                }
            }
            segments.push(ReferenceSegment {
                start_s: start_s as f32,
                v_m_s: finite(&field("v_m_s"), s.v_m_s)? as f32,
                omega_rad_s: finite(&field("omega_rad_s"), s.omega_rad_s)? as f32,
            });
        }
        let built = match n {
            1 => sampler::<1>(start, &segments),
            2 => sampler::<2>(start, &segments),
            3 => sampler::<3>(start, &segments),
            4 => sampler::<4>(start, &segments),
            5 => sampler::<5>(start, &segments),
            6 => sampler::<6>(start, &segments),
            7 => sampler::<7>(start, &segments),
            _ => sampler::<MAX_SEGMENTS>(start, &segments),
        };
        built.map_err(|e| {
            ScenarioError::invalid("reference.segments", format!("refused by the core: {e:?}"))
        })
    }

    /// Checks every filter setting and builds the estimator that runs.
    fn filter(&self, x0: &[f64; 5]) -> Result<Filter, ScenarioError> {
        let f = &self.filter;
        let r = positive_array("measurement.variance", &self.measurement.variance)?;
        let std_r = self.measurement.variance.map(|v| v.sqrt() as f32);
        let p0 = positive_array("filter.initial_variance", &f.initial_variance)?;
        let q = non_negative_array("filter.process_noise", &f.process_noise)?;
        let p0_ukf = positive_array("filter.ukf.initial_variance", &f.ukf.initial_variance)?;
        let (alpha, beta, kappa) = (f.ukf.alpha as f32, f.ukf.beta as f32, f.ukf.kappa as f32);
        let pf = &f.particle_filter;
        if pf.particles != PARTICLES {
            return Err(ScenarioError::invalid(
                "filter.particle_filter.particles",
                format!(
                    "must be {PARTICLES} (got {}): the particle count is a const generic of \
                     the core's ParticleFilter, fixed when the simulator is built",
                    pf.particles
                ),
            ));
        }
        let process_std =
            non_negative_array("filter.particle_filter.process_std", &pf.process_std)?;
        let gate = pf.collapse_gate;
        if gate.is_nan() || gate <= 0.0 {
            return Err(ScenarioError::invalid(
                "filter.particle_filter.collapse_gate",
                format!("must be > 0 (inf: off) (got {gate})"),
            ));
        }
        let gate = gate as f32;
        let prior = p0.map(f32::sqrt);
        let x0 = x0.map(|x| x as f32);
        let ekf_field = |e| {
            ScenarioError::invalid(
                "filter",
                format!("the core's EKF refused P0, Q or R: {e:?}"),
            )
        };
        // Every filter is built (so that every setting is checked); the one
        // that runs is kept.
        let ekf3 = ExtendedKalmanFilter::new(
            PoseModel,
            first::<3>(x0).into(),
            diag(first::<3>(p0)).into(),
            diag(first::<3>(q)).into(),
            diag(first::<3>(r)).into(),
        )
        .map_err(ekf_field)?;
        let ekf5 = ExtendedKalmanFilter::new(
            PoseWheelModel,
            x0.into(),
            diag(p0).into(),
            diag(q).into(),
            diag(r).into(),
        )
        .map_err(ekf_field)?;
        let ukf3 = UnscentedKalmanFilter::<_, 3, 3, 7>::new(
            PoseModel,
            MerweScaledSigmaPoints::new(alpha, beta, kappa).map_err(ukf_field)?,
            first::<3>(x0).into(),
            diag(first::<3>(p0_ukf)).into(),
            diag(first::<3>(q)).into(),
            diag(first::<3>(r)).into(),
        )
        .map_err(ukf_field)?;
        let ukf5 = UnscentedKalmanFilter::<_, 5, 5, 11>::new(
            PoseWheelModel,
            MerweScaledSigmaPoints::new(alpha, beta, kappa).map_err(ukf_field)?,
            x0.into(),
            diag(p0_ukf).into(),
            diag(q).into(),
            diag(r).into(),
        )
        .map_err(ukf_field)?;
        let pf3 = ParticleFilter::<_, 3, 3, PARTICLES>::new(
            PoseModel,
            ParticleFilterConfig::new(first::<3>(process_std).into(), first::<3>(std_r).into())
                .and_then(|c| c.with_collapse_gate(gate))
                .map_err(pf_field)?,
            first::<3>(x0).into(),
            first::<3>(prior).into(),
            self.seed,
        )
        .map_err(pf_field)?;
        let pf5 = ParticleFilter::<_, 5, 5, PARTICLES>::new(
            PoseWheelModel,
            ParticleFilterConfig::new(process_std.into(), std_r.into())
                .and_then(|c| c.with_collapse_gate(gate))
                .map_err(pf_field)?,
            x0.into(),
            prior.into(),
            self.seed,
        )
        .map_err(pf_field)?;
        Ok(match (self.estimator, self.controller) {
            (Estimator::Exact, _) => Filter::Exact,
            (Estimator::Ekf, Controller::Velocity) => Filter::Ekf3(ekf3),
            (Estimator::Ekf, Controller::Torque) => Filter::Ekf5(ekf5),
            (Estimator::Ukf, Controller::Velocity) => Filter::Ukf3(ukf3),
            (Estimator::Ukf, Controller::Torque) => Filter::Ukf5(ukf5),
            (Estimator::ParticleFilter, Controller::Velocity) => Filter::Pf3(Box::new(pf3)),
            (Estimator::ParticleFilter, Controller::Torque) => Filter::Pf5(Box::new(pf5)),
        })
    }
}

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

/// A standard normal draw (Box–Muller).
fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
    let radius = (-2.0 * (1.0 - rng.random::<f64>()).ln()).sqrt();
    radius * (TAU * rng.random::<f64>()).cos()
}

/// The plant: wheel radius and track (`f64`) and `M₀⁻¹` (from the core's
/// `f32` `M₀`).
struct Plant {
    r: f64,
    b: f64,
    inverse_inertia: [[f64; 2]; 2],
}

impl Plant {
    /// The state rate `(Ẋ, Ẏ, ψ̇, ω̇_L, ω̇_R)` for held wheel speeds
    /// (scenario 1: no wheel dynamics) or torques.
    fn rate(&self, s: &[f64; 5], p: f64, torque: Option<[f64; 2]>) -> [f64; 5] {
        let (r, b) = (self.r, self.b);
        let (wl, wr) = (s[3], s[4]);
        let v = r * (wl + wr) / (2.0 * p);
        let w = r * (wr - wl) / (b * p);
        let m = &self.inverse_inertia;
        let accel = torque.map_or([0.0; 2], |tau| {
            [
                (m[0][0] * tau[0] + m[0][1] * tau[1]) * p,
                (m[1][0] * tau[0] + m[1][1] * tau[1]) * p,
            ]
        });
        [v * s[2].cos(), v * s[2].sin(), w, accel[0], accel[1]]
    }

    fn rk4(&self, s: &[f64; 5], p: f64, torque: Option<[f64; 2]>, dt: f64) -> [f64; 5] {
        let f = |s: &[f64; 5]| self.rate(s, p, torque);
        let step = |k: &[f64; 5], c: f64| std::array::from_fn(|i| s[i] + k[i] * c);
        let k1 = f(s);
        let k2 = f(&step(&k1, dt / 2.0));
        let k3 = f(&step(&k2, dt / 2.0));
        let k4 = f(&step(&k3, dt));
        std::array::from_fn(|i| s[i] + (k1[i] + k2[i] * 2.0 + k3[i] * 2.0 + k4[i]) * (dt / 6.0))
    }
}

fn wrap(a: f64) -> f64 {
    let w = (a + PI).rem_euclid(TAU) - PI;
    if w <= -PI { w + TAU } else { w }
}

/// Runs a scenario.
///
/// # Errors
/// [`ScenarioError::Invalid`] naming the first bad field.
pub fn run(scenario: &SlipScenario) -> Result<SlipResult, ScenarioError> {
    let Setup {
        robot,
        velocity,
        reference,
        mut filter,
        initial,
        steps,
    } = scenario.setup()?;
    let inverse = robot
        .wheel_inertia()
        .map(f64::from)
        .try_inverse()
        .ok_or_else(|| ScenarioError::invalid("robot", "the wheel inertia M0 is singular"))?;
    let plant = Plant {
        r: scenario.robot.wheel_radius_m,
        b: scenario.robot.track_width_m,
        inverse_inertia: [
            [inverse[(0, 0)], inverse[(0, 1)]],
            [inverse[(1, 0)], inverse[(1, 1)]],
        ],
    };
    let controller = scenario.controller;
    let period_s = scenario.period_s;
    let h = period_s as f32;
    let substep_s = period_s / f64::from(scenario.plant_substeps);
    let mut velocity_controller = velocity;
    let mut torque_controller = AdaptiveTorqueController::new(velocity);
    let mut rng = ChaCha8Rng::seed_from_u64(scenario.seed);
    let noise_std = scenario.measurement.variance.map(f64::sqrt);
    let n = controller.measured_states();
    let mut state = initial;
    let mut records = Vec::with_capacity((steps / scenario.record_every_steps) as usize + 1);
    for k in 0..steps {
        let t = f64::from(k) * period_s;
        let slip_ratio = ratio_at(&scenario.slip, t);
        let p = 1.0 / (1.0 - slip_ratio);
        let mut measured = state;
        for (i, m) in measured.iter_mut().enumerate().take(n) {
            *m += noise_std[i] * gaussian(&mut rng);
        }
        let estimate = filter.update(&state, &measured.map(|x| x as f32));
        let pose = Pose::new(estimate[0] as f32, estimate[1] as f32, estimate[2] as f32);
        let target = reference(t as f32);
        let true_pose = Pose::new(state[0] as f32, state[1] as f32, state[2] as f32);
        let true_error = tracking_error(&true_pose, &target.pose);
        let (torque, control) = match controller {
            Controller::Velocity => (None, velocity_controller.step(&target, &pose)),
            Controller::Torque => {
                let wheels = WheelSpeeds {
                    left_rad_s: estimate[3] as f32,
                    right_rad_s: estimate[4] as f32,
                };
                let c = torque_controller.step(&target, &pose, wheels);
                (
                    Some([f64::from(c.torque[0]), f64::from(c.torque[1])]),
                    c.velocity,
                )
            }
        };
        if k % scenario.record_every_steps == 0 {
            let torque_wheels = controller == Controller::Torque;
            records.push(SlipRecord {
                t_s: t,
                x_m: state[0],
                y_m: state[1],
                heading_rad: state[2],
                est_x_m: estimate[0],
                est_y_m: estimate[1],
                est_heading_rad: estimate[2],
                est_left_rad_s: torque_wheels.then_some(estimate[3]),
                est_right_rad_s: torque_wheels.then_some(estimate[4]),
                ref_x_m: f64::from(target.pose.position.x),
                ref_y_m: f64::from(target.pose.position.y),
                ref_heading_rad: f64::from(target.pose.heading_rad),
                ref_v_m_s: f64::from(target.velocity.v_m_s),
                ref_omega_rad_s: f64::from(target.velocity.omega_rad_s),
                e1_m: f64::from(true_error[0]),
                e2_m: f64::from(true_error[1]),
                e3_rad: f64::from(true_error[2]),
                slip_estimate: f64::from(control.slip_estimate),
                slip_ratio,
                slip_factor: p,
                left_rad_s: state[3],
                right_rad_s: state[4],
                left_desired_rad_s: f64::from(control.wheels.left_rad_s),
                right_desired_rad_s: f64::from(control.wheels.right_rad_s),
                torque_left_nm: torque.map(|t| t[0]),
                torque_right_nm: torque.map(|t| t[1]),
                estimate_error_m: ((estimate[0] - state[0]).powi(2)
                    + (estimate[1] - state[1]).powi(2))
                .sqrt(),
            });
        }
        if controller == Controller::Velocity {
            state[3] = f64::from(control.wheels.left_rad_s);
            state[4] = f64::from(control.wheels.right_rad_s);
        }
        for _ in 0..scenario.plant_substeps {
            state = plant.rk4(&state, p, torque, substep_s);
        }
        state[2] = wrap(state[2]);
        filter.predict(&control.body, h);
    }
    let summary = summarize(scenario, &records);
    Ok(SlipResult { records, summary })
}

fn summarize(scenario: &SlipScenario, records: &[SlipRecord]) -> SlipSummary {
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

#[cfg(test)]
mod tests {
    use super::*;

    fn minimal(controller: &str) -> SlipScenario {
        SlipScenario::from_toml_str(&format!("name = \"m\"\ncontroller = \"{controller}\"\n"))
            .unwrap()
    }

    #[test]
    fn defaults_are_the_papers_constants() {
        let s = minimal("velocity");
        let r = &s.robot;
        let robot = TrackedRobot::new(
            r.wheel_radius_m as f32,
            r.track_width_m as f32,
            r.mass_kg as f32,
            r.yaw_inertia_kg_m2 as f32,
        )
        .unwrap();
        assert_eq!(robot, TrackedRobot::PAPER);
        let g = &s.gains;
        let gains = SlipGains::new(
            g.k1 as f32,
            g.k2 as f32,
            g.k3 as f32,
            g.k4 as f32,
            g.k5 as f32,
            g.rho as f32,
        )
        .unwrap();
        assert_eq!(gains, SlipGains::PAPER);
        assert_eq!(
            s.filter.particle_filter.process_std.map(|x| x as f32),
            PARTICLE_PROCESS_STD
        );
        let ours = s.reference_sampler().unwrap();
        let paper = PiecewiseReference::<4>::paper().unwrap();
        for k in 0..=1300 {
            let t = k as f32 * 0.05;
            assert_eq!(ours(t), paper.sample(t), "{t}");
        }
        for k in 0..12_000 {
            let t = f64::from(k) * PERIOD_S;
            let paper = if (SLIP_WINDOW_S.0..SLIP_WINDOW_S.1).contains(&t) {
                SLIP_RATIO
            } else {
                0.0
            };
            assert_eq!(slip_ratio(t), paper, "{t}");
        }
    }

    #[test]
    fn the_embedded_files_are_the_defaults_with_the_papers_initial_states() {
        for (name, controller) in [
            ("paper_004_velocity", Controller::Velocity),
            ("paper_004_torque", Controller::Torque),
        ] {
            let file = SlipScenario::embedded(name).unwrap();
            let mut defaults = minimal(controller.name());
            defaults.name = file.name.clone();
            defaults.description = file.description.clone();
            defaults.initial = Some(InitialState::paper(controller));
            assert_eq!(file, defaults, "{name}");
            let toml = file.to_toml_string().unwrap();
            assert_eq!(SlipScenario::from_toml_str(&toml).unwrap(), file, "{toml}");
        }
    }

    #[test]
    fn a_minimal_file_runs_the_same_as_the_embedded_one() {
        let mut a = SlipScenario::embedded("paper_004_torque").unwrap();
        let mut b = minimal("torque");
        for s in [&mut a, &mut b] {
            s.duration_s = 3.0;
            s.name = "x".into();
            s.description.clear();
        }
        assert_eq!(run(&a).unwrap().records, run(&b).unwrap().records);
    }

    #[test]
    fn more_reference_segments_than_the_limit_are_refused() {
        let mut s = minimal("velocity");
        s.reference.segments = (0..=MAX_SEGMENTS)
            .map(|k| SegmentSpec {
                start_s: k as f64,
                v_m_s: 0.5,
                omega_rad_s: 0.0,
            })
            .collect();
        let e = s.validate().unwrap_err();
        assert_eq!(e.field(), Some("reference.segments"), "{e}");
        s.reference.segments.truncate(2);
        s.validate().unwrap();
        s.reference.segments[1].start_s = 0.0;
        let e = s.validate().unwrap_err();
        assert_eq!(e.field(), Some("reference.segments[1].start_s"), "{e}");
    }
}
