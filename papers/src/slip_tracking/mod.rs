//! Slip-adaptive tracking of paper 004 (Iossaqui, Camino & Zampieri,
//! *nonlinear filters for tracked robots under slip*): the tracked robot
//! with longitudinal slip, its reference and error, and the two adaptive
//! controllers, with the filter models of the paper's two scenarios.
//!
//! # Model (1)–(4)
//! Slip ratio `i ∈ [0, 1)`, `p = 1/(1 − i)` ([`slip_factor`]). With wheel
//! speeds `ξ = (ω_L, ω_R)` the robot moves as a unicycle with
//! `v = r(ω_L + ω_R)/(2p)`, `ω = r(ω_R − ω_L)/(b p)` (1)
//! ([`TrackedRobot::body_velocity`]). Dynamics (2): `M̄ ξ̇ = B̄ τ` with
//! `M̄ = SᵀMS = M₀/p²`, `M₀ = [[m r²/4 + J r²/b², m r²/4 − J r²/b²], [·, ·]]`
//! and `B̄ = SᵀB = I/p`, so `ξ̇ = p M₀⁻¹ τ`
//! ([`TrackedRobot::wheel_acceleration`]). The printed `B(q)` has `b/2` in
//! both columns of its last row; the left track's torque turns the robot
//! clockwise, so that entry is `−b/2` (with `+b/2`, `B̄` would not be
//! invertible and (8) would not exist). The reference (3) is a unicycle
//! driven by piecewise constant `(v_r, ω_r)` ([`PiecewiseReference`],
//! integrated exactly along arcs); the error (4) is the reference's offset
//! in the robot's frame ([`tracking_error`], `e3` wrapped to (−π, π]).
//!
//! # Adaptive velocity-based control (5)–(7)
//! ```text
//! ξ = (p̂/2r)·[[2, −b], [2, b]]·(v, ω)                              (5)
//! v = v_r cos e3 + k1 e1,   ω = ω_r + v_r k2 e2 + k3 sin e3         (6)
//! dp̂/dt = ρ (v e1 + ω sin e3 / k2)                                  (7)
//! ```
//! (7) is printed without its dot. It follows from `V = ½(e1² + e2²) +
//! (1 − cos e3)/k2 + (p − p̂)²/(2ρp)`: with the robot moving at `(p̂/p)(v,
//! ω)`, `V̇ = −k1 e1² − (k3/k2) sin² e3`. `p̂` is integrated by forward Euler
//! and projected onto `[1, P_MAX]` (`p ≥ 1` for every slip `i ≥ 0`, and a
//! `p̂ ≤ 0` would reverse the tracks): the projection only removes steps
//! that move away from the true `p`, so `V̇` keeps its sign.
//!
//! # Adaptive torque-based control (8)–(10)
//! `τ = B̄(p̂)⁻¹ M̄(p̂) u = M₀ u / p̂` (8), `u = ξ̇_d + diag(k4, k5)(ξ_d − ξ)`
//! (9), `ξ_d` = (5) with (6) (10), `p̂` by (7). The paper does not say how
//! `ξ̇_d` is obtained; here it is the backward difference of `ξ_d` over the
//! step (0 on the first step and after a rejected one). Differentiating
//! (6)–(7) along the model instead (`ė1 = ω̂ e2 − v̂ + v_r cos e3`, … with
//! `(v̂, ω̂)` from the wheel speeds and `p̂`) does worse: with `p̂ ≠ p` it
//! feeds the adaptation error into the inner loop, and even on the true
//! state `p̂` climbs to 9 during the slip (measured in `host-tests`), where
//! differencing keeps it at 1.33. Evaluating (8) at `p = 1` instead of `p̂`
//! does no better.
//!
//! # Filter models (section "Numerical results")
//! [`PoseModel`] (scenario 1: state `(X, Y, ψ)`) and [`PoseWheelModel`]
//! (scenario 2: `(X, Y, ψ, ω_L, ω_R)`, wheel speeds constant over a step),
//! both driven by the auxiliary `(v, ω)` of (6), first-order (Euler)
//! discretisations with the full state measured. They implement
//! [`wmr_core::filters::ekf::EkfModel`], [`wmr_core::filters::particle_filter::ParticleModel`] and
//! the UKF's model trait.
//!
//! # Files
//! By job, each using only those above it:
//! * `error`: why a configuration was refused ([`SlipTrackingError`]);
//! * `robot`: the tracked robot under slip, (1)–(2) ([`slip_factor`],
//!   [`TrackedRobot`]);
//! * `reference`: the reference (3) ([`PiecewiseReference`]) and the
//!   tracking error (4) ([`tracking_error`]);
//! * `velocity`: the gains ([`SlipGains`]) and the adaptive velocity-based
//!   controller (5)–(7) ([`AdaptiveVelocityController`], [`P_MAX`]);
//! * `torque`: the adaptive torque-based controller (8)–(10)
//!   ([`AdaptiveTorqueController`]), around the velocity-based one;
//! * `models`: the filter models of the two scenarios ([`PoseModel`],
//!   [`PoseWheelModel`]).

mod error;
mod models;
mod reference;
mod robot;
mod torque;
mod velocity;

#[cfg(test)]
mod tests;

pub use error::SlipTrackingError;
pub use models::{PoseModel, PoseWheelModel};
pub use reference::{PiecewiseReference, ReferenceSegment, ReferenceState, tracking_error};
pub use robot::{TrackedRobot, slip_factor};
pub use torque::{AdaptiveTorqueController, TorqueControl};
pub use velocity::{AdaptiveVelocityController, P_MAX, SlipGains, VelocityControl};
