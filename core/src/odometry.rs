//! Encoder counters to wheel increments to body motion (exact-arc odometry).
//!
//! Hardware quadrature counters are 16 or 32 bits wide and wrap. The core
//! never trusts an absolute count: [`WrappingCounter`] keeps the last raw
//! value and returns the signed difference modulo `2^bits`, which is right
//! as long as the wheel turns less than half the counter range between two
//! reads (at 16 bits and 4096 counts/rev that is 8 revolutions per tick).

use crate::geometry::{BodyVelocity, DiffDriveGeometry, WheelSpeeds};

/// Why a counter width was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CounterError {
    /// Width outside 2..=32 bits.
    Width,
}

impl core::fmt::Display for CounterError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::Width => "the encoder counter width must be 2..=32 bits",
        })
    }
}

impl core::error::Error for CounterError {}

/// Signed differences of a wrapping hardware counter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WrappingCounter {
    shift: u32,
    last: Option<u32>,
}

impl WrappingCounter {
    /// A counter of `bits` width (2..=32), with no reading yet.
    ///
    /// # Errors
    /// [`CounterError::Width`] outside 2..=32.
    pub const fn new(bits: u32) -> Result<Self, CounterError> {
        if bits < 2 || bits > 32 {
            return Err(CounterError::Width);
        }
        Ok(Self {
            shift: 32 - bits,
            last: None,
        })
    }

    /// Takes a raw reading and returns the counts since the previous one.
    ///
    /// The first reading only sets the origin and returns 0. Bits above the
    /// counter width are ignored. The result is the difference wrapped to
    /// `[-2^(bits-1), 2^(bits-1))`.
    pub fn delta(&mut self, raw: u32) -> i32 {
        let raw = raw << self.shift;
        let delta = match self.last {
            // Work in the top bits so that i32 arithmetic wraps at the
            // counter's own width; the shift back is arithmetic (sign-keeping).
            Some(last) => (raw.wrapping_sub(last) as i32) >> self.shift,
            None => 0,
        };
        self.last = Some(raw);
        delta
    }

    /// Forgets the origin (after a counter reset or a device fault).
    pub fn reset(&mut self) {
        self.last = None;
    }

    /// Whether an origin has been taken.
    #[must_use]
    pub fn has_origin(&self) -> bool {
        self.last.is_some()
    }
}

/// Motion of the robot over one control period, from the two encoders.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct OdometryStep {
    /// Arc length driven by the axle midpoint, m.
    pub ds_m: f32,
    /// Heading change, rad.
    pub dtheta_rad: f32,
    /// Mean body velocity over the step (`ds/Δt`, `Δθ/Δt`).
    pub body: BodyVelocity,
    /// Mean wheel speeds over the step, rad/s.
    pub wheels: WheelSpeeds,
}

impl OdometryStep {
    /// Odometry from the count increments of both wheels over `dt_s` seconds.
    ///
    /// Exact-arc model: with constant wheel speeds over the step the robot
    /// drives an arc of length `ds = r(Δφ_R + Δφ_L)/2` turning by
    /// `Δθ = r(Δφ_R − Δφ_L)/b`; [`crate::geometry::Pose::advance_arc`] turns
    /// that into a displacement without the error of a straight chord.
    /// `dt_s` must be positive (callers pass the fixed step, or a multiple
    /// of it after missed reads); a non-positive `dt_s` gives zero speeds.
    #[must_use]
    pub fn from_counts(
        geometry: &DiffDriveGeometry,
        left_counts: i32,
        right_counts: i32,
        dt_s: f32,
    ) -> Self {
        let k = geometry.rad_per_count();
        let dphi = WheelSpeeds {
            left_rad_s: left_counts as f32 * k,
            right_rad_s: right_counts as f32 * k,
        };
        // Same linear map as for speeds: increments in, increments out.
        let incr = geometry.body_from_wheels(dphi);
        let inv_dt = if dt_s > 0.0 { 1.0 / dt_s } else { 0.0 };
        Self {
            ds_m: incr.v_m_s,
            dtheta_rad: incr.omega_rad_s,
            body: BodyVelocity {
                v_m_s: incr.v_m_s * inv_dt,
                omega_rad_s: incr.omega_rad_s * inv_dt,
            },
            wheels: WheelSpeeds {
                left_rad_s: dphi.left_rad_s * inv_dt,
                right_rad_s: dphi.right_rad_s * inv_dt,
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn width_is_validated() {
        assert_eq!(WrappingCounter::new(1), Err(CounterError::Width));
        assert_eq!(WrappingCounter::new(33), Err(CounterError::Width));
        assert!(WrappingCounter::new(16).is_ok());
        assert!(WrappingCounter::new(32).is_ok());
    }

    #[test]
    fn sixteen_bit_wrap_both_ways() {
        let mut c = WrappingCounter::new(16).unwrap();
        assert_eq!(c.delta(65_530), 0);
        assert_eq!(c.delta(4), 10); // forward through the wrap
        assert_eq!(c.delta(65_534), -6); // and back
        // Bits above the width are ignored (a 16-bit timer read as u32).
        assert_eq!(c.delta(0xABCD_0000 | 65_535), 1);
    }

    proptest! {
        /// At any speed below half the counter range per read, the sum of the
        /// deltas equals the true count change, whatever the start value.
        #[test]
        fn wrapping_deltas_sum_to_true_motion(
            bits in prop::sample::select(vec![16_u32, 24, 32]),
            start in any::<u32>(),
            steps in prop::collection::vec(-30_000_i64..30_000, 1..200),
        ) {
            let mask: u64 = if bits == 32 { u64::from(u32::MAX) } else { (1_u64 << bits) - 1 };
            let mut c = WrappingCounter::new(bits).unwrap();
            let mut true_count: i64 = i64::from(start);
            c.delta((true_count as u64 & mask) as u32);
            let mut sum: i64 = 0;
            for s in &steps {
                true_count += s;
                sum += i64::from(c.delta((true_count.rem_euclid(1_i64 << 40) as u64 & mask) as u32));
            }
            prop_assert_eq!(sum, steps.iter().sum::<i64>());
        }
    }
}
