//! Algorithms of the four papers that this project reproduces and tests
//! but that no robot runs: they stay out of `wmr-core`, whose every module
//! is on a robot's path (or selectable there).
//!
//! * [`chained_form`]: paper 002 section 2, the chained-form observers and
//!   controllers (Propositions 1–3).
//! * [`robot_frame_observers`]: paper 002 Propositions 5 and 6, observers
//!   of one robot-frame error from the other two.
//! * [`scaled_momenta_observer`]: paper 003 Proposition 2, the momenta
//!   observer with dynamic scaling for any inertia matrix.
//! * [`slip_tracking`]: paper 004, the tracked robot under slip, its
//!   adaptive controllers and its filter models.
//!
//! `host-tests` reproduces their figures; `cargo xtask bench-target`
//! measures paper 004's filter steps on the Cortex-M4. Same rules as the
//! core: `no_std`, no heap, no `unsafe`, no panics on any input.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::indexing_slicing,
        clippy::unreachable,
        clippy::todo,
        clippy::unimplemented
    )
)]

pub mod chained_form;
pub mod robot_frame_observers;
pub mod scaled_momenta_observer;
pub mod slip_tracking;
