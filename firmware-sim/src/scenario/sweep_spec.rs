//! The `[sweep]` table of a scenario (what `firmware-sim sweep` varies:
//! [`SweepSpec`]) and its validated form, the [`SweepPlan`] a [`Setup`]
//! carries. The sweep itself (variations, runs, statistics) is
//! `crate::sweep`, which builds on these.

use serde::{Deserialize, Serialize};

use super::{
    ControllerKind, PlantSetup, PositionSetup, Scenario, ScenarioError, Setup, non_negative,
    positive, probability,
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

/// The `[sweep]` table of a scenario: what `firmware-sim sweep` varies.
///
/// The scenario's optional `[sweep]` table ([`SweepSpec`]) names it; a
/// scenario without one is swept with the defaults (marked *default*):
///
/// | field | what | applies to |
/// |---|---|---|
/// | `start_radius_m = [r_min, r_max]` | initial position uniform (by area) in the annulus around the reference's start, m; *default* `[0, 10]` | all |
/// | `initial_heading` | `"any"` (*default*): uniform in (−π, π]; `"scenario"`: `initial.heading_rad` | all |
/// | `observer_start` | `"scenario"` (*default*): `initial.estimate_*`; `"zero"`; `"unit_disc"`: `(ẑ3, ẑ4)` uniform in the unit disc | output feedback; `unit_disc` not on `diff_drive` (the `Pilot`'s observer starts at 0) |
/// | `tag_offset` | lattice offset uniform in one spacing cell; *default* on where there are tags | `nearest_tag`, `reader` |
/// | `encoder_counts_per_rev = [..]` | one of the listed resolutions, uniformly (at most [`MAX_ENCODER_CHOICES`]) | `diff_drive` |
/// | `position_noise_std_m = [lo, hi]` | std of Gaussian noise on each axis of the fix, uniform in the range, m | `exact`, `nearest_tag` |
/// | `read_miss_probability = [lo, hi]` | probability a tick's fix is missing, uniform in the range | output feedback: `exact`/`nearest_tag` (`measurement.miss_probability`), `reader` (`position.drop_frame_probability`) |
///
/// A field that cannot apply to the scenario's plant, controller or
/// position source is refused when the scenario is validated
/// ([`ScenarioError::Invalid`] naming `sweep.<field>`).
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
}
