//! Plausible ranges of the physical quantities a configuration holds.
//!
//! Every constructor that takes a physical quantity checks it against its
//! range here, once, and refuses it with an error that names the key and
//! states the range. A range is generous (it admits every robot we know
//! of, from a 1 cm micro robot to a 10 m vehicle, and the papers'
//! simulations) but excludes values no robot has, which would otherwise
//! validate and then overflow: a control period of `3.4e38 s` puts the
//! reference at `t = inf` on the second tick, a tag spacing of `3e38 m`
//! puts a tag at `+inf`. With every quantity inside its range the
//! reference, the tag positions and the commands stay finite for the
//! whole `u32` tick count.
//!
//! | quantity | range | unit |
//! |---|---|---|
//! | control period `period_s` | [`PERIOD_S`] | s |
//! | wheel radius `wheel_radius_m` | [`WHEEL_RADIUS_M`] | m |
//! | track width `track_width_m` | [`TRACK_WIDTH_M`] | m |
//! | encoder counts per wheel revolution | [`COUNTS_PER_REV`] | counts |
//! | wheel speed limit `max_wheel_speed_rad_s` | [`WHEEL_SPEED_RAD_S`] | rad/s |
//! | wheel acceleration limit `max_wheel_accel_rad_s2` | [`WHEEL_ACCEL_RAD_S2`] | rad/s² |
//! | speed-loop gains (feed-forward, `kp`, `ki`) | [`SPEED_LOOP_GAIN`] | duty per rad/s, duty per rad |
//! | tracking, observer and law gains | [`GAIN`] | the gain's own unit |
//! | observer minimum speed `min_speed_m_s` | [`MIN_SPEED_M_S`] | m/s |
//! | failsafe deceleration `decel_m_s2` | [`DECEL_M_S2`] | m/s² |
//! | reference size (figure-eight `h1_m`, circle `radius_m`) | [`REFERENCE_SIZE_M`] | m |
//! | reference rate (figure-eight `h2_rad_s`, circle `\|rate_rad_s\|`) | [`REFERENCE_RATE_RAD_S`] | rad/s |
//! | reference speed (line `speed_m_s`) | [`REFERENCE_SPEED_M_S`] | m/s |
//! | floor coordinates (centre, start, grid origin), each axis | [`COORDINATE_M`] | m |
//! | angles (phase, direction) | [`ANGLE_RAD`] | rad |
//! | tag grid spacing `spacing_m` (and the sensors' `tag_spacing_m`) | [`TAG_SPACING_M`] | m |
//! | reader range `read_radius_m` | [`READ_RADIUS_M`] | m |
//! | robot mass `mass_kg` | [`MASS_KG`] | kg |
//! | yaw inertia `yaw_inertia_kg_m2` | [`YAW_INERTIA_KG_M2`] | kg m² |
//! | a wheel's drive-train inertia `wheel_inertia_kg_m2` | [`WHEEL_INERTIA_KG_M2`] | kg m² |
//! | motor stall torque at the wheel `stall_torque_nm` | [`TORQUE_NM`] | N·m |
//! | motor no-load wheel speed `no_load_speed_rad_s` | [`WHEEL_SPEED_RAD_S`] | rad/s |

/// A closed interval `[min, max]` of plausible values of one quantity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Range {
    /// The smallest plausible value.
    pub min: f32,
    /// The largest plausible value.
    pub max: f32,
}

impl Range {
    /// `[min, max]`.
    #[must_use]
    pub const fn new(min: f32, max: f32) -> Self {
        Self { min, max }
    }

    /// Whether `value` lies in the range (never for NaN).
    #[must_use]
    pub fn contains(&self, value: f32) -> bool {
        value >= self.min && value <= self.max
    }

    /// Whether `value` lies in the range symmetric to this one about zero
    /// as well (`|value|` in the range; never for NaN).
    #[must_use]
    pub fn contains_magnitude(&self, value: f32) -> bool {
        self.contains(value.abs())
    }
}

/// `[min, max]`, e.g. `[0.0001, 1]`.
impl core::fmt::Display for Range {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "[{}, {}]", self.min, self.max)
    }
}

/// Control period: 10 kHz to 1 Hz, s.
pub const PERIOD_S: Range = Range::new(1e-4, 1.0);
/// Wheel radius, m.
pub const WHEEL_RADIUS_M: Range = Range::new(1e-3, 2.0);
/// Distance between the wheels' contact points, m.
pub const TRACK_WIDTH_M: Range = Range::new(1e-2, 10.0);
/// Encoder counts per wheel revolution (after quadrature decoding): up to
/// `2^24`, so that the count is exact in `f32`.
pub const COUNTS_PER_REV: Range = Range::new(1.0, 16_777_216.0);
/// Wheel speed limit, rad/s (`1e4` rad/s is 95,000 rpm at the wheel).
pub const WHEEL_SPEED_RAD_S: Range = Range::new(1e-3, 1e4);
/// Wheel acceleration limit, rad/s².
pub const WHEEL_ACCEL_RAD_S2: Range = Range::new(1e-3, 1e6);
/// Speed-loop gains: feed-forward and proportional in duty per rad/s,
/// integral in duty per rad (a duty is in [-1, 1]).
pub const SPEED_LOOP_GAIN: Range = Range::new(0.0, 1e3);
/// A control or observer gain (tracking gains `k1, k2, k3`, the heading
/// observer's `L`, paper 002's observer and law gains), in its own unit.
pub const GAIN: Range = Range::new(1e-6, 1e4);
/// Speed below which paper 001's observer only rotates its estimate, m/s.
pub const MIN_SPEED_M_S: Range = Range::new(0.0, 10.0);
/// Failsafe deceleration, m/s².
pub const DECEL_M_S2: Range = Range::new(1e-3, 100.0);
/// Size of a reference curve (figure-eight half-width, circle radius), m.
pub const REFERENCE_SIZE_M: Range = Range::new(1e-3, 1e4);
/// Angular rate of a reference curve, rad/s (its magnitude, for a circle).
pub const REFERENCE_RATE_RAD_S: Range = Range::new(1e-6, 100.0);
/// Speed of a straight-line reference, m/s.
pub const REFERENCE_SPEED_M_S: Range = Range::new(1e-6, 100.0);
/// A floor coordinate (each axis of a centre, start point, grid origin), m:
/// `f32` still resolves 1 mm at 10 km.
pub const COORDINATE_M: Range = Range::new(-1e4, 1e4);
/// A phase or direction, rad.
pub const ANGLE_RAD: Range = Range::new(-1e3, 1e3);
/// Spacing of a floor's tag grid, m.
pub const TAG_SPACING_M: Range = Range::new(1e-2, 10.0);
/// A reader's range around its antenna, m (0: the nearest tag is read).
pub const READ_RADIUS_M: Range = Range::new(0.0, 1.0);
/// Robot mass, kg.
pub const MASS_KG: Range = Range::new(1e-3, 1e4);
/// Yaw inertia about the axle midpoint, kg m².
pub const YAW_INERTIA_KG_M2: Range = Range::new(1e-9, 1e4);
/// A wheel's drive-train inertia reflected to the wheel, kg m² (may be 0).
pub const WHEEL_INERTIA_KG_M2: Range = Range::new(0.0, 1e4);
/// Motor torque at the wheel, N·m.
pub const TORQUE_NM: Range = Range::new(1e-6, 1e4);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_range_holds_its_ends_and_nothing_else() {
        let r = Range::new(1e-4, 1.0);
        for inside in [1e-4, 0.01, 1.0] {
            assert!(r.contains(inside), "{inside}");
        }
        for outside in [
            0.0,
            9.99e-5,
            1.000_001,
            -0.01,
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            3.4e38,
        ] {
            assert!(!r.contains(outside), "{outside}");
        }
        assert!(r.contains_magnitude(-0.5) && !r.contains_magnitude(-2.0));
        assert!(!r.contains_magnitude(f32::NAN));
    }

    #[test]
    fn a_range_prints_its_ends() {
        assert_eq!(std::format!("{PERIOD_S}"), "[0.0001, 1]");
        assert_eq!(std::format!("{COORDINATE_M}"), "[-10000, 10000]");
    }
}
