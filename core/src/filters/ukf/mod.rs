//! A generic unscented Kalman filter (paper 004, Iossaqui, Camino &
//! Zampieri, *nonlinear filters for tracked robots under slip*, "The UKF
//! algorithm"): `N` states, `M` measurements, additive process and
//! measurement noise, Van der Merwe's scaled sigma points. It follows
//! **FilterPy 1.4.5** (`UnscentedKalmanFilter` with
//! `MerweScaledSigmaPoints`) step for step; `host-tests/tests/ukf_filterpy.rs`
//! checks it against FilterPy's own output.
//!
//! # Sigma points and weights (the paper's UKF section)
//! ```text
//! λ = α²(n + κ) − n        γ = √(n + λ)
//! X = [x,  x + γ√P,  x − γ√P]                      (2n + 1 points)
//! W₀ᵐ = λ/(n + λ)    W₀ᶜ = λ/(n + λ) + (1 − α² + β)    Wᵢᵐ = Wᵢᶜ = 1/(2(n + λ))
//! ```
//! The paper uses `α = 0.01, β = 2, κ = 0` ([`MerweScaledSigmaPoints`]).
//!
//! `√P` is FilterPy's: `scipy.linalg.cholesky((λ + n)P)` returns the upper
//! factor `U` (`(λ + n)P = UᵀU`) and FilterPy takes its **rows**:
//! `σ_{k+1} = x + U[k]`, `σ_{n+k+1} = x − U[k]`, `k = 0 … n−1`. A row of
//! `U` is a column of the lower factor `L = Uᵀ` (`(λ + n)P = LLᵀ`), which is
//! what this module computes (nalgebra's Cholesky, lower triangle):
//! with `Lₖ` its columns, `Σₖ LₖLₖᵀ = LLᵀ = (λ + n)P`. The rows of `L` (the
//! columns of `U`), which a port built on a lower-triangular Cholesky such
//! as numpy's may take by mistake, are not a square root of `P` (their
//! outer products sum to `LᵀL`): on the conformance fixtures that filter
//! ends up 0.06 to 0.9 standard deviations away from FilterPy's.
//!
//! # Time update ([`UnscentedKalmanFilter::predict`])
//! Sigma points of the posterior `(x, P)`, each propagated through the true
//! nonlinear `f` ([`UkfModel::transition`], FilterPy's `fx`) into `σf`,
//! then the unscented transform with the model's hooks:
//! ```text
//! x⁻ = mean_x(σf, Wᵐ)         P⁻ = Σᵢ Wᵢᶜ r(σfᵢ, x⁻) r(σfᵢ, x⁻)ᵀ + Q
//! ```
//! with `mean_x` the state mean (`x_mean_fn`) and `r` the state residual
//! (`residual_x`) of [`UkfModel::angles`].
//!
//! # Measurement update ([`UnscentedKalmanFilter::update`])
//! As in FilterPy 1.4.5, the update **reuses the propagated points `σf`**
//! of the last predict (it does not draw new sigma points from `(x⁻, P⁻)`;
//! FilterPy changed that after 1.4.5):
//! ```text
//! σhᵢ = h(σfᵢ)                ŷ = mean_z(σh, Wᵐ)
//! S = Pyy = Σᵢ Wᵢᶜ rz(σhᵢ, ŷ) rz(σhᵢ, ŷ)ᵀ + R
//! Pxy = Σᵢ Wᵢᶜ r(σfᵢ, x⁻) rz(σhᵢ, ŷ)ᵀ        K = Pxy S⁻¹
//! ỹ = rz(y, ŷ)                x = x⁻ + K ỹ
//! P = Σᵢ Wᵢᶜ eᵢ eᵢᵀ + K R Kᵀ (+ Q),   eᵢ = r(σfᵢ, x⁻) − K rz(σhᵢ, ŷ)
//! ```
//! The last line is a Joseph-type form of FilterPy's `P = P⁻ − K S Kᵀ`: the
//! points' own covariance `Σ Wᶜ r rᵀ` is `P⁻ − Q` for the predict's points
//! (so `Q` is added back) and `P⁻` for redrawn ones, and expanding the sum
//! gives `P⁻ − K Pxyᵀ − Pxy Kᵀ + K S Kᵀ = P⁻ − K S Kᵀ` for the optimal `K`,
//! with FilterPy's weights. Unlike the difference it does not cancel: a
//! measurement that pins a state down leaves that state's deviations
//! `eᵢ ≈ 0` and its variance `≈ K R Kᵀ` (`P₀ = [[100, 0.05], [0.05,
//! 1e-4]]` measured with `R = 1e-12`: `P₂₂ = 1e-12` where the difference
//! gives −2.9e-11 in `f32`). It is positive
//! semi-definite by construction whenever the weights are non-negative;
//! a negative `W₀ᶜ` (small `α`) multiplies `e₀`, the centre point's
//! deviation, which is rounding-sized on a near-linear step. It costs one
//! more `N × S` product than the difference (bench table).
//! (`h` = [`UkfModel::measure`], `mean_z` and `rz` the measurement mean and
//! residual of [`UkfModel::angles`]). Because `σf` predate `Q`,
//! `S` and `Pxy` do not contain it: on a linear system this is the Kalman
//! filter only when `Q = 0`, and otherwise the Kalman filter with
//! `S = H(P⁻ − Q)Hᵀ + R`, `Pxy = (P⁻ − Q)Hᵀ` (the unit tests check both;
//! later FilterPy versions redraw the points to include `Q`). With
//! [`UnscentedKalmanFilter::with_redrawn_update_points`] the update draws
//! fresh points from `(x⁻, P⁻)` instead, as those later versions do: then
//! a linear system is the Kalman filter whatever `Q`, which a filter whose
//! `Q` per step is as large as `R` needs (the fusion estimator's UKF,
//! [`crate::estimation::fusion::ukf`]). `K` comes
//! from a Cholesky solve with `S` (nalgebra's inverse if `S` is not
//! positive definite), not from `S⁻¹` as in FilterPy: in `f32`, nalgebra's
//! closed-form 4 × 4 inverse cost the landmark fixture 3e-4 in `P`. The
//! state is not normalised
//! after the update (FilterPy does not either): an angle may leave
//! (−π, π] by the correction until the next predict's mean brings it back.
//! Where this filter departs from FilterPy, it does so where FilterPy's
//! behaviour is undefined or would fail:
//! * An update with no fresh `σf` (before the first predict, or a second
//!   update after the same predict) draws sigma points from the current
//!   `(x, P)` (no transition). FilterPy would use zeros, or the stale
//!   points of the previous prior; its docs advise recomputing them.
//! * `P` is symmetrised after every step; the update is the Joseph-type
//!   form above, not the difference.
//! * The failures below have defined reactions instead of exceptions.
//!
//! # Centre mean
//! With [`UnscentedKalmanFilter::with_centre_mean`] the predict takes the
//! centre point's image as the prior mean, `x⁻ = f(x, u)` (the extended
//! Kalman filter's mean), and `P⁻ = Σᵢ Wᵢᶜ r(σfᵢ, x⁻) r(σfᵢ, x⁻)ᵀ + Q`, the
//! points' spread about it (`Σ_{i≥1} Wᵢ dᵢ dᵢᵀ + Q` with `dᵢ = r(σfᵢ,
//! σf₀)`): the unscented mean's shift `m`, its second-order term `½
//! Σⱼₖ ∂²f/∂xⱼ∂xₖ Pⱼₖ` (Julier & Uhlmann 2004, "Unscented filtering and
//! nonlinear estimation", Proc. IEEE 92(3), section IV), is left out of
//! the mean, and `P⁻` is the unscented one less its centre term `(β − α²)
//! m mᵀ` (the identity of "Square-root form"). It is for a model in which
//! that term is a bias the system does not have: a robot moving `ds`
//! along a heading `θ` of variance `σ²` moves `ds·cos θ` on the axis,
//! whose expectation is `ds·cos θ̄·e^{−σ²/2}`, but it moves that far along
//! its one true heading, and measurements of the position along its path
//! (which are even in the heading error) then see the unscented mean lag:
//! the fusion estimator's UKF ([`crate::estimation::fusion::ukf`]) at the
//! template's wheel noise on a row of tags lags up to 11 mm a 10 cm cell,
//! which this option removes (docs/fusion.md, "The UKF at the default
//! wheel noise"). For a
//! linear model the two means agree; the update is unchanged. In the
//! square-root form the centre term is then zero (the deviations are taken
//! about the centre point itself).
//!
//! # Square-root form
//! [`UkfForm::SquareRoot`] ([`UnscentedKalmanFilter::with_form`]) is Van
//! der Merwe & Wan's square-root UKF (2001, "The square-root unscented
//! Kalman filter for state and parameter estimation", ICASSP, Algorithm
//! 3.1): it propagates the lower Cholesky factor `L` of `P` (`P = L Lᵀ`,
//! the paper's `Sᵀ`) instead of `P`, with the same points `x ± γLₖ`, the
//! same means and the same FilterPy 1.4.5 reuse of `σf`. The paper forms
//! the factor as `qr([√W₁ (σ₁:₂ₙ − x̄), √Q])` and then `cholupdate`s it
//! with the centre point at weight `W₀ᶜ` (eqs. 20–21), a downdate when
//! `W₀ᶜ < 0`, i.e. for any `α` below about 1. Here the deviations are
//! taken about the centre point, `dᵢ = r(σᵢ, σ₀)` and `m = r(x̄, σ₀)`:
//! for a linear mean `x̄ = σ₀ + Σ_{i≥1} Wᵢ dᵢ`, and
//! ```text
//! Σᵢ Wᵢᶜ (σᵢ − x̄)(σᵢ − x̄)ᵀ = Σ_{i≥1} Wᵢ dᵢ dᵢᵀ + (β − α²) m mᵀ
//! ```
//! (the centre weight `W₀ᶜ = 2 − Σ_{i≥1} Wᵢ − α² + β` cancels to `β − α²`),
//! so `L⁻` is `√Q` updated by the `2n` columns `√Wᵢ dᵢ` and by
//! `√(β − α²) m`: rank-one updates only (Givens rotations, the
//! QR of the paper one column at a time), positive semi-definite by
//! construction, and no downdate of weight 1e4 at `α = 0.01`. Hence the
//! condition `β ≥ α²` ([`UkfError::SquareRootBeta`]; `β = 2` meets it for
//! any `α ≤ 1.41`). The measurement factor `S_y` is built the same way
//! from `√R` (eqs. 23–24), `Pxy` from the same centred sums (eq. 25),
//! `K = (Pxy / S_yᵀ) / S_y` by two triangular solves (eq. 27). The paper
//! then downdates `L⁻` by the `M` columns of `K S_y` (eq. 27), which in
//! `f32` fails exactly where the covariance form's difference cancels (a
//! variance falling by orders of magnitude); instead the posterior factor
//! is built by updates from the Joseph-type sum above, `√Wᵢ (dᵢ − K dzᵢ)`,
//! `√(β − α²)(m − K m_z)` and the columns of `K √R` (and `√Q` for the
//! predict's points). `√Q` and `√R` are semidefinite
//! factors (`Q = 0` allowed), made when they are set.
//! [`UnscentedKalmanFilter::covariance`] is `L Lᵀ`. The form never needs
//! the repair below. The centred identity needs the mean to be the weighted
//! mean of the deviations; an angle's circular mean is not, so with angle
//! components the form departs from FilterPy's covariance where an angle's
//! spread is wide: 6.8e-4 σ and 1.6e-3 of `P` on the four-state
//! range-and-bearing fixture (`host-tests/tests/ukf_filterpy.rs`), worst
//! at the first update from the prior, against 2.4e-5 σ for the covariance
//! form.
//!
//! # Angles
//! A model names its angle components once, [`UkfModel::angles`] (an
//! [`AngleComponents`]), and the filter takes FilterPy's four hooks from
//! it: [`unscented_mean_with_angles`] (the circular mean `atan2(Σ W sin,
//! Σ W cos)`, FilterPy's book recipe) for `x_mean_fn`/`z_mean_fn` and
//! [`residual_with_angles`] (difference wrapped to (−π, π]) for
//! `residual_x`/`residual_z`. (One setting rather than four trait
//! methods, so that no model can override three of them and compile.)
//! The unscented circular mean has resultant `Σ W cos d ≈ 1 − σ²/2` for an angle of variance `σ²`
//! (whatever `α`): above about 2 rad² it turns negative, the mean flips by
//! π and `P⁻` becomes indefinite. FilterPy fails there too (paper 004's
//! `P0 = 10 I` on the heading makes scipy raise at the second predict), so
//! start an angle with a variance well below 2 rad².
//!
//! # `f32` and small `α`
//! With `α = 0.01` and `n = 3`, `W₀ᵐ = −9999` and `Wᵢ = 1666.7`: a plain
//! `Σ W σ` loses four digits to cancellation, and the `f32` weights
//! themselves sum to 1 only within a few 1e-4. The default means are
//! therefore evaluated as `σ₀ + Σ_{i≥1} Wᵢ(σᵢ − σ₀)` (and the circular mean
//! about `σ₀`), equal to FilterPy's `Σ W σ` for weights that sum to one
//! but free of that cancellation. What no evaluation order can recover is
//! the rounding of the points themselves: the offsets `γ√P` (`γ = 0.017`)
//! are stored on top of `x`, and every `f(σᵢ)` is rounded at `ε|x|`, so a
//! predict's mean carries `Σ_{i≥1}|Wᵢ| · ε|x|` (1e4 · 1.2e-7 · |x|, a few
//! 1e-4 · |x|) of rounding and `P⁻` a relative `ε|x|/(γ√P)`. Against
//! FilterPy's `f64` (`host-tests/tests/ukf_filterpy.rs`) that is 0.06 σ in
//! `x` and 0.2–1.4 % in `P` over paper 004's scenario 1, against 2e-5 at
//! `α = 0.5`. The estimator is no worse for it (the errors are a small
//! fraction of its own σ); a larger `α` (0.1 … 1) is the cure when the
//! numbers must reproduce.
//!
//! Without process noise the same rounding accumulates. Each predict's
//! mean carries a rounding-sized shift `m = Σ_{i≥1} Wᵢ(σfᵢ − σf₀)` (a
//! second difference of the points, zero for a linear `f` in exact
//! arithmetic), and the centre term `(β − α²) m mᵀ` of `P⁻` (the
//! covariance form's `W₀ᶜ` term, the square-root form's centre update)
//! adds it as process noise the exact filter does not have; the mean
//! itself takes a random walk of the same size. On a constant-velocity
//! system with `Q = 0`, position measured with `R = 0.04`, 2,000 steps
//! (the `q_zero_drift_is_f32_rounding_at_small_alpha` unit test, against
//! an `f64` Kalman filter), the UKF's `P₁₁` ends at these multiples of the
//! Kalman filter's (covariance form / square-root form), by `|x|`:
//!
//! | `α` | `|x|` ≈ 0 | `|x|` = 1 | `|x|` = 10 | `|x|` = 100 |
//! | --- | --- | --- | --- | --- |
//! | 1 | 1.00 / 1.00 | 1.00 / 1.00 | 1.00 / 1.00 | 0.99 / 0.99 |
//! | 0.1 | 1.01 / 1.01 | 1.01 / 1.01 | 1.08 / 1.08 | 2.1 / 2.1 |
//! | 0.01 | 2.8 / 2.9 | 3.7 / 3.7 | 12.4 / 11.2 | 74 / 97 |
//!
//! and at `α = 0.01` the two filters' position estimates part by 7e-3 to
//! 2.4e-2, about the Kalman filter's own σ (8.9e-3). The same run with
//! `β = α²`, which removes the centre term, ends at 1.1–1.3×: the excess
//! enters through it. Neither form nor the order of the sums cures it (it
//! is in the points, before any sum); `α ≥ 0.1`, or a model whose state
//! is kept near zero (e.g. positions relative to a nearby origin), does.
//! The filter accepts `α = 0.01` because paper 004 uses it, with process
//! noise well above this floor.
//!
//! # Bad input and failures
//! Each of these skips the step, leaves the estimate as it was (except the
//! reset), is counted in [`UkfCounters`] and is reported by the returned
//! [`StepOutcome`]:
//! * a non-finite input `u`, step `dt` (or a negative one), measurement `z`
//!   or per-call `R` (not finite, symmetric and positive semi-definite):
//!   [`StepOutcome::RejectedInput`];
//! * `(λ + n)P` does not factor (not positive definite, e.g. after
//!   rounding; covariance form only): it is symmetrised, each diagonal
//!   entry `aᵢᵢ` raised by `c·ε·aᵢᵢ` (relative to itself, not to the
//!   largest entry, which would swamp small variances; a floor of
//!   `f32::MIN_POSITIVE` for a zero one) and factored again, for
//!   `c = 1, 4, 16, …` up to `N·S` ([`repair_bound`], the size of the
//!   rounding a sum of `S` weighted outer products leaves in `P`); the
//!   first `c` that factors is kept and the step goes on
//!   ([`StepOutcome::Repaired`], counted as a repair). A repair is thus
//!   no larger than the rounding it repairs: on a prior of scale 8192 that
//!   rounds to a singular matrix, it adds 1e-3 to the diagonal (a fixed
//!   jitter of 1e-5 of each entry added 0.082, and a measured state's
//!   partner then kept a variance of 0.164 where the exact one is 2.5e-6;
//!   now 9.8e-4, one ulp of that prior). Otherwise `P` is
//!   reset to the initial covariance given at construction, `x` is kept
//!   and the step is skipped ([`StepOutcome::CovarianceReset`]). The
//!   square-root form holds a triangular factor with a non-negative
//!   diagonal, built by rotations only, so it never needs a repair;
//! * `S` not invertible: [`StepOutcome::SingularInnovation`];
//! * a non-finite result (`x`, `P`, `S` or `K`):
//!   [`StepOutcome::NonFiniteResult`].
//!
//! Everything is stack-allocated: `σf` is an `N × S` matrix, `S = 2N + 1`.
//!
//! # Files
//! * `factor.rs`: the square-root form's small linear algebra (a rank-one
//!   Cholesky update by Givens rotations, the factor of a semi-definite
//!   noise matrix);
//! * `sigma_points.rs`: [`MerweScaledSigmaPoints`], their weights, the
//!   unscented means and residuals ([`AngleComponents`]);
//! * `conditioning.rs`: the covariance helpers both steps share
//!   (finiteness, symmetrising, the check of a noise covariance, the
//!   gain's solve with `S`);
//! * `filter.rs`: the [`UnscentedKalmanFilter`] itself: its state,
//!   construction, settings and accessors;
//! * `predict.rs`: the time update, with the repair and reset of "Bad
//!   input and failures";
//! * `update.rs`: the measurement update and the covariance form's
//!   correction;
//! * `square_root.rs`: the square-root form's correction;
//! * `tests.rs`: the unit tests.

mod conditioning;
mod factor;
mod filter;
mod predict;
mod sigma_points;
mod square_root;
#[cfg(test)]
mod tests;
mod update;

pub use super::StepOutcome;
pub use filter::UnscentedKalmanFilter;

use nalgebra::SVector;
pub use sigma_points::{
    AngleComponents, MerweScaledSigmaPoints, residual_with_angles, unscented_mean,
    unscented_mean_with_angles,
};

/// The largest jitter a repair adds to each diagonal entry of `(λ + n)P`,
/// relative to that entry: `N·S·ε` for `N` states and `S = 2N + 1` sigma
/// points (module docs, "Bad input and failures"). `P` is a weighted sum
/// of `S` outer products (and `Q`), so rounding puts at most about `S ε
/// √(Pᵢᵢ Pⱼⱼ)` into each entry (to first order, for non-negative
/// weights); scaled by its diagonal, that is a perturbation of norm at
/// most `N·S·ε`, which this jitter covers. 1.3e-5 for the fusion UKF's
/// five states, 1.2e-6 for two.
#[must_use]
pub const fn repair_bound<const N: usize, const S: usize>() -> f32 {
    // N·S ≤ 2^24 for any filter that fits in memory: exact in f32.
    (N * S) as f32 * f32::EPSILON
}

/// Why a sigma-point set or a filter was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum UkfError {
    /// `α` not finite and positive.
    Alpha,
    /// `β` not finite.
    Beta,
    /// `κ` not finite, or `n + κ ≤ 0` (then `n + λ = α²(n + κ) ≤ 0`).
    Kappa,
    /// `n + λ = α²(n + κ)` under- or overflows `f32`, so the weights are
    /// not finite.
    Spread,
    /// The initial state is not finite.
    InitialState,
    /// The initial covariance `P₀` (or a reset's) is not finite,
    /// symmetric and positive definite: why.
    InitialCovariance(CovarianceDefect),
    /// The process noise `Q` is not finite, symmetric and positive
    /// semi-definite (`Q = 0` is allowed): why.
    ProcessNoise(CovarianceDefect),
    /// The measurement noise `R` is not finite, symmetric and positive
    /// definite: why. (`R = 0`, or a singular `R`, is refused: an update
    /// with it would pin a combination of states exactly, the innovation
    /// covariance `S` could be singular, and the two forms would fail
    /// differently, by repairs or by skipped updates.)
    MeasurementNoise(CovarianceDefect),
    /// The square-root form ([`UkfForm::SquareRoot`]) needs `β ≥ α²`: its
    /// centre term enters the factor as a rank-one update of weight
    /// `√(β − α²)` (module docs, "Square-root form").
    SquareRootBeta,
}

/// Why a covariance matrix (`P₀`, `Q` or `R`) was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum CovarianceDefect {
    /// An entry is NaN or infinite.
    NotFinite,
    /// `|A − Aᵀ|` exceeds 1e-6 of its largest entry.
    NotSymmetric,
    /// It must be positive definite (`P₀`, `R`) and its `f32` Cholesky
    /// factorisation fails (a negative, zero or rounding-sized pivot).
    NotPositiveDefinite,
    /// It must be positive semi-definite (`Q`) and it does not factor even
    /// with its diagonal raised by 1e-6 of its largest entry.
    NotPositiveSemiDefinite,
}

impl CovarianceDefect {
    /// Why, in words.
    #[must_use]
    pub fn reason(self) -> &'static str {
        match self {
            Self::NotFinite => "has a NaN or infinite entry",
            Self::NotSymmetric => "is not symmetric",
            Self::NotPositiveDefinite => "is not positive definite",
            Self::NotPositiveSemiDefinite => "is not positive semi-definite",
        }
    }
}

impl core::fmt::Display for CovarianceDefect {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.reason())
    }
}

impl core::fmt::Display for UkfError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::Alpha => "alpha (α) must be finite and > 0",
            Self::Beta => "beta (β) must be finite",
            Self::Kappa => "kappa (κ) must be finite with n + κ > 0",
            Self::Spread => {
                "n + λ = α²(n + κ) under- or overflows f32 (the weights are not finite)"
            }
            Self::InitialState => "the initial state must be finite",
            Self::InitialCovariance(why) => {
                return write!(f, "the initial covariance P0 {why}");
            }
            Self::ProcessNoise(why) => return write!(f, "the process noise Q {why}"),
            Self::MeasurementNoise(why) => return write!(f, "the measurement noise R {why}"),
            Self::SquareRootBeta => "beta (β) must be ≥ alpha² (α²) for the square-root form",
        })
    }
}

impl core::error::Error for UkfError {}

/// A system for the [`UnscentedKalmanFilter`]: FilterPy's `fx`, `hx` and
/// its four hooks `residual_x`, `residual_z`, `x_mean_fn`, `z_mean_fn`.
pub trait UkfModel<const N: usize, const M: usize> {
    /// The input `u` (FilterPy's `**fx_args`).
    type Input;

    /// Whether `u` is usable (finite): a rejected input skips the predict.
    fn input_is_finite(&self, u: &Self::Input) -> bool;

    /// `f(x, u, dt)`: the state after a step of `dt_s` seconds (`fx`).
    fn transition(&self, x: &SVector<f32, N>, u: &Self::Input, dt_s: f32) -> SVector<f32, N>;

    /// `h(x)`: the expected measurement (`hx`).
    fn measure(&self, x: &SVector<f32, N>) -> SVector<f32, M>;

    /// Which state and measurement components are angles (default: none).
    /// The filter takes FilterPy's four hooks from it (`residual_x`,
    /// `residual_z`: wrapped differences; `x_mean_fn`, `z_mean_fn`:
    /// circular means; module docs, "Angles"), all four or none for each
    /// component.
    fn angles(&self) -> AngleComponents<N, M> {
        AngleComponents::NONE
    }
}

/// Which covariance the [`UnscentedKalmanFilter`] propagates (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum UkfForm {
    /// `P` itself, FilterPy's equations with a Joseph-type update.
    #[default]
    Covariance,
    /// Its lower Cholesky factor `L` (Van der Merwe & Wan 2001): positive
    /// semi-definite by construction; needs `β ≥ α²`.
    SquareRoot,
}

/// What the filter skipped or repaired, since construction (saturating).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct UkfCounters {
    /// Steps skipped for a non-finite (or negative) `u`, `dt`, `z` or `R`.
    pub rejected_inputs: u32,
    /// Steps skipped for a non-finite result.
    pub non_finite_results: u32,
    /// Updates skipped because `S` was not invertible.
    pub singular_innovations: u32,
    /// Factorisations of `(λ + n)P` that needed the jitter.
    pub covariance_repairs: u32,
    /// Resets of `P` to the initial covariance (the factorisation failed
    /// even jittered).
    pub covariance_resets: u32,
}

pub(crate) fn bump(counter: &mut u32) {
    *counter = counter.saturating_add(1);
}
