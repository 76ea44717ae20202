//! The reference trajectory, checked key by key, and its bounding box.

use wmr_core::reference::Trajectory;
use wmr_core::reference::TrajectorySpec;
use wmr_core::reference::route::{RouteCursor, RoutePlan};

use crate::scenario::route::RouteSetup;

use crate::scenario::error::{ScenarioError, in_range};
use wmr_core::plausible::{ANGLE_RAD, REFERENCE_RATE_RAD_S, REFERENCE_SIZE_M, REFERENCE_SPEED_M_S};

use super::floor_point;

/// The value of a core `f32` key as the file wrote it: the shortest
/// decimal of the `f32`, so that a refusal prints `0.1`, not
/// `0.10000000149011612`.
fn written(v: f32) -> f64 {
    v.to_string().parse().unwrap_or(f64::from(v))
}

/// The scenario's `[reference]`, checked key by key (the core checks the
/// whole when it builds it, but names no key).
///
/// # Errors
/// [`ScenarioError::Invalid`] naming the bad `reference.*` key.
pub fn checked(reference: &TrajectorySpec) -> Result<TrajectorySpec, ScenarioError> {
    let point = |key: &str, [x, y]: [f32; 2]| floor_point(key, [written(x), written(y)]);
    match *reference {
        TrajectorySpec::FigureEight {
            h1_m,
            h2_rad_s,
            phase_rad,
        } => {
            in_range("reference.h1_m", written(h1_m), REFERENCE_SIZE_M, "m")?;
            in_range(
                "reference.h2_rad_s",
                written(h2_rad_s),
                REFERENCE_RATE_RAD_S,
                "rad/s",
            )?;
            in_range("reference.phase_rad", written(phase_rad), ANGLE_RAD, "rad")?;
        }
        TrajectorySpec::Circle {
            center_m,
            radius_m,
            rate_rad_s,
            phase_rad,
        } => {
            if !REFERENCE_RATE_RAD_S.contains_magnitude(rate_rad_s) {
                return Err(ScenarioError::invalid(
                    "reference.rate_rad_s",
                    format!(
                        "its magnitude must be in {REFERENCE_RATE_RAD_S} rad/s, the sign \
                         gives the sense (got {})",
                        written(rate_rad_s)
                    ),
                ));
            }
            point("reference.center_m", center_m)?;
            in_range(
                "reference.radius_m",
                written(radius_m),
                REFERENCE_SIZE_M,
                "m",
            )?;
            in_range("reference.phase_rad", written(phase_rad), ANGLE_RAD, "rad")?;
        }
        TrajectorySpec::Line {
            start_m,
            heading_rad,
            speed_m_s,
        } => {
            point("reference.start_m", start_m)?;
            in_range(
                "reference.heading_rad",
                written(heading_rad),
                ANGLE_RAD,
                "rad",
            )?;
            in_range(
                "reference.speed_m_s",
                written(speed_m_s),
                REFERENCE_SPEED_M_S,
                "m/s",
            )?;
        }
        // A reference family the simulator has no per-key checks for: the
        // core's own refusal names the table.
        _ => {}
    }
    Ok(*reference)
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

/// Bounding box of a route, `([x_min, y_min], [x_max, y_max])`: its
/// waypoints' (the path is inside it: straight legs between waypoints,
/// each corner blend inside the triangle of its corner and its two tangent
/// points, pivots in place), without sampling a plan that may last days.
#[must_use]
pub fn route_bounds(route: &RouteSetup) -> ([f64; 2], [f64; 2]) {
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for w in route.waypoints.as_slice() {
        let (x, y) = (f64::from(w.position_m.x), f64::from(w.position_m.y));
        lo = [lo[0].min(x), lo[1].min(y)];
        hi = [hi[0].max(x), hi[1].max(y)];
    }
    (lo, hi)
}

/// A plan's path: its reference position at every tick from the start to
/// its end or `max_ticks`, whichever comes first (the path sampled every
/// `v·h`: at most 5 mm apart at 0.5 m/s and 100 Hz), m.
#[must_use]
pub fn route_path(plan: &RoutePlan, max_ticks: u32) -> Vec<[f64; 2]> {
    let mut cursor = RouteCursor::new();
    (0..=plan.duration_ticks().min(max_ticks))
        .map(|k| {
            let p = plan.sample(&mut cursor, k).reference.position;
            [f64::from(p.x), f64::from(p.y)]
        })
        .collect()
}
