//! Weighting the particles by a measurement's likelihood (steps 3 to 5 of
//! the module docs of [`super`]), in log space and, for a sharp likelihood
//! of a regularized filter, in stages.
//!
//! # Weights in log space
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
//! # Progressive correction (opt-in)
//! With [`ParticleFilterConfig::with_regularization`] (module
//! `regularization`), a sharp likelihood is applied in stages
//! (progressive correction, Oudjane & Musso 2000; Musso, Oudjane & Le Gland
//! 2001, §12.5): when the weighted mean of `ℓ⁽ⁱ⁾ − min ℓ` (`ℓ = ½ Σ (r/σ_r)²`,
//! nats) exceeds 2, the likelihood is applied as `p(z|x)^λ` with
//! `λ = 2 / spread`, the cloud resampled and regularized, `ℓ` recomputed
//! on the new particles, and so on until the exponents add up to 1 (at
//! most 32 stages; the last takes what remains; each extra stage is
//! counted in `correction_stages`). A prior much wider than the
//! measurement noise then converges onto the measurement instead of onto
//! its single closest particle. Without regularization (the default) an
//! update is one stage, bit for bit the plain filter's.
//!
//! # A likelihood of the model's own
//! [`ParticleFilter::update_with_likelihood`] weights the particles by any
//! `−2 ln p(z | x)` the caller computes (e.g. a quantized measurement:
//! the indicator of the quantization cell, Karlsson & Gustafsson 2005,
//! *Particle filtering for quantized sensor information*, EUSIPCO), through
//! the same weighting, collapse, resampling and regularization as the
//! Gaussian update.
//!
//! [`ParticleFilterConfig::with_regularization`]: super::ParticleFilterConfig::with_regularization

use nalgebra::SVector;

use crate::math;

use super::vector::finite;
use super::{ParticleFilter, ParticleModel};

/// Log-ratios to the best particle below this are weighted 0 (`e^−87` is
/// at the bottom of `f32`'s normal range).
const MIN_LOG_RATIO: f32 = -87.0;

/// Progressive correction (module docs): the most stages an update is
/// split into, and the likelihood spread (nats, weighted mean of the
/// log-likelihood above the best particle's) each stage may apply.
const MAX_STAGES: usize = 32;
const STAGE_NATS: f32 = 2.0;

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
pub(super) fn normalise<const P: usize>(weights: &mut [f32; P]) -> bool {
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

impl<Model, const N: usize, const M: usize, const P: usize, const K: usize>
    ParticleFilter<Model, N, M, P, K>
where
    Model: ParticleModel<N, M>,
{
    pub(super) fn update_weights(&mut self, z: &SVector<f32, M>, inverse_std: &SVector<f32, M>) {
        if !finite(z) {
            self.reject();
            return;
        }
        self.update_weights_by(|model, x| gaussian_distance_sq(model, z, x, inverse_std));
    }

    /// [`Self::update_weights`] with `distance_sq(model, x)` in place of
    /// the Gaussian `Σ_j (r_j/σ_r,j)²` (`ℓ = ½ distance_sq`).
    pub(super) fn update_weights_by(
        &mut self,
        mut distance_sq: impl FnMut(&Model, &SVector<f32, N>) -> f32,
    ) {
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
    pub(super) fn log_likelihoods(
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
    pub(super) fn weigh(&mut self, exponent: f32) -> bool {
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
}
