//! The mission microservice (<https://mavlink.io/en/services/mission.html>):
//! upload, download, clear, set current.
//!
//! Fields are read from each message's wire layout (MAVLink orders them by
//! size): the library's decoder refuses a command or frame number it does
//! not know, and such an item must be answered with its
//! `MAV_MISSION_RESULT`. Only `MAV_MISSION_TYPE_MISSION` is held; a fence
//! or rally upload is refused `MAV_MISSION_UNSUPPORTED`, and their
//! download is empty.

// The legacy MISSION_ITEM / MISSION_REQUEST / MISSION_SET_CURRENT are
// deprecated in the dialect but still sent by ground stations: accepted.
#![allow(deprecated)]

use mavlink::MessageData;
use mavlink::dialects::common as c;
use wmr_core::reference::route::{ROUTE_CAPACITY, RouteError, Waypoints};

use crate::endpoint::{Event, Events, MavlinkEndpoint, RobotView, RouteCheck, Upload};
use crate::mission::{Coord, Item, RawItem, check_item, route_refusal};
use crate::wire::{RxFrame, TxBuffer};

use c::MavMissionResult as R;

fn f32_at(frame: &RxFrame, offset: usize) -> f32 {
    f32::from_le_bytes([
        frame.byte(offset),
        frame.byte(offset + 1),
        frame.byte(offset + 2),
        frame.byte(offset + 3),
    ])
}

fn i32_at(frame: &RxFrame, offset: usize) -> i32 {
    f32_at(frame, offset).to_bits() as i32
}

#[allow(deprecated)]
fn frame_enum(value: u8) -> c::MavFrame {
    match value {
        0 => c::MavFrame::MAV_FRAME_GLOBAL,
        3 => c::MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
        5 => c::MavFrame::MAV_FRAME_GLOBAL_INT,
        6 => c::MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
        _ => c::MavFrame::MAV_FRAME_LOCAL_NED,
    }
}

const MISSION: u8 = 0;

/// The payload of a downloaded item: `MISSION_ITEM_INT` (`int`) or
/// `MISSION_ITEM`, which share their wire layout: param1..4 f32 at 0..16,
/// x and y at 16 and 20 (i32 in 1e-4 m or 1e-7 degree, or f32 in m or
/// degrees), z f32 at 24, seq u16 at 28, command u16 at 30, then target
/// system, target component, frame, current and autocontinue at 32..37
/// (`mission_type`, an extension, is 0, cut as a trailing zero). Written
/// by that layout: the library's two encoders took twice the flash.
fn item_payload(item: &Item, seq: u16, to: (u8, u8), current: bool, int: bool) -> [u8; 37] {
    let (x, y) = if int {
        (item.x.to_le_bytes(), item.y.to_le_bytes())
    } else {
        let scale = if item.is_global() { 1e-7 } else { 1e-4 };
        (
            (item.x as f32 * scale).to_le_bytes(),
            (item.y as f32 * scale).to_le_bytes(),
        )
    };
    let mut payload = [0u8; 37];
    let fields: [(usize, [u8; 4]); 5] = [
        (0, item.hold_s.to_le_bytes()),
        (12, item.yaw_deg.to_le_bytes()),
        (16, x),
        (20, y),
        (24, item.z.to_le_bytes()),
    ];
    for (at, bytes) in fields {
        if let Some(d) = payload.get_mut(at..at + 4) {
            d.copy_from_slice(&bytes);
        }
    }
    let [s0, s1] = seq.to_le_bytes();
    let [c0, c1] = (c::MavCmd::MAV_CMD_NAV_WAYPOINT as u16).to_le_bytes();
    let tail = [
        s0,
        s1,
        c0,
        c1,
        to.0,
        to.1,
        frame_enum(item.frame) as u8,
        u8::from(current),
        1,
    ];
    if let Some(d) = payload.get_mut(28..37) {
        d.copy_from_slice(&tail);
    }
    payload
}

impl MavlinkEndpoint {
    // Out of line: at opt-level 3 with fat LTO, inlined into its caller it
    // is unrolled and duplicated (docs/mavlink.md, Cost).
    #[inline(never)]
    pub(crate) fn on_mission<F>(
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
        let from = (frame.sys_id, frame.comp_id);
        // Where each message carries its target system and component.
        let target = match frame.msg_id {
            c::MISSION_ITEM_INT_DATA::ID | c::MISSION_ITEM_DATA::ID => 32,
            c::MISSION_COUNT_DATA::ID
            | c::MISSION_REQUEST_INT_DATA::ID
            | c::MISSION_REQUEST_DATA::ID
            | c::MISSION_SET_CURRENT_DATA::ID => 2,
            c::MISSION_REQUEST_LIST_DATA::ID | c::MISSION_CLEAR_ALL_DATA::ID => 0,
            // MISSION_ACK from the ground station ends a download: nothing
            // is held for it.
            _ => return,
        };
        if !self.for_us(frame.byte(target), frame.byte(target + 1)) {
            return;
        }
        match frame.msg_id {
            c::MISSION_COUNT_DATA::ID => {
                self.on_count(now_ms, frame.u16_at(0), frame.byte(4), from, tx, events);
            }
            c::MISSION_ITEM_INT_DATA::ID | c::MISSION_ITEM_DATA::ID => {
                self.on_item(now_ms, frame, from, check_route, tx, events);
            }
            c::MISSION_REQUEST_LIST_DATA::ID => {
                let kind = frame.byte(2);
                let count = if kind == MISSION {
                    self.mission().len()
                } else {
                    0
                };
                // MISSION_COUNT: count u16, target system, component,
                // mission_type (an extension).
                let n = count.to_le_bytes();
                self.send_raw(
                    tx,
                    c::MISSION_COUNT_DATA::ID,
                    c::MISSION_COUNT_DATA::EXTRA_CRC,
                    &[n[0], n[1], from.0, from.1, kind],
                );
            }
            c::MISSION_REQUEST_INT_DATA::ID | c::MISSION_REQUEST_DATA::ID => {
                let int = frame.msg_id == c::MISSION_REQUEST_INT_DATA::ID;
                self.on_request(frame.u16_at(0), frame.byte(4), int, from, view, tx);
            }
            c::MISSION_CLEAR_ALL_DATA::ID => {
                let kind = frame.byte(2);
                let mut result = R::MAV_MISSION_ACCEPTED;
                if kind == MISSION || kind == 255 {
                    if events.push(Event::ClearRoute) {
                        self.upload = None;
                        self.clear_active();
                    } else {
                        result = R::MAV_MISSION_ERROR;
                    }
                }
                self.mission_ack(tx, from, result, kind);
            }
            _ => {
                // MISSION_SET_CURRENT.
                let seq = frame.u16_at(0);
                if seq < self.mission().len() && events.push(Event::SetCurrent(seq)) {
                    self.mission_current(tx, seq);
                } else {
                    self.refused();
                    self.status_text(
                        tx,
                        c::MavSeverity::MAV_SEVERITY_WARNING,
                        b"set current refused: no such item",
                    );
                }
            }
        }
    }

    fn clear_active(&mut self) {
        if let Some(m) = self.missions.get_mut(self.active) {
            m.clear();
        }
        self.last_reached = None;
        self.last_current = None;
    }

    fn refused(&mut self) {
        self.counters.mission_refusals = self.counters.mission_refusals.wrapping_add(1);
    }

    /// MISSION_ACK: target system, component, result, mission_type (an
    /// extension).
    // Out of line: called from many places; inlined at each (opt-level 3,
    // fat LTO) it cost flash (docs/mavlink.md, Cost).
    #[inline(never)]
    fn mission_ack(&mut self, tx: &mut TxBuffer<'_>, to: (u8, u8), result: R, kind: u8) {
        self.send_raw(
            tx,
            c::MISSION_ACK_DATA::ID,
            c::MISSION_ACK_DATA::EXTRA_CRC,
            &[to.0, to.1, result as u8, kind],
        );
    }

    /// MISSION_CURRENT: seq u16, total u16 (an extension: the item count).
    // Out of line: called from many places; inlined at each (opt-level 3,
    // fat LTO) it cost flash (docs/mavlink.md, Cost).
    #[inline(never)]
    pub(crate) fn mission_current(&mut self, tx: &mut TxBuffer<'_>, seq: u16) {
        let (s, n) = (seq.to_le_bytes(), self.mission().len().to_le_bytes());
        self.send_raw(
            tx,
            c::MISSION_CURRENT_DATA::ID,
            c::MISSION_CURRENT_DATA::EXTRA_CRC,
            &[s[0], s[1], n[0], n[1]],
        );
    }

    // Out of line: called from many places; inlined at each (opt-level 3,

    // fat LTO) it cost flash (docs/mavlink.md, Cost).

    // Out of line: at opt-level 3 with fat LTO, inlined into its caller it
    // is unrolled and duplicated (docs/mavlink.md, Cost).
    #[inline(never)]
    fn request_item(&mut self, tx: &mut TxBuffer<'_>, up: &Upload) {
        // MISSION_REQUEST_INT: seq u16, target system, target component
        // (mission_type, an extension, 0: cut as a trailing zero).
        let [s0, s1] = up.next.to_le_bytes();
        self.send_raw(
            tx,
            c::MISSION_REQUEST_INT_DATA::ID,
            c::MISSION_REQUEST_INT_DATA::EXTRA_CRC,
            &[s0, s1, up.partner.0, up.partner.1],
        );
    }

    // Out of line: at opt-level 3 with fat LTO, inlined into its caller it
    // is unrolled and duplicated (docs/mavlink.md, Cost).
    #[inline(never)]
    fn on_count(
        &mut self,
        now_ms: u32,
        count: u16,
        kind: u8,
        from: (u8, u8),
        tx: &mut TxBuffer<'_>,
        events: &mut Events,
    ) {
        self.upload = None;
        if kind != MISSION {
            self.refused();
            self.mission_ack(tx, from, R::MAV_MISSION_UNSUPPORTED, kind);
            return;
        }
        if usize::from(count) > ROUTE_CAPACITY {
            self.refused();
            self.mission_ack(tx, from, R::MAV_MISSION_NO_SPACE, kind);
            return;
        }
        if count == 0 {
            // An empty upload clears the mission.
            if events.push(Event::ClearRoute) {
                self.clear_active();
                self.mission_ack(tx, from, R::MAV_MISSION_ACCEPTED, kind);
            } else {
                self.mission_ack(tx, from, R::MAV_MISSION_ERROR, kind);
            }
            return;
        }
        if let Some(staging) = self.missions.get_mut(1 - self.active.min(1)) {
            staging.clear();
        }
        let up = Upload {
            partner: from,
            count,
            next: 0,
            last_ms: now_ms,
            retries: 0,
        };
        self.upload = Some(up);
        self.request_item(tx, &up);
    }

    // Out of line: at opt-level 3 with fat LTO, inlined into its caller it
    // is unrolled and duplicated (docs/mavlink.md, Cost).
    #[inline(never)]
    fn on_item<F>(
        &mut self,
        now_ms: u32,
        frame: &RxFrame,
        from: (u8, u8),
        check_route: &mut RouteCheck<'_, F>,
        tx: &mut TxBuffer<'_>,
        events: &mut Events,
    ) where
        F: FnMut(&Waypoints) -> Result<(), RouteError>,
    {
        let Some(mut up) = self.upload else { return };
        let seq = frame.u16_at(28);
        if from != up.partner || frame.byte(37) != MISSION || seq != up.next {
            // A repeat of an item already stored, or one out of turn: the
            // request for the expected one stands (its timeout re-sends it).
            return;
        }
        let int = frame.msg_id == c::MISSION_ITEM_INT_DATA::ID;
        let coord = |offset| {
            if int {
                Coord::Int(i32_at(frame, offset))
            } else {
                Coord::Float(f32_at(frame, offset))
            }
        };
        let raw = RawItem {
            command: frame.u16_at(30),
            frame: frame.byte(34),
            params: [
                f32_at(frame, 0),
                f32_at(frame, 4),
                f32_at(frame, 8),
                f32_at(frame, 12),
            ],
            x: coord(16),
            y: coord(20),
            z: f32_at(frame, 24),
        };
        let item = match check_item(&raw, self.config.origin.is_some()) {
            Ok(item) => item,
            Err(result) => return self.abort_upload(tx, from, result),
        };
        let staging_index = 1 - self.active.min(1);
        let stored = self
            .missions
            .get_mut(staging_index)
            .is_some_and(|m| m.push(item));
        if !stored {
            return self.abort_upload(tx, from, R::MAV_MISSION_NO_SPACE);
        }
        up.next += 1;
        up.retries = 0;
        up.last_ms = now_ms;
        if up.next < up.count {
            self.upload = Some(up);
            self.request_item(tx, &up);
            return;
        }
        self.upload = None;
        // Written in place, where the caller keeps it (not built here).
        let RouteCheck { check, route } = check_route;
        match self.missions.get(staging_index) {
            Some(m) => m.write_waypoints(self.config.origin.as_ref(), route),
            None => route.clear(),
        }
        if let Err(error) = check(route) {
            self.status_text(
                tx,
                c::MavSeverity::MAV_SEVERITY_WARNING,
                b"mission refused by the route check; previous kept",
            );
            return self.abort_upload(tx, from, route_refusal(error));
        }
        if !events.push(Event::LoadRoute) {
            return self.abort_upload(tx, from, R::MAV_MISSION_ERROR);
        }
        self.active = staging_index;
        self.last_reached = None;
        self.last_current = None;
        self.mission_ack(tx, from, R::MAV_MISSION_ACCEPTED, MISSION);
    }

    fn abort_upload(&mut self, tx: &mut TxBuffer<'_>, to: (u8, u8), result: R) {
        self.upload = None;
        self.refused();
        self.mission_ack(tx, to, result, MISSION);
    }

    /// Re-requests the expected item after the item timeout; cancels the
    /// upload when the retries run out.
    // Out of line: at opt-level 3 with fat LTO, inlined into its caller it
    // is unrolled and duplicated (docs/mavlink.md, Cost).
    #[inline(never)]
    pub(crate) fn upload_timeout(&mut self, now_ms: u32, tx: &mut TxBuffer<'_>) {
        let Some(mut up) = self.upload else { return };
        if now_ms.wrapping_sub(up.last_ms) < self.config.item_timeout_ms {
            return;
        }
        if up.retries < self.config.item_retries {
            up.retries += 1;
            up.last_ms = now_ms;
            self.upload = Some(up);
            self.request_item(tx, &up);
        } else {
            self.upload = None;
            self.counters.upload_timeouts = self.counters.upload_timeouts.wrapping_add(1);
            self.mission_ack(tx, up.partner, R::MAV_MISSION_OPERATION_CANCELLED, MISSION);
        }
    }

    // Out of line: at opt-level 3 with fat LTO, inlined into its caller it
    // is unrolled and duplicated (docs/mavlink.md, Cost).
    #[inline(never)]
    fn on_request(
        &mut self,
        seq: u16,
        kind: u8,
        int: bool,
        to: (u8, u8),
        view: &RobotView,
        tx: &mut TxBuffer<'_>,
    ) {
        let item = if kind == MISSION {
            self.mission().get(seq).copied()
        } else {
            None
        };
        let Some(item) = item else {
            self.refused();
            return self.mission_ack(tx, to, R::MAV_MISSION_INVALID_SEQUENCE, kind);
        };
        let current = seq == view.current;
        let (id, extra) = if int {
            (
                c::MISSION_ITEM_INT_DATA::ID,
                c::MISSION_ITEM_INT_DATA::EXTRA_CRC,
            )
        } else {
            (c::MISSION_ITEM_DATA::ID, c::MISSION_ITEM_DATA::EXTRA_CRC)
        };
        self.send_raw(tx, id, extra, &item_payload(&item, seq, to, current, int));
    }
}

#[cfg(test)]
mod tests {
    use super::{c, item_payload};
    use crate::mission::Item;
    use mavlink::MessageData;

    /// The hand-written item payloads are the library's encodings of the
    /// same items, byte for byte (the library's as long as its
    /// `ENCODED_LEN`; the extension byte past it is 0).
    #[test]
    fn item_payloads_are_the_librarys_encoding() {
        let items = [
            Item {
                frame: 1,
                hold_s: 2.5,
                yaw_deg: f32::NAN,
                x: 12_345,
                y: -67_890,
                z: 0.0,
            },
            Item {
                frame: 6,
                hold_s: 0.0,
                yaw_deg: -90.0,
                x: 473_977_420,
                y: 85_455_940,
                z: 1.5,
            },
            Item {
                frame: 0,
                hold_s: 1.0,
                yaw_deg: 10.0,
                x: -1,
                y: i32::MAX,
                z: -3.0,
            },
        ];
        for (k, item) in items.iter().enumerate() {
            let seq = 7 * k as u16;
            let (to, current) = ((255, 190), k == 1);
            let frame = super::frame_enum(item.frame);
            let int = c::MISSION_ITEM_INT_DATA {
                param1: item.hold_s,
                param4: item.yaw_deg,
                x: item.x,
                y: item.y,
                z: item.z,
                seq,
                command: c::MavCmd::MAV_CMD_NAV_WAYPOINT,
                target_system: to.0,
                target_component: to.1,
                frame,
                current: u8::from(current),
                autocontinue: 1,
                ..Default::default()
            };
            let scale = if item.is_global() { 1e-7 } else { 1e-4 };
            let float = c::MISSION_ITEM_DATA {
                param1: item.hold_s,
                param4: item.yaw_deg,
                x: item.x as f32 * scale,
                y: item.y as f32 * scale,
                z: item.z,
                seq,
                command: c::MavCmd::MAV_CMD_NAV_WAYPOINT,
                target_system: to.0,
                target_component: to.1,
                frame,
                current: u8::from(current),
                autocontinue: 1,
                ..Default::default()
            };
            let mut lib = [0u8; 255];
            let n = int.ser(mavlink::MavlinkVersion::V2, &mut lib);
            let ours = item_payload(item, seq, to, current, true);
            assert_eq!(ours[..n], lib[..n], "MISSION_ITEM_INT {k}");
            assert!(ours[n..].iter().all(|&b| b == 0), "MISSION_ITEM_INT {k}");
            let mut lib = [0u8; 255];
            let n = float.ser(mavlink::MavlinkVersion::V2, &mut lib);
            let ours = item_payload(item, seq, to, current, false);
            assert_eq!(ours[..n], lib[..n], "MISSION_ITEM {k}");
            assert!(ours[n..].iter().all(|&b| b == 0), "MISSION_ITEM {k}");
        }
    }
}
