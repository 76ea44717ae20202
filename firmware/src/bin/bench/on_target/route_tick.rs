//! The whole tick on a route (`robot_tick_route`): the whole tick of
//! `tick.rs` through `Pilot::step_route`. Built only with the feature
//! `bench-route-tick`, in a build of its own, so that the other rows
//! measure a firmware without routes (`firmware/Cargo.toml`).

use wmr_core::devices::encode_frame;
use wmr_core::pilot::Pilot;
use wmr_core::pilot::robot::RobotTick;
use wmr_core::pilot::route::{RouteFollower, RouteOptions, RouteStart};
use wmr_core::reference::route::{
    ROUTE_CAPACITY, RouteLimits, RouteLimitsSpec, Waypoint, Waypoints,
};
use wmr_link::TickInput;
use wmr_link::proxy::ProxyBus;
use wmr_link::session::ProxyRobot;

use super::fail;
use super::route::LIMITS;
use super::stage::Stage;
use super::tick::{WARMUP_TICKS, proxy_robot};
use super::timing::Calibration;
use super::timing::SAMPLES;
use super::timing::timed;
use super::world::{GRID, World, pilot_spec};

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
    robot.tick_on(Some(follower))
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
