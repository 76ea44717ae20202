//! A state estimator on paper 004's tracked robot driving an arc: its
//! predict and update timed, its stack, size and health reported (item 4
//! of the bench's documentation, `main.rs`).

use core::hint::black_box;

use cortex_m_semihosting::hprintln;
use nalgebra::SVector;
use wmr_core::geometry::{BodyVelocity, Pose, Vec2, WheelSpeeds};
use wmr_core::math;
use wmr_papers::slip_tracking::TrackedRobot;

use super::fail;
use super::stack::stack_bytes;
use super::stage::Stage;
use super::timing::SAMPLES;
use super::timing::{Calibration, timed};

/// Paper 004's step `h`, s.
pub(super) const FILTER_STEP_S: f32 = 0.005;
/// The arc the filters' robot drives (turning radius 2 m).
pub(super) const ARC: BodyVelocity = BodyVelocity {
    v_m_s: 0.5,
    omega_rad_s: 0.25,
};
/// Filter steps before sampling starts, 2 s: the particle filters take
/// about 1 s to converge from their prior (`P0 = 10 I`), and their
/// resampling rate changes until then.
const FILTER_WARMUP_STEPS: usize = 400;
/// `R`: variances of the measured `(X, Y, ψ, ω_L, ω_R)` (paper 004).
pub(super) const MEASUREMENT_VARIANCE: [f32; 5] = [0.1, 0.1, 0.2, 0.01, 0.01];

/// Paper 004's tracked robot (no slip) driving [`ARC`], its whole state
/// measured every step with deterministic pseudo-noise: uniform, of
/// `R`'s variances.
pub(super) struct Arc {
    pub(super) pose: Pose,
    wheels: WheelSpeeds,
    /// xorshift32 state.
    noise: u32,
    /// `√(3R)`: a uniform draw on `±√(3R)` has variance `R`.
    noise_half_width: [f32; 5],
}

impl Arc {
    pub(super) fn new(start: Pose) -> Self {
        Self {
            pose: start,
            wheels: TrackedRobot::PAPER.wheels_for(ARC, 1.0),
            noise: 0x2545_F491,
            noise_half_width: MEASUREMENT_VARIANCE.map(|r| math::sqrt(3.0 * r)),
        }
    }

    /// The true `(X, Y, ψ, ω_L, ω_R)`.
    pub(super) fn state(&self) -> SVector<f32, 5> {
        SVector::<f32, 5>::new(
            self.pose.position.x,
            self.pose.position.y,
            self.pose.heading_rad,
            self.wheels.left_rad_s,
            self.wheels.right_rad_s,
        )
    }

    /// Drives one step (exact arc) and returns the measured state.
    pub(super) fn step(&mut self) -> SVector<f32, 5> {
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
pub(super) struct Health {
    /// Steps skipped or recovered from (rejected inputs or results,
    /// singular innovations, covariance resets, particle-filter
    /// collapses and dropped particles): must stay 0.
    pub(super) faults: u32,
    /// UKF factorisations that needed the jitter.
    pub(super) repairs: u32,
    /// Particle-filter resamplings.
    pub(super) resamplings: u32,
}

/// A filter on the [`Arc`]: paper 004's on its model, with all `N`
/// states measured, or the fusion estimator's on odometry and fixes.
pub(super) trait BenchFilter {
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
pub(super) fn bench_filter<F: BenchFilter>(
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

/// A filter, or the bench fails saying `what`.
pub(super) fn built<T, E>(filter: Result<T, E>, what: &str) -> T {
    filter.unwrap_or_else(|_| fail(what))
}
