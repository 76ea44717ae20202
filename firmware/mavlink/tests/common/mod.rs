//! The ground station of the tests: the `mavlink` library (its
//! `embedded` API over byte slices) encodes what it sends and decodes
//! what the endpoint answers.
#![allow(dead_code, deprecated)]

use mavlink::dialects::common::*;
use mavlink::{MavHeader, MavlinkReader, MavlinkVersion};
use wmr_core::reference::route::{RouteLimits, RouteLimitsSpec, RoutePlan, Waypoints};
use wmr_mavlink::{EndpointConfig, EndpointSpec, Event, MavlinkEndpoint, RobotView, TxBuffer};

/// The ground station's ids.
pub const GCS_SYS: u8 = 255;
pub const GCS_COMP: u8 = 190;

pub fn limits() -> RouteLimits {
    RouteLimits::new(&RouteLimitsSpec {
        max_speed_m_s: 0.5,
        max_tangential_accel_m_s2: 0.5,
        max_lateral_accel_m_s2: 0.5,
        blend_deviation_m: 0.05,
        pivot_threshold_rad: 0.5,
        pivot_rate_rad_s: 1.0,
        pivot_accel_rad_s2: 2.0,
    })
    .expect("limits")
}

/// The robot's route check: the core's planner at 100 Hz.
pub fn plan_check(w: &Waypoints) -> Result<(), wmr_core::reference::route::RouteError> {
    RoutePlan::new(w.as_slice(), &limits(), 0.01).map(|_| ())
}

pub struct Rig {
    pub ep: MavlinkEndpoint,
    pub view: RobotView,
    pub now_ms: u32,
    seq: u8,
    pub tx_capacity: usize,
}

impl Rig {
    pub fn new(spec: EndpointSpec) -> Self {
        Self {
            ep: MavlinkEndpoint::new(EndpointConfig::new(&spec).expect("config"), limits()),
            view: RobotView::default(),
            now_ms: 0,
            seq: 0,
            tx_capacity: 4096,
        }
    }

    pub fn default_rig() -> Self {
        Self::new(EndpointSpec {
            telemetry_period_ms: 0,
            ..EndpointSpec::default()
        })
    }

    /// One frame as the ground station sends it (MAVLink 2).
    pub fn encode(&mut self, msg: &MavMessage) -> Vec<u8> {
        let mut buf = [0u8; 300];
        let header = MavHeader {
            system_id: u32::from(GCS_SYS),
            component_id: GCS_COMP,
            sequence: self.seq,
        };
        self.seq = self.seq.wrapping_add(1);
        let n = mavlink::write_v2_msg(&mut &mut buf[..], header, msg).expect("encode");
        buf[..n].to_vec()
    }

    /// The same in MAVLink 1.
    pub fn encode_v1(&mut self, msg: &MavMessage) -> Vec<u8> {
        let mut buf = [0u8; 300];
        let header = MavHeader {
            system_id: u32::from(GCS_SYS),
            component_id: GCS_COMP,
            sequence: self.seq,
        };
        self.seq = self.seq.wrapping_add(1);
        let n = mavlink::write_v1_msg(&mut &mut buf[..], header, msg).expect("encode");
        buf[..n].to_vec()
    }

    /// Feeds bytes at the current time; the events and the decoded answers.
    pub fn feed(&mut self, bytes: &[u8]) -> (Vec<Event>, Vec<MavMessage>) {
        let mut buf = vec![0u8; self.tx_capacity];
        let mut tx = TxBuffer::new(&mut buf);
        let events = self
            .ep
            .handle(self.now_ms, bytes, &self.view, plan_check, &mut tx);
        let out = decode_all(tx.as_slice());
        (events.as_slice().to_vec(), out)
    }

    pub fn send(&mut self, msg: MavMessage) -> (Vec<Event>, Vec<MavMessage>) {
        let bytes = self.encode(&msg);
        self.feed(&bytes)
    }

    /// Advances the clock by `dt_ms` and calls with no bytes.
    pub fn tick(&mut self, dt_ms: u32) -> (Vec<Event>, Vec<MavMessage>) {
        self.now_ms = self.now_ms.wrapping_add(dt_ms);
        self.feed(&[])
    }

    /// Uploads `items` as the mission protocol says; the final
    /// MISSION_ACK's result and every event seen.
    pub fn upload(&mut self, items: &[MavMessage]) -> (MavMissionResult, Vec<Event>) {
        let count = MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
            count: items.len() as u16,
            target_system: 1,
            target_component: 1,
        });
        let (mut events, mut out) = self.send(count);
        for _ in 0..1000 {
            let mut next = None;
            for m in &out {
                match m {
                    MavMessage::MISSION_ACK(ack) => return (ack.mavtype, events),
                    MavMessage::MISSION_REQUEST_INT(r) => next = Some(r.seq),
                    _ => {}
                }
            }
            let seq = next.expect("a request or an ack");
            let (e, o) = self.send(items[usize::from(seq)].clone());
            events.extend(e);
            out = o;
        }
        panic!("upload did not end");
    }

    /// Downloads the mission with MISSION_REQUEST_INT (or the legacy
    /// MISSION_REQUEST): every item message received, in order.
    pub fn download(&mut self, int: bool) -> Vec<MavMessage> {
        let (_, out) = self.send(MavMessage::MISSION_REQUEST_LIST(
            MISSION_REQUEST_LIST_DATA {
                target_system: 1,
                target_component: 1,
            },
        ));
        let count = out
            .iter()
            .find_map(|m| match m {
                MavMessage::MISSION_COUNT(c) => Some(c.count),
                _ => None,
            })
            .expect("MISSION_COUNT");
        let mut items = Vec::new();
        for seq in 0..count {
            let request = if int {
                MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
                    seq,
                    target_system: 1,
                    target_component: 1,
                })
            } else {
                MavMessage::MISSION_REQUEST(MISSION_REQUEST_DATA {
                    seq,
                    target_system: 1,
                    target_component: 1,
                })
            };
            let (_, out) = self.send(request);
            items.extend(out.into_iter().filter(|m| {
                matches!(
                    m,
                    MavMessage::MISSION_ITEM_INT(_) | MavMessage::MISSION_ITEM(_)
                )
            }));
        }
        self.send(MavMessage::MISSION_ACK(MISSION_ACK_DATA {
            target_system: 1,
            target_component: 1,
            mavtype: MavMissionResult::MAV_MISSION_ACCEPTED,
        }));
        items
    }

    /// A COMMAND_LONG to this robot; its events and the ack's result.
    pub fn command(
        &mut self,
        command: MavCmd,
        p1: f32,
        p2: f32,
    ) -> (Vec<Event>, Option<MavResult>) {
        let (events, out) = self.send(MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            command,
            param1: p1,
            param2: p2,
            target_system: 1,
            target_component: 1,
            ..Default::default()
        }));
        (events, ack_of(&out, command as u16))
    }
}

/// The result of the COMMAND_ACK for `command` among `out`.
pub fn ack_of(out: &[MavMessage], command: u16) -> Option<MavResult> {
    out.iter().find_map(|m| match m {
        MavMessage::COMMAND_ACK(a) if a.command as u16 == command => Some(a.result),
        _ => None,
    })
}

/// Every MAVLink 2 message in `bytes`; panics on a frame the library
/// cannot read (the endpoint must only send good frames).
pub fn decode_all(bytes: &[u8]) -> Vec<MavMessage> {
    let mut reader = MavlinkReader::new(bytes);
    let mut out = Vec::new();
    loop {
        match reader.read_message::<MavMessage>(MavlinkVersion::V2) {
            Ok((header, msg)) => {
                assert_eq!((header.system_id, header.component_id), (1, 1));
                out.push(msg);
            }
            // The end of the bytes.
            Err(mavlink::error::MessageReadError::Io) => return out,
            Err(e) => panic!("bad frame from the endpoint: {e:?}"),
        }
    }
}

/// A local-NED NAV_WAYPOINT item: north, east in m, hold s, yaw deg.
pub fn local_item(seq: u16, north_m: f32, east_m: f32, hold_s: f32, yaw_deg: f32) -> MavMessage {
    MavMessage::MISSION_ITEM_INT(MISSION_ITEM_INT_DATA {
        param1: hold_s,
        param4: yaw_deg,
        x: (north_m * 1e4).round() as i32,
        y: (east_m * 1e4).round() as i32,
        z: 0.0,
        seq,
        command: MavCmd::MAV_CMD_NAV_WAYPOINT,
        target_system: 1,
        target_component: 1,
        frame: MavFrame::MAV_FRAME_LOCAL_NED,
        current: 0,
        autocontinue: 1,
        ..Default::default()
    })
}

/// A square of four items, 1 m sides, the last a stop facing north.
pub fn square() -> Vec<MavMessage> {
    vec![
        local_item(0, 0.0, 0.0, 0.0, f32::NAN),
        local_item(1, 0.0, 1.0, 2.0, f32::NAN),
        local_item(2, 1.0, 1.0, 0.0, f32::NAN),
        local_item(3, 1.0, 0.0, 1.5, 0.0),
    ]
}

/// A MAVLink 2 frame from raw parts (for numbers the library cannot encode).
pub fn raw_v2(seq: u8, msg_id: u32, extra: u8, payload: &[u8]) -> Vec<u8> {
    let id = msg_id.to_le_bytes();
    let mut f = vec![
        0xFD,
        payload.len() as u8,
        0,
        0,
        seq,
        GCS_SYS,
        GCS_COMP,
        id[0],
        id[1],
        id[2],
    ];
    f.extend_from_slice(payload);
    let crc = mavlink::calculate_crc(&f[1..], extra);
    f.extend_from_slice(&crc.to_le_bytes());
    f
}
