//! The paper's constants: its step, duration and slip, and the filters'
//! noise and priors.

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
/// chosen with the optimal proposal
/// ([`ProposalSpec::Optimal`](super::ProposalSpec::Optimal), the
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
