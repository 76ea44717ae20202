//! Which mission item the robot drives to and which it reached last,
//! from the route follower's status and the reference (the core's plan
//! does not number its segments by waypoint).
//!
//! A loaded route is the mission from item `base` on. Item `base` counts
//! as reached once that route has started and its clock has moved (the
//! start approach, where there is one, is over); each later item `i`, in
//! order, once the reference has come within the blend deviation (plus
//! [`REACH_MARGIN_M`]) of it and, for a stop, once the robot has settled
//! there (the follower's `stops_reached` has grown since item `i` became
//! current); the last item once the route is done.

use wmr_core::geometry::Vec2;
use wmr_core::pilot::route::RouteStatus;
use wmr_core::reference::route::Waypoints;

/// Added to the blend deviation: a corner's blend passes the corner at
/// the deviation, sampled once a tick.
pub const REACH_MARGIN_M: f32 = 0.005;

/// The mission's progress.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Progress {
    /// The item driven to.
    pub current: u16,
    /// The last item reached in this run.
    pub reached: Option<u16>,
    /// The loaded route's first item.
    base: u16,
    /// The follower's `routes_started` when the route was loaded.
    started_before: u32,
    /// The follower's `stops_reached` when `current` became current.
    stops_before: u32,
    /// Whether item `base` is still to be reached.
    base_pending: bool,
}

impl Progress {
    /// Nothing loaded: [`Progress::default`] as a constant.
    pub(crate) const NONE: Self = Self {
        current: 0,
        reached: None,
        base: 0,
        started_before: 0,
        stops_before: 0,
        base_pending: false,
    };

    /// A route loaded from item `base`; `base_pending`: item `base` is
    /// still to be reached (a start from item 0; otherwise the robot
    /// starts where it is, and drives to `base + 1`); `reached`: what
    /// this run reached before (kept on a continue); `started` and
    /// `stops`: the follower's counters now.
    #[must_use]
    pub fn loaded(
        base: u16,
        base_pending: bool,
        reached: Option<u16>,
        started: u32,
        stops: u32,
    ) -> Self {
        Self {
            current: if base_pending {
                base
            } else {
                base.saturating_add(1)
            },
            reached,
            base,
            started_before: started,
            stops_before: stops,
            base_pending,
        }
    }

    /// No route loaded, item `current` next.
    #[must_use]
    pub fn at(current: u16) -> Self {
        Self {
            current,
            ..Self::default()
        }
    }

    /// Updates after a tick: `reference` is the tick's reference,
    /// `deviation_m` the route's blend deviation.
    pub fn update(
        &mut self,
        mission: &Waypoints,
        status: &RouteStatus,
        started: u32,
        stops: u32,
        reference: Vec2,
        deviation_m: f32,
    ) {
        let items = mission.as_slice();
        let Some(last) = items.len().checked_sub(1) else {
            return;
        };
        let last = u16::try_from(last).unwrap_or(u16::MAX);
        if status.done && started > self.started_before {
            self.reach(last, stops);
            return;
        }
        if self.base_pending {
            if started > self.started_before && status.running && status.elapsed_ticks > 0 {
                self.base_pending = false;
                self.reach(self.base, stops);
            }
            return;
        }
        let Some(item) = items.get(usize::from(self.current)) else {
            return;
        };
        let near = (item.position_m - reference).norm() <= deviation_m + REACH_MARGIN_M;
        let settled = item.stop.is_none() || stops > self.stops_before;
        if self.current < last && near && settled {
            self.reach(self.current, stops);
        }
    }

    fn reach(&mut self, item: u16, stops: u32) {
        self.reached = Some(item);
        self.current = item.saturating_add(1);
        self.stops_before = stops;
    }

    /// Clamps `current` to the mission (after the last is reached it stays
    /// on the last).
    #[must_use]
    pub fn current_in(&self, count: u16) -> u16 {
        self.current.min(count.saturating_sub(1))
    }
}
