//! # A Gaussian estimate truncated to an interval
//! A read of an unchanged tag says the robot is still inside that tag's
//! cell: an inequality constraint on each position axis,
//! `low ≤ x ≤ high`. A Gaussian filter (the EKF, the UKF) enforces it by
//! density-function truncation (Simon & Simon, "Constrained Kalman
//! filtering via density function truncation for turbofan engine health
//! estimation", Int. J. Systems Science 41(2), 2010; Simon, "Kalman
//! filtering with state constraints: a survey of linear and nonlinear
//! algorithms", IET Control Theory & Applications 4(8), 2010, §2.5): the
//! estimate's marginal `N(μ, σ²)` along the axis is cut to the interval,
//! and the filter takes the truncated distribution's mean and variance.
//!
//! # Moments
//! With `α = (low − μ)/σ`, `β = (high − μ)/σ`, `φ` the standard normal
//! density and `Z = Φ(β) − Φ(α)` the mass inside (Johnson, Kotz &
//! Balakrishnan, "Continuous Univariate Distributions" vol. 1, §13.10.1):
//!
//! `μₜ = μ + σ (φ(α) − φ(β)) / Z`,
//! `σₜ² = σ² [1 + (α φ(α) − β φ(β)) / Z − ((φ(α) − φ(β)) / Z)²]`.
//!
//! With the mean outside the interval `Z` is a difference of two tail
//! probabilities and underflows `f32` a dozen σ out; the ratios are then
//! taken through Mills' ratio `M(a) = Q(a)/φ(a)` (`Q = 1 − Φ`):
//! `φ(α)/Z = 1 / (M(α) − e^{−(β²−α²)/2} M(β))` for `0 ≤ α < β`, finite at
//! any distance, with `M` from `erfc` up to `a = 8` and from its
//! asymptotic series `(1 − a⁻² + 3a⁻⁴ − 15a⁻⁶)/a` beyond (relative error
//! below `105 a⁻⁸`, 6e-6 at 8). From 8σ out the variance formula cancels
//! (`1 + αλ − λ²` with `λ ≈ α`), and the truncation is taken as that of
//! the exponential the density is there (within about `1/α²`). A mean
//! above the interval is mirrored.
//!
//! # As a measurement
//! The filters take the truncation as the scalar position measurement
//! whose Kalman update gives exactly those moments: from `σ²` to `σₜ²`
//! needs the noise variance `r = σ² σₜ² / (σ² − σₜ²)`, and from `μ` to
//! `μₜ` the value `z = μ + (μₜ − μ)(σ² + r)/σ²`. The update then moves
//! the correlated states (heading, wheel scales) as the axis' own
//! covariance says, and the filter's gate sees the Mahalanobis distance
//! `(μₜ − μ)² / (σ² − σₜ²)`.

use crate::math;

/// `1/√(2π)`: the standard normal density at 0.
const INV_SQRT_TAU: f32 = 0.398_942_3;

/// From this many standard deviations out, Mills' ratio from its
/// asymptotic series and the truncation as an exponential's (module docs).
const TAIL_FROM: f32 = 8.0;

/// A truncation that shrinks the variance by less than this fraction
/// carries no information worth an update (and its `r` would overflow).
const MIN_VARIANCE_REDUCTION: f32 = 1e-3;

/// The standard normal density `φ(a)`.
fn density(a: f32) -> f32 {
    math::exp(-0.5 * a * a) * INV_SQRT_TAU
}

/// The upper tail `Q(a) = 1 − Φ(a)`.
fn upper_tail(a: f32) -> f32 {
    0.5 * libm::erfcf(a * core::f32::consts::FRAC_1_SQRT_2)
}

/// Mills' ratio `Q(a)/φ(a)` for `a ≥ 0` (module docs).
fn mills_ratio(a: f32) -> f32 {
    if a < TAIL_FROM {
        upper_tail(a) / density(a)
    } else {
        let r = 1.0 / (a * a);
        (1.0 - r * (1.0 - r * (3.0 - 15.0 * r))) / a
    }
}

/// The truncation of `N(0, 1)` to `[a, a + w]`, `a ≥ 8`, as
/// `(mean, variance)`: there the density falls as `e^{−a t}` within the
/// interval (`t` from its near bound) to within `t²/2`, so the truncated
/// exponential's moments, `1/a − w e/(1 − e)` past the bound and
/// `1/a² − w² e/(1 − e)²`, `e = e^{−a w}` (uniform below `a w = 10⁻³`),
/// within about `1/a²` (1.6 % at 8) of the normal's, and without the
/// exact formula's cancellation.
fn far_tail(a: f32, w: f32) -> (f32, f32) {
    let aw = a * w;
    if aw < 1e-3 {
        return (a + 0.5 * w, w * w / 12.0);
    }
    let e = math::exp(-aw);
    let odds = e / (1.0 - e);
    (
        a + 1.0 / a - w * odds,
        1.0 / (a * a) - w * w * odds / (1.0 - e),
    )
}

/// The mean and variance of `N(mean, variance)` truncated to
/// `[low, high]` (module docs). `None` unless the inputs are finite,
/// `variance > 0` and `low < high`, or if the result is not finite.
#[must_use]
pub fn truncated_normal(mean: f32, variance: f32, low: f32, high: f32) -> Option<(f32, f32)> {
    if !(mean.is_finite() && variance.is_finite() && low.is_finite() && high.is_finite())
        || variance <= 0.0
        || low >= high
    {
        return None;
    }
    let sd = math::sqrt(variance);
    let (alpha, beta) = ((low - mean) / sd, (high - mean) / sd);
    // A mean above the interval, mirrored below it.
    let (mirrored, alpha, beta) = if beta <= 0.0 {
        (true, -beta, -alpha)
    } else {
        (false, alpha, beta)
    };
    let (pull, factor) = if alpha >= TAIL_FROM {
        far_tail(alpha, beta - alpha)
    } else {
        // (φ(α), φ(β)) / Z.
        let (low_ratio, high_ratio) = if alpha >= 0.0 {
            // Both bounds above the mean: tail ratios through Mills' ratio.
            let decay = math::exp(-0.5 * (beta - alpha) * (beta + alpha));
            let low_ratio = 1.0 / (mills_ratio(alpha) - decay * mills_ratio(beta));
            (low_ratio, decay * low_ratio)
        } else {
            // The mean inside: Z is at least the smaller half's mass.
            let inside = 1.0 - upper_tail(-alpha) - upper_tail(beta);
            (density(alpha) / inside, density(beta) / inside)
        };
        let pull = low_ratio - high_ratio;
        (
            pull,
            1.0 + alpha * low_ratio - beta * high_ratio - pull * pull,
        )
    };
    let pull = if mirrored { -pull } else { pull };
    let moments = (mean + sd * pull, variance * factor);
    (moments.0.is_finite() && factor > 0.0 && factor <= 1.0).then_some(moments)
}

/// The scalar position measurement `(z, r)` whose Kalman update turns
/// `N(mean, variance)` into its truncation to `[low, high]` (module docs,
/// "As a measurement"). `None` where [`truncated_normal`] has none or the
/// truncation shrinks the variance by less than a thousandth.
#[must_use]
pub fn truncation_measurement(mean: f32, variance: f32, low: f32, high: f32) -> Option<(f32, f32)> {
    let (truncated_mean, truncated_variance) = truncated_normal(mean, variance, low, high)?;
    let reduction = variance - truncated_variance;
    if reduction <= MIN_VARIANCE_REDUCTION * variance {
        return None;
    }
    let noise_variance = variance * truncated_variance / reduction;
    let value = mean + (truncated_mean - mean) * (variance + noise_variance) / variance;
    (value.is_finite() && noise_variance.is_finite() && noise_variance > 0.0)
        .then_some((value, noise_variance))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f32, b: f32, tolerance: f32) -> bool {
        (a - b).abs() <= tolerance * b.abs().max(1.0)
    }

    #[test]
    fn half_and_two_sided_truncations_match_their_closed_forms() {
        // N(0, 1) on [0, ∞): mean √(2/π), variance 1 − 2/π.
        let (mean, variance) = truncated_normal(0.0, 1.0, 0.0, 1e30).unwrap();
        assert!(close(mean, 0.797_884_6, 1e-5), "{mean}");
        assert!(close(variance, 0.363_380_2, 1e-5), "{variance}");
        // N(0, 1) on [−1, 1]: mean 0, variance 1 − 2φ(1)/(Φ(1) − Φ(−1)).
        let (mean, variance) = truncated_normal(0.0, 1.0, -1.0, 1.0).unwrap();
        assert!(mean.abs() < 1e-6, "{mean}");
        assert!(close(variance, 0.291_125_7, 1e-5), "{variance}");
        // Scaled and shifted: N(2, 4) on [2, 6] is 2 + 2·(N(0, 1) on [0, 2]),
        // whose mean is (φ(0) − φ(2))/(Φ(2) − ½) = 0.722_789_8 and variance
        // 1 − 2φ(2)/(Φ(2) − ½) − 0.722_789_8² = 0.251_316_3.
        let (mean, variance) = truncated_normal(2.0, 4.0, 2.0, 6.0).unwrap();
        assert!(close(mean, 2.0 + 2.0 * 0.722_789_8, 1e-5), "{mean}");
        assert!(close(variance, 4.0 * 0.251_316_3, 1e-4), "{variance}");
    }

    #[test]
    fn a_mean_far_outside_lands_just_inside_the_near_bound() {
        let relative = |a: f32, b: f32, tolerance: f32| (a - b).abs() <= tolerance * b.abs();
        // 3 σ out: N(0, 1) on [3, 13] has mean φ(3)/Q(3) = 3.283_099 and
        // variance 1 + 3·3.283_099 − 3.283_099² = 0.070_559 (the mass
        // beyond 13 is 1e-35 of it).
        let (mean, variance) = truncated_normal(0.0, 1.0, 3.0, 13.0).unwrap();
        assert!(relative(mean, 3.283_099, 1e-5), "{mean}");
        assert!(relative(variance, 0.070_559, 1e-3), "{variance}");
        // a σ out, a ≥ 8 (Mills' series): the mean is a + 1/a − 2/a³ + …
        // and the standard deviation 1/a (1 − O(a⁻²)), at any distance (no
        // underflow).
        for a in [7.9_f32, 8.1, 20.0, 1e3, 1e6] {
            let (mean, variance) = truncated_normal(0.0, 1.0, a, a + 10.0).unwrap();
            let inside = (1.0 - 2.0 / (a * a)) / a;
            // Within 5 %, or within two roundings of `mean` where `1/a` is
            // below them.
            let rounding = 2.0 * f32::EPSILON * a;
            assert!(
                relative(mean - a, inside, 0.05) || (mean - a).abs() <= inside + rounding,
                "a {a}: {mean}"
            );
            assert!(
                relative(variance.sqrt(), 1.0 / a, 0.05),
                "a {a}: {variance}"
            );
            // Mirrored: the same distance above the interval.
            let (above, same) = truncated_normal(0.0, 1.0, -a - 10.0, -a).unwrap();
            assert_eq!((above, same), (-mean, variance));
        }
    }

    #[test]
    fn the_measurement_s_kalman_update_gives_the_truncated_moments() {
        for (mean, variance, low, high) in [
            (0.0_f32, 1.0_f32, 0.5_f32, 3.0_f32),
            (0.13, 4e-4, 0.05, 0.15),
            (-0.2, 1e-2, -0.15, -0.05),
            (0.01, 1.6e-3, -0.05, 0.05),
        ] {
            let (target_mean, target_variance) =
                truncated_normal(mean, variance, low, high).unwrap();
            let (z, r) = truncation_measurement(mean, variance, low, high).unwrap();
            let gain = variance / (variance + r);
            let updated_mean = mean + gain * (z - mean);
            let updated_variance = (1.0 - gain) * variance;
            assert!(
                close(updated_mean, target_mean, 1e-4),
                "{updated_mean} {target_mean}"
            );
            assert!(
                close(
                    updated_variance / variance,
                    target_variance / variance,
                    1e-3
                ),
                "{updated_variance} {target_variance}"
            );
        }
    }

    #[test]
    fn a_truncation_that_tells_nothing_is_no_measurement() {
        // 10 σ inside on both sides: the variance shrinks by ~1e-22.
        assert!(truncation_measurement(0.0, 1e-6, -0.01, 0.01).is_none());
        assert!(truncated_normal(0.0, 1e-6, -0.01, 0.01).is_some());
    }

    #[test]
    fn bad_input_has_no_truncation() {
        for (mean, variance, low, high) in [
            (f32::NAN, 1.0, 0.0, 1.0),
            (0.0, f32::INFINITY, 0.0, 1.0),
            (0.0, 0.0, 0.0, 1.0),
            (0.0, -1.0, 0.0, 1.0),
            (0.0, 1.0, 1.0, 1.0),
            (0.0, 1.0, 2.0, 1.0),
            (0.0, 1.0, f32::NEG_INFINITY, 1.0),
        ] {
            assert!(truncated_normal(mean, variance, low, high).is_none());
            assert!(truncation_measurement(mean, variance, low, high).is_none());
        }
    }
}
