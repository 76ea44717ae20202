//! Where the position comes from (the floor, the reader) and its
//! measurement noise.

use wmr_core::reference::Trajectory;

use crate::devices::{LinkFaults, ReaderConfig, ReaderMode};
use std::sync::Arc;

use wmr_core::devices::TagId;

use crate::tags::{Floor, FloorTags, MapFloor};

use crate::scenario::error::{
    ScenarioError, finite, in_range, non_negative, positive, probability,
};
use crate::scenario::schema::Scenario;
use crate::scenario::tables::{ControllerKind, MeasurementSpec, PositionSpec, ReaderModeSpec};
use wmr_core::plausible::{READ_RADIUS_M, TAG_SPACING_M};

use super::{PositionSetup, floor_point, reference_bounds, route_bounds};
use crate::scenario::route::RouteSetup;

impl Scenario {
    pub(super) fn position_setup(
        &self,
        trajectory: &Trajectory,
        route: Option<&RouteSetup>,
        duration_s: f64,
        period_s: f64,
    ) -> Result<PositionSetup, ScenarioError> {
        let floor =
            |spacing_m: f64, offset_m: [f64; 2], margin_m: f64, extent_m: Option<[f64; 4]>| {
                let spacing_m = in_range("position.spacing_m", spacing_m, TAG_SPACING_M, "m")?;
                floor_point("position.offset_m", offset_m)?;
                let (min, max) = match extent_m {
                    Some(e) => {
                        for v in e {
                            finite("position.extent_m", v)?;
                        }
                        ([e[0], e[1]], [e[2], e[3]])
                    }
                    None => {
                        let margin = non_negative("position.margin_m", margin_m)?;
                        let (mut lo, mut hi) = match route {
                            Some(route) => route_bounds(route),
                            None => reference_bounds(trajectory, duration_s, period_s),
                        };
                        lo = [lo[0].min(self.initial.x_m), lo[1].min(self.initial.y_m)];
                        hi = [hi[0].max(self.initial.x_m), hi[1].max(self.initial.y_m)];
                        (
                            [lo[0] - margin, lo[1] - margin],
                            [hi[0] + margin, hi[1] + margin],
                        )
                    }
                };
                FloorTags::covering(spacing_m, offset_m, min, max)
                    .map_err(|e| ScenarioError::invalid("position.extent_m", e.to_string()))
            };
        if !self.floor_tags.is_empty() && !matches!(self.position, PositionSpec::Reader { .. }) {
            return Err(ScenarioError::invalid(
                "floor_tags",
                "a tag map is read by a reader: position.kind = \"reader\"",
            ));
        }
        match self.position {
            PositionSpec::Exact => Ok(PositionSetup::Exact),
            PositionSpec::NearestTag {
                spacing_m,
                offset_m,
                margin_m,
                extent_m,
            } => Ok(PositionSetup::NearestTag(floor(
                spacing_m, offset_m, margin_m, extent_m,
            )?)),
            PositionSpec::Reader {
                spacing_m,
                offset_m,
                margin_m,
                extent_m,
                mode,
                read_radius_m,
                antenna_offset_m,
                // The core's business (`sensor_spec`).
                antenna_offset_compensated: _,
                baud,
                repeat_interval_s,
                corrupt_byte_probability,
                drop_frame_probability,
                seed,
            } => {
                let floor = if self.floor_tags.is_empty() {
                    Floor::Grid(floor(spacing_m, offset_m, margin_m, extent_m)?)
                } else {
                    let tags: Vec<_> = self
                        .floor_tags
                        .iter()
                        .map(|t| (TagId(t.id), [t.x_m, t.y_m]))
                        .collect();
                    if let Some(t) = self.floor_tags.iter().find(|t| t.id > TagId::MASK) {
                        return Err(ScenarioError::invalid(
                            "floor_tags",
                            format!("id {:#x} is wider than the reader's 40 bits", t.id),
                        ));
                    }
                    let map = MapFloor::new(&tags)
                        .map_err(|e| {
                            ScenarioError::invalid(
                                "floor_tags",
                                format!("refused by the core's tag map: {e}"),
                            )
                        })?
                        .ok_or_else(|| ScenarioError::invalid("floor_tags", "no tags"))?;
                    Floor::Map(Arc::new(map))
                };
                let mode = match mode {
                    ReaderModeSpec::Paper => ReaderMode::Paper,
                    ReaderModeSpec::Range => ReaderMode::Range {
                        read_radius_m: in_range(
                            "position.read_radius_m",
                            positive("position.read_radius_m", read_radius_m)?,
                            READ_RADIUS_M,
                            "m",
                        )?,
                        repeat_interval_s: positive(
                            "position.repeat_interval_s",
                            repeat_interval_s,
                        )?,
                    },
                };
                if baud == 0 {
                    return Err(ScenarioError::invalid("position.baud", "must be ≥ 1"));
                }
                Ok(PositionSetup::Reader(
                    floor,
                    ReaderConfig {
                        mode,
                        antenna_offset_m: finite("position.antenna_offset_m", antenna_offset_m)?,
                        baud,
                        faults: LinkFaults {
                            corrupt_byte_probability: probability(
                                "position.corrupt_byte_probability",
                                corrupt_byte_probability,
                            )?,
                            drop_frame_probability: probability(
                                "position.drop_frame_probability",
                                drop_frame_probability,
                            )?,
                            seed,
                        },
                        update_period_s: Some(period_s),
                    },
                ))
            }
        }
    }
}

impl Scenario {
    pub(super) fn measurement_setup(
        &self,
        position: &PositionSetup,
    ) -> Result<MeasurementSpec, ScenarioError> {
        let m = self.measurement;
        non_negative("measurement.noise_std_m", m.noise_std_m)?;
        probability("measurement.miss_probability", m.miss_probability)?;
        if matches!(position, PositionSetup::Reader(..)) && !m.is_clean() {
            return Err(ScenarioError::invalid(
                if m.noise_std_m == 0.0 {
                    "measurement.miss_probability"
                } else {
                    "measurement.noise_std_m"
                },
                "applies to the exact and nearest_tag sources only: the reader's fixes are tag ids \
                 looked up in the grid (for lost frames use position.drop_frame_probability)",
            ));
        }
        if self.controller.kind == ControllerKind::StateFeedback && m.miss_probability > 0.0 {
            return Err(ScenarioError::invalid(
                "measurement.miss_probability",
                "state_feedback needs a position every tick (only output feedback dead-reckons)",
            ));
        }
        Ok(m)
    }
}
