//! From a body command `(v, ω)` to a PWM duty per wheel.
//!
//! ```text
//! BodyVelocity ─► wheel speeds ─► speed limit ─► acceleration limit ─► speed loop ─► signed duty
//!                 (geometry)      (scale both:    (scale the change    (PI + feed-     [-1, 1]
//!                                  keeps ω/v)      of both wheels)      forward)
//! ```
//!
//! * The speed limit scales *both* wheels by the same factor when either
//!   exceeds `max_wheel_speed_rad_s`, so the commanded curvature `ω/v` (the
//!   path) is kept and only the pace along it drops.
//! * The acceleration limit bounds the change of each wheel's target per
//!   step to `max_wheel_accel_rad_s2·h`, again by scaling the change of both
//!   wheels together (the direction of the change in wheel-speed space is
//!   kept, so a pure speed-up stays straight).
//! * The per-wheel speed loop is a PI on the encoder-measured wheel speed
//!   with a feed-forward term, output clamped to [-1, 1], and conditional
//!   integration as anti-windup (the integral does not grow while the output
//!   is saturated in the direction of the error).
//! * With the cargo feature `wheel-speed-observer` and
//!   `DriveConfig::with_speed_observer`, the speed loops run on the wheel
//!   speeds of paper 003's momenta observer
//!   ([`crate::drive::speed_observer`]) instead of the counts differenced
//!   over one tick; it also estimates each wheel's load torque and damping.

pub mod momenta_observer;
pub mod spec;
pub mod speed_observer;

use crate::geometry::{BodyVelocity, DiffDriveGeometry, WheelSpeeds};
use crate::math;
use crate::plausible::{PERIOD_S, SPEED_LOOP_GAIN, WHEEL_ACCEL_RAD_S2, WHEEL_SPEED_RAD_S};

/// Why a drive configuration was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum DriveConfigError {
    /// Control period outside [`PERIOD_S`].
    Period,
    /// Maximum wheel speed outside [`WHEEL_SPEED_RAD_S`].
    MaxWheelSpeed,
    /// Maximum wheel acceleration outside [`WHEEL_ACCEL_RAD_S2`].
    MaxWheelAccel,
    /// A speed-loop gain outside [`SPEED_LOOP_GAIN`].
    SpeedLoopGain,
}

impl core::fmt::Display for DriveConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Period => write!(f, "period_s must be in {PERIOD_S} s"),
            Self::MaxWheelSpeed => write!(
                f,
                "max_wheel_speed_rad_s must be in {WHEEL_SPEED_RAD_S} rad/s"
            ),
            Self::MaxWheelAccel => write!(
                f,
                "max_wheel_accel_rad_s2 must be in {WHEEL_ACCEL_RAD_S2} rad/s²"
            ),
            Self::SpeedLoopGain => write!(
                f,
                "the speed-loop gains (feedforward_duty_per_rad_s, kp_duty_per_rad_s, \
                 ki_duty_per_rad) must each be in {SPEED_LOOP_GAIN}"
            ),
        }
    }
}

impl core::error::Error for DriveConfigError {}

/// Gains of the per-wheel speed loop (duty fractions per rad/s).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SpeedLoopGains {
    /// Feed-forward duty per rad/s of target (≈ 1 / motor speed constant at full duty).
    pub feedforward_duty_per_rad_s: f32,
    /// Proportional gain, duty per rad/s of error.
    pub kp_duty_per_rad_s: f32,
    /// Integral gain, duty per rad of accumulated error (per rad/s·s).
    pub ki_duty_per_rad: f32,
}

impl SpeedLoopGains {
    fn is_valid(&self) -> bool {
        SPEED_LOOP_GAIN.contains(self.feedforward_duty_per_rad_s)
            && SPEED_LOOP_GAIN.contains(self.kp_duty_per_rad_s)
            && SPEED_LOOP_GAIN.contains(self.ki_duty_per_rad)
    }
}

/// Validated drive parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DriveConfig {
    geometry: DiffDriveGeometry,
    period_s: f32,
    max_wheel_speed_rad_s: f32,
    max_wheel_accel_rad_s2: f32,
    speed_loop: SpeedLoopGains,
    #[cfg(feature = "wheel-speed-observer")]
    speed_observer: Option<crate::drive::speed_observer::WheelSpeedObserverConfig>,
}

impl DriveConfig {
    /// Validates the drive parameters.
    ///
    /// # Errors
    /// The first parameter outside its plausible range ([`crate::plausible`]).
    pub fn new(
        geometry: DiffDriveGeometry,
        period_s: f32,
        max_wheel_speed_rad_s: f32,
        max_wheel_accel_rad_s2: f32,
        speed_loop: SpeedLoopGains,
    ) -> Result<Self, DriveConfigError> {
        if !PERIOD_S.contains(period_s) {
            return Err(DriveConfigError::Period);
        }
        if !WHEEL_SPEED_RAD_S.contains(max_wheel_speed_rad_s) {
            return Err(DriveConfigError::MaxWheelSpeed);
        }
        if !WHEEL_ACCEL_RAD_S2.contains(max_wheel_accel_rad_s2) {
            return Err(DriveConfigError::MaxWheelAccel);
        }
        if !speed_loop.is_valid() {
            return Err(DriveConfigError::SpeedLoopGain);
        }
        Ok(Self {
            geometry,
            period_s,
            max_wheel_speed_rad_s,
            max_wheel_accel_rad_s2,
            speed_loop,
            #[cfg(feature = "wheel-speed-observer")]
            speed_observer: None,
        })
    }

    /// Runs the speed loops on the observer's wheel speeds (module docs).
    ///
    /// # Errors
    /// [`DriveConfigError::Period`] if the observer's period is not the
    /// drive's.
    #[cfg(feature = "wheel-speed-observer")]
    pub fn with_speed_observer(
        self,
        observer: crate::drive::speed_observer::WheelSpeedObserverConfig,
    ) -> Result<Self, DriveConfigError> {
        let h = observer.period_s();
        if (h - self.period_s).abs() > 1e-6 * self.period_s {
            return Err(DriveConfigError::Period);
        }
        Ok(Self {
            speed_observer: Some(observer),
            ..self
        })
    }

    /// The speed observer's configuration, if the speed loops use it.
    #[cfg(feature = "wheel-speed-observer")]
    #[must_use]
    pub fn speed_observer(
        &self,
    ) -> Option<&crate::drive::speed_observer::WheelSpeedObserverConfig> {
        self.speed_observer.as_ref()
    }

    /// Robot geometry.
    #[must_use]
    pub fn geometry(&self) -> &DiffDriveGeometry {
        &self.geometry
    }

    /// Control period `h`, s.
    #[must_use]
    pub fn period_s(&self) -> f32 {
        self.period_s
    }

    /// Maximum wheel speed, rad/s.
    #[must_use]
    pub fn max_wheel_speed_rad_s(&self) -> f32 {
        self.max_wheel_speed_rad_s
    }

    /// Maximum wheel acceleration, rad/s².
    #[must_use]
    pub fn max_wheel_accel_rad_s2(&self) -> f32 {
        self.max_wheel_accel_rad_s2
    }

    /// Speed-loop gains.
    #[must_use]
    pub fn speed_loop(&self) -> &SpeedLoopGains {
        &self.speed_loop
    }
}

/// Scales both wheel speeds by one factor so that neither exceeds `max`.
///
/// Returns the limited speeds and whether the limit acted. Non-finite input
/// gives zero speeds (and counts as limited). Each speed is scaled as
/// `(target / largest) · max`: the quotient lies in [−1, 1], so the result
/// never exceeds `max` in magnitude. (`target · (max / largest)` would
/// exceed it, by up to ~10 %, when `max / largest` is a subnormal `f32`
/// with few significant bits: a subnormal limit, or a command near
/// `f32::MAX`; the `pilot_step` fuzz target finds such inputs.)
#[must_use]
pub fn limit_wheel_speeds(target: WheelSpeeds, max_rad_s: f32) -> (WheelSpeeds, bool) {
    if !target.is_finite() {
        return (WheelSpeeds::ZERO, true);
    }
    let largest = target.left_rad_s.abs().max(target.right_rad_s.abs());
    if largest <= max_rad_s {
        return (target, false);
    }
    (
        WheelSpeeds {
            left_rad_s: target.left_rad_s / largest * max_rad_s,
            right_rad_s: target.right_rad_s / largest * max_rad_s,
        },
        true,
    )
}

/// Moves `previous` toward `target` by at most `max_step` per wheel,
/// scaling the change of both wheels together. Returns the result and
/// whether the limit acted.
#[must_use]
pub fn limit_wheel_change(
    previous: WheelSpeeds,
    target: WheelSpeeds,
    max_step_rad_s: f32,
) -> (WheelSpeeds, bool) {
    let dl = target.left_rad_s - previous.left_rad_s;
    let dr = target.right_rad_s - previous.right_rad_s;
    let largest = dl.abs().max(dr.abs());
    if largest.is_nan() || largest <= max_step_rad_s {
        return (target, false);
    }
    // (dl / largest) · max_step, as in `limit_wheel_speeds`: never more
    // than max_step, even when max_step / largest would be subnormal.
    (
        WheelSpeeds {
            left_rad_s: previous.left_rad_s + dl / largest * max_step_rad_s,
            right_rad_s: previous.right_rad_s + dr / largest * max_step_rad_s,
        },
        true,
    )
}

/// One wheel's PI + feed-forward speed loop (state only; gains live in
/// [`DriveConfig`], so they can be swapped without a bump).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WheelSpeedLoop {
    integral_duty: f32,
}

impl WheelSpeedLoop {
    /// Signed duty in [-1, 1] for a target and a measured wheel speed.
    ///
    /// `measured = None` (encoder fault this tick) runs feed-forward plus the
    /// held integral, without proportional action or integration.
    pub fn update(
        &mut self,
        gains: &SpeedLoopGains,
        period_s: f32,
        target_rad_s: f32,
        measured_rad_s: Option<f32>,
    ) -> f32 {
        let feedforward = gains.feedforward_duty_per_rad_s * target_rad_s;
        let Some(measured) = measured_rad_s.filter(|m| m.is_finite()) else {
            return math::clamp_or(feedforward + self.integral_duty, -1.0, 1.0, 0.0);
        };
        let error = target_rad_s - measured;
        let unclamped = feedforward + gains.kp_duty_per_rad_s * error + self.integral_duty;
        // Conditional integration: freeze while saturated and pushing further out.
        let saturated_high = unclamped >= 1.0 && error > 0.0;
        let saturated_low = unclamped <= -1.0 && error < 0.0;
        if !(saturated_high || saturated_low) {
            self.integral_duty = math::clamp_or(
                self.integral_duty + gains.ki_duty_per_rad * error * period_s,
                -1.0,
                1.0,
                0.0,
            );
        }
        math::clamp_or(unclamped, -1.0, 1.0, 0.0)
    }

    /// Clears the integral (after a stop or a fault).
    pub fn reset(&mut self) {
        self.integral_duty = 0.0;
    }
}

/// What the drive did this step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DriveOutput {
    /// Wheel-speed targets after both limits, rad/s.
    pub wheel_targets: WheelSpeeds,
    /// Signed duty of the left motor, [-1, 1].
    pub left_duty: f32,
    /// Signed duty of the right motor, [-1, 1].
    pub right_duty: f32,
    /// The speed limit scaled the command this step.
    pub speed_limited: bool,
    /// The acceleration limit acted this step.
    pub accel_limited: bool,
}

/// Body command → wheel targets → limits → speed loops.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Drive {
    config: DriveConfig,
    previous_targets: WheelSpeeds,
    left: WheelSpeedLoop,
    right: WheelSpeedLoop,
    #[cfg(feature = "wheel-speed-observer")]
    speed_observer: Option<crate::drive::speed_observer::WheelSpeedObserver>,
}

impl Drive {
    /// A drive at rest.
    #[must_use]
    pub fn new(config: DriveConfig) -> Self {
        Self {
            config,
            previous_targets: WheelSpeeds::ZERO,
            left: WheelSpeedLoop::default(),
            right: WheelSpeedLoop::default(),
            #[cfg(feature = "wheel-speed-observer")]
            speed_observer: config
                .speed_observer
                .map(crate::drive::speed_observer::WheelSpeedObserver::new),
        }
    }

    /// The speed observer, if the speed loops use it.
    #[cfg(feature = "wheel-speed-observer")]
    #[must_use]
    pub fn speed_observer(&self) -> Option<&crate::drive::speed_observer::WheelSpeedObserver> {
        self.speed_observer.as_ref()
    }

    /// The configuration.
    #[must_use]
    pub fn config(&self) -> &DriveConfig {
        &self.config
    }

    /// One step. `measured` are the wheel speeds over the last step (None
    /// if an encoder failed this tick). With the speed observer, `measured
    /// × h` are the tick's wheel-angle increments and the loops use the
    /// observer's speeds.
    pub fn step(&mut self, command: BodyVelocity, measured: Option<WheelSpeeds>) -> DriveOutput {
        #[cfg(feature = "wheel-speed-observer")]
        let measured = match self.speed_observer.as_mut() {
            Some(observer) => {
                let h = self.config.period_s;
                observer.measure(measured.map(|m| (m.left_rad_s * h, m.right_rad_s * h)))
            }
            None => measured,
        };
        let c = &self.config;
        let wanted = c.geometry.wheels_from_body(command);
        let (limited, speed_limited) = limit_wheel_speeds(wanted, c.max_wheel_speed_rad_s);
        let (targets, accel_limited) = limit_wheel_change(
            self.previous_targets,
            limited,
            c.max_wheel_accel_rad_s2 * c.period_s,
        );
        self.previous_targets = targets;
        let left_duty = self.left.update(
            &c.speed_loop,
            c.period_s,
            targets.left_rad_s,
            measured.map(|m| m.left_rad_s),
        );
        let right_duty = self.right.update(
            &c.speed_loop,
            c.period_s,
            targets.right_rad_s,
            measured.map(|m| m.right_rad_s),
        );
        #[cfg(feature = "wheel-speed-observer")]
        if let Some(observer) = self.speed_observer.as_mut() {
            observer.apply(left_duty, right_duty);
        }
        DriveOutput {
            wheel_targets: targets,
            left_duty,
            right_duty,
            speed_limited,
            accel_limited,
        }
    }

    /// Immediate stop: targets and integrals to zero (for faults; a planned
    /// stop should ramp through [`Self::step`] with a zero command instead).
    pub fn halt(&mut self) {
        self.previous_targets = WheelSpeeds::ZERO;
        self.left.reset();
        self.right.reset();
        #[cfg(feature = "wheel-speed-observer")]
        if let Some(observer) = self.speed_observer.as_mut() {
            observer.restart();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Neither wheel may exceed the limit. `target · (max / largest)`
    /// exceeds it: by an ulp for ordinary values (the product of two
    /// rounded factors), and by up to ~10 % when `max / largest` is
    /// subnormal (the `pilot_step` fuzz target's finding); these limits and
    /// speeds, as bits, each break it (found by a search over random bit
    /// patterns).
    #[test]
    fn the_speed_limit_holds_when_its_scale_would_be_subnormal() {
        let cases = [
            (0x1c42_d942_u32, 0x582c_9c12_u32),
            (0x3058_38d4, 0x7456_58b5),
            (0x3868_620e, 0x7e62_ae3f),
            (0x2d41_5b82, 0x7533_44fb),
        ]
        .map(|(max, speed)| {
            let speed = f32::from_bits(speed);
            (
                f32::from_bits(max),
                WheelSpeeds {
                    left_rad_s: speed,
                    right_rad_s: -0.5 * speed,
                },
            )
        });
        for (max, target) in cases {
            let (limited, acted) = limit_wheel_speeds(target, max);
            assert!(acted);
            assert!(limited.left_rad_s.abs() <= max, "{max:e}: {limited:?}");
            assert!(limited.right_rad_s.abs() <= max, "{max:e}: {limited:?}");
            let (stepped, acted) = limit_wheel_change(WheelSpeeds::ZERO, target, max);
            assert!(acted);
            assert!(stepped.left_rad_s.abs() <= max && stepped.right_rad_s.abs() <= max);
        }
    }
    use proptest::prelude::*;

    fn config() -> DriveConfig {
        DriveConfig::new(
            DiffDriveGeometry::new(0.03, 0.2, 4096).unwrap(),
            0.01,
            20.0,
            50.0,
            SpeedLoopGains {
                feedforward_duty_per_rad_s: 1.0 / 25.0,
                kp_duty_per_rad_s: 0.02,
                ki_duty_per_rad: 0.2,
            },
        )
        .unwrap()
    }

    #[test]
    fn speed_limit_keeps_curvature() {
        let (w, hit) = limit_wheel_speeds(
            WheelSpeeds {
                left_rad_s: 10.0,
                right_rad_s: 40.0,
            },
            20.0,
        );
        assert!(hit);
        assert_eq!(w.right_rad_s, 20.0);
        assert_eq!(w.left_rad_s, 5.0);
    }

    #[test]
    fn bad_config_is_named() {
        let g = DiffDriveGeometry::new(0.03, 0.2, 4096).unwrap();
        let gains = SpeedLoopGains {
            feedforward_duty_per_rad_s: 0.04,
            kp_duty_per_rad_s: -1.0,
            ki_duty_per_rad: 0.0,
        };
        assert_eq!(
            DriveConfig::new(g, 0.01, 20.0, 50.0, gains),
            Err(DriveConfigError::SpeedLoopGain)
        );
        assert_eq!(
            DriveConfig::new(g, 0.01, 0.0, 50.0, gains),
            Err(DriveConfigError::MaxWheelSpeed)
        );
    }

    #[test]
    fn ramps_at_the_acceleration_limit() {
        let mut d = Drive::new(config());
        let out = d.step(
            BodyVelocity {
                v_m_s: 0.5,
                omega_rad_s: 0.0,
            },
            Some(WheelSpeeds::ZERO),
        );
        assert!(out.accel_limited);
        assert!((out.wheel_targets.left_rad_s - 0.5).abs() < 1e-6); // 50 rad/s² · 10 ms
    }

    proptest! {
        #[test]
        fn duty_is_always_bounded_and_finite(
            v in prop::num::f32::ANY, w in prop::num::f32::ANY,
            ml in prop::num::f32::ANY, mr in prop::num::f32::ANY,
            steps in 1_usize..20,
        ) {
            let mut d = Drive::new(config());
            for _ in 0..steps {
                let out = d.step(BodyVelocity { v_m_s: v, omega_rad_s: w },
                    Some(WheelSpeeds { left_rad_s: ml, right_rad_s: mr }));
                prop_assert!(out.left_duty.is_finite() && out.left_duty.abs() <= 1.0);
                prop_assert!(out.right_duty.is_finite() && out.right_duty.abs() <= 1.0);
                prop_assert!(out.wheel_targets.is_finite());
            }
        }
    }
}
