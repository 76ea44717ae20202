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
//! # Modes
//! A model may give each particle a discrete mode beside its state
//! ([`ParticleModel::MODES`] > 0): the jump-Markov system of Doucet,
//! Gordon & Krishnamurthy 2001 (*Particle filters for state estimation of
//! jump Markov linear systems*, IEEE Trans. Signal Process.
//! 49(3):613–624), whose particles carry the pair `(r, x)`: at each
//! prediction the mode first makes its Markov jump
//! ([`ParticleModel::next_mode`], `r_k ~ p(r_k | r_{k−1})`), then the
//! state moves in the new mode
//! ([`ParticleModel::sample_transition_in_mode`], `x_k ~ p(x_k | x_{k−1},
//! r_k)`); the weights are the state's likelihood, as without modes, and
//! a resampling copies each particle's mode with it (the multiple-model
//! bootstrap filter of McGinnity & Irwin 2000, *Multiple model bootstrap
//! filter for maneuvering target tracking*, IEEE Trans. AES
//! 36(3):1006–1012). The filter keeps the modes in a `u8` array beside
//! the particles (its `K = P` slots, [`ParticleFilter`]); a model without
//! modes (the default) costs no draw and no byte.
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

    /// How many discrete modes a particle carries beside its state (module
    /// docs, "Modes"), at most 255; 0 (the default) for none: the filter
    /// then asks none of the mode methods below and draws nothing for
    /// them. With modes the filter needs `K = P` mode slots and the prior
    /// proposal ([`ParticleFilterError::Modes`] otherwise).
    ///
    /// [`ParticleFilterError::Modes`]: super::ParticleFilterError::Modes
    const MODES: u8 = 0;

    /// A particle's mode at the start, from a uniform draw `uniform` in
    /// [0, 1) (the mode's prior by its inverse distribution function;
    /// default 0). A mode `≥` [`Self::MODES`] is taken as the last one.
    fn initial_mode(&self, uniform: f32) -> u8 {
        let _ = uniform;
        0
    }

    /// The mode after a step from `mode`, from a uniform draw `uniform` in
    /// [0, 1) (the mode's Markov transition; default: kept). Asked before
    /// the step's [`Self::sample_transition_in_mode`]. A mode `≥`
    /// [`Self::MODES`] is taken as the last one.
    fn next_mode(&self, mode: u8, uniform: f32) -> u8 {
        let _ = uniform;
        mode
    }

    /// [`Self::sample_transition`] in mode `mode`, the particle's mode
    /// after [`Self::next_mode`] (default: the mode ignored).
    fn sample_transition_in_mode(
        &self,
        mode: u8,
        x: &SVector<f32, N>,
        u: &Self::Input,
        dt_s: f32,
        process_std: &SVector<f32, N>,
        gaussian: &mut dyn FnMut() -> f32,
    ) -> SVector<f32, N> {
        let _ = mode;
        self.sample_transition(x, u, dt_s, process_std, gaussian)
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
