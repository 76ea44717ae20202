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
//! and are copied back; a model's modes go the same way, each copied with
//! its particle in the one pass over the weights.

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
    systematic_pick(weights, uniform, |k, i| {
        if let (Some(slot), Some(x)) = (out.get_mut(k), source.get(i)) {
            *slot = *x;
        }
    })
}

/// The selection of [`systematic_resample`]: `copy(k, i)` for each pointer
/// `k = 0 … P−1`, in order, with `i` the particle it falls on. Returns
/// `false` (and copies nothing) if the weights do not add up to a finite
/// positive total.
fn systematic_pick<const P: usize>(
    weights: &[f32; P],
    uniform: f32,
    mut copy: impl FnMut(usize, usize),
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
    // The particles with a stretch (positive weight), in order; the
    // positive total guarantees a first one.
    let mut candidates = weights
        .iter()
        .map(|&w| clean(w))
        .enumerate()
        .filter(|&(_, w)| w > 0.0);
    let Some((mut chosen, mut cumulative)) = candidates.next() else {
        return false;
    };
    for k in 0..P {
        let pointer = (k as f32 + uniform) * step;
        // Advance to the first particle whose stretch ends past the pointer
        // (past the end, rounding keeps the last one).
        while pointer >= cumulative {
            let Some((i, w)) = candidates.next() else {
                break;
            };
            chosen = i;
            cumulative += w;
        }
        copy(k, chosen);
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
        let moded = Model::MODES > 0;
        let (particles, buffer) = (&self.particles, &mut self.buffer);
        let (modes, mode_buffer) = (&self.modes, &mut self.mode_buffer);
        let picked = systematic_pick(&self.weights, uniform, |k, i| {
            // Component by component: a whole-vector assignment here
            // becomes a call to `memmove` per copy on the Cortex-M4.
            if let (Some(slot), Some(x)) = (buffer.get_mut(k), particles.get(i)) {
                slot.copy_from(x);
            }
            // Each mode goes with its particle (module docs of the model,
            // "Modes").
            if moded && let (Some(slot), Some(&mode)) = (mode_buffer.get_mut(k), modes.get(i)) {
                *slot = mode;
            }
        });
        if picked {
            self.particles = self.buffer;
            if moded {
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
