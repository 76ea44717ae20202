//! The analytic references on long runs ([`ReferenceClock`]): the
//! figure-eight and a circle on day 30 and across the `u32` tick count's
//! wrap against an `f64` evaluation, the first epoch bit for bit as
//! `TickClock::time_s`, the stepped and the direct time alike, the line's
//! documented limit, and finite samples at any tick.
//!
//! For comparison, `TickClock::time_s(k) = k·h` in `f32` puts the
//! paper's figure-eight 82 mm off on day 30 at 100 Hz (`k as f32` a
//! multiple of 16 ticks, `t` of 0.25 s): measured here too.

use super::{
    Circle, EPOCH_TURNS, FigureEight, ReferenceClock, StraightLine, TickClock, Trajectory,
};
use crate::geometry::Vec2;

const DAY_TICKS: u64 = 86_400 * 100;
const DAY_30_TICKS: u64 = 30 * DAY_TICKS;
/// The `u32` tick count's wrap, 497 days at 100 Hz.
const WRAP: u64 = 1 << 32;

/// The exact point of `traj` at tick `k` in `f64` (paper 001, (51); the
/// circle's `c + r(cos a, sin a)`, `a = ωt + φ`; the line's `p0 + v t`).
fn position_f64(traj: &Trajectory, h: f32, k: u64) -> (f64, f64) {
    let t = k as f64 * f64::from(h);
    match traj {
        Trajectory::FigureEight(f) => {
            let s = f64::from(f.h2_rad_s) * t + f64::from(f.phase_rad);
            let h1 = f64::from(f.h1_m);
            (h1 * (2.0 * s).sin(), h1 * s.sin())
        }
        Trajectory::Circle(c) => {
            let a = f64::from(c.rate_rad_s) * t + f64::from(c.phase_rad);
            let r = f64::from(c.radius_m);
            (
                f64::from(c.centre.x) + r * a.cos(),
                f64::from(c.centre.y) + r * a.sin(),
            )
        }
        Trajectory::StraightLine(l) => (
            f64::from(l.start.x) + f64::from(l.velocity.x) * t,
            f64::from(l.start.y) + f64::from(l.velocity.y) * t,
        ),
    }
}

fn error_m(traj: &Trajectory, h: f32, clock: &ReferenceClock, k: u64) -> f64 {
    let p = traj.sample_at(clock, clock.at_tick(k)).position;
    let (x, y) = position_f64(traj, h, k);
    (f64::from(p.x) - x).hypot(f64::from(p.y) - y)
}

/// The largest error against `f64` over `count` ticks from `first`, every
/// `step`th, each from the stepped time (checked against the direct one).
fn worst_error_m(traj: &Trajectory, h: f32, first: u64, count: u64, step: u64) -> f64 {
    let clock = ReferenceClock::new(&TickClock::new(h).unwrap(), traj);
    let mut time = clock.at_tick(first);
    let mut worst = 0.0_f64;
    for i in 0..count {
        let k = first + i;
        if i % step == 0 {
            assert_eq!(time, clock.at_tick(k), "tick {k}");
            worst = worst.max(error_m(traj, h, &clock, k));
        }
        time = clock.next(time);
    }
    worst
}

fn paper_eight() -> Trajectory {
    FigureEight::paper_001().into()
}

/// `robots/circle_surveyed.toml`'s circle (2 m, 0.1 rad/s) and a fast
/// clockwise one (10 m, 1 rad/s: 10 m/s).
fn circles() -> [Trajectory; 2] {
    [
        Circle::new(Vec2::new(1.0, -2.0), 2.0, 0.1, 0.3)
            .unwrap()
            .into(),
        Circle::new(Vec2::new(-3.0, 4.0), 10.0, -1.0, -2.0)
            .unwrap()
            .into(),
    ]
}

#[test]
fn figure_eight_on_day_30_is_within_1_mm_of_f64() {
    let h = 0.01;
    let traj = paper_eight();
    // One period (314 s) of ticks, every 7th.
    let day_1 = worst_error_m(&traj, h, 0, 31_416, 7);
    let day_30 = worst_error_m(&traj, h, DAY_30_TICKS, 31_416, 7);
    // What k·h in f32 gives on day 30.
    let clock = TickClock::new(h).unwrap();
    let mut plain = 0.0_f64;
    for k in (DAY_30_TICKS..DAY_30_TICKS + 31_416).step_by(7) {
        let p = traj.sample(clock.time_s(k as u32)).position;
        let (x, y) = position_f64(&traj, h, k);
        plain = plain.max((f64::from(p.x) - x).hypot(f64::from(p.y) - y));
    }
    std::println!(
        "figure-eight against f64, largest error over a period: first period {day_1:.3e} m, \
         day 30 {day_30:.3e} m (with t = k·h in f32: {plain:.3e} m)"
    );
    assert!(day_1 < 1e-4, "{day_1}");
    assert!(day_30 < 1e-4, "{day_30}");
    assert!(plain > 1e-2, "{plain}");
}

#[test]
fn circles_on_day_30_are_within_1_mm_of_f64() {
    for (traj, h) in circles().into_iter().zip([0.01, 0.001]) {
        let period_ticks = (core::f64::consts::TAU
            / f64::from(traj.rate_rad_s().unwrap().abs())
            / f64::from(h)) as u64;
        let first = worst_error_m(&traj, h, 0, period_ticks, 3);
        let day_30 = worst_error_m(
            &traj,
            h,
            30 * 86_400 * (1.0 / h).round() as u64,
            period_ticks,
            3,
        );
        std::println!("{traj:?} at h = {h} s: first period {first:.3e} m, day 30 {day_30:.3e} m");
        assert!(day_30 < 1e-3, "{day_30}");
        assert!(first < 1e-3, "{first}");
    }
}

/// Across the `u32` tick count's wrap (and at `2⁴⁰` ticks, 350 years at
/// 100 Hz) each curve stays within 1 mm, the time stepping on.
#[test]
fn across_the_u32_wrap_the_curves_stay_within_1_mm() {
    let mut trajs = circles().to_vec();
    trajs.push(paper_eight());
    for traj in trajs {
        for around in [WRAP, 1 << 40] {
            let worst = worst_error_m(&traj, 0.01, around - 40_000, 80_000, 5);
            assert!(worst < 1e-3, "{traj:?} around {around}: {worst}");
        }
    }
}

/// For the first five turns (and for a line) the time is `k·h` exactly
/// as `TickClock::time_s` gives it, bit for bit: the runs that stay
/// inside them sample as they always did.
#[test]
fn the_first_epoch_is_tick_clock_time_bit_for_bit() {
    let h = 0.01;
    let tick_clock = TickClock::new(h).unwrap();
    let line = Trajectory::from(StraightLine::new(Vec2::new(1.0, 2.0), 0.4, 0.3).unwrap());
    for traj in [paper_eight(), circles()[0], line] {
        let clock = ReferenceClock::new(&tick_clock, &traj);
        let epoch = clock.epoch_ticks().map_or(200_000.0, |e| e);
        let mut time = clock.start();
        let mut k = 0_u32;
        while (k as f32) < epoch - 1.0 {
            assert_eq!(
                clock.time_s(time).to_bits(),
                tick_clock.time_s(k).to_bits(),
                "{traj:?} tick {k}"
            );
            time = clock.next(time);
            k += 1;
        }
    }
    // The paper's figure-eight's epoch: five periods of 314 s.
    let epoch = ReferenceClock::new(&tick_clock, &paper_eight())
        .epoch_ticks()
        .unwrap();
    assert!((epoch - 157_079.63).abs() < 0.05, "{epoch}");
    assert_eq!(EPOCH_TURNS, 5);
}

/// Past an epoch's end the time is back inside the first epoch, the
/// reference where it would be: continuous across the boundary.
#[test]
fn the_time_is_reduced_at_each_epoch() {
    let h = 0.01;
    let traj = paper_eight();
    let clock = ReferenceClock::new(&TickClock::new(h).unwrap(), &traj);
    let epoch = 10.0 * core::f64::consts::PI / (f64::from(0.02_f32) * f64::from(h));
    for n in [1_u64, 2, 1_000, 27_345] {
        let end = (n as f64 * epoch).ceil() as u64;
        for k in end - 3..end + 3 {
            let t = clock.time_s(clock.at_tick(k));
            let want = (k as f64 - n as f64 * epoch + if k < end { epoch } else { 0.0 }) * 0.01;
            // f32 resolves 1,571 s to 1.2e-4 s.
            assert!(
                (f64::from(t) - want).abs() < 2e-4,
                "tick {k}: {t} vs {want}"
            );
            assert!(error_m(&traj, h, &clock, k) < 1e-4);
        }
    }
}

/// More than five turns per tick (the plausible ranges' extreme: 100
/// rad/s at h = 1 s): every tick starts an epoch, and the stepped and
/// direct times still agree and stay within one.
#[test]
fn a_reference_faster_than_an_epoch_a_tick() {
    let h = 1.0;
    let traj = Trajectory::from(Circle::new(Vec2::ZERO, 1.0, 100.0, 0.0).unwrap());
    let clock = ReferenceClock::new(&TickClock::new(h).unwrap(), &traj);
    let epoch = clock.epoch_ticks().unwrap();
    let mut time = clock.start();
    for k in 0..10_000_u64 {
        assert_eq!(time, clock.at_tick(k), "tick {k}");
        let t = clock.time_s(time);
        assert!((0.0..=epoch * h).contains(&t), "{t}");
        assert!(error_m(&traj, h, &clock, k) < 1e-4, "tick {k}");
        time = clock.next(time);
    }
}

/// The line has no period: its point is `start + v·t`, `t = k·h` in
/// `f32`, so its error grows with the distance run (`t`'s rounding,
/// relative 6e-8, and the coordinate's own, 1 mm at 16 km): within 1 mm
/// for its first 4 km, 0.2 m/s for 5.5 h (module documentation).
#[test]
fn the_line_is_within_1_mm_for_its_first_4_km() {
    let h = 0.01;
    let traj = Trajectory::from(StraightLine::new(Vec2::new(-10.0, 5.0), 0.7, 0.2).unwrap());
    let clock = ReferenceClock::new(&TickClock::new(h).unwrap(), &traj);
    assert_eq!(clock.epoch_ticks(), None);
    let last = 2_000_000; // 20,000 s: 4 km.
    let mut worst = 0.0_f64;
    for k in (0..=last).step_by(997).chain([last]) {
        worst = worst.max(error_m(&traj, h, &clock, k));
    }
    std::println!("line over its first 4 km: {worst:.3e} m");
    assert!(worst < 1e-3, "{worst}");
}

/// Every trajectory at the plausible ranges' extremes samples finite at
/// any tick, stepped past the `u32` wrap and directly up to `u64::MAX`.
#[test]
fn samples_are_finite_at_any_tick() {
    let size = crate::plausible::REFERENCE_SIZE_M;
    let rate = crate::plausible::REFERENCE_RATE_RAD_S;
    let speed = crate::plausible::REFERENCE_SPEED_M_S;
    let far = crate::plausible::COORDINATE_M.max;
    let mut trajs = std::vec::Vec::new();
    for r in [rate.min, 1.0, rate.max] {
        trajs.push(Trajectory::from(
            FigureEight::new(size.max, r, 1e3).unwrap(),
        ));
        trajs.push(Trajectory::from(
            Circle::new(Vec2::new(far, -far), size.max, -r, -1e3).unwrap(),
        ));
    }
    for v in [speed.min, speed.max] {
        trajs.push(Trajectory::from(
            StraightLine::new(Vec2::new(far, far), 1e3, v).unwrap(),
        ));
    }
    let periods = [
        crate::plausible::PERIOD_S.min,
        0.01,
        crate::plausible::PERIOD_S.max,
    ];
    for traj in &trajs {
        for h in periods {
            let clock = ReferenceClock::new(&TickClock::new(h).unwrap(), traj);
            let mut time = clock.at_tick(WRAP - 3);
            for _ in 0..6 {
                time = clock.next(time);
                assert!(finite(traj, &clock, time), "{traj:?} at h = {h}");
            }
            for k in [
                0,
                1,
                12_345_678,
                WRAP - 1,
                WRAP,
                1 << 53,
                u64::MAX - 1,
                u64::MAX,
            ] {
                let time = clock.at_tick(k);
                assert!(finite(traj, &clock, time), "{traj:?} at h = {h}, tick {k}");
                assert!(clock.time_s(time) >= 0.0);
            }
        }
    }
}

fn finite(traj: &Trajectory, clock: &ReferenceClock, time: super::ReferenceTime) -> bool {
    let s = traj.sample_at(clock, time);
    s.position.is_finite() && s.velocity.is_finite() && s.acceleration.is_finite()
}

/// The epochs per tick, computed in integers from the `f32` mantissas,
/// agree with `f64` over the plausible ranges: the epoch's length, and
/// the angle `ω·t` at the first epoch's end and at the `u32` wrap, modulo
/// `2π`, within the `f32` resolution of an angle below `10π` (2 µrad) and
/// the drift of `q`'s rounding (the `f64` reference's own rounding
/// counted).
#[test]
fn the_epoch_matches_f64() {
    for h in [1e-4_f32, 3.3e-3, 0.01, 0.05, 1.0] {
        for w in [1e-6_f32, 0.02, 0.1, -0.7, 3.0, 31.0, 100.0] {
            let traj = Trajectory::from(Circle::new(Vec2::ZERO, 1.0, w, 0.0).unwrap());
            let clock = ReferenceClock::new(&TickClock::new(h).unwrap(), &traj);
            let (wf, hf) = (f64::from(w), f64::from(h));
            let want = 10.0 * core::f64::consts::PI / (wf.abs() * hf);
            let got = f64::from(clock.epoch_ticks().unwrap());
            assert!((got / want - 1.0).abs() < 3e-7, "{w} {h}: {got} vs {want}");
            let end = want.ceil() as u64;
            for k in [
                end.saturating_sub(1),
                end,
                end + 1,
                WRAP - 1,
                WRAP,
                WRAP + 1,
            ] {
                let t = f64::from(clock.time_s(clock.at_tick(k)));
                let exact = wf * hf * k as f64;
                let off = (wf * t - exact).rem_euclid(core::f64::consts::TAU);
                let off = off.min(core::f64::consts::TAU - off);
                // Beyond 1e-5 rad: f64's own rounding of `exact`.
                let tolerance = 1e-5 + 4e-16 * exact.abs();
                assert!(off < tolerance, "{w} {h} tick {k}: {off} rad");
            }
        }
    }
}
