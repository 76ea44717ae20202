//! Arbitrary text into the simulator's scenario parser and validator
//! (`Scenario::from_toml_str`, which validates): an error is fine, a panic
//! is not. Nothing is simulated.
//!
//! Validation samples the reference over the whole run to size the floor
//! of tags (`reference_bounds`, one sample per `max(period_s, 0.05 s)`),
//! which is linear in `duration_s`: a valid scenario of a year would make
//! one input take seconds. Scenarios with more than `MAX_SAMPLES` samples
//! are parsed but not validated (the embedded ones have at most 9 600).
//!
//! Also: a schema error from `from_toml_str` is a parse error, and a
//! scenario that validates serializes back to TOML that parses and
//! validates again.

#![no_main]

use firmware_sim::scenario::{Scenario, ScenarioError};
use libfuzzer_sys::fuzz_target;

/// Most reference samples a validation may take here.
const MAX_SAMPLES: f64 = 20_000.0;

fn cheap_to_validate(s: &Scenario) -> bool {
    let samples = s.duration_s / s.period_s.max(0.05);
    // NaN: such a scenario is refused before sampling.
    samples.is_nan() || samples <= MAX_SAMPLES
}

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let parsed = match toml::from_str::<Scenario>(text) {
        Ok(s) => s,
        Err(_) => {
            let e = Scenario::from_toml_str(text).expect_err("the schema refused it");
            assert!(matches!(e, ScenarioError::Parse(_)), "{e:?}");
            return;
        }
    };
    if !cheap_to_validate(&parsed) {
        return;
    }
    let Ok(scenario) = Scenario::from_toml_str(text) else {
        return;
    };
    let again = scenario
        .to_toml_string()
        .expect("a parsed scenario serializes");
    let reparsed = Scenario::from_toml_str(&again)
        .unwrap_or_else(|e| panic!("its own TOML is refused: {e}\n{again}"));
    assert_eq!(
        reparsed.to_toml_string().as_deref().ok(),
        Some(again.as_str())
    );
});
