//! The fusion filters' wheel noise raised when the boundary crossings say
//! it is too small (covariance matching: Mehra 1972, *Approaches to
//! adaptive filtering*, IEEE Trans. Autom. Control 17(5):693–698;
//! Mohamed & Schwarz 1999, *Adaptive Kalman filtering for INS/GPS*,
//! J. Geodesy 73:193–203).
//!
//! A filter configured with a wheel noise below its wheels' own is too
//! sure of its dead reckoning: its crossings' innovations are larger than
//! their predicted spread, the gate refuses the larger ones, and between
//! crossings the estimate drifts further than the filter allows for. On
//! the grid of docs/fusion.md ("The three filters together") a filter
//! tuned 10× low lost to paper 001's observer in 29 of its 81 cases.
//!
//! Each crossing (a 1-D measurement of the crossed axis,
//! [`crate::estimation::fusion::tag_cells`]) gives its normalised
//! innovation squared `d² = y²/S`, `S = P_axis + R`, which has mean 1 for a
//! Gaussian filter whose noise is right. For the EKF and the UKF
//! ([`InnovationTest::MeanNis`]) its exponential average over the crossings
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
//! truncation, the edge constraint's pulls) are not crossings and are not
//! counted: their innovation is large by construction. A range reader
//! gives no crossings, so its filters keep the configured noise.
//!
//! # The particle filter
//! The particle filter takes every read as its cell, not the tracker's
//! crossings; the tracker names the crossing a read would be
//! ([`crate::estimation::fusion::TagCellTracker::crossing`]) and its `d²` is
//! formed against the particles' weighted mean and covariance. The scale
//! multiplies the configured noise, the ceiling of the noise levels
//! ([`crate::estimation::fusion::particle`], "Noise level"): those reach
//! below the configured noise for wheels that slip less, the adaptation
//! above it for wheels that slip more.
//!
//! Its `d²` does not have mean 1 when its noise is right: a cloud of 100
//! particles on three noise levels is narrower than its error, and its
//! `d²` is heavy-tailed. Over the grid's 27 cases at 8 starts each, with the
//! adaptation off, the average `d²` (clipped at 30) was 1.2–6.7 with the
//! noise matched and 0.9–7.0 with it 10× high, so the mean test raised
//! those filters too, and lost 13 grid cases it had won (up to 88 %
//! worse). The particle filter is judged instead by the share of its
//! crossings beyond two standard deviations (`d² > 4`,
//! [`InnovationTest::ShareBeyondTwoSigma`]), an average over about the last
//! fifty crossings: most of them out (the median `d²` above 4) doubles the
//! scale. The same runs put that share at 0.04–0.32 matched and 0.03–0.33
//! 10× high, and at 0.59–0.79 10× low at 1e-4 and 1e-2 m²/m (about one
//! half 5× low). It starts at 0, since the first crossings of a pose still
//! settling are out more often than later ones, and restarts at 0.3 after
//! each change; below 0.1 a raised scale is halved.

/// What a filter's crossings are judged by (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum InnovationTest {
    /// The average `d²` (each clipped at [`NIS_CLIP`]): the EKF and the
    /// UKF, whose `d²` has mean 1 when their noise is right.
    MeanNis,
    /// The share of crossings beyond two standard deviations (`d² > 4`):
    /// the particle filter, whose cloud is narrower than its error even
    /// when its noise is right (module docs, "The particle filter").
    ShareBeyondTwoSigma,
}

/// How [`InnovationTest::MeanNis`] and [`InnovationTest::ShareBeyondTwoSigma`]
/// average and when they change the scale.
struct Rule {
    /// The weight of each crossing's sample in the average.
    weight: f32,
    /// The average above which the scale is doubled.
    raise_above: f32,
    /// The average below which a raised scale is halved.
    lower_below: f32,
    /// The average before the first crossing.
    start: f32,
    /// The average after each change.
    restart: f32,
}

impl InnovationTest {
    /// This test's average and thresholds.
    const fn rule(self) -> Rule {
        match self {
            Self::MeanNis => Rule {
                weight: NIS_AVERAGE_WEIGHT,
                raise_above: RAISE_ABOVE,
                lower_below: LOWER_BELOW,
                start: 1.0,
                restart: 1.0,
            },
            Self::ShareBeyondTwoSigma => Rule {
                weight: SHARE_AVERAGE_WEIGHT,
                raise_above: SHARE_RAISE_ABOVE,
                lower_below: SHARE_LOWER_BELOW,
                start: 0.0,
                restart: SHARE_RESTART,
            },
        }
    }

    /// What one crossing's `d²` adds to the average.
    fn sample(self, nis: f32) -> f32 {
        match self {
            Self::MeanNis => nis.min(NIS_CLIP),
            Self::ShareBeyondTwoSigma => {
                if nis > TWO_SIGMA_NIS {
                    1.0
                } else {
                    0.0
                }
            }
        }
    }
}

/// [`InnovationTest::MeanNis`]: the weight of each crossing's `d²` in the
/// average (about the last ten crossings).
pub const NIS_AVERAGE_WEIGHT: f32 = 0.1;

/// [`InnovationTest::MeanNis`]: the average `d²` above which the wheel
/// noise is doubled.
pub const RAISE_ABOVE: f32 = 4.0;

/// [`InnovationTest::MeanNis`]: the average `d²` below which a raised
/// wheel noise is halved.
pub const LOWER_BELOW: f32 = 0.5;

/// [`InnovationTest::MeanNis`]: the largest `d²` one crossing adds to the
/// average: one alone, from an average of 1, stays below [`RAISE_ABOVE`]
/// (`0.9 + 0.1 · 30 = 3.9`).
pub const NIS_CLIP: f32 = 30.0;

/// [`InnovationTest::ShareBeyondTwoSigma`]: a crossing beyond two standard
/// deviations, `d² > 2²`.
pub const TWO_SIGMA_NIS: f32 = 4.0;

/// [`InnovationTest::ShareBeyondTwoSigma`]: the weight of each crossing in
/// the share (about the last fifty crossings).
pub const SHARE_AVERAGE_WEIGHT: f32 = 0.02;

/// [`InnovationTest::ShareBeyondTwoSigma`]: the share above which the
/// wheel noise is doubled: most crossings beyond two standard deviations,
/// the median `d²` above 4.
pub const SHARE_RAISE_ABOVE: f32 = 0.5;

/// [`InnovationTest::ShareBeyondTwoSigma`]: the share below which a raised
/// wheel noise is halved.
pub const SHARE_LOWER_BELOW: f32 = 0.1;

/// [`InnovationTest::ShareBeyondTwoSigma`]: the share after each change,
/// between the two thresholds. It starts at 0: the first crossings of a
/// pose still settling are far out more often than later ones.
pub const SHARE_RESTART: f32 = 0.3;

/// The largest scale of the configured wheel noise (variance).
pub const MAX_SCALE: f32 = 64.0;

/// The scale of the configured wheel noise (module docs), from the
/// crossings' normalised innovations.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WheelNoiseAdaptation {
    test: InnovationTest,
    /// The average of the crossings' samples ([`InnovationTest`]).
    average: f32,
    scale: f32,
    raised: u32,
    lowered: u32,
}

impl WheelNoiseAdaptation {
    /// At the configured noise (scale 1), no crossing seen, judging the
    /// crossings by `test`.
    #[must_use]
    pub const fn new(test: InnovationTest) -> Self {
        Self {
            test,
            average: test.rule().start,
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
        let rule = self.test.rule();
        self.average = (1.0 - rule.weight) * self.average + rule.weight * self.test.sample(nis);
        let scale = if self.average > rule.raise_above && self.scale < MAX_SCALE {
            self.raised = self.raised.saturating_add(1);
            (2.0 * self.scale).min(MAX_SCALE)
        } else if self.average < rule.lower_below && self.scale > 1.0 {
            self.lowered = self.lowered.saturating_add(1);
            (0.5 * self.scale).max(1.0)
        } else {
            return None;
        };
        self.scale = scale;
        self.average = rule.restart;
        Some(scale)
    }

    /// The test the crossings are judged by.
    #[must_use]
    pub fn test(&self) -> InnovationTest {
        self.test
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
        let mut adaptation = WheelNoiseAdaptation::new(InnovationTest::MeanNis);
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
        let mut adaptation = WheelNoiseAdaptation::new(InnovationTest::MeanNis);
        for nis in [f32::NAN, f32::INFINITY, -1.0] {
            assert_eq!(adaptation.observe(nis), None);
        }
        assert_eq!(
            adaptation,
            WheelNoiseAdaptation::new(InnovationTest::MeanNis)
        );
        // One huge outlier counts 30: 0.9 + 3 = 3.9, not above 4.
        assert_eq!(adaptation.observe(1e9), None);
        assert_eq!(adaptation.scale(), 1.0);
        // A second in a row: 0.9 · 3.9 + 3 = 6.51 raises, once; the
        // restart at 1 keeps a third from raising again alone.
        assert_eq!(adaptation.observe(1e9), Some(2.0));
        assert_eq!(adaptation.observe(1e9), None);
        assert_eq!(adaptation.changes(), (1, 0));
    }

    /// The particle filter's test: crossings that are mostly within two
    /// standard deviations never raise, however far out the others are;
    /// mostly beyond, the scale doubles once the share passes one half,
    /// and comes down again when they return.
    #[test]
    fn the_share_beyond_two_sigma_raises_on_the_median_not_the_tail() {
        // Two crossings in five far out: a mean `d²` of 4.3 raises the mean
        // test, a share of 0.4 does not raise this one.
        let tail = [100.0, 100.0, 0.5, 0.5, 0.5];
        let mut mean = WheelNoiseAdaptation::new(InnovationTest::MeanNis);
        let mut share = WheelNoiseAdaptation::new(InnovationTest::ShareBeyondTwoSigma);
        for nis in tail.iter().cycle().take(1000) {
            let _ = mean.observe(*nis);
            assert_eq!(share.observe(*nis), None);
        }
        assert!(mean.scale() > 1.0, "{mean:?}");
        assert_eq!(share.scale(), 1.0);
        // All far out: the share after n crossings from 0 is 1 − 0.98ⁿ,
        // above one half from the 35th (0.507; the 34th 0.497).
        let mut share = WheelNoiseAdaptation::new(InnovationTest::ShareBeyondTwoSigma);
        let first = (0..1000).find(|_| share.observe(10.0).is_some());
        assert_eq!(first, Some(34));
        // From the restart at 0.3: 1 − 0.7 · 0.98ⁿ > 0.5 from the 17th.
        let second = (0..1000).find(|_| share.observe(10.0).is_some());
        assert_eq!(second, Some(16));
        assert_eq!(share.scale(), 4.0);
        // Back within: 0.3 · 0.98ⁿ < 0.1 from the 55th, twice, to 1.
        let lowered = (0..1000).find(|_| share.observe(0.1).is_some());
        assert_eq!(lowered, Some(54));
        for _ in 0..1000 {
            let _ = share.observe(0.1);
        }
        assert_eq!(share.scale(), 1.0);
        assert_eq!(share.changes(), (2, 2));
        assert_eq!(share.observe(f32::NAN), None);
    }
}
