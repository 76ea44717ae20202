//! `sin`, `cos` and `sincos` computed in `f32` only, with `f32` (and
//! integer) argument reduction: no `f64` anywhere, so nothing here calls
//! the software double-precision routines a Cortex-M4F would need for
//! `libm`'s `sinf`/`cosf` (whose reduction and kernels are in `f64`).
//!
//! # Method
//!
//! `x = k·π/2 + r` with `|r| ≤ π/4` (up to rounding), then
//! `sin x ∈ {sin r, cos r, −sin r, −cos r}` by the quadrant `k mod 4`.
//! `r` is kept as an unevaluated sum `hi + lo` of two `f32`, which is what
//! keeps the result near 1 ulp when `x` is close to a multiple of π/2
//! (there `r` is tiny and a plain `f32` subtraction would lose its digits).
//!
//! * `|x| ≤ π/4`: no reduction.
//! * `|x| ≤ 128` (`k < 128`): Cody–Waite, `π/2 = P1 + P2 + P3` with `P1`,
//!   `P2` of 17 significant bits (so `k·P1`, `k·P2` are exact for
//!   `k < 2⁷`) and `P3` a full `f32`; `x − k·P1` is exact (Sterbenz), the
//!   subtraction of `k·P2` is made exact by TwoSum, and what is left of π/2
//!   (`< 1e-19`, times `k ≤ 82`) is far below the ulp of the smallest `r`
//!   an `f32` in this range can give.
//! * `|x| > 128`, up to `f32::MAX`: Payne–Hanek in integers: `x·2/π mod 4`
//!   as a 2.126-bit fixed-point number from the 24-bit significand times a
//!   128-bit window of the bits of 2/π (the table `TWO_OVER_PI`), exact to
//!   `2⁻¹⁰²` of a quadrant; the remainder is turned back into `hi + lo` and
//!   multiplied by π/2 in pieces whose products are exact. Slower (`u128`
//!   arithmetic) but as accurate as the fast path: no input range is
//!   "accurate only up to".
//!
//! The kernels on `[−π/4, π/4]` are S. L. Moshier's single-precision
//! polynomials from Cephes (`sinf.c`: `sincof`, `coscof`), evaluated in
//! Horner form with the `lo` part of `r` added as its first-order term,
//! and `cos` summed as `w = 1 − z/2` plus the exact rounding error of `w`
//! (the technique of fdlibm's `__kernel_cos`).
//!
//! # Accuracy (measured, see `ulp_tests.rs`)
//!
//! Against `f64` `sin`/`cos` of the same `f32` input, over every positive
//! finite `f32` (exhaustive; negative inputs are the same code by symmetry,
//! `sin(−x) = −sin(x)` and `cos(−x) = cos(x)` bit for bit): see the table
//! in the [parent module](super). Both are below 1 ulp everywhere.
//!
//! # Special values
//!
//! NaN in gives NaN out (`f32::NAN`, the same bits on every target), and so
//! do ±∞ (`sin(±∞) = cos(±∞) = NaN`, as IEEE 754 says). `sin(±0) = ±0`,
//! `cos(±0) = 1`. No `f32` input panics, and the result is always in
//! `[−1, 1]` or NaN.
//!
//! # Determinism
//!
//! Only `+ − ×`, comparisons, `f32 ↔ integer` conversions of small integers
//! and integer arithmetic: IEEE 754 fixes every result, and Rust does not
//! fuse `a·b + c`, so the host (x86-64, SSE) and the Cortex-M4F (VFPv4-SP)
//! compute the same bits. No table lookup depends on anything but `x`.

/// The bits of `2/π` after the binary point, 32 per word, most significant
/// first, preceded by one word of zeros (the integer part and the bits a
/// window starting before the point reads). 288 bits: the largest `f32`
/// (exponent 127) reads bits up to 256. The same digits as fdlibm's
/// `ipio2` table (`k_rem_pio2.c`, there in 24-bit chunks); checked against
/// an arbitrary-precision 2/π by the test `two_over_pi_table_is_exact`.
const TWO_OVER_PI: [u32; 10] = [
    0x0000_0000,
    0xA2F9_836E,
    0x4E44_1529,
    0xFC27_57D1,
    0xF534_DDC0,
    0xDB62_9599,
    0x3C43_9041,
    0xFE51_63AB,
    0xDEBB_C561,
    0xB724_6E3A,
];

/// `2/π` rounded to `f32`, for the quadrant estimate of the fast path.
const FRAC_2_PI: f32 = core::f32::consts::FRAC_2_PI;
/// `π/4` rounded to `f32`.
const FRAC_PI_4: f32 = core::f32::consts::FRAC_PI_4;

/// Largest `|x|` of the Cody–Waite path (`k = round(x·2/π) ≤ 82 < 2⁷`).
pub const FAST_REDUCTION_MAX: f32 = 128.0;

/// Below this `|x|`, `sin x = x` and `cos x = 1` to within 1/6 ulp and
/// 1/2 ulp (`x³/6 < 2⁻²⁴·x/6`); also keeps `x² ` from going subnormal.
const TINY: f32 = f32::from_bits(0x3980_0000); // 2⁻¹²

// π/2 = P1 + P2 + P3 (+ 8e-20), P1 and P2 with ≤ 17 significant bits.
// Computed with 400-bit arithmetic (mpmath) from π; given as bit patterns
// so that a reader can check the trailing zeros (and the test
// `reduction_constants_add_up_to_half_pi` does).
/// `π/2` to 17 bits (12 significant bits in fact).
const P1: f32 = f32::from_bits(0x3FC9_1000); // 1.570 800 781 25
/// Next 17 bits of `π/2`.
const P2: f32 = f32::from_bits(0xB695_7780); // −4.454 457 7e-6
/// The rest of `π/2`, rounded to `f32`.
const P3: f32 = f32::from_bits(0x2C34_611A); // 2.563 344 1e-12

// π/2 = C1 + C2 + C3 (+ 6e-18), C1 and C2 with ≤ 12 significant bits so
// that a 12-bit piece of the reduced argument times either is exact.
/// `π/2` to 12 bits.
const C1: f32 = f32::from_bits(0x3FC9_1000); // 1.570 800 781 25
/// Next 12 bits of `π/2`.
const C2: f32 = f32::from_bits(0xB695_7000); // −4.453 584 6e-6
/// The rest of `π/2`, rounded to `f32`.
const C3: f32 = f32::from_bits(0xB06F_4B9F); // −8.705 515 8e-10

// Cephes `sinf.c` (S. L. Moshier, Cephes Math Library 2.x, 1989), `sincof`
// and `coscof`: sin x = x + x³·S(x²), cos x = 1 − x²/2 + x⁴·C(x²) on
// [−π/4, π/4]. Their approximation error there, measured in 100-bit
// arithmetic with the coefficients as the `f32` below: ≤ 8.0e-9 relative
// for sin (0.13·2⁻²⁴), ≤ 1.8e-10 for cos.
/// `S(z) = S0·z² + S1·z + S2`. (The decimals are Cephes' as published;
/// the compiler rounds them to `f32`, as Cephes' C compiler did.)
#[allow(clippy::excessive_precision)]
const S0: f32 = -1.951_529_589_1e-4;
/// See [`S0`].
#[allow(clippy::excessive_precision)]
const S1: f32 = 8.332_160_873_6e-3;
/// See [`S0`].
#[allow(clippy::excessive_precision)]
const S2: f32 = -1.666_665_461_1e-1;
/// `C(z) = K0·z² + K1·z + K2`.
#[allow(clippy::excessive_precision)]
const K0: f32 = 2.443_315_711_809_948e-5;
/// See [`K0`].
#[allow(clippy::excessive_precision)]
const K1: f32 = -1.388_731_625_493_765e-3;
/// See [`K0`].
#[allow(clippy::excessive_precision)]
const K2: f32 = 4.166_664_568_298_827e-2;

/// `x = quadrant·π/2 + (hi + lo)` for finite `x ≥ TINY`; `|hi + lo| ≤ π/4`
/// up to rounding (a few 1e-6 beyond it on the fast path, where the
/// quadrant comes from an `f32` product), `|lo| ≤ ulp(hi)`.
#[inline]
fn reduce(x: f32) -> (u32, f32, f32) {
    if x <= FRAC_PI_4 {
        (0, x, 0.0)
    } else if x <= FAST_REDUCTION_MAX {
        reduce_cody_waite(x)
    } else {
        reduce_payne_hanek(x)
    }
}

/// Cody–Waite reduction for `π/4 < x ≤ 128`.
#[inline]
fn reduce_cody_waite(x: f32) -> (u32, f32, f32) {
    // Truncation of a positive value: round to nearest. `as` saturates, and
    // x·2/π + 0.5 ≤ 82 here.
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    let k = (x * FRAC_2_PI + 0.5) as u32;
    #[allow(clippy::cast_precision_loss)]
    let kf = k as f32; // exact: k < 2⁷
    let t1 = x - kf * P1; // exact: k·P1 is exact and within a factor 2 of x
    let p2 = kf * P2; // exact
    let (hi, e) = two_sum(t1, -p2);
    let lo = e - kf * P3;
    let (hi, lo) = fast_two_sum(hi, lo);
    (k, hi, lo)
}

/// Payne–Hanek reduction for finite `x > 128`, in integer arithmetic.
fn reduce_payne_hanek(x: f32) -> (u32, f32, f32) {
    let bits = x.to_bits();
    // x = m·2^e, m the 24-bit significand (x is normal here).
    let m = u128::from((bits & 0x007F_FFFF) | 0x0080_0000);
    #[allow(clippy::cast_possible_wrap)]
    let e = ((bits >> 23) & 0xFF) as i32 - 150; // −16 ≤ e ≤ 104
    // The 128 bits of 2/π starting at bit e − 1 after the point (bit 1 is
    // the first): the bits before it give multiples of 4 (whole turns),
    // those after it less than 2⁻¹⁰² of a quadrant.
    #[allow(clippy::cast_sign_loss)]
    let g = (e + 30) as u32; // bit e − 1, counted from the table's start (≥ 14)
    let word = (g / 32) as usize;
    let shift = g % 32;
    let w = |i: usize| u128::from(TWO_OVER_PI.get(word + i).copied().unwrap_or(0));
    let head = (w(0) << 96) | (w(1) << 64) | (w(2) << 32) | w(3);
    let window = (head << shift) | ((w(4) << shift) >> 32);
    // x·2/π mod 4 in 2.126 fixed point: bit j of the product weighs
    // 2^(j − 126), and the wrap-around drops exactly the multiples of 4.
    let product = m.wrapping_mul(window);
    let quadrant = product.wrapping_add(1 << 125) >> 126; // nearest integer
    #[allow(clippy::cast_possible_wrap)]
    let frac = product.wrapping_sub(quadrant << 126) as i128; // in [−2¹²⁵, 2¹²⁵)
    #[allow(clippy::cast_possible_truncation)]
    let quadrant = quadrant as u32;
    let magnitude = frac.unsigned_abs();
    if magnitude == 0 {
        return (quadrant, 0.0, 0.0);
    }
    // The fraction (in quadrants) = magnitude·2⁻¹²⁶. Its leading 48 bits as
    // three 12-bit pieces a, b, c and the next 24 as d (24 + 24 + 24
    // significant bits: far more than the ~33 the worst f32 needs).
    let lz = magnitude.leading_zeros(); // ≥ 2 (|frac| ≤ 2¹²⁵); ≤ 2 + 30 or so for an f32
    let top = magnitude << lz; // bit 127 set
    #[allow(clippy::cast_possible_truncation)]
    let piece =
        |from: u32, width: u32| ((top >> (128 - from - width)) & ((1_u128 << width) - 1)) as u32;
    // piece(from, width) weighs 2^(−126 − lz + 128 − from − width) of a quadrant.
    let scale = |from: u32, width: u32| {
        #[allow(clippy::cast_possible_wrap)]
        let exponent = 2 - (lz as i32) - (from as i32) - (width as i32);
        pow2(exponent)
    };
    #[allow(clippy::cast_precision_loss)]
    let a = piece(0, 12) as f32 * scale(0, 12);
    #[allow(clippy::cast_precision_loss)]
    let b = piece(12, 12) as f32 * scale(12, 12);
    #[allow(clippy::cast_precision_loss)]
    let c = piece(24, 24) as f32 * scale(24, 24);
    // r = (a + b + c)·(C1 + C2 + C3): a·C1, a·C2, b·C1 and b·C2 are exact
    // (12 × 12 bits); the rest is below 2⁻²³ of the result and rounded.
    let hi = a * C1;
    let lo = (a * C2 + b * C1) + (b * C2 + (c * C1 + (a + b) * C3));
    let (hi, lo) = fast_two_sum(hi, lo);
    if frac < 0 {
        (quadrant, -hi, -lo)
    } else {
        (quadrant, hi, lo)
    }
}

/// `2^n` for `−126 ≤ n ≤ 127` (clamped: never needed outside).
#[inline]
fn pow2(n: i32) -> f32 {
    let biased = n.clamp(-126, 127) + 127;
    #[allow(clippy::cast_sign_loss)]
    f32::from_bits((biased as u32) << 23)
}

/// Knuth's TwoSum: `s + e = a + b` exactly, `s = fl(a + b)`.
#[inline]
fn two_sum(a: f32, b: f32) -> (f32, f32) {
    let s = a + b;
    let bb = s - a;
    let e = (a - (s - bb)) + (b - bb);
    (s, e)
}

/// Dekker's Fast2Sum: `s + e = a + b` exactly when `|a| ≥ |b|` (or `a = 0`).
#[inline]
fn fast_two_sum(a: f32, b: f32) -> (f32, f32) {
    let s = a + b;
    let e = b - (s - a);
    (s, e)
}

/// `sin(hi + lo)` for `|hi| ≲ π/4`, `|lo| ≤ ulp(hi)`.
#[inline]
fn sin_kernel(hi: f32, lo: f32) -> f32 {
    let z = hi * hi;
    let poly = (S0 * z + S1) * z + S2;
    // sin(hi + lo) = sin hi + lo·cos hi + O(lo²), cos hi ≈ 1 − z/2.
    hi + (hi * z * poly + lo * (1.0 - 0.5 * z))
}

/// `cos(hi + lo)` for `|hi| ≲ π/4`, `|lo| ≤ ulp(hi)`.
#[inline]
fn cos_kernel(hi: f32, lo: f32) -> f32 {
    let z = hi * hi;
    let poly = (K0 * z + K1) * z + K2;
    let half_z = 0.5 * z;
    let w = 1.0 - half_z;
    // cos(hi + lo) = cos hi − lo·sin hi + O(lo²), sin hi ≈ hi; (1 − w) − z/2
    // is the exact rounding error of w (fdlibm's __kernel_cos).
    w + (((1.0 - w) - half_z) + (z * z * poly - hi * lo))
}

/// Sine of `x` (radians), computed in `f32` only. See the [module](self)
/// for the method, accuracy and special values.
#[must_use]
pub fn sin(x: f32) -> f32 {
    let ax = x.abs();
    if !ax.is_finite() {
        return f32::NAN;
    }
    if ax < TINY {
        return x;
    }
    let (quadrant, hi, lo) = reduce(ax);
    let s = match quadrant & 3 {
        0 => sin_kernel(hi, lo),
        1 => cos_kernel(hi, lo),
        2 => -sin_kernel(hi, lo),
        _ => -cos_kernel(hi, lo),
    };
    if x.is_sign_negative() { -s } else { s }
}

/// Cosine of `x` (radians), computed in `f32` only. See the [module](self).
#[must_use]
pub fn cos(x: f32) -> f32 {
    let ax = x.abs();
    if !ax.is_finite() {
        return f32::NAN;
    }
    if ax < TINY {
        return 1.0;
    }
    let (quadrant, hi, lo) = reduce(ax);
    match quadrant & 3 {
        0 => cos_kernel(hi, lo),
        1 => -sin_kernel(hi, lo),
        2 => -cos_kernel(hi, lo),
        _ => sin_kernel(hi, lo),
    }
}

/// `(sin x, cos x)` from one argument reduction: bit for bit
/// `(sin(x), cos(x))`, for about the price of one of them plus a
/// polynomial. See the [module](self).
#[must_use]
pub fn sincos(x: f32) -> (f32, f32) {
    let ax = x.abs();
    if !ax.is_finite() {
        return (f32::NAN, f32::NAN);
    }
    if ax < TINY {
        return (x, 1.0);
    }
    let (quadrant, hi, lo) = reduce(ax);
    let (s, c) = (sin_kernel(hi, lo), cos_kernel(hi, lo));
    let (s, c) = match quadrant & 3 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    };
    (if x.is_sign_negative() { -s } else { s }, c)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn special_values() {
        for x in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -f32::NAN] {
            assert_eq!(sin(x).to_bits(), f32::NAN.to_bits(), "sin({x})");
            assert_eq!(cos(x).to_bits(), f32::NAN.to_bits(), "cos({x})");
            let (s, c) = sincos(x);
            assert_eq!(
                (s.to_bits(), c.to_bits()),
                (f32::NAN.to_bits(), f32::NAN.to_bits())
            );
        }
        assert_eq!(sin(0.0).to_bits(), 0.0_f32.to_bits());
        assert_eq!(sin(-0.0).to_bits(), (-0.0_f32).to_bits());
        assert_eq!(cos(-0.0), 1.0);
        assert_eq!(sin(f32::MIN_POSITIVE / 4.0), f32::MIN_POSITIVE / 4.0);
        for x in [1.0_f32, 1e3, 1e10, f32::MAX, -f32::MAX] {
            let (s, c) = sincos(x);
            assert!(s.abs() <= 1.0 && c.abs() <= 1.0);
            assert!((s * s + c * c - 1.0).abs() < 1e-6, "{x:e}");
        }
    }

    #[test]
    fn two_over_pi_table_head_matches_f64() {
        // The table was generated with 400-bit arithmetic (mpmath) and is
        // fdlibm's `ipio2`; here its first 64 bits against f64's 2/π. Every
        // word is read by some exponent of the large-argument path, which
        // the ulp tests (`ulp_tests.rs`) sweep up to f32::MAX against f64's
        // own, correctly reduced, sin and cos: a wrong bit anywhere shows
        // there as errors of whole quadrants.
        let head = (u64::from(TWO_OVER_PI[1]) << 32) | u64::from(TWO_OVER_PI[2]);
        #[allow(clippy::cast_precision_loss)]
        let approx = head as f64 / 2f64.powi(64);
        assert_eq!(approx, core::f64::consts::FRAC_2_PI);
        assert_eq!(TWO_OVER_PI[0], 0);
    }

    #[test]
    fn sincos_is_sin_and_cos_bit_for_bit() {
        let mut bits = 0_u32;
        while bits < 0x7F80_0000 {
            for x in [f32::from_bits(bits), -f32::from_bits(bits)] {
                let (s, c) = sincos(x);
                assert_eq!(s.to_bits(), sin(x).to_bits(), "sin {x:e}");
                assert_eq!(c.to_bits(), cos(x).to_bits(), "cos {x:e}");
                assert_eq!(sin(-x).to_bits(), (-sin(x)).to_bits(), "odd {x:e}");
                assert_eq!(cos(-x).to_bits(), cos(x).to_bits(), "even {x:e}");
            }
            bits += 9_973;
        }
    }

    #[test]
    fn reduction_constants_add_up_to_half_pi() {
        let sum = f64::from(P1) + f64::from(P2) + f64::from(P3);
        assert!((sum - core::f64::consts::FRAC_PI_2).abs() < 1e-16);
        let sum = f64::from(C1) + f64::from(C2) + f64::from(C3);
        assert!((sum - core::f64::consts::FRAC_PI_2).abs() < 1e-16);
        // The significant bits that make the products exact.
        for (c, bits) in [(P1, 17), (P2, 17), (C1, 12), (C2, 12)] {
            let mantissa = (c.to_bits() & 0x007F_FFFF) | 0x0080_0000;
            assert!(mantissa.trailing_zeros() >= 24 - bits, "{c:e}");
        }
    }
}
