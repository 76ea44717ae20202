//! Where a route lives on the target: its waypoints as they arrive and
//! the plan that checks them or the follower that follows them
//! ([`RouteStore`]), shared by the HIL session (a route over the link), the
//! Black Pill (a route in its robot image) and the MAVLink run (a mission
//! uploaded by a ground station).

use wmr_core::pilot::route::{RouteFollower, RouteOptions, RouteStart};
use wmr_core::reference::route::{ROUTE_CAPACITY, RouteLimits, RoutePlan, Waypoint, Waypoints};

use crate::route::CAPACITY_U8;
use crate::{RouteRefusal, RouteSpec};

/// Where a session's route lives (24.3 KB: keep it in a `static`): the
/// waypoints as they arrive, and one slot that holds either a scratch plan
/// (while a route is checked) or the follower the robot follows it with.
/// The check needs the plan only until the follower exists, so both share
/// the slot: the store is a plan smaller than a plan and a follower side
/// by side.
#[derive(Debug, Clone)]
pub struct RouteStore {
    /// The route's waypoints, loaded in place chunk by chunk.
    waypoints: Waypoints,
    /// The options of the route being loaded (its follower's).
    options: RouteOptions,
    /// The scratch plan or the follower.
    slot: Slot,
}

/// A [`RouteStore`]'s shared storage.
#[derive(Debug, Clone)]
// Both variants are about 20 KB, on purpose: one holds the other's place.
#[allow(clippy::large_enum_variant)]
enum Slot {
    /// Where a loaded route is planned once, to check it whole before the
    /// follower takes it (the follower plans it again, in its own plan,
    /// when it starts).
    Plan(RoutePlan),
    /// The follower of the last route checked.
    Follower(RouteFollower),
}

impl Default for RouteStore {
    fn default() -> Self {
        Self::new()
    }
}

impl RouteStore {
    /// Empty: no waypoints, an empty plan, no follower.
    #[must_use]
    pub fn new() -> Self {
        Self {
            waypoints: Waypoints::new(),
            options: RouteOptions::default(),
            slot: Slot::Plan(RoutePlan::empty()),
        }
    }

    /// The follower of the last route loaded (`None` before one, or while
    /// one is checked).
    #[must_use]
    pub fn follower(&self) -> Option<&RouteFollower> {
        match &self.slot {
            Slot::Follower(f) => Some(f),
            Slot::Plan(_) => None,
        }
    }

    /// The follower, to lend the robot's tick
    /// ([`wmr_core::pilot::robot::Robot::tick_on`]).
    pub fn follower_mut(&mut self) -> Option<&mut RouteFollower> {
        match &mut self.slot {
            Slot::Follower(f) => Some(f),
            Slot::Plan(_) => None,
        }
    }

    /// Starts loading the route `spec` announces: checks its count (2 to
    /// [`ROUTE_CAPACITY`]), its limits (`RouteLimits::new`) and its
    /// options (`RouteOptions::new`), its MAVLink endpoint settings
    /// (`EndpointConfig::new`) and empties the waypoints. Returns the
    /// validated limits, for [`Self::finish`].
    ///
    /// # Errors
    /// [`RouteRefusal::Size`], [`RouteRefusal::Limits`],
    /// [`RouteRefusal::Options`], [`RouteRefusal::Endpoint`]; nothing is
    /// changed then.
    pub fn begin(&mut self, spec: &RouteSpec) -> Result<RouteLimits, RouteRefusal> {
        if spec.waypoints < 2 || usize::from(spec.waypoints) > ROUTE_CAPACITY {
            return Err(RouteRefusal::Size {
                waypoints: spec.waypoints,
                capacity: CAPACITY_U8,
            });
        }
        let limits = RouteLimits::new(&spec.limits).map_err(RouteRefusal::Limits)?;
        let options = spec.options.build().map_err(RouteRefusal::Options)?;
        spec.mavlink.config()?;
        self.options = options;
        self.waypoints = Waypoints::new();
        Ok(limits)
    }

    /// Appends a waypoint of the route being loaded, in place.
    ///
    /// # Errors
    /// [`RouteRefusal::Route`] with `TooManyWaypoints` past
    /// [`ROUTE_CAPACITY`].
    pub fn push(&mut self, waypoint: Waypoint) -> Result<(), RouteRefusal> {
        self.waypoints.push(waypoint).map_err(RouteRefusal::Route)
    }

    /// Makes the follower a fresh one with no route, in place (the robot
    /// holds where it is); nothing before a follower exists.
    pub fn reset_follower(&mut self) {
        let options = self.options;
        if let Slot::Follower(f) = &mut self.slot {
            *f = RouteFollower::new(options);
        }
    }

    /// The waypoints loaded so far.
    #[must_use]
    pub fn waypoints(&self) -> &Waypoints {
        &self.waypoints
    }

    /// Ends loading: plans the waypoints once under `limits` at the
    /// control period `period_s` (`RoutePlan::replan`, in the slot) to
    /// check them whole, then makes the slot a new follower (with the
    /// options [`Self::begin`] checked) and loads them into it, to start
    /// as `start` says.
    ///
    /// # Errors
    /// [`RouteRefusal::Route`]: the planner's refusal, naming the waypoint
    /// and its key; there is then no follower.
    pub fn finish(
        &mut self,
        limits: &RouteLimits,
        start: RouteStart,
        period_s: f32,
    ) -> Result<(), RouteRefusal> {
        if let Slot::Follower(_) = self.slot {
            self.slot = Slot::Plan(RoutePlan::empty());
        }
        if let Slot::Plan(plan) = &mut self.slot {
            plan.replan(self.waypoints.as_slice(), limits, period_s)
                .map_err(RouteRefusal::Route)?;
        }
        self.slot = Slot::Follower(RouteFollower::new(self.options));
        if let Slot::Follower(follower) = &mut self.slot {
            follower.load(&self.waypoints, limits, start);
        }
        Ok(())
    }
}
