//! Every key of a slip scenario file (`firmware-sim schema --slip`), from
//! the JSON Schema of [`SlipScenario`]'s types (`schemars`, from their
//! serde attributes and doc comments), so the list cannot drift from what
//! parses the file.

use serde_json::Value;

use crate::scenario::keys::{KeyDoc, keys_of};

use super::schema::SlipScenario;

/// The JSON Schema of a slip scenario file (draft 2020-12).
#[must_use]
pub fn slip_schema() -> Value {
    serde_json::to_value(schemars::schema_for!(SlipScenario)).unwrap_or(Value::Null)
}

/// Every key of a slip scenario file, in the order of the file's tables.
#[must_use]
pub fn slip_keys() -> Vec<KeyDoc> {
    keys_of(&slip_schema())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::keys::{markdown, unlisted_keys};
    use crate::slip::{EMBEDDED_SLIP, PARTICLE_COUNTS};

    fn find<'a>(keys: &'a [KeyDoc], key: &str) -> &'a KeyDoc {
        keys.iter()
            .find(|k| k.key == key)
            .unwrap_or_else(|| panic!("`{key}` not listed"))
    }

    /// Every key of every embedded slip scenario, arrays of tables walked
    /// into, is in the table: it is generated from what parses them.
    #[test]
    fn every_key_of_the_embedded_slip_scenarios_is_listed() {
        let unlisted = unlisted_keys(&slip_keys(), EMBEDDED_SLIP);
        assert!(unlisted.is_empty(), "not listed: {unlisted:?}");
        // A key no slip type parses would be reported.
        let wrong = unlisted_keys(&slip_keys(), &[("wrong", "[robot]\nwheel_m = 1.0")]);
        assert_eq!(wrong, ["wrong: robot.wheel_m"]);
    }

    /// Each key states its unit where it has one, its default where it
    /// may be left out, and the values it takes where only some parse or
    /// run.
    #[test]
    fn the_slip_table_states_units_defaults_and_choices() {
        let keys = slip_keys();
        for (key, unit) in [
            ("duration_s", "s"),
            ("period_s", "s"),
            ("robot.wheel_radius_m", "m"),
            ("robot.yaw_inertia_kg_m2", "kg m²"),
            ("gains.k1", "1/s"),
            ("slip.start_s", "s"),
            ("reference.segments.v_m_s", "m/s"),
            ("reference.segments.omega_rad_s", "rad/s"),
            ("initial.left_rad_s", "rad/s"),
            ("windows.during_slip_s", "s"),
        ] {
            assert_eq!(find(&keys, key).unit, unit, "{key}");
        }
        assert_eq!(find(&keys, "period_s").default.as_deref(), Some("0.005"));
        assert_eq!(find(&keys, "estimator").default.as_deref(), Some("\"ekf\""));
        assert!(find(&keys, "name").required);
        assert!(find(&keys, "controller").required);
        let start = find(&keys, "slip.start_s");
        assert!(start.required, "{start:?}");
        assert_eq!(start.applies_when.as_deref(), Some("each `[[slip]]`"));
        // The bounds `validate` checks.
        assert_eq!(find(&keys, "plant_substeps").kind, "integer ≥ 1");
        assert_eq!(find(&keys, "period_s").kind, "number > 0.0");
        assert_eq!(find(&keys, "slip.slip_ratio").kind, "number in [0.0, 1.0)");
        assert_eq!(
            find(&keys, "gains.initial_slip_estimate").kind,
            "number in [1.0, 20.0]"
        );
        let counts: Vec<String> = PARTICLE_COUNTS.iter().map(usize::to_string).collect();
        assert_eq!(
            find(&keys, "filter.particle_filter.particles").kind,
            counts.join(" | ")
        );
        let estimator = &find(&keys, "estimator").kind;
        for e in crate::slip::Estimator::ALL {
            assert!(
                estimator.contains(&format!("\"{}\"", e.name())),
                "{estimator}"
            );
        }
        // JSON has no infinity: the gate's default is in its meaning, not
        // a `null` that would say it has none.
        let gate = find(&keys, "filter.particle_filter.collapse_gate");
        assert!(gate.default.is_none() && !gate.required, "{gate:?}");
        assert!(gate.description.contains("`inf`"), "{gate:?}");
    }

    /// Every key that may be left out says its default (in the default
    /// column or, where JSON cannot state it, in its meaning), every
    /// default is a TOML value, and no meaning holds a rustdoc link (the table is for the file's
    /// writer).
    #[test]
    fn every_optional_slip_key_has_its_default() {
        for k in slip_keys() {
            assert!(
                k.required || k.default.is_some() || k.description.contains("default"),
                "{}: no default stated",
                k.key
            );
            if let Some(d) = &k.default {
                assert!(
                    toml::from_str::<toml::Table>(&format!("x = {d}")).is_ok(),
                    "{}: default {d} is no TOML value",
                    k.key
                );
            }
            assert!(
                !k.description.contains("](") && !k.description.contains("[`"),
                "{}: {}",
                k.key,
                k.description
            );
        }
        let md = markdown(&slip_keys());
        assert!(md.contains("| `slip.slip_ratio` |"), "{md}");
    }
}
