//! Slip-adaptive tracking of paper 004 (Iossaqui, Camino & Zampieri,
//! *nonlinear filters for tracked robots under slip*): the tracked robot
//! with longitudinal slip, its reference and error, and the two adaptive
//! controllers, with the filter models of the paper's two scenarios.
//!
//! # Model (1)–(4)
//! Slip ratio `i ∈ [0, 1)`, `p = 1/(1 − i)` ([`slip_factor`]). With wheel
//! speeds `ξ = (ω_L, ω_R)` the robot moves as a unicycle with
//! `v = r(ω_L + ω_R)/(2p)`, `ω = r(ω_R − ω_L)/(b p)` (1)
//! ([`TrackedRobot::body_velocity`]). Dynamics (2): `M̄ ξ̇ = B̄ τ` with
//! `M̄ = SᵀMS = M₀/p²`, `M₀ = [[m r²/4 + J r²/b², m r²/4 − J r²/b²], [·, ·]]`
//! and `B̄ = SᵀB = I/p`, so `ξ̇ = p M₀⁻¹ τ`
//! ([`TrackedRobot::wheel_acceleration`]). The printed `B(q)` has `b/2` in
//! both columns of its last row; the left track's torque turns the robot
//! clockwise, so that entry is `−b/2` (with `+b/2`, `B̄` would not be
//! invertible and (8) would not exist). The reference (3) is a unicycle
//! driven by piecewise constant `(v_r, ω_r)` ([`PiecewiseReference`],
//! integrated exactly along arcs); the error (4) is the reference's offset
//! in the robot's frame ([`tracking_error`], `e3` wrapped to (−π, π]).
//!
//! # Adaptive velocity-based control (5)–(7)
//! ```text
//! ξ = (p̂/2r)·[[2, −b], [2, b]]·(v, ω)                              (5)
//! v = v_r cos e3 + k1 e1,   ω = ω_r + v_r k2 e2 + k3 sin e3         (6)
//! dp̂/dt = ρ (v e1 + ω sin e3 / k2)                                  (7)
//! ```
//! (7) is printed without its dot. It follows from `V = ½(e1² + e2²) +
//! (1 − cos e3)/k2 + (p − p̂)²/(2ρp)`: with the robot moving at `(p̂/p)(v,
//! ω)`, `V̇ = −k1 e1² − (k3/k2) sin² e3`. `p̂` is integrated by forward Euler
//! and projected onto `[1, P_MAX]` (`p ≥ 1` for every slip `i ≥ 0`, and a
//! `p̂ ≤ 0` would reverse the tracks): the projection only removes steps
//! that move away from the true `p`, so `V̇` keeps its sign.
//!
//! # Adaptive torque-based control (8)–(10)
//! `τ = B̄(p̂)⁻¹ M̄(p̂) u = M₀ u / p̂` (8), `u = ξ̇_d + diag(k4, k5)(ξ_d − ξ)`
//! (9), `ξ_d` = (5) with (6) (10), `p̂` by (7). The paper does not say how
//! `ξ̇_d` is obtained; here it is the backward difference of `ξ_d` over the
//! step (0 on the first step and after a rejected one). Differentiating
//! (6)–(7) along the model instead (`ė1 = ω̂ e2 − v̂ + v_r cos e3`, … with
//! `(v̂, ω̂)` from the wheel speeds and `p̂`) does worse: with `p̂ ≠ p` it
//! feeds the adaptation error into the inner loop, and even on the true
//! state `p̂` climbs to 9 during the slip (measured in `host-tests`), where
//! differencing keeps it at 1.33. Evaluating (8) at `p = 1` instead of `p̂`
//! does no better.
//!
//! # Filter models (section "Numerical results")
//! [`PoseModel`] (scenario 1: state `(X, Y, ψ)`) and [`PoseWheelModel`]
//! (scenario 2: `(X, Y, ψ, ω_L, ω_R)`, wheel speeds constant over a step),
//! both driven by the auxiliary `(v, ω)` of (6), first-order (Euler)
//! discretisations with the full state measured. They implement
//! [`wmr_core::filters::ekf::EkfModel`], [`wmr_core::filters::particle_filter::ParticleModel`] and
//! the UKF's model trait.

use nalgebra::{Matrix2, SMatrix, SVector, Vector2};

use wmr_core::filters::ekf::EkfModel;
use wmr_core::filters::particle_filter::ParticleModel;
use wmr_core::filters::ukf::{AngleComponents, UkfModel, residual_with_angles};
use wmr_core::geometry::{BodyVelocity, Pose, Vec2, WheelSpeeds};
use wmr_core::math;

/// Largest slip factor the adaptation may reach (`i = 0.95`).
pub const P_MAX: f32 = 20.0;

/// `p = 1/(1 − i)` for a slip ratio `i ∈ [0, 1)`; `None` outside.
#[must_use]
pub fn slip_factor(slip_ratio: f32) -> Option<f32> {
    (slip_ratio.is_finite() && (0.0..1.0).contains(&slip_ratio)).then(|| 1.0 / (1.0 - slip_ratio))
}

/// Why a configuration was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum SlipTrackingError {
    /// A physical parameter is not finite and positive.
    Parameter,
    /// A gain is not finite and positive.
    Gain,
    /// The period is not finite and positive.
    Period,
    /// The initial slip factor is not in `[1, P_MAX]`.
    SlipEstimate,
    /// Reference segments are empty, not finite, or their start times do
    /// not increase from 0.
    Reference,
}

impl core::fmt::Display for SlipTrackingError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::Parameter => "a physical parameter must be finite and > 0",
            Self::Gain => "a gain must be finite and > 0",
            Self::Period => "period_s must be finite and > 0 s",
            Self::SlipEstimate => "the initial slip factor must be in [1, P_MAX]",
            Self::Reference => "the reference segments must be non-empty and finite, with start times increasing from 0",
        })
    }
}

impl core::error::Error for SlipTrackingError {}

fn positive(x: f32) -> bool {
    x.is_finite() && x > 0.0
}

/// The tracked robot's parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TrackedRobot {
    wheel_radius_m: f32,
    track_width_m: f32,
    mass_kg: f32,
    yaw_inertia_kg_m2: f32,
}

impl TrackedRobot {
    /// Paper 004's robot: `b = 0.65 m, r = 0.35 m, m = 0.80 kg,
    /// J = 0.0608 kg m²`.
    pub const PAPER: Self = Self {
        wheel_radius_m: 0.35,
        track_width_m: 0.65,
        mass_kg: 0.80,
        yaw_inertia_kg_m2: 0.0608,
    };

    /// Wheel radius `r` (m), distance between the tracks `b` (m), mass `m`
    /// (kg), yaw inertia `J` (kg m²).
    ///
    /// # Errors
    /// [`SlipTrackingError::Parameter`].
    pub fn new(
        wheel_radius_m: f32,
        track_width_m: f32,
        mass_kg: f32,
        yaw_inertia_kg_m2: f32,
    ) -> Result<Self, SlipTrackingError> {
        if [wheel_radius_m, track_width_m, mass_kg, yaw_inertia_kg_m2]
            .iter()
            .all(|&x| positive(x))
        {
            Ok(Self {
                wheel_radius_m,
                track_width_m,
                mass_kg,
                yaw_inertia_kg_m2,
            })
        } else {
            Err(SlipTrackingError::Parameter)
        }
    }

    /// Body velocity of wheel speeds `ξ` under slip factor `p` (1).
    #[must_use]
    pub fn body_velocity(&self, wheels: WheelSpeeds, p: f32) -> BodyVelocity {
        let (r, b) = (self.wheel_radius_m, self.track_width_m);
        BodyVelocity {
            v_m_s: r * (wheels.left_rad_s + wheels.right_rad_s) / (2.0 * p),
            omega_rad_s: r * (wheels.right_rad_s - wheels.left_rad_s) / (b * p),
        }
    }

    /// The wheel speeds (5) that give `body` if the slip factor is `p_hat`.
    #[must_use]
    pub fn wheels_for(&self, body: BodyVelocity, p_hat: f32) -> WheelSpeeds {
        let (r, b) = (self.wheel_radius_m, self.track_width_m);
        let k = p_hat / (2.0 * r);
        WheelSpeeds {
            left_rad_s: k * (2.0 * body.v_m_s - b * body.omega_rad_s),
            right_rad_s: k * (2.0 * body.v_m_s + b * body.omega_rad_s),
        }
    }

    /// `M₀ = p² M̄`, the no-slip inertia of the wheel speeds, kg m².
    #[must_use]
    pub fn wheel_inertia(&self) -> Matrix2<f32> {
        let (r, b) = (self.wheel_radius_m, self.track_width_m);
        let translation = self.mass_kg * r * r / 4.0;
        let rotation = self.yaw_inertia_kg_m2 * r * r / (b * b);
        Matrix2::new(
            translation + rotation,
            translation - rotation,
            translation - rotation,
            translation + rotation,
        )
    }

    /// `ξ̇ = p M₀⁻¹ τ` (2) for torques `(τ_L, τ_R)` (N·m); zero if `M₀` is
    /// singular (it is not for valid parameters).
    #[must_use]
    pub fn wheel_acceleration(&self, torque: Vector2<f32>, p: f32) -> Vector2<f32> {
        self.wheel_inertia()
            .try_inverse()
            .map_or(Vector2::zeros(), |inverse| inverse * torque * p)
    }

    /// `τ = B̄(p̂)⁻¹ M̄(p̂) u = M₀ u / p̂` (8).
    #[must_use]
    pub fn torque_for(&self, acceleration: Vector2<f32>, p_hat: f32) -> Vector2<f32> {
        self.wheel_inertia() * acceleration / p_hat
    }
}

/// One constant-input piece of the reference (3).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ReferenceSegment {
    /// Start time, s.
    pub start_s: f32,
    /// `v_r`, m/s.
    pub v_m_s: f32,
    /// `ω_r`, rad/s.
    pub omega_rad_s: f32,
}

/// The reference at one time.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ReferenceState {
    /// `q_r`.
    pub pose: Pose,
    /// `(v_r, ω_r)`.
    pub velocity: BodyVelocity,
}

/// The reference (3): a unicycle from `start` driven by `K` segments of
/// constant `(v_r, ω_r)`, integrated exactly (straight lines and arcs).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PiecewiseReference<const K: usize> {
    segments: [ReferenceSegment; K],
    /// The pose at each segment's start.
    starts: [Pose; K],
}

/// The pose after driving `velocity` for `dt` from `pose`, exactly.
fn drive(pose: Pose, velocity: BodyVelocity, dt: f32) -> Pose {
    let dtheta = velocity.omega_rad_s * dt;
    let chord = velocity.v_m_s * dt * math::sinc(0.5 * dtheta);
    let mid = pose.heading_rad + 0.5 * dtheta;
    Pose {
        position: Vec2::new(
            pose.position.x + chord * math::cos(mid),
            pose.position.y + chord * math::sin(mid),
        ),
        heading_rad: math::wrap_angle(pose.heading_rad + dtheta),
    }
}

impl<const K: usize> PiecewiseReference<K> {
    /// From a start pose and segments whose start times increase from 0.
    ///
    /// # Errors
    /// [`SlipTrackingError::Reference`].
    pub fn new(start: Pose, segments: [ReferenceSegment; K]) -> Result<Self, SlipTrackingError> {
        let finite = segments
            .iter()
            .all(|s| s.start_s.is_finite() && s.v_m_s.is_finite() && s.omega_rad_s.is_finite());
        let ordered = segments.windows(2).all(|w| match w {
            [a, b] => b.start_s > a.start_s,
            _ => true,
        });
        let from_zero = segments.first().is_some_and(|s| s.start_s == 0.0);
        if !(finite && ordered && from_zero && start.heading_rad.is_finite()) {
            return Err(SlipTrackingError::Reference);
        }
        let mut starts = [start; K];
        let mut pose = start;
        for (i, slot) in starts.iter_mut().enumerate() {
            if let (Some(previous), Some(this)) = (
                i.checked_sub(1).and_then(|j| segments.get(j)),
                segments.get(i),
            ) {
                pose = drive(
                    pose,
                    BodyVelocity {
                        v_m_s: previous.v_m_s,
                        omega_rad_s: previous.omega_rad_s,
                    },
                    this.start_s - previous.start_s,
                );
            }
            *slot = pose;
        }
        Ok(Self { segments, starts })
    }

    /// Paper 004's reference from `(0, 0, 0)`: `v_r = 0.5 m/s` throughout
    /// until 51 s, then 0.7; `ω_r = 0` until 15 s, −0.4 rad/s until 33 s,
    /// +0.4 until 51 s, then 0.
    ///
    /// # Errors
    /// Never for these constants.
    pub fn paper() -> Result<PiecewiseReference<4>, SlipTrackingError> {
        let segment = |start_s, v_m_s, omega_rad_s| ReferenceSegment {
            start_s,
            v_m_s,
            omega_rad_s,
        };
        PiecewiseReference::new(
            Pose::new(0.0, 0.0, 0.0),
            [
                segment(0.0, 0.5, 0.0),
                segment(15.0, 0.5, -0.4),
                segment(33.0, 0.5, 0.4),
                segment(51.0, 0.7, 0.0),
            ],
        )
    }

    /// The reference at `t_s` (≥ 0; earlier times give the start).
    #[must_use]
    pub fn sample(&self, t_s: f32) -> ReferenceState {
        let mut state = ReferenceState {
            pose: self.starts.first().copied().unwrap_or_default(),
            velocity: BodyVelocity::ZERO,
        };
        for (segment, start) in self.segments.iter().zip(self.starts.iter()) {
            if t_s >= segment.start_s || segment.start_s == 0.0 {
                let velocity = BodyVelocity {
                    v_m_s: segment.v_m_s,
                    omega_rad_s: segment.omega_rad_s,
                };
                state = ReferenceState {
                    pose: drive(*start, velocity, (t_s - segment.start_s).max(0.0)),
                    velocity,
                };
            }
        }
        state
    }
}

/// The tracking error (4): the reference's offset in the robot's frame,
/// `(e1, e2, e3)` in m, m, rad (`e3 = ψ_r − ψ` wrapped).
#[must_use]
pub fn tracking_error(pose: &Pose, reference: &Pose) -> [f32; 3] {
    let (s, c) = (math::sin(pose.heading_rad), math::cos(pose.heading_rad));
    let dx = reference.position.x - pose.position.x;
    let dy = reference.position.y - pose.position.y;
    [
        c * dx + s * dy,
        -s * dx + c * dy,
        math::wrap_angle(reference.heading_rad - pose.heading_rad),
    ]
}

/// Gains of (5)–(7) and (9).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SlipGains {
    k1: f32,
    k2: f32,
    k3: f32,
    k4: f32,
    k5: f32,
    rho: f32,
}

impl SlipGains {
    /// The paper's: `k1 = k3 = 6, k2 = 8, k4 = k5 = 4, ρ = 3`.
    pub const PAPER: Self = Self {
        k1: 6.0,
        k2: 8.0,
        k3: 6.0,
        k4: 4.0,
        k5: 4.0,
        rho: 3.0,
    };

    /// `k1, k2, k3` of (6), `k4, k5` of (9) (1/s), `ρ` of (7).
    ///
    /// # Errors
    /// [`SlipTrackingError::Gain`] unless all are finite and positive.
    pub fn new(
        k1: f32,
        k2: f32,
        k3: f32,
        k4: f32,
        k5: f32,
        rho: f32,
    ) -> Result<Self, SlipTrackingError> {
        if [k1, k2, k3, k4, k5, rho].iter().all(|&x| positive(x)) {
            Ok(Self {
                k1,
                k2,
                k3,
                k4,
                k5,
                rho,
            })
        } else {
            Err(SlipTrackingError::Gain)
        }
    }
}

/// What the velocity-based controller did this step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct VelocityControl {
    /// `ξ` (5), rad/s.
    pub wheels: WheelSpeeds,
    /// The auxiliary `(v, ω)` (6).
    pub body: BodyVelocity,
    /// `(e1, e2, e3)` (4) from the pose used.
    pub error: [f32; 3],
    /// `p̂` after this step's update (7).
    pub slip_estimate: f32,
}

/// The adaptive velocity-based controller (5)–(7).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AdaptiveVelocityController {
    robot: TrackedRobot,
    gains: SlipGains,
    period_s: f32,
    slip_estimate: f32,
    rejected_poses: u32,
}

impl AdaptiveVelocityController {
    /// With step `period_s` (s) and `p̂(0)` (paper: 1).
    ///
    /// # Errors
    /// [`SlipTrackingError::Period`] or [`SlipTrackingError::SlipEstimate`].
    pub fn new(
        robot: TrackedRobot,
        gains: SlipGains,
        period_s: f32,
        slip_estimate: f32,
    ) -> Result<Self, SlipTrackingError> {
        if !positive(period_s) {
            return Err(SlipTrackingError::Period);
        }
        if !(slip_estimate.is_finite() && (1.0..=P_MAX).contains(&slip_estimate)) {
            return Err(SlipTrackingError::SlipEstimate);
        }
        Ok(Self {
            robot,
            gains,
            period_s,
            slip_estimate,
            rejected_poses: 0,
        })
    }

    /// `p̂`.
    #[must_use]
    pub fn slip_estimate(&self) -> f32 {
        self.slip_estimate
    }

    /// Steps given a non-finite pose or reference (they command a stop and
    /// leave `p̂` unchanged).
    #[must_use]
    pub fn rejected_poses(&self) -> u32 {
        self.rejected_poses
    }

    /// One step from the reference and the (estimated) pose.
    pub fn step(&mut self, reference: &ReferenceState, pose: &Pose) -> VelocityControl {
        let g = self.gains;
        let error = tracking_error(pose, &reference.pose);
        let [e1, e2, e3] = error;
        let (v_r, w_r) = (reference.velocity.v_m_s, reference.velocity.omega_rad_s);
        let body = BodyVelocity {
            v_m_s: v_r * math::cos(e3) + g.k1 * e1,
            omega_rad_s: w_r + v_r * g.k2 * e2 + g.k3 * math::sin(e3),
        };
        let rate = g.rho * (body.v_m_s * e1 + body.omega_rad_s * math::sin(e3) / g.k2);
        let next = (self.slip_estimate + self.period_s * rate).clamp(1.0, P_MAX);
        if !(body.is_finite() && next.is_finite()) {
            self.rejected_poses = self.rejected_poses.saturating_add(1);
            return VelocityControl {
                slip_estimate: self.slip_estimate,
                ..VelocityControl::default()
            };
        }
        let wheels = self.robot.wheels_for(body, self.slip_estimate);
        self.slip_estimate = next;
        VelocityControl {
            wheels,
            body,
            error,
            slip_estimate: next,
        }
    }
}

/// What the torque-based controller did this step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TorqueControl {
    /// `(τ_L, τ_R)` (8), N·m.
    pub torque: [f32; 2],
    /// The velocity part: `ξ_d` (10), `(v, ω)`, the error, `p̂`.
    pub velocity: VelocityControl,
}

/// The adaptive torque-based controller (8)–(10).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AdaptiveTorqueController {
    velocity: AdaptiveVelocityController,
    last_desired: Option<WheelSpeeds>,
}

impl AdaptiveTorqueController {
    /// Around a velocity controller (its gains hold `k4, k5`).
    #[must_use]
    pub fn new(velocity: AdaptiveVelocityController) -> Self {
        Self {
            velocity,
            last_desired: None,
        }
    }

    /// `p̂`.
    #[must_use]
    pub fn slip_estimate(&self) -> f32 {
        self.velocity.slip_estimate
    }

    /// One step from the reference, the (estimated) pose and wheel speeds.
    pub fn step(
        &mut self,
        reference: &ReferenceState,
        pose: &Pose,
        wheels: WheelSpeeds,
    ) -> TorqueControl {
        let p_hat = self.velocity.slip_estimate;
        let velocity = self.velocity.step(reference, pose);
        let desired = velocity.wheels;
        let h = self.velocity.period_s;
        let g = self.velocity.gains;
        let robot = self.velocity.robot;
        let rate = self.last_desired.map_or(Vector2::zeros(), |last| {
            Vector2::new(
                (desired.left_rad_s - last.left_rad_s) / h,
                (desired.right_rad_s - last.right_rad_s) / h,
            )
        });
        let u = rate
            + Vector2::new(
                g.k4 * (desired.left_rad_s - wheels.left_rad_s),
                g.k5 * (desired.right_rad_s - wheels.right_rad_s),
            );
        let torque = robot.torque_for(u, p_hat);
        if !(torque.iter().all(|x| x.is_finite()) && velocity.body.is_finite()) {
            self.velocity.rejected_poses = self.velocity.rejected_poses.saturating_add(1);
            self.last_desired = None;
            return TorqueControl {
                torque: [0.0; 2],
                velocity,
            };
        }
        self.last_desired = Some(desired);
        TorqueControl {
            torque: [torque.x, torque.y],
            velocity,
        }
    }
}

/// Scenario 1's filter model: `x = (X, Y, ψ)`, input the auxiliary
/// `(v, ω)`, `x⁺ = x + h (v cos ψ, v sin ψ, ω)`, the pose measured.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PoseModel;

/// Scenario 2's filter model: `x = (X, Y, ψ, ω_L, ω_R)`, the pose driven
/// by the auxiliary `(v, ω)` of (6) as in scenario 1 and the wheel speeds
/// held over a step (a random walk through the process noise), the whole
/// state measured. The paper's "linear and angular velocities" are read as
/// (6)'s: computing them from the state's wheel speeds with `p̂` couples
/// the filter to the adaptation, and on the EKF that diverges once `p̂`
/// is off (measured in `host-tests`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PoseWheelModel;

/// The heading's index in both models' states and measurements.
const HEADING: [usize; 1] = [2];

/// `x` with component `heading` wrapped.
fn wrapped_state<const N: usize>(mut x: SVector<f32, N>, heading: usize) -> SVector<f32, N> {
    if let Some(angle) = x.get_mut(heading) {
        *angle = math::wrap_angle(*angle);
    }
    x
}

/// One Euler step of the pose part: `x + h (v cos ψ, v sin ψ, ω, 0, …)`
/// (the heading is component 2).
fn pose_step<const N: usize>(x: &SVector<f32, N>, u: &BodyVelocity, dt_s: f32) -> SVector<f32, N> {
    let heading = x.get(2).copied().unwrap_or(0.0);
    pose_step_at(x, u, dt_s, math::sin(heading), math::cos(heading))
}

/// [`pose_step`] with the heading's sine and cosine given.
fn pose_step_at<const N: usize>(
    x: &SVector<f32, N>,
    u: &BodyVelocity,
    dt_s: f32,
    sin: f32,
    cos: f32,
) -> SVector<f32, N> {
    let mut rate = SVector::<f32, N>::zeros();
    for (r, value) in rate
        .iter_mut()
        .zip([u.v_m_s * cos, u.v_m_s * sin, u.omega_rad_s])
    {
        *r = value;
    }
    x + rate * dt_s
}

/// `∂/∂x` of [`pose_step`]: the identity but for `∂(X, Y)/∂ψ`.
fn pose_step_jacobian<const N: usize>(
    u: &BodyVelocity,
    dt_s: f32,
    sin: f32,
    cos: f32,
) -> SMatrix<f32, N, N> {
    let mut a = SMatrix::<f32, N, N>::identity();
    if let Some(v) = a.get_mut((0, 2)) {
        *v = -dt_s * u.v_m_s * sin;
    }
    if let Some(v) = a.get_mut((1, 2)) {
        *v = dt_s * u.v_m_s * cos;
    }
    a
}

/// The EKF, particle-filter and UKF impls of a pose model with `$n`
/// states, all measured: the pose moved by [`pose_step`], any further
/// states held, the heading wrapped in states and residuals and averaged
/// as an angle.
macro_rules! pose_model_filters {
    ($model:ty, $n:literal) => {
        impl EkfModel<$n, $n> for $model {
            type Input = BodyVelocity;

            fn transition(
                &self,
                x: &SVector<f32, $n>,
                u: &BodyVelocity,
                dt_s: f32,
            ) -> SVector<f32, $n> {
                pose_step(x, u, dt_s)
            }

            fn transition_jacobian(
                &self,
                x: &SVector<f32, $n>,
                u: &BodyVelocity,
                dt_s: f32,
            ) -> SMatrix<f32, $n, $n> {
                pose_step_jacobian(u, dt_s, math::sin(x.z), math::cos(x.z))
            }

            /// One sine and one cosine for both.
            fn transition_with_jacobian(
                &self,
                x: &SVector<f32, $n>,
                u: &BodyVelocity,
                dt_s: f32,
            ) -> (SVector<f32, $n>, SMatrix<f32, $n, $n>) {
                let (s, c) = (math::sin(x.z), math::cos(x.z));
                (
                    pose_step_at(x, u, dt_s, s, c),
                    pose_step_jacobian(u, dt_s, s, c),
                )
            }

            fn measure(&self, x: &SVector<f32, $n>) -> SVector<f32, $n> {
                *x
            }

            fn measurement_jacobian(&self, _x: &SVector<f32, $n>) -> SMatrix<f32, $n, $n> {
                SMatrix::<f32, $n, $n>::identity()
            }

            fn measurement_residual(
                &self,
                z: &SVector<f32, $n>,
                expected: &SVector<f32, $n>,
            ) -> SVector<f32, $n> {
                residual_with_angles(z, expected, &HEADING)
            }

            fn normalize(&self, x: SVector<f32, $n>) -> SVector<f32, $n> {
                wrapped_state(x, 2)
            }
        }

        impl ParticleModel<$n, $n> for $model {
            type Input = BodyVelocity;

            fn transition(
                &self,
                x: &SVector<f32, $n>,
                u: &BodyVelocity,
                dt_s: f32,
            ) -> SVector<f32, $n> {
                pose_step(x, u, dt_s)
            }

            fn measure(&self, x: &SVector<f32, $n>) -> SVector<f32, $n> {
                *x
            }

            fn measurement_residual(
                &self,
                z: &SVector<f32, $n>,
                expected: &SVector<f32, $n>,
            ) -> SVector<f32, $n> {
                residual_with_angles(z, expected, &HEADING)
            }

            fn is_angle(&self, index: usize) -> bool {
                HEADING.contains(&index)
            }

            fn input_is_valid(&self, u: &BodyVelocity) -> bool {
                u.is_finite()
            }

            /// `h(x) = x`, the heading's residual wrapped, `σ_q` additive.
            fn measures_state(&self) -> bool {
                true
            }
        }

        impl UkfModel<$n, $n> for $model {
            type Input = BodyVelocity;

            fn input_is_finite(&self, u: &BodyVelocity) -> bool {
                u.is_finite()
            }

            fn transition(
                &self,
                x: &SVector<f32, $n>,
                u: &BodyVelocity,
                dt_s: f32,
            ) -> SVector<f32, $n> {
                pose_step(x, u, dt_s)
            }

            fn measure(&self, x: &SVector<f32, $n>) -> SVector<f32, $n> {
                *x
            }

            fn angles(&self) -> AngleComponents<$n, $n> {
                AngleComponents::from_indices(&HEADING, &HEADING)
            }
        }
    };
}

pose_model_filters!(PoseModel, 3);
pose_model_filters!(PoseWheelModel, 5);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slip_factor_and_kinematics() {
        assert_eq!(slip_factor(0.0), Some(1.0));
        assert!((slip_factor(0.25).unwrap() - 4.0 / 3.0).abs() < 1e-6);
        assert_eq!(slip_factor(1.0), None);
        assert_eq!(slip_factor(-0.1), None);
        let robot = TrackedRobot::PAPER;
        let body = BodyVelocity {
            v_m_s: 0.5,
            omega_rad_s: -0.4,
        };
        let p = 4.0 / 3.0;
        let back = robot.body_velocity(robot.wheels_for(body, p), p);
        assert!((back.v_m_s - 0.5).abs() < 1e-6 && (back.omega_rad_s + 0.4).abs() < 1e-6);
        // Underestimating the slip slows the robot by p̂/p.
        let slow = robot.body_velocity(robot.wheels_for(body, 1.0), p);
        assert!((slow.v_m_s - 0.5 * 0.75).abs() < 1e-6);
        // (8) inverts (2) when p̂ = p.
        let u = Vector2::new(1.5, -0.5);
        let a = robot.wheel_acceleration(robot.torque_for(u, p), p);
        assert!((a - u).amax() < 1e-5, "{a}");
        assert!(TrackedRobot::new(0.35, 0.0, 0.8, 0.06).is_err());
    }

    #[test]
    fn paper_reference_is_continuous_and_exact() {
        let reference = PiecewiseReference::<4>::paper().unwrap();
        let at = |t: f32| reference.sample(t);
        // 15 s straight at 0.5 m/s.
        let p = at(15.0).pose;
        assert!((p.position.x - 7.5).abs() < 1e-5 && p.position.y.abs() < 1e-6);
        // Continuous across each switch.
        for t in [15.0_f32, 33.0, 51.0] {
            let (a, b) = (at(t - 1e-3).pose, at(t).pose);
            assert!((a.position - b.position).norm() < 1e-3, "{t}");
        }
        // A full circle of radius 0.5/0.4 m at −0.4 rad/s from 15 s comes
        // back to (7.5, 0) after 2π/0.4 s.
        let back = at(15.0 + core::f32::consts::TAU / 0.4).pose;
        assert!(
            (back.position - Vec2::new(7.5, 0.0)).norm() < 1e-3,
            "{back:?}"
        );
        assert_eq!(at(40.0).velocity.omega_rad_s, 0.4);
        assert!(
            PiecewiseReference::new(
                Pose::new(0.0, 0.0, 0.0),
                [ReferenceSegment {
                    start_s: 1.0,
                    v_m_s: 0.5,
                    omega_rad_s: 0.0
                }]
            )
            .is_err()
        );
    }

    #[test]
    fn tracking_error_is_in_the_robot_frame() {
        let pose = Pose::new(1.0, 1.0, core::f32::consts::FRAC_PI_2);
        // Reference 2 m ahead of the robot (along +y), heading π.
        let e = tracking_error(&pose, &Pose::new(1.0, 3.0, core::f32::consts::PI));
        assert!((e[0] - 2.0).abs() < 1e-6 && e[1].abs() < 1e-6);
        assert!((e[2] - core::f32::consts::FRAC_PI_2).abs() < 1e-6);
    }

    #[test]
    fn controller_validates_and_rejects_bad_poses() {
        let robot = TrackedRobot::PAPER;
        assert_eq!(
            AdaptiveVelocityController::new(robot, SlipGains::PAPER, 0.0, 1.0),
            Err(SlipTrackingError::Period)
        );
        assert_eq!(
            AdaptiveVelocityController::new(robot, SlipGains::PAPER, 0.005, 0.5),
            Err(SlipTrackingError::SlipEstimate)
        );
        assert_eq!(
            SlipGains::new(6.0, 8.0, 6.0, 4.0, 4.0, f32::NAN),
            Err(SlipTrackingError::Gain)
        );
        let mut c = AdaptiveVelocityController::new(robot, SlipGains::PAPER, 0.005, 1.0).unwrap();
        let reference = PiecewiseReference::<4>::paper().unwrap().sample(1.0);
        let out = c.step(&reference, &Pose::new(f32::NAN, 0.0, 0.0));
        assert_eq!(out.wheels, WheelSpeeds::default());
        assert_eq!(c.rejected_poses(), 1);
        assert_eq!(c.slip_estimate(), 1.0);
        // Far behind the reference, p̂ moves but stays in [1, P_MAX].
        for _ in 0..10_000 {
            let out = c.step(&reference, &Pose::new(-100.0, 50.0, 3.0));
            assert!((1.0..=P_MAX).contains(&out.slip_estimate));
        }
    }
}
