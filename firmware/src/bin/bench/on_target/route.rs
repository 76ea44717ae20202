//! The route reference (`wmr_core::reference::route`): planning a route of
//! [`ROUTE_CAPACITY`] waypoints in place, and sampling it once a tick.
//! The whole tick on a route is `route_tick.rs`, in a build of its own.
//!
//! The route is the host tests' cost route (`planning_and_sampling_costs_on_the_host`
//! in `core/src/reference/route/tests.rs`): 64 waypoints on two
//! interleaved circles of 10 m and 13 m radius, 0.4 rad apart, every
//! eighth a 0.5 s stop facing its bearing (so with pivots), the last a
//! stop. The plan lives in `.bss` (a `RoutePlan` is about 20 KB), not on
//! the stack, as a robot keeps it.

use wmr_core::geometry::Vec2;
use wmr_core::math;
use wmr_core::reference::route::{
    ROUTE_CAPACITY, RouteCursor, RouteLimits, RouteLimitsSpec, RoutePlan, Waypoint,
};

use super::fail;
use super::stage::Stage;
use super::timing::SAMPLES;
use super::timing::{Calibration, timed};
use super::world::PERIOD_S;

/// The bench route's limits: 1 m/s, 0.5 m/s² along and 0.8 m/s² across
/// the path, blends 10 cm from their corners, pivots above 0.5 rad at up
/// to 1 rad/s and 2 rad/s².
pub(super) const LIMITS: RouteLimitsSpec = RouteLimitsSpec {
    max_speed_m_s: 1.0,
    max_tangential_accel_m_s2: 0.5,
    max_lateral_accel_m_s2: 0.8,
    blend_deviation_m: 0.1,
    pivot_threshold_rad: 0.5,
    pivot_rate_rad_s: 1.0,
    pivot_accel_rad_s2: 2.0,
};

/// Plans on the target (`route_plan`, one plan a sample: fewer samples, as
/// each is about 10^5 instructions) and samples the plan at ticks spread
/// evenly over its whole duration (`route_sample`, the cursor moving
/// forward as a tracker's does).
pub(super) fn bench_route(cal: Calibration) {
    let Some(limits) = RouteLimits::new(&LIMITS).ok() else {
        fail("route limits refused");
    };
    let mut waypoints = [Waypoint::pass(0.0, 0.0); ROUTE_CAPACITY];
    for (i, w) in waypoints.iter_mut().enumerate() {
        let bearing = i as f32 * 0.4;
        let radius_m = if i % 2 == 0 { 10.0 } else { 13.0 };
        let (sin, cos) = math::sincos(bearing);
        let at = Vec2::new(radius_m * cos, radius_m * sin);
        *w = if i % 8 == 7 || i + 1 == ROUTE_CAPACITY {
            Waypoint::stop(at.x, at.y, 0.5).facing(bearing)
        } else {
            Waypoint::pass(at.x, at.y)
        };
    }
    let Some(plan) = cortex_m::singleton!(: RoutePlan = RoutePlan::empty()) else {
        fail("route plan already taken");
    };
    let mut stage = Stage::new("route_plan");
    for _ in 0..PLANS {
        let (counts, planned) = timed(&waypoints, |w| replan(plan, w, &limits));
        if planned.is_err() {
            fail("bench route refused");
        }
        stage.record(counts);
    }
    stage.report(cal);
    let end = plan.duration_ticks();
    let mut cursor = RouteCursor::new();
    let mut stage = Stage::new("route_sample");
    let mut finite = true;
    for k in 0..SAMPLES as u32 {
        let tick = (u64::from(end) * u64::from(k) / SAMPLES as u64) as u32;
        let (counts, x) = timed(&tick, |&t| sample(plan, &mut cursor, t));
        finite &= x.is_finite();
        stage.record(counts);
    }
    if !finite {
        fail("route sample not finite");
    }
    stage.report(cal);
}

/// Plans timed: 20 (each a whole 64-waypoint plan).
const PLANS: usize = 20;

#[inline(never)]
fn replan(
    plan: &mut RoutePlan,
    waypoints: &[Waypoint; ROUTE_CAPACITY],
    limits: &RouteLimits,
) -> Result<(), wmr_core::reference::route::RouteError> {
    plan.replan(waypoints, limits, PERIOD_S)
}

/// One sample's reference position `x + y` (all of it computed).
#[inline(never)]
fn sample(plan: &RoutePlan, cursor: &mut RouteCursor, tick: u32) -> f32 {
    let s = plan.sample(cursor, tick);
    s.reference.position.x + s.reference.position.y + s.reference.velocity.x
}
