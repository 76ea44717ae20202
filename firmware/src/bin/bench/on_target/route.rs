//! The route reference (`wmr_core::reference::route`): planning a route of
//! [`ROUTE_CAPACITY`] waypoints in place, and sampling it once a tick;
//! and the whole tick on a route ([`bench_route_tick`]).
//!
//! The route is the host tests' cost route (`planning_and_sampling_costs_on_the_host`
//! in `core/src/reference/route/tests.rs`): 64 waypoints on two
//! interleaved circles of 10 m and 13 m radius, 0.4 rad apart, every
//! eighth a 0.5 s stop facing its bearing (so with pivots), the last a
//! stop. The plan lives in `.bss` (a `RoutePlan` is about 20 KB), not on
//! the stack, as a robot keeps it.

use wmr_core::devices::encode_frame;
use wmr_core::geometry::Vec2;
use wmr_core::math;
use wmr_core::pilot::Pilot;
use wmr_core::pilot::robot::RobotTick;
use wmr_core::pilot::route::{RouteFollower, RouteOptions, RouteStart};
use wmr_core::reference::route::{
    ROUTE_CAPACITY, RouteCursor, RouteLimits, RouteLimitsSpec, RoutePlan, Waypoint, Waypoints,
};
use wmr_link::TickInput;
use wmr_link::proxy::ProxyBus;
use wmr_link::session::ProxyRobot;

use super::fail;
use super::stage::Stage;
use super::tick::{WARMUP_TICKS, proxy_robot};
use super::timing::SAMPLES;
use super::timing::{Calibration, timed};
use super::world::{GRID, PERIOD_S, World, pilot_spec};

/// The bench route's limits: 1 m/s, 0.5 m/s² along and 0.8 m/s² across
/// the path, blends 10 cm from their corners, pivots above 0.5 rad at up
/// to 1 rad/s and 2 rad/s².
const LIMITS: RouteLimitsSpec = RouteLimitsSpec {
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

/// The route of the whole tick on a route: the bench's figure-eight
/// sampled every [`TICK_ROUTE_SPACING_S`] (about 0.1 m apart), a pass at
/// each waypoint (a corner blend), a stop at each end, under
/// [`TICK_LIMITS`] (2,513 ticks). The world's robot, on the
/// figure-eight, reads its tags near the route, and the timed ticks
/// (0.2 to 2.2 s, about 0.4 m) cross four legs and their blends.
const TICK_ROUTE_SPACING_S: f32 = 0.5;

/// The whole tick's route limits: the figure-eight's speed (0.2 m/s),
/// 0.5 m/s² along and across, blends 10 µm from their corners (the
/// figure-eight turns about 2.5 mrad a waypoint, and a blend's length is
/// about `3e/φ` for a half-turn `φ`: 24 mm of each 0.1 m leg), pivots as
/// [`LIMITS`].
const TICK_LIMITS: RouteLimitsSpec = RouteLimitsSpec {
    max_speed_m_s: 0.2,
    max_tangential_accel_m_s2: 0.5,
    max_lateral_accel_m_s2: 0.5,
    blend_deviation_m: 1.0e-5,
    ..LIMITS
};

#[inline(never)]
fn robot_route_tick(robot: &mut ProxyRobot<'_>, follower: &mut RouteFollower) -> RobotTick {
    robot.tick(Some(follower))
}

/// The whole tick of `tick.rs` (`robot_tick`: the firmware's robot on the
/// HIL link's proxies, paper 001's pilot, the figure-eight's readings: a
/// tag frame every tick) on a route through the figure-eight instead of
/// the figure-eight itself (`Pilot::step_route`, the follower in `.bss`),
/// timed after the same warm-up (the tick that plans the route is the
/// first, not timed): `robot_tick_route`.
#[inline(never)]
pub(super) fn bench_route_tick(cal: Calibration) {
    let spec = pilot_spec(wmr_core::estimation::spec::EstimatorSpec::HeadingObserver);
    let (Ok(config), Ok(grid), Ok(limits)) =
        (spec.build(), GRID.build(), RouteLimits::new(&TICK_LIMITS))
    else {
        fail("bench route tick configuration refused");
    };
    let Ok(pilot) = Pilot::new(config) else {
        fail("bench pilot refused");
    };
    let trajectory = *config.tracker().trajectory();
    let mut waypoints = Waypoints::new();
    for i in 0..ROUTE_CAPACITY {
        let p = trajectory.sample(i as f32 * TICK_ROUTE_SPACING_S).position;
        let w = if i == 0 || i + 1 == ROUTE_CAPACITY {
            Waypoint::stop(p.x, p.y, 0.0)
        } else {
            Waypoint::pass(p.x, p.y)
        };
        if waypoints.push(w).is_err() {
            fail("bench route does not fit");
        }
    }
    let Some(follower) = cortex_m::singleton!(
        : RouteFollower = RouteFollower::new(RouteOptions::default())
    ) else {
        fail("route follower already taken");
    };
    follower.load(&waypoints, &limits, RouteStart::AsGiven);
    let mut world = World::new(&config, grid);
    let bus = ProxyBus::new();
    let mut robot = proxy_robot(&bus, pilot, grid);
    let mut stage = Stage::new("robot_tick_route");
    for k in 0..WARMUP_TICKS + SAMPLES as u32 {
        let r = world.reading(k);
        let Ok(uart) = heapless::Vec::from_slice(&encode_frame(r.tag)) else {
            fail("RFID frame does not fit a tick's UART bytes");
        };
        bus.load(&TickInput {
            tick: r.tick,
            left_count: Some(r.counts[0]),
            right_count: Some(r.counts[1]),
            uart,
        });
        let (counts, _) = timed(&(), |()| robot_route_tick(&mut robot, follower));
        if k >= WARMUP_TICKS {
            stage.record(counts);
        }
    }
    stage.report(cal);
    // The route must have been planned and followed, moving, with a fix
    // every tick.
    let status = follower.status();
    let counters = follower.counters();
    let fixes = robot.pilot().tracker().counters().fixes_used;
    let ticks = WARMUP_TICKS + SAMPLES as u32;
    if counters.routes_started != 1 || counters.routes_refused != 0 || !status.running {
        fail("the bench route was not planned and followed");
    }
    if fixes + 1 < ticks {
        fail("the bench robot on its route did not use a fix every tick");
    }
}
