//! The scenario's top level ([`SlipScenario`]), as the TOML file holds it.

use serde::{Deserialize, Serialize};

use super::choices::{Controller, Estimator};
use super::defaults;
use super::schedule::SlipStep;
use super::tables::{
    FilterSpec, GainsSpec, InitialState, MeasurementSpec, ReferenceSpec, RobotSpec, WindowsSpec,
};

/// A slip scenario (the TOML file's top level).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SlipScenario {
    /// Short name (used for the default output directory).
    pub name: String,
    /// Free text.
    #[serde(default)]
    pub description: String,
    /// Which adaptive controller runs: `velocity` (scenario 1) or `torque`
    /// (scenario 2).
    pub controller: Controller,
    /// What feeds the controller its state: `exact`, `ekf` (default), `ukf`
    /// or `particle_filter` (`firmware-sim slip --estimator` overrides it).
    #[serde(default)]
    pub estimator: Estimator,
    /// Seed of the measurement noise (and of the particle filter) (default
    /// 1; `firmware-sim slip --seed` overrides it).
    #[serde(default = "defaults::seed")]
    pub seed: u64,
    /// Simulated time, s (default 60).
    #[serde(default = "defaults::duration_s")]
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub duration_s: f64,
    /// Control and filter step `h`, s (default 0.005).
    #[serde(default = "defaults::period_s")]
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub period_s: f64,
    /// RK4 substeps of the plant per step, inputs held (default 10).
    #[serde(default = "defaults::plant_substeps")]
    #[schemars(range(min = 1))]
    pub plant_substeps: u32,
    /// A record (CSV row, and sample of the summary's statistics) every
    /// this many steps (default 10: 50 ms).
    #[serde(default = "defaults::record_every_steps")]
    #[schemars(range(min = 1))]
    pub record_every_steps: u32,
    /// Initial pose and wheel speeds; absent: the paper's for the
    /// controller (scenario 1 `(0, −1.5, π/4)`, 2 `(0, −1, π/6, 0, 0)`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub initial: Option<InitialState>,
    /// The slip ratio's steps (`[[slip]]`), in increasing time; 0 before
    /// the first. Default: 0.25 from 22.5 s, 0 from 45 s.
    #[serde(default = "defaults::slip")]
    pub slip: Vec<SlipStep>,
    /// The reference (3): a unicycle from a start pose driven by piecewise
    /// constant speeds (default the paper's).
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
    /// The filters' settings (default the paper's, and the choices
    /// docs/paper-004.md measured).
    #[serde(default)]
    pub filter: FilterSpec,
    /// Windows of the summary's statistics, s (default the paper's
    /// phases).
    #[serde(default)]
    pub windows: WindowsSpec,
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
