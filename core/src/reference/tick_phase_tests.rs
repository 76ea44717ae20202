//! The figure-eight on day 30: what `TickClock::time_s` gives, and what a
//! phase reduced modulo the period in integer ticks would give.
//!
//! `TickClock::time_s(k) = k·h` in `f32` adds no error over time, but on
//! day 30 at 100 Hz (`k = 2.59e8`) `k as f32` is a multiple of 16 ticks and
//! `t = 2.59e6 s` is a multiple of 0.25 s, so `t` is off by up to ~0.2 s
//! and the figure-eight's point (speed up to `√5 h1 h2 = 0.22 m/s`) by up
//! to 82 mm (measured here, against `f64`; 8 µm on day 1).
//!
//! The proposal, measured here (not applied: `TickClock` and
//! `Trajectory::sample` are unchanged): a periodic reference reduces its
//! phase modulo its period in integer arithmetic before any `f32` time is
//! formed. The phase advance per tick in turns, `h2·h/2π`, is held as a
//! 64-bit fixed-point fraction `q` (computed once at construction, on the
//! robot from the exact 48-bit product of the two `f32` mantissas times a
//! 64-bit `1/2π`, in integers); the phase of tick `k` is `k·q mod 2⁶⁴`
//! (`wrapping_mul`, exact modular arithmetic, no drift), and the time fed
//! to the unchanged `sample` is `t' = (k·q / 2⁶⁴)·(2π/h2)`, inside one
//! period, where `f32` resolves 30 µs. The error of `q`'s rounding,
//! 2⁻⁶⁵ turn per tick, is 7e-12 turn after 2.6e8 ticks.

use super::{FigureEight, TickClock, Trajectory};

const DAY_30_TICKS: u32 = 30 * 86_400 * 100;

/// The figure-eight's point at tick `k` in `f64` (paper 001, (51)).
fn position_f64(f: &FigureEight, h: f32, k: u32) -> (f64, f64) {
    let (h1, h2, phi) = (
        f64::from(f.h1_m),
        f64::from(f.h2_rad_s),
        f64::from(f.phase_rad),
    );
    let s = h2 * (f64::from(k) * f64::from(h)) + phi;
    (h1 * (2.0 * s).sin(), h1 * s.sin())
}

/// The proposal: the time inside one period for tick `k`.
fn reduced_time_s(f: &FigureEight, h: f32, k: u32) -> f32 {
    let turns_per_tick = f64::from(f.h2_rad_s) * f64::from(h) / core::f64::consts::TAU;
    // 2⁶⁴ · turns_per_tick, rounded (turns_per_tick < 1).
    let q = (turns_per_tick * 18_446_744_073_709_551_616.0) as u64;
    let phase = u64::from(k).wrapping_mul(q);
    // The top 24 bits as a fraction of a turn, in f32.
    let turns = (phase >> 40) as f32 / 16_777_216.0;
    turns * (core::f32::consts::TAU / f.h2_rad_s)
}

fn error_m(sample: (f32, f32), reference: (f64, f64)) -> f64 {
    (f64::from(sample.0) - reference.0).hypot(f64::from(sample.1) - reference.1)
}

#[test]
fn figure_eight_on_day_30_needs_a_tick_reduced_phase() {
    let h = 0.01;
    let clock = TickClock::new(h).unwrap();
    let eight = FigureEight::paper_001();
    let traj = Trajectory::from(eight);
    let (mut worst_clock, mut worst_reduced, mut worst_day_1) = (0.0_f64, 0.0_f64, 0.0_f64);
    // One period (314 s) of ticks from day 30 on, every 7th.
    for k in (DAY_30_TICKS..DAY_30_TICKS + 31_416).step_by(7) {
        let want = position_f64(&eight, h, k);
        let p = traj.sample(clock.time_s(k)).position;
        worst_clock = worst_clock.max(error_m((p.x, p.y), want));
        let p = traj.sample(reduced_time_s(&eight, h, k)).position;
        worst_reduced = worst_reduced.max(error_m((p.x, p.y), want));
    }
    for k in (0..31_416).step_by(7) {
        let p = traj.sample(clock.time_s(k)).position;
        worst_day_1 = worst_day_1.max(error_m((p.x, p.y), position_f64(&eight, h, k)));
    }
    std::println!(
        "figure-eight against f64, largest error over a period: day 1 {worst_day_1:.3e} m; \
         day 30 with TickClock::time_s {worst_clock:.3e} m, with the tick-reduced phase {worst_reduced:.3e} m"
    );
    // TickClock's t = k·h in f32 cannot keep 1 mm on day 30 ...
    assert!(worst_clock > 1e-3, "{worst_clock}");
    // ... the phase reduced in integer ticks keeps it, as on day 1.
    assert!(worst_reduced < 1e-3, "{worst_reduced}");
    assert!(worst_day_1 < 1e-3, "{worst_day_1}");
}
