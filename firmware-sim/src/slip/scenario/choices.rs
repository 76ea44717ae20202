//! Which adaptive controller a scenario runs, and which estimator feeds
//! it.

use serde::{Deserialize, Serialize};

/// Which adaptive controller (and so which plant and filter state).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
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
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default, schemars::JsonSchema,
)]
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
    /// The core's particle filter ([`PARTICLES`](crate::slip::PARTICLES)
    /// particles unless the scenario asks for another of
    /// [`PARTICLE_COUNTS`](crate::slip::PARTICLE_COUNTS)) on noisy
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
