//! The slip simulation: the plant integrated in `f64`, the noisy
//! measurement, the estimator and the adaptive controller, step by step.

use std::f64::consts::{PI, TAU};

use rand::rngs::ChaCha8Rng;
use rand::{RngExt as _, SeedableRng as _};
use wmr_core::geometry::{Pose, WheelSpeeds};
use wmr_papers::slip_tracking::{AdaptiveTorqueController, tracking_error};

use crate::scenario::ScenarioError;

use super::scenario::{Controller, SlipScenario, ratio_at};
use super::summary::{SlipRecord, SlipResult, summarize};
use super::validate::Setup;

/// A standard normal draw (Box–Muller).
fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
    let radius = (-2.0 * (1.0 - rng.random::<f64>()).ln()).sqrt();
    radius * (TAU * rng.random::<f64>()).cos()
}

/// The plant: wheel radius and track (`f64`) and `M₀⁻¹` (from the core's
/// `f32` `M₀`).
struct Plant {
    r: f64,
    b: f64,
    inverse_inertia: [[f64; 2]; 2],
}

impl Plant {
    /// The state rate `(Ẋ, Ẏ, ψ̇, ω̇_L, ω̇_R)` for held wheel speeds
    /// (scenario 1: no wheel dynamics) or torques.
    fn rate(&self, s: &[f64; 5], p: f64, torque: Option<[f64; 2]>) -> [f64; 5] {
        let (r, b) = (self.r, self.b);
        let (wl, wr) = (s[3], s[4]);
        let v = r * (wl + wr) / (2.0 * p);
        let w = r * (wr - wl) / (b * p);
        let m = &self.inverse_inertia;
        let accel = torque.map_or([0.0; 2], |tau| {
            [
                (m[0][0] * tau[0] + m[0][1] * tau[1]) * p,
                (m[1][0] * tau[0] + m[1][1] * tau[1]) * p,
            ]
        });
        [v * s[2].cos(), v * s[2].sin(), w, accel[0], accel[1]]
    }

    fn rk4(&self, s: &[f64; 5], p: f64, torque: Option<[f64; 2]>, dt: f64) -> [f64; 5] {
        let f = |s: &[f64; 5]| self.rate(s, p, torque);
        let step = |k: &[f64; 5], c: f64| std::array::from_fn(|i| s[i] + k[i] * c);
        let k1 = f(s);
        let k2 = f(&step(&k1, dt / 2.0));
        let k3 = f(&step(&k2, dt / 2.0));
        let k4 = f(&step(&k3, dt));
        std::array::from_fn(|i| s[i] + (k1[i] + k2[i] * 2.0 + k3[i] * 2.0 + k4[i]) * (dt / 6.0))
    }
}

fn wrap(a: f64) -> f64 {
    let w = (a + PI).rem_euclid(TAU) - PI;
    if w <= -PI { w + TAU } else { w }
}

/// Runs a scenario.
///
/// # Errors
/// [`ScenarioError::Invalid`] naming the first bad field.
pub fn run(scenario: &SlipScenario) -> Result<SlipResult, ScenarioError> {
    let Setup {
        robot,
        velocity,
        reference,
        mut filter,
        initial,
        steps,
    } = scenario.setup()?;
    let inverse = robot
        .wheel_inertia()
        .map(f64::from)
        .try_inverse()
        .ok_or_else(|| ScenarioError::invalid("robot", "the wheel inertia M0 is singular"))?;
    let plant = Plant {
        r: scenario.robot.wheel_radius_m,
        b: scenario.robot.track_width_m,
        inverse_inertia: [
            [inverse[(0, 0)], inverse[(0, 1)]],
            [inverse[(1, 0)], inverse[(1, 1)]],
        ],
    };
    let controller = scenario.controller;
    let period_s = scenario.period_s;
    let h = period_s as f32;
    let substep_s = period_s / f64::from(scenario.plant_substeps);
    let mut velocity_controller = velocity;
    let mut torque_controller = AdaptiveTorqueController::new(velocity);
    let mut rng = ChaCha8Rng::seed_from_u64(scenario.seed);
    let noise_std = scenario.measurement.variance.map(f64::sqrt);
    let n = controller.measured_states();
    let mut state = initial;
    let mut records = Vec::with_capacity((steps / scenario.record_every_steps) as usize + 1);
    for k in 0..steps {
        let t = f64::from(k) * period_s;
        let slip_ratio = ratio_at(&scenario.slip, t);
        let p = 1.0 / (1.0 - slip_ratio);
        let mut measured = state;
        for (i, m) in measured.iter_mut().enumerate().take(n) {
            *m += noise_std[i] * gaussian(&mut rng);
        }
        let estimate = filter.update(&state, &measured.map(|x| x as f32));
        let pose = Pose::new(estimate[0] as f32, estimate[1] as f32, estimate[2] as f32);
        let target = reference(t as f32);
        let true_pose = Pose::new(state[0] as f32, state[1] as f32, state[2] as f32);
        let true_error = tracking_error(&true_pose, &target.pose);
        let (torque, control) = match controller {
            Controller::Velocity => (None, velocity_controller.step(&target, &pose)),
            Controller::Torque => {
                let wheels = WheelSpeeds {
                    left_rad_s: estimate[3] as f32,
                    right_rad_s: estimate[4] as f32,
                };
                let c = torque_controller.step(&target, &pose, wheels);
                (
                    Some([f64::from(c.torque[0]), f64::from(c.torque[1])]),
                    c.velocity,
                )
            }
        };
        if k % scenario.record_every_steps == 0 {
            let torque_wheels = controller == Controller::Torque;
            records.push(SlipRecord {
                t_s: t,
                x_m: state[0],
                y_m: state[1],
                heading_rad: state[2],
                est_x_m: estimate[0],
                est_y_m: estimate[1],
                est_heading_rad: estimate[2],
                est_left_rad_s: torque_wheels.then_some(estimate[3]),
                est_right_rad_s: torque_wheels.then_some(estimate[4]),
                ref_x_m: f64::from(target.pose.position.x),
                ref_y_m: f64::from(target.pose.position.y),
                ref_heading_rad: f64::from(target.pose.heading_rad),
                ref_v_m_s: f64::from(target.velocity.v_m_s),
                ref_omega_rad_s: f64::from(target.velocity.omega_rad_s),
                e1_m: f64::from(true_error[0]),
                e2_m: f64::from(true_error[1]),
                e3_rad: f64::from(true_error[2]),
                slip_estimate: f64::from(control.slip_estimate),
                slip_ratio,
                slip_factor: p,
                left_rad_s: state[3],
                right_rad_s: state[4],
                left_desired_rad_s: f64::from(control.wheels.left_rad_s),
                right_desired_rad_s: f64::from(control.wheels.right_rad_s),
                torque_left_nm: torque.map(|t| t[0]),
                torque_right_nm: torque.map(|t| t[1]),
                estimate_error_m: ((estimate[0] - state[0]).powi(2)
                    + (estimate[1] - state[1]).powi(2))
                .sqrt(),
            });
        }
        if controller == Controller::Velocity {
            state[3] = f64::from(control.wheels.left_rad_s);
            state[4] = f64::from(control.wheels.right_rad_s);
        }
        for _ in 0..scenario.plant_substeps {
            state = plant.rk4(&state, p, torque, substep_s);
        }
        state[2] = wrap(state[2]);
        filter.predict(&control.body, h);
    }
    let summary = summarize(scenario, &records);
    Ok(SlipResult { records, summary })
}
