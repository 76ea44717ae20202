//! Whole-stack properties of the `Pilot`: whatever the devices show — any
//! counter values (wraps, jumps, missing reads) and any fix (NaN, ±Inf,
//! far away, stale) — the motor commands are finite duties in [0, 1].

use host_tests::paper_pilot;
use proptest::prelude::*;
use wmr_core::geometry::Vec2;
use wmr_core::pilot::Measurement;
use wmr_core::pilot::tracker::TagFix;

fn any_coordinate() -> impl Strategy<Value = f32> {
    prop_oneof![
        4 => -20.0_f32..20.0,
        1 => prop::num::f32::ANY,
        1 => Just(f32::NAN),
        1 => Just(f32::INFINITY),
    ]
}

fn any_measurement() -> impl Strategy<Value = Measurement> {
    (
        prop::option::weighted(0.9, any::<u32>()),
        prop::option::weighted(0.9, any::<u32>()),
        prop::option::weighted(0.7, (any_coordinate(), any_coordinate(), 0_u32..5)),
    )
        .prop_map(|(l, r, fix)| Measurement {
            left_count: l,
            right_count: r,
            fix: fix.map(|(x, y, age_ticks)| TagFix {
                position: Vec2::new(x, y),
                age_ticks,
            }),
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn motor_commands_are_always_finite_duties(
        measurements in prop::collection::vec(any_measurement(), 1..300),
    ) {
        let mut p = paper_pilot();
        for m in &measurements {
            let out = p.step(m);
            for cmd in [out.left, out.right] {
                prop_assert!(cmd.duty.is_finite() && (0.0..=1.0).contains(&cmd.duty), "{cmd:?}");
            }
            prop_assert!(out.tracker.command.is_finite(), "{:?}", out.tracker);
        }
    }

    /// Plausible encoder motion (counter wrapping at full speed included)
    /// with valid fixes: the tracker never reports a non-finite command.
    #[test]
    fn plausible_inputs_never_need_the_nan_guard(
        start in any::<u16>(),
        steps in prop::collection::vec((-40_i32..40, -40_i32..40, -10.0_f32..10.0, -10.0_f32..10.0), 1..300),
    ) {
        let mut p = paper_pilot();
        let (mut l, mut r) = (u32::from(start), u32::from(start));
        for (dl, dr, x, y) in steps {
            l = l.wrapping_add_signed(dl);
            r = r.wrapping_add_signed(dr);
            p.step(&Measurement {
                left_count: Some(l),
                right_count: Some(r),
                fix: Some(TagFix { position: Vec2::new(x, y), age_ticks: 0 }),
            });
        }
        prop_assert_eq!(p.tracker().counters().non_finite_commands, 0);
        prop_assert_eq!(p.counters().implausible_encoder_reads, 0);
    }
}

proptest! {
    /// Wheels at (up to) full speed for long enough to wrap the 16-bit
    /// counters several times: the pilot's odometry adds up to the true
    /// wheel travel, to the last count.
    #[test]
    fn counter_wrap_at_full_speed_gives_true_odometry(
        start in (any::<u16>(), any::<u16>()),
        speed_fraction in (-1.0_f64..1.0, -1.0_f64..1.0),
        ticks in 500_u32..3000,
    ) {
        let mut p = paper_pilot();
        let geometry = *p.config().drive().geometry();
        let counts_per_rad = f64::from(geometry.counts_per_revolution()) / core::f64::consts::TAU;
        // 20 rad/s is the drive's top wheel speed in `paper_pilot()`.
        let counts_per_tick = (20.0 * speed_fraction.0 * 0.01 * counts_per_rad,
                               20.0 * speed_fraction.1 * 0.01 * counts_per_rad);
        let (mut travelled_l, mut travelled_r) = (0.0_f64, 0.0_f64);
        let (mut odo_l, mut odo_r) = (0.0_f64, 0.0_f64);
        for k in 0..=ticks {
            let true_l = (f64::from(k) * counts_per_tick.0).floor() as i64;
            let true_r = (f64::from(k) * counts_per_tick.1).floor() as i64;
            let raw = |start: u16, c: i64| (i64::from(start) + c).rem_euclid(1 << 16) as u32;
            let out = p.step(&Measurement {
                left_count: Some(raw(start.0, true_l)),
                right_count: Some(raw(start.1, true_r)),
                fix: None,
            });
            odo_l += f64::from(out.odometry.wheels.left_rad_s) * 0.01;
            odo_r += f64::from(out.odometry.wheels.right_rad_s) * 0.01;
            travelled_l = true_l as f64 / counts_per_rad;
            travelled_r = true_r as f64 / counts_per_rad;
        }
        // f32 speeds summed in f64: a few ppm of the distance.
        prop_assert!((odo_l - travelled_l).abs() < 1e-5 * travelled_l.abs() + 1e-4, "{odo_l} vs {travelled_l}");
        prop_assert!((odo_r - travelled_r).abs() < 1e-5 * travelled_r.abs() + 1e-4, "{odo_r} vs {travelled_r}");
        prop_assert_eq!(p.counters().implausible_encoder_reads, 0);
    }
}

/// Paper 001's RFID figure-eight (480 s) through the full device stack with
/// glitching encoders (`[plant.encoder_glitches]`, `seed`): bursts of
/// spurious counts on 1 % of the reads of each encoder, which stay in the
/// counter (a noisy motor without an input filter).
fn glitching_run(min_counts: u32, max_counts: u32) -> firmware_sim::Summary {
    let source = firmware_sim::scenario::embedded_source("figure_eight_rfid_full_stack").unwrap();
    let text = format!(
        "{source}\n[plant.encoder_glitches]\nprobability_per_read = 0.01\n\
         min_counts = {min_counts}\nmax_counts = {max_counts}\nseed = 7\n"
    );
    let run = firmware_sim::run(
        &firmware_sim::Scenario::from_toml_str(&text).unwrap(),
        |_, _| {},
    )
    .unwrap();
    let s = run.summary;
    println!(
        "glitches of {min_counts}–{max_counts} counts: {:?}; error after {} s: max {:.4} / \
         mean {:.4} m",
        s.pilot, s.transient_s, s.max_error_m, s.mean_error_m
    );
    s
}

/// Every burst larger than twice the top wheel speed allows in a tick (≈ 118
/// counts here, plus the tick's own motion, up to ≈ 60) is rejected as an
/// implausible jump: the pilot takes the counter's new value as its
/// origin and loses only that tick's motion (the tracker sees
/// none), and the motors never halt. With bursts of 200–2,000 counts every
/// burst is caught: 978 rejected ticks for 982 bursts, the difference being
/// ticks on which both encoders glitched (one rejected tick each; expected
/// 480 s · 100 /s · 0.01² ≈ 5). The lost ticks cost accuracy: 0.0376 /
/// 0.0159 m max / mean after 100 s against the clean run's 0.0266 /
/// 0.0042 m; paper 001's max bound (0.05 m) holds, its mean bound (0.01 m)
/// does not. (Dead-reckoning a rejected wheel with its previous tick's
/// motion, instead of none, would recover most of it; not done.)
#[test]
fn glitching_encoders_are_rejected_as_implausible_jumps() {
    let s = glitching_run(200, 2_000);
    let pilot = s.pilot.expect("pilot counters");
    // 480 s, 100 reads a second, two encoders, 1 %: about 960 bursts.
    assert!(
        (800..1_100).contains(&pilot.encoder_glitch_bursts),
        "{pilot:?}"
    );
    let rejected = u64::from(pilot.implausible_encoder_reads);
    assert!(rejected <= pilot.encoder_glitch_bursts);
    // Both encoders in one tick: about 5 expected; 15 is 4 standard
    // deviations of a Poisson count above that.
    assert!(pilot.encoder_glitch_bursts - rejected <= 15, "{pilot:?}");
    assert_eq!(pilot.encoder_fault_ticks, pilot.implausible_encoder_reads);
    assert_eq!(pilot.encoder_halt_ticks, 0);
    assert!(s.max_error_m <= 0.05, "{s:?}");
}

/// Bursts below the rejection threshold cannot be told from motion: they
/// pass as odometry error (a heading error the tag fixes must then
/// correct), which is what a timer's input filter is for. With bursts of
/// 1–2,000 counts, 93 % are rejected (914 of 982) and the rest degrade
/// tracking to 0.053 / 0.020 m max / mean (paper 001's bounds: 0.05 /
/// 0.01 m) without halting the motors.
#[test]
fn small_encoder_glitches_pass_as_odometry_error() {
    let s = glitching_run(1, 2_000);
    let pilot = s.pilot.expect("pilot counters");
    let rejected = u64::from(pilot.implausible_encoder_reads);
    // Uniform in 1..=2000: about 94 % exceed the threshold.
    assert!(rejected < pilot.encoder_glitch_bursts, "{pilot:?}");
    assert!(
        rejected * 100 >= pilot.encoder_glitch_bursts * 90,
        "{pilot:?}"
    );
    assert_eq!(pilot.encoder_halt_ticks, 0);
    assert!(s.max_error_m.is_finite() && s.max_error_m < 0.1, "{s:?}");
}
