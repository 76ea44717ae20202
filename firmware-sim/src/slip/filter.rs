//! The state estimator of a slip run: the core's EKF, UKF or particle
//! filter on the 3-state (scenario 1) or 5-state (scenario 2) model, or the
//! true state.

use wmr_core::filters::ekf::ExtendedKalmanFilter;
use wmr_core::filters::particle_filter::{
    ParticleFilter, ParticleFilterConfig, ParticleFilterError, ParticleModel,
};
use wmr_core::filters::ukf::UnscentedKalmanFilter;
use wmr_core::geometry::BodyVelocity;
use wmr_papers::slip_tracking::{PoseModel, PoseWheelModel};

/// Particles of the particle filter by default (paper: 100).
pub const PARTICLES: usize = 100;

/// The particle counts a scenario may ask for (the paper's 100, and 300
/// and 1,000). The count is a const generic of the core's
/// `ParticleFilter`, so each is one instantiation built into the
/// simulator (the enum `Particles`); others are refused at validation.
pub const PARTICLE_COUNTS: [usize; 3] = [100, 300, 1000];

/// A particle filter with one of [`PARTICLE_COUNTS`] particles, boxed (the
/// 1,000-particle 5-state filter is 48 KB).
pub(super) enum Particles<Model: ParticleModel<N, N>, const N: usize> {
    P100(Box<ParticleFilter<Model, N, N, 100>>),
    P300(Box<ParticleFilter<Model, N, N, 300>>),
    P1000(Box<ParticleFilter<Model, N, N, 1000>>),
}

impl<Model, const N: usize> Particles<Model, N>
where
    Model: ParticleModel<N, N, Input = BodyVelocity>,
{
    /// The filter with `count` particles; `None` for a count not in
    /// [`PARTICLE_COUNTS`].
    pub(super) fn new(
        count: usize,
        model: Model,
        config: ParticleFilterConfig<N, N>,
        x0: [f32; N],
        prior_std: [f32; N],
        seed: u64,
    ) -> Option<Result<Self, ParticleFilterError>> {
        let (x0, prior_std) = (x0.into(), prior_std.into());
        Some(match count {
            100 => ParticleFilter::new(model, config, x0, prior_std, seed)
                .map(|f| Self::P100(Box::new(f))),
            300 => ParticleFilter::new(model, config, x0, prior_std, seed)
                .map(|f| Self::P300(Box::new(f))),
            1000 => ParticleFilter::new(model, config, x0, prior_std, seed)
                .map(|f| Self::P1000(Box::new(f))),
            _ => return None,
        })
    }

    fn predict(&mut self, u: &BodyVelocity, h: f32) {
        match self {
            Self::P100(f) => f.predict(u, h),
            Self::P300(f) => f.predict(u, h),
            Self::P1000(f) => f.predict(u, h),
        }
    }

    /// Updates on `z`; the estimate.
    fn update(&mut self, z: [f32; N]) -> [f32; N] {
        let z = z.into();
        let estimate = match self {
            Self::P100(f) => {
                f.update(&z);
                f.estimate()
            }
            Self::P300(f) => {
                f.update(&z);
                f.estimate()
            }
            Self::P1000(f) => {
                f.update(&z);
                f.estimate()
            }
        };
        estimate.into()
    }
}

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
    Pf3(Particles<PoseModel, 3>),
    Pf5(Particles<PoseWheelModel, 5>),
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
                let s = f.update(first::<3>(*z));
                three([s[0], s[1], s[2]])
            }
            Self::Pf5(f) => {
                let s = f.update(*z);
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
