//! Host simulator for `wmr-core`: runs the robot's `no_std` core against
//! simulated plants and virtual devices.
//!
//! ```text
//! Scenario (TOML) ──validate──► Setup (core configs + models) ──run──► RunResult
//!                                                                      ├─ records (one per tick)
//!                                                                      └─ Summary (errors, counters)
//! ```
//!
//! # Modules, in dependency order
//! Each module uses only modules listed before it; none uses one after it,
//! and no two use each other:
//!
//! ```text
//! tags ──┐
//! plant ─┴─► devices ─► scenario ─► report ─┬─► simulation ─┬─► hil
//!                          │         ▲      │               ├─► sweep
//! udp ─────────────────────┼─────────┘      │               └─► sitl
//!                          │                └─► output ─────────► sweep
//!                          │                      └─────────────► slip
//!                          └────────────────────────────────────► slip
//! ```
//!
//! (`A ─► B`: `B` uses `A`; uses that follow along the chain, such as
//! `simulation` using `scenario`, are not drawn.)
//!
//! * [`udp`]: a ground station's UDP side (the `--mavlink` address and
//!   the loopback rule, the socket, the wall-clock pace), shared by `sitl`
//!   and `hil`. Uses nothing of this crate.
//! * [`tags`]: the floor's tag grid (the core's `TagGrid` encoding) and the
//!   nearest-tag lookup. Uses nothing of this crate.
//! * [`plant`]: the kinematic unicycle of paper 001 (exact arcs) and a
//!   differential-drive body with first-order DC motors or, with
//!   `[plant.dynamics]`, rigid-body wheel dynamics (RK4). Uses nothing of
//!   this crate.
//! * [`devices`]: virtual PWM, direction pins, quadrature encoders and an
//!   RFID reader on a baud-timed UART, implementing the same traits as the
//!   firmware's peripherals. Uses `plant`, `tags`.
//! * [`scenario`]: the TOML schema (with the `[sweep]` table's), its
//!   defaults, its validation into a [`Setup`], the embedded scenarios.
//!   Uses `devices`, `plant`, `tags`.
//! * [`report`]: what a run reports: the per-tick [`Record`], the
//!   [`Summary`] (with the HIL figures), the [`RunResult`]. Uses
//!   `devices`, `scenario`, `udp`.
//! * [`output`]: CSV, JSON summary and PNG plot, and the plot helpers
//!   `sweep` and `slip` share. Uses `report`.
//! * [`simulation`]: the loop, calling the core's tracker or controller
//!   directly (unicycle) or its `Robot`/`Pilot` with virtual devices (diff
//!   drive), or a remote tick over a `TargetLink`. Uses `devices`, `plant`,
//!   `tags`, `scenario`, `report`.
//! * [`hil`]: the same runs with the control tick in the real firmware
//!   under QEMU, in lock-step over a serial link, and a ground station on
//!   UDP bridged to its MAVLink endpoint. Uses `scenario`, `report`,
//!   `simulation`, `udp`.
//! * [`sweep`]: Monte Carlo sweeps: seeded variations of a scenario run in
//!   parallel, convergence and error statistics, their files, shards of
//!   the runs for other machines and their merge. Uses
//!   `scenario`, `report`, `simulation`, `output`.
//! * [`sitl`]: the simulated robot in real time (or faster) behind the
//!   robot's MAVLink endpoint (`wmr-mavlink`) on UDP (`firmware-sim
//!   sitl`). Uses `scenario`, `report`, `simulation`, `udp`.
//! * [`telemetry`]: a firmware's telemetry log (`firmware-sim plot`) back
//!   into `run.csv`, `summary.json` and `run.png`. Uses `report`,
//!   `output`.
//! * [`slip`]: paper 004's tracked robot under slip with the adaptive
//!   controllers and the EKF, UKF or particle filter (`firmware-sim slip`),
//!   a second application with its own schema. Uses `scenario` (its error
//!   type and value checks) and `output` (the plot helpers).
//!
//! The binary (`main.rs`, the CLI) uses them all; nothing here uses it.
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
pub mod sitl;
pub mod slip;
pub mod sweep;
pub mod tags;
pub mod telemetry;
pub mod udp;

pub use report::{Record, RunResult, Summary};
pub use scenario::{EMBEDDED, Scenario, ScenarioError, Setup};
pub use simulation::run;
