//! What follows a resampling, if configured: the kernel step of the
//! regularized particle filter, or roughening; both replace the copies
//! resampling makes by distinct particles.
//!
//! # Regularization (opt-in)
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
//! cannot do.
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
//! [`ParticleFilterConfig::with_regularization`]: super::ParticleFilterConfig::with_regularization
//! [`ParticleFilterConfig::with_roughening`]: super::ParticleFilterConfig::with_roughening

use nalgebra::{SMatrix, SVector};

use crate::math;

use super::vector::{finite, wrap_angles};
use super::{ParticleFilter, ParticleModel};

/// The optimal bandwidth of a Gaussian kernel for `states` dimensions and
/// `particles` particles (Musso, Oudjane & Le Gland 2001, eq. for
/// `h_opt` with the Gaussian kernel): `(4 / (P (N + 2)))^{1/(N + 4)}`.
#[must_use]
pub fn optimal_bandwidth(states: usize, particles: usize) -> f32 {
    let base = 4.0 / (particles as f32 * (states as f32 + 2.0));
    math::exp(math::ln(base) / (states as f32 + 4.0))
}

/// The lower Cholesky factor of a finite, symmetric (to 1e-6 of its
/// largest entry) covariance, jittered by 1e-5 of its largest diagonal
/// entry if it is only semi-definite; `None` otherwise.
pub(super) fn covariance_factor<const K: usize>(
    c: &SMatrix<f32, K, K>,
) -> Option<SMatrix<f32, K, K>> {
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

impl<Model, const N: usize, const M: usize, const P: usize, const K: usize>
    ParticleFilter<Model, N, M, P, K>
where
    Model: ParticleModel<N, M>,
{
    /// Roughening (module docs): every particle jittered by
    /// `K E_k P^{−1/d}` per component, angles by the range of their
    /// deviations from the estimate.
    pub(super) fn roughen(&mut self) {
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
    pub(super) fn regularize(&mut self, kernel: &SMatrix<f32, N, N>) {
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
}
