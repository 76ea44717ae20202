//! `COMMAND_LONG` and `COMMAND_INT`, answered with `COMMAND_ACK`.
//!
//! The fields are read from the payload's wire layout rather than through
//! the library's decoder, which refuses a command number it does not know
//! (that command must still be answered, `MAV_RESULT_UNSUPPORTED`).

use mavlink::MessageData;
use mavlink::dialects::common as c;

use crate::endpoint::{Event, Events, MavlinkEndpoint, RobotMode, RobotView};
use crate::wire::{RxFrame, TxBuffer};

/// `MAV_CMD_COMPONENT_ARM_DISARM`.
pub const CMD_ARM_DISARM: u16 = 400;
/// `MAV_CMD_MISSION_START`.
pub const CMD_MISSION_START: u16 = 300;
/// `MAV_CMD_DO_PAUSE_CONTINUE`.
pub const CMD_PAUSE_CONTINUE: u16 = 193;
/// `MAV_CMD_DO_FLIGHTTERMINATION`: the emergency stop.
pub const CMD_TERMINATE: u16 = 185;
/// `MAV_CMD_DO_SET_MISSION_CURRENT`.
pub const CMD_SET_MISSION_CURRENT: u16 = 224;
/// `param2` of a disarm that is forced: an emergency stop.
pub const FORCE_MAGIC: f32 = 21_196.0;

const ACCEPTED: u8 = c::MavResult::MAV_RESULT_ACCEPTED as u8;
const TEMPORARILY_REJECTED: u8 = c::MavResult::MAV_RESULT_TEMPORARILY_REJECTED as u8;
const DENIED: u8 = c::MavResult::MAV_RESULT_DENIED as u8;
const UNSUPPORTED: u8 = c::MavResult::MAV_RESULT_UNSUPPORTED as u8;

/// What a command asks, before the events are pushed.
struct Verdict {
    result: u8,
    events: [Option<Event>; 2],
    reason: &'static [u8],
}

impl Verdict {
    fn accept(first: Option<Event>, second: Option<Event>) -> Self {
        Self {
            result: ACCEPTED,
            events: [first, second],
            reason: b"",
        }
    }

    fn deny(reason: &'static [u8]) -> Self {
        Self {
            result: DENIED,
            events: [None, None],
            reason,
        }
    }
}

fn f32_at(frame: &RxFrame, offset: usize) -> f32 {
    f32::from_le_bytes([
        frame.byte(offset),
        frame.byte(offset + 1),
        frame.byte(offset + 2),
        frame.byte(offset + 3),
    ])
}

impl MavlinkEndpoint {
    // Out of line: at opt-level 3 with fat LTO, inlined into its caller it
    // is unrolled and duplicated (docs/mavlink.md, Cost).
    #[inline(never)]
    pub(crate) fn on_command(
        &mut self,
        frame: &RxFrame,
        view: &RobotView,
        tx: &mut TxBuffer<'_>,
        events: &mut Events,
    ) {
        // Both layouts: param1..param4 at 0..16; command, target system
        // and component at 28, 30, 31.
        let command = frame.u16_at(28);
        if !self.for_us(frame.byte(30), frame.byte(31)) {
            return;
        }
        let p1 = f32_at(frame, 0);
        let p2 = f32_at(frame, 4);
        let verdict = self.decide(command, p1, p2, view);
        let mut result = verdict.result;
        let wanted = verdict.events.iter().flatten().count();
        if result == ACCEPTED && events_left(events) < wanted {
            result = TEMPORARILY_REJECTED;
        }
        if result == ACCEPTED {
            for event in verdict.events.into_iter().flatten() {
                let _ = events.push(event);
            }
        } else {
            self.counters.command_refusals = self.counters.command_refusals.wrapping_add(1);
            if !verdict.reason.is_empty() {
                self.status_text(tx, c::MavSeverity::MAV_SEVERITY_WARNING, verdict.reason);
            }
        }
        self.command_ack(tx, command, result, frame.sys_id, frame.comp_id);
    }

    // Out of line: at opt-level 3 with fat LTO, inlined into its caller it
    // is unrolled and duplicated (docs/mavlink.md, Cost).
    #[inline(never)]
    fn decide(&self, command: u16, p1: f32, p2: f32, view: &RobotView) -> Verdict {
        let count = self.mission().len();
        match command {
            CMD_ARM_DISARM if p1 == 1.0 => {
                Verdict::accept((!view.armed).then_some(Event::Arm), None)
            }
            CMD_ARM_DISARM if p1 == 0.0 && p2 == FORCE_MAGIC => {
                Verdict::accept(Some(Event::EmergencyStop), None)
            }
            CMD_ARM_DISARM if p1 == 0.0 => {
                if view.mode == RobotMode::Running {
                    Verdict::deny(b"disarm denied: running (pause, or force)")
                } else {
                    Verdict::accept(view.armed.then_some(Event::Disarm), None)
                }
            }
            CMD_ARM_DISARM => Verdict::deny(b"arm/disarm: param1 must be 0 or 1"),
            CMD_MISSION_START => {
                if count == 0 {
                    Verdict::deny(b"start denied: no mission")
                } else if !view.armed {
                    Verdict::deny(b"start denied: disarmed")
                } else if view.mode == RobotMode::Stopped {
                    Verdict::deny(b"start denied: stopped (disarm, re-arm)")
                } else if !(p1.is_finite() && p1 >= 0.0 && p1 < f32::from(count)) {
                    Verdict::deny(b"start denied: first item out of the mission")
                } else if p1 >= 1.0 {
                    Verdict::accept(Some(Event::SetCurrent(p1 as u16)), Some(Event::Start))
                } else {
                    Verdict::accept(Some(Event::Start), None)
                }
            }
            CMD_PAUSE_CONTINUE if p1 == 0.0 => match view.mode {
                RobotMode::Running => Verdict::accept(Some(Event::Pause), None),
                RobotMode::Paused => Verdict::accept(None, None),
                _ => Verdict::deny(b"pause denied: not running"),
            },
            CMD_PAUSE_CONTINUE if p1 == 1.0 => match view.mode {
                RobotMode::Paused => Verdict::accept(Some(Event::Continue), None),
                RobotMode::Running => Verdict::accept(None, None),
                _ => Verdict::deny(b"continue denied: not paused"),
            },
            CMD_PAUSE_CONTINUE => Verdict::deny(b"pause/continue: param1 must be 0 or 1"),
            CMD_TERMINATE if p1 > 0.5 => Verdict::accept(Some(Event::EmergencyStop), None),
            CMD_TERMINATE => Verdict::deny(b"termination off: disarm and re-arm instead"),
            CMD_SET_MISSION_CURRENT => {
                if p1.is_finite() && p1 >= 0.0 && p1 < f32::from(count) {
                    Verdict::accept(Some(Event::SetCurrent(p1 as u16)), None)
                } else {
                    Verdict::deny(b"set current denied: no such item")
                }
            }
            _ => Verdict {
                result: UNSUPPORTED,
                events: [None, None],
                reason: b"",
            },
        }
    }

    /// `COMMAND_ACK` written from its wire layout (command u16, result u8,
    /// progress u8, result_param2 i32, target system, target component),
    /// so that an unknown command number is echoed as received.
    // Out of line: called from many places; inlined at each (opt-level 3,
    // fat LTO) it cost flash (docs/mavlink.md, Cost).
    #[inline(never)]
    fn command_ack(&mut self, tx: &mut TxBuffer<'_>, command: u16, result: u8, sys: u8, comp: u8) {
        let cmd = command.to_le_bytes();
        let payload = [cmd[0], cmd[1], result, 0, 0, 0, 0, 0, sys, comp];
        self.send_raw(
            tx,
            c::COMMAND_ACK_DATA::ID,
            c::COMMAND_ACK_DATA::EXTRA_CRC,
            &payload,
        );
    }
}

/// Room left in the event list.
fn events_left(events: &Events) -> usize {
    crate::endpoint::EVENT_CAPACITY.saturating_sub(events.as_slice().len())
}
