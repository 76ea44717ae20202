//! Telemetry: one compact record per emitted control tick, the same on
//! both boards, and its text form as a defmt decoder prints it.
//!
//! The firmware (`firmware/src/telemetry.rs`) prints a [`Record`] with
//! `defmt::println!` (not filtered by `DEFMT_LOG`) every
//! [`Start::every_ticks`]-th tick (`tick % every_ticks == 0`; 0 = off),
//! after a [`Start`] line when a run starts. A decoder (`firmware-sim hil`
//! writing `firmware.log`, `probe-rs run` on the Black Pill, `defmt-print`)
//! turns them into one text line each, which [`parse_line`] reads back:
//!
//! ```text
//! wmr-tlm-start 1 <every_ticks> <period_s>
//! wmr-tlm 1 <tick> <mode> <flags> <ref_x> <ref_y> <x> <y> <cos> <sin> <v> <omega> <duty_l> <duty_r> <ticks_since_fix> <fixes_used> <device_faults>
//! ```
//!
//! The `1` after the tag is [`FORMAT_VERSION`]. `f32`s are printed by the
//! decoder in their shortest round-trip form (`ryu`), so that parsing
//! them gives back the very bits the firmware had. Anything before the
//! tag on a line (a probe's timestamp and level) and after the last field
//! (a probe's location suffix, on its own line or after a space) is
//! ignored; lines without the tag are not telemetry.

use wmr_core::pilot::robot::{RobotCounters, RobotTick};
use wmr_core::pilot::tracker::{TrackerCounters, TrackerMode};

use crate::TickOutput;

/// Version of the text form; bump when a field is added, removed or moved.
pub const FORMAT_VERSION: u32 = 1;

/// The tag that starts a [`Record`] line.
pub const RECORD_TAG: &str = "wmr-tlm";

/// The tag that starts a [`Start`] line.
pub const START_TAG: &str = "wmr-tlm-start";

/// Fields of a record line after the tag and the version.
pub const RECORD_FIELDS: usize = 16;

/// [`Record::flags`]: a tag fix passed the tracker's checks this tick
/// (`TrackerOutput::fix_used`).
pub const FLAG_FIX: u8 = 1;
/// [`Record::flags`]: the drive's wheel-speed limit scaled the command.
pub const FLAG_SPEED_LIMITED: u8 = 1 << 1;
/// [`Record::flags`]: the drive's acceleration limit acted.
pub const FLAG_ACCEL_LIMITED: u8 = 1 << 2;
/// [`Record::flags`]: the motors are stopped for persistent encoder faults.
pub const FLAG_ENCODER_HALT: u8 = 1 << 3;
/// [`Record::flags`]: a motor write failed this tick.
pub const FLAG_MOTOR_FAULT: u8 = 1 << 4;

/// What starts a run's telemetry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Start {
    /// A record every this many ticks (`tick % every_ticks == 0`); 0: none.
    pub every_ticks: u16,
    /// Control period, s (the pilot spec's `period_s`): `t = k·h`.
    pub period_s: f32,
}

/// One control tick, as the firmware saw and drove it. Units: m, m/s,
/// rad/s; duties are fractions of full scale in `[-1, 1]`, positive
/// forward.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Record {
    /// Tick index `k` (`t = k·h`), from 0 at configuration.
    pub tick: u32,
    /// Tracker mode after the tick: 0 awaiting fix, 1 tracking, 2 fix lost.
    pub mode: u8,
    /// `FLAG_*` bits.
    pub flags: u8,
    /// Reference position, m.
    pub reference_m: [f32; 2],
    /// Position the law used (fix or dead-reckoned), m.
    pub position_m: [f32; 2],
    /// Heading estimate `(cos θ̂, sin θ̂)`.
    pub heading: [f32; 2],
    /// Body command `(v m/s, ω rad/s)`.
    pub command: [f32; 2],
    /// The pilot's signed motor duties `(left, right)`, before the PWM's
    /// quantization to whole steps.
    pub duty: [f32; 2],
    /// Ticks since the last valid fix.
    pub ticks_since_fix: u32,
    /// Fixes the tracker used since configuration.
    pub fixes_used: u32,
    /// Device faults since configuration: both encoders' failed reads,
    /// unknown tags and failed motor writes.
    pub device_faults: u32,
}

/// The mode's number in a [`Record`].
#[must_use]
pub fn mode_code(mode: TrackerMode) -> u8 {
    match mode {
        TrackerMode::AwaitingFix => 0,
        TrackerMode::Tracking => 1,
        TrackerMode::FixLost => 2,
    }
}

/// The mode of a [`Record::mode`] number.
#[must_use]
pub fn mode_of_code(code: u8) -> Option<TrackerMode> {
    match code {
        0 => Some(TrackerMode::AwaitingFix),
        1 => Some(TrackerMode::Tracking),
        2 => Some(TrackerMode::FixLost),
        _ => None,
    }
}

impl Record {
    /// The record of tick `out` with the robot's and tracker's counters
    /// after it.
    #[must_use]
    pub fn of(out: &RobotTick, robot: RobotCounters, tracker: TrackerCounters) -> Self {
        let t = &out.pilot.tracker;
        let flag = |on: bool, bit: u8| if on { bit } else { 0 };
        let flags = flag(t.fix_used, FLAG_FIX)
            | flag(out.pilot.drive.speed_limited, FLAG_SPEED_LIMITED)
            | flag(out.pilot.drive.accel_limited, FLAG_ACCEL_LIMITED)
            | flag(out.pilot.encoder_halt, FLAG_ENCODER_HALT)
            | flag(out.motor_fault.is_some(), FLAG_MOTOR_FAULT);
        Self {
            tick: t.tick,
            mode: mode_code(t.mode),
            flags,
            reference_m: [t.reference.position.x, t.reference.position.y],
            position_m: [t.position.x, t.position.y],
            heading: [t.heading.cos_theta, t.heading.sin_theta],
            command: [t.command.v_m_s, t.command.omega_rad_s],
            duty: [out.pilot.left.signed(), out.pilot.right.signed()],
            ticks_since_fix: t.ticks_since_fix,
            fixes_used: tracker.fixes_used,
            device_faults: device_faults(robot),
        }
    }
}

/// What a [`Record`] has beyond the link's [`TickOutput`]: the QEMU
/// board's session builds its records from its answer and these
/// ([`Record::of_answer`]), equal to [`Record::of`] (tested).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Extra {
    /// The tracker's tick index.
    pub tick: u32,
    /// The pilot's signed duties.
    pub duty: [f32; 2],
    /// Ticks since the last valid fix.
    pub ticks_since_fix: u32,
    /// `FLAG_ENCODER_HALT | FLAG_MOTOR_FAULT` bits.
    pub flags: u8,
}

impl Extra {
    /// The extras of tick `out`.
    #[must_use]
    pub fn of(out: &RobotTick) -> Self {
        let flag = |on: bool, bit: u8| if on { bit } else { 0 };
        Self {
            tick: out.pilot.tracker.tick,
            duty: [out.pilot.left.signed(), out.pilot.right.signed()],
            ticks_since_fix: out.pilot.tracker.ticks_since_fix,
            flags: flag(out.pilot.encoder_halt, FLAG_ENCODER_HALT)
                | flag(out.motor_fault.is_some(), FLAG_MOTOR_FAULT),
        }
    }
}

impl Record {
    /// The record of a tick from the link's answer to it and the
    /// [`Extra`]s, with the robot's and tracker's counters after it.
    #[must_use]
    pub fn of_answer(
        answer: &TickOutput,
        extra: Extra,
        robot: RobotCounters,
        tracker: TrackerCounters,
    ) -> Self {
        let flag = |on: bool, bit: u8| if on { bit } else { 0 };
        Self {
            tick: extra.tick,
            mode: mode_code(answer.mode),
            flags: flag(answer.fix, FLAG_FIX)
                | flag(answer.speed_limited, FLAG_SPEED_LIMITED)
                | flag(answer.accel_limited, FLAG_ACCEL_LIMITED)
                | extra.flags,
            reference_m: answer.reference_m,
            position_m: answer.position_m,
            heading: answer.heading,
            command: answer.command,
            duty: extra.duty,
            ticks_since_fix: extra.ticks_since_fix,
            fixes_used: tracker.fixes_used,
            device_faults: device_faults(robot),
        }
    }
}

/// Both encoders' failed reads, unknown tags and failed motor writes.
fn device_faults(robot: RobotCounters) -> u32 {
    robot
        .left_encoder_errors
        .saturating_add(robot.right_encoder_errors)
        .saturating_add(robot.unknown_tags)
        .saturating_add(robot.motor_faults)
}

/// Whether tick `tick` is emitted at a decimation of `every_ticks`.
#[must_use]
pub fn is_emitted(tick: u32, every_ticks: u16) -> bool {
    every_ticks != 0 && tick.is_multiple_of(u32::from(every_ticks))
}

/// A telemetry line, parsed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Line {
    /// A run's start.
    Start(Start),
    /// A tick.
    Record(Record),
}

/// Why a line with a telemetry tag was not read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ParseError {
    /// Another [`FORMAT_VERSION`] (the one found, if it is a number).
    Version(Option<u32>),
    /// Fewer fields than the format has: a truncated line.
    Truncated {
        /// Fields found after the version.
        found: usize,
    },
    /// Field `index` (from 0 after the version) is not a number of its type.
    Field {
        /// The field's index.
        index: usize,
    },
    /// The mode is not 0, 1 or 2.
    Mode(u8),
}

impl core::fmt::Display for ParseError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Version(Some(v)) => write!(
                f,
                "telemetry format version {v}, this reader knows {FORMAT_VERSION}"
            ),
            Self::Version(None) => f.write_str("no telemetry format version after the tag"),
            Self::Truncated { found } => {
                write!(f, "truncated: {found} fields, not all the format has")
            }
            Self::Field { index } => write!(f, "field {index} is not a number of its type"),
            Self::Mode(m) => write!(f, "mode {m} is none of 0, 1, 2"),
        }
    }
}

impl core::error::Error for ParseError {}

/// Reads one line of a decoded log: `None` if it is not telemetry (no tag
/// as a whole word), else the line or why it cannot be read. Text after
/// the last field is ignored (a decoder's location suffix).
#[must_use]
pub fn parse_line(line: &str) -> Option<Result<Line, ParseError>> {
    let mut words = line.split_ascii_whitespace();
    let tag = words.find(|w| *w == RECORD_TAG || *w == START_TAG)?;
    Some(parse_after_tag(tag == START_TAG, words))
}

fn parse_after_tag<'a>(
    start: bool,
    mut words: impl Iterator<Item = &'a str>,
) -> Result<Line, ParseError> {
    let version = words.next().map(str::parse::<u32>);
    match version {
        Some(Ok(FORMAT_VERSION)) => {}
        Some(Ok(v)) => return Err(ParseError::Version(Some(v))),
        _ => return Err(ParseError::Version(None)),
    }
    let mut fields = [""; RECORD_FIELDS];
    let wanted = if start { 2 } else { RECORD_FIELDS };
    let mut found = 0;
    for slot in fields.iter_mut().take(wanted) {
        match words.next() {
            Some(w) => {
                *slot = w;
                found += 1;
            }
            None => return Err(ParseError::Truncated { found }),
        }
    }
    let mut fields = fields.iter().copied().enumerate();
    if start {
        return Ok(Line::Start(Start {
            every_ticks: next(&mut fields)?,
            period_s: next(&mut fields)?,
        }));
    }
    let tick = next(&mut fields)?;
    let mode: u8 = next(&mut fields)?;
    if mode_of_code(mode).is_none() {
        return Err(ParseError::Mode(mode));
    }
    let flags = next(&mut fields)?;
    let mut pair =
        || -> Result<[f32; 2], ParseError> { Ok([next(&mut fields)?, next(&mut fields)?]) };
    let reference_m = pair()?;
    let position_m = pair()?;
    let heading = pair()?;
    let command = pair()?;
    let duty = pair()?;
    Ok(Line::Record(Record {
        tick,
        mode,
        flags,
        reference_m,
        position_m,
        heading,
        command,
        duty,
        ticks_since_fix: next(&mut fields)?,
        fixes_used: next(&mut fields)?,
        device_faults: next(&mut fields)?,
    }))
}

/// The next field, parsed as `T`.
fn next<'a, T: core::str::FromStr>(
    fields: &mut impl Iterator<Item = (usize, &'a str)>,
) -> Result<T, ParseError> {
    let (index, word) = fields.next().ok_or(ParseError::Truncated {
        found: RECORD_FIELDS,
    })?;
    word.parse().map_err(|_| ParseError::Field { index })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The record's line as the firmware's format string and a defmt
    /// decoder print it (`{=f32}` as `ryu` does: shortest round trip).
    fn line_of(r: &Record) -> std::string::String {
        let f = |x: f32| ryu_like(x);
        std::format!(
            "wmr-tlm 1 {} {} {} {} {} {} {} {} {} {} {} {} {} {} {} {}",
            r.tick,
            r.mode,
            r.flags,
            f(r.reference_m[0]),
            f(r.reference_m[1]),
            f(r.position_m[0]),
            f(r.position_m[1]),
            f(r.heading[0]),
            f(r.heading[1]),
            f(r.command[0]),
            f(r.command[1]),
            f(r.duty[0]),
            f(r.duty[1]),
            r.ticks_since_fix,
            r.fixes_used,
            r.device_faults
        )
    }

    /// Rust's `Display` of `f32` is also a shortest round-trip form; `ryu`
    /// writes exponents (`1e-7`), which `str::parse` reads the same.
    fn ryu_like(x: f32) -> std::string::String {
        if x.is_finite() && x != 0.0 && x.abs() < 1e-5 {
            std::format!("{x:e}")
        } else {
            std::format!("{x}")
        }
    }

    fn record() -> Record {
        Record {
            tick: 4_000_000_000,
            mode: 1,
            flags: FLAG_FIX | FLAG_ACCEL_LIMITED,
            reference_m: [0.1, -2.75e-7],
            position_m: [f32::MIN_POSITIVE, -0.0],
            heading: [0.999_999_94, core::f32::consts::PI],
            command: [f32::MAX, -1.0e30],
            duty: [-1.0, 0.333_333_34],
            ticks_since_fix: 7,
            fixes_used: u32::MAX,
            device_faults: 0,
        }
    }

    #[test]
    fn a_record_line_round_trips_bit_for_bit() {
        let r = record();
        let line = line_of(&r);
        // As probe-rs prints it: timestamp and level before, location after.
        let probe = std::format!("0.123456 [INFO ] {line} (src/telemetry.rs:12)");
        for text in [line.clone(), probe] {
            let Some(Ok(Line::Record(back))) = parse_line(&text) else {
                panic!("{text}: {:?}", parse_line(&text));
            };
            assert_eq!(std::format!("{back:?}"), std::format!("{r:?}"));
            for (a, b) in back.position_m.iter().zip(r.position_m) {
                assert_eq!(a.to_bits(), b.to_bits());
            }
        }
    }

    #[test]
    fn a_start_line_is_read() {
        assert_eq!(
            parse_line("wmr-tlm-start 1 10 0.01"),
            Some(Ok(Line::Start(Start {
                every_ticks: 10,
                period_s: 0.01
            })))
        );
    }

    #[test]
    fn other_lines_are_not_telemetry() {
        for line in [
            "",
            "INFO configured",
            "wmr-tlmx 1 2",
            "xwmr-tlm 1 2",
            "wmr-firmware (QEMU board), link protocol 11",
        ] {
            assert_eq!(parse_line(line), None, "{line}");
        }
    }

    #[test]
    fn malformed_and_truncated_lines_say_why() {
        let full = line_of(&record());
        let words: std::vec::Vec<&str> = full.split(' ').collect();
        // Cut after every word: each prefix is truncated, never misread.
        for n in 2..words.len() {
            let cut = words[..n].join(" ");
            assert_eq!(
                parse_line(&cut),
                Some(Err(ParseError::Truncated { found: n - 2 })),
                "{cut}"
            );
        }
        // A word cut in the middle of a number, then the line ends.
        assert_eq!(
            parse_line("wmr-tlm 1"),
            Some(Err(ParseError::Truncated { found: 0 }))
        );
        assert_eq!(
            parse_line("wmr-tlm 2 0"),
            Some(Err(ParseError::Version(Some(2))))
        );
        assert_eq!(
            parse_line("wmr-tlm x"),
            Some(Err(ParseError::Version(None)))
        );
        let bad_mode = full.replacen("wmr-tlm 1 4000000000 1 ", "wmr-tlm 1 4000000000 3 ", 1);
        assert_eq!(parse_line(&bad_mode), Some(Err(ParseError::Mode(3))));
        let bad_float = full.replacen(" 0.1 ", " 0.1x ", 1);
        assert_eq!(
            parse_line(&bad_float),
            Some(Err(ParseError::Field { index: 3 }))
        );
    }

    #[test]
    fn decimation_counts_from_tick_zero() {
        let emitted: std::vec::Vec<u32> = (0..25).filter(|&k| is_emitted(k, 10)).collect();
        assert_eq!(emitted, [0, 10, 20]);
        assert!((0..25).all(|k| !is_emitted(k, 0)));
        assert!((0..25).all(|k| is_emitted(k, 1)));
    }
}
