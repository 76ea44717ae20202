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
//! Its own file implementing [`TrackingLaw`], one arm in [`LawChoice`]
//! and [`Law`] here, and one arm in the spec
//! ([`crate::control::spec::LawSpec`]) that builds it.

pub mod cascaded;
pub mod heading_error_sine;
pub mod interface;
pub mod robot_frame;
pub mod saturated;
pub mod spec;

pub use interface::{LawCommand, TrackingCommand, TrackingLaw};

use crate::control::cascaded::{CascadedController, CascadedGains};
use crate::control::heading_error_sine::{HeadingErrorSineConfig, HeadingErrorSineTracker};
use crate::control::saturated::{TrackingController, TrackingGains};
use crate::geometry::HeadingEstimate;
use crate::geometry::{BodyVelocity, Vec2};
use crate::reference::ReferenceSample;

/// Which law the tracker runs: the one list of laws.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LawChoice {
    /// Paper 001's output-feedback law (27)–(28) (the tracker
    /// configuration's `gains`).
    Saturated,
    /// Paper 002's cascaded controller (31) on the estimated error (30).
    Cascaded(CascadedGains),
    /// Paper 002's Proposition 7: observer of `sin θ_e` + controller (64).
    HeadingErrorSine(HeadingErrorSineConfig),
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
    /// The law `choice` selects; `gains` are paper 001's law's.
    #[must_use]
    pub fn new(choice: LawChoice, gains: TrackingGains) -> Self {
        match choice {
            LawChoice::Saturated => Self::Saturated(TrackingController::new(gains)),
            LawChoice::Cascaded(gains) => Self::Cascaded(CascadedController::new(gains)),
            LawChoice::HeadingErrorSine(config) => {
                Self::HeadingErrorSine(HeadingErrorSineTracker::new(config, 0.0))
            }
        }
    }
}

/// Calls the [`TrackingLaw`] method on the running law.
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
