//! Integration tests of `wmr-core` live in `tests/`: reproductions of the
//! papers' simulations (`paper_001_*.rs`) and whole-stack properties
//! (`robustness.rs`). This library only holds what they share.

use wmr_core::reference::ReferenceSample;

/// Heading of the reference's velocity, `θ_r = atan2(ẏ_r, ẋ_r)` (paper 001, (52)).
#[must_use]
pub fn reference_heading(r: &ReferenceSample) -> f32 {
    libm::atan2f(r.velocity.y, r.velocity.x)
}

/// Turn rate of the reference, `θ̇_r = (ẋ_r ÿ_r − ẏ_r ẍ_r)/v_r²`.
#[must_use]
pub fn reference_turn_rate(r: &ReferenceSample) -> f32 {
    let v2 = r.velocity.x * r.velocity.x + r.velocity.y * r.velocity.y;
    (r.velocity.x * r.acceleration.y - r.velocity.y * r.acceleration.x) / v2
}
