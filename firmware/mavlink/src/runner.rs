//! The robot's side of a mission: armed or not, its [`RobotMode`], the
//! running mission, which item a start drives from, and the progress
//! through it ([`crate::progress`]), driven by the endpoint's [`Event`]s
//! at tick boundaries. The SITL (`firmware-sim sitl`) and the firmware's
//! HIL session run the same runner.
//!
//! The runner does not own the robot's route follower (a
//! [`RouteFollower`] is about 22 KB and lives where its owner keeps it: a
//! `Box`, a `static`): [`MissionRunner::apply`] says what the owner must
//! do to it ([`FollowerAction`]), [`MissionRunner::load`] loads a route
//! into it, and [`MissionRunner::after_tick`] reads its status and
//! counters after each tick.
//!
//! The robot holds (stops and stays) by following a fresh follower with
//! no route: the core's follower then ramps the command to zero at the
//! tracker's failsafe deceleration where the robot is and holds it at
//! exactly zero, motors halted (`wmr_core::pilot::route`, "Refused"):
//! pause, emergency stop, link loss, disarm and a cleared mission all
//! stop that way. A start or a continue loads the mission from the
//! current item into a fresh follower: from item 0 as given (the robot is
//! first driven onto item 0; the very first start uses the robot's own
//! first start, e.g. a known heading at a station), from item `k ≥ 1` as
//! the mission from `k − 1` with its first waypoint replaced by where the
//! robot is ([`RouteStart::FromFirstFix`]). A mission uploaded while the
//! robot drives replaces the running route by the core's rule: at the
//! running route's next rest, from the rest point.
//!
//! What the runner did is returned as a [`Note`] (the SITL writes it to
//! its log); it formats nothing itself.

use wmr_core::geometry::Vec2;
use wmr_core::pilot::route::{RouteCounters, RouteFollower, RouteStart, RouteStatus};
use wmr_core::reference::route::{RouteLimits, Waypoints};

use crate::endpoint::{Estimate, Event, RobotMode, RobotView};
use crate::progress::Progress;

/// What the owner of the route follower must do after an event.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FollowerAction {
    /// Nothing.
    Keep,
    /// Replace the follower by a fresh one with no route (with the same
    /// options): the robot stops and holds where it is.
    Hold,
    /// Load the runner's mission into the running follower as given
    /// ([`MissionRunner::load`]): it replaces the running route at its
    /// next rest.
    Replace,
    /// Replace the follower by a fresh one and load the mission from item
    /// `base` into it with `start` ([`MissionRunner::load`]).
    Run {
        /// The route's first item.
        base: u16,
        /// How the route starts.
        start: RouteStart,
    },
}

/// What the runner did, for a log.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Note {
    /// A mission of this many items was loaded (not running).
    MissionLoaded(u16),
    /// A mission of this many items replaces the running route at its
    /// next rest.
    MissionReplaces(u16),
    /// The mission was cleared; holding.
    Cleared,
    /// Armed.
    Armed,
    /// Disarmed; holding.
    Disarmed,
    /// Started (`resume` false) or continued (true) from item `from`.
    Started {
        /// The item driven from.
        from: u16,
        /// A continue after a pause.
        resume: bool,
    },
    /// Paused; holding.
    Paused,
    /// Emergency stop: stopped until disarmed and re-armed.
    EmergencyStop,
    /// The link was lost while driving or paused: stopped.
    LinkLostStopped,
    /// The link was lost while not driving.
    LinkLost,
    /// The route limits changed: the next route is planned with them.
    RouteLimits,
    /// Gains or failsafe times set: the robot takes them from its next
    /// tick (its owner's `Pilot::retune`).
    Tuning,
}

/// What one event did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Applied {
    /// What the owner must do to its follower.
    pub action: FollowerAction,
    /// What happened, where something did.
    pub note: Option<Note>,
}

impl Applied {
    const fn new(action: FollowerAction, note: Option<Note>) -> Self {
        Self { action, note }
    }
}

/// The robot's mission state (module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct MissionRunner {
    /// The robot's start for its first route from item 0.
    first_start: RouteStart,
    started_once: bool,
    armed: bool,
    mode: RobotMode,
    mission: Waypoints,
    limits: RouteLimits,
    /// The running route's blend deviation, m.
    deviation_m: f32,
    progress: Progress,
    /// A SetCurrent came after the last Done (a Start then starts there,
    /// not at item 0).
    current_set: bool,
    /// Where a route from a later item is built for [`Self::load`], in
    /// place (not on the stack).
    route: Waypoints,
}

impl MissionRunner {
    /// Disarmed, idle, no mission, every field zero: for a `static` built
    /// by clearing memory (it lands in `.bss`), given its route limits by
    /// [`Self::reset_running`] or [`Self::reset_waiting`] before any
    /// other call. Until then its route limits are 0
    /// ([`RouteLimits::BLANK`]): it must not load a follower.
    pub const BLANK: Self = Self {
        first_start: RouteStart::AsGiven,
        started_once: false,
        armed: false,
        mode: RobotMode::Idle,
        mission: Waypoints::new(),
        limits: RouteLimits::BLANK,
        deviation_m: 0.0,
        progress: Progress::NONE,
        current_set: false,
        route: Waypoints::new(),
    };

    /// Disarmed, idle, with no mission; `first_start` is how the first
    /// route from item 0 starts, `limits` the route limits until an event
    /// brings others.
    #[must_use]
    pub fn new(first_start: RouteStart, limits: RouteLimits) -> Self {
        Self {
            first_start,
            limits,
            deviation_m: limits.blend_deviation_m(),
            ..Self::BLANK
        }
    }

    /// Armed and running `mission` from item 0, as started with
    /// `start`: a robot whose route runs from power-on. The owner's
    /// follower is loaded with it already (nothing to do).
    #[must_use]
    pub fn running(mission: &Waypoints, start: RouteStart, limits: RouteLimits) -> Self {
        let mut runner = Self::new(start, limits);
        runner.reset_running(mission, start, limits);
        runner
    }

    /// As [`Self::running`], in place (a runner that lives in a `static`;
    /// no runner is built on the stack).
    pub fn reset_running(&mut self, mission: &Waypoints, start: RouteStart, limits: RouteLimits) {
        self.first_start = start;
        self.started_once = true;
        self.armed = true;
        self.mode = RobotMode::Running;
        self.mission.clone_from(mission);
        self.limits = limits;
        self.deviation_m = limits.blend_deviation_m();
        self.progress = Progress::loaded(0, true, None, 0, 0);
        self.current_set = false;
        self.route.clear();
    }

    /// Disarmed, idle, with `mission` loaded (not running), in place: a
    /// robot that waits at power-on for a ground station to arm and start
    /// it. Its first start from item 0 starts as `start` says. The
    /// owner's follower must hold (no route).
    pub fn reset_waiting(&mut self, mission: &Waypoints, start: RouteStart, limits: RouteLimits) {
        self.first_start = start;
        self.started_once = false;
        self.armed = false;
        self.mode = RobotMode::Idle;
        self.mission.clone_from(mission);
        self.limits = limits;
        self.deviation_m = limits.blend_deviation_m();
        self.progress = Progress::default();
        self.current_set = false;
        self.route.clear();
    }

    /// The mode.
    #[must_use]
    pub fn mode(&self) -> RobotMode {
        self.mode
    }

    /// Armed.
    #[must_use]
    pub fn armed(&self) -> bool {
        self.armed
    }

    /// The route limits the next route is planned with.
    #[must_use]
    pub fn limits(&self) -> RouteLimits {
        self.limits
    }

    /// The mission.
    #[must_use]
    pub fn mission(&self) -> &Waypoints {
        &self.mission
    }

    /// The progress through the mission.
    #[must_use]
    pub fn progress(&self) -> Progress {
        self.progress
    }

    /// What the robot reports to the endpoint, with its estimate.
    #[must_use]
    pub fn view(&self, estimate: Option<Estimate>) -> RobotView {
        RobotView {
            armed: self.armed,
            mode: self.mode,
            estimate,
            current: self.progress.current_in(self.count()),
            reached: self.progress.reached,
        }
    }

    fn count(&self) -> u16 {
        u16::try_from(self.mission.len()).unwrap_or(u16::MAX)
    }

    /// Applies one of the endpoint's events. `mission` is the endpoint's
    /// running mission as a route, `limits` its route limits now,
    /// `counters` the follower's counters now.
    pub fn apply(
        &mut self,
        event: Event,
        mission: &Waypoints,
        limits: RouteLimits,
        counters: RouteCounters,
    ) -> Applied {
        self.apply_with(event, |m| m.clone_from(mission), limits, counters)
    }

    /// As [`Self::apply`], the endpoint's mission written by
    /// `write_mission` into the runner's in place (called for
    /// [`Event::LoadRoute`] only): an owner with little stack does not
    /// copy the route out first.
    pub fn apply_with<F>(
        &mut self,
        event: Event,
        write_mission: F,
        limits: RouteLimits,
        counters: RouteCounters,
    ) -> Applied
    where
        F: FnOnce(&mut Waypoints),
    {
        self.limits = limits;
        match event {
            Event::LoadRoute => {
                write_mission(&mut self.mission);
                let count = self.count();
                if self.mode == RobotMode::Running {
                    self.deviation_m = limits.blend_deviation_m();
                    self.progress = Progress::loaded(
                        0,
                        true,
                        None,
                        counters.routes_started,
                        counters.stops_reached,
                    );
                    return Applied::new(
                        FollowerAction::Replace,
                        Some(Note::MissionReplaces(count)),
                    );
                }
                self.progress = Progress::default();
                self.mode = RobotMode::Idle;
                Applied::new(FollowerAction::Keep, Some(Note::MissionLoaded(count)))
            }
            Event::ClearRoute => {
                self.mission = Waypoints::new();
                self.progress = Progress::default();
                self.hold(RobotMode::Idle, Note::Cleared)
            }
            Event::Arm => {
                self.armed = true;
                Applied::new(FollowerAction::Keep, Some(Note::Armed))
            }
            Event::Disarm => {
                self.armed = false;
                self.hold(RobotMode::Idle, Note::Disarmed)
            }
            Event::Start => {
                if self.mode == RobotMode::Done && !self.current_set {
                    self.progress = Progress::default();
                }
                self.current_set = false;
                self.run_from(self.progress.current_in(self.count()), false)
            }
            Event::Pause if self.mode == RobotMode::Running => {
                self.hold(RobotMode::Paused, Note::Paused)
            }
            Event::Continue if self.mode == RobotMode::Paused => {
                self.run_from(self.progress.current_in(self.count()), true)
            }
            Event::Pause | Event::Continue => Applied::new(FollowerAction::Keep, None),
            Event::EmergencyStop => self.hold(RobotMode::Stopped, Note::EmergencyStop),
            Event::SetCurrent(i) => {
                self.current_set = true;
                self.progress = Progress::at(i);
                if self.mode == RobotMode::Running {
                    self.run_from(i, false)
                } else {
                    Applied::new(FollowerAction::Keep, None)
                }
            }
            Event::LinkLost => {
                if matches!(self.mode, RobotMode::Running | RobotMode::Paused) {
                    self.hold(RobotMode::Stopped, Note::LinkLostStopped)
                } else {
                    Applied::new(FollowerAction::Keep, Some(Note::LinkLost))
                }
            }
            Event::RouteLimits => Applied::new(FollowerAction::Keep, Some(Note::RouteLimits)),
            // The robot's, not the route's: its owner retunes the pilot.
            Event::Tuning => Applied::new(FollowerAction::Keep, Some(Note::Tuning)),
        }
    }

    /// Loads into `follower` the route `action` names: the mission as
    /// given for [`FollowerAction::Replace`] (into the running follower),
    /// the mission from item `base` for [`FollowerAction::Run`] (into the
    /// owner's fresh follower). Nothing for the other actions.
    pub fn load(&mut self, action: FollowerAction, follower: &mut RouteFollower) {
        match action {
            FollowerAction::Replace => {
                follower.load(&self.mission, &self.limits, RouteStart::AsGiven);
            }
            FollowerAction::Run { base, start } => {
                if !copy_tail(&self.mission, usize::from(base), &mut self.route) {
                    return;
                }
                follower.load(&self.route, &self.limits, start);
            }
            FollowerAction::Keep | FollowerAction::Hold => {}
        }
    }

    /// Updates the progress after a tick of the follower: its `status`
    /// and `counters` after the tick, `reference` the tick's reference
    /// position. Returns whether the mission is done at this tick (its
    /// last item reached while the route is done; once per run).
    pub fn after_tick(
        &mut self,
        status: &RouteStatus,
        counters: RouteCounters,
        reference: Vec2,
    ) -> bool {
        if self.mode != RobotMode::Running {
            return false;
        }
        self.progress.update(
            &self.mission,
            status,
            counters.routes_started,
            counters.stops_reached,
            reference,
            self.deviation_m,
        );
        // Done once this mission's last item is reached (a route being
        // replaced may rest on its own end first).
        let last = self.mission.len().checked_sub(1);
        if status.done && self.progress.reached.map(usize::from) == last {
            self.mode = RobotMode::Done;
            return true;
        }
        false
    }

    /// Stops and holds where the robot is, in `mode`.
    fn hold(&mut self, mode: RobotMode, note: Note) -> Applied {
        self.mode = mode;
        Applied::new(FollowerAction::Hold, Some(note))
    }

    /// Drives the mission from item `from` (module documentation);
    /// nothing where `from` is past the mission.
    fn run_from(&mut self, from: u16, resume: bool) -> Applied {
        let (base, start) = match from.checked_sub(1) {
            None => {
                let start = if self.started_once {
                    RouteStart::AsGiven
                } else {
                    self.first_start
                };
                (0_u16, start)
            }
            Some(base) => (base, RouteStart::FromFirstFix),
        };
        if usize::from(base) > self.mission.len() {
            return Applied::new(FollowerAction::Keep, None);
        }
        let reached = if resume { self.progress.reached } else { None };
        self.deviation_m = self.limits.blend_deviation_m();
        self.progress = Progress::loaded(base, from == 0, reached, 0, 0);
        self.started_once = true;
        self.mode = RobotMode::Running;
        Applied::new(
            FollowerAction::Run { base, start },
            Some(Note::Started { from, resume }),
        )
    }
}

/// Writes the waypoints of `from` from index `base` on into `to`;
/// `false` (nothing written) where `base` is past `from`'s end. Out of
/// line, its two routes separate arguments: copied between two fields of
/// one runner, LLVM moved each waypoint with a call of `memmove` (1.5 KB
/// of flash a firmware otherwise need not link).
#[inline(never)]
fn copy_tail(from: &Waypoints, base: usize, to: &mut Waypoints) -> bool {
    let Some(rest) = from.as_slice().get(base..) else {
        return false;
    };
    to.clear();
    for &w in rest {
        // No more than `from` holds, which has the same capacity: cannot
        // fail.
        let _ = to.push(w);
    }
    true
}
