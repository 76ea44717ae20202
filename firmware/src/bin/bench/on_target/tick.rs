//! Paper 001's robot along the figure-eight: each stage of its tick timed on
//! its own, then the whole tick over the HIL link's proxies and its stack
//! (item 3 of the bench's documentation, `main.rs`).

use core::hint::black_box;

use cortex_m_semihosting::hprintln;
use wmr_core::control::saturated::{TrackingCommand, TrackingController, TrackingGains};
use wmr_core::devices::{MotorDriver, MotorWiring, RfidReader, TagGrid, encode_frame};
use wmr_core::drive::{SpeedLoopGains, WheelSpeedLoop};
use wmr_core::estimation::heading_observer::HeadingObserver;
use wmr_core::geometry::HeadingEstimate;
use wmr_core::geometry::{BodyVelocity, DiffDriveGeometry, Vec2};
use wmr_core::odometry::{OdometryStep, WrappingCounter};
use wmr_core::pilot::robot::Robot;
use wmr_core::pilot::robot::RobotTick;
use wmr_core::pilot::tracker::TagFix;
use wmr_core::pilot::{Measurement, Pilot, PilotOutput};
use wmr_core::reference::ReferenceSample;
use wmr_link::TickInput;
use wmr_link::proxy::{ProxyBus, Side};
use wmr_link::session::{ProxyRobot, SessionFloor};

use super::fail;
use super::stack::stack_bytes;
use super::stage::Stage;
use super::timing::SAMPLES;
use super::timing::{Calibration, timed};
use super::world::{GRID, PERIOD_S, Reading, World, pilot_spec};

/// Ticks run before sampling starts (observer and loops settle).
pub(super) const WARMUP_TICKS: u32 = 20;
/// Ticks whose stack is measured (the maximum is reported).
pub(super) const STACK_TICKS: u32 = 10;
/// PWM full scale of the motor proxies, steps.
const PWM_MAX_DUTY: u16 = 1000;

#[inline(never)]
fn odometry(
    counters: &mut [WrappingCounter; 2],
    &(geometry, raw, dt_s): &(DiffDriveGeometry, [u32; 2], f32),
) -> OdometryStep {
    let [left, right] = counters;
    let dl = left.delta(raw[0]);
    let dr = right.delta(raw[1]);
    OdometryStep::from_counts(&geometry, dl, dr, dt_s)
}

#[inline(never)]
fn observer_update(
    observer: &mut HeadingObserver,
    &(body, delta_position): &(BodyVelocity, Vec2),
) -> HeadingEstimate {
    observer.update(body, delta_position);
    observer.estimate()
}

#[inline(never)]
fn output_feedback(
    law: &mut TrackingController,
    (reference, position, estimate): &(ReferenceSample, Vec2, HeadingEstimate),
) -> TrackingCommand {
    law.output_feedback(reference, *position, *estimate)
}

#[inline(never)]
fn speed_loop(
    speed_loop: &mut WheelSpeedLoop,
    (gains, period_s, target_rad_s, measured_rad_s): &(SpeedLoopGains, f32, f32, Option<f32>),
) -> f32 {
    speed_loop.update(gains, *period_s, *target_rad_s, *measured_rad_s)
}

#[inline(never)]
fn pilot_step(pilot: &mut Pilot, measurement: &Measurement) -> PilotOutput {
    pilot.step(measurement)
}

#[inline(never)]
pub(super) fn robot_tick(robot: &mut ProxyRobot<'_>) -> RobotTick {
    robot.tick()
}

/// The firmware's robot on the HIL link's proxies of `bus` (reset to
/// [`PWM_MAX_DUTY`]), as a HIL session builds it.
pub(super) fn proxy_robot(bus: &ProxyBus, pilot: Pilot, grid: TagGrid) -> ProxyRobot<'_> {
    bus.reset(PWM_MAX_DUTY);
    let motor = |side| {
        MotorDriver::new(
            bus.pwm(side),
            bus.direction_pin(side),
            MotorWiring::default(),
        )
    };
    Robot::new(
        pilot,
        (bus.encoder(Side::Left), bus.encoder(Side::Right)),
        (motor(Side::Left), motor(Side::Right)),
        RfidReader::new(bus.uart()),
        SessionFloor::Grid(grid),
    )
}

/// Paper 001's robot along the figure-eight: each stage of its tick
/// timed on its own, then the whole tick and its stack (item 3 of the
/// bench's documentation, `main.rs`). In a function of its own, as
/// [`bench_fusion_tick`] is, so that the two robots and their samples
/// never take stack at the same time.
///
/// [`bench_fusion_tick`]: super::fusion_tick::bench_fusion_tick
#[inline(never)]
pub(super) fn bench_tick(cal: Calibration) {
    let spec = pilot_spec(wmr_core::estimation::spec::EstimatorSpec::HeadingObserver);
    let (Ok(config), Ok(grid)) = (spec.build(), GRID.build()) else {
        fail("bench configuration refused");
    };
    let [k1, k2, k3] = spec.tracker.gains;
    let (Ok(pilot), Ok(gains)) = (Pilot::new(config), TrackingGains::new(k1, k2, k3)) else {
        fail("bench pilot refused");
    };
    let drive = *config.drive();
    let geometry = *drive.geometry();
    let mut world = World::new(&config, grid);

    // Stage by stage, each with its own state, fed from the world and
    // from the previous stage's output.
    let Ok(counter) = WrappingCounter::new(spec.encoder_bits) else {
        fail("bench counter refused");
    };
    let mut counters = [counter; 2];
    // Paper 001's observer (5): the firmware's fusion estimator runs it
    // as its heading guide.
    let Some(observer) = config.tracker().estimator().heading_observer() else {
        fail("bench estimator runs no observer (5)");
    };
    let mut observer = HeadingObserver::new(observer);
    let mut law = TrackingController::new(gains);
    let mut wheel_loop = WheelSpeedLoop::default();
    let mut lone_pilot = pilot.clone();

    // The whole tick: the firmware's robot on the HIL link's proxies.
    let bus = ProxyBus::new();
    let mut robot = proxy_robot(&bus, pilot, grid);
    let load = |r: &Reading| {
        let Ok(uart) = heapless::Vec::from_slice(&encode_frame(r.tag)) else {
            fail("RFID frame does not fit a tick's UART bytes");
        };
        bus.load(&TickInput {
            tick: r.tick,
            left_count: Some(r.counts[0]),
            right_count: Some(r.counts[1]),
            uart,
        });
    };

    let mut stages = [
        Stage::new("odometry"),
        Stage::new("heading_observer"),
        Stage::new("output_feedback"),
        Stage::new("wheel_speed_loop"),
        Stage::new("pilot_step"),
        Stage::new("robot_tick"),
    ];
    let mut previous_tag = None;
    let mut estimate = HeadingEstimate::default();
    for k in 0..WARMUP_TICKS + SAMPLES as u32 {
        let r = world.reading(k);
        let mut c = [0_u32; 6];

        let odo;
        (c[0], odo) = timed(&(geometry, r.counts, PERIOD_S), |i| {
            odometry(&mut counters, i)
        });
        if let Some(previous) = previous_tag {
            (c[1], estimate) = timed(&(odo.body, r.tag_position - previous), |i| {
                observer_update(&mut observer, i)
            });
        }
        previous_tag = Some(r.tag_position);
        let command;
        (c[2], command) = timed(&(r.reference, r.tag_position, estimate), |i| {
            output_feedback(&mut law, i)
        });
        let target = geometry.wheels_from_body(command.body).left_rad_s;
        let input = (
            *drive.speed_loop(),
            PERIOD_S,
            target,
            Some(odo.wheels.left_rad_s),
        );
        (c[3], _) = timed(&input, |i| speed_loop(&mut wheel_loop, i));
        let measurement = Measurement {
            left_count: Some(r.counts[0]),
            right_count: Some(r.counts[1]),
            fix: Some(TagFix {
                position: r.tag_position,
                age_ticks: 0,
            }),
        };
        (c[4], _) = timed(&measurement, |m| pilot_step(&mut lone_pilot, m));
        load(&r);
        (c[5], _) = timed(&(), |()| robot_tick(&mut robot));

        if k >= WARMUP_TICKS {
            for (stage, &counts) in stages.iter_mut().zip(&c) {
                stage.record(counts);
            }
        }
    }
    for stage in &stages {
        stage.report(cal);
    }
    let mut peak = Some(0_u32);
    for k in 0..STACK_TICKS {
        let r = world.reading(WARMUP_TICKS + SAMPLES as u32 + k);
        load(&r);
        let tick = stack_bytes(|| {
            black_box(robot_tick(black_box(&mut robot)));
        });
        peak = peak.zip(tick).map(|(a, b)| a.max(b));
    }
    match peak {
        Some(bytes) => hprintln!("stack robot_tick bytes={}", bytes),
        None => fail("the tick used the whole painted stack window"),
    }

    // The robot must have run the whole path: a frame and a fix every
    // tick, no device fault.
    let rfid = robot.rfid_counters();
    let faults = robot.counters();
    let fixes = robot.pilot().tracker().counters().fixes_used;
    hprintln!(
        "check frames_ok={} unknown_tags={} encoder_errors={} fixes_used={}",
        rfid.frames_ok,
        faults.unknown_tags,
        faults.left_encoder_errors + faults.right_encoder_errors,
        fixes
    );
    let ticks = WARMUP_TICKS + SAMPLES as u32 + STACK_TICKS;
    if rfid.frames_ok != ticks || fixes + 1 < ticks || faults != Default::default() {
        fail("the bench robot did not read a tag and track every tick");
    }
}
