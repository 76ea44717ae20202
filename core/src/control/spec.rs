//! The laws' plain-data description ([`LawSpec`]), validated into a
//! [`LawChoice`] by each law's own constructor; see
//! [`crate::pilot::spec`] for why specs are plain data.

use crate::control::LawChoice;
use crate::control::cascaded::{CascadedGains, CascadedGainsError};
use crate::control::heading_error_sine::{HeadingErrorSineConfig, HeadingErrorSineConfigError};
use crate::control::saturated::TrackingGains;

/// Why a [`LawSpec`] was refused: the law, and its own error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[non_exhaustive]
pub enum LawSpecError {
    /// Paper 002's cascaded controller (31).
    Cascaded(CascadedGainsError),
    /// Paper 002's Proposition 7 observer and controller.
    HeadingErrorSine(HeadingErrorSineConfigError),
}

impl LawSpecError {
    /// The law's key in [`LawSpec`] (its `snake_case` tag).
    #[must_use]
    pub fn law_key(&self) -> &'static str {
        match self {
            Self::Cascaded(_) => "cascaded",
            Self::HeadingErrorSine(_) => "heading_error_sine",
        }
    }

    /// The refused field's key in its law's spec (`c1_per_s`, `gamma`,
    /// …), or `None` for the control period (the tracker's `period_s`).
    #[must_use]
    pub fn field_key(&self) -> Option<&'static str> {
        match self {
            Self::Cascaded(CascadedGainsError::C1) => Some("c1_per_s"),
            Self::Cascaded(CascadedGainsError::C2)
            | Self::HeadingErrorSine(HeadingErrorSineConfigError::C2) => Some("c2_per_s"),
            Self::HeadingErrorSine(HeadingErrorSineConfigError::Gain) => Some("a_s_per_m2"),
            Self::HeadingErrorSine(HeadingErrorSineConfigError::Gamma) => Some("gamma"),
            Self::HeadingErrorSine(HeadingErrorSineConfigError::Period) => None,
        }
    }

    fn inner(&self) -> &(dyn core::error::Error + 'static) {
        match self {
            Self::Cascaded(e) => e,
            Self::HeadingErrorSine(e) => e,
        }
    }
}

impl core::fmt::Display for LawSpecError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        core::fmt::Display::fmt(self.inner(), f)
    }
}

impl core::error::Error for LawSpecError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        Some(self.inner())
    }
}

/// The tracker's law (with the `serde` feature, the `law` key of a
/// scenario's `[controller]` table, externally tagged in `snake_case`:
/// `law = "saturated"`, the default, also spelled `"paper_001"`, or
/// `[controller.law.cascaded]` / `[controller.law.heading_error_sine]`,
/// each field optional with the default documented on it).
#[cfg_attr(feature = "schemars", derive(schemars::JsonSchema))]
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(rename_all = "snake_case", deny_unknown_fields)
)]
#[non_exhaustive]
pub enum LawSpec {
    /// Paper 001's saturated output-feedback law (27)–(28), gains
    /// [`crate::pilot::spec::TrackerSpec::gains`].
    #[default]
    #[cfg_attr(feature = "serde", serde(alias = "paper_001"))]
    Saturated,
    /// Paper 002's cascaded controller (31).
    Cascaded {
        /// `c1`, 1/s (heading error; default 0.5), in [`crate::plausible::GAIN`].
        #[cfg_attr(feature = "serde", serde(default = "LawSpec::default_c"))]
        #[cfg_attr(feature = "schemars", schemars(range(min = crate::plausible::GAIN.min, max = crate::plausible::GAIN.max)))]
        c1_per_s: f32,
        /// `c2`, 1/s (along-track error; default 0.5), in [`crate::plausible::GAIN`].
        #[cfg_attr(feature = "serde", serde(default = "LawSpec::default_c"))]
        #[cfg_attr(feature = "schemars", schemars(range(min = crate::plausible::GAIN.min, max = crate::plausible::GAIN.max)))]
        c2_per_s: f32,
    },
    /// Paper 002's Proposition 7: observer of `sin θ_e` and controller (64).
    HeadingErrorSine {
        /// Observer gain `a`, s/m² (default 100), in [`crate::plausible::GAIN`].
        #[cfg_attr(feature = "serde", serde(default = "LawSpec::default_sine_a"))]
        #[cfg_attr(feature = "schemars", schemars(range(min = crate::plausible::GAIN.min, max = crate::plausible::GAIN.max)))]
        a_s_per_m2: f32,
        /// `c2`, 1/s (default 0.5), in [`crate::plausible::GAIN`].
        #[cfg_attr(feature = "serde", serde(default = "LawSpec::default_c"))]
        #[cfg_attr(feature = "schemars", schemars(range(min = crate::plausible::GAIN.min, max = crate::plausible::GAIN.max)))]
        c2_per_s: f32,
        /// `γ ∈ (0, 1)` (default 0.9).
        #[cfg_attr(feature = "serde", serde(default = "LawSpec::default_gamma"))]
        gamma: f32,
    },
}

impl LawSpec {
    /// The default `c1`, `c2` of [`Self::Cascaded`] and `c2` of
    /// [`Self::HeadingErrorSine`], 1/s.
    pub const DEFAULT_C_PER_S: f32 = 0.5;
    /// The default observer gain `a` of [`Self::HeadingErrorSine`], s/m².
    pub const DEFAULT_SINE_A_S_PER_M2: f32 = 100.0;
    /// The default `γ` of [`Self::HeadingErrorSine`].
    pub const DEFAULT_GAMMA: f32 = 0.9;
    /// The cascaded law with its default gains.
    pub const CASCADED: Self = Self::Cascaded {
        c1_per_s: Self::DEFAULT_C_PER_S,
        c2_per_s: Self::DEFAULT_C_PER_S,
    };
    /// Proposition 7 with its default gains.
    pub const HEADING_ERROR_SINE: Self = Self::HeadingErrorSine {
        a_s_per_m2: Self::DEFAULT_SINE_A_S_PER_M2,
        c2_per_s: Self::DEFAULT_C_PER_S,
        gamma: Self::DEFAULT_GAMMA,
    };

    #[cfg(feature = "serde")]
    fn default_c() -> f32 {
        Self::DEFAULT_C_PER_S
    }
    #[cfg(feature = "serde")]
    fn default_sine_a() -> f32 {
        Self::DEFAULT_SINE_A_S_PER_M2
    }
    #[cfg(feature = "serde")]
    fn default_gamma() -> f32 {
        Self::DEFAULT_GAMMA
    }
}

impl LawSpec {
    /// The validated law for control period `period_s`; paper 001's law
    /// runs with `saturated_gains` (the tracker's `k1, k2, k3`,
    /// [`crate::pilot::spec::TrackerSpec::gains`]).
    ///
    /// # Errors
    /// The law's own refusal.
    // Always inlined, as are the calls it makes on the way to the tracker's
    // gain-bound check: with a compiled-in spec (the Black Pill's `PILOT`)
    // LLVM then folds the whole validation to `Ok` and drops the refusal
    // path; as calls they cost that firmware 2.3 KB of flash (`cargo xtask size`).
    #[inline(always)]
    pub fn build(
        &self,
        saturated_gains: TrackingGains,
        period_s: f32,
    ) -> Result<LawChoice, LawSpecError> {
        Ok(match *self {
            Self::Saturated => LawChoice::Saturated(saturated_gains),
            Self::Cascaded { c1_per_s, c2_per_s } => LawChoice::Cascaded(
                CascadedGains::new(c1_per_s, c2_per_s).map_err(LawSpecError::Cascaded)?,
            ),
            Self::HeadingErrorSine {
                a_s_per_m2,
                c2_per_s,
                gamma,
            } => LawChoice::HeadingErrorSine(
                HeadingErrorSineConfig::new(a_s_per_m2, c2_per_s, gamma, period_s)
                    .map_err(LawSpecError::HeadingErrorSine)?,
            ),
        })
    }
}

/// A law drawn from a fuzzer's bytes, its gains near the defaults
/// ([`crate::fuzzing`]).
#[cfg(feature = "arbitrary")]
impl<'a> arbitrary::Arbitrary<'a> for LawSpec {
    fn arbitrary(u: &mut arbitrary::Unstructured<'a>) -> arbitrary::Result<Self> {
        use crate::fuzzing::float;
        Ok(match u.int_in_range(0_u8..=2)? {
            0 => Self::Saturated,
            1 => Self::Cascaded {
                c1_per_s: float(u, Self::DEFAULT_C_PER_S)?,
                c2_per_s: float(u, Self::DEFAULT_C_PER_S)?,
            },
            _ => Self::HeadingErrorSine {
                a_s_per_m2: float(u, Self::DEFAULT_SINE_A_S_PER_M2)?,
                c2_per_s: float(u, Self::DEFAULT_C_PER_S)?,
                gamma: float(u, Self::DEFAULT_GAMMA)?,
            },
        })
    }
}
