//! The firmware's robot: the core's [`Robot`] tick, able to follow a
//! route. The core's `Robot` owns its [`Pilot`] and ticks it on the
//! configured trajectory only ([`Pilot::step`]); this robot is the same
//! tick with the pilot's step chosen per tick: [`Pilot::step`], or
//! [`Pilot::step_route`] on a [`RouteFollower`] the caller lends. Without
//! a follower it makes the same calls, in the same order, as
//! [`Robot::tick`], so its outputs are bit for bit the core's (the
//! session's tests tick both side by side).
//!
//! [`Robot`]: wmr_core::pilot::robot::Robot
//! [`Robot::tick`]: wmr_core::pilot::robot::Robot::tick

use embedded_io::{Read, ReadReady};
use wmr_core::devices::{
    MotorCommand, MotorFault, QuadratureCounter, RfidCounters, RfidReader, TagLocator,
};
use wmr_core::pilot::robot::{Motor, RobotCounters, RobotTick};
use wmr_core::pilot::route::RouteFollower;
use wmr_core::pilot::tracker::TagFix;
use wmr_core::pilot::{Measurement, Pilot};

/// A robot: two encoders, two motors, an RFID reader, a tag locator, a
/// pilot; ticked on its trajectory or on a route.
pub struct RouteRobot<EL, ER, ML, MR, U, T>
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

impl<EL, ER, ML, MR, U, T> RouteRobot<EL, ER, ML, MR, U, T>
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

    /// One control tick: sense, decide (on `route` if given, else on the
    /// pilot's trajectory), act. Device errors are counted as the core's
    /// `Robot::tick` counts them.
    pub fn tick(&mut self, route: Option<&mut RouteFollower>) -> RobotTick {
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

/// Drives a motor; on a fault, asks it to stop (best effort: a stop is
/// the one command safe whatever state the driver is in) and reports the
/// fault.
fn drive_or_stop<M: Motor>(motor: &mut M, command: MotorCommand) -> Result<(), MotorFault> {
    motor.drive(command).inspect_err(|_| {
        let _ = motor.drive(MotorCommand::STOP);
    })
}
