//! The simulated robot under MAVLink: the same rig as `firmware-sim run`
//! (plant, virtual devices, the core's `Robot` or `Pilot` on a route
//! follower) driven by the mission runner of `wmr-mavlink`
//! ([`wmr_mavlink::runner`]: armed or not, its [`RobotMode`], the mission
//! and its progress), applying the endpoint's [`Event`]s at a tick
//! boundary. This file owns the route follower (in a `Box`) and does to it
//! what the runner asks ([`FollowerAction`]), and writes the runner's
//! [`Note`]s as log lines. A tuning set by a ground station
//! ([`Event::Tuning`]) goes into the rig's pilot (`Pilot::retune`) at
//! that boundary, as on the firmware: it holds from the next tick on.

use wmr_core::geometry::Vec2;
use wmr_core::pilot::route::{RouteFollower, RouteOptions};
use wmr_core::pilot::tuning::{Tuning, TuningSpec};
use wmr_core::reference::route::{RouteLimits, Waypoints};
use wmr_mavlink::{
    Counts, Estimate, Event, FollowerAction, MissionRunner, Note, Progress, RobotMode, RobotView,
};

use wmr_link::PowerOn;

use crate::report::Record;
use crate::scenario::Setup;
use crate::simulation::Stepper;

/// The simulated robot.
pub struct SitlRobot {
    rig: Stepper,
    period_s: f64,
    tick: u32,
    options: RouteOptions,
    runner: MissionRunner,
    last: Option<Record>,
}

impl SitlRobot {
    /// The scenario's robot at power-on, as its `mavlink.power_on` says
    /// and as the firmware starts: `run` (the default), armed and running
    /// the scenario's route exactly as `firmware-sim run` does (its route
    /// follower, start and limits); `wait`, disarmed and idle with the
    /// route loaded as the mission, holding where it stands.
    ///
    /// # Errors
    /// A scenario without a route, or whose tick does not run on a route
    /// follower here.
    pub fn new(setup: &Setup) -> anyhow::Result<Self> {
        let route = setup.route.as_ref().ok_or_else(|| {
            anyhow::anyhow!("sitl needs a route scenario or a robot file with a route ([reference] kind = \"route\")")
        })?;
        let mut rig = Stepper::new(setup);
        let not_a_route_tick = || {
            anyhow::anyhow!(
                "sitl runs the core's tracker, Pilot or Robot; this scenario's tick is not one"
            )
        };
        let mut runner = MissionRunner::new(route.start, route.limits);
        match route.mavlink.power_on {
            PowerOn::Run => {
                if rig.route().is_none() {
                    return Err(not_a_route_tick());
                }
                runner.reset_running(&route.waypoints, route.start, route.limits);
            }
            PowerOn::Wait => {
                rig.swap_route(Box::new(RouteFollower::new(route.options)))
                    .map_err(|_| not_a_route_tick())?;
                runner.reset_waiting(&route.waypoints, route.start, route.limits);
            }
        }
        Ok(Self {
            rig,
            period_s: setup.period_s,
            tick: 0,
            options: route.options,
            runner,
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
        self.runner.mode()
    }

    /// The route limits the next route is planned with.
    #[must_use]
    pub fn limits(&self) -> RouteLimits {
        self.runner.limits()
    }

    /// The gains and failsafe times the robot runs with now.
    #[must_use]
    pub fn tuning(&self) -> Option<TuningSpec> {
        self.rig.tuning()
    }

    /// The tracker's and RFID reader's counters now (the reader's zero
    /// on a robot without one).
    #[must_use]
    pub fn counts(&self) -> Option<Counts> {
        let (tracker, rfid) = self.rig.counters()?;
        let (rfid, unknown) = rfid.unwrap_or_default();
        Some(Counts::of(&tracker, &rfid, unknown))
    }

    /// The last tick's record.
    #[must_use]
    pub fn last(&self) -> Option<&Record> {
        self.last.as_ref()
    }

    /// The progress through the mission.
    #[must_use]
    pub fn progress(&self) -> Progress {
        self.runner.progress()
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
        self.runner.view(estimate)
    }

    /// Applies one of the endpoint's events. `mission` is the endpoint's
    /// running mission as a route, `limits` its route limits now,
    /// `tuning` its gains and failsafe times now (taken on
    /// [`Event::Tuning`]). Returns a line for the log where the robot did
    /// something.
    pub fn apply(
        &mut self,
        event: Event,
        mission: &Waypoints,
        limits: RouteLimits,
        tuning: Option<Tuning>,
    ) -> Option<String> {
        if let (Event::Tuning, Some(tuning)) = (event, tuning) {
            self.rig.retune(&tuning);
        }
        let counters = self
            .rig
            .route()
            .map(RouteFollower::counters)
            .unwrap_or_default();
        let applied = self.runner.apply(event, mission, limits, counters);
        match applied.action {
            FollowerAction::Keep => {}
            FollowerAction::Hold => {
                let _ = self
                    .rig
                    .swap_route(Box::new(RouteFollower::new(self.options)));
            }
            FollowerAction::Replace => {
                if let Some(f) = self.rig.route_mut() {
                    self.runner.load(applied.action, f);
                }
            }
            FollowerAction::Run { .. } => {
                let mut follower = Box::new(RouteFollower::new(self.options));
                self.runner.load(applied.action, &mut follower);
                let _ = self.rig.swap_route(follower);
            }
        }
        applied.note.map(line)
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
        if let Some(f) = self.rig.route() {
            let reference = Vec2::new(record.ref_x_m as f32, record.ref_y_m as f32);
            self.runner.after_tick(&f.status(), f.counters(), reference);
        }
        Ok(self.last.insert(record))
    }
}

/// The log line of what the runner did.
fn line(note: Note) -> String {
    match note {
        Note::MissionLoaded(n) => format!("mission of {n} items loaded"),
        Note::MissionReplaces(n) => {
            format!("mission of {n} items: replaces the running route at its next rest")
        }
        Note::Cleared => "mission cleared: holding".into(),
        Note::Armed => "armed".into(),
        Note::Disarmed => "disarmed: holding".into(),
        Note::Started { from, resume } => format!(
            "{} from item {from}",
            if resume { "continuing" } else { "starting" }
        ),
        Note::Paused => "paused: holding".into(),
        Note::EmergencyStop => "emergency stop: stopped (disarm, re-arm to restart)".into(),
        Note::LinkLostStopped => "link lost: stopped (disarm, re-arm to restart)".into(),
        Note::LinkLost => "link lost".into(),
        Note::RouteLimits => "route limits set: the next route is planned with them".into(),
        Note::Tuning => "gains / failsafe times set: from the next tick".into(),
    }
}
