//! The EKF's and UKF's wheel noise raised when the boundary crossings say
//! it is too small (covariance matching: Mehra 1972, *Approaches to
//! adaptive filtering*, IEEE Trans. Autom. Control 17(5):693–698;
//! Mohamed & Schwarz 1999, *Adaptive Kalman filtering for INS/GPS*,
//! J. Geodesy 73:193–203).
//!
//! A filter configured with a wheel noise below its wheels' own is too
//! sure of its dead reckoning: its crossings' innovations are larger than
//! their predicted spread, the gate refuses the larger ones, and between
//! crossings the estimate drifts further than the filter allows for. On
//! the grid of docs/fusion.md ("The three filters together") the EKF and
//! the UKF tuned 10× low lost to paper 001's observer in 17 of their 54
//! cases (14 of the 18 at 1e-2 m²/m).
//!
//! Each crossing (a 1-D measurement of the crossed axis,
//! [`crate::estimation::fusion::tag_cells`]) gives its normalised
//! innovation squared `d² = y²/S`, `S = P_axis + R`, which has mean 1 for a
//! filter whose noise is right. Its exponential average over the crossings
//! ([`NIS_AVERAGE_WEIGHT`]: about the last ten) above [`RAISE_ABOVE`]
//! doubles the wheel noise's scale, up to [`MAX_SCALE`]; below
//! [`LOWER_BELOW`] halves it, never below 1: the configured noise is a
//! floor, and a filter whose noise is above its wheels' is left as it is
//! configured (it tracks well there, docs/fusion.md). After each change the
//! average restarts at 1, so that the next change waits for crossings made
//! at the new scale. A single crossing counts at most [`NIS_CLIP`], so that
//! one outlier (a crossing the gate refuses can be any distance off) does
//! not double the noise alone: from an average of 1 it lifts it to 3.9;
//! two in a row do. A clip of 100 would let one early crossing of a pose
//! still settling (a `d²` of 50–190) raise the UKF tuned 10× above the
//! wheels' 1e-6 m²/m on the figure-eight over 30 cm tags, 17 % worse for
//! it (median max error 0.0366 → 0.0428 m over the grid's 32 starts).
//!
//! Crossings count only once the guide observer is trusted (its error
//! bound below the one the heading resets use,
//! [`crate::estimation::fusion::FusionEstimator`]): before that a filter
//! acquiring its pose from a far start has large innovations for a reason
//! other than its wheels. Reads of an unchanged tag (a stray estimate's
//! truncation, the edge constraint's pulls) are not crossings
//! ([`crate::estimation::fusion::CellReading`]) and are not counted: their
//! innovation is large by construction. A range reader gives no crossings,
//! so its filters keep the configured noise.
//!
//! The particle filter is not adapted: its noise levels
//! ([`crate::estimation::fusion::particle`], "Noise level") reach below
//! the configured noise only. The same rule on its particles' mean and
//! covariance was measured on the grid (docs/fusion.md, "A wheel noise
//! tuned too low"): it wins where the filter is tuned 10× low but loses
//! more where it is matched or 10× high at 1e-2 m²/m, its cloud's spread
//! too small a measure of its error there.

/// The weight of each crossing's `d²` in the average (module docs).
pub const NIS_AVERAGE_WEIGHT: f32 = 0.1;

/// The average `d²` above which the wheel noise is doubled.
pub const RAISE_ABOVE: f32 = 4.0;

/// The average `d²` below which a raised wheel noise is halved.
pub const LOWER_BELOW: f32 = 0.5;

/// The largest scale of the configured wheel noise (variance).
pub const MAX_SCALE: f32 = 64.0;

/// The largest `d²` one crossing adds to the average: one alone, from an
/// average of 1, stays below [`RAISE_ABOVE`] (`0.9 + 0.1 · 30 = 3.9`).
pub const NIS_CLIP: f32 = 30.0;

/// The scale of the configured wheel noise (module docs), from the
/// crossings' normalised innovations.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WheelNoiseAdaptation {
    average_nis: f32,
    scale: f32,
    raised: u32,
    lowered: u32,
}

impl Default for WheelNoiseAdaptation {
    fn default() -> Self {
        Self::new()
    }
}

impl WheelNoiseAdaptation {
    /// At the configured noise (scale 1), no crossing seen.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            average_nis: 1.0,
            scale: 1.0,
            raised: 0,
            lowered: 0,
        }
    }

    /// Takes a crossing's normalised innovation squared; returns the new
    /// scale if it changed. A NaN, infinite or negative `d²` is ignored.
    pub fn observe(&mut self, nis: f32) -> Option<f32> {
        if !(nis.is_finite() && nis >= 0.0) {
            return None;
        }
        self.average_nis =
            (1.0 - NIS_AVERAGE_WEIGHT) * self.average_nis + NIS_AVERAGE_WEIGHT * nis.min(NIS_CLIP);
        let scale = if self.average_nis > RAISE_ABOVE && self.scale < MAX_SCALE {
            self.raised = self.raised.saturating_add(1);
            (2.0 * self.scale).min(MAX_SCALE)
        } else if self.average_nis < LOWER_BELOW && self.scale > 1.0 {
            self.lowered = self.lowered.saturating_add(1);
            (0.5 * self.scale).max(1.0)
        } else {
            return None;
        };
        self.scale = scale;
        self.average_nis = 1.0;
        Some(scale)
    }

    /// The scale of the configured wheel noise's variance now (≥ 1).
    #[must_use]
    pub fn scale(&self) -> f32 {
        self.scale
    }

    /// Times the scale was doubled and halved, since the start.
    #[must_use]
    pub fn changes(&self) -> (u32, u32) {
        (self.raised, self.lowered)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Crossings at `d² = 1` (a right noise) leave the scale at 1; at
    /// `d² = 10` it doubles about every ten crossings up to its limit; back
    /// at `d² = 0.1` it halves down to 1, never below; each change counted.
    #[test]
    fn the_scale_follows_the_innovations_within_its_bounds() {
        let mut adaptation = WheelNoiseAdaptation::new();
        for _ in 0..1000 {
            assert_eq!(adaptation.observe(1.0), None);
        }
        assert_eq!(adaptation.scale(), 1.0);
        let mut first = None;
        for k in 0..1000 {
            if adaptation.observe(10.0).is_some() && first.is_none() {
                first = Some(k);
            }
        }
        // After n crossings the average is 10 − 9 · 0.9ⁿ: above 4 from the
        // fourth (4.10; the third 3.44).
        assert_eq!(first, Some(3));
        assert_eq!(adaptation.scale(), MAX_SCALE);
        assert_eq!(adaptation.changes(), (6, 0));
        for _ in 0..1000 {
            let _ = adaptation.observe(0.1);
        }
        assert_eq!(adaptation.scale(), 1.0);
        assert_eq!(adaptation.changes(), (6, 6));
    }

    /// One outlier counts at most `NIS_CLIP` and does not raise alone; bad
    /// input is ignored.
    #[test]
    fn an_outlier_is_clipped_and_bad_input_ignored() {
        let mut adaptation = WheelNoiseAdaptation::new();
        for nis in [f32::NAN, f32::INFINITY, -1.0] {
            assert_eq!(adaptation.observe(nis), None);
        }
        assert_eq!(adaptation, WheelNoiseAdaptation::new());
        // One huge outlier counts 30: 0.9 + 3 = 3.9, not above 4.
        assert_eq!(adaptation.observe(1e9), None);
        assert_eq!(adaptation.scale(), 1.0);
        // A second in a row: 0.9 · 3.9 + 3 = 6.51 raises, once; the
        // restart at 1 keeps a third from raising again alone.
        assert_eq!(adaptation.observe(1e9), Some(2.0));
        assert_eq!(adaptation.observe(1e9), None);
        assert_eq!(adaptation.changes(), (1, 0));
    }
}
