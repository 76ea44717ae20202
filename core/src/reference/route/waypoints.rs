//! The route's input: waypoints (fixed capacity) and the limits the plan
//! obeys, each checked once.

use super::bounds::ROUTE_CAPACITY;
use super::error::{LimitKey, RouteError, RouteLimitsError, WaypointKey};
use crate::geometry::Vec2;
use crate::math;
use crate::plausible::{ANGLE_RAD, COORDINATE_M};

/// A stop at a waypoint: the reference comes to rest there.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Stop {
    /// Time at rest (after any pivot to the heading to face), s, `≥ 0`.
    pub dwell_s: f32,
    /// Heading to face while stopped, rad, counter-clockwise from the floor's
    /// +x axis (the crate's convention, [`crate::geometry`]); any value in
    /// [`ANGLE_RAD`], wrapped to (−π, π]. `None`: keep the arrival heading.
    pub face_heading_rad: Option<f32>,
}

/// One waypoint of a route.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Waypoint {
    /// Position in the floor frame `(x, y)`, m.
    pub position_m: Vec2,
    /// A stop here, or `None` to drive through (a corner blend). The last
    /// waypoint is always a stop (`None` there means a dwell of 0 s).
    pub stop: Option<Stop>,
    /// Speed limit of the leg that ends at this waypoint, m/s (`None`: the
    /// route's `max_speed_m_s`); ignored on the first waypoint.
    pub speed_limit_m_s: Option<f32>,
}

impl Waypoint {
    /// A waypoint driven through, at `(x_m, y_m)`.
    #[must_use]
    pub const fn pass(x_m: f32, y_m: f32) -> Self {
        Self {
            position_m: Vec2::new(x_m, y_m),
            stop: None,
            speed_limit_m_s: None,
        }
    }

    /// A stop at `(x_m, y_m)` for `dwell_s` seconds, keeping the arrival
    /// heading.
    #[must_use]
    pub const fn stop(x_m: f32, y_m: f32, dwell_s: f32) -> Self {
        Self {
            position_m: Vec2::new(x_m, y_m),
            stop: Some(Stop {
                dwell_s,
                face_heading_rad: None,
            }),
            speed_limit_m_s: None,
        }
    }

    /// The same waypoint, a stop (of 0 s if it was not one) facing
    /// `heading_rad` (rad, counter-clockwise from +x) while stopped.
    #[must_use]
    pub const fn facing(mut self, heading_rad: f32) -> Self {
        let dwell_s = match self.stop {
            Some(stop) => stop.dwell_s,
            None => 0.0,
        };
        self.stop = Some(Stop {
            dwell_s,
            face_heading_rad: Some(heading_rad),
        });
        self
    }

    /// The same waypoint with a speed limit, m/s, on the leg that ends here.
    #[must_use]
    pub const fn with_speed_limit(mut self, speed_limit_m_s: f32) -> Self {
        self.speed_limit_m_s = Some(speed_limit_m_s);
        self
    }
}

/// Up to [`ROUTE_CAPACITY`] waypoints, in a fixed array (no heap).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Waypoints {
    items: [Waypoint; ROUTE_CAPACITY],
    len: usize,
}

impl Default for Waypoints {
    fn default() -> Self {
        Self::new()
    }
}

impl Waypoints {
    /// No waypoints.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            items: [Self::UNUSED; ROUTE_CAPACITY],
            len: 0,
        }
    }

    /// What the slots past the length hold (never read): a stop at the
    /// origin for 0 s, keeping its heading, whose bits are all zero (a
    /// pass's `None` stop is a non-zero niche), so that a route is built
    /// by clearing memory, and one in a `static` lands in `.bss`.
    const UNUSED: Waypoint = Waypoint::stop(0.0, 0.0, 0.0);

    /// The waypoints of a slice.
    ///
    /// # Errors
    /// [`RouteError::TooManyWaypoints`] for more than [`ROUTE_CAPACITY`].
    pub fn from_slice(waypoints: &[Waypoint]) -> Result<Self, RouteError> {
        let mut out = Self::new();
        for w in waypoints {
            out.push(*w)?;
        }
        Ok(out)
    }

    /// Appends a waypoint (checked when the route is planned).
    ///
    /// # Errors
    /// [`RouteError::TooManyWaypoints`] when full.
    pub fn push(&mut self, waypoint: Waypoint) -> Result<(), RouteError> {
        let slot = self
            .items
            .get_mut(self.len)
            .ok_or(RouteError::TooManyWaypoints)?;
        *slot = waypoint;
        self.len += 1;
        Ok(())
    }

    /// The waypoints held.
    #[must_use]
    pub fn as_slice(&self) -> &[Waypoint] {
        self.items.get(..self.len).unwrap_or(&[])
    }

    /// The waypoints held, to change in place (e.g. a route that starts
    /// where the robot is: its first position replaced).
    pub fn as_mut_slice(&mut self) -> &mut [Waypoint] {
        self.items.get_mut(..self.len).unwrap_or(&mut [])
    }

    /// Removes every waypoint, in place (a route rebuilt where it lives,
    /// not built on the stack and copied).
    pub fn clear(&mut self) {
        self.len = 0;
    }

    /// How many.
    #[must_use]
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether there are none.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

/// Checks every waypoint's values on their own (not the geometry between
/// them, which the planner checks).
pub(super) fn check_waypoints(waypoints: &[Waypoint]) -> Result<(), RouteError> {
    if waypoints.len() > ROUTE_CAPACITY {
        return Err(RouteError::TooManyWaypoints);
    }
    if waypoints.len() < 2 {
        return Err(RouteError::TooFewWaypoints);
    }
    let mut previous: Option<Vec2> = None;
    for (i, w) in waypoints.iter().enumerate() {
        // Capacity 64: the index fits in a u8.
        let index = u8::try_from(i).unwrap_or(u8::MAX);
        let p = w.position_m;
        if !p.is_finite() {
            return Err(RouteError::NotFinite {
                index,
                key: WaypointKey::Position,
            });
        }
        if !(COORDINATE_M.contains(p.x) && COORDINATE_M.contains(p.y)) {
            return Err(RouteError::OutOfRange {
                index,
                key: WaypointKey::Position,
            });
        }
        if previous == Some(p) {
            return Err(RouteError::SameAsPrevious { index });
        }
        previous = Some(p);
        if let Some(stop) = w.stop {
            if !stop.dwell_s.is_finite() {
                return Err(RouteError::NotFinite {
                    index,
                    key: WaypointKey::Dwell,
                });
            }
            if stop.dwell_s < 0.0 {
                return Err(RouteError::NegativeDwell { index });
            }
            if let Some(h) = stop.face_heading_rad {
                if !h.is_finite() {
                    return Err(RouteError::NotFinite {
                        index,
                        key: WaypointKey::FaceHeading,
                    });
                }
                if !ANGLE_RAD.contains(h) {
                    return Err(RouteError::OutOfRange {
                        index,
                        key: WaypointKey::FaceHeading,
                    });
                }
            }
        }
        if let Some(v) = w.speed_limit_m_s {
            if !v.is_finite() {
                return Err(RouteError::NotFinite {
                    index,
                    key: WaypointKey::SpeedLimit,
                });
            }
            if v <= 0.0 {
                return Err(RouteError::SpeedLimit { index });
            }
        }
    }
    Ok(())
}

/// The limits a route's plan obeys, each finite and positive (the pivot
/// threshold in `[0, π]`). Built by [`RouteLimits::new`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RouteLimits {
    max_speed_m_s: f32,
    max_tangential_accel_m_s2: f32,
    max_lateral_accel_m_s2: f32,
    blend_deviation_m: f32,
    pivot_threshold_rad: f32,
    pivot_rate_rad_s: f32,
    pivot_accel_rad_s2: f32,
}

/// [`RouteLimits`] as plain numbers, SI units in the names.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct RouteLimitsSpec {
    /// Largest reference speed, m/s.
    pub max_speed_m_s: f32,
    /// Largest tangential acceleration (and deceleration) `|v̇_r|`, m/s².
    pub max_tangential_accel_m_s2: f32,
    /// Largest lateral acceleration `v_r² κ` on the corner blends, m/s².
    pub max_lateral_accel_m_s2: f32,
    /// Distance from a corner waypoint to its blend (the blend's closest
    /// point to the corner, its largest deviation from the polyline), m.
    pub blend_deviation_m: f32,
    /// At a stop, a direction change larger than this (rad, in `[0, π]`) is
    /// turned in place (a pivot) before the next leg.
    pub pivot_threshold_rad: f32,
    /// Largest angular rate of a pivot, rad/s.
    pub pivot_rate_rad_s: f32,
    /// Largest angular acceleration of a pivot, rad/s².
    pub pivot_accel_rad_s2: f32,
}

impl RouteLimits {
    /// Every limit 0: not a valid limit set ([`Self::new`] refuses it).
    /// A placeholder, all zero bits, in a structure built by clearing
    /// memory (a `static`) that is given its limits before it plans or
    /// loads a route; a route must never be planned with it.
    pub const BLANK: Self = Self {
        max_speed_m_s: 0.0,
        max_tangential_accel_m_s2: 0.0,
        max_lateral_accel_m_s2: 0.0,
        blend_deviation_m: 0.0,
        pivot_threshold_rad: 0.0,
        pivot_rate_rad_s: 0.0,
        pivot_accel_rad_s2: 0.0,
    };

    /// The validated limits.
    ///
    /// # Errors
    /// [`RouteLimitsError`] naming the first field that is not finite or
    /// out of its range.
    pub fn new(spec: &RouteLimitsSpec) -> Result<Self, RouteLimitsError> {
        let positive = |v: f32, key: LimitKey| {
            if v.is_finite() && v > 0.0 {
                Ok(v)
            } else {
                Err(RouteLimitsError(key))
            }
        };
        let threshold = spec.pivot_threshold_rad;
        if !(threshold.is_finite() && (0.0..=math::PI).contains(&threshold)) {
            return Err(RouteLimitsError(LimitKey::PivotThreshold));
        }
        Ok(Self {
            max_speed_m_s: positive(spec.max_speed_m_s, LimitKey::MaxSpeed)?,
            max_tangential_accel_m_s2: positive(
                spec.max_tangential_accel_m_s2,
                LimitKey::MaxTangentialAccel,
            )?,
            max_lateral_accel_m_s2: positive(
                spec.max_lateral_accel_m_s2,
                LimitKey::MaxLateralAccel,
            )?,
            blend_deviation_m: positive(spec.blend_deviation_m, LimitKey::BlendDeviation)?,
            pivot_threshold_rad: threshold,
            pivot_rate_rad_s: positive(spec.pivot_rate_rad_s, LimitKey::PivotRate)?,
            pivot_accel_rad_s2: positive(spec.pivot_accel_rad_s2, LimitKey::PivotAccel)?,
        })
    }

    /// Largest reference speed, m/s.
    #[must_use]
    pub fn max_speed_m_s(&self) -> f32 {
        self.max_speed_m_s
    }
    /// Largest tangential acceleration, m/s².
    #[must_use]
    pub fn max_tangential_accel_m_s2(&self) -> f32 {
        self.max_tangential_accel_m_s2
    }
    /// Largest lateral acceleration on the blends, m/s².
    #[must_use]
    pub fn max_lateral_accel_m_s2(&self) -> f32 {
        self.max_lateral_accel_m_s2
    }
    /// Distance from a corner waypoint to its blend, m.
    #[must_use]
    pub fn blend_deviation_m(&self) -> f32 {
        self.blend_deviation_m
    }
    /// Direction change at a stop above which the reference pivots, rad.
    #[must_use]
    pub fn pivot_threshold_rad(&self) -> f32 {
        self.pivot_threshold_rad
    }
    /// Largest pivot rate, rad/s.
    #[must_use]
    pub fn pivot_rate_rad_s(&self) -> f32 {
        self.pivot_rate_rad_s
    }
    /// Largest pivot angular acceleration, rad/s².
    #[must_use]
    pub fn pivot_accel_rad_s2(&self) -> f32 {
        self.pivot_accel_rad_s2
    }
}
