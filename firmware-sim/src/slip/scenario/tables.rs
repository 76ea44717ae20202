//! The tables a scenario holds, each with the paper's values as its
//! defaults: the initial state, the reference, the robot, the gains, the
//! measurement noise, the filters' settings and the summary's windows.

use std::f64::consts::{FRAC_PI_4, FRAC_PI_6};

use serde::{Deserialize, Serialize};
use wmr_papers::slip_tracking::P_MAX;

use super::super::filter::PARTICLES;
use super::choices::Controller;
use super::defaults;
use super::paper::{INITIAL_VARIANCE, MEASUREMENT_VARIANCE, PROCESS_NOISE, UKF_INITIAL_VARIANCE};
use super::schedule::SegmentSpec;

/// Initial pose and wheel speeds of the robot (and the filters' `x̂0`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct InitialState {
    /// `X`, m (default 0 in a given `[initial]`; no `[initial]`: the
    /// paper's start for the controller).
    #[serde(default)]
    pub x_m: f64,
    /// `Y`, m (default 0 in a given `[initial]`; no `[initial]`: −1.5 for
    /// `velocity`, −1 for `torque`).
    #[serde(default)]
    pub y_m: f64,
    /// `ψ`, rad (default 0 in a given `[initial]`; no `[initial]`: π/4 for
    /// `velocity`, π/6 for `torque`).
    #[serde(default)]
    pub heading_rad: f64,
    /// `ω_L`, rad/s (default 0; scenario 2 only: scenario 1's wheels start
    /// at the first command).
    #[serde(default)]
    pub left_rad_s: f64,
    /// `ω_R`, rad/s (default 0; scenario 2 only).
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

    pub(in crate::slip) fn state(&self) -> [f64; 5] {
        [
            self.x_m,
            self.y_m,
            self.heading_rad,
            self.left_rad_s,
            self.right_rad_s,
        ]
    }
}

/// The reference: a unicycle from a start pose driven by piecewise
/// constant `(v_r, ω_r)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ReferenceSpec {
    /// Start `X`, m (default 0).
    #[serde(default)]
    pub x_m: f64,
    /// Start `Y`, m (default 0).
    #[serde(default)]
    pub y_m: f64,
    /// Start heading, rad (default 0).
    #[serde(default)]
    pub heading_rad: f64,
    /// The constant-input segments (`{ start_s, v_m_s, omega_rad_s }`), 1
    /// to 8 (`MAX_SEGMENTS`), the first at 0 s, in
    /// increasing time (default the paper's four).
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

/// The tracked robot (default: the paper's, `b = 0.65 m, r = 0.35 m,
/// m = 0.80 kg, J = 0.0608 kg m²`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RobotSpec {
    /// Wheel radius `r`, m (default 0.35; > 0).
    #[serde(default = "defaults::wheel_radius_m")]
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub wheel_radius_m: f64,
    /// Track width `b`, m (default 0.65; > 0).
    #[serde(default = "defaults::track_width_m")]
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub track_width_m: f64,
    /// Mass `m`, kg (default 0.80; > 0).
    #[serde(default = "defaults::mass_kg")]
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub mass_kg: f64,
    /// Yaw inertia `J`, kg m² (default 0.0608; > 0).
    #[serde(default = "defaults::yaw_inertia_kg_m2")]
    #[schemars(extend("exclusiveMinimum" = 0.0))]
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
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct GainsSpec {
    /// `k1`, 1/s (default 6; > 0).
    #[serde(default = "defaults::k1")]
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub k1: f64,
    /// `k2`, no unit (default 8; > 0).
    #[serde(default = "defaults::k2")]
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub k2: f64,
    /// `k3`, 1/s (default 6; > 0).
    #[serde(default = "defaults::k3")]
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub k3: f64,
    /// `k4` of (9), 1/s (default 4; > 0; scenario 2 only).
    #[serde(default = "defaults::k45")]
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub k4: f64,
    /// `k5` of (9), 1/s (default 4; > 0; scenario 2 only).
    #[serde(default = "defaults::k45")]
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub k5: f64,
    /// `ρ` of (7), the adaptation gain, no unit (default 3; > 0).
    #[serde(default = "defaults::rho")]
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub rho: f64,
    /// `p̂(0)`, the slip estimate's start, no unit, in `[1, P_MAX]` (`P_MAX`
    /// 20)
    /// (default 1, the paper's).
    #[serde(default = "defaults::initial_slip_estimate")]
    #[schemars(range(min = 1.0, max = P_MAX))]
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
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MeasurementSpec {
    /// Variances of `X, Y` (m²), `ψ` (rad²), `ω_L, ω_R` (rad²/s²): the
    /// noise drawn and the filters' `R` (scenario 1 uses the first three;
    /// default `[0.1, 0.1, 0.2, 0.01, 0.01]`, the paper's).
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
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FilterSpec {
    /// EKF `P0` diagonal, variances of `X, Y` (m²), `ψ` (rad²), `ω_L, ω_R`
    /// (rad²/s²); the particle filter's prior spread is its square root
    /// (default 10 each).
    #[serde(default = "defaults::initial_variance")]
    pub initial_variance: [f64; 5],
    /// EKF and UKF process noise `Q` per step, diagonal variances in
    /// `measurement.variance`'s units (default `[1e-5, 1e-5, 1e-5, 0.01,
    /// 0.01]`, `PROCESS_NOISE`).
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
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct UkfSpec {
    /// Sigma-point spread `α`, no unit (default 0.01, the paper's; > 0).
    #[serde(default = "defaults::alpha")]
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub alpha: f64,
    /// Prior-distribution weight `β`, no unit (default 2, the paper's).
    #[serde(default = "defaults::beta")]
    pub beta: f64,
    /// Secondary scaling `κ`, no unit (default 0, the paper's).
    #[serde(default)]
    pub kappa: f64,
    /// `P0` diagonal, in `filter.initial_variance`'s units (default `[10,
    /// 10, 1, 10, 10]`, `UKF_INITIAL_VARIANCE`: the heading's 1 rad²
    /// because the unscented circular mean turns around above ~2 rad²).
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
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, schemars::JsonSchema,
)]
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
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ParticleFilterSpec {
    /// How many particles: 100, 300 or 1000 (`PARTICLE_COUNTS`, a const
    /// generic of the core's filter; default 100, the paper's, `PARTICLES`;
    /// `firmware-sim slip --particles` overrides it).
    #[serde(default = "defaults::particles")]
    #[schemars(extend("enum" = crate::slip::PARTICLE_COUNTS))]
    pub particles: usize,
    /// Process noise per step, standard deviations of `X, Y` (m), `ψ`
    /// (rad), `ω_L, ω_R` (rad/s) (default `[0.005, 0.005, 0.007, 5, 5]`,
    /// `PARTICLE_PROCESS_STD`).
    #[serde(default = "defaults::particle_process_std")]
    pub process_std: [f64; 5],
    /// Collapse gate on the best particle's squared normalised residual,
    /// no unit (default `inf`: off; JSON has no infinity, so the schema
    /// states no default).
    #[serde(default = "defaults::collapse_gate")]
    #[schemars(transform = without_default)]
    pub collapse_gate: f64,
    /// Regularization after resampling: the kernel bandwidth as a multiple
    /// of the optimal one, no unit (default 1, `PARTICLE_REGULARIZATION`;
    /// 0: off).
    #[serde(default = "defaults::regularization")]
    #[schemars(range(min = 0.0))]
    pub regularization: f64,
    /// How the particles are drawn: `optimal` (the optimal importance
    /// density, closed-form here because every state is measured; core
    /// `particle_filter` docs; the default) or `prior` (the
    /// paper's transition prior).
    #[serde(default)]
    pub proposal: ProposalSpec,
}

/// The particle filter's proposal (`wmr_core::filters::particle_filter::Proposal`).
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, schemars::JsonSchema,
)]
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

/// The summary's windows, `[from, to)` in s, `0 ≤ from < to`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct WindowsSpec {
    /// Tracking errors before the slip, s (default `[15, 22.5]`).
    #[serde(default = "defaults::before_slip_s")]
    pub before_slip_s: [f64; 2],
    /// Tracking errors during the slip, s (default `[25, 45]`).
    #[serde(default = "defaults::during_slip_s")]
    pub during_slip_s: [f64; 2],
    /// Tracking errors after the slip, s (default `[50, 60]`).
    #[serde(default = "defaults::after_slip_s")]
    pub after_slip_s: [f64; 2],
    /// Mean `p̂` during the slip, s (default `[35, 45]`).
    #[serde(default = "defaults::slip_estimate_during_s")]
    pub slip_estimate_during_s: [f64; 2],
    /// Mean `p̂` after the slip, s (default `[55, 60]`).
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

/// Drops a key's `default` from its schema: for a default JSON cannot
/// state (an infinite `f64` serializes as `null`, which would say the key
/// defaults to nothing); the key's doc states it instead.
fn without_default(schema: &mut schemars::Schema) {
    schema.remove("default");
}
