//! Monte Carlo sweeps: many seeded variations of one scenario, run in
//! parallel through the ordinary [`run`], and their
//! convergence and error statistics.
//!
//! # What is varied
//! The scenario's optional `[sweep]` table: see [`SweepSpec`] for its
//! fields, their defaults and where each applies; [`Scenario::validate`]
//! resolves it into a [`SweepPlan`].
//!
//! # Seeds
//! Run `i` of a sweep with seed `S` draws everything from a ChaCha8
//! generator seeded with `S` on stream `i` ([`run_rng`]), always in the same
//! order and always every draw (a field that is not varied still consumes
//! its draws), so a run's variation depends on `(S, i)` only: not on the
//! number of runs, the thread count, or which other fields are varied. The
//! noise and miss RNG of the run is seeded from the same stream.
//!
//! # Convergence
//! With `ε = converge_threshold_m` and `T` the time of the last tick, run
//! `i` **converged** if its tracking error `|p − p_ref|` is below `ε` at
//! every tick from some time `t_c` to `T`, and `T − t_c ≥ converge_hold_s`.
//! The **time to converge** is the smallest such `t_c` (the first tick
//! after the last one with error `≥ ε`; 0 if the error was never above).
//! A run with any non-finite state does not converge. Defaults: `ε` =
//! 0.05 m with the exact position, 3 × the tag spacing with tags, plus
//! 3 × the largest position-noise std when that is varied; hold = 20 % of
//! the duration.
//!
//! # Sharding
//! Because a run depends on `(S, i)` only, a sweep can be split over
//! machines: [`run_sweep_shard`] runs one [`shard::Shard`]'s share of the
//! indices, and [`shard::merge_shards`] merges the shards into what
//! [`run_sweep`] returns (see [`shard`]).

pub mod output;
pub mod shard;

use std::f64::consts::{PI, TAU};

use rand::rngs::ChaCha8Rng;
use rand::{Rng as _, RngExt as _, SeedableRng as _};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::report::{Record, RunResult};
use crate::scenario::{
    ControllerKind, HeadingSweep, ObserverStart, PlantSpec, PositionSpec, Scenario, ScenarioError,
    Setup, SweepPlan, SweepSpec,
};
use crate::simulation::run;

impl SweepPlan {
    /// Samples run `index` of the sweep with seed `sweep_seed` (see the
    /// [module docs](self#seeds)).
    #[must_use]
    pub fn variation(&self, base: &Scenario, sweep_seed: u64, index: u64) -> Variation {
        let mut rng = run_rng(sweep_seed, index);
        let mut u = || rng.random::<f64>();
        let (u_radius, u_angle) = (u(), u());
        let u_heading = u();
        let (u_estimate_radius, u_estimate_angle) = (u(), u());
        let (u_tag_x, u_tag_y) = (u(), u());
        let u_encoder = u();
        let u_noise = u();
        let u_miss = u();
        let fault_seed = rng.next_u64();

        let [r0, r1] = self.start_radius_m;
        let radius = (r0 * r0 + u_radius * (r1 * r1 - r0 * r0)).sqrt();
        let angle = TAU * u_angle;
        let start_m = [
            self.reference_start_m[0] + radius * angle.cos(),
            self.reference_start_m[1] + radius * angle.sin(),
        ];
        let heading_rad = match self.initial_heading {
            HeadingSweep::Any => PI - TAU * u_heading,
            HeadingSweep::Scenario => base.initial.heading_rad,
        };
        let estimate = match self.observer_start {
            ObserverStart::Scenario => [base.initial.estimate_cos, base.initial.estimate_sin],
            ObserverStart::Zero => [0.0, 0.0],
            ObserverStart::UnitDisc => {
                let (r, a) = (u_estimate_radius.sqrt(), TAU * u_estimate_angle);
                [r * a.cos(), r * a.sin()]
            }
        };
        let lerp = |r: [f64; 2], u: f64| r[0] + u * (r[1] - r[0]);
        Variation {
            sweep_seed,
            index,
            start_m,
            heading_rad,
            estimate,
            tag_offset_m: self.tag_offset_cell_m.map(|s| [u_tag_x * s, u_tag_y * s]),
            encoder_counts_per_rev: self.encoder_counts_per_rev.map(|c| {
                let list = c.as_slice();
                list[((u_encoder * list.len() as f64) as usize).min(list.len() - 1)]
            }),
            position_noise_std_m: self.position_noise_std_m.map(|r| lerp(r, u_noise)),
            read_miss_probability: self.read_miss_probability.map(|r| lerp(r, u_miss)),
            fault_seed,
        }
    }

    /// Whether run `records` converged, and when (see the
    /// [module docs](self#convergence)).
    #[must_use]
    pub fn convergence(&self, records: &[Record]) -> Convergence {
        convergence(records, self.converge_threshold_m, self.converge_hold_s)
    }
}

/// The generator of run `index` of a sweep seeded `sweep_seed`: ChaCha8
/// seeded with `sweep_seed`, on stream `index`.
#[must_use]
pub fn run_rng(sweep_seed: u64, index: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(sweep_seed);
    rng.set_stream(index);
    rng
}

/// What run `index` of a sweep varies.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Variation {
    /// The sweep's seed.
    pub sweep_seed: u64,
    /// The run's index.
    pub index: u64,
    /// Initial position `[x, y]`, m.
    pub start_m: [f64; 2],
    /// Initial heading, rad.
    pub heading_rad: f64,
    /// Observer's initial `[ẑ3, ẑ4]`.
    pub estimate: [f64; 2],
    /// Tag lattice offset, m (when varied).
    pub tag_offset_m: Option<[f64; 2]>,
    /// Encoder resolution, counts per revolution (when varied).
    pub encoder_counts_per_rev: Option<u32>,
    /// Position-noise std, m (when varied).
    pub position_noise_std_m: Option<f64>,
    /// Fix-miss probability (when varied).
    pub read_miss_probability: Option<f64>,
    /// Seed of the run's own fault RNG (measurement noise and misses, the
    /// reader's link faults).
    pub fault_seed: u64,
}

impl Variation {
    /// The concrete scenario of this run: `base` with the variation
    /// applied and no `[sweep]` table (`firmware-sim run` takes it as is).
    #[must_use]
    pub fn apply(&self, base: &Scenario) -> Scenario {
        let mut s = base.clone();
        s.sweep = None;
        s.name = format!("{}-seed{}-run{}", base.name, self.sweep_seed, self.index);
        s.description = format!(
            "run {} of the sweep of {} with seed {}",
            self.index, base.name, self.sweep_seed
        );
        s.initial.x_m = self.start_m[0];
        s.initial.y_m = self.start_m[1];
        s.initial.heading_rad = self.heading_rad;
        s.initial.estimate_cos = self.estimate[0];
        s.initial.estimate_sin = self.estimate[1];
        if let Some(counts) = self.encoder_counts_per_rev
            && let PlantSpec::DiffDrive {
                encoder_counts_per_rev,
                ..
            } = &mut s.plant
        {
            *encoder_counts_per_rev = counts;
        }
        s.measurement.seed = self.fault_seed;
        match &mut s.position {
            PositionSpec::Exact => {}
            PositionSpec::NearestTag { offset_m, .. } => {
                if let Some(o) = self.tag_offset_m {
                    *offset_m = o;
                }
            }
            PositionSpec::Reader {
                offset_m,
                drop_frame_probability,
                seed,
                ..
            } => {
                if let Some(o) = self.tag_offset_m {
                    *offset_m = o;
                }
                if let Some(p) = self.read_miss_probability {
                    *drop_frame_probability = p;
                }
                *seed = self.fault_seed;
            }
        }
        if !matches!(s.position, PositionSpec::Reader { .. }) {
            if let Some(std) = self.position_noise_std_m {
                s.measurement.noise_std_m = std;
            }
            if let Some(p) = self.read_miss_probability {
                s.measurement.miss_probability = p;
            }
        }
        s
    }
}

/// Whether and when a run converged.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Convergence {
    /// Below the threshold from `time_s` to the end, for at least the hold.
    pub converged: bool,
    /// Start of the final stretch below the threshold, s (`None` if the
    /// last tick is not below it, or the stretch is shorter than the hold).
    pub time_s: Option<f64>,
}

/// Convergence of `records` for threshold `threshold_m` and hold `hold_s`
/// (see the [module docs](self#convergence)).
#[must_use]
pub fn convergence(records: &[Record], threshold_m: f64, hold_s: f64) -> Convergence {
    let not = Convergence {
        converged: false,
        time_s: None,
    };
    let Some(last) = records.last() else {
        return not;
    };
    // A NaN error is not below the threshold either.
    let below = |r: &Record| r.error_m < threshold_m;
    let start = match records.iter().rposition(|r| !below(r)) {
        None => 0,
        Some(i) if i + 1 < records.len() => i + 1,
        Some(_) => return not,
    };
    let t_c = records[start].t_s;
    if last.t_s - t_c >= hold_s - 1e-9 {
        Convergence {
            converged: true,
            time_s: Some(t_c),
        }
    } else {
        not
    }
}

/// One run of a sweep: what was varied and what came out (one row of
/// `runs.csv`; empty cells for what does not apply).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct SweepRun {
    /// Run index `i`.
    pub index: u64,
    /// The sweep's seed `S` (with `i`, reproduces the run).
    pub seed: u64,
    /// Initial x, m.
    pub start_x_m: f64,
    /// Initial y, m.
    pub start_y_m: f64,
    /// Initial heading, rad.
    pub heading_rad: f64,
    /// Observer's initial `ẑ3` (output feedback).
    pub estimate_cos: Option<f64>,
    /// Observer's initial `ẑ4` (output feedback).
    pub estimate_sin: Option<f64>,
    /// Tag lattice offset x, m (tags).
    pub tag_offset_x_m: Option<f64>,
    /// Tag lattice offset y, m (tags).
    pub tag_offset_y_m: Option<f64>,
    /// Encoder resolution, counts per revolution (diff drive).
    pub encoder_counts_per_rev: Option<u32>,
    /// Position-noise std, m (exact, nearest tag).
    pub position_noise_std_m: Option<f64>,
    /// Probability a tick's fix is missing (output feedback).
    pub read_miss_probability: Option<f64>,
    /// Distance to the reference at `t = 0`, m.
    pub initial_distance_m: f64,
    /// See [`Convergence`].
    pub converged: bool,
    /// Time to converge, s (converged runs).
    pub time_to_converge_s: Option<f64>,
    /// Largest tracking error over `t ≥ transient_s`, m.
    pub max_error_m: f64,
    /// Mean tracking error over `t ≥ transient_s`, m.
    pub mean_error_m: f64,
    /// RMS tracking error over `t ≥ transient_s`, m.
    pub rms_error_m: f64,
    /// Tracking error at the last tick, m.
    pub final_error_m: f64,
    /// Ticks with a non-finite value (expect 0).
    pub non_finite_ticks: u64,
    /// A route run's figures (not a `runs.csv` column: the sweep's
    /// `summary.json` aggregates them).
    #[serde(skip)]
    pub route: Option<RouteRun>,
}

/// A route run's figures in a sweep (ground truth, as in its
/// [`crate::report::RouteReport`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RouteRun {
    /// The route was finished within the duration.
    pub done: bool,
    /// Stops never settled at.
    pub stops_missed: usize,
    /// Largest true stop position error, m.
    pub max_stop_position_error_m: Option<f64>,
    /// Largest true stop heading error (stops facing a heading), degrees.
    pub max_stop_heading_error_deg: Option<f64>,
    /// Largest true cross-track error while moving, m.
    pub max_cross_track_error_m: Option<f64>,
    /// Time taken over the planned duration.
    pub time_ratio: Option<f64>,
}

/// The worst of a route figure over a sweep's runs, and the run it came
/// from.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct WorstRun {
    /// The figure.
    pub value: f64,
    /// The run's index.
    pub index: u64,
    /// The sweep's seed.
    pub seed: u64,
}

/// A route sweep's figures (`summary.json`'s `route`): the worst over all
/// stops of all runs, and the runs that did not finish.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RouteSweepSummary {
    /// Runs whose route was done within the duration.
    pub runs_done: u64,
    /// Runs whose route was not done.
    pub not_done: Vec<RunId>,
    /// Stops never settled at, over all runs.
    pub stops_missed: u64,
    /// Largest true stop position error over all stops of all runs, m.
    pub worst_stop_position_error_m: Option<WorstRun>,
    /// Largest true stop heading error over all stops facing a heading, degrees.
    pub worst_stop_heading_error_deg: Option<WorstRun>,
    /// Largest true cross-track error while moving, m.
    pub worst_cross_track_error_m: Option<WorstRun>,
    /// Largest time taken over the planned duration (done runs).
    pub worst_time_ratio: Option<WorstRun>,
    /// Per-run largest stop position error, over the runs, m.
    pub stop_position_error_m: Percentiles,
    /// Per-run largest cross-track error, over the runs, m.
    pub cross_track_error_m: Percentiles,
}

impl RouteSweepSummary {
    /// Of the rows holding route figures (`None`: none does, e.g. rows
    /// read back from a shard's `runs.csv`, which has no route columns).
    fn of(rows: &[SweepRun]) -> Option<Self> {
        let routes: Vec<(&SweepRun, RouteRun)> = rows
            .iter()
            .filter_map(|r| r.route.map(|f| (r, f)))
            .collect();
        if routes.is_empty() {
            return None;
        }
        let worst = |f: fn(&RouteRun) -> Option<f64>| {
            routes
                .iter()
                .filter_map(|(r, route)| f(route).map(|v| (v, r)))
                .max_by(|a, b| a.0.total_cmp(&b.0).then(b.1.index.cmp(&a.1.index)))
                .map(|(value, r)| WorstRun {
                    value,
                    index: r.index,
                    seed: r.seed,
                })
        };
        let per_run = |f: fn(&RouteRun) -> Option<f64>| {
            Percentiles::of(routes.iter().map(|(_, r)| f(r).unwrap_or(f64::NAN)))
        };
        Some(Self {
            runs_done: routes.iter().filter(|(_, r)| r.done).count() as u64,
            not_done: routes
                .iter()
                .filter(|(_, r)| !r.done)
                .map(|(r, _)| RunId {
                    seed: r.seed,
                    index: r.index,
                })
                .collect(),
            stops_missed: routes.iter().map(|(_, r)| r.stops_missed as u64).sum(),
            worst_stop_position_error_m: worst(|r| r.max_stop_position_error_m),
            worst_stop_heading_error_deg: worst(|r| r.max_stop_heading_error_deg),
            worst_cross_track_error_m: worst(|r| r.max_cross_track_error_m),
            worst_time_ratio: worst(|r| r.time_ratio),
            stop_position_error_m: per_run(|r| r.max_stop_position_error_m),
            cross_track_error_m: per_run(|r| r.max_cross_track_error_m),
        })
    }
}

impl SweepRun {
    fn new(v: &Variation, scenario: &Scenario, result: &RunResult, plan: &SweepPlan) -> Self {
        let s = &result.summary;
        let convergence = if s.non_finite_ticks == 0 {
            plan.convergence(&result.records)
        } else {
            Convergence {
                converged: false,
                time_s: None,
            }
        };
        let output_feedback = scenario.controller.kind == ControllerKind::OutputFeedback;
        let (tag_offset, noise, miss) = match scenario.position {
            PositionSpec::Exact => (
                None,
                Some(scenario.measurement.noise_std_m),
                Some(scenario.measurement.miss_probability),
            ),
            PositionSpec::NearestTag { offset_m, .. } => (
                Some(offset_m),
                Some(scenario.measurement.noise_std_m),
                Some(scenario.measurement.miss_probability),
            ),
            PositionSpec::Reader {
                offset_m,
                drop_frame_probability,
                ..
            } => (Some(offset_m), None, Some(drop_frame_probability)),
        };
        let encoder = match scenario.plant {
            PlantSpec::Unicycle { .. } => None,
            PlantSpec::DiffDrive {
                encoder_counts_per_rev,
                ..
            } => Some(encoder_counts_per_rev),
        };
        Self {
            index: v.index,
            seed: v.sweep_seed,
            start_x_m: scenario.initial.x_m,
            start_y_m: scenario.initial.y_m,
            heading_rad: scenario.initial.heading_rad,
            estimate_cos: output_feedback.then_some(scenario.initial.estimate_cos),
            estimate_sin: output_feedback.then_some(scenario.initial.estimate_sin),
            tag_offset_x_m: tag_offset.map(|o| o[0]),
            tag_offset_y_m: tag_offset.map(|o| o[1]),
            encoder_counts_per_rev: encoder,
            position_noise_std_m: noise,
            read_miss_probability: miss.filter(|_| output_feedback),
            initial_distance_m: result.records.first().map_or(f64::NAN, |r| r.error_m),
            converged: convergence.converged,
            time_to_converge_s: convergence.time_s,
            max_error_m: s.max_error_m,
            mean_error_m: s.mean_error_m,
            rms_error_m: s.rms_error_m,
            final_error_m: s.final_error_m,
            non_finite_ticks: s.non_finite_ticks,
            route: s.route.as_ref().map(|r| RouteRun {
                done: r.done,
                stops_missed: r.stops_missed,
                max_stop_position_error_m: r.max_stop_position_error_m,
                max_stop_heading_error_deg: r.max_stop_heading_error_deg,
                max_cross_track_error_m: r.max_cross_track_error_m,
                time_ratio: r.time_ratio,
            }),
        }
    }
}

/// How many runs, from which seed, on how many threads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SweepOptions {
    /// Number of runs `N` (indices `0 .. N`).
    pub runs: u64,
    /// The sweep's seed `S`.
    pub seed: u64,
    /// Worker threads; 0: one per CPU.
    pub threads: usize,
}

/// `p50`, `p90`, `p99` and the maximum of a quantity over the runs
/// (nearest rank: the `⌈p·n⌉`-th smallest value).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Percentiles {
    /// Median.
    pub p50: f64,
    /// 90th percentile.
    pub p90: f64,
    /// 99th percentile.
    pub p99: f64,
    /// Largest.
    pub max: f64,
}

impl Percentiles {
    /// Of `values` (NaN counts as the largest).
    #[must_use]
    pub fn of(values: impl IntoIterator<Item = f64>) -> Self {
        let mut v: Vec<f64> = values
            .into_iter()
            .map(|x| if x.is_nan() { f64::INFINITY } else { x })
            .collect();
        v.sort_by(f64::total_cmp);
        let rank = |p: f64| {
            if v.is_empty() {
                return f64::NAN;
            }
            let k = (p * v.len() as f64).ceil() as usize;
            v[k.clamp(1, v.len()) - 1]
        };
        Self {
            p50: rank(0.5),
            p90: rank(0.9),
            p99: rank(0.99),
            max: rank(1.0),
        }
    }
}

/// A run, by what reproduces it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct RunId {
    /// The sweep's seed.
    pub seed: u64,
    /// The run's index.
    pub index: u64,
}

/// The slowest run to converge.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SlowestRun {
    /// The run's index.
    pub index: u64,
    /// The sweep's seed.
    pub seed: u64,
    /// Its time to converge, s.
    pub time_to_converge_s: f64,
    /// Its initial distance to the reference, m.
    pub initial_distance_m: f64,
}

/// The figures of a sweep (`summary.json`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SweepSummary {
    /// The swept scenario.
    pub scenario: String,
    /// Plant, controller (estimator + law) and position source.
    pub setup: String,
    /// The sweep's seed `S`.
    pub seed: u64,
    /// Number of runs.
    pub runs: u64,
    /// Simulated time per run, s.
    pub duration_s: f64,
    /// Control period, s.
    pub period_s: f64,
    /// Error statistics window start, s.
    pub transient_s: f64,
    /// What was varied, and the convergence criterion.
    pub plan: SweepPlan,
    /// Runs that converged.
    pub converged: u64,
    /// `converged / runs`.
    pub converged_fraction: f64,
    /// The slowest converged run.
    pub slowest: Option<SlowestRun>,
    /// Runs that did not converge.
    pub not_converged: Vec<RunId>,
    /// Runs with a non-finite value.
    pub non_finite_runs: u64,
    /// Initial distance to the reference over the runs, m.
    pub initial_distance_m: Percentiles,
    /// Per-run largest error after the transient, over the runs, m.
    pub max_error_m: Percentiles,
    /// Per-run mean error after the transient, over the runs, m.
    pub mean_error_m: Percentiles,
    /// Per-run final error, over the runs, m.
    pub final_error_m: Percentiles,
    /// A route sweep's figures.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub route: Option<RouteSweepSummary>,
}

impl SweepSummary {
    fn of(
        scenario: &Scenario,
        setup_label: String,
        setup: &Setup,
        plan: SweepPlan,
        seed: u64,
        rows: &[SweepRun],
    ) -> Self {
        let converged = rows.iter().filter(|r| r.converged).count() as u64;
        let slowest = rows
            .iter()
            .filter_map(|r| r.time_to_converge_s.map(|t| (t, r)))
            // Ties: the lowest index.
            .max_by(|a, b| a.0.total_cmp(&b.0).then(b.1.index.cmp(&a.1.index)))
            .map(|(t, r)| SlowestRun {
                index: r.index,
                seed: r.seed,
                time_to_converge_s: t,
                initial_distance_m: r.initial_distance_m,
            });
        Self {
            scenario: scenario.name.clone(),
            setup: setup_label,
            seed,
            runs: rows.len() as u64,
            duration_s: f64::from(setup.ticks) * setup.period_s,
            period_s: setup.period_s,
            transient_s: setup.transient_s,
            plan,
            converged,
            converged_fraction: if rows.is_empty() {
                f64::NAN
            } else {
                converged as f64 / rows.len() as f64
            },
            slowest,
            not_converged: rows
                .iter()
                .filter(|r| !r.converged)
                .map(|r| RunId {
                    seed: r.seed,
                    index: r.index,
                })
                .collect(),
            non_finite_runs: rows.iter().filter(|r| r.non_finite_ticks > 0).count() as u64,
            initial_distance_m: Percentiles::of(rows.iter().map(|r| r.initial_distance_m)),
            max_error_m: Percentiles::of(rows.iter().map(|r| r.max_error_m)),
            mean_error_m: Percentiles::of(rows.iter().map(|r| r.mean_error_m)),
            final_error_m: Percentiles::of(rows.iter().map(|r| r.final_error_m)),
            route: RouteSweepSummary::of(rows),
        }
    }
}

/// Everything a sweep produced.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepResult {
    /// One row per run, in index order.
    pub rows: Vec<SweepRun>,
    /// The figures.
    pub summary: SweepSummary,
}

/// The plan of `scenario`'s `[sweep]` table, or the defaults without one.
///
/// # Errors
/// The scenario's validation error.
pub fn plan_of(scenario: &Scenario) -> Result<(Setup, SweepPlan), ScenarioError> {
    let setup = scenario.validate()?;
    let plan = match setup.sweep {
        Some(plan) => plan,
        None => SweepPlan::new(&SweepSpec::default(), scenario, &setup)?,
    };
    Ok((setup, plan))
}

/// Runs one variation through [`run`], keeping its records.
///
/// # Errors
/// The varied scenario's validation error (the plan's checks make it
/// unexpected).
pub fn run_variation(
    base: &Scenario,
    plan: &SweepPlan,
    sweep_seed: u64,
    index: u64,
) -> anyhow::Result<(Scenario, RunResult, SweepRun)> {
    let variation = plan.variation(base, sweep_seed, index);
    let scenario = variation.apply(base);
    let result = run(&scenario, |_, _| {})
        .map_err(|e| anyhow::anyhow!("run {index} of the sweep with seed {sweep_seed}: {e}"))?;
    let row = SweepRun::new(&variation, &scenario, &result, plan);
    Ok((scenario, result, row))
}

/// Runs `options.runs` variations of `scenario` in parallel; `progress` is
/// called once per finished run (from the worker threads).
///
/// # Errors
/// The scenario's validation error, a thread pool that cannot start, or
/// the first run that fails.
pub fn run_sweep(
    scenario: &Scenario,
    options: &SweepOptions,
    progress: &(dyn Fn() + Sync),
) -> anyhow::Result<SweepResult> {
    run_indices(scenario, options, 0..options.runs, progress)
}

/// Runs only `shard`'s share of the indices `0 .. options.runs` (see
/// [`shard::Shard::indices`]): the rows the whole sweep has for them, and
/// the figures of those rows alone.
///
/// # Errors
/// As [`run_sweep`].
pub fn run_sweep_shard(
    scenario: &Scenario,
    options: &SweepOptions,
    shard: shard::Shard,
    progress: &(dyn Fn() + Sync),
) -> anyhow::Result<SweepResult> {
    run_indices(scenario, options, shard.indices(options.runs), progress)
}

/// Runs the variations `indices` of `scenario` in parallel.
fn run_indices(
    scenario: &Scenario,
    options: &SweepOptions,
    indices: std::ops::Range<u64>,
    progress: &(dyn Fn() + Sync),
) -> anyhow::Result<SweepResult> {
    let (setup, plan) = plan_of(scenario)?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(options.threads)
        .build()?;
    let rows = pool.install(|| {
        indices
            .into_par_iter()
            .map(|index| {
                let (_, _, row) = run_variation(scenario, &plan, options.seed, index)?;
                progress();
                Ok(row)
            })
            .collect::<anyhow::Result<Vec<SweepRun>>>()
    })?;
    Ok(result_of(scenario, &setup, plan, options.seed, rows))
}

/// The result of a sweep of `scenario` with seed `seed` that produced
/// `rows` (in index order): the figures [`run_sweep`] computes, from rows
/// that were run elsewhere (the shards of [`shard::merge_shards`]).
///
/// # Errors
/// The scenario's validation error.
pub fn summarize(
    scenario: &Scenario,
    seed: u64,
    rows: Vec<SweepRun>,
) -> Result<SweepResult, ScenarioError> {
    let (setup, plan) = plan_of(scenario)?;
    Ok(result_of(scenario, &setup, plan, seed, rows))
}

fn result_of(
    scenario: &Scenario,
    setup: &Setup,
    plan: SweepPlan,
    seed: u64,
    rows: Vec<SweepRun>,
) -> SweepResult {
    let summary = SweepSummary::of(scenario, setup_label(setup), setup, plan, seed, &rows);
    SweepResult { rows, summary }
}

/// "plant, controller, position" as a run's summary names them.
fn setup_label(setup: &Setup) -> String {
    let l = crate::report::SetupLabels::of(setup);
    format!(
        "{} plant, {}, position {}",
        l.plant, l.controller, l.position_source
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::DEFAULT_START_RADIUS_M;

    const BASE: &str = r#"
        name = "t"
        duration_s = 20.0
        transient_s = 10.0
        [reference]
        kind = "figure_eight"
        [position]
        kind = "nearest_tag"
    "#;

    fn scenario(extra: &str) -> Result<Scenario, ScenarioError> {
        Scenario::from_toml_str(&format!("{BASE}\n{extra}\n"))
    }

    #[test]
    fn refuses_what_cannot_apply_naming_the_field() {
        let cases = [
            (
                "[sweep]\nencoder_counts_per_rev = [512]",
                "sweep.encoder_counts_per_rev",
            ),
            (
                "[sweep]\nstart_radius_m = [5.0, 1.0]",
                "sweep.start_radius_m",
            ),
            (
                "[sweep]\nstart_radius_m = [0.0, 1e4]",
                "sweep.start_radius_m",
            ),
            (
                "[sweep]\nread_miss_probability = [0.0, 1.5]",
                "sweep.read_miss_probability",
            ),
            ("[sweep]\nconverge_hold_s = 20.0", "sweep.converge_hold_s"),
            (
                "[sweep]\nconverge_threshold_m = 0.0",
                "sweep.converge_threshold_m",
            ),
            (
                "[controller]\nkind = \"state_feedback\"\n[sweep]\nobserver_start = \"zero\"",
                "sweep.observer_start",
            ),
            (
                "[controller]\nkind = \"state_feedback\"\n[sweep]\nread_miss_probability = [0.1, 0.1]",
                "sweep.read_miss_probability",
            ),
            (
                "[plant]\nkind = \"diff_drive\"\n[sweep]\nobserver_start = \"unit_disc\"",
                "sweep.observer_start",
            ),
            (
                "[plant]\nkind = \"diff_drive\"\n[sweep]\nencoder_counts_per_rev = []",
                "sweep.encoder_counts_per_rev",
            ),
        ];
        for (extra, field) in cases {
            let e = scenario(extra).unwrap_err();
            assert_eq!(e.field(), Some(field), "{extra}: {e}");
        }
        let exact = BASE.replace("nearest_tag", "exact");
        let e =
            Scenario::from_toml_str(&format!("{exact}\n[sweep]\ntag_offset = true\n")).unwrap_err();
        assert_eq!(e.field(), Some("sweep.tag_offset"), "{e}");
        let reader = BASE.replace("nearest_tag", "reader");
        let e = Scenario::from_toml_str(&format!(
            "{reader}\n[sweep]\nposition_noise_std_m = [0.0, 0.01]\n"
        ))
        .unwrap_err();
        assert_eq!(e.field(), Some("sweep.position_noise_std_m"), "{e}");
        let e = scenario("[sweep]\nspeed = 1").unwrap_err();
        assert!(e.to_string().contains("speed"), "{e}");
    }

    #[test]
    fn defaults_fill_in_from_the_scenario() {
        let s = scenario("").unwrap();
        let (_, plan) = plan_of(&s).unwrap();
        assert_eq!(plan.start_radius_m, DEFAULT_START_RADIUS_M);
        assert_eq!(plan.tag_offset_cell_m, Some(0.1));
        assert_eq!(plan.converge_threshold_m, 0.3);
        assert!((plan.converge_hold_s - 4.0).abs() < 1e-9);
        let with = scenario("[sweep]\nposition_noise_std_m = [0.0, 0.02]").unwrap();
        let plan = with.validate().unwrap().sweep.unwrap();
        assert!((plan.converge_threshold_m - 0.36).abs() < 1e-12);
        // Round trip of the table through TOML.
        let again = Scenario::from_toml_str(&with.to_toml_string().unwrap()).unwrap();
        assert_eq!(again, with);
    }

    #[test]
    fn variations_stay_in_their_ranges_and_depend_on_seed_and_index_only() {
        let s = scenario(
            "[sweep]\nstart_radius_m = [2.0, 3.0]\nobserver_start = \"unit_disc\"\n\
             position_noise_std_m = [0.01, 0.02]\nread_miss_probability = [0.0, 0.5]",
        )
        .unwrap();
        let plan = s.validate().unwrap().sweep.unwrap();
        let [rx, ry] = plan.reference_start_m;
        for i in 0..200 {
            let v = plan.variation(&s, 7, i);
            let r = (v.start_m[0] - rx).hypot(v.start_m[1] - ry);
            assert!((2.0 - 1e-9..=3.0 + 1e-9).contains(&r), "{r}");
            assert!(v.heading_rad > -PI && v.heading_rad <= PI);
            assert!(v.estimate[0].hypot(v.estimate[1]) <= 1.0);
            let [ox, oy] = v.tag_offset_m.unwrap();
            assert!((0.0..0.1).contains(&ox) && (0.0..0.1).contains(&oy));
            assert!((0.01..=0.02).contains(&v.position_noise_std_m.unwrap()));
            assert!((0.0..=0.5).contains(&v.read_miss_probability.unwrap()));
            assert_eq!(v, plan.variation(&s, 7, i));
            assert_ne!(v.start_m, plan.variation(&s, 8, i).start_m);
            let applied = v.apply(&s);
            assert!(applied.sweep.is_none());
            assert_eq!(
                applied.measurement.noise_std_m,
                v.position_noise_std_m.unwrap()
            );
        }
        // Varying more fields does not move the starts.
        let fewer = scenario("[sweep]\nstart_radius_m = [2.0, 3.0]").unwrap();
        let fewer_plan = fewer.validate().unwrap().sweep.unwrap();
        assert_eq!(
            fewer_plan.variation(&fewer, 7, 3).start_m,
            plan.variation(&s, 7, 3).start_m
        );
    }

    fn record(t_s: f64, error_m: f64) -> Record {
        Record {
            tick: 0,
            t_s,
            x_m: 0.0,
            y_m: 0.0,
            theta_rad: 0.0,
            ref_x_m: 0.0,
            ref_y_m: 0.0,
            est_x_m: None,
            est_y_m: None,
            est_cos: None,
            est_sin: None,
            est_theta_rad: None,
            heading_error_rad: None,
            v_cmd_m_s: 0.0,
            omega_cmd_rad_s: 0.0,
            left_duty: None,
            right_duty: None,
            fix: true,
            mode: crate::report::Mode::Tracking,
            error_m,
        }
    }

    #[test]
    fn convergence_is_the_last_entry_below_the_threshold_held_to_the_end() {
        let errors = [5.0, 0.01, 0.2, 0.04, 0.03, 0.02, 0.01];
        let records: Vec<Record> = errors
            .iter()
            .enumerate()
            .map(|(k, &e)| record(k as f64, e))
            .collect();
        let c = convergence(&records, 0.05, 3.0);
        assert_eq!(
            c,
            Convergence {
                converged: true,
                time_s: Some(3.0)
            }
        );
        assert!(!convergence(&records, 0.05, 3.5).converged);
        assert_eq!(convergence(&records, 10.0, 6.0).time_s, Some(0.0));
        let mut bad = records.clone();
        bad[6].error_m = f64::NAN;
        assert!(!convergence(&bad, 0.05, 0.0).converged);
    }

    #[test]
    fn percentiles_take_the_nearest_rank() {
        let p = Percentiles::of((1..=100).map(f64::from));
        assert_eq!((p.p50, p.p90, p.p99, p.max), (50.0, 90.0, 99.0, 100.0));
        let p = Percentiles::of([3.0, f64::NAN, 1.0]);
        assert_eq!((p.p50, p.max), (3.0, f64::INFINITY));
    }
}
