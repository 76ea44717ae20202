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
