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

use crate::estimation::fusion::config::PoseFilterConfig;
use crate::estimation::fusion::gate::{PoseCovariance, PoseState};
use crate::math;
use crate::odometry::OdometryStep;

/// The odometry Jacobian `F = ∂x⁺/∂x` by its non-zero entries: `F` is the
/// identity but for the heading column `F[0..2, 2] = (−c sin m, c cos m)`
/// and the scale columns `F[0..3, 3..5] = ∂(x, y, θ)/∂(ε_R, ε_L)` (module
/// docs, "Prediction"). Five of its 25 entries are neither 0 nor 1, and
/// the EKF's predict multiplies by it without the zeros (`EkfCore`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct OdometryJacobian {
    /// `(F[0][2], F[1][2]) = (−c sin m, c cos m)`.
    pub(crate) heading: [f32; 2],
    /// Rows `x, y, θ` of `F[·][3..5]`: `∂(x, y, θ)/∂(ε_R, ε_L)`.
    pub(crate) scale: [[f32; 2]; 3],
}

/// The odometry step through the wheel-scale estimate, and its
/// linearisation at a state (module docs, "Prediction").
pub(crate) struct OdometryLinearisation {
    /// The state after the step.
    pub(crate) state: PoseState,
    /// `F = ∂x⁺/∂x`, by its non-zero entries.
    pub(crate) jacobian: OdometryJacobian,
    /// Rows `x, y, θ` of `G = ∂(x, y, θ)/∂(s_R, s_L)`.
    pub(crate) by_wheels: [[f32; 2]; 3],
    /// Each wheel's travel variance `Σ = diag(α|s_R| + σ₀², α|s_L| + σ₀²)`.
    pub(crate) wheel_variances: [f32; 2],
    /// The variances the scale errors `(ε_R, ε_L)` gain.
    pub(crate) scale_walk: [f32; 2],
}

impl OdometryLinearisation {
    /// The 3×3 block `G Σ Gᵀ` of the process noise, as rows:
    /// `(G Σ Gᵀ)_ij = (G_i0 Σ_R) G_j0 + (G_i1 Σ_L) G_j1` (the order of the
    /// dense matrix product, so that it rounds the same; so rounded it
    /// need not be symmetric to the bit).
    pub(crate) fn pose_noise(&self) -> [[f32; 3]; 3] {
        let [sigma_r, sigma_l] = self.wheel_variances;
        let weighted = self.by_wheels.map(|[r, l]| [r * sigma_r, l * sigma_l]);
        weighted.map(|[wr, wl]| self.by_wheels.map(|[r, l]| wr * r + wl * l))
    }

    /// The process noise as a matrix: `G Σ Gᵀ` in the pose block, the
    /// scale errors' random walk on the diagonal of the last two states.
    pub(crate) fn process_noise(&self) -> PoseCovariance {
        let mut q = PoseCovariance::zeros();
        for (row, values) in q.row_iter_mut().zip(self.pose_noise()) {
            for (entry, value) in row.into_iter().zip(values) {
                *entry = value;
            }
        }
        q.m44 = self.scale_walk[0];
        q.m55 = self.scale_walk[1];
        q
    }
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

/// The odometry step at `state`: the moved state, `F` and the parts of
/// `G Σ Gᵀ` (module docs, "Prediction").
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
    // ∂(x, y, θ)/∂(Δs, Δθ), rows x, y, θ.
    let by_step = [
        [cos_m, -0.5 * chord * sin_m],
        [sin_m, 0.5 * chord * cos_m],
        [0.0, 1.0],
    ];
    // G = ∂(x, y, θ)/∂(Δs, Δθ) · ∂(Δs, Δθ)/∂(s_R, s_L), the latter
    // [[1/2, 1/2], [1/b, −1/b]].
    let inverse_b = 1.0 / b;
    let by_wheels = by_step.map(|[s, t]| [s * 0.5 + t * inverse_b, s * 0.5 + t * -inverse_b]);
    // ∂(x, y, θ)/∂ε = G · diag(nominal_r, nominal_l).
    let scale = by_wheels.map(|[r, l]| [r * nominal_r, l * nominal_l]);
    OdometryLinearisation {
        state: next,
        jacobian: OdometryJacobian {
            heading: [-chord * sin_m, chord * cos_m],
            scale,
        },
        by_wheels,
        wheel_variances: [wheel_variance(config, right), wheel_variance(config, left)],
        scale_walk: [
            scale_walk_variance(config, right),
            scale_walk_variance(config, left),
        ],
    }
}
