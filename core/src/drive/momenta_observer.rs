//! The adaptive momenta observer of paper 003 (Romero & Ortega, *Two
//! globally convergent adaptive speed observers for mechanical systems*),
//! Proposition 1 (section 4.3), with its constant-inertia case (section 6.1).
//!
//! It estimates the velocities of a mechanical system from its positions
//! alone while rejecting unknown constant disturbances `d` and identifying
//! unknown viscous friction coefficients. On a wheeled robot written in its
//! wheel angles (constant inertia, [`WheelInertia`]) that is: clean wheel
//! speeds, the load torque on each wheel and the wheel friction, from the
//! encoder angles.
//!
//! # System (1)–(7)
//! `q̇ = M⁻¹(q) 𝐩`, `𝐩̇ = −∇V − ℜ q̇ + G(q)u + d` with `ℜ = diag(r_i)` (the
//! paper calls it Coulomb friction; as `ℜ q̇` it is viscous). With a
//! factor `M⁻¹ = T Tᵀ` (4) whose columns commute (Assumption 4.1, (8)) and
//! `p = Tᵀ𝐩`, the gyroscopic term `J` of (5)–(6) vanishes:
//! `q̇ = T p`, `ṗ = −Tᵀ(∇V − Gu − d) − R p`, `R = TᵀℜT` (7). A map `Q`
//! with `∇Q = T⁻¹` (9) exists. The friction coefficients at the
//! coordinates `κ` are unknown (Assumption 4.2: those rows `t_k` of `T` are
//! constant), the others known (`ℜ_k`).
//!
//! # Observer (Proposition 1), as derived from its proof
//! ```text
//! p̂ = p_I + λ Q(q)          d̂ = d_I + q          r̂_j = r_I,j − (t_κj·p̂)²/(2λ)
//! Φ(p̂) = [t_κ1 (t_κ1·p̂) … t_κs (t_κs·p̂)]          (R_u p̂ = Φ(p̂) r_u, (11))
//! ṗ_I = −Tᵀ(∇V − Gu − d̂) − Φ(p̂) r̂ − λ p̂ − Tᵀℜ_k T p̂        (21)
//! ṙ_I = (1/λ) Φ(p̂)ᵀ (ṗ_I + λ p̂)                            (after (22))
//! ḋ_I = −T p̂                                                (after (23))
//! ```
//! The errors `p̃ = p̂ − p`, `r̃ = r̂ − r_u`, `d̃ = d̂ − d` obey
//! `p̃̇ = −(R + λI)p̃ − Φ r̃ + Tᵀd̃`, `r̃̇ = Φᵀp̃`, `d̃̇ = −T p̃` (22)–(24), so
//! `V = ½(|p̃|² + |r̃|² + |d̃|²)` (25) has `V̇ = −p̃ᵀ(R + λI)p̃ ≤ −λ|p̃|²`
//! (28): `p̃ → 0` for every initial condition; `r̃, d̃` stay bounded and
//! converge when the motion is persistently exciting.
//!
//! Printed slips (each checked against the proof): the proposition's
//! `ṗ_I` has `λQ(q)` for `λ I_n` (the proof's `∇p_P T p̂ = λ T⁻¹T p̂`);
//! `ṙ_uI` lacks the `1/λ` of `∇r_uP` (27); `ḋ_I = T p̂` has the wrong sign
//! (the proof's `ḋ_I = −∇d_P T p̂`); the `L_i` in `r̂_u` are those of (29),
//! the negatives of (15)'s, hence the minus sign above with (15)'s
//! `L_k = t_k t_kᵀ`.
//!
//! # Adaptation gains
//! The paper's Lyapunov function (25) weighs the three errors equally,
//! which fixes the adaptation speeds in the transformed coordinates. With
//! `V = ½(|p̃|² + r̃ᵀr̃/γ_r + d̃ᵀd̃/γ_d)` the same proof holds for
//! `r̃̇ = γ_r Φᵀp̃`, `d̃̇ = −γ_d T p̃` and any `γ_r, γ_d > 0`
//! ([`MomentaObserverConfig::with_adaptation_gains`]; the paper's are 1).
//! They matter on small machines: a robot's wheels have `T ~ M^{−½}` of
//! order 20, so `Φ = t_k t_kᵀp̂` couples `p̃` and `r̃` at hundreds of rad/s
//! with unit gains, far beyond what a 10 ms step can follow.
//!
//! # Discretization: innovation form
//! The I&I states `(p_I, r_I, d_I)` exist so that `q̇` is never
//! differentiated; in continuous time the observer above is exactly
//! `p̂̇ = f + λ(p − p̂)`, `r̂̇ = γ_r Φ(p̂)ᵀ(p̂ − p)`, `d̂̇ = −γ_d(T p̂ − q̇)` with
//! `f = −Tᵀ(∇V − Gu − d̂) − Φ(p̂) r̂ − Tᵀℜ_k T p̂`, where `p` and `q̇` appear
//! only integrated. A sampled observer has their integrals over a step:
//! `ΔQ = Q(q⁺) − Q(q) = ∫p` and `Δq = ∫T p`. Per step of length `h`, with
//! `u` held and `T, ∇V, Φ` at the step's start:
//!
//! ```text
//! p̂⁺ = p̂ + h f + λ(ΔQ − h p̂)
//! ν  = h p̂⁺ − ΔQ                            (≈ h p̃)
//! r̂⁺ = r̂ + γ_r Φ(p̂⁺)ᵀ ν                    d̂⁺ = d̂ − γ_d (h T p̂⁺ − Δq)
//! ```
//!
//! The parameters are updated with the new `p̂⁺` (symplectic Euler): the
//! skew coupling of `p̃` with `r̃, d̃` then keeps its energy instead of
//! gaining `1 + (hω)²` per step as with forward Euler, and `λ` damps it;
//! stability needs `h(λ + |R|) < 1` and `hω < 2` for the coupling
//! frequencies `ω ~ √γ_d |T|`, `√γ_r |Φ|`. The increments are exact, the
//! rest is first order: the estimates carry an `O(h)` bias (about
//! `h|ṗ̇|/λ` in `p̃` on the crane of section 6.3). Because `d̂` is kept
//! directly (not as `d_I + q`), only position differences enter and a
//! wheel angle may grow for ever without losing `d̂`'s resolution.
//!
//! # Bad input
//! A non-finite `q` or input force, or a non-finite result, is counted
//! (`rejected_updates`), leaves the estimates unchanged and restarts the
//! step (the next valid sample only records its start).
//!
//! The matrix algebra is nalgebra's (`no_std`); its Cholesky factorisation
//! (with `libm`'s `sqrt`) runs only at construction.

use nalgebra::{SMatrix, SVector};

use crate::plausible::{
    GAIN, MASS_KG, PERIOD_S, TORQUE_NM, TRACK_WIDTH_M, WHEEL_INERTIA_KG_M2, WHEEL_RADIUS_M,
    WHEEL_SPEED_RAD_S, YAW_INERTIA_KG_M2,
};

/// A vector of `N` generalised coordinates (or forces, momenta).
pub type Vector<const N: usize> = SVector<f32, N>;
/// An `N × N` matrix.
pub type Matrix<const N: usize> = SMatrix<f32, N, N>;

/// A mechanical system (1)–(2) that satisfies Assumption 4.1, as
/// Proposition 1 needs it.
pub trait MechanicalModel<const N: usize> {
    /// The control input `u`.
    type Input: Copy;
    /// `T(q)`, a factor `M⁻¹(q) = T Tᵀ` whose columns commute (8).
    fn inverse_inertia_factor(&self, q: &Vector<N>) -> Matrix<N>;
    /// `Q(q)` with `∇Q = T⁻¹(q)` (9).
    fn flat_coordinates(&self, q: &Vector<N>) -> Vector<N>;
    /// `∇V(q)`, the potential forces.
    fn potential_gradient(&self, q: &Vector<N>) -> Vector<N>;
    /// `G(q) u`, the generalised forces of the input.
    fn input_forces(&self, q: &Vector<N>, u: &Self::Input) -> Vector<N>;
    /// The known friction coefficients `ℜ_k` (diagonal); the entries at the
    /// unknown coordinates are ignored.
    fn known_friction(&self) -> Vector<N>;
}

/// Why an observer or model configuration was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum MomentaObserverError {
    /// `λ` (1/s) not finite and positive.
    Lambda,
    /// Step `h` not finite and positive.
    Period,
    /// `κ` (1/s, Proposition 2) not finite and positive.
    Kappa,
    /// The initial scaling factor `r(0)` of Proposition 2 is not finite
    /// and at least 1.
    Scaling,
    /// The step is too long for the gains: Proposition 2 needs `h·ψ < 1`
    /// with `ψ = 4(1 + κ)`.
    StepTooLong,
    /// An adaptation gain `γ_r`, `γ_d` not finite and positive.
    AdaptationGain,
    /// An unknown-friction coordinate index is `≥ N`.
    FrictionIndex,
    /// The same coordinate is listed twice as having unknown friction.
    DuplicateFrictionIndex,
    /// The inertia matrix is not finite, symmetric and positive definite.
    Inertia,
    /// A friction coefficient is negative or not finite.
    Friction,
    /// A physical parameter (mass, length, inertia) is not finite and
    /// positive (or, for the wheel inertia, negative).
    Parameter,
}

impl core::fmt::Display for MomentaObserverError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::Lambda => return write!(f, "lambda_per_s (λ) must be in {GAIN} 1/s"),
            Self::Period => return write!(f, "period_s (h) must be in {PERIOD_S} s"),
            Self::Kappa => "kappa_per_s (κ) must be finite and > 0 1/s",
            Self::Scaling => "the initial scaling factor r(0) must be finite and ≥ 1",
            Self::StepTooLong => "the step is too long for the gains: Proposition 2 needs h·ψ < 1 with ψ = 4(1 + κ)",
            Self::AdaptationGain => {
                return write!(
                    f,
                    "the adaptation gains γ_r, γ_d (friction_gain, disturbance_gain) must each be in {GAIN}"
                );
            }
            Self::FrictionIndex => "an unknown-friction coordinate index must be < N",
            Self::DuplicateFrictionIndex => "an unknown-friction coordinate is listed twice",
            Self::Inertia => "the inertia matrix must be finite, symmetric and positive definite",
            Self::Friction => "a friction coefficient must be finite and ≥ 0",
            Self::Parameter => {
                return write!(
                    f,
                    "a physical parameter out of range: mass_kg must be in {MASS_KG} kg, \
                     yaw_inertia_kg_m2 in {YAW_INERTIA_KG_M2} kg m², wheel_inertia_kg_m2 in \
                     {WHEEL_INERTIA_KG_M2} kg m², wheel_radius_m in {WHEEL_RADIUS_M} m, \
                     track_width_m in {TRACK_WIDTH_M} m, stall_torque_nm in {TORQUE_NM} N·m, \
                     no_load_speed_rad_s in {WHEEL_SPEED_RAD_S} rad/s"
                );
            }
        })
    }
}

impl core::error::Error for MomentaObserverError {}

/// Validated gains of a [`MomentaObserver`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MomentaObserverConfig<const S: usize> {
    lambda_per_s: f32,
    period_s: f32,
    unknown_friction: [usize; S],
    friction_gain: f32,
    disturbance_gain: f32,
}

impl<const S: usize> MomentaObserverConfig<S> {
    /// `λ` (1/s), the step `h` (s), and the `S` coordinates whose friction
    /// is unknown and identified (their rows of `T` must be constant,
    /// Assumption 4.2; any coordinates with constant inertia). `N` is the
    /// number of degrees of freedom the indices are checked against.
    ///
    /// # Errors
    /// The first parameter out of range.
    pub fn new<const N: usize>(
        lambda_per_s: f32,
        period_s: f32,
        unknown_friction: [usize; S],
    ) -> Result<Self, MomentaObserverError> {
        if !GAIN.contains(lambda_per_s) {
            return Err(MomentaObserverError::Lambda);
        }
        if !PERIOD_S.contains(period_s) {
            return Err(MomentaObserverError::Period);
        }
        for (i, &k) in unknown_friction.iter().enumerate() {
            if k >= N {
                return Err(MomentaObserverError::FrictionIndex);
            }
            if unknown_friction.iter().skip(i + 1).any(|&other| other == k) {
                return Err(MomentaObserverError::DuplicateFrictionIndex);
            }
        }
        Ok(Self {
            lambda_per_s,
            period_s,
            unknown_friction,
            friction_gain: 1.0,
            disturbance_gain: 1.0,
        })
    }

    /// The adaptation gains `γ_r` (friction) and `γ_d` (disturbance), both
    /// 1 by default as in the paper (module docs).
    ///
    /// # Errors
    /// [`MomentaObserverError::AdaptationGain`] unless both are in
    /// [`GAIN`].
    pub fn with_adaptation_gains(
        self,
        friction_gain: f32,
        disturbance_gain: f32,
    ) -> Result<Self, MomentaObserverError> {
        if !(GAIN.contains(friction_gain) && GAIN.contains(disturbance_gain)) {
            return Err(MomentaObserverError::AdaptationGain);
        }
        Ok(Self {
            friction_gain,
            disturbance_gain,
            ..self
        })
    }

    /// `λ`, 1/s.
    #[must_use]
    pub fn lambda_per_s(&self) -> f32 {
        self.lambda_per_s
    }

    /// The step `h`, s.
    #[must_use]
    pub fn period_s(&self) -> f32 {
        self.period_s
    }
}

/// What the observer keeps of the start of the current step: the sample
/// and, once [`MomentaObserver::apply`] gave it, the input force held over
/// the step.
#[derive(Debug, Clone, Copy, PartialEq)]
struct StepStart<const N: usize> {
    q: Vector<N>,
    forces: Option<Vector<N>>,
}

/// The estimates at the last accepted sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MomentaEstimate<const N: usize, const S: usize> {
    /// `p̂ = Tᵀ𝐩̂`, the transformed momenta.
    pub transformed_momenta: Vector<N>,
    /// `q̇̂ = T(q) p̂`, the velocities (rad/s for angles).
    pub velocity: Vector<N>,
    /// `d̂`, the constant disturbance forces (N·m for wheel torques).
    pub disturbance: Vector<N>,
    /// `r̂_u`, the unknown friction coefficients, in the order configured.
    pub friction: SVector<f32, S>,
}

impl<const N: usize, const S: usize> MomentaEstimate<N, S> {
    fn is_finite(&self) -> bool {
        self.transformed_momenta.iter().all(|x| x.is_finite())
            && self.velocity.iter().all(|x| x.is_finite())
            && self.disturbance.iter().all(|x| x.is_finite())
            && self.friction.iter().all(|x| x.is_finite())
    }
}

/// Proposition 1's observer for a model `M` with `N` degrees of freedom and
/// `S` unknown friction coefficients, in the innovation form of the module
/// docs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MomentaObserver<Model, const N: usize, const S: usize>
where
    Model: MechanicalModel<N>,
{
    model: Model,
    config: MomentaObserverConfig<S>,
    start: Option<StepStart<N>>,
    estimate: MomentaEstimate<N, S>,
    rejected_updates: u32,
}

impl<Model, const N: usize, const S: usize> MomentaObserver<Model, N, S>
where
    Model: MechanicalModel<N>,
{
    /// An observer starting from `p̂ = p̂₀`, `d̂ = d̂₀`, `r̂ = r̂₀`
    /// (non-finite entries are taken as 0).
    #[must_use]
    pub fn new(
        model: Model,
        config: MomentaObserverConfig<S>,
        momenta_0: Vector<N>,
        disturbance_0: Vector<N>,
        friction_0: SVector<f32, S>,
    ) -> Self {
        let clean = |x: f32| if x.is_finite() { x } else { 0.0 };
        let estimate = MomentaEstimate {
            transformed_momenta: momenta_0.map(clean),
            velocity: Vector::zeros(),
            disturbance: disturbance_0.map(clean),
            friction: friction_0.map(clean),
        };
        Self {
            model,
            config,
            start: None,
            estimate,
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
    pub fn config(&self) -> &MomentaObserverConfig<S> {
        &self.config
    }

    /// The estimates at the last accepted sample (the initial guesses until
    /// the first sample; the velocity is 0 until then).
    #[must_use]
    pub fn estimate(&self) -> &MomentaEstimate<N, S> {
        &self.estimate
    }

    /// Samples skipped for non-finite input or result.
    #[must_use]
    pub fn rejected_updates(&self) -> u32 {
        self.rejected_updates
    }

    /// Shifts the position origin by `offset` (e.g. after many wheel turns,
    /// to keep `q⁺ − q` within `f32` resolution): give the next samples as
    /// `q − offset`. Exact for models whose `Q` is linear in `q` (constant
    /// inertia).
    pub fn rebase(&mut self, offset: &Vector<N>) {
        if !offset.iter().all(|x| x.is_finite()) {
            self.rejected_updates = self.rejected_updates.saturating_add(1);
            return;
        }
        if let Some(start) = self.start.as_mut() {
            start.q -= offset;
        }
    }

    /// One sample: the positions `q` measured now and the input `u` that
    /// will be applied until the next sample ([`Self::measure`] then
    /// [`Self::apply`]).
    pub fn update(&mut self, q: &Vector<N>, u: &Model::Input) {
        self.measure(q);
        self.apply(u);
    }

    /// The positions `q` measured now: completes the step since the last
    /// sample (if its input was given) and starts the next one. A loop that
    /// needs the new estimate to choose its input calls this, then
    /// [`Self::apply`].
    pub fn measure(&mut self, q: &Vector<N>) {
        if !q.iter().all(|x| x.is_finite()) {
            self.reject();
            return;
        }
        let now = StepStart {
            q: *q,
            forces: None,
        };
        match self.start.replace(now) {
            Some(StepStart {
                q: start_q,
                forces: Some(forces),
            }) => {
                let next = self.step(&start_q, &forces, q);
                if next.is_finite() {
                    self.estimate = next;
                } else {
                    self.reject();
                }
            }
            _ => {
                let t = self.model.inverse_inertia_factor(q);
                self.estimate.velocity = t * self.estimate.transformed_momenta;
            }
        }
    }

    /// The input `u` applied from the last [`Self::measure`] until the
    /// next. Without a sample to start from it is ignored.
    pub fn apply(&mut self, u: &Model::Input) {
        let Some(start) = self.start.as_mut() else {
            return;
        };
        let forces = self.model.input_forces(&start.q, u);
        if forces.iter().all(|x| x.is_finite()) {
            start.forces = Some(forces);
        } else {
            self.reject();
        }
    }

    /// Forgets the current step (a missed sample, or an input not known):
    /// the next [`Self::measure`] only starts a new step. The estimates are
    /// kept.
    pub fn restart(&mut self) {
        self.start = None;
    }

    fn reject(&mut self) {
        self.rejected_updates = self.rejected_updates.saturating_add(1);
        self.start = None;
    }

    /// One step of the innovation form from `start_q` (input forces
    /// `forces` held) to the sample `q`.
    fn step(
        &self,
        start_q: &Vector<N>,
        forces: &Vector<N>,
        q: &Vector<N>,
    ) -> MomentaEstimate<N, S> {
        let MomentaObserverConfig {
            lambda_per_s: lambda,
            period_s: h,
            unknown_friction,
            friction_gain,
            disturbance_gain,
        } = self.config;
        let e = &self.estimate;
        let t = self.model.inverse_inertia_factor(start_q);
        let p_hat = e.transformed_momenta;
        // Φ(p̂) r̂ = Σ_j t_κj (t_κj·p̂) r̂_j.
        let mut friction_force = Vector::<N>::zeros();
        for (&k, &r) in unknown_friction.iter().zip(e.friction.iter()) {
            friction_force += row(&t, k) * (row_dot(&t, k, &p_hat) * r);
        }
        let mut known = self.model.known_friction();
        for &k in &unknown_friction {
            if let Some(x) = known.get_mut(k) {
                *x = 0.0;
            }
        }
        let known_friction_force = t.transpose() * known.component_mul(&(t * p_hat));
        let model_rate = -(t.transpose()
            * (self.model.potential_gradient(start_q) - *forces - e.disturbance))
            - friction_force
            - known_friction_force;
        let flat_increment = self.model.flat_coordinates(q) - self.model.flat_coordinates(start_q);
        let p_next = p_hat + model_rate * h + (flat_increment - p_hat * h) * lambda;
        let innovation = p_next * h - flat_increment;
        let friction =
            SVector::<f32, S>::from_iterator(unknown_friction.iter().zip(e.friction.iter()).map(
                |(&k, &r)| {
                    r + friction_gain * row_dot(&t, k, &p_next) * row_dot(&t, k, &innovation)
                },
            ));
        let disturbance = e.disturbance - ((t * p_next) * h - (q - start_q)) * disturbance_gain;
        MomentaEstimate {
            transformed_momenta: p_next,
            velocity: self.model.inverse_inertia_factor(q) * p_next,
            disturbance,
            friction,
        }
    }
}

/// Row `k` of `t` as a column vector (zero if out of range; indices are
/// validated at construction).
fn row<const N: usize>(t: &Matrix<N>, k: usize) -> Vector<N> {
    if k < N {
        t.row(k).transpose()
    } else {
        Vector::zeros()
    }
}

/// `t_k · v` for row `k` of `t`.
fn row_dot<const N: usize>(t: &Matrix<N>, k: usize, v: &Vector<N>) -> f32 {
    row(t, k).dot(v)
}

/// A system with constant inertia `M`, no potential, `G = I` (the input is
/// the generalised force) and known friction (section 6.1): `T` is the
/// constant factor `L⁻ᵀ` of the Cholesky factorisation `M = L Lᵀ`, and
/// `Q(q) = T⁻¹q = Lᵀq`. Every friction coefficient may be unknown.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConstantInertia<const N: usize> {
    factor: Matrix<N>,
    factor_inverse: Matrix<N>,
    friction: Vector<N>,
}

impl<const N: usize> ConstantInertia<N> {
    /// From the inertia matrix (symmetric positive definite) and the known
    /// viscous friction coefficients (≥ 0; entries identified by the
    /// observer are ignored).
    ///
    /// # Errors
    /// [`MomentaObserverError::Inertia`] or [`MomentaObserverError::Friction`].
    pub fn new(inertia: Matrix<N>, friction: Vector<N>) -> Result<Self, MomentaObserverError> {
        if !inertia.iter().all(|x| x.is_finite())
            || (inertia - inertia.transpose()).amax() > 1e-6 * inertia.amax()
        {
            return Err(MomentaObserverError::Inertia);
        }
        if !friction.iter().all(|&r| r.is_finite() && r >= 0.0) {
            return Err(MomentaObserverError::Friction);
        }
        let cholesky = nalgebra::Cholesky::new(inertia).ok_or(MomentaObserverError::Inertia)?;
        let lower = cholesky.l();
        let lower_inverse = lower
            .solve_lower_triangular(&Matrix::<N>::identity())
            .ok_or(MomentaObserverError::Inertia)?;
        let factor = lower_inverse.transpose();
        if !factor.iter().all(|x| x.is_finite()) {
            return Err(MomentaObserverError::Inertia);
        }
        Ok(Self {
            factor,
            factor_inverse: lower.transpose(),
            friction,
        })
    }

    /// The constant factor `T` (`M⁻¹ = T Tᵀ`).
    #[must_use]
    pub fn factor(&self) -> &Matrix<N> {
        &self.factor
    }
}

impl<const N: usize> MechanicalModel<N> for ConstantInertia<N> {
    type Input = Vector<N>;

    fn inverse_inertia_factor(&self, _q: &Vector<N>) -> Matrix<N> {
        self.factor
    }

    fn flat_coordinates(&self, q: &Vector<N>) -> Vector<N> {
        self.factor_inverse * q
    }

    fn potential_gradient(&self, _q: &Vector<N>) -> Vector<N> {
        Vector::zeros()
    }

    fn input_forces(&self, _q: &Vector<N>, u: &Vector<N>) -> Vector<N> {
        *u
    }

    fn known_friction(&self) -> Vector<N> {
        self.friction
    }
}

/// The differential-drive robot written in its wheel angles
/// `q = (φ_right, φ_left)` (paper 003 section 6.1): with `v = r(φ̇_R + φ̇_L)/2`
/// and `ω = r(φ̇_R − φ̇_L)/b`, the kinetic energy
/// `½m v² + ½I_z ω² + ½I_w(φ̇_R² + φ̇_L²)` gives the constant inertia
///
/// ```text
/// M = [[m r²/4 + I_z r²/b² + I_w,  m r²/4 − I_z r²/b²      ],
///      [m r²/4 − I_z r²/b²,        m r²/4 + I_z r²/b² + I_w]]   (kg m²)
/// ```
///
/// with the wheels rolling without slip, the motor torques as the input
/// (`G = I`, N·m at the wheel) and the viscous friction of each wheel's
/// drive train in `ℜ`. A slope or a drag acts as a constant load torque `d`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WheelInertia {
    mass_kg: f32,
    yaw_inertia_kg_m2: f32,
    wheel_radius_m: f32,
    track_width_m: f32,
    wheel_inertia_kg_m2: f32,
}

impl WheelInertia {
    /// Mass `m` (kg), yaw inertia `I_z` about the axle midpoint (kg m²),
    /// wheel radius `r` (m), track width `b` (m), and each wheel's own
    /// inertia with its motor and gearbox reflected to the wheel `I_w`
    /// (kg m², may be 0).
    ///
    /// # Errors
    /// [`MomentaObserverError::Parameter`] for a value outside its range
    /// ([`crate::plausible`]).
    pub fn new(
        mass_kg: f32,
        yaw_inertia_kg_m2: f32,
        wheel_radius_m: f32,
        track_width_m: f32,
        wheel_inertia_kg_m2: f32,
    ) -> Result<Self, MomentaObserverError> {
        if !(MASS_KG.contains(mass_kg)
            && YAW_INERTIA_KG_M2.contains(yaw_inertia_kg_m2)
            && WHEEL_RADIUS_M.contains(wheel_radius_m)
            && TRACK_WIDTH_M.contains(track_width_m)
            && WHEEL_INERTIA_KG_M2.contains(wheel_inertia_kg_m2))
        {
            return Err(MomentaObserverError::Parameter);
        }
        Ok(Self {
            mass_kg,
            yaw_inertia_kg_m2,
            wheel_radius_m,
            track_width_m,
            wheel_inertia_kg_m2,
        })
    }

    /// The inertia matrix `M` of the wheel angles, kg m².
    #[must_use]
    pub fn matrix(&self) -> Matrix<2> {
        let r2 = self.wheel_radius_m * self.wheel_radius_m;
        let translation = self.mass_kg * r2 / 4.0;
        let rotation = self.yaw_inertia_kg_m2 * r2 / (self.track_width_m * self.track_width_m);
        let diagonal = translation + rotation + self.wheel_inertia_kg_m2;
        let off = translation - rotation;
        Matrix::<2>::new(diagonal, off, off, diagonal)
    }

    /// The model for the observer, with the known friction of each wheel
    /// (N·m·s/rad; entries the observer identifies are ignored).
    ///
    /// # Errors
    /// [`MomentaObserverError::Friction`] (the matrix is positive definite
    /// by construction).
    pub fn model(&self, friction: Vector<2>) -> Result<ConstantInertia<2>, MomentaObserverError> {
        ConstantInertia::new(self.matrix(), friction)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn robot() -> WheelInertia {
        WheelInertia::new(4.0, 0.08, 0.035, 0.2, 2e-4).unwrap()
    }

    #[test]
    fn configuration_is_validated() {
        assert_eq!(
            MomentaObserverConfig::new::<2>(0.0, 0.01, [0]),
            Err(MomentaObserverError::Lambda)
        );
        assert_eq!(
            MomentaObserverConfig::new::<2>(1.0, f32::NAN, [0]),
            Err(MomentaObserverError::Period)
        );
        assert_eq!(
            MomentaObserverConfig::new::<2>(1.0, 0.01, [2]),
            Err(MomentaObserverError::FrictionIndex)
        );
        assert_eq!(
            MomentaObserverConfig::new::<2>(1.0, 0.01, [1, 1]),
            Err(MomentaObserverError::DuplicateFrictionIndex)
        );
        let not_pd = Matrix::<2>::new(1.0, 2.0, 2.0, 1.0);
        assert_eq!(
            ConstantInertia::new(not_pd, Vector::zeros()),
            Err(MomentaObserverError::Inertia)
        );
        let asymmetric = Matrix::<2>::new(1.0, 0.5, 0.0, 1.0);
        assert_eq!(
            ConstantInertia::new(asymmetric, Vector::zeros()),
            Err(MomentaObserverError::Inertia)
        );
        assert_eq!(
            robot().model(Vector::<2>::new(-1.0, 0.0)),
            Err(MomentaObserverError::Friction)
        );
        assert_eq!(
            WheelInertia::new(4.0, 0.08, 0.0, 0.2, 0.0),
            Err(MomentaObserverError::Parameter)
        );
    }

    #[test]
    fn factor_inverts_the_inertia() {
        let model = robot().model(Vector::zeros()).unwrap();
        let t = model.factor();
        let m = robot().matrix();
        let residual = (t * t.transpose() * m - Matrix::<2>::identity()).amax();
        assert!(residual < 1e-4, "{residual}");
        // ∇Q = T⁻¹ (9): Q is linear with matrix T⁻¹.
        let q = Vector::<2>::new(0.3, -1.2);
        let back = t * model.flat_coordinates(&q);
        assert!((back - q).amax() < 1e-5);
    }

    #[test]
    fn non_finite_input_is_counted_and_ignored() {
        let model = robot().model(Vector::zeros()).unwrap();
        let cfg = MomentaObserverConfig::new::<2>(5.0, 0.01, [0, 1]).unwrap();
        let mut obs = MomentaObserver::new(
            model,
            cfg,
            Vector::zeros(),
            Vector::zeros(),
            SVector::zeros(),
        );
        obs.update(&Vector::zeros(), &Vector::zeros());
        let before = *obs.estimate();
        obs.update(&Vector::<2>::new(f32::NAN, 0.0), &Vector::zeros());
        obs.update(&Vector::zeros(), &Vector::<2>::new(0.0, f32::INFINITY));
        assert_eq!(obs.rejected_updates(), 2);
        assert_eq!(*obs.estimate(), before);
    }

    /// A wheel pair spinning at constant speed against a known load:
    /// the velocity estimate converges to the true speeds.
    #[test]
    fn converges_on_constant_speed() {
        let inertia = robot();
        let friction = Vector::<2>::new(0.01, 0.01);
        let model = inertia.model(friction).unwrap();
        let cfg = MomentaObserverConfig::new::<2>(5.0, 0.001, [0, 1]).unwrap();
        let mut obs = MomentaObserver::new(
            model,
            cfg,
            Vector::zeros(),
            Vector::zeros(),
            SVector::from([0.01, 0.01]),
        );
        let speed = Vector::<2>::new(3.0, 2.0);
        // Torque that holds the speed against the friction: τ = ℜ q̇.
        let torque = friction.component_mul(&speed);
        for k in 0..20_000u16 {
            let q = speed * (f32::from(k) * 0.001);
            obs.update(&q, &torque);
        }
        let err = (obs.estimate().velocity - speed).amax();
        assert!(err < 1e-2, "{:?}", obs.estimate());
    }

    proptest! {
        /// Finite inputs never give a non-finite estimate.
        #[test]
        fn finite_in_finite_out(
            qs in proptest::collection::vec(proptest::array::uniform2(-1e3f32..1e3), 1..20),
            us in proptest::array::uniform2(-1e2f32..1e2),
            lambda in 0.01f32..100.0,
        ) {
            let model = robot().model(Vector::<2>::new(0.01, 0.02)).unwrap();
            let cfg = MomentaObserverConfig::new::<2>(lambda, 0.01, [0]).unwrap();
            let mut obs = MomentaObserver::new(
                model, cfg, Vector::zeros(), Vector::zeros(), SVector::zeros());
            for q in &qs {
                obs.update(&Vector::<2>::from(*q), &Vector::<2>::from(us));
                let e = obs.estimate();
                prop_assert!(e.velocity.iter().all(|x| x.is_finite()));
                prop_assert!(e.friction.iter().all(|x| x.is_finite()));
            }
        }
    }
}
