//! The reference (3), a unicycle driven by piecewise constant inputs and
//! integrated exactly, and the tracking error (4) (module docs of
//! [`super`], "Model (1)–(4)").

use wmr_core::geometry::{BodyVelocity, Pose, Vec2};
use wmr_core::math;

use super::error::SlipTrackingError;

/// One constant-input piece of the reference (3).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ReferenceSegment {
    /// Start time, s.
    pub start_s: f32,
    /// `v_r`, m/s.
    pub v_m_s: f32,
    /// `ω_r`, rad/s.
    pub omega_rad_s: f32,
}

/// The reference at one time.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ReferenceState {
    /// `q_r`.
    pub pose: Pose,
    /// `(v_r, ω_r)`.
    pub velocity: BodyVelocity,
}

/// The reference (3): a unicycle from `start` driven by `K` segments of
/// constant `(v_r, ω_r)`, integrated exactly (straight lines and arcs).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PiecewiseReference<const K: usize> {
    segments: [ReferenceSegment; K],
    /// The pose at each segment's start.
    starts: [Pose; K],
}

/// The pose after driving `velocity` for `dt` from `pose`, exactly.
fn drive(pose: Pose, velocity: BodyVelocity, dt: f32) -> Pose {
    let dtheta = velocity.omega_rad_s * dt;
    let chord = velocity.v_m_s * dt * math::sinc(0.5 * dtheta);
    let mid = pose.heading_rad + 0.5 * dtheta;
    Pose {
        position: Vec2::new(
            pose.position.x + chord * math::cos(mid),
            pose.position.y + chord * math::sin(mid),
        ),
        heading_rad: math::wrap_angle(pose.heading_rad + dtheta),
    }
}

impl<const K: usize> PiecewiseReference<K> {
    /// From a start pose and segments whose start times increase from 0.
    ///
    /// # Errors
    /// [`SlipTrackingError::Reference`].
    pub fn new(start: Pose, segments: [ReferenceSegment; K]) -> Result<Self, SlipTrackingError> {
        let finite = segments
            .iter()
            .all(|s| s.start_s.is_finite() && s.v_m_s.is_finite() && s.omega_rad_s.is_finite());
        let ordered = segments.windows(2).all(|w| match w {
            [a, b] => b.start_s > a.start_s,
            _ => true,
        });
        let from_zero = segments.first().is_some_and(|s| s.start_s == 0.0);
        if !(finite && ordered && from_zero && start.heading_rad.is_finite()) {
            return Err(SlipTrackingError::Reference);
        }
        let mut starts = [start; K];
        let mut pose = start;
        for (i, slot) in starts.iter_mut().enumerate() {
            if let (Some(previous), Some(this)) = (
                i.checked_sub(1).and_then(|j| segments.get(j)),
                segments.get(i),
            ) {
                pose = drive(
                    pose,
                    BodyVelocity {
                        v_m_s: previous.v_m_s,
                        omega_rad_s: previous.omega_rad_s,
                    },
                    this.start_s - previous.start_s,
                );
            }
            *slot = pose;
        }
        Ok(Self { segments, starts })
    }

    /// Paper 004's reference from `(0, 0, 0)`: `v_r = 0.5 m/s` throughout
    /// until 51 s, then 0.7; `ω_r = 0` until 15 s, −0.4 rad/s until 33 s,
    /// +0.4 until 51 s, then 0.
    ///
    /// # Errors
    /// Never for these constants.
    pub fn paper() -> Result<PiecewiseReference<4>, SlipTrackingError> {
        let segment = |start_s, v_m_s, omega_rad_s| ReferenceSegment {
            start_s,
            v_m_s,
            omega_rad_s,
        };
        PiecewiseReference::new(
            Pose::new(0.0, 0.0, 0.0),
            [
                segment(0.0, 0.5, 0.0),
                segment(15.0, 0.5, -0.4),
                segment(33.0, 0.5, 0.4),
                segment(51.0, 0.7, 0.0),
            ],
        )
    }

    /// The reference at `t_s` (≥ 0; earlier times give the start).
    #[must_use]
    pub fn sample(&self, t_s: f32) -> ReferenceState {
        let mut state = ReferenceState {
            pose: self.starts.first().copied().unwrap_or_default(),
            velocity: BodyVelocity::ZERO,
        };
        for (segment, start) in self.segments.iter().zip(self.starts.iter()) {
            if t_s >= segment.start_s || segment.start_s == 0.0 {
                let velocity = BodyVelocity {
                    v_m_s: segment.v_m_s,
                    omega_rad_s: segment.omega_rad_s,
                };
                state = ReferenceState {
                    pose: drive(*start, velocity, (t_s - segment.start_s).max(0.0)),
                    velocity,
                };
            }
        }
        state
    }
}

/// The tracking error (4): the reference's offset in the robot's frame,
/// `(e1, e2, e3)` in m, m, rad (`e3 = ψ_r − ψ` wrapped).
#[must_use]
pub fn tracking_error(pose: &Pose, reference: &Pose) -> [f32; 3] {
    let (s, c) = (math::sin(pose.heading_rad), math::cos(pose.heading_rad));
    let dx = reference.position.x - pose.position.x;
    let dy = reference.position.y - pose.position.y;
    [
        c * dx + s * dy,
        -s * dx + c * dy,
        math::wrap_angle(reference.heading_rad - pose.heading_rad),
    ]
}
