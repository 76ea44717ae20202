//! The core's estimator, law and sensor specs as a scenario chooses
//! them.

use wmr_core::control::spec::LawSpec;
use wmr_core::estimation::spec::{EstimatorSpec, SensorSpec};

use crate::scenario::defaults;
use crate::scenario::error::ScenarioError;
use crate::scenario::schema::Scenario;
use crate::scenario::tables::{ControllerKind, PlantSpec, PositionSpec, ReaderModeSpec};

use super::f;

impl Scenario {
    /// The core's estimator spec, as the scenario chose it; paper 002's and
    /// the fusion estimator only with output feedback, the fusion
    /// estimator only on a tag grid read without added noise. The core
    /// checks its values.
    pub(super) fn estimator_spec(&self) -> Result<EstimatorSpec, ScenarioError> {
        match (self.estimator, self.controller.kind) {
            (EstimatorSpec::HeadingObserver, _) => {}
            (_, ControllerKind::StateFeedback) => {
                return Err(ScenarioError::invalid(
                    "estimator",
                    "state feedback measures the heading: no estimator runs",
                ));
            }
            (EstimatorSpec::Fusion(_), ControllerKind::OutputFeedback) => {
                if matches!(self.position, PositionSpec::Exact) {
                    return Err(ScenarioError::invalid(
                        "estimator.fusion",
                        "the fusion estimator models tag reads: use position nearest_tag or reader",
                    ));
                }
                if self.measurement.noise_std_m > 0.0 {
                    return Err(ScenarioError::invalid(
                        "measurement.noise_std_m",
                        "the fusion estimator's tag model needs fixes on the tag grid (no added noise)",
                    ));
                }
            }
            // Any other estimator needs nothing of the simulator.
            (_, ControllerKind::OutputFeedback) => {}
        }
        Ok(self.estimator)
    }
}

impl Scenario {
    /// What the estimator knows of the sensors: the plant's track width and
    /// count quantization, the floor's spacing, the reader's range and
    /// where its antenna is (unless `antenna_offset_compensated = false`).
    pub(super) fn sensor_spec(&self) -> SensorSpec {
        let antenna_ahead_m = match self.position {
            PositionSpec::Reader {
                antenna_offset_m,
                antenna_offset_compensated: true,
                ..
            } => antenna_offset_m,
            _ => 0.0,
        };
        let (spacing_m, read_radius_m) = match self.position {
            PositionSpec::NearestTag { spacing_m, .. } => (spacing_m, 0.0),
            PositionSpec::Reader {
                spacing_m,
                mode: ReaderModeSpec::Paper,
                ..
            } => (spacing_m, 0.0),
            PositionSpec::Reader {
                spacing_m,
                mode: ReaderModeSpec::Range,
                read_radius_m,
                ..
            } => (spacing_m, read_radius_m),
            // No tags: the fusion estimator is refused above.
            PositionSpec::Exact => (0.0, 0.0),
        };
        // A tag map has no grid spacing (as in the robot's flash image).
        let spacing_m = if self.floor_tags.is_empty() {
            spacing_m
        } else {
            0.0
        };
        let (track_width_m, floor_m2) = match self.plant {
            PlantSpec::DiffDrive {
                wheel_radius_m,
                track_width_m,
                encoder_counts_per_rev,
                ..
            } => {
                let quantum = wheel_radius_m * std::f64::consts::TAU
                    / f64::from(encoder_counts_per_rev.max(1));
                (track_width_m, quantum * quantum / 12.0)
            }
            // The unicycle's odometry is exact: only the noise model's
            // geometry matters, taken as the default robot's.
            PlantSpec::Unicycle { .. } => (defaults::track_width_m(), 1e-9),
        };
        SensorSpec {
            track_width_m: f(track_width_m),
            wheel_variance_floor_m2: f(floor_m2),
            tag_spacing_m: f(spacing_m),
            read_radius_m: f(read_radius_m),
            antenna_offset_m: [f(antenna_ahead_m), 0.0],
        }
    }
}

impl Scenario {
    /// The core's law spec; paper 002's only with output feedback. The
    /// core checks its values.
    pub(super) fn law_spec(&self) -> Result<LawSpec, ScenarioError> {
        match (self.controller.law, self.controller.kind) {
            (LawSpec::Saturated, _) | (_, ControllerKind::OutputFeedback) => {
                Ok(self.controller.law)
            }
            (_, ControllerKind::StateFeedback) => Err(ScenarioError::invalid(
                "controller.law",
                "selects the output-feedback law: use it with kind = \"output_feedback\"",
            )),
        }
    }
}
