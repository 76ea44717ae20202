//! Paper 002, section 2: simulations of the chained form. Figures 2 and 3
//! (the Proposition 2 observer, section 2.3), and the closed loops of
//! Propositions 1 and 3, which the paper does not simulate.
//!
//! The plant and the reference are integrated in `f64`, exactly for inputs
//! held over each step; the algorithms under test are the core's `f32`
//! code, fed measurements rounded to `f32`.
//!
//! The paper's figure 3(c) input `u1 = 1/√t` is singular at `t = 0`; the
//! runs use `1/√(1+t)`, which has the same tail (`∫u1² = ∞`, not PE).

use super::unicycle::{ErrorStats, PAPER_001_START, TrackingRecorder, nearest_tag};
use super::{Figure, Series};
use wmr_core::control::robot_frame::UnicycleReference;
use wmr_core::geometry::{BodyVelocity, Pose};
use wmr_core::reference::{FigureEight, Trajectory};
use wmr_papers::chained_form::{
    ChainedGains, ChainedInput, ChainedObserver, ChainedObserverConfig, ChainedOutput,
    ChainedReference, ChainedState, ChainedStateFeedback, ReducedOrderConfig, ReducedOrderTracker,
};

/// Step of the section 2 simulations, s (the paper does not state its own).
pub const STEP_S: f64 = 0.001;

/// An input profile `t ↦ u(t)`.
pub type InputProfile = fn(f64) -> f64;

/// A chained-form state in `f64`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Chained64 {
    /// `x1`, rad.
    pub x1: f64,
    /// `x2`, m.
    pub x2: f64,
    /// `x3`, m.
    pub x3: f64,
}

impl Chained64 {
    /// (7) integrated exactly over `h` with `(u1, u2)` held.
    #[must_use]
    pub fn advance(self, u1: f64, u2: f64, h: f64) -> Self {
        Self {
            x1: self.x1 + h * u1,
            x2: self.x2 + h * u2,
            x3: self.x3 + h * u1 * self.x2 + 0.5 * h * h * u1 * u2,
        }
    }

    fn to_f32(self) -> ChainedState {
        ChainedState {
            x1_rad: self.x1 as f32,
            x2_m: self.x2 as f32,
            x3_m: self.x3 as f32,
        }
    }

    fn minus(self, other: Self) -> Self {
        Self {
            x1: self.x1 - other.x1,
            x2: self.x2 - other.x2,
            x3: self.x3 - other.x3,
        }
    }

    fn norm(self) -> f64 {
        (self.x1 * self.x1 + self.x2 * self.x2 + self.x3 * self.x3).sqrt()
    }
}

/// The reference's `u2r` in the closed-loop runs: `cos t`, so
/// `x2r = sin t` is bounded.
fn reference_u2(t: f64) -> f64 {
    t.cos()
}

/// The plant under the observer of figures 2 and 3.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Plant {
    /// `u2 = cos t` from `x(0) = 0`: `x2 = sin t` and `x3` move, so the
    /// `f32` estimate of a state of size ~1 floors the error near 1e-5
    /// (more with larger `a2/a3`, which amplifies the rounding of `y2`).
    Moving,
    /// `u2 = 0` at `x = 0`: the robot turns in place at the origin. The
    /// error system (17) does not depend on the state, and here
    /// `x̂ = −x̃` keeps full relative `f32` precision, so slow tails can be
    /// followed far below the moving plant's floor.
    AtOrigin,
}

impl Plant {
    fn u2(self, t: f64) -> f64 {
        match self {
            Self::Moving => t.cos(),
            Self::AtOrigin => 0.0,
        }
    }
}

/// Figures 2 and 3: the Proposition 2 observer on a plant driven by
/// `u1(t)` and `plant`'s `u2`, with the estimate starting at
/// `x(0) − (1, 1, 1)` (every error 1, as in the paper), `a1 = 1` and the
/// given `a2, a3`. Returns `|x̃2|, |x̃3|`, sampled every 10 ms.
///
/// # Panics
/// If the gains are not positive.
#[must_use]
pub fn observer_run(
    plant_kind: Plant,
    u1: InputProfile,
    a2: f32,
    a3: f32,
    duration_s: f64,
) -> [Series; 2] {
    let h = STEP_S;
    let config = ChainedObserverConfig::new(1.0, a2, a3, h as f32).expect("positive gains");
    let mut plant = Chained64::default();
    let mut observer = ChainedObserver::new(
        config,
        ChainedState {
            x1_rad: -1.0,
            x2_m: -1.0,
            x3_m: -1.0,
        },
    );
    let mut out = [Series::new("|x̃2|"), Series::new("|x̃3|")];
    let steps = (duration_s / h).round() as u32;
    for k in 0..=steps {
        let t = f64::from(k) * h;
        if k % 10 == 0 {
            let e = observer.estimate();
            out[0].points.push((t, plant.x2 - f64::from(e.x2_m)));
            out[1].points.push((t, plant.x3 - f64::from(e.x3_m)));
        }
        let (u1, u2) = (u1(t), plant_kind.u2(t));
        plant = plant.advance(u1, u2, h);
        let input = ChainedInput {
            u1_rad_s: u1 as f32,
            u2_m_s: u2 as f32,
        };
        observer.update(input, ChainedOutput::of(plant.to_f32()));
    }
    out
}

/// Which closed loop of section 2 to simulate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ChainedLoop {
    /// Proposition 1: state feedback (10), `x2e` measured.
    StateFeedback,
    /// Proposition 3: the controller (25) on the reduced-order observer of
    /// `x2e` (26), from `x̂2e(0) = 0`.
    ReducedOrder,
}

/// A closed-loop run: `|x_e|` and (Proposition 3 only) `|x̃2e|`.
#[derive(Debug, Clone, PartialEq)]
pub struct ClosedLoopRun {
    /// `|x − x_r|` (Euclidean norm over the three coordinates).
    pub tracking_error: Series,
    /// `|x2e − x̂2e|` (empty for state feedback).
    pub observer_error: Series,
    /// `x̃2e(0) e^{−a1 ∫u1²}` over the inputs actually applied: what the
    /// observer error should be by the derivation in the core's docs.
    pub predicted_observer_error: Series,
    /// The last `x3e`, m (for the cases without excitation).
    pub final_x3e_m: f64,
}

/// Propositions 1 and 3 on a reference driven by `u1r(t)` and
/// `u2r = cos t` from `x_r(0) = 0` (so `x2r = sin t` is bounded), with the
/// plant starting at `(1, 1, 1)` (every error 1), gains
/// `c1 = c2 = c3 = 1` and observer gain `a1 = 10`. Sampled every 10 ms.
///
/// # Panics
/// Never for these constant gains.
#[must_use]
pub fn closed_loop_run(which: ChainedLoop, u1r: InputProfile, duration_s: f64) -> ClosedLoopRun {
    let h = STEP_S;
    let gains = ChainedGains::new(1.0, 1.0, 1.0).expect("positive gains");
    let feedback = ChainedStateFeedback::new(gains);
    let mut tracker = ReducedOrderTracker::new(
        ReducedOrderConfig::new(gains, 10.0, h as f32).expect("positive gains"),
        0.0,
    );
    let mut reference = Chained64::default();
    // `a1` below is the same 10.
    let mut plant = Chained64 {
        x1: 1.0,
        x2: 1.0,
        x3: 1.0,
    };
    let mut run = ClosedLoopRun {
        tracking_error: Series::new("|x_e|"),
        observer_error: Series::new("|x̃2e| (m)"),
        predicted_observer_error: Series::new("x̃2e(0) e^{−a1 ∫u1²}"),
        final_x3e_m: 0.0,
    };
    let a1 = 10.0_f64;
    let initial_miss = plant.x2 - reference.x2;
    let mut integral_u1_squared = 0.0_f64;
    let mut applied = ChainedInput::STOP;
    let steps = (duration_s / h).round() as u32;
    for k in 0..=steps {
        let t = f64::from(k) * h;
        let (u1r, u2r) = (u1r(t), reference_u2(t));
        let error = plant.minus(reference);
        let chained_reference = ChainedReference {
            state: reference.to_f32(),
            input: ChainedInput {
                u1_rad_s: u1r as f32,
                u2_m_s: u2r as f32,
            },
        };
        let measured = ChainedOutput {
            x1_rad: error.x1 as f32,
            x3_m: error.x3 as f32,
        };
        let command = match which {
            ChainedLoop::StateFeedback => feedback.command(error.to_f32(), chained_reference.input),
            ChainedLoop::ReducedOrder => {
                tracker.update(measured, applied, &chained_reference);
                tracker.command(measured, &chained_reference)
            }
        };
        if k % 10 == 0 {
            run.tracking_error.points.push((t, error.norm()));
            if which == ChainedLoop::ReducedOrder {
                let miss = error.x2 - f64::from(tracker.x2e_hat_m());
                run.observer_error.points.push((t, miss));
                run.predicted_observer_error
                    .points
                    .push((t, initial_miss * (-a1 * integral_u1_squared).exp()));
            }
        }
        run.final_x3e_m = error.x3;
        applied = command;
        integral_u1_squared += h * f64::from(command.u1_rad_s).powi(2);
        plant = plant.advance(f64::from(command.u1_rad_s), f64::from(command.u2_m_s), h);
        reference = reference.advance(u1r, u2r, h);
    }
    run
}

/// Proposition 3 driving the unicycle through (6) on paper 001's
/// figure-eight run (start `(0, −6)`, heading 3π/2, 480 s, h = 10 ms, the
/// nearest tag of a 10 cm grid as the position every tick) **with the
/// heading measured exactly**, which RFID does not give: the chained form
/// needs `x1 = θ`. Gains `c1 = 0.5, c2 = 0.5, c3`, observer `a1` as given.
/// Statistics of `|p − p_r|` over `t ≥ 100 s`.
///
/// # Panics
/// If the gains are not positive.
#[must_use]
pub fn figure_eight_with_measured_heading(c3: f32, a1: f32) -> (ErrorStats, Series) {
    let h = 0.01_f64;
    let hf = h as f32;
    let trajectory: Trajectory = FigureEight::paper_001().into();
    let gains = ChainedGains::new(0.5, 0.5, c3).expect("positive gains");
    let mut tracker = ReducedOrderTracker::new(
        ReducedOrderConfig::new(gains, a1, hf).expect("positive gains"),
        0.0,
    );
    let mut robot = PAPER_001_START;
    let mut applied = ChainedInput::STOP;
    let mut recorder = TrackingRecorder::new("002 Prop. 3 (25)–(26), θ measured");
    for k in 0..48_000u32 {
        let t = f64::from(k) * h;
        let sample = trajectory.sample(k as f32 * hf);
        recorder.record(k, t, &robot, sample.position);
        let reference = UnicycleReference::from_sample(&sample).expect("moving reference");
        let reference = ChainedReference::from_unicycle(&reference);
        let tag = nearest_tag(&robot);
        let measured_pose = Pose::new(tag.x, tag.y, robot.theta as f32);
        let state = ChainedState::from_pose(measured_pose);
        let measured = ChainedOutput::of(state.error_from(reference.state));
        tracker.update(measured, applied, &reference);
        let command = tracker.command(measured, &reference);
        let body: BodyVelocity = command.to_body(state.x3_m);
        applied = command;
        robot = robot.advance(f64::from(body.v_m_s), f64::from(body.omega_rad_s), h);
    }
    recorder.finish()
}

/// Figure 2's cases: `(name, title, u1, a2, a3)`. The paper gives `u1` for
/// (a) and (b) only; (c) and (d) vary (b)'s gains, so they keep `u1 = sin t`.
pub const FIGURE_2: [(&str, &str, InputProfile, f32, f32); 4] = [
    (
        "fig2a_chained_observer_u1_const",
        "Fig. 2(a): Prop. 2 observer, u1 = 1; a2 = 1000, a3 = 100",
        |_| 1.0,
        1000.0,
        100.0,
    ),
    (
        "fig2b_chained_observer_u1_sin",
        "Fig. 2(b): u1 = sin t; a2 = 1000, a3 = 10",
        f64::sin,
        1000.0,
        10.0,
    ),
    (
        "fig2c_chained_observer_low_gains",
        "Fig. 2(c): u1 = sin t; a2 = 100, a3 = 10",
        f64::sin,
        100.0,
        10.0,
    ),
    (
        "fig2d_chained_observer_high_gains",
        "Fig. 2(d): u1 = sin t; a2 = 10000, a3 = 100",
        f64::sin,
        10000.0,
        100.0,
    ),
];

/// Figure 3's cases (`u1` not persistently exciting), with figure 2(a)'s
/// gains `a2 = 1000, a3 = 100` (the paper does not give them), run with
/// [`Plant::AtOrigin`] to follow the tails.
pub const FIGURE_3: [(&str, &str, InputProfile); 3] = [
    (
        "fig3a_chained_observer_u1_zero",
        "Fig. 3(a): u1 = 0; a2 = 1000, a3 = 100",
        |_| 0.0,
    ),
    (
        "fig3b_chained_observer_u1_exp",
        "Fig. 3(b): u1 = e^{-t} (∫u1² < ∞)",
        |t| (-t).exp(),
    ),
    (
        "fig3c_chained_observer_u1_invsqrt",
        "Fig. 3(c): u1 = 1/√(1+t) (∫u1² = ∞, not PE)",
        |t| 1.0 / (1.0 + t).sqrt(),
    ),
];

/// The section 2 figures: 2(a)–(d), 3(a)–(c), and the closed loops of
/// Propositions 1 and 3.
#[must_use]
pub fn figures() -> Vec<Figure> {
    let mut figures = Vec::new();
    for (name, title, u1, a2, a3) in FIGURE_2 {
        figures.push(Figure {
            name: name.into(),
            title: title.into(),
            series: observer_run(Plant::Moving, u1, a2, a3, 10.0).to_vec(),
        });
    }
    for (name, title, u1) in FIGURE_3 {
        figures.push(Figure {
            name: name.into(),
            title: title.into(),
            series: observer_run(Plant::AtOrigin, u1, 1000.0, 100.0, 20.0).to_vec(),
        });
    }
    for (name, title, which) in [
        (
            "prop1_chained_state_feedback",
            "Prop. 1: state feedback (10), u1r = sin t; c1 = c2 = c3 = 1",
            ChainedLoop::StateFeedback,
        ),
        (
            "prop3_chained_reduced_order",
            "Prop. 3: controller (25) + observer (26), u1r = sin t; a1 = 10",
            ChainedLoop::ReducedOrder,
        ),
    ] {
        let run = closed_loop_run(which, f64::sin, 30.0);
        let mut series = vec![run.tracking_error];
        if !run.observer_error.points.is_empty() {
            series.push(run.observer_error);
        }
        figures.push(Figure {
            name: name.into(),
            title: title.into(),
            series,
        });
    }
    figures.push(Figure {
        name: "prop3_figure_eight_measured_heading".into(),
        title: "Prop. 3 on the figure-eight, θ measured: |p − p_r| (m)".into(),
        series: vec![figure_eight_with_measured_heading(10.0, 100.0).1],
    });
    figures
}
