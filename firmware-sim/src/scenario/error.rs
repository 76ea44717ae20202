//! Why a scenario is refused, and the checks of single values that make
//! the refusals (shared by the scenario's validation, the sweep table's
//! and the slip scenarios').

/// Why a scenario was refused.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// A file could not be read.
    #[error("cannot read {what} {path}{}", named_by_suffix(.named_by.as_deref()))]
    Io {
        /// What the file is: `scenario file`, `robot file`, `tag map`.
        what: &'static str,
        /// The file.
        path: String,
        /// Who named it, when another file did (`robot = "…"` in a
        /// scenario file, `floor.file` in a robot file).
        named_by: Option<String>,
        /// Why.
        source: std::io::Error,
    },
    /// Not valid TOML, or not the scenario schema (the message names the
    /// key and the line).
    #[error("scenario is not valid: {0}")]
    Parse(String),
    /// A value out of range or inconsistent with another.
    #[error("scenario field `{field}`: {reason}")]
    Invalid {
        /// Dotted path of the field, e.g. `plant.wheel_radius_m`.
        field: String,
        /// What is wrong with it.
        reason: String,
    },
    /// A value of a robot file (or its tag map) out of range.
    #[error("robot file {path}: field `{field}`: {reason}")]
    Robot {
        /// The file (or `[robot]` for a robot embedded in a scenario).
        path: String,
        /// Dotted path of the robot file's key (or a tag map's line).
        field: String,
        /// What is wrong with it.
        reason: String,
    },
}

fn named_by_suffix(named_by: Option<&str>) -> String {
    named_by.map_or_else(String::new, |who| format!(", named by {who}"))
}

impl ScenarioError {
    /// An [`Self::Io`] error of reading `what` at `path`.
    pub(crate) fn io(what: &'static str, path: &std::path::Path, source: std::io::Error) -> Self {
        Self::Io {
            what,
            path: path.display().to_string(),
            named_by: None,
            source,
        }
    }

    /// This error, saying who named the file that could not be read.
    #[must_use]
    pub(crate) fn named_by(self, who: impl Into<String>) -> Self {
        match self {
            Self::Io {
                what,
                path,
                named_by: None,
                source,
            } => Self::Io {
                what,
                path,
                named_by: Some(who.into()),
                source,
            },
            other => other,
        }
    }

    pub(crate) fn invalid(field: &str, reason: impl Into<String>) -> Self {
        Self::Invalid {
            field: field.to_owned(),
            reason: reason.into(),
        }
    }

    /// The offending field's dotted path, for [`Self::Invalid`] and
    /// [`Self::Robot`].
    #[must_use]
    pub fn field(&self) -> Option<&str> {
        match self {
            Self::Invalid { field, .. } | Self::Robot { field, .. } => Some(field),
            _ => None,
        }
    }
}

pub(crate) fn positive(field: &str, v: f64) -> Result<f64, ScenarioError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(ScenarioError::invalid(
            field,
            format!("must be finite and > 0 (got {v})"),
        ))
    }
}

/// `v` if the core takes it: inside `range` once rounded to the core's
/// `f32` (the core's plausible range of the quantity,
/// [`wmr_core::plausible`]), so that the core's own check passes.
pub(crate) fn in_range(
    field: &str,
    v: f64,
    range: wmr_core::plausible::Range,
    unit: &str,
) -> Result<f64, ScenarioError> {
    if range.contains(v as f32) {
        Ok(v)
    } else {
        let unit = if unit.is_empty() {
            String::new()
        } else {
            format!(" {unit}")
        };
        Err(ScenarioError::invalid(
            field,
            format!("must be in {range}{unit} (got {})", shown(v)),
        ))
    }
}

/// `v` as a person reads it: plain between 1e-4 and 1e9, in exponent
/// notation beyond (`3e38`, not 39 digits).
pub(crate) fn shown(v: f64) -> String {
    if v == 0.0 || !v.is_finite() || (1e-4..1e9).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

pub(crate) fn non_negative(field: &str, v: f64) -> Result<f64, ScenarioError> {
    if v.is_finite() && v >= 0.0 {
        Ok(v)
    } else {
        Err(ScenarioError::invalid(
            field,
            format!("must be finite and ≥ 0 (got {v})"),
        ))
    }
}

pub(super) fn finite(field: &str, v: f64) -> Result<f64, ScenarioError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(ScenarioError::invalid(
            field,
            format!("must be finite (got {v})"),
        ))
    }
}

pub(crate) fn probability(field: &str, v: f64) -> Result<f64, ScenarioError> {
    if (0.0..=1.0).contains(&v) {
        Ok(v)
    } else {
        Err(ScenarioError::invalid(
            field,
            format!("must be a probability in [0, 1] (got {v})"),
        ))
    }
}
