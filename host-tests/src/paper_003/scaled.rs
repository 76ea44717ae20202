//! Paper 003, Proposition 2 (the observer with dynamic scaling, for general
//! inertia and known friction) on the 2-D spider crane of section 6.3.
//!
//! The observer gets only `M(q)` and `∂M/∂q3` and factors `M⁻¹` with the
//! standard (lower-triangular) Cholesky factor, which for this crane does
//! *not* have commuting columns (Remark 6.1): the gyroscopic term `J(q, p)`
//! of (6) is not zero and the mismatch terms `Δ_q, Δ_p` the scaling must
//! dominate are live. The plant is the same independent `f64` Lagrangian
//! integration as for Proposition 1, and the true transformed momenta are
//! `p = Tᵀ M q̇ = T⁻¹ q̇`.

use nalgebra::Vector3;
use wmr_core::drive::momenta_observer::{Matrix, Vector};
use wmr_papers::scaled_momenta_observer::{
    InertiaFactor, InertiaModel, ScaledMomentaObserver, ScaledMomentaObserverConfig,
};

use super::{SpiderCrane, rk4};
use crate::paper_002::Series;

/// The crane's friction, all known to Proposition 2: `r = (0, 0, 0.5)`.
const FRICTION: [f64; 3] = [0.0, 0.0, 0.5];

impl InertiaModel<3> for SpiderCrane {
    /// `u = (F_x, F_y)`.
    type Input = [f32; 2];

    fn inertia(&self, q: &Vector<3>) -> Matrix<3> {
        self.inertia(f64::from(q.z)).map(|x| x as f32)
    }

    fn inertia_derivative(&self, q: &Vector<3>, i: usize) -> Matrix<3> {
        if i != 2 {
            return Matrix::<3>::zeros();
        }
        let ml = (self.payload_mass * self.cable_length) as f32;
        let (s, c) = q.z.sin_cos();
        Matrix::<3>::new(0.0, 0.0, -ml * s, 0.0, 0.0, ml * c, -ml * s, ml * c, 0.0)
    }

    fn potential_gradient(&self, _q: &Vector<3>) -> Vector<3> {
        Vector::<3>::zeros()
    }

    fn input_forces(&self, _q: &Vector<3>, u: &[f32; 2]) -> Vector<3> {
        Vector::<3>::new(u[0], u[1], 0.0)
    }

    fn friction(&self) -> Vector<3> {
        Vector::<3>::from(FRICTION.map(|x| x as f32))
    }
}

/// The true transformed momenta `p = T⁻¹ q̇`, `T` the lower Cholesky
/// factor of `M⁻¹`, in `f64`.
fn true_momenta(crane: &SpiderCrane, q: &Vector3<f64>, qd: &Vector3<f64>) -> Vector3<f64> {
    let inverse = crane
        .inertia(q.z)
        .try_inverse()
        .expect("M(q) is positive definite");
    let factor = inverse
        .cholesky()
        .expect("M⁻¹(q) is positive definite")
        .unpack();
    factor
        .solve_lower_triangular(qd)
        .expect("the factor is invertible")
}

/// A run's setup.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScaledCraneRun {
    /// `κ`, 1/s (`ψ = 4(1 + κ)`).
    pub kappa: f32,
    /// `γ_d` (paper: 1).
    pub disturbance_gain: f32,
    /// Initial `p̂`.
    pub momenta_0: [f32; 3],
    /// Initial `d̂`.
    pub disturbance_0: [f32; 3],
    /// Initial scaling factor `r(0) ≥ 1`.
    pub scaling_0: f32,
    /// Observer sample period `h`, s (the plant takes 10 RK4 steps per
    /// sample).
    pub period_s: f64,
    /// Duration, s.
    pub duration_s: f64,
}

/// The errors of a run, sampled every 10 ms.
#[derive(Debug, Clone, PartialEq)]
pub struct ScaledCraneErrors {
    /// `|p̃|`.
    pub momenta: Series,
    /// `|q̇̂ − q̇|`.
    pub velocity: Series,
    /// `|d̃|`.
    pub disturbance: Series,
    /// The scaling factor `r`.
    pub scaling: Series,
    /// `|J(q, p) p|`, the gyroscopic force of the true momenta: how much the
    /// non-commuting factor matters.
    pub gyroscopic: Series,
    /// Samples the observer rejected.
    pub rejected_updates: u32,
}

/// Section 6.3's inputs `F_x = 1.535 cos t, F_y = 7.67 sin t`, disturbance
/// `d = (0.1, 0.2, 0.2)`, friction `(0, 0, 0.5)` (known); plant from rest at
/// the origin by RK4 at `h/10`; the observer samples `q` every `h` in
/// `f32`. Errors are recorded every 10 ms.
///
/// # Panics
/// If the setup's gains are out of range.
#[must_use]
pub fn scaled_crane_run(run: &ScaledCraneRun) -> ScaledCraneErrors {
    let crane = SpiderCrane::PAPER;
    let h = run.period_s;
    let substeps = 10;
    let dt = h / f64::from(substeps);
    let friction = Vector3::from(FRICTION);
    let config = ScaledMomentaObserverConfig::new(run.kappa, h as f32)
        .and_then(|c| c.with_disturbance_gain(run.disturbance_gain))
        .and_then(|c| c.with_initial_scaling(run.scaling_0))
        .expect("valid gains");
    let mut observer = ScaledMomentaObserver::new(
        crane,
        config,
        Vector::<3>::from(run.momenta_0),
        Vector::<3>::from(run.disturbance_0),
    );
    let disturbance = Vector3::new(0.1, 0.2, 0.2);
    let mut q = Vector3::<f64>::zeros();
    let mut qd = Vector3::<f64>::zeros();
    let mut out = ScaledCraneErrors {
        momenta: Series::new("|p̃|"),
        velocity: Series::new("|q̇̂ − q̇|"),
        disturbance: Series::new("|d̃|"),
        scaling: Series::new("r"),
        gyroscopic: Series::new("|J(q,p)p|"),
        rejected_updates: 0,
    };
    let to64 = |v: &Vector<3>| Vector3::new(f64::from(v.x), f64::from(v.y), f64::from(v.z));
    let steps = (run.duration_s / h).round() as u32;
    let sample_every = ((0.01 / h).round() as u32).max(1);
    for k in 0..=steps {
        let t = f64::from(k) * h;
        let u = [(1.535 * t.cos()) as f32, (7.67 * t.sin()) as f32];
        let q32 = q.map(|x| x as f32);
        observer.update(&q32, &u);
        if k % sample_every == 0 {
            let e = observer.estimate();
            let p = true_momenta(&crane, &q, &qd);
            out.momenta
                .points
                .push((t, (to64(&e.transformed_momenta) - p).norm()));
            out.velocity
                .points
                .push((t, (to64(&e.velocity) - qd).norm()));
            out.disturbance
                .points
                .push((t, (to64(&e.disturbance) - disturbance).norm()));
            out.scaling.points.push((t, f64::from(e.scaling)));
            let p32 = p.map(|x| x as f32);
            let gyro = InertiaFactor::at(&crane, &q32)
                .map_or(f64::NAN, |f| f64::from((f.gyroscopic(&p32) * p32).norm()));
            out.gyroscopic.points.push((t, gyro));
        }
        let force = Vector3::new(f64::from(u[0]), f64::from(u[1]), 0.0) + disturbance;
        for _ in 0..substeps {
            (q, qd) = rk4(&crane, &q, &qd, &force, &friction, dt);
        }
    }
    out.rejected_updates = observer.rejected_updates();
    out
}

/// Checks the transformed model (5)–(7) the observer is built on against
/// the `f64` Lagrangian plant: along the paper's motion, the rate of the
/// true `p = T⁻¹q̇` (central differences, 10 µs) against
/// `J(q, p) p − Tᵀ(−F − d) − R p` from the core's factor and gyroscopic
/// term. Returns `(largest residual, largest |J p|)` over 10 s, so a sign
/// slip in `J` (a residual of `2|J p|`) shows.
#[must_use]
pub fn transformed_model_residual() -> (f64, f64) {
    let crane = SpiderCrane::PAPER;
    let friction = Vector3::from(FRICTION);
    let disturbance = Vector3::new(0.1, 0.2, 0.2);
    let dt = 1e-5_f64;
    let mut q = Vector3::<f64>::zeros();
    let mut qd = Vector3::<f64>::zeros();
    let (mut worst, mut largest_gyro) = (0.0_f64, 0.0_f64);
    for k in 0..1_000_000_u32 {
        let t = f64::from(k) * dt;
        let force = Vector3::new(1.535 * t.cos(), 7.67 * t.sin(), 0.0) + disturbance;
        if k % 10_000 == 5_000 {
            let (qm, qdm) = rk4(&crane, &q, &qd, &force, &friction, -dt);
            let (qp, qdp) = rk4(&crane, &q, &qd, &force, &friction, dt);
            let rate =
                (true_momenta(&crane, &qp, &qdp) - true_momenta(&crane, &qm, &qdm)) / (2.0 * dt);
            let p = true_momenta(&crane, &q, &qd).map(|x| x as f32);
            let factor = InertiaFactor::at(&crane, &q.map(|x| x as f32)).expect("factors");
            let t32 = factor.factor();
            let gyro = factor.gyroscopic(&p) * p;
            let friction32 = friction.map(|x| x as f32);
            let model = gyro + t32.transpose() * force.map(|x| x as f32)
                - t32.transpose() * friction32.component_mul(&(t32 * p));
            let residual = (rate - model.map(f64::from)).norm();
            worst = worst.max(residual);
            largest_gyro = largest_gyro.max(f64::from(gyro.norm()));
        }
        (q, qd) = rk4(&crane, &q, &qd, &force, &friction, dt);
    }
    (worst, largest_gyro)
}
