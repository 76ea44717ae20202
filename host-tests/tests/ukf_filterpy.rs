//! `wmr_core::filters::ukf` against FilterPy 1.4.5, step by step.
//!
//! The fixtures in `fixtures/ukf/` were written by `fixtures/ukf/generate.py`
//! (FilterPy's `UnscentedKalmanFilter` with `MerweScaledSigmaPoints`, in
//! `f64`); their headers record the versions, the date and the command.
//! Every parameter, input and measurement in them is an `f32` value, so the
//! two filters see the same data and only the arithmetic differs. After
//! every predict and every update the `f32` filter's `x` and `P` are
//! compared with FilterPy's:
//!
//! * `x` in units of FilterPy's own standard deviation,
//!   `|Δxᵢ| / √Pᵢᵢ` (ψ's difference wrapped), and in absolute terms;
//! * `P` relative to its size, `|ΔPᵢⱼ| / √(Pᵢᵢ Pⱼⱼ)` (the error of the
//!   covariance on the scale of the correlation matrix).
//!
//! # Tolerances
//! `f32` carries `ε = 1.2e-7`. The unscented transform forms the mean as
//! `Σ Wᵢ f(σᵢ)` and every `f(σᵢ)` is an `f32` number rounded at about
//! `ε|x|/2`, so each predict adds an error of order
//! `Σ_{i≥1}|Wᵢ| · ε|x|/2` to the mean (the core's anchored sum removes
//! `W₀`'s cancellation, not this), and the covariance is formed from
//! offsets `γ√P` that are only `γ√P / (ε|x|)` ulps of the state.
//!
//! * `α = 0.5` (`landmarks.txt`, `Σ|Wᵢ| = 4`, `γ = 0.87`): the rounding
//!   stays near `ε`. Measured over 200 steps: `x` within 2.4e-5 σ
//!   (1.2e-6 m or rad), `P` within 1.8e-5 of its size. Asserted 1e-4 for
//!   both: room for another libm or CPU, none for a semantic slip. The
//!   fixture's script ran two variants alongside FilterPy: sigma points from
//!   the rows of the lower Cholesky factor end up 0.058 σ / 0.12 away, an
//!   update on sigma points redrawn from the prior (later FilterPy) 0.036 σ
//!   / 0.63 away; both would fail here by 360× or more.
//! * `α = 0.01` (`scenario1*.txt`, `n + λ = 3e-4`, `W₀ = −9999`,
//!   `Wᵢ = 1666.7`, `Σ|Wᵢ| = 1e4`, `γ = 0.017`): each of the six outer
//!   points of ψ ≈ 3 is rounded twice (stored, then through `f`), each
//!   rounding of standard deviation `ulp/√12 = 7e-8`, so a predict moves
//!   the mean of ψ by about `1666 · √12 · 7e-8 ≈ 4e-4` rad (seen: 1e-4 …
//!   3e-4 rad per predict in the first steps). These add up as a random
//!   walk that only the updates pull back: late in the run the gain is
//!   `K ≈ P/(P + R) ≈ 0.015` per update (every 4 predicts), so the walk
//!   settles near `√(4 · (4e-4)² / (2 · 0.015)) ≈ 5e-3` rad, 0.08 of
//!   FilterPy's `σ_ψ = 0.055`. Measured: `x` within
//!   0.061 σ (2.8e-3 m or rad), `P` within 2.2e-3. With FilterPy's default
//!   hooks the heading is not wrapped and reaches 4.9 rad, and the sigma
//!   offsets of ψ (`γ√P ≈ 1e-3` rad, about 2000 ulps of 4.9) lose more: `P_ψψ`
//!   ends up 0.5–1.4 % low, `x` within 0.048 σ (2.2e-3). Asserted 0.2 σ and
//!   1e-2 (angle hooks), 4e-2 (default hooks): about 3× the measurement.
//!   The `f32` filter is as good an estimator here (its own error is 1 σ),
//!   but these cases cannot check its arithmetic more closely than that,
//!   nor tell the update semantics apart (redrawing is only 8.8e-4 σ /
//!   4.8e-3 away with `Q = 1e-5`); they do catch the wrong Cholesky rows
//!   (0.80 σ / 0.51 and 0.91 σ / 0.56 away). A closer check at this `α`
//!   would need `f64` or a model written in offsets from the mean.

use std::collections::HashMap;
use std::path::Path;

use nalgebra::{SMatrix, SVector};
use wmr_core::filters::ukf::{
    AngleComponents, MerweScaledSigmaPoints, StepOutcome, UkfForm, UkfModel, UnscentedKalmanFilter,
};
use wmr_core::math::{cos, sin, wrap_angle};

type V3 = SVector<f32, 3>;
type M3 = SMatrix<f32, 3, 3>;

/// One fixture file: its parameters by name and its records in order.
struct Fixture {
    params: HashMap<String, Vec<String>>,
    records: Vec<(String, Vec<String>)>,
}

impl Fixture {
    fn read(name: &str) -> Self {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("fixtures/ukf")
            .join(name);
        let text =
            std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        Self::parse(&text)
    }

    fn parse(text: &str) -> Self {
        let mut params = HashMap::new();
        let mut records = Vec::new();
        for line in text
            .lines()
            .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        {
            let mut tokens = line.split_whitespace().map(str::to_owned);
            let key = tokens.next().expect("a key");
            let values: Vec<String> = tokens.collect();
            if key == "predict" || key == "update" {
                records.push((key, values));
            } else {
                params.insert(key, values);
            }
        }
        Self { params, records }
    }

    fn f32s(&self, key: &str) -> Vec<f32> {
        self.params[key]
            .iter()
            .map(|t| t.parse().expect("an f32"))
            .collect()
    }

    fn scalar(&self, key: &str) -> f32 {
        self.f32s(key)[0]
    }

    fn matrix<const K: usize>(&self, key: &str) -> SMatrix<f32, K, K> {
        SMatrix::<f32, K, K>::from_row_slice(&self.f32s(key))
    }
}

/// Paper 004's scenario-1 motion `fx = x + dt (v cos ψ, v sin ψ, ω)`.
fn motion(x: &V3, u: &[f32; 2], dt: f32) -> V3 {
    let [v, w] = *u;
    V3::new(
        x[0] + dt * v * cos(x[2]),
        x[1] + dt * v * sin(x[2]),
        x[2] + dt * w,
    )
}

const PSI: [usize; 1] = [2];

/// Scenario 1: full-state measurement; with `angles`, the four hooks are
/// angle-aware for ψ, as in the fixture's FilterPy filter.
#[derive(Debug, Clone, Copy)]
struct Scenario1 {
    angles: bool,
}

impl UkfModel<3, 3> for Scenario1 {
    type Input = [f32; 2];
    fn input_is_finite(&self, u: &[f32; 2]) -> bool {
        u.iter().all(|v| v.is_finite())
    }
    fn transition(&self, x: &V3, u: &[f32; 2], dt_s: f32) -> V3 {
        motion(x, u, dt_s)
    }
    fn measure(&self, x: &V3) -> V3 {
        *x
    }
    fn angles(&self) -> AngleComponents<3, 3> {
        if self.angles {
            AngleComponents::from_indices(&PSI, &PSI)
        } else {
            AngleComponents::NONE
        }
    }
}

/// Range and bearing (relative to ψ, wrapped) to two landmarks.
#[derive(Debug, Clone, Copy)]
struct Landmarks {
    marks: [[f32; 2]; 2],
}

const BEARINGS: [usize; 2] = [1, 3];

impl UkfModel<3, 4> for Landmarks {
    type Input = [f32; 2];
    fn input_is_finite(&self, u: &[f32; 2]) -> bool {
        u.iter().all(|v| v.is_finite())
    }
    fn transition(&self, x: &V3, u: &[f32; 2], dt_s: f32) -> V3 {
        motion(x, u, dt_s)
    }
    fn measure(&self, x: &V3) -> SVector<f32, 4> {
        let mut z = SVector::<f32, 4>::zeros();
        for (k, [lx, ly]) in self.marks.iter().enumerate() {
            let (dx, dy) = (lx - x[0], ly - x[1]);
            z[2 * k] = dx.hypot(dy);
            z[2 * k + 1] = wrap_angle(dy.atan2(dx) - x[2]);
        }
        z
    }
    fn angles(&self) -> AngleComponents<3, 4> {
        AngleComponents::from_indices(&PSI, &BEARINGS)
    }
}

/// The worst deviations from FilterPy over a run.
#[derive(Debug, Default)]
struct Deviation {
    /// `max |Δxᵢ| / √Pᵢᵢ`.
    state_sigma: f64,
    /// `max |Δxᵢ|` (m, rad).
    state_abs: f64,
    /// `max |ΔPᵢⱼ| / √(Pᵢᵢ Pⱼⱼ)`.
    covariance: f64,
    /// The record where `state_sigma` was reached.
    worst_step: usize,
    steps: usize,
}

/// The worst deviations of the `f32` filter in `form` from FilterPy over
/// `fixture`: an `N`-state model with input `(a, ω)` or `(v, ω)` whose
/// component 2 is the heading, `S = 2N + 1` points. Each record is a
/// predict's input or an update's `z`, then FilterPy's `x` and the upper
/// triangle of its `P` (row by row).
fn run<Model, const N: usize, const M: usize, const S: usize>(
    fixture: &Fixture,
    model: Model,
    form: UkfForm,
) -> Deviation
where
    Model: UkfModel<N, M, Input = [f32; 2]>,
{
    let points = MerweScaledSigmaPoints::<N, S>::new(
        fixture.scalar("alpha"),
        fixture.scalar("beta"),
        fixture.scalar("kappa"),
    )
    .expect("fixture weights");
    let dt = fixture.scalar("dt");
    let mut ukf = UnscentedKalmanFilter::new(
        model,
        points,
        SVector::<f32, N>::from_row_slice(&fixture.f32s("x0")),
        fixture.matrix::<N>("P0"),
        fixture.matrix::<N>("Q"),
        fixture.matrix::<M>("R"),
    )
    .and_then(|f| f.with_form(form))
    .expect("fixture filter");
    let upper_entries = N * (N + 1) / 2;
    let mut dev = Deviation::default();
    for (step, (kind, values)) in fixture.records.iter().enumerate() {
        let width = if kind == "predict" { 2 } else { M };
        assert_eq!(values.len(), width + N + upper_entries, "record {step}");
        let data: Vec<f32> = values[..width]
            .iter()
            .map(|t| t.parse().expect("an f32"))
            .collect();
        let reference: Vec<f64> = values[width..]
            .iter()
            .map(|t| t.parse().expect("an f64"))
            .collect();
        let outcome = if kind == "predict" {
            ukf.predict(&[data[0], data[1]], dt)
        } else {
            ukf.update(&SVector::<f32, M>::from_row_slice(&data))
        };
        assert_eq!(outcome, StepOutcome::Applied, "record {step} ({kind})");
        let (x_ref, p_upper) = reference.split_at(N);
        let mut p_ref = SMatrix::<f64, N, N>::zeros();
        let mut upper = p_upper.iter();
        for i in 0..N {
            for j in i..N {
                let v = *upper.next().expect("the upper triangle");
                p_ref[(i, j)] = v;
                p_ref[(j, i)] = v;
            }
        }
        let (x, p) = (ukf.state(), ukf.covariance());
        for i in 0..N {
            let mut d = f64::from(x[i]) - x_ref[i];
            if i == 2 {
                d = (d + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                    - std::f64::consts::PI;
            }
            let sigma = d.abs() / p_ref[(i, i)].sqrt();
            dev.state_abs = dev.state_abs.max(d.abs());
            if sigma > dev.state_sigma {
                dev.state_sigma = sigma;
                dev.worst_step = step;
            }
            for j in 0..N {
                let scale = (p_ref[(i, i)] * p_ref[(j, j)]).sqrt();
                let e = (f64::from(p[(i, j)]) - p_ref[(i, j)]).abs() / scale;
                dev.covariance = dev.covariance.max(e);
            }
        }
        dev.steps += 1;
    }
    assert_eq!(ukf.counters(), Default::default());
    dev
}

fn report(name: &str, dev: &Deviation) {
    println!(
        "{name}: {} steps; worst |Δx| {:.2e} σ (record {}), {:.2e} m|rad; worst |ΔP|/√(PᵢᵢPⱼⱼ) {:.2e}",
        dev.steps, dev.state_sigma, dev.worst_step, dev.state_abs, dev.covariance
    );
}

/// `α = 0.5`, a range-and-bearing measurement and a non-diagonal `P0`:
/// the tight check (module docs of this file).
#[test]
fn landmarks_alpha_half_matches_filterpy() {
    let fixture = Fixture::read("landmarks.txt");
    let m = fixture.f32s("landmarks");
    let model = Landmarks {
        marks: [[m[0], m[1]], [m[2], m[3]]],
    };
    let dev = run::<_, 3, 4, 7>(&fixture, model, UkfForm::Covariance);
    report("landmarks (α = 0.5)", &dev);
    assert_eq!(dev.steps, 200);
    // Measured 2.4e-5 σ and 1.8e-5 (tolerances: module docs).
    assert!(dev.state_sigma < 1e-4, "{dev:?}");
    assert!(dev.covariance < 1e-4, "{dev:?}");
}

/// Paper 004's scenario 1 with angle-aware hooks, `α = 0.01`.
#[test]
fn scenario1_alpha_001_matches_filterpy() {
    let fixture = Fixture::read("scenario1.txt");
    let dev = run::<_, 3, 3, 7>(&fixture, Scenario1 { angles: true }, UkfForm::Covariance);
    report("scenario 1 (α = 0.01, angle hooks)", &dev);
    assert_eq!(dev.steps, 500);
    // Measured 0.061 σ and 2.2e-3: f32 rounding amplified by Σ|Wᵢ| = 1e4
    // (module docs).
    assert!(dev.state_sigma < 0.2, "{dev:?}");
    assert!(dev.covariance < 1e-2, "{dev:?}");
}

/// Scenario 1 with FilterPy's default hooks and the paper's `P0 = 10 I`.
#[test]
fn scenario1_default_hooks_matches_filterpy() {
    let fixture = Fixture::read("scenario1_plain.txt");
    assert_eq!(fixture.matrix::<3>("P0"), M3::identity() * 10.0);
    let dev = run::<_, 3, 3, 7>(&fixture, Scenario1 { angles: false }, UkfForm::Covariance);
    report("scenario 1 (α = 0.01, default hooks, P0 = 10 I)", &dev);
    assert_eq!(dev.steps, 500);
    // Measured 0.048 σ and 1.4e-2 (P_ψψ low by up to 1.4 % with ψ at 4.9
    // rad; module docs).
    assert!(dev.state_sigma < 0.2, "{dev:?}");
    assert!(dev.covariance < 4e-2, "{dev:?}");
}

/// The four-state case (`fixtures/ukf/range_bearing4.txt`, written
/// by `generate_range_bearing.py`): state `(X, Y, ψ, v)`, input `(a, ω)`,
/// range and bearing to two landmarks, `α = 0.5`, ψ crossing ±π twice.
#[derive(Debug, Clone, Copy)]
struct RangeBearing4 {
    marks: [[f32; 2]; 2],
}

impl UkfModel<4, 4> for RangeBearing4 {
    type Input = [f32; 2];
    fn input_is_finite(&self, u: &[f32; 2]) -> bool {
        u.iter().all(|v| v.is_finite())
    }
    fn transition(&self, x: &SVector<f32, 4>, u: &[f32; 2], dt_s: f32) -> SVector<f32, 4> {
        let [a, w] = *u;
        SVector::<f32, 4>::new(
            x[0] + dt_s * x[3] * cos(x[2]),
            x[1] + dt_s * x[3] * sin(x[2]),
            wrap_angle(x[2] + dt_s * w),
            x[3] + dt_s * a,
        )
    }
    fn measure(&self, x: &SVector<f32, 4>) -> SVector<f32, 4> {
        let mut z = SVector::<f32, 4>::zeros();
        for (k, [lx, ly]) in self.marks.iter().enumerate() {
            let (dx, dy) = (lx - x[0], ly - x[1]);
            z[2 * k] = dx.hypot(dy);
            z[2 * k + 1] = wrap_angle(dy.atan2(dx) - x[2]);
        }
        z
    }
    fn angles(&self) -> AngleComponents<4, 4> {
        AngleComponents::from_indices(&PSI, &BEARINGS)
    }
}

/// The worst deviations of the `f32` filter in `form` from FilterPy over
/// the four-state fixture ([`run`]).
fn run_range_bearing4(form: UkfForm) -> Deviation {
    const TEXT: &str = include_str!("../fixtures/ukf/range_bearing4.txt");
    let fixture = Fixture::parse(TEXT);
    let m = fixture.f32s("landmarks");
    let model = RangeBearing4 {
        marks: [[m[0], m[1]], [m[2], m[3]]],
    };
    run::<_, 4, 4, 9>(&fixture, model, form)
}

/// Both forms against FilterPy on the four-state range-and-bearing case
/// whose heading crosses ±π. The covariance form is FilterPy's algebra
/// (its Joseph-type update is the same `P` for the optimal gain): measured
/// 2.4e-5 σ and 5.5e-6, held to the landmark case's `α = 0.5` tolerance,
/// 1e-4. The square-root form takes its sums about the centre point
/// (module docs of `wmr_core::filters::ukf`, "Square-root form"), which is
/// FilterPy's covariance exactly only where the mean is the weighted mean
/// of the deviations; ψ's and the bearings' means are circular. Measured:
/// 6.8e-4 σ and 1.6e-3, worst at the first update from the wide prior
/// (record 1), where the circular means depart most from the weighted ones
/// (that cause is inferred, not isolated); asserted at 3×, 2e-3 σ and 5e-3.
#[test]
fn range_bearing_four_states_matches_filterpy_in_both_forms() {
    for form in [UkfForm::Covariance, UkfForm::SquareRoot] {
        let dev = run_range_bearing4(form);
        report(
            &format!("range and bearing, N = 4, ψ across ±π ({form:?})"),
            &dev,
        );
        assert_eq!(dev.steps, 300);
        let (state_tol, covariance_tol) = match form {
            UkfForm::Covariance => (1e-4, 1e-4),
            UkfForm::SquareRoot => (2e-3, 5e-3),
        };
        assert!(dev.state_sigma < state_tol, "{form:?}: {dev:?}");
        assert!(dev.covariance < covariance_tol, "{form:?}: {dev:?}");
    }
}
