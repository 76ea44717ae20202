//! The fusion estimator's three filters (EKF, UKF, particle filter) on the
//! same arc, on odometry and position fixes.

use wmr_core::estimation::fusion::particle::{ParticleCore, PoseParticleFilter};
use wmr_core::estimation::fusion::ukf::{PoseUkf, UkfCore};
use wmr_core::estimation::fusion::{
    EkfCore, PoseEkf, PoseFilter, PoseFilterConfig, PoseFilterCore, PositionMeasurement,
};
use wmr_core::geometry::{Pose, Vec2};
use wmr_core::odometry::OdometryStep;

use super::filters::{ARC, Arc, BenchFilter, FILTER_STEP_S, Health, bench_filter, built};
use super::timing::Calibration;

/// The fusion estimator's fix in the bench: the true position, with
/// this variance per axis, m² (a 1 cm fix).
const FUSION_FIX_VARIANCE_M2: f32 = 1e-4;
/// Wheel travel variance per metre of the fusion filters' noise model,
/// m²/m (the UKF and particle filter's tuning in `host-tests`).
const FUSION_WHEEL_VARIANCE_PER_M: f32 = 3e-5;
/// Paper 004's track width `b`, m: the fusion filters' wheel geometry
/// on the [`Arc`].
const FUSION_TRACK_WIDTH_M: f32 = 0.65;
/// A fusion filter's RMS position error must stay below its fixes'.
const MAX_FUSION_RMS_ERROR_M: f32 = 0.014;

/// The particle filter's resamplings, for the fusion filters' health
/// (0 for the Kalman filters).
trait Resamplings {
    fn resamplings(&self) -> u32 {
        0
    }
}

impl Resamplings for EkfCore {}
impl Resamplings for UkfCore {}
impl<const P: usize> Resamplings for ParticleCore<P> {
    fn resamplings(&self) -> u32 {
        self.filter().resamplings()
    }
}

/// The fusion estimator's filters: exact odometry every step and the
/// true position as a 1 cm fix (the worst case: the tracker corrects
/// only when the tag changes).
impl<Core: PoseFilterCore + Resamplings> BenchFilter for PoseFilter<Core> {
    type Input = OdometryStep;
    type Fix = PositionMeasurement;
    const FAULT: &'static str =
        "a fusion filter skipped a step, gated a true fix or lost the robot";
    fn bench_input() -> OdometryStep {
        OdometryStep {
            ds_m: ARC.v_m_s * FILTER_STEP_S,
            dtheta_rad: ARC.omega_rad_s * FILTER_STEP_S,
            ..OdometryStep::default()
        }
    }
    fn bench_fix(arc: &mut Arc) -> PositionMeasurement {
        let _measured = arc.step();
        PositionMeasurement::Point {
            position: arc.pose.position,
            variance_m2: [FUSION_FIX_VARIANCE_M2; 2],
        }
    }
    fn bench_predict(&mut self, odometry: &OdometryStep) {
        self.predict(odometry);
    }
    fn bench_update(&mut self, fix: &PositionMeasurement) {
        // Counted in the filter's counters.
        let _outcome = self.correct(fix);
    }
    fn bench_position(&self) -> Vec2 {
        self.pose().position
    }
    fn bench_health(&self) -> Health {
        let c = self.counters();
        Health {
            faults: c.rejected_predictions + c.fixes_invalid + c.fixes_gated,
            repairs: 0,
            resamplings: self.core().resamplings(),
        }
    }
}

/// The fusion estimator's three filters (the pose and both wheel
/// scales, N = 5), each starting at the true pose with a 1 cm, 0.1 rad
/// spread and a 2 % wheel-scale prior.
#[inline(never)]
pub(super) fn bench_fusion(cal: Calibration) {
    let config = built(
        PoseFilterConfig::new(FUSION_TRACK_WIDTH_M, FUSION_WHEEL_VARIANCE_PER_M, 1e-9, 3.0),
        "fusion filter configuration refused",
    );
    let start = Pose::new(0.0, -1.0, core::f32::consts::FRAC_PI_6);
    let variances = [1e-4, 1e-4, 0.01, 4e-4];
    let mut ekf: PoseEkf = built(
        PoseFilter::new(config, start, variances),
        "fusion EKF refused",
    );
    bench_filter(
        cal,
        "fusion_ekf",
        ["fusion_ekf_predict", "fusion_ekf_update"],
        &mut ekf,
        start,
        MAX_FUSION_RMS_ERROR_M,
    );
    let mut ukf: PoseUkf = built(
        PoseFilter::new(config, start, variances),
        "fusion UKF refused",
    );
    bench_filter(
        cal,
        "fusion_ukf",
        ["fusion_ukf_predict", "fusion_ukf_update"],
        &mut ukf,
        start,
        MAX_FUSION_RMS_ERROR_M,
    );
    let mut pf: PoseParticleFilter = built(
        PoseFilter::new(config, start, variances),
        "fusion particle filter refused",
    );
    bench_filter(
        cal,
        "fusion_pf",
        ["fusion_pf_predict", "fusion_pf_update"],
        &mut pf,
        start,
        MAX_FUSION_RMS_ERROR_M,
    );
}
