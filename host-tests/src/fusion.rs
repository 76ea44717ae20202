//! The encoder + tag fusion EKF ([`wmr_core::estimation::fusion`]) on paper 001's
//! figure-eight with 10 cm tags, against paper 001's position-only loop.
//!
//! The plant is the `f64` unicycle of [`crate::paper_002::unicycle`]; the
//! wheels' cumulative angles are quantized to encoder counts
//! (2048 counts/rev, 3 cm wheels, 20 cm track, as [`crate::paper_pilot`]);
//! the position is the nearest tag every tick (the paper's mode). The EKF
//! pose feeds paper 001's law (14) as if it were the measured pose.

use wmr_core::control::LawChoice;
use wmr_core::control::saturated::{TrackingController, TrackingGains};
use wmr_core::estimation::EstimatorChoice;
use wmr_core::estimation::fusion::{PoseEkf, PoseFilterConfig, PoseFilterCounters, TagCellTracker};
use wmr_core::estimation::heading_observer::HeadingObserverConfig;
use wmr_core::geometry::{DiffDriveGeometry, Pose, Vec2};
use wmr_core::odometry::OdometryStep;
use wmr_core::pilot::tracker::{OutputFeedbackTracker, TagFix, TrackerConfig};
use wmr_core::reference::{FigureEight, Trajectory};

use crate::paper_002::Series;
use crate::paper_002::unicycle::{
    ErrorAccumulator, ErrorStats, PAPER_001_START, TAG_SPACING_M, TrackingRecorder, nearest_tag,
};

/// Wheel radius of the simulated robot, m.
pub const WHEEL_RADIUS_M: f64 = 0.03;
/// Track width, m.
pub const TRACK_WIDTH_M: f64 = 0.2;
/// Encoder counts per wheel revolution.
pub const COUNTS_PER_REV: u32 = 2048;

/// Which estimator closes the loop.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Estimator {
    /// Paper 001: heading observer (5) + output-feedback law (27)–(28),
    /// `L = 0.6`, fed the same encoder odometry and every tag read.
    HeadingObserver,
    /// The fusion EKF + law (14) on its pose.
    FusionEkf,
}

/// How far the simulated wheels are from the nominal model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WheelTruth {
    /// Relative error of the right wheel's true radius (0.005: 0.5 % larger
    /// than the odometry assumes).
    pub right_radius_error: f64,
    /// The same for the left wheel.
    pub left_radius_error: f64,
    /// Random slip: standard deviation of each wheel's travel per √m
    /// driven, m/√m (seeded, reproducible).
    pub slip_std_per_sqrt_m: f64,
}

impl WheelTruth {
    /// Wheels exactly as the model says; only count quantization.
    pub const IDEAL: Self = Self {
        right_radius_error: 0.0,
        left_radius_error: 0.0,
        slip_std_per_sqrt_m: 0.0,
    };
    /// A plausible real robot: radii off by +0.5 % / −0.3 % (tyre wear,
    /// load) and 1 cm/√m of random slip per wheel.
    pub const REALISTIC: Self = Self {
        right_radius_error: 0.005,
        left_radius_error: -0.003,
        slip_std_per_sqrt_m: 0.01,
    };
}

/// The fusion EKF's tuning.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FusionTuning {
    /// Each wheel's travel variance per metre, m²/m.
    pub variance_per_m: f32,
    /// Prior variance of each wheel's scale error (0: not estimated).
    pub scale_prior: f32,
    /// Cell-edge constraint on reads of an unchanged tag.
    pub edges: bool,
}

impl FusionTuning {
    /// Wheels taken as calibrated: travel variance 1e-3 m²/m per wheel, no
    /// scale estimation, no edge constraint.
    pub const FIXED_WHEELS: Self = Self {
        variance_per_m: 1e-3,
        scale_prior: 0.0,
        edges: false,
    };
    /// As [`Self::FIXED_WHEELS`], learning each wheel's scale from a 2 %
    /// prior (the drive then uses the learnt radii).
    pub const LEARN_WHEELS: Self = Self {
        scale_prior: 4e-4,
        ..Self::FIXED_WHEELS
    };
}

/// The result of a fusion run.
#[derive(Debug, Clone, PartialEq)]
pub struct FusionRun {
    /// `|p − p_r|` statistics over `t ≥ 100 s`, m.
    pub tracking: ErrorStats,
    /// `|p̂ − p|` statistics of the EKF over `t ≥ 100 s`, m.
    pub estimation: ErrorStats,
    /// Largest `|θ̂ − θ|` over `t ≥ 100 s`, rad.
    pub heading_error_max_rad: f64,
    /// The EKF's counters at the end.
    pub counters: PoseFilterCounters,
    /// Reads of an unchanged tag (skipped).
    pub same_tag_reads: u32,
    /// `|p − p_r|` every 0.5 s.
    pub series: Series,
}

/// Paper 001 §6.3.2's run (figure-eight `h1 = 5, h2 = 0.02`, start
/// `(0, −6)` heading 3π/2, 480 s, h = 10 ms, gains `k = (0.11, 0.11, 0.1)`)
/// closed by `estimator`, on wheels `wheels`. The fusion EKF uses `tuning`
/// with the count quantization as the travel-variance floor, gate 3σ,
/// and starts at the first tag with heading 0 and `σθ = π`.
///
/// # Panics
/// Never (constant, valid parameters).
#[must_use]
pub fn figure_eight_run(
    estimator: Estimator,
    wheels: WheelTruth,
    tuning: FusionTuning,
) -> FusionRun {
    figure_eight_run_from(estimator, wheels, tuning, 0.0)
}

/// [`figure_eight_run`] from a start moved `start_offset_m` along x (the
/// ensembles of [`crate::ENSEMBLE_OFFSETS_M`]).
///
/// # Panics
/// Never (constant, valid parameters).
#[must_use]
pub fn figure_eight_run_from(
    estimator: Estimator,
    wheels: WheelTruth,
    tuning: FusionTuning,
    start_offset_m: f64,
) -> FusionRun {
    let h = 0.01_f64;
    let hf = h as f32;
    let spacing = TAG_SPACING_M;
    let trajectory: Trajectory = FigureEight::paper_001().into();
    let geometry =
        DiffDriveGeometry::new(WHEEL_RADIUS_M as f32, TRACK_WIDTH_M as f32, COUNTS_PER_REV)
            .expect("valid geometry");
    let count_quantum_m = WHEEL_RADIUS_M * std::f64::consts::TAU / f64::from(COUNTS_PER_REV);
    let config = PoseFilterConfig::new(
        TRACK_WIDTH_M as f32,
        tuning.variance_per_m,
        (count_quantum_m * count_quantum_m / 12.0) as f32,
        3.0,
    )
    .expect("valid filter");
    let tag = nearest_tag;
    let mut robot = PAPER_001_START;
    robot.x += start_offset_m;
    let first = tag(&robot);
    let cell = (spacing * spacing / 12.0) as f32;
    let mut ekf = PoseEkf::new(
        config,
        Pose::new(first.x, first.y, 0.0),
        [cell, cell, std::f32::consts::PI.powi(2), tuning.scale_prior],
    )
    .expect("valid initial state");
    let mut cells = TagCellTracker::new(spacing as f32)
        .expect("positive spacing")
        .with_edge_constraint(tuning.edges);
    let gains = TrackingGains::new(0.11, 0.11, 0.1).expect("gains");
    let mut law = TrackingController::new(gains);
    let observer_config = HeadingObserverConfig::new(0.6, hf).expect("paper gain");
    let mut paper_001 = OutputFeedbackTracker::new(
        TrackerConfig::new(
            EstimatorChoice::HeadingObserver(observer_config),
            LawChoice::Saturated(gains),
            trajectory,
            100,
        )
        .expect("tracker"),
    );
    let mut odometry = OdometryStep::default();
    // Seeded slip noise (xorshift + Box–Muller), reproducible.
    let mut rng_state = 0x9E37_79B9_7F4A_7C15_u64;
    let mut gaussian = move || {
        let mut next = || {
            rng_state ^= rng_state << 13;
            rng_state ^= rng_state >> 7;
            rng_state ^= rng_state << 17;
            (rng_state >> 11) as f64 / (1u64 << 53) as f64
        };
        let (u1, u2) = (next().max(1e-300), next());
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    };
    let (mut wheel_right, mut wheel_left) = (0.0_f64, 0.0_f64);
    let mut counts = (0_i64, 0_i64);
    let mut last_step = Vec2::ZERO;
    let mut recorder = TrackingRecorder::new(match estimator {
        Estimator::FusionEkf => "fusion EKF + 001 law (14)",
        Estimator::HeadingObserver => "001 observer (5) + law (27)–(28)",
    });
    let mut estimation = ErrorAccumulator::default();
    let mut heading_error_max: f64 = 0.0;
    for k in 0..48_000u32 {
        let t = f64::from(k) * h;
        let sample = trajectory.sample(k as f32 * hf);
        let (command, estimate) = match estimator {
            Estimator::FusionEkf => {
                // Measure: the nearest tag, turned into what it tells.
                for m in &cells.measurements(tag(&robot), last_step, ekf.pose().position, || {
                    let covariance = ekf.covariance();
                    [covariance[(0, 0)], covariance[(1, 1)]]
                }) {
                    let before = ekf.pose();
                    let outcome = ekf.correct(m);
                    if std::env::var_os("FUSION_DEBUG").is_some()
                        && outcome != wmr_core::estimation::fusion::FixOutcome::Used
                    {
                        let c = ekf.covariance();
                        eprintln!(
                            "t {t:.2} {outcome:?} {m:?} est ({:.4},{:.4},{:.3}) true ({:.4},{:.4},{:.3}) Pxx {:.2e} Pyy {:.2e} Ptt {:.2e} step {last_step:?}",
                            before.position.x,
                            before.position.y,
                            before.heading_rad,
                            robot.x,
                            robot.y,
                            robot.theta.sin().atan2(robot.theta.cos()),
                            c[(0, 0)],
                            c[(1, 1)],
                            c[(2, 2)]
                        );
                    }
                }
                (law.state_feedback(&sample, ekf.pose()).body, ekf.pose())
            }
            Estimator::HeadingObserver => {
                let fix = TagFix {
                    position: tag(&robot),
                    age_ticks: 0,
                };
                let out = paper_001.step(&odometry, Some(fix));
                let pose = Pose::new(out.position.x, out.position.y, out.heading.heading_rad());
                (out.command, pose)
            }
        };
        recorder.record(k, t, &robot, sample.position);
        if t >= 100.0 {
            estimation.add(
                (robot.x - f64::from(estimate.position.x))
                    .hypot(robot.y - f64::from(estimate.position.y)),
            );
            let dth = (robot.theta - f64::from(estimate.heading_rad)).sin().asin();
            heading_error_max = heading_error_max.max(dth.abs());
        }
        // The wheels turn as commanded (an ideal speed loop on the nominal
        // model); the ground moves by the true radii, plus slip.
        // With the fusion EKF the drive uses the wheel radii it has learnt,
        // `r(1 + ε̂)`, to turn ground speeds into wheel speeds.
        let (v, w) = (f64::from(command.v_m_s), f64::from(command.omega_rad_s));
        let [scale_right, scale_left] = match estimator {
            Estimator::FusionEkf => ekf.wheel_scale_errors().map(|e| 1.0 + f64::from(e)),
            Estimator::HeadingObserver => [1.0; 2],
        };
        let turn_right = (v + 0.5 * w * TRACK_WIDTH_M) * h / (WHEEL_RADIUS_M * scale_right);
        let turn_left = (v - 0.5 * w * TRACK_WIDTH_M) * h / (WHEEL_RADIUS_M * scale_left);
        let travel = |turn: f64, radius_error: f64, noise: f64| {
            let nominal = turn * WHEEL_RADIUS_M * (1.0 + radius_error);
            nominal + wheels.slip_std_per_sqrt_m * nominal.abs().sqrt() * noise
        };
        let right = travel(turn_right, wheels.right_radius_error, gaussian());
        let left = travel(turn_left, wheels.left_radius_error, gaussian());
        robot = robot.advance(
            0.5 * (right + left) / h,
            (right - left) / TRACK_WIDTH_M / h,
            h,
        );
        // Encoders: cumulative wheel angles, quantized to counts.
        wheel_right += turn_right;
        wheel_left += turn_left;
        let per_rad = f64::from(COUNTS_PER_REV) / std::f64::consts::TAU;
        let now = (
            (wheel_left * per_rad).floor() as i64,
            (wheel_right * per_rad).floor() as i64,
        );
        let step = OdometryStep::from_counts(
            &geometry,
            (now.0 - counts.0) as i32,
            (now.1 - counts.1) as i32,
            hf,
        );
        counts = now;
        odometry = step;
        let heading = ekf.pose().heading_rad;
        last_step = Vec2::new(step.ds_m * heading.cos(), step.ds_m * heading.sin());
        ekf.predict(&step);
    }
    let (tracking, series) = recorder.finish();
    FusionRun {
        tracking,
        estimation: estimation.stats(),
        heading_error_max_rad: heading_error_max,
        counters: ekf.counters(),
        same_tag_reads: cells.same_tag_reads(),
        series,
    }
}
