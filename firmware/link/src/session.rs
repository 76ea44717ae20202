//! The firmware's side of a HIL run: messages in, the core's robot in the
//! middle, messages out. Board-independent (the QEMU board feeds it bytes
//! from its host link), so it is tested on the host too.
//!
//! A tag-map floor is loaded into a [`LinkTagMap`] the board lends the
//! session for its lifetime (the QEMU board's is a static: 64 KiB, never
//! on the stack), through a `RefCell`: the session fills it in place
//! between runs, the robot's [`SessionFloor`] looks ids up in it during
//! one. Both take it with `try_borrow*`, never at once (a lookup holds it
//! for the binary search only), so neither can fail or panic.
//!
//! A route (the crate docs, "The route") is loaded into a [`RouteStore`]
//! the board lends the session, its alone (`&mut`): the waypoints are
//! pushed in place into its `Waypoints`, planned once into its scratch
//! `RoutePlan` to check them, and handed to its `RouteFollower`, which the
//! robot's tick is lent ([`Robot::tick_on`]).
//!
//! A run with a route has a MAVLink endpoint and the mission runner of
//! `wmr-mavlink` (the crate docs, "MAVLink"), configured by the route's
//! announcement (`RouteSpec::mavlink`): the runner starts armed and
//! running the loaded route (the robot drives it from its first tick, as
//! without a ground station), or disarmed and idle with the route as the
//! mission (`PowerOn::Wait`). At each tick, before the robot's, the
//! endpoint takes the bytes the host brought since the last tick
//! ([`MavlinkStore`]'s queues) and answers into the send queue; the glue
//! between endpoint, runner and follower is [`crate::mavlink_run`]'s,
//! which the Black Pill's UART shares.

use core::cell::RefCell;

use wmr_core::devices::{MotorDriver, MotorWiring, TagGrid, TagId, TagLocator, TagMap};
use wmr_core::geometry::Vec2;
use wmr_core::pilot::Pilot;
use wmr_core::pilot::robot::Robot;
use wmr_core::pilot::route::{RouteFollower, RouteStart, RouteStatus};
use wmr_core::pilot::spec::SpecError;
use wmr_core::reference::route::{RouteLimits, RouteLimitsSpec};
use wmr_mavlink::EndpointConfig;

use crate::mavlink_run::{self, MavlinkRun};
use crate::proxy::{ProxyBus, ProxyEncoder, ProxyPin, ProxyPwm, ProxyUart, Side};
pub use crate::route_store::RouteStore;
use crate::{
    Configure, Diagnostics, Finished, FloorSpec, HostMessage, LinkCounters, MAP_CAPACITY, MapChunk,
    MapRefusal, MavlinkCounters, MavlinkOut, MavlinkQueues, MotorOutput, PROTOCOL_VERSION, Refusal,
    RouteChunk, RouteRefusal, RouteSpec, TargetMessage, TickOutput, telemetry,
};

/// The tag map of a HIL session: the core's, [`MAP_CAPACITY`] tags.
pub type LinkTagMap = TagMap<MAP_CAPACITY>;

/// The floor a session's robot looks its tag ids up in.
#[derive(Debug, Clone, Copy)]
pub enum SessionFloor<'a> {
    /// A grid, sent whole in `Configure`.
    Grid(TagGrid),
    /// The tag map loaded from `MapChunk`s.
    Map(&'a RefCell<LinkTagMap>),
}

impl TagLocator for SessionFloor<'_> {
    fn locate(&self, id: TagId) -> Option<Vec2> {
        match self {
            Self::Grid(grid) => grid.position(id),
            // Never borrowed mutably during a tick (the session loads the
            // map only between runs); if it were, the tag is unknown.
            Self::Map(map) => map.try_borrow().ok()?.position(id),
        }
    }
}

/// A tag map being loaded, or loaded, for the run.
#[derive(Debug, Clone, Copy)]
struct MapLoad {
    /// Tags `Configure` announced.
    announced: u16,
    /// Tags loaded so far.
    loaded: u16,
}

impl MapLoad {
    /// Whether every announced tag is loaded.
    fn complete(&self) -> bool {
        self.loaded == self.announced
    }

    /// The answer to the chunk that brought the map to `loaded` tags.
    fn answer(&self) -> TargetMessage {
        if self.complete() {
            TargetMessage::Configured
        } else {
            TargetMessage::MapLoaded { tags: self.loaded }
        }
    }
}

/// A route being loaded, or loaded, for the run.
#[derive(Debug, Clone, Copy)]
struct RouteLoad {
    /// Waypoints announced.
    announced: u8,
    /// Waypoints loaded so far.
    loaded: u8,
    /// The validated limits.
    limits: RouteLimits,
    /// Where it starts.
    start: RouteStart,
    /// Its MAVLink endpoint and power-on (checked at the announcement).
    mavlink: crate::MavlinkSettings,
}

impl RouteLoad {
    fn complete(&self) -> bool {
        self.loaded == self.announced
    }
}

/// The MAVLink side of a session's route runs (module documentation):
/// the endpoint and mission runner ([`MavlinkRun`]) and the channel's
/// queues, about 11 KB; the board lends it
/// ([`Session::lend_mavlink`]) from a `static`, and each route run resets
/// it in place, so neither is built on the stack.
#[derive(Debug, Clone)]
pub struct MavlinkStore {
    run: MavlinkRun,
    /// The channel's queues (the crate docs, "MAVLink").
    queues: MavlinkQueues,
}

impl MavlinkStore {
    /// Idle (no run) and not configured, every byte zero: for a `static`
    /// built by clearing memory (in `.bss`, no 11 KB value built on the
    /// stack and copied); each route run configures it
    /// (`MavlinkRun::activate`, [`MavlinkRun::BLANK`]).
    pub const BLANK: Self = Self {
        run: MavlinkRun::BLANK,
        queues: MavlinkQueues::new(),
    };

    /// Route limits to build an idle store with ([`Self::new`]): valid,
    /// and replaced by each run's.
    pub const IDLE_LIMITS: RouteLimitsSpec = MavlinkRun::IDLE_LIMITS;

    /// Idle (no run), its endpoint configured by `config` for every run
    /// (system and component ids, timeouts, telemetry period, origin);
    /// `limits` are replaced by each run's ([`Self::IDLE_LIMITS`] will
    /// do). Infallible and inlined, so that a board builds it in its
    /// `static`, not on the stack.
    #[must_use]
    #[inline(always)]
    pub fn new(config: EndpointConfig, limits: RouteLimits) -> Self {
        Self {
            run: MavlinkRun::new(config, limits),
            queues: MavlinkQueues::new(),
        }
    }
}

/// The robot a HIL session runs: the core's [`Robot`] on proxy devices.
pub type ProxyRobot<'a> = Robot<
    ProxyEncoder<'a>,
    ProxyEncoder<'a>,
    MotorDriver<ProxyPwm<'a>, ProxyPin<'a>>,
    MotorDriver<ProxyPwm<'a>, ProxyPin<'a>>,
    ProxyUart<'a>,
    SessionFloor<'a>,
>;

/// A run in progress.
pub struct Session<'a> {
    bus: &'a ProxyBus,
    /// The tag map's storage, lent by the board.
    map: &'a RefCell<LinkTagMap>,
    /// The tag map of the run (`None`: a grid, or no run).
    map_load: Option<MapLoad>,
    /// The route's storage, lent by the board.
    route: &'a mut RouteStore,
    /// The route of the run (`None`: the pilot's trajectory, or no run).
    route_load: Option<RouteLoad>,
    /// The robot, from `Configure` on (not run until its map is loaded).
    robot: Option<ProxyRobot<'a>>,
    ticks: u32,
    /// The last tick's answer, sent again if the host resends that tick.
    last_answer: Option<TickOutput>,
    repeated_ticks: u32,
    stale_ticks: u32,
    /// Telemetry decimation of the run (`Configure::telemetry_every_ticks`).
    telemetry_every_ticks: u16,
    /// The record of the tick just run, if it is one to emit.
    telemetry: Option<telemetry::Record>,
    /// MAVLink bytes dropped for want of a [`MavlinkStore`].
    mavlink_dropped: u32,
    /// The endpoint and mission runner of route runs, if the board lent
    /// them.
    mav: Option<&'a mut MavlinkStore>,
}

impl<'a> Session<'a> {
    /// A session over `bus`, not yet configured, loading a tag map (if a
    /// run has one) into `map` and a route (if it has one) into `route`.
    #[must_use]
    pub fn new(bus: &'a ProxyBus, map: &'a RefCell<LinkTagMap>, route: &'a mut RouteStore) -> Self {
        Self {
            bus,
            map,
            map_load: None,
            route,
            route_load: None,
            robot: None,
            ticks: 0,
            last_answer: None,
            repeated_ticks: 0,
            stale_ticks: 0,
            telemetry_every_ticks: 0,
            telemetry: None,
            mavlink_dropped: 0,
            mav: None,
        }
    }

    /// Lends the session the MAVLink endpoint and mission runner its
    /// route runs use (module documentation); without, a run's MAVLink
    /// bytes are counted dropped.
    pub fn lend_mavlink(&mut self, store: &'a mut MavlinkStore) {
        store.run.deactivate();
        self.mav = Some(store);
    }

    /// The run's MAVLink side, while it has one.
    fn mav_active(&mut self) -> Option<&mut MavlinkStore> {
        self.mav.as_deref_mut().filter(|m| m.run.is_active())
    }

    /// The telemetry start of the run just configured (`None`: telemetry
    /// off, or no run): for the board to log once.
    #[must_use]
    pub fn telemetry_start(&self) -> Option<telemetry::Start> {
        let robot = self.robot.as_ref().filter(|_| self.is_configured())?;
        (self.telemetry_every_ticks != 0).then(|| telemetry::Start {
            every_ticks: self.telemetry_every_ticks,
            period_s: robot.pilot().tracker().config().clock().period_s(),
        })
    }

    /// The telemetry record of the tick the last [`Self::handle`] ran, if
    /// the decimation emits it (a resent tick, answered from the cache,
    /// has none). By reference: the board's run loop, on the stack's
    /// deepest path, holds no copy.
    #[must_use]
    pub fn telemetry(&self) -> Option<&telemetry::Record> {
        self.telemetry.as_ref()
    }

    /// Whether a configuration was accepted (its tag map and its route,
    /// if it has them, loaded whole).
    #[must_use]
    pub fn is_configured(&self) -> bool {
        self.robot.is_some()
            && self.map_load.is_none_or(|m| m.complete())
            && self.route_load.is_none_or(|r| r.complete())
    }

    /// The route's status (`None`: the run has no route).
    #[must_use]
    pub fn route_status(&self) -> Option<RouteStatus> {
        self.route_follower().map(RouteFollower::status)
    }

    /// The route's follower (`None`: the run has no route): its plan,
    /// status and counters, for a host that runs a session beside the
    /// firmware's.
    #[must_use]
    pub fn route_follower(&self) -> Option<&RouteFollower> {
        self.route_load.and_then(|_| self.route.follower())
    }

    /// Handles one message; `link` are the receiver's counters and
    /// `peak_stack_bytes` the stack high-water mark (reported on `Finish`).
    /// Returns the answer and whether the run is over.
    pub fn handle(
        &mut self,
        message: &HostMessage,
        link: LinkCounters,
        peak_stack_bytes: impl FnOnce() -> u32,
    ) -> (TargetMessage, bool) {
        self.telemetry = None;
        let configured = self.is_configured();
        match message {
            HostMessage::Configure(c) => (self.configure(c), false),
            HostMessage::MapChunk(chunk) => (self.load_map(chunk), false),
            HostMessage::Route(spec) => (self.announce_route(spec, configured), false),
            HostMessage::RouteChunk(chunk) => (self.load_route(chunk), false),
            HostMessage::Tick(input) => {
                match (self.robot.as_mut().filter(|_| configured), self.last_answer) {
                    (None, _) => (TargetMessage::Refused(Refusal::NotConfigured), false),
                    // The host resent a tick whose answer it lost: the same
                    // answer again; the robot does not run the tick twice.
                    (Some(_), Some(last)) if last.tick == input.tick => {
                        self.repeated_ticks = self.repeated_ticks.saturating_add(1);
                        (TargetMessage::Ticked(last), false)
                    }
                    // Older than the last answer: never run late.
                    (Some(_), Some(last)) if input.tick < last.tick => {
                        self.stale_ticks = self.stale_ticks.saturating_add(1);
                        (
                            TargetMessage::Refused(Refusal::StaleTick {
                                last_answered: last.tick,
                            }),
                            false,
                        )
                    }
                    (Some(robot), _) => {
                        self.bus.load(input);
                        if let Some(mav) = self.mav.as_deref_mut().filter(|m| m.run.is_active()) {
                            mavlink_tick(mav, self.route, input.tick, self.last_answer.as_ref());
                            if let Some(tuning) = mav.run.take_tuning() {
                                robot.retune(&tuning);
                            }
                        }
                        let route = self.route_load.and_then(|_| self.route.follower_mut());
                        let out = robot.tick_on(route);
                        if let Some(mav) = self.mav.as_deref_mut() {
                            let r = out.pilot.tracker.reference.position;
                            mav.run.after_tick(self.route, r);
                            note_counts(mav, robot);
                        }
                        // A few scalars, not `&out`: taking the tick's address
                        // kept all of it in this (inlined, deepest) frame.
                        let extra = telemetry::Extra::of(&out);
                        self.ticks = self.ticks.saturating_add(1);
                        let t = &out.pilot.tracker;
                        let answer = TickOutput {
                            tick: input.tick,
                            left: self.bus.motor(Side::Left),
                            right: self.bus.motor(Side::Right),
                            mode: t.mode,
                            reference_m: [t.reference.position.x, t.reference.position.y],
                            position_m: [t.position.x, t.position.y],
                            heading: [t.heading.cos_theta, t.heading.sin_theta],
                            command: [t.command.v_m_s, t.command.omega_rad_s],
                            fix: out.pilot.tracker.fix_used,
                            speed_limited: out.pilot.drive.speed_limited,
                            accel_limited: out.pilot.drive.accel_limited,
                        };
                        self.last_answer = Some(answer);
                        note_telemetry(
                            &mut self.telemetry,
                            self.telemetry_every_ticks,
                            &self.last_answer,
                            extra,
                            robot,
                        );
                        (TargetMessage::Ticked(answer), false)
                    }
                }
            }
            HostMessage::Finish => (
                TargetMessage::Finished(Finished {
                    ticks: self.ticks,
                    peak_stack_bytes: peak_stack_bytes(),
                    motors: self.motors(),
                    counters: self.diagnostics(link),
                    route_done: self.route_status().is_some_and(|s| s.done),
                }),
                true,
            ),
            HostMessage::Mavlink(m) => {
                let out = match self.mav.as_deref_mut() {
                    Some(mav) => mav.queues.exchange(m, configured && mav.run.is_active()),
                    None => {
                        let n = u32::try_from(m.bytes.len()).unwrap_or(u32::MAX);
                        self.mavlink_dropped = self.mavlink_dropped.wrapping_add(n);
                        MavlinkOut {
                            seq: m.seq,
                            counters: MavlinkCounters {
                                rx_dropped_bytes: self.mavlink_dropped,
                                ..MavlinkCounters::default()
                            },
                            ..MavlinkOut::default()
                        }
                    }
                };
                (TargetMessage::Mavlink(out), false)
            }
        }
    }

    /// The link went silent for `silent_ms`: stop the motors (the robot
    /// would otherwise drive on its last command with no sensor data).
    /// Returns the report for the host, with the motors as they are now.
    pub fn link_silent(&mut self, silent_ms: u32) -> TargetMessage {
        self.bus.stop_motors();
        TargetMessage::LinkSilent {
            motors: self.motors(),
            silent_ms,
        }
    }

    fn motors(&self) -> [MotorOutput; 2] {
        [self.bus.motor(Side::Left), self.bus.motor(Side::Right)]
    }

    /// All counters now.
    #[must_use]
    pub fn diagnostics(&self, link: LinkCounters) -> Diagnostics {
        let mut d = Diagnostics {
            link,
            uart_overruns: self.bus.uart_overruns(),
            repeated_ticks: self.repeated_ticks,
            stale_ticks: self.stale_ticks,
            ..Diagnostics::default()
        };
        if let Some(robot) = &self.robot {
            d.rfid = robot.rfid_counters();
            d.robot = robot.counters();
            d.pilot = robot.pilot().counters();
            d.tracker = robot.pilot().tracker().counters();
            d.observer_rejected_updates = robot.pilot().tracker().observer_rejected_updates();
        }
        if let Some(follower) = self.route_load.and_then(|_| self.route.follower()) {
            d.route = follower.counters();
        }
        d
    }

    fn configure(&mut self, c: &Configure) -> TargetMessage {
        if c.protocol != PROTOCOL_VERSION {
            return TargetMessage::Refused(Refusal::Protocol(PROTOCOL_VERSION));
        }
        if let FloorSpec::Map { tags } = c.floor
            && (tags == 0 || usize::from(tags) > MAP_CAPACITY)
        {
            return TargetMessage::Refused(Refusal::Map(MapRefusal::Size {
                tags,
                // `MAP_CAPACITY` fits (the link's tests).
                capacity: u16::try_from(MAP_CAPACITY).unwrap_or(u16::MAX),
            }));
        }
        let built = c.pilot.build().and_then(|config| {
            let pilot = Pilot::new(config).map_err(SpecError::Pilot)?;
            let floor = match c.floor {
                FloorSpec::Grid(grid) => SessionFloor::Grid(grid.build()?),
                FloorSpec::Map { .. } => SessionFloor::Map(self.map),
            };
            Ok((pilot, floor))
        });
        match built {
            Err(e) => TargetMessage::Refused(Refusal::Spec(e)),
            Ok((pilot, floor)) => {
                // The last run's robot goes before its map is emptied.
                self.robot = None;
                self.route_load = None;
                if let Some(mav) = self.mav.as_deref_mut() {
                    mav.run.deactivate();
                    mav.queues.reset();
                }
                self.map_load = match c.floor {
                    FloorSpec::Grid(_) => None,
                    FloorSpec::Map { tags } => {
                        if let Ok(mut map) = self.map.try_borrow_mut() {
                            map.clear();
                        }
                        Some(MapLoad {
                            announced: tags,
                            loaded: 0,
                        })
                    }
                };
                let bus = self.bus;
                bus.reset(c.pwm_max_duty);
                let motor = |side| {
                    MotorDriver::new(
                        bus.pwm(side),
                        bus.direction_pin(side),
                        MotorWiring::default(),
                    )
                };
                self.robot = Some(Robot::new(
                    pilot,
                    (bus.encoder(Side::Left), bus.encoder(Side::Right)),
                    (motor(Side::Left), motor(Side::Right)),
                    wmr_core::devices::RfidReader::new(bus.uart()),
                    floor,
                ));
                self.ticks = 0;
                self.last_answer = None;
                self.telemetry_every_ticks = c.telemetry_every_ticks;
                self.telemetry = None;
                match self.map_load {
                    Some(load) => TargetMessage::MapLoaded { tags: load.loaded },
                    None => TargetMessage::Configured,
                }
            }
        }
    }

    /// Loads a chunk of the announced tag map. A chunk refused while a map
    /// loads leaves the session unconfigured with its motors stopped; a
    /// chunk when no map is loading (`NotLoading`) is refused and changes
    /// nothing, so a stray chunk neither stops a running grid run nor
    /// leaves its motors turning without a robot to drive them.
    fn load_map(&mut self, chunk: &MapChunk) -> TargetMessage {
        match self.load_chunk(chunk) {
            Ok(answer) => answer,
            Err(MapRefusal::NotLoading) => {
                TargetMessage::Refused(Refusal::Map(MapRefusal::NotLoading))
            }
            Err(why) => {
                self.robot = None;
                self.map_load = None;
                self.bus.stop_motors();
                TargetMessage::Refused(Refusal::Map(why))
            }
        }
    }

    fn load_chunk(&mut self, chunk: &MapChunk) -> Result<TargetMessage, MapRefusal> {
        let Some(load) = self.map_load.as_mut().filter(|_| self.robot.is_some()) else {
            return Err(MapRefusal::NotLoading);
        };
        // At most `MAP_CHUNK_TAGS`.
        let n = u16::try_from(chunk.tags.len()).unwrap_or(u16::MAX);
        // The chunk just loaded, sent again (its answer was lost): the
        // same answer, nothing loaded twice.
        if n > 0 && chunk.first.checked_add(n) == Some(load.loaded) {
            return Ok(load.answer());
        }
        if chunk.first != load.loaded {
            return Err(MapRefusal::OutOfOrder {
                expected: load.loaded,
                first: chunk.first,
            });
        }
        if load
            .loaded
            .checked_add(n)
            .is_none_or(|end| end > load.announced)
        {
            return Err(MapRefusal::TooMany {
                announced: load.announced,
            });
        }
        let mut map = self
            .map
            .try_borrow_mut()
            .map_err(|_| MapRefusal::NotLoading)?;
        for tag in &chunk.tags {
            let [x, y] = tag.position_m;
            map.push(TagId(tag.id), Vec2::new(x, y))
                .map_err(|why| MapRefusal::Tag {
                    index: load.loaded,
                    why,
                })?;
            // At most `announced` (checked above).
            load.loaded += 1;
        }
        Ok(load.answer())
    }

    /// Unconfigures the session and stops its motors (a refused route).
    fn refuse_route(&mut self, why: RouteRefusal) -> TargetMessage {
        self.robot = None;
        self.map_load = None;
        self.route_load = None;
        if let Some(mav) = self.mav_active() {
            mav.run.deactivate();
        }
        self.bus.stop_motors();
        TargetMessage::Refused(Refusal::Route(why))
    }

    /// Takes a route's announcement: accepted only while the run is
    /// configured, before its first tick, with no route loading
    /// (`configured`: as [`Self::is_configured`] was on arrival); else
    /// refused, changing nothing.
    fn announce_route(&mut self, spec: &RouteSpec, configured: bool) -> TargetMessage {
        if !configured || self.last_answer.is_some() || self.route_load.is_some() {
            return TargetMessage::Refused(Refusal::Route(RouteRefusal::NotExpected));
        }
        let limits = match self.route.begin(spec) {
            Ok(limits) => limits,
            Err(e) => return self.refuse_route(e),
        };
        self.route_load = Some(RouteLoad {
            announced: spec.waypoints,
            loaded: 0,
            limits,
            start: spec.start,
            mavlink: spec.mavlink,
        });
        TargetMessage::RouteLoaded { waypoints: 0 }
    }

    /// Loads a chunk of the announced route; the last one is planned to
    /// check it and handed to the follower. A refusal while a route loads
    /// unconfigures the session; a chunk when none is loading
    /// (`NotLoading`) is refused and changes nothing.
    fn load_route(&mut self, chunk: &RouteChunk) -> TargetMessage {
        match self.load_route_chunk(chunk) {
            Ok(answer) => answer,
            Err(RouteRefusal::NotLoading) => {
                TargetMessage::Refused(Refusal::Route(RouteRefusal::NotLoading))
            }
            Err(why) => self.refuse_route(why),
        }
    }

    fn load_route_chunk(&mut self, chunk: &RouteChunk) -> Result<TargetMessage, RouteRefusal> {
        let Some(load) = self
            .route_load
            .as_mut()
            .filter(|l| !l.complete())
            .filter(|_| self.robot.is_some())
        else {
            // A chunk resent after the last one: answered again.
            return match self.route_load {
                Some(load) if self.last_answer.is_none() && is_resent(chunk, load.loaded) => {
                    Ok(TargetMessage::Configured)
                }
                _ => Err(RouteRefusal::NotLoading),
            };
        };
        // At most `ROUTE_CHUNK_WAYPOINTS`.
        let n = u8::try_from(chunk.waypoints.len()).unwrap_or(u8::MAX);
        // The chunk just loaded, sent again (its answer was lost): the
        // same answer, nothing loaded twice.
        if is_resent(chunk, load.loaded) {
            return Ok(TargetMessage::RouteLoaded {
                waypoints: load.loaded,
            });
        }
        if chunk.first != load.loaded {
            return Err(RouteRefusal::OutOfOrder {
                expected: load.loaded,
                first: chunk.first,
            });
        }
        if load
            .loaded
            .checked_add(n)
            .is_none_or(|end| end > load.announced)
        {
            return Err(RouteRefusal::TooMany {
                announced: load.announced,
            });
        }
        for w in &chunk.waypoints {
            // At most `announced` ≤ `ROUTE_CAPACITY` (checked above and
            // at the announcement): the push cannot fail.
            self.route.push(*w)?;
            load.loaded += 1;
        }
        if !load.complete() {
            return Ok(TargetMessage::RouteLoaded {
                waypoints: load.loaded,
            });
        }
        let period_s = self
            .robot
            .as_ref()
            .map_or(0.0, |r| r.pilot().tracker().config().clock().period_s());
        self.route.finish(&load.limits, load.start, period_s)?;
        let load = *load;
        // The settings were checked at the announcement: configured.
        if let (Some(mav), Ok(config)) = (self.mav.as_deref_mut(), load.mavlink.config()) {
            mav.run.activate(
                self.route,
                load.start,
                load.limits,
                period_s,
                config,
                load.mavlink.power_on,
            );
            if let Some(robot) = &self.robot {
                // The pilot's own: built by the same checks.
                let _ = mav.run.set_tuning(&robot.pilot().config().tuning());
            }
        }
        Ok(TargetMessage::Configured)
    }
}

/// The MAVLink endpoint's part of a tick, before the robot's (module
/// documentation): the bytes received since the last tick in, its output
/// into the send queue ([`MavlinkRun::before_tick`]). `last` is the last
/// tick's answer (the estimate the endpoint reports).
fn mavlink_tick(
    mav: &mut MavlinkStore,
    route: &mut RouteStore,
    tick: u32,
    last: Option<&TickOutput>,
) {
    let estimate = last.map(|a| mavlink_run::estimate(a.position_m, a.heading, a.command));
    let MavlinkStore { run, queues } = mav;
    queues.tick(|rx, room| run.before_tick(route, tick, estimate, rx, room));
}

/// The robot's counters to the endpoint after its tick, on a route run.
/// Not inlined: the counters are gathered in this frame, not in that of
/// [`Session::handle`], which is on the stack's deepest path.
#[inline(never)]
fn note_counts(mav: &mut MavlinkStore, robot: &ProxyRobot<'_>) {
    if mav.run.is_active() {
        mav.run.set_counts(wmr_mavlink::Counts::of(
            &robot.pilot().tracker().counters(),
            &robot.rfid_counters(),
            robot.counters().unknown_tags,
        ));
    }
}

/// Whether `chunk` is the last one loaded, sent again: it ends where the
/// loading stands and is not empty.
fn is_resent(chunk: &RouteChunk, loaded: u8) -> bool {
    let n = u8::try_from(chunk.waypoints.len()).unwrap_or(u8::MAX);
    n > 0 && chunk.first.checked_add(n) == Some(loaded)
}

/// Puts the record of the tick just answered in `slot` if the decimation
/// emits it. Not inlined: the record is built in this frame, not in the
/// frame of [`Session::handle`], which is on the stack's deepest path.
#[inline(never)]
fn note_telemetry(
    slot: &mut Option<telemetry::Record>,
    every_ticks: u16,
    answer: &Option<TickOutput>,
    extra: telemetry::Extra,
    robot: &ProxyRobot<'_>,
) {
    if let Some(answer) = answer
        && telemetry::is_emitted(extra.tick, every_ticks)
    {
        *slot = Some(telemetry::Record::of_answer(
            answer,
            extra,
            robot.counters(),
            robot.pilot().tracker().counters(),
        ));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ROUTE_CHUNK_WAYPOINTS;
    use crate::TickInput;
    use crate::{MAP_CHUNK_TAGS, MapTag};
    use crate::{MavlinkChunk, MavlinkIn};
    use wmr_core::devices::TagMapError;
    use wmr_core::devices::encode_frame;
    use wmr_core::devices::tag_grid::TagGridSpec;
    use wmr_core::pilot::route::{RouteCounters, RouteOptions, RouteOptionsError};
    use wmr_core::pilot::spec::{PilotSpec, TrackerSpec};
    use wmr_core::pilot::tracker::TrackerMode;
    use wmr_core::reference::TrajectorySpec;
    use wmr_core::reference::route::{
        LimitKey, ROUTE_CAPACITY, RouteError, RouteLimitsError, RouteLimitsSpec, Waypoint,
        WaypointKey, Waypoints,
    };

    /// The grid of [`configure`]: 21 × 21 tags 0.1 m apart around the
    /// origin.
    fn grid() -> TagGridSpec {
        TagGridSpec {
            origin_m: [-1.0, -1.0],
            spacing_m: 0.1,
            rows: 21,
            columns: 21,
        }
    }

    /// Tag `i` of [`map_tags`]: an arbitrary 40-bit id, increasing with
    /// `i`.
    fn map_id(i: u16) -> u64 {
        0x12_0000_0000 + 7919 * u64::from(i)
    }

    /// `n` tags on the x axis 0.1 m apart from -1 m (tag 12 at 0.2 m),
    /// ids from [`map_id`].
    fn map_tags(n: u16) -> std::vec::Vec<MapTag> {
        (0..n)
            .map(|i| MapTag {
                id: map_id(i),
                position_m: [0.1 * f32::from(i) - 1.0, 0.0],
            })
            .collect()
    }

    fn chunk(first: u16, tags: &[MapTag]) -> HostMessage {
        HostMessage::MapChunk(MapChunk {
            first,
            tags: heapless::Vec::from_slice(tags).unwrap(),
        })
    }

    fn map_configure(tags: u16) -> HostMessage {
        HostMessage::Configure(Configure {
            floor: FloorSpec::Map { tags },
            ..configure()
        })
    }

    pub(crate) fn configure() -> Configure {
        Configure {
            protocol: PROTOCOL_VERSION,
            pilot: PilotSpec {
                tracker: TrackerSpec {
                    trajectory: TrajectorySpec::Line {
                        start_m: [0.0, 0.0],
                        heading_rad: 0.0,
                        speed_m_s: 0.2,
                    },
                    ..PilotSpec::EXAMPLE.tracker
                },
                ..PilotSpec::EXAMPLE
            },
            floor: FloorSpec::Grid(grid()),
            pwm_max_duty: 1000,
            telemetry_every_ticks: 0,
        }
    }

    #[test]
    fn configure_then_tick_drives_the_proxies() {
        let bus = ProxyBus::new();
        let map = RefCell::new(LinkTagMap::new());
        let mut route = RouteStore::new();
        let mut s = Session::new(&bus, &map, &mut route);
        let link = LinkCounters::default();
        let tick = |k, uart: &[u8]| {
            HostMessage::Tick(TickInput {
                tick: k,
                left_count: Some(0),
                right_count: Some(0),
                uart: heapless::Vec::from_slice(uart).unwrap(),
            })
        };
        assert_eq!(
            s.handle(&tick(0, &[]), link, || 0).0,
            TargetMessage::Refused(Refusal::NotConfigured)
        );
        let mut bad = configure();
        bad.pilot.tracker.gains[0] = -1.0;
        assert!(matches!(
            s.handle(&HostMessage::Configure(bad), link, || 0).0,
            TargetMessage::Refused(Refusal::Spec(SpecError::Gains(_)))
        ));
        assert_eq!(
            s.handle(&HostMessage::Configure(configure()), link, || 0).0,
            TargetMessage::Configured
        );
        // The tag at row 10, column 12 of the grid: (0.2, 0.0).
        let frame = encode_frame(TagGrid::id(10, 12));
        let (answer, done) = s.handle(&tick(0, &frame), link, || 0);
        assert!(!done);
        let TargetMessage::Ticked(out) = answer else {
            panic!("{answer:?}")
        };
        assert!(out.fix);
        assert_eq!(out.mode, TrackerMode::Tracking);
        assert!((out.position_m[0] - 0.2).abs() < 1e-6);
        let (answer, done) = s.handle(&HostMessage::Finish, link, || 1234);
        assert!(done);
        let TargetMessage::Finished(finished) = answer else {
            panic!("{answer:?}")
        };
        assert_eq!((finished.ticks, finished.peak_stack_bytes), (1, 1234));
        assert_eq!(finished.counters.rfid.frames_ok, 1);
    }

    /// The session's telemetry (built from its answer, [`Record::of_answer`])
    /// is [`Record::of`] of the same robot's tick, every third tick from
    /// tick 0, none for a resent tick; the start says the decimation and
    /// the period.
    ///
    /// [`Record::of_answer`]: telemetry::Record::of_answer
    /// [`Record::of`]: telemetry::Record::of
    #[test]
    fn telemetry_is_the_robots_tick_every_nth_tick() {
        let bus = ProxyBus::new();
        let map = RefCell::new(LinkTagMap::new());
        let mut route = RouteStore::new();
        let mut s = Session::new(&bus, &map, &mut route);
        let link = LinkCounters::default();
        let c = Configure {
            telemetry_every_ticks: 3,
            ..configure()
        };
        assert_eq!(s.telemetry_start(), None, "not configured");
        s.handle(&HostMessage::Configure(c), link, || 0);
        assert_eq!(
            s.telemetry_start(),
            Some(telemetry::Start {
                every_ticks: 3,
                period_s: 0.01
            })
        );
        // The same robot, ticked directly.
        let twin_bus = ProxyBus::new();
        twin_bus.reset(c.pwm_max_duty);
        let motor = |side| {
            MotorDriver::new(
                twin_bus.pwm(side),
                twin_bus.direction_pin(side),
                MotorWiring::default(),
            )
        };
        let mut twin = Robot::new(
            Pilot::new(c.pilot.build().unwrap()).unwrap(),
            (twin_bus.encoder(Side::Left), twin_bus.encoder(Side::Right)),
            (motor(Side::Left), motor(Side::Right)),
            wmr_core::devices::RfidReader::new(twin_bus.uart()),
            SessionFloor::Grid(grid().build().unwrap()),
        );
        let mut emitted = std::vec::Vec::new();
        for k in 0..12_u32 {
            let frame = encode_frame(TagGrid::id(10, 10 + u16::from(k % 2 == 1)));
            let input = TickInput {
                tick: k,
                left_count: Some(7 * k),
                right_count: (k != 5).then_some(9 * k),
                uart: heapless::Vec::from_slice(&frame).unwrap(),
            };
            s.handle(&HostMessage::Tick(input.clone()), link, || 0);
            twin_bus.load(&input);
            let out = twin.tick();
            let expected =
                telemetry::Record::of(&out, twin.counters(), twin.pilot().tracker().counters());
            match s.telemetry() {
                Some(r) => {
                    assert_eq!(std::format!("{r:?}"), std::format!("{expected:?}"));
                    emitted.push(r.tick);
                }
                None => assert!(k % 3 != 0, "tick {k} not emitted"),
            }
            // Resent: answered from the cache, no record.
            s.handle(&HostMessage::Tick(input), link, || 0);
            assert_eq!(s.telemetry(), None);
        }
        assert_eq!(emitted, [0, 3, 6, 9]);
    }

    /// A tag map announced in `Configure` is loaded chunk by chunk (a
    /// chunk sent again is answered again, not loaded twice), the run
    /// starts only when the last tag is in, and the robot then resolves
    /// the map's arbitrary ids to their positions (an id not in the map is
    /// counted as unknown). A second map replaces the first whole.
    #[test]
    fn a_tag_map_is_loaded_in_chunks_and_the_robot_looks_ids_up_in_it() {
        let bus = ProxyBus::new();
        let map = RefCell::new(LinkTagMap::new());
        let mut route = RouteStore::new();
        let mut s = Session::new(&bus, &map, &mut route);
        let link = LinkCounters::default();
        let tick = |k, id: u64| {
            HostMessage::Tick(TickInput {
                tick: k,
                left_count: Some(0),
                right_count: Some(0),
                uart: heapless::Vec::from_slice(&encode_frame(TagId(id))).unwrap(),
            })
        };
        let tags = map_tags(20);
        let answer = |s: &mut Session<'_>, m: &HostMessage| s.handle(m, link, || 0).0;
        assert_eq!(
            answer(&mut s, &map_configure(20)),
            TargetMessage::MapLoaded { tags: 0 }
        );
        assert!(!s.is_configured());
        assert_eq!(
            answer(&mut s, &tick(0, map_id(12))),
            TargetMessage::Refused(Refusal::NotConfigured),
            "no tick before the whole map"
        );
        let k = u16::try_from(MAP_CHUNK_TAGS).unwrap();
        let first = chunk(0, &tags[..MAP_CHUNK_TAGS]);
        assert_eq!(answer(&mut s, &first), TargetMessage::MapLoaded { tags: k });
        // Its answer lost, sent again: the same answer, loaded once.
        assert_eq!(answer(&mut s, &first), TargetMessage::MapLoaded { tags: k });
        assert_eq!(map.borrow().len(), MAP_CHUNK_TAGS);
        let last = chunk(k, &tags[MAP_CHUNK_TAGS..]);
        assert_eq!(answer(&mut s, &last), TargetMessage::Configured);
        assert_eq!(answer(&mut s, &last), TargetMessage::Configured);
        assert!(s.is_configured());
        assert_eq!(map.borrow().len(), 20);

        let TargetMessage::Ticked(out) = answer(&mut s, &tick(0, map_id(12))) else {
            panic!("not ticked")
        };
        assert!(out.fix);
        assert!((out.position_m[0] - 0.2).abs() < 1e-6, "{out:?}");
        assert!(out.position_m[1].abs() < 1e-6, "{out:?}");
        // A grid id is not in this map.
        answer(&mut s, &tick(1, TagGrid::id(10, 12).0));
        let d = s.diagnostics(link);
        assert_eq!((d.rfid.frames_ok, d.robot.unknown_tags), (2, 1));

        // Another map: the first one's tags are gone.
        assert_eq!(
            answer(&mut s, &map_configure(1)),
            TargetMessage::MapLoaded { tags: 0 }
        );
        let other = [MapTag {
            id: 0xFF_0000_0001,
            position_m: [0.5, 0.0],
        }];
        assert_eq!(answer(&mut s, &chunk(0, &other)), TargetMessage::Configured);
        assert_eq!(map.borrow().len(), 1);
        assert_eq!(map.borrow().position(TagId(map_id(12))), None);
    }

    /// What the core's `TagMap` refuses, and a map out of order, too long,
    /// unsorted or not announced, is refused naming the tag and why; the
    /// session is then not configured, and a new `Configure` starts over.
    #[test]
    fn a_bad_map_is_refused_naming_the_tag_and_why() {
        let bus = ProxyBus::new();
        let map = RefCell::new(LinkTagMap::new());
        let mut route = RouteStore::new();
        let mut s = Session::new(&bus, &map, &mut route);
        let link = LinkCounters::default();
        let mut answer = |m: &HostMessage| s.handle(m, link, || 0).0;
        let refused = |why| TargetMessage::Refused(Refusal::Map(why));
        let capacity = 4096;
        for tags in [0, 4097] {
            assert_eq!(
                answer(&map_configure(tags)),
                refused(MapRefusal::Size { tags, capacity })
            );
        }
        let tags = map_tags(4);
        assert_eq!(answer(&chunk(0, &tags)), refused(MapRefusal::NotLoading));
        let cases: [(&[MapTag], MapRefusal); 4] = [
            (
                &[tags[0], tags[1], tags[1]],
                MapRefusal::Tag {
                    index: 2,
                    why: TagMapError::DuplicateId,
                },
            ),
            (
                &[
                    tags[0],
                    MapTag {
                        position_m: [f32::NAN, 0.0],
                        ..tags[1]
                    },
                ],
                MapRefusal::Tag {
                    index: 1,
                    why: TagMapError::NonFinitePosition,
                },
            ),
            (
                &[tags[0], tags[2], tags[1]],
                MapRefusal::Tag {
                    index: 2,
                    why: TagMapError::Unsorted,
                },
            ),
            (&tags, MapRefusal::TooMany { announced: 3 }),
        ];
        for (sent, why) in cases {
            assert_eq!(
                answer(&map_configure(3)),
                TargetMessage::MapLoaded { tags: 0 }
            );
            assert_eq!(answer(&chunk(0, sent)), refused(why));
            // Not configured: no tick, no more chunks.
            assert_eq!(
                answer(&HostMessage::Tick(TickInput {
                    tick: 0,
                    left_count: Some(0),
                    right_count: Some(0),
                    uart: heapless::Vec::new(),
                })),
                TargetMessage::Refused(Refusal::NotConfigured)
            );
            assert_eq!(
                answer(&chunk(3, &tags[3..])),
                refused(MapRefusal::NotLoading)
            );
        }
        assert_eq!(
            answer(&map_configure(4)),
            TargetMessage::MapLoaded { tags: 0 }
        );
        assert_eq!(
            answer(&chunk(2, &tags[2..])),
            refused(MapRefusal::OutOfOrder {
                expected: 0,
                first: 2
            })
        );
        // A grid run after all that.
        assert_eq!(
            answer(&HostMessage::Configure(configure())),
            TargetMessage::Configured
        );
    }

    #[test]
    fn a_silent_link_stops_the_motors() {
        let bus = ProxyBus::new();
        let map = RefCell::new(LinkTagMap::new());
        let mut route = RouteStore::new();
        let mut s = Session::new(&bus, &map, &mut route);
        let link = LinkCounters::default();
        s.handle(&HostMessage::Configure(configure()), link, || 0);
        // Behind the reference with a fix every tick: the robot drives.
        let mut driven = false;
        for k in 0..50 {
            let frame = encode_frame(TagGrid::id(10, 10));
            let msg = HostMessage::Tick(TickInput {
                tick: k,
                left_count: Some(0),
                right_count: Some(0),
                uart: heapless::Vec::from_slice(&frame).unwrap(),
            });
            if let (TargetMessage::Ticked(out), _) = s.handle(&msg, link, || 0) {
                driven |= out.left.duty > 0 || out.right.duty > 0;
            }
        }
        assert!(driven);
        let report = s.link_silent(crate::LINK_TIMEOUT_MS);
        assert_eq!(bus.motor(Side::Left).duty, 0);
        assert_eq!(bus.motor(Side::Right).duty, 0);
        let TargetMessage::LinkSilent { motors, silent_ms } = report else {
            panic!("{report:?}")
        };
        assert_eq!(silent_ms, crate::LINK_TIMEOUT_MS);
        assert!(motors.iter().all(|m| m.duty == 0));
    }

    /// A map chunk while a grid run drives (no map announced) is refused
    /// and leaves the run as it was: still configured, still ticking. A
    /// regression test for a finding of the `link_session` fuzz target:
    /// without the fix, the refusal unconfigures the session and leaves the
    /// motors at their last duty with no robot to drive or stop them.
    #[test]
    fn a_stray_map_chunk_leaves_a_running_robot_alone() {
        let bus = ProxyBus::new();
        let map = RefCell::new(LinkTagMap::new());
        let mut route = RouteStore::new();
        let mut s = Session::new(&bus, &map, &mut route);
        let link = LinkCounters::default();
        s.handle(&HostMessage::Configure(configure()), link, || 0);
        let tick = |k| {
            HostMessage::Tick(TickInput {
                tick: k,
                left_count: Some(0),
                right_count: Some(0),
                uart: heapless::Vec::from_slice(&encode_frame(TagGrid::id(10, 10))).unwrap(),
            })
        };
        let mut driven = false;
        for k in 0..50 {
            if let (TargetMessage::Ticked(out), _) = s.handle(&tick(k), link, || 0) {
                driven |= out.left.duty > 0 || out.right.duty > 0;
            }
        }
        assert!(driven);
        assert_eq!(
            s.handle(&chunk(0, &map_tags(3)), link, || 0).0,
            TargetMessage::Refused(Refusal::Map(MapRefusal::NotLoading))
        );
        assert!(s.is_configured());
        assert!(matches!(
            s.handle(&tick(50), link, || 0).0,
            TargetMessage::Ticked(_)
        ));
    }

    /// A resent tick is answered again without running the robot twice; an
    /// older tick is refused; both are counted.
    #[test]
    fn a_resent_tick_is_answered_again_and_an_older_one_refused() {
        let bus = ProxyBus::new();
        let map = RefCell::new(LinkTagMap::new());
        let mut route = RouteStore::new();
        let mut s = Session::new(&bus, &map, &mut route);
        let link = LinkCounters::default();
        s.handle(&HostMessage::Configure(configure()), link, || 0);
        let tick = |k: u32, counts: u32| {
            let frame = encode_frame(TagGrid::id(10, 10));
            HostMessage::Tick(TickInput {
                tick: k,
                left_count: Some(counts),
                right_count: Some(counts),
                uart: heapless::Vec::from_slice(&frame).unwrap(),
            })
        };
        for k in 0..5 {
            s.handle(&tick(k, 10 * k), link, || 0);
        }
        let (first, _) = s.handle(&tick(5, 50), link, || 0);
        // The same tick again, even with other readings: the first answer.
        let (again, _) = s.handle(&tick(5, 999), link, || 0);
        assert_eq!(again, first);
        let (older, _) = s.handle(&tick(3, 30), link, || 0);
        assert_eq!(
            older,
            TargetMessage::Refused(Refusal::StaleTick { last_answered: 5 })
        );
        let (TargetMessage::Finished(f), true) = s.handle(&HostMessage::Finish, link, || 0) else {
            panic!("no report")
        };
        assert_eq!(f.ticks, 6, "the robot ran each tick once");
        assert_eq!((f.counters.repeated_ticks, f.counters.stale_ticks), (1, 1));
    }

    /// Route limits the test routes fit: 0.3 m/s, 0.5 m/s² along and
    /// across, blends 5 mm from their corners, pivots above 0.5 rad.
    const LIMITS: RouteLimitsSpec = RouteLimitsSpec {
        max_speed_m_s: 0.3,
        max_tangential_accel_m_s2: 0.5,
        max_lateral_accel_m_s2: 0.5,
        blend_deviation_m: 0.005,
        pivot_threshold_rad: 0.5,
        pivot_rate_rad_s: 1.0,
        pivot_accel_rad_s2: 2.0,
    };

    /// `n` waypoints (n ≥ 2) on a zig-zag inside the grid of
    /// [`configure`], from the origin along +x, a stop at each end.
    fn zigzag(n: usize) -> std::vec::Vec<Waypoint> {
        (0..n)
            .map(|i| {
                let x = 0.1 * i as f32;
                let y = if i % 2 == 0 { 0.0 } else { 0.05 };
                if i == 0 || i + 1 == n {
                    Waypoint::stop(x, y, 0.0)
                } else {
                    Waypoint::pass(x, y)
                }
            })
            .collect()
    }

    fn announce(waypoints: u8) -> HostMessage {
        HostMessage::Route(RouteSpec {
            waypoints,
            limits: LIMITS,
            options: RouteOptions::default().spec(),
            start: RouteStart::AsGiven,
            mavlink: crate::MavlinkSettings::default(),
        })
    }

    fn route_chunk(first: u8, waypoints: &[Waypoint]) -> HostMessage {
        HostMessage::RouteChunk(RouteChunk {
            first,
            waypoints: heapless::Vec::from_slice(waypoints).unwrap(),
        })
    }

    fn still_tick(k: u32, fix: bool) -> HostMessage {
        let uart = if fix {
            heapless::Vec::from_slice(&encode_frame(TagGrid::id(10, 10))).unwrap()
        } else {
            heapless::Vec::new()
        };
        HostMessage::Tick(TickInput {
            tick: k,
            left_count: Some(0),
            right_count: Some(0),
            uart,
        })
    }

    /// A route announced after `Configured` is loaded chunk by chunk into
    /// the core's `Waypoints` (a chunk sent again is answered again, not
    /// loaded twice), the run starts only when the last waypoint is in,
    /// and the robot then follows the route, not the pilot's trajectory:
    /// the reference starts at the first waypoint and moves along the
    /// first leg; `Finished` carries the follower's counters.
    #[test]
    fn a_route_is_loaded_in_chunks_and_the_robot_follows_it() {
        let bus = ProxyBus::new();
        let map = RefCell::new(LinkTagMap::new());
        let mut route = RouteStore::new();
        let mut s = Session::new(&bus, &map, &mut route);
        let link = LinkCounters::default();
        let answer = |s: &mut Session<'_>, m: &HostMessage| s.handle(m, link, || 0).0;
        let ws = zigzag(9);
        assert_eq!(
            answer(&mut s, &HostMessage::Configure(configure())),
            TargetMessage::Configured
        );
        assert_eq!(
            answer(&mut s, &announce(9)),
            TargetMessage::RouteLoaded { waypoints: 0 }
        );
        assert!(!s.is_configured());
        assert_eq!(
            answer(&mut s, &still_tick(0, true)),
            TargetMessage::Refused(Refusal::NotConfigured),
            "no tick before the whole route"
        );
        let first = route_chunk(0, &ws[..ROUTE_CHUNK_WAYPOINTS]);
        let k = u8::try_from(ROUTE_CHUNK_WAYPOINTS).unwrap();
        assert_eq!(
            answer(&mut s, &first),
            TargetMessage::RouteLoaded { waypoints: k }
        );
        // Its answer lost, sent again: the same answer, loaded once.
        assert_eq!(
            answer(&mut s, &first),
            TargetMessage::RouteLoaded { waypoints: k }
        );
        assert_eq!(s.route.waypoints().len(), ROUTE_CHUNK_WAYPOINTS);
        let last = route_chunk(k, &ws[ROUTE_CHUNK_WAYPOINTS..]);
        assert_eq!(answer(&mut s, &last), TargetMessage::Configured);
        assert_eq!(answer(&mut s, &last), TargetMessage::Configured);
        assert!(s.is_configured());
        assert_eq!(s.route.waypoints().as_slice(), &ws[..]);
        assert_eq!(s.route_status().map(|r| r.pending), Some(true));

        // The fix at (0, 0), the first waypoint, every tick.
        let mut references = std::vec::Vec::new();
        for k in 0..100 {
            let TargetMessage::Ticked(out) = answer(&mut s, &still_tick(k, true)) else {
                panic!("not ticked")
            };
            references.push(out.reference_m);
        }
        assert_eq!(references[0], [0.0, 0.0], "starts at the first waypoint");
        // 0.2 s in, at 0.5 m/s²: 1 cm along the first leg, toward (0.1, 0.05).
        let [x, y] = references[20];
        assert!(x > 0.005 && x < 0.1, "{x}");
        assert!((y - 0.5 * x).abs() < 1e-6, "on the first leg: {x}, {y}");
        assert!(references.windows(2).all(|w| w[1][0] >= w[0][0]));
        // The robot stands still at the first waypoint: the route's clock
        // waits for it once the reference is `max_lag_m` (5 cm) ahead.
        let [x, y] = references[99];
        let ahead = x.hypot(y);
        assert!(ahead > 0.05 && ahead < 0.051, "{ahead}");
        let status = s.route_status().unwrap();
        assert!(status.running && !status.done && !status.pending);
        let (TargetMessage::Finished(f), true) = s.handle(&HostMessage::Finish, link, || 0) else {
            panic!("no report")
        };
        assert_eq!(f.counters.route.routes_started, 1);
        assert_eq!(f.counters.route.routes_refused, 0);
        assert!(!f.route_done);
        assert!(f.counters.route.clock_wait_ticks > 0);
    }

    fn idle_store() -> MavlinkStore {
        use wmr_mavlink::EndpointSpec;
        MavlinkStore::new(
            EndpointConfig::new(&EndpointSpec::default()).unwrap(),
            RouteLimits::new(&MavlinkStore::IDLE_LIMITS).unwrap(),
        )
    }

    /// A MAVLink 2 frame from a ground station (system 255, component
    /// 190), written by the endpoint's own encoder.
    fn mav_frame(seq: u8, msg_id: u32, extra: u8, payload: &[u8]) -> std::vec::Vec<u8> {
        let mut buf = [0_u8; 300];
        let mut tx = wmr_mavlink::TxBuffer::new(&mut buf);
        assert!(tx.frame([seq, 255, 190], msg_id, extra, payload));
        tx.as_slice().to_vec()
    }

    /// A ground station's heartbeat (`MAV_TYPE_GCS`).
    fn gcs_heartbeat(seq: u8) -> std::vec::Vec<u8> {
        mav_frame(seq, 0, 50, &[0, 0, 0, 0, 6, 8, 0, 4, 3])
    }

    /// `COMMAND_LONG` to system 1, component 1.
    fn command_long(seq: u8, command: u16, param1: f32) -> std::vec::Vec<u8> {
        let mut p = std::vec::Vec::new();
        p.extend_from_slice(&param1.to_le_bytes());
        p.extend_from_slice(&[0; 24]);
        p.extend_from_slice(&command.to_le_bytes());
        p.extend_from_slice(&[1, 1, 0]);
        mav_frame(seq, 76, 152, &p)
    }

    /// Sends `bytes` and then asks until nothing is pending; returns
    /// what the firmware's endpoint wrote.
    fn exchange(s: &mut Session<'_>, seq: &mut u32, bytes: &[u8]) -> std::vec::Vec<u8> {
        let link = LinkCounters::default();
        let mut got = std::vec::Vec::new();
        let mut rest = bytes;
        loop {
            let chunk = MavlinkChunk::from_slice(rest);
            rest = &rest[chunk.len()..];
            let m = HostMessage::Mavlink(MavlinkIn {
                seq: *seq,
                bytes: chunk,
            });
            *seq += 1;
            let TargetMessage::Mavlink(out) = s.handle(&m, link, || 0).0 else {
                panic!("not a MAVLink answer")
            };
            got.extend_from_slice(out.bytes.as_slice());
            if rest.is_empty() && out.pending == 0 {
                return got;
            }
        }
    }

    /// The message ids of the MAVLink 2 frames in `bytes`, in order.
    fn frame_ids(bytes: &[u8]) -> std::vec::Vec<u32> {
        let mut ids = std::vec::Vec::new();
        let mut i = 0;
        while i + 12 <= bytes.len() {
            assert_eq!(bytes[i], 0xFD, "a frame starts at {i}");
            let len = usize::from(bytes[i + 1]);
            ids.push(u32::from_le_bytes([
                bytes[i + 7],
                bytes[i + 8],
                bytes[i + 9],
                0,
            ]));
            i += 12 + len;
        }
        assert_eq!(i, bytes.len(), "whole frames");
        ids
    }

    /// A route run's session answers a ground station through its
    /// endpoint: heartbeats out, and a pause command stops the route (a
    /// fresh follower holds the robot) and is acknowledged; the run's
    /// ticks before it are those of a run without MAVLink. A run
    /// without a route has no endpoint: its bytes are counted dropped.
    /// (The session is lent the endpoint's store as the QEMU board lends
    /// it.)
    #[test]
    fn a_route_run_talks_mavlink_and_a_pause_holds_the_robot() {
        let link = LinkCounters::default();
        let ticks = |with_mavlink: bool| {
            let bus = ProxyBus::new();
            let map = RefCell::new(LinkTagMap::new());
            let mut route = RouteStore::new();
            let mut store = std::boxed::Box::new(idle_store());
            let mut s = Session::new(&bus, &map, &mut route);
            s.lend_mavlink(&mut store);
            let answer = |s: &mut Session<'_>, m: &HostMessage| s.handle(m, link, || 0).0;
            answer(&mut s, &HostMessage::Configure(configure()));
            answer(&mut s, &announce(3));
            assert_eq!(
                answer(&mut s, &route_chunk(0, &zigzag(3))),
                TargetMessage::Configured
            );
            let mut seq = 0;
            let mut outs = std::vec::Vec::new();
            let mut sent = std::vec::Vec::new();
            for k in 0..40 {
                outs.push(answer(&mut s, &still_tick(k, true)));
                if with_mavlink {
                    sent.extend(exchange(&mut s, &mut seq, &[]));
                }
            }
            let status = s.route_status().unwrap();
            assert!(status.running, "the route runs from the first tick");
            if with_mavlink {
                // Heartbeats (id 0) and the rest of the endpoint's output.
                let ids = frame_ids(&sent);
                assert!(ids.contains(&0), "{ids:?}");
                let mut bytes = gcs_heartbeat(0);
                bytes.extend(command_long(1, 193, 0.0));
                let got = exchange(&mut s, &mut seq, &bytes);
                assert!(got.is_empty(), "answered at the next tick");
                answer(&mut s, &still_tick(40, true));
                let got = exchange(&mut s, &mut seq, &[]);
                // COMMAND_ACK (77).
                assert!(frame_ids(&got).contains(&77), "{:?}", frame_ids(&got));
                let status = s.route_status().unwrap();
                assert!(!status.running, "a fresh follower: holding");
                assert_eq!(s.route_follower().unwrap().counters().routes_started, 0);
            }
            outs
        };
        assert_eq!(ticks(false), ticks(true), "MAVLink output changes no tick");

        let bus = ProxyBus::new();
        let map = RefCell::new(LinkTagMap::new());
        let mut route = RouteStore::new();
        let mut store = std::boxed::Box::new(idle_store());
        let mut s = Session::new(&bus, &map, &mut route);
        s.lend_mavlink(&mut store);
        s.handle(&HostMessage::Configure(configure()), link, || 0);
        let m = HostMessage::Mavlink(MavlinkIn {
            seq: 0,
            bytes: MavlinkChunk::from_slice(&gcs_heartbeat(0)),
        });
        let TargetMessage::Mavlink(out) = s.handle(&m, link, || 0).0 else {
            panic!("not a MAVLink answer")
        };
        assert_eq!(out.counters.rx_dropped_bytes, gcs_heartbeat(0).len() as u32);
        assert!(out.bytes.is_empty());
    }

    /// Without a route the session's robot is the core's `Robot`, bit for
    /// bit (the telemetry test ticks both side by side); a grid run's
    /// `Finished` has zero route counters and no route done.
    #[test]
    fn a_run_without_a_route_reports_no_route() {
        let bus = ProxyBus::new();
        let map = RefCell::new(LinkTagMap::new());
        let mut route = RouteStore::new();
        let mut s = Session::new(&bus, &map, &mut route);
        let link = LinkCounters::default();
        s.handle(&HostMessage::Configure(configure()), link, || 0);
        for k in 0..10 {
            s.handle(&still_tick(k, true), link, || 0);
        }
        assert_eq!(s.route_status(), None);
        let (TargetMessage::Finished(f), true) = s.handle(&HostMessage::Finish, link, || 0) else {
            panic!("no report")
        };
        assert_eq!(f.counters.route, RouteCounters::default());
        assert!(!f.route_done);
    }

    /// What the core refuses (a count, a limit, an option, a waypoint: by
    /// its index and key) and a route out of order or too long is refused
    /// naming which and why; the session is then not configured, its
    /// motors stopped, and takes no chunk. A route outside its window (no
    /// configuration, or a run that ticked) and a stray chunk are refused
    /// and change nothing.
    #[test]
    fn a_bad_route_is_refused_naming_the_waypoint_and_key() {
        let bus = ProxyBus::new();
        let map = RefCell::new(LinkTagMap::new());
        let mut route = RouteStore::new();
        let mut s = Session::new(&bus, &map, &mut route);
        let link = LinkCounters::default();
        let answer = |s: &mut Session<'_>, m: &HostMessage| s.handle(m, link, || 0).0;
        let refused = |why| TargetMessage::Refused(Refusal::Route(why));
        let ws = zigzag(4);
        assert_eq!(
            answer(&mut s, &announce(4)),
            refused(RouteRefusal::NotExpected),
            "before any configuration"
        );
        let configured = |s: &mut Session<'_>| {
            let c = HostMessage::Configure(configure());
            assert_eq!(s.handle(&c, link, || 0).0, TargetMessage::Configured);
        };
        configured(&mut s);
        assert_eq!(
            answer(&mut s, &route_chunk(0, &ws)),
            refused(RouteRefusal::NotLoading)
        );
        assert!(s.is_configured(), "a stray chunk changes nothing");

        let with = |f: &dyn Fn(&mut RouteSpec)| {
            let HostMessage::Route(mut spec) = announce(4) else {
                unreachable!()
            };
            f(&mut spec);
            HostMessage::Route(spec)
        };
        let at_announce: [(HostMessage, RouteRefusal); 5] = [
            (
                announce(1),
                RouteRefusal::Size {
                    waypoints: 1,
                    capacity: 64,
                },
            ),
            (
                announce(65),
                RouteRefusal::Size {
                    waypoints: 65,
                    capacity: 64,
                },
            ),
            (
                with(&|r| r.limits.max_speed_m_s = f32::NAN),
                RouteRefusal::Limits(RouteLimitsError(LimitKey::MaxSpeed)),
            ),
            (
                with(&|r| r.limits.pivot_threshold_rad = 4.0),
                RouteRefusal::Limits(RouteLimitsError(LimitKey::PivotThreshold)),
            ),
            (
                with(&|r| r.options.pivot_gain_per_s = 0.0),
                RouteRefusal::Options(RouteOptionsError::PivotGain),
            ),
        ];
        let unconfigured = |s: &mut Session<'_>| {
            assert!(!s.is_configured());
            assert_eq!(bus.motor(Side::Left).duty, 0);
            assert_eq!(bus.motor(Side::Right).duty, 0);
            assert_eq!(
                s.handle(&still_tick(0, true), link, || 0).0,
                TargetMessage::Refused(Refusal::NotConfigured)
            );
            assert_eq!(
                s.handle(&route_chunk(0, &zigzag(2)), link, || 0).0,
                TargetMessage::Refused(Refusal::Route(RouteRefusal::NotLoading))
            );
        };
        for (sent, why) in at_announce {
            configured(&mut s);
            assert_eq!(answer(&mut s, &sent), refused(why));
            unconfigured(&mut s);
        }

        let mut nan_dwell = ws.clone();
        nan_dwell[3] = Waypoint::stop(0.3, 0.05, f32::NAN);
        let mut repeated = ws.clone();
        repeated[2] = repeated[1];
        let mut too_far = ws.clone();
        too_far[1] = Waypoint::pass(1.0e6, 0.0);
        let mut bad_face = ws.clone();
        bad_face[0] = bad_face[0].facing(f32::INFINITY);
        let in_chunks: [(&[Waypoint], RouteRefusal); 6] = [
            (
                &nan_dwell,
                RouteRefusal::Route(RouteError::NotFinite {
                    index: 3,
                    key: WaypointKey::Dwell,
                }),
            ),
            (
                &repeated,
                RouteRefusal::Route(RouteError::SameAsPrevious { index: 2 }),
            ),
            (
                &too_far,
                RouteRefusal::Route(RouteError::OutOfRange {
                    index: 1,
                    key: WaypointKey::Position,
                }),
            ),
            (
                &bad_face,
                RouteRefusal::Route(RouteError::NotFinite {
                    index: 0,
                    key: WaypointKey::FaceHeading,
                }),
            ),
            (&zigzag(5), RouteRefusal::TooMany { announced: 4 }),
            (
                &ws[1..],
                RouteRefusal::OutOfOrder {
                    expected: 0,
                    first: 1,
                },
            ),
        ];
        for (i, (sent, why)) in in_chunks.into_iter().enumerate() {
            configured(&mut s);
            assert_eq!(
                answer(&mut s, &announce(4)),
                TargetMessage::RouteLoaded { waypoints: 0 }
            );
            let first = if i == 5 { 1 } else { 0 };
            assert_eq!(answer(&mut s, &route_chunk(first, sent)), refused(why));
            unconfigured(&mut s);
        }

        // A run that ticked takes no route, and runs on.
        configured(&mut s);
        assert!(matches!(
            answer(&mut s, &still_tick(0, true)),
            TargetMessage::Ticked(_)
        ));
        assert_eq!(
            answer(&mut s, &announce(4)),
            refused(RouteRefusal::NotExpected)
        );
        assert!(s.is_configured());
        assert!(matches!(
            answer(&mut s, &still_tick(1, true)),
            TargetMessage::Ticked(_)
        ));
    }

    /// [`route_messages`] gives the announcement and then full chunks in
    /// order: a session loads a route of `ROUTE_CAPACITY` waypoints from
    /// them, acknowledged with the count so far, the last `Configured`.
    ///
    /// [`route_messages`]: crate::route_messages
    #[test]
    fn route_messages_load_a_full_route() {
        let bus = ProxyBus::new();
        let map = RefCell::new(LinkTagMap::new());
        let mut route = RouteStore::new();
        let mut s = Session::new(&bus, &map, &mut route);
        let link = LinkCounters::default();
        s.handle(&HostMessage::Configure(configure()), link, || 0);
        let ws = Waypoints::from_slice(&zigzag(ROUTE_CAPACITY)).unwrap();
        let messages: std::vec::Vec<_> = crate::route_messages(
            &ws,
            LIMITS,
            &RouteOptions::default(),
            RouteStart::FromFirstFix,
            crate::MavlinkSettings::default(),
        )
        .collect();
        assert_eq!(
            messages.len(),
            1 + ROUTE_CAPACITY.div_ceil(ROUTE_CHUNK_WAYPOINTS)
        );
        let answers: std::vec::Vec<_> =
            messages.iter().map(|m| s.handle(m, link, || 0).0).collect();
        let (last, loaded) = answers.split_last().unwrap();
        assert_eq!(*last, TargetMessage::Configured);
        for (i, a) in loaded.iter().enumerate() {
            let n = u8::try_from(i * ROUTE_CHUNK_WAYPOINTS).unwrap();
            assert_eq!(*a, TargetMessage::RouteLoaded { waypoints: n });
        }
        assert_eq!(*s.route.waypoints(), ws);
        assert!(s.is_configured());
    }
}
