//! The slip scenario's schema: the paper's constants, the TOML tables
//! ([`SlipScenario`] and what it holds) with the paper's values as their
//! defaults, and the embedded scenarios. Checking the values is
//! `validate`'s job.
//!
//! By job, each file using only those above it:
//! * `paper`: the paper's constants ([`PERIOD_S`], [`SLIP_WINDOW_S`],
//!   the filters' noise, ...);
//! * `schedule`: what changes with time, the slip ratio's steps
//!   ([`SlipStep`]) and the reference's segments ([`SegmentSpec`]);
//! * `choices`: which controller and which estimator ([`Controller`],
//!   [`Estimator`]);
//! * `defaults`: the serde defaults, the paper's values;
//! * `tables`: the tables a scenario holds (`[initial]`, `[reference]`,
//!   `[robot]`, `[gains]`, `[measurement]`, `[filter]`, `[windows]`);
//! * `schema`: the scenario's top level ([`SlipScenario`]);
//! * `keys`: the file's key table ([`slip_keys`], `firmware-sim schema
//!   --slip`), from the JSON Schema of the types above ([`slip_schema`]);
//! * this file: the embedded scenarios ([`EMBEDDED_SLIP`]) and the paper's
//!   slip ratio over time ([`slip_ratio`]).

mod choices;
mod defaults;
mod keys;
mod paper;
mod schedule;
mod schema;
mod tables;

pub use choices::{Controller, Estimator};
pub use keys::{slip_keys, slip_schema};
pub use paper::{
    DURATION_S, INITIAL_VARIANCE, MAX_SEGMENTS, MEASUREMENT_VARIANCE, PARTICLE_PROCESS_STD,
    PARTICLE_REGULARIZATION, PERIOD_S, PROCESS_NOISE, SLIP_RATIO, SLIP_WINDOW_S,
    UKF_INITIAL_VARIANCE,
};
pub(super) use schedule::ratio_at;
pub use schedule::{SegmentSpec, SlipStep};
pub use schema::SlipScenario;
pub use tables::{
    FilterSpec, GainsSpec, InitialState, MeasurementSpec, ParticleFilterSpec, ProposalSpec,
    ReferenceSpec, RobotSpec, UkfFormSpec, UkfSpec, WindowsSpec,
};

/// The slip scenarios shipped with the simulator, as `(file name, TOML
/// text)`: the paper's scenarios 1 and 2.
pub const EMBEDDED_SLIP: &[(&str, &str)] = &[
    (
        "paper_004_velocity",
        include_str!("../../../scenarios/slip/paper_004_velocity.toml"),
    ),
    (
        "paper_004_torque",
        include_str!("../../../scenarios/slip/paper_004_torque.toml"),
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
