//! The endpoint: bytes in, events for the robot and frames out.

use mavlink::MessageData;
use mavlink::dialects::common as c;
use wmr_core::pilot::tuning::{Tuning, TuningSpec};
use wmr_core::reference::route::{RouteError, RouteLimits, Waypoints};

use crate::config::EndpointConfig;
use crate::mission::Mission;
use crate::telemetry::Counts;
use crate::wire::{Parser, RxCounters, RxFrame, TxBuffer};

/// Events one [`MavlinkEndpoint::handle`] call can return; a command past
/// them is answered `MAV_RESULT_TEMPORARILY_REJECTED` (counted).
pub const EVENT_CAPACITY: usize = 16;

/// What the robot is doing, as the heartbeat's `custom_mode` says it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RobotMode {
    /// No route running (none loaded, or not started): `custom_mode` 0.
    #[default]
    Idle = 0,
    /// Driving the route: 1.
    Running = 1,
    /// Route paused (at rest, resumable): 2.
    Paused = 2,
    /// Route finished: 3.
    Done = 3,
    /// Stopped by an emergency stop or a failsafe (link loss, a fault): 4.
    Stopped = 4,
}

/// The robot's state estimate, floor frame.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Estimate {
    /// Position x, m.
    pub x_m: f32,
    /// Position y, m.
    pub y_m: f32,
    /// Heading, rad, counter-clockwise from +x.
    pub heading_rad: f32,
    /// Forward speed, m/s.
    pub speed_m_s: f32,
    /// Turn rate, rad/s, counter-clockwise.
    pub turn_rate_rad_s: f32,
}

/// What the robot reports to the endpoint each call.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RobotView {
    /// Motors enabled.
    pub armed: bool,
    /// Route state.
    pub mode: RobotMode,
    /// The estimate, `None` while it has none (no telemetry then).
    pub estimate: Option<Estimate>,
    /// Index of the waypoint being driven to.
    pub current: u16,
    /// Index of the last waypoint reached in this run, `None` before the
    /// first (a restart resets it).
    pub reached: Option<u16>,
}

/// What the robot must do.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Event {
    /// A new mission was accepted: load [`MavlinkEndpoint::route`] (the
    /// route check passed it already).
    LoadRoute,
    /// The mission was cleared: drop the route (stop if driving it).
    ClearRoute,
    /// Enable the motors.
    Arm,
    /// Disable the motors (stop first).
    Disarm,
    /// Start the route from its current waypoint.
    Start,
    /// Pause the route (come to rest on it).
    Pause,
    /// Continue a paused route.
    Continue,
    /// Stop now and latch stopped (`MAV_CMD_DO_FLIGHTTERMINATION`, or a
    /// forced disarm).
    EmergencyStop,
    /// Make waypoint `i` the current one.
    SetCurrent(u16),
    /// No ground-station heartbeat for the link timeout: stop, as the
    /// other failsafes do. Sent once per loss.
    LinkLost,
    /// A route limit was set (`PARAM_SET`): plan the next route with
    /// [`MavlinkEndpoint::route_limits`].
    RouteLimits,
    /// A gain or failsafe time was set (`PARAM_SET`): take
    /// [`MavlinkEndpoint::tuning`] (`Pilot::retune`, from the next tick).
    Tuning,
}

/// The events of one call, in the order their frames came.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Events {
    items: [Event; EVENT_CAPACITY],
    len: usize,
}

impl Default for Events {
    fn default() -> Self {
        Self {
            items: [Event::LinkLost; EVENT_CAPACITY],
            len: 0,
        }
    }
}

impl Events {
    /// The events.
    #[must_use]
    pub fn as_slice(&self) -> &[Event] {
        self.items.get(..self.len).unwrap_or(&[])
    }

    /// Whether another event fits.
    #[must_use]
    pub fn has_room(&self) -> bool {
        self.len < EVENT_CAPACITY
    }

    // Out of line: called from six handlers; inlined in each it cost flash.
    #[inline(never)]
    pub(crate) fn push(&mut self, event: Event) -> bool {
        match self.items.get_mut(self.len) {
            Some(slot) => {
                *slot = event;
                self.len += 1;
                true
            }
            None => false,
        }
    }
}

/// Counts of what the endpoint received, refused and dropped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Counters {
    /// The parser's counts.
    pub rx: RxCounters,
    /// Frames addressed to another system or component (ignored).
    pub not_for_us: u32,
    /// Mission uploads, items, set-currents and requests refused.
    pub mission_refusals: u32,
    /// Uploads cancelled after the item re-requests ran out.
    pub upload_timeouts: u32,
    /// Commands answered other than `MAV_RESULT_ACCEPTED`.
    pub command_refusals: u32,
    /// Parameter reads and sets refused (unknown name, value refused).
    pub param_refusals: u32,
    /// Link losses.
    pub link_losses: u32,
    /// Outgoing frames dropped: no room in the caller's buffer.
    pub tx_dropped: u32,
}

impl Counters {
    /// Every count 0 ([`MavlinkEndpoint::BLANK`]).
    pub(crate) const ZERO: Self = Self {
        rx: RxCounters::ZERO,
        not_for_us: 0,
        mission_refusals: 0,
        upload_timeouts: 0,
        command_refusals: 0,
        param_refusals: 0,
        link_losses: 0,
        tx_dropped: 0,
    };
}

/// An upload in progress.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Upload {
    /// The ground station's system and component ids.
    pub partner: (u8, u8),
    pub count: u16,
    pub next: u16,
    pub last_ms: u32,
    pub retries: u8,
}

/// The MAVLink endpoint of one robot (see the crate docs).
#[derive(Debug, Clone)]
pub struct MavlinkEndpoint {
    pub(crate) config: EndpointConfig,
    pub(crate) limits: RouteLimits,
    pub(crate) parser: Parser,
    pub(crate) counters: Counters,
    pub(crate) seq: u8,
    /// The running mission and the upload's staging area; `active` picks.
    pub(crate) missions: [Mission; 2],
    pub(crate) active: usize,
    pub(crate) upload: Option<Upload>,
    pub(crate) gcs_heartbeat_ms: Option<u32>,
    pub(crate) link_lost: bool,
    pub(crate) last_heartbeat_ms: Option<u32>,
    pub(crate) last_telemetry_ms: Option<u32>,
    pub(crate) last_current: Option<u16>,
    pub(crate) last_reached: Option<u16>,
    pub(crate) last_mode: Option<(bool, RobotMode)>,
    /// The robot's gains and failsafe times, as last set
    /// ([`Self::set_tuning`], `PARAM_SET`).
    pub(crate) tuning: TuningSlot,
    /// The robot's counters, as last told ([`Self::set_counts`]).
    pub(crate) counts: Option<Counts>,
    /// The counter sent next, and when the last one went.
    pub(crate) next_count: u8,
    pub(crate) last_count_ms: Option<u32>,
}

/// The robot's gains and failsafe times if told: an `Option<Tuning>`
/// with its tag first (`repr(u8)`), so that "not told" is all zero bits
/// ([`MavlinkEndpoint::BLANK`]); an `Option`'s `None` is a non-zero niche
/// of `Tuning`.
#[repr(u8)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum TuningSlot {
    NotTold = 0,
    Told(Tuning),
}

impl TuningSlot {
    pub(crate) fn get(self) -> Option<Tuning> {
        match self {
            Self::NotTold => None,
            Self::Told(tuning) => Some(tuning),
        }
    }
}

/// An upload's route check and where the uploaded route is written for
/// it ([`MavlinkEndpoint::handle_in`]).
pub(crate) struct RouteCheck<'r, F> {
    pub check: F,
    pub route: &'r mut Waypoints,
}

/// Heartbeat period, ms (MAVLink's 1 Hz).
const HEARTBEAT_PERIOD_MS: u32 = 1_000;

/// The `STATUSTEXT` of a mode change, by [`RobotMode`] value: NUL-padded
/// to one width, as `STATUSTEXT` pads its text on the wire (one table
/// of 65 bytes rather than five strings and two tables of their
/// addresses and lengths).
const MODE_TEXT: [[u8; 13]; 5] = [
    *b"mode: idle\0\0\0",
    *b"mode: running",
    *b"mode: paused\0",
    *b"mode: done\0\0\0",
    *b"mode: stopped",
];

/// Whether `period_ms` has passed since `last` (or it never happened).
pub(crate) fn due(now_ms: u32, last: Option<u32>, period_ms: u32) -> bool {
    last.is_none_or(|t| now_ms.wrapping_sub(t) >= period_ms)
}

impl MavlinkEndpoint {
    /// An endpoint not configured yet, every field zero: for a `static`
    /// built by clearing memory (it lands in `.bss`, and building it is a
    /// `memset`, not a copy of a 3.5 KB value), given its configuration
    /// by [`Self::reset`] before any other call. Until then its system
    /// id, timeouts and route limits are 0: not an endpoint to talk with
    /// (a route must not be planned with its limits).
    pub const BLANK: Self = Self {
        config: EndpointConfig::BLANK,
        limits: RouteLimits::BLANK,
        parser: Parser::new(),
        counters: Counters::ZERO,
        seq: 0,
        missions: [const { Mission::new() }; 2],
        active: 0,
        upload: None,
        gcs_heartbeat_ms: None,
        link_lost: false,
        last_heartbeat_ms: None,
        last_telemetry_ms: None,
        last_current: None,
        last_reached: None,
        // Zero bits (`None` is not): `reset` makes it `None`.
        last_mode: Some((false, RobotMode::Idle)),
        tuning: TuningSlot::NotTold,
        counts: None,
        next_count: 0,
        last_count_ms: None,
    };

    /// An endpoint with no mission; `limits` are the route limits the
    /// parameters start from (the robot file's).
    #[must_use]
    // Out of line: at opt-level 3 with fat LTO, inlined into its caller it
    // is unrolled and duplicated (docs/mavlink.md, Cost).
    #[inline(never)]
    pub fn new(config: EndpointConfig, limits: RouteLimits) -> Self {
        Self::new_in_place(config, limits)
    }

    /// As [`Self::new`], always inlined: built where its caller puts it
    /// (a `static` of a board with little stack), not in a frame of its
    /// own and copied out.
    #[must_use]
    #[inline(always)]
    pub fn new_in_place(config: EndpointConfig, limits: RouteLimits) -> Self {
        Self {
            config,
            limits,
            last_mode: None,
            ..Self::BLANK
        }
    }

    /// The counters.
    #[must_use]
    pub fn counters(&self) -> Counters {
        self.counters
    }

    /// The running mission's items.
    #[must_use]
    pub fn mission(&self) -> &Mission {
        self.missions.get(self.active).unwrap_or(&self.missions[0])
    }

    /// The running mission as a route (floor frame).
    #[must_use]
    pub fn route(&self) -> Waypoints {
        self.mission().waypoints(self.config.origin.as_ref())
    }

    /// [`Self::route`] written into `out` in place.
    pub fn route_into(&self, out: &mut Waypoints) {
        self.mission()
            .write_waypoints(self.config.origin.as_ref(), out);
    }

    /// Makes `route` the running mission (a robot's own route, from its
    /// robot file), as `MAV_FRAME_LOCAL_NED` items: north and east at
    /// 1e-4 m, a stop's dwell as its hold time and its heading as its
    /// yaw, so that a ground station reads back what the robot runs and
    /// can start it. An item has no field for a waypoint's speed limit,
    /// and a stop with no dwell and no heading reads back as a pass: the
    /// robot runs the route itself, not these items, until a mission is
    /// uploaded. Waypoints past the mission's capacity (none: both hold
    /// `ROUTE_CAPACITY`) are left out.
    // Out of line: called once a run, off the tick's path.
    #[inline(never)]
    pub fn load_route_mission(&mut self, route: &Waypoints) {
        let Some(mission) = self.missions.get_mut(self.active) else {
            return;
        };
        mission.clear();
        for w in route.as_slice() {
            let (north_m, east_m) = crate::geo::floor_to_ned(w.position_m.x, w.position_m.y);
            let (hold_s, yaw_deg) = match w.stop {
                Some(stop) => (
                    stop.dwell_s,
                    stop.face_heading_rad.map_or(f32::NAN, |h| {
                        crate::geo::heading_to_yaw(h) * (180.0 / wmr_core::math::PI)
                    }),
                ),
                None => (0.0, f32::NAN),
            };
            // Floor coordinates within the core's ±1e4 m: 1e8 at most.
            let _ = mission.push(crate::mission::Item {
                frame: c::MavFrame::MAV_FRAME_LOCAL_NED as u8,
                hold_s,
                yaw_deg,
                x: libm::roundf(north_m * 1e4) as i32,
                y: libm::roundf(east_m * 1e4) as i32,
                z: 0.0,
            });
        }
    }

    /// As [`Self::new`], in place: no mission, nothing heard, counters
    /// zero (a new run of a robot whose endpoint lives in a `static`; no
    /// endpoint is built on the stack).
    pub fn reset(&mut self, config: EndpointConfig, limits: RouteLimits) {
        self.config = config;
        self.limits = limits;
        self.parser.reset();
        self.counters = Counters::default();
        self.seq = 0;
        for mission in &mut self.missions {
            mission.clear();
        }
        self.active = 0;
        self.upload = None;
        self.gcs_heartbeat_ms = None;
        self.link_lost = false;
        self.last_heartbeat_ms = None;
        self.last_telemetry_ms = None;
        self.last_current = None;
        self.last_reached = None;
        self.last_mode = None;
        self.tuning = TuningSlot::NotTold;
        self.counts = None;
        self.next_count = 0;
        self.last_count_ms = None;
    }

    /// The robot's gains and failsafe times the parameters start from
    /// (its configuration's: `PilotConfig::tuning`); until told, they
    /// read NaN and are refused. A spec its own checks refuse is not
    /// taken (returned).
    ///
    /// # Errors
    /// The core's refusal of `spec`.
    pub fn set_tuning(
        &mut self,
        spec: &TuningSpec,
    ) -> Result<(), wmr_core::pilot::spec::SpecError> {
        self.tuning = TuningSlot::Told(spec.build()?);
        Ok(())
    }

    /// The gains and failsafe times as last set, for the robot to take on
    /// [`Event::Tuning`] (`Pilot::retune`).
    #[must_use]
    pub fn tuning(&self) -> Option<Tuning> {
        self.tuning.get()
    }

    /// The robot's counters now, sent at `counters_period_ms`
    /// (`NAMED_VALUE_INT`, [`crate::telemetry::COUNTER_NAMES`]).
    pub fn set_counts(&mut self, counts: Counts) {
        self.counts = Some(counts);
    }

    /// Whether the link is lost (a ground station was heard, then not for
    /// the link timeout).
    #[must_use]
    pub fn link_lost(&self) -> bool {
        self.link_lost
    }

    /// Takes the bytes received since the last call, answers them, and
    /// sends what is due at `now_ms` (a free-running millisecond clock,
    /// wrapping): the heartbeat (1 Hz), `MISSION_CURRENT` and
    /// `MISSION_ITEM_REACHED` on change, telemetry, link-loss and upload
    /// timeouts. Frames go to `tx`; a frame that does not fit is dropped
    /// and counted.
    ///
    /// `check_route` decides whether an uploaded mission can run (the
    /// robot plans it with its limits and period: `RoutePlan::replan`):
    /// a refusal is answered with the closest `MAV_MISSION_RESULT` and the
    /// running mission is kept.
    // Out of line: at opt-level 3 with fat LTO, inlined into its caller it
    // is unrolled and duplicated (docs/mavlink.md, Cost).
    #[inline(never)]
    pub fn handle<F>(
        &mut self,
        now_ms: u32,
        rx: &[u8],
        view: &RobotView,
        check_route: F,
        tx: &mut TxBuffer<'_>,
    ) -> Events
    where
        F: FnMut(&Waypoints) -> Result<(), RouteError>,
    {
        let mut route = Waypoints::new();
        self.handle_in(now_ms, rx, view, check_route, tx, &mut route)
    }

    /// As [`Self::handle`], an uploaded mission written as a route into
    /// `route` for `check_route` (a caller with little stack keeps it in
    /// a `static`; [`Self::handle`] has it in its frame, 1.8 KB).
    // Out of line: at opt-level 3 with fat LTO, inlined into its caller it
    // is unrolled and duplicated (docs/mavlink.md, Cost).
    #[inline(never)]
    pub fn handle_in<F>(
        &mut self,
        now_ms: u32,
        rx: &[u8],
        view: &RobotView,
        check_route: F,
        tx: &mut TxBuffer<'_>,
        route: &mut Waypoints,
    ) -> Events
    where
        F: FnMut(&Waypoints) -> Result<(), RouteError>,
    {
        let mut check_route = RouteCheck {
            check: check_route,
            route,
        };
        let mut events = Events::default();
        let dropped_before = tx.dropped();
        for &byte in rx {
            self.parser.push(byte, &mut self.counters.rx);
            while let Some(frame) = self.parser.next_frame(&mut self.counters.rx) {
                self.dispatch(now_ms, &frame, view, &mut check_route, tx, &mut events);
            }
        }
        self.periodic(now_ms, view, tx, &mut events);
        let dropped = tx.dropped().wrapping_sub(dropped_before);
        self.counters.tx_dropped = self.counters.tx_dropped.wrapping_add(dropped);
        events
    }

    /// Whether a message's target is this robot (0 = broadcast).
    pub(crate) fn for_us(&mut self, target_system: u8, target_component: u8) -> bool {
        let ok = (target_system == 0 || target_system == self.config.system_id)
            && (target_component == 0 || target_component == self.config.component_id);
        if !ok {
            self.counters.not_for_us = self.counters.not_for_us.wrapping_add(1);
        }
        ok
    }

    // Out of line: at opt-level 3 with fat LTO, inlined into its caller it
    // is unrolled and duplicated (docs/mavlink.md, Cost).
    #[inline(never)]
    fn dispatch<F>(
        &mut self,
        now_ms: u32,
        frame: &RxFrame,
        view: &RobotView,
        check_route: &mut RouteCheck<'_, F>,
        tx: &mut TxBuffer<'_>,
        events: &mut Events,
    ) where
        F: FnMut(&Waypoints) -> Result<(), RouteError>,
    {
        match frame.msg_id {
            c::HEARTBEAT_DATA::ID => self.on_heartbeat(now_ms, frame, tx),
            c::COMMAND_LONG_DATA::ID | c::COMMAND_INT_DATA::ID => {
                self.on_command(frame, view, tx, events);
            }
            c::PARAM_REQUEST_LIST_DATA::ID
            | c::PARAM_REQUEST_READ_DATA::ID
            | c::PARAM_SET_DATA::ID => self.on_param(frame, tx, events),
            _ => self.on_mission(now_ms, frame, view, check_route, tx, events),
        }
    }

    fn on_heartbeat(&mut self, now_ms: u32, frame: &RxFrame, tx: &mut TxBuffer<'_>) {
        // HEARTBEAT payload: custom_mode u32, type u8 at 4. A controlling
        // peer is a ground station or a companion computer (mavros and
        // MAVSDK's companion mode send `MAV_TYPE_ONBOARD_CONTROLLER`);
        // another vehicle's heartbeat is not.
        let peer = frame.byte(4);
        if peer != c::MavType::MAV_TYPE_GCS as u8
            && peer != c::MavType::MAV_TYPE_ONBOARD_CONTROLLER as u8
        {
            return;
        }
        self.gcs_heartbeat_ms = Some(now_ms);
        if self.link_lost {
            self.link_lost = false;
            self.status_text(tx, c::MavSeverity::MAV_SEVERITY_INFO, b"link regained");
        }
    }

    // Out of line: at opt-level 3 with fat LTO, inlined into its caller it
    // is unrolled and duplicated (docs/mavlink.md, Cost).
    #[inline(never)]
    fn periodic(
        &mut self,
        now_ms: u32,
        view: &RobotView,
        tx: &mut TxBuffer<'_>,
        events: &mut Events,
    ) {
        if let Some(t) = self.gcs_heartbeat_ms
            && !self.link_lost
            && now_ms.wrapping_sub(t) >= self.config.link_timeout_ms
        {
            self.link_lost = true;
            self.counters.link_losses = self.counters.link_losses.wrapping_add(1);
            // The loss is reported even when the event list is full: the
            // robot reads `link_lost()` as well.
            let _ = events.push(Event::LinkLost);
            self.status_text(
                tx,
                c::MavSeverity::MAV_SEVERITY_CRITICAL,
                b"link lost: no GCS heartbeat, stopping",
            );
        }
        self.upload_timeout(now_ms, tx);
        let mode = (view.armed, view.mode);
        if self.last_mode.is_some_and(|m| m != mode) {
            let text = MODE_TEXT
                .get(view.mode as usize)
                .map_or(&[][..], |t| &t[..]);
            self.status_text(tx, c::MavSeverity::MAV_SEVERITY_NOTICE, text);
        }
        let heartbeat_due = due(now_ms, self.last_heartbeat_ms, HEARTBEAT_PERIOD_MS);
        if heartbeat_due || self.last_mode != Some(mode) {
            self.last_heartbeat_ms = Some(now_ms);
            self.last_mode = Some(mode);
            self.heartbeat(view, tx);
        }
        if heartbeat_due {
            self.sys_status(tx);
        }
        let count = self.mission().len();
        if count > 0 && (heartbeat_due || self.last_current != Some(view.current)) {
            self.last_current = Some(view.current);
            self.mission_current(tx, view.current);
        }
        self.reached(view, tx);
        self.telemetry(now_ms, view, tx);
        self.send_count(now_ms, tx);
    }

    // Out of line: at opt-level 3 with fat LTO, inlined into its caller it
    // is unrolled and duplicated (docs/mavlink.md, Cost).
    #[inline(never)]
    fn reached(&mut self, view: &RobotView, tx: &mut TxBuffer<'_>) {
        let count = self.mission().len();
        match view.reached {
            None => self.last_reached = None,
            Some(r) if count == 0 => self.last_reached = Some(r),
            Some(r) => {
                // Each index once, in order, even if several were passed
                // between two calls; a lower index is a restart.
                let first = match self.last_reached {
                    Some(last) if r > last => last + 1,
                    Some(last) if r == last => return,
                    _ => 0,
                };
                let last = r.min(count.saturating_sub(1));
                for seq in first..=last {
                    // MISSION_ITEM_REACHED: seq u16.
                    self.send_raw(
                        tx,
                        c::MISSION_ITEM_REACHED_DATA::ID,
                        c::MISSION_ITEM_REACHED_DATA::EXTRA_CRC,
                        &seq.to_le_bytes(),
                    );
                }
                self.last_reached = Some(r);
            }
        }
    }

    /// Sends a `STATUSTEXT` (cut to its 50 characters), written by its
    /// layout: severity, then the text (NUL-padded; the extension fields
    /// `id`, `chunk_seq` left 0: one chunk).
    // Out of line: called from many places; inlined at each (opt-level 3,
    // fat LTO) it cost flash (docs/mavlink.md, Cost).
    #[inline(never)]
    pub(crate) fn status_text(
        &mut self,
        tx: &mut TxBuffer<'_>,
        severity: c::MavSeverity,
        text: &[u8],
    ) {
        let mut payload = [0u8; 51];
        payload[0] = severity as u8;
        let n = text.len().min(50);
        if let (Some(d), Some(s)) = (payload.get_mut(1..1 + n), text.get(..n)) {
            d.copy_from_slice(s);
        }
        self.send_raw(
            tx,
            c::STATUSTEXT_DATA::ID,
            c::STATUSTEXT_DATA::EXTRA_CRC,
            &payload,
        );
    }

    /// Sends a payload given as little-endian 32-bit words (at most 8,
    /// the longest of the messages written so: `SYS_STATUS`' fields before
    /// its zero extensions), its trailing zeros cut by [`Self::send_raw`].
    /// The heartbeat, `SYS_STATUS`, the position and attitude telemetry
    /// and `PARAM_VALUE` are written by their wire layout in words: one
    /// copy of this function rather than one of the library's encoder per
    /// message (each test compares the bytes with the library's).
    // Out of line: called from many places; inlined at each (opt-level 3,
    // fat LTO) it cost flash (docs/mavlink.md, Cost).
    #[inline(never)]
    pub(crate) fn send_words(&mut self, tx: &mut TxBuffer<'_>, id: u32, extra: u8, words: &[u32]) {
        let mut payload = [0u8; 32];
        for (bytes, word) in payload.chunks_exact_mut(4).zip(words) {
            bytes.copy_from_slice(&word.to_le_bytes());
        }
        // Only the message's own words: the cut of the trailing zeros
        // scans no more than it must (a tick's cost).
        let len = (4 * words.len()).min(payload.len());
        self.send_raw(tx, id, extra, payload.get(..len).unwrap_or(&payload));
    }

    /// Sends a payload already serialised (its trailing zeros cut, as
    /// MAVLink 2 sends them).
    // Out of line: called from many places; inlined at each (opt-level 3,
    // fat LTO) it cost flash (docs/mavlink.md, Cost).
    #[inline(never)]
    pub(crate) fn send_raw(&mut self, tx: &mut TxBuffer<'_>, id: u32, extra: u8, payload: &[u8]) {
        let n = payload.iter().rposition(|&b| b != 0).map_or(1, |i| i + 1);
        let payload = payload.get(..n).unwrap_or(payload);
        let header = [self.seq, self.config.system_id, self.config.component_id];
        if tx.frame(header, id, extra, payload) {
            self.seq = self.seq.wrapping_add(1);
        }
    }
}
