//! Paper 002, section 3: simulations of the mobile car (figures 4 to 8),
//! of Propositions 5 and 6 (which the paper does not simulate), and the
//! position-only comparison on paper 001's figure-eight with 10 cm tags.
//!
//! The plant and the reference are integrated in `f64` with exact arcs
//! (inputs held over each step); the algorithms under test are the core's
//! `f32` code. Errors fed to the robot-frame observers are computed in
//! `f64` from the true poses (a sensor that measures them), then rounded
//! to `f32`.

use super::{Figure, Series};
use wmr_core::control::LawChoice;
use wmr_core::control::cascaded::{CascadedController, CascadedGains};
use wmr_core::control::heading_error_sine::{HeadingErrorSineConfig, HeadingErrorSineTracker};
use wmr_core::control::robot_frame::{RobotFrameError, UnicycleReference};
use wmr_core::control::saturated::{TrackingController, TrackingGains};
use wmr_core::estimation::EstimatorChoice;
use wmr_core::estimation::heading_observer::HeadingObserverConfig;
use wmr_core::estimation::pose_observer::{PoseEstimate, PoseObserver, PoseObserverConfig};
use wmr_core::geometry::{BodyVelocity, Vec2};
use wmr_core::odometry::OdometryStep;
use wmr_core::pilot::tracker::{OutputFeedbackTracker, TagFix, TrackerConfig};
use wmr_core::reference::{FigureEight, Trajectory};
use wmr_papers::robot_frame_observers::{LateralErrorObserver, LongitudinalErrorObserver};

/// Step of the section 3 simulations, s (the paper does not state its own).
pub const STEP_S: f64 = 0.001;

/// A speed profile `t ↦ v(t)`.
pub type SpeedProfile = fn(f64) -> f64;
/// Reference inputs `t ↦ (v_r, ω_r, v̇_r)`.
pub type ReferenceInputs = fn(f64) -> (f64, f64, f64);

/// An `f64` pose, integrated with exact arcs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose64 {
    /// x, m.
    pub x: f64,
    /// y, m.
    pub y: f64,
    /// θ, rad (integrated, not wrapped).
    pub theta: f64,
}

impl Pose64 {
    /// The pose after `(v, ω)` held for `h` seconds.
    #[must_use]
    pub fn advance(self, v: f64, w: f64, h: f64) -> Self {
        let half = 0.5 * w * h;
        let sinc = if half.abs() < 1e-8 {
            1.0
        } else {
            half.sin() / half
        };
        let chord = v * h * sinc;
        let mid = self.theta + half;
        Self {
            x: self.x + chord * mid.cos(),
            y: self.y + chord * mid.sin(),
            theta: self.theta + w * h,
        }
    }

    /// The error (30) of `self` (the robot) against `reference`, in `f64`.
    #[must_use]
    pub fn error_to(self, reference: Self) -> (f64, f64, f64) {
        let (dx, dy) = (reference.x - self.x, reference.y - self.y);
        let (s, c) = self.theta.sin_cos();
        let mut th = (reference.theta - self.theta).rem_euclid(std::f64::consts::TAU);
        if th > std::f64::consts::PI {
            th -= std::f64::consts::TAU;
        }
        (c * dx + s * dy, -s * dx + c * dy, th)
    }
}

/// A reference unicycle driven by `(v_r(t), ω_r(t))`, with `v̇_r(t)`.
pub struct InputReference {
    /// `t ↦ (v_r, ω_r, v̇_r)`.
    pub inputs: ReferenceInputs,
    /// Current pose.
    pub pose: Pose64,
}

impl InputReference {
    /// The reference at time `t` for the core.
    fn sample(&self, t: f64) -> UnicycleReference {
        let (v, w, dv) = (self.inputs)(t);
        UnicycleReference {
            position: Vec2::new(self.pose.x as f32, self.pose.y as f32),
            heading_rad: self.pose.theta as f32,
            v_m_s: v as f32,
            omega_rad_s: w as f32,
            dv_m_s2: dv as f32,
        }
    }

    fn advance(&mut self, t: f64, h: f64) {
        let (v, w, _) = (self.inputs)(t);
        self.pose = self.pose.advance(v, w, h);
    }
}

/// Figure 4/5: the Proposition 4 observer on a robot driven by `(v(t), ω)`,
/// from `x̃ = 10, ỹ = 40, θ̃ = π/2` (`s̃ = 1, c̃ = 0`), gains
/// `a1 = a2 = 10, a3 = a4 = 100`. Returns `|x̃|, |ỹ|, |θ̃|` series
/// (`θ̃` from `atan2(ŝ, ĉ)`, wrapped), sampled every 10 ms.
#[must_use]
pub fn pose_observer_run(v_of_t: SpeedProfile, omega: f64, duration_s: f64) -> [Series; 3] {
    let h = STEP_S;
    let cfg = PoseObserverConfig::new(10.0, 10.0, 100.0, 100.0, h as f32).expect("paper gains");
    // True heading 0: s = 0, c = 1. θ̃ = π/2 means the estimate points at −π/2.
    let mut obs = PoseObserver::new(
        cfg,
        PoseEstimate {
            position: Vec2::new(-10.0, -40.0),
            cos_theta: 0.0,
            sin_theta: -1.0,
        },
    );
    let mut pose = Pose64 {
        x: 0.0,
        y: 0.0,
        theta: 0.0,
    };
    let mut out = [
        Series::new("|x̃| (m)"),
        Series::new("|ỹ| (m)"),
        Series::new("|θ̃| (rad)"),
    ];
    let steps = (duration_s / h).round() as u32;
    for k in 0..=steps {
        let t = f64::from(k) * h;
        if k % 10 == 0 {
            let e = obs.estimate();
            let th_hat = f64::from(e.sin_theta).atan2(f64::from(e.cos_theta));
            let mut dth = (pose.theta - th_hat).rem_euclid(std::f64::consts::TAU);
            if dth > std::f64::consts::PI {
                dth -= std::f64::consts::TAU;
            }
            out[0].points.push((t, pose.x - f64::from(e.position.x)));
            out[1].points.push((t, pose.y - f64::from(e.position.y)));
            out[2].points.push((t, dth));
        }
        let v = v_of_t(t);
        pose = pose.advance(v, omega, h);
        obs.update(
            BodyVelocity {
                v_m_s: v as f32,
                omega_rad_s: omega as f32,
            },
            Vec2::new(pose.x as f32, pose.y as f32),
        );
    }
    out
}

/// Which closed loop of section 3.2 to simulate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RobotFrameLoop {
    /// Controller (31) with measured errors, Proposition 5 observing `y_e`.
    LateralObserver,
    /// Controller (50): (31) with `x̂_e` from Proposition 6.
    LongitudinalObserver,
    /// Proposition 7: controller (64) with the observer (65) of `sin θ_e`.
    HeadingErrorSine,
}

/// Time series of one section 3.2 run, sampled every 10 ms.
#[derive(Debug, Clone, PartialEq)]
pub struct RobotFrameRun {
    /// `|(x_e, y_e)|`, m.
    pub position_error: Series,
    /// `|θ_e|`, rad.
    pub heading_error: Series,
    /// The observer's error (`ỹ_e`, `x̃_e` or `ψ̃`).
    pub observer_error: Series,
}

/// Runs a section 3.2 loop from `(x_e, y_e, θ_e) = (10, 20, π/2)` (the
/// initial errors of section 3.2.4), observer estimate 0 (so `ψ̃(0) = 1`
/// for Proposition 7, as in the paper), with the reference inputs given.
///
/// Gains: Proposition 7 uses the paper's `c2 = 2, a = 10, γ = 0.9`;
/// Propositions 5 and 6 (no simulation in the paper) use `c1 = 1, c2 = 2`
/// for (31) and `c_y = c_e = 1 s`.
#[must_use]
pub fn robot_frame_run(
    which: RobotFrameLoop,
    inputs: ReferenceInputs,
    duration_s: f64,
) -> RobotFrameRun {
    let h = STEP_S;
    let hf = h as f32;
    let mut reference = InputReference {
        inputs,
        pose: Pose64 {
            x: 0.0,
            y: 0.0,
            theta: 0.0,
        },
    };
    // Robot placed so that the error (30) is (10, 20, π/2): robot heading
    // θ = θ_r − π/2 = −π/2; reference − robot = R(θ)(10, 20).
    let theta: f64 = -std::f64::consts::FRAC_PI_2;
    let (s, c) = theta.sin_cos();
    let mut robot = Pose64 {
        x: -(c * 10.0 - s * 20.0),
        y: -(s * 10.0 + c * 20.0),
        theta,
    };
    let cascaded = CascadedController::new(CascadedGains::new(1.0, 2.0).expect("gains"));
    let mut lateral = LateralErrorObserver::new(1.0, hf, 0.0).expect("gains");
    let mut longitudinal = LongitudinalErrorObserver::new(1.0, hf, 0.0).expect("gains");
    let mut sine = HeadingErrorSineTracker::new(
        HeadingErrorSineConfig::new(10.0, 2.0, 0.9, hf).expect("paper gains"),
        0.0,
    );
    let mut run = RobotFrameRun {
        position_error: Series::new("|(x_e, y_e)| (m)"),
        heading_error: Series::new("|θ_e| (rad)"),
        observer_error: Series::new(match which {
            RobotFrameLoop::LateralObserver => "|ỹ_e| (m)",
            RobotFrameLoop::LongitudinalObserver => "|x̃_e| (m)",
            RobotFrameLoop::HeadingErrorSine => "|ψ̃| = |sin θ_e − ψ̂|",
        }),
    };
    let mut applied = BodyVelocity::ZERO;
    let steps = (duration_s / h).round() as u32;
    for k in 0..=steps {
        let t = f64::from(k) * h;
        let r = reference.sample(t);
        let (xe, ye, the) = robot.error_to(reference.pose);
        let measured = RobotFrameError {
            x_e_m: xe as f32,
            y_e_m: ye as f32,
            theta_e_rad: the as f32,
        };
        let (command, observer_error) = match which {
            RobotFrameLoop::LateralObserver => {
                lateral.update(measured, applied, r);
                (
                    cascaded.command(&r, measured.x_e_m, measured.theta_e_rad),
                    ye - f64::from(lateral.estimate_m()),
                )
            }
            RobotFrameLoop::LongitudinalObserver => {
                longitudinal.update(measured, applied, r);
                (
                    cascaded.command(&r, longitudinal.estimate_m(), measured.theta_e_rad),
                    xe - f64::from(longitudinal.estimate_m()),
                )
            }
            RobotFrameLoop::HeadingErrorSine => {
                sine.update(measured, applied, r);
                (
                    sine.command(&r, measured.x_e_m),
                    the.sin() - f64::from(sine.psi_hat()),
                )
            }
        };
        if k % 10 == 0 {
            run.position_error.points.push((t, xe.hypot(ye)));
            run.heading_error.points.push((t, the));
            run.observer_error.points.push((t, observer_error));
        }
        applied = command;
        robot = robot.advance(f64::from(command.v_m_s), f64::from(command.omega_rad_s), h);
        reference.advance(t, h);
    }
    run
}

/// `v_r = ω_r = 1` (figure 6).
#[must_use]
pub fn constant_inputs(_t: f64) -> (f64, f64, f64) {
    (1.0, 1.0, 0.0)
}

/// `v_r = 1`, `ω_r = 1/√(1+t)`: `∫ω_r² = ∞` but not persistently exciting
/// (figure 7; the paper does not print its signal).
#[must_use]
pub fn fading_turn_inputs(t: f64) -> (f64, f64, f64) {
    (1.0, 1.0 / (1.0 + t).sqrt(), 0.0)
}

/// `v_r = e^{−t/2}`, `ω_r = 1`: `v_r` not persistently exciting and
/// `∫v_r² < ∞` (figure 8; the paper does not print its signal).
#[must_use]
pub fn fading_speed_inputs(t: f64) -> (f64, f64, f64) {
    let v = (-0.5 * t).exp();
    (v, 1.0, -0.5 * v)
}

/// One pairing of the position-only comparison.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pairing {
    /// Paper 001: heading observer (5) + law (27)–(28).
    HeadingObserverWithSaturatedLaw,
    /// Proposition 4's observer `(ĉ, ŝ)` in place of 001's + law (27)–(28).
    PoseObserverWithSaturatedLaw,
    /// Proposition 4's observer, `θ̂ = atan2(ŝ, ĉ)`, errors (30) from it,
    /// cascaded controller (31).
    PoseObserverWithCascaded,
    /// Proposition 4's observer, `(x_e, y_e)` from its `θ̂`, Proposition 7's
    /// observer of `sin θ_e` and controller (64).
    PoseObserverWithProp7,
}

impl Pairing {
    /// Every pairing that runs on position-only data.
    pub const ALL: [Self; 4] = [
        Self::HeadingObserverWithSaturatedLaw,
        Self::PoseObserverWithSaturatedLaw,
        Self::PoseObserverWithCascaded,
        Self::PoseObserverWithProp7,
    ];

    /// Row label.
    #[must_use]
    pub fn label(self) -> &'static str {
        match self {
            Self::HeadingObserverWithSaturatedLaw => "001 observer (5) + 001 law (27)–(28)",
            Self::PoseObserverWithSaturatedLaw => "002 Prop. 4 observer (37) + 001 law (27)–(28)",
            Self::PoseObserverWithCascaded => "002 Prop. 4 observer (37) + cascaded law (31)",
            Self::PoseObserverWithProp7 => {
                "002 Prop. 4 observer (37) → (x_e, y_e) + Prop. 7 (64)–(65)"
            }
        }
    }
}

/// Paper 001 §6.3.2's start: `(0, −6)`, heading 3π/2.
pub const PAPER_001_START: Pose64 = Pose64 {
    x: 0.0,
    y: -6.0,
    theta: 1.5 * std::f64::consts::PI,
};

/// Spacing of the tag grid in the figure-eight runs, m.
pub const TAG_SPACING_M: f64 = 0.1;

/// The nearest tag of the [`TAG_SPACING_M`] grid through the origin.
#[must_use]
pub fn nearest_tag(p: &Pose64) -> Vec2 {
    let s = TAG_SPACING_M;
    Vec2::new(
        ((p.x / s).round() * s) as f32,
        ((p.y / s).round() * s) as f32,
    )
}

/// Records the tracking error `|p − p_r|` of a figure-eight run: its
/// statistics over `t ≥ 100 s` and a series every 0.5 s (50 ticks).
#[derive(Debug, Clone, PartialEq)]
pub struct TrackingRecorder {
    stats: ErrorAccumulator,
    series: Series,
}

impl TrackingRecorder {
    /// An empty record whose series has this label.
    #[must_use]
    pub fn new(label: &str) -> Self {
        Self {
            stats: ErrorAccumulator::default(),
            series: Series::new(label),
        }
    }

    /// Records tick `k` at time `t` (s): the robot against the reference
    /// position; returns the error, m.
    pub fn record(&mut self, k: u32, t: f64, robot: &Pose64, reference: Vec2) -> f64 {
        let error = (robot.x - f64::from(reference.x)).hypot(robot.y - f64::from(reference.y));
        if t >= 100.0 {
            self.stats.add(error);
        }
        if k.is_multiple_of(50) {
            self.series.points.push((t, error));
        }
        error
    }

    /// The statistics and the series.
    #[must_use]
    pub fn finish(self) -> (ErrorStats, Series) {
        (self.stats.stats(), self.series)
    }
}

/// Accumulates a run's position errors into [`ErrorStats`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ErrorAccumulator {
    n: u32,
    sum: f64,
    sum2: f64,
    max: f64,
}

impl ErrorAccumulator {
    /// Adds one error sample, m.
    pub fn add(&mut self, error_m: f64) {
        self.n += 1;
        self.sum += error_m;
        self.sum2 += error_m * error_m;
        self.max = self.max.max(error_m);
    }

    /// Max, mean and RMS of the samples added (zeros if none).
    #[must_use]
    pub fn stats(&self) -> ErrorStats {
        let n = f64::from(self.n.max(1));
        ErrorStats {
            max_m: self.max,
            mean_m: self.sum / n,
            rms_m: (self.sum2 / n).sqrt(),
        }
    }
}

/// Position error statistics of a comparison run, m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorStats {
    /// Largest error after the transient.
    pub max_m: f64,
    /// Mean error after the transient.
    pub mean_m: f64,
    /// RMS error after the transient.
    pub rms_m: f64,
}

/// Paper 001 §6.3.2's run (figure-eight `h1 = 5, h2 = 0.02`, start
/// `(0, −6)`, heading 3π/2, heading estimate `(0, 0)`, 480 s, h = 10 ms,
/// position = the nearest tag of a 10 cm grid every tick) with one
/// pairing; statistics of `|p − p_r|` over `t ≥ 100 s`, and the error
/// series every 0.5 s.
///
/// Gains: 001's `k = (0.11, 0.11, 0.1)`, `L = 0.6`; Proposition 4
/// `a1 = a2 = 1.5 /s, a3 = a4 = 100 /m²` (tuned here for the figure-eight's
/// `v_r ≈ 0.07–0.11 m/s`: `a4 v_r² ≈ 0.5–1.2 /s`); (31) `c1 = 0.5, c2 = 0.5`;
/// Proposition 7 `a = 100 s/m², c2 = 0.5, γ = 0.9`.
#[must_use]
pub fn figure_eight_comparison(pairing: Pairing) -> (ErrorStats, Series) {
    figure_eight_comparison_from(pairing, 0.0)
}

/// [`figure_eight_comparison`] from a start moved `start_offset_m` along x
/// (the ensembles of [`crate::ENSEMBLE_OFFSETS_M`]).
///
/// # Panics
/// Never (constant, valid parameters).
#[must_use]
pub fn figure_eight_comparison_from(pairing: Pairing, start_offset_m: f64) -> (ErrorStats, Series) {
    let h = 0.01_f64;
    let hf = h as f32;
    let trajectory: Trajectory = FigureEight::paper_001().into();
    let tag = |p: Pose64| nearest_tag(&p);
    let mut robot = PAPER_001_START;
    robot.x += start_offset_m;
    let gains = TrackingGains::new(0.11, 0.11, 0.1).expect("paper gains");
    let observer_cfg = HeadingObserverConfig::new(0.6, hf).expect("paper gain");
    let tracker_cfg = TrackerConfig::new(
        EstimatorChoice::HeadingObserver(observer_cfg),
        LawChoice::Saturated(gains),
        trajectory,
        100,
    )
    .expect("tracker");
    let mut tracker = OutputFeedbackTracker::new(tracker_cfg);
    let mut law = TrackingController::new(gains);
    let pose_cfg = PoseObserverConfig::new(1.5, 1.5, 100.0, 100.0, hf).expect("gains");
    let start = tag(robot);
    let mut pose_observer = PoseObserver::new(
        pose_cfg,
        PoseEstimate {
            position: start,
            cos_theta: 0.0,
            sin_theta: 0.0,
        },
    );
    let cascaded = CascadedController::new(CascadedGains::new(0.5, 0.5).expect("gains"));
    let mut sine = HeadingErrorSineTracker::new(
        HeadingErrorSineConfig::new(100.0, 0.5, 0.9, hf).expect("gains"),
        0.0,
    );
    let mut applied = BodyVelocity::ZERO;
    let mut recorder = TrackingRecorder::new(pairing.label());
    let steps = 48_000u32;
    for k in 0..steps {
        let t = f64::from(k) * h;
        let sample = trajectory.sample(k as f32 * hf);
        recorder.record(k, t, &robot, sample.position);
        let position = tag(robot);
        let command = match pairing {
            Pairing::HeadingObserverWithSaturatedLaw => {
                let odometry = OdometryStep {
                    ds_m: applied.v_m_s * hf,
                    dtheta_rad: applied.omega_rad_s * hf,
                    body: applied,
                    ..OdometryStep::default()
                };
                tracker
                    .step(
                        &odometry,
                        Some(TagFix {
                            position,
                            age_ticks: 0,
                        }),
                    )
                    .command
            }
            _ => {
                if k > 0 {
                    pose_observer.update(applied, position);
                }
                let e = pose_observer.estimate();
                let reference = UnicycleReference::from_sample(&sample).expect("moving reference");
                let norm = e.cos_theta.hypot(e.sin_theta);
                let (c, s) = if norm > 1e-6 {
                    (e.cos_theta / norm, e.sin_theta / norm)
                } else {
                    (1.0, 0.0)
                };
                let theta_hat = s.atan2(c);
                let error =
                    RobotFrameError::with_heading(reference.pose(), position, c, s, theta_hat);
                match pairing {
                    Pairing::PoseObserverWithSaturatedLaw => {
                        law.output_feedback(&sample, position, e.heading()).body
                    }
                    Pairing::PoseObserverWithCascaded => {
                        cascaded.command(&reference, error.x_e_m, error.theta_e_rad)
                    }
                    _ => {
                        sine.update(error, applied, reference);
                        sine.command(&reference, error.x_e_m)
                    }
                }
            }
        };
        applied = if command.is_finite() {
            command
        } else {
            BodyVelocity::ZERO
        };
        robot = robot.advance(f64::from(applied.v_m_s), f64::from(applied.omega_rad_s), h);
    }
    recorder.finish()
}

/// The section 3 figures: 4 (observer, `v = 1` and `v = sin t`), 5 (`v`
/// not persistently exciting), 6–8 (Proposition 7), and Propositions 5, 6.
#[must_use]
pub fn figures() -> Vec<Figure> {
    let mut figures = Vec::new();
    let observer_cases: [(&str, &str, SpeedProfile); 5] = [
        (
            "fig4a_pose_observer_v1",
            "Fig. 4(a): Prop. 4 observer, v = 1, ω = 0.5",
            |_| 1.0,
        ),
        (
            "fig4b_pose_observer_vsin",
            "Fig. 4(b): Prop. 4 observer, v = sin t, ω = 0.5",
            f64::sin,
        ),
        (
            "fig5a_pose_observer_v_exp",
            "Fig. 5(a): v = e^{-t} (∫v² < ∞)",
            |t| (-t).exp(),
        ),
        (
            "fig5b_pose_observer_v_inv",
            "Fig. 5(b): v = 1/(1+t) (∫v² < ∞)",
            |t| 1.0 / (1.0 + t),
        ),
        (
            "fig5c_pose_observer_v_invsqrt",
            "Fig. 5(c): v = 1/√(1+t) (∫v² = ∞, not PE)",
            |t| 1.0 / (1.0 + t).sqrt(),
        ),
    ];
    for (name, title, v) in observer_cases {
        figures.push(Figure {
            name: name.into(),
            title: format!("{title}; a1 = a2 = 10, a3 = a4 = 100"),
            series: pose_observer_run(v, 0.5, 20.0).to_vec(),
        });
    }
    let loops: [(&str, &str, RobotFrameLoop, ReferenceInputs); 5] = [
        (
            "fig6_prop7_constant",
            "Fig. 6: Prop. 7, v_r = ω_r = 1; c2 = 2, a = 10, γ = 0.9",
            RobotFrameLoop::HeadingErrorSine,
            constant_inputs,
        ),
        (
            "fig7_prop7_omega_not_pe",
            "Fig. 7: Prop. 7, ω_r = 1/√(1+t) (not PE)",
            RobotFrameLoop::HeadingErrorSine,
            fading_turn_inputs,
        ),
        (
            "fig8_prop7_v_not_pe",
            "Fig. 8: Prop. 7, v_r = e^{-t/2} (not PE)",
            RobotFrameLoop::HeadingErrorSine,
            fading_speed_inputs,
        ),
        (
            "prop5_lateral_observer",
            "Prop. 5: observer of y_e under (31), v_r = ω_r = 1; c_y = 1",
            RobotFrameLoop::LateralObserver,
            constant_inputs,
        ),
        (
            "prop6_longitudinal_observer",
            "Prop. 6: observer of x_e + controller (50), v_r = ω_r = 1; c_e = 1",
            RobotFrameLoop::LongitudinalObserver,
            constant_inputs,
        ),
    ];
    for (name, title, which, inputs) in loops {
        let run = robot_frame_run(which, inputs, 30.0);
        figures.push(Figure {
            name: name.into(),
            title: title.into(),
            series: vec![run.position_error, run.heading_error, run.observer_error],
        });
    }
    let comparison = Pairing::ALL
        .iter()
        .map(|&p| figure_eight_comparison(p).1)
        .collect();
    figures.push(Figure {
        name: "figure_eight_position_only".into(),
        title: "Figure-eight, nearest 10 cm tag: |p − p_r| (m)".into(),
        series: comparison,
    });
    figures
}
