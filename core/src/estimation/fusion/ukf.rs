//! The fusion estimator's pose filter as an unscented Kalman filter: the
//! state, odometry noise model, tag measurements, gate and re-localisation
//! of [`crate::estimation::fusion`] (whose module docs this follows), with the
//! prediction done by paper 004's UKF ([`crate::filters::ukf`]) instead of the
//! EKF's linearisation.
//!
//! # Prediction
//! The 11 Merwe sigma points of `(x, y, θ, ε_R, ε_L)` are each moved along
//! the exact arc of their own wheel travels `(1 + ε) s` (as the EKF's
//! mean, [`crate::estimation::fusion`], "Prediction"). The prior mean is
//! the centre point's image, the mean moved along its own arc, and the
//! prior covariance the points' spread about it plus `Q`
//! ([`UnscentedKalmanFilter::with_centre_mean`]): the points' weighted
//! mean would add the second-order term of the heading's spread, `ds cos θ̂
//! (E[cos δ] − 1)` along the motion (Julier & Uhlmann 2004, section IV;
//! Gustafsson & Hendeby 2012, "Some relations between extended and
//! unscented Kalman filters", IEEE Trans. Signal Processing 60(2), whose
//! EKF2 carries the same term), the expected shortening of a step whose
//! heading is uncertain. The robot moves its full step along its one
//! heading, and along a row of tags, where only the crossings along the
//! path are seen and the heading's variance grows unobserved (0.05 rad²/m
//! at the template's 1e-3 m²/m), that term made every crossing find the
//! estimate up to 11 mm short of the boundary; those one-signed
//! innovations drove the heading through the points' position–heading
//! covariance until it oscillated (docs/fusion.md, "The UKF at the default
//! wheel noise": 0.103 m worst error on the template's figure-eight, 0.0057
//! m with the centre mean, the EKF's 0.0056). The points still carry the
//! covariance through the nonlinear arc. `Q = G Σ Gᵀ` (the wheel
//! travel noise mapped into the pose at the current mean, and the scale
//! errors' random walk) is the EKF's, set before each step
//! ([`UnscentedKalmanFilter::set_process_noise`]): additive process noise,
//! as in FilterPy.
//!
//! Sigma points: `α = 1`, `β = 2`, `κ = 0`: every weight is ≥ 0
//! (`W₀ᵐ = 0`, `Wᵢ = 1/10`), which the circular mean of the heading needs
//! (a negative centre weight, as with `κ = 3 − n`, turns the circular mean
//! of a wide heading spread half a turn around), and the points sit at
//! `±√5 σ`. The odometry step carries the motion; the UKF's `dt` is not
//! used (0).
//!
//! # The heading's spread
//! A heading sigma point more than half a turn from the mean wraps to the
//! other side and the spread it stood for is lost, so the heading's
//! variance is capped at [`HEADING_VARIANCE_CAP`] = `(0.9π/√5)²` (σθ ≤ 1.26
//! rad, 72°): at start, where the heading is unknown (the filter's
//! `σθ = π`), at every reset, and after any step that exceeds it. The cap
//! scales the heading's row and column of `P` together, which keeps `P`
//! positive definite and the heading's correlations. An unknown heading
//! (uniform on the circle, σ = 1.81 rad) is then claimed a little tighter
//! than it is: the gate and re-localisation of [`crate::estimation::fusion`], and
//! the fusion estimator's guide, deal with the wrong locks this allows.

//! # Correction
//! The update draws its sigma points from the prior `(x⁻, P⁻)`
//! ([`UnscentedKalmanFilter::with_redrawn_update_points`], FilterPy after
//! 1.4.5), not from the propagated points, which predate `Q`: here `Q` per
//! step (wheel noise over 2.5 mm of travel, ~1e-6 m²) is as large as a
//! boundary crossing's `R`, and 1.4.5's reuse left `P_xx` twice what the
//! Kalman filter gives after each crossing (measured: 2.1e-6 against
//! 1.0e-6 m²), so the filter fell behind its fixes. A fix is linear in the
//! state (`H` selects `x`, `y` or both), so the innovation covariance of
//! the points is exactly `H P Hᵀ + R`: the Mahalanobis gate of
//! [`crate::estimation::fusion`] applies unchanged. A 2-D fix is the UKF's
//! `update(z, R)`; a 1-D one updates the measured component alone
//! ([`UnscentedKalmanFilter::update_component`]).
//!
//! # Positive definiteness
//! The sigma points need a Cholesky factor of `P`, so `P` must be positive
//! definite. A wheel-scale error that is not estimated (prior variance 0)
//! and a heading reset to variance 0 would make it singular: every
//! variance is floored at [`VARIANCE_FLOOR`] (σ = 10⁻⁵, i.e. 10 ppm of
//! wheel scale or 0.01 mm, far below anything the tags resolve) at start
//! and reset, and `Q` adds 10⁻⁴ of it per step to the scale errors (so
//! that their variance never decays to 0 between fixes). A failed
//! factorisation is then repaired or reset by the UKF itself (counted in
//! its counters, [`UkfCore::filter`]).
//!
//! # Cost
//! 11 sigma points, each one odometry arc (a `sin`, `cos` and `sinc`), a
//! 5×5 Cholesky per step and per fix, and `Q` from the EKF's
//! linearisation: see the bench table in docs/budgets.md.

use nalgebra::{Matrix2, SVector, Vector2};

use crate::estimation::fusion::config::PoseFilterConfig;
use crate::estimation::fusion::gate::{
    PoseCovariance, PoseFilter, PoseFilterCore, PoseState, PositionMeasurement,
};
use crate::estimation::fusion::odometry_noise::{linearise_odometry, odometry_transition};
use crate::filters::ukf::{
    AngleComponents, MerweScaledSigmaPoints, UkfModel, UnscentedKalmanFilter,
};
use crate::math;
use crate::odometry::OdometryStep;

/// Sigma-point spread `α` (module docs).
pub const SIGMA_POINT_ALPHA: f32 = 1.0;
/// Prior-knowledge term `β` (2: Gaussian).
pub const SIGMA_POINT_BETA: f32 = 2.0;
/// Secondary scaling `κ`.
pub const SIGMA_POINT_KAPPA: f32 = 0.0;
/// The largest heading variance the filter holds (module docs), rad²:
/// `(0.9π/√5)²`, so that the heading's sigma points (at `±√5 σ`) stay
/// within 0.9π of the mean.
pub const HEADING_VARIANCE_CAP: f32 = 0.81 * core::f32::consts::PI * core::f32::consts::PI / 5.0;
/// The smallest variance any state keeps (module docs), state units².
pub const VARIANCE_FLOOR: f32 = 1e-10;

/// What `Q` adds to each scale error's variance per step (module docs).
const SCALE_VARIANCE_PER_STEP: f32 = VARIANCE_FLOOR * 1e-4;

/// The heading's index in the state.
const HEADING: [usize; 1] = [2];

/// The pose on odometry, for the UKF: wheel travels scaled by `(1 + ε)`,
/// exact arc; the measurement is the position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometryPoseModel {
    track_width_m: f32,
}

impl UkfModel<5, 2> for OdometryPoseModel {
    type Input = OdometryStep;

    fn input_is_finite(&self, u: &OdometryStep) -> bool {
        u.ds_m.is_finite() && u.dtheta_rad.is_finite()
    }

    fn transition(&self, x: &PoseState, u: &OdometryStep, _dt_s: f32) -> PoseState {
        odometry_transition(x, u, self.track_width_m)
    }

    fn measure(&self, x: &PoseState) -> SVector<f32, 2> {
        Vector2::new(x.x, x.y)
    }

    fn angles(&self) -> AngleComponents<5, 2> {
        const ANGLES: AngleComponents<5, 2> = AngleComponents::from_indices(&HEADING, &[]);
        ANGLES
    }
}

/// The UKF as a [`PoseFilterCore`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UkfCore {
    filter: UnscentedKalmanFilter<OdometryPoseModel, 5, 2, 11>,
}

/// The pose UKF.
pub type PoseUkf = PoseFilter<UkfCore>;

/// `covariance` with its diagonal floored at [`VARIANCE_FLOOR`] and the
/// heading's variance capped at [`HEADING_VARIANCE_CAP`] (its row and
/// column scaled together; module docs).
fn conditioned(covariance: &PoseCovariance) -> PoseCovariance {
    let mut c = *covariance;
    for i in 0..5 {
        if let Some(v) = c.get_mut((i, i)) {
            *v = v.max(VARIANCE_FLOOR);
        }
    }
    if c.m33 > HEADING_VARIANCE_CAP {
        let scale = math::sqrt(HEADING_VARIANCE_CAP / c.m33);
        c.row_mut(2).scale_mut(scale);
        c.column_mut(2).scale_mut(scale);
        // Exactly the cap, whatever the rounding of scale².
        c.m33 = HEADING_VARIANCE_CAP;
    }
    c
}

impl UkfCore {
    /// The UKF inside (its counters say what it skipped or repaired).
    #[must_use]
    pub fn filter(&self) -> &UnscentedKalmanFilter<OdometryPoseModel, 5, 2, 11> {
        &self.filter
    }
}

impl PoseFilterCore for UkfCore {
    fn start(
        config: &PoseFilterConfig,
        mean: &PoseState,
        covariance: &PoseCovariance,
    ) -> Option<Self> {
        let points =
            MerweScaledSigmaPoints::new(SIGMA_POINT_ALPHA, SIGMA_POINT_BETA, SIGMA_POINT_KAPPA)
                .ok()?;
        let model = OdometryPoseModel {
            track_width_m: config.track_width_m(),
        };
        // R is given with every fix; this one is never used.
        let r = Matrix2::identity();
        UnscentedKalmanFilter::new(
            model,
            points,
            *mean,
            conditioned(covariance),
            PoseCovariance::zeros(),
            r,
        )
        .ok()
        .map(|filter| Self {
            filter: filter.with_redrawn_update_points().with_centre_mean(),
        })
    }

    fn predict(&mut self, config: &PoseFilterConfig, odometry: &OdometryStep) -> bool {
        let mean = *self.filter.state();
        let mut q = linearise_odometry(config, &mean, odometry).process_noise();
        q.m44 += SCALE_VARIANCE_PER_STEP;
        q.m55 += SCALE_VARIANCE_PER_STEP;
        let applied = self.filter.set_process_noise(q).is_ok()
            && self.filter.predict(odometry, 0.0).is_applied();
        if applied && self.filter.covariance().m33 > HEADING_VARIANCE_CAP {
            let (mean, covariance) = (*self.filter.state(), *self.filter.covariance());
            // A covariance the UKF refuses stays as it is (its own repair
            // deals with it at the next step).
            let _ = self.filter.reset(mean, conditioned(&covariance));
        }
        applied
    }

    fn mean(&self) -> PoseState {
        *self.filter.state()
    }

    fn covariance(&self) -> PoseCovariance {
        *self.filter.covariance()
    }

    fn update(&mut self, measurement: &PositionMeasurement) -> bool {
        let outcome = match *measurement {
            PositionMeasurement::Point { .. } | PositionMeasurement::Ellipse { .. } => {
                let Some((position, r)) = measurement.position_and_covariance() else {
                    return false;
                };
                self.filter
                    .update_with_noise(&Vector2::new(position.x, position.y), &r)
            }
            PositionMeasurement::X {
                value_m,
                variance_m2,
            } => self.filter.update_component(0, value_m, variance_m2),
            PositionMeasurement::Y {
                value_m,
                variance_m2,
            } => self.filter.update_component(1, value_m, variance_m2),
        };
        outcome.is_applied()
    }

    fn reset(&mut self, mean: &PoseState, covariance: &PoseCovariance) -> bool {
        self.filter.reset(*mean, conditioned(covariance)).is_ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimation::fusion::test_support::stays_finite;
    use crate::estimation::fusion::{FixOutcome, PoseEkf};
    use crate::geometry::Pose;
    use proptest::prelude::*;

    fn config() -> PoseFilterConfig {
        PoseFilterConfig::new(0.2, 1e-4, 1e-9, 3.0).unwrap()
    }

    fn arc(k: u32) -> OdometryStep {
        OdometryStep {
            ds_m: 0.002,
            dtheta_rad: if k % 200 < 100 { 0.004 } else { -0.003 },
            ..OdometryStep::default()
        }
    }

    /// With a small heading variance the odometry is nearly linear over a
    /// tick and the UKF is the EKF: the same fixes from a 1 cm, 0.05 rad
    /// start give the same estimate within 0.5 mm and 2 mrad.
    #[test]
    fn near_linear_it_agrees_with_the_ekf() {
        let start = Pose::new(0.0, 0.0, 0.3);
        let variances = [1e-4, 1e-4, 2.5e-3, 0.0];
        let mut ekf = PoseEkf::new(config(), start, variances).unwrap();
        let mut ukf = PoseUkf::new(config(), start, variances).unwrap();
        let mut truth = Pose::new(0.01, -0.005, 0.35);
        let mut worst = (0.0_f32, 0.0_f32);
        for k in 0..2000 {
            let step = arc(k);
            truth = truth.advance_arc(step.ds_m, step.dtheta_rad);
            ekf.predict(&step);
            ukf.predict(&step);
            if k % 25 == 24 {
                let fix = PositionMeasurement::Point {
                    position: truth.position,
                    variance_m2: [1e-4, 1e-4],
                };
                assert_eq!(ekf.correct(&fix), FixOutcome::Used);
                assert_eq!(ukf.correct(&fix), FixOutcome::Used);
            }
            let (e, u) = (ekf.pose(), ukf.pose());
            worst.0 = worst.0.max((e.position - u.position).norm());
            worst.1 = worst
                .1
                .max(math::wrap_angle(e.heading_rad - u.heading_rad).abs());
        }
        assert!(worst.0 < 5e-4 && worst.1 < 2e-3, "{worst:?}");
        assert_eq!(ukf.counters().rejected_predictions, 0);
        assert_eq!(
            ukf.core().filter().counters(),
            crate::filters::ukf::UkfCounters::default()
        );
    }

    /// Along a row of tags the heading's variance grows unobserved; the
    /// prior mean still moves the whole step along the mean heading (the
    /// centre mean, module docs), as the EKF's does: 0.4 rad² of heading
    /// variance (the template's 1e-3 m²/m after 8 m of a row), 10 cm driven
    /// in 2.5 mm steps along `x`. The points' mean would fall 17 mm short.
    #[test]
    fn a_wide_heading_does_not_shorten_the_step() {
        let config = PoseFilterConfig::new(0.2, 1e-3, 1e-9, 3.0).unwrap();
        let start = Pose::new(0.0, 0.0, 0.0);
        let variances = [1e-6, 1e-6, 0.4, 0.0];
        let mut ekf = PoseEkf::new(config, start, variances).unwrap();
        let mut ukf = PoseUkf::new(config, start, variances).unwrap();
        let step = OdometryStep {
            ds_m: 0.0025,
            ..OdometryStep::default()
        };
        for _ in 0..40 {
            ekf.predict(&step);
            ukf.predict(&step);
        }
        let (e, u) = (ekf.pose().position, ukf.pose().position);
        assert!((u.x - 0.1).abs() < 1e-5 && u.y.abs() < 1e-6, "{u:?}");
        assert!((u - e).norm() < 1e-5, "{u:?} {e:?}");
        // The points still carry the spread through the arc: the cross-track
        // variance is the points' `Σ W (d sin δ)²`, half the EKF's `d² σθ²`
        // (`sin² (√5 σθ)` at weight 0.2 is 0.195 against `σθ²` = 0.4).
        let (pe, pu) = (ekf.covariance(), ukf.covariance());
        let ratio = pu.m22 / pe.m22;
        assert!(ratio > 0.4 && ratio < 0.6, "{} {}", pu.m22, pe.m22);
    }

    /// An unknown heading (`σθ = π`) is held at the cap, and so is a
    /// heading reset wider than it; the position variances are untouched.
    #[test]
    fn the_heading_variance_is_capped() {
        let pi2 = core::f32::consts::PI * core::f32::consts::PI;
        let mut ukf =
            PoseUkf::new(config(), Pose::new(1.0, 2.0, 0.0), [0.01, 0.02, pi2, 0.0]).unwrap();
        let c = ukf.covariance();
        assert_eq!(c.m33, HEADING_VARIANCE_CAP);
        assert_eq!((c.m11, c.m22, c.m44), (0.01, 0.02, VARIANCE_FLOOR));
        assert!(ukf.reset_heading(1.0, 10.0));
        assert_eq!(ukf.covariance().m33, HEADING_VARIANCE_CAP);
        assert!((ukf.pose().heading_rad - 1.0).abs() < 1e-6);
        assert!(!ukf.reset_heading(f32::NAN, 0.1));
    }

    proptest! {
        /// Finite or not, no input leaves the estimate non-finite.
        #[test]
        fn finite_out_on_any_input(
            steps in proptest::collection::vec((-1.0f32..1.0, -1.0f32..1.0, any::<bool>()), 1..40),
            fixes in proptest::collection::vec((-100.0f32..100.0, -100.0f32..100.0, 0u8..5), 1..40),
        ) {
            let mut filter = PoseUkf::new(config(), Pose::new(0.0, 0.0, 0.0), [1.0, 1.0, 9.0, 4e-4]).unwrap();
            prop_assert!(stays_finite(&mut filter, &steps, &fixes));
        }
    }
}
