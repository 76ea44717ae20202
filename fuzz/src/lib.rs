//! What the fuzz targets share: specs and values drawn from the fuzzer's
//! bytes.
//!
//! Each spec of the core is drawn by its own `Arbitrary` implementation,
//! beside the spec (the core's cargo feature `arbitrary`), from typical
//! values that are sometimes scaled, raw or special
//! ([`wmr_core::fuzzing`]); a new estimator or law brings its own, and
//! nothing here changes.

use arbitrary::{Result, Unstructured};
use wmr_core::devices::tag_grid::TagGridSpec;
use wmr_core::estimation::spec::{EstimatorSpec, FusionFilterSpec};
use wmr_core::pilot::spec::PilotSpec;

pub use wmr_core::fuzzing::float;

/// A pilot spec around a typical 2048-count, 0.3 m robot at 100 Hz, on
/// any estimator and law.
///
/// # Errors
/// Never in practice.
pub fn pilot_spec(u: &mut Unstructured) -> Result<PilotSpec> {
    u.arbitrary()
}

/// As [`pilot_spec`], but the fusion estimator's particle filter (100
/// particles: ten times the EKF's work per tick) is replaced by the UKF,
/// for the targets that fuzz what is around the pilot rather than the
/// pilot.
///
/// # Errors
/// Never in practice.
pub fn light_pilot_spec(u: &mut Unstructured) -> Result<PilotSpec> {
    let mut spec: PilotSpec = u.arbitrary()?;
    if let EstimatorSpec::Fusion(f) = &mut spec.tracker.estimator
        && f.filter == FusionFilterSpec::ParticleFilter
    {
        f.filter = FusionFilterSpec::Ukf;
    }
    Ok(spec)
}

/// A tag grid around the origin, 0.1 m spacing.
///
/// # Errors
/// Never in practice.
pub fn tag_grid_spec(u: &mut Unstructured) -> Result<TagGridSpec> {
    u.arbitrary()
}

/// The next raw encoder counter after `previous`: mostly a small move,
/// sometimes a failed read (`None`) or any value (a jump).
///
/// # Errors
/// Never in practice.
pub fn encoder_count(u: &mut Unstructured, previous: u32) -> Result<Option<u32>> {
    Ok(match u.int_in_range(0_u8..=15)? {
        0 => None,
        1 => Some(u.arbitrary()?),
        _ => Some(previous.wrapping_add_signed(i32::from(u.arbitrary::<i8>()?))),
    })
}
