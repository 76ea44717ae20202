//! Component-wise helpers on the state vectors that every part of the
//! filter shares: finiteness and sign checks, and the wrapping of angle
//! components.

use nalgebra::SVector;

use crate::math;

/// Wraps the components of `x` flagged in `angles` to (−π, π].
// Always inlined: as a call it cost the N = 5 predicts 0.9–1.7 % on the
// Cortex-M4 (`cargo xtask bench-target`); inlined, the counts are unchanged.
#[inline(always)]
pub(super) fn wrap_angles<const N: usize>(x: &mut SVector<f32, N>, angles: &[bool; N]) {
    for (value, &angle) in x.iter_mut().zip(angles.iter()) {
        if angle {
            *value = math::wrap_angle(*value);
        }
    }
}

/// `true` if every entry is finite and `≥ 0`.
pub(super) fn non_negative<const K: usize>(v: &SVector<f32, K>) -> bool {
    v.iter().all(|&s| s.is_finite() && s >= 0.0)
}

/// `true` if every entry is finite.
pub(super) fn finite<const K: usize>(v: &SVector<f32, K>) -> bool {
    v.iter().all(|s| s.is_finite())
}
