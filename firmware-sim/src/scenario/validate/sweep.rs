//! The `[sweep]` table's plan.

use crate::scenario::error::{ScenarioError, non_negative, positive, probability};
use crate::scenario::schema::Scenario;
use crate::scenario::sweep_spec::{
    DEFAULT_EXACT_THRESHOLD_M, DEFAULT_HOLD_FRACTION, DEFAULT_START_RADIUS_M,
    DEFAULT_THRESHOLD_SPACINGS, EncoderChoices, MAX_ENCODER_CHOICES, ObserverStart, SweepPlan,
    SweepSpec,
};
use crate::scenario::tables::ControllerKind;

use super::{PlantSetup, PositionSetup, Setup};

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
        let spacing_m = match &setup.position {
            PositionSetup::Exact => None,
            PositionSetup::NearestTag(floor) => Some(floor.spacing_m()),
            PositionSetup::Reader(floor, _) => floor.spacing_m(),
        };
        let tag_offset_cell_m = match (spec.tag_offset, spacing_m) {
            (Some(true), None) => {
                return Err(ScenarioError::invalid(
                    "sweep.tag_offset",
                    "position.kind = \"exact\" and a tag-map floor have no tag grid to offset",
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
