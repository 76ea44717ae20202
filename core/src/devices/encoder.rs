//! Wheel encoders: the raw quadrature counter a HAL provides.
//!
//! embedded-hal 1.0 has no encoder trait, so the core defines
//! [`QuadratureCounter`]. An implementation only reads the hardware counter
//! (e.g. an STM32 timer in encoder mode, a PIO state machine on an RP2040,
//! the simulator's virtual encoder); wrap-around and direction are handled by
//! [`crate::odometry::WrappingCounter`], which turns successive raw counts
//! into signed increments.

/// A quadrature decoder's raw hardware counter (e.g. an STM32 timer in encoder mode).
pub trait QuadratureCounter {
    /// Error of the underlying peripheral.
    type Error: core::fmt::Debug;

    /// The raw, wrapping counter value. Only the low `bits` bits are meaningful (the width is configured where the counter is consumed, see `crate::odometry::WrappingCounter`).
    ///
    /// # Errors
    /// The peripheral could not be read; the caller counts the fault and
    /// keeps the previous origin (or resets it).
    fn raw_count(&mut self) -> Result<u32, Self::Error>;
}

impl<T: QuadratureCounter + ?Sized> QuadratureCounter for &mut T {
    type Error = T::Error;

    #[inline]
    fn raw_count(&mut self) -> Result<u32, Self::Error> {
        T::raw_count(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::odometry::WrappingCounter;

    /// A 16-bit timer that counts by a fixed step per read, or fails.
    struct FakeTimer {
        count: u16,
        step: i16,
        fail: bool,
    }

    #[derive(Debug, PartialEq)]
    struct TimerFault;

    impl QuadratureCounter for FakeTimer {
        type Error = TimerFault;
        fn raw_count(&mut self) -> Result<u32, TimerFault> {
            if self.fail {
                return Err(TimerFault);
            }
            self.count = self.count.wrapping_add_signed(self.step);
            Ok(u32::from(self.count))
        }
    }

    /// Generic consumer, as the control loop would be.
    fn delta_of<C: QuadratureCounter>(c: &mut C, w: &mut WrappingCounter) -> Option<i32> {
        c.raw_count().ok().map(|raw| w.delta(raw))
    }

    #[test]
    fn counter_feeds_wrapping_deltas_through_a_reference() {
        let mut timer = FakeTimer {
            count: 65_500,
            step: -40,
            fail: false,
        };
        let mut w = WrappingCounter::new(16).unwrap();
        // Through `&mut T` (the blanket impl) and directly.
        assert_eq!(delta_of(&mut &mut timer, &mut w), Some(0));
        timer.step = 50; // forward through the 16-bit wrap
        assert_eq!(delta_of(&mut &mut timer, &mut w), Some(50));
        assert_eq!(delta_of(&mut timer, &mut w), Some(50));
        timer.fail = true;
        assert_eq!(delta_of(&mut &mut timer, &mut w), None);
        assert_eq!(timer.raw_count(), Err(TimerFault));
    }
}
