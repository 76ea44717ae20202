//! The pose EKF: the prediction of [`crate::estimation::fusion::odometry_noise`]
//! (`P⁺ = F P Fᵀ + G Σ Gᵀ` with the sparse odometry Jacobian) and the
//! Joseph-form correction of [`crate::estimation::fusion::gate`].

use nalgebra::{Matrix2, SMatrix, Vector2};

use crate::estimation::fusion::config::PoseFilterConfig;
use crate::estimation::fusion::gate::{
    PoseCovariance, PoseFilter, PoseFilterCore, PoseState, PositionMeasurement, STATES,
};
use crate::estimation::fusion::odometry_noise::linearise_odometry;
use crate::geometry::Vec2;
use crate::math;
use crate::odometry::OdometryStep;

type Row = SMatrix<f32, 1, STATES>;

/// The pose EKF.
pub type PoseEkf = PoseFilter<EkfCore>;

/// The EKF of the module docs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EkfCore {
    state: PoseState,
    covariance: PoseCovariance,
}

impl PoseFilterCore for EkfCore {
    fn start(
        _config: &PoseFilterConfig,
        mean: &PoseState,
        covariance: &PoseCovariance,
    ) -> Option<Self> {
        let mut core = Self {
            state: PoseState::zeros(),
            covariance: PoseCovariance::zeros(),
        };
        core.reset(mean, covariance).then_some(core)
    }

    fn predict(&mut self, config: &PoseFilterConfig, odometry: &OdometryStep) -> bool {
        let step = linearise_odometry(config, &self.state, odometry);
        let covariance = symmetric(
            step.jacobian * self.covariance * step.jacobian.transpose() + step.process_noise,
        );
        let finite =
            step.state.iter().all(|x| x.is_finite()) && covariance.iter().all(|x| x.is_finite());
        if finite {
            self.state = step.state;
            self.covariance = covariance;
        }
        finite
    }

    fn mean(&self) -> PoseState {
        self.state
    }

    fn covariance(&self) -> PoseCovariance {
        self.covariance
    }

    fn update(&mut self, measurement: &PositionMeasurement) -> bool {
        match *measurement {
            PositionMeasurement::Point { .. } | PositionMeasurement::Ellipse { .. } => measurement
                .position_and_covariance()
                .is_some_and(|(position, r)| self.update_point(position, r)),
            PositionMeasurement::X {
                value_m,
                variance_m2,
            } => self.update_axis(
                Row::from_row_slice(&[1.0, 0.0, 0.0, 0.0, 0.0]),
                value_m,
                variance_m2,
            ),
            PositionMeasurement::Y {
                value_m,
                variance_m2,
            } => self.update_axis(
                Row::from_row_slice(&[0.0, 1.0, 0.0, 0.0, 0.0]),
                value_m,
                variance_m2,
            ),
        }
    }

    fn reset(&mut self, mean: &PoseState, covariance: &PoseCovariance) -> bool {
        let finite = mean.iter().all(|x| x.is_finite()) && covariance.iter().all(|x| x.is_finite());
        if finite {
            self.state = *mean;
            self.state.z = math::wrap_angle(mean.z);
            self.covariance = symmetric(*covariance);
        }
        finite
    }
}

impl EkfCore {
    fn update_point(&mut self, position: Vec2, r: Matrix2<f32>) -> bool {
        let h = SMatrix::<f32, 2, STATES>::from_row_slice(&[
            1.0, 0.0, 0.0, 0.0, 0.0, //
            0.0, 1.0, 0.0, 0.0, 0.0,
        ]);
        let innovation = Vector2::new(position.x - self.state.x, position.y - self.state.y);
        let s = h * self.covariance * h.transpose() + r;
        let Some(s_inv) = s.try_inverse() else {
            return false;
        };
        let gain = self.covariance * h.transpose() * s_inv;
        self.apply(gain * innovation, gain * h, gain * r * gain.transpose())
    }

    fn update_axis(&mut self, h: Row, value: f32, variance: f32) -> bool {
        let innovation = value - (h * self.state).x;
        let s = (h * self.covariance * h.transpose()).x + variance;
        if !(s.is_finite() && s > 0.0) {
            return false;
        }
        let gain = self.covariance * h.transpose() / s;
        self.apply(
            gain * innovation,
            gain * h,
            gain * gain.transpose() * variance,
        )
    }

    /// `x̂ += Δx`, Joseph-form covariance with `KH` and `KRKᵀ`.
    fn apply(
        &mut self,
        correction: PoseState,
        gain_h: PoseCovariance,
        gain_r_gain: PoseCovariance,
    ) -> bool {
        let mut state = self.state + correction;
        state.z = math::wrap_angle(state.z);
        let keep = PoseCovariance::identity() - gain_h;
        let covariance = symmetric(keep * self.covariance * keep.transpose() + gain_r_gain);
        let finite =
            state.iter().all(|x| x.is_finite()) && covariance.iter().all(|x| x.is_finite());
        if finite {
            self.state = state;
            self.covariance = covariance;
        }
        finite
    }
}

pub(crate) fn symmetric(m: PoseCovariance) -> PoseCovariance {
    (m + m.transpose()) * 0.5
}
