//! Selection (step 6 of the module docs of [`super`]): the particles are
//! resampled when the effective sample size falls below the configured
//! fraction of `P`, then regularized or roughened if configured (module
//! `regularization`).
//!
//! # Systematic resampling
//! One uniform draw `u ∈ [0, 1)` and `P` evenly spaced pointers
//! `(k + u)/P`, `k = 0 … P−1`, on the cumulative weights: particle `i` is
//! copied once for each pointer in `[Σ_{j<i} w̃⁽ʲ⁾, Σ_{j≤i} w̃⁽ʲ⁾)`, so it gets
//! `⌊P w̃⁽ⁱ⁾⌋` or `⌈P w̃⁽ⁱ⁾⌉` copies (the lowest-variance of the standard
//! schemes, `O(P)`). The copies go to a second particle array of the filter
//! and are copied back; a model's modes go the same way, with their
//! particles.

use super::regularization::covariance_factor;
use super::{ParticleFilter, ParticleModel};

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
    resample_slices(source, weights, uniform, out)
}

/// [`systematic_resample`] on slices: `out.len()` pointers over the
/// pairs of `source` and `weights` (the shorter one's length).
fn resample_slices<T: Copy>(source: &[T], weights: &[f32], uniform: f32, out: &mut [T]) -> bool {
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
    let step = total / out.len() as f32;
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

impl<Model, const N: usize, const M: usize, const P: usize, const K: usize>
    ParticleFilter<Model, N, M, P, K>
where
    Model: ParticleModel<N, M>,
{
    /// Resamples if the effective sample size fell below the threshold.
    pub(super) fn resample_if_degenerate(&mut self) {
        let threshold = self.config.resample_fraction * P as f32;
        if self.effective_sample_size() < threshold {
            self.resample();
        }
    }

    /// Systematic resampling into the buffer, then back; weights `1/P`;
    /// then the regularization, if configured.
    pub(super) fn resample(&mut self) {
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
            // The same weights and pointer pick the same particles: each
            // mode goes with its particle (module docs of the model,
            // "Modes").
            if Model::MODES > 0
                && resample_slices(&self.modes, &self.weights, uniform, &mut self.mode_buffer)
            {
                self.modes = self.mode_buffer;
            }
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
}
