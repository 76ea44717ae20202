//! The tracked robot under slip (module docs of [`super`], "Model
//! (1)–(4)"): the slip factor, the kinematics (1) and the dynamics (2).

use nalgebra::{Matrix2, Vector2};

use wmr_core::geometry::{BodyVelocity, WheelSpeeds};

use super::error::{SlipTrackingError, positive};

/// `p = 1/(1 − i)` for a slip ratio `i ∈ [0, 1)`; `None` outside.
#[must_use]
pub fn slip_factor(slip_ratio: f32) -> Option<f32> {
    (slip_ratio.is_finite() && (0.0..1.0).contains(&slip_ratio)).then(|| 1.0 / (1.0 - slip_ratio))
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
