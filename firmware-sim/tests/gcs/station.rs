//! The in-process ground station of `sitl.rs` and `hil_mavlink.rs`: the
//! `mavlink` library over a loopback UDP socket, talking to the robot
//! (the SITL's, or the firmware under QEMU through `firmware-sim hil`'s
//! bridge) once it has spoken. Every wait is in the robot's time (its
//! `LOCAL_POSITION_NED`'s `time_boot_ms`), capped by [`WALL_CAP`] of wall
//! time.

use std::net::{SocketAddr, UdpSocket};
use std::time::{Duration, Instant};

use mavlink::dialects::common::*;
use mavlink::{MavHeader, MavlinkReader, MavlinkVersion};

/// A wall-clock cap on any wait: only a hung robot reaches it (the waits
/// themselves are in the robot's time).
pub const WALL_CAP: Duration = Duration::from_secs(60);

/// The ground station: a socket, the robot's address once it has spoken,
/// the robot's time, mode and waypoints reached from what it sends, the
/// datagrams sent.
pub struct Gcs {
    pub socket: UdpSocket,
    pub robot: Option<SocketAddr>,
    seq: u8,
    /// Send a heartbeat every [`Self::heartbeat_every`] of wall time while
    /// waiting (once the robot has spoken).
    pub heartbeats: bool,
    pub heartbeat_every: Duration,
    last_heartbeat: Instant,
    /// The robot's time, ms (from its telemetry).
    pub sim_ms: u32,
    /// Each `MISSION_ITEM_REACHED`'s item, in order.
    pub reached: Vec<u16>,
    /// The last heartbeat's custom mode.
    pub mode: Option<u32>,
    /// Datagrams sent.
    pub sent: u64,
}

impl Gcs {
    /// Bound to a free loopback port; no heartbeats until
    /// [`Self::heartbeats`] is set.
    pub fn new(heartbeat_every: Duration) -> Self {
        let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
        socket
            .set_read_timeout(Some(Duration::from_millis(2)))
            .unwrap();
        Self {
            socket,
            robot: None,
            seq: 0,
            heartbeats: false,
            heartbeat_every,
            last_heartbeat: Instant::now(),
            sim_ms: 0,
            reached: Vec::new(),
            mode: None,
            sent: 0,
        }
    }

    pub fn port(&self) -> u16 {
        self.socket.local_addr().unwrap().port()
    }

    pub fn send(&mut self, msg: &MavMessage) {
        let mut buf = [0u8; 300];
        let header = MavHeader {
            system_id: 255,
            component_id: 190,
            sequence: self.seq,
        };
        self.seq = self.seq.wrapping_add(1);
        let n = mavlink::write_v2_msg(&mut &mut buf[..], header, msg).unwrap();
        self.send_raw(&buf[..n]);
    }

    pub fn send_raw(&mut self, datagram: &[u8]) {
        let to = self.robot.expect("the robot spoke first");
        self.socket.send_to(datagram, to).unwrap();
        self.sent += 1;
    }

    pub fn heartbeat(&mut self) {
        self.send(&MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            mavtype: MavType::MAV_TYPE_GCS,
            autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
            system_status: MavState::MAV_STATE_ACTIVE,
            mavlink_version: 3,
            ..Default::default()
        }));
    }

    /// Receives (with heartbeats, while [`Self::heartbeats`]) until
    /// `until` holds for a message, within `sim_timeout_ms` of the robot's
    /// time (`None` past it).
    pub fn receive_until(
        &mut self,
        what: &str,
        sim_timeout_ms: u32,
        mut until: impl FnMut(&MavMessage) -> bool,
    ) -> Option<MavMessage> {
        let start_sim = self.sim_ms;
        let wall = Instant::now();
        let mut buf = [0u8; 2048];
        loop {
            if self.heartbeats
                && self.robot.is_some()
                && self.last_heartbeat.elapsed() >= self.heartbeat_every
            {
                self.last_heartbeat = Instant::now();
                self.heartbeat();
            }
            if let Ok((n, from)) = self.socket.recv_from(&mut buf) {
                self.robot = Some(from);
                let mut reader = MavlinkReader::new(&buf[..n]);
                while let Ok((_, msg)) = reader.read_message::<MavMessage>(MavlinkVersion::V2) {
                    match &msg {
                        MavMessage::LOCAL_POSITION_NED(p) => {
                            self.sim_ms = self.sim_ms.max(p.time_boot_ms);
                        }
                        MavMessage::MISSION_ITEM_REACHED(r) => self.reached.push(r.seq),
                        MavMessage::HEARTBEAT(h) => self.mode = Some(h.custom_mode),
                        _ => {}
                    }
                    if until(&msg) {
                        return Some(msg);
                    }
                }
            }
            if self.sim_ms.saturating_sub(start_sim) > sim_timeout_ms {
                return None;
            }
            assert!(wall.elapsed() < WALL_CAP, "{what}: the robot hung");
        }
    }

    /// [`Self::receive_until`], which must succeed.
    pub fn wait(
        &mut self,
        what: &str,
        sim_timeout_ms: u32,
        until: impl FnMut(&MavMessage) -> bool,
    ) -> MavMessage {
        self.receive_until(what, sim_timeout_ms, until)
            .unwrap_or_else(|| panic!("{what}: not within {sim_timeout_ms} ms of the robot's time"))
    }

    /// Waits for a heartbeat in custom mode `mode`.
    pub fn mode_is(&mut self, what: &str, mode: u32, sim_timeout_ms: u32) {
        self.wait(
            what,
            sim_timeout_ms,
            |m| matches!(m, MavMessage::HEARTBEAT(h) if h.custom_mode == mode),
        );
    }

    /// Sends `COMMAND_LONG` `command` (`param1` = `p1`) and returns its
    /// `COMMAND_ACK`'s result.
    pub fn command(&mut self, command: MavCmd, p1: f32) -> MavResult {
        self.send(&MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            command,
            param1: p1,
            target_system: 1,
            target_component: 1,
            ..Default::default()
        }));
        match self.wait(
            "COMMAND_ACK",
            5000,
            |m| matches!(m, MavMessage::COMMAND_ACK(a) if a.command == command),
        ) {
            MavMessage::COMMAND_ACK(a) => a.result,
            _ => unreachable!(),
        }
    }

    /// Uploads waypoints (floor x east, y north, m; hold s): the ack.
    pub fn upload(&mut self, items: &[(f32, f32, f32)]) -> MavMissionResult {
        self.send(&MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
            count: items.len() as u16,
            target_system: 1,
            target_component: 1,
        }));
        loop {
            let msg = self.wait("upload", 10_000, |m| {
                matches!(
                    m,
                    MavMessage::MISSION_REQUEST_INT(_) | MavMessage::MISSION_ACK(_)
                )
            });
            match msg {
                MavMessage::MISSION_ACK(a) => return a.mavtype,
                MavMessage::MISSION_REQUEST_INT(r) => {
                    let (x, y, hold) = items[usize::from(r.seq)];
                    self.send(&MavMessage::MISSION_ITEM_INT(MISSION_ITEM_INT_DATA {
                        param1: hold,
                        param4: f32::NAN,
                        x: (y * 1e4).round() as i32,
                        y: (x * 1e4).round() as i32,
                        seq: r.seq,
                        command: MavCmd::MAV_CMD_NAV_WAYPOINT,
                        target_system: 1,
                        target_component: 1,
                        frame: MavFrame::MAV_FRAME_LOCAL_NED,
                        autocontinue: 1,
                        ..Default::default()
                    }));
                }
                _ => unreachable!(),
            }
        }
    }

    /// The number of items of the robot's mission (`MISSION_REQUEST_LIST`
    /// answered with `MISSION_COUNT`).
    pub fn mission_count(&mut self) -> u16 {
        self.send(&MavMessage::MISSION_REQUEST_LIST(
            MISSION_REQUEST_LIST_DATA {
                target_system: 1,
                target_component: 1,
            },
        ));
        match self.wait("MISSION_COUNT", 5000, |m| {
            matches!(m, MavMessage::MISSION_COUNT(_))
        }) {
            MavMessage::MISSION_COUNT(c) => c.count,
            _ => unreachable!(),
        }
    }

    pub fn request_param(&mut self, name: &str) {
        self.send(&MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
            param_index: -1,
            target_system: 1,
            target_component: 1,
            param_id: name.into(),
        }));
    }

    /// `RT_MAX_SPEED`, asked again after each second of the robot's time
    /// without an answer, as a ground station does: a request sent into
    /// a flood may be dropped (by the kernel or the bridge's backlog,
    /// counted).
    pub fn read_max_speed(&mut self) -> f32 {
        for _ in 0..5 {
            self.request_param("RT_MAX_SPEED");
            let answer = self.receive_until("PARAM_VALUE", 1000, |m| {
                matches!(m, MavMessage::PARAM_VALUE(p) if p.param_id.to_str() == Ok("RT_MAX_SPEED"))
            });
            if let Some(MavMessage::PARAM_VALUE(p)) = answer {
                return p.param_value;
            }
        }
        panic!("RT_MAX_SPEED: no PARAM_VALUE to 5 requests, 1 s of the robot's time each")
    }

    /// The last datagram: a parameter request answered with nothing sent
    /// after it (heartbeats stopped), so that the bridge has read (or the
    /// kernel dropped) every datagram sent before it. A parameter no
    /// earlier request asked for, so that no late answer to one is taken
    /// for its answer.
    pub fn last_datagram(&mut self) {
        self.heartbeats = false;
        self.request_param("LINK_TIMEOUT_MS");
        let answer = self.receive_until("the last PARAM_VALUE", 5000, |m| {
            matches!(m, MavMessage::PARAM_VALUE(p) if p.param_id.to_str() == Ok("LINK_TIMEOUT_MS"))
        });
        assert!(answer.is_some(), "no PARAM_VALUE to the last request");
    }
}
