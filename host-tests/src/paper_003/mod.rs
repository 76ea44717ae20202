//! Simulations of paper 003 (Romero & Ortega), shared by
//! `tests/paper_003_*.rs` (which assert on them) and the example
//! `paper_003_figures` (which plots them).
//!
//! * [`SpiderCrane`]: the 2-D spider crane of section 6.3 as a
//!   [`MechanicalModel`] for the core's observer, and its plant, integrated
//!   independently in `f64` from its Lagrangian (RK4).
//! * [`wheel_run`]: the differential drive in its wheel angles with
//!   1024-count encoders at the control rate: the observer's wheel speeds
//!   against differencing the counts, load torque and friction estimates.
//! * [`scaled`]: Proposition 2 (dynamic scaling) on the same crane with
//!   the Cholesky factor of its inverse inertia.

use nalgebra::{Matrix3, Vector3};
use wmr_core::drive::momenta_observer::{
    Matrix, MechanicalModel, MomentaObserver, MomentaObserverConfig, Vector, WheelInertia,
};

use crate::paper_002::Series;

pub mod drive_loop;
pub mod scaled;

/// The 2-D spider crane gantry cart of section 6.3: a ring of mass `m_r`
/// at `(q1, q2)` and a payload of mass `m` on a cable of length `L3` at
/// angle `q3`, payload at `(q1 + L3 sin q3, q2 − L3 cos q3)`. The paper
/// gives no potential energy (its constants are in its reference \[9\]); the
/// simulations here take the motion in a horizontal plane, `V = 0`. The
/// observer uses `∇V` exactly as the plant does, so this only shapes the
/// excitation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpiderCrane {
    /// Ring mass `m_r`, kg.
    pub ring_mass: f64,
    /// Payload mass `m`, kg.
    pub payload_mass: f64,
    /// Cable length `L3`, m.
    pub cable_length: f64,
}

impl SpiderCrane {
    /// The paper's parameters: `m_r = 0.5 kg, m = 1 kg, L3 = 0.5 m`.
    pub const PAPER: Self = Self {
        ring_mass: 0.5,
        payload_mass: 1.0,
        cable_length: 0.5,
    };

    /// `(a, b, c)` of (53).
    pub(crate) fn constants(&self) -> (f64, f64, f64) {
        let (mr, m, l) = (self.ring_mass, self.payload_mass, self.cable_length);
        let a = 1.0 / (mr + m).sqrt();
        let c = ((mr + m) / (m * l * l * mr)).sqrt();
        let b = 1.0 / (c * l * mr);
        (a, b, c)
    }

    /// The inertia matrix `M(q)`.
    #[must_use]
    pub fn inertia(&self, q3: f64) -> Matrix3<f64> {
        let (mr, m, l) = (self.ring_mass, self.payload_mass, self.cable_length);
        let (s, c) = q3.sin_cos();
        Matrix3::new(
            mr + m,
            0.0,
            m * l * c,
            0.0,
            mr + m,
            m * l * s,
            m * l * c,
            m * l * s,
            m * l * l,
        )
    }

    /// `T⁻¹(q)` (printed after (53)): the true transformed momenta are
    /// `p = Tᵀ𝐩 = T⁻¹ q̇`.
    #[must_use]
    pub fn factor_inverse(&self, q3: f64) -> Matrix3<f64> {
        let (a, _, c) = self.constants();
        let ml = a * self.cable_length * self.payload_mass;
        let (s, co) = q3.sin_cos();
        Matrix3::new(
            1.0 / a,
            0.0,
            ml * co,
            0.0,
            1.0 / a,
            ml * s,
            0.0,
            0.0,
            1.0 / c,
        )
    }

    /// The plant's acceleration from the Lagrangian, independent of (53):
    /// `M q̈ = F + d − ℜ q̇ − (−m L3 sin q3 q̇3², m L3 cos q3 q̇3², 0)`.
    pub(crate) fn acceleration(
        &self,
        q: &Vector3<f64>,
        qd: &Vector3<f64>,
        force: &Vector3<f64>,
        friction: &Vector3<f64>,
    ) -> Vector3<f64> {
        let (m, l) = (self.payload_mass, self.cable_length);
        let (s, c) = q.z.sin_cos();
        let w2 = qd.z * qd.z;
        let centripetal = Vector3::new(-m * l * s * w2, m * l * c * w2, 0.0);
        let rhs = force - friction.component_mul(qd) - centripetal;
        self.inertia(q.z)
            .lu()
            .solve(&rhs)
            .expect("M(q) is positive definite")
    }
}

impl MechanicalModel<3> for SpiderCrane {
    /// `u = (F_x, F_y)`, `G = [[1, 0], [0, 1], [0, 0]]`.
    type Input = [f32; 2];

    fn inverse_inertia_factor(&self, q: &Vector<3>) -> Matrix<3> {
        let (a, b, c) = self.constants();
        let (s, co) = f64::from(q.z).sin_cos();
        Matrix::<3>::new(
            a as f32,
            0.0,
            (-b * co) as f32,
            0.0,
            a as f32,
            (-b * s) as f32,
            0.0,
            0.0,
            c as f32,
        )
    }

    fn flat_coordinates(&self, q: &Vector<3>) -> Vector<3> {
        let (a, _, c) = self.constants();
        let ml = a * self.cable_length * self.payload_mass;
        let (q1, q2, q3) = (f64::from(q.x), f64::from(q.y), f64::from(q.z));
        Vector::<3>::new(
            (q1 / a + ml * q3.sin()) as f32,
            (q2 / a - ml * q3.cos()) as f32,
            (q3 / c) as f32,
        )
    }

    fn potential_gradient(&self, _q: &Vector<3>) -> Vector<3> {
        Vector::<3>::zeros()
    }

    fn input_forces(&self, _q: &Vector<3>, u: &[f32; 2]) -> Vector<3> {
        Vector::<3>::new(u[0], u[1], 0.0)
    }

    fn known_friction(&self) -> Vector<3> {
        // r1 = r2 = 0 known; r3 identified (its entry is ignored).
        Vector::<3>::zeros()
    }
}

/// A crane run's setup.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CraneRun {
    /// `λ`, 1/s (paper: 0.8).
    pub lambda: f32,
    /// Initial `p̂`.
    pub momenta_0: [f32; 3],
    /// Initial `d̂`.
    pub disturbance_0: [f32; 3],
    /// Initial `r̂3`.
    pub friction_0: f32,
    /// `d1` steps by this much at each multiple of `d1_step_every_s`
    /// (alternating up and down), 0 for none (paper's figure 7).
    pub d1_step: f64,
    /// Period of the `d1` steps, s.
    pub d1_step_every_s: f64,
    /// Duration, s.
    pub duration_s: f64,
}

impl CraneRun {
    /// The paper's figure 3/4 setup with `λ = 0.8` and these initial
    /// estimates.
    #[must_use]
    pub fn paper(momenta_0: [f32; 3], disturbance_0: [f32; 3], friction_0: f32) -> Self {
        Self {
            lambda: 0.8,
            momenta_0,
            disturbance_0,
            friction_0,
            d1_step: 0.0,
            d1_step_every_s: 0.0,
            duration_s: 60.0,
        }
    }
}

/// The errors of a crane run, sampled every 10 ms.
#[derive(Debug, Clone, PartialEq)]
pub struct CraneErrors {
    /// `|p̃|`, the transformed momenta error.
    pub momenta: Series,
    /// `|d̃|`.
    pub disturbance: Series,
    /// `r̃3`.
    pub friction: Series,
    /// `d1` and `d̂1` (for the step run).
    pub d1: Series,
    /// `d̂1`.
    pub d1_hat: Series,
    /// `V = ½(|p̃|² + |d̃|² + r̃²)` (25).
    pub lyapunov: Series,
}

/// Section 6.3: inputs `F_x = 1.535 cos t, F_y = 7.67 sin t`,
/// `d = (0.1, 0.2, 0.2)`, `r = (0, 0, 0.5)` with `r3` unknown; plant from
/// rest at the origin, integrated with RK4 at 0.1 ms; the observer samples
/// `q` every `h = 1 ms` (`f32`).
///
/// # Panics
/// If the setup's `λ` is not positive.
#[must_use]
pub fn crane_run(run: &CraneRun) -> CraneErrors {
    let crane = SpiderCrane::PAPER;
    let h = 1e-3_f64;
    let substeps = 10;
    let dt = h / f64::from(substeps);
    let friction = Vector3::new(0.0, 0.0, 0.5);
    let config =
        MomentaObserverConfig::new::<3>(run.lambda, h as f32, [2]).expect("positive lambda");
    let mut observer = MomentaObserver::new(
        crane,
        config,
        Vector::<3>::from(run.momenta_0),
        Vector::<3>::from(run.disturbance_0),
        nalgebra::SVector::<f32, 1>::new(run.friction_0),
    );
    let mut q = Vector3::<f64>::zeros();
    let mut qd = Vector3::<f64>::zeros();
    let mut out = CraneErrors {
        momenta: Series::new("|p̃|"),
        disturbance: Series::new("|d̃|"),
        friction: Series::new("|r̃3|"),
        d1: Series::new("d1"),
        d1_hat: Series::new("d̂1"),
        lyapunov: Series::new("V (25)"),
    };
    let disturbance = |t: f64| {
        let steps = if run.d1_step_every_s > 0.0 {
            (t / run.d1_step_every_s).floor() as i64
        } else {
            0
        };
        let d1 = 0.1 + if steps % 2 == 1 { run.d1_step } else { 0.0 };
        Vector3::new(d1, 0.2, 0.2)
    };
    let steps = (run.duration_s / h).round() as u32;
    for k in 0..=steps {
        let t = f64::from(k) * h;
        let u = [(1.535 * t.cos()) as f32, (7.67 * t.sin()) as f32];
        let q32 = Vector::<3>::new(q.x as f32, q.y as f32, q.z as f32);
        observer.update(&q32, &u);
        if k % 10 == 0 {
            let e = observer.estimate();
            let p = crane.factor_inverse(q.z) * qd;
            let p_err = Vector3::new(
                f64::from(e.transformed_momenta.x),
                f64::from(e.transformed_momenta.y),
                f64::from(e.transformed_momenta.z),
            ) - p;
            let d = disturbance(t);
            let d_err = Vector3::new(
                f64::from(e.disturbance.x),
                f64::from(e.disturbance.y),
                f64::from(e.disturbance.z),
            ) - d;
            let r_err = f64::from(e.friction.x) - friction.z;
            out.momenta.points.push((t, p_err.norm()));
            out.disturbance.points.push((t, d_err.norm()));
            out.friction.points.push((t, r_err));
            out.d1.points.push((t, d.x));
            out.d1_hat.points.push((t, f64::from(e.disturbance.x)));
            out.lyapunov.points.push((
                t,
                0.5 * (p_err.norm_squared() + d_err.norm_squared() + r_err * r_err),
            ));
        }
        // Plant over [t, t + h] with the input held (zero-order hold, as
        // the observer assumes) and the disturbance of t.
        let force = Vector3::new(f64::from(u[0]), f64::from(u[1]), 0.0) + disturbance(t);
        for _ in 0..substeps {
            (q, qd) = rk4(&crane, &q, &qd, &force, &friction, dt);
        }
    }
    out
}

pub(crate) fn rk4(
    crane: &SpiderCrane,
    q: &Vector3<f64>,
    qd: &Vector3<f64>,
    force: &Vector3<f64>,
    friction: &Vector3<f64>,
    dt: f64,
) -> (Vector3<f64>, Vector3<f64>) {
    let f = |q: &Vector3<f64>, qd: &Vector3<f64>| (*qd, crane.acceleration(q, qd, force, friction));
    let (k1q, k1v) = f(q, qd);
    let (k2q, k2v) = f(&(q + k1q * (dt / 2.0)), &(qd + k1v * (dt / 2.0)));
    let (k3q, k3v) = f(&(q + k2q * (dt / 2.0)), &(qd + k2v * (dt / 2.0)));
    let (k4q, k4v) = f(&(q + k3q * dt), &(qd + k3v * dt));
    (
        q + (k1q + k2q * 2.0 + k3q * 2.0 + k4q) * (dt / 6.0),
        qd + (k1v + k2v * 2.0 + k3v * 2.0 + k4v) * (dt / 6.0),
    )
}

/// The robot used by [`wheel_run`]: 4 kg, yaw inertia 0.08 kg m², wheel
/// radius 3.5 cm, track 20 cm, each wheel's drive train 2e-4 kg m² at the
/// wheel; viscous friction 0.01 N·m·s/rad per wheel.
///
/// # Panics
/// Never (constant, valid parameters).
#[must_use]
pub fn small_robot() -> WheelInertia {
    WheelInertia::new(4.0, 0.08, 0.035, 0.2, 2e-4).expect("valid robot")
}

/// Observer gains of a wheel run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WheelGains {
    /// `λ`, 1/s.
    pub lambda: f32,
    /// `γ_r`.
    pub friction_gain: f32,
    /// `γ_d`.
    pub disturbance_gain: f32,
}

/// The gains the wheel runs use: `λ = 5 /s` (quantization noise in `p̂`
/// grows with `λ`, and through the quadratic friction update it biases
/// `r̂`), `γ_r = 0.01`, `γ_d = 0.1`: chosen on a 9-point grid for the
/// speed RMS and unbiased friction.
pub const WHEEL_GAINS: WheelGains = WheelGains {
    lambda: 5.0,
    friction_gain: 0.01,
    disturbance_gain: 0.1,
};

/// Results of a wheel run.
#[derive(Debug, Clone, PartialEq)]
pub struct WheelRun {
    /// RMS error of the observer's wheel speeds after the first 2 s, rad/s.
    pub observer_speed_rms: f64,
    /// RMS error of differencing the counts over one tick, rad/s.
    pub differencing_speed_rms: f64,
    /// Load torque estimate of each wheel, mean over the last 20 s, N·m.
    pub final_load_torque: [f64; 2],
    /// Load torque estimate of each wheel, mean over the 20 s before the
    /// load step, N·m (truth: 0).
    pub pre_step_load_torque: [f64; 2],
    /// True load torque after the step, N·m.
    pub true_load_torque: f64,
    /// Friction estimate of each wheel, mean over the last 20 s, N·m·s/rad.
    pub final_friction: [f64; 2],
    /// True friction, N·m·s/rad.
    pub true_friction: f64,
    /// Time after the load step until the mean of the two load estimates
    /// first reaches 90 % of the step, s (`None` if it never does).
    pub load_rise_s: Option<f64>,
    /// Right wheel: true speed, observer, differencing (rad/s), every tick.
    pub speeds: [Series; 3],
    /// Load torque estimates and truth (N·m), every tick.
    pub loads: [Series; 3],
}

/// The differential drive in its wheel angles, 1024-count encoders read
/// every `h = 10 ms`, observer gains `gains`, both frictions identified. The
/// motors apply a varying torque (two sines per wheel, so speeds and
/// accelerations excite the friction estimate) for `duration_s`; at
/// `load_step_s` the robot drives onto a 5 % slope: a load torque of
/// `−m g sin α r / 2` on each wheel.
///
/// # Panics
/// If a gain is not positive.
#[must_use]
pub fn wheel_run(gains: WheelGains, duration_s: f64, load_step_s: f64) -> WheelRun {
    let robot = small_robot();
    let m = robot.matrix();
    let inertia = nalgebra::Matrix2::new(
        f64::from(m.m11),
        f64::from(m.m12),
        f64::from(m.m21),
        f64::from(m.m22),
    );
    let inertia_inv = inertia.try_inverse().expect("positive definite");
    let friction = 0.01_f64;
    let h = 0.01_f64;
    let substeps = 20;
    let dt = h / f64::from(substeps);
    let counts_per_rad = 1024.0 / std::f64::consts::TAU;
    let model = robot.model(Vector::<2>::zeros()).expect("valid model");
    let config = MomentaObserverConfig::new::<2>(gains.lambda, h as f32, [0, 1])
        .and_then(|c| c.with_adaptation_gains(gains.friction_gain, gains.disturbance_gain))
        .expect("positive gains");
    let mut observer = MomentaObserver::new(
        model,
        config,
        Vector::<2>::zeros(),
        Vector::<2>::zeros(),
        nalgebra::SVector::<f32, 2>::zeros(),
    );
    let slope_torque = -4.0 * 9.81 * 0.05_f64.atan().sin() * 0.035 / 2.0;
    let load = |t: f64| if t >= load_step_s { slope_torque } else { 0.0 };
    let mut q = nalgebra::Vector2::<f64>::zeros();
    let mut qd = nalgebra::Vector2::<f64>::zeros();
    let mut last_counts = [0_i64; 2];
    let (mut n, mut sum_obs, mut sum_diff) = (0_u32, 0.0, 0.0);
    let mut rise: Option<f64> = None;
    let (mut final_load, mut pre_load, mut final_friction) = ([0.0; 2], [0.0; 2], [0.0; 2]);
    let (mut n_final, mut n_pre) = (0_u32, 0_u32);
    let mut speeds = [
        Series::new("true φ̇_R"),
        Series::new("observer"),
        Series::new("differencing counts"),
    ];
    let mut loads = [
        Series::new("d̂_R"),
        Series::new("d̂_L"),
        Series::new("true load"),
    ];
    let steps = (duration_s / h).round() as u32;
    for k in 0..=steps {
        let t = f64::from(k) * h;
        let counts = [
            (q.x * counts_per_rad).floor() as i64,
            (q.y * counts_per_rad).floor() as i64,
        ];
        let measured = Vector::<2>::new(
            (counts[0] as f64 / counts_per_rad) as f32,
            (counts[1] as f64 / counts_per_rad) as f32,
        );
        let torque = nalgebra::Vector2::new(
            0.06 + 0.05 * (0.9 * t).sin() + 0.02 * (3.1 * t).sin(),
            0.06 + 0.05 * (0.7 * t).sin() - 0.02 * (2.3 * t).cos(),
        );
        observer.update(
            &measured,
            &Vector::<2>::new(torque.x as f32, torque.y as f32),
        );
        let e = observer.estimate();
        let differencing = [
            (counts[0] - last_counts[0]) as f64 / counts_per_rad / h,
            (counts[1] - last_counts[1]) as f64 / counts_per_rad / h,
        ];
        last_counts = counts;
        if t >= 2.0 {
            n += 1;
            sum_obs +=
                (f64::from(e.velocity.x) - qd.x).powi(2) + (f64::from(e.velocity.y) - qd.y).powi(2);
            // Differencing over the last tick estimates the mean speed of
            // that tick; compared with the speed now, as a speed loop uses it.
            sum_diff += (differencing[0] - qd.x).powi(2) + (differencing[1] - qd.y).powi(2);
        }
        speeds[0].points.push((t, qd.x));
        speeds[1].points.push((t, f64::from(e.velocity.x)));
        speeds[2].points.push((t, differencing[0]));
        loads[0].points.push((t, f64::from(e.disturbance.x)));
        loads[1].points.push((t, f64::from(e.disturbance.y)));
        loads[2].points.push((t, load(t)));
        let loads_now = [f64::from(e.disturbance.x), f64::from(e.disturbance.y)];
        if t >= load_step_s
            && rise.is_none()
            && 0.5 * (loads_now[0] + loads_now[1]) <= 0.9 * slope_torque
        {
            rise = Some(t - load_step_s);
        }
        if t > duration_s - 20.0 {
            n_final += 1;
            for i in 0..2 {
                final_load[i] += loads_now[i];
                final_friction[i] += f64::from(e.friction[i]);
            }
        }
        if t < load_step_s && t >= load_step_s - 20.0 {
            n_pre += 1;
            for i in 0..2 {
                pre_load[i] += loads_now[i];
            }
        }
        for _ in 0..substeps {
            let force = torque + nalgebra::Vector2::repeat(load(t));
            let accel = |qd: &nalgebra::Vector2<f64>| inertia_inv * (force - qd * friction);
            let k1 = accel(&qd);
            let k2 = accel(&(qd + k1 * (dt / 2.0)));
            let k3 = accel(&(qd + k2 * (dt / 2.0)));
            let k4 = accel(&(qd + k3 * dt));
            let qd_next = qd + (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (dt / 6.0);
            q += (qd + qd_next) * (dt / 2.0);
            qd = qd_next;
        }
    }
    let n = f64::from(n.max(1) * 2);
    let mean = |sum: [f64; 2], n: u32| sum.map(|x| x / f64::from(n.max(1)));
    WheelRun {
        observer_speed_rms: (sum_obs / n).sqrt(),
        differencing_speed_rms: (sum_diff / n).sqrt(),
        final_load_torque: mean(final_load, n_final),
        pre_step_load_torque: mean(pre_load, n_pre),
        true_load_torque: slope_torque,
        final_friction: mean(final_friction, n_final),
        true_friction: friction,
        load_rise_s: rise,
        speeds,
        loads,
    }
}
