//! Host simulator for `wmr-core`: runs the robot's `no_std` core against
//! simulated plants and virtual devices.
//!
//! ```text
//! Scenario (TOML) ──validate──► Setup (core configs + models) ──run──► RunResult
//!                                                                      ├─ records (one per tick)
//!                                                                      └─ Summary (errors, counters)
//! ```
//!
//! * [`plant`]: the kinematic unicycle of paper 001 (exact arcs) and a
//!   differential-drive body with first-order DC motors or, with
//!   `[plant.dynamics]`, rigid-body wheel dynamics (RK4).
//! * [`devices`]: virtual PWM, direction pins, quadrature encoders and an
//!   RFID reader on a baud-timed UART, implementing the same traits as the
//!   firmware's peripherals.
//! * [`tags`]: the floor's tag grid (the core's `TagGrid` encoding) and the
//!   nearest-tag lookup.
//! * [`scenario`]: the TOML schema, its validation, the embedded scenarios.
//! * [`report`]: the per-tick records and the summary of a run, shared by
//!   everything after the simulation.
//! * [`simulation`]: the loop, calling the core's tracker or controller directly
//!   (unicycle) or its `Robot`/`Pilot` with virtual devices (diff drive).
//! * [`output`]: CSV, JSON summary and PNG plot.
//! * [`sweep`]: Monte Carlo sweeps: seeded variations of a scenario run in
//!   parallel, convergence and error statistics.
//! * [`hil`]: the same runs with the control tick in the real firmware
//!   under QEMU, in lock-step over a serial link.
//! * [`slip`]: paper 004's tracked robot under slip with the adaptive
//!   controllers and the EKF, UKF or particle filter (`firmware-sim slip`).
//!
//! ```no_run
//! use firmware_sim::{run, Scenario};
//! let scenario = Scenario::embedded("figure_eight_rfid")?;
//! let result = run(&scenario, |_, _| {})?;
//! assert!(result.summary.max_error_m < 0.1);
//! # Ok::<(), firmware_sim::ScenarioError>(())
//! ```

pub mod devices;
pub mod hil;
pub mod output;
pub mod plant;
pub mod report;
pub mod scenario;
pub mod simulation;
pub mod slip;
pub mod sweep;
pub mod tags;

pub use report::{Record, RunResult, Summary};
pub use scenario::{EMBEDDED, Scenario, ScenarioError, Setup};
pub use simulation::run;
