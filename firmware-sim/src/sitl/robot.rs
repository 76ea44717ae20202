//! The simulated robot under MAVLink: the same rig as `firmware-sim run`
//! (plant, virtual devices, the core's `Robot` or `Pilot` on a route
//! follower), armed or not, in a [`RobotMode`], applying the endpoint's
//! [`Event`]s at a tick boundary.
//!
//! The robot holds (stops and stays) by following a fresh follower with
//! no route: the core's follower then ramps the command to zero at the
//! tracker's failsafe deceleration where the robot is and holds it at
//! exactly zero, motors halted (`wmr_core::pilot::route`, "Refused"):
//! pause, emergency stop, link loss, disarm and a cleared mission all
//! stop that way. A start or a continue loads the mission from the
//! current item into a fresh follower: from item 0 as given (the robot is
//! first driven onto item 0; the very first start uses the scenario's own
//! `start`, e.g. a known heading at a station), from item `k ≥ 1` as the
//! mission from `k − 1` with its first waypoint replaced by where the
//! robot is (`RouteStart::FromFirstFix`). A mission uploaded while the
//! robot drives replaces the running route by the core's rule: at the
//! running route's next rest, from the rest point.

use wmr_core::geometry::Vec2;
use wmr_core::pilot::route::{RouteFollower, RouteOptions, RouteStart};
use wmr_core::reference::route::{RouteLimits, Waypoints};
use wmr_mavlink::{Estimate, Event, RobotMode, RobotView};

use crate::report::Record;
use crate::scenario::Setup;
use crate::simulation::Stepper;

use super::progress::Progress;

/// The simulated robot.
pub struct SitlRobot {
    rig: Stepper,
    period_s: f64,
    tick: u32,
    options: RouteOptions,
    /// The scenario's start, for the first start.
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
    last: Option<Record>,
}

impl SitlRobot {
    /// The scenario's robot, disarmed, idle, with no mission, holding
    /// where it stands.
    ///
    /// # Errors
    /// A scenario without a route, or whose tick does not run on a route
    /// follower here.
    pub fn new(setup: &Setup) -> anyhow::Result<Self> {
        let route = setup.route.as_ref().ok_or_else(|| {
            anyhow::anyhow!("sitl needs a route scenario or a robot file with a route ([reference] kind = \"route\")")
        })?;
        let mut rig = Stepper::new(setup);
        rig.swap_route(Box::new(RouteFollower::new(route.options)))
            .map_err(|_| {
                anyhow::anyhow!(
                    "sitl runs the core's tracker, Pilot or Robot; this scenario's tick is not one"
                )
            })?;
        Ok(Self {
            rig,
            period_s: setup.period_s,
            tick: 0,
            options: route.options,
            first_start: route.start,
            started_once: false,
            armed: false,
            mode: RobotMode::Idle,
            mission: Waypoints::new(),
            limits: route.limits,
            deviation_m: route.limits.blend_deviation_m(),
            progress: Progress::default(),
            current_set: false,
            last: None,
        })
    }

    /// The control period, s.
    #[must_use]
    pub fn period_s(&self) -> f64 {
        self.period_s
    }

    /// Ticks run.
    #[must_use]
    pub fn ticks(&self) -> u32 {
        self.tick
    }

    /// The mode.
    #[must_use]
    pub fn mode(&self) -> RobotMode {
        self.mode
    }

    /// The route limits the next route is planned with.
    #[must_use]
    pub fn limits(&self) -> RouteLimits {
        self.limits
    }

    /// The last tick's record.
    #[must_use]
    pub fn last(&self) -> Option<&Record> {
        self.last.as_ref()
    }

    /// The progress through the mission.
    #[must_use]
    pub fn progress(&self) -> Progress {
        self.progress
    }

    /// The running follower.
    #[must_use]
    pub fn follower(&self) -> Option<&RouteFollower> {
        self.rig.route()
    }

    /// What the robot reports to the endpoint.
    #[must_use]
    pub fn view(&self) -> RobotView {
        let estimate = self.last.as_ref().and_then(|r| {
            let (x, y, theta) = (r.est_x_m?, r.est_y_m?, r.est_theta_rad?);
            Some(Estimate {
                x_m: x as f32,
                y_m: y as f32,
                heading_rad: theta as f32,
                speed_m_s: r.v_cmd_m_s as f32,
                turn_rate_rad_s: r.omega_cmd_rad_s as f32,
            })
        });
        RobotView {
            armed: self.armed,
            mode: self.mode,
            estimate,
            current: self.progress.current_in(self.mission.len() as u16),
            reached: self.progress.reached,
        }
    }

    /// Applies one of the endpoint's events. `mission` is the endpoint's
    /// running mission as a route, `limits` its route limits now. Returns
    /// a line for the log where the robot did something.
    pub fn apply(
        &mut self,
        event: Event,
        mission: &Waypoints,
        limits: RouteLimits,
    ) -> Option<String> {
        self.limits = limits;
        match event {
            Event::LoadRoute => {
                self.mission = *mission;
                if self.mode == RobotMode::Running {
                    let (started, stops) = self.counters();
                    if let Some(f) = self.rig.route_mut() {
                        f.load(mission, &limits, RouteStart::AsGiven);
                    }
                    self.deviation_m = limits.blend_deviation_m();
                    self.progress = Progress::loaded(0, true, None, started, stops);
                    return Some(format!(
                        "mission of {} items: replaces the running route at its next rest",
                        mission.len()
                    ));
                }
                self.progress = Progress::default();
                self.mode = RobotMode::Idle;
                Some(format!("mission of {} items loaded", mission.len()))
            }
            Event::ClearRoute => {
                self.mission = Waypoints::new();
                self.progress = Progress::default();
                self.hold(RobotMode::Idle);
                Some("mission cleared: holding".into())
            }
            Event::Arm => {
                self.armed = true;
                Some("armed".into())
            }
            Event::Disarm => {
                self.armed = false;
                self.hold(RobotMode::Idle);
                Some("disarmed: holding".into())
            }
            Event::Start => {
                if self.mode == RobotMode::Done && !self.current_set {
                    self.progress = Progress::default();
                }
                self.current_set = false;
                self.run_from(self.progress.current_in(self.mission.len() as u16), false)
            }
            Event::Pause if self.mode == RobotMode::Running => {
                self.hold(RobotMode::Paused);
                Some("paused: holding".into())
            }
            Event::Continue if self.mode == RobotMode::Paused => {
                self.run_from(self.progress.current_in(self.mission.len() as u16), true)
            }
            Event::Pause | Event::Continue => None,
            Event::EmergencyStop => {
                self.hold(RobotMode::Stopped);
                Some("emergency stop: stopped (disarm, re-arm to restart)".into())
            }
            Event::SetCurrent(i) => {
                self.current_set = true;
                self.progress = Progress::at(i);
                if self.mode == RobotMode::Running {
                    self.run_from(i, false)
                } else {
                    None
                }
            }
            Event::LinkLost => {
                if matches!(self.mode, RobotMode::Running | RobotMode::Paused) {
                    self.hold(RobotMode::Stopped);
                    Some("link lost: stopped (disarm, re-arm to restart)".into())
                } else {
                    Some("link lost".into())
                }
            }
            Event::RouteLimits => {
                Some("route limits set: the next route is planned with them".into())
            }
        }
    }

    /// One control tick at `t = k·h`, then the plant advances a period.
    ///
    /// # Errors
    /// A tick of the rig that fails (none does on a local rig).
    pub fn step(&mut self) -> anyhow::Result<&Record> {
        let k = self.tick;
        let record = self.rig.tick(k, f64::from(k) * self.period_s)?;
        self.rig.advance(self.period_s);
        self.tick = k.saturating_add(1);
        if self.mode == RobotMode::Running {
            let (started, stops) = self.counters();
            if let Some(f) = self.rig.route() {
                let status = f.status();
                let reference = Vec2::new(record.ref_x_m as f32, record.ref_y_m as f32);
                self.progress.update(
                    &self.mission,
                    &status,
                    started,
                    stops,
                    reference,
                    self.deviation_m,
                );
                // Done once this mission's last item is reached (a route
                // being replaced may rest on its own end first).
                let last = self.mission.len().checked_sub(1);
                if status.done && self.progress.reached.map(usize::from) == last {
                    self.mode = RobotMode::Done;
                }
            }
        }
        Ok(self.last.insert(record))
    }

    fn counters(&self) -> (u32, u32) {
        self.rig.route().map_or((0, 0), |f| {
            let c = f.counters();
            (c.routes_started, c.stops_reached)
        })
    }

    /// Stops and holds where the robot is, in `mode`.
    fn hold(&mut self, mode: RobotMode) {
        let idle = Box::new(RouteFollower::new(self.options));
        let _ = self.rig.swap_route(idle);
        self.mode = mode;
    }

    /// Drives the mission from item `from` (module documentation).
    fn run_from(&mut self, from: u16, resume: bool) -> Option<String> {
        let items = self.mission.as_slice();
        let (base, start) = if from == 0 {
            let start = if self.started_once {
                RouteStart::AsGiven
            } else {
                self.first_start
            };
            (0_u16, start)
        } else {
            (from - 1, RouteStart::FromFirstFix)
        };
        let route = items
            .get(usize::from(base)..)
            .and_then(|rest| Waypoints::from_slice(rest).ok())?;
        let mut follower = Box::new(RouteFollower::new(self.options));
        follower.load(&route, &self.limits, start);
        let reached = if resume { self.progress.reached } else { None };
        let _ = self.rig.swap_route(follower);
        self.deviation_m = self.limits.blend_deviation_m();
        self.progress = Progress::loaded(base, from == 0, reached, 0, 0);
        self.started_once = true;
        self.mode = RobotMode::Running;
        Some(format!(
            "{} from item {from}",
            if resume { "continuing" } else { "starting" }
        ))
    }
}
