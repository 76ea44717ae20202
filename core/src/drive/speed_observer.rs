//! Wheel speeds, load torques and drive-train damping from the encoder
//! angles: paper 003's Proposition 1 ([`crate::drive::momenta_observer`]) on the
//! differential drive written in its wheel angles ([`WheelInertia`],
//! section 6.1), for the drive's speed loops in place of differenced
//! counts.
//!
//! # Motor model
//! Each wheel is driven by a DC motor through a gearbox; with the electrical
//! time constant neglected its torque at the wheel is
//! `τ = τ_stall·u − (τ_stall/ω_0)·φ̇` for the signed duty `u ∈ [−1, 1]`,
//! `τ_stall` the torque at full duty and standstill and `ω_0` the no-load
//! wheel speed at full duty. The observer's input is `G u = τ_stall·u`
//! (N·m); the back-EMF term `(τ_stall/ω_0)·φ̇` is viscous, so it joins the
//! drive-train friction in the *identified* damping `r̂` of each wheel
//! (initial guess `τ_stall/ω_0`). A slope, a drag or a towed load is the
//! constant disturbance `d̂` (N·m at each wheel, negative when it brakes
//! forward motion).
//!
//! # Timing
//! Per control tick the drive calls [`WheelSpeedObserver::measure`] with
//! the wheel-angle increments of the tick, uses the speeds it returns, then
//! [`WheelSpeedObserver::apply`] with the duties it commands until the next
//! tick. A tick without a valid encoder read (or a stop) restarts the step:
//! the estimates are held and the next read only starts a new step.
//!
//! # Angle range
//! The accumulated wheel angles are re-based to 0 whenever they pass
//! [`REBASE_RAD`], so `f32` keeps the resolution of the increments however
//! far the robot drives (exact: the inertia is constant).

use crate::drive::momenta_observer::{
    ConstantInertia, MomentaObserver, MomentaObserverConfig, MomentaObserverError, Vector,
    WheelInertia,
};
use crate::geometry::WheelSpeeds;
use crate::plausible::{TORQUE_NM, WHEEL_SPEED_RAD_S};

/// The accumulated wheel angle (rad) past which the origin is moved.
pub const REBASE_RAD: f32 = 1000.0;

/// Validated parameters of a [`WheelSpeedObserver`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WheelSpeedObserverConfig {
    inertia: WheelInertia,
    model: ConstantInertia<2>,
    stall_torque_nm: f32,
    damping_guess_nm_s_per_rad: f32,
    observer: MomentaObserverConfig<2>,
}

impl WheelSpeedObserverConfig {
    /// Default `λ`, 1/s: the wheel-speed noise from count quantization
    /// grows with it (measured on the robot of `host-tests`' paper 003).
    pub const DEFAULT_LAMBDA_PER_S: f32 = 5.0;
    /// Default friction adaptation gain `γ_r`.
    pub const DEFAULT_FRICTION_GAIN: f32 = 0.01;
    /// Default disturbance adaptation gain `γ_d`.
    pub const DEFAULT_DISTURBANCE_GAIN: f32 = 0.1;

    /// The robot's wheel-angle inertia, the motors' torque at the wheel at
    /// full duty and standstill `τ_stall` (N·m) and their no-load wheel
    /// speed at full duty `ω_0` (rad/s), for a control period `period_s`
    /// (s), with the default gains.
    ///
    /// # Errors
    /// [`MomentaObserverError::Parameter`] for a torque or speed outside
    /// its range ([`crate::plausible`]), or the period's error.
    pub fn new(
        inertia: WheelInertia,
        stall_torque_nm: f32,
        no_load_speed_rad_s: f32,
        period_s: f32,
    ) -> Result<Self, MomentaObserverError> {
        if !(TORQUE_NM.contains(stall_torque_nm) && WHEEL_SPEED_RAD_S.contains(no_load_speed_rad_s))
        {
            return Err(MomentaObserverError::Parameter);
        }
        let damping_guess_nm_s_per_rad = stall_torque_nm / no_load_speed_rad_s;
        if !(damping_guess_nm_s_per_rad.is_finite() && damping_guess_nm_s_per_rad > 0.0) {
            return Err(MomentaObserverError::Parameter);
        }
        let model = inertia.model(Vector::zeros())?;
        let observer =
            MomentaObserverConfig::new::<2>(Self::DEFAULT_LAMBDA_PER_S, period_s, [0, 1])?
                .with_adaptation_gains(
                    Self::DEFAULT_FRICTION_GAIN,
                    Self::DEFAULT_DISTURBANCE_GAIN,
                )?;
        Ok(Self {
            inertia,
            model,
            stall_torque_nm,
            damping_guess_nm_s_per_rad,
            observer,
        })
    }

    /// Other gains: `λ` (1/s), `γ_r`, `γ_d` (module docs of
    /// [`crate::drive::momenta_observer`]).
    ///
    /// # Errors
    /// The gain out of range.
    pub fn with_gains(
        self,
        lambda_per_s: f32,
        friction_gain: f32,
        disturbance_gain: f32,
    ) -> Result<Self, MomentaObserverError> {
        let observer =
            MomentaObserverConfig::new::<2>(lambda_per_s, self.observer.period_s(), [0, 1])?
                .with_adaptation_gains(friction_gain, disturbance_gain)?;
        Ok(Self { observer, ..self })
    }

    /// The robot's inertia.
    #[must_use]
    pub fn inertia(&self) -> &WheelInertia {
        &self.inertia
    }

    /// The control period `h`, s.
    #[must_use]
    pub fn period_s(&self) -> f32 {
        self.observer.period_s()
    }
}

/// The observer with the wheel angles it accumulates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WheelSpeedObserver {
    config: WheelSpeedObserverConfig,
    observer: MomentaObserver<ConstantInertia<2>, 2, 2>,
    /// `(φ_R, φ_L)` since the last re-base, rad.
    angles: Vector<2>,
}

impl WheelSpeedObserver {
    /// An observer at rest: speeds and loads 0, damping at its guess.
    #[must_use]
    pub fn new(config: WheelSpeedObserverConfig) -> Self {
        let guess = config.damping_guess_nm_s_per_rad;
        Self {
            config,
            observer: MomentaObserver::new(
                config.model,
                config.observer,
                Vector::zeros(),
                Vector::zeros(),
                nalgebra::SVector::<f32, 2>::new(guess, guess),
            ),
            angles: Vector::zeros(),
        }
    }

    /// The configuration.
    #[must_use]
    pub fn config(&self) -> &WheelSpeedObserverConfig {
        &self.config
    }

    /// This tick's wheel-angle increments `(left, right)` in rad (`None`
    /// without a valid read: the step restarts and `None` is returned).
    /// Returns the estimated wheel speeds now.
    pub fn measure(&mut self, increments_rad: Option<(f32, f32)>) -> Option<WheelSpeeds> {
        let Some((left, right)) = increments_rad.filter(|(l, r)| l.is_finite() && r.is_finite())
        else {
            self.observer.restart();
            return None;
        };
        if self.angles.amax() > REBASE_RAD {
            self.observer.rebase(&self.angles);
            self.angles = Vector::zeros();
        }
        self.angles += Vector::<2>::new(right, left);
        let rejected = self.observer.rejected_updates();
        self.observer.measure(&self.angles);
        if self.observer.rejected_updates() != rejected {
            return None;
        }
        Some(self.estimate_speeds())
    }

    /// The wheel speeds at the last accepted sample, rad/s.
    #[must_use]
    pub fn estimate_speeds(&self) -> WheelSpeeds {
        let v = self.observer.estimate().velocity;
        WheelSpeeds {
            left_rad_s: v.y,
            right_rad_s: v.x,
        }
    }

    /// The signed duties `(left, right)` commanded until the next tick.
    pub fn apply(&mut self, left_duty: f32, right_duty: f32) {
        let stall = self.config.stall_torque_nm;
        self.observer
            .apply(&Vector::<2>::new(stall * right_duty, stall * left_duty));
    }

    /// Forgets the current step (a stop or a fault): the estimates are held.
    pub fn restart(&mut self) {
        self.observer.restart();
    }

    /// The estimated load torque on each wheel `(left, right)`, N·m
    /// (negative brakes forward motion).
    #[must_use]
    pub fn load_torques_nm(&self) -> (f32, f32) {
        let d = self.observer.estimate().disturbance;
        (d.y, d.x)
    }

    /// The identified damping of each wheel `(left, right)`, back-EMF plus
    /// drive-train friction, N·m·s/rad.
    #[must_use]
    pub fn damping_nm_s_per_rad(&self) -> (f32, f32) {
        let r = self.observer.estimate().friction;
        (r.y, r.x)
    }

    /// Samples the observer skipped (non-finite input or result).
    #[must_use]
    pub fn rejected_updates(&self) -> u32 {
        self.observer.rejected_updates()
    }
}

#[cfg(feature = "defmt")]
impl defmt::Format for WheelSpeedObserverConfig {
    fn format(&self, f: defmt::Formatter) {
        defmt::write!(
            f,
            "WheelSpeedObserverConfig {{ {}, stall torque: {} N·m, damping guess: {} N·m·s/rad }}",
            self.inertia,
            self.stall_torque_nm,
            self.damping_guess_nm_s_per_rad
        );
    }
}

#[cfg(feature = "defmt")]
impl defmt::Format for WheelSpeedObserver {
    fn format(&self, f: defmt::Formatter) {
        let v = self.observer.estimate().velocity;
        defmt::write!(
            f,
            "WheelSpeedObserver {{ right: {} rad/s, left: {} rad/s, rejected: {} }}",
            v.x,
            v.y,
            self.observer.rejected_updates()
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config() -> WheelSpeedObserverConfig {
        let inertia = WheelInertia::new(4.0, 0.08, 0.035, 0.2, 2e-4).unwrap();
        WheelSpeedObserverConfig::new(inertia, 0.5, 20.0, 0.01).unwrap()
    }

    #[test]
    fn configuration_is_validated() {
        let inertia = *config().inertia();
        assert_eq!(
            WheelSpeedObserverConfig::new(inertia, 0.0, 20.0, 0.01),
            Err(MomentaObserverError::Parameter)
        );
        assert_eq!(
            WheelSpeedObserverConfig::new(inertia, 0.5, f32::NAN, 0.01),
            Err(MomentaObserverError::Parameter)
        );
        assert_eq!(
            WheelSpeedObserverConfig::new(inertia, 0.5, 20.0, 0.0),
            Err(MomentaObserverError::Period)
        );
        assert_eq!(
            config().with_gains(5.0, -1.0, 0.1),
            Err(MomentaObserverError::AdaptationGain)
        );
    }

    /// Both wheels at full duty against the back-EMF only: the speed
    /// settles at the no-load speed, and the observer follows it from the
    /// angles.
    #[test]
    fn follows_a_motor_at_no_load_speed() {
        let mut obs = WheelSpeedObserver::new(config());
        let h = 0.01_f32;
        // Exact steady state: 20 rad/s on both wheels.
        obs.measure(Some((0.0, 0.0)));
        obs.apply(1.0, 1.0);
        let mut last = None;
        for _ in 0..500 {
            last = obs.measure(Some((20.0 * h, 20.0 * h)));
            obs.apply(1.0, 1.0);
        }
        let speeds = last.unwrap();
        assert!((speeds.left_rad_s - 20.0).abs() < 0.05, "{speeds:?}");
        assert!((speeds.right_rad_s - 20.0).abs() < 0.05, "{speeds:?}");
        // Far past REBASE_RAD: 100 rad per 500 ticks... 5000 more ticks.
        for _ in 0..5000 {
            last = obs.measure(Some((20.0 * h, 20.0 * h)));
            obs.apply(1.0, 1.0);
        }
        let speeds = last.unwrap();
        assert!((speeds.left_rad_s - 20.0).abs() < 0.05, "{speeds:?}");
        assert!(obs.angles.amax() <= REBASE_RAD + 1.0);
    }

    #[test]
    fn missing_and_bad_reads_restart_the_step() {
        let mut obs = WheelSpeedObserver::new(config());
        assert!(obs.measure(None).is_none());
        assert!(obs.measure(Some((f32::NAN, 0.0))).is_none());
        assert!(obs.measure(Some((0.1, 0.1))).is_some());
        obs.apply(f32::INFINITY, 0.0);
        assert_eq!(obs.rejected_updates(), 1);
    }
}
