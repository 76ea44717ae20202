//! Virtual devices: the peripherals the firmware talks to, implementing the
//! same traits, backed by the simulated plant.
//!
//! * [`VirtualPwm`] + [`VirtualDirectionPin`] ([`embedded_hal`] 1.0 PWM and
//!   GPIO) write one motor's [`MotorSignals`], which the simulation loop
//!   turns into the signed duty the plant's motor sees.
//! * [`VirtualEncoder`] ([`QuadratureCounter`]) reads a [`WheelShaft`]
//!   angle that the loop updates from the plant: quantized to whole counts
//!   and wrapping at the counter's width, like a timer in encoder mode.
//! * [`VirtualUart`] ([`embedded_io::Read`] + [`embedded_io::ReadReady`])
//!   delivers the bytes a [`VirtualRfidReader`] sends, each one only once
//!   its 10 bit times at the configured baud rate have passed, so a frame
//!   can span control ticks.
//!
//! Devices share state with the loop through `Rc<Cell<_>>` /
//! `Rc<RefCell<_>>` handles: single-threaded, like the firmware's tick.

use std::cell::{Cell, RefCell};
use std::collections::VecDeque;
use std::convert::Infallible;
use std::f64::consts::TAU;
use std::rc::Rc;

use embedded_hal::digital::{self, OutputPin};
use embedded_hal::pwm::{self, SetDutyCycle};
use wmr_core::devices::{QuadratureCounter, TagId, encode_frame};

use crate::plant::PlantPose;
use crate::tags::Floor;

// ---------------------------------------------------------------------------
// Motors: PWM + direction pin.

/// What a motor's driver inputs show: PWM compare value and direction level.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MotorLine {
    /// PWM duty in steps of `max_duty`.
    pub duty: u16,
    /// Full-scale PWM duty.
    pub max_duty: u16,
    /// Direction pin level (high = forward, as the core's default wiring).
    pub direction_high: bool,
    /// Times the direction pin changed while the duty was non-zero (the
    /// shoot-through hazard the core's driver sequencing avoids; expect 0).
    pub reversals_under_drive: u32,
    /// PWM writes above `max_duty` (refused; expect 0).
    pub out_of_range_writes: u32,
}

/// Shared handle on one motor's driver inputs.
#[derive(Debug, Clone, Default)]
pub struct MotorSignals(Rc<Cell<MotorLine>>);

impl MotorSignals {
    /// A motor with a PWM of `max_duty` steps, duty 0, pin low.
    #[must_use]
    pub fn new(max_duty: u16) -> Self {
        Self(Rc::new(Cell::new(MotorLine {
            max_duty,
            ..MotorLine::default()
        })))
    }

    /// The driver inputs now.
    #[must_use]
    pub fn line(&self) -> MotorLine {
        self.0.get()
    }

    /// The signed duty the motor sees, in [−1, 1] (positive forward).
    #[must_use]
    pub fn signed_duty(&self) -> f64 {
        let l = self.0.get();
        if l.max_duty == 0 {
            return 0.0;
        }
        let magnitude = f64::from(l.duty) / f64::from(l.max_duty);
        if l.direction_high {
            magnitude
        } else {
            -magnitude
        }
    }

    fn update(&self, f: impl FnOnce(&mut MotorLine)) {
        let mut l = self.0.get();
        f(&mut l);
        self.0.set(l);
    }
}

/// A PWM channel ([`SetDutyCycle`]) driving a virtual motor.
///
/// Refuses (and counts) duties above the maximum, as a strict HAL would.
#[derive(Debug, Clone)]
pub struct VirtualPwm {
    signals: MotorSignals,
}

impl VirtualPwm {
    /// The PWM input of `signals`' motor.
    #[must_use]
    pub fn new(signals: MotorSignals) -> Self {
        Self { signals }
    }
}

impl pwm::ErrorType for VirtualPwm {
    type Error = pwm::ErrorKind;
}

impl SetDutyCycle for VirtualPwm {
    fn max_duty_cycle(&self) -> u16 {
        self.signals.line().max_duty
    }

    fn set_duty_cycle(&mut self, duty: u16) -> Result<(), pwm::ErrorKind> {
        if duty > self.signals.line().max_duty {
            self.signals.update(|l| l.out_of_range_writes += 1);
            return Err(pwm::ErrorKind::Other);
        }
        self.signals.update(|l| l.duty = duty);
        Ok(())
    }
}

/// The direction pin ([`OutputPin`]) of a virtual motor.
#[derive(Debug, Clone)]
pub struct VirtualDirectionPin {
    signals: MotorSignals,
}

impl VirtualDirectionPin {
    /// The direction input of `signals`' motor.
    #[must_use]
    pub fn new(signals: MotorSignals) -> Self {
        Self { signals }
    }

    fn set(&mut self, high: bool) {
        self.signals.update(|l| {
            if l.direction_high != high && l.duty != 0 {
                l.reversals_under_drive += 1;
            }
            l.direction_high = high;
        });
    }
}

impl digital::ErrorType for VirtualDirectionPin {
    type Error = Infallible;
}

impl OutputPin for VirtualDirectionPin {
    fn set_low(&mut self) -> Result<(), Infallible> {
        self.set(false);
        Ok(())
    }

    fn set_high(&mut self) -> Result<(), Infallible> {
        self.set(true);
        Ok(())
    }
}

// ---------------------------------------------------------------------------
// Encoders.

/// Shared handle on a wheel's angle (rad, continuous, positive forward).
#[derive(Debug, Clone, Default)]
pub struct WheelShaft(Rc<Cell<f64>>);

impl WheelShaft {
    /// A wheel at angle 0.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Sets the wheel angle, rad.
    pub fn set_angle_rad(&self, angle_rad: f64) {
        self.0.set(angle_rad);
    }

    /// The wheel angle, rad.
    #[must_use]
    pub fn angle_rad(&self) -> f64 {
        self.0.get()
    }
}

/// Spurious edges on an encoder's lines (a noisy motor without an input
/// filter): on a read, with `probability_per_read`, a burst of `min_counts`
/// to `max_counts` extra counts, up or down, lands in the counter and stays
/// there, as it would in a timer's counter.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct EncoderGlitches {
    /// Probability that a read finds a new burst, per read.
    pub probability_per_read: f64,
    /// Smallest burst, counts (≥ 1).
    pub min_counts: u32,
    /// Largest burst, counts (≥ `min_counts`).
    pub max_counts: u32,
    /// RNG seed (the right encoder uses `seed + 1`).
    pub seed: u64,
}

/// A quadrature counter ([`QuadratureCounter`]) on a virtual wheel.
///
/// `count = floor(angle / (2π / counts_per_rev))`, reported modulo
/// `2^bits`: quantized to whole counts and wrapping, as a hardware timer in
/// encoder mode; plus, optionally, the bursts of [`EncoderGlitches`].
#[derive(Debug, Clone)]
pub struct VirtualEncoder {
    shaft: WheelShaft,
    counts_per_rev: u32,
    mask: u64,
    glitches: EncoderGlitches,
    rng: fastrand::Rng,
    /// Counts the bursts put into the counter so far.
    extra_counts: i64,
    /// Bursts so far (shared with whoever reports them).
    bursts: Rc<Cell<u64>>,
}

impl VirtualEncoder {
    /// Default counter width, bits (most STM32 timers).
    pub const DEFAULT_BITS: u32 = 16;

    /// An encoder of `counts_per_rev` (quadrature counts per wheel turn) with
    /// a `bits`-wide counter (clamped to 1..=32).
    #[must_use]
    pub fn new(shaft: WheelShaft, counts_per_rev: u32, bits: u32) -> Self {
        let bits = bits.clamp(1, 32);
        Self {
            shaft,
            counts_per_rev,
            mask: (1_u64 << bits) - 1,
            glitches: EncoderGlitches::default(),
            rng: fastrand::Rng::with_seed(0),
            extra_counts: 0,
            bursts: Rc::new(Cell::new(0)),
        }
    }

    /// The same encoder with `glitches`, seeded with `seed`; returns the
    /// shared count of bursts injected.
    #[must_use]
    pub fn with_glitches(mut self, glitches: EncoderGlitches, seed: u64) -> (Self, Rc<Cell<u64>>) {
        self.glitches = glitches;
        self.rng = fastrand::Rng::with_seed(seed);
        let bursts = Rc::clone(&self.bursts);
        (self, bursts)
    }

    /// The unwrapped count the wheel angle corresponds to.
    #[must_use]
    pub fn absolute_count(&self) -> i64 {
        (self.shaft.angle_rad() * f64::from(self.counts_per_rev) / TAU).floor() as i64
    }
}

impl QuadratureCounter for VirtualEncoder {
    type Error = Infallible;

    fn raw_count(&mut self) -> Result<u32, Infallible> {
        let g = self.glitches;
        if g.probability_per_read > 0.0 && self.rng.f64() < g.probability_per_read {
            let min = g.min_counts.max(1);
            let size = i64::from(self.rng.u32(min..=g.max_counts.max(min)));
            self.extra_counts += if self.rng.bool() { size } else { -size };
            self.bursts.set(self.bursts.get() + 1);
        }
        // Two's complement, then the low `bits` bits: a down-counting timer
        // wraps from 0 to 2^bits − 1.
        Ok(((self.absolute_count() + self.extra_counts) as u64 & self.mask) as u32)
    }
}

// ---------------------------------------------------------------------------
// RFID reader and its UART.

/// The serial line between the reader and the MCU's UART.
#[derive(Debug, Default)]
struct SerialLine {
    /// Bytes sent, with the time each finishes arriving (s).
    queue: VecDeque<(f64, u8)>,
    /// Simulation time (s), set by the loop through the reader model.
    now_s: f64,
}

/// Time tolerance of the line, s (well below one bit at any baud rate).
const TIME_EPS_S: f64 = 1e-9;

/// The MCU's UART receiving the reader's bytes ([`embedded_io::Read`] +
/// [`embedded_io::ReadReady`]).
///
/// A byte is ready once it has fully arrived (10 bit times after its start
/// bit). `read` never blocks: with nothing ready it returns `Ok(0)` (the
/// core only reads after `read_ready`).
#[derive(Debug, Clone)]
pub struct VirtualUart {
    line: Rc<RefCell<SerialLine>>,
}

impl embedded_io::ErrorType for VirtualUart {
    type Error = Infallible;
}

impl embedded_io::ReadReady for VirtualUart {
    fn read_ready(&mut self) -> Result<bool, Infallible> {
        let line = self.line.borrow();
        Ok(line
            .queue
            .front()
            .is_some_and(|&(t, _)| t <= line.now_s + TIME_EPS_S))
    }
}

impl embedded_io::Read for VirtualUart {
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Infallible> {
        let mut line = self.line.borrow_mut();
        let now = line.now_s;
        let mut n = 0;
        for slot in buf.iter_mut() {
            match line.queue.front() {
                Some(&(t, byte)) if t <= now + TIME_EPS_S => {
                    *slot = byte;
                    line.queue.pop_front();
                    n += 1;
                }
                _ => break,
            }
        }
        Ok(n)
    }
}

/// When the reader reports a tag.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ReaderMode {
    /// Paper 001, section 6.3.2: the nearest tag, every control tick.
    Paper,
    /// A real reader: only a tag within `read_radius_m` of the antenna, on
    /// entering its range and then every `repeat_interval_s` while in range.
    Range {
        /// Read radius around the antenna, m.
        read_radius_m: f64,
        /// Repeat interval while the same tag stays in range, s.
        repeat_interval_s: f64,
    },
}

/// Optional faults of the reader link, drawn from a seeded RNG.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkFaults {
    /// Probability that a byte arrives with one bit flipped.
    pub corrupt_byte_probability: f64,
    /// Probability that a frame is lost entirely.
    pub drop_frame_probability: f64,
    /// RNG seed.
    pub seed: u64,
}

impl Default for LinkFaults {
    fn default() -> Self {
        Self {
            corrupt_byte_probability: 0.0,
            drop_frame_probability: 0.0,
            seed: 1,
        }
    }
}

/// Configuration of a [`VirtualRfidReader`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReaderConfig {
    /// When tags are reported.
    pub mode: ReaderMode,
    /// Antenna position ahead of the axle midpoint, m (the core takes the
    /// tag's position as the axle midpoint's, so a non-zero offset is an
    /// uncompensated bias).
    pub antenna_offset_m: f64,
    /// Line speed, baud (10 bits per byte: 8N1).
    pub baud: u32,
    /// Link faults (off by default).
    pub faults: LinkFaults,
    /// Time between two [`VirtualRfidReader::update`]s (the control
    /// period), s, when known: a range-mode reader whose repeat interval is
    /// shorter repeats between updates too (each repeat at its time, the
    /// line permitting), up to the line's capacity. `None`: one report per
    /// update at most.
    pub update_period_s: Option<f64>,
}

impl Default for ReaderConfig {
    fn default() -> Self {
        Self {
            mode: ReaderMode::Paper,
            antenna_offset_m: 0.0,
            baud: 115_200,
            faults: LinkFaults::default(),
            update_period_s: None,
        }
    }
}

/// What the reader model did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub struct ReaderModelCounters {
    /// Frames put on the line.
    pub frames_sent: u64,
    /// Reports not sent because the previous frame was still on the line.
    pub skipped_line_busy: u64,
    /// Frames lost (fault injection).
    pub frames_dropped: u64,
    /// Bytes sent with a flipped bit (fault injection).
    pub bytes_corrupted: u64,
}

/// The RFID reader hardware: sees the floor tags near its antenna and sends
/// [`encode_frame`] frames down a serial line to a [`VirtualUart`].
#[derive(Debug)]
pub struct VirtualRfidReader {
    config: ReaderConfig,
    floor: Floor,
    line: Rc<RefCell<SerialLine>>,
    /// Line idle from this time on, s.
    busy_until_s: f64,
    /// Last tag reported in range mode and when.
    last_report: Option<(TagId, f64)>,
    rng: fastrand::Rng,
    counters: ReaderModelCounters,
}

impl VirtualRfidReader {
    /// A reader over `floor`, and the UART at the other end of its line.
    #[must_use]
    pub fn new(config: ReaderConfig, floor: Floor) -> (Self, VirtualUart) {
        let line = Rc::new(RefCell::new(SerialLine::default()));
        let uart = VirtualUart {
            line: Rc::clone(&line),
        };
        let reader = Self {
            config,
            floor,
            line,
            busy_until_s: f64::NEG_INFINITY,
            last_report: None,
            rng: fastrand::Rng::with_seed(config.faults.seed),
            counters: ReaderModelCounters::default(),
        };
        (reader, uart)
    }

    /// Time one byte takes on the line, s.
    #[must_use]
    pub fn byte_time_s(&self) -> f64 {
        10.0 / f64::from(self.config.baud.max(1))
    }

    /// What the model did so far.
    #[must_use]
    pub fn counters(&self) -> ReaderModelCounters {
        self.counters
    }

    /// Bytes sent but not yet read by the UART's owner.
    #[must_use]
    pub fn bytes_pending(&self) -> usize {
        self.line.borrow().queue.len()
    }

    /// Advances the line to `t_s` without looking at the floor.
    pub fn set_time(&mut self, t_s: f64) {
        self.line.borrow_mut().now_s = t_s;
    }

    /// Advances the line to `t_s` and lets the reader look at the floor
    /// with the robot at `pose`; a report starts its frame at `t_s`.
    pub fn update(&mut self, t_s: f64, pose: &PlantPose) {
        self.line.borrow_mut().now_s = t_s;
        let (ax, ay) = pose.point_ahead(self.config.antenna_offset_m);
        let tag = self.floor.nearest(ax, ay);
        let report = match self.config.mode {
            ReaderMode::Paper => true,
            ReaderMode::Range {
                read_radius_m,
                repeat_interval_s,
            } => {
                if tag.distance_m > read_radius_m {
                    self.last_report = None;
                    false
                } else {
                    match self.last_report {
                        Some((id, at)) if id == tag.id => {
                            t_s - at >= repeat_interval_s - TIME_EPS_S
                        }
                        _ => true,
                    }
                }
            }
        };
        if report {
            self.send(t_s, tag.id);
        }
        // A reader repeating faster than it is updated: the repeats until the
        // next update, each when due (or when the line frees up). Repeat
        // intervals of an update period or more never get here, so their
        // timing is that of one report per update.
        if let (
            ReaderMode::Range {
                repeat_interval_s, ..
            },
            Some(period_s),
            Some((id, _)),
        ) = (
            self.config.mode,
            self.config.update_period_s,
            self.last_report,
        ) && repeat_interval_s < period_s
            && id == tag.id
        {
            let next_update_s = t_s + period_s;
            // Bounded by what the line can carry in a period (a dropped
            // frame does not occupy the line, so a tiny interval alone
            // would not bound it).
            let most = (period_s / self.byte_time_s()).ceil().min(1e6) as usize + 1;
            for _ in 0..most {
                let Some((_, at)) = self.last_report else {
                    break;
                };
                let due = (at + repeat_interval_s).max(self.busy_until_s);
                if due >= next_update_s - TIME_EPS_S {
                    break;
                }
                self.send(due, id);
            }
        }
    }

    /// Sends one frame for `id` starting at `t_s`, unless the line is busy.
    pub fn send(&mut self, t_s: f64, id: TagId) {
        if self.busy_until_s > t_s + TIME_EPS_S {
            self.counters.skipped_line_busy += 1;
            return;
        }
        self.last_report = Some((id, t_s));
        let faults = self.config.faults;
        if faults.drop_frame_probability > 0.0 && self.rng.f64() < faults.drop_frame_probability {
            self.counters.frames_dropped += 1;
            return;
        }
        let byte_time = self.byte_time_s();
        let mut line = self.line.borrow_mut();
        for (i, &byte) in encode_frame(id).iter().enumerate() {
            let mut byte = byte;
            if faults.corrupt_byte_probability > 0.0
                && self.rng.f64() < faults.corrupt_byte_probability
            {
                byte ^= 1 << self.rng.u8(0..8);
                self.counters.bytes_corrupted += 1;
            }
            line.queue
                .push_back((t_s + (i as f64 + 1.0) * byte_time, byte));
        }
        self.busy_until_s = t_s + encode_frame(id).len() as f64 * byte_time;
        self.counters.frames_sent += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use embedded_io::{Read, ReadReady};
    use wmr_core::devices::{RfidReader, TagLocator};
    use wmr_core::odometry::WrappingCounter;

    use crate::tags::FloorTags;

    fn floor() -> Floor {
        Floor::Grid(FloorTags::covering(0.1, [0.0, 0.0], [-1.0, -1.0], [1.0, 1.0]).unwrap())
    }

    #[test]
    fn encoder_quantizes_with_floor() {
        let shaft = WheelShaft::new();
        let mut e = VirtualEncoder::new(shaft.clone(), 2048, 16);
        let count = TAU / 2048.0;
        shaft.set_angle_rad(2.999 * count);
        assert_eq!(e.raw_count(), Ok(2));
        shaft.set_angle_rad(3.001 * count);
        assert_eq!(e.raw_count(), Ok(3));
        // Just below zero is count −1: 0xFFFF on a 16-bit counter.
        shaft.set_angle_rad(-0.001 * count);
        assert_eq!(e.raw_count(), Ok(0xFFFF));
    }

    #[test]
    fn encoder_wraps_at_its_width_and_the_core_unwraps_it() {
        let shaft = WheelShaft::new();
        let mut e = VirtualEncoder::new(shaft.clone(), 4096, 16);
        let count = TAU / 4096.0;
        shaft.set_angle_rad(65_530.5 * count);
        assert_eq!(e.raw_count(), Ok(65_530));
        shaft.set_angle_rad(65_540.5 * count);
        assert_eq!(e.raw_count(), Ok(4));
        // The core's counter sees +10 across the wrap, then −20 back.
        let mut w = WrappingCounter::new(16).unwrap();
        shaft.set_angle_rad(65_530.5 * count);
        w.delta(e.raw_count().unwrap());
        shaft.set_angle_rad(65_540.5 * count);
        assert_eq!(w.delta(e.raw_count().unwrap()), 10);
        shaft.set_angle_rad(65_520.5 * count);
        assert_eq!(w.delta(e.raw_count().unwrap()), -20);
        // 12-bit counter.
        let mut e12 = VirtualEncoder::new(shaft.clone(), 4096, 12);
        shaft.set_angle_rad(4097.5 * count);
        assert_eq!(e12.raw_count(), Ok(1));
    }

    #[test]
    fn pwm_and_pin_make_a_signed_duty() {
        let s = MotorSignals::new(1000);
        let mut pwm = VirtualPwm::new(s.clone());
        let mut pin = VirtualDirectionPin::new(s.clone());
        assert_eq!(pwm.max_duty_cycle(), 1000);
        pin.set_high().unwrap();
        pwm.set_duty_cycle(250).unwrap();
        assert_eq!(s.signed_duty(), 0.25);
        assert_eq!(pwm.set_duty_cycle(1001), Err(pwm::ErrorKind::Other));
        assert_eq!(s.line().out_of_range_writes, 1);
        pin.set_low().unwrap(); // under drive: counted
        assert_eq!(s.signed_duty(), -0.25);
        assert_eq!(s.line().reversals_under_drive, 1);
    }

    /// A range-mode reader repeating faster than its updates fills the
    /// line between them: 160,000 Bd is 160 bytes, 11.4 frames, per 10 ms.
    #[test]
    fn fast_repeats_fill_the_line_between_updates() {
        let config = ReaderConfig {
            mode: ReaderMode::Range {
                read_radius_m: 0.08,
                repeat_interval_s: 1e-4,
            },
            baud: 160_000,
            update_period_s: Some(0.01),
            ..ReaderConfig::default()
        };
        let (mut reader, _uart) = VirtualRfidReader::new(config, floor());
        let pose = PlantPose::new(0.31, -0.2, 0.0);
        reader.update(0.0, &pose);
        // Frames start at 0, 0.875 ms, ... 9.625 ms: 12 begin before 10 ms.
        assert_eq!(reader.counters().frames_sent, 12);
        reader.update(0.01, &pose);
        // The 12th frame still holds the line at 10 ms: the update's own
        // report is skipped, the repeats go on from where it ends.
        assert_eq!(reader.counters().skipped_line_busy, 1);
        assert_eq!(reader.counters().frames_sent, 23);
        // Without the period: one report per update.
        let (mut reader, _uart) = VirtualRfidReader::new(
            ReaderConfig {
                update_period_s: None,
                ..config
            },
            floor(),
        );
        reader.update(0.0, &pose);
        assert_eq!(reader.counters().frames_sent, 1);
    }

    #[test]
    fn uart_delivers_bytes_at_the_baud_rate() {
        let config = ReaderConfig {
            baud: 9600,
            ..ReaderConfig::default()
        };
        let (mut reader, mut uart) = VirtualRfidReader::new(config, floor());
        let byte_time = 10.0 / 9600.0;
        assert!((reader.byte_time_s() - byte_time).abs() < 1e-15);
        let pose = PlantPose::new(0.31, -0.2, 0.0);
        reader.update(0.0, &pose);
        assert_eq!(reader.bytes_pending(), 14);
        let mut buf = [0_u8; 32];
        // Nothing has fully arrived at t = 0, nor just before the first byte ends.
        assert_eq!(uart.read_ready(), Ok(false));
        reader.set_time(0.99 * byte_time);
        assert_eq!(uart.read_ready(), Ok(false));
        // 5.5 byte times: 5 bytes.
        reader.set_time(5.5 * byte_time);
        assert_eq!(uart.read(&mut buf), Ok(5));
        assert_eq!(buf[0], 0x02);
        // The frame is 14.6 ms at 9600 Bd: a 10 ms tick later the line is
        // still busy, so the next report is skipped.
        reader.update(0.01, &pose);
        assert_eq!(reader.counters().skipped_line_busy, 1);
        assert_eq!(uart.read(&mut buf), Ok(4)); // bytes 6..=9 have arrived by 10 ms
        reader.update(0.02, &pose);
        assert_eq!(reader.counters().frames_sent, 2);

        // The core's reader gets the tag once the whole frame is in: 14
        // bytes, 14.58 ms.
        let (mut reader, uart) = VirtualRfidReader::new(config, floor());
        let mut rfid = RfidReader::new(uart);
        reader.update(0.0, &pose);
        reader.set_time(0.0145);
        assert_eq!(rfid.poll(), None);
        reader.set_time(0.0146);
        let tag = rfid.poll().unwrap();
        let p = floor().locate(tag).unwrap();
        assert!(
            (p.x - 0.3).abs() < 1e-6 && (p.y + 0.2).abs() < 1e-6,
            "{p:?}"
        );
    }

    #[test]
    fn range_mode_reports_on_entry_and_repeats() {
        let config = ReaderConfig {
            mode: ReaderMode::Range {
                read_radius_m: 0.02,
                repeat_interval_s: 0.05,
            },
            antenna_offset_m: 0.1,
            ..ReaderConfig::default()
        };
        let (mut reader, _uart) = VirtualRfidReader::new(config, floor());
        // Antenna at (0.1 + 0.05, 0): 5 cm from the nearest tag, out of range.
        reader.update(0.0, &PlantPose::new(0.05, 0.0, 0.0));
        assert_eq!(reader.counters().frames_sent, 0);
        // Antenna at (0.21, 0): 1 cm from tag (0.2, 0).
        reader.update(0.01, &PlantPose::new(0.11, 0.0, 0.0));
        assert_eq!(reader.counters().frames_sent, 1);
        for k in 2..=5 {
            reader.update(f64::from(k) * 0.01, &PlantPose::new(0.11, 0.0, 0.0));
        }
        assert_eq!(reader.counters().frames_sent, 1);
        reader.update(0.06, &PlantPose::new(0.11, 0.0, 0.0));
        assert_eq!(reader.counters().frames_sent, 2);
    }

    #[test]
    fn faults_are_seeded_and_counted() {
        let run = || {
            let config = ReaderConfig {
                faults: LinkFaults {
                    corrupt_byte_probability: 0.05,
                    drop_frame_probability: 0.1,
                    seed: 7,
                },
                ..ReaderConfig::default()
            };
            let (mut reader, uart) = VirtualRfidReader::new(config, floor());
            let mut rfid = RfidReader::new(uart);
            let mut good = 0;
            for k in 0..1000 {
                reader.update(f64::from(k) * 0.01, &PlantPose::new(0.3, 0.4, 0.0));
                good += usize::from(rfid.poll().is_some());
            }
            (reader.counters(), rfid.counters(), good)
        };
        let (a, parser, good) = run();
        assert_eq!(run().0, a);
        assert!(a.frames_dropped > 50 && a.bytes_corrupted > 300, "{a:?}");
        assert!(parser.bad_checksum + parser.malformed > 100, "{parser:?}");
        assert!(good > 300 && good < 900, "{good}");
    }
}
