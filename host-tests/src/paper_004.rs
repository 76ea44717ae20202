//! Paper 004's two simulation scenarios (Iossaqui, Camino & Zampieri):
//! the tracked robot under a slip ratio that steps from 0 to 0.25 during
//! 22.5–45 s, tracking the piecewise reference with the adaptive
//! velocity-based (scenario 1) or torque-based (scenario 2) controller on
//! the estimates of a nonlinear filter fed with noisy full-state
//! measurements (`R` as in the paper), `h = 5 ms`, 60 s.
//!
//! The plant is integrated in `f64` (RK4, 10 substeps per step, inputs
//! held); the controllers and filters are the core's (`f32`). Measurement
//! noise is drawn from ChaCha8 with a fixed seed (Box–Muller).
//!
//! Choices the paper leaves open, each measured:
//! * the filters start at the known initial state (`x̂0 = E[x0] = q(0)`)
//!   with `P0 = 10 I` (the UKF's heading variance 1 rad²: its circular mean
//!   turns around above ~2 rad²); starting them at 0 made `p̂` jump to
//!   2.5 within 0.1 s on the initial estimate error;
//! * process noise [`PROCESS_NOISE`] (the paper's plant has none; with
//!   `Q = 0` the EKF stopped following the measurements and scenario 1
//!   diverged; 1e-4 and 1e-6 tracked worse);
//! * both scenarios' filters move the pose with the controller's `(v, ω)`
//!   of (6) (see `PoseWheelModel`);
//! * the particle filter's collapse gate is off: from `P0 = 10 I` every
//!   particle is beyond its default 13σ of the first measurement in 5-D,
//!   and it would ignore measurements for ever.
//!
//! Law (7) integrates `k1 e1² + (k3/k2) sin² e3` terms whose mean is
//! positive under estimate noise, so noisier estimates push `p̂` up: the
//! particle filter's do (scenario 1: `p̂` 1.7–8.2), and in scenario 2 the
//! drift, through `p̂` in (8), made 3 of 5 seeded runs diverge.

use nalgebra::{SMatrix, SVector, Vector2};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt as _, SeedableRng as _};
use wmr_core::ekf::ExtendedKalmanFilter;
use wmr_core::geometry::{Pose, WheelSpeeds};
use wmr_core::particle_filter::{ParticleFilter, ParticleFilterConfig};
use wmr_core::slip_tracking::{
    AdaptiveTorqueController, AdaptiveVelocityController, PiecewiseReference, PoseModel,
    PoseWheelModel, SlipGains, TrackedRobot, tracking_error,
};
use wmr_core::ukf::{MerweScaledSigmaPoints, UnscentedKalmanFilter};

use crate::paper_002::Series;

/// Control and filter step, s.
pub const PERIOD_S: f64 = 0.005;
/// Simulated time, s.
pub const DURATION_S: f64 = 60.0;
/// When the slip starts and ends, s.
pub const SLIP_WINDOW_S: (f64, f64) = (22.5, 45.0);
/// The slip ratio during the window.
pub const SLIP_RATIO: f64 = 0.25;

/// The slip ratio `i(t)`.
#[must_use]
pub fn slip_ratio(t: f64) -> f64 {
    if (SLIP_WINDOW_S.0..SLIP_WINDOW_S.1).contains(&t) {
        SLIP_RATIO
    } else {
        0.0
    }
}

/// How the controller gets its state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Estimator {
    /// The true state, no noise (the controllers' own behaviour).
    Exact,
    /// The core's EKF on noisy measurements.
    Ekf,
    /// The core's UKF (α = 0.01, β = 2, κ = 0) on noisy measurements.
    Ukf,
    /// The core's particle filter (100 particles) on noisy measurements.
    ParticleFilter,
}

/// Particles of the particle filter (paper: 100).
pub const PARTICLES: usize = 100;

/// The particle filter's process noise per step (standard deviations). The
/// EKF's `Q` (0.003 per step) leaves 100 particles too few distinct ones
/// after resampling (the cloud cannot follow a heading error back); of the
/// spreads tried (0.003–0.03) this one tracked best in scenario 1.
pub const PARTICLE_PROCESS_STD: [f32; 5] = [0.01, 0.01, 0.02, 0.5, 0.5];

/// Which of the paper's scenarios.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scenario {
    /// Adaptive velocity-based control, state `(X, Y, ψ)`, from
    /// `(0, −1.5, π/4)`.
    Velocity,
    /// Adaptive torque-based control, state `(X, Y, ψ, ω_L, ω_R)`, from
    /// `(0, −1, π/6, 0, 0)`.
    Torque,
}

/// The filter's process noise per step: position and heading, and (in
/// scenario 2) wheel speeds. The paper does not give its `Q` (its plant has
/// none); with `Q = 0` the filters stop listening to the measurements.
pub const PROCESS_NOISE: [f64; 5] = [1e-5, 1e-5, 1e-5, 1e-2, 1e-2];

/// A run's time series (every 50 ms) and summary.
#[derive(Debug, Clone, PartialEq)]
pub struct SlipRun {
    /// `e1, e2, e3` (4) of the true pose against the reference.
    pub error: [Series; 3],
    /// `p̂`.
    pub slip_estimate: Series,
    /// `|estimated − true position|`, m.
    pub estimate_error: Series,
    /// Scenario 2: `ω_L − ω_Ld`, `ω_R − ω_Rd` of the true wheel speeds.
    pub wheel_error: [Series; 2],
    /// True path `(X, Y)`.
    pub path: Vec<(f64, f64)>,
}

impl SlipRun {
    /// RMS of `|(e1, e2)|` over `[from, to)`, m.
    #[must_use]
    pub fn position_error_rms(&self, from: f64, to: f64) -> f64 {
        let (sum, n) = self.error[0]
            .points
            .iter()
            .zip(&self.error[1].points)
            .filter(|(a, _)| a.0 >= from && a.0 < to)
            .fold((0.0, 0_u32), |(s, n), (a, b)| {
                (s + a.1 * a.1 + b.1 * b.1, n + 1)
            });
        (sum / f64::from(n.max(1))).sqrt()
    }

    /// RMS of `e3` over `[from, to)`, rad.
    #[must_use]
    pub fn heading_error_rms(&self, from: f64, to: f64) -> f64 {
        let (sum, n) = self.error[2]
            .points
            .iter()
            .filter(|a| a.0 >= from && a.0 < to)
            .fold((0.0, 0_u32), |(s, n), a| (s + a.1 * a.1, n + 1));
        (sum / f64::from(n.max(1))).sqrt()
    }

    /// Mean `p̂` over `[from, to)`.
    #[must_use]
    pub fn mean_slip_estimate(&self, from: f64, to: f64) -> f64 {
        let (sum, n) = self
            .slip_estimate
            .points
            .iter()
            .filter(|a| a.0 >= from && a.0 < to)
            .fold((0.0, 0_u32), |(s, n), a| (s + a.1, n + 1));
        sum / f64::from(n.max(1))
    }
}

/// A standard normal draw (Box–Muller).
fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
    let radius = (-2.0 * (1.0 - rng.random::<f64>()).ln()).sqrt();
    radius * (std::f64::consts::TAU * rng.random::<f64>()).cos()
}

/// The plant's state rate: `(Ẋ, Ẏ, ψ̇, ω̇_L, ω̇_R)` for held wheel speeds
/// (scenario 1: the last two are the commanded speeds, no dynamics) or
/// torques.
fn plant_rate(
    robot: &TrackedRobot,
    s: &SVector<f64, 5>,
    p: f64,
    torque: Option<Vector2<f64>>,
) -> SVector<f64, 5> {
    let (r, b) = (0.35_f64, 0.65_f64);
    debug_assert_eq!(*robot, TrackedRobot::PAPER);
    let (wl, wr) = (s[3], s[4]);
    let v = r * (wl + wr) / (2.0 * p);
    let w = r * (wr - wl) / (b * p);
    let accel = torque.map_or(Vector2::zeros(), |tau| {
        let m0 = robot.wheel_inertia().map(f64::from);
        m0.try_inverse().expect("M0 invertible") * tau * p
    });
    SVector::<f64, 5>::new(v * s[2].cos(), v * s[2].sin(), w, accel.x, accel.y)
}

fn rk4(
    robot: &TrackedRobot,
    s: &SVector<f64, 5>,
    p: f64,
    torque: Option<Vector2<f64>>,
    dt: f64,
) -> SVector<f64, 5> {
    let f = |s: &SVector<f64, 5>| plant_rate(robot, s, p, torque);
    let k1 = f(s);
    let k2 = f(&(s + k1 * (dt / 2.0)));
    let k3 = f(&(s + k2 * (dt / 2.0)));
    let k4 = f(&(s + k3 * dt));
    s + (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (dt / 6.0)
}

fn wrap(a: f64) -> f64 {
    let w = (a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
    if w <= -std::f64::consts::PI {
        w + std::f64::consts::TAU
    } else {
        w
    }
}

/// Runs a scenario with an estimator and a noise seed.
///
/// # Panics
/// If a constant configuration is refused.
#[must_use]
pub fn slip_run(scenario: Scenario, estimator: Estimator, seed: u64) -> SlipRun {
    let robot = TrackedRobot::PAPER;
    let h = PERIOD_S as f32;
    let reference = PiecewiseReference::<4>::paper().expect("paper reference");
    let velocity =
        AdaptiveVelocityController::new(robot, SlipGains::PAPER, h, 1.0).expect("paper gains");
    let mut velocity_controller = velocity;
    let mut torque_controller = AdaptiveTorqueController::new(velocity);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise_std = [0.1_f64.sqrt(), 0.1_f64.sqrt(), 0.2_f64.sqrt(), 0.1, 0.1];
    let (x0, n) = match scenario {
        Scenario::Velocity => (
            SVector::<f64, 5>::new(0.0, -1.5, std::f64::consts::FRAC_PI_4, 0.0, 0.0),
            3,
        ),
        Scenario::Torque => (
            SVector::<f64, 5>::new(0.0, -1.0, std::f64::consts::FRAC_PI_6, 0.0, 0.0),
            5,
        ),
    };
    let diag = |v: &[f64]| v.iter().map(|&x| x as f32).collect::<Vec<_>>();
    let q = diag(&PROCESS_NOISE);
    let r = diag(&[0.1, 0.1, 0.2, 0.01, 0.01]);
    // x̂0 = E[x0]: the initial state is known (the paper gives it), its
    // covariance P0 = 10 I.
    let x0_32 = x0.map(|x| x as f32);
    let mut ekf3 = ExtendedKalmanFilter::new(
        PoseModel,
        x0_32.fixed_rows::<3>(0).into_owned(),
        SMatrix::<f32, 3, 3>::identity() * 10.0,
        SMatrix::<f32, 3, 3>::from_diagonal(&SVector::<f32, 3>::from_column_slice(&q[..3])),
        SMatrix::<f32, 3, 3>::from_diagonal(&SVector::<f32, 3>::from_column_slice(&r[..3])),
    )
    .expect("valid filter");
    let mut ekf5 = ExtendedKalmanFilter::new(
        PoseWheelModel,
        x0_32,
        SMatrix::<f32, 5, 5>::identity() * 10.0,
        SMatrix::<f32, 5, 5>::from_diagonal(&SVector::<f32, 5>::from_column_slice(&q)),
        SMatrix::<f32, 5, 5>::from_diagonal(&SVector::<f32, 5>::from_column_slice(&r)),
    )
    .expect("valid filter");
    // The UKF's heading variance starts at 1 rad², not the paper's 10: the
    // unscented circular mean turns around above ~2 rad² (core::ukf docs).
    let p0_ukf = [10.0_f32, 10.0, 1.0, 10.0, 10.0];
    let mut ukf3 = UnscentedKalmanFilter::<_, 3, 3, 7>::new(
        PoseModel,
        MerweScaledSigmaPoints::paper().expect("paper parameters"),
        x0_32.fixed_rows::<3>(0).into_owned(),
        SMatrix::<f32, 3, 3>::from_diagonal(&SVector::<f32, 3>::from_column_slice(&p0_ukf[..3])),
        SMatrix::<f32, 3, 3>::from_diagonal(&SVector::<f32, 3>::from_column_slice(&q[..3])),
        SMatrix::<f32, 3, 3>::from_diagonal(&SVector::<f32, 3>::from_column_slice(&r[..3])),
    )
    .expect("valid filter");
    let mut ukf5 = UnscentedKalmanFilter::<_, 5, 5, 11>::new(
        PoseWheelModel,
        MerweScaledSigmaPoints::paper().expect("paper parameters"),
        x0_32,
        SMatrix::<f32, 5, 5>::from_diagonal(&SVector::<f32, 5>::from(p0_ukf)),
        SMatrix::<f32, 5, 5>::from_diagonal(&SVector::<f32, 5>::from_column_slice(&q)),
        SMatrix::<f32, 5, 5>::from_diagonal(&SVector::<f32, 5>::from_column_slice(&r)),
    )
    .expect("valid filter");
    let std_r = diag(&[0.1, 0.1, 0.2, 0.01, 0.01].map(f64::sqrt));
    let prior = SVector::<f32, 5>::repeat(10.0_f32.sqrt());
    let mut pf3 = ParticleFilter::<_, 3, 3, PARTICLES>::new(
        PoseModel,
        ParticleFilterConfig::new(
            SVector::<f32, 3>::from_column_slice(&PARTICLE_PROCESS_STD[..3]),
            SVector::<f32, 3>::from_column_slice(&std_r[..3]),
        )
        .and_then(|c| c.with_collapse_gate(f32::INFINITY))
        .expect("valid noise"),
        x0_32.fixed_rows::<3>(0).into_owned(),
        prior.fixed_rows::<3>(0).into_owned(),
        seed,
    )
    .expect("valid filter");
    let mut pf5 = ParticleFilter::<_, 5, 5, PARTICLES>::new(
        PoseWheelModel,
        ParticleFilterConfig::new(
            SVector::<f32, 5>::from(PARTICLE_PROCESS_STD),
            SVector::<f32, 5>::from_column_slice(&std_r),
        )
        .and_then(|c| c.with_collapse_gate(f32::INFINITY))
        .expect("valid noise"),
        x0_32,
        prior,
        seed,
    )
    .expect("valid filter");
    let mut state = x0;
    let mut out = SlipRun {
        error: [Series::new("e1"), Series::new("e2"), Series::new("e3")],
        slip_estimate: Series::new("p̂"),
        estimate_error: Series::new("|estimate − true position|"),
        wheel_error: [Series::new("ω_L − ω_Ld"), Series::new("ω_R − ω_Rd")],
        path: Vec::new(),
    };
    let steps = (DURATION_S / PERIOD_S).round() as u32;
    for k in 0..steps {
        let t = f64::from(k) * PERIOD_S;
        let p = 1.0 / (1.0 - slip_ratio(t));
        let mut measured = state;
        for (i, m) in measured.iter_mut().enumerate().take(n) {
            *m += noise_std[i] * gaussian(&mut rng);
        }
        let measured32 = measured.map(|x| x as f32);
        let estimate: SVector<f64, 5> = match (estimator, scenario) {
            (Estimator::Exact, _) => state,
            (Estimator::Ekf, Scenario::Velocity) => {
                ekf3.update(&measured32.fixed_rows::<3>(0).into_owned());
                let e = ekf3.state().map(f64::from);
                SVector::<f64, 5>::new(e.x, e.y, e.z, 0.0, 0.0)
            }
            (Estimator::Ekf, Scenario::Torque) => {
                ekf5.update(&measured32);
                ekf5.state().map(f64::from)
            }
            (Estimator::Ukf, Scenario::Velocity) => {
                ukf3.update(&measured32.fixed_rows::<3>(0).into_owned());
                let e = ukf3.state().map(f64::from);
                SVector::<f64, 5>::new(e.x, e.y, e.z, 0.0, 0.0)
            }
            (Estimator::Ukf, Scenario::Torque) => {
                ukf5.update(&measured32);
                ukf5.state().map(f64::from)
            }
            (Estimator::ParticleFilter, Scenario::Velocity) => {
                pf3.update(&measured32.fixed_rows::<3>(0).into_owned());
                let e = pf3.estimate().map(f64::from);
                SVector::<f64, 5>::new(e.x, e.y, e.z, 0.0, 0.0)
            }
            (Estimator::ParticleFilter, Scenario::Torque) => {
                pf5.update(&measured32);
                pf5.estimate().map(f64::from)
            }
        };
        let pose = Pose::new(estimate.x as f32, estimate.y as f32, estimate.z as f32);
        let target = reference.sample(t as f32);
        let true_pose = Pose::new(state.x as f32, state.y as f32, state.z as f32);
        let true_error = tracking_error(&true_pose, &target.pose);
        let (torque, control) = match scenario {
            Scenario::Velocity => (None, velocity_controller.step(&target, &pose)),
            Scenario::Torque => {
                let wheels = WheelSpeeds {
                    left_rad_s: estimate[3] as f32,
                    right_rad_s: estimate[4] as f32,
                };
                let c = torque_controller.step(&target, &pose, wheels);
                (
                    Some(Vector2::new(f64::from(c.torque[0]), f64::from(c.torque[1]))),
                    c.velocity,
                )
            }
        };
        if k % 10 == 0 {
            for (series, e) in out.error.iter_mut().zip(true_error) {
                series.points.push((t, f64::from(e)));
            }
            out.slip_estimate
                .points
                .push((t, f64::from(control.slip_estimate)));
            out.estimate_error.points.push((
                t,
                ((estimate.x - state.x).powi(2) + (estimate.y - state.y).powi(2)).sqrt(),
            ));
            out.wheel_error[0]
                .points
                .push((t, state[3] - f64::from(control.wheels.left_rad_s)));
            out.wheel_error[1]
                .points
                .push((t, state[4] - f64::from(control.wheels.right_rad_s)));
            out.path.push((state.x, state.y));
        }
        if scenario == Scenario::Velocity {
            state[3] = f64::from(control.wheels.left_rad_s);
            state[4] = f64::from(control.wheels.right_rad_s);
        }
        for _ in 0..10 {
            state = rk4(&robot, &state, p, torque, PERIOD_S / 10.0);
        }
        state[2] = wrap(state[2]);
        match (estimator, scenario) {
            (Estimator::Ekf, Scenario::Velocity) => ekf3.predict(&control.body, h),
            (Estimator::Ekf, Scenario::Torque) => ekf5.predict(&control.body, h),
            (Estimator::Ukf, Scenario::Velocity) => {
                ukf3.predict(&control.body, h);
            }
            (Estimator::Ukf, Scenario::Torque) => {
                ukf5.predict(&control.body, h);
            }
            (Estimator::ParticleFilter, Scenario::Velocity) => pf3.predict(&control.body, h),
            (Estimator::ParticleFilter, Scenario::Torque) => pf5.predict(&control.body, h),
            (Estimator::Exact, _) => {}
        }
    }
    out
}
