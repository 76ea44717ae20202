//! Tracking laws: from the reference and the estimated pose to a body
//! command `(v, ω)`, behind one interface ([`TrackingLaw`]) and one list
//! ([`LawChoice`], dispatched by [`Law`]):
//!
//! | choice | law | paper |
//! |---|---|---|
//! | [`LawChoice::Saturated`] | [`saturated`]: atan-saturated position errors, (27)–(28) (and state feedback (14)) | 001 |
//! | [`LawChoice::Cascaded`] | [`cascaded`]: controller (31) on the error (30) | 002, section 3 |
//! | [`LawChoice::HeadingErrorSine`] | [`heading_error_sine`]: observer of `sin θ_e` + controller (64) | 002, Proposition 7 |
//!
//! The laws of paper 002 work on the robot-frame error (30) computed from
//! the estimated heading ([`robot_frame`]).
//!
//! # Adding a law
//! Its own file, its arms in the lists here, and its spec beside it in
//! [`spec`]: nothing outside this module changes. The recipe, step by
//! step: `docs/architecture.md`, "Adding an estimator or a law".

pub mod cascaded;
pub mod heading_error_sine;
pub mod interface;
pub mod robot_frame;
pub mod saturated;
pub mod spec;

pub use interface::{LawCommand, TrackingCommand, TrackingLaw};

use crate::control::cascaded::{CascadedController, CascadedGains};
use crate::control::heading_error_sine::{HeadingErrorSineConfig, HeadingErrorSineTracker};
use crate::control::saturated::{GainBound, TrackingController, TrackingGains};
use crate::geometry::HeadingEstimate;
use crate::geometry::{BodyVelocity, Vec2};
use crate::reference::{ReferenceSample, SpeedBounds};

/// Which law the tracker runs, with its configuration: the one list of
/// laws. Each names itself ([`Self::label`]).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum LawChoice {
    /// Paper 001's output-feedback law (27)–(28) with gains `k1, k2, k3`.
    Saturated(TrackingGains),
    /// Paper 002's cascaded controller (31) on the estimated error (30).
    Cascaded(CascadedGains),
    /// Paper 002's Proposition 7: observer of `sin θ_e` + controller (64).
    HeadingErrorSine(HeadingErrorSineConfig),
}

impl LawChoice {
    /// The law's own step, s, where it has one (Proposition 7's observer);
    /// it must be the tracker's control period.
    #[must_use]
    pub fn period_s(&self) -> Option<f32> {
        match self {
            Self::Saturated(_) | Self::Cascaded(_) => None,
            Self::HeadingErrorSine(config) => Some(config.period_s()),
        }
    }

    /// What paper 001's gain bound (15) says for this law's gains and a
    /// reference of speed bounds `bounds` (`None` for the laws it does not
    /// concern).
    #[must_use]
    // Always inlined so that a compiled-in spec's validation folds away: see `LawSpec::build`.
    #[inline(always)]
    pub fn gain_bound(&self, bounds: SpeedBounds) -> Option<GainBound> {
        match self {
            Self::Saturated(gains) => Some(gains.check_bound(bounds)),
            Self::Cascaded(_) | Self::HeadingErrorSine(_) => None,
        }
    }

    /// What the law does when the reference stands still (`v_r = 0`, a
    /// route's stops and pivots), and so whether it may be left in charge
    /// there. A route's tracker never is: it holds the robot still at a
    /// stop and turns it in place itself (module `pilot::route`), and runs
    /// the law only while the reference moves faster than
    /// `pilot::route::SLOW_SPEED_M_S` (below it, leaving and reaching a
    /// rest, it holds the path's tangent).
    #[must_use]
    pub fn at_rest(&self) -> LawAtRest {
        match self {
            Self::Saturated(_) => LawAtRest::SeeksPoint,
            Self::Cascaded(_) | Self::HeadingErrorSine(_) => LawAtRest::Undefined,
        }
    }

    /// The law's name in reports: `law 001`, `cascaded law` or
    /// `sin θe law`.
    #[must_use]
    pub fn label(&self) -> &'static str {
        match self {
            Self::Saturated(_) => "law 001",
            Self::Cascaded(_) => "cascaded law",
            Self::HeadingErrorSine(_) => "sin θe law",
        }
    }
}

/// What a law does with a reference at rest ([`LawChoice::at_rest`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum LawAtRest {
    /// Paper 001's law (14)/(27)–(28): with `ẋ_r = ẏ_r = 0` it commands
    /// `u = −f(ζ)`, toward the point, and `V̇ ≤ 0` (25) still holds; but
    /// its speed floor `v ≥ (1 − γ)·v_rm` (21) is gone (`v_rm = 0`, the
    /// gain bound (15) does not apply) and at the point `θ* = atan2(u)` is
    /// undefined, so position noise turns into creeping and turning on
    /// the spot: it supports a stop only until it is reached.
    SeeksPoint,
    /// Paper 002's laws on the robot-frame error (30): the reference's
    /// heading, and so the error, is undefined at rest; the tracker
    /// commands zero and counts the tick
    /// (`TrackerCounters::reference_standstill_ticks`). Neither their
    /// convergence nor a pivot is defined there.
    Undefined,
}

/// The running law: [`LawChoice`] built.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Law {
    /// [`LawChoice::Saturated`].
    Saturated(TrackingController),
    /// [`LawChoice::Cascaded`].
    Cascaded(CascadedController),
    /// [`LawChoice::HeadingErrorSine`].
    HeadingErrorSine(HeadingErrorSineTracker),
}

impl Law {
    /// The law `choice`, at rest.
    #[must_use]
    pub fn new(choice: LawChoice) -> Self {
        match choice {
            LawChoice::Saturated(gains) => Self::Saturated(TrackingController::new(gains)),
            LawChoice::Cascaded(gains) => Self::Cascaded(CascadedController::new(gains)),
            LawChoice::HeadingErrorSine(config) => {
                Self::HeadingErrorSine(HeadingErrorSineTracker::new(config, 0.0))
            }
        }
    }
}

macro_rules! dispatch {
    ($self:ident, $method:ident($($arg:expr),*)) => {
        match $self {
            Self::Saturated(law) => TrackingLaw::$method(law, $($arg),*),
            Self::Cascaded(law) => TrackingLaw::$method(law, $($arg),*),
            Self::HeadingErrorSine(law) => TrackingLaw::$method(law, $($arg),*),
        }
    };
}

impl TrackingLaw for Law {
    fn command(
        &mut self,
        reference: &ReferenceSample,
        position: Vec2,
        heading: HeadingEstimate,
        driven: BodyVelocity,
    ) -> LawCommand {
        dispatch!(self, command(reference, position, heading, driven))
    }

    fn restart(&mut self) {
        dispatch!(self, restart())
    }

    fn rejected_updates(&self) -> u32 {
        dispatch!(self, rejected_updates())
    }
}
