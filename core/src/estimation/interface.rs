//! The estimator interface: what the tracker asks of every estimator.

use crate::geometry::HeadingEstimate;
use crate::geometry::Vec2;
use crate::odometry::OdometryStep;

/// What an estimator counted beyond rejected updates (zero for the
/// observers).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EstimatorCounters {
    /// Fix measurements a Mahalanobis gate rejected.
    pub fixes_gated: u32,
    /// Times the estimator re-localised after consecutive gated fixes.
    pub relocalisations: u32,
    /// Times the estimator's heading was reset to its guide observer's.
    pub heading_resets: u32,
}

/// A pose estimator on odometry and tag fixes.
pub trait PoseEstimator {
    /// One tick: `odometry` over the last control period, `fix` the tag
    /// position accepted this tick (finite and fresh), `last_position` what
    /// this method returned the tick before (the tracker keeps it, so no
    /// estimator stores it twice), `after_gap` whether ticks without a fix
    /// came before this one. Returns the position the law uses this tick
    /// (m, world frame); `None` while the estimator does not know where the
    /// robot is (before the first fix).
    fn step(
        &mut self,
        odometry: &OdometryStep,
        fix: Option<Vec2>,
        last_position: Option<Vec2>,
        after_gap: bool,
    ) -> Option<Vec2>;

    /// The heading estimate `(cos θ̂, sin θ̂)` after the last step (`(0, 0)`
    /// where nothing is known).
    fn heading(&self) -> HeadingEstimate;

    /// Updates skipped for non-finite input or result.
    fn rejected_updates(&self) -> u32;

    /// Gated fixes, re-localisations and heading resets.
    fn counters(&self) -> EstimatorCounters;

    /// Whether the estimator's own failsafe takes the fix as lost (`None`:
    /// it has none, and the tracker's fix timeout decides).
    fn blind_distance_lost(&self) -> Option<bool>;

    /// Takes `heading_rad` (counter-clockwise from +x) as the robot's
    /// heading now, known from outside (a robot parked facing a known
    /// way: [`crate::pilot::route::RouteStart::AsGivenHeadingKnown`]). A
    /// non-finite heading is ignored.
    fn assume_heading(&mut self, heading_rad: f32);
}
