//! Van der Merwe's scaled sigma points, their weights and the unscented
//! means and residuals (module docs of [`super`]).

use nalgebra::{SMatrix, SVector};

use crate::math;

use super::UkfError;
use super::factor::rank_one_update;

/// Van der Merwe's scaled sigma points for `N` states (FilterPy's
/// `MerweScaledSigmaPoints(n, alpha, beta, kappa)` with its default
/// Cholesky square root): the parameters and the `S = 2N + 1` weights.
///
/// `S` is a separate const parameter only because stable Rust cannot write
/// `SMatrix<f32, N, { 2 * N + 1 }>` (`generic_const_exprs` is unstable);
/// [`Self::new`] checks `S = 2N + 1` (and `N ≥ 1`) when it is compiled, so
/// a wrong count is a build error, not a run-time one:
/// ```
/// use wmr_core::filters::ukf::MerweScaledSigmaPoints;
/// assert!(MerweScaledSigmaPoints::<3, 7>::new(0.5, 2.0, 0.0).is_ok());
/// ```
/// ```compile_fail
/// use wmr_core::filters::ukf::MerweScaledSigmaPoints;
/// // 6 ≠ 2·3 + 1: "the sigma-point count S must be 2N + 1 with N > 0".
/// let _ = MerweScaledSigmaPoints::<3, 6>::new(0.5, 2.0, 0.0);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MerweScaledSigmaPoints<const N: usize, const S: usize> {
    alpha: f32,
    beta: f32,
    kappa: f32,
    /// `n + λ = α²(n + κ)`.
    pub(super) spread: f32,
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
    /// The first of [`UkfError::Alpha`], [`UkfError::Beta`],
    /// [`UkfError::Kappa`], [`UkfError::Spread`] out of range. `S = 2N + 1`
    /// and `N ≥ 1` are checked when the call is compiled (type docs).
    pub fn new(alpha: f32, beta: f32, kappa: f32) -> Result<Self, UkfError> {
        const {
            assert!(
                N > 0 && S == 2 * N + 1,
                "the sigma-point count S must be 2N + 1 with N > 0"
            );
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
    /// None for these parameters (the `Result` is [`Self::new`]'s).
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

    /// `√(β − α²)`, the weight of the square-root form's centre term
    /// (module docs, "Square-root form"), if `β ≥ α²`.
    pub(super) fn centre_term(&self) -> Option<f32> {
        let excess = self.beta - self.alpha * self.alpha;
        (excess >= 0.0).then(|| math::sqrt(excess))
    }

    /// A factor `L` of `base baseᵀ + Σ_{i≥1} Wᵢ dᵢ dᵢᵀ + (β − α²) d₀ d₀ᵀ`
    /// for deviations `d` centred on the first point (column 0: the mean's
    /// deviation), by rank-one updates of `base`: the square-root form's
    /// `qr` and `cholupdate` (module docs). It equals the factor of
    /// `Σᵢ Wᵢᶜ (σᵢ − x̄)(σᵢ − x̄)ᵀ` (+ `base baseᵀ`) for a linear mean.
    pub(super) fn centred_factor<const R: usize>(
        &self,
        base: SMatrix<f32, R, R>,
        deviations: &SMatrix<f32, R, S>,
    ) -> SMatrix<f32, R, R> {
        let mut l = base;
        let Some((centre, others)) = deviations.data.0.split_first() else {
            return l;
        };
        let centre_weight = self.centre_term().unwrap_or(0.0);
        rank_one_update(&mut l, &(SVector::from(*centre) * centre_weight));
        let w = math::sqrt(self.point_weight);
        for column in others {
            rank_one_update(&mut l, &(SVector::from(*column) * w));
        }
        l
    }

    /// `Σ_{i≥1} Wᵢ aᵢ bᵢᵀ + (β − α²) a₀ b₀ᵀ` for deviations centred on the
    /// first point: the cross covariance of [`Self::centred_factor`].
    pub(super) fn centred_cross<const R: usize, const K: usize>(
        &self,
        a: &SMatrix<f32, R, S>,
        b: &SMatrix<f32, K, S>,
    ) -> SMatrix<f32, R, K> {
        let mut cross = SMatrix::<f32, R, K>::zeros();
        let excess = self.beta - self.alpha * self.alpha;
        for (i, (a, b)) in a.data.0.iter().zip(b.data.0.iter()).enumerate() {
            let w = if i == 0 { excess } else { self.point_weight };
            cross += SVector::<f32, R>::from(*a) * SVector::<f32, K>::from(*b).transpose() * w;
        }
        cross
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
pub(super) fn lower_factor<const N: usize>(a: &SMatrix<f32, N, N>) -> Option<SMatrix<f32, N, N>> {
    let l = nalgebra::Cholesky::new(*a)?.l();
    l.iter().all(|v| v.is_finite()).then_some(l)
}

/// `[x, x + L₀ … x + L_{n−1}, x − L₀ … x − L_{n−1}]` (columns `Lₖ` of `l`).
pub(super) fn points_from_factor<const N: usize, const S: usize>(
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

/// The weighted mean `Σ Wᵢ σᵢ` of the columns of `sigmas`, evaluated as
/// `σ₀ + Σ_{i≥1} Wᵢ(σᵢ − σ₀)`: the same for weights that sum to one (the
/// contract; `weights[0]` is not read), without the cancellation of
/// `|W₀| ~ 10⁴` (module docs). The filter's mean for components that are
/// not angles ([`AngleComponents`]), FilterPy's `np.dot(Wm, sigmas)`.
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
    mean_with_angle_indices(sigmas, weights, angles.iter().copied())
}

/// [`unscented_mean_with_angles`] for the angle components `angles`.
fn mean_with_angle_indices<const R: usize, const S: usize>(
    sigmas: &SMatrix<f32, R, S>,
    weights: &SVector<f32, S>,
    angles: impl Iterator<Item = usize>,
) -> SVector<f32, R> {
    let mut mean = unscented_mean(sigmas, weights);
    for i in angles {
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
    residual_with_angle_indices(a, b, angles.iter().copied())
}

/// [`residual_with_angles`] for the angle components `angles`.
fn residual_with_angle_indices<const R: usize>(
    a: &SVector<f32, R>,
    b: &SVector<f32, R>,
    angles: impl Iterator<Item = usize>,
) -> SVector<f32, R> {
    let mut d = a - b;
    for i in angles {
        if let Some(v) = d.get_mut(i) {
            *v = math::wrap_angle(*v);
        }
    }
    d
}

/// Which components of a model's state (`N`) and measurement (`M`) are
/// angles in radians: the one setting ([`super::UkfModel::angles`]) from
/// which the filter takes FilterPy's four hooks, `residual_x` and
/// `residual_z` (differences wrapped to (−π, π], [`residual_with_angles`])
/// and `x_mean_fn` and `z_mean_fn` (circular means,
/// [`unscented_mean_with_angles`]), so that a model cannot wrap an angle's
/// residuals and forget its mean.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AngleComponents<const N: usize, const M: usize> {
    state: [bool; N],
    measurement: [bool; M],
}

impl<const N: usize, const M: usize> AngleComponents<N, M> {
    /// No angles: plain differences and weighted means.
    pub const NONE: Self = Self {
        state: [false; N],
        measurement: [false; M],
    };

    /// `state[i]`: state component `i` is an angle; `measurement[j]`:
    /// measurement component `j` is.
    #[must_use]
    pub const fn new(state: [bool; N], measurement: [bool; M]) -> Self {
        Self { state, measurement }
    }

    /// The angles listed by index; indices `≥ N` (`≥ M`) are ignored, as
    /// [`residual_with_angles`] ignores them.
    #[must_use]
    #[allow(
        clippy::indexing_slicing,
        reason = "a const fn cannot use get_mut; every index is checked against its length first"
    )]
    pub const fn from_indices(state: &[usize], measurement: &[usize]) -> Self {
        let mut angles = Self::NONE;
        let mut k = 0;
        while k < state.len() {
            if state[k] < N {
                angles.state[state[k]] = true;
            }
            k += 1;
        }
        let mut k = 0;
        while k < measurement.len() {
            if measurement[k] < M {
                angles.measurement[measurement[k]] = true;
            }
            k += 1;
        }
        angles
    }

    /// Which state components are angles.
    #[must_use]
    pub const fn state(&self) -> [bool; N] {
        self.state
    }

    /// Which measurement components are angles.
    #[must_use]
    pub const fn measurement(&self) -> [bool; M] {
        self.measurement
    }

    /// `a − b` for states, angles wrapped.
    #[must_use]
    pub fn state_residual(&self, a: &SVector<f32, N>, b: &SVector<f32, N>) -> SVector<f32, N> {
        residual_with_angle_indices(a, b, indices(&self.state))
    }

    /// `a − b` for measurements, angles wrapped.
    #[must_use]
    pub fn measurement_residual(
        &self,
        a: &SVector<f32, M>,
        b: &SVector<f32, M>,
    ) -> SVector<f32, M> {
        residual_with_angle_indices(a, b, indices(&self.measurement))
    }

    /// The mean of state sigma points, circular for angles.
    #[must_use]
    pub fn state_mean<const S: usize>(
        &self,
        sigmas: &SMatrix<f32, N, S>,
        weights: &SVector<f32, S>,
    ) -> SVector<f32, N> {
        mean_with_angle_indices(sigmas, weights, indices(&self.state))
    }

    /// The mean of measurement sigma points, circular for angles.
    #[must_use]
    pub fn measurement_mean<const S: usize>(
        &self,
        sigmas: &SMatrix<f32, M, S>,
        weights: &SVector<f32, S>,
    ) -> SVector<f32, M> {
        mean_with_angle_indices(sigmas, weights, indices(&self.measurement))
    }
}

/// The indices of the `true` flags.
fn indices<const K: usize>(flags: &[bool; K]) -> impl Iterator<Item = usize> + '_ {
    flags
        .iter()
        .enumerate()
        .filter_map(|(i, &angle)| angle.then_some(i))
}
