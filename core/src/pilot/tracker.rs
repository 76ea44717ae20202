//! Position-only trajectory tracking: paper 001's output-feedback system
//! (observer (5) + law (27)–(28), Theorem 3) with the bookkeeping a robot
//! needs around it: where the position comes from between tag fixes, what
//! happens before the first fix, and the failsafe when fixes stop.
//!
//! # Estimator and law
//! The tracker has no algorithm of its own: its configuration names one
//! estimator of [`crate::estimation`] ([`EstimatorChoice`]) and one law of
//! [`crate::control`] ([`LawChoice`]) ([`TrackerConfig::new`]; paper 001's
//! pair is `EstimatorChoice::HeadingObserver` with `LawChoice::Saturated`),
//! and sees them only through [`PoseEstimator`] and [`TrackingLaw`]. Where a law on the robot-frame error finds the
//! reference standing still (its heading undefined), the command is zero
//! and the tick is counted ([`TrackerCounters::reference_standstill_ticks`]).
//!
//! The gain bound (15) ([`TrackerConfig::gain_bound`]) concerns law
//! (27)–(28) only.
//!
//! # One step
//! Each step takes the odometry over the *last* control period (the `v, ω`
//! that were actually driven, from the encoders) and the tag fix read this
//! tick, if any:
//!
//! 1. Fix: rejected (and counted) if not finite or older than
//!    `max_fix_age_ticks`.
//! 2. Estimator: steps with the odometry and the accepted fix and gives the
//!    position the law uses (for the observers, the fix or, without one,
//!    the last position dead-reckoned along the odometry arc:
//!    [`crate::estimation::dead_reckoning`]) and the heading estimate.
//! 3. Law at the reference's time of tick `k` (below, "Reference time")
//!    from the reference, that position and heading, or the failsafe
//!    below.
//!
//! # Reference time
//! The trajectory is sampled at the time of the ticks since the tracker
//! started, reduced modulo whole periods of a periodic reference in
//! integer arithmetic ([`ReferenceClock`]: module
//! [`crate::reference`], "Time on long runs"), advanced by one tick each
//! step ([`OutputFeedbackTracker::step`] and
//! [`OutputFeedbackTracker::step_route`] alike). It is `t_k = k·h` for
//! the first [`crate::reference::EPOCH_TURNS`] turns of a figure-eight or
//! circle, and for a line; day 30 samples as day 1, and the reference
//! goes on past the `u32` tick count ([`TrackerOutput::tick`] saturates
//! at `u32::MAX`, after 497 days at 100 Hz; the reference's time does
//! not depend on it).
//!
//! # Modes and failsafe
//! * [`TrackerMode::AwaitingFix`]: no fix since start: command zero (the
//!   robot does not know where it is).
//! * [`TrackerMode::Tracking`]: the law drives.
//! * [`TrackerMode::FixLost`]: no fix for more than
//!   `fix_timeout_ticks` (or, where the estimator has a failsafe of its
//!   own, [`PoseEstimator::blind_distance_lost`], e.g. the fusion
//!   estimator's limit on the distance driven since the last fix, whatever
//!   the time): the robot
//!   must not drive on blind forever, so the
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
//!
//! # Routes
//! [`OutputFeedbackTracker::step_route`] follows a route
//! ([`crate::pilot::route::RouteFollower`], lent by the caller each tick)
//! instead of the configured trajectory: the same fix checks, estimator
//! and failsafe; the law while the route's reference moves, and the
//! route's own hold and pivot where it rests (module [`crate::pilot::route`]).
//! [`OutputFeedbackTracker::step`] is unchanged by it.
//!
//! # The reader's antenna
//! A tag is read where the antenna is, at `d = (d_x, d_y)` from the axle
//! midpoint in the robot's frame (`x` ahead, `y` to the left;
//! [`TrackerConfig::with_antenna_offset`]). Every estimator and law works
//! on the axle midpoint, so each accepted fix `p_a` becomes
//! `p = p_a − R(θ̂) d`, with `R(θ̂) = [[ĉ, −ŝ], [ŝ, ĉ]]` from the heading
//! estimate `(ĉ, ŝ)` before this tick's update, scaled down to unit length
//! where it is longer (an estimate still converging, `|(ĉ, ŝ)| < 1`,
//! moves the fix by less: at `(0, 0)`, before any heading is known, not
//! at all). With a zero offset the fix is used as it is, bit for bit.

use crate::control::saturated::{GainBound, TrackingCommand, TrackingGains};
use crate::control::{Law, LawChoice, LawCommand, TrackingLaw};
use crate::estimation::heading_observer::ObserverConfigError;
use crate::estimation::{Estimator, EstimatorChoice, PoseEstimator};
use crate::geometry::HeadingEstimate;
use crate::geometry::{BodyVelocity, Vec2};
use crate::odometry::OdometryStep;
use crate::pilot::route::{RouteFollower, Steer};
use crate::plausible::{DECEL_M_S2, PERIOD_S};
use crate::reference::{
    ReferenceClock, ReferenceError, ReferenceSample, ReferenceTime, TickClock, Trajectory,
};

/// Why a [`TrackerConfig`] was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum TrackerConfigError {
    /// Control period outside [`PERIOD_S`].
    Period,
    /// The observer's configuration (its period must equal the tracker's).
    Observer(ObserverConfigError),
    /// Failsafe deceleration outside [`crate::plausible::DECEL_M_S2`].
    FailsafeDecel,
    /// Fix timeout of zero ticks.
    FixTimeout,
    /// A law whose own step (Proposition 7's) is not the estimator's.
    AlgorithmPeriod,
    /// Antenna offset not finite, or farther than
    /// [`TrackerConfig::MAX_ANTENNA_OFFSET_M`] from the axle midpoint.
    AntennaOffset,
}

impl core::fmt::Display for TrackerConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Period => write!(f, "period_s must be in {PERIOD_S} s"),
            Self::Observer(e) => core::fmt::Display::fmt(e, f),
            Self::FailsafeDecel => write!(f, "failsafe_decel_m_s2 must be in {DECEL_M_S2} m/s²"),
            Self::FixTimeout => f.write_str("fix_timeout_ticks must be ≥ 1"),
            Self::AlgorithmPeriod => f.write_str(
                "the law's own step (paper 002's Proposition 7) must be the estimator's period_s",
            ),
            Self::AntennaOffset => {
                f.write_str("antenna_offset_m must be finite and within 1 m of the axle midpoint")
            }
        }
    }
}

impl core::error::Error for TrackerConfigError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            Self::Observer(e) => Some(e),
            _ => None,
        }
    }
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
    trajectory: Trajectory,
    reference_clock: ReferenceClock,
    fix_timeout_ticks: u32,
    max_fix_age_ticks: u32,
    failsafe_decel_m_s2: f32,
    estimator: EstimatorChoice,
    law: LawChoice,
    antenna_offset: Vec2,
}

impl TrackerConfig {
    /// Farthest the reader's antenna may sit from the axle midpoint, m (a
    /// larger figure is a unit mistake, not a robot).
    pub const MAX_ANTENNA_OFFSET_M: f32 = 1.0;

    /// Default failsafe deceleration, m/s².
    pub const DEFAULT_FAILSAFE_DECEL_M_S2: f32 = 0.5;
    /// Default age beyond which a fix is stale, ticks.
    pub const DEFAULT_MAX_FIX_AGE_TICKS: u32 = 2;

    /// A configuration from the estimator, the law and the reference.
    ///
    /// `fix_timeout_ticks`: ticks without a valid fix before the failsafe.
    /// The control period is the estimator's step
    /// ([`EstimatorChoice::period_s`]). For paper 001's law the gain bound
    /// (15) is evaluated by [`Self::gain_bound`]; a violated bound is
    /// reported, not refused (the paper's own gains violate it).
    ///
    /// # Errors
    /// [`TrackerConfigError::FixTimeout`] for a zero timeout,
    /// [`TrackerConfigError::Period`] for a step outside [`PERIOD_S`],
    /// [`TrackerConfigError::AlgorithmPeriod`] if the law's own step
    /// (Proposition 7's) is not the estimator's.
    // Inlined so that the spec's build assembles the configuration (with
    // the fusion estimator's settings) in place rather than in this
    // function's frame and copying it out: the firmware's `Configure` path
    // sets its peak stack.
    #[inline(always)]
    pub fn new(
        estimator: EstimatorChoice,
        law: LawChoice,
        trajectory: Trajectory,
        fix_timeout_ticks: u32,
    ) -> Result<Self, TrackerConfigError> {
        let fix_timeout_ticks = Self::check_fix_timeout(fix_timeout_ticks)?;
        let clock = TickClock::new(estimator.period_s())?;
        if law
            .period_s()
            .is_some_and(|law_s| law_s.to_bits() != clock.period_s().to_bits())
        {
            return Err(TrackerConfigError::AlgorithmPeriod);
        }
        Ok(Self {
            clock,
            trajectory,
            reference_clock: ReferenceClock::new(&clock, &trajectory),
            fix_timeout_ticks,
            max_fix_age_ticks: Self::DEFAULT_MAX_FIX_AGE_TICKS,
            failsafe_decel_m_s2: Self::DEFAULT_FAILSAFE_DECEL_M_S2,
            estimator,
            law,
            antenna_offset: Vec2::ZERO,
        })
    }

    /// Where the RFID reader's antenna sits, m, in the robot's frame from
    /// the axle midpoint (`x` ahead, `y` to the left); the default is the
    /// midpoint itself. Fixes are moved back to the midpoint with the
    /// heading estimate (module documentation).
    ///
    /// # Errors
    /// [`TrackerConfigError::AntennaOffset`] if not finite or farther
    /// than [`Self::MAX_ANTENNA_OFFSET_M`].
    pub fn with_antenna_offset(mut self, offset_m: Vec2) -> Result<Self, TrackerConfigError> {
        if !(offset_m.is_finite() && offset_m.norm() <= Self::MAX_ANTENNA_OFFSET_M) {
            return Err(TrackerConfigError::AntennaOffset);
        }
        self.antenna_offset = offset_m;
        Ok(self)
    }

    /// The antenna's offset from the axle midpoint, m (robot frame).
    #[must_use]
    pub fn antenna_offset(&self) -> Vec2 {
        self.antenna_offset
    }

    /// The heading estimator.
    #[must_use]
    pub fn estimator(&self) -> EstimatorChoice {
        self.estimator
    }

    /// The law.
    #[must_use]
    pub fn law(&self) -> LawChoice {
        self.law
    }

    /// Sets the failsafe deceleration, m/s².
    ///
    /// # Errors
    /// [`TrackerConfigError::FailsafeDecel`] outside [`DECEL_M_S2`].
    pub fn with_failsafe_decel(mut self, decel_m_s2: f32) -> Result<Self, TrackerConfigError> {
        self.failsafe_decel_m_s2 = Self::check_failsafe_decel(decel_m_s2)?;
        Ok(self)
    }

    /// The fix timeout's check ([`Self::new`]'s, and a run-time
    /// [`TuningSpec`]'s): at least one tick.
    ///
    /// # Errors
    /// [`TrackerConfigError::FixTimeout`] for zero.
    #[inline(always)]
    pub fn check_fix_timeout(ticks: u32) -> Result<u32, TrackerConfigError> {
        if ticks == 0 {
            Err(TrackerConfigError::FixTimeout)
        } else {
            Ok(ticks)
        }
    }

    /// The failsafe deceleration's check ([`Self::with_failsafe_decel`]'s,
    /// and a run-time [`TuningSpec`]'s), m/s².
    ///
    /// # Errors
    /// [`TrackerConfigError::FailsafeDecel`] outside [`DECEL_M_S2`].
    #[inline(always)]
    pub fn check_failsafe_decel(decel_m_s2: f32) -> Result<f32, TrackerConfigError> {
        if DECEL_M_S2.contains(decel_m_s2) {
            Ok(decel_m_s2)
        } else {
            Err(TrackerConfigError::FailsafeDecel)
        }
    }

    /// Takes `tuning`'s gains (law (27)–(28) only: with another law they
    /// are not used, and [`Self::tuning`] reports none), fix timeout, fix
    /// age and failsafe deceleration, in place (no copy of the whole
    /// configuration: flash and stack on the firmware); [`Self::gain_bound`]
    /// then judges the new gains. Infallible: a [`Tuning`] is checked
    /// already.
    pub fn retune(&mut self, tuning: &Tuning) {
        if let (LawChoice::Saturated(_), Some(gains)) = (self.law, tuning.gains()) {
            self.law = LawChoice::Saturated(gains);
        }
        self.fix_timeout_ticks = tuning.fix_timeout_ticks();
        self.max_fix_age_ticks = tuning.max_fix_age_ticks();
        self.failsafe_decel_m_s2 = tuning.failsafe_decel_m_s2();
    }

    /// The tracker's part of a [`TuningSpec`] (its
    /// `max_encoder_fault_ticks` is the pilot's: 0 here): law
    /// (27)–(28)'s gains (`None` with another law), the fix timeout and
    /// age, the failsafe deceleration.
    #[must_use]
    pub fn tuning(&self) -> TuningSpec {
        TuningSpec {
            gains: match self.law {
                LawChoice::Saturated(g) => Some([g.k1(), g.k2(), g.k3()]),
                _ => None,
            },
            fix_timeout_ticks: self.fix_timeout_ticks,
            max_fix_age_ticks: self.max_fix_age_ticks,
            failsafe_decel_m_s2: self.failsafe_decel_m_s2,
            max_encoder_fault_ticks: 0,
        }
    }

    /// The failsafe deceleration, m/s².
    #[must_use]
    pub fn failsafe_decel_m_s2(&self) -> f32 {
        self.failsafe_decel_m_s2
    }

    /// The age (ticks) beyond which a fix is stale.
    #[must_use]
    pub fn max_fix_age_ticks(&self) -> u32 {
        self.max_fix_age_ticks
    }

    /// Sets the age (ticks) beyond which a fix is stale and rejected.
    #[must_use]
    pub fn with_max_fix_age(mut self, ticks: u32) -> Self {
        self.max_fix_age_ticks = ticks;
        self
    }

    /// What the gain bound (15) says for paper 001's law's gains and this
    /// reference (`None` for the other laws, which it does not concern).
    /// Evaluated when asked (not kept: a firmware that never asks links
    /// none of it).
    #[must_use]
    pub fn gain_bound(&self) -> Option<GainBound> {
        self.law.gain_bound(self.trajectory.speed_bounds())
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

    /// The clock the reference is sampled by (module documentation,
    /// "Reference time").
    #[must_use]
    pub fn reference_clock(&self) -> &ReferenceClock {
        &self.reference_clock
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
    /// Ticks a paper 002 law commanded zero because the reference stood
    /// still (its heading, and so the error (30), is undefined there).
    pub reference_standstill_ticks: u32,
    /// Fix measurements the fusion EKF's Mahalanobis gate rejected.
    pub fixes_gated: u32,
    /// Times the fusion EKF re-localised after consecutive gated fixes.
    pub relocalisations: u32,
    /// Times the fusion EKF's heading was reset to its guide observer's.
    pub heading_resets: u32,
}

/// The result of one tracker step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TrackerOutput {
    /// The body command to drive (zero when not tracking).
    pub command: BodyVelocity,
    /// Mode after this step.
    pub mode: TrackerMode,
    /// Tick index of this step since the tracker started (saturates at
    /// `u32::MAX`; the reference's time does not depend on it: module
    /// documentation, "Reference time").
    pub tick: u32,
    /// Reference at this tick.
    pub reference: ReferenceSample,
    /// Position used by the law this tick (fix or dead-reckoned), m.
    pub position: Vec2,
    /// The estimator's `(cos θ, sin θ)` estimate after this step.
    pub heading: HeadingEstimate,
    /// The internals of law (27)–(28) (zero unless tracking with it; for
    /// the other laws only `body` is set).
    pub law: TrackingCommand,
    /// Ticks since the last valid fix.
    pub ticks_since_fix: u32,
    /// This tick's tag fix passed the tracker's checks (finite, no older
    /// than `max_fix_age_ticks`) and went to the estimator: counted in
    /// [`TrackerCounters::fixes_used`]. False without a fix, and for a fix
    /// refused here (counted in [`TrackerCounters::invalid_fixes`] or
    /// [`TrackerCounters::stale_fixes`]). The fusion estimator may still
    /// gate an accepted fix's measurements ([`TrackerCounters::fixes_gated`]).
    pub fix_used: bool,
}

/// Paper 001's output-feedback tracker with fix handling and failsafe.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct OutputFeedbackTracker {
    config: TrackerConfig,
    estimator: Estimator,
    law: Law,
    tick: u32,
    reference_time: ReferenceTime,
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
        Self::starting_at(config, HeadingEstimate::default())
    }

    /// A tracker whose estimator starts from the heading estimate
    /// `initial` (paper 001's `ẑ(0)`; paper 002's pose observer takes it
    /// as its `(ĉ, ŝ)`, and its position from the first fix).
    ///
    /// # Errors
    /// [`ObserverConfigError::InitialEstimate`] if not finite.
    pub fn with_initial_heading(
        config: TrackerConfig,
        initial: HeadingEstimate,
    ) -> Result<Self, ObserverConfigError> {
        if !(initial.cos_theta.is_finite() && initial.sin_theta.is_finite()) {
            return Err(ObserverConfigError::InitialEstimate);
        }
        Ok(Self::starting_at(config, initial))
    }

    fn starting_at(config: TrackerConfig, initial: HeadingEstimate) -> Self {
        let estimator = Estimator::new(config.estimator, initial);
        let law = Law::new(config.law);
        Self {
            config,
            estimator,
            law,
            tick: 0,
            reference_time: ReferenceTime::default(),
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

    /// Takes `tuning` from the next step on ([`TrackerConfig::retune`]):
    /// law (27)–(28)'s new gains bumplessly (its held heading kept,
    /// [`crate::control::saturated::TrackingController::set_gains`]), the
    /// fix timeout, fix age and failsafe deceleration for the next fix
    /// check and ramp. The mode, estimate and counters are kept.
    pub fn retune(&mut self, tuning: &Tuning) {
        self.config.retune(tuning);
        if let (Law::Saturated(law), LawChoice::Saturated(gains)) = (&mut self.law, self.config.law)
        {
            law.set_gains(gains);
        }
    }

    /// Counters since start.
    #[must_use]
    pub fn counters(&self) -> TrackerCounters {
        let estimator = self.estimator.counters();
        TrackerCounters {
            fixes_gated: estimator.fixes_gated,
            relocalisations: estimator.relocalisations,
            heading_resets: estimator.heading_resets,
            ..self.counters
        }
    }

    /// Estimator (and, for Proposition 7, its `sin θ_e` observer) updates
    /// skipped for non-finite input.
    #[must_use]
    pub fn observer_rejected_updates(&self) -> u32 {
        self.estimator
            .rejected_updates()
            .saturating_add(self.law.rejected_updates())
    }

    /// One control step; `odometry` covers the last period, `fix` is this tick's.
    pub fn step(&mut self, odometry: &OdometryStep, fix: Option<TagFix>) -> TrackerOutput {
        self.step_on(odometry, fix, None)
    }

    /// One control step on the route `route` instead of the configured
    /// trajectory (module [`crate::pilot::route`]: its clock, stops,
    /// pivots, loading and replacement); the fix handling, estimator and
    /// failsafe are [`Self::step`]'s. The output's reference is the
    /// route's; where the route is, and its counters, `route` tells.
    pub fn step_route(
        &mut self,
        odometry: &OdometryStep,
        fix: Option<TagFix>,
        route: &mut RouteFollower,
    ) -> TrackerOutput {
        self.step_on(odometry, fix, Some(route))
    }

    /// [`Self::step_route`] on `route` if given, else [`Self::step`]. One
    /// body with one call of [`Self::drive`], so that a caller that takes
    /// both (the pilot, the robot) has its output built in place: with a
    /// call in each, the two outputs meet in a temporary that is copied
    /// into the caller's result (88 B, about 100 instructions a tick).
    pub(crate) fn step_on(
        &mut self,
        odometry: &OdometryStep,
        fix: Option<TagFix>,
        mut route: Option<&mut RouteFollower>,
    ) -> TrackerOutput {
        let time = self.reference_time;
        let (tick, fix_used) = self.estimate(odometry, fix);
        let (reference, steer, heading, on_route) = match route.as_deref_mut() {
            None => (
                self.config
                    .trajectory
                    .sample_at(&self.config.reference_clock, time),
                Steer::Law { restart: false },
                self.estimator.heading(),
                None,
            ),
            Some(route) => {
                let tracking = self.position.is_some() && !self.fix_lost();
                let period_s = self.config.clock.period_s();
                if route.is_pending() {
                    let heading = self.estimator.heading();
                    if let Some(known) = route.start(tracking, self.position, heading, period_s) {
                        self.estimator.assume_heading(known);
                    }
                }
                let heading = self.estimator.heading();
                let (reference, steer) = route.begin(tracking, self.position, heading, period_s);
                (reference, steer, heading, Some(tracking))
            }
        };
        let out = self.drive(tick, fix_used, heading, odometry, reference, steer);
        if let (Some(route), Some(tracking)) = (route, on_route) {
            route.end(tracking, out.command, self.position, heading);
        }
        out
    }

    /// Fix checks and the estimator's step; the tick and whether a fix
    /// was used.
    fn estimate(&mut self, odometry: &OdometryStep, fix: Option<TagFix>) -> (u32, bool) {
        let tick = self.tick;
        self.tick = self.tick.saturating_add(1);
        self.reference_time = self.config.reference_clock.next(self.reference_time);

        let fix = fix.and_then(|f| self.accept(f));
        let previous = self.position;
        let after_gap = self.ticks_since_fix > 0;
        if fix.is_some() {
            self.ticks_since_fix = 0;
        } else if previous.is_some() {
            self.ticks_since_fix = self.ticks_since_fix.saturating_add(1);
            self.counters.dead_reckoned_steps = self.counters.dead_reckoned_steps.saturating_add(1);
        }
        self.position = self.estimator.step(odometry, fix, previous, after_gap);
        (tick, fix.is_some())
    }

    /// The law (or the failsafe, or a route's hold or pivot: `steer`) from
    /// the position and heading estimate; `tick` and `fix_used` are
    /// [`Self::estimate`]'s, `heading` the estimator's (as it is when this
    /// is called). The output is whole when this returns (nothing
    /// is written into it after), so that a caller's result is built in
    /// place rather than copied from a temporary (88 B a tick).
    fn drive(
        &mut self,
        tick: u32,
        fix_used: bool,
        heading: HeadingEstimate,
        odometry: &OdometryStep,
        reference: ReferenceSample,
        steer: Steer,
    ) -> TrackerOutput {
        let current = self.position;
        let mut out = TrackerOutput {
            tick,
            reference,
            heading,
            ticks_since_fix: self.ticks_since_fix,
            fix_used,
            ..TrackerOutput::default()
        };
        let Some(position) = current else {
            self.mode = TrackerMode::AwaitingFix;
            self.last_command = BodyVelocity::ZERO;
            out.mode = self.mode;
            return out;
        };
        out.position = position;

        if self.fix_lost() {
            if self.mode != TrackerMode::FixLost {
                self.counters.failsafe_entries = self.counters.failsafe_entries.saturating_add(1);
            }
            self.mode = TrackerMode::FixLost;
            self.last_command = self.ramp_down(self.last_command);
        } else {
            let restart = matches!(steer, Steer::Law { restart: true });
            if self.mode != TrackerMode::Tracking || restart {
                self.law.restart();
            }
            self.mode = TrackerMode::Tracking;
            let body = match steer {
                Steer::Law { .. } => {
                    out.law = match self
                        .law
                        .command(&reference, position, heading, odometry.body)
                    {
                        LawCommand::Drive(command) => command,
                        LawCommand::ReferenceStandstill => {
                            self.counters.reference_standstill_ticks =
                                self.counters.reference_standstill_ticks.saturating_add(1);
                            TrackingCommand::default()
                        }
                    };
                    out.law.body
                }
                Steer::Hold => self.ramp_down(self.last_command),
                Steer::Body(command) => command,
            };
            self.last_command = if body.is_finite() {
                body
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

    /// Whether the fix counts as lost: the estimator's own failsafe where
    /// it has one ([`PoseEstimator::blind_distance_lost`]), otherwise more
    /// than `fix_timeout_ticks` without a fix.
    fn fix_lost(&self) -> bool {
        self.estimator
            .blind_distance_lost()
            .unwrap_or(self.ticks_since_fix > self.config.fix_timeout_ticks)
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
            Some(self.axle_midpoint(fix.position))
        }
    }

    /// The axle midpoint of a robot whose antenna is at `antenna`, by the
    /// heading estimate (module documentation, "The reader's antenna").
    fn axle_midpoint(&self, antenna: Vec2) -> Vec2 {
        let d = self.config.antenna_offset;
        if d == Vec2::ZERO {
            return antenna;
        }
        let h = self.estimator.heading();
        let (c, s) = (h.cos_theta, h.sin_theta);
        let length = crate::math::sqrt(c * c + s * s);
        // The estimators guard theirs; should one not be finite, the fix
        // is not moved rather than made non-finite.
        if !length.is_finite() {
            return antenna;
        }
        // Longer than 1: the direction alone.
        let scale = if length > 1.0 { 1.0 / length } else { 1.0 };
        let (c, s) = (c * scale, s * scale);
        Vec2::new(
            antenna.x - (c * d.x - s * d.y),
            antenna.y - (s * d.x + c * d.y),
        )
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

/// The run-time tunable numbers of a pilot (`crate::pilot::tuning`).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TuningSpec {
    /// Law (27)–(28)'s `[k1, k2, k3]`, each in [`crate::plausible::GAIN`];
    /// `None` for a pilot on another law (it has no `k1, k2, k3`).
    pub gains: Option<[f32; 3]>,
    /// Ticks without a valid fix before the failsafe engages, ≥ 1.
    pub fix_timeout_ticks: u32,
    /// Age beyond which a fix is stale, ticks.
    pub max_fix_age_ticks: u32,
    /// Failsafe deceleration, m/s², in [`crate::plausible::DECEL_M_S2`].
    pub failsafe_decel_m_s2: f32,
    /// Consecutive encoder fault ticks bridged before the motors stop.
    pub max_encoder_fault_ticks: u32,
}

/// A checked [`TuningSpec`] ([`TuningSpec::build`]).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Tuning {
    spec: TuningSpec,
    gains: Option<TrackingGains>,
}

impl Tuning {
    /// A tuning whose values were checked ([`TuningSpec::build`]).
    pub(crate) fn checked(spec: TuningSpec, gains: Option<TrackingGains>) -> Self {
        Self { spec, gains }
    }

    /// Its numbers.
    #[must_use]
    pub fn spec(&self) -> &TuningSpec {
        &self.spec
    }

    /// Law (27)–(28)'s gains, `None` for another law.
    #[must_use]
    pub fn gains(&self) -> Option<TrackingGains> {
        self.gains
    }

    /// Ticks without a valid fix before the failsafe engages.
    #[must_use]
    pub fn fix_timeout_ticks(&self) -> u32 {
        self.spec.fix_timeout_ticks
    }

    /// Age beyond which a fix is stale, ticks.
    #[must_use]
    pub fn max_fix_age_ticks(&self) -> u32 {
        self.spec.max_fix_age_ticks
    }

    /// Failsafe deceleration, m/s².
    #[must_use]
    pub fn failsafe_decel_m_s2(&self) -> f32 {
        self.spec.failsafe_decel_m_s2
    }

    /// Consecutive encoder fault ticks bridged before the motors stop.
    #[must_use]
    pub fn max_encoder_fault_ticks(&self) -> u32 {
        self.spec.max_encoder_fault_ticks
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::cascaded::CascadedGains;
    use crate::control::heading_error_sine::HeadingErrorSineConfig;
    use crate::control::saturated::TrackingGains;
    use crate::estimation::heading_observer::HeadingObserverConfig;
    use crate::estimation::pose_observer::PoseObserverConfig;
    use crate::geometry::Pose;
    use crate::reference::{FigureEight, StraightLine};

    fn tracker(timeout: u32) -> OutputFeedbackTracker {
        let line = StraightLine::new(Vec2::ZERO, 0.0, 0.2).unwrap();
        let cfg = TrackerConfig::new(
            EstimatorChoice::HeadingObserver(HeadingObserverConfig::new(1.0, 0.01).unwrap()),
            LawChoice::Saturated(TrackingGains::new(0.05, 0.05, 1.0).unwrap()),
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
    fn an_antenna_offset_is_validated() {
        let cfg = *tracker(10).config();
        assert!(cfg.with_antenna_offset(Vec2::new(0.1, -0.05)).is_ok());
        for bad in [
            Vec2::new(f32::NAN, 0.0),
            Vec2::new(0.0, f32::INFINITY),
            Vec2::new(0.8, 0.8),
        ] {
            assert_eq!(
                cfg.with_antenna_offset(bad).unwrap_err(),
                TrackerConfigError::AntennaOffset
            );
        }
    }

    /// Fixes are moved from the antenna back to the axle midpoint by the
    /// heading estimate: not at all before any heading is known, by the
    /// whole offset once it has converged.
    #[test]
    fn fixes_move_from_the_antenna_to_the_axle_midpoint() {
        let offset = Vec2::new(0.1, 0.02);
        let cfg = tracker(1000).config().with_antenna_offset(offset).unwrap();
        let mut t = OutputFeedbackTracker::new(cfg);
        // The first fix: heading (0, 0), nothing known, the fix as it is.
        let first = t.step(&moving(0.2), fix(0.5, 0.0));
        assert_eq!(first.position, Vec2::new(0.5, 0.0));
        // Driving along +x with a fix each tick: the observer learns the
        // heading, and the fix moves back by R(θ̂)·offset.
        let mut out = first;
        for k in 1..3000 {
            let x = 0.5 + 0.2 * 0.01 * k as f32;
            out = t.step(&moving(0.2), fix(x, 0.0));
        }
        let h = out.heading;
        assert!(
            (h.cos_theta - 1.0).abs() < 0.05 && h.sin_theta.abs() < 0.05,
            "{h:?}"
        );
        let x = 0.5 + 0.2 * 0.01 * 3000.0;
        let next = t.step(&moving(0.2), fix(x, 0.0));
        assert!((next.position.x - (x - 0.1)).abs() < 0.01, "{next:?}");
        assert!((next.position.y - (-0.02)).abs() < 0.01, "{next:?}");
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

    /// On day 30 and across its `u32` tick count's end (497 days at
    /// 100 Hz) the tracker's figure-eight is within 1 mm of the `f64`
    /// curve and moves on (the output's tick saturates, the reference's
    /// time does not depend on it).
    #[test]
    fn the_reference_lasts_past_day_30_and_the_u32_tick() {
        let eight = FigureEight::paper_001();
        let cfg = TrackerConfig::new(
            EstimatorChoice::HeadingObserver(HeadingObserverConfig::new(1.0, 0.01).unwrap()),
            LawChoice::Saturated(TrackingGains::new(0.05, 0.05, 1.0).unwrap()),
            eight.into(),
            10,
        )
        .unwrap();
        let exact = |k: u64| {
            let s = f64::from(0.02_f32) * (k as f64 * f64::from(0.01_f32))
                + f64::from(-core::f32::consts::FRAC_PI_2);
            (5.0 * (2.0 * s).sin(), 5.0 * s.sin())
        };
        let clock = *cfg.reference_clock();
        for first in [30 * 86_400 * 100_u64, u64::from(u32::MAX) - 3] {
            let mut t = OutputFeedbackTracker::new(cfg);
            t.tick = u32::try_from(first).unwrap();
            t.reference_time = clock.at_tick(first);
            let mut previous = None;
            for k in first..first + 8 {
                let out = t.step(&moving(0.2), fix(0.0, -5.0));
                assert_eq!(u64::from(out.tick), k.min(u64::from(u32::MAX)));
                let p = out.reference.position;
                let (x, y) = exact(k);
                let error = (f64::from(p.x) - x).hypot(f64::from(p.y) - y);
                assert!(error < 1e-3, "tick {k}: {error} m");
                assert_ne!(Some(p), previous, "tick {k}");
                previous = Some(p);
            }
        }
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

    /// The step's answer says whether this tick's fix went to the
    /// estimator, exactly when `fixes_used` counts it: not for a missing,
    /// non-finite or stale fix, which the tracker counts instead.
    #[test]
    fn the_answer_says_a_fix_was_used_only_when_it_was() {
        let mut t = tracker(10);
        let still = OdometryStep::default();
        let stale = Some(TagFix {
            position: Vec2::ZERO,
            age_ticks: TrackerConfig::DEFAULT_MAX_FIX_AGE_TICKS + 1,
        });
        let oldest_fresh = Some(TagFix {
            position: Vec2::ZERO,
            age_ticks: TrackerConfig::DEFAULT_MAX_FIX_AGE_TICKS,
        });
        let cases = [
            (None, false),
            (fix(f32::INFINITY, 0.0), false),
            (fix(0.0, f32::NAN), false),
            (stale, false),
            (fix(0.0, 0.0), true),
            (oldest_fresh, true),
            (None, false),
        ];
        for (fix, used) in cases {
            let before = t.counters();
            let out = t.step(&still, fix);
            let after = t.counters();
            assert_eq!(out.fix_used, used, "{fix:?}");
            assert_eq!(after.fixes_used - before.fixes_used, u32::from(used));
            let refused = (after.invalid_fixes - before.invalid_fixes)
                + (after.stale_fixes - before.stale_fixes);
            assert_eq!(refused, u32::from(fix.is_some() && !used), "{fix:?}");
        }
        assert_eq!(t.counters().fixes_used, 2);
    }

    #[test]
    fn paper_gains_are_accepted_and_reported() {
        let estimator =
            EstimatorChoice::HeadingObserver(HeadingObserverConfig::new(0.6, 0.01).unwrap());
        let law = LawChoice::Saturated(TrackingGains::new(0.11, 0.11, 0.1).unwrap());
        let cfg = TrackerConfig::new(estimator, law, FigureEight::paper_001().into(), 100).unwrap();
        assert_eq!(cfg.gain_bound().map(|b| b.is_satisfied()), Some(false));
        assert_eq!(
            TrackerConfig::new(estimator, law, FigureEight::paper_001().into(), 0),
            Err(TrackerConfigError::FixTimeout)
        );
        // The bound (15) concerns law (27)–(28) only.
        let cascaded = LawChoice::Cascaded(CascadedGains::new(1.0, 1.0).unwrap());
        let cfg =
            TrackerConfig::new(estimator, cascaded, FigureEight::paper_001().into(), 100).unwrap();
        assert_eq!(cfg.gain_bound(), None);
    }

    #[test]
    fn the_law_must_share_the_estimator_step() {
        let line = StraightLine::new(Vec2::ZERO, 0.0, 0.2).unwrap();
        let sine_at = |h| {
            LawChoice::HeadingErrorSine(HeadingErrorSineConfig::new(10.0, 1.0, 0.9, h).unwrap())
        };
        let pose_observer = EstimatorChoice::PoseObserver(
            PoseObserverConfig::new(1.0, 1.0, 1.0, 1.0, 0.01).unwrap(),
        );
        assert_eq!(
            TrackerConfig::new(pose_observer, sine_at(0.02), line.into(), 10),
            Err(TrackerConfigError::AlgorithmPeriod)
        );
        let cfg = TrackerConfig::new(pose_observer, sine_at(0.01), line.into(), 10).unwrap();
        assert_eq!(cfg.clock().period_s(), 0.01);
    }

    #[test]
    fn a_tracker_starts_from_a_finite_initial_heading_only() {
        let config = tracker(10).config;
        let north = HeadingEstimate {
            cos_theta: 0.0,
            sin_theta: 1.0,
        };
        let t = OutputFeedbackTracker::with_initial_heading(config, north).unwrap();
        assert_eq!(t.estimator.heading(), north);
        let nan = HeadingEstimate {
            cos_theta: f32::NAN,
            sin_theta: 0.0,
        };
        assert_eq!(
            OutputFeedbackTracker::with_initial_heading(config, nan).err(),
            Some(ObserverConfigError::InitialEstimate)
        );
    }

    /// Pose observer + cascaded law (31) on a circle, from the wrong side
    /// and heading unknown: converges (the circle's ω_r is persistently
    /// exciting).
    #[test]
    fn pose_observer_with_cascaded_law_converges_on_a_circle() {
        use crate::reference::Circle;
        let h = 0.01;
        let circle: Trajectory = Circle::new(Vec2::ZERO, 2.0, 0.25, 0.0).unwrap().into();
        let cfg = TrackerConfig::new(
            EstimatorChoice::PoseObserver(
                PoseObserverConfig::new(2.0, 2.0, 20.0, 20.0, h).unwrap(),
            ),
            LawChoice::Cascaded(CascadedGains::new(1.0, 1.0).unwrap()),
            circle,
            10,
        )
        .unwrap();
        let mut t = OutputFeedbackTracker::new(cfg);
        let mut pose = Pose::new(-1.0, 0.5, 2.5);
        let mut odometry = OdometryStep::default();
        let mut out = TrackerOutput::default();
        for _ in 0..24_000 {
            out = t.step(
                &odometry,
                Some(TagFix {
                    position: pose.position,
                    age_ticks: 0,
                }),
            );
            let c = out.command;
            odometry = OdometryStep {
                ds_m: c.v_m_s * h,
                dtheta_rad: c.omega_rad_s * h,
                body: c,
                ..OdometryStep::default()
            };
            pose = pose.advance_arc(c.v_m_s * h, c.omega_rad_s * h);
        }
        // The fix this tick against the reference this tick. The y_e mode
        // of (32) decays at about ω_r²/c2 = 0.06 /s, hence 240 s (measured
        // 2.5e-4 m).
        let error = (out.position - out.reference.position).norm();
        std::println!("error after 240 s: {error}");
        assert!(error < 1e-3, "error after 240 s: {error}");
        assert_eq!(t.counters().reference_standstill_ticks, 0);
    }

    /// The fusion filter of the tests: 20 cm track, 1e-3 m²/m, 3σ gate.
    #[cfg(feature = "fusion-ekf")]
    fn fusion_filter() -> crate::estimation::fusion::PoseFilterConfig {
        crate::estimation::fusion::PoseFilterConfig::new(0.2, 1e-3, 1e-9, 3.0).unwrap()
    }

    /// A tracker on the fusion estimator `settings`, following the line
    /// through the origin at 0.5 rad, 0.2 m/s, h = 10 ms, fix timeout 50.
    #[cfg(feature = "fusion-ekf")]
    fn fusion_tracker(
        settings: crate::estimation::fusion::FusionSettings,
    ) -> OutputFeedbackTracker {
        let h = 0.01;
        let line = StraightLine::new(Vec2::ZERO, 0.5, 0.2).unwrap();
        let cfg = TrackerConfig::new(
            EstimatorChoice::Fusion {
                settings,
                guide: HeadingObserverConfig::new(1.0, h).unwrap(),
            },
            LawChoice::Saturated(TrackingGains::new(0.3, 0.3, 1.0).unwrap()),
            line.into(),
            50,
        )
        .unwrap();
        OutputFeedbackTracker::new(cfg)
    }

    /// The fusion EKF as the tracker's estimator: from an unknown heading,
    /// on nearest-tag fixes of a 10 cm grid, the robot joins a straight line
    /// at 0.5 rad to the grid and follows it within a few millimetres.
    /// (Along a row of tags the lateral error goes unseen within the cell:
    /// 2.4 cm on the line `y = 0`.)
    #[cfg(feature = "fusion-ekf")]
    #[test]
    fn fusion_ekf_estimator_tracks_a_line_from_tag_fixes() {
        use crate::estimation::fusion::FusionSettings;
        let h = 0.01;
        let mut t = fusion_tracker(FusionSettings::new(fusion_filter(), 0.1, 0.0).unwrap());
        let mut robot = Pose::new(-0.3, 0.4, 2.0);
        let mut odometry = OdometryStep::default();
        let nearest = |p: Vec2| Vec2::new((p.x * 10.0).round() / 10.0, (p.y * 10.0).round() / 10.0);
        let mut worst_late = 0.0_f32;
        for k in 0..6000u16 {
            let out = t.step(
                &odometry,
                Some(TagFix {
                    position: nearest(robot.position),
                    age_ticks: 0,
                }),
            );
            let c = out.command;
            odometry = OdometryStep {
                ds_m: c.v_m_s * h,
                dtheta_rad: c.omega_rad_s * h,
                body: c,
                ..OdometryStep::default()
            };
            robot = robot.advance_arc(c.v_m_s * h, c.omega_rad_s * h);
            if k >= 4000 {
                let r = out.reference.position;
                worst_late = worst_late.max(crate::math::hypot(
                    robot.position.x - r.x,
                    robot.position.y - r.y,
                ));
            }
        }
        // Measured 0.0037 m.
        assert!(worst_late < 0.01, "{worst_late}");
        let counters = t.counters();
        assert!(
            counters.fixes_used == 6000 && counters.non_finite_commands == 0,
            "{counters:?}"
        );
    }

    /// A fix the fusion EKF's gate rejects still passed the tracker's
    /// checks: the answer says it was used, as `fixes_used` counts it, and
    /// `fixes_gated` says the estimator's gate refused its measurement.
    #[cfg(feature = "fusion-ekf")]
    #[test]
    fn a_gated_fix_is_used_by_the_tracker_and_counted_by_the_gate() {
        use crate::estimation::fusion::FusionSettings;
        let mut t = fusion_tracker(FusionSettings::new(fusion_filter(), 0.1, 0.0).unwrap());
        let still = OdometryStep::default();
        for _ in 0..50 {
            assert!(t.step(&still, fix(0.0, 0.0)).fix_used);
        }
        let before = t.counters();
        assert_eq!(before.fixes_gated, 0);
        // Two metres from where the robot stands still: far outside 3σ.
        let out = t.step(&still, fix(2.0, 0.0));
        let after = t.counters();
        assert!(out.fix_used, "{out:?}");
        assert_eq!(after.fixes_used, before.fixes_used + 1);
        assert!(after.fixes_gated > before.fixes_gated, "{after:?}");
    }

    /// With a distance limit the fusion estimator's failsafe counts metres
    /// driven since the last fix, not ticks: standing still without fixes
    /// for 20× the fix timeout stays `Tracking`; driving 0.3 m blind
    /// (limit 0.25 m) enters `FixLost`, and the next fix leaves it.
    #[cfg(feature = "fusion-ekf")]
    #[test]
    fn fusion_failsafe_counts_distance_not_time() {
        use crate::estimation::fusion::FusionSettings;
        let settings = FusionSettings::new(fusion_filter(), 0.3, 0.0)
            .and_then(|s| s.with_read_radius(0.05))
            .and_then(|s| s.with_max_blind_distance(0.25))
            .unwrap();
        assert_eq!(
            settings.with_max_blind_distance(f32::NAN),
            Err(crate::estimation::fusion::PoseFilterError::BlindDistance)
        );
        let mut t = fusion_tracker(settings);
        let fix = TagFix {
            position: Vec2::ZERO,
            age_ticks: 0,
        };
        let still = OdometryStep::default();
        assert_eq!(t.step(&still, Some(fix)).mode, TrackerMode::Tracking);
        for _ in 0..1000 {
            assert_eq!(t.step(&still, None).mode, TrackerMode::Tracking);
        }
        let moving = OdometryStep {
            ds_m: 0.002,
            ..OdometryStep::default()
        };
        let modes: Vec<TrackerMode> = (0..150).map(|_| t.step(&moving, None).mode).collect();
        // 0.25 m after 125 steps of 2 mm (give or take f32 rounding).
        assert!(modes.iter().take(124).all(|m| *m == TrackerMode::Tracking));
        assert_eq!(modes.last(), Some(&TrackerMode::FixLost));
        assert_eq!(t.counters().failsafe_entries, 1);
        assert_eq!(t.step(&moving, Some(fix)).mode, TrackerMode::Tracking);
    }
}
