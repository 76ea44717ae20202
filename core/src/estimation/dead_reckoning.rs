//! Dead reckoning between tag fixes for the observers that only estimate
//! the heading from positions (paper 001's observer (5), paper 002's
//! Proposition 4 observer).
//!
//! Those observers are fed a position every tick. A tick with a fix gives
//! the tag's position; a tick without one moves the last position along the
//! odometry arc at the observer's own heading `θ̂`
//! ([`crate::geometry::Pose::advance_arc`]), so the observer sees no
//! innovation from it (its update with a dead-reckoned position is the
//! prediction alone). A non-finite dead-reckoned position keeps the last
//! one. Before the first fix there is no position and the observer waits;
//! the first fix starts it ([`PositionObserver::start_at`]).

use crate::estimation::heading_observer::HeadingObserver;
use crate::estimation::interface::{EstimatorCounters, PoseEstimator};
use crate::estimation::pose_observer::{PoseEstimate, PoseObserver};
use crate::geometry::HeadingEstimate;
use crate::geometry::{BodyVelocity, Pose, Vec2};
use crate::odometry::OdometryStep;

/// An observer that takes a position every tick (fix or dead-reckoned).
pub trait PositionObserver {
    /// The heading estimate `(ĉ, ŝ)` now.
    fn heading(&self) -> HeadingEstimate;

    /// The first position (before it, the observer is not updated).
    fn start_at(&mut self, position: Vec2);

    /// One step: the `(v, ω)` driven over the step and the positions at its
    /// start and end.
    fn update(&mut self, driven: BodyVelocity, previous: Vec2, now: Vec2);

    /// Updates skipped for non-finite input.
    fn rejected_updates(&self) -> u32;

    /// The heading estimate set to `(cos θ, sin θ)` of a known heading.
    fn assume_heading(&mut self, heading_rad: f32);
}

impl PositionObserver for HeadingObserver {
    fn heading(&self) -> HeadingEstimate {
        self.estimate()
    }

    /// Observer (5) needs only position changes: nothing to start.
    fn start_at(&mut self, _position: Vec2) {}

    fn update(&mut self, driven: BodyVelocity, previous: Vec2, now: Vec2) {
        HeadingObserver::update(self, driven, now - previous);
    }

    fn rejected_updates(&self) -> u32 {
        HeadingObserver::rejected_updates(self)
    }

    fn assume_heading(&mut self, heading_rad: f32) {
        HeadingObserver::assume_heading(self, heading_rad);
    }
}

impl PositionObserver for PoseObserver {
    fn heading(&self) -> HeadingEstimate {
        self.estimate().heading()
    }

    /// The pose observer's position starts at the first fix (its heading
    /// estimate is kept).
    fn start_at(&mut self, position: Vec2) {
        let e = self.estimate();
        self.reset(PoseEstimate { position, ..e });
    }

    fn update(&mut self, driven: BodyVelocity, _previous: Vec2, now: Vec2) {
        PoseObserver::update(self, driven, now);
    }

    fn rejected_updates(&self) -> u32 {
        PoseObserver::rejected_updates(self)
    }

    fn assume_heading(&mut self, heading_rad: f32) {
        if heading_rad.is_finite() {
            let (sin_theta, cos_theta) = crate::math::sincos(heading_rad);
            let e = self.estimate();
            self.reset(PoseEstimate {
                cos_theta,
                sin_theta,
                ..e
            });
        }
    }
}

/// A [`PositionObserver`] with dead reckoning between fixes: a
/// [`PoseEstimator`].
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DeadReckoning<O> {
    observer: O,
}

impl<O: PositionObserver> DeadReckoning<O> {
    /// Dead reckoning for `observer`.
    #[must_use]
    pub fn new(observer: O) -> Self {
        Self { observer }
    }

    /// The observer.
    #[must_use]
    pub fn observer(&self) -> &O {
        &self.observer
    }
}

impl<O: PositionObserver> PoseEstimator for DeadReckoning<O> {
    fn step(
        &mut self,
        odometry: &OdometryStep,
        fix: Option<Vec2>,
        previous: Option<Vec2>,
        _after_gap: bool,
    ) -> Option<Vec2> {
        let current = match (fix, previous) {
            (Some(p), _) => Some(p),
            (None, Some(p)) => Some(dead_reckon(p, self.observer.heading(), odometry)),
            (None, None) => None,
        };
        match (previous, current) {
            (Some(prev), Some(now)) => self.observer.update(odometry.body, prev, now),
            (None, Some(first)) => self.observer.start_at(first),
            _ => {}
        }
        current
    }

    fn heading(&self) -> HeadingEstimate {
        self.observer.heading()
    }

    fn rejected_updates(&self) -> u32 {
        self.observer.rejected_updates()
    }

    fn counters(&self) -> EstimatorCounters {
        EstimatorCounters::default()
    }

    fn blind_distance_lost(&self) -> Option<bool> {
        None
    }

    fn assume_heading(&mut self, heading_rad: f32) {
        self.observer.assume_heading(heading_rad);
    }
}

/// `position` moved along the odometry arc at the heading `θ̂` of
/// `heading`; `position` itself if that is not finite.
fn dead_reckon(position: Vec2, heading: HeadingEstimate, odometry: &OdometryStep) -> Vec2 {
    let pose = Pose {
        position,
        heading_rad: heading.heading_rad(),
    };
    let next = pose
        .advance_arc(odometry.ds_m, odometry.dtheta_rad)
        .position;
    if next.is_finite() { next } else { position }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimation::heading_observer::HeadingObserverConfig;

    fn moving(ds_m: f32) -> OdometryStep {
        OdometryStep {
            ds_m,
            body: BodyVelocity {
                v_m_s: ds_m / 0.01,
                omega_rad_s: 0.0,
            },
            ..OdometryStep::default()
        }
    }

    /// Nothing before the first fix; the fix itself on a fix tick; without
    /// one, the last position moved along the observer's heading; a
    /// non-finite step keeps the last position.
    #[test]
    fn fixes_then_dead_reckoning_at_the_observer_heading() {
        let config = HeadingObserverConfig::new(1.0, 0.01).unwrap();
        // Heading estimate +y (cos 0, sin 1).
        let observer = HeadingObserver::with_initial_estimate(
            config,
            HeadingEstimate {
                cos_theta: 0.0,
                sin_theta: 1.0,
            },
        )
        .unwrap();
        let mut estimator = DeadReckoning::new(observer);
        assert_eq!(estimator.step(&moving(0.0), None, None, false), None);
        let first = Vec2::new(1.0, 2.0);
        let p = estimator.step(&moving(0.0), Some(first), None, false);
        assert_eq!(p, Some(first));
        let p = estimator.step(&moving(0.01), None, p, false).unwrap();
        assert!(
            (p.x - 1.0).abs() < 1e-6 && (p.y - 2.01).abs() < 1e-6,
            "{p:?}"
        );
        let q = estimator.step(&moving(f32::NAN), None, Some(p), true);
        assert_eq!(q, Some(p));
        assert_eq!(estimator.counters(), EstimatorCounters::default());
        assert_eq!(estimator.blind_distance_lost(), None);
    }
}
