//! A local rig ticked one tick at a time by another module of this crate
//! (the SITL), its route's follower swappable between ticks.

use wmr_core::devices::RfidCounters;
use wmr_core::pilot::route::RouteFollower;
use wmr_core::pilot::tracker::TrackerCounters;
use wmr_core::pilot::tuning::{Tuning, TuningSpec};

use crate::report::Record;
use crate::scenario::Setup;

use super::rig::Rig;

/// A local rig (the core's tracker, `Pilot` or `Robot`, as `run` builds
/// it for `setup`).
pub(crate) struct Stepper(Rig<'static>);

impl Stepper {
    /// The rig `run` would build for `setup`.
    pub(crate) fn new(setup: &Setup) -> Self {
        Self(Rig::new(setup))
    }

    /// Tick `k` at `t_s`: the record of it.
    ///
    /// # Errors
    /// None on a local rig (the type is the remote rig's).
    pub(crate) fn tick(&mut self, k: u32, t_s: f64) -> anyhow::Result<Record> {
        self.0.tick(k, t_s)
    }

    /// The plant advances `dt_s` with what was commanded.
    pub(crate) fn advance(&mut self, dt_s: f64) {
        self.0.advance(dt_s);
    }

    /// The route's follower.
    pub(crate) fn route(&self) -> Option<&RouteFollower> {
        self.0.route()
    }

    /// The route's follower, mutable.
    pub(crate) fn route_mut(&mut self) -> Option<&mut RouteFollower> {
        self.0.route_mut()
    }

    /// Puts `follower` in place of the route's follower (module `rig`).
    pub(crate) fn swap_route(
        &mut self,
        follower: Box<RouteFollower>,
    ) -> Result<Option<Box<RouteFollower>>, Box<RouteFollower>> {
        self.0.swap_route(follower)
    }

    /// The gains and failsafe times the tracker runs with (module `rig`).
    pub(crate) fn tuning(&self) -> Option<TuningSpec> {
        self.0.tuning()
    }

    /// Takes `tuning` from the next tick on (module `rig`).
    pub(crate) fn retune(&mut self, tuning: &Tuning) -> bool {
        self.0.retune(tuning)
    }

    /// The tracker's and the reader's counters (module `rig`).
    pub(crate) fn counters(&self) -> Option<(TrackerCounters, Option<(RfidCounters, u32)>)> {
        self.0.counters()
    }
}
