//! DC motor behind an H-bridge: one PWM channel for the magnitude, one GPIO
//! for the direction (the common "PWM + DIR" wiring of driver boards such as
//! the DRV8871/MC33926/Cytron MDD family in sign-magnitude mode).
//!
//! [`MotorCommand`] is the sanitised, hardware-independent command;
//! [`MotorDriver`] puts it on an [`embedded_hal::pwm::SetDutyCycle`] and an
//! [`embedded_hal::digital::OutputPin`].

use embedded_hal::digital::{self, OutputPin, PinState};
use embedded_hal::pwm::{self, SetDutyCycle};

/// Sense of rotation of a motor, as seen by the robot (forward drives the
/// robot forward, whatever the motor's mounting; see [`MotorWiring`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Direction {
    /// Drives the robot forward.
    Forward,
    /// Drives the robot backward.
    Reverse,
}

/// A motor command: a duty-cycle magnitude and a direction.
///
/// `duty` is a fraction of full voltage in `[0, 1]`. The fields are public
/// for convenience; whatever they hold, [`MotorCommand::sanitized`] (which
/// [`MotorDriver::apply`] always calls) brings them back into range.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct MotorCommand {
    /// Duty-cycle magnitude, fraction in `[0, 1]`.
    pub duty: f32,
    /// Sense of rotation.
    pub direction: Direction,
}

impl MotorCommand {
    /// No drive (duty 0, [`Direction::Forward`]).
    pub const STOP: Self = Self {
        duty: 0.0,
        direction: Direction::Forward,
    };

    /// Maps a signed duty in `[-1, 1]` (positive forward) to magnitude and
    /// direction.
    ///
    /// The magnitude is clamped to `[0, 1]`, so finite out-of-range values
    /// saturate at full duty in their direction. NaN and `±∞` give
    /// [`Self::STOP`]: a non-finite duty is a numerical fault upstream, not
    /// an intent, and garbage never reaches a motor. A zero magnitude
    /// (including `-0.0`) is always [`Self::STOP`].
    #[must_use]
    pub fn from_signed(duty: f32) -> Self {
        let direction = if duty < 0.0 {
            Direction::Reverse
        } else {
            Direction::Forward
        };
        Self {
            duty: duty.abs(),
            direction,
        }
        .sanitized()
    }

    /// The command with `duty` clamped to `[0, 1]`; a non-finite duty, and
    /// any duty that ends up zero, give [`Self::STOP`].
    #[must_use]
    pub fn sanitized(self) -> Self {
        if self.is_stop() {
            return Self::STOP;
        }
        Self {
            duty: self.duty.min(1.0),
            direction: self.direction,
        }
    }

    /// The signed duty in `[-1, 1]` (positive forward) of the sanitised
    /// command; inverse of [`Self::from_signed`].
    #[must_use]
    pub fn signed(self) -> f32 {
        let c = self.sanitized();
        match c.direction {
            Direction::Forward => c.duty,
            Direction::Reverse => -c.duty,
        }
    }

    /// Whether the command, once sanitised, drives nothing (zero, negative
    /// or non-finite duty).
    #[must_use]
    pub fn is_stop(self) -> bool {
        !self.duty.is_finite() || self.duty <= 0.0
    }
}

impl Default for MotorCommand {
    fn default() -> Self {
        Self::STOP
    }
}

/// How a motor is wired to its driver.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MotorWiring {
    /// Flip which direction-pin level means forward.
    ///
    /// Not reversed: pin high = [`Direction::Forward`]. A differential-drive
    /// robot's two motors are usually mounted mirror-image, so one of them
    /// needs `reversed: true` for both to drive the robot forward on
    /// [`Direction::Forward`].
    pub reversed: bool,
}

impl MotorWiring {
    /// The direction-pin level that gives `direction`.
    #[must_use]
    pub fn pin_state(self, direction: Direction) -> PinState {
        let high = matches!(direction, Direction::Forward) != self.reversed;
        PinState::from(high)
    }
}

/// A motor driver peripheral failed. The driver holds no partial state that
/// would make a retry unsafe: the next [`MotorDriver::apply`] starts over.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MotorFault {
    /// Setting the PWM duty failed.
    Pwm(pwm::ErrorKind),
    /// Setting the direction pin failed.
    DirectionPin(digital::ErrorKind),
}

// embedded-hal's `ErrorKind`s only implement defmt 0.3's `Format`, so this
// one is written by hand (the kinds are non-exhaustive: newer ones print as
// "Unknown").
#[cfg(feature = "defmt")]
impl defmt::Format for MotorFault {
    fn format(&self, f: defmt::Formatter<'_>) {
        match self {
            Self::Pwm(kind) => {
                let kind = match kind {
                    pwm::ErrorKind::Other => "Other",
                    _ => "Unknown",
                };
                defmt::write!(f, "Pwm({=str})", kind);
            }
            Self::DirectionPin(kind) => {
                let kind = match kind {
                    digital::ErrorKind::Other => "Other",
                    _ => "Unknown",
                };
                defmt::write!(f, "DirectionPin({=str})", kind);
            }
        }
    }
}

impl core::fmt::Display for MotorFault {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Pwm(kind) => write!(f, "motor PWM fault: {kind}"),
            Self::DirectionPin(kind) => write!(f, "motor direction pin fault: {kind}"),
        }
    }
}

impl core::error::Error for MotorFault {}

/// One motor: a PWM channel for the duty magnitude and a direction pin.
///
/// Sequencing: when the direction changes, [`Self::apply`] first sets the
/// duty to 0, then flips the direction pin, then sets the new duty. Reversing
/// an H-bridge under drive can briefly short a leg (shoot-through) on drivers
/// without dead-time insertion and slams the motor's back-EMF into the
/// supply; passing through zero duty avoids both. The pin is written only
/// when the direction changes (and on the first non-zero command, when its
/// level is unknown); a zero-duty command never touches it.
#[derive(Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MotorDriver<P: SetDutyCycle, D: OutputPin> {
    pwm: P,
    direction_pin: D,
    wiring: MotorWiring,
    /// Direction the pin is known to be set for; `None` until set, or after
    /// a failed write (level unknown).
    direction: Option<Direction>,
}

impl<P: SetDutyCycle, D: OutputPin> MotorDriver<P, D> {
    /// Takes the PWM channel and direction pin.
    ///
    /// Nothing is written to the hardware here; call [`Self::stop`] at start
    /// if the PWM may come up non-zero.
    #[must_use]
    pub fn new(pwm: P, direction_pin: D, wiring: MotorWiring) -> Self {
        Self {
            pwm,
            direction_pin,
            wiring,
            direction: None,
        }
    }

    /// Drives the motor with `cmd`, sanitised first (see
    /// [`MotorCommand::sanitized`]).
    ///
    /// The duty is scaled to the PWM's `max_duty_cycle()`, rounded to the
    /// nearest step and never above the maximum. See the type's
    /// documentation for the direction-change sequence.
    ///
    /// # Errors
    /// The first peripheral write that failed. If the zero-duty step of a
    /// direction change fails, the pin is not touched; if the pin write
    /// fails, the duty stays at 0 and the pin is rewritten next time.
    pub fn apply(&mut self, cmd: MotorCommand) -> Result<(), MotorFault> {
        let cmd = cmd.sanitized();
        if cmd.is_stop() {
            return self.stop();
        }
        if self.direction != Some(cmd.direction) {
            self.stop()?;
            self.direction = None;
            self.direction_pin
                .set_state(self.wiring.pin_state(cmd.direction))
                .map_err(|e| MotorFault::DirectionPin(digital::Error::kind(&e)))?;
            self.direction = Some(cmd.direction);
        }
        let duty = duty_steps(cmd.duty, self.pwm.max_duty_cycle());
        self.set_duty(duty)
    }

    /// Sets the duty to 0 (coast or brake, as the driver board does at 0);
    /// the direction pin is left as it is.
    ///
    /// # Errors
    /// [`MotorFault::Pwm`] if the PWM write failed.
    pub fn stop(&mut self) -> Result<(), MotorFault> {
        self.set_duty(0)
    }

    /// The direction the pin is known to be set for (`None` before the first
    /// non-zero command or after a failed pin write).
    #[must_use]
    pub fn direction(&self) -> Option<Direction> {
        self.direction
    }

    /// The wiring given at construction.
    #[must_use]
    pub fn wiring(&self) -> MotorWiring {
        self.wiring
    }

    /// Gives the PWM channel and direction pin back.
    #[must_use]
    pub fn release(self) -> (P, D) {
        (self.pwm, self.direction_pin)
    }

    fn set_duty(&mut self, duty: u16) -> Result<(), MotorFault> {
        self.pwm
            .set_duty_cycle(duty)
            .map_err(|e| MotorFault::Pwm(pwm::Error::kind(&e)))
    }
}

/// `duty` (in `[0, 1]`, already sanitised) in PWM steps of `max`, rounded to
/// nearest and capped at `max`.
fn duty_steps(duty: f32, max: u16) -> u16 {
    // f32 represents every u16 exactly; `as` saturates (and maps NaN to 0,
    // though sanitised duties are never NaN).
    let steps = (duty * f32::from(max) + 0.5) as u16;
    steps.min(max)
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::convert::Infallible;
    use proptest::prelude::*;
    use std::cell::RefCell;
    use std::rc::Rc;
    use std::vec::Vec;

    /// Every hardware write, in order.
    #[derive(Debug, Clone, Copy, PartialEq)]
    enum Op {
        Duty(u16),
        Pin(bool),
    }

    type Log = Rc<RefCell<Vec<Op>>>;

    struct FakePwm {
        max: u16,
        log: Log,
        fail: bool,
    }

    impl pwm::ErrorType for FakePwm {
        type Error = pwm::ErrorKind;
    }

    impl SetDutyCycle for FakePwm {
        fn max_duty_cycle(&self) -> u16 {
            self.max
        }
        fn set_duty_cycle(&mut self, duty: u16) -> Result<(), pwm::ErrorKind> {
            if self.fail {
                return Err(pwm::ErrorKind::Other);
            }
            assert!(duty <= self.max, "duty {duty} above max {}", self.max);
            self.log.borrow_mut().push(Op::Duty(duty));
            Ok(())
        }
    }

    struct FakePin {
        log: Log,
        fail: bool,
    }

    impl digital::ErrorType for FakePin {
        type Error = digital::ErrorKind;
    }

    impl OutputPin for FakePin {
        fn set_low(&mut self) -> Result<(), digital::ErrorKind> {
            self.set_state(PinState::Low)
        }
        fn set_high(&mut self) -> Result<(), digital::ErrorKind> {
            self.set_state(PinState::High)
        }
        fn set_state(&mut self, state: PinState) -> Result<(), digital::ErrorKind> {
            if self.fail {
                return Err(digital::ErrorKind::Other);
            }
            self.log.borrow_mut().push(Op::Pin(state.into()));
            Ok(())
        }
    }

    fn driver(max: u16, reversed: bool) -> (MotorDriver<FakePwm, FakePin>, Log) {
        let log = Log::default();
        let pwm = FakePwm {
            max,
            log: log.clone(),
            fail: false,
        };
        let pin = FakePin {
            log: log.clone(),
            fail: false,
        };
        (MotorDriver::new(pwm, pin, MotorWiring { reversed }), log)
    }

    fn take(log: &Log) -> Vec<Op> {
        core::mem::take(&mut *log.borrow_mut())
    }

    #[test]
    fn from_signed_maps_sign_clamps_and_stops_on_nan() {
        let c = MotorCommand::from_signed(-0.25);
        assert_eq!((c.duty, c.direction), (0.25, Direction::Reverse));
        let c = MotorCommand::from_signed(0.5);
        assert_eq!((c.duty, c.direction), (0.5, Direction::Forward));
        let c = MotorCommand::from_signed(-3.0);
        assert_eq!((c.duty, c.direction), (1.0, Direction::Reverse));
        assert_eq!(MotorCommand::from_signed(f32::INFINITY), MotorCommand::STOP);
        assert_eq!(
            MotorCommand::from_signed(f32::NEG_INFINITY),
            MotorCommand::STOP
        );
        assert_eq!(MotorCommand::from_signed(f32::NAN), MotorCommand::STOP);
        assert_eq!(MotorCommand::from_signed(-0.0), MotorCommand::STOP);
        assert_eq!(MotorCommand::from_signed(0.0), MotorCommand::STOP);
        assert!(MotorCommand::STOP.is_stop());
        assert!(
            MotorCommand {
                duty: f32::NAN,
                direction: Direction::Reverse
            }
            .is_stop()
        );
        assert!(!MotorCommand::from_signed(-0.1).is_stop());
        assert_eq!(MotorCommand::default(), MotorCommand::STOP);
    }

    #[test]
    fn hand_built_garbage_is_sanitised() {
        let nan = MotorCommand {
            duty: f32::NAN,
            direction: Direction::Reverse,
        };
        assert_eq!(nan.sanitized(), MotorCommand::STOP);
        let big = MotorCommand {
            duty: 7.0,
            direction: Direction::Reverse,
        };
        assert_eq!(big.sanitized().duty, 1.0);
        assert_eq!(big.signed(), -1.0);
        let neg = MotorCommand {
            duty: -0.5,
            direction: Direction::Reverse,
        };
        assert_eq!(neg.sanitized(), MotorCommand::STOP);
    }

    #[test]
    fn first_command_sets_pin_between_zero_and_duty() {
        let (mut m, log) = driver(1000, false);
        assert_eq!(m.direction(), None);
        m.apply(MotorCommand::from_signed(0.5)).unwrap();
        assert_eq!(take(&log), [Op::Duty(0), Op::Pin(true), Op::Duty(500)]);
        assert_eq!(m.direction(), Some(Direction::Forward));
    }

    #[test]
    fn pin_touched_only_on_direction_change_via_zero_duty() {
        let (mut m, log) = driver(1000, false);
        m.apply(MotorCommand::from_signed(0.5)).unwrap();
        take(&log);
        m.apply(MotorCommand::from_signed(0.7)).unwrap();
        assert_eq!(take(&log), [Op::Duty(700)]);
        m.apply(MotorCommand::from_signed(-0.3)).unwrap();
        assert_eq!(take(&log), [Op::Duty(0), Op::Pin(false), Op::Duty(300)]);
        // Stopping keeps the pin; resuming the same way does not rewrite it.
        m.apply(MotorCommand::STOP).unwrap();
        assert_eq!(take(&log), [Op::Duty(0)]);
        m.apply(MotorCommand::from_signed(-0.3)).unwrap();
        assert_eq!(take(&log), [Op::Duty(300)]);
        m.stop().unwrap();
        assert_eq!(take(&log), [Op::Duty(0)]);
    }

    #[test]
    fn reversed_wiring_flips_the_pin_level() {
        let (mut m, log) = driver(1000, true);
        m.apply(MotorCommand::from_signed(0.5)).unwrap();
        assert_eq!(take(&log), [Op::Duty(0), Op::Pin(false), Op::Duty(500)]);
        m.apply(MotorCommand::from_signed(-0.5)).unwrap();
        assert_eq!(take(&log), [Op::Duty(0), Op::Pin(true), Op::Duty(500)]);
        assert!(m.wiring().reversed);
    }

    #[test]
    fn duty_is_rounded_and_never_above_max() {
        assert_eq!(duty_steps(1.0, u16::MAX), u16::MAX);
        assert_eq!(duty_steps(1.0, 3), 3);
        assert_eq!(duty_steps(0.5, 3), 2); // 1.5 rounds up
        assert_eq!(duty_steps(0.49, 3), 1);
        assert_eq!(duty_steps(0.0, 999), 0);
        assert_eq!(duty_steps(1.0, 0), 0);
        let (mut m, log) = driver(255, false);
        m.apply(MotorCommand::from_signed(7.0)).unwrap();
        assert_eq!(take(&log).last(), Some(&Op::Duty(255)));
    }

    #[test]
    fn nan_command_only_zeroes_the_duty() {
        let (mut m, log) = driver(1000, false);
        m.apply(MotorCommand {
            duty: f32::NAN,
            direction: Direction::Reverse,
        })
        .unwrap();
        assert_eq!(take(&log), [Op::Duty(0)]);
        assert_eq!(m.direction(), None);
    }

    #[test]
    fn faults_are_reported_and_recovered_from() {
        let (mut m, log) = driver(1000, false);
        m.direction_pin.fail = true;
        assert_eq!(
            m.apply(MotorCommand::from_signed(0.5)),
            Err(MotorFault::DirectionPin(digital::ErrorKind::Other))
        );
        // Duty was zeroed before the pin write failed, never driven after.
        assert_eq!(take(&log), [Op::Duty(0)]);
        assert_eq!(m.direction(), None);
        m.direction_pin.fail = false;
        m.apply(MotorCommand::from_signed(0.5)).unwrap();
        assert_eq!(take(&log), [Op::Duty(0), Op::Pin(true), Op::Duty(500)]);

        m.pwm.fail = true;
        // The zero-duty step fails: the pin must not be flipped.
        assert_eq!(
            m.apply(MotorCommand::from_signed(-0.5)),
            Err(MotorFault::Pwm(pwm::ErrorKind::Other))
        );
        assert_eq!(take(&log), []);
        assert_eq!(m.direction(), Some(Direction::Forward));
        assert_eq!(m.stop(), Err(MotorFault::Pwm(pwm::ErrorKind::Other)));
        let (pwm, _pin) = m.release();
        assert!(pwm.fail);
    }

    #[test]
    fn works_with_infallible_hal_types() {
        struct Pwm(u16);
        impl pwm::ErrorType for Pwm {
            type Error = Infallible;
        }
        impl SetDutyCycle for Pwm {
            fn max_duty_cycle(&self) -> u16 {
                100
            }
            fn set_duty_cycle(&mut self, duty: u16) -> Result<(), Infallible> {
                self.0 = duty;
                Ok(())
            }
        }
        struct Pin(bool);
        impl digital::ErrorType for Pin {
            type Error = Infallible;
        }
        impl OutputPin for Pin {
            fn set_low(&mut self) -> Result<(), Infallible> {
                self.0 = false;
                Ok(())
            }
            fn set_high(&mut self) -> Result<(), Infallible> {
                self.0 = true;
                Ok(())
            }
        }
        let mut m = MotorDriver::new(Pwm(7), Pin(true), MotorWiring::default());
        m.apply(MotorCommand::from_signed(-0.42)).unwrap();
        let (pwm, pin) = m.release();
        assert_eq!((pwm.0, pin.0), (42, false));
    }

    proptest! {
        /// Whatever the command and PWM resolution: duty never above max,
        /// every pin write sits between a zero duty and the next duty, and a
        /// direction change always passes through zero duty.
        #[test]
        fn any_command_sequence_is_safe(
            max in 1_u16..,
            cmds in prop::collection::vec(
                prop_oneof![
                    -1.5_f32..1.5,
                    Just(f32::NAN),
                    Just(f32::INFINITY),
                    Just(f32::NEG_INFINITY),
                    Just(0.0),
                ],
                1..40,
            ),
        ) {
            let (mut m, log) = driver(max, false);
            for &c in &cmds {
                m.apply(MotorCommand::from_signed(c)).unwrap();
            }
            let ops = take(&log);
            let mut duty = None;
            let mut pin = None;
            for op in ops {
                match op {
                    Op::Duty(d) => {
                        prop_assert!(d <= max);
                        duty = Some(d);
                    }
                    Op::Pin(p) => {
                        prop_assert_eq!(duty, Some(0));
                        prop_assert_ne!(pin, Some(p));
                        pin = Some(p);
                    }
                }
            }
        }
    }
}
