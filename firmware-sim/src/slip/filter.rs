//! The state estimator of a slip run: the core's EKF, UKF or particle
//! filter on the 3-state (scenario 1) or 5-state (scenario 2) model, or the
//! true state.

use wmr_core::filters::ekf::ExtendedKalmanFilter;
use wmr_core::filters::particle_filter::ParticleFilter;
use wmr_core::filters::ukf::UnscentedKalmanFilter;
use wmr_core::geometry::BodyVelocity;
use wmr_papers::slip_tracking::{PoseModel, PoseWheelModel};

/// Particles of the particle filter (paper: 100). A const generic of the
/// core's `ParticleFilter`: a scenario must ask for exactly this many.
pub const PARTICLES: usize = 100;

/// A diagonal matrix as nested arrays (column-major, as `nalgebra`'s
/// `From<[[T; R]; C]>` takes them).
pub(super) fn diag<const N: usize>(d: [f32; N]) -> [[f32; N]; N] {
    let mut m = [[0.0; N]; N];
    for (i, row) in m.iter_mut().enumerate() {
        row[i] = d[i];
    }
    m
}

pub(super) fn first<const N: usize>(a: [f32; 5]) -> [f32; N] {
    std::array::from_fn(|i| a[i])
}

/// The state estimator of a run.
// One per run: the size difference between the variants does not matter.
#[allow(clippy::large_enum_variant)]
pub(super) enum Filter {
    Exact,
    Ekf3(ExtendedKalmanFilter<PoseModel, 3, 3>),
    Ekf5(ExtendedKalmanFilter<PoseWheelModel, 5, 5>),
    Ukf3(UnscentedKalmanFilter<PoseModel, 3, 3, 7>),
    Ukf5(UnscentedKalmanFilter<PoseWheelModel, 5, 5, 11>),
    Pf3(Box<ParticleFilter<PoseModel, 3, 3, PARTICLES>>),
    Pf5(Box<ParticleFilter<PoseWheelModel, 5, 5, PARTICLES>>),
}

impl Filter {
    /// Updates on a measurement; the estimate (the truth for `Exact`;
    /// zero wheel speeds for the 3-state filters).
    pub(super) fn update(&mut self, truth: &[f64; 5], z: &[f32; 5]) -> [f64; 5] {
        let three = |e: [f32; 3]| [f64::from(e[0]), f64::from(e[1]), f64::from(e[2]), 0.0, 0.0];
        let five = |e: [f32; 5]| e.map(f64::from);
        match self {
            Self::Exact => *truth,
            Self::Ekf3(f) => {
                f.update(&first::<3>(*z).into());
                let s = f.state();
                three([s[0], s[1], s[2]])
            }
            Self::Ekf5(f) => {
                f.update(&(*z).into());
                let s = f.state();
                five([s[0], s[1], s[2], s[3], s[4]])
            }
            Self::Ukf3(f) => {
                f.update(&first::<3>(*z).into());
                let s = f.state();
                three([s[0], s[1], s[2]])
            }
            Self::Ukf5(f) => {
                f.update(&(*z).into());
                let s = f.state();
                five([s[0], s[1], s[2], s[3], s[4]])
            }
            Self::Pf3(f) => {
                f.update(&first::<3>(*z).into());
                let s = f.estimate();
                three([s[0], s[1], s[2]])
            }
            Self::Pf5(f) => {
                f.update(&(*z).into());
                let s = f.estimate();
                five([s[0], s[1], s[2], s[3], s[4]])
            }
        }
    }

    pub(super) fn predict(&mut self, u: &BodyVelocity, h: f32) {
        match self {
            Self::Exact => {}
            Self::Ekf3(f) => {
                f.predict(u, h);
            }
            Self::Ekf5(f) => {
                f.predict(u, h);
            }
            Self::Ukf3(f) => {
                f.predict(u, h);
            }
            Self::Ukf5(f) => {
                f.predict(u, h);
            }
            Self::Pf3(f) => f.predict(u, h),
            Self::Pf5(f) => f.predict(u, h),
        }
    }
}
