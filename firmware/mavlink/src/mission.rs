//! Mission items as received, their checks, and their route.
//!
//! An item is kept as the ground station sent it (frame, integer x/y), so
//! that a download returns what was uploaded; the route
//! ([`Mission::waypoints`]) is computed from it.
//!
//! Only `MAV_CMD_NAV_WAYPOINT` is supported: `param1` = hold time, s (the
//! stop's dwell), `param4` = yaw, degrees clockwise from north (the
//! heading to face while stopped; NaN = none). An item with a hold time
//! `> 0` or a yaw is a stop; otherwise it is driven through (a corner
//! blend). `param2` (acceptance radius) and `param3` (pass radius) are
//! ignored: the route's geometry decides. `z` must be finite and is
//! ignored (the robot stays on the floor).

use mavlink::dialects::common::{MavCmd, MavFrame, MavMissionResult};
use wmr_core::math;
use wmr_core::reference::route::{
    ROUTE_CAPACITY, RouteError, Stop, Waypoint, WaypointKey, Waypoints,
};

use crate::geo::{self, Origin};

const FRAME_GLOBAL: u8 = MavFrame::MAV_FRAME_GLOBAL as u8;
const FRAME_LOCAL_NED: u8 = MavFrame::MAV_FRAME_LOCAL_NED as u8;
const FRAME_GLOBAL_RELATIVE_ALT: u8 = MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT as u8;
const FRAME_GLOBAL_INT: u8 = 5;
const FRAME_GLOBAL_RELATIVE_ALT_INT: u8 = 6;
const NAV_WAYPOINT: u16 = MavCmd::MAV_CMD_NAV_WAYPOINT as u16;

/// One mission item as received: a `MAV_CMD_NAV_WAYPOINT`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Item {
    /// `MAV_FRAME` value.
    pub frame: u8,
    /// Hold time, s (`param1`).
    pub hold_s: f32,
    /// Yaw, degrees (`param4`), NaN = none.
    pub yaw_deg: f32,
    /// x as `MISSION_ITEM_INT` carries it: 1e-4 m (local), 1e-7 degree
    /// of latitude (global).
    pub x: i32,
    /// y, likewise (east 1e-4 m, or longitude 1e-7 degree).
    pub y: i32,
    /// z, m (ignored).
    pub z: f32,
}

impl Item {
    /// A slot past the mission's length (never read). All zero bits, so
    /// that a mission is built by clearing its memory: a slot with a NaN
    /// yaw made the compiler keep a 1.5 KB copy of the 64 empty slots in
    /// flash to build a mission from.
    const EMPTY: Self = Self {
        frame: 0,
        hold_s: 0.0,
        yaw_deg: 0.0,
        x: 0,
        y: 0,
        z: 0.0,
    };

    /// Whether the frame is a global one (x, y in 1e-7 degrees).
    #[must_use]
    pub fn is_global(&self) -> bool {
        is_global(self.frame)
    }
}

fn is_global(frame: u8) -> bool {
    matches!(
        frame,
        FRAME_GLOBAL | FRAME_GLOBAL_RELATIVE_ALT | FRAME_GLOBAL_INT | FRAME_GLOBAL_RELATIVE_ALT_INT
    )
}

/// The fields of a received item, before its checks.
#[derive(Debug, Clone, Copy)]
pub struct RawItem {
    /// `MAV_CMD` value.
    pub command: u16,
    /// `MAV_FRAME` value.
    pub frame: u8,
    /// `param1`..`param4`.
    pub params: [f32; 4],
    /// x: integer (`MISSION_ITEM_INT`) or float (`MISSION_ITEM`).
    pub x: Coord,
    /// y, likewise.
    pub y: Coord,
    /// z.
    pub z: f32,
}

/// A coordinate as sent.
#[derive(Debug, Clone, Copy)]
pub enum Coord {
    /// `MISSION_ITEM_INT`: 1e-4 m (local) or 1e-7 degree (global).
    Int(i32),
    /// `MISSION_ITEM`: m (local) or degrees (global).
    Float(f32),
}

impl Coord {
    /// As the integer of `MISSION_ITEM_INT`; `None` if not finite or
    /// beyond `limit` (in the float's unit).
    fn to_int(self, global: bool, limit: f32) -> Option<i32> {
        match self {
            Coord::Int(v) => Some(v),
            Coord::Float(v) => {
                if !v.is_finite() || v.abs() > limit {
                    return None;
                }
                let scale = if global { 1e7 } else { 1e4 };
                Some(libm::roundf(v * scale) as i32)
            }
        }
    }
}

/// Checks one received item (command, frame, parameters, coordinates)
/// and keeps it as an [`Item`], or says which `MAV_MISSION_RESULT` refuses
/// it.
///
/// # Errors
/// `MAV_MISSION_UNSUPPORTED` (a command other than `NAV_WAYPOINT`),
/// `MAV_MISSION_UNSUPPORTED_FRAME` (not local NED or a global frame, or a
/// global frame with no origin configured), `MAV_MISSION_INVALID_PARAM1`
/// (hold time NaN, infinite or negative), `_PARAM4` (yaw infinite),
/// `_PARAM5_X` / `_PARAM6_Y` (NaN, infinite, or beyond ±1e5 m or the
/// globe), `_PARAM7` (z not finite).
pub fn check_item(raw: &RawItem, has_origin: bool) -> Result<Item, MavMissionResult> {
    if raw.command != NAV_WAYPOINT {
        return Err(MavMissionResult::MAV_MISSION_UNSUPPORTED);
    }
    let global = is_global(raw.frame);
    if !(global || raw.frame == FRAME_LOCAL_NED) || (global && !has_origin) {
        return Err(MavMissionResult::MAV_MISSION_UNSUPPORTED_FRAME);
    }
    let [hold_s, _, _, yaw_deg] = raw.params;
    if !(hold_s.is_finite() && hold_s >= 0.0) {
        return Err(MavMissionResult::MAV_MISSION_INVALID_PARAM1);
    }
    if yaw_deg.is_infinite() {
        return Err(MavMissionResult::MAV_MISSION_INVALID_PARAM4);
    }
    let (x_limit, y_limit) = if global { (90.0, 180.0) } else { (1e5, 1e5) };
    let x = raw
        .x
        .to_int(global, x_limit)
        .ok_or(MavMissionResult::MAV_MISSION_INVALID_PARAM5_X)?;
    let y = raw
        .y
        .to_int(global, y_limit)
        .ok_or(MavMissionResult::MAV_MISSION_INVALID_PARAM6_Y)?;
    if !raw.z.is_finite() {
        return Err(MavMissionResult::MAV_MISSION_INVALID_PARAM7);
    }
    Ok(Item {
        frame: raw.frame,
        hold_s,
        yaw_deg,
        x,
        y,
        z: raw.z,
    })
}

/// The `MAV_MISSION_RESULT` closest to a route the core refuses.
#[must_use]
pub fn route_refusal(error: RouteError) -> MavMissionResult {
    match error {
        RouteError::TooManyWaypoints => MavMissionResult::MAV_MISSION_NO_SPACE,
        RouteError::NotFinite { key, .. } | RouteError::OutOfRange { key, .. } => match key {
            WaypointKey::Position => MavMissionResult::MAV_MISSION_INVALID_PARAM5_X,
            WaypointKey::Dwell => MavMissionResult::MAV_MISSION_INVALID_PARAM1,
            WaypointKey::FaceHeading => MavMissionResult::MAV_MISSION_INVALID_PARAM4,
            WaypointKey::SpeedLimit => MavMissionResult::MAV_MISSION_INVALID,
        },
        RouteError::NegativeDwell { .. } => MavMissionResult::MAV_MISSION_INVALID_PARAM1,
        RouteError::TooFewWaypoints
        | RouteError::Period
        | RouteError::SameAsPrevious { .. }
        | RouteError::SpeedLimit { .. }
        | RouteError::BlendDoesNotFit { .. }
        | RouteError::TooLong => MavMissionResult::MAV_MISSION_INVALID,
    }
}

/// Up to [`ROUTE_CAPACITY`] items.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mission {
    items: [Item; ROUTE_CAPACITY],
    len: u16,
}

impl Default for Mission {
    fn default() -> Self {
        Self::new()
    }
}

impl Mission {
    /// No items.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            items: [Item::EMPTY; ROUTE_CAPACITY],
            len: 0,
        }
    }

    /// How many items.
    #[must_use]
    pub fn len(&self) -> u16 {
        self.len
    }

    /// Whether there are none.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Removes every item.
    pub fn clear(&mut self) {
        self.len = 0;
    }

    /// Item `seq`, if held.
    #[must_use]
    pub fn get(&self, seq: u16) -> Option<&Item> {
        if seq < self.len {
            self.items.get(usize::from(seq))
        } else {
            None
        }
    }

    /// Appends an item; `false` when full.
    pub fn push(&mut self, item: Item) -> bool {
        match self.items.get_mut(usize::from(self.len)) {
            Some(slot) => {
                *slot = item;
                self.len += 1;
                true
            }
            None => false,
        }
    }

    /// The route of the items: floor positions through the frame mapping
    /// (`origin` for the global frames), stops from hold time and yaw.
    /// Items in a global frame without an origin (refused on upload) are
    /// placed at a NaN position, which the core refuses.
    #[must_use]
    pub fn waypoints(&self, origin: Option<&Origin>) -> Waypoints {
        let mut out = Waypoints::new();
        self.write_waypoints(origin, &mut out);
        out
    }

    /// [`Self::waypoints`] written into `out` in place (its waypoints
    /// replaced): a caller with little stack keeps the route where it
    /// lives.
    pub fn write_waypoints(&self, origin: Option<&Origin>, out: &mut Waypoints) {
        out.clear();
        for item in self.items.iter().take(usize::from(self.len)) {
            let (x_m, y_m) = if item.is_global() {
                match origin {
                    Some(o) => o.to_floor(item.x, item.y),
                    None => (f32::NAN, f32::NAN),
                }
            } else {
                geo::ned_to_floor(item.x as f32 * 1e-4, item.y as f32 * 1e-4)
            };
            let face_heading_rad = if item.yaw_deg.is_nan() {
                None
            } else {
                Some(geo::yaw_to_heading(item.yaw_deg * (math::PI / 180.0)))
            };
            let stop = if item.hold_s > 0.0 || face_heading_rad.is_some() {
                Some(Stop {
                    dwell_s: item.hold_s,
                    face_heading_rad,
                })
            } else {
                None
            };
            let waypoint = Waypoint {
                position_m: wmr_core::geometry::Vec2::new(x_m, y_m),
                stop,
                speed_limit_m_s: None,
            };
            // At most ROUTE_CAPACITY items: the push cannot fail.
            let _ = out.push(waypoint);
        }
    }
}
