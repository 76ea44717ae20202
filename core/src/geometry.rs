//! Planar vectors and poses, differential-drive geometry, wheel ↔ body speeds.
//!
//! Frames and units: the world frame is the floor's (x east, y north, in
//! metres; the RFID tag map uses it); headings `θ` are measured from the
//! world x axis, counter-clockwise positive, in radians. Wheel speeds are
//! angular speeds of the wheels in rad/s, positive when the wheel drives the
//! robot forward.

use crate::math;
use crate::plausible::{COUNTS_PER_REV, TRACK_WIDTH_M, WHEEL_RADIUS_M};

/// A planar vector in metres (or m/s, m/s², as the field it sits in says).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Vec2 {
    /// x component.
    pub x: f32,
    /// y component.
    pub y: f32,
}

impl Vec2 {
    /// The zero vector.
    pub const ZERO: Self = Self { x: 0.0, y: 0.0 };

    /// A vector from its components.
    #[must_use]
    pub const fn new(x: f32, y: f32) -> Self {
        Self { x, y }
    }

    /// Euclidean length.
    #[must_use]
    pub fn norm(self) -> f32 {
        math::hypot(self.x, self.y)
    }

    /// The dot product `self·other`.
    #[must_use]
    pub fn dot(self, other: Self) -> f32 {
        self.x * other.x + self.y * other.y
    }

    /// Both components finite.
    #[must_use]
    pub fn is_finite(self) -> bool {
        self.x.is_finite() && self.y.is_finite()
    }

    /// Rotates counter-clockwise by the angle whose cosine and sine are given.
    #[must_use]
    pub fn rotated(self, cos_a: f32, sin_a: f32) -> Self {
        Self {
            x: cos_a * self.x - sin_a * self.y,
            y: sin_a * self.x + cos_a * self.y,
        }
    }

    /// Scales both components.
    #[must_use]
    pub fn scaled(self, k: f32) -> Self {
        Self {
            x: k * self.x,
            y: k * self.y,
        }
    }
}

impl core::ops::Add for Vec2 {
    type Output = Self;
    fn add(self, rhs: Self) -> Self {
        Self::new(self.x + rhs.x, self.y + rhs.y)
    }
}

impl core::ops::Sub for Vec2 {
    type Output = Self;
    fn sub(self, rhs: Self) -> Self {
        Self::new(self.x - rhs.x, self.y - rhs.y)
    }
}

/// A robot pose: position in metres, heading in radians (world frame).
///
/// The heading is kept as integrated (not wrapped) by [`Pose::advance_arc`],
/// so that a plant's heading history is continuous; wrap it with
/// [`math::wrap_angle`] where a principal value is needed.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Pose {
    /// Position of the axle midpoint, m.
    pub position: Vec2,
    /// Heading, rad, counter-clockwise from the world x axis.
    pub heading_rad: f32,
}

impl Pose {
    /// A pose from its components.
    #[must_use]
    pub const fn new(x_m: f32, y_m: f32, heading_rad: f32) -> Self {
        Self {
            position: Vec2::new(x_m, y_m),
            heading_rad,
        }
    }

    /// The pose after driving an arc of length `ds_m` while turning by
    /// `dtheta_rad` (exact for constant `v`, `ω` over the step).
    ///
    /// Exact-arc integration of the unicycle (paper 001, eq. (1)):
    /// `Δp = ds · sinc(Δθ/2) · (cos(θ + Δθ/2), sin(θ + Δθ/2))`, which has no
    /// singularity at `Δθ = 0` (straight line).
    #[must_use]
    pub fn advance_arc(self, ds_m: f32, dtheta_rad: f32) -> Self {
        let chord = ds_m * math::sinc(0.5 * dtheta_rad);
        let mid = self.heading_rad + 0.5 * dtheta_rad;
        let (sin_mid, cos_mid) = math::sincos(mid);
        Self {
            position: Vec2::new(
                self.position.x + chord * cos_mid,
                self.position.y + chord * sin_mid,
            ),
            heading_rad: self.heading_rad + dtheta_rad,
        }
    }
}

/// Body velocity of a unicycle-like robot.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BodyVelocity {
    /// Forward speed of the axle midpoint, m/s.
    pub v_m_s: f32,
    /// Yaw rate, rad/s, counter-clockwise positive.
    pub omega_rad_s: f32,
}

impl BodyVelocity {
    /// Standing still.
    pub const ZERO: Self = Self {
        v_m_s: 0.0,
        omega_rad_s: 0.0,
    };

    /// Both components finite.
    #[must_use]
    pub fn is_finite(self) -> bool {
        self.v_m_s.is_finite() && self.omega_rad_s.is_finite()
    }
}

/// Angular speeds of the two wheels, rad/s, positive driving forward.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WheelSpeeds {
    /// Left wheel, rad/s.
    pub left_rad_s: f32,
    /// Right wheel, rad/s.
    pub right_rad_s: f32,
}

impl WheelSpeeds {
    /// Both wheels at rest.
    pub const ZERO: Self = Self {
        left_rad_s: 0.0,
        right_rad_s: 0.0,
    };

    /// Both components finite.
    #[must_use]
    pub fn is_finite(self) -> bool {
        self.left_rad_s.is_finite() && self.right_rad_s.is_finite()
    }
}

/// Why a [`DiffDriveGeometry`] was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum GeometryError {
    /// Wheel radius outside [`WHEEL_RADIUS_M`].
    WheelRadius,
    /// Track width (distance between wheel contact points) outside
    /// [`TRACK_WIDTH_M`].
    TrackWidth,
    /// Encoder counts per wheel revolution outside [`COUNTS_PER_REV`].
    CountsPerRevolution,
}

impl core::fmt::Display for GeometryError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::WheelRadius => write!(f, "wheel_radius_m must be in {WHEEL_RADIUS_M} m"),
            Self::TrackWidth => write!(f, "track_width_m must be in {TRACK_WIDTH_M} m"),
            Self::CountsPerRevolution => {
                write!(f, "encoder_counts_per_rev must be in {COUNTS_PER_REV}")
            }
        }
    }
}

impl core::error::Error for GeometryError {}

/// Dimensions of a differential-drive robot and its encoders.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DiffDriveGeometry {
    wheel_radius_m: f32,
    track_width_m: f32,
    counts_per_revolution: u32,
    rad_per_count: f32,
}

impl DiffDriveGeometry {
    /// Validates the dimensions.
    ///
    /// `counts_per_revolution` is in quadrature counts at the wheel (i.e.
    /// after any gearbox and the ×4 of quadrature decoding).
    ///
    /// # Errors
    /// The first parameter outside its plausible range ([`crate::plausible`]).
    pub fn new(
        wheel_radius_m: f32,
        track_width_m: f32,
        counts_per_revolution: u32,
    ) -> Result<Self, GeometryError> {
        if !WHEEL_RADIUS_M.contains(wheel_radius_m) {
            return Err(GeometryError::WheelRadius);
        }
        if !TRACK_WIDTH_M.contains(track_width_m) {
            return Err(GeometryError::TrackWidth);
        }
        if !COUNTS_PER_REV.contains(counts_per_revolution as f32) {
            return Err(GeometryError::CountsPerRevolution);
        }
        Ok(Self {
            wheel_radius_m,
            track_width_m,
            counts_per_revolution,
            rad_per_count: math::TAU / counts_per_revolution as f32,
        })
    }

    /// Wheel radius, m.
    #[must_use]
    pub fn wheel_radius_m(&self) -> f32 {
        self.wheel_radius_m
    }

    /// Track width, m.
    #[must_use]
    pub fn track_width_m(&self) -> f32 {
        self.track_width_m
    }

    /// Encoder counts per wheel revolution.
    #[must_use]
    pub fn counts_per_revolution(&self) -> u32 {
        self.counts_per_revolution
    }

    /// Wheel rotation per encoder count, rad.
    #[must_use]
    pub fn rad_per_count(&self) -> f32 {
        self.rad_per_count
    }

    /// Body velocity from wheel speeds: `v = r(ω_R + ω_L)/2`, `ω = r(ω_R − ω_L)/b`.
    #[must_use]
    pub fn body_from_wheels(&self, wheels: WheelSpeeds) -> BodyVelocity {
        let r = self.wheel_radius_m;
        BodyVelocity {
            v_m_s: 0.5 * r * (wheels.right_rad_s + wheels.left_rad_s),
            omega_rad_s: r * (wheels.right_rad_s - wheels.left_rad_s) / self.track_width_m,
        }
    }

    /// Wheel speeds for a body velocity (inverse of [`Self::body_from_wheels`]).
    #[must_use]
    pub fn wheels_from_body(&self, body: BodyVelocity) -> WheelSpeeds {
        let half_turn = 0.5 * self.track_width_m * body.omega_rad_s;
        WheelSpeeds {
            left_rad_s: (body.v_m_s - half_turn) / self.wheel_radius_m,
            right_rad_s: (body.v_m_s + half_turn) / self.wheel_radius_m,
        }
    }
}

/// An estimate `(ĉ, ŝ)` of `(cos θ, sin θ)`: the heading as every estimator
/// gives it and every law reads it (paper 001's observer state `(ẑ3, ẑ4)`).
///
/// Not normalised: its length tends to 1 as the observer converges, and a
/// length far from 1 says the estimate is not yet trustworthy.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct HeadingEstimate {
    /// `ẑ3`, estimate of `cos θ`.
    pub cos_theta: f32,
    /// `ẑ4`, estimate of `sin θ`.
    pub sin_theta: f32,
}

impl HeadingEstimate {
    /// `θ̂ = atan2(ẑ4, ẑ3)` (11), in [−π, π]; 0 while the estimate is (0, 0).
    #[must_use]
    pub fn heading_rad(&self) -> f32 {
        math::atan2(self.sin_theta, self.cos_theta)
    }

    /// `V_o = ½|z − ẑ|²` for a known true heading (the paper's Lyapunov function (9)).
    #[must_use]
    pub fn lyapunov(&self, true_heading_rad: f32) -> f32 {
        let ec = math::cos(true_heading_rad) - self.cos_theta;
        let es = math::sin(true_heading_rad) - self.sin_theta;
        0.5 * (ec * ec + es * es)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn construction_names_the_bad_parameter() {
        assert_eq!(
            DiffDriveGeometry::new(0.0, 0.3, 1024),
            Err(GeometryError::WheelRadius)
        );
        assert_eq!(
            DiffDriveGeometry::new(0.03, f32::NAN, 1024),
            Err(GeometryError::TrackWidth)
        );
        assert_eq!(
            DiffDriveGeometry::new(0.03, 0.3, 0),
            Err(GeometryError::CountsPerRevolution)
        );
    }

    #[test]
    fn wheel_body_round_trip() {
        let g = DiffDriveGeometry::new(0.035, 0.25, 4096).unwrap();
        let body = BodyVelocity {
            v_m_s: 0.3,
            omega_rad_s: -0.7,
        };
        let back = g.body_from_wheels(g.wheels_from_body(body));
        assert!((back.v_m_s - 0.3).abs() < 1e-6);
        assert!((back.omega_rad_s + 0.7).abs() < 1e-6);
    }

    #[test]
    fn arc_closes_a_circle() {
        // Quarter turns of a unit circle, four of them, end where they began.
        let mut pose = Pose::new(1.0, 0.0, math::PI / 2.0);
        for _ in 0..4 {
            pose = pose.advance_arc(math::PI / 2.0, math::PI / 2.0);
        }
        assert!((pose.position.x - 1.0).abs() < 1e-5);
        assert!(pose.position.y.abs() < 1e-5);
    }
}
