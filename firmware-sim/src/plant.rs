//! Simulated plants: what the robot's body does with the commands it gets.
//!
//! Plant state is `f64` (the core is `f32`): the simulated world should be
//! more accurate than the controller it judges, so that the errors measured
//! are the controller's and not the simulator's.
//!
//! * [`Unicycle`]: paper 001, eq. (1), `ẋ = v cos θ`, `ẏ = v sin θ`,
//!   `θ̇ = ω`, integrated *exactly* over a step with constant `v, ω` (an arc).
//! * [`DiffDrivePlant`]: two DC motors driving the wheels of a
//!   differential-drive robot, integrated with RK4. By default each wheel is
//!   a first-order system; with [`WheelDynamics`] the wheels carry the
//!   body's rigid-body inertia (paper 003, section 6.1), the motors' torque
//!   with back-EMF, viscous friction and a slope load ([`LoadTorque`]).

use std::f64::consts::PI;

/// A planar pose in `f64`: position (m) and heading (rad, continuous, not wrapped).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct PlantPose {
    /// x of the axle midpoint, m.
    pub x_m: f64,
    /// y of the axle midpoint, m.
    pub y_m: f64,
    /// Heading, rad, counter-clockwise from the world x axis (integrated,
    /// so it keeps counting past ±π).
    pub heading_rad: f64,
}

impl PlantPose {
    /// A pose from its components.
    #[must_use]
    pub const fn new(x_m: f64, y_m: f64, heading_rad: f64) -> Self {
        Self {
            x_m,
            y_m,
            heading_rad,
        }
    }

    /// The heading wrapped to (−π, π].
    #[must_use]
    pub fn wrapped_heading_rad(&self) -> f64 {
        wrap_angle(self.heading_rad)
    }

    /// The point `offset_m` ahead of the axle midpoint along the heading
    /// (e.g. an antenna mounted in front of the axle).
    #[must_use]
    pub fn point_ahead(&self, offset_m: f64) -> (f64, f64) {
        (
            self.x_m + offset_m * self.heading_rad.cos(),
            self.y_m + offset_m * self.heading_rad.sin(),
        )
    }

    /// Whether every component is finite.
    #[must_use]
    pub fn is_finite(&self) -> bool {
        self.x_m.is_finite() && self.y_m.is_finite() && self.heading_rad.is_finite()
    }
}

/// Wraps an angle to (−π, π].
#[must_use]
pub fn wrap_angle(angle: f64) -> f64 {
    let wrapped = angle - 2.0 * PI * (angle / (2.0 * PI)).round();
    if wrapped <= -PI {
        wrapped + 2.0 * PI
    } else {
        wrapped
    }
}

/// `sin(x)/x`, 1 at 0, accurate near 0.
fn sinc(x: f64) -> f64 {
    if x.abs() < 1e-4 {
        1.0 - x * x / 6.0
    } else {
        x.sin() / x
    }
}

/// The kinematic unicycle of paper 001, eq. (1): the commanded `v, ω` are
/// the robot's velocities (no dynamics, no slip).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Unicycle {
    pose: PlantPose,
}

impl Unicycle {
    /// A unicycle at `pose`.
    #[must_use]
    pub fn new(pose: PlantPose) -> Self {
        Self { pose }
    }

    /// The current pose.
    #[must_use]
    pub fn pose(&self) -> PlantPose {
        self.pose
    }

    /// Drives `v_m_s`, `omega_rad_s` (held constant) for `dt_s` seconds: an
    /// exact arc, `Δp = v·dt·sinc(ω·dt/2)·(cos(θ + ω·dt/2), sin(θ + ω·dt/2))`.
    pub fn step(&mut self, v_m_s: f64, omega_rad_s: f64, dt_s: f64) {
        self.advance_arc(v_m_s * dt_s, omega_rad_s * dt_s);
    }

    /// Moves `ds` metres along an arc turning `dtheta` radians (the exact
    /// arc of [`Self::step`]).
    pub fn advance_arc(&mut self, ds: f64, dtheta: f64) {
        let chord = ds * sinc(0.5 * dtheta);
        let mid = self.pose.heading_rad + 0.5 * dtheta;
        self.pose.x_m += chord * mid.cos();
        self.pose.y_m += chord * mid.sin();
        self.pose.heading_rad += dtheta;
    }
}

/// Wheels that do not roll as their rotation says: each wheel's travel on
/// the ground is `(1 + e)·m + n`, for a travel `m` measured from its
/// rotation (what the encoders and the odometry see), a systematic scale
/// error `e` and a zero-mean Gaussian slip noise `n` of variance
/// `q·|m|` (`q` per metre rolled, so that the noise of a distance `D` has
/// variance `q·D` whatever the step): the odometry model of the fusion
/// filters (docs/fusion.md; Thrun, Burgard & Fox, *Probabilistic
/// Robotics*, 2005, section 5.4, with a per-wheel variance proportional to
/// the distance), so that a filter's `wheel_variance_per_m` and scale
/// prior can be matched to the plant or mis-tuned on purpose. The plant
/// moves on the ground travels; the odometry keeps the measured ones.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct WheelErrors {
    /// `q`, the slip noise's variance per metre a wheel rolls, m²/m (≥ 0).
    pub travel_variance_m2_per_m: f64,
    /// `[e_R, e_L]`, each wheel's scale error (right, left): its ground
    /// travel is `1 + e` times its measured travel.
    pub scale_error: [f64; 2],
    /// The track width that maps wheel travels to the body's turn, m.
    pub track_width_m: f64,
    /// The seed of the noise (the run's `measurement.seed`, on its own
    /// stream, [`RollingWheels::STREAM`]).
    pub seed: u64,
}

/// [`WheelErrors`] with their noise generator: one per run.
#[derive(Debug)]
pub struct RollingWheels {
    errors: WheelErrors,
    rng: rand::rngs::ChaCha8Rng,
}

impl RollingWheels {
    /// The ChaCha8 stream of the wheel noise: the fix noise of the same
    /// seed uses stream 0, so switching the wheels on does not change the
    /// fix noise a run draws.
    pub const STREAM: u64 = 0x5748_4545_4c53; // "WHEELS"

    /// The wheels of `errors`.
    #[must_use]
    pub fn new(errors: WheelErrors) -> Self {
        use rand::SeedableRng as _;
        let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(errors.seed);
        rng.set_stream(Self::STREAM);
        Self { errors, rng }
    }

    /// The errors.
    #[must_use]
    pub fn errors(&self) -> &WheelErrors {
        &self.errors
    }

    /// The ground travels `(right, left)` of wheels whose rotation
    /// measured `right_m`, `left_m`. Draws two standard normals every call
    /// (Box–Muller), whatever the travels, so that a run's draws do not
    /// depend on its motion.
    pub fn ground_travels(&mut self, right_m: f64, left_m: f64) -> (f64, f64) {
        use rand::RngExt as _;
        let radius = (-2.0 * (1.0 - self.rng.random::<f64>()).ln()).sqrt();
        let angle = std::f64::consts::TAU * self.rng.random::<f64>();
        let e = &self.errors;
        let noise = |m: f64, normal: f64| (e.travel_variance_m2_per_m * m.abs()).sqrt() * normal;
        (
            (1.0 + e.scale_error[0]) * right_m + noise(right_m, radius * angle.cos()),
            (1.0 + e.scale_error[1]) * left_m + noise(left_m, radius * angle.sin()),
        )
    }

    /// The body motion `(ds, dθ)` on the ground of a body motion `ds`
    /// metres, turning `dtheta` radians, measured by the wheels: the
    /// wheel travels `ds ± (b/2)·dθ`, through [`Self::ground_travels`],
    /// back to `((g_R + g_L)/2, (g_R − g_L)/b)`.
    pub fn ground_motion(&mut self, ds: f64, dtheta: f64) -> (f64, f64) {
        let b = self.errors.track_width_m;
        let (right, left) = self.ground_travels(ds + 0.5 * b * dtheta, ds - 0.5 * b * dtheta);
        (0.5 * (right + left), (right - left) / b)
    }
}

/// Standard gravity `g` of the slope load ([`LoadTorque`]), m/s².
pub const GRAVITY_M_S2: f64 = 9.81;

/// A load torque on both wheels: the robot drives onto a slope, uphill.
///
/// The final slope is `grade_percent` (rise per 100 of run), the angle
/// `α = atan(grade_percent / 100)`. The angle ramps *linearly in the
/// angle* (not in the torque) from 0 at `start_s` to `α` at
/// `start_s + ramp_s` and stays there; `ramp_s = 0` is a step at `start_s`.
/// Gravity's pull along the slope, `m g sin α`, is shared by the two
/// wheels, so each carries `d = −m g sin α · r / 2` (N·m; negative: it
/// opposes forward motion; a negative grade is downhill and helps). The
/// slope is taken to rise along the robot's heading whatever the robot
/// turns to: a disturbance torque, not a terrain model. A grade of 0 is no
/// load ([`LoadTorque::NONE`], the default).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct LoadTorque {
    /// When the robot starts onto the slope, s of plant time
    /// ([`DiffDrivePlant::elapsed_s`]).
    pub start_s: f64,
    /// Time the grade angle takes from 0 to its final value, s (≥ 0;
    /// 0 = step).
    pub ramp_s: f64,
    /// Final grade, percent (rise per 100 of run, in (−100, 100);
    /// negative = downhill; 0 = no load).
    pub grade_percent: f64,
}

impl LoadTorque {
    /// No load.
    pub const NONE: Self = Self {
        start_s: 0.0,
        ramp_s: 0.0,
        grade_percent: 0.0,
    };

    /// The slope angle under the robot at plant time `t_s`, rad.
    #[must_use]
    pub fn grade_angle_rad(&self, t_s: f64) -> f64 {
        let since_start_s = t_s - self.start_s;
        if self.grade_percent == 0.0 || since_start_s < 0.0 {
            return 0.0;
        }
        let full_rad = (self.grade_percent / 100.0).atan();
        if since_start_s >= self.ramp_s {
            full_rad
        } else {
            full_rad * since_start_s / self.ramp_s
        }
    }

    /// The load torque on each wheel at plant time `t_s` of a robot of
    /// `mass_kg` on wheels of `wheel_radius_m`, `−m g sin α(t) · r / 2`,
    /// N·m (positive drives forward).
    #[must_use]
    pub fn wheel_torque_nm(&self, t_s: f64, mass_kg: f64, wheel_radius_m: f64) -> f64 {
        -mass_kg * GRAVITY_M_S2 * self.grade_angle_rad(t_s).sin() * wheel_radius_m / 2.0
    }
}

/// Rigid-body wheel dynamics of a [`DiffDrivePlant`] (paper 003, section
/// 6.1). The wheel angles `q = (φ_L, φ_R)` (both positive forward) obey
///
/// ```text
/// M q̈ = τ_m(u, q̇) − b q̇ + d(t)·(1, 1)
/// M = [[m r²/4 + I_z r²/b_t² + I_w,  m r²/4 − I_z r²/b_t²      ],
///      [m r²/4 − I_z r²/b_t²,        m r²/4 + I_z r²/b_t² + I_w]]   (kg m²)
/// τ_m = τ_stall·u − (τ_stall/ω₀)·q̇                   (N·m at each wheel)
/// ```
///
/// `M` comes from the kinetic energy `½m v² + ½I_z ω² + ½I_w(φ̇_L² + φ̇_R²)`
/// with the wheels rolling without slip and the centre of mass on the
/// axle midpoint (no Coriolis terms); `r` and `b_t` are
/// [`DiffDriveParams::wheel_radius_m`] and
/// [`DiffDriveParams::track_width_m`]. Each motor gives its stall torque
/// at full duty and zero speed, less its back-EMF; `ω₀` is
/// [`DiffDriveParams::wheel_speed_at_full_duty_rad_s`], read here as the
/// motor's *no-load* speed at full duty (the armature inductance is
/// neglected). `d(t)` is [`Self::load`].
///
/// `M` is symmetric with equal diagonals, so driving and turning
/// decouple: the mean wheel speed has inertia `m r²/2 + I_w`, half the
/// speed difference `2 I_z r²/b_t² + I_w`, both against the damping
/// `K = τ_stall/ω₀ + b`. A constant duty settles at
/// `q̇ = (τ_stall·u + d)/K`, below `ω₀·u` when `b > 0`.
/// [`DiffDriveParams::motor_time_constant_s`] is not used: the time
/// constants are the inertias over `K`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct WheelDynamics {
    /// Robot mass `m`, kg (> 0).
    pub mass_kg: f64,
    /// Yaw inertia `I_z` about the axle midpoint, kg m² (> 0).
    pub yaw_inertia_kg_m2: f64,
    /// Inertia `I_w` of each wheel with its motor and gearbox reflected to
    /// the wheel, kg m² (≥ 0; may be 0).
    pub wheel_inertia_kg_m2: f64,
    /// Viscous friction `b` of each wheel's drive train, N·m·s/rad (≥ 0).
    pub viscous_friction_nm_s_per_rad: f64,
    /// Motor torque at the wheel at full duty and zero speed `τ_stall`,
    /// N·m (> 0).
    pub stall_torque_nm: f64,
    /// The load torque `d(t)` on each wheel.
    pub load: LoadTorque,
}

impl WheelDynamics {
    /// The inertia matrix `M` of the wheel angles `(φ_L, φ_R)` on wheels of
    /// `wheel_radius_m` `r` a track `track_width_m` `b_t` apart, kg m².
    #[must_use]
    pub fn mass_matrix_kg_m2(&self, wheel_radius_m: f64, track_width_m: f64) -> [[f64; 2]; 2] {
        let r2 = wheel_radius_m * wheel_radius_m;
        let translation = self.mass_kg * r2 / 4.0;
        let rotation = self.yaw_inertia_kg_m2 * r2 / (track_width_m * track_width_m);
        let diagonal = translation + rotation + self.wheel_inertia_kg_m2;
        let off = translation - rotation;
        [[diagonal, off], [off, diagonal]]
    }

    /// The eigenvalues of `M`: `(m r²/2 + I_w, 2 I_z r²/b_t² + I_w)`, the
    /// inertias of the mean wheel speed and of half the speed difference,
    /// kg m².
    fn modal_inertias_kg_m2(&self, wheel_radius_m: f64, track_width_m: f64) -> (f64, f64) {
        let r2 = wheel_radius_m * wheel_radius_m;
        (
            0.5 * self.mass_kg * r2 + self.wheel_inertia_kg_m2,
            2.0 * self.yaw_inertia_kg_m2 * r2 / (track_width_m * track_width_m)
                + self.wheel_inertia_kg_m2,
        )
    }
}

/// Parameters of a [`DiffDrivePlant`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct DiffDriveParams {
    /// Wheel radius `r`, m.
    pub wheel_radius_m: f64,
    /// Track width `b` (distance between the wheel contact points), m.
    pub track_width_m: f64,
    /// Motor + wheel time constant `τ`, s (first-order model only).
    pub motor_time_constant_s: f64,
    /// Steady-state wheel speed at full duty `k_duty`, rad/s (with
    /// [`Self::dynamics`]: the motor's no-load speed at full duty `ω₀`).
    pub wheel_speed_at_full_duty_rad_s: f64,
    /// RK4 substeps per [`DiffDrivePlant::step`].
    pub substeps: u32,
    /// Rigid-body wheel dynamics; `None` (the default): each wheel is the
    /// first-order system `τ·φ̈ = k_duty·u − φ̇`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dynamics: Option<WheelDynamics>,
}

impl Default for DiffDriveParams {
    fn default() -> Self {
        Self {
            wheel_radius_m: 0.03,
            track_width_m: 0.2,
            motor_time_constant_s: 0.05,
            wheel_speed_at_full_duty_rad_s: 20.0,
            substeps: 10,
            dynamics: None,
        }
    }
}

/// State of a [`DiffDrivePlant`], as one vector for the integrator.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct DiffDriveState {
    /// `[x, y, θ, φ_L, φ_R, φ̇_L, φ̇_R]`.
    s: [f64; 7],
}

/// A differential-drive robot with two DC motors.
///
/// By default each motor and its wheel are a first-order system driven by
/// the signed duty `u ∈ [−1, 1]`: `τ·φ̈ = k_duty·u − φ̇` (the electrical time
/// constant neglected, back-EMF and viscous friction lumped into `τ`), so a
/// constant duty settles at `φ̇ = k_duty·u`. With
/// [`DiffDriveParams::dynamics`] the wheels follow the rigid-body model of
/// [`WheelDynamics`] instead. The body follows the differential-drive
/// kinematics without slip, `v = r(φ̇_R + φ̇_L)/2`, `ω = r(φ̇_R − φ̇_L)/b`.
/// The duties are held over a step (zero-order hold, as a PWM peripheral
/// does) and the state is integrated with classic RK4 over
/// [`DiffDriveParams::substeps`] substeps. The plant keeps its own clock
/// ([`Self::elapsed_s`]), which times the load.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiffDrivePlant {
    params: DiffDriveParams,
    state: DiffDriveState,
    /// Plant time since [`Self::new`], s: the sum of the step lengths.
    elapsed_s: f64,
    /// Rounding error of `elapsed_s` (Kahan summation), s.
    elapsed_carry_s: f64,
}

impl DiffDrivePlant {
    /// A plant at rest at `pose`, wheel angles 0, plant time 0.
    #[must_use]
    pub fn new(params: DiffDriveParams, pose: PlantPose) -> Self {
        let mut state = DiffDriveState::default();
        state.s[0] = pose.x_m;
        state.s[1] = pose.y_m;
        state.s[2] = pose.heading_rad;
        Self {
            params,
            state,
            elapsed_s: 0.0,
            elapsed_carry_s: 0.0,
        }
    }

    /// Plant time since [`Self::new`], s: the sum of the `dt_s` of every
    /// [`Self::step`] (compensated, so it stays exact to rounding over
    /// long runs of short steps).
    #[must_use]
    pub fn elapsed_s(&self) -> f64 {
        self.elapsed_s
    }

    /// The load torque on each wheel now, N·m (positive drives forward;
    /// 0 without [`DiffDriveParams::dynamics`]).
    #[must_use]
    pub fn load_torque_nm(&self) -> f64 {
        self.params.dynamics.map_or(0.0, |d| {
            d.load
                .wheel_torque_nm(self.elapsed_s, d.mass_kg, self.params.wheel_radius_m)
        })
    }

    /// Kinetic energy of the body and wheels `½ q̇ᵀ M q̇`, J (`None` without
    /// [`DiffDriveParams::dynamics`], which has no masses).
    #[must_use]
    pub fn kinetic_energy_j(&self) -> Option<f64> {
        let d = self.params.dynamics?;
        let [[a, c], _] =
            d.mass_matrix_kg_m2(self.params.wheel_radius_m, self.params.track_width_m);
        let (wl, wr) = self.wheel_speeds_rad_s();
        Some(0.5 * (a * (wl * wl + wr * wr) + 2.0 * c * wl * wr))
    }

    /// The parameters.
    #[must_use]
    pub fn params(&self) -> &DiffDriveParams {
        &self.params
    }

    /// The current pose of the axle midpoint.
    #[must_use]
    pub fn pose(&self) -> PlantPose {
        PlantPose::new(self.state.s[0], self.state.s[1], self.state.s[2])
    }

    /// Wheel angles `(φ_L, φ_R)`, rad (continuous; positive drives forward).
    #[must_use]
    pub fn wheel_angles_rad(&self) -> (f64, f64) {
        (self.state.s[3], self.state.s[4])
    }

    /// Wheel speeds `(φ̇_L, φ̇_R)`, rad/s.
    #[must_use]
    pub fn wheel_speeds_rad_s(&self) -> (f64, f64) {
        (self.state.s[5], self.state.s[6])
    }

    /// Body velocity `(v, ω)` from the current wheel speeds.
    #[must_use]
    pub fn body_velocity(&self) -> (f64, f64) {
        let (wl, wr) = self.wheel_speeds_rad_s();
        let r = self.params.wheel_radius_m;
        (
            0.5 * r * (wr + wl),
            r * (wr - wl) / self.params.track_width_m,
        )
    }

    /// Moves the body `ds` metres along an arc turning `dtheta` radians
    /// from its pose, wheels and their speeds untouched: the ground's part
    /// of the motion that the wheels' rotation does not show
    /// ([`RollingWheels`]).
    pub fn slide(&mut self, ds: f64, dtheta: f64) {
        let chord = ds * sinc(0.5 * dtheta);
        let mid = self.state.s[2] + 0.5 * dtheta;
        self.state.s[0] += chord * mid.cos();
        self.state.s[1] += chord * mid.sin();
        self.state.s[2] += dtheta;
    }

    /// Advances `dt_s` seconds with the signed duties `left`, `right` held
    /// (each clamped to [−1, 1]; NaN counts as 0).
    pub fn step(&mut self, left_duty: f64, right_duty: f64, dt_s: f64) {
        let clamp = |u: f64| if u.is_nan() { 0.0 } else { u.clamp(-1.0, 1.0) };
        let u = (clamp(left_duty), clamp(right_duty));
        let n = self.params.substeps.max(1);
        let h = dt_s / f64::from(n);
        let t0 = self.elapsed_s;
        for i in 0..n {
            // Substep times from the step's start, not summed substep by substep.
            let t = t0 + f64::from(i) * h;
            self.state.s = rk4(&self.state.s, t, h, |t, s| self.derivative(t, s, u));
        }
        // Kahan summation of the step lengths.
        let y = dt_s - self.elapsed_carry_s;
        let sum = self.elapsed_s + y;
        self.elapsed_carry_s = (sum - self.elapsed_s) - y;
        self.elapsed_s = sum;
    }

    fn derivative(&self, t_s: f64, s: &[f64; 7], (ul, ur): (f64, f64)) -> [f64; 7] {
        let p = &self.params;
        let (wl, wr) = (s[5], s[6]);
        let v = 0.5 * p.wheel_radius_m * (wr + wl);
        let omega = p.wheel_radius_m * (wr - wl) / p.track_width_m;
        let (al, ar) = match &p.dynamics {
            None => {
                let k = p.wheel_speed_at_full_duty_rad_s;
                let tau = p.motor_time_constant_s;
                ((k * ul - wl) / tau, (k * ur - wr) / tau)
            }
            Some(d) => {
                // Each wheel's torque: motor (stall torque less back-EMF,
                // which cancels it at the no-load speed), friction, load; N·m.
                let no_load_speed = p.wheel_speed_at_full_duty_rad_s;
                let damping = d.stall_torque_nm / no_load_speed + d.viscous_friction_nm_s_per_rad;
                let load = d.load.wheel_torque_nm(t_s, d.mass_kg, p.wheel_radius_m);
                let fl = d.stall_torque_nm * ul - damping * wl + load;
                let fr = d.stall_torque_nm * ur - damping * wr + load;
                // M's eigenvectors are (1, 1) and (−1, 1): solve M q̈ = F in them.
                let (common, differential) =
                    d.modal_inertias_kg_m2(p.wheel_radius_m, p.track_width_m);
                let sum = (fl + fr) / common; // φ̈_L + φ̈_R
                let difference = (fr - fl) / differential; // φ̈_R − φ̈_L
                (0.5 * (sum - difference), 0.5 * (sum + difference))
            }
        };
        [v * s[2].cos(), v * s[2].sin(), omega, wl, wr, al, ar]
    }
}

/// One classic Runge–Kutta step of `ṡ = f(t, s)` from time `t` (the inputs
/// held; `t` drives only the load).
fn rk4<const N: usize>(
    s: &[f64; N],
    t: f64,
    h: f64,
    f: impl Fn(f64, &[f64; N]) -> [f64; N],
) -> [f64; N] {
    let add = |a: &[f64; N], b: &[f64; N], k: f64| -> [f64; N] {
        let mut out = *a;
        for (o, bi) in out.iter_mut().zip(b) {
            *o += k * bi;
        }
        out
    };
    let k1 = f(t, s);
    let k2 = f(t + 0.5 * h, &add(s, &k1, 0.5 * h));
    let k3 = f(t + 0.5 * h, &add(s, &k2, 0.5 * h));
    let k4 = f(t + h, &add(s, &k3, h));
    let mut out = *s;
    for i in 0..N {
        out[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plant() -> DiffDrivePlant {
        DiffDrivePlant::new(DiffDriveParams::default(), PlantPose::new(1.0, 2.0, 0.3))
    }

    #[test]
    fn unicycle_closes_a_circle_exactly() {
        // Radius 2 m at 0.5 m/s: one turn takes 4π/0.5 s. 100 steps of it.
        let mut u = Unicycle::new(PlantPose::new(2.0, 0.0, 0.5 * PI));
        let period = 2.0 * PI * 2.0 / 0.5;
        for _ in 0..100 {
            u.step(0.5, 0.25, period / 100.0);
        }
        let p = u.pose();
        assert!((p.x_m - 2.0).abs() < 1e-12 && p.y_m.abs() < 1e-12, "{p:?}");
        assert!((p.heading_rad - 2.5 * PI).abs() < 1e-12);
    }

    #[test]
    fn unicycle_straight_line() {
        let mut u = Unicycle::new(PlantPose::new(0.0, 0.0, 0.0));
        u.step(2.0, 0.0, 1.5);
        assert_eq!(u.pose(), PlantPose::new(3.0, 0.0, 0.0));
    }

    #[test]
    fn equal_duties_drive_straight() {
        let mut p = plant();
        for _ in 0..200 {
            p.step(0.5, 0.5, 0.01);
        }
        let pose = p.pose();
        assert!((pose.heading_rad - 0.3).abs() < 1e-12);
        // Along the heading: the lateral offset is zero.
        let (dx, dy) = (pose.x_m - 1.0, pose.y_m - 2.0);
        let lateral = -dx * 0.3_f64.sin() + dy * 0.3_f64.cos();
        assert!(lateral.abs() < 1e-12, "{lateral}");
        assert!(dx * 0.3_f64.cos() + dy * 0.3_f64.sin() > 0.5);
    }

    #[test]
    fn opposite_duties_spin_in_place() {
        let mut p = plant();
        for _ in 0..300 {
            p.step(-0.4, 0.4, 0.01);
        }
        let pose = p.pose();
        assert!((pose.x_m - 1.0).abs() < 1e-12 && (pose.y_m - 2.0).abs() < 1e-12);
        // Steady state ω = r·2·k·u/b = 0.03·2·8/0.2 = 2.4 rad/s, minus the lag τ.
        let expected = 2.4 * (3.0 - 0.05 * (1.0 - (-3.0_f64 / 0.05).exp()));
        assert!((pose.heading_rad - 0.3 - expected).abs() < 1e-6, "{pose:?}");
    }

    #[test]
    fn steady_state_speed_is_k_duty_times_u() {
        let mut p = plant();
        // 20 τ: e^-20 of the transient left.
        for _ in 0..100 {
            p.step(0.25, -0.75, 0.01);
        }
        let (wl, wr) = p.wheel_speeds_rad_s();
        assert!(
            (wl - 5.0).abs() < 1e-6 && (wr + 15.0).abs() < 1e-6,
            "{wl} {wr}"
        );
        // One time constant after a step: 1 − 1/e of the way.
        let mut q = plant();
        q.step(1.0, 1.0, 0.05);
        let (wl, _) = q.wheel_speeds_rad_s();
        // RK4 with 10 substeps of τ/10: relative error ~1e-6.
        assert!((wl - 20.0 * (1.0 - (-1.0_f64).exp())).abs() < 2e-5, "{wl}");
    }

    #[test]
    fn duties_are_clamped() {
        let mut p = plant();
        for _ in 0..100 {
            p.step(5.0, f64::NAN, 0.01);
        }
        let (wl, wr) = p.wheel_speeds_rad_s();
        assert!((wl - 20.0).abs() < 1e-6 && wr == 0.0);
    }

    /// A 4 kg robot on the default geometry (`r` = 0.03 m, `b_t` = 0.2 m,
    /// `ω₀` = 20 rad/s), `I_z` = 0.08 kg m², `I_w` = 2e-4 kg m², stall torque
    /// 0.6 N·m, friction `b`. By hand: mean-speed inertia
    /// `m r²/2 + I_w` = 0.0018 + 0.0002 = 0.002 kg m², half-difference
    /// inertia `2 I_z r²/b_t² + I_w` = 0.0036 + 0.0002 = 0.0038 kg m²,
    /// damping `K = 0.6/20 + b`.
    fn rigid(friction: f64, load: LoadTorque) -> DiffDrivePlant {
        let params = DiffDriveParams {
            dynamics: Some(WheelDynamics {
                mass_kg: 4.0,
                yaw_inertia_kg_m2: 0.08,
                wheel_inertia_kg_m2: 2e-4,
                viscous_friction_nm_s_per_rad: friction,
                stall_torque_nm: 0.6,
                load,
            }),
            ..DiffDriveParams::default()
        };
        DiffDrivePlant::new(params, PlantPose::new(1.0, 2.0, 0.3))
    }

    /// `sin(atan(g/100))` by the identity `x/√(1 + x²)`.
    fn sin_of_grade(grade_percent: f64) -> f64 {
        let x = grade_percent / 100.0;
        x / (1.0 + x * x).sqrt()
    }

    #[test]
    fn rigid_equal_duties_settle_at_the_analytic_speed_and_drive_straight() {
        // K = 0.03 + 0.01 = 0.04 N·m·s/rad: steady 0.6·0.5/0.04 = 7.5 rad/s,
        // time constant 0.002/0.04 = 0.05 s.
        let mut p = rigid(0.01, LoadTorque::NONE);
        for _ in 0..5 {
            p.step(0.5, 0.5, 0.01);
        }
        let (wl, wr) = p.wheel_speeds_rad_s();
        let one_tau = 7.5 * (1.0 - (-1.0_f64).exp());
        assert!((wl - one_tau).abs() < 1e-8 && wl == wr, "{wl} {wr}");
        for _ in 5..200 {
            p.step(0.5, 0.5, 0.01);
        }
        let (wl, wr) = p.wheel_speeds_rad_s();
        assert!((wl - 7.5).abs() < 1e-9 && wl == wr, "{wl} {wr}");
        let pose = p.pose();
        assert_eq!(pose.heading_rad, 0.3);
        let (dx, dy) = (pose.x_m - 1.0, pose.y_m - 2.0);
        let lateral = -dx * 0.3_f64.sin() + dy * 0.3_f64.cos();
        assert!(lateral.abs() < 1e-12, "{lateral}");
        // Distance: r·7.5·(t − τ(1 − e^(−t/τ))) at t = 2 s.
        let along = dx * 0.3_f64.cos() + dy * 0.3_f64.sin();
        let expected = 0.03 * 7.5 * (2.0 - 0.05 * (1.0 - (-40.0_f64).exp()));
        assert!((along - expected).abs() < 1e-9, "{along} {expected}");
        let (v, omega) = p.body_velocity();
        assert!((v - 0.225).abs() < 1e-10 && omega == 0.0);
    }

    #[test]
    fn rigid_opposite_duties_spin_in_place_at_the_analytic_rate() {
        // Half-difference: 0.6·0.4/0.04 = 6 rad/s, time constant
        // 0.0038/0.04 = 0.095 s; ω = r·2·6/b_t = 1.8 rad/s.
        let mut p = rigid(0.01, LoadTorque::NONE);
        for _ in 0..300 {
            p.step(-0.4, 0.4, 0.01);
        }
        let pose = p.pose();
        assert_eq!((pose.x_m, pose.y_m), (1.0, 2.0));
        let (wl, wr) = p.wheel_speeds_rad_s();
        assert_eq!(wl, -wr);
        assert!((wr - 6.0 * (1.0 - (-3.0_f64 / 0.095).exp())).abs() < 1e-9);
        let (v, omega) = p.body_velocity();
        assert!(v == 0.0 && (omega - 1.8).abs() < 1e-9, "{omega}");
        let expected = 1.8 * (3.0 - 0.095 * (1.0 - (-3.0_f64 / 0.095).exp()));
        assert!((pose.heading_rad - 0.3 - expected).abs() < 1e-9, "{pose:?}");
    }

    #[test]
    fn slope_step_lowers_the_steady_speed_by_load_over_damping() {
        // 10 % grade: d = −4·9.81·sin α·0.03/2 per wheel, α = atan 0.1.
        let d = -4.0 * 9.81 * sin_of_grade(10.0) * 0.03 / 2.0;
        let load = LoadTorque {
            start_s: 1.0,
            ramp_s: 0.0,
            grade_percent: 10.0,
        };
        let mut p = rigid(0.01, load);
        for _ in 0..99 {
            p.step(0.5, 0.5, 0.01);
        }
        assert_eq!(p.load_torque_nm(), 0.0);
        let (wl, _) = p.wheel_speeds_rad_s();
        assert!((wl - 7.5).abs() < 1e-7, "{wl}");
        for _ in 99..300 {
            p.step(0.5, 0.5, 0.01);
        }
        assert!(
            (p.load_torque_nm() - d).abs() < 1e-15,
            "{}",
            p.load_torque_nm()
        );
        // 40 time constants after the step: 7.5 − |d|/0.04 = 6.0358 rad/s.
        let (wl, wr) = p.wheel_speeds_rad_s();
        let expected = 7.5 + d / 0.04;
        assert!((expected - 6.035_802_8).abs() < 1e-7, "{expected}");
        assert!((wl - expected).abs() < 1e-9 && wl == wr, "{wl} {expected}");
        assert_eq!(p.pose().heading_rad, 0.3);
    }

    #[test]
    fn slope_ramp_is_linear_in_the_angle_and_ends_at_the_same_speed() {
        let load = LoadTorque {
            start_s: 1.0,
            ramp_s: 2.0,
            grade_percent: 10.0,
        };
        let mut p = rigid(0.01, load);
        for _ in 0..200 {
            p.step(0.5, 0.5, 0.01);
        }
        // Half-way up the ramp the angle is α/2: sin(α/2) = √((1 − cos α)/2),
        // cos α = 1/√1.01.
        assert!((p.elapsed_s() - 2.0).abs() < 1e-15, "{}", p.elapsed_s());
        let half = ((1.0 - 1.0 / 1.01_f64.sqrt()) / 2.0).sqrt();
        let d_half = -4.0 * 9.81 * half * 0.03 / 2.0;
        assert!((p.load_torque_nm() - d_half).abs() < 1e-12);
        for _ in 200..600 {
            p.step(0.5, 0.5, 0.01);
        }
        let d = -4.0 * 9.81 * sin_of_grade(10.0) * 0.03 / 2.0;
        assert!((p.load_torque_nm() - d).abs() < 1e-15);
        let (wl, _) = p.wheel_speeds_rad_s();
        assert!((wl - (7.5 + d / 0.04)).abs() < 1e-9, "{wl}");
    }

    #[test]
    fn coasting_without_friction_only_the_back_emf_brakes() {
        // b = 0: K = 0.6/20 = 0.03; a full duty settles at ω₀ = 20 rad/s.
        let mut p = rigid(0.0, LoadTorque::NONE);
        for _ in 0..200 {
            p.step(1.0, 1.0, 0.01);
        }
        let (wl, _) = p.wheel_speeds_rad_s();
        assert!((wl - 20.0).abs() < 1e-9, "{wl}");
        for _ in 0..100 {
            p.step(0.2, 0.9, 0.01);
        }
        let (wl0, wr0) = p.wheel_speeds_rad_s();
        let (mean0, half0) = (0.5 * (wl0 + wr0), 0.5 * (wr0 - wl0));
        // ½q̇ᵀMq̇ = (m r²/2 + I_w)·mean² + (2 I_z r²/b_t² + I_w)·half².
        let energy = |mean: f64, half: f64| 0.002 * mean * mean + 0.0038 * half * half;
        let mut last = p.kinetic_energy_j().unwrap();
        assert!((last - energy(mean0, half0)).abs() < 1e-15);
        for _ in 0..50 {
            p.step(0.0, 0.0, 0.01);
            let now = p.kinetic_energy_j().unwrap();
            assert!(now < last, "{now} {last}");
            last = now;
        }
        // Each mode decays with its own time constant: 0.002/0.03 s and
        // 0.0038/0.03 s.
        let mean = mean0 * (-0.5 * 0.03 / 0.002_f64).exp();
        let half = half0 * (-0.5 * 0.03 / 0.0038_f64).exp();
        let (wl, wr) = p.wheel_speeds_rad_s();
        assert!((wl - (mean - half)).abs() < 1e-9, "{wl}");
        assert!((wr - (mean + half)).abs() < 1e-9, "{wr}");
        assert!((last - energy(mean, half)).abs() < 1e-12);
    }

    #[test]
    fn decoupled_rigid_body_is_the_first_order_model() {
        // I_z = m b_t²/4 makes M diagonal: each wheel is then
        // (m r²/2 + I_w)·φ̈ = τ_stall·u − (τ_stall/ω₀)·φ̇, i.e. the
        // first-order model with τ = 0.002·20/0.8 = 0.05 s, k_duty = ω₀.
        let rigid = DiffDriveParams {
            dynamics: Some(WheelDynamics {
                mass_kg: 4.0,
                yaw_inertia_kg_m2: 0.04,
                wheel_inertia_kg_m2: 2e-4,
                viscous_friction_nm_s_per_rad: 0.0,
                stall_torque_nm: 0.8,
                load: LoadTorque::NONE,
            }),
            ..DiffDriveParams::default()
        };
        let m = rigid.dynamics.unwrap().mass_matrix_kg_m2(0.03, 0.2);
        assert!(m[0][1].abs() < 1e-18 && (m[0][0] - 0.002).abs() < 1e-15);
        let mut a = DiffDrivePlant::new(rigid, PlantPose::new(1.0, 2.0, 0.3));
        let mut b = plant();
        for k in 0..500 {
            let t = f64::from(k) * 0.01;
            let (l, r) = ((0.7 * t).sin(), 0.5 * (1.3 * t).cos());
            a.step(l, r, 0.01);
            b.step(l, r, 0.01);
        }
        let (pa, pb) = (a.pose(), b.pose());
        assert!((pa.x_m - pb.x_m).abs() < 1e-10 && (pa.y_m - pb.y_m).abs() < 1e-10);
        assert!((pa.heading_rad - pb.heading_rad).abs() < 1e-10);
        let (sa, sb) = (a.wheel_speeds_rad_s(), b.wheel_speeds_rad_s());
        assert!((sa.0 - sb.0).abs() < 1e-10 && (sa.1 - sb.1).abs() < 1e-10);
        let (qa, qb) = (a.wheel_angles_rad(), b.wheel_angles_rad());
        assert!((qa.0 - qb.0).abs() < 1e-10 && (qa.1 - qb.1).abs() < 1e-10);
        assert_eq!(b.kinetic_energy_j(), None);
        assert_eq!(b.load_torque_nm(), 0.0);
    }

    #[test]
    fn rigid_duties_are_clamped() {
        let mut p = rigid(0.01, LoadTorque::NONE);
        for _ in 0..200 {
            p.step(5.0, f64::NAN, 0.01);
        }
        // Duties (1, 0): the mean speed heads for 0.6·0.5/0.04 = 7.5 rad/s
        // (time constant 0.05 s), half the difference for −7.5 rad/s
        // (0.095 s). The body couples the wheels: the undriven right wheel
        // is dragged along, `7.5·(e^(−t/0.095) − e^(−t/0.05))`, and lets go.
        let (mean, half) = (
            7.5 * (1.0 - (-2.0_f64 / 0.05).exp()),
            -7.5 * (1.0 - (-2.0_f64 / 0.095).exp()),
        );
        let (wl, wr) = p.wheel_speeds_rad_s();
        assert!((wl - (mean - half)).abs() < 1e-10, "{wl}");
        assert!((wr - (mean + half)).abs() < 1e-12 && wr > 5e-9, "{wr}");
        for _ in 0..200 {
            p.step(5.0, f64::NAN, 0.01);
        }
        // Full duty: 0.6/0.04 = 15 rad/s.
        let (wl, wr) = p.wheel_speeds_rad_s();
        assert!((wl - 15.0).abs() < 1e-12 && wr.abs() < 1e-12, "{wl} {wr}");
    }

    #[test]
    fn load_angle_ramps_and_steps() {
        let ramp = LoadTorque {
            start_s: 1.0,
            ramp_s: 4.0,
            grade_percent: -20.0,
        };
        let full = -(0.2_f64.atan());
        assert_eq!(ramp.grade_angle_rad(0.999), 0.0);
        assert_eq!(ramp.grade_angle_rad(1.0), 0.0);
        assert!((ramp.grade_angle_rad(2.0) - 0.25 * full).abs() < 1e-15);
        assert_eq!(ramp.grade_angle_rad(5.0), full);
        assert_eq!(ramp.grade_angle_rad(50.0), full);
        // Downhill helps: a positive torque.
        let d = ramp.wheel_torque_nm(9.0, 2.0, 0.05);
        assert!((d - 2.0 * 9.81 * sin_of_grade(20.0) * 0.05 / 2.0).abs() < 1e-15);
        let step = LoadTorque {
            ramp_s: 0.0,
            ..ramp
        };
        assert_eq!(step.grade_angle_rad(0.999), 0.0);
        assert_eq!(step.grade_angle_rad(1.0), full);
        assert_eq!(LoadTorque::NONE.wheel_torque_nm(3.0, 4.0, 0.03), 0.0);
        assert_eq!(LoadTorque::default(), LoadTorque::NONE);
    }

    #[test]
    fn the_clock_sums_the_steps_without_drift() {
        let mut p = DiffDrivePlant::new(
            DiffDriveParams {
                substeps: 1,
                ..DiffDriveParams::default()
            },
            PlantPose::default(),
        );
        let mut naive = 0.0_f64;
        for _ in 0..100_000 {
            p.step(0.0, 0.0, 0.01);
            naive += 0.01;
        }
        assert!((p.elapsed_s() - 1000.0).abs() < 1e-12, "{}", p.elapsed_s());
        // What it saves: the plain sum is off by 7.6e-10 s.
        assert!((naive - 1000.0).abs() > 1e-10, "{naive}");
    }

    #[test]
    fn wrap() {
        assert!((wrap_angle(3.0 * PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(-PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(-0.5) + 0.5).abs() < 1e-15);
    }

    fn wheels(q: f64, scale_error: [f64; 2], seed: u64) -> RollingWheels {
        RollingWheels::new(WheelErrors {
            travel_variance_m2_per_m: q,
            scale_error,
            track_width_m: 0.2,
            seed,
        })
    }

    /// Over 1 m rolled in steps of 1 mm (and of 1 cm), each wheel's ground
    /// travel has mean `(1 + e)·1 m` and variance `q·1 m`, the two wheels
    /// independent: over 4,000 metres, within 3 standard errors.
    #[test]
    fn wheel_travel_noise_grows_with_the_distance_rolled() {
        let (q, e) = (1e-4, [0.01, -0.02]);
        for step_m in [1e-3, 1e-2] {
            let mut w = wheels(q, e, 3);
            let steps = (1.0 / step_m) as usize;
            let runs = 4000;
            let (mut sum, mut sum2, mut cross) = ([0.0_f64; 2], [0.0_f64; 2], 0.0);
            for _ in 0..runs {
                let mut total = [0.0_f64; 2];
                for _ in 0..steps {
                    let (r, l) = w.ground_travels(step_m, step_m);
                    total[0] += r;
                    total[1] += l;
                }
                for i in 0..2 {
                    sum[i] += total[i];
                    sum2[i] += total[i] * total[i];
                }
                cross += (total[0] - 1.0 - e[0]) * (total[1] - 1.0 - e[1]);
            }
            let n = f64::from(runs);
            for i in 0..2 {
                let mean = sum[i] / n;
                let variance = sum2[i] / n - mean * mean;
                // Standard errors of the mean and of the variance.
                assert!(
                    (mean - (1.0 + e[i])).abs() < 3.0 * (q / n).sqrt(),
                    "{step_m}: {mean}"
                );
                assert!(
                    (variance - q).abs() < 3.0 * q * (2.0 / n).sqrt(),
                    "{step_m}: {variance}"
                );
            }
            assert!((cross / n).abs() < 3.0 * q / n.sqrt(), "{cross}");
        }
    }

    /// No noise and no scale error: the ground travels are the measured
    /// ones; the scale error alone scales them; the same seed draws the
    /// same noise, another seed other noise; the body motion turns by the
    /// difference of the wheels over the track.
    #[test]
    fn wheel_errors_are_exact_and_seeded() {
        let mut ideal = wheels(0.0, [0.0, 0.0], 1);
        assert_eq!(ideal.ground_travels(0.01, -0.02), (0.01, -0.02));
        let mut scaled = wheels(0.0, [0.5, -0.5], 1);
        assert_eq!(scaled.ground_travels(0.02, 0.02), (0.03, 0.01));
        let (ds, dtheta) = wheels(0.0, [0.5, -0.5], 1).ground_motion(0.02, 0.0);
        assert!((ds - 0.02).abs() < 1e-15 && (dtheta - 0.02 / 0.2).abs() < 1e-15);
        let draws = |seed| {
            let mut w = wheels(1e-4, [0.0, 0.0], seed);
            (0..10)
                .map(|_| w.ground_travels(0.01, 0.01))
                .collect::<Vec<_>>()
        };
        assert_eq!(draws(5), draws(5));
        assert_ne!(draws(5), draws(6));
    }
}
