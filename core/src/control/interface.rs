//! The law interface: what the tracker asks of every tracking law.

use crate::geometry::HeadingEstimate;
use crate::geometry::{BodyVelocity, Vec2};
use crate::reference::ReferenceSample;

/// A law's command and, for paper 001's law (27)–(28), the quantities
/// behind it (zero for the other laws).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TrackingCommand {
    /// `(v, ω)` to drive.
    pub body: BodyVelocity,
    /// Position error `(ζ1, ζ2)`, m (robot minus reference).
    pub position_error: Vec2,
    /// Desired heading `θ*`, rad, in [−π, π].
    pub desired_heading_rad: f32,
    /// `θ̇*` as used (0 while `θ*` is held), rad/s.
    pub desired_heading_rate_rad_s: f32,
    /// Heading error `e = wrap(θ − θ*)` (or with `θ̂`), rad.
    pub heading_error_rad: f32,
}

/// What a law commands this tick.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LawCommand {
    /// A command (for paper 001's law with its internals; for the others
    /// only [`TrackingCommand::body`] is set).
    Drive(TrackingCommand),
    /// The reference stands still, so its heading, and a law on the
    /// robot-frame error (30), is undefined: the tracker commands zero
    /// and counts the tick.
    ReferenceStandstill,
}

/// A trajectory-tracking law on the estimated position and heading.
pub trait TrackingLaw {
    /// The command at this tick: the reference now, the position the
    /// estimator gives (m), its heading estimate, and the `(v, ω)` driven
    /// over the last period (from the odometry).
    fn command(
        &mut self,
        reference: &ReferenceSample,
        position: Vec2,
        heading: HeadingEstimate,
        driven: BodyVelocity,
    ) -> LawCommand;

    /// The tracker (re-)enters tracking after standing still or the
    /// failsafe: a law with memory of past ticks forgets it here.
    fn restart(&mut self);

    /// Updates of the law's own observer skipped for non-finite input.
    fn rejected_updates(&self) -> u32;
}
