//! The core's `Drive` with its per-wheel speed loops closed on the
//! simulator's rigid-body wheel dynamics (`firmware_sim::plant`, with
//! `[plant.dynamics]`), once on the counts differenced over a tick and once
//! on paper 003's wheel-speed observer (`DriveConfig::with_speed_observer`):
//! how well each regulates the wheel speeds, and what the observer says of
//! the load and the damping.

use firmware_sim::plant::{DiffDriveParams, DiffDrivePlant, LoadTorque, PlantPose, WheelDynamics};
use wmr_core::drive::momenta_observer::WheelInertia;
use wmr_core::drive::speed_observer::WheelSpeedObserverConfig;
use wmr_core::drive::{Drive, DriveConfig, SpeedLoopGains};
use wmr_core::geometry::{BodyVelocity, DiffDriveGeometry, WheelSpeeds};

use crate::paper_002::Series;

/// Encoder counts per wheel revolution.
pub const COUNTS_PER_REV: u32 = 1024;
/// Control period, s.
pub const PERIOD_S: f64 = 0.01;

/// The robot: 4 kg, yaw inertia 0.08 kg m², each wheel's drive train
/// 2e-4 kg m², wheel radius 3 cm, track 20 cm, motors of 0.6 N·m stall
/// torque and 20 rad/s no-load speed (back-EMF damping 0.03 N·m·s/rad),
/// drive-train friction 0.01 N·m·s/rad; a 5 % slope from `slope_start_s`
/// (a 1 s ramp).
#[must_use]
pub fn robot_params(slope_start_s: f64) -> DiffDriveParams {
    DiffDriveParams {
        wheel_radius_m: 0.03,
        track_width_m: 0.2,
        wheel_speed_at_full_duty_rad_s: 20.0,
        dynamics: Some(WheelDynamics {
            mass_kg: 4.0,
            yaw_inertia_kg_m2: 0.08,
            wheel_inertia_kg_m2: 2e-4,
            viscous_friction_nm_s_per_rad: 0.01,
            stall_torque_nm: 0.6,
            load: LoadTorque {
                start_s: slope_start_s,
                ramp_s: 1.0,
                grade_percent: 5.0,
            },
        }),
        ..DiffDriveParams::default()
    }
}

/// Which wheel speeds the speed loops run on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SpeedSource {
    /// Encoder counts differenced over one tick.
    Differencing,
    /// Paper 003's observer on the counts and the commanded duties.
    Observer,
}

/// What a run measured (after the first 5 s).
#[derive(Debug, Clone, PartialEq)]
pub struct DriveLoopRun {
    /// RMS of (true wheel speed − the drive's target), both wheels, rad/s.
    pub regulation_rms: f64,
    /// RMS of the speed the loops used − the true speed, rad/s.
    pub feedback_error_rms: f64,
    /// RMS of the change of duty from tick to tick (PWM jitter).
    pub duty_step_rms: f64,
    /// Observer only: mean load torque estimate over the last 20 s, per
    /// wheel `(left, right)`, N·m.
    pub load_estimate_nm: Option<(f64, f64)>,
    /// True load torque per wheel at the end, N·m.
    pub true_load_nm: f64,
    /// Observer only: mean damping estimate over the last 20 s, N·m·s/rad.
    pub damping_estimate: Option<(f64, f64)>,
    /// True damping per wheel (back-EMF + friction), N·m·s/rad.
    pub true_damping: f64,
    /// Left wheel: true speed, the speed the loop used, the target (rad/s).
    pub left_speeds: [Series; 3],
}

/// The body command: a varying speed and turn rate.
#[must_use]
pub fn command(t: f64) -> BodyVelocity {
    BodyVelocity {
        v_m_s: (0.25 + 0.1 * (0.5 * t).sin()) as f32,
        omega_rad_s: (0.6 * (0.3 * t).sin()) as f32,
    }
}

/// Runs the drive for `duration_s` with the slope from `slope_start_s`.
///
/// # Panics
/// If the constant configuration is refused.
#[must_use]
pub fn drive_loop_run(source: SpeedSource, duration_s: f64, slope_start_s: f64) -> DriveLoopRun {
    let params = robot_params(slope_start_s);
    let dynamics = params.dynamics.expect("set above");
    let h = PERIOD_S as f32;
    let geometry = DiffDriveGeometry::new(
        params.wheel_radius_m as f32,
        params.track_width_m as f32,
        COUNTS_PER_REV,
    )
    .expect("valid geometry");
    let mut config = DriveConfig::new(
        geometry,
        h,
        18.0,
        50.0,
        SpeedLoopGains {
            feedforward_duty_per_rad_s: 1.0 / 20.0,
            kp_duty_per_rad_s: 0.02,
            ki_duty_per_rad: 0.5,
        },
    )
    .expect("valid drive");
    if source == SpeedSource::Observer {
        let inertia = WheelInertia::new(
            dynamics.mass_kg as f32,
            dynamics.yaw_inertia_kg_m2 as f32,
            params.wheel_radius_m as f32,
            params.track_width_m as f32,
            dynamics.wheel_inertia_kg_m2 as f32,
        )
        .expect("valid robot");
        let observer =
            WheelSpeedObserverConfig::new(inertia, dynamics.stall_torque_nm as f32, 20.0, h)
                .expect("valid observer");
        config = config.with_speed_observer(observer).expect("same period");
    }
    let mut drive = Drive::new(config);
    let mut plant = DiffDrivePlant::new(params, PlantPose::new(0.0, 0.0, 0.0));
    let counts_per_rad = f64::from(COUNTS_PER_REV) / std::f64::consts::TAU;
    let counts = |angle: f64| (angle * counts_per_rad).floor();
    let (mut last_left, mut last_right) = (0.0, 0.0);
    let (mut last_duty_left, mut last_duty_right) = (0.0_f64, 0.0_f64);
    let (mut n, mut regulation, mut feedback, mut duty_steps) = (0_u32, 0.0, 0.0, 0.0);
    let (mut n_late, mut load, mut damping) = (0_u32, (0.0, 0.0), (0.0, 0.0));
    let mut left_speeds = [
        Series::new("true φ̇_L"),
        Series::new("speed the loop used"),
        Series::new("target"),
    ];
    let steps = (duration_s / PERIOD_S).round() as u32;
    for k in 0..steps {
        let t = f64::from(k) * PERIOD_S;
        let (angle_left, angle_right) = plant.wheel_angles_rad();
        let (c_left, c_right) = (counts(angle_left), counts(angle_right));
        let measured = WheelSpeeds {
            left_rad_s: ((c_left - last_left) / counts_per_rad / PERIOD_S) as f32,
            right_rad_s: ((c_right - last_right) / counts_per_rad / PERIOD_S) as f32,
        };
        (last_left, last_right) = (c_left, c_right);
        let out = drive.step(command(t), (k > 0).then_some(measured));
        let used = match drive.speed_observer() {
            Some(observer) => observer.estimate_speeds(),
            None => measured,
        };
        let (true_left, true_right) = plant.wheel_speeds_rad_s();
        if t >= 5.0 {
            n += 1;
            regulation += (true_left - f64::from(out.wheel_targets.left_rad_s)).powi(2)
                + (true_right - f64::from(out.wheel_targets.right_rad_s)).powi(2);
            feedback += (f64::from(used.left_rad_s) - true_left).powi(2)
                + (f64::from(used.right_rad_s) - true_right).powi(2);
            duty_steps += (f64::from(out.left_duty) - last_duty_left).powi(2)
                + (f64::from(out.right_duty) - last_duty_right).powi(2);
        }
        if t >= duration_s - 20.0
            && let Some(observer) = drive.speed_observer()
        {
            n_late += 1;
            let (l, r) = observer.load_torques_nm();
            load.0 += f64::from(l);
            load.1 += f64::from(r);
            let (l, r) = observer.damping_nm_s_per_rad();
            damping.0 += f64::from(l);
            damping.1 += f64::from(r);
        }
        left_speeds[0].points.push((t, true_left));
        left_speeds[1].points.push((t, f64::from(used.left_rad_s)));
        left_speeds[2]
            .points
            .push((t, f64::from(out.wheel_targets.left_rad_s)));
        (last_duty_left, last_duty_right) = (f64::from(out.left_duty), f64::from(out.right_duty));
        plant.step(
            f64::from(out.left_duty),
            f64::from(out.right_duty),
            PERIOD_S,
        );
    }
    let rms = |sum: f64| (sum / f64::from(2 * n.max(1))).sqrt();
    let mean = |(a, b): (f64, f64)| {
        let k = f64::from(n_late.max(1));
        (a / k, b / k)
    };
    let observed = n_late > 0;
    DriveLoopRun {
        regulation_rms: rms(regulation),
        feedback_error_rms: rms(feedback),
        duty_step_rms: rms(duty_steps),
        load_estimate_nm: observed.then(|| mean(load)),
        true_load_nm: plant.load_torque_nm(),
        damping_estimate: observed.then(|| mean(damping)),
        true_damping: dynamics.stall_torque_nm / 20.0 + dynamics.viscous_friction_nm_s_per_rad,
        left_speeds,
    }
}
