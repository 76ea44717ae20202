//! The filter models of the paper's two scenarios (module docs of
//! [`super`], "Filter models"), for the core's EKF, particle filter and
//! UKF.

use nalgebra::{SMatrix, SVector};

use wmr_core::filters::ekf::EkfModel;
use wmr_core::filters::particle_filter::ParticleModel;
use wmr_core::filters::ukf::{AngleComponents, UkfModel, residual_with_angles};
use wmr_core::geometry::BodyVelocity;
use wmr_core::math;

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
