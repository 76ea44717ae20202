//! Why a route's limits or waypoints were refused.

use super::bounds::{MAX_ROUTE_TICKS, ROUTE_CAPACITY};
use crate::plausible::{ANGLE_RAD, COORDINATE_M, PERIOD_S};

/// A field of [`super::RouteLimits`], as its error names it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum LimitKey {
    /// `max_speed_m_s`.
    MaxSpeed,
    /// `max_tangential_accel_m_s2`.
    MaxTangentialAccel,
    /// `max_lateral_accel_m_s2`.
    MaxLateralAccel,
    /// `blend_deviation_m`.
    BlendDeviation,
    /// `pivot_threshold_rad`.
    PivotThreshold,
    /// `pivot_rate_rad_s`.
    PivotRate,
    /// `pivot_accel_rad_s2`.
    PivotAccel,
}

impl LimitKey {
    /// The field's name, with its unit.
    #[must_use]
    pub fn key(self) -> &'static str {
        match self {
            Self::MaxSpeed => "max_speed_m_s",
            Self::MaxTangentialAccel => "max_tangential_accel_m_s2",
            Self::MaxLateralAccel => "max_lateral_accel_m_s2",
            Self::BlendDeviation => "blend_deviation_m",
            Self::PivotThreshold => "pivot_threshold_rad",
            Self::PivotRate => "pivot_rate_rad_s",
            Self::PivotAccel => "pivot_accel_rad_s2",
        }
    }
}

/// A field of a [`super::Waypoint`], as its error names it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum WaypointKey {
    /// `position_m`.
    Position,
    /// `stop.dwell_s`.
    Dwell,
    /// `stop.face_heading_rad`.
    FaceHeading,
    /// `speed_limit_m_s`.
    SpeedLimit,
}

impl WaypointKey {
    /// The field's name, with its unit.
    #[must_use]
    pub fn key(self) -> &'static str {
        match self {
            Self::Position => "position_m",
            Self::Dwell => "stop.dwell_s",
            Self::FaceHeading => "stop.face_heading_rad",
            Self::SpeedLimit => "speed_limit_m_s",
        }
    }
}

/// Why [`super::RouteLimits::new`] refused a limit: the field named is not
/// finite or is out of its range (every rate and acceleration `> 0`, the
/// blend deviation `> 0`, the pivot threshold in `[0, π]`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct RouteLimitsError(pub LimitKey);

impl core::fmt::Display for RouteLimitsError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self.0 {
            LimitKey::PivotThreshold => write!(f, "pivot_threshold_rad must be in [0, π]"),
            key => write!(f, "{} must be finite and > 0", key.key()),
        }
    }
}

impl core::error::Error for RouteLimitsError {}

/// Why a route was refused ([`super::RoutePlan::new`],
/// [`super::Waypoints::push`]). `index` is the waypoint's, from 0.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum RouteError {
    /// Fewer than two waypoints.
    TooFewWaypoints,
    /// More than [`super::ROUTE_CAPACITY`] waypoints.
    TooManyWaypoints,
    /// The control period outside [`PERIOD_S`].
    Period,
    /// A value that is NaN or infinite.
    NotFinite {
        /// The waypoint.
        index: u8,
        /// Its field.
        key: WaypointKey,
    },
    /// A position outside [`COORDINATE_M`] on an axis, or a heading to
    /// face outside [`ANGLE_RAD`].
    OutOfRange {
        /// The waypoint.
        index: u8,
        /// Its field.
        key: WaypointKey,
    },
    /// The waypoint is at the same position as the one before it.
    SameAsPrevious {
        /// The waypoint.
        index: u8,
    },
    /// A stop's dwell below 0 s.
    NegativeDwell {
        /// The waypoint.
        index: u8,
    },
    /// A leg's speed limit `≤ 0`.
    SpeedLimit {
        /// The waypoint that ends the leg.
        index: u8,
    },
    /// The corner blend at this waypoint, with the deviation
    /// `blend_deviation_m`, is longer than its legs allow (with the blends
    /// of the neighbouring corners), or the turn is a reversal.
    BlendDoesNotFit {
        /// The corner's waypoint.
        index: u8,
    },
    /// The route lasts more than [`super::MAX_ROUTE_TICKS`] ticks.
    TooLong,
}

impl core::fmt::Display for RouteError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::TooFewWaypoints => write!(f, "a route needs at least two waypoints"),
            Self::TooManyWaypoints => {
                write!(f, "a route holds at most {} waypoints", ROUTE_CAPACITY)
            }
            Self::Period => write!(f, "period_s must be in {PERIOD_S} s"),
            Self::NotFinite { index, key } => {
                write!(f, "waypoint {index}: {} must be finite", key.key())
            }
            Self::OutOfRange { index, key } => write!(
                f,
                "waypoint {index}: {} must be in {} on each axis (m) or in {} (rad)",
                key.key(),
                COORDINATE_M,
                ANGLE_RAD
            ),
            Self::SameAsPrevious { index } => write!(
                f,
                "waypoint {index}: position_m equals the previous waypoint's"
            ),
            Self::NegativeDwell { index } => {
                write!(f, "waypoint {index}: stop.dwell_s must be >= 0")
            }
            Self::SpeedLimit { index } => {
                write!(f, "waypoint {index}: speed_limit_m_s must be > 0")
            }
            Self::BlendDoesNotFit { index } => write!(
                f,
                "waypoint {index}: the corner blend does not fit its legs with \
                 blend_deviation_m (lower it, move the waypoints apart, or make it a stop)"
            ),
            Self::TooLong => write!(f, "the route lasts more than {} ticks", MAX_ROUTE_TICKS),
        }
    }
}

impl core::error::Error for RouteError {}
