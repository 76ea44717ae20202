//! Paper 002 (Jakubiak, Nijmeijer & Lefeber), section 2: the chained form
//! of the unicycle, its state feedback (Proposition 1), its full-state
//! observer (Proposition 2) and the controller on a reduced-order observer
//! (Proposition 3).
//!
//! # Change of coordinates (6) and chained form (7)
//! ```text
//! x1 = θ                          u1 = ω
//! x2 = x cos θ + y sin θ          u2 = v − ω x3             (6a), (6b)
//! x3 = x sin θ − y cos θ
//! ẋ1 = u1,  ẋ2 = u2,  ẋ3 = u1 x2                            (7)
//! ```
//! The inverse is `θ = x1`, `x = x2 cos x1 + x3 sin x1`,
//! `y = x2 sin x1 − x3 cos x1`, `ω = u1`, `v = u2 + u1 x3`
//! ([`ChainedState::from_pose`], [`ChainedState::to_pose`],
//! [`ChainedInput::from_body`], [`ChainedInput::to_body`]). `x2, x3` are the
//! world position rotated into the robot's frame (metres), so the form
//! depends on where the world origin is.
//!
//! # Proposition 1, state feedback (10)
//! `u1 = u1r − c1 x1e`, `u2 = u2r − c2 x2e − c3 u1 x3e` with `x_e = x − x_r`
//! ([`ChainedStateFeedback`]): globally K-exponentially stable when `x2r` is
//! bounded and `u1r` persistently exciting. Sampled, it is held over each
//! step (zero-order hold).
//!
//! # Proposition 2, full-state observer (14), (16)
//! With outputs `y1 = x1`, `y2 = x3` (13), the observer is a copy of (7)
//! with injections `f1 = a1 x̃1`, `f2 = a2 u1 x̃3`, `f3 = a3 x̃3`, where the
//! injected `x̃1 = y1 − x̂1`, `x̃3 = y2 − x̂3` are measured residuals. The
//! printed (16) reads as if `f` used the unknown error; only the measured
//! residual makes (14) implementable, and it is what the proof's error
//! system (17) uses: `x̃̇2 = −a2 u1 x̃3`, `x̃̇3 = u1 x̃2 − a3 x̃3`, for which
//! `V = x̃2² + a2 x̃3²` has `V̇ = −2 a2 a3 x̃3²`.
//!
//! Discretization ([`ChainedObserver::update`]): with the inputs held over a
//! step of length `h`, (7) is integrated exactly by [`ChainedState::advance`]
//! (`x3⁺ = x3 + h u1 x2 + ½h² u1 u2`). The observer predicts with the same
//! map and corrects with a backward-Euler (implicit) step of the injection,
//! using `y2` measured at the step's end:
//!
//! ```text
//! r    = (y2⁺ − x̂3⁻) / (1 + h a3 + h² a2 u1²)      x̂⁻ = advance(x̂, u, h)
//! x̂3⁺ = y2⁺ − r,   x̂2⁺ = x̂2⁻ + h a2 u1 r
//! x̂1⁺ = y1⁺ − e^{−a1 h} wrap(y1⁺ − x̂1⁻)
//! ```
//!
//! The error then obeys exactly `(I − hA) x̃⁺ = x̃` with `A` the matrix of
//! (17); since `PA + AᵀP = diag(0, −2 a2 a3) ≤ 0` for `P = diag(1, a2)`,
//! `|x̃|²_P = |x̃⁺|²_P − h x̃⁺ᵀ(PA + AᵀP)x̃⁺ + h²|Ax̃⁺|²_P ≥ |x̃⁺|²_P`: the
//! discrete `V` never increases, for any step, gains or input, as in
//! continuous time. The denominator is ≥ 1. With `u1 ≡ 0` nothing corrects
//! `x̃2` (the paper's figure 3(a)).
//!
//! # Proposition 3, reduced-order observer and controller (25)–(26)
//! The controller (25) is (10) with the estimate `x̂2e` of the unmeasured
//! `x2e`; the outputs are `x1e` and `x3e` (19). The paper's observer (26)
//! estimates `z = x2e − a1 u1 x3e`, which needs `u̇1`. Derived from the
//! closed loop under (25) rather than under (10), the printed (26b) has two
//! slips:
//! * its last term has the wrong sign: (21) gives `+b2 c1 x2r x1e`, i.e.
//!   `+a1 c1 u1 x2r x1e`;
//! * under (25), `ẋ2e = u2 − u2r = −c2 x̂2e − c3 u1 x3e` is known to the
//!   observer, so the `−c2` terms of (26b) cancel against it and the error
//!   obeys `x̃̇2e = −a1 u1² x̃2e`, not `−(a1 u1² + c2) x̃2e` as printed after
//!   (24) and in (29b) (the same slip as Proposition 6, see
//!   [`wmr_core::control::heading_error_sine`]). `x̃2e` converges exponentially when
//!   `u1` is persistently exciting, which the proposition assumes of `u1r`
//!   (and `u1 → u1r`), so its conclusion stands.
//!
//! A sampled observer measures the change of `x3e` directly, which is what
//! the `z` construction stands in for ([`ReducedOrderTracker::update`]): over
//! a step with held inputs `ẋ3e = u1 x2 − u1r x2r` integrates exactly to
//!
//! ```text
//! ν     = Δx3e − h (u1 x̂2e,mid + (u1 − u1r) x2r,mid)      = h u1 x̃2e
//! x̂2e⁺ = x̂2e + h (u2 − u2r) + a1 u1 φ(a1 u1² h) ν,     φ(k) = (1 − e^{−k})/k
//! ```
//!
//! (`mid` values at half step: `x̂2e + ½h(u2 − u2r)`, `x2r + ½h u2r`), so
//! `x̃2e⁺ = e^{−a1 u1² h} x̃2e`: exactly the decay of the continuous
//! observer, and `u̇1` is not needed.
//!
//! # Angle convention
//! `x1 = θ` is kept as given (integrated, not wrapped), like
//! [`Pose::heading_rad`]. `x2, x3` are 2π-periodic in `x1`, so differences
//! of `x1` are wrapped to (−π, π] where they are used (the error `x1e` in
//! [`ChainedState::error_from`], the residual `y1 − x̂1`): the controllers
//! turn the short way round, and (11a) `ẋ1e = −c1 x1e` holds between wraps
//! (a wrap happens only at `|x1e| = π`, where `−c1 x1e` points inward from
//! both sides).
//!
//! # Bad input
//! Non-finite inputs or results are counted (`rejected_updates`) and leave
//! an observer's estimate unchanged; a controller given a non-finite error,
//! reference or estimate commands [`ChainedInput::STOP`] (`u = 0`, which is
//! `v = ω = 0`).

use wmr_core::control::robot_frame::UnicycleReference;
use wmr_core::geometry::{BodyVelocity, Pose, Vec2};
use wmr_core::math;

/// Why a gain or step of this module was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum ChainedFormError {
    /// `c1` (1/s) not finite and positive.
    C1,
    /// `c2` (1/s) not finite and positive.
    C2,
    /// `c3` (1/m) not finite and positive.
    C3,
    /// An observer's `a1` not finite and positive.
    A1,
    /// Proposition 2's `a2` (1/m²) not finite and positive.
    A2,
    /// Proposition 2's `a3` (1/s) not finite and positive.
    A3,
    /// Control period not finite and positive.
    Period,
}

impl core::fmt::Display for ChainedFormError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::C1 => "c1 must be finite and > 0 1/s",
            Self::C2 => "c2 must be finite and > 0 1/s",
            Self::C3 => "c3 must be finite and > 0 1/m",
            Self::A1 => "an observer's a1 must be finite and > 0",
            Self::A2 => "Proposition 2's a2 must be finite and > 0 1/m²",
            Self::A3 => "Proposition 2's a3 must be finite and > 0 1/s",
            Self::Period => "period_s must be finite and > 0 s",
        })
    }
}

impl core::error::Error for ChainedFormError {}

fn positive(x: f32) -> bool {
    x.is_finite() && x > 0.0
}

/// A state of the chained form (7).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ChainedState {
    /// `x1 = θ`, rad.
    pub x1_rad: f32,
    /// `x2 = x cos θ + y sin θ`, m.
    pub x2_m: f32,
    /// `x3 = x sin θ − y cos θ`, m.
    pub x3_m: f32,
}

impl ChainedState {
    /// The coordinates (6a) of a pose.
    #[must_use]
    pub fn from_pose(pose: Pose) -> Self {
        let (s, c) = (math::sin(pose.heading_rad), math::cos(pose.heading_rad));
        let p = pose.position;
        Self {
            x1_rad: pose.heading_rad,
            x2_m: p.x * c + p.y * s,
            x3_m: p.x * s - p.y * c,
        }
    }

    /// The pose of these coordinates (inverse of (6a)).
    #[must_use]
    pub fn to_pose(self) -> Pose {
        let (s, c) = (math::sin(self.x1_rad), math::cos(self.x1_rad));
        Pose {
            position: Vec2::new(self.x2_m * c + self.x3_m * s, self.x2_m * s - self.x3_m * c),
            heading_rad: self.x1_rad,
        }
    }

    /// The tracking error `x − x_r` (9), with `x1e` wrapped to (−π, π].
    #[must_use]
    pub fn error_from(self, reference: Self) -> Self {
        Self {
            x1_rad: math::wrap_angle(self.x1_rad - reference.x1_rad),
            x2_m: self.x2_m - reference.x2_m,
            x3_m: self.x3_m - reference.x3_m,
        }
    }

    /// The state after `input` held for `h` seconds: (7) integrated exactly.
    #[must_use]
    pub fn advance(self, input: ChainedInput, h_s: f32) -> Self {
        let x2_next = self.x2_m + h_s * input.u2_m_s;
        Self {
            x1_rad: self.x1_rad + h_s * input.u1_rad_s,
            x2_m: x2_next,
            x3_m: self.x3_m + h_s * input.u1_rad_s * 0.5 * (self.x2_m + x2_next),
        }
    }

    /// All components finite.
    #[must_use]
    pub fn is_finite(self) -> bool {
        self.x1_rad.is_finite() && self.x2_m.is_finite() && self.x3_m.is_finite()
    }
}

/// Inputs of the chained form (7).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ChainedInput {
    /// `u1 = ω`, rad/s.
    pub u1_rad_s: f32,
    /// `u2 = v − ω x3`, m/s.
    pub u2_m_s: f32,
}

impl ChainedInput {
    /// `u = 0`: the robot stands still (`v = ω = 0`) wherever it is.
    pub const STOP: Self = Self {
        u1_rad_s: 0.0,
        u2_m_s: 0.0,
    };

    /// The feedback transformation (6b) at a state with this `x3`.
    #[must_use]
    pub fn from_body(body: BodyVelocity, x3_m: f32) -> Self {
        Self {
            u1_rad_s: body.omega_rad_s,
            u2_m_s: body.v_m_s - body.omega_rad_s * x3_m,
        }
    }

    /// The robot's `(v, ω)` for these inputs at a state with this `x3`.
    #[must_use]
    pub fn to_body(self, x3_m: f32) -> BodyVelocity {
        BodyVelocity {
            v_m_s: self.u2_m_s + self.u1_rad_s * x3_m,
            omega_rad_s: self.u1_rad_s,
        }
    }

    /// Both components finite.
    #[must_use]
    pub fn is_finite(self) -> bool {
        self.u1_rad_s.is_finite() && self.u2_m_s.is_finite()
    }
}

/// A reference of the chained form (8): its state and inputs at one time.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ChainedReference {
    /// `x_r`.
    pub state: ChainedState,
    /// `u_r`.
    pub input: ChainedInput,
}

impl ChainedReference {
    /// A unicycle reference (e.g. from one of the core's trajectories via
    /// [`UnicycleReference::from_sample`]) in chained coordinates.
    #[must_use]
    pub fn from_unicycle(reference: &UnicycleReference) -> Self {
        let state = ChainedState::from_pose(reference.pose());
        let body = BodyVelocity {
            v_m_s: reference.v_m_s,
            omega_rad_s: reference.omega_rad_s,
        };
        Self {
            state,
            input: ChainedInput::from_body(body, state.x3_m),
        }
    }

    /// All components finite.
    #[must_use]
    pub fn is_finite(&self) -> bool {
        self.state.is_finite() && self.input.is_finite()
    }
}

/// The measured outputs `y1 = x1`, `y2 = x3` (13), or their errors (19).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ChainedOutput {
    /// `x1` (or `x1e`), rad.
    pub x1_rad: f32,
    /// `x3` (or `x3e`), m.
    pub x3_m: f32,
}

impl ChainedOutput {
    /// The outputs of a state.
    #[must_use]
    pub fn of(state: ChainedState) -> Self {
        Self {
            x1_rad: state.x1_rad,
            x3_m: state.x3_m,
        }
    }

    /// Both components finite.
    #[must_use]
    pub fn is_finite(self) -> bool {
        self.x1_rad.is_finite() && self.x3_m.is_finite()
    }
}

/// Validated gains `c1, c2, c3` of (10) and (25).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ChainedGains {
    c1_per_s: f32,
    c2_per_s: f32,
    c3_per_m: f32,
}

impl ChainedGains {
    /// `c1` (1/s, heading), `c2` (1/s, `x2e`), `c3` (1/m, `x3e` coupling).
    ///
    /// # Errors
    /// The first gain that is not finite and positive.
    pub fn new(c1_per_s: f32, c2_per_s: f32, c3_per_m: f32) -> Result<Self, ChainedFormError> {
        if !positive(c1_per_s) {
            return Err(ChainedFormError::C1);
        }
        if !positive(c2_per_s) {
            return Err(ChainedFormError::C2);
        }
        if !positive(c3_per_m) {
            return Err(ChainedFormError::C3);
        }
        Ok(Self {
            c1_per_s,
            c2_per_s,
            c3_per_m,
        })
    }

    /// `[c1, c2, c3]`.
    #[must_use]
    pub fn gains(&self) -> [f32; 3] {
        [self.c1_per_s, self.c2_per_s, self.c3_per_m]
    }

    /// (10) with `x2e` given (measured, or estimated as in (25)); STOP if
    /// anything is not finite.
    fn law(&self, reference: ChainedInput, x1e: f32, x2e: f32, x3e: f32) -> ChainedInput {
        let u1 = reference.u1_rad_s - self.c1_per_s * x1e;
        let u = ChainedInput {
            u1_rad_s: u1,
            u2_m_s: reference.u2_m_s - self.c2_per_s * x2e - self.c3_per_m * u1 * x3e,
        };
        if u.is_finite() { u } else { ChainedInput::STOP }
    }
}

/// Proposition 1: the state feedback (10).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ChainedStateFeedback {
    gains: ChainedGains,
}

impl ChainedStateFeedback {
    /// A controller with these gains.
    #[must_use]
    pub fn new(gains: ChainedGains) -> Self {
        Self { gains }
    }

    /// The gains.
    #[must_use]
    pub fn gains(&self) -> &ChainedGains {
        &self.gains
    }

    /// The inputs (10) for the error `x − x_r` (see
    /// [`ChainedState::error_from`]) and the reference inputs `u_r`.
    /// [`ChainedInput::STOP`] if either is not finite.
    #[must_use]
    pub fn command(&self, error: ChainedState, reference: ChainedInput) -> ChainedInput {
        self.gains
            .law(reference, error.x1_rad, error.x2_m, error.x3_m)
    }
}

/// Validated gains and step of the Proposition 2 observer.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ChainedObserverConfig {
    a1_per_s: f32,
    a2_per_m2: f32,
    a3_per_s: f32,
    period_s: f32,
}

impl ChainedObserverConfig {
    /// Gains `a1` (1/s), `a2` (1/m², with `x1` in rad), `a3` (1/s) of (16)
    /// and the step `h` (s). The paper's figure 2(a): `a2 = 1000, a3 = 100`.
    ///
    /// # Errors
    /// The first parameter that is not finite and positive.
    pub fn new(
        a1_per_s: f32,
        a2_per_m2: f32,
        a3_per_s: f32,
        period_s: f32,
    ) -> Result<Self, ChainedFormError> {
        if !positive(a1_per_s) {
            return Err(ChainedFormError::A1);
        }
        if !positive(a2_per_m2) {
            return Err(ChainedFormError::A2);
        }
        if !positive(a3_per_s) {
            return Err(ChainedFormError::A3);
        }
        if !positive(period_s) {
            return Err(ChainedFormError::Period);
        }
        Ok(Self {
            a1_per_s,
            a2_per_m2,
            a3_per_s,
            period_s,
        })
    }

    /// The step `h`, s.
    #[must_use]
    pub fn period_s(&self) -> f32 {
        self.period_s
    }

    /// `[a1, a2, a3]`.
    #[must_use]
    pub fn gains(&self) -> [f32; 3] {
        [self.a1_per_s, self.a2_per_m2, self.a3_per_s]
    }
}

/// Proposition 2: the full-state observer (14), (16) of the chained form,
/// discretized as in the module docs.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ChainedObserver {
    config: ChainedObserverConfig,
    estimate: ChainedState,
    rejected_updates: u32,
}

impl ChainedObserver {
    /// An observer starting from `initial` (a non-finite initial state
    /// starts from the origin instead).
    #[must_use]
    pub fn new(config: ChainedObserverConfig, initial: ChainedState) -> Self {
        Self {
            config,
            estimate: if initial.is_finite() {
                initial
            } else {
                ChainedState::default()
            },
            rejected_updates: 0,
        }
    }

    /// The configuration.
    #[must_use]
    pub fn config(&self) -> &ChainedObserverConfig {
        &self.config
    }

    /// The estimate `x̂`.
    #[must_use]
    pub fn estimate(&self) -> ChainedState {
        self.estimate
    }

    /// Updates skipped because an input or the result was not finite.
    #[must_use]
    pub fn rejected_updates(&self) -> u32 {
        self.rejected_updates
    }

    /// One step: `input` held over the step, `measured` the outputs at its
    /// end. A non-finite input or result leaves the estimate unchanged and
    /// is counted.
    pub fn update(&mut self, input: ChainedInput, measured: ChainedOutput) {
        if !(input.is_finite() && measured.is_finite()) {
            self.rejected_updates = self.rejected_updates.saturating_add(1);
            return;
        }
        let ChainedObserverConfig {
            a1_per_s: a1,
            a2_per_m2: a2,
            a3_per_s: a3,
            period_s: h,
        } = self.config;
        let u1 = input.u1_rad_s;
        let predicted = self.estimate.advance(input, h);
        let residual = (measured.x3_m - predicted.x3_m) / (1.0 + h * a3 + h * h * a2 * u1 * u1);
        let heading_residual = math::wrap_angle(measured.x1_rad - predicted.x1_rad);
        let next = ChainedState {
            x1_rad: measured.x1_rad - math::exp(-a1 * h) * heading_residual,
            x2_m: predicted.x2_m + h * a2 * u1 * residual,
            x3_m: measured.x3_m - residual,
        };
        if next.is_finite() {
            self.estimate = next;
        } else {
            self.rejected_updates = self.rejected_updates.saturating_add(1);
        }
    }
}

/// Validated gains and step of the Proposition 3 tracker.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ReducedOrderConfig {
    gains: ChainedGains,
    a1_s_per_m2: f32,
    period_s: f32,
}

impl ReducedOrderConfig {
    /// The controller gains of (25), the observer gain `a1` of (26) (s/rad²
    /// with `u1` in rad/s; not Proposition 2's `a1`) and the step `h` (s).
    ///
    /// # Errors
    /// [`ChainedFormError::A1`] or [`ChainedFormError::Period`].
    pub fn new(
        gains: ChainedGains,
        a1_s_per_m2: f32,
        period_s: f32,
    ) -> Result<Self, ChainedFormError> {
        if !positive(a1_s_per_m2) {
            return Err(ChainedFormError::A1);
        }
        if !positive(period_s) {
            return Err(ChainedFormError::Period);
        }
        Ok(Self {
            gains,
            a1_s_per_m2,
            period_s,
        })
    }

    /// The step `h`, s.
    #[must_use]
    pub fn period_s(&self) -> f32 {
        self.period_s
    }
}

/// What the tracker remembers of the start of the current step.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
struct StepStart {
    x3e_m: f32,
    reference: ChainedReference,
}

/// Proposition 3: the reduced-order observer of `x2e` (26, in the innovation
/// form of the module docs) and the controller (25) on its estimate.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ReducedOrderTracker {
    config: ReducedOrderConfig,
    x2e_hat_m: f32,
    start: Option<StepStart>,
    rejected_updates: u32,
}

impl ReducedOrderTracker {
    /// A tracker with the estimate `x̂2e(0)` (m; 0 when nothing is known, a
    /// non-finite value is taken as 0).
    #[must_use]
    pub fn new(config: ReducedOrderConfig, x2e_hat_0_m: f32) -> Self {
        Self {
            config,
            x2e_hat_m: if x2e_hat_0_m.is_finite() {
                x2e_hat_0_m
            } else {
                0.0
            },
            start: None,
            rejected_updates: 0,
        }
    }

    /// `x̂2e`, m.
    #[must_use]
    pub fn x2e_hat_m(&self) -> f32 {
        self.x2e_hat_m
    }

    /// Updates skipped for non-finite input or result.
    #[must_use]
    pub fn rejected_updates(&self) -> u32 {
        self.rejected_updates
    }

    /// One step of the observer: the error outputs `(x1e, x3e)` measured now
    /// (`x1e` is not needed by the observer), the inputs `u` applied over the
    /// step just ended, and the reference now. The first call (and the first
    /// after a rejected one) only records the step's start. A non-finite
    /// input or result is counted, keeps the estimate, and restarts the
    /// innovation (a step's change of `x3e` is never taken across a gap).
    pub fn update(
        &mut self,
        measured: ChainedOutput,
        applied: ChainedInput,
        reference: &ChainedReference,
    ) {
        if !(measured.is_finite() && applied.is_finite() && reference.is_finite()) {
            self.reject();
            return;
        }
        let now = StepStart {
            x3e_m: measured.x3_m,
            reference: *reference,
        };
        let Some(start) = self.start.replace(now) else {
            return;
        };
        let h = self.config.period_s;
        let a1 = self.config.a1_s_per_m2;
        let (u1, u2) = (applied.u1_rad_s, applied.u2_m_s);
        let ChainedInput {
            u1_rad_s: u1r,
            u2_m_s: u2r,
        } = start.reference.input;
        let x2e_rate = u2 - u2r;
        let x2e_mid = self.x2e_hat_m + 0.5 * h * x2e_rate;
        let x2r_mid = start.reference.state.x2_m + 0.5 * h * u2r;
        let innovation = (measured.x3_m - start.x3e_m) - h * (u1 * x2e_mid + (u1 - u1r) * x2r_mid);
        let k = a1 * u1 * u1 * h;
        let next = self.x2e_hat_m
            + h * x2e_rate
            + a1 * u1 * math::one_minus_exp_neg_over_x(k) * innovation;
        if next.is_finite() {
            self.x2e_hat_m = next;
        } else {
            self.reject();
        }
    }

    fn reject(&mut self) {
        self.rejected_updates = self.rejected_updates.saturating_add(1);
        self.start = None;
    }

    /// The inputs (25) from the measured `(x1e, x3e)`, the current `x̂2e`
    /// and the reference inputs; [`ChainedInput::STOP`] if anything is not
    /// finite.
    #[must_use]
    pub fn command(&self, measured: ChainedOutput, reference: &ChainedReference) -> ChainedInput {
        self.config.gains.law(
            reference.input,
            measured.x1_rad,
            self.x2e_hat_m,
            measured.x3_m,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn configuration_names_the_bad_gain() {
        assert_eq!(ChainedGains::new(0.0, 1.0, 1.0), Err(ChainedFormError::C1));
        assert_eq!(
            ChainedGains::new(1.0, f32::NAN, 1.0),
            Err(ChainedFormError::C2)
        );
        assert_eq!(ChainedGains::new(1.0, 1.0, -1.0), Err(ChainedFormError::C3));
        assert_eq!(
            ChainedObserverConfig::new(1.0, 1.0, 1.0, 0.0),
            Err(ChainedFormError::Period)
        );
        assert_eq!(
            ChainedObserverConfig::new(1.0, f32::INFINITY, 1.0, 0.01),
            Err(ChainedFormError::A2)
        );
        let gains = ChainedGains::new(1.0, 1.0, 1.0).unwrap();
        assert_eq!(
            ReducedOrderConfig::new(gains, 0.0, 0.01),
            Err(ChainedFormError::A1)
        );
    }

    /// (6) turns the unicycle into (7): one exact-arc step of the robot is
    /// one exact step of the chained form with the transformed inputs.
    #[test]
    fn unicycle_steps_are_chained_form_steps() {
        let pose = Pose::new(1.5, -0.7, 0.4);
        let body = BodyVelocity {
            v_m_s: 0.8,
            omega_rad_s: -0.6,
        };
        let h = 0.01;
        let x = ChainedState::from_pose(pose);
        let u = ChainedInput::from_body(body, x.x3_m);
        // (7) with u2 = v − ω x3 held is exact only while x3 does not
        // change u2; over one short step the mismatch is O(h²).
        let via_chained = x.advance(u, h).to_pose();
        let direct = pose.advance_arc(body.v_m_s * h, body.omega_rad_s * h);
        let d = math::hypot(
            via_chained.position.x - direct.position.x,
            via_chained.position.y - direct.position.y,
        );
        assert!(d < 1e-4, "{via_chained:?} vs {direct:?}");
        assert!((via_chained.heading_rad - direct.heading_rad).abs() < 1e-6);
        let back = u.to_body(x.x3_m);
        assert!((back.v_m_s - body.v_m_s).abs() < 1e-6 && back.omega_rad_s == body.omega_rad_s);
    }

    #[test]
    fn error_wraps_the_heading() {
        let a = ChainedState {
            x1_rad: 3.0,
            x2_m: 1.0,
            x3_m: 2.0,
        };
        let b = ChainedState {
            x1_rad: -3.0,
            x2_m: 0.5,
            x3_m: 2.5,
        };
        let e = a.error_from(b);
        assert!((e.x1_rad - (6.0 - math::TAU)).abs() < 1e-5, "{e:?}");
        assert_eq!((e.x2_m, e.x3_m), (0.5, -0.5));
    }

    #[test]
    fn non_finite_input_is_counted_and_stops_the_controllers() {
        let cfg = ChainedObserverConfig::new(1.0, 1000.0, 100.0, 0.01).unwrap();
        let mut obs = ChainedObserver::new(cfg, ChainedState::default());
        let before = obs.estimate();
        obs.update(
            ChainedInput {
                u1_rad_s: f32::NAN,
                u2_m_s: 0.0,
            },
            ChainedOutput::default(),
        );
        assert_eq!((obs.estimate(), obs.rejected_updates()), (before, 1));

        let gains = ChainedGains::new(1.0, 1.0, 1.0).unwrap();
        let feedback = ChainedStateFeedback::new(gains);
        let bad = ChainedState {
            x1_rad: f32::INFINITY,
            ..ChainedState::default()
        };
        assert_eq!(
            feedback.command(bad, ChainedInput::default()),
            ChainedInput::STOP
        );

        let mut tracker = ReducedOrderTracker::new(
            ReducedOrderConfig::new(gains, 10.0, 0.01).unwrap(),
            f32::NAN,
        );
        assert_eq!(tracker.x2e_hat_m(), 0.0);
        let reference = ChainedReference::default();
        tracker.update(
            ChainedOutput {
                x1_rad: 0.0,
                x3_m: f32::NAN,
            },
            ChainedInput::STOP,
            &reference,
        );
        assert_eq!(tracker.rejected_updates(), 1);
        let nan_out = ChainedOutput {
            x1_rad: f32::NAN,
            x3_m: 0.0,
        };
        assert_eq!(tracker.command(nan_out, &reference), ChainedInput::STOP);
    }

    /// With `u1 ≡ 0` nothing corrects `x̃2` (figure 3(a)), and `x̃3` decays.
    #[test]
    fn without_turning_x2_is_unobservable() {
        let cfg = ChainedObserverConfig::new(1.0, 1000.0, 100.0, 0.01).unwrap();
        let mut obs = ChainedObserver::new(
            cfg,
            ChainedState {
                x1_rad: -1.0,
                x2_m: -1.0,
                x3_m: -1.0,
            },
        );
        for _ in 0..1000 {
            obs.update(ChainedInput::STOP, ChainedOutput::default());
        }
        let e = obs.estimate();
        assert_eq!(e.x2_m, -1.0);
        assert!(e.x3_m.abs() < 1e-6 && e.x1_rad.abs() < 1e-4, "{e:?}");
    }

    /// The reduced-order estimate decays exactly like `e^{−a1 ∫u1²}`.
    #[test]
    fn reduced_order_error_decays_at_a1_u1_squared() {
        let h = 0.01_f32;
        let gains = ChainedGains::new(1.0, 1.0, 1.0).unwrap();
        let cfg = ReducedOrderConfig::new(gains, 2.0, h).unwrap();
        let mut tracker = ReducedOrderTracker::new(cfg, 0.0);
        // Constant reference inputs, robot already on the reference except
        // x2e = 1 (unknown to the observer).
        let reference = ChainedReference {
            state: ChainedState::default(),
            input: ChainedInput {
                u1_rad_s: 1.0,
                u2_m_s: 0.0,
            },
        };
        let mut robot = ChainedState {
            x1_rad: 0.0,
            x2_m: 1.0,
            x3_m: 0.0,
        };
        let mut reference_now = reference;
        let measure = |robot: ChainedState, r: &ChainedReference| {
            ChainedOutput::of(robot.error_from(r.state))
        };
        tracker.update(
            measure(robot, &reference_now),
            ChainedInput::STOP,
            &reference_now,
        );
        // Drive with the reference inputs only (open loop) for 100 steps:
        // x2e stays 1, and x̃2e = 1 − x̂2e must fall by e^{−a1 u1² h} a step.
        for _ in 0..100 {
            robot = robot.advance(reference.input, h);
            reference_now.state = reference_now.state.advance(reference.input, h);
            tracker.update(
                measure(robot, &reference_now),
                reference.input,
                &reference_now,
            );
        }
        let remaining = 1.0 - tracker.x2e_hat_m();
        let expected = math::exp(-2.0);
        assert!(
            (remaining - expected).abs() < 1e-4,
            "{remaining} vs {expected}"
        );
    }

    proptest! {
        /// (6a) and its inverse round-trip (heading kept as given).
        #[test]
        fn transform_round_trips(
            x in -1000.0f32..1000.0, y in -1000.0f32..1000.0, th in -20.0f32..20.0,
        ) {
            let back = ChainedState::from_pose(Pose::new(x, y, th)).to_pose();
            let tol = 1e-5 * (1.0 + x.abs() + y.abs());
            prop_assert!((back.position.x - x).abs() <= tol, "{back:?}");
            prop_assert!((back.position.y - y).abs() <= tol, "{back:?}");
            prop_assert_eq!(back.heading_rad, th);
        }

        /// (6b) and its inverse round-trip.
        #[test]
        fn feedback_transformation_round_trips(
            v in -10.0f32..10.0, w in -10.0f32..10.0, x3 in -100.0f32..100.0,
        ) {
            let body = ChainedInput::from_body(BodyVelocity { v_m_s: v, omega_rad_s: w }, x3)
                .to_body(x3);
            prop_assert!((body.v_m_s - v).abs() <= 1e-5 * (1.0 + (w * x3).abs()));
            prop_assert_eq!(body.omega_rad_s, w);
        }

        /// The discrete `V = x̃2² + a2 x̃3²` never increases (module docs).
        #[test]
        fn observer_lyapunov_never_increases(
            e2 in -10.0f32..10.0, e3 in -10.0f32..10.0,
            u1 in -5.0f32..5.0, u2 in -5.0f32..5.0, x2 in -10.0f32..10.0,
            a2 in 0.1f32..10_000.0, a3 in 0.1f32..100.0, h in 1e-4f32..0.1,
        ) {
            let cfg = ChainedObserverConfig::new(1.0, a2, a3, h).unwrap();
            let truth = ChainedState { x1_rad: 0.0, x2_m: x2, x3_m: 0.0 };
            let mut obs = ChainedObserver::new(cfg, ChainedState {
                x1_rad: 0.0, x2_m: x2 - e2, x3_m: -e3,
            });
            let input = ChainedInput { u1_rad_s: u1, u2_m_s: u2 };
            let next = truth.advance(input, h);
            obs.update(input, ChainedOutput::of(next));
            let est = obs.estimate();
            let v0 = e2 * e2 + a2 * e3 * e3;
            let (n2, n3) = (next.x2_m - est.x2_m, next.x3_m - est.x3_m);
            let v1 = n2 * n2 + a2 * n3 * n3;
            // f32 rounding of the states (size ~|x2|) bounds the slack.
            let slack = 1e-4 * (1.0 + v0);
            prop_assert!(v1 <= v0 + slack, "V {v0} -> {v1}");
        }

        /// Finite inputs give finite outputs everywhere in this module.
        #[test]
        fn finite_in_finite_out(
            s in proptest::array::uniform3(-1e3f32..1e3),
            r in proptest::array::uniform3(-1e3f32..1e3),
            u in proptest::array::uniform2(-1e2f32..1e2),
            ur in proptest::array::uniform2(-1e2f32..1e2),
            h in 1e-4f32..0.1,
        ) {
            let state = ChainedState { x1_rad: s[0], x2_m: s[1], x3_m: s[2] };
            let reference = ChainedReference {
                state: ChainedState { x1_rad: r[0], x2_m: r[1], x3_m: r[2] },
                input: ChainedInput { u1_rad_s: ur[0], u2_m_s: ur[1] },
            };
            let input = ChainedInput { u1_rad_s: u[0], u2_m_s: u[1] };
            let gains = ChainedGains::new(1.0, 1.0, 1.0).unwrap();
            prop_assert!(ChainedState::from_pose(state.to_pose()).is_finite());
            let error = state.error_from(reference.state);
            prop_assert!(ChainedStateFeedback::new(gains).command(error, reference.input).is_finite());

            let mut obs = ChainedObserver::new(
                ChainedObserverConfig::new(1.0, 1e4, 100.0, h).unwrap(), state);
            obs.update(input, ChainedOutput::of(reference.state));
            prop_assert!(obs.estimate().is_finite());

            let mut tracker = ReducedOrderTracker::new(
                ReducedOrderConfig::new(gains, 10.0, h).unwrap(), 0.0);
            tracker.update(ChainedOutput::of(error), input, &reference);
            tracker.update(ChainedOutput::of(state), input, &reference);
            prop_assert!(tracker.x2e_hat_m().is_finite());
            prop_assert!(tracker.command(ChainedOutput::of(error), &reference).is_finite());
        }
    }
}
