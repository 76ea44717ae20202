//! Why a configuration was refused, and the check of a parameter.

/// Why a configuration was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum SlipTrackingError {
    /// A physical parameter is not finite and positive.
    Parameter,
    /// A gain is not finite and positive.
    Gain,
    /// The period is not finite and positive.
    Period,
    /// The initial slip factor is not in `[1, P_MAX]`.
    SlipEstimate,
    /// Reference segments are empty, not finite, or their start times do
    /// not increase from 0.
    Reference,
}

impl core::fmt::Display for SlipTrackingError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::Parameter => "a physical parameter must be finite and > 0",
            Self::Gain => "a gain must be finite and > 0",
            Self::Period => "period_s must be finite and > 0 s",
            Self::SlipEstimate => "the initial slip factor must be in [1, P_MAX]",
            Self::Reference => "the reference segments must be non-empty and finite, with start times increasing from 0",
        })
    }
}

impl core::error::Error for SlipTrackingError {}

pub(super) fn positive(x: f32) -> bool {
    x.is_finite() && x > 0.0
}
