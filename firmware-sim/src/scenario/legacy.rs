//! Keys that moved, and where to: scenario files written before the
//! estimator and the law became the core's own spec types
//! (`wmr_core::pilot::spec::{EstimatorSpec, LawSpec}`) fail with an error
//! that names the new key instead of a bare `unknown field`.
//!
//! | old key | new key |
//! |---|---|
//! | `observer.kind = "paper_001"` | `estimator = "heading_observer"` (the default) |
//! | `observer.kind = "pose"`, `observer.pose_gains` | `[estimator.pose_observer]`, `gains` |
//! | `observer.kind = "fusion_ekf"` / `"fusion_ukf"` / `"fusion_particle_filter"` | `[estimator.fusion]`, `filter = "ekf"` / `"ukf"` / `"particle_filter"` |
//! | `observer.fusion_<key>` | `estimator.fusion.<key>` |
//! | `controller.law = "cascaded"`, `controller.c1`, `c2` | `[controller.law.cascaded]`, `c1_per_s`, `c2_per_s` |
//! | `controller.law = "heading_error_sine"`, `controller.a`, `c2`, `gamma` | `[controller.law.heading_error_sine]`, `a_s_per_m2`, `c2_per_s`, `gamma` |

/// Where the `[observer]` table's key that moved went, if `table` has one.
pub(super) fn observer_key(table: &toml::Table) -> Option<String> {
    if let Some(kind) = table.get("kind") {
        let new = match kind.as_str() {
            Some("paper_001") => "estimator = \"heading_observer\" (the default: remove the key)",
            Some("pose") => "[estimator.pose_observer] (its gains: `gains`)",
            Some("fusion_ekf") => "[estimator.fusion] with filter = \"ekf\" (the default)",
            Some("fusion_ukf") => "[estimator.fusion] with filter = \"ukf\"",
            Some("fusion_particle_filter") => {
                "[estimator.fusion] with filter = \"particle_filter\""
            }
            _ => {
                "the top-level `estimator` (\"heading_observer\", [estimator.pose_observer] or [estimator.fusion])"
            }
        };
        return Some(format!(
            "observer.kind moved: the estimator is chosen by {new}; [observer] keeps paper 001's \
             observer (5), gain_per_m and min_speed_m_s"
        ));
    }
    if table.contains_key("pose_gains") {
        return Some("observer.pose_gains moved to estimator.pose_observer.gains".into());
    }
    table.keys().find_map(|key| {
        let new = key.strip_prefix("fusion_")?;
        Some(format!("observer.{key} moved to estimator.fusion.{new}"))
    })
}

/// Where the `[controller]` table's key that moved went, if `table` has one.
pub(super) fn controller_key(table: &toml::Table) -> Option<String> {
    let law = table.get("law").and_then(toml::Value::as_str);
    match law {
        Some("cascaded") => {
            return Some(
                "controller.law = \"cascaded\" moved to the table [controller.law.cascaded] \
                 (gains c1_per_s, c2_per_s)"
                    .into(),
            );
        }
        Some("heading_error_sine") => {
            return Some(
                "controller.law = \"heading_error_sine\" moved to the table \
                 [controller.law.heading_error_sine] (a_s_per_m2, c2_per_s, gamma)"
                    .into(),
            );
        }
        _ => {}
    }
    let moved = [
        ("c1", "controller.law.cascaded.c1_per_s"),
        (
            "c2",
            "controller.law.cascaded.c2_per_s or controller.law.heading_error_sine.c2_per_s",
        ),
        ("a", "controller.law.heading_error_sine.a_s_per_m2"),
        ("gamma", "controller.law.heading_error_sine.gamma"),
    ];
    moved
        .iter()
        .find(|(old, _)| table.contains_key(*old))
        .map(|(old, new)| format!("controller.{old} moved to {new}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(text: &str) -> toml::Table {
        text.parse().unwrap()
    }

    #[test]
    fn every_moved_observer_key_names_its_new_key() {
        for (old, new) in [
            (
                "kind = \"fusion_ukf\"",
                "[estimator.fusion] with filter = \"ukf\"",
            ),
            ("kind = \"pose\"", "[estimator.pose_observer]"),
            ("kind = \"paper_001\"", "estimator = \"heading_observer\""),
            ("pose_gains = [1, 2, 3, 4]", "estimator.pose_observer.gains"),
            (
                "fusion_gate_sigma = 3.0",
                "observer.fusion_gate_sigma moved to estimator.fusion.gate_sigma",
            ),
            (
                "fusion_particle_seed = 3",
                "moved to estimator.fusion.particle_seed",
            ),
        ] {
            let message = observer_key(&table(old)).unwrap();
            assert!(message.contains(new), "{old}: {message}");
        }
        assert_eq!(observer_key(&table("gain_per_m = 0.6")), None);
    }

    #[test]
    fn every_moved_controller_key_names_its_new_key() {
        for (old, new) in [
            ("law = \"cascaded\"", "[controller.law.cascaded]"),
            (
                "law = \"heading_error_sine\"",
                "[controller.law.heading_error_sine]",
            ),
            ("c1 = 0.5", "controller.law.cascaded.c1_per_s"),
            ("a = 100.0", "controller.law.heading_error_sine.a_s_per_m2"),
            ("gamma = 0.9", "controller.law.heading_error_sine.gamma"),
        ] {
            let message = controller_key(&table(old)).unwrap();
            assert!(message.contains(new), "{old}: {message}");
        }
        assert_eq!(
            controller_key(&table("law = \"paper_001\"\nk1 = 0.1")),
            None
        );
    }
}
