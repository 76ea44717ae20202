//! The reference trajectory, checked key by key, and its bounding box.

use wmr_core::reference::Trajectory;
use wmr_core::reference::TrajectorySpec;

use crate::scenario::error::{ScenarioError, in_range};
use crate::scenario::tables::ReferenceSpec;
use wmr_core::plausible::{ANGLE_RAD, REFERENCE_RATE_RAD_S, REFERENCE_SIZE_M, REFERENCE_SPEED_M_S};

use super::{f, floor_point};

impl ReferenceSpec {
    /// The core trajectory.
    ///
    /// # Errors
    /// [`ScenarioError::Invalid`] naming the bad `reference.*` field.
    pub fn build(&self) -> Result<Trajectory, ScenarioError> {
        self.spec()?
            .build()
            .map_err(|e| ScenarioError::invalid("reference", format!("refused by the core: {e}")))
    }

    /// The core's plain spec of the reference (checked field by field).
    ///
    /// # Errors
    /// [`ScenarioError::Invalid`] naming the bad `reference.*` field.
    pub fn spec(&self) -> Result<TrajectorySpec, ScenarioError> {
        Ok(match *self {
            Self::FigureEight {
                h1_m,
                h2_rad_s,
                phase_rad,
            } => TrajectorySpec::FigureEight {
                h1_m: f(in_range("reference.h1_m", h1_m, REFERENCE_SIZE_M, "m")?),
                h2_rad_s: f(in_range(
                    "reference.h2_rad_s",
                    h2_rad_s,
                    REFERENCE_RATE_RAD_S,
                    "rad/s",
                )?),
                phase_rad: f(in_range(
                    "reference.phase_rad",
                    phase_rad,
                    ANGLE_RAD,
                    "rad",
                )?),
            },
            Self::Circle {
                center_m,
                radius_m,
                rate_rad_s,
                phase_rad,
            } => {
                if !REFERENCE_RATE_RAD_S.contains_magnitude(rate_rad_s as f32) {
                    return Err(ScenarioError::invalid(
                        "reference.rate_rad_s",
                        format!(
                            "its magnitude must be in {REFERENCE_RATE_RAD_S} rad/s, the sign \
                             gives the sense (got {rate_rad_s})"
                        ),
                    ));
                }
                TrajectorySpec::Circle {
                    center_m: floor_point("reference.center_m", center_m)?,
                    radius_m: f(in_range(
                        "reference.radius_m",
                        radius_m,
                        REFERENCE_SIZE_M,
                        "m",
                    )?),
                    rate_rad_s: f(rate_rad_s),
                    phase_rad: f(in_range(
                        "reference.phase_rad",
                        phase_rad,
                        ANGLE_RAD,
                        "rad",
                    )?),
                }
            }
            Self::Line {
                start_m,
                heading_rad,
                speed_m_s,
            } => TrajectorySpec::Line {
                start_m: floor_point("reference.start_m", start_m)?,
                heading_rad: f(in_range(
                    "reference.heading_rad",
                    heading_rad,
                    ANGLE_RAD,
                    "rad",
                )?),
                speed_m_s: f(in_range(
                    "reference.speed_m_s",
                    speed_m_s,
                    REFERENCE_SPEED_M_S,
                    "m/s",
                )?),
            },
        })
    }
}

/// Bounding box of the reference over `[0, duration_s]`, sampled at
/// `max(period, 0.05 s)`, `([x_min, y_min], [x_max, y_max])`.
#[must_use]
pub fn reference_bounds(
    trajectory: &Trajectory,
    duration_s: f64,
    period_s: f64,
) -> ([f64; 2], [f64; 2]) {
    let step = period_s.max(0.05);
    let n = (duration_s / step).ceil() as u64;
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for k in 0..=n {
        let t = (k as f64 * step).min(duration_s);
        let p = trajectory.sample(t as f32).position;
        let (x, y) = (f64::from(p.x), f64::from(p.y));
        lo = [lo[0].min(x), lo[1].min(y)];
        hi = [hi[0].max(x), hi[1].max(y)];
    }
    (lo, hi)
}
