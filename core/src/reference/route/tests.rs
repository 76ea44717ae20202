//! The route planner's tests: continuity, limits, stops, pivots, blend
//! deviation, refusals, day-30 accuracy against an `f64` evaluation of the
//! same plan, and the tick counter's wrap.

use super::plan::{Kind, Segment};
use super::*;
use crate::geometry::Vec2;
use std::vec::Vec;

const H: f32 = 0.01;
/// 30 days at 100 Hz.
const DAY_30_TICKS: u32 = 30 * 86_400 * 100;

fn spec() -> RouteLimitsSpec {
    RouteLimitsSpec {
        max_speed_m_s: 1.0,
        max_tangential_accel_m_s2: 0.5,
        max_lateral_accel_m_s2: 0.8,
        blend_deviation_m: 0.1,
        pivot_threshold_rad: 0.5,
        pivot_rate_rad_s: 1.0,
        pivot_accel_rad_s2: 2.0,
    }
}

fn limits() -> RouteLimits {
    RouteLimits::new(&spec()).unwrap()
}

/// Corners (left and right, gentle and sharp), a speed-limited leg, a stop
/// facing a heading, a stop with a pivot, a stop-and-go below the pivot
/// threshold, and the final stop facing a heading.
fn waypoints() -> Vec<Waypoint> {
    std::vec![
        Waypoint::stop(0.0, 0.0, 0.5),
        Waypoint::pass(4.0, 0.0),
        Waypoint::pass(4.0, 3.0).with_speed_limit(0.4),
        Waypoint::stop(1.0, 4.0, 1.5).facing(2.0),
        Waypoint::pass(-2.0, 2.0),
        Waypoint::stop(-2.0, -2.0, 0.5),
        Waypoint::pass(2.0, -2.0),
        Waypoint::stop(5.0, -1.0, 0.2),
        Waypoint::pass(8.0, -0.2),
        Waypoint::stop(8.0, 2.0, 0.0).facing(-3.0),
    ]
}

fn plan(period_s: f32) -> RoutePlan {
    RoutePlan::new(&waypoints(), &limits(), period_s).unwrap()
}

/// Every sample of the plan from tick 0 until done, with its segment.
fn samples(plan: &RoutePlan) -> Vec<(RouteSample, usize)> {
    let mut cursor = RouteCursor::new();
    let mut out = Vec::new();
    for k in 0..=plan.duration_ticks() {
        let s = plan.sample(&mut cursor, k);
        out.push((s, usize::from(cursor.segment)));
        if s.done {
            break;
        }
    }
    out
}

fn curvature(s: &RouteSample) -> Option<f32> {
    match s.mode {
        RouteMode::Moving { curvature_per_m } => Some(curvature_per_m),
        _ => None,
    }
}

fn cross(a: Vec2, b: Vec2) -> f32 {
    a.x * b.y - a.y * b.x
}

fn dot(a: Vec2, b: Vec2) -> f32 {
    a.x * b.x + a.y * b.y
}

#[test]
fn the_route_ends_done_at_the_last_waypoint() {
    let plan = plan(H);
    let all = samples(&plan);
    let (last, _) = all.last().copied().unwrap();
    assert!(last.done);
    assert_eq!(last.reference.position, Vec2::new(8.0, 2.0));
    assert_eq!(
        last.mode,
        RouteMode::Stopped {
            hold_heading_rad: Some(-3.0)
        }
    );
    assert!(all.iter().rev().skip(1).all(|(s, _)| !s.done));
    assert!(plan.segment_count() <= MAX_SEGMENTS);
    // Done stays done, however the ticks go on.
    let mut cursor = RouteCursor::new();
    assert!(plan.sample(&mut cursor, u32::MAX).done);
    assert!(plan.sample(&mut cursor, 0).done);
}

/// Position, velocity and `ω_r = v κ` have no jump while moving, sampled
/// at 1 kHz: position steps by at most `v_max h`, velocity by at most
/// `|a|_max h`, `ω_r` by at most `h · max |ω̇_r|` with
/// `|ω̇_r| ≤ a_t κ_peak + a_lat / L` on each blend; the differences
/// of position and velocity match velocity and acceleration.
#[test]
fn position_velocity_and_turn_rate_are_continuous() {
    let h = 0.001;
    let plan = plan(h);
    let l = spec();
    let omega_dot_max = plan
        .segments()
        .iter()
        .filter_map(|s| match s.kind {
            Kind::BlendIn { phi, .. } | Kind::BlendOut { phi, .. } => Some(
                l.max_tangential_accel_m_s2 * 2.0 * phi / s.length
                    + l.max_lateral_accel_m_s2 / s.length,
            ),
            _ => None,
        })
        .fold(0.0_f32, f32::max);
    assert!(omega_dot_max > 0.0);
    let a_max = l.max_tangential_accel_m_s2.hypot(l.max_lateral_accel_m_s2);
    let all = samples(&plan);
    let (mut worst_dp, mut worst_dv, mut worst_dw) = (0.0_f32, 0.0_f32, 0.0_f32);
    for pair in all.windows(2) {
        let [(a, _), (b, _)] = pair else { continue };
        let (ra, rb) = (a.reference, b.reference);
        let dp = (rb.position - ra.position).norm();
        let dv = (rb.velocity - ra.velocity).norm();
        worst_dp = worst_dp.max(dp / h);
        worst_dv = worst_dv.max(dv / h);
        assert!(dp <= l.max_speed_m_s * h * 1.001 + 1e-6, "{dp} {a:?} {b:?}");
        assert!(dv <= a_max * h * 1.001 + 1e-5, "{dv} {a:?} {b:?}");
        // Position differences are the mean velocity (f32 positions of a
        // few metres round to 5e-7 m: 1e-3 m/s at h = 1 ms).
        let mean_v = (ra.velocity + rb.velocity).scaled(0.5);
        let fd = (rb.position - ra.position).scaled(1.0 / h);
        assert!((fd - mean_v).norm() < 3e-3, "{fd:?} {mean_v:?} {a:?}");
        if let (Some(ka), Some(kb)) = (curvature(a), curvature(b)) {
            let dw = (kb * rb.speed() - ka * ra.speed()).abs();
            worst_dw = worst_dw.max(dw / h);
            assert!(dw <= omega_dot_max * h * 1.01 + 1e-5, "{dw} {a:?} {b:?}");
            // ω_r from the velocity and acceleration agrees with v κ.
            if ra.speed() > 0.05 {
                let w = cross(ra.velocity, ra.acceleration) / (ra.speed() * ra.speed());
                assert!((w - ka * ra.speed()).abs() < 1e-3 * (1.0 + w.abs()));
            }
            // Velocity differences are the acceleration, away from the
            // trapezoids' switches (where the tangential one jumps).
            if (rb.acceleration - ra.acceleration).norm() < 0.05 {
                let fd = (rb.velocity - ra.velocity).scaled(1.0 / h);
                let mean_a = (ra.acceleration + rb.acceleration).scaled(0.5);
                assert!((fd - mean_a).norm() < 0.02, "{fd:?} {mean_a:?} {a:?}");
            }
        }
    }
    std::println!(
        "largest per-second jumps at 1 kHz: |dp|/h {worst_dp:.4} m/s, |dv|/h {worst_dv:.4} m/s², |dω|/h {worst_dw:.4} rad/s² (bound {omega_dot_max:.4})"
    );
}

/// Speed under the route's and each leg's limit, tangential and lateral
/// acceleration under theirs, every sample.
#[test]
fn limits_hold_at_every_sample() {
    let plan = plan(H);
    let l = spec();
    let segments = plan.segments();
    let mut on_limited_leg = 0;
    for (s, j) in samples(&plan) {
        let r = s.reference;
        let v = r.speed();
        assert!(v <= l.max_speed_m_s * (1.0 + 1e-6), "{s:?}");
        assert!(v <= segments[j].cap * (1.0 + 1e-6) + 1e-7, "{s:?}");
        if v > 1e-3 {
            let t = r.velocity.scaled(1.0 / v);
            let along = dot(r.acceleration, t).abs();
            let across = cross(t, r.acceleration).abs();
            assert!(along <= l.max_tangential_accel_m_s2 * (1.0 + 1e-5), "{s:?}");
            assert!(across <= l.max_lateral_accel_m_s2 * (1.0 + 1e-4), "{s:?}");
            let k = curvature(&s).unwrap();
            assert!(v * v * k.abs() <= l.max_lateral_accel_m_s2 * (1.0 + 1e-4));
        }
        // The leg from (4, 0) to (4, 3) is limited to 0.4 m/s.
        let p = r.position;
        if (p.x - 4.0).abs() < 1e-3 && p.y > 0.5 && p.y < 2.5 {
            on_limited_leg += 1;
            assert!(v <= 0.4 * (1.0 + 1e-6), "{s:?}");
        }
    }
    assert!(on_limited_leg > 100);
    let bounds = plan.speed_bounds();
    assert_eq!(bounds.min_m_s, 0.0);
    assert!(bounds.max_m_s > 0.9 && bounds.max_m_s <= 1.0);
}

/// At rest exactly (zero velocity and acceleration, on the waypoint)
/// while stopped or pivoting; the speed reaches zero on the tick that
/// the stop begins.
#[test]
fn the_reference_is_at_rest_at_stops() {
    let plan = plan(H);
    let stops: Vec<Vec2> = waypoints()
        .iter()
        .filter(|w| w.stop.is_some())
        .map(|w| w.position_m)
        .collect();
    let all = samples(&plan);
    let mut at_rest = 0;
    for pair in all.windows(2) {
        let [(a, _), (b, _)] = pair else { continue };
        if curvature(b).is_none() {
            at_rest += 1;
            assert_eq!(b.reference.velocity, Vec2::ZERO);
            assert_eq!(b.reference.acceleration, Vec2::ZERO);
            assert!(stops.contains(&b.reference.position), "{b:?}");
            if curvature(a).is_some() {
                // The last moving sample before a stop is within a tick
                // of rest.
                assert!(a.reference.speed() <= spec().max_tangential_accel_m_s2 * H * 1.001);
                assert!((a.reference.position - b.reference.position).norm() < 1e-3);
            }
        }
    }
    // Dwells of 0.5 + 1.5 + 0.5 + 0.2 s, pivots besides.
    assert!(at_rest >= 270, "{at_rest}");
}

/// Pivots: rate and angular acceleration under their limits, the rate
/// continuous, the heading the integral of the rate, and the pivots end
/// on the headings to face and on the next leg's direction.
#[test]
fn pivots_obey_their_limits_and_end_on_their_headings() {
    let h = 0.001;
    let plan = plan(h);
    let l = spec();
    let all = samples(&plan);
    let mut pivoting = 0;
    let mut holds = Vec::new();
    for pair in all.windows(2) {
        let [(a, _), (b, _)] = pair else { continue };
        if let RouteMode::Stopped {
            hold_heading_rad: Some(hold),
        } = b.mode
            && holds.last() != Some(&hold)
        {
            holds.push(hold);
        }
        let RouteMode::Pivoting {
            heading_rad: ha,
            rate_rad_s: wa,
            accel_rad_s2: aa,
        } = a.mode
        else {
            continue;
        };
        pivoting += 1;
        assert!(wa.abs() <= l.pivot_rate_rad_s * (1.0 + 1e-6));
        assert!(aa.abs() <= l.pivot_accel_rad_s2);
        if let RouteMode::Pivoting {
            heading_rad: hb,
            rate_rad_s: wb,
            ..
        } = b.mode
        {
            assert!((wb - wa).abs() <= l.pivot_accel_rad_s2 * h * 1.001 + 1e-6);
            let turned = crate::math::wrap_angle(hb - ha);
            assert!((turned - 0.5 * (wa + wb) * h).abs() < 2e-6, "{a:?} {b:?}");
        }
    }
    assert!(pivoting > 1000, "{pivoting}");
    // The headings held: (1, 4) faces 2.0; (-2, -2) pivots from -π/2 to
    // the next leg, 0; (5, -1) keeps its arrival (a turn of 0.06 rad,
    // below the threshold: a stop-and-go); (8, 2) faces -3.0.
    let arrival = 1.0_f32.atan2(3.0);
    let expected = [2.0, 0.0, arrival, -3.0];
    assert_eq!(holds.len(), expected.len(), "{holds:?}");
    for (got, want) in holds.iter().zip(expected) {
        assert!((got - want).abs() < 1e-5, "{holds:?}");
    }
}

/// Each blend's closest point to its corner is `blend_deviation_m` from
/// it, and no point of a blend is farther than that from the polyline.
#[test]
fn blends_deviate_from_the_corner_by_the_key() {
    let h = 0.001;
    let plan = plan(h);
    let e = spec().blend_deviation_m;
    let wps = waypoints();
    let all = samples(&plan);
    let distance_to_leg = |p: Vec2, a: Vec2, b: Vec2| {
        let d = b - a;
        let t = (dot(p - a, d) / dot(d, d)).clamp(0.0, 1.0);
        (a + d.scaled(t) - p).norm()
    };
    let mut corners = 0;
    for (i, w) in wps.iter().enumerate() {
        if w.stop.is_some() || i == 0 || i + 1 == wps.len() {
            continue;
        }
        corners += 1;
        let closest = all
            .iter()
            .map(|(s, _)| (s.reference.position - w.position_m).norm())
            .fold(f32::MAX, f32::min);
        assert!((closest - e).abs() < 1e-4, "corner {i}: {closest}");
    }
    assert_eq!(corners, 5);
    let worst = all
        .iter()
        .map(|(s, _)| {
            wps.windows(2)
                .map(|p| distance_to_leg(s.reference.position, p[0].position_m, p[1].position_m))
                .fold(f32::MAX, f32::min)
        })
        .fold(0.0_f32, f32::max);
    assert!(worst <= e * (1.0 + 1e-4), "{worst}");
    std::println!("largest distance from the polyline: {worst} m (key {e} m)");
}

#[test]
fn fresnel_series_matches_a_quadrature() {
    for phi in [1e-4_f32, 0.3, 0.8, 1.2, 1.55] {
        for r in [0.0_f32, 0.25, 0.5, 0.9, 1.0] {
            let (c, s) = geometry::fresnel(phi, r);
            let (mut cr, mut sr) = (0.0_f64, 0.0_f64);
            let n = 20_000;
            let dw = f64::from(r) / f64::from(n);
            for i in 0..n {
                let w = (f64::from(i) + 0.5) * dw;
                let a = f64::from(phi) * w * w;
                cr += a.cos() * dw;
                sr += a.sin() * dw;
            }
            assert!((f64::from(c) - cr).abs() < 3e-7, "C({phi}, {r})");
            assert!((f64::from(s) - sr).abs() < 3e-7, "S({phi}, {r})");
        }
    }
}

// ---------------------------------------------------------------- refusals

fn refusal(wps: &[Waypoint]) -> RouteError {
    RoutePlan::new(wps, &limits(), H).unwrap_err()
}

#[test]
fn refusals_name_the_waypoint_and_the_key() {
    let a = Waypoint::stop(0.0, 0.0, 0.0);
    let b = Waypoint::pass(1.0, 0.0);
    let c = Waypoint::stop(1.0, 1.0, 0.0);
    assert_eq!(refusal(&[]), RouteError::TooFewWaypoints);
    assert_eq!(refusal(&[a]), RouteError::TooFewWaypoints);
    assert_eq!(
        refusal(&[a, b, b, c]),
        RouteError::SameAsPrevious { index: 2 }
    );
    let nan = Waypoint::pass(f32::NAN, 0.0);
    assert_eq!(
        refusal(&[a, nan, c]),
        RouteError::NotFinite {
            index: 1,
            key: WaypointKey::Position
        }
    );
    assert_eq!(
        refusal(&[a, Waypoint::pass(1e5, 0.0), c]),
        RouteError::OutOfRange {
            index: 1,
            key: WaypointKey::Position
        }
    );
    assert_eq!(
        refusal(&[a, b, Waypoint::stop(1.0, 1.0, f32::INFINITY)]),
        RouteError::NotFinite {
            index: 2,
            key: WaypointKey::Dwell
        }
    );
    assert_eq!(
        refusal(&[a, b, c.facing(f32::NAN)]),
        RouteError::NotFinite {
            index: 2,
            key: WaypointKey::FaceHeading
        }
    );
    assert_eq!(
        refusal(&[a, b, c.facing(1e4)]),
        RouteError::OutOfRange {
            index: 2,
            key: WaypointKey::FaceHeading
        }
    );
    assert_eq!(
        refusal(&[a, b.with_speed_limit(f32::NAN), c]),
        RouteError::NotFinite {
            index: 1,
            key: WaypointKey::SpeedLimit
        }
    );
    assert_eq!(
        refusal(&[a, b, c.with_speed_limit(0.0)]),
        RouteError::SpeedLimit { index: 2 }
    );
    assert_eq!(
        refusal(&[a, b, c.with_speed_limit(-1.0)]),
        RouteError::SpeedLimit { index: 2 }
    );
    assert_eq!(
        refusal(&[a, b, Waypoint::stop(1.0, 1.0, -0.1)]),
        RouteError::NegativeDwell { index: 2 }
    );
    // The blend at (1, 0) (a right angle, deviation 0.1 m) needs about
    // 0.2 m of each leg; its second leg is 0.1 m long.
    assert_eq!(
        refusal(&[a, b, Waypoint::stop(1.0, 0.1, 0.0)]),
        RouteError::BlendDoesNotFit { index: 1 }
    );
    // Two corners whose blends (each ~0.34 m along the legs) overlap on
    // the 0.6 m leg between them: the one that needs more of it (the
    // gentler turn, 90° against 94°) is named.
    assert_eq!(
        refusal(&[
            a,
            b,
            Waypoint::pass(1.0, 0.6),
            Waypoint::stop(2.5, 0.5, 0.0)
        ]),
        RouteError::BlendDoesNotFit { index: 1 }
    );
    // A reversal through a corner.
    assert_eq!(
        refusal(&[a, b, Waypoint::stop(0.0, 0.001, 0.0)]),
        RouteError::BlendDoesNotFit { index: 1 }
    );
    // A gentle turn's blend is long (L ≈ 3e/φ): 0.05 rad needs ~12 m.
    assert_eq!(
        refusal(&[a, b, Waypoint::stop(2.0, 0.05, 0.0)]),
        RouteError::BlendDoesNotFit { index: 1 }
    );
    assert_eq!(
        RoutePlan::new(&[a, c], &limits(), 0.0).unwrap_err(),
        RouteError::Period
    );
    assert_eq!(
        refusal(&[a, Waypoint::stop(1.0, 0.0, 1e12)]),
        RouteError::TooLong
    );
    // Capacity.
    let many: Vec<Waypoint> = (0..=ROUTE_CAPACITY)
        .map(|i| Waypoint::stop(i as f32, 0.0, 0.0))
        .collect();
    assert_eq!(refusal(&many), RouteError::TooManyWaypoints);
    let mut held = Waypoints::new();
    for w in &many[..ROUTE_CAPACITY] {
        held.push(*w).unwrap();
    }
    assert_eq!(held.push(a), Err(RouteError::TooManyWaypoints));
    assert_eq!(
        Waypoints::from_slice(&many),
        Err(RouteError::TooManyWaypoints)
    );
    assert!(RoutePlan::new(held.as_slice(), &limits(), H).is_ok());
    // The text names the index and the key.
    let text = std::format!(
        "{}",
        RouteError::NotFinite {
            index: 7,
            key: WaypointKey::Dwell
        }
    );
    assert!(
        text.contains("waypoint 7") && text.contains("stop.dwell_s"),
        "{text}"
    );
    let text = std::format!("{}", RouteError::BlendDoesNotFit { index: 3 });
    assert!(text.contains("waypoint 3") && text.contains("blend_deviation_m"));
}

#[test]
fn limits_are_refused_by_name() {
    type Field = fn(&mut RouteLimitsSpec) -> &mut f32;
    let fields: [(Field, LimitKey); 7] = [
        (|s| &mut s.max_speed_m_s, LimitKey::MaxSpeed),
        (
            |s| &mut s.max_tangential_accel_m_s2,
            LimitKey::MaxTangentialAccel,
        ),
        (|s| &mut s.max_lateral_accel_m_s2, LimitKey::MaxLateralAccel),
        (|s| &mut s.blend_deviation_m, LimitKey::BlendDeviation),
        (|s| &mut s.pivot_threshold_rad, LimitKey::PivotThreshold),
        (|s| &mut s.pivot_rate_rad_s, LimitKey::PivotRate),
        (|s| &mut s.pivot_accel_rad_s2, LimitKey::PivotAccel),
    ];
    for (field, key) in fields {
        let bad: &[f32] = if key == LimitKey::PivotThreshold {
            &[-0.1, 3.2, f32::NAN, f32::INFINITY]
        } else {
            &[0.0, -1.0, f32::NAN, f32::INFINITY, f32::NEG_INFINITY]
        };
        for &v in bad {
            let mut s = spec();
            *field(&mut s) = v;
            assert_eq!(RouteLimits::new(&s), Err(RouteLimitsError(key)), "{v}");
            let text = std::format!("{}", RouteLimitsError(key));
            assert!(text.contains(key.key()), "{text}");
        }
    }
    let mut s = spec();
    s.pivot_threshold_rad = 0.0;
    assert!(RouteLimits::new(&s).is_ok());
}

/// No input panics or leaks a non-finite sample: random waypoints and
/// limits, planned or refused; every plan sampled.
#[test]
fn random_routes_plan_or_refuse_and_sample_finite() {
    let mut state = 0x2545_f491_u32;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        state
    };
    let mut unit = move || (next() as f32) / (u32::MAX as f32);
    let mut planned = 0;
    for _ in 0..300 {
        let n = 2 + (unit() * 10.0) as usize;
        let wps: Vec<Waypoint> = (0..n)
            .map(|_| {
                let mut w = Waypoint::pass(unit() * 20.0 - 10.0, unit() * 20.0 - 10.0);
                if unit() < 0.3 {
                    w = Waypoint::stop(w.position_m.x, w.position_m.y, unit() * 2.0);
                }
                if unit() < 0.2 {
                    w = w.facing(unit() * 10.0 - 5.0);
                }
                if unit() < 0.2 {
                    w = w.with_speed_limit(unit() * 2.0);
                }
                w
            })
            .collect();
        let mut s = spec();
        s.blend_deviation_m = 0.01 + unit() * 0.3;
        s.pivot_threshold_rad = unit() * 3.0;
        let Ok(l) = RouteLimits::new(&s) else {
            continue;
        };
        let Ok(plan) = RoutePlan::new(&wps, &l, 0.02) else {
            continue;
        };
        planned += 1;
        let mut cursor = RouteCursor::new();
        let end = plan.duration_ticks();
        for k in (0..end + 5).step_by(3) {
            let r = plan.sample(&mut cursor, k);
            assert!(r.reference.position.is_finite() && r.reference.velocity.is_finite());
            assert!(r.reference.acceleration.is_finite());
            assert!(r.reference.speed() <= s.max_speed_m_s * 1.0001);
        }
        assert_eq!(
            plan.sample(&mut cursor, end).reference.position,
            wps.last().unwrap().position_m
        );
    }
    assert!(planned > 50, "{planned}");
}

// ------------------------------------------------- day 30 and the wrap

/// The plan's `f64` evaluation at absolute time `t_s`: the segments'
/// start times from their ticks and offsets, the profiles, lines and
/// clothoids (by quadrature) in `f64`.
fn position_f64(plan: &RoutePlan, t_s: f64) -> (f64, f64) {
    let h = f64::from(plan.period_s());
    let start = |s: &Segment| f64::from(s.first_tick) * h - f64::from(s.offset_s);
    let segments = plan.segments();
    let seg = segments
        .iter()
        .rev()
        .find(|s| start(s) <= t_s + 1e-12)
        .unwrap();
    let tau = (t_s - start(seg)).min(f64::from(seg.duration_s));
    let p = seg.profile;
    let (v0, vp, a) = (f64::from(p.v0), f64::from(p.peak), f64::from(p.accel));
    let (t1, t2, t3) = (
        f64::from(p.t_accel_s),
        f64::from(p.t_cruise_s),
        f64::from(p.t_decel_s),
    );
    let d1 = 0.5 * (v0 + vp) * t1;
    let dist = if tau < t1 {
        tau * (v0 + 0.5 * a * tau)
    } else if tau < t1 + t2 {
        d1 + vp * (tau - t1)
    } else {
        let t = (tau - t1 - t2).min(t3);
        d1 + vp * t2 + t * (vp - 0.5 * a * t)
    }
    .clamp(0.0, f64::from(p.length));
    let (ox, oy) = (f64::from(seg.origin.x), f64::from(seg.origin.y));
    let (dx, dy) = (f64::from(seg.dir.x), f64::from(seg.dir.y));
    let l = f64::from(seg.length);
    let fresnel = |phi: f64, r: f64| {
        let n = 2_000;
        let (mut c, mut s) = (0.0, 0.0);
        for i in 0..n {
            let w = (f64::from(i) + 0.5) * r / f64::from(n);
            c += (phi * w * w).cos() * r / f64::from(n);
            s += (phi * w * w).sin() * r / f64::from(n);
        }
        (c, s)
    };
    let rotate = |x: f64, y: f64| (dx * x - dy * y, dy * x + dx * y);
    match seg.kind {
        Kind::Line => (ox + dx * dist, oy + dy * dist),
        Kind::BlendIn { phi, sign } => {
            let (c, s) = fresnel(f64::from(phi), dist / l);
            let (x, y) = rotate(l * c, l * f64::from(sign) * s);
            (ox + x, oy + y)
        }
        Kind::BlendOut { phi, sign } => {
            let (c, s) = fresnel(f64::from(phi), (l - dist) / l);
            let (x, y) = rotate(-l * c, l * f64::from(sign) * s);
            (ox + x, oy + y)
        }
        Kind::Pivot { .. } | Kind::Dwell { .. } => (ox, oy),
    }
}

fn error_m(s: &RouteSample, (x, y): (f64, f64)) -> f64 {
    (f64::from(s.reference.position.x) - x).hypot(f64::from(s.reference.position.y) - y)
}

/// A route started on day 30 of a free-running tick counter samples bit
/// for bit as one started at tick 0, and a route that itself runs 30 days
/// (a 30-day dwell, then a lap) is within 1 mm of the `f64` evaluation of
/// its plan on day 30.
#[test]
fn day_30_samples_as_day_1() {
    let plan = plan(H);
    let (mut c0, mut c30) = (RouteCursor::new(), RouteCursor::new());
    let mut worst = 0.0_f64;
    for k in 0..=plan.duration_ticks() {
        let day_1 = plan.sample(&mut c0, k);
        let day_30 = plan.sample_at(&mut c30, DAY_30_TICKS + k, DAY_30_TICKS);
        assert_eq!(day_1, day_30);
        worst = worst.max(error_m(
            &day_1,
            position_f64(&plan, f64::from(k) * f64::from(H)),
        ));
    }
    assert!(worst < 1e-3, "{worst}");

    let mut wps = waypoints();
    wps[0] = Waypoint::stop(0.0, 0.0, 30.0 * 86_400.0);
    let long = RoutePlan::new(&wps, &limits(), H).unwrap();
    let start = long.segments()[1].first_tick;
    assert!(start >= DAY_30_TICKS, "{start}");
    let mut cursor = RouteCursor::new();
    let mut worst_30 = 0.0_f64;
    for k in (start - 10)..=long.duration_ticks() {
        let s = long.sample(&mut cursor, k);
        worst_30 = worst_30.max(error_m(
            &s,
            position_f64(&long, f64::from(k) * f64::from(H)),
        ));
    }
    std::println!(
        "largest error against f64: day 1 {:.3e} m, after a 30-day dwell {:.3e} m",
        worst,
        worst_30
    );
    assert!(worst_30 < 1e-3, "{worst_30}");
}

/// Across the `u32` counter's wrap the route samples as from tick 0.
#[test]
fn the_tick_counter_wraps() {
    let plan = plan(H);
    let start = u32::MAX - 1_000;
    let (mut c0, mut cw) = (RouteCursor::new(), RouteCursor::new());
    for k in 0..=plan.duration_ticks() + 10 {
        let now = start.wrapping_add(k);
        assert_eq!(plan.sample(&mut c0, k), plan.sample_at(&mut cw, now, start));
    }
    // Done, then the elapsed count itself wraps: still done.
    assert!(plan.sample_at(&mut cw, start.wrapping_sub(1), start).done);
    assert!(plan.sample_at(&mut cw, start, start).done);
}

/// A cursor that goes back in time finds its segment again.
#[test]
fn a_cursor_may_jump_back() {
    let plan = plan(H);
    let forward: Vec<RouteSample> = samples(&plan).iter().map(|(s, _)| *s).collect();
    let mut cursor = RouteCursor::new();
    let _ = plan.sample(&mut cursor, plan.duration_ticks() - 1);
    // All but the last (done: the cursor then stays done).
    let before_done = &forward[..forward.len() - 1];
    for (k, want) in before_done.iter().enumerate().rev().step_by(37) {
        assert_eq!(plan.sample(&mut cursor, k as u32), *want);
    }
}

/// Planning and sampling costs on the host (the Cortex-M4 figures are for
/// the on-target bench, stage 2).
#[test]
fn planning_and_sampling_costs_on_the_host() {
    let wps: Vec<Waypoint> = (0..ROUTE_CAPACITY)
        .map(|i| {
            let a = i as f32 * 0.4;
            let r = 10.0 + 3.0 * (i % 2) as f32;
            let w = Waypoint::pass(r * a.cos(), r * a.sin());
            if i % 8 == 7 || i + 1 == ROUTE_CAPACITY {
                Waypoint::stop(w.position_m.x, w.position_m.y, 0.5).facing(a)
            } else {
                w
            }
        })
        .collect();
    let l = limits();
    let t = std::time::Instant::now();
    let runs = 200;
    let mut plan = RoutePlan::new(&wps, &l, H).unwrap();
    for _ in 0..runs {
        plan = RoutePlan::new(std::hint::black_box(&wps), &l, H).unwrap();
    }
    let plan_ns = t.elapsed().as_nanos() / runs;
    let mut cursor = RouteCursor::new();
    let end = plan.duration_ticks();
    let t = std::time::Instant::now();
    let mut acc = 0.0;
    for k in 0..end {
        acc += plan
            .sample(&mut cursor, std::hint::black_box(k))
            .reference
            .position
            .x;
    }
    let sample_ns = t.elapsed().as_nanos() / u128::from(end);
    std::println!(
        "64 waypoints: {} segments, {end} ticks; plan {plan_ns} ns, sample {sample_ns} ns on the host ({acc}); \
         RoutePlan {} bytes, Waypoints {} bytes",
        plan.segment_count(),
        core::mem::size_of::<RoutePlan>(),
        core::mem::size_of::<Waypoints>()
    );
    assert!(plan.segment_count() > 64);
}

/// Planning in place gives the plan `new` gives; a refusal leaves the
/// plan empty, done at once.
#[test]
fn replanning_in_place() {
    let mut plan = RoutePlan::empty();
    let mut cursor = RouteCursor::new();
    assert!(plan.sample(&mut cursor, 0).done);
    plan.replan(&waypoints(), &limits(), H).unwrap();
    assert_eq!(plan, RoutePlan::new(&waypoints(), &limits(), H).unwrap());
    let refused = plan.replan(&waypoints()[..1], &limits(), H);
    assert_eq!(refused, Err(RouteError::TooFewWaypoints));
    assert_eq!(plan.segment_count(), 0);
    let mut cursor = RouteCursor::new();
    assert!(plan.sample(&mut cursor, 0).done);
}

/// An `f32` that is any bit pattern (NaN, ±∞, subnormal, huge) one time
/// in ten, a plausible value otherwise.
fn wild(plausible: core::ops::Range<f32>) -> impl proptest::strategy::Strategy<Value = f32> {
    use proptest::prelude::*;
    prop_oneof![1 => proptest::num::f32::ANY, 9 => plausible]
}

proptest::proptest! {
    #![proptest_config(proptest::test_runner::Config::with_cases(2_000))]

    /// Whatever the numbers, planning returns (a plan or a refusal) and a
    /// plan samples finite values, at rest on the last waypoint at its end.
    #[test]
    fn any_numbers_plan_or_refuse_without_panic(
        points in proptest::collection::vec(
            (wild(-20.0..20.0), wild(-20.0..20.0), wild(-1.0..3.0), wild(-4.0..4.0), wild(-0.5..2.0), 0_u8..8),
            0..6,
        ),
        l in (wild(0.01..2.0), wild(0.01..2.0), wild(0.01..2.0), wild(0.001..0.5), wild(-0.2..3.3), wild(0.01..3.0), wild(0.01..5.0)),
        period_s in wild(0.001..0.1),
    ) {
        let wps: Vec<Waypoint> = points
            .iter()
            .map(|&(x, y, dwell, face, limit, flags)| {
                let mut w = if flags & 1 == 1 {
                    Waypoint::stop(x, y, dwell)
                } else {
                    Waypoint::pass(x, y)
                };
                if flags & 2 == 2 {
                    w = w.facing(face);
                }
                if flags & 4 == 4 {
                    w = w.with_speed_limit(limit);
                }
                w
            })
            .collect();
        let spec = RouteLimitsSpec {
            max_speed_m_s: l.0,
            max_tangential_accel_m_s2: l.1,
            max_lateral_accel_m_s2: l.2,
            blend_deviation_m: l.3,
            pivot_threshold_rad: l.4,
            pivot_rate_rad_s: l.5,
            pivot_accel_rad_s2: l.6,
        };
        let Ok(limits) = RouteLimits::new(&spec) else { return Ok(()) };
        let Ok(plan) = RoutePlan::new(&wps, &limits, period_s) else { return Ok(()) };
        let mut cursor = RouteCursor::new();
        let end = plan.duration_ticks();
        let step = (end / 500).max(1);
        let mut k = 0_u32;
        while k <= end {
            let s = plan.sample(&mut cursor, k);
            proptest::prop_assert!(s.reference.position.is_finite());
            proptest::prop_assert!(s.reference.velocity.is_finite());
            proptest::prop_assert!(s.reference.acceleration.is_finite());
            k += step;
        }
        let s = plan.sample(&mut cursor, end);
        proptest::prop_assert!(s.done);
        proptest::prop_assert_eq!(s.reference.position, wps.last().unwrap().position_m);
    }
}
