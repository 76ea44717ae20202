//! The `[sweep]` table of a scenario (what `firmware-sim sweep` varies:
//! [`SweepSpec`]) and its validated form, the [`SweepPlan`] a
//! [`Setup`](super::Setup) carries. The sweep itself (variations, runs,
//! statistics) builds on these.

use serde::{Deserialize, Serialize};

/// How the initial heading is chosen.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default, schemars::JsonSchema,
)]
#[serde(rename_all = "snake_case")]
pub enum HeadingSweep {
    /// Uniform in (−π, π].
    #[default]
    Any,
    /// The scenario's `initial.heading_rad`.
    Scenario,
}

/// How the observer's initial estimate `(ẑ3, ẑ4)` is chosen.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default, schemars::JsonSchema,
)]
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
/// ([`ScenarioError::Invalid`](super::ScenarioError::Invalid) naming
/// `sweep.<field>`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default, schemars::JsonSchema)]
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
/// [`SweepPlan`] and the [`Setup`](super::Setup) holding it stay `Copy`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EncoderChoices {
    pub(super) values: [u32; MAX_ENCODER_CHOICES],
    pub(super) len: usize,
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
