//! The seeded generator of the filter's uniform and Gaussian draws.
//!
//! # Random numbers
//! xoshiro128++ from `rand` (`rand::rngs::Xoshiro128PlusPlus`, 128-bit
//! state, 32-bit outputs: native on a Cortex-M, no atomics), seeded from a
//! `u64` through SplitMix64. Uniform draws take the top 24 bits of an
//! output (`[0, 1)` in steps of 2⁻²⁴). Gaussian draws use the Box–Muller
//! transform on [`crate::math`]'s `ln`, `sqrt`, `sin`, `cos`:
//! `ρ = √(−2 ln u₁)`, `(ρ cos 2πu₂, ρ sin 2πu₂)` with `u₁ ∈ (0, 1]`, one
//! of each pair kept for the next draw; it costs the same for every draw
//! (no rejection loop, unlike the polar method), and the 24-bit `u₁` bounds
//! `|ξ| ≤ √(48 ln 2) ≈ 5.77`, a tail cut that changes nothing at 100
//! particles. Runs are reproducible: the same seed, configuration and
//! inputs give bit-identical particles and estimates for a given math
//! backend (`libm` and `micromath` give different, each reproducible,
//! runs). `rand_distr` is not used: without `std` its math goes through
//! `num-traits` and `libm`, bypassing the `micromath` switch.

use nalgebra::SVector;
use rand::rngs::Xoshiro128PlusPlus;
use rand::{Rng, SeedableRng};

use crate::math;

/// 2⁻²⁴: one step of a 24-bit uniform draw.
const UNIT_24: f32 = 1.0 / 16_777_216.0;

/// The seeded generator and the spare Gaussian draw of Box–Muller.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Noise {
    rng: Xoshiro128PlusPlus,
    spare: Option<f32>,
}

impl Noise {
    pub(super) fn new(seed: u64) -> Self {
        Self {
            rng: Xoshiro128PlusPlus::seed_from_u64(seed),
            spare: None,
        }
    }

    /// Uniform in [0, 1), 24 bits.
    pub(super) fn uniform(&mut self) -> f32 {
        (self.rng.next_u32() >> 8) as f32 * UNIT_24
    }

    /// Standard normal (Box–Muller, module docs).
    pub(super) fn gaussian(&mut self) -> f32 {
        if let Some(z) = self.spare.take() {
            return z;
        }
        // (0, 1]: ln stays finite.
        let u1 = ((self.rng.next_u32() >> 8) + 1) as f32 * UNIT_24;
        let angle = math::TAU * self.uniform();
        // max(0): an approximate ln(1) may come out a hair above 0. Spelled
        // out with `f32::max(0.0)`'s results (NaN and values below 0 give
        // 0, −0 stays −0, on the host and the Cortex-M4 alike), where
        // `f32::max` is a call to `fmaxf` on the Cortex-M4.
        let square = -2.0 * math::ln(u1);
        let square = if square.is_nan() || square < 0.0 {
            0.0
        } else {
            square
        };
        let radius = math::sqrt(square);
        let (sin, cos) = math::sincos(angle);
        self.spare = Some(radius * sin);
        radius * cos
    }

    /// `x + σ ∘ ξ`, `ξ ~ N(0, I)`, angle components wrapped; a component
    /// that would overflow keeps its value.
    pub(super) fn perturb<const N: usize>(
        &mut self,
        x: &mut SVector<f32, N>,
        std: &SVector<f32, N>,
        angles: &[bool; N],
    ) {
        for ((value, &sigma), &angle) in x.iter_mut().zip(std.iter()).zip(angles.iter()) {
            let moved = if sigma > 0.0 {
                *value + sigma * self.gaussian()
            } else {
                *value
            };
            let moved = if angle {
                math::wrap_angle(moved)
            } else {
                moved
            };
            if moved.is_finite() {
                *value = moved;
            }
        }
    }
}
