//! # Prediction (every tick)
//! The odometry step, with the wheel travels scaled by `(1 + ε̂)`, gives
//! `(Δs, Δθ)` and moves the pose along an exact arc,
//! `p⁺ = p + Δs sinc(Δθ/2) (cos m, sin m)`, `θ⁺ = θ + Δθ`, `m = θ + Δθ/2`
//! (as [`crate::geometry::Pose::advance_arc`]), with Jacobian
//! `F = I + [[0, 0, −c sin m], [0, 0, c cos m], [0, 0, 0]]`,
//! `c = Δs sinc(Δθ/2)`. Each wheel's travel `s_R, s_L` carries independent
//! noise of variance `α|s| + σ₀²` (slip and wheel-radius error grow with the
//! distance driven; `σ₀` is the count quantization), mapped into the state
//! through `∂(p, θ)/∂(s_R, s_L)`: `P⁺ = F P Fᵀ + G Σ Gᵀ`, where `F` also
//! carries `∂(p, θ)/∂ε` and `ε`'s own random walk adds its variance per
//! metre driven.

use nalgebra::{Matrix2, Matrix3x2, Vector2};

use crate::estimation::fusion::config::PoseFilterConfig;
use crate::estimation::fusion::gate::{PoseCovariance, PoseState};
use crate::math;
use crate::odometry::OdometryStep;

/// The odometry step through the wheel-scale estimate, and its
/// linearisation at a state (module docs, "Prediction").
pub(crate) struct OdometryLinearisation {
    /// The state after the step.
    pub(crate) state: PoseState,
    /// `F = ∂x⁺/∂x`.
    pub(crate) jacobian: PoseCovariance,
    /// `G Σ Gᵀ` plus the scale errors' random walk.
    pub(crate) process_noise: PoseCovariance,
}

/// Each wheel's travel `(s_R, s_L)` for an odometry step `(Δs, Δθ)` on a
/// track `b`: `Δs ± Δθ b/2`.
pub(crate) fn wheel_travels(ds_m: f32, dtheta_rad: f32, track_width_m: f32) -> (f32, f32) {
    (
        ds_m + 0.5 * dtheta_rad * track_width_m,
        ds_m - 0.5 * dtheta_rad * track_width_m,
    )
}

/// The pose `(x, y, θ)` of `state` moved along the exact arc of wheel
/// travels `(right, left)` (m) on a track `b`; the scale errors kept.
pub(crate) fn drive_wheels(
    state: &PoseState,
    right: f32,
    left: f32,
    track_width_m: f32,
) -> PoseState {
    let (ds, dth) = (0.5 * (right + left), (right - left) / track_width_m);
    let mid = state.z + 0.5 * dth;
    let chord = ds * math::sinc(0.5 * dth);
    let mut next = *state;
    let (sin_mid, cos_mid) = math::sincos(mid);
    next.x += chord * cos_mid;
    next.y += chord * sin_mid;
    next.z = math::wrap_angle(state.z + dth);
    next
}

/// The state after an odometry step, each wheel's nominal travel scaled
/// by its `(1 + ε)` and driven along the exact arc (the transition of the
/// UKF's sigma points and of the particle filter's noiseless particle; the
/// EKF computes the same move in [`linearise_odometry`], sharing its sines
/// with the Jacobian).
pub(crate) fn odometry_transition(
    state: &PoseState,
    odometry: &OdometryStep,
    track_width_m: f32,
) -> PoseState {
    let (right, left) = wheel_travels(odometry.ds_m, odometry.dtheta_rad, track_width_m);
    drive_wheels(
        state,
        right * (1.0 + state.w),
        left * (1.0 + state.a),
        track_width_m,
    )
}

/// The variance of a wheel's travel `s`: `α|s| + σ₀²`.
pub(crate) fn wheel_variance(config: &PoseFilterConfig, travel_m: f32) -> f32 {
    config.variance_per_m * travel_m.abs() + config.variance_floor_m2
}

/// The variance the scale error of a wheel that travelled `s` gains.
pub(crate) fn scale_walk_variance(config: &PoseFilterConfig, travel_m: f32) -> f32 {
    config.scale_walk_per_m * travel_m.abs()
}

/// The odometry step at `state`: the moved state, `F` and `G Σ Gᵀ` (module
/// docs, "Prediction").
pub(crate) fn linearise_odometry(
    config: &PoseFilterConfig,
    state: &PoseState,
    odometry: &OdometryStep,
) -> OdometryLinearisation {
    let b = config.track_width_m;
    let (theta, eps_r, eps_l) = (state.z, state.w, state.a);
    // Nominal wheel travels, then scaled by the estimated errors.
    let (nominal_r, nominal_l) = wheel_travels(odometry.ds_m, odometry.dtheta_rad, b);
    let (right, left) = (nominal_r * (1.0 + eps_r), nominal_l * (1.0 + eps_l));
    let (ds, dth) = (0.5 * (right + left), (right - left) / b);
    let mid = theta + 0.5 * dth;
    let (sin_m, cos_m) = math::sincos(mid);
    let chord = ds * math::sinc(0.5 * dth);
    let mut next = *state;
    next.x += chord * cos_m;
    next.y += chord * sin_m;
    next.z = math::wrap_angle(theta + dth);
    // ∂(x, y, θ)/∂(Δs, Δθ), then ∂(Δs, Δθ)/∂(s_R, s_L).
    let by_step = Matrix3x2::new(
        cos_m,
        -0.5 * chord * sin_m,
        sin_m,
        0.5 * chord * cos_m,
        0.0,
        1.0,
    );
    let by_wheels = by_step * Matrix2::new(0.5, 0.5, 1.0 / b, -1.0 / b);
    let mut jacobian = PoseCovariance::identity();
    jacobian
        .fixed_view_mut::<2, 1>(0, 2)
        .copy_from(&Vector2::new(-chord * sin_m, chord * cos_m));
    // ∂(x, y, θ)/∂ε = ∂/∂(s_R, s_L) · diag(nominal_r, nominal_l).
    let by_scale = by_wheels * Matrix2::new(nominal_r, 0.0, 0.0, nominal_l);
    jacobian.fixed_view_mut::<3, 2>(0, 3).copy_from(&by_scale);
    let noise = Matrix2::from_diagonal(&Vector2::new(
        wheel_variance(config, right),
        wheel_variance(config, left),
    ));
    let mut process_noise = PoseCovariance::zeros();
    process_noise
        .fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(by_wheels * noise * by_wheels.transpose()));
    process_noise
        .fixed_view_mut::<2, 2>(3, 3)
        .copy_from(&Matrix2::from_diagonal(&Vector2::new(
            scale_walk_variance(config, right),
            scale_walk_variance(config, left),
        )));
    OdometryLinearisation {
        state: next,
        jacobian,
        process_noise,
    }
}
