//! The math backend's functions, one call per sample.

use wmr_core::math;

use super::stage::Stage;
use super::timing::SAMPLES;
use super::timing::{Calibration, timed};

/// One math-backend call per sample, over a spread of arguments.
pub(super) fn bench_math(cal: Calibration) {
    type MathFn = fn(&[f32; 2]) -> f32;
    type Arguments = fn(usize) -> [f32; 2];
    /// `k`-th of `SAMPLES` points spread over `[a, b]`.
    fn spread(k: usize, a: f32, b: f32) -> f32 {
        a + (b - a) * k as f32 / (SAMPLES - 1) as f32
    }
    let cases: [(&str, MathFn, Arguments); 7] = [
        (
            "math_sin",
            |x| math::sin(x[0]),
            |k| [spread(k, -3.2, 3.2), 0.0],
        ),
        (
            "math_cos",
            |x| math::cos(x[0]),
            |k| [spread(k, -3.2, 3.2), 0.0],
        ),
        (
            "math_sincos",
            |x| {
                let (s, c) = math::sincos(x[0]);
                s + c
            },
            |k| [spread(k, -3.2, 3.2), 0.0],
        ),
        (
            "math_atan",
            |x| math::atan(x[0]),
            |k| [spread(k, -4.0, 4.0), 0.0],
        ),
        (
            "math_atan2",
            |x| math::atan2(x[0], x[1]),
            |k| {
                let a = spread(k, -3.1, 3.1);
                [math::sin(a), math::cos(a)]
            },
        ),
        (
            "math_exp",
            |x| math::exp(x[0]),
            |k| [spread(k, -0.2, 0.0), 0.0],
        ),
        (
            "math_sqrt",
            |x| math::sqrt(x[0]),
            |k| [spread(k, 0.01, 50.0), 0.0],
        ),
    ];
    for (name, f, input) in cases {
        let mut stage = Stage::new(name);
        for k in 0..SAMPLES {
            stage.record(timed(&input(k), |x| call_math(f, x)).0);
        }
        stage.report(cal);
    }
}

/// A math function behind a call, as the core calls it.
#[inline(never)]
fn call_math(f: fn(&[f32; 2]) -> f32, x: &[f32; 2]) -> f32 {
    f(x)
}
