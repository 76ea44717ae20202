//! Every key of a scenario file, with its type or allowed values, default,
//! unit and meaning (`firmware-sim schema`), generated from the types that
//! parse the file: their JSON Schema (`schemars`, from the serde
//! attributes and doc comments of [`Scenario`] and the core's specs), so
//! the list cannot drift from what is accepted.

use serde_json::{Map, Value};

use super::Scenario;

/// One key of a scenario file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct KeyDoc {
    /// Dotted path: `reference.radius_m`.
    pub key: String,
    /// When it applies (`reference.kind = "circle"`), if not always.
    pub applies_when: Option<String>,
    /// Its type, or the values it takes.
    pub kind: String,
    /// Its default, if it may be left out.
    pub default: Option<String>,
    /// Whether it must be given (where its table is).
    pub required: bool,
    /// Its unit, from its name (`_m`: m, `_rad_s`: rad/s, …).
    pub unit: &'static str,
    /// Its documentation.
    pub description: String,
}

/// The JSON Schema of a scenario file (draft 2020-12), for editors that
/// check TOML against one.
#[must_use]
pub fn scenario_schema() -> Value {
    serde_json::to_value(schemars::schema_for!(Scenario)).unwrap_or(Value::Null)
}

/// The JSON Schema of a robot file (draft 2020-12).
#[must_use]
pub fn robot_schema() -> Value {
    serde_json::to_value(schemars::schema_for!(super::robot::RobotFile)).unwrap_or(Value::Null)
}

/// Every key of a scenario file, in the order of the file's tables.
#[must_use]
pub fn scenario_keys() -> Vec<KeyDoc> {
    keys_of(&scenario_schema())
}

/// Every key of a robot file (`robot = "FILE"`, or a scenario's `[robot]`
/// table), in the order of the file's tables.
#[must_use]
pub fn robot_keys() -> Vec<KeyDoc> {
    keys_of(&robot_schema())
}

/// Every key of the TOML file a JSON Schema describes (its `$defs`
/// followed), in the order of the file's tables: the key table of any
/// file whose types derive `schemars::JsonSchema` (the slip scenario's
/// too).
#[must_use]
pub fn keys_of(schema: &Value) -> Vec<KeyDoc> {
    let defs = schema
        .get("$defs")
        .and_then(Value::as_object)
        .cloned()
        .unwrap_or_default();
    let mut keys = Vec::new();
    Walker {
        defs: &defs,
        keys: &mut keys,
    }
    .table("", schema, None);
    keys
}

/// The unit a key's documentation states (`Radius, m.`), if one of the
/// known ones follows a comma.
#[must_use]
pub fn unit_in(description: &str) -> Option<&'static str> {
    const UNITS: [&str; 19] = [
        "m²/m", "m/s²", "rad/s²", "s/m²", "m/s", "rad/s", "1/s", "1/m", "kg·m²", "kg m²", "N·m",
        "m²", "rad", "ms", "Hz", "kg", "Bd", "s", "m",
    ];
    description.match_indices(", ").find_map(|(i, sep)| {
        let rest = description.get(i + sep.len()..)?;
        UNITS.iter().copied().find(|u| {
            rest.strip_prefix(u).is_some_and(|after| {
                after.is_empty() || after.starts_with(['.', ' ', ',', ')', ';'])
            })
        })
    })
}

/// The unit a key's name states (the project's naming convention).
#[must_use]
pub fn unit_of(key: &str) -> &'static str {
    const SUFFIXES: [(&str, &str); 27] = [
        ("_deg_s2", "°/s²"),
        ("_deg_s", "°/s"),
        ("_deg", "°"),
        ("_nm_s_per_rad", "N·m·s/rad"),
        ("_duty_per_rad_s", "duty/(rad/s)"),
        ("_duty_per_rad", "duty/rad"),
        ("_kg_m2", "kg·m²"),
        ("_m2_per_m", "m²/m"),
        ("_m_s2", "m/s²"),
        ("_rad_s2", "rad/s²"),
        ("_s_per_m2", "s/m²"),
        ("_m_s", "m/s"),
        ("_rad_s", "rad/s"),
        ("_per_s", "1/s"),
        ("_per_m", "1/m"),
        ("_per_rev", "counts/rev"),
        ("_m2", "m²"),
        ("_kg", "kg"),
        ("_nm", "N·m"),
        ("_rad", "rad"),
        ("_hz", "Hz"),
        ("_ms", "ms"),
        ("_s", "s"),
        ("_m", "m"),
        ("baud", "Bd"),
        ("_bits", "bits"),
        ("_ticks", "ticks"),
    ];
    let name = key.rsplit('.').next().unwrap_or(key);
    SUFFIXES
        .iter()
        .find(|(suffix, _)| name.ends_with(suffix))
        .map_or("", |(_, unit)| unit)
}

struct Walker<'a> {
    defs: &'a Map<String, Value>,
    keys: &'a mut Vec<KeyDoc>,
}

impl Walker<'_> {
    /// `schema` with its `$ref` followed (its own description and default
    /// kept over the target's).
    fn resolve(&self, schema: &Value) -> Value {
        let Some(target) = schema
            .get("$ref")
            .and_then(Value::as_str)
            .and_then(|r| r.strip_prefix("#/$defs/"))
            .and_then(|name| self.defs.get(name))
        else {
            return schema.clone();
        };
        let mut merged = self.resolve(target);
        if let (Some(m), Some(own)) = (merged.as_object_mut(), schema.as_object()) {
            for (k, v) in own {
                if k != "$ref" {
                    m.insert(k.clone(), v.clone());
                }
            }
        }
        merged
    }

    /// The keys of a table schema under `prefix`.
    fn table(&mut self, prefix: &str, schema: &Value, applies_when: Option<&str>) {
        let schema = self.resolve(schema);
        let required: Vec<&str> = schema
            .get("required")
            .and_then(Value::as_array)
            .map(|r| r.iter().filter_map(Value::as_str).collect())
            .unwrap_or_default();
        let Some(properties) = schema.get("properties").and_then(Value::as_object) else {
            return;
        };
        for (name, sub) in properties {
            let key = if prefix.is_empty() {
                name.clone()
            } else {
                format!("{prefix}.{name}")
            };
            self.entry(&key, sub, applies_when, required.contains(&name.as_str()));
        }
    }

    /// One property: a leaf, a table, or a choice of variants.
    fn entry(&mut self, key: &str, sub: &Value, applies_when: Option<&str>, required: bool) {
        let own_description = text(sub);
        let default = sub.get("default");
        let schema = self.resolve(&without_null(&self.resolve(sub)));
        let description = own_description.unwrap_or_else(|| text(&schema).unwrap_or_default());
        if let Some(variants) = schema
            .get("oneOf")
            .or_else(|| schema.get("anyOf"))
            .and_then(Value::as_array)
        {
            self.variants(key, variants, applies_when, required, default, description);
        } else if schema.get("properties").is_some() {
            self.table(key, &schema, applies_when);
        } else {
            self.leaf(
                key,
                &schema,
                applies_when,
                required,
                default.map(render),
                description,
            );
        }
    }

    fn leaf(
        &mut self,
        key: &str,
        schema: &Value,
        applies_when: Option<&str>,
        required: bool,
        default: Option<String>,
        description: String,
    ) {
        self.keys.push(KeyDoc {
            key: key.to_owned(),
            applies_when: applies_when.map(str::to_owned),
            kind: kind_of(schema),
            default,
            required: required && !is_optional(schema),
            unit: unit_in(&description).unwrap_or_else(|| unit_of(key)),
            description,
        });
        // An array of tables (`[[slip]]`, `segments = [{ … }]`): the keys
        // of each of its tables.
        if let Some(items) = schema.get("items") {
            let items = self.resolve(items);
            if items.get("properties").is_some() {
                self.table(key, &items, Some(&format!("each `[[{key}]]`")));
            }
        }
    }

    /// A serde enum: unit variants (strings), internally tagged tables
    /// (`kind = "…"`), or externally tagged tables (`[key.variant]`).
    fn variants(
        &mut self,
        key: &str,
        variants: &[Value],
        applies_when: Option<&str>,
        required: bool,
        default: Option<&Value>,
        description: String,
    ) {
        let variants: Vec<Value> = variants.iter().map(|v| self.resolve(v)).collect();
        let tag_values: Vec<String> = variants
            .iter()
            .filter_map(|v| v.pointer("/properties/kind/const").map(render))
            .collect();
        if !tag_values.is_empty() && tag_values.len() == variants.len() {
            // Internally tagged: `key.kind` chooses, each variant's keys
            // apply under it.
            // A default table shows as its tag.
            let default = default.map(|d| d.get("kind").map_or_else(|| render(d), render));
            self.keys.push(KeyDoc {
                key: format!("{key}.kind"),
                applies_when: applies_when.map(str::to_owned),
                kind: tag_values.join(" | "),
                default: default.clone(),
                required: default.is_none() && required,
                unit: "",
                description,
            });
            for (variant, tag) in variants.iter().zip(&tag_values) {
                let when = format!("{key}.kind = {tag}");
                let mut variant = variant.clone();
                if let Some(p) = variant.get_mut("properties").and_then(Value::as_object_mut) {
                    p.remove("kind");
                }
                self.table(key, &variant, Some(&when));
            }
            return;
        }
        // Unit variants are strings; a variant with fields is a table of
        // its own name.
        let mut choices = Vec::new();
        let mut tables = Vec::new();
        for v in &variants {
            if let Some(values) = v.get("enum").and_then(Value::as_array) {
                choices.extend(values.iter().map(render));
            } else if let Some(c) = v.get("const") {
                choices.push(render(c));
            } else if let Some(props) = v.get("properties").and_then(Value::as_object)
                && props.len() == 1
                && let Some((name, inner)) = props.iter().next()
            {
                choices.push(format!("[{key}.{name}]"));
                tables.push((name.clone(), inner.clone()));
            } else {
                choices.push(kind_of(v));
            }
        }
        self.keys.push(KeyDoc {
            key: key.to_owned(),
            applies_when: applies_when.map(str::to_owned),
            kind: choices.join(" | "),
            default: default.map(render),
            required,
            unit: unit_of(key),
            description,
        });
        for (name, inner) in tables {
            let table_key = format!("{key}.{name}");
            let when = format!("[{table_key}]");
            self.table(&table_key, &inner, Some(&when));
        }
    }
}

/// `schema` without a `null` alternative (an `Option`).
fn without_null(schema: &Value) -> Value {
    let Some(any) = schema.get("anyOf").and_then(Value::as_array) else {
        return schema.clone();
    };
    let rest: Vec<&Value> = any
        .iter()
        .filter(|v| v.get("type").and_then(Value::as_str) != Some("null"))
        .collect();
    match rest.as_slice() {
        [only] if rest.len() < any.len() => {
            let mut v = (*only).clone();
            if let (Some(m), Some(d)) = (v.as_object_mut(), schema.get("description")) {
                m.entry("description").or_insert_with(|| d.clone());
            }
            v
        }
        _ => schema.clone(),
    }
}

fn is_optional(schema: &Value) -> bool {
    match schema.get("type") {
        Some(Value::Array(types)) => types.iter().any(|t| t == "null"),
        _ => false,
    }
}

/// A leaf's type, or its allowed values.
fn kind_of(schema: &Value) -> String {
    if let Some(values) = schema.get("enum").and_then(Value::as_array) {
        return values.iter().map(render).collect::<Vec<_>>().join(" | ");
    }
    if let Some(c) = schema.get("const") {
        return render(c);
    }
    let types: Vec<String> = match schema.get("type") {
        Some(Value::String(t)) => vec![t.clone()],
        Some(Value::Array(ts)) => ts
            .iter()
            .filter_map(Value::as_str)
            .filter(|t| *t != "null")
            .map(str::to_owned)
            .collect(),
        _ => Vec::new(),
    };
    match types.first().map(String::as_str) {
        Some("number") => number_range(schema),
        Some("integer") => {
            match (
                schema.get("minimum").map(render),
                schema.get("maximum").map(render),
            ) {
                (Some(min), Some(max)) => format!("integer in [{min}, {max}]"),
                (Some(min), None) => format!("integer ≥ {min}"),
                _ => "integer".into(),
            }
        }
        Some("boolean") => "true | false".into(),
        Some("string") => "string".into(),
        Some("array") => {
            let item = schema.get("items").map_or_else(|| "value".into(), kind_of);
            match (schema.get("minItems"), schema.get("maxItems")) {
                (Some(a), Some(b)) if a == b => format!("[{item}; {a}]"),
                _ => format!("[{item}, …]"),
            }
        }
        _ => "table".into(),
    }
}

/// A number's type with its bounds, inclusive (`minimum`, `maximum`) or
/// exclusive (`exclusiveMinimum`, `exclusiveMaximum`): `number in [0.0,
/// 1.0)`, `number > 0.0`, `number`.
fn number_range(schema: &Value) -> String {
    // The inclusive bound if given, else the exclusive one, as (bracket,
    // comparison, value).
    let bound = |bounds: [(&str, &'static str, &'static str); 2]| {
        bounds
            .into_iter()
            .find_map(|(key, bracket, cmp)| schema.get(key).map(|v| (bracket, cmp, render(v))))
    };
    let lower = bound([("minimum", "[", "≥"), ("exclusiveMinimum", "(", ">")]);
    let upper = bound([("maximum", "]", "≤"), ("exclusiveMaximum", ")", "<")]);
    match (lower, upper) {
        (Some((open, _, min)), Some((close, _, max))) => {
            format!("number in {open}{min}, {max}{close}")
        }
        (Some((_, cmp, bound)), None) | (None, Some((_, cmp, bound))) => {
            format!("number {cmp} {bound}")
        }
        (None, None) => "number".into(),
    }
}

fn text(schema: &Value) -> Option<String> {
    schema
        .get("description")
        .and_then(Value::as_str)
        .map(|d| d.split_whitespace().collect::<Vec<_>>().join(" "))
}

/// The default column of an optional key without a default value (the
/// key's meaning says what leaving it out does).
const NOT_GIVEN: &str = "(not given)";

/// A JSON value as it is written in TOML (an `f32` default in its
/// shortest `f32` form: 0.001, not 0.0010000000474974513).
fn render(v: &Value) -> String {
    match v {
        Value::String(s) => format!("\"{s}\""),
        // An optional key without a default: TOML has no null.
        Value::Null => NOT_GIVEN.into(),
        Value::Number(n) if n.is_f64() => {
            let x = n.as_f64().unwrap_or(f64::NAN);
            #[allow(clippy::cast_possible_truncation)]
            let single = x as f32;
            if f64::from(single) == x {
                format!("{single:?}")
            } else {
                format!("{x:?}")
            }
        }
        Value::Array(items) => format!(
            "[{}]",
            items.iter().map(render).collect::<Vec<_>>().join(", ")
        ),
        // A table in an array (`[[slip]]`'s default) as an inline table.
        Value::Object(fields) => format!(
            "{{ {} }}",
            fields
                .iter()
                .map(|(k, v)| format!("{k} = {}", render(v)))
                .collect::<Vec<_>>()
                .join(", ")
        ),
        other => other.to_string(),
    }
}

/// The keys as a markdown table.
#[must_use]
pub fn markdown(keys: &[KeyDoc]) -> String {
    let mut md = String::from(
        "| key | applies when | type or values | default | unit | meaning |\n\
         | --- | --- | --- | --- | --- | --- |\n",
    );
    for k in keys {
        let default = match (&k.default, k.required) {
            (Some(d), _) if d == NOT_GIVEN => d.clone(),
            (Some(d), _) => format!("`{d}`"),
            (None, true) => "required".into(),
            (None, false) => NOT_GIVEN.into(),
        };
        md.push_str(&format!(
            "| `{}` | {} | {} | {} | {} | {} |\n",
            k.key,
            k.applies_when.as_deref().unwrap_or(""),
            k.kind.replace('|', "\\|"),
            default,
            k.unit,
            k.description.replace('|', "\\|")
        ));
    }
    md
}

/// The keys TOML files (`(name, text)`) give that a key table does not
/// list, as `name: key`: none, for files the table's types parse.
#[cfg(test)]
pub(crate) fn unlisted_keys(keys: &[KeyDoc], files: &[(&str, &str)]) -> Vec<String> {
    let mut unlisted = Vec::new();
    for (name, text) in files {
        let table: toml::Table = text
            .parse()
            .unwrap_or_else(|e| panic!("{name} is no TOML: {e}"));
        let mut used = Vec::new();
        dotted_keys("", &table, &mut used);
        unlisted.extend(
            used.iter()
                .filter(|key| !keys.iter().any(|k| &k.key == *key))
                .map(|key| format!("{name}: {key}")),
        );
    }
    unlisted
}

/// The dotted keys a TOML table gives (`a.b.c`), an array of tables as
/// its own key and its tables' keys under it (`slip`, `slip.start_s`).
#[cfg(test)]
fn dotted_keys(prefix: &str, table: &toml::Table, out: &mut Vec<String>) {
    for (k, v) in table {
        let key = if prefix.is_empty() {
            k.clone()
        } else {
            format!("{prefix}.{k}")
        };
        match v {
            toml::Value::Table(t) => dotted_keys(&key, t, out),
            toml::Value::Array(items) => {
                for item in items {
                    if let toml::Value::Table(t) = item {
                        dotted_keys(&key, t, out);
                    }
                }
                out.push(key);
            }
            _ => out.push(key),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::EMBEDDED;

    /// Every key of every shipped scenario is in the list: it is generated
    /// from what parses them.
    #[test]
    fn every_key_of_the_shipped_scenarios_is_listed() {
        // `[estimator] = "heading_observer"` style string variants are the
        // table's own key.
        let unlisted = unlisted_keys(&scenario_keys(), EMBEDDED);
        assert!(unlisted.is_empty(), "not listed: {unlisted:?}");
    }

    /// Every key of every shipped robot file is in the robot list.
    #[test]
    fn every_key_of_the_shipped_robots_is_listed() {
        let keys = robot_keys();
        let listed: Vec<&str> = keys.iter().map(|k| k.key.as_str()).collect();
        for key in [
            "plant.wheel_radius_m",
            "drive.speed_observer.mass_kg",
            "reader.antenna_offset_m",
            "floor.file",
            "floor.spacing_m",
            "estimator.fusion.filter",
        ] {
            assert!(listed.contains(&key), "`{key}` not listed");
        }
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots");
        let mut robots = 0;
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            let text = std::fs::read_to_string(&path).unwrap();
            if path.extension().is_none_or(|e| e != "toml") || text.contains("\nrobot = ") {
                continue; // tag maps and scenarios
            }
            robots += 1;
            let name = path.display().to_string();
            let unlisted = unlisted_keys(&keys, &[(&name, &text)]);
            assert!(unlisted.is_empty(), "not listed: {unlisted:?}");
        }
        assert!(robots >= 2, "{robots} robot files in {}", dir.display());
    }

    /// The list states each bound a value is checked against: the core's
    /// plausible ranges of physical quantities, and the integers' real
    /// lower bounds (≥ 1 where 0 is refused), in TOML's words.
    #[test]
    fn the_list_states_the_bounds_that_are_checked() {
        let keys = scenario_keys();
        let kind = |key: &str| {
            keys.iter()
                .find(|k| k.key == key)
                .unwrap_or_else(|| panic!("{key} not listed"))
                .kind
                .clone()
        };
        assert_eq!(kind("period_s"), "number in [0.0001, 1.0]");
        assert_eq!(kind("controller.k1"), "number in [1e-6, 10000.0]");
        assert_eq!(kind("plant.wheel_radius_m"), "number in [0.001, 2.0]");
        assert_eq!(kind("plant.encoder_bits"), "integer in [2, 32]");
        assert_eq!(kind("plant.substeps"), "integer ≥ 1");
        assert_eq!(kind("position.baud"), "integer ≥ 1");
        assert_eq!(kind("telemetry.every_ticks"), "integer in [1, 65535]");
        for k in &keys {
            assert!(
                !k.description.contains("Some(") && !k.description.contains("`None`"),
                "{}: {}",
                k.key,
                k.description
            );
        }
    }

    #[test]
    fn the_list_states_defaults_units_and_choices() {
        let keys = scenario_keys();
        let find = |key: &str, when: Option<&str>| {
            keys.iter()
                .find(|k| k.key == key && k.applies_when.as_deref() == when)
                .unwrap_or_else(|| panic!("{key} ({when:?}) not listed"))
        };
        let radius = find("reference.radius_m", Some("reference.kind = \"circle\""));
        assert!(radius.required && radius.default.is_none());
        assert_eq!(radius.unit, "m");
        let kinds = find("reference.kind", None);
        for k in ["\"figure_eight\"", "\"circle\"", "\"line\""] {
            assert!(kinds.kind.contains(k), "{kinds:?}");
        }
        let min_speed = find("observer.min_speed_m_s", None);
        assert_eq!(min_speed.unit, "m/s");
        assert!(min_speed.default.is_some());
        let gate = find("estimator.fusion.gate_sigma", Some("[estimator.fusion]"));
        assert_eq!(gate.default.as_deref(), Some("3.0"));
        let estimator = find("estimator", None);
        assert!(
            estimator.kind.contains("\"heading_observer\""),
            "{estimator:?}"
        );
        assert!(
            estimator.kind.contains("[estimator.fusion]"),
            "{estimator:?}"
        );
    }

    #[test]
    fn exclusive_bounds_are_stated_as_such() {
        let kind = |schema: Value| kind_of(&schema);
        use serde_json::json;
        assert_eq!(
            kind(json!({"type": "number", "minimum": 0.0, "exclusiveMaximum": 1.0})),
            "number in [0.0, 1.0)"
        );
        assert_eq!(
            kind(json!({"type": "number", "exclusiveMinimum": 0.0})),
            "number > 0.0"
        );
        assert_eq!(
            kind(json!({"type": "number", "maximum": 2.0})),
            "number ≤ 2.0"
        );
        assert_eq!(kind(json!({"type": "number"})), "number");
    }

    #[test]
    fn units_come_from_the_names() {
        assert_eq!(unit_of("drive.max_wheel_accel_rad_s2"), "rad/s²");
        assert_eq!(unit_of("observer.gain_per_m"), "1/m");
        assert_eq!(unit_of("duration_s"), "s");
        assert_eq!(unit_of("name"), "");
        assert_eq!(
            unit_in("Each wheel's travel variance per metre driven, m²/m (default 1e-3)."),
            Some("m²/m")
        );
        assert_eq!(unit_in("Radius, m."), Some("m"));
        assert_eq!(unit_in("Free text."), None);
    }

    /// Every default the key tables print is a TOML value (or says that
    /// the key is required or may be left out).
    #[test]
    fn defaults_are_printed_as_toml_values() {
        for k in scenario_keys().into_iter().chain(robot_keys()) {
            let Some(d) = k.default else { continue };
            if d == NOT_GIVEN {
                continue;
            }
            assert!(
                toml::from_str::<toml::Table>(&format!("x = {d}")).is_ok(),
                "{}: default {d} is no TOML value",
                k.key
            );
        }
        let md = markdown(&scenario_keys());
        assert!(!md.contains("`none`") && !md.contains("Some("), "{md}");
    }
}
