//! On-target benchmark: instructions per call of the control tick and of its
//! stages, and of paper 004's filter steps, and the peak stack of one tick
//! and of each filter step, under QEMU.
//!
//! Run by `cargo xtask bench-target`, which builds it for each math backend
//! and runs
//!
//! ```text
//! qemu-system-arm -M netduinoplus2 -icount shift=0 -nographic \
//!     -semihosting-config enable=on,target=native -kernel <ELF>
//! ```
//!
//! # Method
//! With `-icount shift=0` QEMU advances its virtual clock by exactly 1 ns per
//! guest instruction, and SysTick on the core clock (168 MHz on
//! `netduinoplus2`) counts that clock: 0.168 SysTick counts per instruction,
//! deterministic whatever the host's speed. The binary
//!
//! 1. calibrates counts per instruction against a `subs`/`bne` loop (2
//!    instructions per iteration; cross-checked with a block of `nop`s) and
//!    refuses to report if it is not 0.168 (QEMU run without `-icount`);
//! 2. measures the empty measurement (SysTick reads and `black_box`), and
//!    subtracts it from every sample;
//! 3. drives a robot along paper 001's figure-eight (a tag fix and a 14-byte
//!    RFID frame every tick, wrapping 16-bit encoder counters) and times,
//!    each in its own `#[inline(never)]` function with its inputs through
//!    `black_box`: the odometry (two counter deltas and `OdometryStep::
//!    from_counts`), the heading observer update, the output-feedback law,
//!    one wheel speed loop, `Pilot::step`, and the whole `Robot::tick` over
//!    the HIL link's proxy devices (encoders, RFID frame parsing, tag
//!    lookup, pilot, both motor drivers); with the cargo feature
//!    `fusion-ekf`, the same whole tick of a second robot whose tracker
//!    runs the fusion EKF estimator (`EstimatorSpec::Fusion`, default
//!    settings) and reads a tag frame every other tick only, its ticks
//!    with a tag fix and its dead-reckoned ticks reported apart
//!    (`robot_tick_fusion_fix`, `robot_tick_fusion_dead_reckoned`; the fix
//!    ticks include the filter's corrections, when the tag changed);
//! 4. times paper 004's nonlinear filters, a predict then an update each
//!    5 ms step, each call in its own `#[inline(never)]` function: the EKF,
//!    the UKF (`MerweScaledSigmaPoints::paper()`) and the particle filter
//!    (100 particles; `pf3`/`pf5` with the paper's prior proposal,
//!    `pf3o`/`pf5o` with the slip scenarios' optimal proposal and
//!    regularization) on `PoseModel` (N = M = 3, scenario 1) and on
//!    `PoseWheelModel` (N = M = 5, scenario 2), set up as
//!    `host_tests::paper_004` sets them up, while paper 004's tracked robot
//!    drives an arc (0.5 m/s, 0.25 rad/s) and its whole state is measured
//!    with deterministic uniform pseudo-noise of `R`'s variances; sampling
//!    starts after 2 s (the particle filters converge from their prior in
//!    about 1 s). Each filter must skip no step and track the robot (RMS
//!    position error below the measurements');
//! 5. plans a route of 64 waypoints in place (`route_plan`) and samples it
//!    at 200 ticks spread over its duration (`route_sample`), then runs
//!    the whole tick of item 3 on a route through the figure-eight
//!    (`Pilot::step_route`: `robot_tick_route`, in a build with the
//!    feature `bench-route-tick` of its own);
//! 6. runs the MAVLink endpoint's part of a tick (`wmr_link::mavlink_run`)
//!    as the Black Pill runs it, with telemetry at 10 Hz and a ground
//!    station's heartbeat arriving at 1 Hz, averaged over 2 s of ticks
//!    (`mavlink_tick`), and the MAVLink USART's interrupt handler
//!    (`wmr_link::rx_ring::on_interrupt`, the board's) on registers in
//!    RAM for each byte received and sent (`mavlink_usart_interrupt`, per
//!    call; `mavlink_tick_with_interrupts`, a tick with its interrupts;
//!    `on_target/mavlink.rs`);
//! 7. paints a window below the stack pointer, runs one call (a tick, a
//!    filter step) and reports the bytes it used below its caller's stack
//!    pointer.
//!
//! A sample is one call, quantized to one SysTick count (≈ 6 instructions):
//! the mean over the samples (whose start phases differ) is good to about
//! an instruction, median/min/max to ±6. Counts include the call and the
//! loading of the arguments. Instructions are a proxy for Cortex-M4 cycles,
//! not cycles (QEMU models no wait states, pipeline or FPU latencies).
//!
//! # Output (semihosting, one record a line)
//! ```text
//! wmr-bench backend=<f32|libm|micromath> samples=<n> machine=<netduinoplus2|microbit>
//! calibration counts_per_instruction=<f> loop_counts_per_iteration=<f> nop_counts_per_instruction=<f> overhead_instructions=<f>
//! bench <name> mean=<f> median=<i> min=<i> max=<i> n=<i>
//! stack <filter step> bytes=<i>
//! filter <name> state_bytes=<i> position_rms_error_m=<f> faults=<i> repairs=<i> resamplings=<i> steps=<i>
//! stack robot_tick bytes=<i>
//! stack robot_tick_fusion bytes=<i>      (feature `fusion-ekf`)
//! done
//! ```
//! then the program exits through semihosting (status 0, or 1 on failure).
//!
//! # Modules
//! The entry (below) runs, in this order, the modules of `on_target/`:
//! `tick.rs` (paper 001's robot, stage by stage and whole, on `world.rs`),
//! `fusion_tick.rs` (the fusion estimator's whole tick), `math_backend.rs`,
//! `route.rs` (planning and sampling a 64-waypoint route), `mavlink.rs`
//! (the MAVLink endpoint's tick), `paper_004.rs`
//! and `fusion_filters.rs` (the filters, on the arc of `filters.rs`). `timing.rs` counts instructions and calibrates,
//! `stage.rs` reports a stage's samples and `stack.rs` measures stack.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
// The Cortex-M0 build leaves the filter benches out (`main`).
#[cfg_attr(not(target_abi = "eabihf"), allow(dead_code, unused_imports))]
mod on_target {
    mod filters;
    mod fusion_filters;
    mod fusion_tick;
    mod math_backend;
    // Not in the Cortex-M0 bench (`wmr-bench-m0` has no `wmr-mavlink`;
    // its 16 KiB of RAM hold no route store beside the bench).
    #[cfg(target_abi = "eabihf")]
    mod mavlink;
    mod paper_004;
    mod route;
    #[cfg(feature = "bench-route-tick")]
    mod route_tick;
    mod stack;
    mod stage;
    mod tick;
    mod timing;
    mod world;

    use cortex_m::peripheral::syst::SystClkSource;
    use cortex_m_semihosting::debug::{self, EXIT_FAILURE, EXIT_SUCCESS};
    use cortex_m_semihosting::hprintln;
    // Links the device crate: it provides the interrupt vectors (the
    // Cortex-M0 build, `wmr-bench-m0`, uses cortex-m-rt's default table).
    #[cfg(target_abi = "eabihf")]
    use stm32f4xx_hal as _;

    use fusion_filters::bench_fusion;
    #[cfg(all(feature = "fusion-particle-filter", target_abi = "eabihf"))]
    use fusion_tick::FUSION_PF_TICK;
    #[cfg(feature = "fusion-ekf")]
    use fusion_tick::{FUSION_EKF_TICK, bench_fusion_tick};
    use math_backend::bench_math;
    #[cfg(target_abi = "eabihf")]
    use mavlink::bench_mavlink;
    use paper_004::bench_paper_004;
    use route::bench_route;
    #[cfg(feature = "bench-route-tick")]
    use route_tick::bench_route_tick;
    use tick::bench_tick;
    use timing::SAMPLES;
    use timing::{MACHINE, SYSTICK_MASK, calibrate};

    /// Math backend this binary was built with.
    const BACKEND: &str = if cfg!(feature = "micromath") {
        "micromath"
    } else if cfg!(feature = "libm") {
        "libm"
    } else {
        "f32"
    };

    fn fail(why: &str) -> ! {
        hprintln!("error {}", why);
        debug::exit(EXIT_FAILURE);
        loop {
            cortex_m::asm::wfi();
        }
    }

    #[cortex_m_rt::entry]
    fn main() -> ! {
        let Some(mut cp) = cortex_m::Peripherals::take() else {
            fail("core peripherals already taken");
        };
        cp.SYST.set_clock_source(SystClkSource::Core);
        cp.SYST.set_reload(SYSTICK_MASK);
        cp.SYST.clear_current();
        cp.SYST.enable_counter();

        hprintln!(
            "wmr-bench backend={} samples={} machine={}",
            BACKEND,
            SAMPLES,
            MACHINE
        );
        let cal = calibrate();

        bench_tick(cal);
        #[cfg(feature = "fusion-ekf")]
        bench_fusion_tick(cal, &FUSION_EKF_TICK);
        #[cfg(all(feature = "fusion-particle-filter", target_abi = "eabihf"))]
        bench_fusion_tick(cal, &FUSION_PF_TICK);
        bench_math(cal);
        // The filters' states and stacks (up to 5 KB and 2.4 KB each) and
        // a route plan (20 KB) do not fit beside the bench in the nRF51's
        // 16 KiB of RAM: the M0 measures the ticks and the math only.
        #[cfg(target_abi = "eabihf")]
        {
            bench_route(cal);
            bench_mavlink(cal);
            // A build of its own (feature `bench-route-tick`), so that
            // the other rows measure a firmware without routes.
            #[cfg(feature = "bench-route-tick")]
            bench_route_tick(cal);
            bench_paper_004(cal);
            bench_fusion(cal);
        }
        hprintln!("done");
        debug::exit(EXIT_SUCCESS);
        loop {
            cortex_m::asm::wfi();
        }
    }

    #[panic_handler]
    fn panic(info: &core::panic::PanicInfo) -> ! {
        hprintln!("error panic: {}", info);
        debug::exit(EXIT_FAILURE);
        loop {
            cortex_m::asm::wfi();
        }
    }
}

/// On the host this binary is a stub, so that workspace-wide host commands
/// pass over it.
#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!(
        "wmr-bench runs on a microcontroller under QEMU: use `cargo xtask bench-target` \
         (thumbv7em-none-eabihf)"
    );
    std::process::exit(2);
}
