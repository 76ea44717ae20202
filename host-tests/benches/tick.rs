//! Host benchmark of one control tick and its stages (criterion).
//!
//! Host nanoseconds say little about a Cortex-M4; on-target instruction
//! counts come from the QEMU benchmark (firmware issue). This bench tracks
//! regressions of the same code on the development machine.

use criterion::{Criterion, criterion_group, criterion_main};
use host_tests::paper_pilot;
use std::hint::black_box;
use wmr_core::control::saturated::{TrackingController, TrackingGains};
use wmr_core::estimation::heading_observer::{HeadingObserver, HeadingObserverConfig};
use wmr_core::geometry::HeadingEstimate;
use wmr_core::geometry::{BodyVelocity, Vec2};
use wmr_core::pilot::Measurement;
use wmr_core::pilot::tracker::TagFix;
use wmr_core::reference::{FigureEight, Trajectory};

const H: f32 = 0.01;

fn bench(c: &mut Criterion) {
    c.bench_function("pilot_tick", |b| {
        let mut p = paper_pilot();
        let mut k: u32 = 0;
        b.iter(|| {
            k = k.wrapping_add(1);
            let m = Measurement {
                left_count: Some(k.wrapping_mul(11)),
                right_count: Some(k.wrapping_mul(12)),
                fix: Some(TagFix {
                    position: Vec2::new(0.1 * (k % 7) as f32, -5.9),
                    age_ticks: 0,
                }),
            };
            black_box(p.step(black_box(&m)))
        });
    });
    c.bench_function("heading_observer_update", |b| {
        let mut o = HeadingObserver::new(HeadingObserverConfig::new(0.6, H).unwrap());
        b.iter(|| {
            o.update(
                black_box(BodyVelocity {
                    v_m_s: 0.2,
                    omega_rad_s: 0.05,
                }),
                black_box(Vec2::new(0.0019, 0.0004)),
            );
            black_box(o.estimate())
        });
    });
    c.bench_function("output_feedback_law", |b| {
        let traj = Trajectory::from(FigureEight::paper_001());
        let r = traj.sample(37.0);
        let mut law = TrackingController::new(TrackingGains::new(0.11, 0.11, 0.1).unwrap());
        b.iter(|| {
            black_box(law.output_feedback(
                black_box(&r),
                black_box(Vec2::new(0.3, -5.8)),
                black_box(HeadingEstimate {
                    cos_theta: -0.9,
                    sin_theta: 0.3,
                }),
            ))
        });
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
