//! How the particles of a step are drawn: from the transition prior (the
//! paper's) or from the optimal importance density.
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
//! the system (the module docs of [`super`]). Per component, with `q = σ_q²`, `r = σ_r²`,
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
//! [`ParticleFilterConfig::with_proposal`]: super::ParticleFilterConfig::with_proposal

use nalgebra::SVector;

use crate::math;

use super::vector::{finite, wrap_angles};
use super::{ParticleFilter, ParticleModel};

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

impl<Model, const N: usize, const M: usize, const P: usize, const K: usize>
    ParticleFilter<Model, N, M, P, K>
where
    Model: ParticleModel<N, M>,
{
    /// The update of the optimal proposal (module docs, "The optimal
    /// proposal"), on particles at `f(x_{k−1})`: weights by
    /// `N(z; f, Q + R)`, the estimate from the per-particle posterior
    /// means, resampling on the effective sample size, then the draw.
    pub(super) fn update_optimal(&mut self, z: &SVector<f32, M>, std: &SVector<f32, M>) {
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

    /// Every particle `x + σ ∘ ξ` (angles wrapped): the optimal proposal's
    /// draws.
    pub(super) fn diffuse(&mut self, spread: &SVector<f32, N>) {
        for x in self.particles.iter_mut() {
            self.noise.perturb(x, spread, &self.angles);
        }
    }
}
