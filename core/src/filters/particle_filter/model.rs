//! The system a [`ParticleFilter`] estimates: the [`ParticleModel`] gives the
//! transition `f` and the measurement `h` (the module docs of [`super`],
//! "System"), says which state components are angles and may draw a
//! particle's step with its process noise itself.
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
//! [`ParticleFilter`]: super::ParticleFilter
//! [`ParticleFilter::covariance`]: super::ParticleFilter::covariance

use nalgebra::SVector;

use super::vector::finite;

/// A system for the [`ParticleFilter`]: `x_k = f(x_{k−1}, u, h) + w`,
/// `y = h(x) + v`, with the noises given by the [`ParticleFilterConfig`].
///
/// [`ParticleFilter`]: super::ParticleFilter
/// [`ParticleFilterConfig`]: super::ParticleFilterConfig
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
    ///
    /// [`Proposal::Optimal`]: super::Proposal::Optimal
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
