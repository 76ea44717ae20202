//! What may change while a pilot runs: law (27)–(28)'s gains and the
//! failsafe times (a ground station's parameters, `wmr-mavlink`).
//!
//! A [`TuningSpec`] holds the numbers, as a robot file states them
//! ([`crate::pilot::spec::PilotSpec`]'s `tracker.gains`,
//! `tracker.fix_timeout_ticks`, `tracker.max_fix_age_ticks`,
//! `tracker.failsafe_decel_m_s2`, `max_encoder_fault_ticks`).
//! [`TuningSpec::build`] checks each with the check a robot file's value
//! goes through ([`TrackingGains::new`],
//! [`TrackerConfig::check_fix_timeout`],
//! [`TrackerConfig::check_failsafe_decel`]; the fix age and the encoder
//! fault ticks take any count, as in a robot file) and refuses with the
//! same [`SpecError`]. The checked [`Tuning`] is applied by
//! [`crate::pilot::Pilot::retune`] (or
//! [`crate::pilot::tracker::OutputFeedbackTracker::retune`]) from the next
//! tick on: the gains bumplessly, the failsafe times at the next fix check.

use crate::control::saturated::TrackingGains;
use crate::pilot::spec::SpecError;
use crate::pilot::tracker::TrackerConfig;
// The types live beside the tracker that takes them, so that the tracker
// needs nothing from here; the checks here need the robot file's errors.
pub use crate::pilot::tracker::{Tuning, TuningSpec};

impl TuningSpec {
    /// The checked tuning.
    ///
    /// # Errors
    /// The first value refused, as a robot file's: [`SpecError::Gains`],
    /// then [`SpecError::Tracker`] (fix timeout, failsafe deceleration).
    pub fn build(&self) -> Result<Tuning, SpecError> {
        let gains = match self.gains {
            Some([k1, k2, k3]) => Some(TrackingGains::new(k1, k2, k3).map_err(SpecError::Gains)?),
            None => None,
        };
        let fix_timeout_ticks =
            TrackerConfig::check_fix_timeout(self.fix_timeout_ticks).map_err(SpecError::Tracker)?;
        let failsafe_decel_m_s2 = TrackerConfig::check_failsafe_decel(self.failsafe_decel_m_s2)
            .map_err(SpecError::Tracker)?;
        Ok(Tuning::checked(
            TuningSpec {
                gains: self.gains,
                fix_timeout_ticks,
                max_fix_age_ticks: self.max_fix_age_ticks,
                failsafe_decel_m_s2,
                max_encoder_fault_ticks: self.max_encoder_fault_ticks,
            },
            gains,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pilot::spec::PilotSpec;
    use crate::pilot::{Pilot, PilotConfig};

    /// The example pilot's tuning, as its configuration reports it.
    fn example() -> (PilotConfig, TuningSpec) {
        let config = PilotSpec::EXAMPLE.build().unwrap();
        let tuning = config.tuning();
        (config, tuning)
    }

    /// A configuration reports the robot file's numbers, and a tuning
    /// built from them changes nothing.
    #[test]
    fn the_tuning_of_a_configuration_is_its_spec() {
        let (config, tuning) = example();
        let spec = PilotSpec::EXAMPLE;
        assert_eq!(tuning.gains, Some(spec.tracker.gains));
        assert_eq!(tuning.fix_timeout_ticks, spec.tracker.fix_timeout_ticks);
        assert_eq!(tuning.max_fix_age_ticks, spec.tracker.max_fix_age_ticks);
        assert_eq!(tuning.failsafe_decel_m_s2, spec.tracker.failsafe_decel_m_s2);
        assert_eq!(tuning.max_encoder_fault_ticks, spec.max_encoder_fault_ticks);
        let mut retuned = config;
        retuned.retune(&tuning.build().unwrap());
        assert_eq!(retuned, config);
    }

    /// Each value is refused as the robot file's would be, with the same
    /// error.
    #[test]
    fn refusals_are_the_robot_files() {
        let (_, tuning) = example();
        type Tune = fn(&mut TuningSpec);
        type File = fn(&mut PilotSpec);
        let cases: [(Tune, File); 4] = [
            (
                |t| t.gains = Some([0.5, f32::NAN, 1.0]),
                |s| s.tracker.gains[1] = f32::NAN,
            ),
            (
                |t| t.gains = Some([0.5, 0.5, -1.0]),
                |s| s.tracker.gains[2] = -1.0,
            ),
            (
                |t| t.fix_timeout_ticks = 0,
                |s| s.tracker.fix_timeout_ticks = 0,
            ),
            (
                |t| t.failsafe_decel_m_s2 = 1e3,
                |s| s.tracker.failsafe_decel_m_s2 = 1e3,
            ),
        ];
        for (tune, file) in cases {
            let mut t = tuning;
            tune(&mut t);
            let mut s = PilotSpec::EXAMPLE;
            file(&mut s);
            assert_eq!(t.build().unwrap_err(), s.build().unwrap_err());
        }
    }

    /// A retuned pilot has the configuration a robot file with the new
    /// numbers builds.
    #[test]
    fn a_retuned_pilot_is_the_robot_file_with_its_numbers() {
        let (config, mut tuning) = example();
        tuning.gains = Some([0.2, 0.3, 0.4]);
        tuning.fix_timeout_ticks = 7;
        tuning.max_fix_age_ticks = 4;
        tuning.failsafe_decel_m_s2 = 1.5;
        tuning.max_encoder_fault_ticks = 9;
        let mut pilot = Pilot::new(config).unwrap();
        pilot.retune(&tuning.build().unwrap());
        let mut spec = PilotSpec::EXAMPLE;
        spec.tracker.gains = [0.2, 0.3, 0.4];
        spec.tracker.fix_timeout_ticks = 7;
        spec.tracker.max_fix_age_ticks = 4;
        spec.tracker.failsafe_decel_m_s2 = 1.5;
        spec.max_encoder_fault_ticks = 9;
        assert_eq!(*pilot.config(), spec.build().unwrap());
        assert_eq!(pilot.config().tuning(), tuning);
    }
}
