//! Values drawn from a fuzzer's bytes, for the specs' `Arbitrary`
//! implementations (cargo feature `arbitrary`; each spec's lives beside
//! it).
//!
//! Each value is most often a typical one (so that most specs build and a
//! fuzz target reaches the control loop) and otherwise a scaled, raw or
//! special one: NaN, ±∞, ±0, subnormal, huge. When the bytes run out every
//! draw gives its typical value, so a short input is a valid spec.

use arbitrary::{Result, Unstructured};

/// Values a validation must refuse, or must take at their edge.
pub const SPECIAL_F32: [f32; 14] = [
    f32::NAN,
    f32::INFINITY,
    f32::NEG_INFINITY,
    0.0,
    -0.0,
    f32::MAX,
    f32::MIN,
    f32::MIN_POSITIVE,
    1e-45, // smallest subnormal
    f32::EPSILON,
    1e30,
    -1e30,
    1.0,
    -1.0,
];

/// A float: `typical` most of the time, otherwise `typical` scaled, a
/// special value, or any bit pattern.
///
/// # Errors
/// Never in practice (`Unstructured` gives defaults when empty).
pub fn float(u: &mut Unstructured, typical: f32) -> Result<f32> {
    Ok(match u.int_in_range(0_u8..=15)? {
        0..=9 => typical,
        10 => typical * *u.choose(&[0.0, -1.0, 0.5, 2.0, 10.0, 1e3, 1e-3, 1e6])?,
        11 => *u.choose(&SPECIAL_F32)?,
        12 => f32::from_bits(u.arbitrary()?),
        _ => typical * (1.0 + f32::from(u.arbitrary::<i8>()?) / 64.0),
    })
}

/// A count: `typical` most of the time, otherwise small or any.
///
/// # Errors
/// Never in practice.
pub fn count(u: &mut Unstructured, typical: u32) -> Result<u32> {
    Ok(match u.int_in_range(0_u8..=7)? {
        0..=4 => typical,
        5 => u.int_in_range(0..=3)?,
        6 => *u.choose(&[u32::MAX, u32::MAX - 1, 1 << 31, 1 << 16, 65_535])?,
        _ => u.arbitrary()?,
    })
}
