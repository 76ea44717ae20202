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
//! with `mean_x` = [`UkfModel::state_mean`] (`x_mean_fn`) and `r` =
//! [`UkfModel::state_residual`] (`residual_x`).
//!
//! # Measurement update ([`UnscentedKalmanFilter::update`])
//! As in FilterPy 1.4.5, the update **reuses the propagated points `σf`**
//! of the last predict (it does not draw new sigma points from `(x⁻, P⁻)`;
//! FilterPy changed that after 1.4.5):
//! ```text
//! σhᵢ = h(σfᵢ)                ŷ = mean_z(σh, Wᵐ)
//! S = Pyy = Σᵢ Wᵢᶜ rz(σhᵢ, ŷ) rz(σhᵢ, ŷ)ᵀ + R
//! Pxy = Σᵢ Wᵢᶜ r(σfᵢ, x⁻) rz(σhᵢ, ŷ)ᵀ        K = Pxy S⁻¹
//! ỹ = rz(y, ŷ)                x = x⁻ + K ỹ      P = P⁻ − K S Kᵀ
//! ```
//! (`h` = [`UkfModel::measure`], `mean_z` = [`UkfModel::measurement_mean`],
//! `rz` = [`UkfModel::measurement_residual`]). Because `σf` predate `Q`,
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
//! * `P` is symmetrised after every step; `K S Kᵀ` is formed as FilterPy
//!   forms it and the asymmetry it leaves is rounding.
//! * The failures below have defined reactions instead of exceptions.
//!
//! # Angles
//! A state or measurement with angle components overrides the four hooks;
//! [`unscented_mean_with_angles`] (the circular mean `atan2(Σ W sin, Σ W
//! cos)`, FilterPy's book recipe) and [`residual_with_angles`] (difference
//! wrapped to (−π, π]) do it for chosen components. The unscented circular
//! mean has resultant `Σ W cos d ≈ 1 − σ²/2` for an angle of variance `σ²`
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
//! # Bad input and failures
//! Each of these skips the step, leaves the estimate as it was (except the
//! reset), is counted in [`UkfCounters`] and is reported by the returned
//! [`UkfOutcome`]:
//! * a non-finite input `u`, step `dt` (or a negative one), measurement `z`
//!   or per-call `R` (not finite, symmetric and positive semi-definite):
//!   [`UkfOutcome::RejectedInput`];
//! * `(λ + n)P` does not factor (not positive definite, e.g. after
//!   rounding): it is symmetrised, its diagonal raised by
//!   [`COVARIANCE_JITTER`] times its largest diagonal entry, and factored
//!   again; if that works the step goes on ([`UkfOutcome::Repaired`],
//!   counted as a repair). Otherwise `P` is reset to the initial covariance
//!   given at construction, `x` is kept and the step is skipped
//!   ([`UkfOutcome::CovarianceReset`]);
//! * `S` not invertible: [`UkfOutcome::SingularInnovation`];
//! * a non-finite result (`x`, `P`, `S` or `K`):
//!   [`UkfOutcome::NonFiniteResult`].
//!
//! Everything is stack-allocated: `σf` is an `N × S` matrix, `S = 2N + 1`.

use nalgebra::{SMatrix, SVector};

use crate::math;

/// The jitter added to the diagonal of `(λ + n)P` when it does not factor,
/// relative to its largest diagonal entry: about 80 `f32` ulps, above the
/// rounding that makes a positive definite `P` fail, below any variance
/// that matters.
pub const COVARIANCE_JITTER: f32 = 1e-5;

/// Why a sigma-point set or a filter was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum UkfError {
    /// The number of sigma points `S` is not `2N + 1`, or `N = 0`. `S` is
    /// a separate const parameter only because stable Rust cannot write
    /// `SMatrix<f32, N, { 2 * N + 1 }>` (`generic_const_exprs` is
    /// unstable); it is checked here instead.
    SigmaPointCount,
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
    /// The initial covariance is not finite, symmetric and positive
    /// definite.
    InitialCovariance,
    /// The process noise `Q` is not finite, symmetric and positive
    /// semi-definite.
    ProcessNoise,
    /// The measurement noise `R` is not finite, symmetric and positive
    /// semi-definite.
    MeasurementNoise,
}

impl core::fmt::Display for UkfError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::SigmaPointCount => "the sigma-point count S must be 2N + 1 with N > 0",
            Self::Alpha => "alpha (α) must be finite and > 0",
            Self::Beta => "beta (β) must be finite",
            Self::Kappa => "kappa (κ) must be finite with n + κ > 0",
            Self::Spread => {
                "n + λ = α²(n + κ) under- or overflows f32 (the weights are not finite)"
            }
            Self::InitialState => "the initial state must be finite",
            Self::InitialCovariance => {
                "the initial covariance must be finite, symmetric and positive definite"
            }
            Self::ProcessNoise => {
                "the process noise Q must be finite, symmetric and positive semi-definite"
            }
            Self::MeasurementNoise => {
                "the measurement noise R must be finite, symmetric and positive semi-definite"
            }
        })
    }
}

impl core::error::Error for UkfError {}

/// Van der Merwe's scaled sigma points for `N` states (FilterPy's
/// `MerweScaledSigmaPoints(n, alpha, beta, kappa)` with its default
/// Cholesky square root): the parameters and the `S = 2N + 1` weights.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MerweScaledSigmaPoints<const N: usize, const S: usize> {
    alpha: f32,
    beta: f32,
    kappa: f32,
    /// `n + λ = α²(n + κ)`.
    spread: f32,
    /// `W₀ᵐ`.
    centre_mean: f32,
    /// `W₀ᶜ`.
    centre_covariance: f32,
    /// `Wᵢ`, `i ≥ 1`.
    point_weight: f32,
}

impl<const N: usize, const S: usize> MerweScaledSigmaPoints<N, S> {
    /// The weights for spread `α > 0` (the paper's 0.01; FilterPy
    /// suggests 1e-3 … 1), prior-knowledge term `β` (2 is optimal for a
    /// Gaussian prior) and secondary scaling `κ` (0, or `3 − n`).
    ///
    /// # Errors
    /// [`UkfError::SigmaPointCount`] unless `S = 2N + 1` and `N ≥ 1`; the
    /// first of [`UkfError::Alpha`], [`UkfError::Beta`],
    /// [`UkfError::Kappa`], [`UkfError::Spread`] out of range.
    pub fn new(alpha: f32, beta: f32, kappa: f32) -> Result<Self, UkfError> {
        if N == 0 || S != 2 * N + 1 {
            return Err(UkfError::SigmaPointCount);
        }
        if !(alpha.is_finite() && alpha > 0.0) {
            return Err(UkfError::Alpha);
        }
        if !beta.is_finite() {
            return Err(UkfError::Beta);
        }
        // N ≤ 2^24 for any matrix that fits in memory: exact in f32.
        let n = N as f32;
        if !(kappa.is_finite() && n + kappa > 0.0) {
            return Err(UkfError::Kappa);
        }
        // n + λ computed directly, not as (α²(n + κ) − n) + n, which would
        // lose the digits of a small α.
        let spread = alpha * alpha * (n + kappa);
        let point_weight = 0.5 / spread;
        // λ/(n + λ) = 1 − n/(n + λ).
        let centre_mean = 1.0 - n / spread;
        let centre_covariance = centre_mean + (1.0 - alpha * alpha + beta);
        if !(spread.is_finite()
            && spread > 0.0
            && point_weight.is_finite()
            && centre_mean.is_finite()
            && centre_covariance.is_finite())
        {
            return Err(UkfError::Spread);
        }
        Ok(Self {
            alpha,
            beta,
            kappa,
            spread,
            centre_mean,
            centre_covariance,
            point_weight,
        })
    }

    /// The paper's parameters: `α = 0.01, β = 2, κ = 0`.
    ///
    /// # Errors
    /// [`UkfError::SigmaPointCount`] unless `S = 2N + 1` and `N ≥ 1`.
    pub fn paper() -> Result<Self, UkfError> {
        Self::new(0.01, 2.0, 0.0)
    }

    /// `α`.
    #[must_use]
    pub fn alpha(&self) -> f32 {
        self.alpha
    }

    /// `β`.
    #[must_use]
    pub fn beta(&self) -> f32 {
        self.beta
    }

    /// `κ`.
    #[must_use]
    pub fn kappa(&self) -> f32 {
        self.kappa
    }

    /// `λ = α²(n + κ) − n`.
    #[must_use]
    pub fn lambda(&self) -> f32 {
        self.spread - N as f32
    }

    /// `γ = √(n + λ)`, the scale of the points' offsets.
    #[must_use]
    pub fn gamma(&self) -> f32 {
        math::sqrt(self.spread)
    }

    /// The mean weights `Wᵐ` (`W₀ᵐ = λ/(n + λ)`, the others
    /// `1/(2(n + λ))`); they sum to one.
    #[must_use]
    pub fn mean_weights(&self) -> SVector<f32, S> {
        self.weights(self.centre_mean)
    }

    /// The covariance weights `Wᶜ` (`W₀ᶜ = W₀ᵐ + 1 − α² + β`, the others as
    /// `Wᵐ`).
    #[must_use]
    pub fn covariance_weights(&self) -> SVector<f32, S> {
        self.weights(self.centre_covariance)
    }

    fn weights(&self, centre: f32) -> SVector<f32, S> {
        let mut weights = SVector::<f32, S>::repeat(self.point_weight);
        if let Some(w) = weights.get_mut(0) {
            *w = centre;
        }
        weights
    }

    /// The sigma points of `(x, P)` as columns, in FilterPy's order
    /// (module docs): `x`, then `x + Lₖ`, then `x − Lₖ`, with `Lₖ` the
    /// columns of the lower Cholesky factor of `(n + λ)P` (the rows of
    /// scipy's upper factor). `None` if `(n + λ)P` is not positive definite
    /// (only its lower triangle is read).
    #[must_use]
    pub fn sigma_points(
        &self,
        x: &SVector<f32, N>,
        p: &SMatrix<f32, N, N>,
    ) -> Option<SMatrix<f32, N, S>> {
        lower_factor(&(p * self.spread)).map(|l| points_from_factor(x, &l))
    }
}

/// The lower Cholesky factor of `a` (lower triangle read), if it is
/// positive definite and the factor finite.
fn lower_factor<const N: usize>(a: &SMatrix<f32, N, N>) -> Option<SMatrix<f32, N, N>> {
    let l = nalgebra::Cholesky::new(*a)?.l();
    l.iter().all(|v| v.is_finite()).then_some(l)
}

/// `[x, x + L₀ … x + L_{n−1}, x − L₀ … x − L_{n−1}]` (columns `Lₖ` of `l`).
fn points_from_factor<const N: usize, const S: usize>(
    x: &SVector<f32, N>,
    l: &SMatrix<f32, N, N>,
) -> SMatrix<f32, N, S> {
    let mut sigmas = SMatrix::<f32, N, S>::zeros();
    let mut columns = sigmas.column_iter_mut();
    if let Some(mut centre) = columns.next() {
        centre.copy_from(x);
    }
    // `l` first in each zip, so that running out of `l` does not consume a
    // column of `sigmas`.
    for (offset, mut column) in l.column_iter().zip(columns.by_ref()) {
        column.copy_from(&(x + offset));
    }
    for (offset, mut column) in l.column_iter().zip(columns) {
        column.copy_from(&(x - offset));
    }
    sigmas
}

/// `K = Pxy S⁻¹` for a symmetric `S`: as `Kᵀ = S⁻¹ Pxyᵀ` by Cholesky when
/// `S` is positive definite (the normal case), else with nalgebra's inverse
/// (FilterPy always inverts, `np.linalg.inv`); `None` if `S` is singular
/// or `K` not finite. The Cholesky solve matters in `f32`: nalgebra's
/// closed-form 4 × 4 inverse of the landmark fixture's `S` put 3e-4 of
/// error into the first update's `P`.
fn kalman_gain<const N: usize, const M: usize>(
    cross: &SMatrix<f32, N, M>,
    s: &SMatrix<f32, M, M>,
) -> Option<SMatrix<f32, N, M>> {
    let gain = match nalgebra::Cholesky::new(*s) {
        Some(factor) => factor.solve(&cross.transpose()).transpose(),
        None => cross * s.try_inverse()?,
    };
    all_finite(&gain).then_some(gain)
}

/// `(a + aᵀ)/2`.
fn symmetrize<const K: usize>(a: &SMatrix<f32, K, K>) -> SMatrix<f32, K, K> {
    (a + a.transpose()) * 0.5
}

fn all_finite<const R: usize, const C: usize>(a: &SMatrix<f32, R, C>) -> bool {
    a.iter().all(|v| v.is_finite())
}

/// Finite, symmetric to `f32` rounding and positive semi-definite (it
/// factors once its diagonal is raised by 1e-6 of its largest entry).
fn is_noise_covariance<const K: usize>(a: &SMatrix<f32, K, K>) -> bool {
    let scale = a.amax();
    all_finite(a)
        && (a - a.transpose()).amax() <= 1e-6 * scale
        && lower_factor(
            &(a + SMatrix::<f32, K, K>::identity() * (1e-6 * scale).max(f32::MIN_POSITIVE)),
        )
        .is_some()
}

/// The weighted mean `Σ Wᵢ σᵢ` of the columns of `sigmas`, evaluated as
/// `σ₀ + Σ_{i≥1} Wᵢ(σᵢ − σ₀)`: the same for weights that sum to one (the
/// contract; `weights[0]` is not read), without the cancellation of
/// `|W₀| ~ 10⁴` (module docs). The default of [`UkfModel::state_mean`] and
/// [`UkfModel::measurement_mean`], FilterPy's `np.dot(Wm, sigmas)`.
#[must_use]
pub fn unscented_mean<const R: usize, const S: usize>(
    sigmas: &SMatrix<f32, R, S>,
    weights: &SVector<f32, S>,
) -> SVector<f32, R> {
    // The columns as the arrays they are stored in (column-major), not
    // through nalgebra's column views: `column_iter` checks each index
    // against the width at run time (`assert_view_index`) and builds each
    // difference from an iterator (`allocate_from_iterator`), two panic
    // paths that LTO keeps (`cargo xtask panic-free`). The arithmetic is
    // the same, element by element and in the same order.
    let Some((centre, columns)) = sigmas.data.0.split_first() else {
        return SVector::zeros();
    };
    let mut offset = SVector::<f32, R>::zeros();
    for (column, &w) in columns.iter().zip(weights.iter().skip(1)) {
        for ((o, &x), &c) in offset.iter_mut().zip(column).zip(centre) {
            *o += (x - c) * w;
        }
    }
    SVector::from(*centre) + offset
}

/// [`unscented_mean`], except that the components listed in `angles`
/// (radians; indices `≥ R` are ignored) get the circular mean
/// `atan2(Σ Wᵢ sin σᵢ, Σ Wᵢ cos σᵢ)` wrapped to (−π, π] (FilterPy's book
/// recipe for `x_mean_fn`/`z_mean_fn`). It is evaluated about the first
/// point, `σ₀ + atan2(Σ_{i≥1} Wᵢ sin dᵢ, 1 − Σ_{i≥1} 2Wᵢ sin²(dᵢ/2))` with
/// `dᵢ = σᵢ − σ₀`, the same angle for weights that sum to one. The
/// denominator, the mean resultant, is about `1 − var/2`: above a variance
/// of about 2 rad² it is negative and the "mean" points the other way
/// (module docs).
#[must_use]
pub fn unscented_mean_with_angles<const R: usize, const S: usize>(
    sigmas: &SMatrix<f32, R, S>,
    weights: &SVector<f32, S>,
    angles: &[usize],
) -> SVector<f32, R> {
    let mut mean = unscented_mean(sigmas, weights);
    for &i in angles {
        let Some(row) = sigmas.row_iter().nth(i) else {
            continue;
        };
        let Some(&centre) = row.get(0) else {
            continue;
        };
        let (mut sine, mut versine) = (0.0_f32, 0.0_f32);
        for (&angle, &w) in row.iter().zip(weights.iter()).skip(1) {
            let d = math::wrap_angle(angle - centre);
            let half = math::sin(0.5 * d);
            sine += w * math::sin(d);
            versine += w * 2.0 * half * half;
        }
        if let Some(m) = mean.get_mut(i) {
            *m = math::wrap_angle(centre + math::atan2(sine, 1.0 - versine));
        }
    }
    mean
}

/// `a − b` with the components listed in `angles` (radians; indices `≥ R`
/// are ignored) wrapped to (−π, π] (FilterPy's book recipe for
/// `residual_x`/`residual_z`).
#[must_use]
pub fn residual_with_angles<const R: usize>(
    a: &SVector<f32, R>,
    b: &SVector<f32, R>,
    angles: &[usize],
) -> SVector<f32, R> {
    let mut d = a - b;
    for &i in angles {
        if let Some(v) = d.get_mut(i) {
            *v = math::wrap_angle(*v);
        }
    }
    d
}

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

    /// `a − b` for states (`residual_x`; default plain difference, see
    /// [`residual_with_angles`]).
    fn state_residual(&self, a: &SVector<f32, N>, b: &SVector<f32, N>) -> SVector<f32, N> {
        a - b
    }

    /// `a − b` for measurements (`residual_z`; default plain difference).
    fn measurement_residual(&self, a: &SVector<f32, M>, b: &SVector<f32, M>) -> SVector<f32, M> {
        a - b
    }

    /// The weighted mean of state sigma points (columns) with weights
    /// summing to one (`x_mean_fn`; default [`unscented_mean`], see
    /// [`unscented_mean_with_angles`]).
    fn state_mean<const S: usize>(
        &self,
        sigmas: &SMatrix<f32, N, S>,
        weights: &SVector<f32, S>,
    ) -> SVector<f32, N> {
        unscented_mean(sigmas, weights)
    }

    /// The weighted mean of measurement sigma points (`z_mean_fn`; default
    /// [`unscented_mean`]).
    fn measurement_mean<const S: usize>(
        &self,
        sigmas: &SMatrix<f32, M, S>,
        weights: &SVector<f32, S>,
    ) -> SVector<f32, M> {
        unscented_mean(sigmas, weights)
    }
}

/// What a [`UnscentedKalmanFilter::predict`] or
/// [`UnscentedKalmanFilter::update`] did (module docs, "Bad input and
/// failures").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum UkfOutcome {
    /// The step was applied.
    Applied,
    /// The step was applied after `(λ + n)P` was symmetrised and jittered
    /// to factor.
    Repaired,
    /// Skipped: non-finite input, step, measurement or per-call noise.
    RejectedInput,
    /// Skipped: `(λ + n)P` did not factor even jittered; `P` was reset to
    /// the initial covariance, `x` kept.
    CovarianceReset,
    /// Skipped: the innovation covariance `S` is not invertible.
    SingularInnovation,
    /// Skipped: the result was not finite; the estimate is unchanged.
    NonFiniteResult,
}

impl UkfOutcome {
    /// Whether the step changed the estimate as the filter equations say
    /// ([`Self::Applied`] or [`Self::Repaired`]).
    #[must_use]
    pub fn is_applied(self) -> bool {
        matches!(self, Self::Applied | Self::Repaired)
    }
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

fn bump(counter: &mut u32) {
    *counter = counter.saturating_add(1);
}

/// The unscented Kalman filter of the module docs for a model with `N`
/// states and `M` measurements; `S` must be `2N + 1` (checked by
/// [`MerweScaledSigmaPoints::new`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UnscentedKalmanFilter<Model, const N: usize, const M: usize, const S: usize>
where
    Model: UkfModel<N, M>,
{
    model: Model,
    points: MerweScaledSigmaPoints<N, S>,
    x: SVector<f32, N>,
    p: SMatrix<f32, N, N>,
    initial_covariance: SMatrix<f32, N, N>,
    q: SMatrix<f32, N, N>,
    r: SMatrix<f32, M, M>,
    /// FilterPy's `sigmas_f`: the last predict's propagated points.
    sigmas_f: SMatrix<f32, N, S>,
    /// `sigmas_f` belong to the current `(x, P)` (a predict, and no update
    /// or reset, since).
    sigmas_f_fresh: bool,
    /// Draw the update's points from `(x⁻, P⁻)` rather than reuse `σf`.
    redraw_for_update: bool,
    innovation: SVector<f32, M>,
    innovation_covariance: SMatrix<f32, M, M>,
    gain: SMatrix<f32, N, M>,
    counters: UkfCounters,
}

impl<Model, const N: usize, const M: usize, const S: usize> UnscentedKalmanFilter<Model, N, M, S>
where
    Model: UkfModel<N, M>,
{
    /// A filter at `x0` with covariance `p0` (also the covariance a failed
    /// factorisation resets to), process noise `q` (added once per
    /// predict, whatever `dt`, as in FilterPy) and measurement noise `r`.
    ///
    /// # Errors
    /// [`UkfError::InitialState`], [`UkfError::InitialCovariance`] (not
    /// finite, symmetric and positive definite), [`UkfError::ProcessNoise`]
    /// or [`UkfError::MeasurementNoise`] (not finite, symmetric and
    /// positive semi-definite).
    pub fn new(
        model: Model,
        points: MerweScaledSigmaPoints<N, S>,
        x0: SVector<f32, N>,
        p0: SMatrix<f32, N, N>,
        q: SMatrix<f32, N, N>,
        r: SMatrix<f32, M, M>,
    ) -> Result<Self, UkfError> {
        if !all_finite(&x0) {
            return Err(UkfError::InitialState);
        }
        if !(is_noise_covariance(&p0) && lower_factor(&p0).is_some()) {
            return Err(UkfError::InitialCovariance);
        }
        if !is_noise_covariance(&q) {
            return Err(UkfError::ProcessNoise);
        }
        if !is_noise_covariance(&r) {
            return Err(UkfError::MeasurementNoise);
        }
        let p0 = symmetrize(&p0);
        Ok(Self {
            model,
            points,
            x: x0,
            p: p0,
            initial_covariance: p0,
            q: symmetrize(&q),
            r: symmetrize(&r),
            sigmas_f: SMatrix::zeros(),
            sigmas_f_fresh: false,
            redraw_for_update: false,
            innovation: SVector::zeros(),
            innovation_covariance: SMatrix::zeros(),
            gain: SMatrix::zeros(),
            counters: UkfCounters::default(),
        })
    }

    /// Updates draw their sigma points from the prior `(x⁻, P⁻)`, which
    /// includes `Q`, instead of reusing the last predict's `σf` (module
    /// docs, "Measurement update": FilterPy after 1.4.5).
    #[must_use]
    pub fn with_redrawn_update_points(self) -> Self {
        Self {
            redraw_for_update: true,
            ..self
        }
    }

    /// The model.
    #[must_use]
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The sigma points' parameters and weights.
    #[must_use]
    pub fn sigma_point_weights(&self) -> &MerweScaledSigmaPoints<N, S> {
        &self.points
    }

    /// The state estimate `x` (the prior `x⁻` after a predict, the
    /// posterior after an update).
    #[must_use]
    pub fn state(&self) -> &SVector<f32, N> {
        &self.x
    }

    /// Its covariance `P`.
    #[must_use]
    pub fn covariance(&self) -> &SMatrix<f32, N, N> {
        &self.p
    }

    /// The initial covariance, which a failed factorisation resets `P` to.
    #[must_use]
    pub fn initial_covariance(&self) -> &SMatrix<f32, N, N> {
        &self.initial_covariance
    }

    /// The process noise `Q`.
    #[must_use]
    pub fn process_noise(&self) -> &SMatrix<f32, N, N> {
        &self.q
    }

    /// The measurement noise `R`.
    #[must_use]
    pub fn measurement_noise(&self) -> &SMatrix<f32, M, M> {
        &self.r
    }

    /// The innovation `ỹ = rz(y, ŷ)` of the last applied update (zeros
    /// before the first).
    #[must_use]
    pub fn innovation(&self) -> &SVector<f32, M> {
        &self.innovation
    }

    /// Its covariance `S = Pyy` (with `R`) of the last applied update.
    #[must_use]
    pub fn innovation_covariance(&self) -> &SMatrix<f32, M, M> {
        &self.innovation_covariance
    }

    /// The gain `K` of the last applied update.
    #[must_use]
    pub fn gain(&self) -> &SMatrix<f32, N, M> {
        &self.gain
    }

    /// The propagated sigma points `σf` (columns) of the last predict, if
    /// the next update will use them (no update or reset since).
    #[must_use]
    pub fn propagated_sigma_points(&self) -> Option<&SMatrix<f32, N, S>> {
        self.sigmas_f_fresh.then_some(&self.sigmas_f)
    }

    /// What was skipped or repaired so far.
    #[must_use]
    pub fn counters(&self) -> UkfCounters {
        self.counters
    }

    /// Sets `Q`.
    ///
    /// # Errors
    /// [`UkfError::ProcessNoise`] (not finite, symmetric and positive
    /// semi-definite); `Q` is unchanged.
    pub fn set_process_noise(&mut self, q: SMatrix<f32, N, N>) -> Result<(), UkfError> {
        if !is_noise_covariance(&q) {
            return Err(UkfError::ProcessNoise);
        }
        self.q = symmetrize(&q);
        Ok(())
    }

    /// Sets `R`.
    ///
    /// # Errors
    /// [`UkfError::MeasurementNoise`] (not finite, symmetric and positive
    /// semi-definite); `R` is unchanged.
    pub fn set_measurement_noise(&mut self, r: SMatrix<f32, M, M>) -> Result<(), UkfError> {
        if !is_noise_covariance(&r) {
            return Err(UkfError::MeasurementNoise);
        }
        self.r = symmetrize(&r);
        Ok(())
    }

    /// Restarts from `x` with covariance `p` (the counters and the initial
    /// covariance are kept; the next update draws its points from here).
    ///
    /// # Errors
    /// [`UkfError::InitialState`] or [`UkfError::InitialCovariance`]; the
    /// filter is unchanged.
    pub fn reset(&mut self, x: SVector<f32, N>, p: SMatrix<f32, N, N>) -> Result<(), UkfError> {
        if !all_finite(&x) {
            return Err(UkfError::InitialState);
        }
        if !(is_noise_covariance(&p) && lower_factor(&p).is_some()) {
            return Err(UkfError::InitialCovariance);
        }
        self.x = x;
        self.p = symmetrize(&p);
        self.sigmas_f_fresh = false;
        Ok(())
    }

    /// The sigma points of the current `(x, P)`, with the repair and reset
    /// of the module docs: `Ok((points, repaired))`, or `Err` after a reset.
    fn draw_sigma_points(&mut self) -> Result<(SMatrix<f32, N, S>, bool), UkfOutcome> {
        if let Some(points) = self.points.sigma_points(&self.x, &self.p) {
            return Ok((points, false));
        }
        let scaled = symmetrize(&(self.p * self.points.spread));
        let largest = scaled.diagonal().amax();
        let jitter = (COVARIANCE_JITTER * largest).max(f32::MIN_POSITIVE);
        let jittered = scaled + SMatrix::<f32, N, N>::identity() * jitter;
        if let Some(l) = lower_factor(&jittered) {
            bump(&mut self.counters.covariance_repairs);
            return Ok((points_from_factor(&self.x, &l), true));
        }
        self.p = self.initial_covariance;
        self.sigmas_f_fresh = false;
        bump(&mut self.counters.covariance_resets);
        Err(UkfOutcome::CovarianceReset)
    }

    /// The time update over `dt_s` seconds (≥ 0) with input `u`: FilterPy's
    /// `predict(dt, u=u)` (module docs). On return [`Self::state`] and
    /// [`Self::covariance`] are the prior `x⁻, P⁻`.
    pub fn predict(&mut self, u: &Model::Input, dt_s: f32) -> UkfOutcome {
        if !(dt_s.is_finite() && dt_s >= 0.0 && self.model.input_is_finite(u)) {
            bump(&mut self.counters.rejected_inputs);
            return UkfOutcome::RejectedInput;
        }
        let (sigmas, repaired) = match self.draw_sigma_points() {
            Ok(drawn) => drawn,
            Err(outcome) => return outcome,
        };
        let mut sigmas_f = SMatrix::<f32, N, S>::zeros();
        for (sigma, mut propagated) in sigmas.column_iter().zip(sigmas_f.column_iter_mut()) {
            propagated.copy_from(&self.model.transition(&sigma.into_owned(), u, dt_s));
        }
        let x = self
            .model
            .state_mean(&sigmas_f, &self.points.mean_weights());
        let mut p = self.q;
        for (sigma, &w) in sigmas_f
            .column_iter()
            .zip(self.points.covariance_weights().iter())
        {
            let d = self.model.state_residual(&sigma.into_owned(), &x);
            p += d * d.transpose() * w;
        }
        if !(all_finite(&x) && all_finite(&p) && all_finite(&sigmas_f)) {
            bump(&mut self.counters.non_finite_results);
            self.sigmas_f_fresh = false;
            return UkfOutcome::NonFiniteResult;
        }
        self.x = x;
        self.p = symmetrize(&p);
        self.sigmas_f = sigmas_f;
        self.sigmas_f_fresh = true;
        if repaired {
            UkfOutcome::Repaired
        } else {
            UkfOutcome::Applied
        }
    }

    /// The measurement update with `z` and the filter's `R`: FilterPy's
    /// `update(z)` (module docs), on the last predict's `σf`.
    pub fn update(&mut self, z: &SVector<f32, M>) -> UkfOutcome {
        let r = self.r;
        self.update_with(z, &r)
    }

    /// The measurement update with `z` and, for this call only, the
    /// measurement noise `r` (FilterPy's `update(z, R)`; an `r` that is not
    /// finite, symmetric and positive semi-definite rejects the update).
    pub fn update_with_noise(&mut self, z: &SVector<f32, M>, r: &SMatrix<f32, M, M>) -> UkfOutcome {
        if !is_noise_covariance(r) {
            bump(&mut self.counters.rejected_inputs);
            return UkfOutcome::RejectedInput;
        }
        self.update_with(z, &symmetrize(r))
    }

    /// The measurement update with component `index` (`< M`) of the
    /// measurement only, `z` with variance `r`: for a sensor that reported
    /// only part of the measurement vector this tick. It is the update of
    /// the scalar measurement `h_i(x)` (row `index` of the model's
    /// `measure`, its residual and mean), with the same sigma points,
    /// checks and outcomes as [`Self::update`]. Afterwards
    /// [`Self::innovation`], [`Self::innovation_covariance`] and
    /// [`Self::gain`] hold it in full-measurement shape, zero outside
    /// component `index` (as a full update with infinite variance on the
    /// other components would leave them). An `index ≥ M`, or an `r` that
    /// is not finite and ≥ 0, rejects the update.
    pub fn update_component(&mut self, index: usize, z: f32, r: f32) -> UkfOutcome {
        if !(index < M && z.is_finite() && r.is_finite() && r >= 0.0) {
            bump(&mut self.counters.rejected_inputs);
            return UkfOutcome::RejectedInput;
        }
        let (sigmas_f, repaired, sigmas_h, z_mean) = match self.measurement_sigmas() {
            Ok(drawn) => drawn,
            Err(outcome) => return outcome,
        };
        let mut dz = SMatrix::<f32, 1, S>::zeros();
        for (sigma_h, d) in sigmas_h.column_iter().zip(dz.iter_mut()) {
            let residual = self
                .model
                .measurement_residual(&sigma_h.into_owned(), &z_mean);
            *d = residual.get(index).copied().unwrap_or(f32::NAN);
        }
        let mut full_z = z_mean;
        if let Some(component) = full_z.get_mut(index) {
            *component = z;
        }
        let innovation = self
            .model
            .measurement_residual(&full_z, &z_mean)
            .get(index)
            .copied()
            .unwrap_or(f32::NAN);
        let innovation = SVector::<f32, 1>::new(innovation);
        let r = SMatrix::<f32, 1, 1>::new(r);
        match self.correct(&sigmas_f, &dz, &innovation, &r) {
            Ok((gain, s)) => {
                self.innovation = SVector::zeros();
                self.innovation_covariance = SMatrix::zeros();
                self.gain = SMatrix::zeros();
                if let Some(v) = self.innovation.get_mut(index) {
                    *v = innovation.x;
                }
                if let Some(v) = self.innovation_covariance.get_mut((index, index)) {
                    *v = s.x;
                }
                if let Some(mut column) = self.gain.columns_mut(index, 1).column_iter_mut().next() {
                    column.copy_from(&gain);
                }
                Self::outcome(repaired)
            }
            Err(outcome) => outcome,
        }
    }

    fn update_with(&mut self, z: &SVector<f32, M>, r: &SMatrix<f32, M, M>) -> UkfOutcome {
        if !all_finite(z) {
            bump(&mut self.counters.rejected_inputs);
            return UkfOutcome::RejectedInput;
        }
        let (sigmas_f, repaired, sigmas_h, z_mean) = match self.measurement_sigmas() {
            Ok(drawn) => drawn,
            Err(outcome) => return outcome,
        };
        let mut dz = SMatrix::<f32, M, S>::zeros();
        for (sigma_h, mut d) in sigmas_h.column_iter().zip(dz.column_iter_mut()) {
            d.copy_from(
                &self
                    .model
                    .measurement_residual(&sigma_h.into_owned(), &z_mean),
            );
        }
        let innovation = self.model.measurement_residual(z, &z_mean);
        match self.correct(&sigmas_f, &dz, &innovation, r) {
            Ok((gain, s)) => {
                self.innovation = innovation;
                self.innovation_covariance = s;
                self.gain = gain;
                Self::outcome(repaired)
            }
            Err(outcome) => outcome,
        }
    }

    fn outcome(repaired: bool) -> UkfOutcome {
        if repaired {
            UkfOutcome::Repaired
        } else {
            UkfOutcome::Applied
        }
    }

    /// The update's points: the last predict's `σf` if still fresh (else
    /// drawn from `(x, P)`), whether they were repaired, their images
    /// under `h` and the mean of those.
    #[allow(clippy::type_complexity)]
    fn measurement_sigmas(
        &mut self,
    ) -> Result<
        (
            SMatrix<f32, N, S>,
            bool,
            SMatrix<f32, M, S>,
            SVector<f32, M>,
        ),
        UkfOutcome,
    > {
        let (sigmas_f, repaired) = if self.sigmas_f_fresh && !self.redraw_for_update {
            (self.sigmas_f, false)
        } else {
            self.draw_sigma_points()?
        };
        let mut sigmas_h = SMatrix::<f32, M, S>::zeros();
        for (sigma, mut measured) in sigmas_f.column_iter().zip(sigmas_h.column_iter_mut()) {
            measured.copy_from(&self.model.measure(&sigma.into_owned()));
        }
        let z_mean = self
            .model
            .measurement_mean(&sigmas_h, &self.points.mean_weights());
        Ok((sigmas_f, repaired, sigmas_h, z_mean))
    }

    /// The correction from the measurement residuals `dz` of the points
    /// `sigmas_f` (columns) and the innovation, with noise `r` (`K`
    /// measured components): `S`, `P_xz`, the gain, and `x, P` updated.
    /// Returns the gain and `S`, or the outcome of a failure (counted).
    fn correct<const K: usize>(
        &mut self,
        sigmas_f: &SMatrix<f32, N, S>,
        dz: &SMatrix<f32, K, S>,
        innovation: &SVector<f32, K>,
        r: &SMatrix<f32, K, K>,
    ) -> Result<(SMatrix<f32, N, K>, SMatrix<f32, K, K>), UkfOutcome> {
        let mut s = *r;
        let mut cross = SMatrix::<f32, N, K>::zeros();
        for ((sigma_f, d), &w) in sigmas_f
            .column_iter()
            .zip(dz.column_iter())
            .zip(self.points.covariance_weights().iter())
        {
            let dx = self.model.state_residual(&sigma_f.into_owned(), &self.x);
            s += d * d.transpose() * w;
            cross += dx * d.transpose() * w;
        }
        if !(all_finite(&s) && all_finite(&cross)) {
            bump(&mut self.counters.non_finite_results);
            return Err(UkfOutcome::NonFiniteResult);
        }
        let Some(gain) = kalman_gain(&cross, &s) else {
            bump(&mut self.counters.singular_innovations);
            return Err(UkfOutcome::SingularInnovation);
        };
        let x = self.x + gain * innovation;
        let p = self.p - gain * s * gain.transpose();
        if !(all_finite(&x) && all_finite(&p) && all_finite(&gain) && all_finite(innovation)) {
            bump(&mut self.counters.non_finite_results);
            return Err(UkfOutcome::NonFiniteResult);
        }
        self.x = x;
        self.p = symmetrize(&p);
        self.sigmas_f_fresh = false;
        Ok((gain, s))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    type V3 = SVector<f32, 3>;
    type M3 = SMatrix<f32, 3, 3>;

    /// Paper 004's scenario-1 kinematics, full-state measurement, angle
    /// hooks on ψ.
    #[derive(Debug, Clone, Copy, PartialEq)]
    struct Unicycle;

    const PSI: [usize; 1] = [2];

    impl UkfModel<3, 3> for Unicycle {
        type Input = [f32; 2];
        fn input_is_finite(&self, u: &[f32; 2]) -> bool {
            u.iter().all(|v| v.is_finite())
        }
        fn transition(&self, x: &V3, u: &[f32; 2], dt: f32) -> V3 {
            let [v, w] = *u;
            V3::new(
                x[0] + dt * v * math::cos(x[2]),
                x[1] + dt * v * math::sin(x[2]),
                x[2] + dt * w,
            )
        }
        fn measure(&self, x: &V3) -> V3 {
            *x
        }
        fn state_residual(&self, a: &V3, b: &V3) -> V3 {
            residual_with_angles(a, b, &PSI)
        }
        fn measurement_residual(&self, a: &V3, b: &V3) -> V3 {
            residual_with_angles(a, b, &PSI)
        }
        fn state_mean<const S: usize>(
            &self,
            sigmas: &SMatrix<f32, 3, S>,
            weights: &SVector<f32, S>,
        ) -> V3 {
            unscented_mean_with_angles(sigmas, weights, &PSI)
        }
        fn measurement_mean<const S: usize>(
            &self,
            sigmas: &SMatrix<f32, 3, S>,
            weights: &SVector<f32, S>,
        ) -> V3 {
            unscented_mean_with_angles(sigmas, weights, &PSI)
        }
    }

    fn unicycle_filter(alpha: f32) -> UnscentedKalmanFilter<Unicycle, 3, 3, 7> {
        UnscentedKalmanFilter::new(
            Unicycle,
            MerweScaledSigmaPoints::new(alpha, 2.0, 0.0).unwrap(),
            V3::new(0.0, 0.0, 0.5),
            M3::from_diagonal(&V3::new(1.0, 1.0, 0.2)),
            M3::identity() * 1e-4,
            M3::from_diagonal(&V3::new(0.1, 0.1, 0.2)),
        )
        .unwrap()
    }

    /// A linear system `x⁺ = A x + B u`, `z = H x`.
    #[derive(Debug, Clone, Copy, PartialEq)]
    struct Linear {
        a: SMatrix<f32, 2, 2>,
        b: SVector<f32, 2>,
        h: SMatrix<f32, 1, 2>,
    }

    impl UkfModel<2, 1> for Linear {
        type Input = f32;
        fn input_is_finite(&self, u: &f32) -> bool {
            u.is_finite()
        }
        fn transition(&self, x: &SVector<f32, 2>, u: &f32, _dt: f32) -> SVector<f32, 2> {
            self.a * x + self.b * *u
        }
        fn measure(&self, x: &SVector<f32, 2>) -> SVector<f32, 1> {
            self.h * x
        }
    }

    fn spd() -> M3 {
        M3::new(0.3, 0.1, 0.02, 0.1, 0.25, -0.03, 0.02, -0.03, 0.1)
    }

    #[test]
    fn sigma_point_count_is_checked() {
        assert_eq!(
            MerweScaledSigmaPoints::<3, 6>::new(0.5, 2.0, 0.0),
            Err(UkfError::SigmaPointCount)
        );
        assert_eq!(
            MerweScaledSigmaPoints::<3, 8>::new(0.5, 2.0, 0.0),
            Err(UkfError::SigmaPointCount)
        );
        assert_eq!(
            MerweScaledSigmaPoints::<0, 1>::new(0.5, 2.0, 0.0),
            Err(UkfError::SigmaPointCount)
        );
        assert!(MerweScaledSigmaPoints::<3, 7>::new(0.5, 2.0, 0.0).is_ok());
        assert!(MerweScaledSigmaPoints::<1, 3>::paper().is_ok());
    }

    #[test]
    fn parameters_are_validated() {
        type P = MerweScaledSigmaPoints<3, 7>;
        assert_eq!(P::new(0.0, 2.0, 0.0), Err(UkfError::Alpha));
        assert_eq!(P::new(f32::NAN, 2.0, 0.0), Err(UkfError::Alpha));
        assert_eq!(P::new(0.5, f32::INFINITY, 0.0), Err(UkfError::Beta));
        assert_eq!(P::new(0.5, 2.0, -3.0), Err(UkfError::Kappa));
        assert_eq!(P::new(0.5, 2.0, f32::NAN), Err(UkfError::Kappa));
        assert_eq!(P::new(1e-30, 2.0, 0.0), Err(UkfError::Spread));
        let points = P::new(0.5, 2.0, 0.0).unwrap();
        let bad_p0 = M3::new(1.0, 2.0, 0.0, 2.0, 1.0, 0.0, 0.0, 0.0, 1.0);
        let new = |x0: V3, p0: M3, q: M3, r: M3| {
            UnscentedKalmanFilter::new(Unicycle, points, x0, p0, q, r).map(|_| ())
        };
        let i = M3::identity();
        assert_eq!(
            new(V3::new(f32::NAN, 0.0, 0.0), i, i, i),
            Err(UkfError::InitialState)
        );
        assert_eq!(
            new(V3::zeros(), bad_p0, i, i),
            Err(UkfError::InitialCovariance)
        );
        assert_eq!(
            new(V3::zeros(), M3::zeros(), i, i),
            Err(UkfError::InitialCovariance)
        );
        assert_eq!(new(V3::zeros(), i, -i, i), Err(UkfError::ProcessNoise));
        assert_eq!(
            new(V3::zeros(), i, i, bad_p0),
            Err(UkfError::MeasurementNoise)
        );
        // Q = 0 and a singular R are allowed (semi-definite).
        assert_eq!(new(V3::zeros(), i, M3::zeros(), M3::zeros()), Ok(()));
    }

    /// The mean weights sum to one; the values are FilterPy's.
    #[test]
    fn weights() {
        for (alpha, kappa) in [
            (0.01_f32, 0.0_f32),
            (0.001, 0.0),
            (0.5, 0.0),
            (1.0, 0.0),
            (0.3, 1.0),
        ] {
            let points = MerweScaledSigmaPoints::<3, 7>::new(alpha, 2.0, kappa).unwrap();
            let wm = points.mean_weights();
            let wc = points.covariance_weights();
            let sum: f64 = wm.iter().map(|&w| f64::from(w)).sum();
            let size: f64 = wm.iter().map(|&w| f64::from(w).abs()).sum();
            assert!(
                (sum - 1.0).abs() <= size * f64::from(f32::EPSILON),
                "α {alpha}: Σ Wm − 1 = {:e}",
                sum - 1.0
            );
            let (a, k) = (f64::from(alpha), f64::from(kappa));
            let lambda = a * a * (3.0 + k) - 3.0;
            let expect_w0 = lambda / (3.0 + lambda);
            let expect_wi = 0.5 / (3.0 + lambda);
            let close =
                |got: f32, want: f64| (f64::from(got) - want).abs() <= 1e-6 * want.abs().max(1.0);
            assert!(close(wm[0], expect_w0), "{} {}", wm[0], expect_w0);
            assert!(close(wc[0], expect_w0 + 1.0 - a * a + 2.0));
            for k in 1..7 {
                assert!(close(wm[k], expect_wi) && wm[k] == wc[k]);
            }
            assert!(close(points.lambda(), lambda));
            assert!(close(points.gamma(), (3.0 + lambda).sqrt()));
        }
        // The paper's: W0 = −9999, Wi = 1666.67.
        let paper = MerweScaledSigmaPoints::<3, 7>::paper().unwrap();
        assert!((paper.mean_weights()[0] + 9999.0).abs() < 1e-2);
        assert!((paper.mean_weights()[1] - 1666.6667).abs() < 1e-3);
    }

    /// The points are FilterPy's (rows of scipy's upper factor = columns of
    /// the lower one, `+` half first) and their unscented transform
    /// reproduces `x` and `P`.
    #[test]
    fn sigma_points_reproduce_mean_and_covariance() {
        let x = V3::new(1.0, -2.0, 0.5);
        let p = spd();
        for (alpha, tol) in [(1.0_f32, 1e-6_f32), (0.5, 1e-6), (0.01, 1e-3)] {
            let points = MerweScaledSigmaPoints::<3, 7>::new(alpha, 2.0, 0.0).unwrap();
            let sigmas = points.sigma_points(&x, &p).unwrap();
            let l = (p * points.spread).cholesky().unwrap().l();
            for k in 0..3 {
                assert_eq!(sigmas.column(0), x);
                assert_eq!(sigmas.column(k + 1), x + l.column(k));
                assert_eq!(sigmas.column(k + 4), x - l.column(k));
            }
            // The points are x ± Lₖ rounded to f32 (ε|x|/2 each); the mean
            // weighs that rounding by Σ|Wᵢ| (1e4 for α = 0.01).
            let spread: f32 = points.mean_weights().iter().skip(1).map(|w| w.abs()).sum();
            let mean = unscented_mean(&sigmas, &points.mean_weights());
            let mean_tol = spread * f32::EPSILON * x.amax();
            assert!((mean - x).amax() < mean_tol, "α {alpha}: {mean}");
            let mut cov = M3::zeros();
            for (s, &w) in sigmas.column_iter().zip(points.covariance_weights().iter()) {
                let d = s - mean;
                cov += d * d.transpose() * w;
            }
            let err = (cov - p).amax() / p.amax();
            assert!(err < tol, "α {alpha}: relative error {err:e}");
        }
    }

    /// On a linear system the UKF is the Kalman filter, with FilterPy
    /// 1.4.5's twist: the update's `S` and `Pxy` come from the propagated
    /// points, which do not carry `Q` (module docs). With `Q = 0` that is
    /// the Kalman filter exactly; with `Q ≠ 0` it is the Kalman filter
    /// whose `S = H(P⁻ − Q)Hᵀ + R` and `Pxy = (P⁻ − Q)Hᵀ`.
    #[test]
    fn linear_system_is_the_kalman_filter() {
        let model = Linear {
            a: SMatrix::<f32, 2, 2>::new(1.0, 0.1, 0.0, 0.95),
            b: SVector::<f32, 2>::new(0.005, 0.1),
            h: SMatrix::<f32, 1, 2>::new(1.0, 0.0),
        };
        let r = SMatrix::<f32, 1, 1>::new(0.04);
        let x0 = SVector::<f32, 2>::new(0.5, -0.2);
        let p0 = SMatrix::<f32, 2, 2>::new(1.0, 0.3, 0.3, 0.5);
        let noisy = SMatrix::<f32, 2, 2>::new(1e-3, 2e-4, 2e-4, 2e-3);
        for q in [SMatrix::<f32, 2, 2>::zeros(), noisy] {
            for alpha in [0.01_f32, 0.5, 1.0] {
                let points = MerweScaledSigmaPoints::<2, 5>::new(alpha, 2.0, 0.0).unwrap();
                // The f32 rounding of the points (|x| ≤ 1), amplified by
                // Σ|Wᵢ| (1e4 for α = 0.01: module docs), and some growth
                // over the run; 1e-5 otherwise.
                let spread: f32 = points.mean_weights().iter().skip(1).map(|w| w.abs()).sum();
                let tol = (5.0 * spread * f32::EPSILON).max(1e-5);
                let mut ukf = UnscentedKalmanFilter::new(model, points, x0, p0, q, r).unwrap();
                let (mut x, mut p) = (x0, p0);
                let mut worst = (0.0_f32, 0.0_f32);
                for k in 0..50_u8 {
                    let u = 0.3 * f32::from(k % 7) - 0.8;
                    let z = SVector::<f32, 1>::new(0.02 * f32::from(k) - 0.5 * f32::from(k % 3));
                    assert_eq!(ukf.predict(&u, 0.1), UkfOutcome::Applied);
                    x = model.a * x + model.b * u;
                    let without_q = model.a * p * model.a.transpose();
                    p = without_q + q;
                    assert_eq!(ukf.update(&z), UkfOutcome::Applied);
                    let s = model.h * without_q * model.h.transpose() + r;
                    let k_gain = without_q * model.h.transpose() * s.try_inverse().unwrap();
                    x += k_gain * (z - model.h * x);
                    p -= k_gain * s * k_gain.transpose();
                    worst.0 = worst.0.max((ukf.state() - x).amax());
                    worst.1 = worst.1.max((ukf.covariance() - p).amax() / p.amax());
                    assert!((ukf.innovation_covariance() - s).amax() < tol * s.amax());
                }
                println!(
                    "α {alpha}, |Q| {}: worst |Δx| {:.1e}, |ΔP|/|P| {:.1e} (tolerance {tol:.1e})",
                    q.amax(),
                    worst.0,
                    worst.1
                );
                assert!(
                    worst.0 < tol && worst.1 < tol,
                    "α {alpha}, Q {q}: {worst:?} ≥ {tol}"
                );
                assert_eq!(ukf.counters(), UkfCounters::default());
            }
        }
    }

    /// A linear system measured in full (`h = I`).
    #[derive(Debug, Clone, Copy, PartialEq)]
    struct FullyMeasured(SMatrix<f32, 2, 2>);

    impl UkfModel<2, 2> for FullyMeasured {
        type Input = f32;
        fn input_is_finite(&self, u: &f32) -> bool {
            u.is_finite()
        }
        fn transition(&self, x: &SVector<f32, 2>, u: &f32, _dt: f32) -> SVector<f32, 2> {
            self.0 * x + SVector::<f32, 2>::new(0.0, *u)
        }
        fn measure(&self, x: &SVector<f32, 2>) -> SVector<f32, 2> {
            *x
        }
    }

    /// With the update's points redrawn from `(x⁻, P⁻)`, one-component
    /// updates of a linear system are the scalar Kalman filter, `Q` and
    /// all (where the reused points leave `Q` out); the innovation, its
    /// covariance and the gain are reported in full shape, zero outside the
    /// component; a bad index or variance is refused and counted.
    #[test]
    fn component_updates_are_the_scalar_kalman_filter() {
        let a = SMatrix::<f32, 2, 2>::new(1.0, 0.1, 0.0, 0.95);
        let q = SMatrix::<f32, 2, 2>::new(1e-3, 2e-4, 2e-4, 2e-3);
        let (x0, p0) = (
            SVector::<f32, 2>::new(0.5, -0.2),
            SMatrix::<f32, 2, 2>::new(1.0, 0.3, 0.3, 0.5),
        );
        let points = MerweScaledSigmaPoints::<2, 5>::new(1.0, 2.0, 0.0).unwrap();
        let mut ukf =
            UnscentedKalmanFilter::new(FullyMeasured(a), points, x0, p0, q, SMatrix::identity())
                .unwrap()
                .with_redrawn_update_points();
        let (mut x, mut p) = (x0, p0);
        let mut worst = 0.0_f32;
        for k in 0..40_u8 {
            let u = 0.2 * f32::from(k % 5) - 0.4;
            assert_eq!(ukf.predict(&u, 0.1), UkfOutcome::Applied);
            x = a * x + SVector::<f32, 2>::new(0.0, u);
            p = a * p * a.transpose() + q;
            let index = usize::from(k % 2);
            let (z, r) = (0.05 * f32::from(k) - 0.3, 0.01 + 0.01 * f32::from(k % 3));
            assert_eq!(ukf.update_component(index, z, r), UkfOutcome::Applied);
            let s = p[(index, index)] + r;
            let gain = p.column(index) / s;
            let innovation = z - x[index];
            x += gain * innovation;
            p -= gain * gain.transpose() * s;
            worst = worst
                .max((ukf.state() - x).amax())
                .max((ukf.covariance() - p).amax());
            let other = 1 - index;
            assert!((ukf.innovation()[index] - innovation).abs() < 1e-4);
            assert_eq!(ukf.innovation()[other], 0.0);
            assert!((ukf.innovation_covariance()[(index, index)] - s).abs() < 1e-4);
            assert_eq!(ukf.gain().column(other).amax(), 0.0);
        }
        assert!(worst < 1e-5, "{worst}");
        for (index, z, r) in [(2, 0.0, 1.0), (0, f32::NAN, 1.0), (0, 0.0, -1.0)] {
            assert_eq!(ukf.update_component(index, z, r), UkfOutcome::RejectedInput);
        }
        assert_eq!(ukf.counters().rejected_inputs, 3);
    }

    /// A `P` that is not positive definite: a rounding-sized defect is
    /// repaired by the jitter; a real one resets `P` to `P0` and skips.
    #[test]
    fn cholesky_failure_repairs_or_resets() {
        let mut ukf = unicycle_filter(0.5);
        // Singular (semi-definite) P: the jitter repairs it.
        ukf.p = M3::new(1.0, 1.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.1);
        assert_eq!(ukf.predict(&[1.0, 0.1], 0.1), UkfOutcome::Repaired);
        assert_eq!(ukf.counters().covariance_repairs, 1);
        assert!(ukf.covariance().iter().all(|v| v.is_finite()));
        // Indefinite P: reset and skipped.
        let x = *ukf.state();
        ukf.p = M3::new(1.0, 2.0, 0.0, 2.0, 1.0, 0.0, 0.0, 0.0, 1.0);
        assert_eq!(ukf.predict(&[1.0, 0.1], 0.1), UkfOutcome::CovarianceReset);
        assert_eq!(ukf.counters().covariance_resets, 1);
        assert_eq!(ukf.covariance(), ukf.initial_covariance());
        assert_eq!(*ukf.state(), x);
        assert!(ukf.propagated_sigma_points().is_none());
        // And the filter goes on from there.
        assert_eq!(ukf.predict(&[1.0, 0.1], 0.1), UkfOutcome::Applied);
        // An update with no fresh points draws them, and resets the same way.
        ukf.p = -M3::identity();
        assert_eq!(ukf.update(&V3::zeros()), UkfOutcome::Applied);
        ukf.p = -M3::identity();
        assert_eq!(ukf.update(&V3::zeros()), UkfOutcome::CovarianceReset);
        assert_eq!(ukf.counters().covariance_resets, 2);
    }

    #[test]
    fn bad_input_is_skipped_and_counted() {
        let mut ukf = unicycle_filter(0.01);
        assert_eq!(ukf.predict(&[0.5, 0.2], 0.005), UkfOutcome::Applied);
        let (x, p) = (*ukf.state(), *ukf.covariance());
        assert_eq!(
            ukf.update(&V3::new(f32::NAN, 0.0, 0.0)),
            UkfOutcome::RejectedInput
        );
        assert_eq!(
            ukf.update_with_noise(&V3::zeros(), &(M3::identity() * f32::INFINITY)),
            UkfOutcome::RejectedInput
        );
        assert_eq!(
            ukf.predict(&[f32::NAN, 0.2], 0.005),
            UkfOutcome::RejectedInput
        );
        assert_eq!(
            ukf.predict(&[0.5, 0.2], f32::NAN),
            UkfOutcome::RejectedInput
        );
        assert_eq!(ukf.predict(&[0.5, 0.2], -0.005), UkfOutcome::RejectedInput);
        // Finite input, non-finite result (overflow in f).
        assert_eq!(ukf.predict(&[3e38, 0.2], 1e3), UkfOutcome::NonFiniteResult);
        assert_eq!(ukf.counters().rejected_inputs, 5);
        assert_eq!(ukf.counters().non_finite_results, 1);
        assert_eq!((*ukf.state(), *ukf.covariance()), (x, p));
        // Still works afterwards.
        assert_eq!(ukf.predict(&[0.5, 0.2], 0.005), UkfOutcome::Applied);
        assert_eq!(ukf.update(&V3::new(0.0, 0.0, 0.5)), UkfOutcome::Applied);
    }

    /// A measurement that carries no information and no noise: `S = 0`.
    #[test]
    fn singular_innovation_is_skipped() {
        let model = Linear {
            a: SMatrix::<f32, 2, 2>::identity(),
            b: SVector::<f32, 2>::zeros(),
            h: SMatrix::<f32, 1, 2>::zeros(),
        };
        let points = MerweScaledSigmaPoints::<2, 5>::new(0.5, 2.0, 0.0).unwrap();
        let mut ukf = UnscentedKalmanFilter::new(
            model,
            points,
            SVector::zeros(),
            SMatrix::identity(),
            SMatrix::zeros(),
            SMatrix::zeros(),
        )
        .unwrap();
        assert_eq!(ukf.predict(&0.0, 0.1), UkfOutcome::Applied);
        let x = *ukf.state();
        assert_eq!(
            ukf.update(&SVector::<f32, 1>::new(1.0)),
            UkfOutcome::SingularInnovation
        );
        assert_eq!(ukf.counters().singular_innovations, 1);
        assert_eq!(*ukf.state(), x);
        // The points are still those of the predict.
        assert!(ukf.propagated_sigma_points().is_some());
    }

    /// The update reuses σf: after a predict, the update's cross covariance
    /// comes from the propagated points, not from points redrawn at x⁻.
    #[test]
    fn update_reuses_the_propagated_points() {
        let mut a = unicycle_filter(0.5);
        let mut b = a;
        let z = V3::new(0.1, 0.2, 0.4);
        a.predict(&[2.0, 3.0], 0.2);
        b.predict(&[2.0, 3.0], 0.2);
        let kept = *a.propagated_sigma_points().unwrap();
        assert_eq!(a.update(&z), UkfOutcome::Applied);
        assert!(a.propagated_sigma_points().is_none());
        // Redrawn from (x⁻, P⁻): not the same update (f is nonlinear).
        b.sigmas_f_fresh = false;
        assert_eq!(b.update(&z), UkfOutcome::Applied);
        assert!((a.state() - b.state()).amax() > 1e-5);
        // The propagated points are 7 distinct images of the prior's.
        assert!(kept.column(1) != kept.column(4));
    }

    #[test]
    fn angles_wrap_through_pi() {
        let points = MerweScaledSigmaPoints::<1, 3>::new(1.0, 2.0, 0.0).unwrap();
        let w = points.mean_weights();
        let sigmas = SMatrix::<f32, 1, 3>::new(3.1, -3.1, 3.0);
        let mean = unscented_mean_with_angles(&sigmas, &w, &[0, 7]);
        let sum_sin: f32 = sigmas
            .iter()
            .zip(w.iter())
            .map(|(&a, &w)| w * a.sin())
            .sum();
        let sum_cos: f32 = sigmas
            .iter()
            .zip(w.iter())
            .map(|(&a, &w)| w * a.cos())
            .sum();
        assert!((mean[0] - sum_sin.atan2(sum_cos)).abs() < 1e-5, "{mean}");
        let d = residual_with_angles(
            &SVector::<f32, 2>::new(3.1, 3.1),
            &SVector::<f32, 2>::new(-3.1, -3.1),
            &[1, 9],
        );
        assert!((d[0] - 6.2).abs() < 1e-6 && (d[1] - (6.2 - math::TAU)).abs() < 1e-5);
        // The filter crosses π without a jump.
        let mut ukf = unicycle_filter(0.01);
        ukf.reset(V3::new(0.0, 0.0, 3.1), M3::identity() * 0.01)
            .unwrap();
        for _ in 0..20 {
            ukf.predict(&[0.5, 1.0], 0.01);
            ukf.update(&V3::new(0.0, 0.0, -3.1));
        }
        let psi = ukf.state()[2];
        assert!(math::wrap_angle(psi + 3.1).abs() < 0.2, "{}", ukf.state());
        assert_eq!(ukf.counters(), UkfCounters::default());
    }

    proptest! {
        /// The array-based `unscented_mean` gives, bit for bit, what the
        /// column-view version it replaced gave (`σ₀ + Σ Wᵢ(σᵢ − σ₀)`
        /// through `column_iter`), for any finite points and weights.
        #[test]
        fn unscented_mean_is_bitwise_the_column_view_formula(
            points in proptest::collection::vec(-1e3_f32..1e3, 3 * 7),
            weights in proptest::collection::vec(-1e4_f32..1e4, 7),
        ) {
            let sigmas = SMatrix::<f32, 3, 7>::from_column_slice(&points);
            let weights = SVector::<f32, 7>::from_column_slice(&weights);
            let mut columns = sigmas.column_iter();
            let centre = columns.next().unwrap();
            let mut offset = SVector::<f32, 3>::zeros();
            for (column, &w) in columns.zip(weights.iter().skip(1)) {
                offset += (column - centre) * w;
            }
            let before = centre + offset;
            let now = unscented_mean(&sigmas, &weights);
            for (a, b) in now.iter().zip(before.iter()) {
                prop_assert_eq!(a.to_bits(), b.to_bits());
            }
        }

        /// Finite inputs and measurements never give a non-finite estimate.
        #[test]
        fn finite_in_finite_out(
            steps in proptest::collection::vec(
                (proptest::array::uniform2(-5f32..5.0), proptest::array::uniform3(-10f32..10.0)),
                1..30),
            alpha in prop_oneof![Just(0.01f32), Just(0.5), Just(1.0)],
        ) {
            let mut ukf = unicycle_filter(alpha);
            for (u, z) in &steps {
                ukf.predict(u, 0.05);
                ukf.update(&V3::from(*z));
                prop_assert!(ukf.state().iter().all(|v| v.is_finite()));
                prop_assert!(ukf.covariance().iter().all(|v| v.is_finite()));
            }
        }
    }
}
