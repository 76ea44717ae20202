//! Routes: a reference through waypoints, with curvature-continuous corner
//! blends, stops, pivots in place and a speed profile, planned on the
//! robot without allocation and sampled from integer ticks.
//!
//! # What a route is
//!
//! Up to [`ROUTE_CAPACITY`] [`Waypoint`]s (floor frame, m). Each is driven
//! through (a corner blend) or is a [`Stop`] (at rest for `dwell_s`,
//! optionally facing a heading); the first and last are always stops
//! (the route starts and ends at rest). Each may cap the speed of the leg
//! that ends at it. [`RouteLimits`] holds the rest: the largest speed,
//! tangential and lateral accelerations, the blends' deviation from the
//! corners, the pivot threshold, rate and angular acceleration.
//!
//! # Method
//!
//! * **Corner blends: a symmetric pair of clothoids (Euler spirals).** The
//!   curvature rises linearly with arc length from 0 to its peak at the
//!   blend's midpoint and falls back to 0, so the path is G2 (curvature
//!   continuous) and, at a continuous speed, `ω_r = v_r κ` has no jump
//!   while moving. This is the classic clothoid-pair (symmetric Euler
//!   spiral) corner of road and rail design, as used for mobile robots by
//!   Fleury, Souères, Laumond & Simeon, "Primitives for smoothing mobile
//!   robot trajectories", IEEE Trans. Robotics and Automation 11(3),
//!   441–448, 1995 (their "SCC" turn without the arc), with the Fresnel
//!   integrals by their power series (Abramowitz & Stegun, *Handbook of
//!   Mathematical Functions*, 7.3.11 and 7.3.13). The blend is sized so that its
//!   closest point to the corner (its midpoint, which is also its largest
//!   deviation from the polyline) is exactly `blend_deviation_m` away:
//!   the formulas and their `f32` evaluation are in the `geometry` file.
//!   A blend longer than its legs allow, with its neighbours' (the leg
//!   must hold the end of the blend at each of its ends), is refused
//!   ([`RouteError::BlendDoesNotFit`], naming the corner): a gentle turn
//!   makes a long blend (`L ≈ 3e/φ` for a half-turn `φ`), so lower the
//!   deviation or drop the near-collinear waypoint. A turn below
//!   `STRAIGHT_THROUGH_RAD` (1e-4 rad) is driven through without a blend;
//!   a turn above `MAX_CORNER_TURN_RAD` (3.1 rad) is refused (make it a
//!   stop).
//! * **Stops and pivots.** At a stop the reference decelerates to exactly
//!   zero. With a heading to face, it pivots to it (the short way), dwells,
//!   then pivots to the next leg if that turns by more than
//!   `pivot_threshold_rad`. Without one, it pivots to the next leg if
//!   that turns by more than the threshold from the arrival direction,
//!   then dwells. A smaller turn is a sharp stop-and-go: the reference
//!   leaves at rest along the new leg and the tracker absorbs the heading
//!   difference (at most the threshold) while speeding up. A pivot is a
//!   trapezoid (or triangle) in angle under `pivot_rate_rad_s` and
//!   `pivot_accel_rad_s2`. At the first waypoint the robot is assumed to
//!   face the heading to face, if given, else the first leg.
//! * **Speed profile.** Each moving segment (line, half blend) has a speed
//!   cap: `max_speed_m_s`, the `speed_limit_m_s` of the leg it lies on
//!   (a blend's halves lie on the two legs of its corner), and on a blend
//!   `√(a_lat/κ_peak)` (so `v² κ ≤ a_lat` everywhere on it). A forward
//!   and a backward pass over the segments' boundary speeds (in squares,
//!   `v1² ≤ v0² + 2aL` and back) give the largest boundary speeds under
//!   the caps and `max_tangential_accel_m_s2`, zero at every stop; each
//!   segment is then a trapezoid in time (accelerate, cruise,
//!   decelerate). Speed is continuous, tangential acceleration is
//!   piecewise constant (no jerk limit).
//!
//! # Discretization and time
//!
//! The plan is continuous in time; it is sampled at the integer tick `k`
//! since the route started ([`RoutePlan::sample`]) or of a free-running
//! `u32` counter ([`RoutePlan::sample_at`], across the counter's wrap).
//! Each segment starts at an integer tick plus a sub-tick offset, and the
//! time into the current segment is `offset + (k − k_first)·h` from an
//! integer difference, so day 30 samples as day 1 (no large `f32` time
//! anywhere: the error is relative to a segment's own duration, `f32`
//! rounding of a segment's length, at most 0.6 mm for a 10 km segment).
//! A segment shorter than a tick may be skipped by the samples (not by
//! the plan).
//!
//! With the `micromath` backend (sin/cos/atan2 off by ~1e-3) the path's
//! tangent is off unit length by as much, and so are the sampled speed
//! and accelerations against their limits; the default and `libm`
//! backends keep them to `f32` rounding (the tests run on both).
//!
//! # Units and angles
//!
//! SI units, `f32`: metres, seconds, m/s, m/s², radians, rad/s, rad/s².
//! Headings are counter-clockwise from the floor's +x axis
//! ([`crate::geometry`]), wrapped to (−π, π]; curvature is positive
//! turning counter-clockwise.
//!
//! # Costs
//!
//! No heap, no `unsafe`, no panic on any input (checked indexing only).
//! [`RoutePlan`] holds up to [`MAX_SEGMENTS`] segments in a
//! `heapless::Vec` (20.5 KB; [`Waypoints`] 1.8 KB). Planning is one pass
//! over the waypoints (an `atan2`, a `sincos` and the blend's series per
//! corner) and three over the segments (one square root per boundary):
//! `O(n)`, no iteration to converge. A sample is a cursor step, a
//! trapezoid lookup and, on a blend, 13 multiply–adds of the Fresnel
//! series and one `sincos`.
//!
//! Measured on QEMU's Cortex-M4F (`netduinoplus2`, `-icount shift=0`,
//! SysTick counting 0.168 per instruction, release build, default math
//! backend) for 64 waypoints on a spiral (8 stops facing a heading, 197
//! segments, 434 s at 100 Hz): [`RoutePlan::replan`] 123,550
//! instructions, [`RoutePlan::new`] 148,040 (its 20 KB result is copied
//! out); a sample 184 instructions on average, 285 at most, over every
//! tick of the route.
//!
//! # Speed bounds
//!
//! [`RoutePlan::speed_bounds`] gives `v_rm = 0`: a route stops, so paper
//! 001's Assumption 1 (`v_r ≥ v_rm > 0`) fails and its gain bound (15)
//! does not apply to a route with stops.

mod bounds;
mod error;
mod geometry;
mod plan;
mod profile;
#[cfg(test)]
mod tests;
mod waypoints;

pub use bounds::{MAX_ROUTE_TICKS, MAX_SEGMENTS, ROUTE_CAPACITY};
pub use error::{LimitKey, RouteError, RouteLimitsError, WaypointKey};
pub use plan::{RouteCursor, RouteMode, RoutePlan, RouteSample};
pub use waypoints::{RouteLimits, RouteLimitsSpec, Stop, Waypoint, Waypoints};
