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
//! 5. paints a window below the stack pointer, runs one call (a tick, a
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
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
// The Cortex-M0 build leaves the filter benches out (`main`).
#[cfg_attr(not(target_abi = "eabihf"), allow(dead_code, unused_imports))]
mod on_target {
    use core::hint::black_box;

    use cortex_m::peripheral::SYST;
    use cortex_m::peripheral::syst::SystClkSource;
    use cortex_m_semihosting::debug::{self, EXIT_FAILURE, EXIT_SUCCESS};
    use cortex_m_semihosting::hprintln;
    // Links the device crate: it provides the interrupt vectors (the
    // Cortex-M0 build, `wmr-bench-m0`, uses cortex-m-rt's default table).
    #[cfg(target_abi = "eabihf")]
    use stm32f4xx_hal as _;

    use nalgebra::{SMatrix, SVector};
    use wmr_core::control::saturated::{TrackingCommand, TrackingController, TrackingGains};
    use wmr_core::devices::tag_grid::TagGridSpec;
    use wmr_core::devices::{MotorDriver, MotorWiring, RfidReader, TagGrid, TagId, encode_frame};
    use wmr_core::drive::spec::DriveSpec;
    use wmr_core::drive::{SpeedLoopGains, WheelSpeedLoop};
    use wmr_core::estimation::fusion::particle::{ParticleCore, PoseParticleFilter};
    use wmr_core::estimation::fusion::ukf::{PoseUkf, UkfCore};
    use wmr_core::estimation::fusion::{
        EkfCore, PoseEkf, PoseFilter, PoseFilterConfig, PoseFilterCore, PositionMeasurement,
    };
    use wmr_core::estimation::heading_observer::HeadingObserver;
    use wmr_core::filters::ekf::{EkfModel, ExtendedKalmanFilter};
    use wmr_core::filters::particle_filter::{
        ParticleFilter, ParticleFilterConfig, ParticleModel, Proposal,
    };
    use wmr_core::filters::ukf::{
        MerweScaledSigmaPoints, UkfForm, UkfModel, UnscentedKalmanFilter,
    };
    use wmr_core::geometry::HeadingEstimate;
    use wmr_core::geometry::{BodyVelocity, DiffDriveGeometry, Pose, Vec2, WheelSpeeds};
    use wmr_core::math;
    use wmr_core::odometry::{OdometryStep, WrappingCounter};
    use wmr_core::pilot::robot::{Robot, RobotTick};
    use wmr_core::pilot::spec::{PilotSpec, TrackerSpec};
    use wmr_core::pilot::tracker::TagFix;
    use wmr_core::pilot::{Measurement, Pilot, PilotOutput};
    use wmr_core::reference::TrajectorySpec;
    use wmr_core::reference::{ReferenceSample, Trajectory};
    use wmr_link::TickInput;
    use wmr_link::proxy::{ProxyBus, Side};
    use wmr_link::session::{ProxyRobot, SessionFloor};
    use wmr_papers::slip_tracking::{PoseModel, PoseWheelModel, TrackedRobot};

    /// Math backend this binary was built with.
    const BACKEND: &str = if cfg!(feature = "micromath") {
        "micromath"
    } else if cfg!(feature = "libm") {
        "libm"
    } else {
        "f32"
    };

    /// The machine: QEMU's `netduinoplus2` (STM32F405, Cortex-M4F) for
    /// `thumbv7em-none-eabihf`, its `microbit` (nRF51822, Cortex-M0) for
    /// `thumbv6m-none-eabi` (`wmr-bench-m0`).
    const MACHINE: &str = if cfg!(target_abi = "eabihf") {
        "netduinoplus2"
    } else {
        "microbit"
    };
    /// Core clock of the machine, Hz: 168 MHz, 16 MHz.
    const CORE_CLOCK_HZ: f32 = if cfg!(target_abi = "eabihf") {
        168.0e6
    } else {
        16.0e6
    };
    /// Virtual nanoseconds per instruction, `2^shift` of QEMU's `-icount
    /// shift`: 0 on the M4F (0.168 counts per instruction), 6 on the M0 (64
    /// ns: 1.024 counts per instruction, where shift 0 would quantize a
    /// sample to 62 instructions).
    const NS_PER_INSTRUCTION: f32 = if cfg!(target_abi = "eabihf") {
        1.0
    } else {
        64.0
    };
    /// SysTick counts per instruction.
    const EXPECTED_COUNTS_PER_INSTRUCTION: f32 = CORE_CLOCK_HZ * NS_PER_INSTRUCTION * 1.0e-9;
    /// SysTick is a 24-bit down-counter.
    const SYSTICK_MASK: u32 = 0x00FF_FFFF;

    /// Timed calls per stage.
    const SAMPLES: usize = 200;
    /// Ticks run before sampling starts (observer and loops settle).
    const WARMUP_TICKS: u32 = 20;
    /// Ticks whose stack is measured (the maximum is reported).
    const STACK_TICKS: u32 = 10;
    /// Bytes painted below the stack pointer before a stack-measured tick
    /// (the nRF51 has 16 KiB of RAM in all).
    const STACK_WINDOW_BYTES: usize = if cfg!(target_abi = "eabihf") {
        16 * 1024
    } else {
        8 * 1024
    };
    /// Instructions in the `nop` block of the cross-check.
    const NOP_BLOCK: u32 = 4000;

    /// The control period, s.
    const PERIOD_S: f32 = 0.01;
    /// PWM full scale of the motor proxies, steps.
    const PWM_MAX_DUTY: u16 = 1000;

    /// Paper 001's figure-eight and observer gain, on a small robot (as
    /// `host_tests::paper_pilot` and the simulator's defaults).
    fn pilot_spec(estimator: wmr_core::estimation::spec::EstimatorSpec) -> PilotSpec {
        PilotSpec {
            tracker: TrackerSpec {
                period_s: PERIOD_S,
                trajectory: TrajectorySpec::FigureEight {
                    h1_m: 5.0,
                    h2_rad_s: 0.02,
                    phase_rad: -core::f32::consts::FRAC_PI_2,
                },
                gains: [0.11, 0.11, 0.1],
                observer_gain_per_m: 0.6,
                observer_min_speed_m_s: 1.0e-3,
                fix_timeout_ticks: 100,
                failsafe_decel_m_s2: 0.5,
                max_fix_age_ticks: 2,
                estimator,
                law: wmr_core::control::spec::LawSpec::Saturated,
                sensors: wmr_core::estimation::spec::SensorSpec {
                    track_width_m: 0.2,
                    // Count quantum q = 2π·0.03 m / 2048: q²/12.
                    wheel_variance_floor_m2: 7.06e-10,
                    tag_spacing_m: 0.1,
                    read_radius_m: 0.0,
                    antenna_offset_m: [0.0; 2],
                },
            },
            drive: DriveSpec {
                wheel_radius_m: 0.03,
                track_width_m: 0.2,
                encoder_counts_per_rev: 2048,
                max_wheel_speed_rad_s: 20.0,
                max_wheel_accel_rad_s2: 100.0,
                feedforward_duty_per_rad_s: 0.05,
                kp_duty_per_rad_s: 0.02,
                ki_duty_per_rad: 0.1,
                speed_observer: None,
            },
            encoder_bits: 16,
            max_encoder_fault_ticks: 5,
        }
    }

    /// Tags every 10 cm over the figure-eight (±5 m) with a 1 m margin.
    const GRID: TagGridSpec = TagGridSpec {
        origin_m: [-6.0, -6.0],
        spacing_m: 0.1,
        rows: 121,
        columns: 121,
    };

    // ---------------------------------------------------------------- timing

    /// `f(input)` and the SysTick counts it took (the counter runs down and
    /// wraps every 2^24 counts, ≈ 100 ms of virtual time: far longer than
    /// any call).
    ///
    /// `black_box` pins the work between the two reads: `input` is complete
    /// before the first read and opaque to `f`, and the result is taken
    /// before the second read. Inside the window are only the call, the
    /// function, and one `black_box` each way (counted in the empty
    /// measurement).
    #[inline(always)]
    fn timed<I, R>(input: &I, f: impl FnOnce(&I) -> R) -> (u32, R) {
        let input = black_box(input);
        let start = SYST::get_current();
        let result = black_box(f(black_box(input)));
        let end = SYST::get_current();
        (start.wrapping_sub(end) & SYSTICK_MASK, result)
    }

    /// `iterations` (≥ 1) turns of a `subs`/`bne` loop: 2 instructions each.
    #[inline(never)]
    fn spin(iterations: u32) {
        let iterations = iterations.max(1);
        // SAFETY: a countdown in one register; it touches no memory, no
        // stack and no other register, and ends (iterations ≥ 1).
        #[allow(unsafe_code)]
        unsafe {
            core::arch::asm!(
                "2:",
                "subs {n}, {n}, #1",
                "bne 2b",
                n = inout(reg) iterations => _,
                options(nomem, nostack),
            );
        }
    }

    /// Exactly [`NOP_BLOCK`] `nop`s.
    #[inline(never)]
    fn nops() {
        // SAFETY: `nop`s only.
        #[allow(unsafe_code)]
        unsafe {
            core::arch::asm!(
                ".rept {n}",
                "nop",
                ".endr",
                n = const NOP_BLOCK,
                options(nomem, nostack, preserves_flags),
            );
        }
    }

    /// Mean of SysTick counts over `n` runs of `f`.
    fn mean_counts(n: u32, mut f: impl FnMut() -> u32) -> f32 {
        let total: u64 = (0..n).map(|_| u64::from(f())).sum();
        total as f32 / n as f32
    }

    /// Counts → instructions.
    #[derive(Clone, Copy)]
    struct Calibration {
        counts_per_instruction: f32,
        overhead_instructions: f32,
    }

    impl Calibration {
        fn instructions(self, counts: f32) -> f32 {
            counts / self.counts_per_instruction - self.overhead_instructions
        }
    }

    /// Per-call SysTick counts of one stage.
    struct Stage {
        name: &'static str,
        counts: [u32; SAMPLES],
        n: usize,
    }

    impl Stage {
        const fn new(name: &'static str) -> Self {
            Self {
                name,
                counts: [0; SAMPLES],
                n: 0,
            }
        }

        fn record(&mut self, counts: u32) {
            if let Some(slot) = self.counts.get_mut(self.n) {
                *slot = counts;
                self.n += 1;
            }
        }

        fn report(&self, cal: Calibration) {
            let Some(samples) = self.counts.get(..self.n).filter(|s| !s.is_empty()) else {
                hprintln!("bench {} no-samples", self.name);
                return;
            };
            let mut sorted = [0_u32; SAMPLES];
            let sorted = &mut sorted[..samples.len()];
            sorted.copy_from_slice(samples);
            sorted.sort_unstable();
            let total: u64 = samples.iter().map(|&c| u64::from(c)).sum();
            let instr = |c: u32| nearest(cal.instructions(c as f32));
            hprintln!(
                "bench {} mean={:.1} median={} min={} max={} n={}",
                self.name,
                cal.instructions(total as f32 / samples.len() as f32),
                instr(sorted[sorted.len() / 2]),
                instr(sorted[0]),
                instr(sorted[sorted.len() - 1]),
                samples.len()
            );
        }
    }

    /// Nearest integer (of a value that fits an `i32`).
    fn nearest(x: f32) -> i32 {
        math::floor(x + 0.5) as i32
    }

    // ------------------------------------------------------------- the world

    /// One tick of the world: the robot on the reference, its encoders, the
    /// tag under it.
    struct Reading {
        tick: u32,
        reference: ReferenceSample,
        counts: [u32; 2],
        tag: TagId,
        tag_position: Vec2,
    }

    /// A robot driving exactly along the reference (its wheels integrate
    /// the reference's `v`, `ω`), reading the nearest floor tag every tick.
    struct World {
        trajectory: Trajectory,
        geometry: DiffDriveGeometry,
        grid: TagGrid,
        wheel_angle_rad: [f32; 2],
    }

    /// Encoder counters start here, so that they wrap at 16 bits early on.
    const COUNTER_START: i32 = 65_000;

    impl World {
        /// The world of a bench pilot's `config` on the tag `grid`.
        fn new(config: &wmr_core::pilot::PilotConfig, grid: TagGrid) -> Self {
            Self {
                trajectory: *config.tracker().trajectory(),
                geometry: *config.drive().geometry(),
                grid,
                wheel_angle_rad: [0.0; 2],
            }
        }

        fn reading(&mut self, tick: u32) -> Reading {
            let reference = self.trajectory.sample(tick as f32 * PERIOD_S);
            let vel = reference.velocity;
            let acc = reference.acceleration;
            let v = vel.norm();
            let omega = if v > 1e-6 {
                (vel.x * acc.y - vel.y * acc.x) / (v * v)
            } else {
                0.0
            };
            let wheels = self.geometry.wheels_from_body(BodyVelocity {
                v_m_s: v,
                omega_rad_s: omega,
            });
            let [left, right] = &mut self.wheel_angle_rad;
            *left += wheels.left_rad_s * PERIOD_S;
            *right += wheels.right_rad_s * PERIOD_S;
            let count = |angle: f32| {
                let counts = nearest(angle / self.geometry.rad_per_count());
                COUNTER_START.wrapping_add(counts).cast_unsigned() & 0xFFFF
            };
            let counts = [count(*left), count(*right)];
            let origin = self.grid.origin();
            let spacing = self.grid.spacing_m();
            let cell = |x: f32, n: u16| nearest(x / spacing).clamp(0, i32::from(n) - 1) as u16;
            let column = cell(reference.position.x - origin.x, self.grid.columns());
            let row = cell(reference.position.y - origin.y, self.grid.rows());
            let tag = TagGrid::id(row, column);
            let tag_position = self.grid.position(tag).unwrap_or(reference.position);
            Reading {
                tick,
                reference,
                counts,
                tag,
                tag_position,
            }
        }
    }

    // ------------------------------------------------------- timed functions

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
    fn robot_tick(robot: &mut ProxyRobot<'_>) -> RobotTick {
        robot.tick()
    }

    /// Bytes of stack `f` uses below this function's stack pointer; `None`
    /// if it used the whole painted window. `f` should be one call of an
    /// `#[inline(never)]` function (its arguments prepared by the caller).
    #[inline(never)]
    fn stack_bytes(f: impl FnOnce()) -> Option<u32> {
        let paint = cortex_m_rt::STACK_PAINT_VALUE;
        // The stack region's low end: cortex-m-rt's linker symbol (set by
        // flip-link too, when the stack is placed below the statics); only
        // its address is used.
        #[allow(unsafe_code)]
        unsafe extern "C" {
            static _stack_end: u32;
        }
        let floor = (&raw const _stack_end) as usize;
        let sp = cortex_m::register::msp::read() as usize;
        let window = STACK_WINDOW_BYTES.min(sp.saturating_sub(floor)) & !3;
        let bottom = sp - window;
        // SAFETY: writes `paint` to the words of [bottom, sp): free stack
        // below this function's frame (the stack pointer of a Rust function
        // does not move after its prologue) and above the statics; no
        // interrupt is enabled, so nothing else uses that memory now. The
        // loop uses registers only.
        #[allow(unsafe_code)]
        unsafe {
            core::arch::asm!(
                "2:",
                "cmp {p}, {top}",
                "bhs 3f",
                "str {v}, [{p}]",
                "adds {p}, {p}, #4",
                "b 2b",
                "3:",
                p = inout(reg) bottom => _,
                top = in(reg) sp,
                v = in(reg) paint,
                options(nostack),
            );
        }
        f();
        let mut addr = bottom;
        while addr < sp {
            // SAFETY: `addr` is word-aligned (sp is, and the window is a
            // multiple of 4) and inside the RAM just painted; a volatile
            // read of RAM has no side effects.
            #[allow(unsafe_code)]
            let word = unsafe { core::ptr::read_volatile(addr as *const u32) };
            if word != paint {
                break;
            }
            addr += 4;
        }
        (addr > bottom).then(|| u32::try_from(sp - addr).unwrap_or(u32::MAX))
    }

    /// One math-backend call per sample, over a spread of arguments.
    fn bench_math(cal: Calibration) {
        type MathFn = fn(&[f32; 2]) -> f32;
        type Arguments = fn(usize) -> [f32; 2];
        /// `k`-th of `SAMPLES` points spread over `[a, b]`.
        fn spread(k: usize, a: f32, b: f32) -> f32 {
            a + (b - a) * k as f32 / (SAMPLES - 1) as f32
        }
        let cases: [(&str, MathFn, Arguments); 7] = [
            (
                "math_sin",
                |x| math::sin(x[0]),
                |k| [spread(k, -3.2, 3.2), 0.0],
            ),
            (
                "math_cos",
                |x| math::cos(x[0]),
                |k| [spread(k, -3.2, 3.2), 0.0],
            ),
            (
                "math_sincos",
                |x| {
                    let (s, c) = math::sincos(x[0]);
                    s + c
                },
                |k| [spread(k, -3.2, 3.2), 0.0],
            ),
            (
                "math_atan",
                |x| math::atan(x[0]),
                |k| [spread(k, -4.0, 4.0), 0.0],
            ),
            (
                "math_atan2",
                |x| math::atan2(x[0], x[1]),
                |k| {
                    let a = spread(k, -3.1, 3.1);
                    [math::sin(a), math::cos(a)]
                },
            ),
            (
                "math_exp",
                |x| math::exp(x[0]),
                |k| [spread(k, -0.2, 0.0), 0.0],
            ),
            (
                "math_sqrt",
                |x| math::sqrt(x[0]),
                |k| [spread(k, 0.01, 50.0), 0.0],
            ),
        ];
        for (name, f, input) in cases {
            let mut stage = Stage::new(name);
            for k in 0..SAMPLES {
                stage.record(timed(&input(k), |x| call_math(f, x)).0);
            }
            stage.report(cal);
        }
    }

    /// A math function behind a call, as the core calls it.
    #[inline(never)]
    fn call_math(f: fn(&[f32; 2]) -> f32, x: &[f32; 2]) -> f32 {
        f(x)
    }

    // ------------------------------------------------- paper 004's filters

    /// Paper 004's step `h`, s.
    const FILTER_STEP_S: f32 = 0.005;
    /// The arc the filters' robot drives (turning radius 2 m).
    const ARC: BodyVelocity = BodyVelocity {
        v_m_s: 0.5,
        omega_rad_s: 0.25,
    };
    /// Filter steps before sampling starts, 2 s: the particle filters take
    /// about 1 s to converge from their prior (`P0 = 10 I`), and their
    /// resampling rate changes until then.
    const FILTER_WARMUP_STEPS: usize = 400;
    /// `R`: variances of the measured `(X, Y, ψ, ω_L, ω_R)` (paper 004).
    const MEASUREMENT_VARIANCE: [f32; 5] = [0.1, 0.1, 0.2, 0.01, 0.01];
    /// `Q` per step (`host_tests::paper_004::PROCESS_NOISE`).
    const PROCESS_VARIANCE: [f32; 5] = [1e-5, 1e-5, 1e-5, 1e-2, 1e-2];
    /// `P0 = 10 I` (EKF; the particle filter's prior).
    const INITIAL_VARIANCE: [f32; 5] = [10.0; 5];
    /// The UKF's `P0`: heading variance 1 rad² (its circular mean turns
    /// around above ~2 rad², `wmr_core::filters::ukf` docs).
    const UKF_INITIAL_VARIANCE: [f32; 5] = [10.0, 10.0, 1.0, 10.0, 10.0];
    /// Particles (paper 004).
    const PARTICLES: usize = 100;
    /// The particle filter's process noise per step, standard deviations
    /// (`host_tests::paper_004::PARTICLE_PROCESS_STD`).
    const PARTICLE_PROCESS_STD: [f32; 5] = [0.01, 0.01, 0.02, 0.5, 0.5];
    /// The particle filter's generator seed.
    const PARTICLE_SEED: u64 = 4;
    /// Every filter's RMS position error over the sampled steps must stay
    /// below the measurements' own (`√(0.1 + 0.1)` m): no worse than not
    /// filtering. Measured: EKF and UKF 0.015 m, particle filters 0.04 to
    /// 0.22 m (micromath, N = 5).
    const MAX_FILTER_RMS_ERROR_M: f32 = 0.45;

    /// Paper 004's tracked robot (no slip) driving [`ARC`], its whole state
    /// measured every step with deterministic pseudo-noise: uniform, of
    /// `R`'s variances.
    struct Arc {
        pose: Pose,
        wheels: WheelSpeeds,
        /// xorshift32 state.
        noise: u32,
        /// `√(3R)`: a uniform draw on `±√(3R)` has variance `R`.
        noise_half_width: [f32; 5],
    }

    impl Arc {
        fn new(start: Pose) -> Self {
            Self {
                pose: start,
                wheels: TrackedRobot::PAPER.wheels_for(ARC, 1.0),
                noise: 0x2545_F491,
                noise_half_width: MEASUREMENT_VARIANCE.map(|r| math::sqrt(3.0 * r)),
            }
        }

        /// The true `(X, Y, ψ, ω_L, ω_R)`.
        fn state(&self) -> SVector<f32, 5> {
            SVector::<f32, 5>::new(
                self.pose.position.x,
                self.pose.position.y,
                self.pose.heading_rad,
                self.wheels.left_rad_s,
                self.wheels.right_rad_s,
            )
        }

        /// Drives one step (exact arc) and returns the measured state.
        fn step(&mut self) -> SVector<f32, 5> {
            let pose = self
                .pose
                .advance_arc(ARC.v_m_s * FILTER_STEP_S, ARC.omega_rad_s * FILTER_STEP_S);
            self.pose = Pose::new(
                pose.position.x,
                pose.position.y,
                math::wrap_angle(pose.heading_rad),
            );
            let mut z = self.state();
            for (z, half_width) in z.iter_mut().zip(self.noise_half_width) {
                *z += half_width * self.uniform();
            }
            z[2] = math::wrap_angle(z[2]);
            z
        }

        /// Uniform on [−1, 1) (xorshift32, 24 bits).
        fn uniform(&mut self) -> f32 {
            let mut x = self.noise;
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            self.noise = x;
            (x >> 8) as f32 * (2.0 / 16_777_216.0) - 1.0
        }
    }

    /// What a filter skipped or repaired over its run.
    #[derive(Default)]
    struct Health {
        /// Steps skipped or recovered from (rejected inputs or results,
        /// singular innovations, covariance resets, particle-filter
        /// collapses and dropped particles): must stay 0.
        faults: u32,
        /// UKF factorisations that needed the jitter.
        repairs: u32,
        /// Particle-filter resamplings.
        resamplings: u32,
    }

    /// A filter on the [`Arc`]: paper 004's on its model, with all `N`
    /// states measured, or the fusion estimator's on odometry and fixes.
    trait BenchFilter {
        /// What a predict takes, the same every step.
        type Input;
        /// What an update takes.
        type Fix;
        /// Said when the filter skipped a step or lost the robot.
        const FAULT: &'static str;
        fn bench_input() -> Self::Input;
        /// Drives the arc one step and returns that step's fix.
        fn bench_fix(arc: &mut Arc) -> Self::Fix;
        fn bench_predict(&mut self, input: &Self::Input);
        fn bench_update(&mut self, fix: &Self::Fix);
        fn bench_position(&self) -> Vec2;
        fn bench_health(&self) -> Health;
    }

    /// Paper 004's filters: the auxiliary `(v, ω)` of the arc over a
    /// step, and the first `N` components of the arc's noisy measured state.
    const PAPER_004_FAULT: &str = "a paper 004 filter skipped a step or lost the robot";

    fn paper_004_input() -> (BodyVelocity, f32) {
        (ARC, FILTER_STEP_S)
    }

    fn paper_004_fix<const N: usize>(arc: &mut Arc) -> SVector<f32, N> {
        arc.step().fixed_rows::<N>(0).into_owned()
    }

    fn position_of<const N: usize>(x: &SVector<f32, N>) -> Vec2 {
        Vec2::new(
            x.get(0).copied().unwrap_or(f32::NAN),
            x.get(1).copied().unwrap_or(f32::NAN),
        )
    }

    impl<Model, const N: usize> BenchFilter for ExtendedKalmanFilter<Model, N, N>
    where
        Model: EkfModel<N, N, Input = BodyVelocity>,
    {
        type Input = (BodyVelocity, f32);
        type Fix = SVector<f32, N>;
        const FAULT: &'static str = PAPER_004_FAULT;
        fn bench_input() -> Self::Input {
            paper_004_input()
        }
        fn bench_fix(arc: &mut Arc) -> Self::Fix {
            paper_004_fix(arc)
        }
        fn bench_predict(&mut self, (u, dt_s): &(BodyVelocity, f32)) {
            // Counted in the filter's counters (`bench_health`).
            let _outcome = self.predict(u, *dt_s);
        }
        fn bench_update(&mut self, z: &SVector<f32, N>) {
            let _outcome = self.update(z);
        }
        fn bench_position(&self) -> Vec2 {
            position_of(self.state())
        }
        fn bench_health(&self) -> Health {
            let c = self.counters();
            Health {
                faults: c.rejected_predictions + c.rejected_updates + c.singular_innovations,
                ..Health::default()
            }
        }
    }

    impl<Model, const N: usize, const S: usize> BenchFilter for UnscentedKalmanFilter<Model, N, N, S>
    where
        Model: UkfModel<N, N, Input = BodyVelocity>,
    {
        type Input = (BodyVelocity, f32);
        type Fix = SVector<f32, N>;
        const FAULT: &'static str = PAPER_004_FAULT;
        fn bench_input() -> Self::Input {
            paper_004_input()
        }
        fn bench_fix(arc: &mut Arc) -> Self::Fix {
            paper_004_fix(arc)
        }
        fn bench_predict(&mut self, (u, dt_s): &(BodyVelocity, f32)) {
            // Counted in the filter's counters (`bench_health`).
            let _outcome = self.predict(u, *dt_s);
        }
        fn bench_update(&mut self, z: &SVector<f32, N>) {
            let _outcome = self.update(z);
        }
        fn bench_position(&self) -> Vec2 {
            position_of(self.state())
        }
        fn bench_health(&self) -> Health {
            let c = self.counters();
            Health {
                faults: c.rejected_inputs
                    + c.non_finite_results
                    + c.singular_innovations
                    + c.covariance_resets,
                repairs: c.covariance_repairs,
                resamplings: 0,
            }
        }
    }

    impl<Model, const N: usize, const P: usize> BenchFilter for ParticleFilter<Model, N, N, P>
    where
        Model: ParticleModel<N, N, Input = BodyVelocity>,
    {
        type Input = (BodyVelocity, f32);
        type Fix = SVector<f32, N>;
        const FAULT: &'static str = PAPER_004_FAULT;
        fn bench_input() -> Self::Input {
            paper_004_input()
        }
        fn bench_fix(arc: &mut Arc) -> Self::Fix {
            paper_004_fix(arc)
        }
        fn bench_predict(&mut self, (u, dt_s): &(BodyVelocity, f32)) {
            self.predict(u, *dt_s);
        }
        fn bench_update(&mut self, z: &SVector<f32, N>) {
            self.update(z);
        }
        fn bench_position(&self) -> Vec2 {
            position_of(&self.estimate())
        }
        fn bench_health(&self) -> Health {
            let c = self.counters();
            Health {
                faults: c.rejected_inputs + c.collapses + c.dropped_particles,
                repairs: 0,
                resamplings: c.resamplings,
            }
        }
    }

    /// The particle filter's resamplings, for the fusion filters' health
    /// (0 for the Kalman filters).
    trait Resamplings {
        fn resamplings(&self) -> u32 {
            0
        }
    }

    impl Resamplings for EkfCore {}
    impl Resamplings for UkfCore {}
    impl<const P: usize> Resamplings for ParticleCore<P> {
        fn resamplings(&self) -> u32 {
            self.filter().resamplings()
        }
    }

    /// The fusion estimator's filters: exact odometry every step and the
    /// true position as a 1 cm fix (the worst case: the tracker corrects
    /// only when the tag changes).
    impl<Core: PoseFilterCore + Resamplings> BenchFilter for PoseFilter<Core> {
        type Input = OdometryStep;
        type Fix = PositionMeasurement;
        const FAULT: &'static str =
            "a fusion filter skipped a step, gated a true fix or lost the robot";
        fn bench_input() -> OdometryStep {
            OdometryStep {
                ds_m: ARC.v_m_s * FILTER_STEP_S,
                dtheta_rad: ARC.omega_rad_s * FILTER_STEP_S,
                ..OdometryStep::default()
            }
        }
        fn bench_fix(arc: &mut Arc) -> PositionMeasurement {
            let _measured = arc.step();
            PositionMeasurement::Point {
                position: arc.pose.position,
                variance_m2: [FUSION_FIX_VARIANCE_M2; 2],
            }
        }
        fn bench_predict(&mut self, odometry: &OdometryStep) {
            self.predict(odometry);
        }
        fn bench_update(&mut self, fix: &PositionMeasurement) {
            // Counted in the filter's counters.
            let _outcome = self.correct(fix);
        }
        fn bench_position(&self) -> Vec2 {
            self.pose().position
        }
        fn bench_health(&self) -> Health {
            let c = self.counters();
            Health {
                faults: c.rejected_predictions + c.fixes_invalid + c.fixes_gated,
                repairs: 0,
                resamplings: self.core().resamplings(),
            }
        }
    }

    #[inline(never)]
    fn filter_predict<F: BenchFilter>(filter: &mut F, input: &F::Input) {
        filter.bench_predict(input);
    }

    #[inline(never)]
    fn filter_update<F: BenchFilter>(filter: &mut F, fix: &F::Fix) {
        filter.bench_update(fix);
    }

    /// Runs `filter` along an [`Arc`] from `start`, a predict then an
    /// update each step, and reports both stages, the stack of one call of
    /// each, the filter's size and its health; fails if it skipped a step
    /// or its RMS position error exceeds `max_rms_error_m`.
    fn bench_filter<F: BenchFilter>(
        cal: Calibration,
        name: &str,
        [predict_name, update_name]: [&'static str; 2],
        filter: &mut F,
        start: Pose,
        max_rms_error_m: f32,
    ) {
        let mut arc = Arc::new(start);
        let mut stages = [Stage::new(predict_name), Stage::new(update_name)];
        let input = F::bench_input();
        let mut sum_sq_error = 0.0;
        for k in 0..FILTER_WARMUP_STEPS + SAMPLES {
            let fix = F::bench_fix(&mut arc);
            let (predict, ()) = timed(&input, |i| filter_predict(filter, i));
            let (update, ()) = timed(&fix, |f| filter_update(filter, f));
            if k >= FILTER_WARMUP_STEPS {
                stages[0].record(predict);
                stages[1].record(update);
                let error = filter.bench_position() - arc.pose.position;
                sum_sq_error += error.x * error.x + error.y * error.y;
            }
        }
        let rms_error = math::sqrt(sum_sq_error / SAMPLES as f32);
        for stage in &stages {
            stage.report(cal);
        }
        let fix = F::bench_fix(&mut arc);
        let stacks = [
            stack_bytes(|| filter_predict(filter, black_box(&input))),
            stack_bytes(|| filter_update(filter, black_box(&fix))),
        ];
        for (stage, bytes) in stages.iter().zip(stacks) {
            match bytes {
                Some(bytes) => hprintln!("stack {} bytes={}", stage.name, bytes),
                None => fail("a filter step used the whole painted stack window"),
            }
        }
        let health = filter.bench_health();
        hprintln!(
            "filter {} state_bytes={} position_rms_error_m={:.4} faults={} repairs={} resamplings={} steps={}",
            name,
            core::mem::size_of::<F>(),
            rms_error,
            health.faults,
            health.repairs,
            health.resamplings,
            FILTER_WARMUP_STEPS + SAMPLES + 1
        );
        // False for a NaN error too.
        let tracked = rms_error <= max_rms_error_m;
        if health.faults > 0 || !tracked {
            fail(F::FAULT);
        }
    }

    /// The first `N` components of a 5-vector.
    fn head<const N: usize>(x: &SVector<f32, 5>) -> SVector<f32, N> {
        x.fixed_rows::<N>(0).into_owned()
    }

    /// `diag(values[..N])`.
    fn diagonal<const N: usize>(values: [f32; 5]) -> SMatrix<f32, N, N> {
        SMatrix::from_diagonal(&head(&SVector::from(values)))
    }

    /// A filter, or the bench fails saying `what`.
    fn built<T, E>(filter: Result<T, E>, what: &str) -> T {
        filter.unwrap_or_else(|_| fail(what))
    }

    /// Paper 004's EKF, UKF and particle filter on scenario 1's
    /// `PoseModel` (N = 3) and scenario 2's `PoseWheelModel` (N = 5), set
    /// up as `host_tests::paper_004` sets them up (each starts at the true
    /// state; the particle filter's state, 2.9 KB and 4.6 KB, lives in this
    /// function's frame).
    #[inline(never)]
    fn bench_paper_004(cal: Calibration) {
        let scenario_1 = Pose::new(0.0, -1.5, core::f32::consts::FRAC_PI_4);
        let scenario_2 = Pose::new(0.0, -1.0, core::f32::consts::FRAC_PI_6);
        let (x1, x2) = (Arc::new(scenario_1).state(), Arc::new(scenario_2).state());
        let (q, r) = (PROCESS_VARIANCE, MEASUREMENT_VARIANCE);

        let mut ekf3 = built(
            ExtendedKalmanFilter::new(
                PoseModel,
                head::<3>(&x1),
                diagonal(INITIAL_VARIANCE),
                diagonal(q),
                diagonal(r),
            ),
            "EKF (N = 3) refused",
        );
        bench_filter(
            cal,
            "ekf3",
            ["ekf3_predict", "ekf3_update"],
            &mut ekf3,
            scenario_1,
            MAX_FILTER_RMS_ERROR_M,
        );
        let mut ekf5 = built(
            ExtendedKalmanFilter::new(
                PoseWheelModel,
                x2,
                diagonal(INITIAL_VARIANCE),
                diagonal(q),
                diagonal(r),
            ),
            "EKF (N = 5) refused",
        );
        bench_filter(
            cal,
            "ekf5",
            ["ekf5_predict", "ekf5_update"],
            &mut ekf5,
            scenario_2,
            MAX_FILTER_RMS_ERROR_M,
        );

        let mut ukf3 = built(
            MerweScaledSigmaPoints::paper().and_then(|points| {
                UnscentedKalmanFilter::<_, 3, 3, 7>::new(
                    PoseModel,
                    points,
                    head(&x1),
                    diagonal(UKF_INITIAL_VARIANCE),
                    diagonal(q),
                    diagonal(r),
                )
            }),
            "UKF (N = 3) refused",
        );
        bench_filter(
            cal,
            "ukf3",
            ["ukf3_predict", "ukf3_update"],
            &mut ukf3,
            scenario_1,
            MAX_FILTER_RMS_ERROR_M,
        );
        let mut ukf5 = built(
            MerweScaledSigmaPoints::paper().and_then(|points| {
                UnscentedKalmanFilter::<_, 5, 5, 11>::new(
                    PoseWheelModel,
                    points,
                    x2,
                    diagonal(UKF_INITIAL_VARIANCE),
                    diagonal(q),
                    diagonal(r),
                )
            }),
            "UKF (N = 5) refused",
        );
        bench_filter(
            cal,
            "ukf5",
            ["ukf5_predict", "ukf5_update"],
            &mut ukf5,
            scenario_2,
            MAX_FILTER_RMS_ERROR_M,
        );
        // The square-root form of the same two filters.
        let mut srukf3 = built(
            MerweScaledSigmaPoints::paper().and_then(|points| {
                UnscentedKalmanFilter::<_, 3, 3, 7>::new(
                    PoseModel,
                    points,
                    head(&x1),
                    diagonal(UKF_INITIAL_VARIANCE),
                    diagonal(q),
                    diagonal(r),
                )?
                .with_form(UkfForm::SquareRoot)
            }),
            "square-root UKF (N = 3) refused",
        );
        bench_filter(
            cal,
            "srukf3",
            ["srukf3_predict", "srukf3_update"],
            &mut srukf3,
            scenario_1,
            MAX_FILTER_RMS_ERROR_M,
        );
        let mut srukf5 = built(
            MerweScaledSigmaPoints::paper().and_then(|points| {
                UnscentedKalmanFilter::<_, 5, 5, 11>::new(
                    PoseWheelModel,
                    points,
                    x2,
                    diagonal(UKF_INITIAL_VARIANCE),
                    diagonal(q),
                    diagonal(r),
                )?
                .with_form(UkfForm::SquareRoot)
            }),
            "square-root UKF (N = 5) refused",
        );
        bench_filter(
            cal,
            "srukf5",
            ["srukf5_predict", "srukf5_update"],
            &mut srukf5,
            scenario_2,
            MAX_FILTER_RMS_ERROR_M,
        );

        let prior = [
            ("pf3", ["pf3_predict", "pf3_update"]),
            ("pf5", ["pf5_predict", "pf5_update"]),
        ];
        bench_particle_filters(cal, prior, &PRIOR_PROPOSAL, [scenario_1, scenario_2]);
        let optimal = [
            ("pf3o", ["pf3o_predict", "pf3o_update"]),
            ("pf5o", ["pf5o_predict", "pf5o_update"]),
        ];
        bench_particle_filters(cal, optimal, &OPTIMAL_PROPOSAL, [scenario_1, scenario_2]);
    }

    /// A particle-filter setting of the bench.
    struct ParticleSetting {
        process_std: [f32; 5],
        /// Regularization bandwidth scale (0: off).
        regularization: f32,
        proposal: Proposal,
    }

    /// The prior proposal (the paper's), unregularized, with the prior
    /// proposal's process noise (`PARTICLE_PROCESS_STD`): the rows `pf3`,
    /// `pf5`.
    const PRIOR_PROPOSAL: ParticleSetting = ParticleSetting {
        process_std: PARTICLE_PROCESS_STD,
        regularization: 0.0,
        proposal: Proposal::Prior,
    };

    /// The slip scenario files' setting (firmware-sim
    /// `slip::PARTICLE_PROCESS_STD`, `PARTICLE_REGULARIZATION`, the optimal
    /// proposal; docs/paper-004.md): the rows `pf3o`, `pf5o`.
    const OPTIMAL_PROPOSAL: ParticleSetting = ParticleSetting {
        process_std: [0.005, 0.005, 0.007, 5.0, 5.0],
        regularization: 1.0,
        proposal: Proposal::Optimal,
    };

    /// Paper 004's particle filter (100 particles) on both models with
    /// `setting`, benchmarked as `names[0]` (N = 3, from `starts[0]`) and
    /// `names[1]` (N = 5, from `starts[1]`), each a filter's name and its stages';
    /// both filters live in this frame.
    #[inline(never)]
    fn bench_particle_filters(
        cal: Calibration,
        names: [(&'static str, [&'static str; 2]); 2],
        setting: &ParticleSetting,
        [scenario_1, scenario_2]: [Pose; 2],
    ) {
        let (x1, x2) = (Arc::new(scenario_1).state(), Arc::new(scenario_2).state());
        let process_std = SVector::from(setting.process_std);
        let measurement_std = SVector::from(MEASUREMENT_VARIANCE.map(math::sqrt));
        let prior_std = SVector::from(INITIAL_VARIANCE.map(math::sqrt));
        let mut pf3 = built(
            ParticleFilterConfig::new(head(&process_std), head(&measurement_std))
                .and_then(|c| c.with_collapse_gate(f32::INFINITY))
                .and_then(|c| c.with_regularization(setting.regularization))
                .map(|c| c.with_proposal(setting.proposal))
                .and_then(|config| {
                    ParticleFilter::<_, 3, 3, PARTICLES>::new(
                        PoseModel,
                        config,
                        head(&x1),
                        head(&prior_std),
                        PARTICLE_SEED,
                    )
                }),
            "particle filter (N = 3) refused",
        );
        let [(name3, stages3), (name5, stages5)] = names;
        bench_filter(
            cal,
            name3,
            stages3,
            &mut pf3,
            scenario_1,
            MAX_FILTER_RMS_ERROR_M,
        );
        let mut pf5 = built(
            ParticleFilterConfig::new(process_std, measurement_std)
                .and_then(|c| c.with_collapse_gate(f32::INFINITY))
                .and_then(|c| c.with_regularization(setting.regularization))
                .map(|c| c.with_proposal(setting.proposal))
                .and_then(|config| {
                    ParticleFilter::<_, 5, 5, PARTICLES>::new(
                        PoseWheelModel,
                        config,
                        x2,
                        prior_std,
                        PARTICLE_SEED,
                    )
                }),
            "particle filter (N = 5) refused",
        );
        bench_filter(
            cal,
            name5,
            stages5,
            &mut pf5,
            scenario_2,
            MAX_FILTER_RMS_ERROR_M,
        );
    }

    // ------------------------------------------------------- fusion filters

    /// The fusion estimator's fix in the bench: the true position, with
    /// this variance per axis, m² (a 1 cm fix).
    const FUSION_FIX_VARIANCE_M2: f32 = 1e-4;
    /// Wheel travel variance per metre of the fusion filters' noise model,
    /// m²/m (the UKF and particle filter's tuning in `host-tests`).
    const FUSION_WHEEL_VARIANCE_PER_M: f32 = 3e-5;
    /// Paper 004's track width `b`, m: the fusion filters' wheel geometry
    /// on the [`Arc`].
    const FUSION_TRACK_WIDTH_M: f32 = 0.65;
    /// A fusion filter's RMS position error must stay below its fixes'.
    const MAX_FUSION_RMS_ERROR_M: f32 = 0.014;

    /// The fusion estimator's three filters (the pose and both wheel
    /// scales, N = 5), each starting at the true pose with a 1 cm, 0.1 rad
    /// spread and a 2 % wheel-scale prior.
    #[inline(never)]
    fn bench_fusion(cal: Calibration) {
        let config = built(
            PoseFilterConfig::new(FUSION_TRACK_WIDTH_M, FUSION_WHEEL_VARIANCE_PER_M, 1e-9, 3.0),
            "fusion filter configuration refused",
        );
        let start = Pose::new(0.0, -1.0, core::f32::consts::FRAC_PI_6);
        let variances = [1e-4, 1e-4, 0.01, 4e-4];
        let mut ekf: PoseEkf = built(
            PoseFilter::new(config, start, variances),
            "fusion EKF refused",
        );
        bench_filter(
            cal,
            "fusion_ekf",
            ["fusion_ekf_predict", "fusion_ekf_update"],
            &mut ekf,
            start,
            MAX_FUSION_RMS_ERROR_M,
        );
        let mut ukf: PoseUkf = built(
            PoseFilter::new(config, start, variances),
            "fusion UKF refused",
        );
        bench_filter(
            cal,
            "fusion_ukf",
            ["fusion_ukf_predict", "fusion_ukf_update"],
            &mut ukf,
            start,
            MAX_FUSION_RMS_ERROR_M,
        );
        let mut pf: PoseParticleFilter = built(
            PoseFilter::new(config, start, variances),
            "fusion particle filter refused",
        );
        bench_filter(
            cal,
            "fusion_pf",
            ["fusion_pf_predict", "fusion_pf_update"],
            &mut pf,
            start,
            MAX_FUSION_RMS_ERROR_M,
        );
    }

    // ------------------------------------------------------------------ main

    /// The firmware's robot on the HIL link's proxies of `bus` (reset to
    /// [`PWM_MAX_DUTY`]), as a HIL session builds it.
    fn proxy_robot(bus: &ProxyBus, pilot: Pilot, grid: TagGrid) -> ProxyRobot<'_> {
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
    /// module's documentation). In a function of its own, as
    /// [`bench_fusion_tick`] is, so that the two robots and their samples
    /// never take stack at the same time.
    #[inline(never)]
    fn bench_tick(cal: Calibration) {
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

    /// One whole-tick bench of the fusion estimator: its filter and the
    /// names its figures are reported under.
    #[cfg(feature = "fusion-ekf")]
    struct FusionTick {
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
    const FUSION_EKF_TICK: FusionTick = FusionTick {
        filter: wmr_core::estimation::spec::FusionFilterSpec::Ekf,
        fix: "robot_tick_fusion_fix",
        dead_reckoned: "robot_tick_fusion_dead_reckoned",
        stack: "robot_tick_fusion",
    };

    /// The fusion particle filter's whole tick: with the bench's reader of
    /// the nearest tag, each read is the particles' cell likelihood (what a
    /// robot built with `fusion-particle-filter` runs).
    #[cfg(all(feature = "fusion-particle-filter", target_abi = "eabihf"))]
    const FUSION_PF_TICK: FusionTick = FusionTick {
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
    #[cfg(feature = "fusion-ekf")]
    #[inline(never)]
    fn bench_fusion_tick(cal: Calibration, bench: &FusionTick) {
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

    fn fail(why: &str) -> ! {
        hprintln!("error {}", why);
        debug::exit(EXIT_FAILURE);
        loop {
            cortex_m::asm::wfi();
        }
    }

    fn calibrate() -> Calibration {
        const SHORT: u32 = 1_000;
        const LONG: u32 = 101_000;
        let short = mean_counts(4, || timed(&SHORT, |&n| spin(n)).0);
        let long = mean_counts(4, || timed(&LONG, |&n| spin(n)).0);
        let loop_counts_per_iteration = (long - short) / (LONG - SHORT) as f32;
        // The loop's two instructions per iteration, checked against a
        // block of single instructions.
        let counts_per_instruction = 0.5 * loop_counts_per_iteration;
        let empty = mean_counts(SAMPLES as u32, || timed(&0_u32, |_| ()).0);
        let nop_block = mean_counts(SAMPLES as u32, || timed(&0_u32, |_| nops()).0);
        let nop_counts_per_instruction = (nop_block - empty) / NOP_BLOCK as f32;
        let cal = Calibration {
            counts_per_instruction,
            overhead_instructions: empty / counts_per_instruction,
        };
        hprintln!(
            "calibration counts_per_instruction={:.5} loop_counts_per_iteration={:.5} \
             nop_counts_per_instruction={:.4} overhead_instructions={:.1}",
            counts_per_instruction,
            loop_counts_per_iteration,
            nop_counts_per_instruction,
            cal.overhead_instructions
        );
        let off = |x: f32| (x / EXPECTED_COUNTS_PER_INSTRUCTION - 1.0).abs() > 0.01;
        if off(counts_per_instruction) || off(nop_counts_per_instruction) {
            fail(
                "SysTick does not count the expected counts per instruction: run QEMU \
                 with `-icount shift=0` (netduinoplus2, 168 MHz) or `-icount shift=6` \
                 (microbit, 16 MHz)",
            );
        }
        cal
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
        // The filters' states and stacks (up to 5 KB and 2.4 KB each) do
        // not fit beside the bench in the nRF51's 16 KiB of RAM: the M0
        // measures the ticks and the math only.
        #[cfg(target_abi = "eabihf")]
        {
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
