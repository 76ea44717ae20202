//! The [`ParticleFilter`] (the module docs of [`super`]): its particles and
//! weights, construction from the prior, prediction, the updates, the
//! estimate and its covariance, reset and collapse recovery.
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
//! [`DEFAULT_COLLAPSE_GATE`]: super::DEFAULT_COLLAPSE_GATE

use nalgebra::{SMatrix, SVector};

use crate::math;

use super::noise::Noise;
use super::regularization::covariance_factor;
use super::vector::{finite, non_negative, wrap_angles};
use super::weights::normalise;
use super::{
    ParticleFilterConfig, ParticleFilterError, ParticleModel, Proposal, optimal_bandwidth,
};

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

/// The particle filter (module docs): model `Model`, `N` states, `M`
/// measurements, `P` particles, and `K` mode slots: `P` for a model with
/// modes (a `u8` per particle beside it, module docs of the model,
/// "Modes"), 0 (the default) for one without.
#[derive(Debug, Clone, PartialEq)]
pub struct ParticleFilter<Model, const N: usize, const M: usize, const P: usize, const K: usize = 0>
where
    Model: ParticleModel<N, M>,
{
    pub(super) model: Model,
    pub(super) config: ParticleFilterConfig<N, M>,
    /// The spread of a collapse's redraw, resolved at construction.
    pub(super) recovery_std: SVector<f32, N>,
    /// Which components are angles (asked of the model once).
    pub(super) angles: [bool; N],
    /// The regularization kernel's bandwidth `h` (0: off) and its
    /// shrinkage `a = √(1 − h²)`, resolved at construction.
    pub(super) bandwidth: f32,
    pub(super) shrinkage: f32,
    pub(super) particles: [SVector<f32, N>; P],
    /// Where predictions and resamplings are built before being taken.
    pub(super) buffer: [SVector<f32, N>; P],
    /// Each particle's mode (`K = P` with modes, else empty), and where
    /// predictions and resamplings build them.
    pub(super) modes: [u8; K],
    pub(super) mode_buffer: [u8; K],
    /// Normalised (sum 1) between calls.
    pub(super) weights: [f32; P],
    /// `ℓ⁽ⁱ⁾ = −ln p(z | x⁽ⁱ⁾) + const` of the update in progress.
    pub(super) log_likelihood: [f32; P],
    pub(super) estimate: SVector<f32, N>,
    pub(super) noise: Noise,
    pub(super) counters: ParticleFilterCounters,
    /// [`Proposal::Optimal`]: the particles are `f(x_{k−1})` (or, before
    /// the first update, the prior mean), their noise still to draw
    /// (module docs, "The optimal proposal").
    pub(super) draw_pending: bool,
    /// The standard deviations of that noise: `σ_q`, or the prior's.
    pub(super) pending_std: SVector<f32, N>,
}

impl<Model, const N: usize, const M: usize, const P: usize, const K: usize>
    ParticleFilter<Model, N, M, P, K>
where
    Model: ParticleModel<N, M>,
{
    /// A filter whose `P` particles are drawn from the Gaussian prior
    /// `N(prior_mean, diag(prior_std²))` (per component, state units; the
    /// paper's `P(0) = 10 I` is `prior_std = √10` everywhere) with equal
    /// weights, by a generator seeded with `seed`, and then, for a model
    /// with modes, each particle's mode from
    /// [`ParticleModel::initial_mode`]. The estimate is `prior_mean`
    /// (angles wrapped) until the first step.
    ///
    /// # Errors
    /// [`ParticleFilterError::NoParticles`] for `P = 0`,
    /// [`ParticleFilterError::PriorMean`] for a non-finite mean,
    /// [`ParticleFilterError::PriorStd`] for a negative or non-finite
    /// spread, [`ParticleFilterError::Proposal`] for
    /// [`Proposal::Optimal`] with a model that does not measure its state,
    /// [`ParticleFilterError::Modes`] for a model with modes and `K ≠ P`
    /// or the optimal proposal.
    pub fn new(
        model: Model,
        config: ParticleFilterConfig<N, M>,
        prior_mean: SVector<f32, N>,
        prior_std: SVector<f32, N>,
        seed: u64,
    ) -> Result<Self, ParticleFilterError> {
        let start = Start::of::<Model, M, P, K>(&model, &config, &prior_mean, &prior_std)?;
        let mut filter = Self {
            model,
            recovery_std: config.recovery_std.unwrap_or(prior_std),
            config,
            angles: start.angles,
            bandwidth: start.bandwidth,
            shrinkage: start.shrinkage,
            particles: [start.mean; P],
            buffer: [start.mean; P],
            modes: [0; K],
            mode_buffer: [0; K],
            weights: [1.0 / P as f32; P],
            log_likelihood: [0.0; P],
            estimate: start.mean,
            noise: Noise::new(seed),
            counters: ParticleFilterCounters::default(),
            draw_pending: false,
            pending_std: prior_std,
        };
        filter.draw_prior(&prior_std);
        filter.redraw_modes();
        Ok(filter)
    }

    /// [`Self::new`] in place: the filter becomes, field by field, the one
    /// `new` would return for the same arguments (counters zeroed, the
    /// generator reseeded), without a second filter on the stack to move
    /// from (a filter of 100 particles of 5 states is 5 KB: on a 4–8 KiB
    /// microcontroller stack a move is a large part of it).
    ///
    /// # Errors
    /// As [`Self::new`]; the filter is then unchanged.
    pub fn init(
        &mut self,
        model: Model,
        config: ParticleFilterConfig<N, M>,
        prior_mean: SVector<f32, N>,
        prior_std: SVector<f32, N>,
        seed: u64,
    ) -> Result<(), ParticleFilterError> {
        let start = Start::of::<Model, M, P, K>(&model, &config, &prior_mean, &prior_std)?;
        self.model = model;
        self.recovery_std = config.recovery_std.unwrap_or(prior_std);
        self.config = config;
        self.angles = start.angles;
        self.bandwidth = start.bandwidth;
        self.shrinkage = start.shrinkage;
        self.particles.fill(start.mean);
        self.buffer.fill(start.mean);
        self.modes.fill(0);
        self.mode_buffer.fill(0);
        self.weights.fill(1.0 / P as f32);
        self.log_likelihood.fill(0.0);
        self.estimate = start.mean;
        self.noise = Noise::new(seed);
        self.counters = ParticleFilterCounters::default();
        self.draw_pending = false;
        self.pending_std = prior_std;
        self.draw_prior(&prior_std);
        self.redraw_modes();
        Ok(())
    }

    /// A particle at the origin, as a constant.
    #[cfg_attr(not(feature = "fusion-particle-filter"), allow(dead_code))]
    const ORIGIN: SVector<f32, N> =
        SVector::from_array_storage(nalgebra::ArrayStorage([[0.0; N]; 1]));
    /// Every particle at the origin, as a constant.
    #[cfg_attr(not(feature = "fusion-particle-filter"), allow(dead_code))]
    const ALL_AT_ORIGIN: [SVector<f32, N>; P] = [Self::ORIGIN; P];

    /// A filter on `model` whose particles all sit at the origin with
    /// zero weights and zero spreads (the plain prior proposal, no
    /// regularization or roughening, seed 0): not a filter to run, but a
    /// slot for [`Self::init`] to start in place. Its arrays are
    /// constants, which the compiler writes straight into the place the
    /// filter is returned to (no 5 KB temporary on the stack); not
    /// inlined, so that the caller's place is that destination.
    #[inline(never)]
    #[cfg_attr(not(feature = "fusion-particle-filter"), allow(dead_code))]
    pub(crate) fn blank(model: Model) -> Self {
        Self {
            model,
            config: ParticleFilterConfig {
                process_std: Self::ORIGIN,
                measurement_std: SVector::from_array_storage(nalgebra::ArrayStorage([[1.0; M]; 1])),
                inverse_measurement_std: SVector::from_array_storage(nalgebra::ArrayStorage(
                    [[1.0; M]; 1],
                )),
                resample_fraction: super::DEFAULT_RESAMPLE_FRACTION,
                recovery_std: None,
                collapse_gate: super::DEFAULT_COLLAPSE_GATE,
                regularization: 0.0,
                roughening: 0.0,
                proposal: Proposal::Prior,
            },
            recovery_std: Self::ORIGIN,
            angles: [false; N],
            bandwidth: 0.0,
            shrinkage: 1.0,
            particles: Self::ALL_AT_ORIGIN,
            buffer: Self::ALL_AT_ORIGIN,
            modes: [0; K],
            mode_buffer: [0; K],
            weights: [0.0; P],
            log_likelihood: [0.0; P],
            estimate: Self::ORIGIN,
            noise: Noise::new(0),
            counters: ParticleFilterCounters {
                resamplings: 0,
                collapses: 0,
                rejected_inputs: 0,
                dropped_particles: 0,
                correction_stages: 0,
            },
            draw_pending: false,
            pending_std: Self::ORIGIN,
        }
    }

    /// The start's draw: with [`Proposal::Optimal`] the first update draws
    /// from `p(x_0 | y_0)` (module docs); otherwise every particle from the
    /// prior.
    fn draw_prior(&mut self, prior_std: &SVector<f32, N>) {
        if self.config.proposal == Proposal::Optimal {
            self.draw_pending = true;
        } else {
            self.redraw(prior_std);
        }
    }

    /// Every particle's mode drawn from its prior
    /// ([`ParticleModel::initial_mode`], one uniform draw each), as at the
    /// start and at a [`Self::reset`]; the states and weights are left as
    /// they are. A model without modes draws nothing.
    pub fn redraw_modes(&mut self) {
        if Model::MODES == 0 {
            return;
        }
        for mode in self.modes.iter_mut() {
            *mode = self
                .model
                .initial_mode(self.noise.uniform())
                .min(Model::MODES.saturating_sub(1));
        }
    }

    /// The model.
    #[must_use]
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The model, to change its parameters from the next step on.
    pub fn model_mut(&mut self) -> &mut Model {
        &mut self.model
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
            // The upper triangle of `(d dᵀ) w`, mirrored below after the
            // sum: `(d_i d_j) w` and `(d_j d_i) w` are the same `f32`.
            for (j, &dj) in d.as_slice().iter().enumerate() {
                for (i, &di) in d.as_slice().iter().enumerate().take(j + 1) {
                    if let Some(c) = covariance.get_mut((i, j)) {
                        *c += (di * dj) * w;
                    }
                }
            }
        }
        covariance.fill_lower_triangle_with_upper_triangle();
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

    /// Their modes (module docs of the model, "Modes"; empty for a filter
    /// without mode slots).
    #[must_use]
    pub fn modes(&self) -> &[u8; K] {
        &self.modes
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
        let moded = Model::MODES > 0;
        let noise = &mut self.noise;
        for (slot, (x, next)) in self
            .particles
            .iter()
            .zip(self.buffer.iter_mut())
            .enumerate()
        {
            let mut moved = if optimal {
                self.model.transition(x, u, dt_s)
            } else if moded {
                // The mode's jump, then the state's move in it (module docs
                // of the model, "Modes").
                let mode = self.modes.get(slot).copied().unwrap_or(0);
                let jumped = self
                    .model
                    .next_mode(mode, noise.uniform())
                    .min(Model::MODES.saturating_sub(1));
                if let Some(next_mode) = self.mode_buffer.get_mut(slot) {
                    *next_mode = jumped;
                }
                let mut gaussian = || noise.gaussian();
                self.model.sample_transition_in_mode(
                    jumped,
                    x,
                    u,
                    dt_s,
                    &self.config.process_std,
                    &mut gaussian,
                )
            } else {
                let mut gaussian = || noise.gaussian();
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
        for (slot, ((x, next), w)) in self
            .particles
            .iter_mut()
            .zip(self.buffer.iter())
            .zip(self.weights.iter_mut())
            .enumerate()
        {
            if finite(next) {
                *x = *next;
                // A dropped particle keeps its mode with its state.
                if moded
                    && let (Some(mode), Some(&jumped)) =
                        (self.modes.get_mut(slot), self.mode_buffer.get(slot))
                {
                    *mode = jumped;
                }
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
    /// `mean` (angles wrapped); a model's modes are drawn from their prior
    /// ([`Self::redraw_modes`]), as at the start. Counters and the
    /// generator's stream go on.
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
        self.redraw_modes();
        self.weights = [1.0 / P as f32; P];
        self.estimate = centre;
        self.draw_pending = false;
        Ok(())
    }

    /// Moves every particle by `reposition(x, gaussian)` (`gaussian`: the
    /// filter's own standard normal draws), then gives them equal weights
    /// and takes their mean as the estimate: e.g. sensor resetting (Lenser
    /// & Veloso 2000), some components redrawn from a measurement while
    /// the others keep what each particle knows. Angles are wrapped after
    /// the move; a particle the move would leave non-finite keeps its old
    /// state. Counters go on; a pending draw of the optimal proposal is
    /// dropped (the move replaces it).
    pub fn reposition(
        &mut self,
        mut reposition: impl FnMut(&mut SVector<f32, N>, &mut dyn FnMut() -> f32),
    ) {
        let noise = &mut self.noise;
        let mut gaussian = || noise.gaussian();
        for x in self.particles.iter_mut() {
            let mut moved = *x;
            reposition(&mut moved, &mut gaussian);
            wrap_angles(&mut moved, &self.angles);
            if finite(&moved) {
                *x = moved;
            }
        }
        self.weights.fill(1.0 / P as f32);
        self.draw_pending = false;
        self.refresh_estimate();
    }

    /// Moves every particle by `shift` (a deterministic map of the state,
    /// e.g. a translation of the whole cloud), keeping its weight, and
    /// takes the weighted mean as the estimate. Angles are wrapped after
    /// the move; a particle the move would leave non-finite keeps its old
    /// state. A pending draw of the optimal proposal is dropped (the move
    /// replaces it).
    pub fn shift(&mut self, mut shift: impl FnMut(&mut SVector<f32, N>)) {
        for x in self.particles.iter_mut() {
            let mut moved = *x;
            shift(&mut moved);
            wrap_angles(&mut moved, &self.angles);
            if finite(&moved) {
                *x = moved;
            }
        }
        self.draw_pending = false;
        self.refresh_estimate();
    }

    /// Collapse recovery (module docs): redraw around the kept estimate.
    pub(super) fn collapse(&mut self) {
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

    pub(super) fn reject(&mut self) {
        self.counters.rejected_inputs = self.counters.rejected_inputs.saturating_add(1);
    }

    /// `x − reference` with angle components wrapped.
    pub(super) fn deviation(
        &self,
        x: &SVector<f32, N>,
        reference: &SVector<f32, N>,
    ) -> SVector<f32, N> {
        let mut d = x - reference;
        wrap_angles(&mut d, &self.angles);
        d
    }

    /// Sets the estimate to the weighted mean of the particles (linear
    /// components about the previous estimate, for resolution far from the
    /// origin; angles on the circle). `false` (estimate kept) if the mean is
    /// not finite.
    pub(super) fn refresh_estimate(&mut self) -> bool {
        // Arrays and slices: zipped, their iterators compile to one indexed
        // loop, where nalgebra's matrix iterators each keep a position and
        // an end per component.
        let mut linear = [0.0_f32; N];
        let mut sines = [0.0_f32; N];
        let mut cosines = [0.0_f32; N];
        for (x, &w) in self.particles.iter().zip(self.weights.iter()) {
            let components = x
                .as_slice()
                .iter()
                .zip(self.estimate.as_slice())
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

/// What [`ParticleFilter::new`] and [`ParticleFilter::init`] resolve from
/// their arguments once they are valid.
struct Start<const N: usize> {
    angles: [bool; N],
    bandwidth: f32,
    shrinkage: f32,
    /// The prior mean, angles wrapped.
    mean: SVector<f32, N>,
}

impl<const N: usize> Start<N> {
    /// The checks of [`ParticleFilter::new`], in its order.
    fn of<Model: ParticleModel<N, M>, const M: usize, const P: usize, const K: usize>(
        model: &Model,
        config: &ParticleFilterConfig<N, M>,
        prior_mean: &SVector<f32, N>,
        prior_std: &SVector<f32, N>,
    ) -> Result<Self, ParticleFilterError> {
        if P == 0 {
            return Err(ParticleFilterError::NoParticles);
        }
        if !finite(prior_mean) {
            return Err(ParticleFilterError::PriorMean);
        }
        if !non_negative(prior_std) {
            return Err(ParticleFilterError::PriorStd);
        }
        if config.proposal == Proposal::Optimal && !(M == N && model.measures_state()) {
            return Err(ParticleFilterError::Proposal);
        }
        if Model::MODES > 0 && (K != P || config.proposal == Proposal::Optimal) {
            return Err(ParticleFilterError::Modes);
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
        let mut mean = *prior_mean;
        wrap_angles(&mut mean, &angles);
        Ok(Self {
            angles,
            bandwidth,
            shrinkage,
            mean,
        })
    }
}
