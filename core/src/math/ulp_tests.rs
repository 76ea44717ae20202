//! Accuracy of the math backend against `f64` references, in ulps of the
//! `f32` result.
//!
//! The error of `got` against the real value `want` (here an `f64`, whose
//! own error is below 2⁻²⁹ of an `f32` ulp) is `|got − want| / ulp(want)`,
//! where `ulp(want)` is the spacing of the `f32` numbers in the binade of
//! `want` (`2^(e − 23)` for `2^e ≤ |want| < 2^(e+1)`, `2⁻¹⁴⁹` below
//! `2⁻¹²⁶`). A correctly rounded result has error ≤ 0.5.
//!
//! Two kinds of tests:
//!
//! * the default ones (`cargo test -p wmr-core`), strided sweeps of a few
//!   million inputs over every binade, a couple of seconds;
//! * `#[ignore]`d exhaustive ones, every `f32` of each range (about 2·10⁹
//!   inputs per function, both cores: minutes):
//!
//!   ```sh
//!   cargo test -p wmr-core --release --lib math::ulp_tests -- --ignored --nocapture
//!   ```
//!
//! Both print a table (with `--nocapture`) and assert the bounds the
//! [module docs](super) state. They test the backend as built, so they
//! are off with `micromath`, whose errors are of another order.

use std::sync::Mutex;
use std::thread;

use super::{atan, atan2, cos, exp, ln, sin, sincos};

/// `|got − want|` in ulps of `want`'s `f32` binade; 0 if both are the same
/// infinity or both NaN, ∞ if only one is.
fn ulp_error(got: f32, want: f64) -> f64 {
    if got.is_nan() || want.is_nan() {
        return if got.is_nan() && want.is_nan() {
            0.0
        } else {
            f64::INFINITY
        };
    }
    #[allow(clippy::cast_possible_truncation)]
    let rounded = want as f32;
    if got.is_infinite() || rounded.is_infinite() {
        return if got == rounded { 0.0 } else { f64::INFINITY };
    }
    let magnitude = want.abs();
    #[allow(clippy::cast_possible_wrap, clippy::cast_possible_truncation)]
    let exponent = if magnitude < f64::from(f32::MIN_POSITIVE) {
        -126
    } else {
        ((magnitude.to_bits() >> 52) & 0x7FF) as i32 - 1023
    };
    (f64::from(got) - want).abs() / 2f64.powi(exponent - 23)
}

/// The worst error of a sweep: where, how much, over how many inputs.
#[derive(Debug, Clone, Copy)]
struct Worst {
    ulp: f64,
    at: f32,
    at_y: f32,
    count: u64,
}

impl Worst {
    const NONE: Self = Self {
        ulp: 0.0,
        at: 0.0,
        at_y: 0.0,
        count: 0,
    };

    fn merge(self, other: Self) -> Self {
        let mut worst = if other.ulp > self.ulp { other } else { self };
        worst.count = self.count + other.count;
        worst
    }
}

/// Every `stride`-th `f32` from `from` to `to` (both ends included, of the
/// same sign, in either order: the bit patterns of same-sign floats are
/// ordered by magnitude), on all cores; `error(x)` is the error at `x`.
fn sweep(from: f32, to: f32, stride: u32, error: impl Fn(f32) -> f64 + Sync) -> Worst {
    assert_eq!(from.is_sign_negative(), to.is_sign_negative());
    let (lo, hi) = (
        from.to_bits().min(to.to_bits()),
        from.to_bits().max(to.to_bits()),
    );
    let threads = thread::available_parallelism().map_or(1, std::num::NonZero::get);
    let chunks = u32::try_from(threads * 64).unwrap_or(64);
    let span = (hi - lo) / chunks + 1;
    let next = Mutex::new(0_u32);
    let result = Mutex::new(Worst::NONE);
    thread::scope(|scope| {
        for _ in 0..threads {
            scope.spawn(|| {
                loop {
                    let chunk = {
                        let mut n = next.lock().unwrap();
                        *n += 1;
                        *n - 1
                    };
                    if chunk >= chunks {
                        break;
                    }
                    let start = lo.saturating_add(chunk.saturating_mul(span));
                    if start > hi {
                        break;
                    }
                    let end = start.saturating_add(span - 1).min(hi);
                    // Aligned to the stride from `lo`, so the chunks tile it.
                    let mut bits = start + (stride - (start - lo) % stride) % stride;
                    let mut worst = Worst::NONE;
                    while bits <= end {
                        let x = f32::from_bits(bits);
                        let e = error(x);
                        worst.count += 1;
                        if e > worst.ulp || e.is_nan() {
                            worst.ulp = if e.is_nan() { f64::INFINITY } else { e };
                            worst.at = x;
                        }
                        bits = match bits.checked_add(stride) {
                            Some(b) => b,
                            None => break,
                        };
                    }
                    let mut r = result.lock().unwrap();
                    *r = r.merge(worst);
                }
            });
        }
    });
    result.into_inner().unwrap()
}

/// One row of the printed table, and the assertion of its bound.
fn check(name: &str, range: &str, worst: Worst, bound: f64) {
    println!(
        "| `{name}` | {range} | {} | {:.3} | {:e}{} |",
        worst.count,
        worst.ulp,
        worst.at,
        if worst.at_y == 0.0 {
            String::new()
        } else {
            format!(", x = {:e}", worst.at_y)
        }
    );
    assert!(
        worst.ulp <= bound,
        "{name} over {range}: {:.3} ulp at {:e} (bound {bound})",
        worst.ulp,
        worst.at
    );
}

fn header() {
    println!("| function | range | inputs | max ulp | at |\n| --- | --- | ---: | ---: | --- |");
}

/// `f32` just above `x` (`x ≥ 0`).
fn above(x: f32) -> f32 {
    f32::from_bits(x.to_bits() + 1)
}

/// The `f32` next to `x` away from 0 (`step` 1) or towards it (`step` −1).
fn above_magnitude(x: f32, step: i32) -> f32 {
    f32::from_bits(x.to_bits().wrapping_add_signed(step))
}

const FRAC_PI_4: f32 = core::f32::consts::FRAC_PI_4;
const TAU: f32 = core::f32::consts::TAU;
/// 2²⁴: beyond, every f32 is an even integer.
const TWO_24: f32 = 16_777_216.0;

/// `sin`, `cos` (and that `sincos` is both) over the ranges of the module
/// docs: every `f32` if `exhaustive` (positive inputs), else every
/// `stride`-th (given per range: about 4, 3.6, 1, 0.14 and 0.2 million
/// inputs) of both signs.
fn sin_cos_rows(exhaustive: bool) {
    let ranges: [(&str, f32, f32, u32); 5] = [
        ("[0, π/4]", 0.0, FRAC_PI_4, 257),
        ("(π/4, 2π]", above(FRAC_PI_4), TAU, 7),
        ("(2π, 128]", above(TAU), 128.0, 37),
        ("(128, 2²⁴]", above(128.0), TWO_24, 1_021),
        ("(2²⁴, f32::MAX]", above(TWO_24), f32::MAX, 4_099),
    ];
    let signs: &[f32] = if exhaustive { &[1.0] } else { &[1.0, -1.0] };
    for (range, from, to, stride) in ranges {
        let stride = if exhaustive { 1 } else { stride };
        let s = sweep(from, to, stride, |x| {
            signs
                .iter()
                .map(|sign| {
                    let x = sign * x;
                    let (s, c) = sincos(x);
                    if s.to_bits() != sin(x).to_bits() || c.to_bits() != cos(x).to_bits() {
                        return f64::INFINITY;
                    }
                    ulp_error(s, f64::from(x).sin())
                })
                .fold(0.0, f64::max)
        });
        check("sin", range, s, SIN_COS_BOUND);
        let c = sweep(from, to, stride, |x| {
            signs
                .iter()
                .map(|sign| ulp_error(cos(sign * x), f64::from(sign * x).cos()))
                .fold(0.0, f64::max)
        });
        check("cos", range, c, SIN_COS_BOUND);
    }
}

/// The bounds asserted, a little above what was measured (module docs).
const SIN_COS_BOUND: f64 = 1.0;
const ATAN_BOUND: f64 = 1.0;
const ATAN2_BOUND: f64 = 2.0;
const EXP_BOUND: f64 = 1.0;
const LN_BOUND: f64 = 1.0;

/// About `ln(2⁻¹⁵⁰)`: below, `exp` rounds to 0.
const EXP_MIN: f32 = -103.972_08;
/// About `ln(f32::MAX)`: above, `exp` overflows.
const EXP_MAX: f32 = 88.722_83;

/// `−ln(2¹²⁶)`, rounded: below it `exp` is subnormal.
const EXP_SUBNORMAL: f32 = -87.336_55;

fn exp_rows(stride: u32) {
    let ranges: [(&str, f32, f32); 5] = [
        (
            "[−103.97, −87.34] (subnormal results)",
            EXP_MIN,
            EXP_SUBNORMAL,
        ),
        ("(−87.34, −1]", above_magnitude(EXP_SUBNORMAL, -1), -1.0),
        ("(−1, 0]", above_magnitude(-1.0, -1), -0.0),
        ("[0, 1)", 0.0, above_magnitude(1.0, -1)),
        ("[1, 88.72]", 1.0, EXP_MAX),
    ];
    for (range, from, to) in ranges {
        let worst = sweep(from, to, stride, |x| ulp_error(exp(x), f64::from(x).exp()));
        check("exp", range, worst, EXP_BOUND);
    }
    // Beyond: exactly 0 and +∞.
    for x in [-104.0, -1e30, f32::NEG_INFINITY] {
        assert_eq!(exp(x).to_bits(), 0);
    }
    for x in [89.0, 1e30, f32::INFINITY] {
        assert_eq!(exp(x), f32::INFINITY);
    }
    assert!(exp(f32::NAN).is_nan());
}

fn ln_rows(stride: u32) {
    let ranges: [(&str, f32, f32); 4] = [
        (
            "(0, 2⁻¹²⁶) (subnormal)",
            f32::from_bits(1),
            f32::from_bits(0x007F_FFFF),
        ),
        ("[2⁻¹²⁶, 0.5)", f32::MIN_POSITIVE, above_magnitude(0.5, -1)),
        ("[0.5, 2)", 0.5, above_magnitude(2.0, -1)),
        ("[2, f32::MAX]", 2.0, f32::MAX),
    ];
    for (range, from, to) in ranges {
        let worst = sweep(from, to, stride, |x| ulp_error(ln(x), f64::from(x).ln()));
        check("ln", range, worst, LN_BOUND);
    }
}

/// `negative`: the mirror inputs too (the exhaustive run leaves them out:
/// `atanf` works on `|x|` and sets the sign last).
fn atan_rows(stride: u32, negative: bool) {
    let ranges: [(&str, f32, f32); 3] = [
        ("[0, 7/16)", 0.0, above_magnitude(0.4375, -1)),
        ("[7/16, 39/16)", 0.4375, above_magnitude(2.4375, -1)),
        ("[39/16, f32::MAX]", 2.4375, f32::MAX),
    ];
    for (range, from, to) in ranges {
        let worst = sweep(from, to, stride, |x| {
            let e = ulp_error(atan(x), f64::from(x).atan());
            if negative {
                e.max(ulp_error(atan(-x), f64::from(-x).atan()))
            } else {
                e
            }
        });
        check("atan", range, worst, ATAN_BOUND);
    }
}

/// `atan2` over `n` pseudo-random `(y, x)`: directions uniform on the
/// circle and magnitudes log-uniform over `[2⁻⁶⁰, 2⁶⁰]` each, so the
/// quotient `y/x` spans the whole range, plus the axes and diagonals.
fn atan2_row(n: u32) {
    // SplitMix32-like generator, fixed seed: the same inputs every run.
    let input = |i: u32| {
        let mut z = i.wrapping_mul(0x9E37_79B9).wrapping_add(0x7F4A_7C15);
        let mut next = || {
            z = z.wrapping_add(0x9E37_79B9);
            let mut v = z;
            v = (v ^ (v >> 16)).wrapping_mul(0x85EB_CA6B);
            v = (v ^ (v >> 13)).wrapping_mul(0xC2B2_AE35);
            v ^ (v >> 16)
        };
        let unit = |v: u32| f64::from(v) / 4_294_967_296.0;
        let angle = unit(next()) * std::f64::consts::TAU - std::f64::consts::PI;
        let scale = 2f64.powf(unit(next()) * 120.0 - 60.0);
        let ratio = 2f64.powf(unit(next()) * 40.0 - 20.0);
        #[allow(clippy::cast_possible_truncation)]
        let (y, x) = (
            (angle.sin() * scale * ratio) as f32,
            (angle.cos() * scale) as f32,
        );
        (y, x)
    };
    let threads = thread::available_parallelism().map_or(1, std::num::NonZero::get);
    let threads = u32::try_from(threads).unwrap_or(1);
    let mut worst = Worst::NONE;
    thread::scope(|scope| {
        let handles: Vec<_> = (0..threads)
            .map(|t| {
                scope.spawn(move || {
                    let mut w = Worst::NONE;
                    let mut i = t;
                    while i < n {
                        let (y, x) = input(i);
                        let e = ulp_error(atan2(y, x), f64::from(y).atan2(f64::from(x)));
                        w.count += 1;
                        if e > w.ulp {
                            w = Worst {
                                ulp: e,
                                at: y,
                                at_y: x,
                                count: w.count,
                            };
                        }
                        i += threads;
                    }
                    w
                })
            })
            .collect();
        for h in handles {
            worst = worst.merge(h.join().unwrap());
        }
    });
    let specials = [
        0.0_f32,
        -0.0,
        1.0,
        -1.0,
        1e-30,
        -1e30,
        f32::MAX,
        f32::MIN_POSITIVE,
    ];
    for y in specials {
        for x in specials {
            let e = ulp_error(atan2(y, x), f64::from(y).atan2(f64::from(x)));
            worst.count += 1;
            if e > worst.ulp {
                worst = Worst {
                    ulp: e,
                    at: y,
                    at_y: x,
                    count: worst.count,
                };
            }
        }
    }
    check(
        "atan2",
        "random (y, x), see `atan2_row`",
        worst,
        ATAN2_BOUND,
    );
}

/// Strided, both signs: seconds with the test profile's optimisation.
#[test]
fn sin_cos_within_bound_strided() {
    header();
    sin_cos_rows(false);
}

#[test]
#[ignore = "exhaustive, minutes: cargo test -p wmr-core --release --lib math::ulp_tests -- --ignored"]
fn sin_cos_within_bound_exhaustive() {
    header();
    sin_cos_rows(true);
}

#[test]
fn exp_ln_atan_within_bound_strided() {
    header();
    exp_rows(251);
    ln_rows(1_021);
    atan_rows(1_021, true);
    atan2_row(1 << 20);
}

#[test]
#[ignore = "exhaustive, minutes: cargo test -p wmr-core --release --lib math::ulp_tests -- --ignored"]
fn exp_ln_atan_within_bound_exhaustive() {
    header();
    exp_rows(1);
    ln_rows(1);
    atan_rows(1, false);
    atan2_row(1 << 26);
}

#[test]
fn ulp_error_is_measured_in_the_binade_of_the_reference() {
    assert_eq!(ulp_error(1.0, 1.0), 0.0);
    assert_eq!(ulp_error(above(1.0), 1.0), 1.0);
    // Just below 1 the spacing halves.
    assert_eq!(ulp_error(1.0, 1.0 - 2f64.powi(-24)), 1.0);
    assert_eq!(ulp_error(f32::from_bits(1), 0.0), 1.0);
    assert_eq!(ulp_error(f32::INFINITY, 1e300), 0.0);
    assert_eq!(ulp_error(f32::MAX, 1e300), f64::INFINITY);
    assert_eq!(ulp_error(f32::NAN, f64::NAN), 0.0);
}
