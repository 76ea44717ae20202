//! One control tick, devices to duties: the `Pilot`.
//!
//! ```text
//! Measurement ──► wrapping counter deltas ──► exact-arc odometry ─┐
//!  (raw encoder counters,                                         ├─► OutputFeedbackTracker ──► BodyVelocity
//!   this tick's tag fix)  ───────────────────────────────────────┘     (observer (5) + law (27)–(28))     │
//!                                                                                                        ▼
//!                      MotorCommand ◄── signed duty ◄── speed loops ◄── limits ◄── wheel speeds ◄── Drive
//! ```
//!
//! The `Pilot` is pure logic: it never touches a device. [`crate::pilot::robot::Robot`]
//! reads the devices into a [`Measurement`], calls [`Pilot::step`] and writes
//! the [`PilotOutput`]'s motor commands; the simulator and the firmware use
//! the same path.
//!
//! # Encoder faults
//! A tick with a failed (or implausible) encoder read is a *fault tick*:
//! the odometry of that tick is unknown, so neither counter's origin moves
//! (the next good read covers all the missed ticks, and its odometry is
//! spread over them), the tracker sees zero motion, and the speed loops run
//! feed-forward plus their held integral. After more than
//! `max_encoder_fault_ticks` consecutive fault ticks the motors are stopped
//! ([`PilotOutput::encoder_halt`]) until reads return. A read is implausible
//! when a wheel moved more than twice the drive's maximum wheel speed
//! allows; its counter origin is then dropped and re-taken.

pub mod robot;
pub mod route;
pub mod spec;
pub mod tracker;
pub mod tuning;

use crate::devices::MotorCommand;
use crate::drive::{Drive, DriveConfig, DriveOutput};
use crate::geometry::WheelSpeeds;
use crate::odometry::{CounterError, OdometryStep, WrappingCounter};
use crate::pilot::route::RouteFollower;
use crate::pilot::tracker::{OutputFeedbackTracker, TagFix, TrackerConfig, TrackerOutput};
use crate::pilot::tuning::{Tuning, TuningSpec};

/// Why a [`PilotConfig`] was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum PilotConfigError {
    /// Encoder counter width outside 2..=32 bits.
    EncoderBits,
    /// The tracker's and the drive's control periods differ.
    PeriodMismatch,
}

impl core::fmt::Display for PilotConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::EncoderBits => "encoder_bits must be 2..=32",
            Self::PeriodMismatch => "the tracker's and the drive's period_s must be equal",
        })
    }
}

impl core::error::Error for PilotConfigError {}

impl From<CounterError> for PilotConfigError {
    fn from(_: CounterError) -> Self {
        Self::EncoderBits
    }
}

/// Validated configuration of a [`Pilot`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PilotConfig {
    tracker: TrackerConfig,
    drive: DriveConfig,
    encoder_bits: u32,
    max_encoder_fault_ticks: u32,
}

impl PilotConfig {
    /// Default number of consecutive encoder fault ticks tolerated.
    pub const DEFAULT_MAX_ENCODER_FAULT_TICKS: u32 = 5;

    /// Combines a tracker and a drive configuration with the width of the
    /// hardware encoder counters (16 for most STM32 timers, 32 for TIM2/TIM5).
    ///
    /// # Errors
    /// A bad counter width, or periods that differ.
    pub fn new(
        tracker: TrackerConfig,
        drive: DriveConfig,
        encoder_bits: u32,
    ) -> Result<Self, PilotConfigError> {
        WrappingCounter::new(encoder_bits)?;
        let (a, b) = (tracker.clock().period_s(), drive.period_s());
        if (a - b).abs() > 1e-9 * a.abs().max(b.abs()) {
            return Err(PilotConfigError::PeriodMismatch);
        }
        Ok(Self {
            tracker,
            drive,
            encoder_bits,
            max_encoder_fault_ticks: Self::DEFAULT_MAX_ENCODER_FAULT_TICKS,
        })
    }

    /// Sets how many consecutive encoder fault ticks are bridged before the
    /// motors are stopped.
    #[must_use]
    pub fn with_max_encoder_fault_ticks(mut self, ticks: u32) -> Self {
        self.max_encoder_fault_ticks = ticks;
        self
    }

    /// What may change at run time: law (27)–(28)'s gains and the
    /// failsafe times ([`crate::pilot::tuning`]).
    #[must_use]
    pub fn tuning(&self) -> TuningSpec {
        TuningSpec {
            max_encoder_fault_ticks: self.max_encoder_fault_ticks,
            ..self.tracker.tuning()
        }
    }

    /// Takes `tuning` in place ([`TrackerConfig::retune`], and the encoder
    /// fault ticks).
    pub fn retune(&mut self, tuning: &Tuning) {
        self.tracker.retune(tuning);
        self.max_encoder_fault_ticks = tuning.max_encoder_fault_ticks();
    }

    /// The tracker's configuration.
    #[must_use]
    pub fn tracker(&self) -> &TrackerConfig {
        &self.tracker
    }

    /// The drive's configuration.
    #[must_use]
    pub fn drive(&self) -> &DriveConfig {
        &self.drive
    }
}

/// What the devices showed this tick.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Measurement {
    /// Raw left encoder counter, `None` if the read failed.
    pub left_count: Option<u32>,
    /// Raw right encoder counter, `None` if the read failed.
    pub right_count: Option<u32>,
    /// A tag fix read this tick (already mapped to a floor position).
    pub fix: Option<TagFix>,
}

/// Counters of the pilot's own fault handling.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct PilotCounters {
    /// Ticks with a missing encoder read.
    pub encoder_fault_ticks: u32,
    /// Encoder reads rejected as implausibly large jumps.
    pub implausible_encoder_reads: u32,
    /// Ticks on which the motors were stopped for encoder faults.
    pub encoder_halt_ticks: u32,
}

/// The result of one tick.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PilotOutput {
    /// Command for the left motor.
    pub left: MotorCommand,
    /// Command for the right motor.
    pub right: MotorCommand,
    /// Odometry of the last period (zero on a fault tick).
    pub odometry: OdometryStep,
    /// Tracker step (mode, estimate, reference, law).
    pub tracker: TrackerOutput,
    /// Drive step (wheel targets, duties, limits).
    pub drive: DriveOutput,
    /// Motors stopped for persistent encoder faults.
    pub encoder_halt: bool,
}

/// Encoders → odometry → tracker → drive, one tick at a time.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Pilot {
    config: PilotConfig,
    left_counter: WrappingCounter,
    right_counter: WrappingCounter,
    /// Ticks the next counter delta will span (since the counters' origin).
    ticks_since_origin: u32,
    /// Consecutive fault ticks (0 after a good read).
    fault_run: u32,
    tracker: OutputFeedbackTracker,
    drive: Drive,
    counters: PilotCounters,
}

impl Pilot {
    /// A pilot at tick 0, motors at rest.
    ///
    /// # Errors
    /// [`PilotConfigError::EncoderBits`] can not occur for a validated
    /// configuration; construction is fallible like every other stage's.
    pub fn new(config: PilotConfig) -> Result<Self, PilotConfigError> {
        let counter = WrappingCounter::new(config.encoder_bits)?;
        Ok(Self {
            config,
            left_counter: counter,
            right_counter: counter,
            ticks_since_origin: 0,
            fault_run: 0,
            tracker: OutputFeedbackTracker::new(config.tracker),
            drive: Drive::new(config.drive),
            counters: PilotCounters::default(),
        })
    }

    /// The configuration.
    #[must_use]
    pub fn config(&self) -> &PilotConfig {
        &self.config
    }

    /// The tracker (counters, configuration).
    #[must_use]
    pub fn tracker(&self) -> &OutputFeedbackTracker {
        &self.tracker
    }

    /// The drive (its configuration and, with the feature
    /// `wheel-speed-observer`, the speed observer's estimates).
    #[must_use]
    pub fn drive(&self) -> &Drive {
        &self.drive
    }

    /// Takes `tuning` from the next tick on ([`crate::pilot::tuning`]):
    /// the tracker's ([`OutputFeedbackTracker::retune`]) and the encoder
    /// fault ticks (a run of faults already counted is judged by the new
    /// figure at the next tick).
    pub fn retune(&mut self, tuning: &Tuning) {
        self.config.retune(tuning);
        self.tracker.retune(tuning);
    }

    /// The pilot's own counters.
    #[must_use]
    pub fn counters(&self) -> PilotCounters {
        self.counters
    }

    /// One control tick.
    pub fn step(&mut self, measurement: &Measurement) -> PilotOutput {
        self.step_on(measurement, None)
    }

    /// One control tick on the route `route` instead of the configured
    /// trajectory ([`OutputFeedbackTracker::step_route`]; load it with
    /// [`RouteFollower::load`]). The follower is the caller's, lent each
    /// tick, so a `Pilot` is no larger for routes (module [`route`]).
    pub fn step_route(
        &mut self,
        measurement: &Measurement,
        route: &mut RouteFollower,
    ) -> PilotOutput {
        self.step_on(measurement, Some(route))
    }

    fn step_on(
        &mut self,
        measurement: &Measurement,
        route: Option<&mut RouteFollower>,
    ) -> PilotOutput {
        let odometry = self.odometry(measurement);
        let odometry_step = odometry.unwrap_or_default();
        let mut route = route;
        let tracker = self
            .tracker
            .step_on(&odometry_step, measurement.fix, route.as_deref_mut());
        let holding = route.is_some_and(|route| route.is_holding());

        let encoder_halt = self.fault_run > self.config.max_encoder_fault_ticks;
        let drive = if encoder_halt {
            self.counters.encoder_halt_ticks = self.counters.encoder_halt_ticks.saturating_add(1);
            self.drive.halt();
            DriveOutput::default()
        } else {
            let drive = self.drive.step(tracker.command, odometry.map(|o| o.wheels));
            if holding && drive.wheel_targets == WheelSpeeds::ZERO {
                // Settled at a route's stop: the motors at exactly zero
                // (no speed loop holding a duty from its integral).
                self.drive.halt();
                DriveOutput {
                    left_duty: 0.0,
                    right_duty: 0.0,
                    ..drive
                }
            } else {
                drive
            }
        };
        PilotOutput {
            left: MotorCommand::from_signed(drive.left_duty),
            right: MotorCommand::from_signed(drive.right_duty),
            odometry: odometry.unwrap_or_default(),
            tracker,
            drive,
            encoder_halt,
        }
    }

    /// Odometry of this tick, `None` on a fault tick.
    fn odometry(&mut self, m: &Measurement) -> Option<OdometryStep> {
        self.ticks_since_origin = self.ticks_since_origin.saturating_add(1);
        let (Some(left_raw), Some(right_raw)) = (m.left_count, m.right_count) else {
            self.fault_tick();
            return None;
        };
        let (dl, dr) = (
            self.left_counter.delta(left_raw),
            self.right_counter.delta(right_raw),
        );
        let dt = self.ticks_since_origin as f32 * self.config.drive.period_s();
        self.ticks_since_origin = 0;
        let geometry = self.config.drive.geometry();
        // Twice the drive's top wheel speed over the elapsed time, plus one
        // count of quantization.
        let plausible =
            2.0 * self.config.drive.max_wheel_speed_rad_s() * dt / geometry.rad_per_count() + 1.0;
        if (dl.unsigned_abs() as f32) > plausible || (dr.unsigned_abs() as f32) > plausible {
            // This read is the new origin (delta() already took it); the
            // motion since the last good read is lost, and counted.
            self.counters.implausible_encoder_reads =
                self.counters.implausible_encoder_reads.saturating_add(1);
            self.fault_tick();
            return None;
        }
        self.fault_run = 0;
        Some(OdometryStep::from_counts(geometry, dl, dr, dt))
    }

    fn fault_tick(&mut self) {
        self.fault_run = self.fault_run.saturating_add(1);
        self.counters.encoder_fault_ticks = self.counters.encoder_fault_ticks.saturating_add(1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::LawChoice;
    use crate::control::saturated::TrackingGains;
    use crate::drive::SpeedLoopGains;
    use crate::estimation::EstimatorChoice;
    use crate::estimation::heading_observer::HeadingObserverConfig;
    use crate::geometry::{DiffDriveGeometry, Vec2};
    use crate::reference::StraightLine;

    fn pilot() -> Pilot {
        let h = 0.01;
        let tracker = TrackerConfig::new(
            EstimatorChoice::HeadingObserver(HeadingObserverConfig::new(1.0, h).unwrap()),
            LawChoice::Saturated(TrackingGains::new(0.05, 0.05, 1.0).unwrap()),
            StraightLine::new(Vec2::ZERO, 0.0, 0.2).unwrap().into(),
            50,
        )
        .unwrap();
        let drive = DriveConfig::new(
            DiffDriveGeometry::new(0.03, 0.2, 2048).unwrap(),
            h,
            20.0,
            100.0,
            SpeedLoopGains {
                feedforward_duty_per_rad_s: 0.05,
                kp_duty_per_rad_s: 0.02,
                ki_duty_per_rad: 0.1,
            },
        )
        .unwrap();
        Pilot::new(PilotConfig::new(tracker, drive, 16).unwrap()).unwrap()
    }

    fn at(left: u32, right: u32) -> Measurement {
        Measurement {
            left_count: Some(left),
            right_count: Some(right),
            fix: Some(TagFix {
                position: Vec2::ZERO,
                age_ticks: 0,
            }),
        }
    }

    #[test]
    fn missed_reads_are_bridged_then_halt() {
        let mut p = pilot();
        p.step(&at(100, 100));
        let out = p.step(&at(110, 110));
        assert!(!out.encoder_halt);
        // Five missed ticks are bridged on feed-forward...
        let missing = Measurement {
            left_count: None,
            ..at(0, 0)
        };
        for _ in 0..PilotConfig::DEFAULT_MAX_ENCODER_FAULT_TICKS {
            assert!(!p.step(&missing).encoder_halt);
        }
        // ...the sixth stops the motors.
        let out = p.step(&missing);
        assert!(out.encoder_halt);
        assert!(out.left.is_stop() && out.right.is_stop());
        // A good read covers all seven ticks since the last one.
        let out = p.step(&at(180, 180));
        assert!(!out.encoder_halt);
        let expected = 70.0 * p.config().drive().geometry().rad_per_count() / (7.0 * 0.01);
        assert!((out.odometry.wheels.left_rad_s - expected).abs() < 1e-3);
        assert_eq!(p.counters().encoder_fault_ticks, 6);
    }

    #[test]
    fn implausible_jump_is_rejected() {
        let mut p = pilot();
        p.step(&at(0, 0));
        let out = p.step(&at(30_000, 0));
        assert_eq!(out.odometry, OdometryStep::default());
        assert_eq!(p.counters().implausible_encoder_reads, 1);
        // The jump became the new origin: the next tick is measured from it.
        let out = p.step(&at(30_010, 10));
        assert!(out.odometry.ds_m > 0.0);
    }

    #[test]
    fn mismatched_periods_are_refused() {
        let p = pilot();
        let tracker = TrackerConfig::new(
            EstimatorChoice::HeadingObserver(HeadingObserverConfig::new(1.0, 0.02).unwrap()),
            LawChoice::Saturated(TrackingGains::new(0.05, 0.05, 1.0).unwrap()),
            StraightLine::new(Vec2::ZERO, 0.0, 0.2).unwrap().into(),
            50,
        )
        .unwrap();
        assert_eq!(
            PilotConfig::new(tracker, *p.config().drive(), 16),
            Err(PilotConfigError::PeriodMismatch)
        );
        assert_eq!(
            PilotConfig::new(*p.config().tracker(), *p.config().drive(), 40),
            Err(PilotConfigError::EncoderBits)
        );
    }
}
