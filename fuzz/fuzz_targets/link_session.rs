//! The firmware's side of a HIL run, fed from the fuzzer: byte streams into
//! its `Receiver`, each message it decodes into `Session::handle`, each
//! answer through the firmware's `Sender` and back through `decode`.
//!
//! The bytes come as a sequence of operations: well-formed messages
//! (configurations from arbitrary specs, ticks with arbitrary encoder
//! counters and UART bytes, finish, MAVLink chunks), the same with bytes corrupted,
//! arbitrary payloads framed correctly (so that they reach postcard), raw
//! garbage, and link silences.
//!
//! Every answer: encodes into one frame of at most `MAX_FRAME_BYTES` that
//! the host decodes to the same message; a tick's PWM duties are within the
//! configured full scale and its command finite; a configuration is
//! accepted exactly when the core builds it; a tick before any accepted
//! configuration is refused; motors without a configured run are stopped;
//! a map chunk when no map loads changes nothing; a route (announced
//! with arbitrary limits and options, its waypoints in chunks, in order or
//! not) is taken only right after a configuration, loads until its count,
//! and a refusal while loading leaves the run unconfigured with its motors
//! stopped, while a stray one changes nothing; a silent link stops the
//! motors.

#![no_main]

use std::cell::RefCell;

use arbitrary::{Result, Unstructured};
use libfuzzer_sys::fuzz_target;
use wmr_core::devices::TagGrid;
use wmr_core::devices::encode_frame;
use wmr_core::pilot::route::RouteStart;
use wmr_core::reference::route::{RouteLimitsSpec, Waypoint};
use wmr_fuzz::{encoder_count, light_pilot_spec, tag_grid_spec};
use wmr_link::FloorSpec;
use wmr_link::proxy::{ProxyBus, Side};
use wmr_link::session::{LinkTagMap, RouteStore, Session};
use wmr_link::{
    Configure, Frame, HostMessage, MAVLINK_CHUNK_BYTES, MAX_FRAME_BYTES, MAX_UART_BYTES_PER_TICK,
    MapRefusal, MavlinkChunk, MavlinkIn, PROTOCOL_VERSION, ROUTE_CHUNK_WAYPOINTS, Receiver,
    Refusal, RouteChunk, RouteOptionsSpec, RouteRefusal, RouteSpec, Sender, TargetMessage,
    TickInput, decode, encode,
};

/// Operations per input at most.
const MAX_OPS: usize = 64;

struct Harness<'a> {
    session: Session<'a>,
    bus: &'a ProxyBus,
    /// The firmware's receiver (host to firmware).
    rx: Receiver,
    /// The host's side.
    host_tx: Sender,
    firmware_tx: Sender,
    /// Full scale of the last accepted configuration.
    pwm_max_duty: Option<u16>,
    /// The full-scale duty of a tag map's run while its map loads.
    loading_duty: Option<u16>,
    /// The full-scale duty of a run while its route loads.
    route_loading_duty: Option<u16>,
    /// A run that has ticked since its configuration (takes no route).
    ticked: bool,
    /// The next waypoint of the route loading, as the last answer said.
    route_next: u8,
    /// The configured run has a route (takes no other).
    routed: bool,
    counts: (u32, u32),
    tick: u32,
}

impl Harness<'_> {
    /// Bytes into the firmware's receiver; each message decoded is handled.
    fn feed(&mut self, bytes: &[u8]) {
        for &b in bytes {
            if let Some(Ok(message)) = self.rx.push::<HostMessage>(b) {
                self.handle(&message);
            }
        }
    }

    fn send(&mut self, message: HostMessage, corrupt: Option<(usize, u8)>) {
        let mut out = [0; MAX_FRAME_BYTES];
        let mut bytes = self
            .host_tx
            .frame(message, &mut out)
            .expect("every host message fits a frame")
            .to_vec();
        if let Some((at, flip)) = corrupt {
            let at = at % bytes.len();
            bytes[at] ^= flip;
        }
        self.feed(&bytes);
    }

    fn handle(&mut self, message: &HostMessage) {
        let link = self.rx.counters();
        let before = self.session.diagnostics(link);
        let (answer, _done) = self.session.handle(message, link, || 1234);
        let after = self.session.diagnostics(link);

        // The answer goes out in one frame, and the host reads it back (the
        // host's receiver is tested by `link_decode`: `decode` here).
        let mut out = [0; MAX_FRAME_BYTES];
        let bytes = self
            .firmware_tx
            .frame(answer, &mut out)
            .expect("every answer fits a frame");
        assert!(bytes.len() <= MAX_FRAME_BYTES);
        let (terminator, body) = bytes.split_last().expect("a frame is never empty");
        assert_eq!(*terminator, 0);
        let mut body = body.to_vec();
        let read_back = decode::<TargetMessage>(&mut body)
            .expect("the host decodes every answer")
            .body;
        if read_back != answer {
            // Only NaN (!= itself) may tell them apart: same bytes.
            let (mut a, mut b) = ([0; MAX_FRAME_BYTES], [0; MAX_FRAME_BYTES]);
            let reencode = |m, out| encode(&Frame { seq: 0, body: m }, out).map(<[u8]>::to_vec);
            assert_eq!(reencode(read_back, &mut a), reencode(answer, &mut b));
        }

        let max = |m: Option<u16>| m.map_or(1, |d| d.max(1));
        match (message, answer) {
            (HostMessage::Configure(c), _) if c.protocol != PROTOCOL_VERSION => {
                assert_eq!(
                    answer,
                    TargetMessage::Refused(Refusal::Protocol(PROTOCOL_VERSION))
                );
            }
            // A map announced (only an arbitrary payload does: the harness's
            // own configurations are grids): accepted, the run is unconfigured
            // until the whole map is in; refused, nothing changes.
            (
                HostMessage::Configure(
                    c @ Configure {
                        floor: FloorSpec::Map { .. },
                        ..
                    },
                ),
                _,
            ) => match answer {
                TargetMessage::MapLoaded { tags: 0 } => {
                    assert!(c.pilot.build().is_ok(), "{c:?}");
                    self.pwm_max_duty = None;
                    self.loading_duty = Some(c.pwm_max_duty);
                    self.route_loading_duty = None;
                    self.ticked = false;
                    self.routed = false;
                }
                TargetMessage::Refused(Refusal::Spec(_) | Refusal::Map(_)) => {}
                _ => panic!("{c:?} answered with {answer:?}"),
            },
            (HostMessage::MapChunk(_), _) => match answer {
                TargetMessage::MapLoaded { .. } => assert!(self.loading_duty.is_some()),
                TargetMessage::Configured => {
                    self.pwm_max_duty = self.loading_duty.take();
                    assert!(self.pwm_max_duty.is_some());
                }
                // No map loading: refused, and a running robot runs on.
                TargetMessage::Refused(Refusal::Map(MapRefusal::NotLoading)) => {
                    assert!(self.loading_duty.is_none());
                }
                TargetMessage::Refused(Refusal::Map(_)) => {
                    // A chunk refused while a map loads leaves the session
                    // unconfigured.
                    assert!(self.loading_duty.is_some());
                    self.pwm_max_duty = None;
                    self.loading_duty = None;
                }
                _ => panic!("{message:?} answered with {answer:?}"),
            },
            (HostMessage::Configure(c), _) => {
                let builds = c.pilot.build().is_ok()
                    && matches!(c.floor, FloorSpec::Grid(grid) if grid.build().is_ok());
                assert_eq!(
                    answer == TargetMessage::Configured,
                    builds,
                    "{c:?}: {answer:?}"
                );
                if builds {
                    self.pwm_max_duty = Some(c.pwm_max_duty);
                    self.loading_duty = None;
                    self.route_loading_duty = None;
                    self.ticked = false;
                    self.routed = false;
                } else {
                    assert!(matches!(answer, TargetMessage::Refused(Refusal::Spec(_))));
                }
            }
            (HostMessage::Route(spec), _) => match answer {
                TargetMessage::RouteLoaded { waypoints: 0 } => {
                    assert!(self.pwm_max_duty.is_some() && !self.ticked);
                    assert!(self.route_loading_duty.is_none());
                    assert!((2..=64).contains(&spec.waypoints), "{spec:?}");
                    self.route_loading_duty = self.pwm_max_duty.take();
                    self.route_next = 0;
                }
                // Outside its window: nothing changes.
                TargetMessage::Refused(Refusal::Route(RouteRefusal::NotExpected)) => {
                    assert!(
                        self.pwm_max_duty.is_none()
                            || self.ticked
                            || self.routed
                            || self.route_loading_duty.is_some()
                    );
                }
                TargetMessage::Refused(Refusal::Route(
                    RouteRefusal::Size { .. }
                    | RouteRefusal::Limits(_)
                    | RouteRefusal::Options(_)
                    | RouteRefusal::Endpoint(_),
                )) => {
                    assert!(self.pwm_max_duty.is_some() && !self.ticked);
                    self.pwm_max_duty = None;
                }
                _ => panic!("{message:?} answered with {answer:?}"),
            },
            (HostMessage::RouteChunk(_), _) => match answer {
                TargetMessage::RouteLoaded { waypoints } => {
                    assert!(self.route_loading_duty.is_some());
                    self.route_next = waypoints;
                }
                TargetMessage::Configured => {
                    // The last chunk, or the last sent again.
                    if self.route_loading_duty.is_some() {
                        self.pwm_max_duty = self.route_loading_duty.take();
                    }
                    self.routed = true;
                    assert!(self.pwm_max_duty.is_some());
                }
                TargetMessage::Refused(Refusal::Route(RouteRefusal::NotLoading)) => {
                    assert!(self.route_loading_duty.is_none());
                }
                TargetMessage::Refused(Refusal::Route(_)) => {
                    assert!(self.route_loading_duty.is_some());
                    self.pwm_max_duty = None;
                    self.route_loading_duty = None;
                }
                _ => panic!("{message:?} answered with {answer:?}"),
            },
            (HostMessage::Tick(_), TargetMessage::Refused(Refusal::NotConfigured)) => {
                assert!(self.pwm_max_duty.is_none());
            }
            // A tick older than the last answered: refused, never run.
            (HostMessage::Tick(_), TargetMessage::Refused(Refusal::StaleTick { .. })) => {
                assert!(self.pwm_max_duty.is_some());
            }
            (HostMessage::Tick(input), TargetMessage::Ticked(t)) => {
                assert!(self.pwm_max_duty.is_some());
                self.ticked = true;
                assert_eq!(t.tick, input.tick);
                let full = max(self.pwm_max_duty);
                assert!(
                    t.left.duty <= full && t.right.duty <= full,
                    "{t:?} over {full}"
                );
                assert!(t.command.iter().all(|c| c.is_finite()), "{t:?}");
                // The answer says a fix was used exactly when the tracker
                // counted one used this tick (a repeated tick is answered
                // again without running).
                if after.repeated_ticks == before.repeated_ticks {
                    let used = after.tracker.fixes_used - before.tracker.fixes_used;
                    assert_eq!(u32::from(t.fix), used, "{t:?}");
                }
            }
            // The channel answers every message, any time: its own seq,
            // and nothing queued without an endpoint (counted dropped).
            (HostMessage::Mavlink(m), TargetMessage::Mavlink(out)) => {
                assert_eq!(out.seq, m.seq);
                assert!(out.bytes.len() <= MAVLINK_CHUNK_BYTES);
            }
            (HostMessage::Finish, TargetMessage::Finished(f)) => {
                let full = max(self.pwm_max_duty);
                assert!(f.motors.iter().all(|m| m.duty <= full), "{f:?}");
                assert_eq!(f.peak_stack_bytes, 1234);
            }
            _ => panic!("{message:?} answered with {answer:?}"),
        }
        // A configured run's motors within its full scale; without one
        // (never configured, a map loading or refused), stopped.
        let full = self.pwm_max_duty.map_or(0, |d| d.max(1));
        for side in [Side::Left, Side::Right] {
            assert!(self.bus.motor(side).duty <= full, "{message:?}");
        }
    }

    fn configure(&mut self, u: &mut Unstructured) -> Result<HostMessage> {
        Ok(HostMessage::Configure(Configure {
            protocol: if u.ratio(1, 16)? {
                u.arbitrary()?
            } else {
                PROTOCOL_VERSION
            },
            pilot: light_pilot_spec(u)?,
            floor: FloorSpec::Grid(tag_grid_spec(u)?),
            pwm_max_duty: match u.int_in_range(0_u8..=3)? {
                0 => u.arbitrary()?,
                _ => 1000,
            },
            telemetry_every_ticks: u.arbitrary()?,
        }))
    }

    /// A route's announcement: mostly plausible, sometimes arbitrary.
    fn route(&mut self, u: &mut Unstructured) -> Result<HostMessage> {
        let plausible = u.ratio(3, 4)?;
        let f = |u: &mut Unstructured, typical: f32| -> Result<f32> {
            Ok(if plausible { typical } else { u.arbitrary()? })
        };
        Ok(HostMessage::Route(RouteSpec {
            waypoints: if plausible {
                u.int_in_range(2..=64)?
            } else {
                u.arbitrary()?
            },
            limits: RouteLimitsSpec {
                max_speed_m_s: f(u, 0.3)?,
                max_tangential_accel_m_s2: f(u, 0.5)?,
                max_lateral_accel_m_s2: f(u, 0.5)?,
                blend_deviation_m: f(u, 0.005)?,
                pivot_threshold_rad: f(u, 0.5)?,
                pivot_rate_rad_s: f(u, 1.0)?,
                pivot_accel_rad_s2: f(u, 2.0)?,
            },
            options: RouteOptionsSpec {
                pivot_gain_per_s: f(u, 5.0)?,
                position_tolerance_m: f(u, 0.01)?,
                heading_tolerance_rad: f(u, 0.02)?,
                max_lag_m: f(u, 0.05)?,
                approach_speed_m_s: f(u, 0.05)?,
                approach_timeout_s: f(u, 5.0)?,
            },
            start: match u.int_in_range(0..=2u8)? {
                0 => RouteStart::AsGiven,
                1 => RouteStart::FromFirstFix,
                _ => RouteStart::AsGivenHeadingKnown,
            },
            mavlink: if plausible {
                wmr_link::MavlinkSettings::default()
            } else {
                wmr_link::MavlinkSettings {
                    system_id: u.arbitrary()?,
                    component_id: u.arbitrary()?,
                    link_timeout_ms: u.arbitrary()?,
                    item_timeout_ms: u.arbitrary()?,
                    item_retries: u.arbitrary()?,
                    telemetry_period_ms: u.arbitrary()?,
                    counters_period_ms: u.arbitrary()?,
                    origin_e7: if u.arbitrary()? {
                        Some([u.arbitrary()?, u.arbitrary()?])
                    } else {
                        None
                    },
                    power_on: if u.arbitrary()? {
                        wmr_link::PowerOn::Wait
                    } else {
                        wmr_link::PowerOn::Run
                    },
                }
            },
        }))
    }

    /// A chunk of a route: mostly the next waypoints, on a zig-zag from
    /// the origin, each a pass or a stop; sometimes anywhere, with
    /// arbitrary values.
    fn route_chunk(&mut self, u: &mut Unstructured) -> Result<HostMessage> {
        let first = if u.ratio(7, 8)? {
            self.route_next
        } else {
            u.arbitrary()?
        };
        let n = u.int_in_range(0..=ROUTE_CHUNK_WAYPOINTS)?;
        let mut waypoints = heapless::Vec::new();
        for i in 0..n {
            let at = usize::from(first) + i;
            let w = if u.ratio(15, 16)? {
                let x = 0.1 * at as f32;
                let y = if at % 2 == 0 { 0.0 } else { 0.05 };
                match u.int_in_range(0_u8..=3)? {
                    0 => Waypoint::stop(x, y, 0.0),
                    1 => Waypoint::stop(x, y, 0.1).facing(0.3),
                    _ => Waypoint::pass(x, y),
                }
            } else {
                let stop = u.arbitrary::<bool>()?;
                let w = if stop {
                    Waypoint::stop(u.arbitrary()?, u.arbitrary()?, u.arbitrary()?)
                } else {
                    Waypoint::pass(u.arbitrary()?, u.arbitrary()?)
                };
                if u.arbitrary()? {
                    w.with_speed_limit(u.arbitrary()?)
                } else {
                    w
                }
            };
            let _ = waypoints.push(w);
        }
        Ok(HostMessage::RouteChunk(RouteChunk { first, waypoints }))
    }

    fn tick(&mut self, u: &mut Unstructured) -> Result<HostMessage> {
        let left = encoder_count(u, self.counts.0)?;
        let right = encoder_count(u, self.counts.1)?;
        self.counts = (
            left.unwrap_or(self.counts.0),
            right.unwrap_or(self.counts.1),
        );
        let mut uart = heapless::Vec::new();
        match u.int_in_range(0_u8..=3)? {
            // A tag of the typical grid (21 × 21 from (-1, -1)), or any tag.
            0 => {
                let id = if u.arbitrary()? {
                    TagGrid::id(u.int_in_range(0..=20)?, u.int_in_range(0..=20)?)
                } else {
                    wmr_core::devices::TagId(u.arbitrary()?)
                };
                let _ = uart.extend_from_slice(&encode_frame(id));
            }
            1 => {
                let len = u.int_in_range(0..=MAX_UART_BYTES_PER_TICK)?;
                for _ in 0..len {
                    let _ = uart.push(u.arbitrary()?);
                }
            }
            _ => {}
        }
        self.tick = if u.ratio(1, 16)? {
            u.arbitrary()?
        } else {
            self.tick.wrapping_add(1)
        };
        Ok(HostMessage::Tick(TickInput {
            tick: self.tick,
            left_count: left,
            right_count: right,
            uart,
        }))
    }
}

fn run(u: &mut Unstructured, bus: &ProxyBus) -> Result<()> {
    let map = RefCell::new(LinkTagMap::new());
    let mut route = Box::new(RouteStore::new());
    let mut h = Harness {
        session: Session::new(bus, &map, &mut route),
        bus,
        rx: Receiver::new(),
        host_tx: Sender::default(),
        firmware_tx: Sender::default(),
        pwm_max_duty: None,
        loading_duty: None,
        route_loading_duty: None,
        ticked: false,
        route_next: 0,
        routed: false,
        counts: (0, 0),
        tick: 0,
    };
    for _ in 0..MAX_OPS {
        if u.is_empty() {
            break;
        }
        let corrupt = if u.ratio(1, 16)? {
            Some((u.arbitrary()?, u.int_in_range(1..=255)?))
        } else {
            None
        };
        match u.int_in_range(0_u8..=19)? {
            0..=1 => {
                let m = h.configure(u)?;
                h.send(m, corrupt);
            }
            2..=11 => {
                let m = h.tick(u)?;
                h.send(m, corrupt);
            }
            12 => h.send(HostMessage::Finish, corrupt),
            19 => {
                let len = u.int_in_range(0..=MAVLINK_CHUNK_BYTES)?;
                let bytes = MavlinkChunk::from_slice(u.bytes(len)?);
                let seq = u.arbitrary()?;
                h.send(HostMessage::Mavlink(MavlinkIn { seq, bytes }), corrupt);
            }
            16 => {
                let m = h.route(u)?;
                h.send(m, corrupt);
            }
            17 | 18 => {
                let m = h.route_chunk(u)?;
                h.send(m, corrupt);
            }
            13 => {
                // An arbitrary payload, framed correctly.
                const CRC: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);
                let len = u.int_in_range(0..=400)?;
                let mut raw: Vec<u8> = u.bytes(len)?.to_vec();
                raw.extend_from_slice(&CRC.checksum(&raw.clone()).to_le_bytes());
                let mut framed = vec![0; cobs::max_encoding_length(raw.len()) + 1];
                let n = cobs::encode(&raw, &mut framed);
                framed.truncate(n);
                framed.push(0);
                h.feed(&framed);
            }
            14 => {
                let len = u.int_in_range(0..=64)?;
                let garbage = u.bytes(len)?.to_vec();
                h.feed(&garbage);
            }
            _ => {
                let report = h.session.link_silent(wmr_link::LINK_TIMEOUT_MS);
                for side in [Side::Left, Side::Right] {
                    assert_eq!(bus.motor(side).duty, 0);
                }
                assert!(
                    matches!(report, TargetMessage::LinkSilent { motors, .. } if motors.iter().all(|m| m.duty == 0)),
                    "{report:?}"
                );
            }
        }
    }
    Ok(())
}

fuzz_target!(|data: &[u8]| {
    let bus = ProxyBus::new();
    let _ = run(&mut Unstructured::new(data), &bus);
});
