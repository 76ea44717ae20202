//! What a scenario changes with time: the slip ratio's steps and the
//! reference's constant-input segments.

use serde::{Deserialize, Serialize};

/// The slip ratio of `steps` at `t`: the last step started at or before
/// `t`, 0 before the first.
pub(in crate::slip) fn ratio_at(steps: &[SlipStep], t: f64) -> f64 {
    steps
        .iter()
        .take_while(|s| s.start_s <= t)
        .last()
        .map_or(0.0, |s| s.slip_ratio)
}

/// From `start_s` on, the slip ratio is `slip_ratio`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SlipStep {
    /// When the step starts, s (≥ 0, later than the step before).
    #[schemars(range(min = 0.0))]
    pub start_s: f64,
    /// The longitudinal slip ratio `i` from then on, no unit, in `[0, 1)`
    /// (`p = 1/(1 − i)`).
    #[schemars(range(min = 0.0), extend("exclusiveMaximum" = 1.0))]
    pub slip_ratio: f64,
}

/// One constant-input piece of the reference.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SegmentSpec {
    /// When the segment starts, s (the first at 0, later than the segment
    /// before).
    pub start_s: f64,
    /// The reference's speed `v_r`, m/s.
    pub v_m_s: f64,
    /// The reference's turn rate `ω_r`, rad/s.
    pub omega_rad_s: f64,
}
