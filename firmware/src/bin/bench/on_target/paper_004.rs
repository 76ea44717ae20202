//! Paper 004's nonlinear filters, set up as `host_tests::paper_004` sets
//! them up: the EKF, the UKF in both forms and the particle filter with
//! either proposal, on scenario 1's and scenario 2's models.

use nalgebra::{SMatrix, SVector};
use wmr_core::filters::ekf::{EkfModel, ExtendedKalmanFilter};
use wmr_core::filters::particle_filter::{
    ParticleFilter, ParticleFilterConfig, ParticleModel, Proposal,
};
use wmr_core::filters::ukf::{MerweScaledSigmaPoints, UkfForm, UkfModel, UnscentedKalmanFilter};
use wmr_core::geometry::{BodyVelocity, Pose, Vec2};
use wmr_core::math;
use wmr_papers::slip_tracking::{PoseModel, PoseWheelModel};

use super::filters::{
    ARC, Arc, BenchFilter, FILTER_STEP_S, Health, MEASUREMENT_VARIANCE, bench_filter, built,
};
use super::timing::Calibration;

/// `Q` per step (`host_tests::paper_004::PROCESS_NOISE`).
const PROCESS_VARIANCE: [f32; 5] = [1e-5, 1e-5, 1e-5, 1e-2, 1e-2];
/// `P0 = 10 I` (EKF; the particle filter's prior).
const INITIAL_VARIANCE: [f32; 5] = [10.0; 5];
/// The UKF's `P0`: heading variance 1 rad² (its circular mean turns
/// around above ~2 rad², `wmr_core::filters::ukf` docs).
const UKF_INITIAL_VARIANCE: [f32; 5] = [10.0, 10.0, 1.0, 10.0, 10.0];
/// Particles (paper 004).
const PARTICLES: usize = 100;
/// The particle filter's process noise per step, standard deviations
/// (`host_tests::paper_004::PARTICLE_PROCESS_STD`).
const PARTICLE_PROCESS_STD: [f32; 5] = [0.01, 0.01, 0.02, 0.5, 0.5];
/// The particle filter's generator seed.
const PARTICLE_SEED: u64 = 4;
/// Every filter's RMS position error over the sampled steps must stay
/// below the measurements' own (`√(0.1 + 0.1)` m): no worse than not
/// filtering. Measured: EKF and UKF 0.015 m, particle filters 0.04 to
/// 0.22 m (micromath, N = 5).
const MAX_FILTER_RMS_ERROR_M: f32 = 0.45;

/// Paper 004's filters: the auxiliary `(v, ω)` of the arc over a
/// step, and the first `N` components of the arc's noisy measured state.
const PAPER_004_FAULT: &str = "a paper 004 filter skipped a step or lost the robot";

fn paper_004_input() -> (BodyVelocity, f32) {
    (ARC, FILTER_STEP_S)
}

fn paper_004_fix<const N: usize>(arc: &mut Arc) -> SVector<f32, N> {
    arc.step().fixed_rows::<N>(0).into_owned()
}

fn position_of<const N: usize>(x: &SVector<f32, N>) -> Vec2 {
    Vec2::new(
        x.get(0).copied().unwrap_or(f32::NAN),
        x.get(1).copied().unwrap_or(f32::NAN),
    )
}

impl<Model, const N: usize> BenchFilter for ExtendedKalmanFilter<Model, N, N>
where
    Model: EkfModel<N, N, Input = BodyVelocity>,
{
    type Input = (BodyVelocity, f32);
    type Fix = SVector<f32, N>;
    const FAULT: &'static str = PAPER_004_FAULT;
    fn bench_input() -> Self::Input {
        paper_004_input()
    }
    fn bench_fix(arc: &mut Arc) -> Self::Fix {
        paper_004_fix(arc)
    }
    fn bench_predict(&mut self, (u, dt_s): &(BodyVelocity, f32)) {
        // Counted in the filter's counters (`bench_health`).
        let _outcome = self.predict(u, *dt_s);
    }
    fn bench_update(&mut self, z: &SVector<f32, N>) {
        let _outcome = self.update(z);
    }
    fn bench_position(&self) -> Vec2 {
        position_of(self.state())
    }
    fn bench_health(&self) -> Health {
        let c = self.counters();
        Health {
            faults: c.rejected_predictions + c.rejected_updates + c.singular_innovations,
            ..Health::default()
        }
    }
}

impl<Model, const N: usize, const S: usize> BenchFilter for UnscentedKalmanFilter<Model, N, N, S>
where
    Model: UkfModel<N, N, Input = BodyVelocity>,
{
    type Input = (BodyVelocity, f32);
    type Fix = SVector<f32, N>;
    const FAULT: &'static str = PAPER_004_FAULT;
    fn bench_input() -> Self::Input {
        paper_004_input()
    }
    fn bench_fix(arc: &mut Arc) -> Self::Fix {
        paper_004_fix(arc)
    }
    fn bench_predict(&mut self, (u, dt_s): &(BodyVelocity, f32)) {
        // Counted in the filter's counters (`bench_health`).
        let _outcome = self.predict(u, *dt_s);
    }
    fn bench_update(&mut self, z: &SVector<f32, N>) {
        let _outcome = self.update(z);
    }
    fn bench_position(&self) -> Vec2 {
        position_of(self.state())
    }
    fn bench_health(&self) -> Health {
        let c = self.counters();
        Health {
            faults: c.rejected_inputs
                + c.non_finite_results
                + c.singular_innovations
                + c.covariance_resets,
            repairs: c.covariance_repairs,
            resamplings: 0,
        }
    }
}

impl<Model, const N: usize, const P: usize> BenchFilter for ParticleFilter<Model, N, N, P>
where
    Model: ParticleModel<N, N, Input = BodyVelocity>,
{
    type Input = (BodyVelocity, f32);
    type Fix = SVector<f32, N>;
    const FAULT: &'static str = PAPER_004_FAULT;
    fn bench_input() -> Self::Input {
        paper_004_input()
    }
    fn bench_fix(arc: &mut Arc) -> Self::Fix {
        paper_004_fix(arc)
    }
    fn bench_predict(&mut self, (u, dt_s): &(BodyVelocity, f32)) {
        self.predict(u, *dt_s);
    }
    fn bench_update(&mut self, z: &SVector<f32, N>) {
        self.update(z);
    }
    fn bench_position(&self) -> Vec2 {
        position_of(&self.estimate())
    }
    fn bench_health(&self) -> Health {
        let c = self.counters();
        Health {
            faults: c.rejected_inputs + c.collapses + c.dropped_particles,
            repairs: 0,
            resamplings: c.resamplings,
        }
    }
}

/// The first `N` components of a 5-vector.
fn head<const N: usize>(x: &SVector<f32, 5>) -> SVector<f32, N> {
    x.fixed_rows::<N>(0).into_owned()
}

/// `diag(values[..N])`.
fn diagonal<const N: usize>(values: [f32; 5]) -> SMatrix<f32, N, N> {
    SMatrix::from_diagonal(&head(&SVector::from(values)))
}

/// Paper 004's EKF, UKF and particle filter on scenario 1's
/// `PoseModel` (N = 3) and scenario 2's `PoseWheelModel` (N = 5), set
/// up as `host_tests::paper_004` sets them up (each starts at the true
/// state; the particle filter's state, 2.9 KB and 4.6 KB, lives in this
/// function's frame).
#[inline(never)]
pub(super) fn bench_paper_004(cal: Calibration) {
    let scenario_1 = Pose::new(0.0, -1.5, core::f32::consts::FRAC_PI_4);
    let scenario_2 = Pose::new(0.0, -1.0, core::f32::consts::FRAC_PI_6);
    let (x1, x2) = (Arc::new(scenario_1).state(), Arc::new(scenario_2).state());
    let (q, r) = (PROCESS_VARIANCE, MEASUREMENT_VARIANCE);

    let mut ekf3 = built(
        ExtendedKalmanFilter::new(
            PoseModel,
            head::<3>(&x1),
            diagonal(INITIAL_VARIANCE),
            diagonal(q),
            diagonal(r),
        ),
        "EKF (N = 3) refused",
    );
    bench_filter(
        cal,
        "ekf3",
        ["ekf3_predict", "ekf3_update"],
        &mut ekf3,
        scenario_1,
        MAX_FILTER_RMS_ERROR_M,
    );
    let mut ekf5 = built(
        ExtendedKalmanFilter::new(
            PoseWheelModel,
            x2,
            diagonal(INITIAL_VARIANCE),
            diagonal(q),
            diagonal(r),
        ),
        "EKF (N = 5) refused",
    );
    bench_filter(
        cal,
        "ekf5",
        ["ekf5_predict", "ekf5_update"],
        &mut ekf5,
        scenario_2,
        MAX_FILTER_RMS_ERROR_M,
    );

    let mut ukf3 = built(
        MerweScaledSigmaPoints::paper().and_then(|points| {
            UnscentedKalmanFilter::<_, 3, 3, 7>::new(
                PoseModel,
                points,
                head(&x1),
                diagonal(UKF_INITIAL_VARIANCE),
                diagonal(q),
                diagonal(r),
            )
        }),
        "UKF (N = 3) refused",
    );
    bench_filter(
        cal,
        "ukf3",
        ["ukf3_predict", "ukf3_update"],
        &mut ukf3,
        scenario_1,
        MAX_FILTER_RMS_ERROR_M,
    );
    let mut ukf5 = built(
        MerweScaledSigmaPoints::paper().and_then(|points| {
            UnscentedKalmanFilter::<_, 5, 5, 11>::new(
                PoseWheelModel,
                points,
                x2,
                diagonal(UKF_INITIAL_VARIANCE),
                diagonal(q),
                diagonal(r),
            )
        }),
        "UKF (N = 5) refused",
    );
    bench_filter(
        cal,
        "ukf5",
        ["ukf5_predict", "ukf5_update"],
        &mut ukf5,
        scenario_2,
        MAX_FILTER_RMS_ERROR_M,
    );
    // The square-root form of the same two filters.
    let mut srukf3 = built(
        MerweScaledSigmaPoints::paper().and_then(|points| {
            UnscentedKalmanFilter::<_, 3, 3, 7>::new(
                PoseModel,
                points,
                head(&x1),
                diagonal(UKF_INITIAL_VARIANCE),
                diagonal(q),
                diagonal(r),
            )?
            .with_form(UkfForm::SquareRoot)
        }),
        "square-root UKF (N = 3) refused",
    );
    bench_filter(
        cal,
        "srukf3",
        ["srukf3_predict", "srukf3_update"],
        &mut srukf3,
        scenario_1,
        MAX_FILTER_RMS_ERROR_M,
    );
    let mut srukf5 = built(
        MerweScaledSigmaPoints::paper().and_then(|points| {
            UnscentedKalmanFilter::<_, 5, 5, 11>::new(
                PoseWheelModel,
                points,
                x2,
                diagonal(UKF_INITIAL_VARIANCE),
                diagonal(q),
                diagonal(r),
            )?
            .with_form(UkfForm::SquareRoot)
        }),
        "square-root UKF (N = 5) refused",
    );
    bench_filter(
        cal,
        "srukf5",
        ["srukf5_predict", "srukf5_update"],
        &mut srukf5,
        scenario_2,
        MAX_FILTER_RMS_ERROR_M,
    );

    let prior = [
        ("pf3", ["pf3_predict", "pf3_update"]),
        ("pf5", ["pf5_predict", "pf5_update"]),
    ];
    bench_particle_filters(cal, prior, &PRIOR_PROPOSAL, [scenario_1, scenario_2]);
    let optimal = [
        ("pf3o", ["pf3o_predict", "pf3o_update"]),
        ("pf5o", ["pf5o_predict", "pf5o_update"]),
    ];
    bench_particle_filters(cal, optimal, &OPTIMAL_PROPOSAL, [scenario_1, scenario_2]);
}

/// A particle-filter setting of the bench.
struct ParticleSetting {
    process_std: [f32; 5],
    /// Regularization bandwidth scale (0: off).
    regularization: f32,
    proposal: Proposal,
}

/// The prior proposal (the paper's), unregularized, with the prior
/// proposal's process noise (`PARTICLE_PROCESS_STD`): the rows `pf3`,
/// `pf5`.
const PRIOR_PROPOSAL: ParticleSetting = ParticleSetting {
    process_std: PARTICLE_PROCESS_STD,
    regularization: 0.0,
    proposal: Proposal::Prior,
};

/// The slip scenario files' setting (firmware-sim
/// `slip::PARTICLE_PROCESS_STD`, `PARTICLE_REGULARIZATION`, the optimal
/// proposal; docs/paper-004.md): the rows `pf3o`, `pf5o`.
const OPTIMAL_PROPOSAL: ParticleSetting = ParticleSetting {
    process_std: [0.005, 0.005, 0.007, 5.0, 5.0],
    regularization: 1.0,
    proposal: Proposal::Optimal,
};

/// Paper 004's particle filter (100 particles) on both models with
/// `setting`, benchmarked as `names[0]` (N = 3, from `starts[0]`) and
/// `names[1]` (N = 5, from `starts[1]`), each a filter's name and its stages';
/// both filters live in this frame.
#[inline(never)]
fn bench_particle_filters(
    cal: Calibration,
    names: [(&'static str, [&'static str; 2]); 2],
    setting: &ParticleSetting,
    [scenario_1, scenario_2]: [Pose; 2],
) {
    let (x1, x2) = (Arc::new(scenario_1).state(), Arc::new(scenario_2).state());
    let process_std = SVector::from(setting.process_std);
    let measurement_std = SVector::from(MEASUREMENT_VARIANCE.map(math::sqrt));
    let prior_std = SVector::from(INITIAL_VARIANCE.map(math::sqrt));
    let mut pf3 = built(
        ParticleFilterConfig::new(head(&process_std), head(&measurement_std))
            .and_then(|c| c.with_collapse_gate(f32::INFINITY))
            .and_then(|c| c.with_regularization(setting.regularization))
            .map(|c| c.with_proposal(setting.proposal))
            .and_then(|config| {
                ParticleFilter::<_, 3, 3, PARTICLES>::new(
                    PoseModel,
                    config,
                    head(&x1),
                    head(&prior_std),
                    PARTICLE_SEED,
                )
            }),
        "particle filter (N = 3) refused",
    );
    let [(name3, stages3), (name5, stages5)] = names;
    bench_filter(
        cal,
        name3,
        stages3,
        &mut pf3,
        scenario_1,
        MAX_FILTER_RMS_ERROR_M,
    );
    let mut pf5 = built(
        ParticleFilterConfig::new(process_std, measurement_std)
            .and_then(|c| c.with_collapse_gate(f32::INFINITY))
            .and_then(|c| c.with_regularization(setting.regularization))
            .map(|c| c.with_proposal(setting.proposal))
            .and_then(|config| {
                ParticleFilter::<_, 5, 5, PARTICLES>::new(
                    PoseWheelModel,
                    config,
                    x2,
                    prior_std,
                    PARTICLE_SEED,
                )
            }),
        "particle filter (N = 5) refused",
    );
    bench_filter(
        cal,
        name5,
        stages5,
        &mut pf5,
        scenario_2,
        MAX_FILTER_RMS_ERROR_M,
    );
}
