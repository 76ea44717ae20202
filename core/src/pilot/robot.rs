//! The robot: devices around a [`Pilot`].
//!
//! [`Robot::tick`] is the whole control tick of the firmware and of the
//! simulator's full-stack runs: read both encoder counters, drain the RFID
//! reader's UART (non-blocking, bounded work), look the tag up in the
//! [`TagLocator`] (a tag table or a computed grid), run the [`Pilot`] (on
//! its trajectory, or on a route the caller lends: [`Robot::tick_on`]),
//! write both motors. Device errors never
//! stop the tick: each one is counted in [`RobotCounters`] and becomes a
//! documented input to the pilot (a failed encoder read is a missing
//! count; an unknown tag is no fix; a motor write error is retried next
//! tick, and after it the motor is asked to stop).

use embedded_hal::digital::OutputPin;
use embedded_hal::pwm::SetDutyCycle;
use embedded_io::{Read, ReadReady};

use crate::devices::{
    MotorCommand, MotorDriver, MotorFault, QuadratureCounter, RfidCounters, RfidReader, TagLocator,
};
use crate::pilot::route::RouteFollower;
use crate::pilot::tracker::TagFix;
use crate::pilot::{Measurement, Pilot, PilotOutput};

/// A motor that takes [`MotorCommand`]s (implemented by [`MotorDriver`];
/// the seam where a board with a different driver plugs in).
pub trait Motor {
    /// Drives the motor.
    ///
    /// # Errors
    /// The fault of the underlying peripheral.
    fn drive(&mut self, command: MotorCommand) -> Result<(), MotorFault>;
}

impl<P: SetDutyCycle, D: OutputPin> Motor for MotorDriver<P, D> {
    fn drive(&mut self, command: MotorCommand) -> Result<(), MotorFault> {
        self.apply(command)
    }
}

/// Counters of device-level faults (the RFID parser keeps its own).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct RobotCounters {
    /// Failed reads of the left encoder counter.
    pub left_encoder_errors: u32,
    /// Failed reads of the right encoder counter.
    pub right_encoder_errors: u32,
    /// Valid frames whose tag is not in the map.
    pub unknown_tags: u32,
    /// Failed motor writes (either motor).
    pub motor_faults: u32,
}

/// What one tick did, for logging and telemetry.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RobotTick {
    /// The pilot's step.
    pub pilot: PilotOutput,
    /// The tag fix read this tick (a valid frame whose tag the locator
    /// knows), before the tracker's checks; whether the tracker used it is
    /// `pilot.tracker.fix_used`.
    pub fix: Option<TagFix>,
    /// The last motor fault of this tick, if any.
    pub motor_fault: Option<MotorFault>,
}

/// A robot: two encoders, two motors, an RFID reader, a tag locator, a pilot.
pub struct Robot<EL, ER, ML, MR, U, T>
where
    U: Read + ReadReady,
{
    pilot: Pilot,
    left_encoder: EL,
    right_encoder: ER,
    left_motor: ML,
    right_motor: MR,
    rfid: RfidReader<U>,
    tags: T,
    counters: RobotCounters,
}

impl<EL, ER, ML, MR, U, T> Robot<EL, ER, ML, MR, U, T>
where
    EL: QuadratureCounter,
    ER: QuadratureCounter,
    ML: Motor,
    MR: Motor,
    U: Read + ReadReady,
    T: TagLocator,
{
    /// Assembles a robot. Motors are not touched until the first tick.
    pub fn new(
        pilot: Pilot,
        (left_encoder, right_encoder): (EL, ER),
        (left_motor, right_motor): (ML, MR),
        rfid: RfidReader<U>,
        tags: T,
    ) -> Self {
        Self {
            pilot,
            left_encoder,
            right_encoder,
            left_motor,
            right_motor,
            rfid,
            tags,
            counters: RobotCounters::default(),
        }
    }

    /// The pilot.
    #[must_use]
    pub fn pilot(&self) -> &Pilot {
        &self.pilot
    }

    /// Takes `tuning` from the next tick on ([`Pilot::retune`]).
    pub fn retune(&mut self, tuning: &crate::pilot::tuning::Tuning) {
        self.pilot.retune(tuning);
    }

    /// Device fault counters.
    #[must_use]
    pub fn counters(&self) -> RobotCounters {
        self.counters
    }

    /// The RFID parser's counters.
    #[must_use]
    pub fn rfid_counters(&self) -> RfidCounters {
        self.rfid.counters()
    }

    /// The tag locator.
    #[must_use]
    pub fn tags(&self) -> &T {
        &self.tags
    }

    /// One control tick: sense, decide, act.
    pub fn tick(&mut self) -> RobotTick {
        self.tick_on(None)
    }

    /// One control tick on `route` if given ([`Pilot::step_route`], the
    /// follower the caller's, lent each tick), else on the pilot's
    /// trajectory ([`Pilot::step`], as [`Self::tick`]): sense, decide, act.
    pub fn tick_on(&mut self, route: Option<&mut RouteFollower>) -> RobotTick {
        let left_count = self.left_encoder.raw_count().ok();
        if left_count.is_none() {
            self.counters.left_encoder_errors = self.counters.left_encoder_errors.saturating_add(1);
        }
        let right_count = self.right_encoder.raw_count().ok();
        if right_count.is_none() {
            self.counters.right_encoder_errors =
                self.counters.right_encoder_errors.saturating_add(1);
        }
        // The reader's age bound goes to the tracker, which rejects (and
        // counts) a fix older than its `max_fix_age_ticks`.
        let fix = self
            .rfid
            .poll_read()
            .and_then(|read| match self.tags.locate(read.id) {
                Some(position) => Some(TagFix {
                    position,
                    age_ticks: read.age_ticks,
                }),
                None => {
                    self.counters.unknown_tags = self.counters.unknown_tags.saturating_add(1);
                    None
                }
            });
        let measurement = Measurement {
            left_count,
            right_count,
            fix,
        };
        let pilot = match route {
            None => self.pilot.step(&measurement),
            Some(route) => self.pilot.step_route(&measurement, route),
        };
        let mut motor_fault = None;
        for result in [
            drive_or_stop(&mut self.left_motor, pilot.left),
            drive_or_stop(&mut self.right_motor, pilot.right),
        ] {
            if let Err(fault) = result {
                self.counters.motor_faults = self.counters.motor_faults.saturating_add(1);
                motor_fault = Some(fault);
            }
        }
        RobotTick {
            pilot,
            fix,
            motor_fault,
        }
    }
}

/// Drives a motor; on a fault, asks it to stop (best effort) and reports the fault.
fn drive_or_stop<M: Motor>(motor: &mut M, command: MotorCommand) -> Result<(), MotorFault> {
    motor.drive(command).inspect_err(|_| {
        // The write failed half-way or not at all: a stop is the one command
        // that is safe whatever state the driver is in. Its own failure adds
        // nothing the first fault did not already report.
        let _ = motor.drive(MotorCommand::STOP);
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::LawChoice;
    use crate::control::saturated::TrackingGains;
    use crate::devices::{TagId, encode_frame};
    use crate::drive::{DriveConfig, SpeedLoopGains};
    use crate::estimation::EstimatorChoice;
    use crate::estimation::heading_observer::HeadingObserverConfig;
    use crate::geometry::{DiffDriveGeometry, Vec2};
    use crate::pilot::PilotConfig;
    use crate::pilot::tracker::TrackerConfig;
    use crate::reference::StraightLine;

    struct StillEncoder;
    impl QuadratureCounter for StillEncoder {
        type Error = ();
        fn raw_count(&mut self) -> Result<u32, ()> {
            Ok(0)
        }
    }

    struct IdleMotor;
    impl Motor for IdleMotor {
        fn drive(&mut self, _: MotorCommand) -> Result<(), MotorFault> {
            Ok(())
        }
    }

    /// A UART that holds one frame until it is read.
    struct OneFrame {
        frame: [u8; crate::devices::rfid::FRAME_LEN],
        pos: usize,
    }
    impl embedded_io::ErrorType for OneFrame {
        type Error = embedded_io::ErrorKind;
    }
    impl ReadReady for OneFrame {
        fn read_ready(&mut self) -> Result<bool, Self::Error> {
            Ok(self.pos < self.frame.len())
        }
    }
    impl Read for OneFrame {
        fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
            let rest = self.frame.get(self.pos..).unwrap_or_default();
            let n = rest.len().min(buf.len());
            buf[..n].copy_from_slice(&rest[..n]);
            self.pos += n;
            Ok(n)
        }
    }

    /// A locator that puts every tag at `at`.
    struct Everywhere {
        at: Vec2,
    }
    impl TagLocator for Everywhere {
        fn locate(&self, _: TagId) -> Option<Vec2> {
            Some(self.at)
        }
    }

    fn robot_reading_a_tag_at(
        at: Vec2,
    ) -> Robot<StillEncoder, StillEncoder, IdleMotor, IdleMotor, OneFrame, Everywhere> {
        let h = 0.01;
        let tracker = TrackerConfig::new(
            EstimatorChoice::HeadingObserver(HeadingObserverConfig::new(1.0, h).unwrap()),
            LawChoice::Saturated(TrackingGains::new(0.05, 0.05, 1.0).unwrap()),
            StraightLine::new(Vec2::ZERO, 0.0, 0.2).unwrap().into(),
            50,
        )
        .unwrap();
        let gains = SpeedLoopGains {
            feedforward_duty_per_rad_s: 0.05,
            kp_duty_per_rad_s: 0.05,
            ki_duty_per_rad: 0.5,
        };
        let geometry = DiffDriveGeometry::new(0.03, 0.2, 2048).unwrap();
        let drive = DriveConfig::new(geometry, h, 20.0, 40.0, gains).unwrap();
        let pilot = Pilot::new(PilotConfig::new(tracker, drive, 16).unwrap()).unwrap();
        let uart = OneFrame {
            frame: encode_frame(TagId(7)),
            pos: 0,
        };
        Robot::new(
            pilot,
            (StillEncoder, StillEncoder),
            (IdleMotor, IdleMotor),
            RfidReader::new(uart),
            Everywhere { at },
        )
    }

    /// A tag read whose position the tracker refuses is reported as read
    /// but not used: the tick's answer agrees with the tracker's counters.
    #[test]
    fn a_refused_fix_is_read_but_not_used() {
        let mut robot = robot_reading_a_tag_at(Vec2::new(f32::INFINITY, 0.0));
        let tick = robot.tick();
        assert!(tick.fix.is_some());
        assert!(!tick.pilot.tracker.fix_used, "{tick:?}");
        let c = robot.pilot().tracker().counters();
        assert_eq!((c.invalid_fixes, c.fixes_used), (1, 0));

        let mut robot = robot_reading_a_tag_at(Vec2::new(0.1, 0.0));
        let tick = robot.tick();
        assert!(tick.pilot.tracker.fix_used, "{tick:?}");
        assert_eq!(robot.pilot().tracker().counters().fixes_used, 1);
    }
}
