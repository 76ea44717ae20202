//! The robust momenta observer with dynamic scaling of paper 003 (Romero &
//! Ortega), Proposition 2 (section 5, (31)–(52)): velocities from positions
//! for a *general* mechanical system, any inertia matrix `M(q)`, with known
//! friction and unknown constant disturbances `d`.
//!
//! Where [`wmr_core::drive::momenta_observer`] (Proposition 1) needs a factor of
//! `M⁻¹` with commuting columns and its flat coordinates `Q(q)` (a PDE
//! solved by hand), this observer takes only `M(q)` and its partial
//! derivatives ([`InertiaModel`]) and factors `M⁻¹ = T Tᵀ` itself with the
//! standard, lower-triangular Cholesky factor `T` (Remarks 3.1 and 6.1),
//! and `∂T/∂q_i = −T·Λ(Tᵀ (∂M/∂q_i) T)` with `Λ(X)` the lower triangle of
//! `X` with its diagonal halved (differentiate `T Tᵀ = M⁻¹`, whose
//! derivative is `−M⁻¹ (∂M/∂q_i) M⁻¹`). The *upper*-triangular factor of
//! the crane's `M⁻¹` is the commuting factor (53) of section 6.3, for which
//! `J = 0`; the lower one is not (Remark 6.1).
//!
//! # System (1), (5)–(7)
//! With `p = Tᵀ𝐩`: `q̇ = T p`,
//! `ṗ = J(q, p) p − Tᵀ(∇V − G u − d) − R p`, `R = Tᵀ ℜ T`, and the
//! gyroscopic `J_jk(q, p) = −𝐩ᵀ[T_j, T_k]` with `𝐩 = T⁻ᵀ p`, `[f, g] =
//! (∂g/∂q) f − (∂f/∂q) g` the Lie bracket of the columns `T_j` of `T`.
//! (6) prints `−pᵀ[T_j, T_k]`: differentiating `p = Tᵀ𝐩` along Hamilton's
//! equations gives `ṗ_j = Σ_k p_k 𝐩ᵀ[T_k, T_j] + …`, the bracket paired
//! with the original momenta `𝐩` (the plain text lost the bold, or the
//! print slipped); with `p` the model is off by the whole gyroscopic force
//! on the crane (checked in `host-tests`).
//! Writing `D_j = Σ_i T_ij ∂T/∂q_i` (the derivative of `T` along `T_j`),
//! `[T_j, T_k] = D_j e_k − D_k e_j`, so `J(q, p) = Wᵀ − W` with rows
//! `W_k = (D_kᵀ 𝐩)ᵀ`, and the `J̄` of property (P.ii), `J(q, p) p̄ =
//! J̄(q, p̄) p`, is `J̄(q, p̄) = (E(p̄)ᵀ − U(p̄)) T⁻ᵀ` with `E(p̄) = Σ_k p̄_k
//! D_k` and rows `U_j = (D_j p̄)ᵀ`. (For a factor with commuting columns
//! `J = 0`.)
//!
//! # Observer (Proposition 2), as derived from its proof
//! States `X = (𝐪, 𝐩, p_I, d_I, r)` (31), estimates (33):
//! `p̂ = p_I + H(𝐪, 𝐩) q`, `d̂ = d_I + γ_d q / r²` (51), with
//! `H(q, p) = [ψ I + J̄(q, p)] T⁻¹(q)` (36)–(37) and
//!
//! ```text
//! ṗ_I = f(p̂) − H(𝐪,𝐩) T p̂ − ∇_𝐪 p_P 𝐪̇ − ∇_𝐩 p_P 𝐩̇           (34)
//! f(p̂) = J(q,p̂) p̂ − R p̂ − Tᵀ(∇V − G u − d̂)
//! 𝐪̇ = T p̂ − ψ1 e_q          𝐩̇ = f(p̂) − ψ2 e_p                  (44)
//! ṙ = −(ψ/4)(r − 1) + (r/ψ)(‖Δ_p T‖² + ‖Δ_q T‖²),  r(0) ≥ 1        (46)
//! ḋ_I = −(γ_d/r²) T p̂ + 2 γ_d q ṙ / r³                             (47)
//! e_q = 𝐪 − q,  e_p = 𝐩 − p̂                                        (41)
//! Δ_q = H(q, p̂) − H(𝐪, p̂),  Δ_p = H(𝐪, p̂) − H(𝐪, 𝐩)               (40)
//! ψ = 4(1 + κ)                                                      (50)
//! ψ1 = ½ r²‖T‖² + r(r−1)‖Δ_q T‖²/(ψ|e_q|²) + κ                     (50), ψ4
//! ψ2 = ½ r²‖H(𝐪,𝐩)‖²‖T‖² + r(r−1)‖Δ_p T‖²/(ψ|e_p|²) + κ            (50), ψ5
//! ```
//!
//! giving `p̃̇ = [J − ψI − R + (Δ_q + Δ_p)T] p̃ + Tᵀ d̃`, `d̃̇ = −(γ_d/r²) T p̃`
//! (48) and, with `η = p̃/r` (42),
//! `V = ½(|η|² + |e_q|² + |e_p|² + (r−1)² + |d̃|²/γ_d)` (49),
//! `V̇ ≤ −κ(|η|² + |e_q|² + |e_p|² + (r−1)²)` (52): `p̃ → 0` from every
//! initial condition and `r ≥ 1` stays bounded.
//!
//! Choices and slips, each checked against the proof:
//! * the paper's `ψ4, ψ5` use bounds `‖Δ_q‖ ≤ ‖Δ̄_q‖|e_q|` it leaves
//!   abstract; the smallest valid choice `‖Δ̄_q‖ = ‖Δ_q T‖/(‖T‖|e_q|)` is
//!   computable (both `H` are known), so it is used, and 0 when `e = 0`
//!   (then `Δ = 0` exactly);
//! * every matrix norm is the Frobenius norm, an upper bound of the induced
//!   2-norm the proof uses: each inequality of the proof still holds;
//! * (34) prints `T(q)ᵀ(q)∇V` and `v` for `Tᵀ∇V` and `TᵀGu`;
//! * (47) is written for `d_P = q/r²`; with an adaptation gain `γ_d` (the
//!   weight `1/γ_d` on `|d̃|²` in `V`, as in [`wmr_core::drive::momenta_observer`])
//!   the cross term cancels for `d_P = γ_d q/r²` (paper: `γ_d = 1`).
//!
//! # Discretization: innovation form
//! The I&I states exist so that `q̇` is never differentiated. Per sample
//! step of length `h` (input held), with `T, J, H, f` at the step's start
//! and the measured `Δq = q⁺ − q`, the increments of `p_P = H(𝐪, 𝐩) q`
//! along the observer's own `(𝐪, 𝐩)` (the `∇_𝐪 p_P 𝐪̇ + ∇_𝐩 p_P 𝐩̇`
//! terms of (34)) are exact differences, and `p̂ = p_I + p_P` becomes
//!
//! ```text
//! ν  = h T p̂ − Δq                                  (≈ ∫ T p̃)
//! p̂⁺ = p̂ + h f(p̂) − H(𝐪, 𝐩) ν
//! d̂⁺ = d̂ − (γ_d / r²)(h T p̂⁺ − Δq)                 (p̂⁺: symplectic, as in Prop. 1)
//! r⁺ = 1 + e^{−ψh/4}(r − 1) + h (r/ψ)(‖Δ_p T‖² + ‖Δ_q T‖²)
//! 𝐪⁺ = q⁺ + e^{−ψ1 h} e_q + ν                      (so e_q⁺ = e^{−ψ1 h} e_q + ν)
//! 𝐩⁺ = p̂⁺ + e^{−ψ2 h} e_p + H(𝐪, 𝐩) ν              (so e_p⁺ = e^{−ψ2 h} e_p + H ν)
//! ```
//!
//! `r⁺ ≥ 1` whenever `r ≥ 1`, in `f32` too (`1 + x ≥ 1` for `x ≥ 0`). The
//! damping of `e_q, e_p` is integrated exactly, so the large `ψ1, ψ2` the
//! scaling asks for cannot make the step unstable; the injection `H ν ≈
//! h(ψ + J̄)p̃` needs `hψ < 1` (checked at construction). Only position
//! differences enter, never `H q` with a large `q`.
//!
//! A sampled observer could evaluate `H` at `(q, p̂)` instead of the
//! filtered `(𝐪, 𝐩)`, making `Δ = 0`; this one keeps to the paper.
//!
//! # Bad input
//! A non-finite `q` or input force, an inertia matrix that is not positive
//! definite at `q` or `𝐪`, or a non-finite result is counted
//! (`rejected_updates`), leaves the estimates unchanged and restarts the
//! step.

use nalgebra::Cholesky;

use wmr_core::drive::momenta_observer::{Matrix, MomentaObserverError, Vector};
use wmr_core::math;

/// A mechanical system (1)–(2) with a configuration-dependent inertia
/// matrix and known friction, as Proposition 2 needs it.
pub trait InertiaModel<const N: usize> {
    /// The control input `u`.
    type Input: Copy;
    /// The inertia matrix `M(q)` (symmetric positive definite).
    fn inertia(&self, q: &Vector<N>) -> Matrix<N>;
    /// `∂M/∂q_i` at `q` (`i < N`; the observer never asks for more).
    fn inertia_derivative(&self, q: &Vector<N>, i: usize) -> Matrix<N>;
    /// `∇V(q)`, the potential forces.
    fn potential_gradient(&self, q: &Vector<N>) -> Vector<N>;
    /// `G(q) u`, the generalised forces of the input.
    fn input_forces(&self, q: &Vector<N>, u: &Self::Input) -> Vector<N>;
    /// The viscous friction coefficients `ℜ = diag(r_i)`, all known.
    fn friction(&self) -> Vector<N>;
}

/// The Cholesky factor `T` of `M⁻¹(q)` (lower triangular) at one
/// configuration, with what the observer derives from it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InertiaFactor<const N: usize> {
    factor: Matrix<N>,
    factor_inverse: Matrix<N>,
    /// `D_j = Σ_i T_ij ∂T/∂q_i` for each column `j`.
    directional: [Matrix<N>; N],
}

impl<const N: usize> InertiaFactor<N> {
    /// Factors `M(q)`; `None` if it is not finite and positive definite.
    #[must_use]
    pub fn at<Model: InertiaModel<N>>(model: &Model, q: &Vector<N>) -> Option<Self> {
        let inertia = model.inertia(q);
        if !inertia.iter().all(|x| x.is_finite()) {
            return None;
        }
        let inverse = Cholesky::new(inertia)?.inverse();
        let factor = Cholesky::new(inverse)?.unpack();
        let factor_inverse = factor.solve_lower_triangular(&Matrix::<N>::identity())?;
        let derivatives: [Matrix<N>; N] = core::array::from_fn(|i| {
            let projected = factor.transpose() * model.inertia_derivative(q, i) * factor;
            -(factor * lower_half(&projected))
        });
        let directional = core::array::from_fn(|j| {
            factor
                .column(j)
                .iter()
                .zip(derivatives.iter())
                .fold(Matrix::<N>::zeros(), |sum, (&t, dt)| sum + dt * t)
        });
        let out = Self {
            factor,
            factor_inverse,
            directional,
        };
        let finite = out.factor.iter().all(|x| x.is_finite())
            && out
                .directional
                .iter()
                .all(|d| d.iter().all(|x| x.is_finite()));
        finite.then_some(out)
    }

    /// `T` (`M⁻¹ = T Tᵀ`, lower triangular).
    #[must_use]
    pub fn factor(&self) -> &Matrix<N> {
        &self.factor
    }

    /// `T⁻¹`.
    #[must_use]
    pub fn factor_inverse(&self) -> &Matrix<N> {
        &self.factor_inverse
    }

    /// The gyroscopic matrix `J(q, p)` of (6), skew-symmetric:
    /// `J_jk = −𝐩ᵀ[T_j, T_k]` with `𝐩 = T⁻ᵀ p` (module docs).
    #[must_use]
    pub fn gyroscopic(&self, p: &Vector<N>) -> Matrix<N> {
        let momenta = self.factor_inverse.transpose() * p;
        let mut w = Matrix::<N>::zeros();
        for (d, mut row) in self.directional.iter().zip(w.row_iter_mut()) {
            row.copy_from(&(d.transpose() * momenta).transpose());
        }
        w.transpose() - w
    }

    /// `J̄(q, p̄)` of property (P.ii): `J(q, p) p̄ = J̄(q, p̄) p`.
    #[must_use]
    pub fn gyroscopic_bar(&self, p_bar: &Vector<N>) -> Matrix<N> {
        let weighted = self
            .directional
            .iter()
            .zip(p_bar.iter())
            .fold(Matrix::<N>::zeros(), |sum, (d, &pk)| sum + d * pk);
        let mut u = Matrix::<N>::zeros();
        for (d, mut row) in self.directional.iter().zip(u.row_iter_mut()) {
            row.copy_from(&(d * p_bar).transpose());
        }
        (weighted.transpose() - u) * self.factor_inverse.transpose()
    }

    /// `H(q, p) = [ψI + J̄(q, p)] T⁻¹(q)` (36).
    fn injection(&self, psi: f32, p: &Vector<N>) -> Matrix<N> {
        (Matrix::<N>::identity() * psi + self.gyroscopic_bar(p)) * self.factor_inverse
    }
}

/// The lower triangle of `x` with its diagonal halved.
fn lower_half<const N: usize>(x: &Matrix<N>) -> Matrix<N> {
    x.lower_triangle() - Matrix::<N>::from_diagonal(&(x.diagonal() * 0.5))
}

/// Validated gains of a [`ScaledMomentaObserver`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ScaledMomentaObserverConfig {
    kappa_per_s: f32,
    period_s: f32,
    disturbance_gain: f32,
    initial_scaling: f32,
}

impl ScaledMomentaObserverConfig {
    /// `κ` (1/s, the guaranteed decay rate of (52); `ψ = 4(1 + κ)`) and the
    /// step `h` (s); `γ_d = 1` as in the paper.
    ///
    /// # Errors
    /// [`MomentaObserverError::Kappa`] for `κ`,
    /// [`MomentaObserverError::Period`] for `h`, and
    /// [`MomentaObserverError::StepTooLong`] when `hψ ≥ 1`.
    pub fn new(kappa_per_s: f32, period_s: f32) -> Result<Self, MomentaObserverError> {
        if !(kappa_per_s.is_finite() && kappa_per_s > 0.0) {
            return Err(MomentaObserverError::Kappa);
        }
        if !(period_s.is_finite() && period_s > 0.0) {
            return Err(MomentaObserverError::Period);
        }
        if period_s * 4.0 * (1.0 + kappa_per_s) >= 1.0 {
            return Err(MomentaObserverError::StepTooLong);
        }
        Ok(Self {
            kappa_per_s,
            period_s,
            disturbance_gain: 1.0,
            initial_scaling: 1.0,
        })
    }

    /// The disturbance adaptation gain `γ_d` (module docs).
    ///
    /// # Errors
    /// [`MomentaObserverError::AdaptationGain`] unless finite and positive.
    pub fn with_disturbance_gain(self, gain: f32) -> Result<Self, MomentaObserverError> {
        if !(gain.is_finite() && gain > 0.0) {
            return Err(MomentaObserverError::AdaptationGain);
        }
        Ok(Self {
            disturbance_gain: gain,
            ..self
        })
    }

    /// The initial scaling factor `r(0)` (1 by default; any `r(0) ≥ 1` is
    /// allowed by (46)).
    ///
    /// # Errors
    /// [`MomentaObserverError::Scaling`] unless finite and `≥ 1`.
    pub fn with_initial_scaling(self, scaling: f32) -> Result<Self, MomentaObserverError> {
        if !(scaling.is_finite() && scaling >= 1.0) {
            return Err(MomentaObserverError::Scaling);
        }
        Ok(Self {
            initial_scaling: scaling,
            ..self
        })
    }

    /// `ψ = 4(1 + κ)`, 1/s.
    #[must_use]
    pub fn psi_per_s(&self) -> f32 {
        4.0 * (1.0 + self.kappa_per_s)
    }

    /// The step `h`, s.
    #[must_use]
    pub fn period_s(&self) -> f32 {
        self.period_s
    }
}

/// The estimates at the last accepted sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScaledMomentaEstimate<const N: usize> {
    /// `p̂ = Tᵀ𝐩̂` with `T` the Cholesky factor of `M⁻¹` (module docs).
    pub transformed_momenta: Vector<N>,
    /// `q̇̂ = T(q) p̂`.
    pub velocity: Vector<N>,
    /// `d̂`, the constant disturbance forces.
    pub disturbance: Vector<N>,
    /// The dynamic scaling factor `r ≥ 1` (46).
    pub scaling: f32,
}

/// The observer's filter states `(𝐪, 𝐩)` of (44).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Filters<const N: usize> {
    q: Vector<N>,
    p: Vector<N>,
}

/// The start of the current step.
#[derive(Debug, Clone, Copy, PartialEq)]
struct StepStart<const N: usize> {
    q: Vector<N>,
    forces: Vector<N>,
    factor: InertiaFactor<N>,
}

/// Proposition 2's observer for a model with `N` degrees of freedom, in
/// the innovation form of the module docs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScaledMomentaObserver<Model, const N: usize>
where
    Model: InertiaModel<N>,
{
    model: Model,
    config: ScaledMomentaObserverConfig,
    start: Option<StepStart<N>>,
    filters: Option<Filters<N>>,
    estimate: ScaledMomentaEstimate<N>,
    rejected_updates: u32,
}

impl<Model, const N: usize> ScaledMomentaObserver<Model, N>
where
    Model: InertiaModel<N>,
{
    /// An observer starting from `p̂ = p̂₀`, `d̂ = d̂₀` and the configured
    /// `r(0)`, with the
    /// filters at the first sample (`𝐪 = q`, `𝐩 = p̂₀`). Non-finite initial
    /// entries are taken as 0.
    #[must_use]
    pub fn new(
        model: Model,
        config: ScaledMomentaObserverConfig,
        momenta_0: Vector<N>,
        disturbance_0: Vector<N>,
    ) -> Self {
        let clean = |x: f32| if x.is_finite() { x } else { 0.0 };
        Self {
            model,
            config,
            start: None,
            filters: None,
            estimate: ScaledMomentaEstimate {
                transformed_momenta: momenta_0.map(clean),
                velocity: Vector::zeros(),
                disturbance: disturbance_0.map(clean),
                scaling: config.initial_scaling,
            },
            rejected_updates: 0,
        }
    }

    /// The model.
    #[must_use]
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The configuration.
    #[must_use]
    pub fn config(&self) -> &ScaledMomentaObserverConfig {
        &self.config
    }

    /// The estimates at the last accepted sample.
    #[must_use]
    pub fn estimate(&self) -> &ScaledMomentaEstimate<N> {
        &self.estimate
    }

    /// Samples skipped for bad input or a non-finite result.
    #[must_use]
    pub fn rejected_updates(&self) -> u32 {
        self.rejected_updates
    }

    /// One sample: the positions `q` measured now and the input `u` held
    /// until the next sample.
    pub fn update(&mut self, q: &Vector<N>, u: &Model::Input) {
        let forces = self.model.input_forces(q, u);
        if !(q.iter().all(|x| x.is_finite()) && forces.iter().all(|x| x.is_finite())) {
            self.reject();
            return;
        }
        let Some(factor) = InertiaFactor::at(&self.model, q) else {
            self.reject();
            return;
        };
        let now = StepStart {
            q: *q,
            forces,
            factor,
        };
        let (Some(start), Some(filters)) = (self.start.replace(now), self.filters) else {
            self.filters = Some(Filters {
                q: *q,
                p: self.estimate.transformed_momenta,
            });
            self.estimate.velocity = factor.factor * self.estimate.transformed_momenta;
            return;
        };
        match self.step(&start, &filters, q, &factor) {
            Some((estimate, filters)) => {
                self.estimate = estimate;
                self.filters = Some(filters);
            }
            None => self.reject(),
        }
    }

    fn reject(&mut self) {
        self.rejected_updates = self.rejected_updates.saturating_add(1);
        self.start = None;
    }

    /// One step of the innovation form from `start` to the sample `q`
    /// (factored as `now`); `None` if `M(𝐪)` does not factor or a result is
    /// not finite.
    fn step(
        &self,
        start: &StepStart<N>,
        filters: &Filters<N>,
        q: &Vector<N>,
        now: &InertiaFactor<N>,
    ) -> Option<(ScaledMomentaEstimate<N>, Filters<N>)> {
        let ScaledMomentaObserverConfig {
            kappa_per_s: kappa,
            period_s: h,
            disturbance_gain,
            ..
        } = self.config;
        let psi = self.config.psi_per_s();
        let e = &self.estimate;
        let (p_hat, r) = (e.transformed_momenta, e.scaling);
        let at_q = &start.factor;
        let at_filter = InertiaFactor::at(&self.model, &filters.q)?;
        let t = at_q.factor;
        let friction_force = t.transpose() * self.model.friction().component_mul(&(t * p_hat));
        let model_rate = at_q.gyroscopic(&p_hat) * p_hat
            - friction_force
            - t.transpose()
                * (self.model.potential_gradient(&start.q) - start.forces - e.disturbance);
        // ∇_q p_P = H(𝐪, 𝐩).
        let injection = at_filter.injection(psi, &filters.p);
        let dq = q - start.q;
        let innovation = t * p_hat * h - dq;
        let p_next = p_hat + model_rate * h - injection * innovation;
        let disturbance = e.disturbance - (t * p_next * h - dq) * (disturbance_gain / (r * r));
        // The dynamic scaling (40), (46).
        let at_q_p_hat = at_q.injection(psi, &p_hat);
        let at_filter_p_hat = at_filter.injection(psi, &p_hat);
        let delta_q = (at_q_p_hat - at_filter_p_hat) * t;
        let delta_p = (at_filter_p_hat - injection) * t;
        let (sigma_q, sigma_p) = (delta_q.norm_squared(), delta_p.norm_squared());
        let r_next =
            1.0 + math::exp(-psi * h / 4.0) * (r - 1.0) + h * r * (sigma_p + sigma_q) / psi;
        let (e_q, e_p) = (filters.q - start.q, filters.p - p_hat);
        let ratio = |sigma: f32, e: f32| if e > 0.0 { sigma / e } else { 0.0 };
        let t_norm2 = t.norm_squared();
        let scaled = r * (r - 1.0) / psi;
        let psi_1 = 0.5 * r * r * t_norm2 + scaled * ratio(sigma_q, e_q.norm_squared()) + kappa;
        let psi_2 = 0.5 * r * r * injection.norm_squared() * t_norm2
            + scaled * ratio(sigma_p, e_p.norm_squared())
            + kappa;
        let next_filters = Filters {
            q: q + e_q * math::exp(-psi_1 * h) + innovation,
            p: p_next + e_p * math::exp(-psi_2 * h) + injection * innovation,
        };
        let estimate = ScaledMomentaEstimate {
            transformed_momenta: p_next,
            velocity: now.factor * p_next,
            disturbance,
            scaling: r_next,
        };
        let finite = |v: &Vector<N>| v.iter().all(|x| x.is_finite());
        (finite(&p_next)
            && finite(&estimate.velocity)
            && finite(&disturbance)
            && r_next.is_finite()
            && finite(&next_filters.q)
            && finite(&next_filters.p))
        .then_some((estimate, next_filters))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A planar two-link arm, `M(q) = [[a + 2b cos q2, c + b cos q2],
    /// [c + b cos q2, c]]`: its inertia has non-zero curvature, so no factor
    /// with commuting columns exists and `J ≠ 0` for every factor.
    #[derive(Debug, Clone, Copy)]
    struct TwoLinkArm;

    impl InertiaModel<2> for TwoLinkArm {
        type Input = Vector<2>;
        fn inertia(&self, q: &Vector<2>) -> Matrix<2> {
            let c2 = math::cos(q.y);
            Matrix::<2>::new(3.0 + 2.0 * c2, 1.0 + c2, 1.0 + c2, 1.0)
        }
        fn inertia_derivative(&self, q: &Vector<2>, i: usize) -> Matrix<2> {
            let s2 = math::sin(q.y);
            if i == 1 {
                Matrix::<2>::new(-2.0 * s2, -s2, -s2, 0.0)
            } else {
                Matrix::<2>::zeros()
            }
        }
        fn potential_gradient(&self, _q: &Vector<2>) -> Vector<2> {
            Vector::zeros()
        }
        fn input_forces(&self, _q: &Vector<2>, u: &Vector<2>) -> Vector<2> {
            *u
        }
        fn friction(&self) -> Vector<2> {
            Vector::<2>::new(0.1, 0.1)
        }
    }

    #[test]
    fn configuration_is_validated() {
        assert_eq!(
            ScaledMomentaObserverConfig::new(0.0, 0.001),
            Err(MomentaObserverError::Kappa)
        );
        assert_eq!(
            ScaledMomentaObserverConfig::new(1.0, -1.0),
            Err(MomentaObserverError::Period)
        );
        // ψ = 8: h = 0.125 s is the limit.
        assert_eq!(
            ScaledMomentaObserverConfig::new(1.0, 0.125),
            Err(MomentaObserverError::StepTooLong)
        );
        assert!(ScaledMomentaObserverConfig::new(1.0, 0.12).is_ok());
        assert_eq!(
            ScaledMomentaObserverConfig::new(1.0, 0.01)
                .unwrap()
                .with_disturbance_gain(f32::NAN),
            Err(MomentaObserverError::AdaptationGain)
        );
    }

    #[test]
    fn factor_and_its_derivative() {
        let q = Vector::<2>::new(0.3, 0.7);
        let f = InertiaFactor::at(&TwoLinkArm, &q).unwrap();
        let t = f.factor();
        let m = TwoLinkArm.inertia(&q);
        assert!((t * t.transpose() * m - Matrix::<2>::identity()).amax() < 1e-5);
        assert!((t * f.factor_inverse() - Matrix::<2>::identity()).amax() < 1e-5);
        assert!(t.m12 == 0.0, "lower triangular");
        // ∂T/∂q2 by central differences against D_j = Σ_i T_ij ∂T/∂q_i:
        // with ∂T/∂q1 = 0, D_j = T_2j ∂T/∂q2.
        let dq = 1e-2_f32;
        let plus = InertiaFactor::at(&TwoLinkArm, &(q + Vector::<2>::new(0.0, dq))).unwrap();
        let minus = InertiaFactor::at(&TwoLinkArm, &(q - Vector::<2>::new(0.0, dq))).unwrap();
        let numeric = (plus.factor() - minus.factor()) / (2.0 * dq);
        let analytic = f.directional[1] / t.m22;
        assert!((numeric - analytic).amax() < 1e-3, "{numeric} {analytic}");
        assert!((f.directional[0] - analytic * t.m21).amax() < 1e-6);
    }

    #[test]
    fn non_positive_inertia_is_rejected_and_counted() {
        #[derive(Debug, Clone, Copy)]
        struct Broken;
        impl InertiaModel<1> for Broken {
            type Input = f32;
            fn inertia(&self, q: &Vector<1>) -> Matrix<1> {
                Matrix::<1>::new(q.x)
            }
            fn inertia_derivative(&self, _q: &Vector<1>, _i: usize) -> Matrix<1> {
                Matrix::<1>::new(1.0)
            }
            fn potential_gradient(&self, _q: &Vector<1>) -> Vector<1> {
                Vector::zeros()
            }
            fn input_forces(&self, _q: &Vector<1>, u: &f32) -> Vector<1> {
                Vector::<1>::new(*u)
            }
            fn friction(&self) -> Vector<1> {
                Vector::zeros()
            }
        }
        let cfg = ScaledMomentaObserverConfig::new(1.0, 0.01).unwrap();
        let mut obs = ScaledMomentaObserver::new(Broken, cfg, Vector::zeros(), Vector::zeros());
        obs.update(&Vector::<1>::new(1.0), &0.0);
        obs.update(&Vector::<1>::new(-1.0), &0.0);
        obs.update(&Vector::<1>::new(f32::NAN), &0.0);
        obs.update(&Vector::<1>::new(1.0), &f32::INFINITY);
        assert_eq!(obs.rejected_updates(), 3);
        assert!(obs.estimate().transformed_momenta.x.is_finite());
    }

    proptest! {
        /// `J(q, p)` is skew-symmetric and (P.ii) `J(q, p) p̄ = J̄(q, p̄) p`.
        #[test]
        fn gyroscopic_properties(
            q in proptest::array::uniform2(-3.0f32..3.0),
            p in proptest::array::uniform2(-5.0f32..5.0),
            p_bar in proptest::array::uniform2(-5.0f32..5.0),
        ) {
            let f = InertiaFactor::at(&TwoLinkArm, &Vector::<2>::from(q)).unwrap();
            let (p, p_bar) = (Vector::<2>::from(p), Vector::<2>::from(p_bar));
            let j = f.gyroscopic(&p);
            prop_assert!((j + j.transpose()).amax() < 1e-4);
            let lhs = j * p_bar;
            let rhs = f.gyroscopic_bar(&p_bar) * p;
            prop_assert!((lhs - rhs).amax() < 1e-3 * (1.0 + lhs.amax()), "{} {}", lhs, rhs);
        }

        /// Finite inputs give finite estimates and the scaling factor
        /// never drops below 1.
        #[test]
        fn scaling_stays_at_least_one(
            qs in proptest::collection::vec(proptest::array::uniform2(-1e2f32..1e2), 1..30),
            u in proptest::array::uniform2(-50f32..50.0),
            p0 in proptest::array::uniform2(-1e2f32..1e2),
            kappa in 0.01f32..20.0,
        ) {
            let cfg = ScaledMomentaObserverConfig::new(kappa, 0.001).unwrap();
            let mut obs = ScaledMomentaObserver::new(
                TwoLinkArm, cfg, Vector::<2>::from(p0), Vector::zeros());
            for q in &qs {
                obs.update(&Vector::<2>::from(*q), &Vector::<2>::from(u));
                let e = obs.estimate();
                prop_assert!(e.scaling >= 1.0, "{}", e.scaling);
                prop_assert!(e.velocity.iter().all(|x| x.is_finite()));
                prop_assert!(e.disturbance.iter().all(|x| x.is_finite()));
            }
        }
    }
}
