//! Following a route ([`crate::reference::route`]) through its stops and
//! pivots: the storage the route is planned into, the route's own clock,
//! what the tracker commands at rest, and the counters of stops and pivots.
//!
//! # Where the route lives
//! A [`RoutePlan`] is about 20 KB. The tracker and the [`super::Pilot`]
//! are built in place by the firmware and their configuration is a `Copy`
//! value passed around, so neither holds one: a [`RouteFollower`] does,
//! owned by the caller (a `static`, or the task's state), and lent to
//! [`OutputFeedbackTracker::step_route`](super::tracker::OutputFeedbackTracker::step_route)
//! (or [`super::Pilot::step_route`]) each tick. A robot without routes
//! pays nothing, and the tracker on an analytic
//! [`crate::reference::Trajectory`] ([`super::tracker::OutputFeedbackTracker::step`])
//! is unchanged, bit for bit.
//!
//! # Loading and replacing a route
//! [`RouteFollower::load`] copies the waypoints (1.8 KB) and the limits;
//! the next step plans them in place ([`RoutePlan::replan`], about 124,000
//! instructions on a Cortex-M4F for 64 waypoints: under a millisecond at
//! 168 MHz, in that one tick), at a tick boundary:
//!
//! * **No route has run yet.** [`RouteStart::AsGiven`]: the route is
//!   planned as loaded, at the next step where the tracker knows the
//!   robot's position, and the robot is first driven onto its first
//!   waypoint ("Arrivals"). [`RouteStart::AsGivenHeadingKnown`]: the same,
//!   and the heading the planner assumes there (the first waypoint's
//!   heading to face, else the first leg's direction) is given to the
//!   estimator as known ([`crate::estimation::PoseEstimator::assume_heading`]):
//!   a robot parked at its station knows which way it faces, and no
//!   estimator observes the heading at rest. [`RouteStart::FromFirstFix`]: the first
//!   waypoint's position is replaced by the estimated position at that
//!   step (the first accepted fix, moved to the axle midpoint, or the
//!   estimate the tracker already has), so the first leg starts where
//!   the robot is, and its heading to face becomes the estimator's
//!   heading (where it has one): the planner takes the robot to face it
//!   there, so a first leg that turns more than the pivot threshold from
//!   the robot's heading starts with a pivot (a face heading given on the
//!   first waypoint is not kept). With [`RouteStart::AsGiven`] the planner
//!   assumes the robot faces the first leg (or the first stop's heading
//!   to face): a heading that differs is absorbed while leaving (below
//!   [`SLOW_SPEED_M_S`], the tangent hold, for a few ticks) and then by
//!   the law, which may well turn on the spot to do it. Told a wrong
//!   heading, the fusion estimator is corrected by its guide observer
//!   once that has converged (metres of driving), the observers by
//!   driving as from any start.
//! * **A route is running or has run.** The robot stops first: the
//!   running route goes on until its reference is at rest on a waypoint
//!   (`Stopped`, after any pivot, or its end; every route ends in a stop,
//!   so that comes), and at that tick the new route is planned with its
//!   first waypoint's position replaced by the rest point and its heading
//!   to face by the heading the reference holds there (so the new route
//!   pivots first where its first leg turns away from it). The reference
//!   is then continuous in position (the same point) and velocity (zero
//!   on both sides) across the switch. A replacement loaded before the
//!   previous one started replaces it.
//! * **Refused.** A route the planner refuses (a [`RouteError`]: also
//!   the case when the replaced first waypoint equals the second) is
//!   counted ([`RouteCounters::routes_refused`], [`RouteStatus::refused`])
//!   and the robot is held still where the reference rests (or where it
//!   is, before any route): never at the empty plan's origin.
//!
//! # The route's clock
//! Time is the integer count of ticks the route has been followed,
//! sampled with [`RoutePlan::sample`]: 0 at the tick it is planned, one
//! more after each step in which the tracker drove it (`Tracking`) and
//! the robot kept up. The clock stands (the reference waits for the robot
//! rather than running away from it):
//!
//! * while the tracker awaits a fix or is in its failsafe (`FixLost`,
//!   ramping down); the law rejoins the reference when fixes return;
//! * while the law steers and the robot lags the moving reference by more
//!   than [`RouteOptions::max_lag_m`] along the reference's velocity
//!   (`(p_r − p̂)·v_r/|v_r|`), counted in
//!   [`RouteCounters::clock_wait_ticks`]. This is the virtual-vehicle
//!   idea of Egerstedt, Hu & Stotsky, "Control of mobile platforms using a
//!   virtual vehicle approach", IEEE Trans. Automatic Control 46(11),
//!   1777–1782, 2001 (the reference's progress depends on the tracking
//!   error), with a rate of 1 or 0 per tick so that the clock stays an
//!   integer. The sample taken while waiting keeps its velocity, so the
//!   law's feed-forward still drives the robot on; only a robot *behind*
//!   is waited for (one beside or ahead of the reference would not come
//!   closer by it, and one ahead would wait forever);
//! * during an arrival approach (below).
//!
//! A robot that lags is therefore not left behind: the route takes longer
//! than planned (the simulator's `time_ratio`) instead.
//! The count starts from zero with each route, so the tracker's own tick
//! counter and its wrap do not concern it, and a plan is shorter than
//! [`crate::reference::route::MAX_ROUTE_TICKS`] (2³¹): it saturates long
//! after the route is done.
//!
//! # Arrivals
//! Where the reference comes to rest on a waypoint (and at the start of
//! a first route loaded [`RouteStart::AsGiven`] or
//! [`RouteStart::AsGivenHeadingKnown`], whose first waypoint the robot may
//! not be on), the robot is driven onto the rest point before the clock
//! goes on: the stop's dwell, its pivot and the next leg wait for it. With
//! `d` the estimated distance to the point and `e_∥` its component along
//! the estimated heading:
//!
//! * beyond [`NEAR_OF_TOLERANCE`] times [`RouteOptions::position_tolerance_m`]
//!   (5 cm by default), the robot turns toward the point (or away from it
//!   and backs up, the smaller turn), `ω = k_θ·e_β` within the route's
//!   pivot rate, and drives as far as it faces it,
//!   `v = ±min(k_a·d·cos e_β, v_a)` ([`APPROACH_GAIN_PER_S`],
//!   [`RouteOptions::approach_speed_m_s`]): a go-to-point law;
//! * within it, the robot only creeps along its heading, `v = sat(k_a·e_∥)`,
//!   `ω = 0`, and has arrived once `|e_∥|` is within
//!   [`ARRIVAL_BAND_OF_TOLERANCE`] of the tolerance. Its estimated stop
//!   error across its heading is the path's cross-track error at
//!   arrival (turning toward a point this close would turn the robot
//!   by tens of degrees, and back on leaving).
//!
//! An approach is counted tick by tick ([`RouteCounters::approach_ticks`]);
//! one longer than [`RouteOptions::approach_timeout_s`] ends where the
//! robot is, counted in [`RouteCounters::approach_timeouts`] (the stop's
//! error then shows in [`RouteCounters::stop_errors`]). Without a heading
//! estimate (paper 001's observer before it has driven) there is no
//! approach: the robot settles where it is.
//!
//! # At rest: stops, pivots, the end
//! While the reference moves the law drives, except below
//! [`SLOW_SPEED_M_S`] (leaving and reaching a rest), where the robot holds
//! the path's tangent instead (`v = v_r·cos e`, `ω = k_θ·e`, with the
//! estimator's heading; the law where it has none). Where it rests, the law is
//! not asked ([`crate::control::LawChoice::at_rest`]: paper 001's law
//! would creep after position noise, paper 002's are undefined there):
//!
//! * **Stopped.** The command ramps to zero from the last one at the
//!   tracker's failsafe deceleration (`v` lowered by `a·h` a tick, `ω`
//!   scaled with it; a pure turn slowed by `a·h` rad/s a tick) and, once
//!   it is zero, is exactly zero until the reference moves again: the
//!   robot has *settled* (no law output, no creeping after position
//!   noise). At the first settle of a stop it is counted
//!   ([`RouteCounters::stops_reached`]). At every settle (after arrival,
//!   after a pivot) the stop's error is measured: the estimated position
//!   from the reference point and, where the reference holds a heading and
//!   the estimator has one, the heading's; beyond
//!   [`RouteOptions::position_tolerance_m`] or
//!   [`RouteOptions::heading_tolerance_rad`] (1 cm and 1°, the product
//!   goals) the stop counts once in [`RouteCounters::stop_errors`]. The
//!   errors are the estimator's, as the robot knows them; a test measures
//!   the true ones. [`super::Pilot::step_route`] then also halts the
//!   drive once its wheel targets are zero ([`RouteStatus::holding`]), so
//!   the motors' duties are exactly zero, not a speed loop's integral.
//! * **Pivoting** to `θ_r` at `ω_r`: `v = 0`, `ω = ω_r + k_θ·wrap(θ_r − θ̂)`
//!   with `θ̂` the estimator's heading and `k_θ`
//!   [`RouteOptions::pivot_gain_per_s`] (capped at `1/h`, so that one tick
//!   never turns past the reference: the discrete heading error obeys
//!   `e⁺ = (1 − k_θ h)·e`). Each pivot segment counts once
//!   ([`RouteCounters::pivots`]). No estimator observes the heading at
//!   standstill ([`crate::estimation::EstimatorChoice::heading_at_standstill`]):
//!   each turns its heading by the encoders' rotation, so a pivot is as
//!   good as the heading was when the robot stopped. Paper 001's observer
//!   (5) starts from `(0, 0)` and only learns the heading while driving:
//!   while its estimate is shorter than [`MIN_HEADING_NORM`] (no heading
//!   yet, e.g. a pivot at the first waypoint) the pivot is open loop,
//!   `ω = ω_r` ([`RouteCounters::open_loop_pivot_ticks`]). Paper 002's
//!   pose observer, started from `(0, 0)`, grows its `(ĉ, ŝ)` slowly
//!   (measured `(0.41, 0)` after 0.5 m at `a3 = a4 = 20`), so its first
//!   pivots may be open loop too; an open-loop pivot through the drive's
//!   acceleration limits overshot by 4.2° in a test.
//! * **Done.** Once the reference rests on the last waypoint and the robot
//!   has settled, [`RouteStatus::done`] is set and the robot stays held,
//!   its command exactly zero; [`RouteCounters::routes_done`] counts it.
//!
//! A non-finite estimate or command keeps the tracker's own handling
//! (its failsafe, its zero for a non-finite command); a non-finite
//! heading estimate makes a pivot open loop.

use crate::geometry::{BodyVelocity, HeadingEstimate, Vec2};
use crate::math;
use crate::reference::ReferenceSample;
use crate::reference::route::{
    RouteCursor, RouteError, RouteLimits, RouteMode, RoutePlan, RouteSample, Stop, Waypoint,
    Waypoints,
};

/// The shortest heading estimate `|(ĉ, ŝ)|` a pivot steers by: below it
/// (paper 001's observer before the robot has driven, `(0, 0)`) the
/// heading is unknown and a pivot runs open loop.
pub const MIN_HEADING_NORM: f32 = 0.5;

/// The reference speed below which a moving route's reference is not
/// given to the law, m/s: the first and last ticks of a leg, leaving or
/// reaching a rest. There paper 001's law (14) steers toward `u = ṗ_r −
/// f(ζ)`, which a millimetre of position error turns around (measured: a
/// 1 mm arrival error made it command 33 rad/s on the first tick of the
/// next leg, and spin the robot); instead the robot holds the path's
/// tangent, `v = v_r·cos e` and `ω = k_θ·e`. At the limits' 0.5 m/s² the
/// reference covers 0.4 mm and 40 ms below this speed.
pub const SLOW_SPEED_M_S: f32 = 0.02;

/// A squared reference speed above which the speed is certainly not
/// below [`SLOW_SPEED_M_S`], m²/s²: that speed's square with a 10 % margin
/// (5 % in speed), far above the rounding of the squared norm and the few
/// ulps by which [`crate::math::hypot`] may differ from the exact norm, so
/// the test on the square alone decides as `norm() >= SLOW_SPEED_M_S`
/// would, without the root; a speed within the margin (or NaN) is decided
/// by the norm itself.
const CERTAINLY_NOT_SLOW_M2_S2: f32 = 1.1 * SLOW_SPEED_M_S * SLOW_SPEED_M_S;

/// The arrival approach's gain on the along-heading distance to the rest
/// point, 1/s: 1 cm short commands 2 cm/s (under the approach's speed cap).
pub const APPROACH_GAIN_PER_S: f32 = 2.0;

/// Leaving a rest, the robot is turned in place onto the leg's direction
/// while its heading estimate is further off than this, rad (about 11°);
/// the law is not given a robot facing away from the path (measured: 140°
/// off, paper 001's law spun it at 18 rad/s and it left the path by 37 cm).
pub const DEPARTURE_ALIGN_RAD: f32 = 0.2;

/// Within this many position tolerances of the rest point, the arrival
/// approach only creeps along the robot's heading: the distance across it
/// is the path's cross-track error at arrival, and turning toward a point
/// a few centimetres to the side turns the robot by tens of degrees (and
/// back again on leaving), which costs more than it gains (measured: a
/// 1 cm offset turned the robot by 145° and it left the stop 31 cm wide).
pub const NEAR_OF_TOLERANCE: f32 = 5.0;

/// The arrival approach ends, in its near radius, once the distance to
/// the rest point along the robot's heading is within this fraction of the
/// position tolerance; what is left across the heading is the path's
/// cross-track error at arrival.
pub const ARRIVAL_BAND_OF_TOLERANCE: f32 = 0.25;

/// Where a loaded route's first leg starts, when no route has run before
/// it (a replacement always starts where the running route rests).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[non_exhaustive]
pub enum RouteStart {
    /// At the first waypoint, as loaded; the robot is assumed to face the
    /// first leg (or the first waypoint's heading to face), and the
    /// estimator is not told so.
    #[default]
    AsGiven,
    /// At the estimated position when the route starts (the robot's first
    /// accepted fix, or its estimate if it has one already): the first
    /// waypoint's position is replaced by it.
    FromFirstFix,
    /// As [`RouteStart::AsGiven`], and the heading the robot faces there
    /// is known (a robot parked at its station): when the route starts,
    /// the estimator takes it as its heading
    /// ([`crate::estimation::PoseEstimator::assume_heading`]).
    AsGivenHeadingKnown,
}

/// Why [`RouteOptions`] were refused: the field (its name in
/// [`RouteOptionsSpec`]) and its range.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[non_exhaustive]
pub enum RouteOptionsError {
    /// `pivot_gain_per_s` not finite or outside `(0, 1000]` 1/s.
    PivotGain,
    /// `position_tolerance_m` or `heading_tolerance_rad` not finite or
    /// not positive.
    Tolerance,
    /// `max_lag_m` not finite or not positive.
    MaxLag,
    /// `approach_speed_m_s` not finite or outside `(0, 1]` m/s.
    ApproachSpeed,
    /// `approach_timeout_s` not finite or negative.
    ApproachTimeout,
}

impl RouteOptionsError {
    /// The field of [`RouteOptionsSpec`] refused (for
    /// [`RouteOptionsError::Tolerance`], the position's: the heading's
    /// shares the variant).
    #[must_use]
    pub fn field(&self) -> &'static str {
        match self {
            Self::PivotGain => "pivot_gain_per_s",
            Self::Tolerance => "position_tolerance_m",
            Self::MaxLag => "max_lag_m",
            Self::ApproachSpeed => "approach_speed_m_s",
            Self::ApproachTimeout => "approach_timeout_s",
        }
    }
}

impl core::fmt::Display for RouteOptionsError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::PivotGain => "pivot_gain_per_s must be in (0, 1000] 1/s",
            Self::Tolerance => "the stop tolerances must be finite and positive",
            Self::MaxLag => "max_lag_m must be finite and positive",
            Self::ApproachSpeed => "approach_speed_m_s must be in (0, 1] m/s",
            Self::ApproachTimeout => "approach_timeout_s must be finite and ≥ 0 s",
        })
    }
}

impl core::error::Error for RouteOptionsError {}

/// [`RouteOptions`] as plain numbers, as a robot file or a link message
/// gives them; [`RouteOptionsSpec::build`] checks them.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct RouteOptionsSpec {
    /// The pivot's heading gain `k_θ`, 1/s, in `(0, 1000]`.
    pub pivot_gain_per_s: f32,
    /// A stop's position tolerance, m, finite and `> 0`.
    pub position_tolerance_m: f32,
    /// A stop's heading tolerance, rad, finite and `> 0`.
    pub heading_tolerance_rad: f32,
    /// How far the robot may lag the moving reference along the path
    /// before the route's clock waits for it, m, finite and `> 0`.
    pub max_lag_m: f32,
    /// The arrival approach's largest speed, m/s, in `(0, 1]`.
    pub approach_speed_m_s: f32,
    /// The longest arrival approach, s, finite and `≥ 0` (0: none).
    pub approach_timeout_s: f32,
}

impl Default for RouteOptionsSpec {
    fn default() -> Self {
        RouteOptions::default().spec()
    }
}

impl RouteOptionsSpec {
    /// The validated options.
    ///
    /// # Errors
    /// The first field out of its range ([`RouteOptionsError::field`]).
    pub fn build(&self) -> Result<RouteOptions, RouteOptionsError> {
        RouteOptions::new(self)
    }
}

/// How a route is followed: the pivot gain, the stop tolerances, how far
/// the clock lets the robot lag, and the arrival approach; each checked
/// once (module documentation, "The route's clock" and "At rest").
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RouteOptions {
    spec: RouteOptionsSpec,
}

impl Default for RouteOptions {
    fn default() -> Self {
        Self {
            spec: RouteOptionsSpec {
                pivot_gain_per_s: Self::DEFAULT_PIVOT_GAIN_PER_S,
                position_tolerance_m: Self::DEFAULT_POSITION_TOLERANCE_M,
                heading_tolerance_rad: Self::DEFAULT_HEADING_TOLERANCE_RAD,
                max_lag_m: Self::DEFAULT_MAX_LAG_M,
                approach_speed_m_s: Self::DEFAULT_APPROACH_SPEED_M_S,
                approach_timeout_s: Self::DEFAULT_APPROACH_TIMEOUT_S,
            },
        }
    }
}

impl RouteOptions {
    /// Default `k_θ`, 1/s: a heading error decays with a 0.2 s time
    /// constant, well inside a pivot's ramps at 1 rad/s² and 1 rad/s, and
    /// `k_θ·h = 0.05` at 100 Hz (a tenth of the stability limit `k_θ h <
    /// 2` of `e⁺ = (1 − k_θ h)·e`).
    pub const DEFAULT_PIVOT_GAIN_PER_S: f32 = 5.0;
    /// Default stop position tolerance, m (the product goal, 1 cm).
    pub const DEFAULT_POSITION_TOLERANCE_M: f32 = 0.01;
    /// Default stop heading tolerance, rad (the product goal, 1°).
    pub const DEFAULT_HEADING_TOLERANCE_RAD: f32 = core::f32::consts::PI / 180.0;
    /// Default largest lag behind the moving reference, m: a robot further
    /// behind is waited for.
    pub const DEFAULT_MAX_LAG_M: f32 = 0.05;
    /// Default arrival approach speed cap, m/s.
    pub const DEFAULT_APPROACH_SPEED_M_S: f32 = 0.05;
    /// Default longest arrival approach, s.
    pub const DEFAULT_APPROACH_TIMEOUT_S: f32 = 5.0;

    /// Options from `spec`.
    ///
    /// # Errors
    /// The first field out of its range, in the order of
    /// [`RouteOptionsSpec`]'s fields.
    pub fn new(spec: &RouteOptionsSpec) -> Result<Self, RouteOptionsError> {
        let gain = spec.pivot_gain_per_s;
        if !(gain > 0.0 && gain <= 1000.0) {
            return Err(RouteOptionsError::PivotGain);
        }
        let positive = |x: f32| x.is_finite() && x > 0.0;
        if !(positive(spec.position_tolerance_m) && positive(spec.heading_tolerance_rad)) {
            return Err(RouteOptionsError::Tolerance);
        }
        if !positive(spec.max_lag_m) {
            return Err(RouteOptionsError::MaxLag);
        }
        if !(spec.approach_speed_m_s > 0.0 && spec.approach_speed_m_s <= 1.0) {
            return Err(RouteOptionsError::ApproachSpeed);
        }
        if !(spec.approach_timeout_s.is_finite() && spec.approach_timeout_s >= 0.0) {
            return Err(RouteOptionsError::ApproachTimeout);
        }
        Ok(Self { spec: *spec })
    }

    /// The numbers, as [`RouteOptionsSpec`].
    #[must_use]
    pub fn spec(&self) -> RouteOptionsSpec {
        self.spec
    }

    /// The pivot's heading gain `k_θ`, 1/s.
    #[must_use]
    pub fn pivot_gain_per_s(&self) -> f32 {
        self.spec.pivot_gain_per_s
    }

    /// The stop position tolerance, m.
    #[must_use]
    pub fn position_tolerance_m(&self) -> f32 {
        self.spec.position_tolerance_m
    }

    /// The stop heading tolerance, rad.
    #[must_use]
    pub fn heading_tolerance_rad(&self) -> f32 {
        self.spec.heading_tolerance_rad
    }

    /// The largest lag behind the moving reference before the clock
    /// waits, m.
    #[must_use]
    pub fn max_lag_m(&self) -> f32 {
        self.spec.max_lag_m
    }

    /// The arrival approach's speed cap, m/s.
    #[must_use]
    pub fn approach_speed_m_s(&self) -> f32 {
        self.spec.approach_speed_m_s
    }

    /// The longest arrival approach, s.
    #[must_use]
    pub fn approach_timeout_s(&self) -> f32 {
        self.spec.approach_timeout_s
    }
}

/// Counters of a [`RouteFollower`] since it was made.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct RouteCounters {
    /// Stops at which the robot settled (once per stop).
    pub stops_reached: u32,
    /// Stops whose error at a settle exceeded the tolerances (once per stop).
    pub stop_errors: u32,
    /// Pivot segments turned (once each).
    pub pivots: u32,
    /// Pivot ticks run open loop (`ω = ω_r`: no heading estimate).
    pub open_loop_pivot_ticks: u32,
    /// Routes planned and started (replacements included).
    pub routes_started: u32,
    /// Routes the planner refused.
    pub routes_refused: u32,
    /// Routes finished: at rest on their last waypoint, settled.
    pub routes_done: u32,
    /// Ticks the route's clock waited for a robot lagging the moving
    /// reference by more than [`RouteOptions::max_lag_m`].
    pub clock_wait_ticks: u32,
    /// Ticks of arrival approach (the robot driven onto a stop it reached
    /// short or long) and of departure alignment (turned onto the next
    /// leg before leaving), the route's clock standing.
    pub approach_ticks: u32,
    /// Arrival approaches ended by [`RouteOptions::approach_timeout_s`]
    /// rather than by arriving.
    pub approach_timeouts: u32,
}

/// A stop's error at a settle, as the estimator knows it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StopError {
    /// Distance of the estimated position from the stop, m.
    pub position_m: f32,
    /// `|wrap(θ̂ − θ_hold)|`, rad, where the reference holds a heading and
    /// the estimator has one.
    pub heading_rad: Option<f32>,
}

/// Where a [`RouteFollower`] is.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RouteStatus {
    /// A route is planned and being followed (or done and held).
    pub running: bool,
    /// The route rests on its last waypoint and the robot has settled
    /// there (its command exactly zero).
    pub done: bool,
    /// This tick's command was a settled hold, exactly zero: at a stop
    /// (or the end) once the ramp reached zero, or held with no route
    /// running. [`super::Pilot::step_route`] then also zeroes the motors
    /// once the drive's wheel targets are zero.
    pub holding: bool,
    /// The running route's reference mode this tick.
    pub mode: Option<RouteMode>,
    /// Ticks the running route has been followed.
    pub elapsed_ticks: u32,
    /// A loaded route waits to start (for a position, or for the running
    /// route's next rest).
    pub pending: bool,
    /// Why the last loaded route was refused, until one is accepted.
    pub refused: Option<RouteError>,
    /// The error at the last settle.
    pub last_stop: Option<StopError>,
}

/// What the tracker does this tick on a route.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Steer {
    /// The law, on the reference (`restart`: first tick after a rest).
    Law { restart: bool },
    /// Ramp the command to zero, then hold it at exactly zero.
    Hold,
    /// This body command: a pivot in place, the tangent hold below
    /// [`SLOW_SPEED_M_S`], or an arrival approach.
    Body(BodyVelocity),
}

/// A route waiting for its tick.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Pending {
    waypoints: Waypoints,
    limits: RouteLimits,
    start: RouteStart,
}

/// The stop (rest phase) the reference is in.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct Rest {
    settled: bool,
    reached: bool,
    error_counted: bool,
    pivot_segment: Option<u16>,
}

/// A route's storage and progress: the plan (planned in place), its
/// cursor and clock, a route waiting to replace it, the counters. Owned by
/// the caller and lent to the tracker each tick (module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct RouteFollower {
    options: RouteOptions,
    plan: RoutePlan,
    cursor: RouteCursor,
    running: bool,
    elapsed_ticks: u32,
    pending: Option<Pending>,
    /// Where the robot is held with no route running (after a refusal).
    hold_at: Option<Vec2>,
    /// The reference's rest point and the heading it holds there, where
    /// a replacement starts.
    rest_point: Option<(Vec2, Option<f32>)>,
    rest: Option<Rest>,
    sample: Option<RouteSample>,
    done: bool,
    holding: bool,
    /// The last tick was slow (below [`SLOW_SPEED_M_S`]): the law restarts.
    was_slow: bool,
    /// The reference has moved since the last rest: the next rest is an
    /// arrival, approached before the clock goes on.
    arriving: bool,
    /// Ticks of the current arrival approach.
    approach_ticks: u32,
    /// The reference has just left a rest (or the route started): the
    /// robot is turned onto the leg's direction first.
    departing: bool,
    /// A first route as given: the robot is driven onto its first waypoint
    /// before the clock starts.
    starting: bool,
    /// The running route's pivot rate, rad/s: the largest turn rate of the
    /// tangent hold and the arrival approach too.
    turn_rate_rad_s: f32,

    refused: Option<RouteError>,
    last_stop: Option<StopError>,
    counters: RouteCounters,
}

impl RouteFollower {
    /// No route yet; loads are followed with `options`. Build it where it
    /// is to stay (about 22 KB).
    #[must_use]
    pub const fn new(options: RouteOptions) -> Self {
        Self {
            options,
            plan: RoutePlan::empty(),
            cursor: RouteCursor::new(),
            running: false,
            elapsed_ticks: 0,
            pending: None,
            hold_at: None,
            rest_point: None,
            rest: None,
            sample: None,
            done: false,
            holding: false,
            was_slow: false,
            arriving: false,
            approach_ticks: 0,
            departing: false,
            starting: false,
            turn_rate_rad_s: 0.0,
            refused: None,
            last_stop: None,
            counters: RouteCounters {
                stops_reached: 0,
                stop_errors: 0,
                pivots: 0,
                open_loop_pivot_ticks: 0,
                routes_started: 0,
                routes_refused: 0,
                routes_done: 0,
                clock_wait_ticks: 0,
                approach_ticks: 0,
                approach_timeouts: 0,
            },
        }
    }

    /// Queues `waypoints` under `limits` to start at the next tick
    /// boundary where it can (module documentation, "Loading and
    /// replacing a route"); planned by the step that starts it, which
    /// reports a refusal in [`RouteStatus::refused`].
    pub fn load(&mut self, waypoints: &Waypoints, limits: &RouteLimits, start: RouteStart) {
        self.pending = Some(Pending {
            waypoints: *waypoints,
            limits: *limits,
            start,
        });
    }

    /// The options.
    #[must_use]
    pub fn options(&self) -> &RouteOptions {
        &self.options
    }

    /// The running plan (empty before a route has started).
    #[must_use]
    pub fn plan(&self) -> &RoutePlan {
        &self.plan
    }

    /// Counters since the follower was made.
    #[must_use]
    pub fn counters(&self) -> RouteCounters {
        self.counters
    }

    /// Where the follower is, after the last step.
    #[must_use]
    pub fn status(&self) -> RouteStatus {
        RouteStatus {
            running: self.running,
            done: self.done,
            holding: self.holding,
            mode: self.sample.map(|s| s.mode),
            elapsed_ticks: self.elapsed_ticks,
            pending: self.pending.is_some(),
            refused: self.refused,
            last_stop: self.last_stop,
        }
    }

    /// [`RouteStatus::holding`], alone.
    pub(crate) fn is_holding(&self) -> bool {
        self.holding
    }

    /// A loaded route waits to start.
    pub(crate) fn is_pending(&self) -> bool {
        self.pending.is_some()
    }

    /// Starts a loaded route if it may start this tick (module
    /// documentation, "Loading and replacing a route"). `tracking`: the
    /// tracker drives this tick. Returns the heading the estimator is to
    /// take as known, rad, where the route starts with
    /// [`RouteStart::AsGivenHeadingKnown`].
    pub(crate) fn start(
        &mut self,
        tracking: bool,
        position: Option<Vec2>,
        heading: HeadingEstimate,
        period_s: f32,
    ) -> Option<f32> {
        if tracking {
            self.start_pending(position, heading, period_s)
        } else {
            None
        }
    }

    /// The tick's reference and what to do with it. `tracking`: the
    /// tracker drives this tick (it has a position and the fix is not
    /// lost); the route's clock advances only then, and only when the
    /// robot does not lag the moving reference by more than
    /// [`RouteOptions::max_lag_m`] and is not being driven onto a stop it
    /// has reached short or long (module documentation, "The route's
    /// clock").
    pub(crate) fn begin(
        &mut self,
        tracking: bool,
        position: Option<Vec2>,
        heading: HeadingEstimate,
        period_s: f32,
    ) -> (ReferenceSample, Steer) {
        if !self.running {
            let at = self.hold_at.or(position).unwrap_or(Vec2::ZERO);
            if tracking {
                self.hold_at = Some(at);
            }
            return (at_rest(at), Steer::Hold);
        }
        let sample = self.plan.sample(&mut self.cursor, self.elapsed_ticks);
        self.sample = Some(sample);
        let mut advance = tracking;
        // An arrival (a rest after moving, or the route's start) is
        // approached first, the clock standing.
        let moving = matches!(sample.mode, RouteMode::Moving { .. });
        if self.starting || (self.arriving && !moving) {
            let target = sample.reference.position;
            match self.approach(target, position, heading, period_s, tracking) {
                Some(command) => return (sample.reference, Steer::Body(command)),
                None => {
                    self.starting = false;
                    self.arriving = false;
                    self.approach_ticks = 0;
                }
            }
        }
        let steer = match sample.mode {
            RouteMode::Moving { .. } => {
                self.rest_point = None;
                self.arriving = true;
                let left_rest = self.rest.take().is_some();
                if left_rest {
                    self.departing = true;
                    self.approach_ticks = 0;
                }
                if self.departing {
                    match self.align(&sample.reference, heading, period_s, tracking) {
                        Some(command) => return (sample.reference, Steer::Body(command)),
                        None => {
                            self.departing = false;
                            self.approach_ticks = 0;
                        }
                    }
                }
                match self.slow(&sample.reference, heading, period_s) {
                    Some(command) => {
                        self.was_slow = true;
                        Steer::Body(command)
                    }
                    None => {
                        let restart = left_rest || self.was_slow;
                        self.was_slow = false;
                        // Only where the law steers onto the reference:
                        // the tangent hold (leaving a rest) has no
                        // position feedback to catch up with.
                        if tracking && self.lags(&sample.reference, position) {
                            advance = false;
                            self.counters.clock_wait_ticks =
                                self.counters.clock_wait_ticks.saturating_add(1);
                        }
                        Steer::Law { restart }
                    }
                }
            }
            RouteMode::Stopped { .. } | RouteMode::Pivoting { .. } => {
                self.at_rest(sample, heading, period_s, tracking)
            }
        };
        if advance {
            self.elapsed_ticks = self.elapsed_ticks.saturating_add(1);
        }
        (sample.reference, steer)
    }

    /// What to do on a rest segment once arrived: hold, or pivot.
    fn at_rest(
        &mut self,
        sample: RouteSample,
        heading: HeadingEstimate,
        period_s: f32,
        tracking: bool,
    ) -> Steer {
        match sample.mode {
            RouteMode::Pivoting {
                heading_rad,
                rate_rad_s,
                ..
            } => {
                self.rest_point = None;
                let segment = self.cursor.segment_index();
                let rest = self.rest.get_or_insert_with(Rest::default);
                rest.settled = false;
                if tracking && rest.pivot_segment != Some(segment) {
                    rest.pivot_segment = Some(segment);
                    self.counters.pivots = self.counters.pivots.saturating_add(1);
                }
                Steer::Body(self.pivot(heading_rad, rate_rad_s, heading, period_s, tracking))
            }
            RouteMode::Stopped { hold_heading_rad } => {
                self.rest_point = Some((sample.reference.position, hold_heading_rad));
                self.rest.get_or_insert_with(Rest::default);
                Steer::Hold
            }
            RouteMode::Moving { .. } => Steer::Hold,
        }
    }

    /// Whether the robot at `position` lags the moving reference by more
    /// than [`RouteOptions::max_lag_m`] along the reference's velocity (a
    /// robot beside or ahead of it is not waited for: waiting would not
    /// bring it closer).
    fn lags(&self, reference: &ReferenceSample, position: Option<Vec2>) -> bool {
        let Some(position) = position else {
            return false;
        };
        // `(p_r − p̂)·v > L·|v|`, squared (no root, no division per tick):
        // both sides positive, so it holds exactly where the unsquared
        // form does; a NaN makes it false.
        let ahead = (reference.position - position).dot(reference.velocity);
        let limit = self.options.max_lag_m();
        ahead > 0.0 && ahead * ahead > limit * limit * reference.velocity.dot(reference.velocity)
    }

    /// The arrival approach onto the rest point `target` (module
    /// documentation, "At rest"): `None` once arrived (or with no heading
    /// or position to approach with, or timed out: counted), else the
    /// command. With `d` the distance to the point and `e_∥` its component
    /// along the robot's heading: within the near radius
    /// ([`NEAR_OF_TOLERANCE`] of the position tolerance) the robot creeps
    /// along its heading, `v = sat(k_a·e_∥)`, `ω = 0`, and has arrived once
    /// `|e_∥|` is within [`ARRIVAL_BAND_OF_TOLERANCE`] of the tolerance;
    /// beyond it, it turns toward the point (or away from it, backing
    /// up, whichever is the smaller turn), `ω = k_θ·e_β`, and drives as far
    /// as it faces it, `v = ±sat(k_a·d·cos e_β)`. Both under
    /// [`RouteOptions::approach_speed_m_s`].
    fn approach(
        &mut self,
        target: Vec2,
        position: Option<Vec2>,
        heading: HeadingEstimate,
        period_s: f32,
        tracking: bool,
    ) -> Option<BodyVelocity> {
        let position = position?;
        let estimate = heading_rad(heading)?;
        let tolerance = self.options.position_tolerance_m();
        let (sin_theta, cos_theta) = math::sincos(estimate);
        let to_target = target - position;
        let distance = to_target.norm();
        let along = to_target.dot(Vec2::new(cos_theta, sin_theta));
        // A non-finite distance or along-heading error: nothing to steer
        // by, taken as arrived.
        if !(distance.is_finite() && along.is_finite()) {
            return None;
        }
        let near = distance <= NEAR_OF_TOLERANCE * tolerance;
        if near && along.abs() <= ARRIVAL_BAND_OF_TOLERANCE * tolerance {
            return None;
        }
        if !self.approach_tick(period_s, tracking) {
            return None;
        }
        let cap = self.options.approach_speed_m_s();
        if near {
            return Some(BodyVelocity {
                v_m_s: (APPROACH_GAIN_PER_S * along).max(-cap).min(cap),
                omega_rad_s: 0.0,
            });
        }
        let bearing = math::wrap_angle(math::atan2(to_target.y, to_target.x) - estimate);
        // Facing away from it: back up to it instead.
        let (turn, direction) = if bearing.abs() > core::f32::consts::FRAC_PI_2 {
            (math::wrap_angle(bearing + core::f32::consts::PI), -1.0)
        } else {
            (bearing, 1.0)
        };
        let gain = self.heading_gain(period_s);
        // Turn first: drive only once facing the point within
        // `DEPARTURE_ALIGN_RAD` (the same alignment as leaving a rest).
        let speed = if turn.abs() <= DEPARTURE_ALIGN_RAD {
            (APPROACH_GAIN_PER_S * distance * math::cos(turn))
                .max(0.0)
                .min(cap)
        } else {
            0.0
        };
        Some(BodyVelocity {
            v_m_s: direction * speed,
            omega_rad_s: self.turn_rate(gain * turn),
        })
    }

    /// The departure alignment: where the reference leaves a rest and the
    /// estimated heading is more than [`DEPARTURE_ALIGN_RAD`] off the
    /// leg's direction `θ_t` (the reference velocity's, or its
    /// acceleration's at rest), the robot turns in place, `v = 0`, `ω =
    /// k_θ·wrap(θ_t − θ̂)` within the route's pivot rate, the clock
    /// standing (counted in [`RouteCounters::approach_ticks`]); `None` once
    /// aligned, with no heading or direction to align with, or after
    /// [`RouteOptions::approach_timeout_s`] (counted).
    fn align(
        &mut self,
        reference: &ReferenceSample,
        heading: HeadingEstimate,
        period_s: f32,
        tracking: bool,
    ) -> Option<BodyVelocity> {
        let estimate = heading_rad(heading)?;
        let error = math::wrap_angle(leg_direction(reference)? - estimate);
        if error.abs() <= DEPARTURE_ALIGN_RAD || error.is_nan() {
            return None;
        }
        if !self.approach_tick(period_s, tracking) {
            return None;
        }
        let gain = self.heading_gain(period_s);
        Some(BodyVelocity {
            v_m_s: 0.0,
            omega_rad_s: self.turn_rate(gain * error),
        })
    }

    /// One more tick of the current approach or alignment (counted while
    /// `tracking`); `false` once it has lasted
    /// [`RouteOptions::approach_timeout_s`] (the timeout counted).
    fn approach_tick(&mut self, period_s: f32, tracking: bool) -> bool {
        if self.approach_ticks as f32 * period_s >= self.options.approach_timeout_s() {
            self.counters.approach_timeouts = self.counters.approach_timeouts.saturating_add(1);
            return false;
        }
        if tracking {
            self.approach_ticks = self.approach_ticks.saturating_add(1);
            self.counters.approach_ticks = self.counters.approach_ticks.saturating_add(1);
        }
        true
    }

    /// The heading gain `k_θ`, capped at `1/h` so that one tick never turns
    /// past the reference (`e⁺ = (1 − k_θ h)·e`).
    fn heading_gain(&self, period_s: f32) -> f32 {
        self.options.pivot_gain_per_s().min(1.0 / period_s)
    }

    /// `omega` within the route's pivot rate (a NaN stays NaN: the
    /// tracker zeroes a non-finite command).
    fn turn_rate(&self, omega: f32) -> f32 {
        let cap = self.turn_rate_rad_s;
        if omega > cap {
            cap
        } else if omega < -cap {
            -cap
        } else {
            omega
        }
    }

    /// After the tracker's command: a hold that reached exactly zero has
    /// settled (counted, its error measured, the route done at its end).
    pub(crate) fn end(
        &mut self,
        tracking: bool,
        command: BodyVelocity,
        position: Option<Vec2>,
        heading: HeadingEstimate,
    ) {
        let at_zero = || command.v_m_s == 0.0 && command.omega_rad_s == 0.0;
        self.holding = false;
        // Read in place: moving on a leg (the common tick) ends here.
        let sample = match &self.sample {
            Some(sample) if self.running => sample,
            _ => {
                self.holding = tracking && at_zero();
                return;
            }
        };
        let RouteMode::Stopped { hold_heading_rad } = sample.mode else {
            return;
        };
        let sample = *sample;
        let (Some(rest), Some(position)) = (self.rest.as_mut(), position) else {
            return;
        };
        if !(tracking && at_zero()) {
            return;
        }
        self.holding = true;
        if sample.done && !self.done {
            self.done = true;
            self.counters.routes_done = self.counters.routes_done.saturating_add(1);
        }
        if rest.settled {
            return;
        }
        rest.settled = true;
        let heading_error = hold_heading_rad
            .zip(heading_rad(heading))
            .map(|(hold, estimate)| math::wrap_angle(estimate - hold).abs());
        let error = StopError {
            position_m: (position - sample.reference.position).norm(),
            heading_rad: heading_error,
        };
        self.last_stop = Some(error);
        if !rest.reached {
            rest.reached = true;
            self.counters.stops_reached = self.counters.stops_reached.saturating_add(1);
        }
        // Not within: a NaN error counts too.
        let within = |e: f32, tolerance: f32| e <= tolerance;
        let beyond = !within(error.position_m, self.options.position_tolerance_m())
            || error
                .heading_rad
                .is_some_and(|e| !within(e, self.options.heading_tolerance_rad()));
        if beyond && !rest.error_counted {
            rest.error_counted = true;
            self.counters.stop_errors = self.counters.stop_errors.saturating_add(1);
        }
    }

    /// Below [`SLOW_SPEED_M_S`] (leaving or reaching a rest), where the
    /// estimator has a heading: `v = v_r·cos e`, `ω = k_θ·e` (within the
    /// route's pivot rate) with `e =
    /// wrap(θ_t − θ̂)` toward the path's tangent `θ_t` (the reference
    /// velocity's direction, or its acceleration's at rest); `None` to
    /// leave it to the law.
    fn slow(
        &self,
        reference: &ReferenceSample,
        heading: HeadingEstimate,
        period_s: f32,
    ) -> Option<BodyVelocity> {
        // Moving on a leg (the common tick): the squared speed, without
        // the root, tells it for certain (see `CERTAINLY_NOT_SLOW_M2_S2`).
        let speed_sq = reference.velocity.dot(reference.velocity);
        if speed_sq > CERTAINLY_NOT_SLOW_M2_S2 {
            return None;
        }
        let speed = reference.velocity.norm();
        if speed.is_nan() || speed >= SLOW_SPEED_M_S {
            return None;
        }
        let estimate = heading_rad(heading)?;
        let error = math::wrap_angle(leg_direction(reference)? - estimate);
        let gain = self.heading_gain(period_s);
        Some(BodyVelocity {
            v_m_s: speed * math::cos(error),
            omega_rad_s: self.turn_rate(gain * error),
        })
    }

    /// `v = 0`, `ω = ω_r + k_θ·wrap(θ_r − θ̂)`, or `ω_r` open loop.
    fn pivot(
        &mut self,
        heading_rad_r: f32,
        rate_rad_s: f32,
        heading: HeadingEstimate,
        period_s: f32,
        tracking: bool,
    ) -> BodyVelocity {
        let omega = match heading_rad(heading) {
            Some(estimate) => {
                let gain = self.heading_gain(period_s);
                rate_rad_s + gain * math::wrap_angle(heading_rad_r - estimate)
            }
            None => {
                if tracking {
                    self.counters.open_loop_pivot_ticks =
                        self.counters.open_loop_pivot_ticks.saturating_add(1);
                }
                rate_rad_s
            }
        };
        BodyVelocity {
            v_m_s: 0.0,
            omega_rad_s: omega,
        }
    }

    /// Plans the pending route if it may start now.
    /// The heading the estimator is to take as known, where the route
    /// starts with [`RouteStart::AsGivenHeadingKnown`].
    fn start_pending(
        &mut self,
        position: Option<Vec2>,
        heading: HeadingEstimate,
        period_s: f32,
    ) -> Option<f32> {
        let start = self.pending.as_ref().map(|p| p.start)?;
        // A replacement starts where the running reference rests; the
        // first route where it is loaded or where the robot is.
        let estimated = heading_rad(heading);
        let from = if self.running {
            match self.rest_point {
                Some((at, held)) => Some((at, held.or(estimated))),
                None => return None,
            }
        } else if let Some(at) = self.hold_at.filter(|_| self.counters.routes_started > 0) {
            Some((at, estimated))
        } else {
            match start {
                RouteStart::AsGiven | RouteStart::AsGivenHeadingKnown => None,
                RouteStart::FromFirstFix => match position {
                    Some(at) => Some((at, estimated)),
                    None => return None,
                },
            }
        };
        let hold = from.map(|(at, _)| at).or(self.hold_at).or(position);
        self.cursor = RouteCursor::new();
        self.elapsed_ticks = 0;
        self.rest = None;
        self.rest_point = None;
        self.sample = None;
        self.done = false;
        // A first route as given starts with an approach to its first
        // waypoint; a route from the first fix, or replacing one, starts
        // where the robot is.
        self.starting = from.is_none();
        self.arriving = false;
        self.approach_ticks = 0;
        self.departing = true;
        let known_start = from.is_none() && start == RouteStart::AsGivenHeadingKnown;
        // Changed and planned where it is (1.8 KB of waypoints, 20 KB of
        // plan): no copy on the stack.
        let pending = self.pending.as_mut()?;
        self.turn_rate_rad_s = pending.limits.pivot_rate_rad_s();
        if let (Some(first), Some((at, facing))) =
            (pending.waypoints.as_mut_slice().first_mut(), from)
        {
            first.position_m = at;
            if let Some(facing) = facing {
                let dwell_s = first.stop.map_or(0.0, |stop| stop.dwell_s);
                first.stop = Some(Stop {
                    dwell_s,
                    face_heading_rad: Some(facing),
                });
            }
        }
        let planned = self
            .plan
            .replan(pending.waypoints.as_slice(), &pending.limits, period_s);
        let facing = known_start
            .then(|| start_heading(pending.waypoints.as_slice()))
            .flatten();
        self.pending = None;
        match planned {
            Ok(()) => {
                self.running = true;
                self.refused = None;
                self.hold_at = None;
                self.counters.routes_started = self.counters.routes_started.saturating_add(1);
                facing
            }
            Err(e) => {
                self.running = false;
                self.refused = Some(e);
                self.hold_at = hold;
                self.counters.routes_refused = self.counters.routes_refused.saturating_add(1);
                None
            }
        }
    }
}

/// The estimate's heading, rad, if it is finite and long enough to mean one.
fn heading_rad(heading: HeadingEstimate) -> Option<f32> {
    let (c, s) = (heading.cos_theta, heading.sin_theta);
    let norm = math::hypot(c, s);
    (norm.is_finite() && norm >= MIN_HEADING_NORM).then(|| math::atan2(s, c))
}

/// The heading the planner takes the robot to face at the first waypoint:
/// its heading to face, else the first leg's direction, rad.
fn start_heading(waypoints: &[Waypoint]) -> Option<f32> {
    let first = waypoints.first()?;
    if let Some(facing) = first.stop.and_then(|stop| stop.face_heading_rad) {
        return Some(facing);
    }
    let leg = waypoints.get(1)?.position_m - first.position_m;
    (leg != Vec2::ZERO && leg.is_finite()).then(|| math::atan2(leg.y, leg.x))
}

/// The path's direction at `reference`, rad: its velocity's, or at rest
/// its acceleration's (the way it leaves); `None` where neither gives one.
fn leg_direction(reference: &ReferenceSample) -> Option<f32> {
    let tangent = if reference.velocity == Vec2::ZERO {
        reference.acceleration
    } else {
        reference.velocity
    };
    (tangent != Vec2::ZERO && tangent.is_finite()).then(|| math::atan2(tangent.y, tangent.x))
}

/// A reference at rest at `at`.
fn at_rest(at: Vec2) -> ReferenceSample {
    ReferenceSample {
        position: at,
        velocity: Vec2::ZERO,
        acceleration: Vec2::ZERO,
    }
}

#[cfg(test)]
mod arrival_tests;
#[cfg(test)]
mod tests;
