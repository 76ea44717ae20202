//! The one place the core calls transcendental functions.
//!
//! Every `sin`, `cos`, `atan2`, `sqrt`, `exp` in the core goes through this
//! module, so the backend can be swapped by a cargo feature and the
//! backends compared on the same code path:
//!
//! * default (no feature): `f32`-native. `sin`, `cos` and [`sincos`] are
//!   this crate's own [`kernels`] (`f32` argument reduction and Cephes
//!   polynomials); `atan`, `atan2`, `exp`, `ln`, `sqrt` and `floor` are the
//!   `libm` crate's `f32` functions, which are fdlibm's single-precision
//!   code (FreeBSD `s_atanf.c`, `e_atan2f.c`, `e_expf.c`, `e_logf.c`) and
//!   compute in `f32` and integers only (`sqrtf` is a correctly rounded
//!   integer algorithm on the Cortex-M4F: the `vsqrt.f32` instruction is
//!   out of reach without `unsafe` or nightly). Nothing in the default
//!   backend uses `f64`, so the firmware links no software double-precision
//!   routine (`cargo xtask size` fails if one appears).
//! * `libm`: everything from the `libm` crate, `sinf`/`cosf` included,
//!   whose argument reduction and kernels are in `f64` (software on a
//!   Cortex-M4F, about 1 300 instructions a call): for comparison.
//! * `micromath`: fast approximations (relative error up to a few 1e-3 for
//!   `atan2`, ~1e-3 for `sin`/`cos`); wins when another is enabled too.
//!
//! The host and the firmware compile the same backend from the same
//! source, and every function above is IEEE 754 `f32` arithmetic with no
//! fused multiply–add, so both compute the same bits (the HIL run relies
//! on it).
//!
//! # Accuracy of the default backend
//!
//! Maximum error in ulps of the `f32` result against `f64` references,
//! measured over **every** `f32` of each range (for `sin`, `cos` and
//! `atan` the positive ones: negative inputs run the same code and flip the
//! sign, which the strided test checks bit for bit), with
//! `cargo test -p wmr-core --release --lib math::ulp_tests -- --ignored --nocapture`
//! (`ulp_tests.rs`; the default `cargo test` runs a strided sweep of the
//! same ranges and asserts the same bounds):
//!
//! | function | implementation | range (every `f32` in it) | max error, ulp |
//! | --- | --- | --- | ---: |
//! | `sin` | [`kernels`] | `[0, π/4]` | 0.788 |
//! | `sin` | [`kernels`] | `(π/4, 2π]` | 0.835 |
//! | `sin` | [`kernels`] | `(2π, 128]` | 0.840 |
//! | `sin` | [`kernels`] | `(128, 2²⁴]` | 0.844 |
//! | `sin` | [`kernels`] | `(2²⁴, f32::MAX]` | 0.856 |
//! | `cos` | [`kernels`] | `[0, π/4]` | 0.749 |
//! | `cos` | [`kernels`] | `(π/4, 2π]` | 0.848 |
//! | `cos` | [`kernels`] | `(2π, 128]` | 0.823 |
//! | `cos` | [`kernels`] | `(128, 2²⁴]` | 0.849 |
//! | `cos` | [`kernels`] | `(2²⁴, f32::MAX]` | 0.851 |
//! | `exp` | `libm::expf` | `[−103.97, −87.34]` (subnormal results) | 0.747 |
//! | `exp` | `libm::expf` | `(−87.34, −1]` | 0.910 |
//! | `exp` | `libm::expf` | `(−1, 1)` | 0.851 |
//! | `exp` | `libm::expf` | `[1, 88.72]` | 0.901 |
//! | `ln` | `libm::logf` | `(0, 2⁻¹²⁶)` (subnormal) | 0.503 |
//! | `ln` | `libm::logf` | `[2⁻¹²⁶, 0.5)` | 0.768 |
//! | `ln` | `libm::logf` | `[0.5, 2)` | 0.835 |
//! | `ln` | `libm::logf` | `[2, f32::MAX]` | 0.781 |
//! | `atan` | `libm::atanf` | `[0, 7/16)` | 0.707 |
//! | `atan` | `libm::atanf` | `[7/16, 39/16)` | 0.852 |
//! | `atan` | `libm::atanf` | `[39/16, f32::MAX]` | 0.765 |
//! | `atan2` | `libm::atan2f` | 67 million pseudo-random `(y, x)` (not exhaustive) | 1.478 |
//! | `sqrt` | `libm::sqrtf` | correctly rounded (integer algorithm) | ≤ 0.5 |
//! | `floor` | `libm::floorf` | exact | 0 |
//!
//! `sincos` equals `(sin, cos)` bit for bit. The tests assert 1 ulp for
//! every function but `atan2`, for which they assert 2 (its `y/x` is
//! rounded before the arc tangent). The exhaustive run takes about 10
//! minutes on two cores.
//!
//! Outside these ranges: `exp` is `+∞` above 88.72 and `+0` below −103.98;
//! `ln` of a negative number or of −∞ is NaN, `ln(±0) = −∞`,
//! `ln(+∞) = +∞`; `atan(±∞) = ±π/2`, `atan2` follows C99 Annex F for zeros
//! and infinities. Every function gives NaN for a NaN input, and `sin`,
//! `cos` and `sincos` give NaN for ±∞.
//!
//! Also holds the small numeric helpers the algorithms share: angle
//! wrapping, `sinc`, and `(1 - e^-x)/x`, each written to stay finite where a
//! naive formula would divide by zero.

pub mod kernels;
#[cfg(all(test, not(feature = "micromath")))]
mod ulp_tests;

/// π as `f32`.
pub const PI: f32 = core::f32::consts::PI;
/// 2π as `f32`.
pub const TAU: f32 = core::f32::consts::TAU;

/// One function of the backend: `micromath` if on, else the `libm` crate's
/// function if `libm` is on, else the default given (an `f32`-native
/// implementation).
macro_rules! backend {
    ($(#[$doc:meta])* $name:ident($($arg:ident),*) => libm::$libm:ident, default $default:path) => {
        $(#[$doc])*
        #[inline]
        #[must_use]
        pub fn $name($($arg: f32),*) -> f32 {
            #[cfg(feature = "micromath")]
            {
                micromath::F32Ext::$name($($arg),*)
            }
            #[cfg(all(feature = "libm", not(feature = "micromath")))]
            {
                libm::$libm($($arg),*)
            }
            #[cfg(not(any(feature = "libm", feature = "micromath")))]
            {
                $default($($arg),*)
            }
        }
    };
}

backend!(
    /// Sine of an angle in radians.
    sin(x) => libm::sinf, default kernels::sin
);
backend!(
    /// Cosine of an angle in radians.
    cos(x) => libm::cosf, default kernels::cos
);
backend!(
    /// Arc tangent, result in [-π/2, π/2].
    atan(x) => libm::atanf, default libm::atanf
);
backend!(
    /// Four-quadrant arc tangent of `y/x`, result in [-π, π].
    atan2(y, x) => libm::atan2f, default libm::atan2f
);
backend!(
    /// Square root (NaN for negative input), correctly rounded but with
    /// `micromath`.
    sqrt(x) => libm::sqrtf, default libm::sqrtf
);
backend!(
    /// Natural exponential.
    exp(x) => libm::expf, default libm::expf
);
backend!(
    /// Natural logarithm (NaN for negative input, −∞ at 0).
    ln(x) => libm::logf, default libm::logf
);
backend!(
    /// Largest integer value not greater than `x`.
    floor(x) => libm::floorf, default libm::floorf
);

/// `(sin x, cos x)`. With the default backend both come from one argument
/// reduction ([`kernels::sincos`]) and equal `(sin(x), cos(x))` bit for
/// bit; with the others it is that pair.
#[inline]
#[must_use]
pub fn sincos(x: f32) -> (f32, f32) {
    #[cfg(any(feature = "libm", feature = "micromath"))]
    {
        (sin(x), cos(x))
    }
    #[cfg(not(any(feature = "libm", feature = "micromath")))]
    {
        kernels::sincos(x)
    }
}

/// `sqrt(x² + y²)`, without the overflow of the naive formula for |x|, |y| > 1e19.
#[inline]
#[must_use]
pub fn hypot(x: f32, y: f32) -> f32 {
    let ax = x.abs();
    let ay = y.abs();
    let big = if ax > ay { ax } else { ay };
    let small = if ax > ay { ay } else { ax };
    if big == 0.0 || !big.is_finite() {
        // 0 for (0, 0); inf/NaN propagate as they should.
        return big + small;
    }
    let ratio = small / big;
    big * sqrt(1.0 + ratio * ratio)
}

/// Wraps an angle to the half-open interval (-π, π].
///
/// Non-finite input gives NaN (never a "valid-looking" angle): callers that
/// feed actuators check finiteness downstream.
///
/// An angle already in the interval (the common case, e.g. every
/// per-tick heading update) returns at once and inline; the others (and
/// NaN, which fails both comparisons) take one out-of-line copy of the
/// reduction, instead of one inlined copy of it and of `floor` per caller.
#[inline]
#[must_use]
pub fn wrap_angle(angle: f32) -> f32 {
    if angle > -PI && angle <= PI {
        return angle;
    }
    wrap_angle_outside(angle)
}

/// [`wrap_angle`] of an angle outside (−π, π] or not finite.
#[inline(never)]
fn wrap_angle_outside(angle: f32) -> f32 {
    if !angle.is_finite() {
        return f32::NAN;
    }
    let turns = floor((angle + PI) / TAU);
    let mut wrapped = angle - turns * TAU; // in [-π, π) up to rounding
    if wrapped <= -PI {
        wrapped += TAU;
    }
    if wrapped > PI {
        wrapped -= TAU;
    }
    wrapped
}

/// Below this magnitude, rad, [`sinc`] and [`unit_rotation`] use their
/// Taylor series instead of `sin`/`cos`: per-tick rotations (`ωh`, at most
/// a few hundredths of a radian on a robot) and small heading errors never
/// reach the trigonometric kernels.
pub const SERIES_MAX_RAD: f32 = 0.1;

/// `sin(x)/x`, with the removable singularity at 0 filled in (`sinc(0) = 1`).
///
/// For |x| ≤ [`SERIES_MAX_RAD`] the Taylor series `1 − x²/6 + x⁴/120 −
/// x⁶/5040` (Horner form), whose first omitted term `x⁸/362880` is below
/// 3e-14 there, far under half an ulp of 1; otherwise `sin(x)/x`.
#[inline]
#[must_use]
pub fn sinc(x: f32) -> f32 {
    if x.abs() <= SERIES_MAX_RAD {
        let x2 = x * x;
        1.0 - x2 / 6.0 * (1.0 - x2 / 20.0 * (1.0 - x2 / 42.0))
    } else {
        sin(x) / x
    }
}

/// `(1 - e^{-x}) / x` for `x >= 0`, equal to 1 at `x = 0`.
///
/// The exact one-step gain of a first-order decay `ė = -a e + a u` held over
/// a step: `1 - e^{-a h} = a h · one_minus_exp_neg_over_x(a h)`. Written so
/// that it stays finite and accurate as `x → 0` (where `a` is a speed that
/// may vanish).
#[inline]
#[must_use]
pub fn one_minus_exp_neg_over_x(x: f32) -> f32 {
    if x.abs() < 0.5 {
        // Taylor series Σ (−x)^n/(n+1)!, to n = 7: the truncation error at
        // |x| = 0.5 is 0.5⁸/9! ≈ 1e-8, below f32 resolution. The direct
        // formula would lose up to 5 digits to cancellation here.
        1.0 - x
            * (1.0 / 2.0
                - x * (1.0 / 6.0
                    - x * (1.0 / 24.0
                        - x * (1.0 / 120.0
                            - x * (1.0 / 720.0 - x * (1.0 / 5040.0 - x / 40320.0))))))
    } else {
        (1.0 - exp(-x)) / x
    }
}

/// `(sin a, cos a)` of a rotation, of unit length to within an ulp or two,
/// so that rotating by it preserves norms even with an approximate math
/// backend. `(0, 1)` (no rotation) for a non-finite angle.
///
/// For |a| ≤ [`SERIES_MAX_RAD`] (a tick's `ωh`, the case that matters):
/// the Taylor series `sin a = a (1 − a²/6 (1 − a²/20))` and `cos a = 1 −
/// a²/2 (1 − a²/12 (1 − a²/30))`, whose first omitted terms (`a⁷/5040`,
/// `a⁸/40320`) are below 2e-11 there, so the pair is as accurate as the
/// kernels' and `sin² + cos²` is 1 to within f32 rounding, with no call,
/// square root or division. Otherwise `sincos(a)` normalised by its length
/// (`micromath`'s sin/cos are off by ~1e-3, which would otherwise let a
/// rotated error grow by that factor every step).
#[inline]
#[must_use]
pub fn unit_rotation(angle: f32) -> (f32, f32) {
    if angle.abs() <= SERIES_MAX_RAD {
        let a2 = angle * angle;
        let s = angle * (1.0 - a2 / 6.0 * (1.0 - a2 / 20.0));
        let c = 1.0 - a2 / 2.0 * (1.0 - a2 / 12.0 * (1.0 - a2 / 30.0));
        return (s, c);
    }
    let (s, c) = sincos(angle);
    let n = hypot(s, c);
    if n > 0.0 { (s / n, c / n) } else { (0.0, 1.0) }
}

/// Clamps `x` to `[lo, hi]`; NaN maps to `nan_to` so it never leaks out.
#[inline]
#[must_use]
pub fn clamp_or(x: f32, lo: f32, hi: f32, nan_to: f32) -> f32 {
    if x.is_nan() {
        nan_to
    } else if x < lo {
        lo
    } else if x > hi {
        hi
    } else {
        x
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn wrap_angle_maps_to_half_open_interval() {
        assert_eq!(wrap_angle(PI), PI);
        assert_eq!(wrap_angle(-PI), PI);
        assert!((wrap_angle(3.0 * PI) - PI).abs() < 1e-5);
        assert!((wrap_angle(1.5 * PI) + 0.5 * PI).abs() < 1e-5);
        assert!(wrap_angle(f32::NAN).is_nan());
        assert!(wrap_angle(f32::INFINITY).is_nan());
    }

    #[test]
    fn small_argument_branches_match_f64() {
        for x in [0.0_f32, 1e-6, 9.9e-4, 1.01e-3, 0.1, 0.499, 0.501, 3.0] {
            let xd = f64::from(x);
            let sinc_ref = if x == 0.0 { 1.0 } else { xd.sin() / xd };
            assert!((f64::from(sinc(x)) - sinc_ref).abs() < 1e-6, "sinc({x})");
            // The f32 formula (1 - e^-x)/x cancels catastrophically near 0:
            // compare against f64.
            let phi_ref = if x == 0.0 { 1.0 } else { -(-xd).exp_m1() / xd };
            let phi = f64::from(one_minus_exp_neg_over_x(x));
            assert!(
                (phi - phi_ref).abs() < 1e-6,
                "phi({x}) = {phi} vs {phi_ref}"
            );
        }
    }

    /// The series branches against `f64` over every 1,000th f32 step of
    /// their range and just past it: within 2 ulp (of the result, or of 1
    /// for `cos` and `sinc`), and `sin² + cos²` within 4 ulp of 1.
    #[test]
    fn series_branches_match_f64() {
        let ulp = |v: f64| f64::from(f32::EPSILON) * v.abs().max(f64::from(f32::MIN_POSITIVE));
        let mut x = 0.0_f32;
        let mut checked = 0;
        while x <= 0.11 {
            for a in [x, -x] {
                let ad = f64::from(a);
                let (s, c) = unit_rotation(a);
                assert!(
                    (f64::from(s) - ad.sin()).abs() <= 2.0 * ulp(ad.sin()),
                    "sin {a}"
                );
                assert!((f64::from(c) - ad.cos()).abs() <= 2.0 * ulp(1.0), "cos {a}");
                let norm = f64::from(s).hypot(f64::from(c));
                assert!((norm - 1.0).abs() <= 4.0 * ulp(1.0), "norm {a}");
                let sinc_ref = if a == 0.0 { 1.0 } else { ad.sin() / ad };
                assert!(
                    (f64::from(sinc(a)) - sinc_ref).abs() <= 2.0 * ulp(1.0),
                    "sinc {a}"
                );
            }
            checked += 1;
            x = f32::from_bits(x.to_bits() + 1000);
        }
        assert!(checked > 1_000_000, "{checked}");
        assert_eq!(unit_rotation(f32::NAN), (0.0, 1.0));
        assert_eq!(unit_rotation(f32::INFINITY), (0.0, 1.0));
    }

    proptest! {
        #[test]
        fn wrapped_angle_is_in_range_and_equivalent(a in -1.0e4_f32..1.0e4) {
            let w = wrap_angle(a);
            prop_assert!(w > -PI && w <= PI);
            // Same direction: compare unit vectors (f32 loses ~|a|·ε in the turns).
            let tol = 1e-6 * a.abs().max(1.0) * 4.0;
            prop_assert!((libm::cosf(w) - libm::cosf(a)).abs() <= tol + 1e-5);
            prop_assert!((libm::sinf(w) - libm::sinf(a)).abs() <= tol + 1e-5);
        }

        #[test]
        fn hypot_matches_naive_in_safe_range(x in -1.0e6_f32..1.0e6, y in -1.0e6_f32..1.0e6) {
            let naive = libm::sqrtf(x * x + y * y);
            prop_assert!((hypot(x, y) - naive).abs() <= naive * 1e-6 + 1e-30);
        }
    }
}
