//! The path's pieces: straight lines and symmetric clothoid-pair corner
//! blends (see the module docs of [`super`] for the method).
//!
//! A blend of a corner turning by `δ` (signed, `σ = sign δ`,
//! `φ = |δ|/2`) is two clothoids of length `L` each. Along the first, at
//! `r = s/L ∈ [0, 1]`, the tangent turns by `σ φ r²` and the curvature is
//! `κ = σ 2φ r / L`; the second is the first mirrored about the corner's
//! bisector. In the frame of the incoming leg (x along it, y to the turn's
//! side) the first clothoid's point at `r` is `L (C(φ, r), S(φ, r))`, with
//! the generalised Fresnel integrals
//!
//! `C(φ, r) = ∫₀ʳ cos(φ w²) dw`, `S(φ, r) = ∫₀ʳ sin(φ w²) dw`,
//!
//! evaluated by their power series in `x = φ r² ≤ π/2`
//! (`C = r Σ (−1)ⁿ x²ⁿ / ((2n)! (4n+1))`, `S = r x Σ (−1)ⁿ x²ⁿ /
//! ((2n+1)! (4n+3))`), 7 and 6 terms, whose first omitted terms are below
//! 2e-10 and 2e-9 at `x = π/2`: under `f32` resolution, in `f32`, with no
//! call. The blend's midpoint is `L (C₁, S₁)` (`C₁ = C(φ, 1)`), so its
//! distance to the corner (the blend's closest point to it, and its largest
//! deviation from the polyline) is `e = L S₁ / cos φ`, and it starts at
//! `T = L (C₁ + S₁ tan φ)` before the corner.

use crate::geometry::Vec2;
use crate::math;

/// A turn smaller than this, rad, is driven straight through without a
/// blend: the reference's direction then jumps by at most this angle, its
/// velocity by `v · 1e-4`. Waypoints on one line computed in `f32` turn by
/// a few 1e-7 rad.
pub const STRAIGHT_THROUGH_RAD: f32 = 1e-4;

/// A turn larger than this, rad (177.6°), is a reversal: refused as a
/// corner (make the waypoint a stop, where the reference pivots).
pub const MAX_CORNER_TURN_RAD: f32 = 3.1;

/// `C(φ, r)` and `S(φ, r)` (see the module docs), for `φ ∈ [0, π/2]`,
/// `r ∈ [0, 1]`: 13 multiply–adds.
#[must_use]
pub fn fresnel(phi: f32, r: f32) -> (f32, f32) {
    let x = phi * r * r;
    let y = x * x;
    // C: (−1)ⁿ / ((2n)! (4n+1)), n = 0..6.
    let c = 1.0
        - y * (1.0 / 10.0
            - y * (1.0 / 216.0
                - y * (1.0 / 9_360.0
                    - y * (1.0 / 685_440.0 - y * (1.0 / 76_204_800.0 - y / 1.197_504e10)))));
    // S: (−1)ⁿ / ((2n+1)! (4n+3)), n = 0..5.
    let s = 1.0 / 3.0
        - y * (1.0 / 42.0
            - y * (1.0 / 1_320.0
                - y * (1.0 / 75_600.0 - y * (1.0 / 6_894_720.0 - y / 918_086_400.0))));
    (r * c, r * x * s)
}

/// One corner's blend, designed from the legs' directions and the
/// deviation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Blend {
    /// Length of each of the two clothoids, m.
    pub half_length_m: f32,
    /// Half the turn, `φ = |δ|/2`, rad.
    pub half_turn_rad: f32,
    /// `+1` for a left (counter-clockwise) turn, `−1` for a right one.
    pub sign: f32,
    /// Distance along each leg from the corner to the blend's end, m.
    pub tangent_m: f32,
    /// Curvature at the blend's midpoint, its largest, 1/m.
    pub peak_curvature_per_m: f32,
}

/// What a corner needs: nothing (straight through), a blend, or a refusal
/// (a reversal, or a degenerate blend).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Corner {
    /// The turn is below [`STRAIGHT_THROUGH_RAD`].
    Straight,
    /// A blend.
    Blend(Blend),
    /// The turn is above [`MAX_CORNER_TURN_RAD`], or the blend is not finite.
    Refused,
}

/// The blend of a corner between legs of unit directions `u_in`, `u_out`,
/// at the distance `deviation_m` from the corner.
#[must_use]
pub fn design_corner(u_in: Vec2, u_out: Vec2, deviation_m: f32) -> Corner {
    let cross = u_in.x * u_out.y - u_in.y * u_out.x;
    let dot = u_in.x * u_out.x + u_in.y * u_out.y;
    let turn = math::atan2(cross, dot);
    if !turn.is_finite() {
        return Corner::Refused;
    }
    if turn.abs() < STRAIGHT_THROUGH_RAD {
        return Corner::Straight;
    }
    if turn.abs() > MAX_CORNER_TURN_RAD {
        return Corner::Refused;
    }
    let phi = 0.5 * turn.abs();
    let (c1, s1) = fresnel(phi, 1.0);
    let (sin_phi, cos_phi) = math::sincos(phi);
    // φ ∈ [5e-5, 1.55]: S₁ ≥ φ/3·0.9 > 0 and cos φ ≥ 0.02.
    let half_length_m = deviation_m * cos_phi / s1;
    let tangent_m = half_length_m * c1 + deviation_m * sin_phi;
    let peak = 2.0 * phi / half_length_m;
    if !(half_length_m > 0.0 && tangent_m.is_finite() && peak.is_finite()) {
        return Corner::Refused;
    }
    Corner::Blend(Blend {
        half_length_m,
        half_turn_rad: phi,
        sign: if turn > 0.0 { 1.0 } else { -1.0 },
        tangent_m,
        peak_curvature_per_m: peak,
    })
}

/// Point offset, unit tangent and curvature at arc length `s_m` along the
/// blend's first clothoid (which starts at the incoming leg's end, heading
/// `dir`), relative to its start.
#[must_use]
pub fn entering(dir: Vec2, half_length_m: f32, phi: f32, sign: f32, s_m: f32) -> (Vec2, Vec2, f32) {
    let r = math::clamp_or(s_m / half_length_m, 0.0, 1.0, 0.0);
    let (c, s) = fresnel(phi, r);
    let offset = Vec2::new(c, sign * s)
        .rotated(dir.x, dir.y)
        .scaled(half_length_m);
    let (sa, ca) = math::sincos(sign * phi * r * r);
    let tangent = Vec2::new(ca, sa).rotated(dir.x, dir.y);
    (offset, tangent, sign * 2.0 * phi * r / half_length_m)
}

/// Point offset (from the blend's end, which heads `dir` along the
/// outgoing leg), unit tangent and curvature at arc length `s_m` along the
/// blend's second clothoid.
#[must_use]
pub fn leaving(dir: Vec2, half_length_m: f32, phi: f32, sign: f32, s_m: f32) -> (Vec2, Vec2, f32) {
    let r = math::clamp_or((half_length_m - s_m) / half_length_m, 0.0, 1.0, 0.0);
    let (c, s) = fresnel(phi, r);
    let offset = Vec2::new(-c, sign * s)
        .rotated(dir.x, dir.y)
        .scaled(half_length_m);
    let (sa, ca) = math::sincos(-sign * phi * r * r);
    let tangent = Vec2::new(ca, sa).rotated(dir.x, dir.y);
    (offset, tangent, sign * 2.0 * phi * r / half_length_m)
}
