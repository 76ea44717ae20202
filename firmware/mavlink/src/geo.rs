//! The floor frame against MAVLink's local NED and global frames.
//!
//! # Floor ↔ NED
//!
//! The floor frame is taken as ENU, the convention of ROS (REP 103) and of
//! mavros's ENU↔NED conversion: floor +x = east, floor +y = north, up out
//! of the floor. So `north = y_floor`, `east = x_floor`, `down = 0`, and a
//! floor heading `ψ` (counter-clockwise from +x, rad) is the MAVLink yaw
//! `π/2 − ψ` (clockwise from north), wrapped to (−π, π].
//!
//! # Global ↔ floor
//!
//! Through a geodetic origin (the floor's (0, 0), latitude and longitude
//! in 1e-7 degree integers as MAVLink carries them): the differences are
//! taken in integers (exact; the longitude difference wrapped across the
//! antimeridian), then scaled in `f32` by the WGS-84 radii of curvature at
//! the origin (meridional `M`, prime vertical `N`), with the longitude
//! scaled by the cosine of the mid-latitude of the origin and the point:
//! an equirectangular local tangent plane. A 1e-7 degree step is 1.1 cm
//! north; differences up to 2²⁴ units (1.68 degrees, ~186 km) are exact
//! in `f32`, far beyond the floor's ±1e4 m. The plane's error against the
//! ellipsoid grows as `(d/R)²`: below 1 mm within 1 km of the origin and
//! about 2.5 cm at 10 km.

use wmr_core::math;

/// WGS-84 semi-major axis, m.
const WGS84_A_M: f32 = 6_378_137.0;
/// WGS-84 first eccentricity squared.
const WGS84_E2: f32 = 6.694_38e-3;
/// Radians per 1e-7 degree.
const RAD_PER_E7: f32 = math::PI / 180.0 * 1e-7;

/// A floor heading (rad, counter-clockwise from +x) as a MAVLink yaw (rad,
/// clockwise from north).
#[must_use]
pub fn heading_to_yaw(heading_rad: f32) -> f32 {
    mirror(heading_rad)
}

/// A MAVLink yaw (rad, clockwise from north) as a floor heading.
#[must_use]
pub fn yaw_to_heading(yaw_rad: f32) -> f32 {
    mirror(yaw_rad)
}

/// The angle mirrored about the diagonal between +x and north, π/2 − a,
/// wrapped: the same map both ways between a heading and a yaw.
// Out of line: inlined at each of its three callers it cost flash.
#[inline(never)]
fn mirror(angle_rad: f32) -> f32 {
    math::wrap_angle(math::PI / 2.0 - angle_rad)
}

/// Floor `(x, y)` from NED `(north, east)`, m.
#[must_use]
pub fn ned_to_floor(north_m: f32, east_m: f32) -> (f32, f32) {
    (east_m, north_m)
}

/// NED `(north, east)` from floor `(x, y)`, m.
#[must_use]
pub fn floor_to_ned(x_m: f32, y_m: f32) -> (f32, f32) {
    (y_m, x_m)
}

/// The floor's geodetic origin, with its local radii.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Origin {
    lat_e7: i32,
    lon_e7: i32,
    /// Metres north per 1e-7 degree of latitude.
    north_m_per_e7: f32,
    /// Metres east per 1e-7 degree of longitude on the equator of the
    /// prime vertical (times the mid-latitude's cosine).
    east_m_per_e7: f32,
}

impl Origin {
    /// The origin at `lat_e7`, `lon_e7` (1e-7 degrees; checked by the
    /// configuration: |latitude| ≤ 85°, |longitude| ≤ 180°).
    #[must_use]
    pub fn new(lat_e7: i32, lon_e7: i32) -> Self {
        let phi = lat_e7 as f32 * RAD_PER_E7;
        let s = math::sin(phi);
        let w2 = 1.0 - WGS84_E2 * s * s;
        let w = math::sqrt(w2);
        let meridional = WGS84_A_M * (1.0 - WGS84_E2) / (w2 * w);
        let prime = WGS84_A_M / w;
        Self {
            lat_e7,
            lon_e7,
            north_m_per_e7: meridional * RAD_PER_E7,
            east_m_per_e7: prime * RAD_PER_E7,
        }
    }

    /// Latitude, 1e-7 degree.
    #[must_use]
    pub fn lat_e7(&self) -> i32 {
        self.lat_e7
    }

    /// Longitude, 1e-7 degree.
    #[must_use]
    pub fn lon_e7(&self) -> i32 {
        self.lon_e7
    }

    // Out of line: inlined into both conversions it cost flash.
    #[inline(never)]
    fn cos_mid(&self, dlat_e7: i64) -> f32 {
        let mid = (i64::from(self.lat_e7) + dlat_e7 / 2) as f32 * RAD_PER_E7;
        math::cos(mid)
    }

    /// Floor `(x, y)`, m, of a point at `lat_e7`, `lon_e7`.
    #[must_use]
    pub fn to_floor(&self, lat_e7: i32, lon_e7: i32) -> (f32, f32) {
        let dlat = i64::from(lat_e7) - i64::from(self.lat_e7);
        let mut dlon = i64::from(lon_e7) - i64::from(self.lon_e7);
        if dlon > 1_800_000_000 {
            dlon -= 3_600_000_000;
        } else if dlon < -1_800_000_000 {
            dlon += 3_600_000_000;
        }
        let north = dlat as f32 * self.north_m_per_e7;
        let east = dlon as f32 * self.east_m_per_e7 * self.cos_mid(dlat);
        ned_to_floor(north, east)
    }

    /// Latitude and longitude, 1e-7 degree, of floor `(x, y)`, m
    /// (saturated to the integer range for a non-finite or huge input).
    #[must_use]
    pub fn to_global(&self, x_m: f32, y_m: f32) -> (i32, i32) {
        let (north, east) = floor_to_ned(x_m, y_m);
        let dlat = libm::roundf(north / self.north_m_per_e7) as i64;
        let cos = self.cos_mid(dlat);
        let dlon = if cos > 0.0 {
            libm::roundf(east / (self.east_m_per_e7 * cos)) as i64
        } else {
            0
        };
        let lat = (i64::from(self.lat_e7) + dlat).clamp(-900_000_000, 900_000_000);
        let mut lon = i64::from(self.lon_e7) + dlon;
        if lon > 1_800_000_000 {
            lon -= 3_600_000_000;
        } else if lon < -1_800_000_000 {
            lon += 3_600_000_000;
        }
        (lat as i32, lon.clamp(-1_800_000_000, 1_800_000_000) as i32)
    }
}
