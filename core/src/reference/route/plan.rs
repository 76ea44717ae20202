//! The plan: segments in time (lines, blend halves, pivots, dwells), each
//! starting at an integer tick plus a sub-tick offset, and its sampling by
//! a cursor.

use super::bounds::{MAX_ROUTE_TICKS, MAX_SEGMENTS};
use super::error::RouteError;
use super::geometry::{self, Blend, Corner};
use super::profile::Trapezoid;
use super::waypoints::{RouteLimits, Stop, Waypoint, check_waypoints};
use crate::geometry::Vec2;
use crate::math;
use crate::plausible::PERIOD_S;
use crate::reference::{ReferenceSample, SpeedBounds};

/// What the reference does at a sample.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RouteMode {
    /// Driving along the path; `ω_r = v_r κ`.
    Moving {
        /// Signed curvature of the path at the reference point, 1/m
        /// (positive turning counter-clockwise).
        curvature_per_m: f32,
    },
    /// At rest on a waypoint.
    Stopped {
        /// Heading to hold, rad, counter-clockwise from +x, in (−π, π]
        /// (`None`: at the first waypoint, with no heading to face).
        hold_heading_rad: Option<f32>,
    },
    /// At rest on a waypoint, turning in place.
    Pivoting {
        /// The reference heading, rad, counter-clockwise from +x, in (−π, π].
        heading_rad: f32,
        /// Its rate, rad/s (positive counter-clockwise).
        rate_rad_s: f32,
        /// Its angular acceleration, rad/s².
        accel_rad_s2: f32,
    },
}

/// The route's reference at one tick.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RouteSample {
    /// Position (m), velocity (m/s) and acceleration (m/s²) of the
    /// reference point; velocity and acceleration exactly zero while
    /// stopped or pivoting.
    pub reference: ReferenceSample,
    /// Moving, stopped or pivoting.
    pub mode: RouteMode,
    /// The route is over: the reference rests on the last waypoint (and
    /// stays so, whatever the ticks that follow).
    pub done: bool,
}

/// Where a plan's sampling is: one per run of a route, starting at
/// [`RouteCursor::new`]. It moves forward with the ticks (a backward jump
/// is allowed and searched for) and, once the route is done, stays done.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RouteCursor {
    pub(super) segment: u16,
    done: bool,
}

impl RouteCursor {
    /// At the route's start.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            segment: 0,
            done: false,
        }
    }

    /// The index of the segment the last sample fell in (0 at the start):
    /// two samples in the same segment share it, so a caller can tell one
    /// pivot (or stop) from the next even with no other sample between.
    #[must_use]
    pub const fn segment_index(&self) -> u16 {
        self.segment
    }
}

/// What a segment is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Kind {
    /// A straight line from `origin` along `dir`.
    Line,
    /// A blend's first clothoid, from `origin` heading `dir`.
    BlendIn { phi: f32, sign: f32 },
    /// A blend's second clothoid, ending at `origin` heading `dir`.
    BlendOut { phi: f32, sign: f32 },
    /// A turn in place at `origin` by `sign · length` rad from `from_rad`.
    Pivot { from_rad: f32, sign: f32 },
    /// At rest at `origin` for `length` s.
    Dwell { hold_rad: Option<f32> },
}

/// One piece of the plan.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Segment {
    pub(super) kind: Kind,
    /// Start point (the end point for [`Kind::BlendOut`]), m.
    pub(super) origin: Vec2,
    /// Unit direction of the line or of the blend's leg.
    pub(super) dir: Vec2,
    /// Length (m), turn (rad, pivot) or dwell (s).
    pub(super) length: f32,
    /// Speed cap (m/s; rad/s for a pivot).
    pub(super) cap: f32,
    pub(super) profile: Trapezoid,
    /// Duration, s.
    pub(super) duration_s: f32,
    /// The first tick (since the route's start) in this segment.
    pub(super) first_tick: u32,
    /// Time into the segment at `first_tick`, s, in `[0, h]`.
    pub(super) offset_s: f32,
}

const EMPTY: Segment = Segment {
    kind: Kind::Line,
    origin: Vec2::ZERO,
    dir: Vec2::ZERO,
    length: 0.0,
    cap: 0.0,
    profile: Trapezoid {
        v0: 0.0,
        peak: 0.0,
        v1: 0.0,
        accel: 0.0,
        t_accel_s: 0.0,
        t_cruise_s: 0.0,
        t_decel_s: 0.0,
        length: 0.0,
    },
    duration_s: 0.0,
    first_tick: 0,
    offset_s: 0.0,
};

impl Kind {
    fn is_moving(self) -> bool {
        matches!(
            self,
            Self::Line | Self::BlendIn { .. } | Self::BlendOut { .. }
        )
    }
}

impl Segment {
    /// The sample at `t_s` into the segment.
    fn sample(&self, t_s: f32) -> RouteSample {
        let at_rest = |mode| RouteSample {
            reference: ReferenceSample {
                position: self.origin,
                velocity: Vec2::ZERO,
                acceleration: Vec2::ZERO,
            },
            mode,
            done: false,
        };
        let (s, v, a) = self.profile.at(t_s);
        let (offset, tangent, curvature) = match self.kind {
            Kind::Dwell { hold_rad } => {
                return at_rest(RouteMode::Stopped {
                    hold_heading_rad: hold_rad,
                });
            }
            Kind::Pivot { from_rad, sign } => {
                return at_rest(RouteMode::Pivoting {
                    heading_rad: math::wrap_angle(from_rad + sign * s),
                    rate_rad_s: sign * v,
                    accel_rad_s2: sign * a,
                });
            }
            Kind::Line => (self.dir.scaled(s), self.dir, 0.0),
            Kind::BlendIn { phi, sign } => geometry::entering(self.dir, self.length, phi, sign, s),
            Kind::BlendOut { phi, sign } => geometry::leaving(self.dir, self.length, phi, sign, s),
        };
        let normal = Vec2::new(-tangent.y, tangent.x);
        RouteSample {
            reference: ReferenceSample {
                position: self.origin + offset,
                velocity: tangent.scaled(v),
                acceleration: tangent.scaled(a) + normal.scaled(v * v * curvature),
            },
            mode: RouteMode::Moving {
                curvature_per_m: curvature,
            },
            done: false,
        }
    }
}

/// A route planned in time: segments, each starting at an integer tick.
///
/// Up to [`MAX_SEGMENTS`] segments in a fixed-capacity vector (about 20 KB
/// in all): on the robot, keep one where it is to stay (a `static` or the
/// task's state) and plan into it with [`RoutePlan::replan`], which
/// neither initialises nor copies the storage; [`RoutePlan::new`] returns
/// the plan by value (a copy of it on most targets).
#[derive(Debug, Clone, PartialEq)]
pub struct RoutePlan {
    segments: heapless::Vec<Segment, MAX_SEGMENTS>,
    period_s: f32,
    end_tick: u32,
    peak_speed_m_s: f32,
}

impl Default for RoutePlan {
    fn default() -> Self {
        Self::empty()
    }
}

impl RoutePlan {
    /// A plan with no segments: sampled, it is done at once, at rest at
    /// the origin. Fill it with [`RoutePlan::replan`].
    #[must_use]
    pub const fn empty() -> Self {
        Self {
            segments: heapless::Vec::new(),
            period_s: 0.0,
            end_tick: 0,
            peak_speed_m_s: 0.0,
        }
    }

    /// Plans the route through `waypoints` under `limits`, sampled every
    /// `period_s` seconds.
    ///
    /// # Errors
    /// [`RouteError`], naming the waypoint and its field: fewer than 2 or
    /// more than [`super::ROUTE_CAPACITY`] waypoints, a value not finite or
    /// out of range, two equal consecutive positions, a negative dwell, a
    /// speed limit `≤ 0`, a corner blend that does not fit, a period
    /// outside [`PERIOD_S`], a route longer than [`MAX_ROUTE_TICKS`].
    pub fn new(
        waypoints: &[Waypoint],
        limits: &RouteLimits,
        period_s: f32,
    ) -> Result<Self, RouteError> {
        let mut plan = Self::empty();
        plan.replan(waypoints, limits, period_s)?;
        Ok(plan)
    }

    /// [`RoutePlan::new`] in place, replacing this plan (start a new
    /// [`RouteCursor`] with it). On a refusal the plan is left empty
    /// (done at once).
    ///
    /// # Errors
    /// As [`RoutePlan::new`].
    pub fn replan(
        &mut self,
        waypoints: &[Waypoint],
        limits: &RouteLimits,
        period_s: f32,
    ) -> Result<(), RouteError> {
        self.segments.clear();
        self.period_s = period_s;
        self.end_tick = 0;
        self.peak_speed_m_s = 0.0;
        let planned = self.plan(waypoints, limits, period_s);
        if planned.is_err() {
            self.segments.clear();
            self.end_tick = 0;
            self.peak_speed_m_s = 0.0;
        }
        planned
    }

    fn plan(
        &mut self,
        waypoints: &[Waypoint],
        limits: &RouteLimits,
        period_s: f32,
    ) -> Result<(), RouteError> {
        if !PERIOD_S.contains(period_s) {
            return Err(RouteError::Period);
        }
        check_waypoints(waypoints)?;
        self.lay_out(waypoints, limits)?;
        self.profile(limits);
        self.schedule()
    }

    /// The control period `h`, s.
    #[must_use]
    pub fn period_s(&self) -> f32 {
        self.period_s
    }

    /// The first tick (since the start) at which the route is done.
    #[must_use]
    pub fn duration_ticks(&self) -> u32 {
        self.end_tick
    }

    /// How many segments the plan holds (lines, blend halves, pivots,
    /// dwells), at most [`MAX_SEGMENTS`].
    #[must_use]
    pub fn segment_count(&self) -> usize {
        self.segments.len()
    }

    /// Bounds of the reference speed `v_r`: `v_rm = 0` (the route stops),
    /// `v_rM` the highest speed the plan reaches, m/s. With `v_rm = 0`
    /// paper 001's Assumption 1 fails and its gain bound (15), which
    /// divides by `v_rm`, does not apply: a tracker driving a route must
    /// not rely on it (nor on any law whose convergence needs
    /// `v_r ≥ v_rm > 0`) through the stops.
    #[must_use]
    pub fn speed_bounds(&self) -> SpeedBounds {
        SpeedBounds {
            min_m_s: 0.0,
            max_m_s: self.peak_speed_m_s,
        }
    }

    /// The reference `elapsed_ticks` ticks after the route's start.
    ///
    /// Time into the current segment is `offset + (k − k_first)·h`, from
    /// an integer difference of ticks: a route sampled on day 30 is as
    /// accurate as on day 1. Cost: the cursor moves forward over the
    /// segments that ended since the last call (usually none, amortised
    /// at most one per segment over a run); a backward jump is a binary
    /// search (8 steps).
    pub fn sample(&self, cursor: &mut RouteCursor, elapsed_ticks: u32) -> RouteSample {
        if cursor.done || elapsed_ticks >= self.end_tick {
            cursor.done = true;
            return self.final_sample();
        }
        let segments = self.segments.as_slice();
        let mut j = usize::from(cursor.segment);
        if segments.get(j).is_none_or(|s| s.first_tick > elapsed_ticks) {
            j = segments
                .partition_point(|s| s.first_tick <= elapsed_ticks)
                .saturating_sub(1);
        }
        while segments
            .get(j + 1)
            .is_some_and(|s| s.first_tick <= elapsed_ticks)
        {
            j += 1;
        }
        cursor.segment = u16::try_from(j).unwrap_or(0);
        match segments.get(j) {
            Some(s) => {
                let ticks_in = elapsed_ticks.wrapping_sub(s.first_tick);
                s.sample(s.offset_s + ticks_in as f32 * self.period_s)
            }
            None => self.final_sample(),
        }
    }

    /// The reference at the tick `now_tick` of a free-running `u32` tick
    /// counter, for a route started at `start_tick` of the same counter.
    ///
    /// The elapsed ticks are `now_tick − start_tick` modulo 2³², right
    /// across the counter's wrap (at 100 Hz every 497 days, at 1 kHz every
    /// 49.7 days) for any route shorter than 2³² ticks (every plan is
    /// shorter than [`MAX_ROUTE_TICKS`] = 2³¹). Once the route is done the
    /// cursor keeps it done, so that a second wrap of the elapsed count
    /// cannot restart it.
    pub fn sample_at(
        &self,
        cursor: &mut RouteCursor,
        now_tick: u32,
        start_tick: u32,
    ) -> RouteSample {
        self.sample(cursor, now_tick.wrapping_sub(start_tick))
    }

    /// At rest on the last waypoint, done.
    fn final_sample(&self) -> RouteSample {
        let last = self.segments.last().unwrap_or(&EMPTY);
        let mut sample = last.sample(last.duration_s);
        sample.done = true;
        sample
    }

    /// The segments, for the tests' `f64` evaluation.
    #[cfg(test)]
    pub(super) fn segments(&self) -> &[Segment] {
        self.segments.as_slice()
    }

    fn push(&mut self, segment: Segment) -> Result<(), RouteError> {
        // Never full: at most 4 segments per waypoint (`MAX_SEGMENTS`).
        self.segments
            .push(segment)
            .map_err(|_| RouteError::TooManyWaypoints)
    }

    /// The path's segments in order (geometry and caps; no timing yet).
    fn lay_out(&mut self, waypoints: &[Waypoint], limits: &RouteLimits) -> Result<(), RouteError> {
        let last = waypoints.len().saturating_sub(1);
        let position = |i: usize| waypoints.get(i).map(|w| w.position_m);
        // Unit direction and length of the leg that ends at waypoint i.
        let leg = |i: usize| -> Result<(Vec2, f32), RouteError> {
            let index = index_u8(i);
            let (Some(a), Some(b)) = (i.checked_sub(1).and_then(position), position(i)) else {
                return Err(RouteError::TooFewWaypoints);
            };
            let d = b - a;
            let length = d.norm();
            let dir = d.scaled(1.0 / length);
            if length > 0.0 && dir.is_finite() {
                Ok((dir, length))
            } else {
                Err(RouteError::SameAsPrevious { index })
            }
        };
        let lateral_cap =
            |b: &Blend| math::sqrt(limits.max_lateral_accel_m_s2() / b.peak_curvature_per_m);
        let no_stop = Stop {
            dwell_s: 0.0,
            face_heading_rad: None,
        };

        let first = waypoints.first().ok_or(RouteError::TooFewWaypoints)?;
        let (first_dir, _) = leg(1)?;
        let stop = first.stop.unwrap_or(no_stop);
        self.stop_at(first.position_m, None, Some(first_dir), stop, limits)?;

        let mut start_blend: Option<Blend> = None;
        for (i, w) in waypoints.iter().enumerate().skip(1) {
            let index = index_u8(i);
            let from = position(i - 1).ok_or(RouteError::TooFewWaypoints)?;
            let (dir, length) = leg(i)?;
            let next_dir = if i < last { Some(leg(i + 1)?.0) } else { None };
            let is_stop = i == last || w.stop.is_some();
            let end_blend = match next_dir {
                Some(next) if !is_stop => {
                    match geometry::design_corner(dir, next, limits.blend_deviation_m()) {
                        Corner::Straight => None,
                        Corner::Blend(b) => Some(b),
                        Corner::Refused => return Err(RouteError::BlendDoesNotFit { index }),
                    }
                }
                _ => None,
            };
            let t_start = start_blend.map_or(0.0, |b| b.tangent_m);
            let t_end = end_blend.map_or(0.0, |b| b.tangent_m);
            if t_start + t_end > length {
                let index = if t_end >= t_start {
                    index
                } else {
                    index.saturating_sub(1)
                };
                return Err(RouteError::BlendDoesNotFit { index });
            }
            let cap = w
                .speed_limit_m_s
                .map_or(limits.max_speed_m_s(), |v| v.min(limits.max_speed_m_s()));
            let line_start = from + dir.scaled(t_start);
            let moving = |kind, origin, length, cap| Segment {
                kind,
                origin,
                dir,
                length,
                cap,
                ..EMPTY
            };
            if let Some(b) = start_blend {
                self.push(moving(
                    Kind::BlendOut {
                        phi: b.half_turn_rad,
                        sign: b.sign,
                    },
                    line_start,
                    b.half_length_m,
                    cap.min(lateral_cap(&b)),
                ))?;
            }
            let line_length = length - t_start - t_end;
            if line_length > 0.0 {
                self.push(moving(Kind::Line, line_start, line_length, cap))?;
            }
            if let Some(b) = end_blend {
                self.push(moving(
                    Kind::BlendIn {
                        phi: b.half_turn_rad,
                        sign: b.sign,
                    },
                    w.position_m - dir.scaled(t_end),
                    b.half_length_m,
                    cap.min(lateral_cap(&b)),
                ))?;
            }
            if is_stop {
                let stop = w.stop.unwrap_or(no_stop);
                self.stop_at(w.position_m, Some(dir), next_dir, stop, limits)?;
                start_blend = None;
            } else {
                start_blend = end_blend;
            }
        }
        Ok(())
    }

    /// A stop's segments: pivot to the heading to face, dwell, pivot to
    /// the next leg if it turns more than the threshold from it; without
    /// a heading to face, pivot to the next leg if it turns more than the
    /// threshold from the arrival, then dwell. `arrival` is `None` at the
    /// first waypoint (the robot is assumed to face the heading to face,
    /// if any, else the first leg).
    fn stop_at(
        &mut self,
        at: Vec2,
        arrival: Option<Vec2>,
        next: Option<Vec2>,
        stop: Stop,
        limits: &RouteLimits,
    ) -> Result<(), RouteError> {
        let heading = |d: Vec2| math::atan2(d.y, d.x);
        let mut hold = match (stop.face_heading_rad, arrival) {
            (Some(face), None) => Some(math::wrap_angle(face)),
            (_, arrival) => arrival.map(heading),
        };
        if let (Some(face), Some(from)) = (stop.face_heading_rad, hold) {
            let face = math::wrap_angle(face);
            self.pivot(at, from, face, limits)?;
            hold = Some(face);
        }
        let to_next = |hold: Option<f32>| -> Option<(f32, f32)> {
            let (from, to) = (hold?, heading(next?));
            let turn = math::wrap_angle(to - from);
            (turn.abs() > limits.pivot_threshold_rad()).then_some((from, to))
        };
        if stop.face_heading_rad.is_none()
            && let Some((from, to)) = to_next(hold)
        {
            self.pivot(at, from, to, limits)?;
            hold = Some(to);
        }
        self.push(Segment {
            kind: Kind::Dwell { hold_rad: hold },
            origin: at,
            length: stop.dwell_s,
            ..EMPTY
        })?;
        if stop.face_heading_rad.is_some()
            && let Some((from, to)) = to_next(hold)
        {
            self.pivot(at, from, to, limits)?;
        }
        Ok(())
    }

    /// A pivot at `at` from heading `from` to `to` (rad), the short way;
    /// none if they are equal.
    fn pivot(
        &mut self,
        at: Vec2,
        from: f32,
        to: f32,
        limits: &RouteLimits,
    ) -> Result<(), RouteError> {
        let turn = math::wrap_angle(to - from);
        if turn == 0.0 || !turn.is_finite() {
            return Ok(());
        }
        self.push(Segment {
            kind: Kind::Pivot {
                from_rad: from,
                sign: if turn > 0.0 { 1.0 } else { -1.0 },
            },
            origin: at,
            length: turn.abs(),
            cap: limits.pivot_rate_rad_s(),
            ..EMPTY
        })
    }

    /// The speed profile: the largest speeds at the segments' boundaries
    /// that the caps and the tangential acceleration allow, zero at the
    /// stops (a forward and a backward pass over squared speeds), then a
    /// trapezoid on each segment; the pivots' trapezoids; the durations.
    fn profile(&mut self, limits: &RouteLimits) {
        let accel = limits.max_tangential_accel_m_s2();
        let segments = self.segments.as_mut_slice();
        let moving_cap = |s: Option<&Segment>| match s {
            Some(s) if s.kind.is_moving() => s.cap,
            _ => 0.0,
        };
        // Forward: v1² ≤ v0² + 2aL, each boundary under both caps.
        let mut previous = 0.0_f32;
        for j in 0..segments.len() {
            let next_cap = moving_cap(segments.get(j + 1));
            let Some(s) = segments.get_mut(j) else { break };
            if s.kind.is_moving() {
                let w1 = (s.cap * s.cap)
                    .min(next_cap * next_cap)
                    .min(previous + 2.0 * accel * s.length);
                s.profile.v0 = previous;
                s.profile.v1 = w1;
                previous = w1;
            } else {
                previous = 0.0;
            }
        }
        // Backward: v0² ≤ v1² + 2aL.
        let mut next = 0.0_f32;
        for s in segments.iter_mut().rev() {
            if s.kind.is_moving() {
                let w1 = s.profile.v1.min(next);
                let w0 = s.profile.v0.min(w1 + 2.0 * accel * s.length);
                s.profile.v0 = w0;
                s.profile.v1 = w1;
                next = w0;
            } else {
                next = 0.0;
            }
        }
        let mut peak = 0.0_f32;
        // The last moving segment's end speed, squared and not: the next
        // segment starts at it (one square root per boundary).
        let mut boundary = (0.0_f32, 0.0_f32);
        for s in segments.iter_mut() {
            s.profile = match s.kind {
                Kind::Dwell { .. } => Trapezoid::default(),
                Kind::Pivot { .. } => Trapezoid::new(
                    s.length,
                    0.0,
                    0.0,
                    limits.pivot_rate_rad_s(),
                    limits.pivot_accel_rad_s2(),
                ),
                _ => {
                    let (w0, w1) = (s.profile.v0, s.profile.v1);
                    let v0 = if w0 == boundary.0 {
                        boundary.1
                    } else {
                        math::sqrt(w0)
                    };
                    let v1 = math::sqrt(w1);
                    boundary = (w1, v1);
                    let p = Trapezoid::new(s.length, v0, v1, s.cap, accel);
                    peak = peak.max(p.peak);
                    p
                }
            };
            if !s.kind.is_moving() {
                boundary = (0.0, 0.0);
            }
            s.duration_s = match s.kind {
                Kind::Dwell { .. } => s.length,
                _ => s.profile.duration_s(),
            };
        }
        self.peak_speed_m_s = peak;
    }

    /// Each segment's first tick and the time into it at that tick: the
    /// segment starting at `T` (s) starts at tick `⌈T/h⌉` with the offset
    /// `⌈T/h⌉·h − T ∈ [0, h)`, carried from segment to segment as an
    /// integer and a sub-tick remainder (never as a large `f32` time).
    fn schedule(&mut self) -> Result<(), RouteError> {
        let h = self.period_s;
        let mut first_tick: u32 = 0;
        let mut offset = 0.0_f32;
        for s in self.segments.as_mut_slice() {
            s.first_tick = first_tick;
            s.offset_s = offset;
            let d = s.duration_s;
            let q = (d - offset) / h;
            if !(d.is_finite() && d >= 0.0 && q < MAX_ROUTE_TICKS as f32) {
                return Err(RouteError::TooLong);
            }
            // Ticks into the segment at the next one's first tick: the
            // smallest n ≥ 0 with offset + n·h ≥ d.
            let mut n = -math::floor(-q);
            let mut next_offset = offset + n * h - d;
            if next_offset < 0.0 {
                let more = -math::floor(next_offset / h);
                n += more;
                next_offset += more * h;
            }
            if next_offset >= h && n >= 1.0 {
                n -= 1.0;
                next_offset -= h;
            }
            // n is an integer in [0, 2³¹] here.
            let n = n.max(0.0) as u32;
            first_tick = first_tick
                .checked_add(n)
                .filter(|&t| t <= MAX_ROUTE_TICKS)
                .ok_or(RouteError::TooLong)?;
            offset = math::clamp_or(next_offset, 0.0, h, 0.0);
        }
        // The route is done from the first tick at or after its end; a
        // route whose every segment is shorter than a tick is done on tick 1.
        self.end_tick = first_tick.max(1);
        Ok(())
    }
}

/// A waypoint index as the errors carry it (the capacity, 64, fits).
fn index_u8(i: usize) -> u8 {
    u8::try_from(i).unwrap_or(u8::MAX)
}
