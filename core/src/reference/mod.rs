//! Reference trajectories evaluated from an integer tick count.
//!
//! Time is never accumulated as `t += h` in `f32` (over 480 s at 1 kHz that
//! drifts by seconds, paper-001 slip 8): a [`TickClock`] turns the integer
//! tick index `k` into `t = k·h` afresh at every tick, so the rounding error
//! of `t` is one `f32` rounding (relative 6e-8), never a sum of them.
//!
//! # Time on long runs
//!
//! Relative 6e-8 is not enough for a robot that runs for weeks: on day 30
//! at 100 Hz (`k = 2.6e8`) `k as f32` is a multiple of 16 ticks, and the
//! paper's figure-eight sampled at `t = k·h` is 82 mm off its exact point
//! (against `f64`; 8 µm in its first period). The tracker therefore
//! samples through a [`ReferenceClock`]:
//!
//! * **Convention.** A periodic reference's angle is `s = ω·t + φ` (the
//!   figure-eight's `h2·t + φ`, a circle's `ω·t + φ`, `ω` signed); its
//!   period is `T = 2π/|ω|`. Time `t` is in seconds since the trajectory
//!   started (tick 0), tick `k` at `t = k·h`. Sampling at `t` and at
//!   `t − m·5T` gives the same point, velocity and acceleration.
//! * **Method.** The time is reduced modulo an *epoch* of
//!   [`EPOCH_TURNS`] = 5 periods (`5T`, an angle of `10π`) in integer
//!   arithmetic before any `f32` time is formed. The epochs per tick,
//!   `q = |ω|·h / 10π`, are held as a 64-bit fraction (units of `2⁻⁶⁴`
//!   epoch), computed once on the robot from the exact 48-bit product of
//!   the two `f32` mantissas times a 64-bit constant `2⁶⁸/10π`, in
//!   integers (no `f64`). Each tick adds `q` to the epoch phase
//!   (`u64`, exact modular arithmetic, [`ReferenceClock::next`]); a carry
//!   starts an epoch, whose first tick lies `δ = phase/q` ticks (`f32`,
//!   below one tick) past the epoch's start. The sampled time is
//!   `(w + δ)·h`, `w` the whole ticks since the epoch's first tick:
//!   `k·h` exactly, bit for bit as [`TickClock::time_s`], through the
//!   first five turns (the 480 s paper figure-eight is 1.5 turns, every
//!   scenario of the simulator is within 3.2: each samples at `k·h`).
//!   The phase does not depend on the caller's `u32` tick count, so it
//!   goes on past its wrap (497 days at 100 Hz);
//!   [`ReferenceClock::at_tick`] gives any tick's time directly (the
//!   same bits as stepping there).
//! * **Error.** `q`'s rounding (≤ 1.5 units of `2⁻⁶⁴`) drifts the angle
//!   by at most `k·1.5·10π·2⁻⁶⁴ = k·2.6e-18` rad: 7e-10 rad on day 30 at
//!   100 Hz, 1.1e-8 rad at the `u32` wrap. Within an epoch the error is
//!   `f32`'s, as in the first five turns: the time's roundings (relative
//!   1.2e-7) and `ω·t + φ`'s (an angle below `10π + |φ|`, resolved to
//!   2 µrad for `|φ| ≤ π`), each below 6e-6 rad, plus `δ`'s (relative
//!   2e-7 of under a tick). Measured against `f64` over a period
//!   (`clock_tests`): the paper's figure-eight 7.7 µm in its first period
//!   and 10 µm on day 30; a 2 m circle at 0.1 rad/s 4.8 µm on day 30, a
//!   10 m one at 1 rad/s (h = 1 ms) 44 µm; within 1 mm across the `u32`
//!   wrap and at `2⁴⁰` ticks. Five turns rather than one keep the
//!   existing runs bit for bit at that cost: one turn would bound the
//!   angle by `2π + |φ|` (about 5 times finer) and change every run
//!   longer than a turn in its last bits.
//! * **The line** has no period: its point is `start + v·t`, `t = k·h`
//!   from the whole ticks since it started (`u64`, past the `u32` wrap),
//!   computed relative to its start. Its error grows with the distance
//!   run, `d`: `t`'s rounding (relative 1.2e-7 of `d`) plus the `f32`
//!   coordinate's (0.5 mm at 8 km from the origin, 1 mm at 16 km).
//!   Measured: 0.33 mm over its first 4 km (0.2 m/s for 5.5 h). That is
//!   a documented limit, not a refusal: a line leaves the plausible
//!   floor ([`crate::plausible::COORDINATE_M`], 10 km on an axis) long
//!   before its time matters, and a robot on it has left any real floor
//!   and lost its tag fixes (the tracker's failsafe stops it); its
//!   samples stay finite for any tick.
//!
//! Each trajectory gives position, velocity and acceleration (paper 001,
//! Assumption 1 needs `ẋr, ẏr` and bounded `ẍr, ÿr`; the corrected `θ̇*` of
//! (14)/(28) uses the accelerations) and the bounds `v_rm ≤ v_r ≤ v_rM` of
//! (2) that the gain bound (15) is checked against.
//!
//! [`route`] adds routes through waypoints (lines, clothoid corner
//! blends, stops and pivots), sampled from integer ticks.

mod clock;
pub mod route;

pub use clock::{EPOCH_TURNS, ReferenceClock, ReferenceTime};

use crate::geometry::Vec2;
use crate::math;
use crate::plausible::{
    ANGLE_RAD, COORDINATE_M, PERIOD_S, REFERENCE_RATE_RAD_S, REFERENCE_SIZE_M, REFERENCE_SPEED_M_S,
};

/// Why a clock or trajectory was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum ReferenceError {
    /// Control period outside [`PERIOD_S`].
    Period,
    /// Amplitude / radius outside [`REFERENCE_SIZE_M`].
    Size,
    /// Angular rate (its magnitude) outside [`REFERENCE_RATE_RAD_S`], or a
    /// line's speed outside [`REFERENCE_SPEED_M_S`].
    Rate,
    /// Centre or start point outside [`COORDINATE_M`] on an axis, or phase
    /// or direction outside [`ANGLE_RAD`].
    Placement,
}

impl core::fmt::Display for ReferenceError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Period => write!(f, "period_s must be in {PERIOD_S} s"),
            Self::Size => write!(
                f,
                "the amplitude h1_m or radius_m must be in {REFERENCE_SIZE_M} m"
            ),
            Self::Rate => write!(
                f,
                "the angular rate (h2_rad_s, |rate_rad_s|) must be in {REFERENCE_RATE_RAD_S} rad/s, \
                 a line's speed_m_s in {REFERENCE_SPEED_M_S} m/s"
            ),
            Self::Placement => write!(
                f,
                "center_m and start_m must be in {COORDINATE_M} m on each axis, \
                 phase_rad and heading_rad in {ANGLE_RAD} rad"
            ),
        }
    }
}

impl core::error::Error for ReferenceError {}

/// Whether both coordinates of `p` lie in [`COORDINATE_M`].
fn on_the_floor(p: Vec2) -> bool {
    COORDINATE_M.contains(p.x) && COORDINATE_M.contains(p.y)
}

/// Converts the integer tick index into seconds: `t = k·h` (for a long
/// run, a periodic reference is sampled through a [`ReferenceClock`]:
/// module documentation, "Time on long runs").
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TickClock {
    period_s: f32,
}

impl TickClock {
    /// A clock with a fixed period (the control step `h`), s.
    ///
    /// # Errors
    /// [`ReferenceError::Period`] outside [`PERIOD_S`].
    pub fn new(period_s: f32) -> Result<Self, ReferenceError> {
        if PERIOD_S.contains(period_s) {
            Ok(Self { period_s })
        } else {
            Err(ReferenceError::Period)
        }
    }

    /// The control period `h`, s.
    #[must_use]
    pub fn period_s(&self) -> f32 {
        self.period_s
    }

    /// Time of tick `k`, s. One rounding, no accumulation; exact ticks are
    /// representable up to `k = 2^24` (46 h at 10 ms), beyond which `t`
    /// keeps a relative accuracy of 6e-8 (on day 30 at 100 Hz, up to 0.2 s:
    /// module documentation, "Time on long runs").
    #[must_use]
    pub fn time_s(&self, tick: u32) -> f32 {
        tick as f32 * self.period_s
    }
}

/// Position, velocity and acceleration of the reference point at one time.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ReferenceSample {
    /// `(x_r, y_r)`, m.
    pub position: Vec2,
    /// `(ẋ_r, ẏ_r)`, m/s.
    pub velocity: Vec2,
    /// `(ẍ_r, ÿ_r)`, m/s².
    pub acceleration: Vec2,
}

impl ReferenceSample {
    /// Reference speed `v_r = |(ẋ_r, ẏ_r)|`, m/s.
    #[must_use]
    pub fn speed(&self) -> f32 {
        self.velocity.norm()
    }
}

/// Bounds `v_rm ≤ v_r(t) ≤ v_rM` of the reference speed (paper 001, eq. (2)).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SpeedBounds {
    /// `v_rm`, m/s (0 if the reference can stop: Assumption 1 fails).
    pub min_m_s: f32,
    /// `v_rM`, m/s.
    pub max_m_s: f32,
}

/// The figure-eight of paper 001, eqs. (51)–(52), with a phase.
///
/// `x_r = h1·sin(2s)`, `y_r = h1·sin(s)`, with `s = h2·t + φ`. The paper's
/// runs start at `(x_r, y_r) = (0, −5)`, which needs `φ = −π/2`
/// (paper-001 slip 7); `φ = 0` gives the printed (51).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FigureEight {
    h1_m: f32,
    h2_rad_s: f32,
    phase_rad: f32,
}

impl FigureEight {
    /// `h1` (half-width, m), `h2` (rad/s) and phase `φ` (rad).
    ///
    /// # Errors
    /// The first parameter outside its plausible range ([`crate::plausible`]).
    pub fn new(h1_m: f32, h2_rad_s: f32, phase_rad: f32) -> Result<Self, ReferenceError> {
        if !REFERENCE_SIZE_M.contains(h1_m) {
            return Err(ReferenceError::Size);
        }
        if !REFERENCE_RATE_RAD_S.contains(h2_rad_s) {
            return Err(ReferenceError::Rate);
        }
        if !ANGLE_RAD.contains(phase_rad) {
            return Err(ReferenceError::Placement);
        }
        Ok(Self {
            h1_m,
            h2_rad_s,
            phase_rad,
        })
    }

    /// The paper's figure-eight: `h1 = 5 m`, `h2 = 0.02 rad/s`, `φ = −π/2`.
    #[must_use]
    pub fn paper_001() -> Self {
        Self {
            h1_m: 5.0,
            h2_rad_s: 0.02,
            phase_rad: -0.5 * math::PI,
        }
    }

    fn sample(&self, t_s: f32) -> ReferenceSample {
        let (h1, h2) = (self.h1_m, self.h2_rad_s);
        // Reduce the phase to (−π, π] before doubling it, so that sin/cos
        // see small arguments however long the run.
        let s = math::wrap_angle(h2 * t_s + self.phase_rad);
        let (s1, c1) = math::sincos(s);
        let (s2, c2) = (2.0 * s1 * c1, c1 * c1 - s1 * s1);
        ReferenceSample {
            position: Vec2::new(h1 * s2, h1 * s1),
            velocity: Vec2::new(2.0 * h1 * h2 * c2, h1 * h2 * c1),
            acceleration: Vec2::new(-4.0 * h1 * h2 * h2 * s2, -h1 * h2 * h2 * s1),
        }
    }

    fn speed_bounds(&self) -> SpeedBounds {
        // v_r² = (h1 h2)² (4 cos²2s + cos²s). With c = cos²s ∈ [0, 1],
        // 4(2c − 1)² + c is minimal at c = 15/32 (value 31/64) and maximal at
        // c = 1 (value 5).
        let scale = self.h1_m * self.h2_rad_s;
        SpeedBounds {
            min_m_s: scale * math::sqrt(31.0 / 64.0),
            max_m_s: scale * math::sqrt(5.0),
        }
    }
}

/// A circle driven counter-clockwise (or clockwise for negative rate).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Circle {
    centre: Vec2,
    radius_m: f32,
    rate_rad_s: f32,
    phase_rad: f32,
}

impl Circle {
    /// Centre (m), radius (m), angular rate (rad/s, sign = direction, not 0)
    /// and the polar angle of the start point (rad).
    ///
    /// # Errors
    /// The first parameter outside its plausible range ([`crate::plausible`]).
    pub fn new(
        centre: Vec2,
        radius_m: f32,
        rate_rad_s: f32,
        phase_rad: f32,
    ) -> Result<Self, ReferenceError> {
        if !REFERENCE_SIZE_M.contains(radius_m) {
            return Err(ReferenceError::Size);
        }
        if !REFERENCE_RATE_RAD_S.contains_magnitude(rate_rad_s) {
            return Err(ReferenceError::Rate);
        }
        if !(on_the_floor(centre) && ANGLE_RAD.contains(phase_rad)) {
            return Err(ReferenceError::Placement);
        }
        Ok(Self {
            centre,
            radius_m,
            rate_rad_s,
            phase_rad,
        })
    }

    fn sample(&self, t_s: f32) -> ReferenceSample {
        let a = math::wrap_angle(self.rate_rad_s * t_s + self.phase_rad);
        let (s, c) = math::sincos(a);
        let (r, w) = (self.radius_m, self.rate_rad_s);
        ReferenceSample {
            position: Vec2::new(self.centre.x + r * c, self.centre.y + r * s),
            velocity: Vec2::new(-r * w * s, r * w * c),
            acceleration: Vec2::new(-r * w * w * c, -r * w * w * s),
        }
    }

    fn speed_bounds(&self) -> SpeedBounds {
        let v = self.radius_m * self.rate_rad_s.abs();
        SpeedBounds {
            min_m_s: v,
            max_m_s: v,
        }
    }
}

/// A straight line at constant speed.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StraightLine {
    start: Vec2,
    velocity: Vec2,
}

impl StraightLine {
    /// Start point (m), heading (rad) and speed (m/s, positive).
    ///
    /// # Errors
    /// The first parameter outside its plausible range ([`crate::plausible`]).
    pub fn new(start: Vec2, heading_rad: f32, speed_m_s: f32) -> Result<Self, ReferenceError> {
        if !REFERENCE_SPEED_M_S.contains(speed_m_s) {
            return Err(ReferenceError::Rate);
        }
        if !(on_the_floor(start) && ANGLE_RAD.contains(heading_rad)) {
            return Err(ReferenceError::Placement);
        }
        Ok(Self {
            start,
            velocity: Vec2::new(
                speed_m_s * math::cos(heading_rad),
                speed_m_s * math::sin(heading_rad),
            ),
        })
    }

    fn sample(&self, t_s: f32) -> ReferenceSample {
        ReferenceSample {
            position: self.start + self.velocity.scaled(t_s),
            velocity: self.velocity,
            acceleration: Vec2::ZERO,
        }
    }

    fn speed_bounds(&self) -> SpeedBounds {
        let v = self.velocity.norm();
        SpeedBounds {
            min_m_s: v,
            max_m_s: v,
        }
    }
}

/// The reference trajectories the core knows, as one `Copy` value (no `dyn`
/// in the control loop; a scenario file names one of these).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Trajectory {
    /// Paper 001's figure-eight (51).
    FigureEight(FigureEight),
    /// A circle.
    Circle(Circle),
    /// A straight line.
    StraightLine(StraightLine),
}

impl Trajectory {
    /// Position, velocity and acceleration at time `t_s` (s).
    #[must_use]
    pub fn sample(&self, t_s: f32) -> ReferenceSample {
        match self {
            Self::FigureEight(f) => f.sample(t_s),
            Self::Circle(c) => c.sample(t_s),
            Self::StraightLine(l) => l.sample(t_s),
        }
    }

    /// The rate of the periodic angle, rad/s: the figure-eight's `h2`
    /// (its period `2π/h2`), a circle's `ω` (signed; period `2π/|ω|`);
    /// `None` for a line, which has no period.
    #[must_use]
    pub fn rate_rad_s(&self) -> Option<f32> {
        match self {
            Self::FigureEight(f) => Some(f.h2_rad_s),
            Self::Circle(c) => Some(c.rate_rad_s),
            Self::StraightLine(_) => None,
        }
    }

    /// Bounds of the reference speed over all time (paper 001, eq. (2)).
    #[must_use]
    // Always inlined so that a compiled-in spec's validation folds away: see `LawSpec::build`.
    #[inline(always)]
    pub fn speed_bounds(&self) -> SpeedBounds {
        match self {
            Self::FigureEight(f) => f.speed_bounds(),
            Self::Circle(c) => c.speed_bounds(),
            Self::StraightLine(l) => l.speed_bounds(),
        }
    }
}

impl From<FigureEight> for Trajectory {
    fn from(f: FigureEight) -> Self {
        Self::FigureEight(f)
    }
}
impl From<Circle> for Trajectory {
    fn from(c: Circle) -> Self {
        Self::Circle(c)
    }
}
impl From<StraightLine> for Trajectory {
    fn from(l: StraightLine) -> Self {
        Self::StraightLine(l)
    }
}

/// A reference trajectory by its parameters (SI units, radians), each in
/// its plausible range ([`crate::plausible`]: sizes in
/// [`crate::plausible::REFERENCE_SIZE_M`], rates in
/// [`crate::plausible::REFERENCE_RATE_RAD_S`], a line's speed in
/// [`crate::plausible::REFERENCE_SPEED_M_S`], points in
/// [`crate::plausible::COORDINATE_M`] on each axis, angles in
/// [`crate::plausible::ANGLE_RAD`]).
///
/// With the features `serde` and `std` (host tools: serde reads a tagged
/// table with an allocator) this is a file's `[reference]` table, tagged
/// by `kind` (`"figure_eight"`, `"circle"`, `"line"`), each key with the
/// default documented on it. The HIL link and the robot image carry it in
/// their own compact form, with `serde` alone (`TrajectoryWire`, inside
/// `TrackerSpec`).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(
    all(feature = "serde", feature = "std"),
    derive(serde::Serialize, serde::Deserialize),
    serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)
)]
#[cfg_attr(feature = "schemars", derive(schemars::JsonSchema))]
#[non_exhaustive]
pub enum TrajectorySpec {
    /// Paper 001's figure-eight ([`FigureEight::new`]), `x = h1 sin 2s`,
    /// `y = h1 sin s`, `s = h2 t + φ`.
    FigureEight {
        /// Half-width `h1`, m (default 5, the paper's).
        #[cfg_attr(
            all(feature = "serde", feature = "std"),
            serde(default = "TrajectorySpec::paper_h1_m")
        )]
        #[cfg_attr(feature = "schemars", schemars(range(min = crate::plausible::REFERENCE_SIZE_M.min, max = crate::plausible::REFERENCE_SIZE_M.max)))]
        h1_m: f32,
        /// Rate `h2`, rad/s (default 0.02, the paper's).
        #[cfg_attr(
            all(feature = "serde", feature = "std"),
            serde(default = "TrajectorySpec::paper_h2_rad_s")
        )]
        #[cfg_attr(feature = "schemars", schemars(range(min = crate::plausible::REFERENCE_RATE_RAD_S.min, max = crate::plausible::REFERENCE_RATE_RAD_S.max)))]
        h2_rad_s: f32,
        /// Phase `φ`, rad (default −π/2: the start at `(0, −h1)`, as the
        /// paper's runs).
        #[cfg_attr(
            all(feature = "serde", feature = "std"),
            serde(default = "TrajectorySpec::paper_phase_rad")
        )]
        #[cfg_attr(feature = "schemars", schemars(range(min = crate::plausible::ANGLE_RAD.min, max = crate::plausible::ANGLE_RAD.max)))]
        phase_rad: f32,
    },
    /// A circle ([`Circle::new`]).
    Circle {
        /// Centre `[x, y]`, m (default the origin).
        #[cfg_attr(all(feature = "serde", feature = "std"), serde(default))]
        center_m: [f32; 2],
        /// Radius, m.
        #[cfg_attr(feature = "schemars", schemars(range(min = crate::plausible::REFERENCE_SIZE_M.min, max = crate::plausible::REFERENCE_SIZE_M.max)))]
        radius_m: f32,
        /// Angular rate, rad/s (negative: clockwise; its magnitude in the
        /// reference rates' range, `wmr_core::plausible::REFERENCE_RATE_RAD_S`).
        rate_rad_s: f32,
        /// Polar angle of the start point, rad (default 0).
        #[cfg_attr(all(feature = "serde", feature = "std"), serde(default))]
        #[cfg_attr(feature = "schemars", schemars(range(min = crate::plausible::ANGLE_RAD.min, max = crate::plausible::ANGLE_RAD.max)))]
        phase_rad: f32,
    },
    /// A straight line at constant speed ([`StraightLine::new`]).
    Line {
        /// Start `[x, y]`, m (default the origin).
        #[cfg_attr(all(feature = "serde", feature = "std"), serde(default))]
        start_m: [f32; 2],
        /// Direction, rad (default 0: along x).
        #[cfg_attr(all(feature = "serde", feature = "std"), serde(default))]
        #[cfg_attr(feature = "schemars", schemars(range(min = crate::plausible::ANGLE_RAD.min, max = crate::plausible::ANGLE_RAD.max)))]
        heading_rad: f32,
        /// Speed, m/s.
        #[cfg_attr(feature = "schemars", schemars(range(min = crate::plausible::REFERENCE_SPEED_M_S.min, max = crate::plausible::REFERENCE_SPEED_M_S.max)))]
        speed_m_s: f32,
    },
}

/// [`TrajectorySpec`] as the HIL link and the robot image carry it
/// (postcard, which has no tagged tables): serde's remote form of the
/// same enum, so the two cannot differ (`#[serde(with =
/// "TrajectoryWire")]` on a `TrajectorySpec` field).
#[cfg(feature = "serde")]
#[derive(serde::Serialize, serde::Deserialize)]
#[serde(remote = "TrajectorySpec")]
pub enum TrajectoryWire {
    /// [`TrajectorySpec::FigureEight`].
    #[allow(missing_docs)]
    FigureEight {
        h1_m: f32,
        h2_rad_s: f32,
        phase_rad: f32,
    },
    /// [`TrajectorySpec::Circle`].
    #[allow(missing_docs)]
    Circle {
        center_m: [f32; 2],
        radius_m: f32,
        rate_rad_s: f32,
        phase_rad: f32,
    },
    /// [`TrajectorySpec::Line`].
    #[allow(missing_docs)]
    Line {
        start_m: [f32; 2],
        heading_rad: f32,
        speed_m_s: f32,
    },
}

impl TrajectorySpec {
    /// Paper 001's half-width `h1`, m.
    pub const PAPER_H1_M: f32 = 5.0;
    /// Paper 001's rate `h2`, rad/s.
    pub const PAPER_H2_RAD_S: f32 = 0.02;
    /// The phase of paper 001's runs, rad: the start at `(0, −h1)`.
    pub const PAPER_PHASE_RAD: f32 = -core::f32::consts::FRAC_PI_2;

    #[cfg(all(feature = "serde", feature = "std"))]
    fn paper_h1_m() -> f32 {
        Self::PAPER_H1_M
    }
    #[cfg(all(feature = "serde", feature = "std"))]
    fn paper_h2_rad_s() -> f32 {
        Self::PAPER_H2_RAD_S
    }
    #[cfg(all(feature = "serde", feature = "std"))]
    fn paper_phase_rad() -> f32 {
        Self::PAPER_PHASE_RAD
    }

    /// The validated trajectory.
    ///
    /// # Errors
    /// The constructor's refusal.
    pub fn build(&self) -> Result<Trajectory, ReferenceError> {
        Ok(match *self {
            Self::FigureEight {
                h1_m,
                h2_rad_s,
                phase_rad,
            } => FigureEight::new(h1_m, h2_rad_s, phase_rad)?.into(),
            Self::Circle {
                center_m: [cx, cy],
                radius_m,
                rate_rad_s,
                phase_rad,
            } => Circle::new(Vec2::new(cx, cy), radius_m, rate_rad_s, phase_rad)?.into(),
            Self::Line {
                start_m: [x, y],
                heading_rad,
                speed_m_s,
            } => StraightLine::new(Vec2::new(x, y), heading_rad, speed_m_s)?.into(),
        })
    }
}

/// A reference drawn from a fuzzer's bytes, near paper 001's sizes
/// ([`crate::fuzzing`]).
#[cfg(feature = "arbitrary")]
impl<'a> arbitrary::Arbitrary<'a> for TrajectorySpec {
    fn arbitrary(u: &mut arbitrary::Unstructured<'a>) -> arbitrary::Result<Self> {
        use crate::fuzzing::float;
        Ok(match u.int_in_range(0_u8..=2)? {
            0 => Self::Line {
                start_m: [float(u, 0.0)?, float(u, 0.0)?],
                heading_rad: float(u, 0.0)?,
                speed_m_s: float(u, 0.2)?,
            },
            1 => Self::FigureEight {
                h1_m: float(u, 5.0)?,
                h2_rad_s: float(u, 0.02)?,
                phase_rad: float(u, -core::f32::consts::FRAC_PI_2)?,
            },
            _ => Self::Circle {
                center_m: [float(u, 0.0)?, float(u, 0.0)?],
                radius_m: float(u, 1.0)?,
                rate_rad_s: float(u, 0.2)?,
                phase_rad: float(u, 0.0)?,
            },
        })
    }
}

#[cfg(test)]
mod clock_tests;

#[cfg(test)]
mod tests {
    use super::*;

    /// Central differences of position/velocity match velocity/acceleration.
    fn check_derivatives(traj: Trajectory) {
        let dt = 1e-2_f32;
        for i in 0..200 {
            let t = i as f32 * 1.7;
            let (a, b, c) = (traj.sample(t - dt), traj.sample(t), traj.sample(t + dt));
            let vel = (c.position - a.position).scaled(0.5 / dt);
            let acc = (c.velocity - a.velocity).scaled(0.5 / dt);
            assert!((vel - b.velocity).norm() < 2e-3, "velocity at t={t}");
            assert!(
                (acc - b.acceleration).norm() < 2e-3,
                "acceleration at t={t}"
            );
        }
    }

    #[test]
    fn derivatives_are_consistent() {
        check_derivatives(FigureEight::paper_001().into());
        check_derivatives(
            Circle::new(Vec2::new(1.0, 2.0), 3.0, -0.2, 0.3)
                .unwrap()
                .into(),
        );
        check_derivatives(
            StraightLine::new(Vec2::new(1.0, 2.0), 0.4, 0.3)
                .unwrap()
                .into(),
        );
    }

    #[test]
    fn paper_figure_eight_starts_at_0_minus_5() {
        let s = Trajectory::from(FigureEight::paper_001()).sample(0.0);
        assert!(s.position.x.abs() < 1e-5 && (s.position.y + 5.0).abs() < 1e-5);
    }

    #[test]
    fn figure_eight_speed_bounds_hold_over_a_period() {
        let traj = Trajectory::from(FigureEight::paper_001());
        let b = traj.speed_bounds();
        let (mut lo, mut hi) = (f32::MAX, 0.0_f32);
        // One period of s is 2π/h2 = 314 s.
        for k in 0..31_416 {
            let v = traj.sample(k as f32 * 0.01).speed();
            lo = lo.min(v);
            hi = hi.max(v);
        }
        assert!(
            lo >= b.min_m_s * (1.0 - 1e-4) && lo < b.min_m_s * 1.001,
            "{lo} vs {b:?}"
        );
        assert!(
            hi <= b.max_m_s * (1.0 + 1e-4) && hi > b.max_m_s * 0.999,
            "{hi} vs {b:?}"
        );
    }

    #[test]
    fn clock_does_not_accumulate() {
        let clock = TickClock::new(0.001).unwrap();
        // 480 s at 1 kHz: one rounding, not 480 000 of them.
        assert!((clock.time_s(480_000) - 480.0).abs() < 1e-4);
        assert_eq!(TickClock::new(0.0), Err(ReferenceError::Period));
    }
}
