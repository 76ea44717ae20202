//! A particle filter (paper 004, Iossaqui, Camino & Zampieri, *Nonlinear
//! filters for tracked robots under slip*, "The PF algorithm", after
//! Haykin 2001): sequential importance sampling with the transition prior
//! as the proposal, systematic resampling, and the MMSE estimate. `N`
//! states, `M` measurements and `P` particles, all fixed at compile time
//! (the paper: `P = 100`); no heap.
//!
//! # System
//! The paper's discrete model `x_k = f(x_{k−1}, u_{k−1}) + w_k`,
//! `y_k = h(x_k) + v_k` with `w ~ N(0, Q)`, `v ~ N(0, R)` and both
//! covariances diagonal here: `Q = diag(σ_q²)` per step and
//! `R = diag(σ_r²)` ([`ParticleFilterConfig`]). The model
//! ([`ParticleModel`]) gives `f` and `h`; the filter adds the process noise.
//!
//! # Algorithm
//! ```text
//! 1. x_0⁽ⁱ⁾ ~ N(x̄_0, diag(σ_0²)),  w_0⁽ⁱ⁾ = 1/P                  (initialisation)
//! 2. x_k⁽ⁱ⁾ = f(x_{k−1}⁽ⁱ⁾, u, dt) + σ_q ∘ ξ⁽ⁱ⁾,  ξ ~ N(0, I)      (importance sampling,
//!                                                                π = p(x_k | x_{k−1}))
//! 3. w_k⁽ⁱ⁾ ∝ w_{k−1}⁽ⁱ⁾ p(y_k | x_k⁽ⁱ⁾),                        (weights)
//!    ln p(y | x) = −½ Σ_j (r_j / σ_r,j)² + const,  r = residual(y, h(x))
//! 4. w̃⁽ⁱ⁾ = w⁽ⁱ⁾ / Σ_j w⁽ʲ⁾                                      (normalisation)
//! 5. x̂_k = Σ_i w̃⁽ⁱ⁾ x_k⁽ⁱ⁾                                       (MMSE estimate)
//! 6. if 1/Σ_i (w̃⁽ⁱ⁾)² < threshold: systematic resampling, w = 1/P  (selection)
//! ```
//!
//! With the transition prior as the proposal `π`, the paper's weight
//! `w_{k−1} p(y|x) p(x|x_{k−1}) / π(x | x_{0:k−1}, Y)` reduces to
//! `w_{k−1} p(y|x)` (step 3); the paper calls `π` the posterior, but in its
//! formula it is the importance density. The paper prints the normalising sum
//! over `w⁽ⁱ⁾` for `w⁽ʲ⁾` (step 4), resets the weights as "`w = x̃ = 1/N`"
//! and takes the estimate as the plain mean `(1/N) Σ x⁽ⁱ⁾` of the
//! resampled set. Here the estimate is the weighted mean *before*
//! resampling: the same expectation, without the resampling noise. The
//! paper resamples every step; here it happens when the effective sample
//! size `1/Σw̃²` falls below a configured fraction of `P` (default ½,
//! [`DEFAULT_RESAMPLE_FRACTION`]; 1 resamples at every update that is not
//! perfectly balanced, as the paper does, 0 never). The paper's
//! simulations set the process noise `w_k` to zero; a particle filter
//! needs `Q > 0` (or it degenerates to the few initial particles that
//! survive resampling).
//!
//! ## Weights in log space
//! `ln w⁽ⁱ⁾ + ln p(y | x⁽ⁱ⁾)` is formed for every particle, the largest is
//! subtracted before exponentiating, so the best particle always gets
//! `e⁰ = 1` before normalisation and a measurement many `σ_r` away from
//! every particle still weights them by their relative likelihood instead
//! of underflowing all of them to 0 as `exp(−d²/2)` does in `f32` beyond
//! `d² ≈ 175`. Ratios below `e^−87` (≈ 1.6·10⁻³⁸, the bottom of `f32`'s
//! normal range) are set to 0, and weights below `f32::MIN_POSITIVE` count
//! as 0 (so `ln` is never asked for a subnormal, where `micromath`'s is not
//! defined).
//!
//! ## Systematic resampling ([`systematic_resample`])
//! One uniform draw `u ∈ [0, 1)` and `P` evenly spaced pointers
//! `(k + u)/P`, `k = 0 … P−1`, on the cumulative weights: particle `i` is
//! copied once for each pointer in `[Σ_{j<i} w̃⁽ʲ⁾, Σ_{j≤i} w̃⁽ʲ⁾)`, so it gets
//! `⌊P w̃⁽ⁱ⁾⌋` or `⌈P w̃⁽ⁱ⁾⌉` copies (the lowest-variance of the standard
//! schemes, `O(P)`). The copies go to a second particle array of the filter
//! and are copied back.
//!
//! # Angles
//! The model says which state components are angles
//! ([`ParticleModel::is_angle`], asked once at construction). Those are
//! wrapped to (−π, π] after every propagation and draw, their estimate is
//! the circular mean `atan2(Σ w̃ sin θ⁽ⁱ⁾, Σ w̃ cos θ⁽ⁱ⁾)` (in (−π, π]; 0 if the
//! particles are spread evenly around the circle), and their deviations in
//! [`ParticleFilter::covariance`] are wrapped. Angle components of a
//! measurement are the model's business: override
//! [`ParticleModel::measurement_residual`] to wrap them
//! ([`crate::math::wrap_angle`]).
//!
//! # Random numbers
//! xoshiro128++ from `rand` (`rand::rngs::Xoshiro128PlusPlus`, 128-bit
//! state, 32-bit outputs: native on a Cortex-M, no atomics), seeded from a
//! `u64` through SplitMix64. Uniform draws take the top 24 bits of an
//! output (`[0, 1)` in steps of 2⁻²⁴). Gaussian draws use the Box–Muller
//! transform on [`crate::math`]'s `ln`, `sqrt`, `sin`, `cos`:
//! `ρ = √(−2 ln u₁)`, `(ρ cos 2πu₂, ρ sin 2πu₂)` with `u₁ ∈ (0, 1]`, one
//! of each pair kept for the next draw; it costs the same for every draw
//! (no rejection loop, unlike the polar method), and the 24-bit `u₁` bounds
//! `|ξ| ≤ √(48 ln 2) ≈ 5.77`, a tail cut that changes nothing at 100
//! particles. Runs are reproducible: the same seed, configuration and
//! inputs give bit-identical particles and estimates for a given math
//! backend (`libm` and `micromath` give different, each reproducible,
//! runs). `rand_distr` is not used: without `std` its math goes through
//! `num-traits` and `libm`, bypassing the `micromath` switch.
//!
//! # Bad input and collapse
//! * A non-finite `z`, a non-finite or negative `dt_s`, or an input the
//!   model refuses ([`ParticleModel::input_is_valid`]) skips the step:
//!   nothing changes but the counter `rejected_inputs`.
//! * A prediction that leaves *every* particle non-finite (e.g. a NaN input
//!   the model did not screen) is treated the same way (rolled back,
//!   counted in `rejected_inputs`). If only some particles come out
//!   non-finite, those keep their previous state with weight 0 (counted in
//!   `dropped_particles`) and the rest are renormalised.
//! * A particle whose measurement residual is not finite gets weight 0.
//! * **Collapse**: if no particle keeps a positive finite weight, or the
//!   measurement is beyond the collapse gate from every particle
//!   (`min_i Σ_j (r_j⁽ⁱ⁾/σ_r,j)² >` [`DEFAULT_COLLAPSE_GATE`] = 174.67 by
//!   default: the distance at which the paper's linear-space weights would
//!   all underflow `f32`, ≈ 13 σ for one measurement), the filter keeps its
//!   previous estimate, redraws every particle around it with the recovery
//!   spread (the prior's `σ_0` unless configured), resets the weights to
//!   `1/P`, ignores the measurement and counts a `collapse`. The filter
//!   never holds a non-finite particle, weight or estimate.
//!
//! # Regularization and progressive correction (opt-in)
//! With [`ParticleFilterConfig::with_regularization`] (bandwidth scale
//! `s > 0`), every resampling is followed by the kernel step of the
//! regularized particle filter (Musso, Oudjane & Le Gland 2001, *Improving
//! regularised particle filters*, in Doucet, de Freitas & Gordon (eds.),
//! *Sequential Monte Carlo Methods in Practice*, ch. 12): with `C` the
//! weighted covariance of the cloud before resampling, `C = L Lᵀ`
//! (Cholesky, jittered if only semi-definite), `h = s·h_opt`,
//! `h_opt = (4/(P(N+2)))^{1/(N+4)}` (their optimal bandwidth for the
//! Gaussian kernel, [`optimal_bandwidth`]: 0.50 for `N = 3`, 0.56 for
//! `N = 5` at `P = 100`),
//! ```text
//! x⁽ⁱ⁾ ← x̂ + a (x⁽ⁱ⁾ − x̂) + h L ξ⁽ⁱ⁾,   a = √(1 − h²),  ξ ~ N(0, I)
//! ```
//! (angles: deviations wrapped, results wrapped). The shrinkage `a` (Liu &
//! West 2001, *Combined parameter and state estimation in simulation-based
//! filtering*) keeps the cloud's mean and covariance, where Musso et al.'s
//! plain kernel would inflate the covariance by `1 + h²` at every
//! resampling; it replaces the copies resampling makes by distinct
//! particles (sample impoverishment), which is what a small process noise
//! cannot do. The same setting applies a sharp likelihood in stages
//! (progressive correction, Oudjane & Musso 2000; Musso et al. 2001,
//! §12.5): when the weighted mean of `ℓ⁽ⁱ⁾ − min ℓ` (`ℓ = ½ Σ (r/σ_r)²`,
//! nats) exceeds 2, the likelihood is applied as `p(z|x)^λ` with
//! `λ = 2 / spread`, the cloud resampled and regularized, `ℓ` recomputed
//! on the new particles, and so on until the exponents add up to 1 (at
//! most 32 stages; the last takes what remains; each extra stage is
//! counted in `correction_stages`). A prior much wider than the
//! measurement noise then converges onto the measurement instead of onto
//! its single closest particle. Without regularization (the default) an
//! update is one stage, bit for bit the plain filter's.
//!
//! # Roughening (opt-in)
//! With [`ParticleFilterConfig::with_roughening`]`(K)`, every resampling
//! is followed by the roughening of Gordon, Salmond & Smith 1993 (*Novel
//! approach to nonlinear/non-Gaussian Bayesian state estimation*, IEE
//! Proc. F 140(2):107–113, §4): each component `k` of each particle gets
//! an independent `N(0, σ_k²)` jitter, `σ_k = K E_k P^{−1/d}`, `E_k` the
//! component's range over the resampled particles (angles: of their
//! wrapped deviations from the estimate) and `d` the number of components
//! with a non-zero range (a component all particles share, e.g. a wheel
//! scale that is not estimated, stays as it is). It needs no covariance
//! factor (unlike the regularization above), and does not turn on
//! progressive correction. Off by default, and then bit for bit the plain
//! filter.
//!
//! # A likelihood of the model's own
//! [`ParticleFilter::update_with_likelihood`] weights the particles by any
//! `−2 ln p(z | x)` the caller computes (e.g. a quantized measurement:
//! the indicator of the quantization cell, Karlsson & Gustafsson 2005,
//! *Particle filtering for quantized sensor information*, EUSIPCO), through
//! the same weighting, collapse, resampling and regularization as the
//! Gaussian update.
//!
//! # The optimal proposal (opt-in)
//! With [`ParticleFilterConfig::with_proposal`]`(`[`Proposal::Optimal`]`)`
//! the particles are drawn from the optimal importance density
//! `p(x_k | x_{k−1}⁽ⁱ⁾, y_k)` instead of the transition prior (Doucet,
//! Godsill & Andrieu 2000, *On sequential Monte Carlo sampling methods for
//! Bayesian filtering*, Stat. Comput. 10:197–208, §II.D; with the
//! resampling between weighting and drawing it is the fully adapted
//! auxiliary particle filter of Pitt & Shephard 1999, *Filtering via
//! simulation: auxiliary particle filters*, JASA 94:590–599). It is
//! closed-form when the measurement is the state plus Gaussian noise
//! (`h(x) = x`, `M = N`: the model says so with
//! [`ParticleModel::measures_state`], or [`ParticleFilter::new`] refuses
//! the setting) and the process noise is the additive diagonal `σ_q` of
//! the module's system. Per component, with `q = σ_q²`, `r = σ_r²`,
//! `f⁽ⁱ⁾ = f(x_{k−1}⁽ⁱ⁾, u)` and the residual `e⁽ⁱ⁾ = y − f⁽ⁱ⁾` (heading
//! components wrapped by the model's residual):
//! ```text
//! w_k⁽ⁱ⁾ ∝ w_{k−1}⁽ⁱ⁾ N(y; f⁽ⁱ⁾, Q + R),   ln: −½ Σ_j e_j² / (q_j + r_j)   (weights)
//! x̂_k = Σ_i w̃⁽ⁱ⁾ m⁽ⁱ⁾,   m⁽ⁱ⁾ = f⁽ⁱ⁾ + K ∘ e⁽ⁱ⁾,   K = q / (q + r)     (estimate)
//! resample if the effective sample size is below the threshold
//! x_k⁽ⁱ⁾ = m⁽ⁱ⁾ + √(K r) ∘ ξ⁽ⁱ⁾,  ξ ~ N(0, I)                          (draw)
//! ```
//! (`K r = q r/(q + r)`, the posterior variance of one component; a
//! component with `σ_r = +∞` gets `K = 0` and the prior's `σ_q`). The
//! weight does not depend on where the particle lands, so a process noise
//! far wider than the measurement noise (scenario 2 of paper 004: wheel
//! speeds moved by the torques by several rad/s per step, measured to
//! 0.1 rad/s) does not scatter the particles where the likelihood is nil,
//! as the prior does. [`ParticleFilter::predict`] therefore only moves
//! the particles to `f⁽ⁱ⁾` and leaves the draw pending (the estimate is their weighted
//! mean, the predicted mean, and [`ParticleFilter::covariance`] adds `Q`);
//! the next [`ParticleFilter::update`] weights and draws as above, and a
//! second prediction without an update in between first draws the
//! pending noise from the prior (no measurement came). The prior
//! `N(x̄_0, diag(σ_0²))` is handled the same way: the filter starts with
//! every particle at `x̄_0` and the draw pending with `σ_0` in place of
//! `σ_q`, so a first update draws from the exact posterior `p(x_0 | y_0)`
//! (all weights equal) rather than weighting a sparse cloud by a sharp
//! likelihood. An update that finds no draw pending (a second update on
//! the same step, or after a collapse) is the prior proposal's. Progressive correction does
//! not apply (the likelihood is applied in one stage); regularization, if
//! configured, follows the resampling before the draw. With the default
//! [`Proposal::Prior`] nothing of this runs, bit for bit.
//!
//! # Memory
//! Two particle arrays (the set and the resampling/prediction buffer),
//! `2·P·N·4` bytes, the weights and the log-likelihoods `8P`, and
//! `21N + 8M + 76` bytes of
//! configuration, estimate, angle flags, the optimal proposal's pending
//! spread, generator and counters (rounded
//! up to a multiple of 4), plus the model. Measured (`size_of`, the same on
//! a 32-bit MCU as on the host: every field is 4-byte aligned) with a
//! zero-sized model, `P = 100`: **3 364 B** for `N = M = 3` (scenario 1 of
//! the paper) and **5 024 B** for `N = M = 5` (scenario 2): keep the filter
//! in a `static` or a task's state rather than on a small stack. A
//! prediction calls the model's `transition` `P` times and draws up to
//! `N·P` Gaussians (`N·P/2` `ln`, `sqrt`, `sin`, `cos`); an update calls
//! `measure` and `measurement_residual` `P` times and `ln` and `exp` up to
//! `P` times each.
//!
//! # Example
//! ```
//! use nalgebra::Vector1;
//! use wmr_core::filters::particle_filter::{
//!     ParticleFilter, ParticleFilterConfig, ParticleFilterError, ParticleModel,
//! };
//!
//! /// A position (m) driven by a speed (m/s), measured directly.
//! struct Walk;
//!
//! impl ParticleModel<1, 1> for Walk {
//!     type Input = f32;
//!     fn transition(&self, x: &Vector1<f32>, v: &f32, dt_s: f32) -> Vector1<f32> {
//!         x.add_scalar(v * dt_s)
//!     }
//!     fn measure(&self, x: &Vector1<f32>) -> Vector1<f32> {
//!         *x
//!     }
//!     fn input_is_valid(&self, v: &f32) -> bool {
//!         v.is_finite()
//!     }
//! }
//!
//! // σ_q = 0.05 m per step, σ_r = 0.3 m; prior 0 ± √10 m, 100 particles.
//! let config = ParticleFilterConfig::new(Vector1::new(0.05), Vector1::new(0.3))?;
//! let mut pf: ParticleFilter<Walk, 1, 1, 100> =
//!     ParticleFilter::new(Walk, config, Vector1::new(0.0), Vector1::new(10f32.sqrt()), 42)?;
//! for _ in 0..50 {
//!     pf.predict(&0.0, 0.01);
//!     pf.update(&Vector1::new(1.0));
//! }
//! assert!((pf.estimate().x - 1.0).abs() < 0.2);
//! assert_eq!(pf.collapses(), 0);
//! # Ok::<(), ParticleFilterError>(())
//! ```

use nalgebra::{SMatrix, SVector};
use rand::rngs::Xoshiro128PlusPlus;
use rand::{Rng, SeedableRng};

use crate::math;

/// Default resampling threshold as a fraction of `P`: resample when the
/// effective sample size falls below `P/2`.
pub const DEFAULT_RESAMPLE_FRACTION: f32 = 0.5;

/// Default collapse gate on the squared normalised distance
/// `Σ_j (r_j/σ_r,j)²` of the measurement to the *closest* particle:
/// `−2 ln(f32::MIN_POSITIVE) ≈ 174.67`, where `exp(−d²/2)` (the paper's
/// linear-space likelihood) underflows `f32`'s normal range for every
/// particle (module docs).
pub const DEFAULT_COLLAPSE_GATE: f32 = 174.673_1;

/// Log-ratios to the best particle below this are weighted 0 (`e^−87` is
/// at the bottom of `f32`'s normal range).
const MIN_LOG_RATIO: f32 = -87.0;

/// Progressive correction (module docs): the most stages an update is
/// split into, and the likelihood spread (nats, weighted mean of the
/// log-likelihood above the best particle's) each stage may apply.
const MAX_STAGES: usize = 32;
const STAGE_NATS: f32 = 2.0;

/// 2⁻²⁴: one step of a 24-bit uniform draw.
const UNIT_24: f32 = 1.0 / 16_777_216.0;

/// How the particles of a step are drawn (module docs, "The optimal
/// proposal").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Proposal {
    /// The transition prior `p(x_k | x_{k−1})`: `f(x) + σ_q ∘ ξ`, weighted
    /// by the likelihood (the paper's; the default).
    #[default]
    Prior,
    /// The optimal importance density `p(x_k | x_{k−1}, y_k)` for a model
    /// that measures its state ([`ParticleModel::measures_state`]).
    Optimal,
}

/// A system for the [`ParticleFilter`]: `x_k = f(x_{k−1}, u, h) + w`,
/// `y = h(x) + v`, with the noises given by the [`ParticleFilterConfig`].
pub trait ParticleModel<const N: usize, const M: usize> {
    /// The input `u` held over a step.
    type Input;

    /// `f(x, u, dt_s)`: the deterministic part of the state after a step of
    /// `dt_s` seconds (the filter adds the process noise and wraps the
    /// angles). A non-finite result drops that particle (module docs).
    fn transition(&self, x: &SVector<f32, N>, u: &Self::Input, dt_s: f32) -> SVector<f32, N>;

    /// `h(x)`: the measurement expected in state `x`.
    fn measure(&self, x: &SVector<f32, N>) -> SVector<f32, M>;

    /// The residual `z − ẑ` (default: the plain difference). Override it to
    /// wrap angle components to (−π, π] ([`crate::math::wrap_angle`]), or a
    /// heading measured near ±π looks 2π away from half of the particles.
    fn measurement_residual(
        &self,
        z: &SVector<f32, M>,
        expected: &SVector<f32, M>,
    ) -> SVector<f32, M> {
        z - expected
    }

    /// Whether state component `index` (`< N`) is an angle in radians: it is
    /// then kept wrapped to (−π, π] and averaged on the circle (default:
    /// none is). Asked once, when the filter is built.
    fn is_angle(&self, index: usize) -> bool {
        let _ = index;
        false
    }

    /// Whether `u` may be used (default: always). Return `false` for a
    /// non-finite input to have the step skipped and counted before any
    /// particle is moved; otherwise a NaN input is caught only when it makes
    /// every propagated particle non-finite.
    fn input_is_valid(&self, u: &Self::Input) -> bool {
        let _ = u;
        true
    }

    /// Whether the measurement is the state itself, component for
    /// component (`M = N`, `h(x) = x`, and [`Self::measurement_residual`]
    /// the difference with the angles wrapped), and the process noise the
    /// additive `σ_q` of the default [`Self::sample_transition`] (default:
    /// `false`). Only then may the filter use [`Proposal::Optimal`], whose
    /// draw is computed from `f` and the noises rather than by the model.
    fn measures_state(&self) -> bool {
        false
    }

    /// One particle's step with its process noise, drawing standard
    /// normals from `gaussian`. The default is the module's
    /// `f(x, u, dt_s) + σ_q ∘ ξ` with the configured `σ_q` (`process_std`;
    /// a component whose noise would make it non-finite keeps its noiseless
    /// value; a non-finite `f` is returned as is, without drawing). Override
    /// it when the noise enters elsewhere, e.g. an odometry model that
    /// perturbs each wheel's travel. The filter wraps the angle components
    /// afterwards and drops a non-finite result (module docs).
    fn sample_transition(
        &self,
        x: &SVector<f32, N>,
        u: &Self::Input,
        dt_s: f32,
        process_std: &SVector<f32, N>,
        gaussian: &mut dyn FnMut() -> f32,
    ) -> SVector<f32, N> {
        let mut moved = self.transition(x, u, dt_s);
        if finite(&moved) {
            for (value, &sigma) in moved.iter_mut().zip(process_std.iter()) {
                if sigma > 0.0 {
                    let noisy = *value + sigma * gaussian();
                    if noisy.is_finite() {
                        *value = noisy;
                    }
                }
            }
        }
        moved
    }
}

/// Why a [`ParticleFilterConfig`] or a [`ParticleFilter`] was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum ParticleFilterError {
    /// A process-noise standard deviation is negative or not finite.
    ProcessStd,
    /// A measurement-noise standard deviation is not finite and positive
    /// (or so small that its inverse overflows).
    MeasurementStd,
    /// The resampling threshold is not a fraction in [0, 1].
    ResampleThreshold,
    /// A recovery standard deviation is negative or not finite.
    RecoveryStd,
    /// The collapse gate is NaN or not positive.
    CollapseGate,
    /// The regularization bandwidth scale is not in [0, 1/h_opt] (finite,
    /// `≥ 0`, and the kernel's bandwidth `h` at most 1).
    Regularization,
    /// The prior mean is not finite.
    PriorMean,
    /// A prior standard deviation is negative or not finite.
    PriorStd,
    /// `P = 0`: a filter needs at least one particle.
    NoParticles,
    /// [`Proposal::Optimal`] for a model that does not measure its state
    /// ([`ParticleModel::measures_state`], `M = N`).
    Proposal,
}

impl core::fmt::Display for ParticleFilterError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::ProcessStd => "each process-noise standard deviation must be finite and ≥ 0",
            Self::MeasurementStd => "each measurement-noise standard deviation must be finite and > 0 (and its inverse finite)",
            Self::ResampleThreshold => "the resampling threshold must be a fraction in [0, 1]",
            Self::RecoveryStd => "each recovery standard deviation must be finite and ≥ 0",
            Self::CollapseGate => "the collapse gate must be > 0 (not NaN)",
            Self::Regularization => "the regularization bandwidth scale must be finite and ≥ 0, and the kernel bandwidth h at most 1",
            Self::PriorMean => "the prior mean must be finite",
            Self::PriorStd => "each prior standard deviation must be finite and ≥ 0",
            Self::NoParticles => "the particle count P must be ≥ 1",
            Self::Proposal => "the optimal proposal needs a model whose measurement is its state (ParticleModel::measures_state, M = N)",
        })
    }
}

impl core::error::Error for ParticleFilterError {}

/// Validated noise levels and thresholds of a [`ParticleFilter`] with `N`
/// states and `M` measurements.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParticleFilterConfig<const N: usize, const M: usize> {
    process_std: SVector<f32, N>,
    measurement_std: SVector<f32, M>,
    inverse_measurement_std: SVector<f32, M>,
    resample_fraction: f32,
    recovery_std: Option<SVector<f32, N>>,
    collapse_gate: f32,
    regularization: f32,
    roughening: f32,
    proposal: Proposal,
}

impl<const N: usize, const M: usize> ParticleFilterConfig<N, M> {
    /// The process noise `σ_q` (per component, per *step*, in the state's
    /// units: the paper's discrete `Q = diag(σ_q²)`; scale it yourself if
    /// the step varies) and the measurement noise `σ_r` (per component, in
    /// the measurement's units: `R = diag(σ_r²)`). A zero `σ_q` leaves that
    /// component without noise. Resampling below `P/2`, the prior's spread
    /// for recovery and the default collapse gate until changed.
    ///
    /// # Errors
    /// [`ParticleFilterError::ProcessStd`] for a negative or non-finite
    /// `σ_q`, [`ParticleFilterError::MeasurementStd`] for a `σ_r` that is
    /// not finite and positive.
    pub fn new(
        process_std: SVector<f32, N>,
        measurement_std: SVector<f32, M>,
    ) -> Result<Self, ParticleFilterError> {
        if !non_negative(&process_std) {
            return Err(ParticleFilterError::ProcessStd);
        }
        let inverse_measurement_std = measurement_std.map(|s| 1.0 / s);
        let positive = measurement_std.iter().all(|&s| s.is_finite() && s > 0.0)
            && inverse_measurement_std.iter().all(|s| s.is_finite());
        if !positive {
            return Err(ParticleFilterError::MeasurementStd);
        }
        Ok(Self {
            process_std,
            measurement_std,
            inverse_measurement_std,
            resample_fraction: DEFAULT_RESAMPLE_FRACTION,
            recovery_std: None,
            collapse_gate: DEFAULT_COLLAPSE_GATE,
            regularization: 0.0,
            roughening: 0.0,
            proposal: Proposal::Prior,
        })
    }

    /// Resample when the effective sample size `1/Σw̃²` drops below
    /// `fraction·P` (default ½; 1: at nearly every update, as in the paper;
    /// 0: never).
    ///
    /// # Errors
    /// [`ParticleFilterError::ResampleThreshold`] unless `fraction` is in
    /// [0, 1].
    pub fn with_resample_threshold(self, fraction: f32) -> Result<Self, ParticleFilterError> {
        if !(0.0..=1.0).contains(&fraction) {
            return Err(ParticleFilterError::ResampleThreshold);
        }
        Ok(Self {
            resample_fraction: fraction,
            ..self
        })
    }

    /// The spread (per component, state units) the particles are redrawn
    /// with around the estimate after a collapse (default: the prior's).
    ///
    /// # Errors
    /// [`ParticleFilterError::RecoveryStd`] for a negative or non-finite
    /// entry.
    pub fn with_recovery_std(
        self,
        recovery_std: SVector<f32, N>,
    ) -> Result<Self, ParticleFilterError> {
        if !non_negative(&recovery_std) {
            return Err(ParticleFilterError::RecoveryStd);
        }
        Ok(Self {
            recovery_std: Some(recovery_std),
            ..self
        })
    }

    /// The collapse gate on `min_i Σ_j (r_j⁽ⁱ⁾/σ_r,j)²` (dimensionless;
    /// default [`DEFAULT_COLLAPSE_GATE`]); `f32::INFINITY` collapses only
    /// when no particle keeps a weight, so that a far-off measurement pulls
    /// all the weight onto the closest particles instead.
    ///
    /// # Errors
    /// [`ParticleFilterError::CollapseGate`] for NaN or a gate that is not
    /// positive.
    pub fn with_collapse_gate(self, gate: f32) -> Result<Self, ParticleFilterError> {
        if gate.is_nan() || gate <= 0.0 {
            return Err(ParticleFilterError::CollapseGate);
        }
        Ok(Self {
            collapse_gate: gate,
            ..self
        })
    }

    /// Regularizes after every resampling (module docs, "Regularization"):
    /// each resampled particle is shrunk towards the mean and jittered by
    /// a Gaussian kernel of bandwidth `h = scale · h_opt` (Musso, Oudjane &
    /// Le Gland 2001; `h_opt` their optimal bandwidth for `N` states and
    /// `P` particles; shrinkage after Liu & West 2001, so that the cloud's
    /// mean and covariance are kept). `scale = 0` (the default) turns it
    /// off; `1` is the optimal bandwidth for a Gaussian posterior, smaller
    /// values for a multimodal one.
    ///
    /// # Errors
    /// [`ParticleFilterError::Regularization`] for a negative or
    /// non-finite scale; [`ParticleFilter::new`] refuses one whose `h`
    /// exceeds 1 for its `N` and `P`.
    pub fn with_regularization(self, scale: f32) -> Result<Self, ParticleFilterError> {
        if !(scale.is_finite() && scale >= 0.0) {
            return Err(ParticleFilterError::Regularization);
        }
        Ok(Self {
            regularization: scale,
            ..self
        })
    }

    /// Roughening after every resampling (module docs, "Roughening";
    /// Gordon, Salmond & Smith 1993): each component of each particle
    /// jittered by `N(0, (K E_k P^{−1/d})²)`, `E_k` the component's range
    /// over the resampled particles and `d` the number of components with
    /// a non-zero range. `K = 0` (the default) turns it off.
    ///
    /// # Errors
    /// [`ParticleFilterError::Regularization`] for a negative or
    /// non-finite `K`.
    pub fn with_roughening(self, k: f32) -> Result<Self, ParticleFilterError> {
        if !(k.is_finite() && k >= 0.0) {
            return Err(ParticleFilterError::Regularization);
        }
        Ok(Self {
            roughening: k,
            ..self
        })
    }

    /// The roughening constant `K` (0: off).
    #[must_use]
    pub fn roughening(&self) -> f32 {
        self.roughening
    }

    /// Draws the particles from `proposal` (default [`Proposal::Prior`];
    /// module docs, "The optimal proposal"). [`ParticleFilter::new`]
    /// refuses [`Proposal::Optimal`] for a model that does not measure its
    /// state.
    #[must_use]
    pub fn with_proposal(self, proposal: Proposal) -> Self {
        Self { proposal, ..self }
    }

    /// How the particles are drawn.
    #[must_use]
    pub fn proposal(&self) -> Proposal {
        self.proposal
    }

    /// The regularization bandwidth as a multiple of the optimal one (0:
    /// off).
    #[must_use]
    pub fn regularization(&self) -> f32 {
        self.regularization
    }

    /// `σ_q`, per component and step, state units.
    #[must_use]
    pub fn process_std(&self) -> &SVector<f32, N> {
        &self.process_std
    }

    /// `σ_r`, per component, measurement units.
    #[must_use]
    pub fn measurement_std(&self) -> &SVector<f32, M> {
        &self.measurement_std
    }

    /// The resampling threshold as a fraction of `P`.
    #[must_use]
    pub fn resample_fraction(&self) -> f32 {
        self.resample_fraction
    }

    /// The configured recovery spread (`None`: the prior's).
    #[must_use]
    pub fn recovery_std(&self) -> Option<&SVector<f32, N>> {
        self.recovery_std.as_ref()
    }

    /// The collapse gate (squared normalised distance).
    #[must_use]
    pub fn collapse_gate(&self) -> f32 {
        self.collapse_gate
    }
}

/// The optimal bandwidth of a Gaussian kernel for `states` dimensions and
/// `particles` particles (Musso, Oudjane & Le Gland 2001, eq. for
/// `h_opt` with the Gaussian kernel): `(4 / (P (N + 2)))^{1/(N + 4)}`.
#[must_use]
pub fn optimal_bandwidth(states: usize, particles: usize) -> f32 {
    let base = 4.0 / (particles as f32 * (states as f32 + 2.0));
    math::exp(math::ln(base) / (states as f32 + 4.0))
}

/// Wraps the components of `x` flagged in `angles` to (−π, π].
// Always inlined: as a call it cost the N = 5 predicts 0.9–1.7 % on the
// Cortex-M4 (`cargo xtask bench-target`); inlined, the counts are unchanged.
#[inline(always)]
fn wrap_angles<const N: usize>(x: &mut SVector<f32, N>, angles: &[bool; N]) {
    for (value, &angle) in x.iter_mut().zip(angles.iter()) {
        if angle {
            *value = math::wrap_angle(*value);
        }
    }
}

/// `true` if every entry is finite and `≥ 0`.
fn non_negative<const K: usize>(v: &SVector<f32, K>) -> bool {
    v.iter().all(|&s| s.is_finite() && s >= 0.0)
}

/// The lower Cholesky factor of a finite, symmetric (to 1e-6 of its
/// largest entry) covariance, jittered by 1e-5 of its largest diagonal
/// entry if it is only semi-definite; `None` otherwise.
fn covariance_factor<const K: usize>(c: &SMatrix<f32, K, K>) -> Option<SMatrix<f32, K, K>> {
    let scale = c.amax();
    if !(c.iter().all(|v| v.is_finite()) && (c - c.transpose()).amax() <= 1e-6 * scale) {
        return None;
    }
    let symmetric = (c + c.transpose()) * 0.5;
    if let Some(l) = nalgebra::Cholesky::new(symmetric) {
        return Some(l.l());
    }
    let jitter = (1e-5 * symmetric.diagonal().amax()).max(f32::MIN_POSITIVE);
    nalgebra::Cholesky::new(symmetric + SMatrix::<f32, K, K>::identity() * jitter).map(|l| l.l())
}

/// `true` if every entry is finite.
fn finite<const K: usize>(v: &SVector<f32, K>) -> bool {
    v.iter().all(|s| s.is_finite())
}

/// What a [`ParticleFilter`] did besides its normal steps: nothing is
/// dropped silently.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct ParticleFilterCounters {
    /// Systematic resamplings (effective sample size below the threshold).
    pub resamplings: u32,
    /// Collapses recovered from by redrawing the particles (module docs).
    pub collapses: u32,
    /// Steps skipped: non-finite `z` or `dt_s`, negative `dt_s`, an input
    /// the model refused, or a prediction that left no particle finite.
    pub rejected_inputs: u32,
    /// Particles whose propagation came out non-finite (given weight 0).
    pub dropped_particles: u32,
    /// Extra stages of progressive correction (each a partial update, a
    /// resampling and a regularization: module docs).
    pub correction_stages: u32,
}

/// The seeded generator and the spare Gaussian draw of Box–Muller.
#[derive(Debug, Clone, PartialEq)]
struct Noise {
    rng: Xoshiro128PlusPlus,
    spare: Option<f32>,
}

impl Noise {
    fn new(seed: u64) -> Self {
        Self {
            rng: Xoshiro128PlusPlus::seed_from_u64(seed),
            spare: None,
        }
    }

    /// Uniform in [0, 1), 24 bits.
    fn uniform(&mut self) -> f32 {
        (self.rng.next_u32() >> 8) as f32 * UNIT_24
    }

    /// Standard normal (Box–Muller, module docs).
    fn gaussian(&mut self) -> f32 {
        if let Some(z) = self.spare.take() {
            return z;
        }
        // (0, 1]: ln stays finite.
        let u1 = ((self.rng.next_u32() >> 8) + 1) as f32 * UNIT_24;
        let angle = math::TAU * self.uniform();
        // max(0): an approximate ln(1) may come out a hair above 0.
        let radius = math::sqrt((-2.0 * math::ln(u1)).max(0.0));
        let (sin, cos) = math::sincos(angle);
        self.spare = Some(radius * sin);
        radius * cos
    }

    /// `x + σ ∘ ξ`, `ξ ~ N(0, I)`, angle components wrapped; a component
    /// that would overflow keeps its value.
    fn perturb<const N: usize>(
        &mut self,
        x: &mut SVector<f32, N>,
        std: &SVector<f32, N>,
        angles: &[bool; N],
    ) {
        for ((value, &sigma), &angle) in x.iter_mut().zip(std.iter()).zip(angles.iter()) {
            let moved = if sigma > 0.0 {
                *value + sigma * self.gaussian()
            } else {
                *value
            };
            let moved = if angle {
                math::wrap_angle(moved)
            } else {
                moved
            };
            if moved.is_finite() {
                *value = moved;
            }
        }
    }
}

/// Systematic resampling (module docs): copies `source[i]` into `out` once
/// for each pointer `(k + uniform)/P · Σw` that falls in particle `i`'s
/// stretch of the cumulative weights, in order. Negative and NaN weights
/// count as 0; a `uniform` outside [0, 1) (or NaN) is taken as 0.
///
/// Returns `false` (and leaves `out` alone) if the weights do not add up to
/// a finite positive total.
pub fn systematic_resample<T: Copy, const P: usize>(
    source: &[T; P],
    weights: &[f32; P],
    uniform: f32,
    out: &mut [T; P],
) -> bool {
    let clean = |w: f32| if w > 0.0 { w } else { 0.0 };
    let total: f32 = weights.iter().map(|&w| clean(w)).sum();
    if !(total.is_finite() && total > 0.0) {
        return false;
    }
    let uniform = if (0.0..1.0).contains(&uniform) {
        uniform
    } else {
        0.0
    };
    let step = total / P as f32;
    let mut candidates = source.iter().zip(weights.iter().map(|&w| clean(w)));
    let mut chosen: Option<&T> = None;
    let mut cumulative = 0.0_f32;
    for (k, slot) in out.iter_mut().enumerate() {
        let pointer = (k as f32 + uniform) * step;
        // Advance to the first particle whose stretch ends past the pointer;
        // zero-weight particles have no stretch and are never chosen (past
        // the end, rounding keeps the last positive one).
        while chosen.is_none() || pointer >= cumulative {
            let Some((x, w)) = candidates.next() else {
                break;
            };
            if w > 0.0 {
                chosen = Some(x);
                cumulative += w;
            }
        }
        if let Some(x) = chosen {
            *slot = *x;
        }
    }
    true
}

/// `Σ_j (r_j/σ_r,j)²` of the residual of `z` at `x` (`inverse_std` =
/// `1/σ_r`): twice the Gaussian negative log-likelihood.
fn gaussian_distance_sq<Model, const N: usize, const M: usize>(
    model: &Model,
    z: &SVector<f32, M>,
    x: &SVector<f32, N>,
    inverse_std: &SVector<f32, M>,
) -> f32
where
    Model: ParticleModel<N, M>,
{
    let residual = model.measurement_residual(z, &model.measure(x));
    residual
        .iter()
        .zip(inverse_std.iter())
        .map(|(r, inv)| {
            let n = r * inv;
            n * n
        })
        .sum()
}

/// Scales the weights to sum 1; `false` if their sum is not finite and
/// positive (then they are left alone).
fn normalise<const P: usize>(weights: &mut [f32; P]) -> bool {
    let total: f32 = weights.iter().sum();
    if !(total.is_finite() && total > 0.0) {
        return false;
    }
    let scale = 1.0 / total;
    for w in weights.iter_mut() {
        *w *= scale;
    }
    true
}

/// The particle filter (module docs): model `Model`, `N` states, `M`
/// measurements, `P` particles.
#[derive(Debug, Clone, PartialEq)]
pub struct ParticleFilter<Model, const N: usize, const M: usize, const P: usize>
where
    Model: ParticleModel<N, M>,
{
    model: Model,
    config: ParticleFilterConfig<N, M>,
    /// The spread of a collapse's redraw, resolved at construction.
    recovery_std: SVector<f32, N>,
    /// Which components are angles (asked of the model once).
    angles: [bool; N],
    /// The regularization kernel's bandwidth `h` (0: off) and its
    /// shrinkage `a = √(1 − h²)`, resolved at construction.
    bandwidth: f32,
    shrinkage: f32,
    particles: [SVector<f32, N>; P],
    /// Where predictions and resamplings are built before being taken.
    buffer: [SVector<f32, N>; P],
    /// Normalised (sum 1) between calls.
    weights: [f32; P],
    /// `ℓ⁽ⁱ⁾ = −ln p(z | x⁽ⁱ⁾) + const` of the update in progress.
    log_likelihood: [f32; P],
    estimate: SVector<f32, N>,
    noise: Noise,
    counters: ParticleFilterCounters,
    /// [`Proposal::Optimal`]: the particles are `f(x_{k−1})` (or, before
    /// the first update, the prior mean), their noise still to draw
    /// (module docs, "The optimal proposal").
    draw_pending: bool,
    /// The standard deviations of that noise: `σ_q`, or the prior's.
    pending_std: SVector<f32, N>,
}

impl<Model, const N: usize, const M: usize, const P: usize> ParticleFilter<Model, N, M, P>
where
    Model: ParticleModel<N, M>,
{
    /// A filter whose `P` particles are drawn from the Gaussian prior
    /// `N(prior_mean, diag(prior_std²))` (per component, state units; the
    /// paper's `P(0) = 10 I` is `prior_std = √10` everywhere) with equal
    /// weights, by a generator seeded with `seed`. The estimate is
    /// `prior_mean` (angles wrapped) until the first step.
    ///
    /// # Errors
    /// [`ParticleFilterError::NoParticles`] for `P = 0`,
    /// [`ParticleFilterError::PriorMean`] for a non-finite mean,
    /// [`ParticleFilterError::PriorStd`] for a negative or non-finite
    /// spread, [`ParticleFilterError::Proposal`] for
    /// [`Proposal::Optimal`] with a model that does not measure its state.
    pub fn new(
        model: Model,
        config: ParticleFilterConfig<N, M>,
        prior_mean: SVector<f32, N>,
        prior_std: SVector<f32, N>,
        seed: u64,
    ) -> Result<Self, ParticleFilterError> {
        if P == 0 {
            return Err(ParticleFilterError::NoParticles);
        }
        if !finite(&prior_mean) {
            return Err(ParticleFilterError::PriorMean);
        }
        if !non_negative(&prior_std) {
            return Err(ParticleFilterError::PriorStd);
        }
        if config.proposal == Proposal::Optimal && !(M == N && model.measures_state()) {
            return Err(ParticleFilterError::Proposal);
        }
        let bandwidth = if config.regularization > 0.0 {
            config.regularization * optimal_bandwidth(N, P)
        } else {
            0.0
        };
        if !(bandwidth.is_finite() && bandwidth <= 1.0) {
            return Err(ParticleFilterError::Regularization);
        }
        let shrinkage = math::sqrt((1.0 - bandwidth * bandwidth).max(0.0));
        let angles: [bool; N] = core::array::from_fn(|index| model.is_angle(index));
        let mut mean = prior_mean;
        wrap_angles(&mut mean, &angles);
        let mut filter = Self {
            model,
            recovery_std: config.recovery_std.unwrap_or(prior_std),
            config,
            angles,
            bandwidth,
            shrinkage,
            particles: [mean; P],
            buffer: [mean; P],
            weights: [1.0 / P as f32; P],
            log_likelihood: [0.0; P],
            estimate: mean,
            noise: Noise::new(seed),
            counters: ParticleFilterCounters::default(),
            draw_pending: false,
            pending_std: prior_std,
        };
        if filter.config.proposal == Proposal::Optimal {
            // The first update draws from p(x_0 | y_0) (module docs).
            filter.draw_pending = true;
        } else {
            filter.redraw(&prior_std);
        }
        Ok(filter)
    }

    /// The model.
    #[must_use]
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The configuration.
    #[must_use]
    pub fn config(&self) -> &ParticleFilterConfig<N, M> {
        &self.config
    }

    /// The MMSE estimate `Σ w̃⁽ⁱ⁾ x⁽ⁱ⁾` after the last step (circular mean for
    /// angles, in (−π, π]); the prior mean before any step; unchanged by a
    /// rejected step or a collapse.
    #[must_use]
    pub fn estimate(&self) -> SVector<f32, N> {
        self.estimate
    }

    /// The weighted covariance `Σ w̃⁽ⁱ⁾ d⁽ⁱ⁾ d⁽ⁱ⁾ᵀ` of the particles as they
    /// are now (after a resampling: of the resampled set) about
    /// [`Self::estimate`], `d = x⁽ⁱ⁾ − x̂` with angle components wrapped to
    /// (−π, π] (for angles: a small-spread approximation), plus
    /// `diag(σ_q²)` while a draw of the optimal proposal is pending
    /// (between a prediction and its update). State units
    /// squared. If the spread overflows `f32` (deviations beyond about
    /// 10¹⁹ state units, after absurd but finite inputs) the result is
    /// `f32::MAX · I`: finite, and as uncertain as `f32` can say.
    #[must_use]
    pub fn covariance(&self) -> SMatrix<f32, N, N> {
        let mut covariance = SMatrix::<f32, N, N>::zeros();
        for (x, &w) in self.particles.iter().zip(self.weights.iter()) {
            let d = self.deviation(x, &self.estimate);
            covariance += (d * d.transpose()) * w;
        }
        if self.draw_pending {
            for (i, &sigma) in self.pending_std.iter().enumerate() {
                if let Some(c) = covariance.get_mut((i, i)) {
                    *c += sigma * sigma;
                }
            }
        }
        if covariance.iter().all(|c| c.is_finite()) {
            covariance
        } else {
            SMatrix::<f32, N, N>::identity() * f32::MAX
        }
    }

    /// The effective sample size `1/Σ w̃²`, from 1 (one particle holds all
    /// the weight) to `P` (equal weights).
    #[must_use]
    pub fn effective_sample_size(&self) -> f32 {
        let sum_sq: f32 = self.weights.iter().map(|w| w * w).sum();
        if sum_sq > 0.0 { 1.0 / sum_sq } else { 0.0 }
    }

    /// The particles.
    #[must_use]
    pub fn particles(&self) -> &[SVector<f32, N>; P] {
        &self.particles
    }

    /// Their normalised weights (sum 1).
    #[must_use]
    pub fn weights(&self) -> &[f32; P] {
        &self.weights
    }

    /// What was resampled, recovered or skipped.
    #[must_use]
    pub fn counters(&self) -> ParticleFilterCounters {
        self.counters
    }

    /// Systematic resamplings so far.
    #[must_use]
    pub fn resamplings(&self) -> u32 {
        self.counters.resamplings
    }

    /// Collapses recovered from so far.
    #[must_use]
    pub fn collapses(&self) -> u32 {
        self.counters.collapses
    }

    /// Steps skipped for bad input so far.
    #[must_use]
    pub fn rejected_inputs(&self) -> u32 {
        self.counters.rejected_inputs
    }

    /// Prediction (importance sampling, steps 2 and 5 of the module docs):
    /// every particle moves to `f(x, u, dt_s) + σ_q ∘ ξ` (angles wrapped),
    /// the weights stay, and the estimate becomes the predicted mean.
    /// Skipped and counted for a non-finite or negative `dt_s`, an input
    /// the model refuses, or one that leaves no particle finite.
    ///
    /// With [`Proposal::Optimal`] the particles move to `f(x, u, dt_s)`
    /// only, and the update draws their noise (module docs, "The optimal
    /// proposal"); a draw still pending from the previous prediction (no
    /// update came) is first made from the prior, `σ_q ∘ ξ`.
    pub fn predict(&mut self, u: &Model::Input, dt_s: f32) {
        if !(dt_s.is_finite() && dt_s >= 0.0 && self.model.input_is_valid(u)) {
            self.reject();
            return;
        }
        let optimal = self.config.proposal == Proposal::Optimal;
        if optimal && self.draw_pending {
            let spread = self.pending_std;
            self.diffuse(&spread);
            self.draw_pending = false;
        }
        let mut dropped = 0_usize;
        let noise = &mut self.noise;
        let mut gaussian = || noise.gaussian();
        for (x, next) in self.particles.iter().zip(self.buffer.iter_mut()) {
            let mut moved = if optimal {
                self.model.transition(x, u, dt_s)
            } else {
                self.model
                    .sample_transition(x, u, dt_s, &self.config.process_std, &mut gaussian)
            };
            if finite(&moved) {
                wrap_angles(&mut moved, &self.angles);
                *next = moved;
            } else {
                // Marks the particle as dropped for the pass below.
                *next = SVector::repeat(f32::NAN);
                dropped += 1;
            }
        }
        if dropped >= P {
            self.reject();
            return;
        }
        for ((x, next), w) in self
            .particles
            .iter_mut()
            .zip(self.buffer.iter())
            .zip(self.weights.iter_mut())
        {
            if finite(next) {
                *x = *next;
            } else {
                *w = 0.0;
            }
        }
        if dropped > 0 {
            let dropped = u32::try_from(dropped).unwrap_or(u32::MAX);
            self.counters.dropped_particles =
                self.counters.dropped_particles.saturating_add(dropped);
            if !normalise(&mut self.weights) {
                self.collapse();
                return;
            }
        }
        self.draw_pending = optimal;
        self.pending_std = self.config.process_std;
        self.refresh_estimate();
    }

    /// Measurement update with `z` (steps 3–6 of the module docs): the
    /// weights are multiplied by the Gaussian likelihood of `z` (in log
    /// space), normalised, the estimate becomes their weighted mean, and
    /// the particles are resampled if the effective sample size fell below
    /// the threshold. A non-finite `z` is skipped and counted; a collapse is
    /// recovered from as the module docs say.
    pub fn update(&mut self, z: &SVector<f32, M>) {
        if self.draw_pending {
            let std = self.config.measurement_std;
            self.update_optimal(z, &std);
            return;
        }
        let inverse_std = self.config.inverse_measurement_std;
        self.update_weights(z, &inverse_std);
    }

    /// [`Self::update`] with, for this call only, the measurement noise
    /// `σ_r = std` (per component, measurement units). A component with
    /// `σ_r = +∞` is not measured: it adds nothing to any weight, whatever
    /// its `z` (which must still be finite). A NaN, zero or negative `σ_r`
    /// (or one whose inverse overflows) skips the step, counted as a
    /// rejected input.
    pub fn update_with_std(&mut self, z: &SVector<f32, M>, std: &SVector<f32, M>) {
        let inverse_std = std.map(|s| 1.0 / s);
        let valid = std.iter().all(|&s| s > 0.0) && finite(&inverse_std);
        if !valid {
            self.reject();
            return;
        }
        if self.draw_pending {
            self.update_optimal(z, std);
            return;
        }
        self.update_weights(z, &inverse_std);
    }

    /// [`Self::update`] with a likelihood of the model's own:
    /// `distance_sq(x)` is `−2 ln p(z | x)` up to a constant, in place of
    /// the Gaussian `Σ_j (r_j/σ_r,j)²` (e.g. a quantized measurement: 0 in
    /// the cell the reading names, growing outside it). It goes through the
    /// same weighting, collapse gate, progressive correction (if
    /// regularized), resampling and regularization as the Gaussian update.
    /// A particle whose `distance_sq` is NaN or `+∞` gets weight 0; if no
    /// particle keeps a finite one the update is a collapse (module docs).
    /// A draw of the optimal proposal still pending is first made from the
    /// prior (the likelihood is not Gaussian, so no closed-form draw).
    pub fn update_with_likelihood(&mut self, distance_sq: impl Fn(&SVector<f32, N>) -> f32) {
        if self.draw_pending {
            let spread = self.pending_std;
            self.diffuse(&spread);
            self.draw_pending = false;
        }
        self.update_weights_by(|_, x| distance_sq(x));
    }

    /// Restarts from `N(mean, covariance)`: every particle is redrawn from
    /// that Gaussian (through the lower Cholesky factor of `covariance`,
    /// after the same symmetrise-and-jitter repair as the UKF's if it is
    /// only semi-definite), with equal weights, and the estimate becomes
    /// `mean` (angles wrapped). Counters and the generator's stream go on.
    ///
    /// # Errors
    /// [`ParticleFilterError::PriorMean`] for a non-finite mean,
    /// [`ParticleFilterError::PriorStd`] for a covariance that is not
    /// finite, symmetric and positive semi-definite; the filter is then
    /// unchanged.
    pub fn reset(
        &mut self,
        mean: &SVector<f32, N>,
        covariance: &SMatrix<f32, N, N>,
    ) -> Result<(), ParticleFilterError> {
        if !finite(mean) {
            return Err(ParticleFilterError::PriorMean);
        }
        let Some(factor) = covariance_factor(covariance) else {
            return Err(ParticleFilterError::PriorStd);
        };
        let mut centre = *mean;
        wrap_angles(&mut centre, &self.angles);
        for x in self.particles.iter_mut() {
            let draw = SVector::<f32, N>::from_fn(|_, _| self.noise.gaussian());
            let mut moved = centre + factor * draw;
            wrap_angles(&mut moved, &self.angles);
            *x = if finite(&moved) { moved } else { centre };
        }
        self.weights = [1.0 / P as f32; P];
        self.estimate = centre;
        self.draw_pending = false;
        Ok(())
    }

    /// The update of the optimal proposal (module docs, "The optimal
    /// proposal"), on particles at `f(x_{k−1})`: weights by
    /// `N(z; f, Q + R)`, the estimate from the per-particle posterior
    /// means, resampling on the effective sample size, then the draw.
    fn update_optimal(&mut self, z: &SVector<f32, M>, std: &SVector<f32, M>) {
        if !finite(z) {
            self.reject();
            return;
        }
        // Per component (M = N, checked at construction): the gain
        // K = q/(q + r), the posterior spread √(K r), and 1/√(q + r) for the
        // weights; an unmeasured component (r = ∞) keeps the prior's σ_q.
        let mut gain = SVector::<f32, M>::zeros();
        let mut spread = SVector::<f32, N>::zeros();
        let mut inverse_std = SVector::<f32, M>::zeros();
        let components = gain
            .iter_mut()
            .zip(spread.iter_mut())
            .zip(inverse_std.iter_mut())
            .zip(self.pending_std.iter().zip(std.iter()));
        for (((k, s), inv), (&sigma_q, &sigma_r)) in components {
            let (q, r) = (sigma_q * sigma_q, sigma_r * sigma_r);
            if r.is_finite() {
                *k = q / (q + r);
                *s = math::sqrt(*k * r);
                *inv = 1.0 / math::sqrt(q + r);
            } else {
                *s = sigma_q;
            }
        }
        if !(finite(&gain) && finite(&spread) && finite(&inverse_std)) {
            self.reject();
            return;
        }
        let (closest, _) = self.log_likelihoods(z, &inverse_std);
        if !closest.is_finite() || closest > self.config.collapse_gate || !self.weigh(1.0) {
            self.collapse();
            return;
        }
        for i in 0..P {
            let Some(x) = self.particles.get(i).copied() else {
                break;
            };
            let innovation = self.model.measurement_residual(z, &self.model.measure(&x));
            let mut mean = x;
            for ((value, &e), &k) in mean.iter_mut().zip(innovation.iter()).zip(gain.iter()) {
                *value += k * e;
            }
            wrap_angles(&mut mean, &self.angles);
            if finite(&mean)
                && let Some(slot) = self.particles.get_mut(i)
            {
                *slot = mean;
            }
        }
        // Refreshed again, on the posterior means. (`weigh` refreshed it on
        // `f`; skipping that pass moves the linear components' reference
        // point and so the last bits of every run: left as it is.)
        self.refresh_estimate();
        self.draw_pending = false;
        self.resample_if_degenerate();
        self.diffuse(&spread);
    }

    /// Resamples if the effective sample size fell below the threshold.
    fn resample_if_degenerate(&mut self) {
        let threshold = self.config.resample_fraction * P as f32;
        if self.effective_sample_size() < threshold {
            self.resample();
        }
    }

    /// Every particle `x + σ ∘ ξ` (angles wrapped): the optimal proposal's
    /// draws.
    fn diffuse(&mut self, spread: &SVector<f32, N>) {
        for x in self.particles.iter_mut() {
            self.noise.perturb(x, spread, &self.angles);
        }
    }

    fn update_weights(&mut self, z: &SVector<f32, M>, inverse_std: &SVector<f32, M>) {
        if !finite(z) {
            self.reject();
            return;
        }
        self.update_weights_by(|model, x| gaussian_distance_sq(model, z, x, inverse_std));
    }

    /// [`Self::update_weights`] with `distance_sq(model, x)` in place of
    /// the Gaussian `Σ_j (r_j/σ_r,j)²` (`ℓ = ½ distance_sq`).
    fn update_weights_by(&mut self, mut distance_sq: impl FnMut(&Model, &SVector<f32, N>) -> f32) {
        // The share of the likelihood still to apply (progressive
        // correction, module docs; one stage without regularization).
        let mut remaining = 1.0_f32;
        for stage in 0..MAX_STAGES {
            let (closest, spread) = self.log_likelihoods_by(&mut distance_sq);
            if !closest.is_finite() || closest > self.config.collapse_gate {
                self.collapse();
                return;
            }
            let last = self.bandwidth <= 0.0
                || stage + 1 >= MAX_STAGES
                || remaining * spread <= STAGE_NATS;
            let exponent = if last { remaining } else { STAGE_NATS / spread };
            if !self.weigh(exponent) {
                self.collapse();
                return;
            }
            if last {
                self.resample_if_degenerate();
                return;
            }
            self.resample();
            self.counters.correction_stages = self.counters.correction_stages.saturating_add(1);
            remaining -= exponent;
        }
    }

    /// Fills `log_likelihood` with `½ Σ_j (r_j⁽ⁱ⁾/σ_r,j)²` (`+∞` for a
    /// particle without weight or with a non-finite residual); returns the
    /// smallest `Σ_j (r_j/σ_r,j)²` of a weighted particle (`+∞` if none)
    /// and the weighted mean of `ℓ⁽ⁱ⁾ − min ℓ` (the likelihood's spread over
    /// the cloud, nats).
    fn log_likelihoods(
        &mut self,
        z: &SVector<f32, M>,
        inverse_std: &SVector<f32, M>,
    ) -> (f32, f32) {
        self.log_likelihoods_by(|model, x| gaussian_distance_sq(model, z, x, inverse_std))
    }

    /// [`Self::log_likelihoods`] with `distance_sq(model, x)` in place of
    /// the Gaussian `Σ_j (r_j/σ_r,j)²`.
    fn log_likelihoods_by(
        &mut self,
        mut distance_sq: impl FnMut(&Model, &SVector<f32, N>) -> f32,
    ) -> (f32, f32) {
        let mut closest = f32::INFINITY;
        let mut weighted = 0.0_f32;
        for ((x, &w), l) in self
            .particles
            .iter()
            .zip(self.weights.iter())
            .zip(self.log_likelihood.iter_mut())
        {
            let distance_sq = distance_sq(&self.model, x);
            *l = if w >= f32::MIN_POSITIVE && distance_sq.is_finite() {
                if distance_sq < closest {
                    closest = distance_sq;
                }
                weighted += w * distance_sq;
                0.5 * distance_sq
            } else {
                f32::INFINITY
            };
        }
        let spread = 0.5 * (weighted - closest);
        let spread = if spread.is_finite() && spread > 0.0 {
            spread
        } else {
            0.0
        };
        (closest, spread)
    }

    /// `w⁽ⁱ⁾ ← w⁽ⁱ⁾ e^{−λ ℓ⁽ⁱ⁾}` in log space, normalised, and the estimate
    /// refreshed; `false` if no weight or no finite estimate is left.
    fn weigh(&mut self, exponent: f32) -> bool {
        let mut max_log = f32::NEG_INFINITY;
        for (w, &l) in self.weights.iter_mut().zip(self.log_likelihood.iter()) {
            let log_weight = if *w >= f32::MIN_POSITIVE && l.is_finite() {
                math::ln(*w) - exponent * l
            } else {
                f32::NEG_INFINITY
            };
            let log_weight = if log_weight.is_nan() {
                f32::NEG_INFINITY
            } else {
                log_weight
            };
            if log_weight > max_log {
                max_log = log_weight;
            }
            *w = log_weight;
        }
        if !max_log.is_finite() {
            return false;
        }
        for w in self.weights.iter_mut() {
            let ratio = *w - max_log;
            *w = if ratio > MIN_LOG_RATIO {
                math::exp(ratio)
            } else {
                0.0
            };
        }
        normalise(&mut self.weights) && self.refresh_estimate()
    }

    /// Systematic resampling into the buffer, then back; weights `1/P`;
    /// then the regularization, if configured.
    fn resample(&mut self) {
        // The kernel's shape: the weighted cloud's covariance before
        // resampling (the resampled one's expectation, without its noise).
        let factor = if self.bandwidth > 0.0 {
            covariance_factor(&self.covariance())
        } else {
            None
        };
        let uniform = self.noise.uniform();
        if systematic_resample(&self.particles, &self.weights, uniform, &mut self.buffer) {
            self.particles = self.buffer;
            self.weights = [1.0 / P as f32; P];
            self.counters.resamplings = self.counters.resamplings.saturating_add(1);
            if let Some(factor) = factor {
                self.regularize(&(factor * self.bandwidth));
            }
            if self.config.roughening > 0.0 {
                self.roughen();
            }
        }
    }

    /// Roughening (module docs): every particle jittered by
    /// `K E_k P^{−1/d}` per component, angles by the range of their
    /// deviations from the estimate.
    fn roughen(&mut self) {
        let mut low = SVector::<f32, N>::repeat(f32::INFINITY);
        let mut high = SVector::<f32, N>::repeat(f32::NEG_INFINITY);
        for x in &self.particles {
            let d = self.deviation(x, &self.estimate);
            low = low.inf(&d);
            high = high.sup(&d);
        }
        let range = high - low;
        let dimensions = range.iter().filter(|&&e| e > 0.0 && e.is_finite()).count();
        if dimensions == 0 {
            return;
        }
        // P^{−1/d}.
        let shrink = math::exp(-math::ln(P as f32) / dimensions as f32);
        let scale = self.config.roughening * shrink;
        let spread = range.map(|e| {
            if e.is_finite() && e > 0.0 {
                scale * e
            } else {
                0.0
            }
        });
        for x in self.particles.iter_mut() {
            self.noise.perturb(x, &spread, &self.angles);
        }
    }

    /// The kernel step after a resampling (module docs, "Regularization"):
    /// `x⁽ⁱ⁾ ← x̂ + a (x⁽ⁱ⁾ − x̂) + h L ξ⁽ⁱ⁾`, `ξ ~ N(0, I)`, with `kernel =
    /// h L`; angles wrapped; a particle that would become non-finite is
    /// kept as it was.
    fn regularize(&mut self, kernel: &SMatrix<f32, N, N>) {
        let centre = self.estimate;
        let shrinkage = self.shrinkage;
        for i in 0..P {
            let Some(x) = self.particles.get(i).copied() else {
                break;
            };
            let draw = SVector::<f32, N>::from_fn(|_, _| self.noise.gaussian());
            let mut moved = centre + self.deviation(&x, &centre) * shrinkage + kernel * draw;
            wrap_angles(&mut moved, &self.angles);
            if finite(&moved)
                && let Some(slot) = self.particles.get_mut(i)
            {
                *slot = moved;
            }
        }
    }

    /// Collapse recovery (module docs): redraw around the kept estimate.
    fn collapse(&mut self) {
        let spread = self.recovery_std;
        self.redraw(&spread);
        self.counters.collapses = self.counters.collapses.saturating_add(1);
    }

    /// Every particle `x̂ + σ ∘ ξ`, equal weights; the estimate is kept
    /// (and no draw is pending).
    fn redraw(&mut self, spread: &SVector<f32, N>) {
        for x in self.particles.iter_mut() {
            *x = self.estimate;
            self.noise.perturb(x, spread, &self.angles);
        }
        self.weights = [1.0 / P as f32; P];
        self.draw_pending = false;
    }

    fn reject(&mut self) {
        self.counters.rejected_inputs = self.counters.rejected_inputs.saturating_add(1);
    }

    /// `x − reference` with angle components wrapped.
    fn deviation(&self, x: &SVector<f32, N>, reference: &SVector<f32, N>) -> SVector<f32, N> {
        let mut d = x - reference;
        wrap_angles(&mut d, &self.angles);
        d
    }

    /// Sets the estimate to the weighted mean of the particles (linear
    /// components about the previous estimate, for resolution far from the
    /// origin; angles on the circle). `false` (estimate kept) if the mean is
    /// not finite.
    fn refresh_estimate(&mut self) -> bool {
        let mut linear = SVector::<f32, N>::zeros();
        let mut sines = SVector::<f32, N>::zeros();
        let mut cosines = SVector::<f32, N>::zeros();
        for (x, &w) in self.particles.iter().zip(self.weights.iter()) {
            let components = x
                .iter()
                .zip(self.estimate.iter())
                .zip(self.angles.iter())
                .zip(linear.iter_mut())
                .zip(sines.iter_mut().zip(cosines.iter_mut()));
            for ((((&value, &reference), &angle), sum), (sin_sum, cos_sum)) in components {
                if angle {
                    let (sin, cos) = math::sincos(value);
                    *sin_sum += w * sin;
                    *cos_sum += w * cos;
                } else {
                    *sum += w * (value - reference);
                }
            }
        }
        let total: f32 = self.weights.iter().sum();
        let mut mean = self.estimate;
        let components = mean
            .iter_mut()
            .zip(self.angles.iter())
            .zip(linear.iter())
            .zip(sines.iter().zip(cosines.iter()));
        for (((value, &angle), &sum), (&sin_sum, &cos_sum)) in components {
            *value = if angle {
                math::wrap_angle(math::atan2(sin_sum, cos_sum))
            } else {
                *value + sum / total
            };
        }
        if finite(&mean) {
            self.estimate = mean;
            true
        } else {
            false
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{PI, wrap_angle};
    use nalgebra::{Vector1, Vector3};
    use proptest::prelude::*;

    /// 1-D random walk driven by a velocity, measured directly.
    #[derive(Debug, Clone, Copy, PartialEq)]
    struct Walk;

    impl ParticleModel<1, 1> for Walk {
        type Input = f32;
        fn transition(&self, x: &Vector1<f32>, u: &f32, dt_s: f32) -> Vector1<f32> {
            Vector1::new(x[0] + u * dt_s)
        }
        fn measure(&self, x: &Vector1<f32>) -> Vector1<f32> {
            *x
        }
        fn input_is_valid(&self, u: &f32) -> bool {
            u.is_finite()
        }
        fn measures_state(&self) -> bool {
            true
        }
    }

    /// [`Walk`] without input screening.
    #[derive(Debug, Clone, Copy, PartialEq)]
    struct UncheckedWalk;

    impl ParticleModel<1, 1> for UncheckedWalk {
        type Input = f32;
        fn transition(&self, x: &Vector1<f32>, u: &f32, dt_s: f32) -> Vector1<f32> {
            Vector1::new(x[0] + u * dt_s)
        }
        fn measure(&self, x: &Vector1<f32>) -> Vector1<f32> {
            *x
        }
    }

    /// A walk whose transition is undefined for `x > 0`.
    #[derive(Debug, Clone, Copy, PartialEq)]
    struct HalfDefined;

    impl ParticleModel<1, 1> for HalfDefined {
        type Input = f32;
        fn transition(&self, x: &Vector1<f32>, u: &f32, dt_s: f32) -> Vector1<f32> {
            if x[0] > 0.0 {
                Vector1::new(f32::NAN)
            } else {
                Vector1::new(x[0] + u * dt_s)
            }
        }
        fn measure(&self, x: &Vector1<f32>) -> Vector1<f32> {
            *x
        }
    }

    /// A heading turning at a rate `u` (rad/s), measured directly.
    #[derive(Debug, Clone, Copy, PartialEq)]
    struct Heading;

    impl ParticleModel<1, 1> for Heading {
        type Input = f32;
        fn transition(&self, x: &Vector1<f32>, u: &f32, dt_s: f32) -> Vector1<f32> {
            Vector1::new(x[0] + u * dt_s)
        }
        fn measure(&self, x: &Vector1<f32>) -> Vector1<f32> {
            *x
        }
        fn measurement_residual(&self, z: &Vector1<f32>, e: &Vector1<f32>) -> Vector1<f32> {
            Vector1::new(wrap_angle(z[0] - e[0]))
        }
        fn is_angle(&self, index: usize) -> bool {
            index == 0
        }
    }

    /// Scenario 1 of the paper: the pose `(X, Y, Ψ)` of a unicycle driven
    /// by `(v, ω)`, first-order discretised, measured directly.
    #[derive(Debug, Clone, Copy, PartialEq)]
    struct Unicycle;

    impl ParticleModel<3, 3> for Unicycle {
        type Input = (f32, f32);
        fn transition(&self, x: &Vector3<f32>, u: &(f32, f32), dt_s: f32) -> Vector3<f32> {
            let (v, w) = *u;
            Vector3::new(
                x[0] + v * math::cos(x[2]) * dt_s,
                x[1] + v * math::sin(x[2]) * dt_s,
                x[2] + w * dt_s,
            )
        }
        fn measure(&self, x: &Vector3<f32>) -> Vector3<f32> {
            *x
        }
        fn measurement_residual(&self, z: &Vector3<f32>, e: &Vector3<f32>) -> Vector3<f32> {
            let mut r = z - e;
            r[2] = wrap_angle(r[2]);
            r
        }
        fn is_angle(&self, index: usize) -> bool {
            index == 2
        }
        fn input_is_valid(&self, u: &(f32, f32)) -> bool {
            u.0.is_finite() && u.1.is_finite()
        }
        fn measures_state(&self) -> bool {
            true
        }
    }

    /// Scenario 2's sizes: pose and two wheel speeds.
    #[derive(Debug, Clone, Copy, PartialEq)]
    struct FiveStates;

    impl ParticleModel<5, 5> for FiveStates {
        type Input = ();
        fn transition(&self, x: &SVector<f32, 5>, _: &(), _: f32) -> SVector<f32, 5> {
            *x
        }
        fn measure(&self, x: &SVector<f32, 5>) -> SVector<f32, 5> {
            *x
        }
    }

    const PRIOR_STD: f32 = 3.162_277_7; // √10: the paper's P(0) = 10 I

    fn walk_config(q: f32, r: f32) -> ParticleFilterConfig<1, 1> {
        ParticleFilterConfig::new(Vector1::new(q), Vector1::new(r)).unwrap()
    }

    fn walk(seed: u64, config: ParticleFilterConfig<1, 1>) -> ParticleFilter<Walk, 1, 1, 100> {
        ParticleFilter::new(
            Walk,
            config,
            Vector1::new(5.0),
            Vector1::new(PRIOR_STD),
            seed,
        )
        .unwrap()
    }

    fn all_finite<Model: ParticleModel<N, M>, const N: usize, const M: usize, const P: usize>(
        f: &ParticleFilter<Model, N, M, P>,
    ) -> bool {
        f.particles().iter().all(finite)
            && f.weights().iter().all(|w| w.is_finite() && *w >= 0.0)
            && (f.weights().iter().sum::<f32>() - 1.0).abs() < 1e-4
            && finite(&f.estimate())
    }

    /// One step of [`scenario`]: the input, the true pose, the measurement.
    type ScenarioStep = ((f32, f32), Vector3<f32>, Vector3<f32>);

    /// The paper's scenario 1 on a unicycle: the truth, its inputs and its
    /// noisy measurements for `steps` steps of 0.1 s.
    fn scenario(steps: usize) -> Vec<ScenarioStep> {
        let mut noise = Noise::new(99);
        let mut truth = Vector3::new(0.0, -1.5, PI / 4.0);
        let r = Vector3::new(0.1f32.sqrt(), 0.1f32.sqrt(), 0.2f32.sqrt());
        (0..steps)
            .map(|k| {
                let u = (0.5, if k < 100 { -0.4 } else { 0.4 });
                truth = Unicycle.transition(&truth, &u, 0.1);
                truth[2] = wrap_angle(truth[2]);
                let z = truth + r.map(|s| s * noise.gaussian());
                (u, truth, z)
            })
            .collect()
    }

    fn unicycle(seed: u64) -> ParticleFilter<Unicycle, 3, 3, 100> {
        unicycle_drawing_from(seed, Proposal::Prior)
    }

    fn unicycle_drawing_from(seed: u64, proposal: Proposal) -> ParticleFilter<Unicycle, 3, 3, 100> {
        let config = ParticleFilterConfig::new(
            Vector3::new(0.02, 0.02, 0.02),
            Vector3::new(0.1f32.sqrt(), 0.1f32.sqrt(), 0.2f32.sqrt()),
        )
        .unwrap()
        .with_proposal(proposal);
        ParticleFilter::new(
            Unicycle,
            config,
            Vector3::zeros(),
            Vector3::repeat(PRIOR_STD),
            seed,
        )
        .unwrap()
    }

    #[test]
    fn reproducible_from_the_seed_and_sensitive_to_it() {
        let steps = scenario(300);
        let mut a = unicycle(7);
        let mut b = unicycle(7);
        let mut c = unicycle(8);
        let mut differing = 0;
        let (mut error_2s, mut worst_10s, mut worst_late, mut worst_heading) =
            (0.0f32, 0.0f32, 0.0f32, 0.0f32);
        for (k, (u, truth, z)) in steps.iter().enumerate() {
            for f in [&mut a, &mut b] {
                f.predict(u, 0.1);
                f.update(z);
            }
            c.predict(u, 0.1);
            c.update(z);
            let bits = |v: Vector3<f32>| v.map(f32::to_bits);
            assert_eq!(bits(a.estimate()), bits(b.estimate()), "step {k}");
            assert_eq!(
                a.covariance().map(f32::to_bits),
                b.covariance().map(f32::to_bits)
            );
            if bits(a.estimate()) != bits(c.estimate()) {
                differing += 1;
            }
            let e = a.estimate() - truth;
            let e = (e[0] * e[0] + e[1] * e[1]).sqrt();
            if k == 19 {
                error_2s = e;
            }
            if k >= 100 {
                worst_10s = worst_10s.max(e);
            }
            if k >= 220 {
                worst_late = worst_late.max(e);
                worst_heading = worst_heading.max(wrap_angle(a.estimate()[2] - truth[2]).abs());
            }
        }
        assert_eq!(a, b);
        assert_eq!(a.counters(), b.counters());
        assert_eq!(differing, 300);
        println!(
            "unicycle from (0, 0, 0) ± √10 to (0, −1.5, π/4), seed 7: position error at 2 s \
             {error_2s:.3} m, worst after 10 s {worst_10s:.3} m, after 22 s {worst_late:.3} m \
             and {worst_heading:.3} rad; resamplings {}, collapses {}",
            a.resamplings(),
            a.collapses()
        );
        // From this prior (the heading is nearly uniform) 100 particles with
        // σ_q = 0.02 came within 0.3 m for good by 10 s for 91 of 100 seeds
        // (88 with micromath), by 21.1 s for all of them (measured over 60 s).
        assert!(worst_late < 0.3 && worst_heading < 0.2);
        assert_eq!(a.collapses(), 0);
    }

    /// A per-call `σ_r` replaces the configured one; an infinite one
    /// leaves its component unmeasured; a zero or NaN one is refused.
    #[test]
    fn update_with_std_weights_only_the_measured_components() {
        let mut configured = unicycle(7);
        let mut per_call = unicycle(7);
        let z = Vector3::new(0.5, -0.3, 0.2);
        configured.update(&z);
        per_call.update_with_std(&z, configured.config().measurement_std());
        assert_eq!(configured.weights(), per_call.weights());
        // Only x measured: the weights depend on x alone, whatever z's y, ψ.
        let (mut a, mut b) = (unicycle(8), unicycle(8));
        // σ wide enough that nothing is resampled: the weights are the
        // normalised likelihoods of x alone.
        let std = Vector3::new(3.0 * PRIOR_STD, f32::INFINITY, f32::INFINITY);
        a.update_with_std(&Vector3::new(0.4, 0.0, 0.0), &std);
        b.update_with_std(&Vector3::new(0.4, 9.0, -2.0), &std);
        assert_eq!(a.resamplings(), 0);
        assert_eq!(a.weights(), b.weights());
        let likelihood = |x: &Vector3<f32>| (-0.5 * ((0.4 - x[0]) / std[0]).powi(2)).exp();
        let total: f32 = a.particles().iter().map(likelihood).sum();
        for (x, w) in a.particles().iter().zip(a.weights()) {
            assert!((w - likelihood(x) / total).abs() < 1e-5);
        }
        for bad in [0.0, f32::NAN, -1.0] {
            a.update_with_std(&z, &Vector3::new(bad, 1.0, 1.0));
        }
        assert_eq!(a.rejected_inputs(), 3);
    }

    /// A reset redraws the particles from the Gaussian it is given (its
    /// sample mean and covariance within sampling error of 400 particles)
    /// and refuses a covariance that is not one.
    #[test]
    fn reset_draws_from_the_given_gaussian() {
        let mut pf: ParticleFilter<Unicycle, 3, 3, 400> = ParticleFilter::new(
            Unicycle,
            ParticleFilterConfig::new(Vector3::zeros(), Vector3::repeat(1.0)).unwrap(),
            Vector3::zeros(),
            Vector3::repeat(1.0),
            3,
        )
        .unwrap();
        let mean = Vector3::new(2.0, -1.0, 3.0);
        let covariance =
            SMatrix::<f32, 3, 3>::new(0.04, 0.01, 0.0, 0.01, 0.09, 0.0, 0.0, 0.0, 0.01);
        pf.reset(&mean, &covariance).unwrap();
        assert_eq!(pf.estimate(), Vector3::new(2.0, -1.0, 3.0));
        let sample_mean = pf.particles().iter().sum::<Vector3<f32>>() / 400.0;
        // ψ near π wraps: compare the linear components' moments.
        assert!((sample_mean[0] - 2.0).abs() < 0.03 && (sample_mean[1] + 1.0).abs() < 0.045);
        let c = pf.covariance();
        for (i, j, tolerance) in [(0, 0, 0.01), (1, 1, 0.02), (0, 1, 0.01), (2, 2, 0.003)] {
            assert!(
                (c[(i, j)] - covariance[(i, j)]).abs() < tolerance,
                "{i}{j}: {c}"
            );
        }
        let not_symmetric = SMatrix::<f32, 3, 3>::new(1.0, 0.5, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0);
        assert_eq!(
            pf.reset(&mean, &not_symmetric),
            Err(ParticleFilterError::PriorStd)
        );
        assert_eq!(
            pf.reset(&Vector3::new(f32::NAN, 0.0, 0.0), &covariance),
            Err(ParticleFilterError::PriorMean)
        );
    }

    /// The particle filter against the exact Kalman filter on a random
    /// walk with `σ_q = q`, `σ_r = r` for 500 steps from 5 ± √10 (the truth
    /// starts at 0): its RMS error, the Kalman filter's, RMS(PF − KF), the
    /// Kalman filter's final σ and the PF's worst error after step 50.
    fn against_the_kalman_filter(q: f32, r: f32, proposal: Proposal) -> (f64, f64, f64, f64, f32) {
        let mut world = Noise::new(2024);
        let mut truth = 0.0f32;
        let mut pf = walk(1, walk_config(q, r).with_proposal(proposal));
        // The exact answer for this linear-Gaussian case.
        let (mut kf, mut kf_var) = (5.0f64, 10.0f64);
        let (mut pf_sq, mut kf_sq, mut gap_sq, mut n) = (0.0f64, 0.0f64, 0.0f64, 0);
        let mut worst = 0.0f32;
        for k in 0..500 {
            truth += q * world.gaussian();
            let z = truth + r * world.gaussian();
            pf.predict(&0.0, 0.1);
            pf.update(&Vector1::new(z));
            kf_var += f64::from(q * q);
            let gain = kf_var / (kf_var + f64::from(r * r));
            kf += gain * (f64::from(z) - kf);
            kf_var *= 1.0 - gain;
            if k >= 50 {
                let e = f64::from(pf.estimate()[0] - truth);
                pf_sq += e * e;
                kf_sq += (kf - f64::from(truth)).powi(2);
                gap_sq += (f64::from(pf.estimate()[0]) - kf).powi(2);
                n += 1;
                worst = worst.max((pf.estimate()[0] - truth).abs());
            }
        }
        let rms = |s: f64| (s / f64::from(n)).sqrt();
        let (pf_rms, kf_rms, gap_rms) = (rms(pf_sq), rms(kf_sq), rms(gap_sq));
        println!(
            "random walk (q {q}, r {r}, {proposal:?}, 500 steps, from 5 ± √10 to 0): PF RMS error \
             {pf_rms:.4}, KF RMS error {kf_rms:.4}, KF σ {:.4}, RMS(PF − KF) {gap_rms:.4}, worst PF \
             error {worst:.4}, resamplings {}, collapses {}",
            kf_var.sqrt(),
            pf.resamplings(),
            pf.collapses()
        );
        assert!(all_finite(&pf));
        (pf_rms, kf_rms, gap_rms, kf_var.sqrt(), worst)
    }

    #[test]
    fn random_walk_converges_like_the_kalman_filter() {
        let (pf_rms, kf_rms, gap_rms, kf_sigma, worst) =
            against_the_kalman_filter(0.1, 0.5, Proposal::Prior);
        assert!(pf_rms < 1.15 * kf_rms);
        assert!(gap_rms < 0.3 * kf_sigma);
        // Over 30 seeds: PF/KF RMS ratio 0.97–1.04, RMS(PF − KF) 0.11–0.20 σ,
        // worst error 2.5–4.1 σ (the KF's own worst is of the same order).
        assert!(worst < 5.0 * kf_sigma as f32);
    }

    #[test]
    fn the_optimal_proposal_converges_like_the_kalman_filter() {
        let (pf_rms, kf_rms, gap_rms, kf_sigma, worst) =
            against_the_kalman_filter(0.1, 0.5, Proposal::Optimal);
        assert!(pf_rms < 1.15 * kf_rms);
        assert!(gap_rms < 0.3 * kf_sigma);
        assert!(worst < 5.0 * kf_sigma as f32);
    }

    /// Paper 004's wheel speeds: a process noise 50 times the measurement
    /// noise. The prior scatters 100 particles over ±5 where the likelihood
    /// is ±0.1 wide; the optimal proposal draws each one where the
    /// measurement puts it.
    #[test]
    fn the_optimal_proposal_follows_a_process_noise_far_wider_than_the_measurement() {
        let (prior_rms, kf_rms, _, kf_sigma, _) =
            against_the_kalman_filter(5.0, 0.1, Proposal::Prior);
        let (optimal_rms, _, gap_rms, _, worst) =
            against_the_kalman_filter(5.0, 0.1, Proposal::Optimal);
        assert!(optimal_rms < 1.15 * kf_rms);
        assert!(gap_rms < 0.3 * kf_sigma);
        assert!(worst < 5.0 * kf_sigma as f32);
        assert!(prior_rms > 1.5 * optimal_rms);
    }

    #[test]
    fn the_optimal_proposal_needs_a_model_that_measures_its_state() {
        /// [`Walk`] without saying that it measures its state.
        struct Opaque;
        impl ParticleModel<1, 1> for Opaque {
            type Input = f32;
            fn transition(&self, x: &Vector1<f32>, u: &f32, dt_s: f32) -> Vector1<f32> {
                Walk.transition(x, u, dt_s)
            }
            fn measure(&self, x: &Vector1<f32>) -> Vector1<f32> {
                *x
            }
        }
        let config = walk_config(0.1, 0.5);
        let (mean, std) = (Vector1::new(0.0), Vector1::new(1.0));
        let refused = ParticleFilter::<Opaque, 1, 1, 10>::new(
            Opaque,
            config.with_proposal(Proposal::Optimal),
            mean,
            std,
            1,
        );
        assert_eq!(refused.err(), Some(ParticleFilterError::Proposal));
        assert!(ParticleFilter::<Opaque, 1, 1, 10>::new(Opaque, config, mean, std, 1).is_ok());
        assert_eq!(config.proposal(), Proposal::Prior);
    }

    /// The first update draws from `p(x_0 | y_0)`, the prior's Gaussian
    /// times the likelihood: the estimate is its mean, the particles have
    /// equal weights and its spread.
    #[test]
    fn the_optimal_proposal_starts_from_the_exact_posterior() {
        let (q, r) = (0.1f32, 0.5f32);
        let mut pf: ParticleFilter<Walk, 1, 1, 1000> = ParticleFilter::new(
            Walk,
            walk_config(q, r).with_proposal(Proposal::Optimal),
            Vector1::new(5.0),
            Vector1::new(PRIOR_STD),
            7,
        )
        .unwrap();
        // Pending: every particle at the prior mean, the covariance the prior's.
        assert!(pf.particles().iter().all(|x| x[0] == 5.0));
        assert!((pf.covariance()[0] - 10.0).abs() < 1e-4);
        pf.update(&Vector1::new(1.0));
        let gain = 10.0 / (10.0 + r * r);
        let mean = 5.0 + gain * (1.0 - 5.0);
        let variance = gain * r * r;
        // f32 sums over 1,000 particles.
        assert!(
            (pf.estimate()[0] - mean).abs() < 1e-4,
            "{} against {mean}",
            pf.estimate()[0]
        );
        assert!(pf.weights().iter().all(|&w| (w - 1e-3).abs() < 1e-7));
        let spread = pf.covariance()[0];
        println!(
            "first update: estimate {} (exact {mean}), variance {spread} (exact {variance})",
            pf.estimate()[0]
        );
        // 1,000 draws: the sample variance is within ±10 % (2.2 standard errors).
        assert!((spread / variance - 1.0).abs() < 0.1);
        assert_eq!(pf.collapses(), 0);
    }

    /// A prediction with no update since the last one draws the pending
    /// noise from the prior before moving on.
    #[test]
    fn the_optimal_proposal_draws_a_missed_updates_noise_from_the_prior() {
        let mut pf = walk(3, walk_config(0.5, 0.1).with_proposal(Proposal::Optimal));
        pf.update(&Vector1::new(5.0));
        let after_update = pf.covariance()[0];
        pf.predict(&1.0, 0.1);
        // Moved by f only; the covariance says the draw is pending.
        assert!((pf.estimate()[0] - 5.1).abs() < 0.05);
        // About the moved mean instead of the update's estimate: equal but
        // for the sample mean's offset, ≈ (√(K r²/P))² = 1e-4.
        let pending = pf.covariance()[0];
        assert!(
            (pending - (after_update + 0.25)).abs() < 1e-3,
            "{pending} against {after_update} + 0.25"
        );
        pf.predict(&1.0, 0.1);
        // The first step's noise drawn (0.5 per step over 100 particles),
        // the second's pending.
        let drawn = pf.covariance()[0] - 0.25;
        println!(
            "after two predictions: drawn variance {drawn} (expected ≈ {})",
            after_update + 0.25
        );
        assert!(drawn > 0.15 && drawn < 0.4);
        assert_eq!(pf.rejected_inputs(), 0);
    }

    #[test]
    fn resampling_follows_the_effective_sample_size() {
        let mut f = walk(3, walk_config(0.1, 0.5));
        assert!((f.effective_sample_size() - 100.0).abs() < 1e-3);
        f.predict(&0.0, 0.1);
        assert!((f.effective_sample_size() - 100.0).abs() < 1e-3);
        // A σ 0.5 measurement of a σ √10 cloud leaves an ESS ≈ P·0.5/√10.
        f.update(&Vector1::new(5.0));
        assert_eq!(f.resamplings(), 1);
        assert!((f.effective_sample_size() - 100.0).abs() < 1e-3);
        assert!(f.weights().iter().all(|&w| w == 0.01));

        let never = walk_config(0.1, 0.5).with_resample_threshold(0.0).unwrap();
        let mut f = walk(3, never);
        for _ in 0..20 {
            f.predict(&0.0, 0.1);
            f.update(&Vector1::new(5.0));
        }
        assert_eq!(f.resamplings(), 0);
        let ess = f.effective_sample_size();
        println!("ESS after 20 updates without resampling: {ess:.2} of 100");
        assert!(ess < 10.0);

        let always = walk_config(0.1, 0.5).with_resample_threshold(1.0).unwrap();
        let mut f = walk(3, always);
        for _ in 0..20 {
            f.predict(&0.0, 0.1);
            f.update(&Vector1::new(5.0));
        }
        assert_eq!(f.resamplings(), 20);
    }

    fn multiplicities<const P: usize>(weights: &[f32; P], uniform: f32) -> [usize; P] {
        let source: [usize; P] = core::array::from_fn(|i| i);
        let mut out = [usize::MAX; P];
        assert!(systematic_resample(&source, weights, uniform, &mut out));
        let mut counts = [0; P];
        for i in out {
            counts[i] += 1;
        }
        // Systematic resampling keeps the order.
        assert!(out.windows(2).all(|w| w[0] <= w[1]));
        counts
    }

    #[test]
    fn systematic_resampling_gives_the_expected_multiplicities() {
        let weights = [0.5, 0.25, 0.25, 0.0];
        for u in [
            0.0,
            0.25,
            0.5,
            0.999_999,
            f32::NAN,
            -1.0,
            1.0,
            f32::INFINITY,
        ] {
            assert_eq!(multiplicities(&weights, u), [2, 1, 1, 0], "u = {u}");
        }
        // Pointers 0.125, 0.375, 0.625, 0.875 on cumulative 0.1, 0.3, 0.6, 1.
        assert_eq!(multiplicities(&[0.1, 0.2, 0.3, 0.4], 0.5), [0, 1, 1, 2]);
        // Unnormalised, negative and NaN weights.
        assert_eq!(multiplicities(&[1.0, 2.0, 3.0, 4.0], 0.5), [0, 1, 1, 2]);
        assert_eq!(
            multiplicities(&[f32::NAN, 2.0, -3.0, 2.0], 0.5),
            [0, 2, 0, 2]
        );
        // All weight on the last particle, after zero weights.
        assert_eq!(multiplicities(&[0.0, 0.0, 0.0, 1.0], 0.0), [0, 0, 0, 4]);
        // Each particle gets ⌊P w⌋ or ⌈P w⌉ copies.
        let mut noise = Noise::new(5);
        let mut weights = [0.0f32; 100];
        for w in &mut weights {
            *w = noise.uniform().powi(4);
        }
        let total: f32 = weights.iter().sum();
        let counts = multiplicities(&weights, noise.uniform());
        for (&c, &w) in counts.iter().zip(&weights) {
            let expected = 100.0 * w / total;
            assert!(
                (c as f32) >= expected.floor() - 1e-3 && (c as f32) <= expected.ceil() + 1e-3,
                "{c} copies for {expected}"
            );
        }
        // Nothing to resample from.
        let mut out = [7usize; 3];
        assert!(!systematic_resample(
            &[0, 1, 2],
            &[0.0, -1.0, f32::NAN],
            0.5,
            &mut out
        ));
        assert!(!systematic_resample(
            &[0, 1, 2],
            &[1.0, f32::INFINITY, 0.0],
            0.5,
            &mut out
        ));
        assert_eq!(out, [7; 3]);
    }

    #[test]
    fn an_absurd_measurement_collapses_and_the_filter_recovers() {
        let mut f = walk(4, walk_config(0.1, 0.5));
        for _ in 0..30 {
            f.predict(&0.0, 0.1);
            f.update(&Vector1::new(0.0));
        }
        let before = f.estimate();
        assert!(before[0].abs() < 0.3);
        f.update(&Vector1::new(1.0e6));
        assert_eq!(f.collapses(), 1);
        assert_eq!(f.estimate()[0].to_bits(), before[0].to_bits());
        assert!(all_finite(&f));
        assert!(f.weights().iter().all(|&w| w == 0.01));
        // Redrawn with the prior's spread (variance 10).
        let spread = f.covariance()[(0, 0)];
        println!("variance after the collapse: {spread:.2} (recovery spread 10)");
        assert!(spread > 5.0 && spread < 15.0);
        // (r/σ)² overflows f32: every log-weight is −∞.
        f.update(&Vector1::new(1.0e30));
        assert_eq!(f.collapses(), 2);
        assert!(all_finite(&f));
        for _ in 0..30 {
            f.predict(&0.0, 0.1);
            f.update(&Vector1::new(0.0));
        }
        assert!(f.estimate()[0].abs() < 0.3);
        assert_eq!(f.collapses(), 2);

        // A configured recovery spread.
        let tight = walk_config(0.1, 0.5)
            .with_recovery_std(Vector1::new(0.1))
            .unwrap();
        let mut f = walk(4, tight);
        f.update(&Vector1::new(1.0e6));
        assert_eq!(f.collapses(), 1);
        assert!(f.covariance()[(0, 0)] < 0.03);

        // Without the gate the weight goes to the particle closest to the
        // measurement, with no underflow.
        let ungated = walk_config(0.1, 0.5)
            .with_collapse_gate(f32::INFINITY)
            .unwrap();
        let mut f = walk(4, ungated);
        let highest = f.particles().iter().map(|x| x[0]).fold(f32::MIN, f32::max);
        f.update(&Vector1::new(1.0e6));
        assert_eq!(f.collapses(), 0);
        assert_eq!(f.resamplings(), 1);
        assert_eq!(f.estimate()[0], highest);
        assert!(all_finite(&f));
    }

    #[test]
    fn non_finite_input_is_skipped_and_counted() {
        let mut f = walk(5, walk_config(0.1, 0.5));
        f.predict(&0.0, 0.1);
        f.update(&Vector1::new(4.0));
        let before = f.clone();
        f.update(&Vector1::new(f32::NAN));
        f.update(&Vector1::new(f32::INFINITY));
        f.predict(&f32::NAN, 0.1);
        f.predict(&0.0, f32::NAN);
        f.predict(&0.0, f32::INFINITY);
        f.predict(&0.0, -0.1);
        assert_eq!(f.rejected_inputs(), 6);
        assert_eq!(f.particles(), before.particles());
        assert_eq!(f.weights(), before.weights());
        assert_eq!(f.estimate(), before.estimate());
        assert_eq!(f.noise, before.noise);

        // Not screened by the model: caught because no particle survives.
        let mut f = ParticleFilter::<_, 1, 1, 100>::new(
            UncheckedWalk,
            walk_config(0.1, 0.5),
            Vector1::new(0.0),
            Vector1::new(1.0),
            5,
        )
        .unwrap();
        let before = f.clone();
        f.predict(&f32::NAN, 0.1);
        assert_eq!(f.rejected_inputs(), 1);
        assert_eq!(f.particles(), before.particles());
        assert_eq!(f.estimate(), before.estimate());
    }

    #[test]
    fn particles_the_model_cannot_move_are_dropped() {
        let mut f = ParticleFilter::<_, 1, 1, 100>::new(
            HalfDefined,
            walk_config(0.1, 0.5),
            Vector1::new(0.0),
            Vector1::new(1.0),
            6,
        )
        .unwrap();
        let positive = f.particles().iter().filter(|x| x[0] > 0.0).count();
        f.predict(&0.0, 0.1);
        assert_eq!(f.counters().dropped_particles as usize, positive);
        for (x, w) in f.particles().iter().zip(f.weights()) {
            if x[0] > 0.0 {
                assert!(*w == 0.0 || x[0] < 0.5, "a dropped particle kept weight");
            }
        }
        assert!(all_finite(&f));
        assert!(f.estimate()[0] < 0.0);
        assert_eq!(f.rejected_inputs(), 0);
        f.update(&Vector1::new(-0.5));
        assert!(all_finite(&f));
    }

    #[test]
    fn the_heading_estimate_is_the_circular_mean() {
        let config = walk_config(0.01, 0.1);
        let mut f = ParticleFilter::<_, 1, 1, 100>::new(
            Heading,
            config,
            Vector1::new(PI),
            Vector1::new(0.3),
            7,
        )
        .unwrap();
        assert!(f.particles().iter().all(|x| x[0] > -PI && x[0] <= PI));
        f.predict(&0.0, 0.1);
        let naive: f32 = f.particles().iter().map(|x| x[0]).sum::<f32>() / 100.0;
        let circular = f.estimate()[0];
        println!("headings around π: circular mean {circular:.4}, arithmetic mean {naive:.4}");
        assert!(wrap_angle(circular - PI).abs() < 0.1);
        assert!(naive.abs() < 1.5);

        // Hand-made: 3/4 of the weight at π − 0.1, 1/4 at −π + 0.1.
        for (i, (x, w)) in f.particles.iter_mut().zip(f.weights.iter_mut()).enumerate() {
            x[0] = if i % 2 == 0 { PI - 0.1 } else { -PI + 0.1 };
            *w = if i % 2 == 0 { 0.015 } else { 0.005 };
        }
        assert!(f.refresh_estimate());
        let expected = f64::atan2(
            0.75 * (std::f64::consts::PI - 0.1).sin() + 0.25 * (-std::f64::consts::PI + 0.1).sin(),
            0.75 * (std::f64::consts::PI - 0.1).cos() + 0.25 * (-std::f64::consts::PI + 0.1).cos(),
        );
        // micromath's atan2, sin and cos are good to a few 1e-3.
        let tolerance = if cfg!(feature = "micromath") {
            5e-3
        } else {
            1e-5
        };
        assert!((f64::from(f.estimate()[0]) - expected).abs() < tolerance);
        // Equal weights on both sides: ±π, not 0.
        f.weights = [0.01; 100];
        assert!(f.refresh_estimate());
        assert!(f64::from(wrap_angle(f.estimate()[0] - PI).abs()) < tolerance);
        // The deviations in the covariance are wrapped: 0.1 rad, not 2π − 0.1.
        assert!(f64::from((f.covariance()[(0, 0)] - 0.01).abs()) < 10.0 * tolerance);
    }

    #[test]
    fn a_heading_is_tracked_across_pi() {
        let mut world = Noise::new(11);
        let mut f = ParticleFilter::<_, 1, 1, 100>::new(
            Heading,
            walk_config(0.02, 0.1),
            Vector1::new(0.0),
            Vector1::new(PRIOR_STD),
            8,
        )
        .unwrap();
        let mut truth = 2.0f32;
        let mut worst = 0.0f32;
        for k in 0..300 {
            truth = wrap_angle(truth + 1.0 * 0.1);
            let z = wrap_angle(truth + 0.1 * world.gaussian());
            f.predict(&1.0, 0.1);
            f.update(&Vector1::new(z));
            let e = f.estimate()[0];
            assert!(e > -PI && e <= PI);
            if k >= 10 {
                worst = worst.max(wrap_angle(e - truth).abs());
            }
        }
        println!("heading across ±π (ω 1 rad/s, σ 0.1 rad, 300 steps): worst error {worst:.4} rad");
        assert!(worst < 0.15);
        assert_eq!(f.collapses(), 0);
    }

    #[test]
    fn configuration_is_validated() {
        type E = ParticleFilterError;
        let c =
            |q: f32, r: f32| ParticleFilterConfig::<1, 1>::new(Vector1::new(q), Vector1::new(r));
        assert_eq!(c(-0.1, 1.0).err(), Some(E::ProcessStd));
        assert_eq!(c(f32::NAN, 1.0).err(), Some(E::ProcessStd));
        assert!(c(0.0, 1.0).is_ok());
        assert_eq!(c(0.1, 0.0).err(), Some(E::MeasurementStd));
        assert_eq!(c(0.1, f32::INFINITY).err(), Some(E::MeasurementStd));
        assert_eq!(c(0.1, 1e-40).err(), Some(E::MeasurementStd));
        let ok = c(0.1, 1.0).unwrap();
        assert_eq!(ok.resample_fraction(), DEFAULT_RESAMPLE_FRACTION);
        assert_eq!(ok.collapse_gate(), DEFAULT_COLLAPSE_GATE);
        assert!(ok.recovery_std().is_none());
        assert!(
            (DEFAULT_COLLAPSE_GATE + 2.0 * f32::MIN_POSITIVE.ln()).abs() < 1e-3,
            "the gate is −2 ln(f32::MIN_POSITIVE)"
        );
        for bad in [-0.1, 1.1, f32::NAN] {
            assert_eq!(
                ok.with_resample_threshold(bad).err(),
                Some(E::ResampleThreshold)
            );
        }
        assert_eq!(
            ok.with_recovery_std(Vector1::new(-1.0)).err(),
            Some(E::RecoveryStd)
        );
        for bad in [0.0, -1.0, f32::NAN] {
            assert_eq!(ok.with_collapse_gate(bad).err(), Some(E::CollapseGate));
        }
        let new = |mean: f32, std: f32| {
            ParticleFilter::<_, 1, 1, 10>::new(Walk, ok, Vector1::new(mean), Vector1::new(std), 0)
                .err()
        };
        assert_eq!(new(f32::NAN, 1.0), Some(E::PriorMean));
        assert_eq!(new(0.0, -1.0), Some(E::PriorStd));
        assert_eq!(new(0.0, f32::INFINITY), Some(E::PriorStd));
        assert_eq!(new(0.0, 0.0), None);
        let none =
            ParticleFilter::<_, 1, 1, 0>::new(Walk, ok, Vector1::new(0.0), Vector1::new(1.0), 0);
        assert_eq!(none.err(), Some(E::NoParticles));
    }

    #[test]
    fn an_absurd_finite_input_saturates_the_covariance() {
        // Found by the property test below: a speed of 1e30 m/s spreads the
        // particles so far that Σ w d dᵀ overflows.
        let mut f = unicycle(0);
        f.predict(&(1.0e30, 0.3), 0.732_417_4);
        f.update(&Vector3::new(0.0, 0.0, f32::NAN));
        assert_eq!(f.rejected_inputs(), 1);
        assert!(all_finite(&f));
        let c = f.covariance();
        assert!(c.iter().all(|c| c.is_finite()));
        assert_eq!(c, SMatrix::<f32, 3, 3>::identity() * f32::MAX);
    }

    #[test]
    fn the_optimal_bandwidth_is_musso_oudjanes() {
        // (4 / (P (N + 2)))^(1/(N + 4)): N = 3, P = 100: 0.008^(1/7).
        for (n, p) in [(1usize, 100usize), (3, 100), (5, 100), (3, 1000)] {
            let exact = (4.0 / (p as f64 * (n as f64 + 2.0))).powf(1.0 / (n as f64 + 4.0));
            let h = f64::from(optimal_bandwidth(n, p));
            assert!((h - exact).abs() < 1e-4, "N {n} P {p}: {h} against {exact}");
        }
        let too_wide = walk_config(0.1, 0.5).with_regularization(10.0).unwrap();
        let built = ParticleFilter::<_, 1, 1, 100>::new(
            Walk,
            too_wide,
            Vector1::new(0.0),
            Vector1::new(1.0),
            0,
        );
        assert_eq!(built.err(), Some(ParticleFilterError::Regularization));
        for bad in [-1.0, f32::NAN, f32::INFINITY] {
            assert_eq!(
                walk_config(0.1, 0.5).with_regularization(bad).err(),
                Some(ParticleFilterError::Regularization)
            );
        }
    }

    #[test]
    fn regularization_keeps_the_clouds_mean_and_spread_and_its_diversity() {
        let regularized = walk_config(0.0, 0.5).with_regularization(1.0).unwrap();
        let mut f = walk(12, regularized);
        let mut plain = walk(12, walk_config(0.0, 0.5));
        // One update from a σ √10 prior resamples (ESS ≈ 16 of 100).
        f.update(&Vector1::new(5.0));
        plain.update(&Vector1::new(5.0));
        assert_eq!(plain.resamplings(), 1);
        let distinct = |f: &ParticleFilter<Walk, 1, 1, 100>| {
            let mut values: Vec<u32> = f.particles().iter().map(|x| x[0].to_bits()).collect();
            values.sort_unstable();
            values.dedup();
            values.len()
        };
        println!(
            "distinct particles after one resampling: {} plain, {} regularized; variance {:.4} / {:.4}; stages {}",
            distinct(&plain),
            distinct(&f),
            plain.covariance()[(0, 0)],
            f.covariance()[(0, 0)],
            f.counters().correction_stages
        );
        assert!(distinct(&plain) < 40);
        assert_eq!(distinct(&f), 100);
        // The posterior of N(5, 10) measured as 5 ± 0.5: 5 ± 0.49.
        let exact_variance = 1.0 / (1.0 / 10.0 + 1.0 / 0.25);
        assert!((f.estimate()[0] - 5.0).abs() < 0.15);
        let variance = f.covariance()[(0, 0)];
        assert!(
            variance > 0.6 * exact_variance && variance < 1.5 * exact_variance,
            "{variance}"
        );
    }

    #[test]
    fn a_sharp_likelihood_is_applied_in_stages() {
        // A σ √10 prior against a σ 0.01 measurement: ≈ 1 particle in 300
        // lies within 1σ of it; in one step the weight falls on one
        // particle, in stages the cloud closes in on the measurement.
        let sharp = walk_config(0.0, 0.01).with_regularization(1.0).unwrap();
        let mut f = walk(13, sharp);
        let mut plain = walk(13, walk_config(0.0, 0.01));
        f.update(&Vector1::new(6.0));
        plain.update(&Vector1::new(6.0));
        let (staged, single) = (
            (f.estimate()[0] - 6.0).abs(),
            (plain.estimate()[0] - 6.0).abs(),
        );
        println!(
            "error after one σ 0.01 update of a σ √10 cloud: {single:.4} in one step, {staged:.4} in {} stages",
            f.counters().correction_stages + 1
        );
        assert!(f.counters().correction_stages > 0);
        assert_eq!(plain.counters().correction_stages, 0);
        assert!(staged < 0.02 && staged < single);
        assert!(all_finite(&f));
        assert_eq!(f.collapses(), 0);
    }

    #[test]
    fn memory_footprint() {
        let three = core::mem::size_of::<ParticleFilter<Unicycle, 3, 3, 100>>();
        let five = core::mem::size_of::<ParticleFilter<FiveStates, 5, 5, 100>>();
        println!("P = 100: {three} B for N = M = 3, {five} B for N = M = 5");
        // The roughening constant included (4 B each).
        assert_eq!(three, 3364);
        assert_eq!(five, 5024);
    }

    /// An `f32` that is often non-finite or absurd.
    fn wild() -> impl Strategy<Value = f32> {
        prop_oneof![
            4 => -10.0f32..10.0,
            1 => Just(f32::NAN),
            1 => Just(f32::INFINITY),
            1 => Just(f32::NEG_INFINITY),
            1 => Just(1.0e30f32),
            1 => Just(-3.0e38f32),
            1 => any::<f32>(),
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// Whatever comes in, the particles, weights and estimate stay
        /// finite and the weights normalised.
        #[test]
        fn nothing_non_finite_gets_in(
            steps in proptest::collection::vec((wild(), wild(), wild(), wild()), 1..40),
            seed in any::<u64>(),
        ) {
            let proposal = if seed % 2 == 0 { Proposal::Prior } else { Proposal::Optimal };
            let mut f = unicycle_drawing_from(seed, proposal);
            for &(v, dt, x, heading) in &steps {
                f.predict(&(v, 0.3), dt.abs().min(1.0));
                f.update(&Vector3::new(x, -x, heading));
                prop_assert!(all_finite(&f));
                let ess = f.effective_sample_size();
                prop_assert!((0.999..=100.01).contains(&ess));
                prop_assert!(f.estimate()[2] > -PI && f.estimate()[2] <= PI);
                prop_assert!(f.covariance().iter().all(|c| c.is_finite()));
            }
        }
    }
}
