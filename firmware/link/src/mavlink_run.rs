//! The MAVLink endpoint and mission runner of a robot that follows a
//! route (the crate docs, "MAVLink"), whatever carries its bytes: the QEMU
//! board's session takes them from the HIL link's channel
//! ([`crate::session::MavlinkStore`]), the Black Pill from its MAVLink
//! UART's ring. One home for the glue, so both boards behave alike.
//!
//! At each tick, before the robot's ([`MavlinkRun::before_tick`]), the
//! endpoint takes the bytes received since the last tick and the runner's
//! view, and writes its output into the caller's room; its events are
//! applied to the runner, and what the runner asks is done to the
//! [`RouteStore`]'s follower in place (a hold: a fresh follower with no
//! route; a start: a fresh follower loaded from an item; a replacement: a
//! load into the running follower). After the robot's tick
//! ([`MavlinkRun::after_tick`]) the runner reads the follower's status. A
//! run that receives no MAVLink byte gets no event, so its robot runs
//! exactly as without the endpoint; a ground station heard and then
//! silent for the link timeout is [`wmr_mavlink::Event::LinkLost`]: the
//! runner holds the robot where it is. An uploaded mission is checked
//! only for its size here (no second 20 KB plan to plan it into): one the
//! planner refuses is refused by the follower when it starts, counted
//! (`RouteCounters::routes_refused`), and the robot holds where it is.
//!
//! The robot's gains and failsafe times are parameters too: its owner
//! tells the run the pilot's ([`MavlinkRun::set_tuning`], after each
//! [`MavlinkRun::activate`]), and after [`MavlinkRun::before_tick`] takes
//! a tuning the ground station set ([`MavlinkRun::take_tuning`]) into the
//! pilot (`Robot::retune`) before the robot's tick: it holds from that
//! tick on. Its counters go to the endpoint after each tick
//! ([`MavlinkRun::set_counts`]).

use wmr_core::geometry::Vec2;
use wmr_core::pilot::route::{RouteFollower, RouteStart};
use wmr_core::pilot::tuning::{Tuning, TuningSpec};
use wmr_core::reference::route::{RouteError, RouteLimits, RouteLimitsSpec, Waypoints};
use wmr_mavlink::{
    Counts, EndpointConfig, Estimate, Event, Events, FollowerAction, MavlinkEndpoint,
    MissionRunner, TxBuffer,
};

use crate::route::PowerOn;
use crate::route_store::RouteStore;

/// A route run's MAVLink side (module documentation): the endpoint, the
/// mission runner and where an uploaded mission is written for its check,
/// about 9 KB; keep it in a `static`, built in place ([`Self::BLANK`] or
/// [`Self::new`]) and reset in place by each run ([`Self::activate`]).
#[derive(Debug, Clone)]
pub struct MavlinkRun {
    endpoint: MavlinkEndpoint,
    runner: MissionRunner,
    /// The control period, µs: the endpoint's clock is the tick's time.
    period_us: u32,
    /// The run has a route: the endpoint and the runner are its.
    active: bool,
    /// Where the endpoint writes an uploaded mission as a route to check
    /// it (`MavlinkEndpoint::handle_in`): here, not on the stack.
    route_check: Waypoints,
    /// A ground station set the gains or failsafe times since the owner
    /// last took them ([`Self::take_tuning`]).
    retune: bool,
}

impl MavlinkRun {
    /// Route limits to build an idle run with ([`Self::new`]): valid, and
    /// replaced by each run's.
    pub const IDLE_LIMITS: RouteLimitsSpec = RouteLimitsSpec {
        max_speed_m_s: 0.3,
        max_tangential_accel_m_s2: 0.5,
        max_lateral_accel_m_s2: 0.5,
        blend_deviation_m: 0.02,
        pivot_threshold_rad: 0.5,
        pivot_rate_rad_s: 1.0,
        pivot_accel_rad_s2: 2.0,
    };

    /// Idle (no run) and not configured, every field zero: for a `static`
    /// built by clearing memory (a `memset`, no 9 KB value built on the
    /// stack and copied; the static lands in `.bss`). Its endpoint and
    /// runner are blank (`MavlinkEndpoint::BLANK`, `MissionRunner::BLANK`)
    /// until [`Self::activate`] configures both: meanwhile
    /// [`Self::before_tick`] takes no byte and sends none, and
    /// [`Self::after_tick`] does nothing, as for any run not active.
    pub const BLANK: Self = Self {
        endpoint: MavlinkEndpoint::BLANK,
        runner: MissionRunner::BLANK,
        period_us: 0,
        active: false,
        route_check: Waypoints::new(),
        retune: false,
    };

    /// Idle (no run), its endpoint configured by `config` for every run
    /// (system and component ids, timeouts, telemetry period, origin);
    /// `limits` are replaced by each run's ([`Self::IDLE_LIMITS`] will
    /// do). Infallible and inlined, so that it is built where its caller
    /// puts it; a board's `static` starts from [`Self::BLANK`] instead.
    #[must_use]
    #[inline(always)]
    pub fn new(config: EndpointConfig, limits: RouteLimits) -> Self {
        Self {
            endpoint: MavlinkEndpoint::new_in_place(config, limits),
            runner: MissionRunner::new(RouteStart::AsGiven, limits),
            period_us: 0,
            active: false,
            route_check: Waypoints::new(),
            retune: false,
        }
    }

    /// A new route run on `route` (the route just loaded into the
    /// store), in place: the endpoint reset with `config` (the route's
    /// `MavlinkSettings::config`) and the route as its mission
    /// ([`MavlinkEndpoint::load_route_mission`]); the runner running the
    /// route as `start` says under `limits` ([`PowerOn::Run`]), or
    /// disarmed and idle with the route loaded, the follower holding
    /// ([`PowerOn::Wait`]); the endpoint's clock ticks `period_s` a tick.
    pub fn activate(
        &mut self,
        route: &mut RouteStore,
        start: RouteStart,
        limits: RouteLimits,
        period_s: f32,
        config: EndpointConfig,
        power_on: PowerOn,
    ) {
        self.endpoint.reset(config, limits);
        self.endpoint.load_route_mission(route.waypoints());
        match power_on {
            PowerOn::Run => self.runner.reset_running(route.waypoints(), start, limits),
            PowerOn::Wait => {
                self.runner.reset_waiting(route.waypoints(), start, limits);
                route.reset_follower();
            }
        }
        // A period of at most hours (the pilot's check): fits.
        self.period_us = (period_s * 1.0e6 + 0.5) as u32;
        self.active = true;
        self.retune = false;
    }

    /// The robot's gains and failsafe times (`PilotConfig::tuning`), which
    /// the parameters start from; after each [`Self::activate`] (until
    /// told they read NaN and are refused).
    ///
    /// # Errors
    /// The core's refusal (not for a running pilot's own).
    pub fn set_tuning(
        &mut self,
        spec: &TuningSpec,
    ) -> Result<(), wmr_core::pilot::spec::SpecError> {
        self.endpoint.set_tuning(spec)
    }

    /// The gains and failsafe times a ground station set since the last
    /// call, for the robot to take before its tick (`Robot::retune`);
    /// `None` if none were set.
    pub fn take_tuning(&mut self) -> Option<Tuning> {
        if core::mem::take(&mut self.retune) {
            self.endpoint.tuning()
        } else {
            None
        }
    }

    /// The robot's counters after its tick, for the endpoint to send
    /// (`NAMED_VALUE_INT` at its counters period).
    pub fn set_counts(&mut self, counts: Counts) {
        self.endpoint.set_counts(counts);
    }

    /// Ends the run's MAVLink side (no route any more).
    pub fn deactivate(&mut self) {
        self.active = false;
    }

    /// Whether a route run is on.
    #[must_use]
    pub fn is_active(&self) -> bool {
        self.active
    }

    /// The endpoint (its counters, for a log).
    #[must_use]
    pub fn endpoint(&self) -> &MavlinkEndpoint {
        &self.endpoint
    }

    /// The mission runner (its mode, for a log).
    #[must_use]
    pub fn runner(&self) -> &MissionRunner {
        &self.runner
    }

    /// The endpoint's part of tick `tick` (counted from 0), before the
    /// robot's: `rx` (the bytes received since the last tick) in, its
    /// output written at the start of `room`, its events applied to the
    /// runner and `route`'s follower. `estimate` is the last tick's (the
    /// one the endpoint reports). Returns the bytes written and the
    /// frames dropped for want of room. Nothing while no run is on. Not
    /// inlined: the route it reads out of the endpoint (1.8 KB) is in
    /// this frame, off the robot's tick's deepest path.
    #[inline(never)]
    pub fn before_tick(
        &mut self,
        route: &mut RouteStore,
        tick: u32,
        estimate: Option<Estimate>,
        rx: &[u8],
        room: &mut [u8],
    ) -> (usize, u32) {
        if !self.active {
            return (0, 0);
        }
        let now_ms = tick_ms(tick, self.period_us);
        let Self {
            endpoint,
            runner,
            route_check,
            ..
        } = self;
        let view = runner.view(estimate);
        let room_len = room.len();
        let mut tx = TxBuffer::new(room);
        let events = endpoint.handle_in(now_ms, rx, &view, check_mission, &mut tx, route_check);
        let written = (tx.len().min(room_len), tx.dropped());
        if !events.as_slice().is_empty() {
            apply_events(endpoint, runner, route, &events);
            self.retune |= events.as_slice().contains(&Event::Tuning);
        }
        written
    }

    /// After the robot's tick: the runner reads the follower's status and
    /// counters, `reference` the tick's reference position. Nothing while
    /// no run is on or before the route has a follower.
    pub fn after_tick(&mut self, route: &RouteStore, reference: Vec2) {
        if let (true, Some(f)) = (self.active, route.follower()) {
            self.runner.after_tick(&f.status(), f.counters(), reference);
        }
    }
}

/// The start of tick `tick` of `period_us`, ms, wrapping (the endpoint's
/// clock takes differences only): `tick × period_us / 1000` rounded down,
/// modulo 2^32, in `u32` arithmetic (a `u64` division links 0.9 KB of
/// `__aeabi_uldivmod` into a firmware that had none). With `tick = 1000 a
/// + b` and `period_us = 1000 p + r`: `tick × p + a × r + ⌊b × r / 1000⌋`,
/// where `b × r < 10^6`.
#[must_use]
pub fn tick_ms(tick: u32, period_us: u32) -> u32 {
    let (a, b) = (tick / 1000, tick % 1000);
    let (p, r) = (period_us / 1000, period_us % 1000);
    tick.wrapping_mul(p)
        .wrapping_add(a.wrapping_mul(r))
        .wrapping_add(b * r / 1000)
}

/// The estimate a tick reports to the endpoint: its position (m), its
/// heading as (cos, sin) and its command (forward speed m/s, turn rate
/// rad/s).
#[must_use]
pub fn estimate(position_m: [f32; 2], heading: [f32; 2], command: [f32; 2]) -> Estimate {
    Estimate {
        x_m: position_m[0],
        y_m: position_m[1],
        heading_rad: libm::atan2f(heading[1], heading[0]),
        speed_m_s: command[0],
        turn_rate_rad_s: command[1],
    }
}

/// Applies the endpoint's events to the runner and what it asks to the
/// follower, in place. Not inlined: a route loaded into the follower
/// passes through this frame (about 2 KB), which ticks without an event
/// do not take.
#[inline(never)]
fn apply_events(
    endpoint: &MavlinkEndpoint,
    runner: &mut MissionRunner,
    route: &mut RouteStore,
    events: &Events,
) {
    let limits = endpoint.route_limits();
    for &event in events.as_slice() {
        let counters = route
            .follower()
            .map(RouteFollower::counters)
            .unwrap_or_default();
        let write = |m: &mut Waypoints| endpoint.route_into(m);
        let action = runner.apply_with(event, write, limits, counters).action;
        match action {
            FollowerAction::Keep => {}
            FollowerAction::Hold => route.reset_follower(),
            FollowerAction::Replace => {
                if let Some(f) = route.follower_mut() {
                    runner.load(action, f);
                }
            }
            FollowerAction::Run { .. } => {
                route.reset_follower();
                if let Some(f) = route.follower_mut() {
                    runner.load(action, f);
                }
            }
        }
    }
}

/// The check of an uploaded mission on the firmware: its size (module
/// documentation).
fn check_mission(route: &Waypoints) -> Result<(), RouteError> {
    if route.len() < 2 {
        Err(RouteError::TooFewWaypoints)
    } else {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::{MavlinkRun, tick_ms};
    use crate::RouteSpec;
    use crate::route_store::RouteStore;
    use wmr_core::pilot::route::{RouteOptionsSpec, RouteStart};
    use wmr_core::reference::route::Waypoint;
    use wmr_mavlink::{EndpointConfig, EndpointSpec};

    /// A run on a 3-waypoint route, as a board sets it up: the store
    /// loaded and planned, the run activated on it.
    fn a_run() -> (Box<RouteStore>, Box<MavlinkRun>) {
        let spec = RouteSpec {
            waypoints: 3,
            limits: MavlinkRun::IDLE_LIMITS,
            options: RouteOptionsSpec::default(),
            start: RouteStart::AsGiven,
            mavlink: crate::MavlinkSettings::default(),
        };
        let mut store = Box::new(RouteStore::new());
        let limits = store.begin(&spec).unwrap();
        for w in [
            Waypoint::pass(0.0, 0.0),
            Waypoint::stop(1.0, 0.0, 2.0),
            Waypoint::pass(1.0, 1.0),
        ] {
            store.push(w).unwrap();
        }
        store.finish(&limits, spec.start, 0.01).unwrap();
        let config = EndpointConfig::new(&EndpointSpec::default()).unwrap();
        let mut run = Box::new(MavlinkRun::new(config, limits));
        run.activate(
            &mut store,
            spec.start,
            limits,
            0.01,
            spec.mavlink.config().unwrap(),
            spec.mavlink.power_on,
        );
        (store, run)
    }

    /// The lengths of the MAVLink 2 frames (unsigned: 12 bytes around the
    /// payload) that `bytes` is made of, `None` if it does not split into
    /// whole frames.
    fn whole_frames(mut bytes: &[u8]) -> Option<Vec<usize>> {
        let mut lengths = Vec::new();
        while !bytes.is_empty() {
            let (&magic, rest) = bytes.split_first()?;
            let len = 12 + usize::from(*rest.first()?);
            if magic != 0xFD || bytes.len() < len {
                return None;
            }
            lengths.push(len);
            bytes = &bytes[len..];
        }
        Some(lengths)
    }

    /// A transmit ring with less room than the tick's frames: the frames
    /// that do not fit are dropped whole, counted by the endpoint and
    /// returned, and what is written is whole frames only.
    #[test]
    fn frames_past_the_room_are_dropped_whole_and_counted() {
        let (mut store, mut run) = a_run();
        // The first tick sends every periodic frame at once (HEARTBEAT,
        // SYS_STATUS, the position telemetry): more than 30 bytes.
        let mut room = [0_u8; 30];
        let (written, dropped) = run.before_tick(&mut store, 0, None, &[], &mut room);
        assert!(dropped > 0, "nothing dropped into 30 bytes");
        assert_eq!(run.endpoint().counters().tx_dropped, dropped);
        let frames = whole_frames(&room[..written]).expect("whole frames only");
        assert_eq!(frames.iter().sum::<usize>(), written);
        // With room, the next periodic frames go out and nothing more is
        // dropped.
        let mut room = [0_u8; 1024];
        let (written, more) = run.before_tick(&mut store, 100, None, &[], &mut room);
        assert_eq!(more, 0);
        assert!(whole_frames(&room[..written]).is_some_and(|f| !f.is_empty()));
        assert_eq!(run.endpoint().counters().tx_dropped, dropped);
    }

    /// A route whose robot file says `power_on = "wait"`: the run starts
    /// disarmed and idle with the route as its mission (the endpoint's
    /// too, so a ground station reads it back and starts it), the
    /// follower holding; an arm and a start run it from item 0 as the
    /// route's own start says.
    #[test]
    fn a_waiting_run_holds_until_armed_and_started() {
        use crate::{MavlinkSettings, PowerOn};
        use wmr_mavlink::RobotMode;
        let (mut store, mut run) = a_run();
        assert_eq!(run.runner().mode(), RobotMode::Running);
        assert!(run.runner().armed());
        assert_eq!(run.endpoint().mission().len(), 3);
        let limits =
            wmr_core::reference::route::RouteLimits::new(&MavlinkRun::IDLE_LIMITS).unwrap();
        let wait = MavlinkSettings {
            power_on: PowerOn::Wait,
            ..MavlinkSettings::default()
        };
        run.activate(
            &mut store,
            RouteStart::AsGiven,
            limits,
            0.01,
            wait.config().unwrap(),
            wait.power_on,
        );
        assert_eq!(run.runner().mode(), RobotMode::Idle);
        assert!(!run.runner().armed());
        assert_eq!(run.runner().mission(), store.waypoints());
        assert!(!store.follower().unwrap().status().pending);
        // The endpoint's mission is the route in the local frame: item 1
        // is the stop at (1, 0) with its 2 s dwell, north 0, east 1 m.
        let item = *run.endpoint().mission().get(1).unwrap();
        assert_eq!((item.x, item.y, item.hold_s), (0, 10_000, 2.0));
        assert_eq!(
            run.endpoint().route().as_slice()[1],
            Waypoint::stop(1.0, 0.0, 2.0)
        );
        // A ground station's arm, then start (COMMAND_LONG 400 and 300,
        // a tick each: a start is checked against the robot's view),
        // framed by the endpoint's own encoder.
        for (tick, command, p1) in [(0_u32, 400_u16, 1.0_f32), (1, 300, 0.0)] {
            let mut bytes = [0_u8; 64];
            let mut tx = wmr_mavlink::TxBuffer::new(&mut bytes);
            let mut payload = [0_u8; 33];
            payload[..4].copy_from_slice(&p1.to_le_bytes());
            payload[28..30].copy_from_slice(&command.to_le_bytes());
            payload[30] = 1;
            payload[31] = 1;
            assert!(tx.frame([tick as u8, 255, 190], 76, 152, &payload));
            let len = tx.len();
            let mut room = [0_u8; 1024];
            run.before_tick(&mut store, tick, None, &bytes[..len], &mut room);
        }
        assert_eq!(run.runner().mode(), RobotMode::Running);
        assert!(run.runner().armed());
        assert!(store.follower().unwrap().status().pending);
    }

    /// A blank run (`MavlinkRun::BLANK`, every byte zero) is idle before
    /// it is activated: it takes no byte, sends none, commands nothing;
    /// activated, it is a run built by `MavlinkRun::new` and activated
    /// alike: tick for tick the same bytes out, with a ground station's
    /// heartbeats, a disarm and an arm coming in, the same runner and
    /// the same counters.
    #[test]
    fn a_blank_run_activated_runs_as_a_built_one() {
        use wmr_mavlink::{Counts, RobotMode};
        let (mut built_store, mut built) = a_run();
        let (mut blank_store, _) = a_run();
        let mut blank = Box::new(MavlinkRun::BLANK);
        let mut room = [0_u8; 1024];
        let heartbeat = [0xFD_u8, 9, 0, 0, 0, 255, 190, 0, 0, 0];
        assert_eq!(
            blank.before_tick(&mut blank_store, 0, None, &heartbeat, &mut room),
            (0, 0)
        );
        blank.after_tick(&blank_store, wmr_core::geometry::Vec2::new(0.0, 0.0));
        assert!(!blank.is_active());
        assert_eq!(blank.runner().mode(), RobotMode::Idle);
        assert!(!blank.runner().armed());
        assert_eq!(blank.take_tuning(), None);
        let spec = crate::MavlinkSettings::default();
        let limits =
            wmr_core::reference::route::RouteLimits::new(&MavlinkRun::IDLE_LIMITS).unwrap();
        blank.activate(
            &mut blank_store,
            RouteStart::AsGiven,
            limits,
            0.01,
            spec.config().unwrap(),
            spec.power_on,
        );
        assert!(blank.is_active());
        assert_eq!(blank.runner(), built.runner());
        // A ground station's heartbeat every 100 ticks, a disarm
        // (COMMAND_LONG 400, 0) at tick 150 and an arm at 250, framed by
        // the endpoint's own encoder.
        let input = |tick: u32| {
            let mut bytes = [0_u8; 64];
            let mut tx = wmr_mavlink::TxBuffer::new(&mut bytes);
            if tick.is_multiple_of(100) {
                // HEARTBEAT of a MAV_TYPE_GCS (6), MAV_AUTOPILOT_INVALID (8).
                let payload = [0, 0, 0, 0, 6, 8, 0, 0, 4];
                assert!(tx.frame([tick as u8, 255, 190], 0, 50, &payload));
            }
            if tick == 150 || tick == 250 {
                let mut payload = [0_u8; 33];
                let p1: f32 = if tick == 150 { 0.0 } else { 1.0 };
                payload[..4].copy_from_slice(&p1.to_le_bytes());
                payload[28..30].copy_from_slice(&400_u16.to_le_bytes());
                payload[30] = 1;
                payload[31] = 1;
                assert!(tx.frame([tick as u8, 255, 190], 76, 152, &payload));
            }
            let len = tx.len();
            (bytes, len)
        };
        let mut sent = 0;
        for tick in 0..400_u32 {
            let (bytes, len) = input(tick);
            let estimate = Some(super::estimate(
                [0.01 * tick as f32, 0.0],
                [1.0, 0.0],
                [0.1, 0.0],
            ));
            let mut out = [[0_u8; 1024]; 2];
            let a = built.before_tick(&mut built_store, tick, estimate, &bytes[..len], &mut out[0]);
            let b = blank.before_tick(&mut blank_store, tick, estimate, &bytes[..len], &mut out[1]);
            assert_eq!(a, b, "tick {tick}");
            assert_eq!(out[0][..a.0], out[1][..b.0], "tick {tick}");
            sent += a.0;
            for (run, store) in [(&mut built, &built_store), (&mut blank, &blank_store)] {
                run.after_tick(store, wmr_core::geometry::Vec2::new(0.0, 0.0));
                run.set_counts(Counts([tick; wmr_mavlink::COUNTERS]));
            }
            assert_eq!(blank.runner(), built.runner(), "tick {tick}");
            assert_eq!(blank.endpoint().counters(), built.endpoint().counters());
        }
        assert!(sent > 0);
        assert!(built.runner().armed());
        assert_eq!(built.endpoint().counters().rx.frames, 6);
    }

    /// The `u32` clock agrees with the exact `u64` product over 1000,
    /// wrapped to 32 bits.
    #[test]
    fn the_tick_clock_is_the_u64_product_over_1000_wrapped() {
        let exact =
            |t: u32, p: u32| ((u64::from(t) * u64::from(p) / 1000) & u64::from(u32::MAX)) as u32;
        for p in [
            1,
            999,
            1_000,
            1_001,
            5_000,
            10_000,
            12_345,
            99_999,
            3_600_000_000,
        ] {
            for t in [
                0,
                1,
                7,
                999,
                1_000,
                1_001,
                123_456,
                4_294_966,
                u32::MAX / 3,
                u32::MAX,
            ] {
                assert_eq!(tick_ms(t, p), exact(t, p), "tick {t} period {p} us");
            }
        }
    }
}
