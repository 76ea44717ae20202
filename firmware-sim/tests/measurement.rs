//! Noise and misses on the position fix (`[measurement]`).

use firmware_sim::{Scenario, run};

#[test]
fn noise_and_misses_reach_the_tracker_and_are_counted() {
    let mut s = Scenario::embedded("figure_eight_rfid").unwrap();
    s.duration_s = 20.0;
    s.transient_s = 10.0;
    let clean = run(&s, |_, _| {}).unwrap();
    assert!(clean.summary.measurement.is_none());
    s.measurement.noise_std_m = 0.05;
    s.measurement.miss_probability = 0.25;
    let noisy = run(&s, |_, _| {}).unwrap();
    let m = noisy.summary.measurement.unwrap();
    let tracker = noisy.summary.tracker.unwrap();
    // About a quarter of the 2000 fixes removed, each one dead-reckoned.
    assert!((400..600).contains(&m.missed_fixes), "{m:?}");
    assert_eq!(tracker.fixes_used + m.missed_fixes, 2000);
    // Noise moves the fixes off the tag lattice.
    let off_lattice = noisy
        .records
        .iter()
        .filter(|r| r.fix)
        .filter_map(|r| r.est_x_m)
        .filter(|x| ((x / 0.1).round() * 0.1 - x).abs() > 1e-4)
        .count();
    assert!(off_lattice > 1000, "{off_lattice}");
    // Same seed, same run.
    assert_eq!(run(&s, |_, _| {}).unwrap().records, noisy.records);
}
