//! The whole tick of a robot whose tracker runs the fusion estimator, its
//! ticks with a tag fix and its dead-reckoned ticks reported apart (item 3
//! of the bench's documentation, `main.rs`).

use core::hint::black_box;

use cortex_m_semihosting::hprintln;
use wmr_core::devices::encode_frame;
use wmr_core::pilot::Pilot;
use wmr_link::TickInput;
use wmr_link::proxy::ProxyBus;

use super::fail;
use super::stack::stack_bytes;
use super::stage::Stage;
use super::tick::{STACK_TICKS, WARMUP_TICKS, proxy_robot, robot_tick};
use super::timing::SAMPLES;
use super::timing::{Calibration, timed};
use super::world::{GRID, Reading, World, pilot_spec};

/// One whole-tick bench of the fusion estimator: its filter and the
/// names its figures are reported under.
#[cfg(feature = "fusion-ekf")]
pub(super) struct FusionTick {
    filter: wmr_core::estimation::spec::FusionFilterSpec,
    /// Stage of the ticks with a tag fix.
    fix: &'static str,
    /// Stage of the dead-reckoned ticks.
    dead_reckoned: &'static str,
    /// Name of its stack line.
    stack: &'static str,
}

/// The fusion EKF's whole tick (the estimator's default filter).
#[cfg(feature = "fusion-ekf")]
pub(super) const FUSION_EKF_TICK: FusionTick = FusionTick {
    filter: wmr_core::estimation::spec::FusionFilterSpec::Ekf,
    fix: "robot_tick_fusion_fix",
    dead_reckoned: "robot_tick_fusion_dead_reckoned",
    stack: "robot_tick_fusion",
};

/// The fusion particle filter's whole tick: with the bench's reader of
/// the nearest tag, each read is the particles' cell likelihood (what a
/// robot built with `fusion-particle-filter` runs).
#[cfg(all(feature = "fusion-particle-filter", target_abi = "eabihf"))]
pub(super) const FUSION_PF_TICK: FusionTick = FusionTick {
    filter: wmr_core::estimation::spec::FusionFilterSpec::ParticleFilter,
    fix: "robot_tick_fusion_pf_fix",
    dead_reckoned: "robot_tick_fusion_pf_dead_reckoned",
    stack: "robot_tick_fusion_pf",
};

/// The whole tick with the fusion estimator (`EstimatorSpec::Fusion`,
/// default settings but `bench.filter`) on its own proxies, over the
/// same readings as paper 001's robot in [`bench_tick`] (the same
/// world, from its first tick), but a tag frame on even ticks only: its
/// ticks with a fix and its dead-reckoned ticks are reported apart,
/// then its stack over fix and dead-reckoned ticks alike. In a function
/// of its own, so that its robot and its samples take stack only while
/// it runs (the Cortex-M0 has 16 KiB of RAM in all).
///
/// [`bench_tick`]: super::tick::bench_tick
#[cfg(feature = "fusion-ekf")]
#[inline(never)]
pub(super) fn bench_fusion_tick(cal: Calibration, bench: &FusionTick) {
    let spec = pilot_spec(wmr_core::estimation::spec::EstimatorSpec::Fusion(
        wmr_core::estimation::spec::FusionSpec {
            filter: bench.filter,
            ..Default::default()
        },
    ));
    let (Ok(config), Ok(grid)) = (spec.build(), GRID.build()) else {
        fail("bench fusion configuration refused");
    };
    let Ok(pilot) = Pilot::new(config) else {
        fail("bench fusion pilot refused");
    };
    let mut world = World::new(&config, grid);
    let bus = ProxyBus::new();
    let mut robot = proxy_robot(&bus, pilot, world.grid);
    // Loads the proxies with `r`, its tag frame on even ticks only;
    // whether it carries one.
    let load = |r: &Reading| {
        let frame = r.tick.is_multiple_of(2);
        let uart = if frame {
            let Ok(uart) = heapless::Vec::from_slice(&encode_frame(r.tag)) else {
                fail("RFID frame does not fit a tick's UART bytes");
            };
            uart
        } else {
            heapless::Vec::new()
        };
        bus.load(&TickInput {
            tick: r.tick,
            left_count: Some(r.counts[0]),
            right_count: Some(r.counts[1]),
            uart,
        });
        frame
    };
    let mut frames = 0_u32;
    let mut stages = [Stage::new(bench.fix), Stage::new(bench.dead_reckoned)];
    for k in 0..WARMUP_TICKS + SAMPLES as u32 {
        let r = world.reading(k);
        let frame = load(&r);
        frames += u32::from(frame);
        let (counts, _) = timed(&(), |()| robot_tick(&mut robot));
        if k >= WARMUP_TICKS {
            let [fix, dead_reckoned] = &mut stages;
            if frame { fix } else { dead_reckoned }.record(counts);
        }
    }
    for stage in &stages {
        stage.report(cal);
    }
    let mut peak = Some(0_u32);
    for k in 0..STACK_TICKS {
        let r = world.reading(WARMUP_TICKS + SAMPLES as u32 + k);
        frames += u32::from(load(&r));
        let tick = stack_bytes(|| {
            black_box(robot_tick(black_box(&mut robot)));
        });
        peak = peak.zip(tick).map(|(a, b)| a.max(b));
    }
    match peak {
        Some(bytes) => hprintln!("stack {} bytes={}", bench.stack, bytes),
        None => fail("the fusion tick used the whole painted stack window"),
    }
    // Every frame read and used, no device fault, never in the
    // failsafe, the filter correcting with some fixes.
    let rfid = robot.rfid_counters();
    let faults = robot.counters();
    let tracker = robot.pilot().tracker().counters();
    hprintln!(
        "check {} frames_ok={} fixes_used={} failsafe_entries={} fixes_gated={}",
        bench.stack,
        rfid.frames_ok,
        tracker.fixes_used,
        tracker.failsafe_entries,
        tracker.fixes_gated
    );
    if rfid.frames_ok != frames
        || tracker.fixes_used + 1 < frames
        || faults != Default::default()
        || tracker.failsafe_entries != 0
    {
        fail("the fusion bench robot did not read its tags and track");
    }
}
