//! Simulated plants: what the robot's body does with the commands it gets.
//!
//! Plant state is `f64` (the core is `f32`): the simulated world should be
//! more accurate than the controller it judges, so that the errors measured
//! are the controller's and not the simulator's.
//!
//! * [`Unicycle`]: paper 001, eq. (1), `ẋ = v cos θ`, `ẏ = v sin θ`,
//!   `θ̇ = ω`, integrated *exactly* over a step with constant `v, ω` (an arc).
//! * [`DiffDrivePlant`]: two DC motors with first-order dynamics driving the
//!   wheels of a differential-drive robot, integrated with RK4.

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
        let ds = v_m_s * dt_s;
        let dtheta = omega_rad_s * dt_s;
        let chord = ds * sinc(0.5 * dtheta);
        let mid = self.pose.heading_rad + 0.5 * dtheta;
        self.pose.x_m += chord * mid.cos();
        self.pose.y_m += chord * mid.sin();
        self.pose.heading_rad += dtheta;
    }
}

/// Parameters of a [`DiffDrivePlant`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct DiffDriveParams {
    /// Wheel radius `r`, m.
    pub wheel_radius_m: f64,
    /// Track width `b` (distance between the wheel contact points), m.
    pub track_width_m: f64,
    /// Motor + wheel time constant `τ`, s.
    pub motor_time_constant_s: f64,
    /// Steady-state wheel speed at full duty `k_duty`, rad/s.
    pub wheel_speed_at_full_duty_rad_s: f64,
    /// RK4 substeps per [`DiffDrivePlant::step`].
    pub substeps: u32,
}

impl Default for DiffDriveParams {
    fn default() -> Self {
        Self {
            wheel_radius_m: 0.03,
            track_width_m: 0.2,
            motor_time_constant_s: 0.05,
            wheel_speed_at_full_duty_rad_s: 20.0,
            substeps: 10,
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
/// Each motor and its wheel are a first-order system driven by the signed
/// duty `u ∈ [−1, 1]`: `τ·φ̈ = k_duty·u − φ̇` (the electrical time constant
/// neglected, back-EMF and viscous friction lumped into `τ`), so a constant
/// duty settles at `φ̇ = k_duty·u`. The body follows the differential-drive
/// kinematics without slip, `v = r(φ̇_R + φ̇_L)/2`, `ω = r(φ̇_R − φ̇_L)/b`.
/// The duties are held over a step (zero-order hold, as a PWM peripheral
/// does) and the state is integrated with classic RK4 over
/// [`DiffDriveParams::substeps`] substeps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiffDrivePlant {
    params: DiffDriveParams,
    state: DiffDriveState,
}

impl DiffDrivePlant {
    /// A plant at rest at `pose`, wheel angles 0.
    #[must_use]
    pub fn new(params: DiffDriveParams, pose: PlantPose) -> Self {
        let mut state = DiffDriveState::default();
        state.s[0] = pose.x_m;
        state.s[1] = pose.y_m;
        state.s[2] = pose.heading_rad;
        Self { params, state }
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

    /// Advances `dt_s` seconds with the signed duties `left`, `right` held
    /// (each clamped to [−1, 1]; NaN counts as 0).
    pub fn step(&mut self, left_duty: f64, right_duty: f64, dt_s: f64) {
        let clamp = |u: f64| if u.is_nan() { 0.0 } else { u.clamp(-1.0, 1.0) };
        let u = (clamp(left_duty), clamp(right_duty));
        let n = self.params.substeps.max(1);
        let h = dt_s / f64::from(n);
        for _ in 0..n {
            self.state.s = rk4(&self.state.s, h, |s| self.derivative(s, u));
        }
    }

    fn derivative(&self, s: &[f64; 7], (ul, ur): (f64, f64)) -> [f64; 7] {
        let p = &self.params;
        let (wl, wr) = (s[5], s[6]);
        let v = 0.5 * p.wheel_radius_m * (wr + wl);
        let omega = p.wheel_radius_m * (wr - wl) / p.track_width_m;
        let k = p.wheel_speed_at_full_duty_rad_s;
        let tau = p.motor_time_constant_s;
        [
            v * s[2].cos(),
            v * s[2].sin(),
            omega,
            wl,
            wr,
            (k * ul - wl) / tau,
            (k * ur - wr) / tau,
        ]
    }
}

/// One classic Runge–Kutta step of `ṡ = f(s)` (autonomous: inputs held).
fn rk4<const N: usize>(s: &[f64; N], h: f64, f: impl Fn(&[f64; N]) -> [f64; N]) -> [f64; N] {
    let add = |a: &[f64; N], b: &[f64; N], k: f64| -> [f64; N] {
        let mut out = *a;
        for (o, bi) in out.iter_mut().zip(b) {
            *o += k * bi;
        }
        out
    };
    let k1 = f(s);
    let k2 = f(&add(s, &k1, 0.5 * h));
    let k3 = f(&add(s, &k2, 0.5 * h));
    let k4 = f(&add(s, &k3, h));
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

    #[test]
    fn wrap() {
        assert!((wrap_angle(3.0 * PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(-PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(-0.5) + 0.5).abs() < 1e-15);
    }
}
