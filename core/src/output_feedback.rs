//! Position-only trajectory tracking: paper 001's output-feedback system
//! (observer (5) + law (27)–(28), Theorem 3) with the bookkeeping a robot
//! needs around it: where the position comes from between tag fixes, what
//! happens before the first fix, and the failsafe when fixes stop.
//!
//! # One step
//! Each step takes the odometry over the *last* control period (the `v, ω`
//! that were actually driven, from the encoders) and the tag fix read this
//! tick, if any:
//!
//! 1. Position: a valid fix replaces the position; without one the last
//!    position is dead-reckoned along the odometry arc using the observer's
//!    heading `θ̂` (so the observer sees no innovation from it).
//! 2. Observer (5): updated with the odometry `(v, ω)` and the position
//!    change of step 1.
//! 3. Law (27)–(28) at `t_k = k·h` from the reference, the position and
//!    `(ẑ3, ẑ4)`.
//!
//! # Modes and failsafe
//! * [`TrackerMode::AwaitingFix`]: no fix since start: command zero (the
//!   robot does not know where it is).
//! * [`TrackerMode::Tracking`]: the law drives.
//! * [`TrackerMode::FixLost`]: no fix for more than
//!   `fix_timeout_ticks`: the robot must not drive on blind forever, so the
//!   command ramps down to zero at `failsafe_decel_m_s2` (ω scaled with v,
//!   so it slows along the arc it was on) and stays at zero. The observer
//!   and dead reckoning keep running. The first valid fix returns to
//!   `Tracking` (the law is global, so it rejoins the reference from
//!   wherever the robot stopped, at bounded speed).
//!
//! Fixes with a non-finite position, or older than `max_fix_age_ticks`,
//! are rejected and counted; a non-finite command (which valid
//! configuration and finite measurements do not produce) is replaced by
//! zero and counted.

use crate::geometry::{BodyVelocity, Pose, Vec2};
use crate::heading_observer::{
    HeadingEstimate, HeadingObserver, HeadingObserverConfig, ObserverConfigError,
};
use crate::odometry::OdometryStep;
use crate::reference::{ReferenceError, ReferenceSample, TickClock, Trajectory};
use crate::tracking::{GainBound, TrackingCommand, TrackingController, TrackingGains};

/// Why a [`TrackerConfig`] was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum TrackerConfigError {
    /// Control period not finite and positive.
    Period,
    /// The observer's configuration (its period must equal the tracker's).
    Observer(ObserverConfigError),
    /// Failsafe deceleration not finite and positive.
    FailsafeDecel,
    /// Fix timeout of zero ticks.
    FixTimeout,
}

impl From<ObserverConfigError> for TrackerConfigError {
    fn from(e: ObserverConfigError) -> Self {
        Self::Observer(e)
    }
}

impl From<ReferenceError> for TrackerConfigError {
    fn from(_: ReferenceError) -> Self {
        Self::Period
    }
}

/// Validated configuration of an [`OutputFeedbackTracker`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TrackerConfig {
    clock: TickClock,
    observer: HeadingObserverConfig,
    gains: TrackingGains,
    trajectory: Trajectory,
    fix_timeout_ticks: u32,
    max_fix_age_ticks: u32,
    failsafe_decel_m_s2: f32,
    gain_bound: GainBound,
}

impl TrackerConfig {
    /// Default failsafe deceleration, m/s².
    pub const DEFAULT_FAILSAFE_DECEL_M_S2: f32 = 0.5;
    /// Default age beyond which a fix is stale, ticks.
    pub const DEFAULT_MAX_FIX_AGE_TICKS: u32 = 2;

    /// A configuration from the observer's, the gains and the reference.
    ///
    /// `fix_timeout_ticks`: ticks without a valid fix before the failsafe.
    /// The control period is the observer's. The gain bound (15) is
    /// evaluated here and available from [`Self::gain_bound`]; a violated
    /// bound is reported, not refused (the paper's own gains violate it).
    ///
    /// # Errors
    /// [`TrackerConfigError::FixTimeout`] for a zero timeout.
    pub fn new(
        observer: HeadingObserverConfig,
        gains: TrackingGains,
        trajectory: Trajectory,
        fix_timeout_ticks: u32,
    ) -> Result<Self, TrackerConfigError> {
        if fix_timeout_ticks == 0 {
            return Err(TrackerConfigError::FixTimeout);
        }
        Ok(Self {
            clock: TickClock::new(observer.period_s())?,
            observer,
            gains,
            trajectory,
            fix_timeout_ticks,
            max_fix_age_ticks: Self::DEFAULT_MAX_FIX_AGE_TICKS,
            failsafe_decel_m_s2: Self::DEFAULT_FAILSAFE_DECEL_M_S2,
            gain_bound: gains.check_bound(trajectory.speed_bounds()),
        })
    }

    /// Sets the failsafe deceleration, m/s².
    ///
    /// # Errors
    /// [`TrackerConfigError::FailsafeDecel`] if not finite and positive.
    pub fn with_failsafe_decel(mut self, decel_m_s2: f32) -> Result<Self, TrackerConfigError> {
        if !(decel_m_s2.is_finite() && decel_m_s2 > 0.0) {
            return Err(TrackerConfigError::FailsafeDecel);
        }
        self.failsafe_decel_m_s2 = decel_m_s2;
        Ok(self)
    }

    /// Sets the age (ticks) beyond which a fix is stale and rejected.
    #[must_use]
    pub fn with_max_fix_age(mut self, ticks: u32) -> Self {
        self.max_fix_age_ticks = ticks;
        self
    }

    /// What the gain bound (15) says for these gains and this reference.
    #[must_use]
    pub fn gain_bound(&self) -> GainBound {
        self.gain_bound
    }

    /// The tick clock (control period).
    #[must_use]
    pub fn clock(&self) -> &TickClock {
        &self.clock
    }

    /// The reference trajectory.
    #[must_use]
    pub fn trajectory(&self) -> &Trajectory {
        &self.trajectory
    }

    /// The observer's configuration.
    #[must_use]
    pub fn observer(&self) -> &HeadingObserverConfig {
        &self.observer
    }

    /// Ticks without a valid fix before the failsafe engages.
    #[must_use]
    pub fn fix_timeout_ticks(&self) -> u32 {
        self.fix_timeout_ticks
    }
}

/// A position fix from a floor tag.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TagFix {
    /// The tag's floor position, m (world frame).
    pub position: Vec2,
    /// Ticks between the read and this step (0: read during this tick).
    pub age_ticks: u32,
}

/// What the tracker is doing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum TrackerMode {
    /// No valid fix yet: standing still.
    #[default]
    AwaitingFix,
    /// Tracking the reference.
    Tracking,
    /// Fixes lost for longer than the timeout: ramping down / stopped.
    FixLost,
}

/// Counters of everything the tracker refused or worked around.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct TrackerCounters {
    /// Valid fixes used.
    pub fixes_used: u32,
    /// Fixes with a non-finite position.
    pub invalid_fixes: u32,
    /// Fixes older than the configured maximum age.
    pub stale_fixes: u32,
    /// Steps whose position was dead-reckoned (no fix that tick).
    pub dead_reckoned_steps: u32,
    /// Times the failsafe engaged.
    pub failsafe_entries: u32,
    /// Non-finite commands replaced by zero.
    pub non_finite_commands: u32,
}

/// The result of one tracker step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TrackerOutput {
    /// The body command to drive (zero when not tracking).
    pub command: BodyVelocity,
    /// Mode after this step.
    pub mode: TrackerMode,
    /// Tick index of this step (`t = k·h`).
    pub tick: u32,
    /// Reference at this tick.
    pub reference: ReferenceSample,
    /// Position used by the law this tick (fix or dead-reckoned), m.
    pub position: Vec2,
    /// The observer's `(ẑ3, ẑ4)` after this step.
    pub heading: HeadingEstimate,
    /// The law's internals (zero unless tracking).
    pub law: TrackingCommand,
    /// Ticks since the last valid fix.
    pub ticks_since_fix: u32,
}

/// Paper 001's output-feedback tracker with fix handling and failsafe.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct OutputFeedbackTracker {
    config: TrackerConfig,
    observer: HeadingObserver,
    controller: TrackingController,
    tick: u32,
    position: Option<Vec2>,
    ticks_since_fix: u32,
    last_command: BodyVelocity,
    mode: TrackerMode,
    counters: TrackerCounters,
}

impl OutputFeedbackTracker {
    /// A tracker at tick 0, heading estimate `(0, 0)`, awaiting its first fix.
    #[must_use]
    pub fn new(config: TrackerConfig) -> Self {
        Self::with_observer(config, HeadingObserver::new(config.observer))
    }

    /// A tracker whose observer starts from a given estimate.
    #[must_use]
    pub fn with_observer(config: TrackerConfig, observer: HeadingObserver) -> Self {
        Self {
            config,
            observer,
            controller: TrackingController::new(config.gains),
            tick: 0,
            position: None,
            ticks_since_fix: 0,
            last_command: BodyVelocity::ZERO,
            mode: TrackerMode::AwaitingFix,
            counters: TrackerCounters::default(),
        }
    }

    /// The configuration.
    #[must_use]
    pub fn config(&self) -> &TrackerConfig {
        &self.config
    }

    /// Counters since start.
    #[must_use]
    pub fn counters(&self) -> TrackerCounters {
        self.counters
    }

    /// Observer updates skipped for non-finite input.
    #[must_use]
    pub fn observer_rejected_updates(&self) -> u32 {
        self.observer.rejected_updates()
    }

    /// One control step; `odometry` covers the last period, `fix` is this tick's.
    pub fn step(&mut self, odometry: &OdometryStep, fix: Option<TagFix>) -> TrackerOutput {
        let tick = self.tick;
        self.tick = self.tick.saturating_add(1);

        let fix = fix.and_then(|f| self.accept(f));
        let previous = self.position;
        let current = match (fix, previous) {
            (Some(p), _) => {
                self.ticks_since_fix = 0;
                Some(p)
            }
            (None, Some(p)) => {
                self.ticks_since_fix = self.ticks_since_fix.saturating_add(1);
                self.counters.dead_reckoned_steps =
                    self.counters.dead_reckoned_steps.saturating_add(1);
                let pose = Pose {
                    position: p,
                    heading_rad: self.observer.estimate().heading_rad(),
                };
                let next = pose
                    .advance_arc(odometry.ds_m, odometry.dtheta_rad)
                    .position;
                Some(if next.is_finite() { next } else { p })
            }
            (None, None) => None,
        };
        if let (Some(prev), Some(now)) = (previous, current) {
            self.observer.update(odometry.body, now - prev);
        }
        self.position = current;

        let reference = self
            .config
            .trajectory
            .sample(self.config.clock.time_s(tick));
        let heading = self.observer.estimate();
        let mut out = TrackerOutput {
            tick,
            reference,
            heading,
            ticks_since_fix: self.ticks_since_fix,
            ..TrackerOutput::default()
        };
        let Some(position) = current else {
            self.mode = TrackerMode::AwaitingFix;
            self.last_command = BodyVelocity::ZERO;
            out.mode = self.mode;
            return out;
        };
        out.position = position;

        if self.ticks_since_fix > self.config.fix_timeout_ticks {
            if self.mode != TrackerMode::FixLost {
                self.counters.failsafe_entries = self.counters.failsafe_entries.saturating_add(1);
            }
            self.mode = TrackerMode::FixLost;
            self.last_command = self.ramp_down(self.last_command);
        } else {
            self.mode = TrackerMode::Tracking;
            let law = self
                .controller
                .output_feedback(&reference, position, heading);
            out.law = law;
            self.last_command = if law.body.is_finite() {
                law.body
            } else {
                self.counters.non_finite_commands =
                    self.counters.non_finite_commands.saturating_add(1);
                BodyVelocity::ZERO
            };
        }
        out.mode = self.mode;
        out.command = self.last_command;
        out
    }

    fn accept(&mut self, fix: TagFix) -> Option<Vec2> {
        if !fix.position.is_finite() {
            self.counters.invalid_fixes = self.counters.invalid_fixes.saturating_add(1);
            None
        } else if fix.age_ticks > self.config.max_fix_age_ticks {
            self.counters.stale_fixes = self.counters.stale_fixes.saturating_add(1);
            None
        } else {
            self.counters.fixes_used = self.counters.fixes_used.saturating_add(1);
            Some(fix.position)
        }
    }

    /// Lowers |v| by `decel·h` toward zero, scaling ω with v (same arc);
    /// a pure turn (v = 0) is slowed at the same rate in rad/s².
    fn ramp_down(&self, command: BodyVelocity) -> BodyVelocity {
        let dv = self.config.failsafe_decel_m_s2 * self.config.clock.period_s();
        let speed = command.v_m_s.abs();
        if speed > 0.0 {
            let new_speed = (speed - dv).max(0.0);
            let k = new_speed / speed;
            BodyVelocity {
                v_m_s: command.v_m_s * k,
                omega_rad_s: command.omega_rad_s * k,
            }
        } else {
            let w = command.omega_rad_s;
            BodyVelocity {
                v_m_s: 0.0,
                omega_rad_s: w.signum() * (w.abs() - dv).max(0.0),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::{FigureEight, StraightLine};

    fn tracker(timeout: u32) -> OutputFeedbackTracker {
        let line = StraightLine::new(Vec2::ZERO, 0.0, 0.2).unwrap();
        let cfg = TrackerConfig::new(
            HeadingObserverConfig::new(1.0, 0.01).unwrap(),
            TrackingGains::new(0.05, 0.05, 1.0).unwrap(),
            line.into(),
            timeout,
        )
        .unwrap();
        OutputFeedbackTracker::new(cfg)
    }

    fn moving(v: f32) -> OdometryStep {
        OdometryStep {
            ds_m: v * 0.01,
            body: BodyVelocity {
                v_m_s: v,
                omega_rad_s: 0.0,
            },
            ..OdometryStep::default()
        }
    }

    fn fix(x: f32, y: f32) -> Option<TagFix> {
        Some(TagFix {
            position: Vec2::new(x, y),
            age_ticks: 0,
        })
    }

    #[test]
    fn stands_still_until_the_first_fix() {
        let mut t = tracker(10);
        for _ in 0..5 {
            let out = t.step(&OdometryStep::default(), None);
            assert_eq!(out.mode, TrackerMode::AwaitingFix);
            assert_eq!(out.command, BodyVelocity::ZERO);
        }
        let out = t.step(&OdometryStep::default(), fix(0.0, 0.0));
        assert_eq!(out.mode, TrackerMode::Tracking);
        assert!(out.command.v_m_s > 0.1);
    }

    #[test]
    fn failsafe_ramps_down_then_recovers() {
        let mut t = tracker(10);
        let mut out = t.step(&OdometryStep::default(), fix(0.0, 0.0));
        let v0 = out.command.v_m_s;
        // Ten ticks without a fix: still tracking on dead reckoning.
        for _ in 0..10 {
            out = t.step(&moving(v0), None);
            assert_eq!(out.mode, TrackerMode::Tracking);
        }
        // The eleventh: failsafe, speed falls by decel·h = 0.005 m/s per tick.
        let mut last = out.command.v_m_s;
        for _ in 0..200 {
            out = t.step(&moving(last), None);
            assert_eq!(out.mode, TrackerMode::FixLost);
            assert!(out.command.v_m_s <= last);
            assert!(last - out.command.v_m_s <= 0.005 + 1e-6);
            last = out.command.v_m_s;
        }
        assert_eq!(out.command, BodyVelocity::ZERO);
        assert_eq!(t.counters().failsafe_entries, 1);
        // A fix returns: tracking again (the reference has moved on).
        out = t.step(&moving(0.0), fix(0.4, 0.0));
        assert_eq!(out.mode, TrackerMode::Tracking);
        assert!(out.command.v_m_s > 0.0);
    }

    #[test]
    fn bad_and_stale_fixes_are_counted_and_ignored() {
        let mut t = tracker(10);
        t.step(&OdometryStep::default(), fix(f32::NAN, 0.0));
        t.step(
            &OdometryStep::default(),
            Some(TagFix {
                position: Vec2::ZERO,
                age_ticks: TrackerConfig::DEFAULT_MAX_FIX_AGE_TICKS + 1,
            }),
        );
        let c = t.counters();
        assert_eq!((c.invalid_fixes, c.stale_fixes, c.fixes_used), (1, 1, 0));
        assert_eq!(
            t.step(&OdometryStep::default(), None).mode,
            TrackerMode::AwaitingFix
        );
    }

    #[test]
    fn paper_gains_are_accepted_and_reported() {
        let cfg = TrackerConfig::new(
            HeadingObserverConfig::new(0.6, 0.01).unwrap(),
            TrackingGains::new(0.11, 0.11, 0.1).unwrap(),
            FigureEight::paper_001().into(),
            100,
        )
        .unwrap();
        assert!(!cfg.gain_bound().is_satisfied());
        assert_eq!(
            TrackerConfig::new(
                *cfg.observer(),
                TrackingGains::new(0.11, 0.11, 0.1).unwrap(),
                FigureEight::paper_001().into(),
                0
            ),
            Err(TrackerConfigError::FixTimeout)
        );
    }
}
