//! The slip scenario's schema: the paper's constants, the TOML tables
//! ([`SlipScenario`] and what it holds) with the paper's values as their
//! defaults, and the embedded scenarios. Checking the values is
//! `validate`'s job.

use std::f64::consts::{FRAC_PI_4, FRAC_PI_6};

use serde::{Deserialize, Serialize};

use super::filter::PARTICLES;

/// Control and filter step of the paper, s.
pub const PERIOD_S: f64 = 0.005;
/// Simulated time of the paper, s.
pub const DURATION_S: f64 = 60.0;
/// When the paper's slip starts and ends, s.
pub const SLIP_WINDOW_S: (f64, f64) = (22.5, 45.0);
/// The paper's slip ratio during the window.
pub const SLIP_RATIO: f64 = 0.25;
/// The filters' process noise per step (variances): position and heading,
/// and (scenario 2) wheel speeds. The paper does not give its `Q` (its
/// plant has none); with `Q = 0` the filters stop listening to the
/// measurements.
pub const PROCESS_NOISE: [f64; 5] = [1e-5, 1e-5, 1e-5, 1e-2, 1e-2];
/// The particle filter's process noise per step (standard deviations),
/// chosen with the optimal proposal ([`ProposalSpec::Optimal`], the
/// default) over seeds 1–20 of both scenarios (docs/paper-004.md): of the
/// pose spreads tried (position 0.005–0.02 m, heading 0.002–0.02 rad) this
/// one gave the smallest worst ratio to the EKF in both. A smaller heading
/// spread (0.002–0.004) or the EKF's own `Q` (0.003 everywhere) lets the
/// cloud lag the robot (3 of 20 seeds diverged at 0.002); a larger one
/// (0.02, with 0.01 m of position) gives noisier
/// estimates, which law (7) turns into a higher `p̂`.
///
/// The wheel speeds' 5 rad/s: scenario 2's torques move a wheel by up to
/// 8.6 rad/s in one 5 ms step, which a random walk of 0.5 cannot reach
/// (17σ). With the prior proposal that spread leaves 100 particles sparse
/// around the 0.1 rad/s measurement (worst ratio to the EKF 16.5); the
/// optimal proposal draws them where the measurement puts them (0.3, 1 and
/// 5 rad/s gave worst ratios 2.41, 1.31 and 1.24). Scenario 1 uses the
/// first three entries.
pub const PARTICLE_PROCESS_STD: [f32; 5] = [0.005, 0.005, 0.007, 5.0, 5.0];
/// The particle filter's regularization after resampling: the kernel
/// bandwidth as a multiple of Musso, Oudjane & Le Gland's optimal one
/// (core `particle_filter` docs; also turns on progressive correction).
/// Without it (0) the prior `P0 = 10 I` collapses onto one particle at the
/// first update, 2 m from the truth in scenario 2, and 11 of seeds 1–20
/// diverged there.
pub const PARTICLE_REGULARIZATION: f32 = 1.0;
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

/// The slip ratio of `steps` at `t`: the last step started at or before
/// `t`, 0 before the first.
pub(super) fn ratio_at(steps: &[SlipStep], t: f64) -> f64 {
    steps
        .iter()
        .take_while(|s| s.start_s <= t)
        .last()
        .map_or(0.0, |s| s.slip_ratio)
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
    /// The core's particle filter ([`PARTICLES`] particles unless the
    /// scenario asks for another of [`PARTICLE_COUNTS`](super::PARTICLE_COUNTS)) on noisy
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

    pub(super) fn state(&self) -> [f64; 5] {
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
    /// `form = "covariance"` (default) or `"square_root"`: which form of
    /// the core's UKF runs (the square-root form needs `β ≥ α²`).
    #[serde(default)]
    pub form: UkfFormSpec,
}

/// The form of the core's UKF (`wmr_core::filters::ukf::UkfForm`). The
/// covariance form is the default: the square-root form does no better
/// on either scenario (docs/paper-004.md) and costs more.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum UkfFormSpec {
    /// `P` propagated (FilterPy's equations, Joseph-type update).
    #[default]
    Covariance,
    /// Its Cholesky factor (Van der Merwe & Wan 2001).
    SquareRoot,
}

impl Default for UkfSpec {
    fn default() -> Self {
        Self {
            alpha: defaults::alpha(),
            beta: defaults::beta(),
            kappa: 0.0,
            initial_variance: UKF_INITIAL_VARIANCE,
            form: UkfFormSpec::Covariance,
        }
    }
}

/// The particle filter's settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParticleFilterSpec {
    /// One of [`PARTICLE_COUNTS`](super::PARTICLE_COUNTS) (a const generic of the core's filter;
    /// default [`PARTICLES`], the paper's 100).
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
    /// Regularization after resampling: the kernel bandwidth as a multiple
    /// of the optimal one (default [`PARTICLE_REGULARIZATION`]; 0: off).
    #[serde(default = "defaults::regularization")]
    pub regularization: f64,
    /// How the particles are drawn: `optimal` (the optimal importance
    /// density, closed-form here because every state is measured; core
    /// `particle_filter` docs; the default) or `prior` (the
    /// paper's transition prior).
    #[serde(default)]
    pub proposal: ProposalSpec,
}

/// The particle filter's proposal (`wmr_core::filters::particle_filter::Proposal`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ProposalSpec {
    /// `f(x) + σ_q ξ`, weighted by the likelihood (the paper's).
    Prior,
    /// `p(x_k | x_{k−1}, y_k)`, weighted by `N(y; f(x), Q + R)`
    /// (Doucet, Godsill & Andrieu 2000; the default: docs/paper-004.md).
    #[default]
    Optimal,
}

impl Default for ParticleFilterSpec {
    fn default() -> Self {
        Self {
            particles: PARTICLES,
            process_std: defaults::particle_process_std(),
            collapse_gate: defaults::collapse_gate(),
            regularization: defaults::regularization(),
            proposal: ProposalSpec::Optimal,
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
        [0.005, 0.005, 0.007, 5.0, 5.0]
    }
    pub fn collapse_gate() -> f64 {
        f64::INFINITY
    }
    pub fn regularization() -> f64 {
        f64::from(super::PARTICLE_REGULARIZATION)
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

impl SlipScenario {
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
}
