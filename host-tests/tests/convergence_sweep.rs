//! Paper 001's global convergence, Monte Carlo: the state-feedback law (14)
//! and the output-feedback law (27)–(28) with observer (5) on the
//! figure-eight, exact position, unicycle plant, from random starts up to
//! 50 m from the reference's start with any heading (and, for output
//! feedback, a random observer state `(ẑ3, ẑ4)` in the unit disc).
//!
//! Each law runs with the paper's gains `k1 = k2 = 0.11`, which break the
//! gain bound (15) for this reference (γ = 3.51), and with
//! `k1 = k2 = 0.025`, which satisfy it: γ = √2·0.025·(π/2)/v_rm = 0.80 with
//! `v_rm = 0.1·√(31/64) = 0.0696 m/s`, so (21)–(22) guarantee
//! `0.014 ≤ v ≤ 0.279 m/s`. They are the largest round gains with a 20 %
//! margin to the bound: far from the reference the law closes in at most at
//! `√2·k·π/2` (0.056 m/s here), so from 50 m the convergence time scales
//! with `1/k`, and the margin keeps `v ≥ 0.2·v_rm` for the observer.
//!
//! "Converged" (see `firmware_sim::sweep`): the tracking error is below
//! 0.05 m from some time `t_c` to the end and for at least the last 100 s.
//! The durations come from 1,000-run release sweeps per case (seed 7;
//! slowest time to converge: state feedback 272 s with the paper's gains,
//! 627 s with the bound's; output feedback 304 s and 881 s), plus the hold
//! and a margin. Every one of those 4,000 runs converged, as do the runs
//! here.
//!
//! `cargo test -p host-tests --test convergence_sweep -- --nocapture`
//! prints each case's fraction and slowest run.

use std::time::Instant;

use firmware_sim::Scenario;
use firmware_sim::scenario::{HeadingSweep, ObserverStart, SweepSpec};
use firmware_sim::sweep::output::runs_csv;
use firmware_sim::sweep::{SweepOptions, SweepResult, run_sweep};
use wmr_core::control::saturated::GainBound;

/// Runs per case.
const RUNS: u64 = 100;
/// The sweeps' seed.
const SEED: u64 = 1;
/// Starts up to this far from the reference's start, m.
const START_RADIUS_M: f64 = 50.0;
/// The error must stay below the threshold for at least this long, s.
const HOLD_S: f64 = 100.0;
/// `k1 = k2` that satisfy the gain bound (15) with γ = 0.80, m/s.
const BOUND_GAINS: f64 = 0.025;

/// Which gains.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Gains {
    /// The paper's `k1 = k2 = 0.11` (break (15)).
    Paper,
    /// `k1 = k2 = BOUND_GAINS` (satisfy (15)).
    WithinBound,
}

/// The embedded scenario `name` swept from up to 50 m away, any heading,
/// and (output feedback) a random observer state.
fn swept(name: &str, gains: Gains, duration_s: f64) -> Scenario {
    let mut s = Scenario::embedded(name).expect("embedded scenario");
    s.duration_s = duration_s;
    if gains == Gains::WithinBound {
        s.controller.k1 = BOUND_GAINS;
        s.controller.k2 = BOUND_GAINS;
    }
    let output_feedback = name != "figure_eight_state_feedback";
    s.sweep = Some(SweepSpec {
        start_radius_m: Some([0.0, START_RADIUS_M]),
        initial_heading: HeadingSweep::Any,
        observer_start: if output_feedback {
            ObserverStart::UnitDisc
        } else {
            ObserverStart::Scenario
        },
        converge_hold_s: Some(HOLD_S),
        ..SweepSpec::default()
    });
    s
}

/// Sweeps `scenario`, prints the figures, and checks what every case must
/// show: the gain bound as expected, finite runs, starts that reach far.
fn sweep(scenario: &Scenario, gains: Gains) -> SweepResult {
    let setup = scenario.validate().expect("valid sweep scenario");
    let bound = setup.gains.check_bound(setup.trajectory.speed_bounds());
    match (gains, bound) {
        (Gains::Paper, GainBound::Violated { gamma }) => assert!(gamma > 3.5, "{gamma}"),
        (Gains::WithinBound, GainBound::Satisfied { gamma, .. }) => {
            assert!(gamma < 0.81, "{gamma}");
        }
        other => panic!("unexpected gain bound {other:?}"),
    }
    let wall = Instant::now();
    let options = SweepOptions {
        runs: RUNS,
        seed: SEED,
        threads: 0,
    };
    let result = run_sweep(scenario, &options, &|| {}).expect("sweep runs");
    let s = &result.summary;
    println!(
        "{} ({:?} gains, {bound:?}), {} s: converged {}/{} = {:.3}; slowest {}; {:.1} s wall",
        scenario.name,
        gains,
        scenario.duration_s,
        s.converged,
        s.runs,
        s.converged_fraction,
        s.slowest.map_or("none".to_owned(), |r| format!(
            "index {} (seed {}) from {:.2} m, converged at {:.1} s",
            r.index, r.seed, r.initial_distance_m, r.time_to_converge_s
        )),
        wall.elapsed().as_secs_f64()
    );
    assert_eq!(s.runs, RUNS);
    assert_eq!(s.non_finite_runs, 0);
    assert_eq!(s.plan.converge_threshold_m, 0.05);
    // The sample reaches the far edge of the disc.
    assert!(s.initial_distance_m.max > 0.9 * START_RADIUS_M);
    result
}

/// Every run converged, and ends far inside the threshold.
fn assert_all_converge(result: &SweepResult) {
    let s = &result.summary;
    assert!(
        s.not_converged.is_empty(),
        "not converged (seed, index): {:?}",
        s.not_converged
    );
    assert_eq!(s.converged, RUNS);
    assert_eq!(s.converged_fraction, 1.0);
    let slowest = s.slowest.expect("converged runs have a slowest");
    assert!(slowest.time_to_converge_s <= s.duration_s - HOLD_S);
    assert!(s.final_error_m.max < 1e-3, "{:?}", s.final_error_m);
}

#[test]
fn state_feedback_14_with_the_papers_gains_converges_from_50_m() {
    let s = swept("figure_eight_state_feedback", Gains::Paper, 500.0);
    assert_all_converge(&sweep(&s, Gains::Paper));
}

#[test]
fn state_feedback_14_with_gains_within_the_bound_converges_from_50_m() {
    let s = swept("figure_eight_state_feedback", Gains::WithinBound, 1000.0);
    assert_all_converge(&sweep(&s, Gains::WithinBound));
}

#[test]
fn output_feedback_27_28_with_the_papers_gains_converges_from_50_m() {
    let s = swept("figure_eight_exact", Gains::Paper, 550.0);
    assert_all_converge(&sweep(&s, Gains::Paper));
}

#[test]
fn output_feedback_27_28_with_gains_within_the_bound_converges_from_50_m() {
    let s = swept("figure_eight_exact", Gains::WithinBound, 1300.0);
    assert_all_converge(&sweep(&s, Gains::WithinBound));
}

#[test]
fn same_seed_gives_the_same_runs_on_one_and_two_threads() {
    let mut s = swept("figure_eight_exact", Gains::Paper, 200.0);
    // Vary every field that applies, so that every draw is exercised.
    if let Some(sweep) = &mut s.sweep {
        sweep.position_noise_std_m = Some([0.0, 0.01]);
        sweep.read_miss_probability = Some([0.0, 0.2]);
        sweep.converge_hold_s = Some(20.0);
    }
    let with = |threads: usize, seed: u64| {
        let options = SweepOptions {
            runs: 12,
            seed,
            threads,
        };
        run_sweep(&s, &options, &|| {}).expect("sweep runs")
    };
    let one = with(1, SEED);
    let two = with(2, SEED);
    let csv = runs_csv(&one.rows).expect("csv");
    assert_eq!(csv, runs_csv(&two.rows).expect("csv"));
    assert_eq!(one.summary, two.summary);
    assert_ne!(csv, runs_csv(&with(2, SEED + 1).rows).expect("csv"));
    println!(
        "12 runs: identical runs.csv ({} bytes) and summary on 1 and 2 threads",
        csv.len()
    );
}
