//! Refusals of the core's spec builder, named by the file's key and
//! value.

use wmr_core::control::saturated::GainError;
use wmr_core::drive::DriveConfigError;
use wmr_core::estimation::heading_observer::ObserverConfigError;
use wmr_core::pilot::spec::{SpecError, SpecSection};
use wmr_core::pilot::tracker::TrackerConfigError;

use crate::scenario::error::{ScenarioError, shown};
use crate::scenario::schema::Scenario;

/// A refusal of the core's spec builder, named by the scenario key it came
/// from, in the core's own words (which name the field and the rule), with
/// the key's value in `scenario` where the key is a value rather than a
/// table.
pub(super) fn spec_refusal(e: SpecError, scenario: &Scenario) -> ScenarioError {
    // An estimator's and a law's tables carry their spec's key.
    let table;
    let field = match e.section() {
        SpecSection::Trajectory => "reference",
        SpecSection::Estimator(key) => {
            let field = match e {
                SpecError::Estimator(inner) => inner.field_key(),
                _ => None,
            };
            table = match field {
                Some(field) => format!("estimator.{key}.{field}"),
                None => format!("estimator.{key}"),
            };
            &table
        }
        SpecSection::Law(key) => {
            let field = match e {
                SpecError::Law(inner) => inner.field_key(),
                _ => None,
            };
            table = match field {
                Some(field) => format!("controller.law.{key}.{field}"),
                None => format!("controller.law.{key}"),
            };
            &table
        }
        // The sensor facts come from the plant and the floor.
        SpecSection::Sensors | SpecSection::TagGrid => "position",
        SpecSection::Drive => "drive",
        SpecSection::SpeedObserver => "drive.speed_observer",
        SpecSection::Pilot => "plant",
        SpecSection::Build => "estimator",
        SpecSection::Tracker => match e {
            SpecError::Gains(GainError::K1) => "controller.k1",
            SpecError::Gains(GainError::K2) => "controller.k2",
            SpecError::Gains(GainError::K3) => "controller.k3",
            SpecError::Observer(ObserverConfigError::Gain) => "observer.gain_per_m",
            SpecError::Observer(ObserverConfigError::MinSpeed) => "observer.min_speed_m_s",
            SpecError::Observer(_) => "observer",
            SpecError::Tracker(TrackerConfigError::FailsafeDecel) => "failsafe.decel_m_s2",
            SpecError::Tracker(TrackerConfigError::FixTimeout) => "failsafe.fix_timeout_s",
            SpecError::Tracker(TrackerConfigError::Period) => "period_s",
            _ => "failsafe",
        },
    };
    let field = match e {
        SpecError::Drive(DriveConfigError::MaxWheelSpeed) => "drive.max_wheel_speed_rad_s",
        SpecError::Drive(DriveConfigError::MaxWheelAccel) => "drive.max_wheel_accel_rad_s2",
        SpecError::Drive(DriveConfigError::Period)
        | SpecError::Observer(ObserverConfigError::Period)
        | SpecError::Tracker(TrackerConfigError::Period) => "period_s",
        _ => field,
    };
    let mut reason = match core::error::Error::source(&e) {
        Some(inner) => format!("refused by the core: {inner}"),
        None => format!("refused by the core: {e}"),
    };
    if let Some(value) = scenario.value_at(field) {
        let value = match value {
            toml::Value::Float(v) => shown(v),
            other => other.to_string(),
        };
        reason.push_str(&format!(" (got {value})"));
    }
    ScenarioError::invalid(field, reason)
}

impl Scenario {
    /// The value of the dotted key `path` as this scenario holds it (its
    /// defaults filled in), unless the key is a table or absent.
    pub(super) fn value_at(&self, path: &str) -> Option<toml::Value> {
        let mut value = toml::Value::try_from(self).ok()?;
        for key in path.split('.') {
            value = value.get(key)?.clone();
        }
        (!value.is_table()).then_some(value)
    }
}
