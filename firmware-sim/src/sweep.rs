//! Monte Carlo sweeps: many seeded variations of one scenario, run in
//! parallel through the ordinary [`run`], and their
//! convergence and error statistics.
//!
//! # What is varied
//! The scenario's optional `[sweep]` table ([`SweepSpec`]) names it; a
//! scenario without one is swept with the defaults (marked *default*):
//!
//! | field | what | applies to |
//! |---|---|---|
//! | `start_radius_m = [r_min, r_max]` | initial position uniform (by area) in the annulus around the reference's start, m; *default* `[0, 10]` | all |
//! | `initial_heading` | `"any"` (*default*): uniform in (−π, π]; `"scenario"`: `initial.heading_rad` | all |
//! | `observer_start` | `"scenario"` (*default*): `initial.estimate_*`; `"zero"`; `"unit_disc"`: `(ẑ3, ẑ4)` uniform in the unit disc | output feedback; `unit_disc` not on `diff_drive` (the `Pilot`'s observer starts at 0) |
//! | `tag_offset` | lattice offset uniform in one spacing cell; *default* on where there are tags | `nearest_tag`, `reader` |
//! | `encoder_counts_per_rev = [..]` | one of the listed resolutions, uniformly (at most [`MAX_ENCODER_CHOICES`]) | `diff_drive` |
//! | `position_noise_std_m = [lo, hi]` | std of Gaussian noise on each axis of the fix, uniform in the range, m | `exact`, `nearest_tag` |
//! | `read_miss_probability = [lo, hi]` | probability a tick's fix is missing, uniform in the range | output feedback: `exact`/`nearest_tag` (`measurement.miss_probability`), `reader` (`position.drop_frame_probability`) |
//!
//! A field that cannot apply to the scenario's plant, controller or
//! position source is refused when the scenario is validated
//! ([`ScenarioError::Invalid`] naming `sweep.<field>`).
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

pub mod output;

use std::f64::consts::{PI, TAU};

use rand::rngs::ChaCha8Rng;
use rand::{Rng as _, RngExt as _, SeedableRng as _};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::report::{Record, RunResult};
use crate::run::run;
use crate::scenario::{
    ControllerKind, PlantSetup, PlantSpec, PositionSetup, PositionSpec, Scenario, ScenarioError,
    Setup, non_negative, positive, probability,
};

/// How the initial heading is chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum HeadingSweep {
    /// Uniform in (−π, π].
    #[default]
    Any,
    /// The scenario's `initial.heading_rad`.
    Scenario,
}

/// How the observer's initial estimate `(ẑ3, ẑ4)` is chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum ObserverStart {
    /// The scenario's `initial.estimate_cos`, `initial.estimate_sin`.
    #[default]
    Scenario,
    /// `(0, 0)`: heading unknown.
    Zero,
    /// Uniform (by area) in the unit disc.
    UnitDisc,
}

/// The `[sweep]` table of a scenario: what `firmware-sim sweep` varies
/// (see the [module docs](self) for the defaults and what applies where).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct SweepSpec {
    /// Initial position uniform (by area) in the annulus `[r_min, r_max]`
    /// around the reference's start, m (default `[0, 10]`; `[0, 0]`: on
    /// the reference's start).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start_radius_m: Option<[f64; 2]>,
    /// Initial heading.
    #[serde(default)]
    pub initial_heading: HeadingSweep,
    /// Observer's initial estimate.
    #[serde(default)]
    pub observer_start: ObserverStart,
    /// Tag lattice offset uniform in one spacing cell (default: on with
    /// tags).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tag_offset: Option<bool>,
    /// Encoder resolutions to pick from, counts per wheel revolution.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub encoder_counts_per_rev: Option<Vec<u32>>,
    /// Range `[lo, hi]` of the position-noise std, m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub position_noise_std_m: Option<[f64; 2]>,
    /// Range `[lo, hi]` of the probability a tick's fix is missing.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub read_miss_probability: Option<[f64; 2]>,
    /// Convergence threshold `ε`, m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub converge_threshold_m: Option<f64>,
    /// How long the error must stay below `ε` before the end, s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub converge_hold_s: Option<f64>,
}

/// Most encoder resolutions a sweep picks from.
pub const MAX_ENCODER_CHOICES: usize = 8;

/// Encoder resolutions to pick from (a fixed-capacity list, so that a
/// [`SweepPlan`] and the [`Setup`] holding it stay `Copy`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EncoderChoices {
    values: [u32; MAX_ENCODER_CHOICES],
    len: usize,
}

impl EncoderChoices {
    /// The resolutions, counts per revolution.
    #[must_use]
    pub fn as_slice(&self) -> &[u32] {
        &self.values[..self.len]
    }
}

impl Serialize for EncoderChoices {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_seq(self.as_slice())
    }
}

/// A validated `[sweep]` table, resolved against its scenario: every
/// field applies, the defaults are filled in.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SweepPlan {
    /// The reference's position at `t = 0`, m.
    pub reference_start_m: [f64; 2],
    /// Annulus of initial positions around it, m.
    pub start_radius_m: [f64; 2],
    /// Initial heading.
    pub initial_heading: HeadingSweep,
    /// Observer's initial estimate.
    pub observer_start: ObserverStart,
    /// Tag spacing, m, when the lattice offset is varied within one cell.
    pub tag_offset_cell_m: Option<f64>,
    /// Encoder resolutions picked from (`diff_drive`).
    pub encoder_counts_per_rev: Option<EncoderChoices>,
    /// Range of the position-noise std, m.
    pub position_noise_std_m: Option<[f64; 2]>,
    /// Range of the fix-miss probability.
    pub read_miss_probability: Option<[f64; 2]>,
    /// Convergence threshold `ε`, m.
    pub converge_threshold_m: f64,
    /// Time the error must stay below `ε` before the end, s.
    pub converge_hold_s: f64,
}

/// Default annulus of initial positions, m.
pub const DEFAULT_START_RADIUS_M: [f64; 2] = [0.0, 10.0];
/// Default convergence threshold with the exact position, m.
pub const DEFAULT_EXACT_THRESHOLD_M: f64 = 0.05;
/// Default convergence threshold with tags, in tag spacings.
pub const DEFAULT_THRESHOLD_SPACINGS: f64 = 3.0;
/// Default hold below the threshold, as a fraction of the duration.
pub const DEFAULT_HOLD_FRACTION: f64 = 0.2;

fn range(field: &str, r: [f64; 2], max: Option<f64>) -> Result<[f64; 2], ScenarioError> {
    let lo = non_negative(field, r[0])?;
    let hi = non_negative(field, r[1])?;
    if lo > hi || max.is_some_and(|m| hi > m) {
        let bound = max.map(|m| format!(" ≤ {m}")).unwrap_or_default();
        return Err(ScenarioError::invalid(
            field,
            format!("must be [lo, hi] with 0 ≤ lo ≤ hi{bound} (got [{lo}, {hi}])"),
        ));
    }
    Ok([lo, hi])
}

impl SweepPlan {
    /// Validates `spec` against its scenario and the scenario's validated
    /// setup (called by [`Scenario::validate`]).
    ///
    /// # Errors
    /// [`ScenarioError::Invalid`] naming the `sweep.*` field that is out of
    /// range or cannot apply to this scenario.
    pub fn new(
        spec: &SweepSpec,
        scenario: &Scenario,
        setup: &Setup,
    ) -> Result<Self, ScenarioError> {
        let start = setup.trajectory.sample(0.0).position;
        let reference_start_m = [f64::from(start.x), f64::from(start.y)];
        let start_radius_m = range(
            "sweep.start_radius_m",
            spec.start_radius_m.unwrap_or(DEFAULT_START_RADIUS_M),
            None,
        )?;
        let output_feedback = setup.controller == ControllerKind::OutputFeedback;
        let diff_drive = matches!(setup.plant, PlantSetup::DiffDrive { .. });
        match spec.observer_start {
            ObserverStart::Scenario => {}
            _ if !output_feedback => {
                return Err(ScenarioError::invalid(
                    "sweep.observer_start",
                    "state_feedback runs no observer: remove it or use \"scenario\"",
                ));
            }
            ObserverStart::UnitDisc if diff_drive => {
                return Err(ScenarioError::invalid(
                    "sweep.observer_start",
                    "the diff_drive plant runs the core's Pilot, whose observer always starts at (0, 0)",
                ));
            }
            ObserverStart::Zero | ObserverStart::UnitDisc => {}
        }
        let spacing_m = match setup.position {
            PositionSetup::Exact => None,
            PositionSetup::NearestTag(floor) | PositionSetup::Reader(floor, _) => {
                Some(floor.spacing_m())
            }
        };
        let tag_offset_cell_m = match (spec.tag_offset, spacing_m) {
            (Some(true), None) => {
                return Err(ScenarioError::invalid(
                    "sweep.tag_offset",
                    "position.kind = \"exact\" has no tags to offset",
                ));
            }
            (Some(false), _) => None,
            (_, spacing) => spacing,
        };
        let encoder_counts_per_rev = match &spec.encoder_counts_per_rev {
            None => None,
            Some(_) if !diff_drive => {
                return Err(ScenarioError::invalid(
                    "sweep.encoder_counts_per_rev",
                    "only the diff_drive plant has encoders",
                ));
            }
            Some(list) => {
                if list.is_empty() || list.len() > MAX_ENCODER_CHOICES || list.contains(&0) {
                    return Err(ScenarioError::invalid(
                        "sweep.encoder_counts_per_rev",
                        format!(
                            "must list 1 to {MAX_ENCODER_CHOICES} resolutions, each ≥ 1 (got {list:?})"
                        ),
                    ));
                }
                let mut values = [0; MAX_ENCODER_CHOICES];
                values[..list.len()].copy_from_slice(list);
                Some(EncoderChoices {
                    values,
                    len: list.len(),
                })
            }
        };
        let position_noise_std_m = match spec.position_noise_std_m {
            None => None,
            Some(_) if matches!(setup.position, PositionSetup::Reader(..)) => {
                return Err(ScenarioError::invalid(
                    "sweep.position_noise_std_m",
                    "the reader's fixes are tag ids looked up in the grid: noise applies to the \
                     exact and nearest_tag sources only",
                ));
            }
            Some(r) => Some(range("sweep.position_noise_std_m", r, None)?),
        };
        let read_miss_probability = match spec.read_miss_probability {
            None => None,
            Some(_) if !output_feedback => {
                return Err(ScenarioError::invalid(
                    "sweep.read_miss_probability",
                    "state_feedback needs a position every tick (only output feedback dead-reckons)",
                ));
            }
            Some(r) => {
                let r = range("sweep.read_miss_probability", r, Some(1.0))?;
                probability("sweep.read_miss_probability", r[1])?;
                Some(r)
            }
        };
        let default_threshold = spacing_m.map_or(DEFAULT_EXACT_THRESHOLD_M, |s| {
            DEFAULT_THRESHOLD_SPACINGS * s
        }) + position_noise_std_m.map_or(0.0, |r| 3.0 * r[1]);
        // To the nanometre: 0.3, not 0.30000000000000004, in the outputs.
        let default_threshold = (default_threshold * 1e9).round() / 1e9;
        let converge_threshold_m = positive(
            "sweep.converge_threshold_m",
            spec.converge_threshold_m.unwrap_or(default_threshold),
        )?;
        let duration_s = f64::from(setup.ticks) * setup.period_s;
        let converge_hold_s = non_negative(
            "sweep.converge_hold_s",
            spec.converge_hold_s
                .unwrap_or(DEFAULT_HOLD_FRACTION * duration_s),
        )?;
        if converge_hold_s >= duration_s {
            return Err(ScenarioError::invalid(
                "sweep.converge_hold_s",
                format!("must be shorter than the run ({duration_s} s)"),
            ));
        }
        let plan = Self {
            reference_start_m,
            start_radius_m,
            initial_heading: spec.initial_heading,
            observer_start: spec.observer_start,
            tag_offset_cell_m,
            encoder_counts_per_rev,
            position_noise_std_m,
            read_miss_probability,
            converge_threshold_m,
            converge_hold_s,
        };
        plan.check_extreme_starts(scenario)?;
        Ok(plan)
    }

    /// Validates the scenario with the start at the annulus' extremes on
    /// each axis (the floor of tags must cover every start, and the floor
    /// is a rectangle, so these bound every run's).
    fn check_extreme_starts(&self, scenario: &Scenario) -> Result<(), ScenarioError> {
        let r = self.start_radius_m[1];
        let [x, y] = self.reference_start_m;
        for (dx, dy) in [(r, 0.0), (-r, 0.0), (0.0, r), (0.0, -r)] {
            let mut probe = scenario.clone();
            probe.sweep = None;
            probe.initial.x_m = x + dx;
            probe.initial.y_m = y + dy;
            probe.validate().map_err(|e| {
                ScenarioError::invalid(
                    "sweep.start_radius_m",
                    format!("a start {r} m from the reference's start is refused: {e}"),
                )
            })?;
        }
        Ok(())
    }

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
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
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
            PlantSpec::Unicycle => None,
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
    let (setup, plan) = plan_of(scenario)?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(options.threads)
        .build()?;
    let rows = pool.install(|| {
        (0..options.runs)
            .into_par_iter()
            .map(|index| {
                let (_, _, row) = run_variation(scenario, &plan, options.seed, index)?;
                progress();
                Ok(row)
            })
            .collect::<anyhow::Result<Vec<SweepRun>>>()
    })?;
    let summary = SweepSummary::of(
        scenario,
        setup_label(&setup),
        &setup,
        plan,
        options.seed,
        &rows,
    );
    Ok(SweepResult { rows, summary })
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
