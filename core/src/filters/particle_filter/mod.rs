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
//! # Parts
//! Each part is a file of this module, described in full in its own module
//! docs (`cargo doc --document-private-items`):
//! * `model.rs`: the system ([`ParticleModel`]) and **angles**: state
//!   components the model names angles are kept wrapped to (−π, π] and
//!   averaged on the circle; a measurement's angle components are the
//!   model's to wrap ([`ParticleModel::measurement_residual`]).
//! * `config.rs`: the noise levels and thresholds ([`ParticleFilterConfig`]),
//!   validated when set, and why one is refused ([`ParticleFilterError`]).
//! * `filter.rs`: the [`ParticleFilter`] itself, and **bad input and
//!   collapse**: a step with non-finite or refused input is skipped and
//!   counted ([`ParticleFilterCounters`]); when no particle keeps a weight, or
//!   the measurement is beyond the collapse gate ([`DEFAULT_COLLAPSE_GATE`])
//!   from every particle, the filter keeps its estimate and redraws the
//!   particles around it. It never holds a non-finite particle, weight or
//!   estimate.
//! * `weights.rs`: the weights **in log space** (a measurement far from every
//!   particle still weights them by their relative likelihood), **progressive
//!   correction** (Oudjane & Musso 2000; Musso, Oudjane & Le Gland 2001,
//!   §12.5: a sharp likelihood applied in stages) and **a likelihood of the
//!   model's own** ([`ParticleFilter::update_with_likelihood`]; e.g. a
//!   quantized measurement, Karlsson & Gustafsson 2005, *Particle filtering
//!   for quantized sensor information*, EUSIPCO).
//! * `resampling.rs`: **systematic resampling** ([`systematic_resample`]) when
//!   the effective sample size falls below the threshold.
//! * `regularization.rs`: **regularization** after resampling (opt-in; Musso,
//!   Oudjane & Le Gland 2001, *Improving regularised particle filters*, in
//!   Doucet, de Freitas & Gordon (eds.), *Sequential Monte Carlo Methods in
//!   Practice*, ch. 12, with the shrinkage of Liu & West 2001, *Combined
//!   parameter and state estimation in simulation-based filtering*;
//!   [`optimal_bandwidth`]), and **roughening** (opt-in; Gordon, Salmond &
//!   Smith 1993, *Novel approach to nonlinear/non-Gaussian Bayesian state
//!   estimation*, IEE Proc. F 140(2):107–113, §4).
//! * `proposal.rs`: **the optimal proposal** (opt-in, [`Proposal::Optimal`]:
//!   Doucet, Godsill & Andrieu 2000, *On sequential Monte Carlo sampling
//!   methods for Bayesian filtering*, Stat. Comput. 10:197–208, §II.D; the
//!   fully adapted auxiliary particle filter of Pitt & Shephard 1999,
//!   *Filtering via simulation: auxiliary particle filters*, JASA
//!   94:590–599) for a model that measures its state.
//! * `noise.rs`: the **random numbers**: xoshiro128++ seeded from a `u64`,
//!   Gaussian draws by Box–Muller; runs are reproducible from the seed.
//! * `vector.rs`: component-wise checks and angle wrapping the others share.
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

mod config;
mod filter;
mod model;
mod noise;
mod proposal;
mod regularization;
mod resampling;
#[cfg(test)]
mod tests;
mod vector;
mod weights;

pub use config::{
    DEFAULT_COLLAPSE_GATE, DEFAULT_RESAMPLE_FRACTION, ParticleFilterConfig, ParticleFilterError,
};
pub use filter::{ParticleFilter, ParticleFilterCounters};
pub use model::ParticleModel;
pub use proposal::Proposal;
pub use regularization::optimal_bandwidth;
pub use resampling::systematic_resample;
