//! Validation: [`SlipScenario::validate`] checks every value and builds
//! what a run needs (the robot, the controller, the reference sampler and
//! the estimator).

use wmr_core::filters::ekf::ExtendedKalmanFilter;
use wmr_core::filters::particle_filter::{ParticleFilterConfig, ParticleFilterError, Proposal};
use wmr_core::filters::ukf::{MerweScaledSigmaPoints, UkfError, UkfForm, UnscentedKalmanFilter};
use wmr_core::geometry::Pose;
use wmr_papers::slip_tracking::{
    AdaptiveVelocityController, P_MAX, PiecewiseReference, PoseModel, PoseWheelModel,
    ReferenceSegment, ReferenceState, SlipGains, SlipTrackingError, TrackedRobot,
};

use crate::scenario::{ScenarioError, non_negative, positive};

use super::filter::{Filter, PARTICLE_COUNTS, Particles, diag, first};
use super::scenario::{
    Controller, Estimator, MAX_SEGMENTS, ProposalSpec, SlipScenario, UkfFormSpec,
};

fn finite(field: &str, v: f64) -> Result<f64, ScenarioError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(ScenarioError::invalid(
            field,
            format!("must be finite (got {v})"),
        ))
    }
}

fn positive_array<const N: usize>(
    field: &str,
    values: &[f64; N],
) -> Result<[f32; N], ScenarioError> {
    let mut out = [0.0; N];
    for (i, (o, &v)) in out.iter_mut().zip(values).enumerate() {
        *o = positive(&format!("{field}[{i}]"), v)? as f32;
    }
    Ok(out)
}

fn non_negative_array<const N: usize>(
    field: &str,
    values: &[f64; N],
) -> Result<[f32; N], ScenarioError> {
    let mut out = [0.0; N];
    for (i, (o, &v)) in out.iter_mut().zip(values).enumerate() {
        *o = non_negative(&format!("{field}[{i}]"), v)? as f32;
    }
    Ok(out)
}

fn window(field: &str, w: [f64; 2]) -> Result<(), ScenarioError> {
    let [from, to] = w;
    if !(from.is_finite() && to.is_finite() && from >= 0.0 && from < to) {
        return Err(ScenarioError::invalid(
            field,
            format!("must be [from, to] with 0 ≤ from < to, finite (got [{from}, {to}])"),
        ));
    }
    Ok(())
}

/// The reference sampler: `PiecewiseReference<K>` for the scenario's `K`.
pub(super) type Sampler = Box<dyn Fn(f32) -> ReferenceState + Send + Sync>;

fn sampler<const K: usize>(
    start: Pose,
    segments: &[ReferenceSegment],
) -> Result<Sampler, SlipTrackingError> {
    let segments: [ReferenceSegment; K] = segments
        .try_into()
        .map_err(|_| SlipTrackingError::Reference)?;
    let reference = PiecewiseReference::<K>::new(start, segments)?;
    Ok(Box::new(move |t| reference.sample(t)))
}

fn ukf_field(e: UkfError) -> ScenarioError {
    let (field, what) = match e {
        UkfError::Alpha => ("filter.ukf.alpha", "must be finite and > 0"),
        UkfError::Beta => ("filter.ukf.beta", "must be finite"),
        UkfError::Kappa => ("filter.ukf.kappa", "must be finite with n + κ > 0"),
        UkfError::Spread => ("filter.ukf.alpha", "gives non-finite sigma-point weights"),
        UkfError::InitialCovariance(why) => ("filter.ukf.initial_variance", why.reason()),
        UkfError::ProcessNoise(why) => ("filter.process_noise", why.reason()),
        UkfError::MeasurementNoise(why) => ("measurement.variance", why.reason()),
        UkfError::SquareRootBeta => (
            "filter.ukf.beta",
            "must be ≥ alpha² for form = \"square_root\"",
        ),
        _ => ("filter.ukf", "refused"),
    };
    ScenarioError::invalid(field, format!("{what} (the core's UKF: {e})"))
}

fn pf_field(e: ParticleFilterError) -> ScenarioError {
    let field = match e {
        ParticleFilterError::ProcessStd => "filter.particle_filter.process_std",
        ParticleFilterError::MeasurementStd => "measurement.variance",
        ParticleFilterError::CollapseGate => "filter.particle_filter.collapse_gate",
        ParticleFilterError::Regularization => "filter.particle_filter.regularization",
        ParticleFilterError::PriorStd => "filter.initial_variance",
        ParticleFilterError::PriorMean => "initial",
        ParticleFilterError::Proposal => "filter.particle_filter.proposal",
        _ => "filter.particle_filter",
    };
    ScenarioError::invalid(field, format!("refused by the core's particle filter: {e}"))
}

/// A validated scenario, ready to run.
pub(super) struct Setup {
    pub(super) robot: TrackedRobot,
    pub(super) velocity: AdaptiveVelocityController,
    pub(super) reference: Sampler,
    pub(super) filter: Filter,
    pub(super) initial: [f64; 5],
    pub(super) steps: u32,
}

impl SlipScenario {
    /// Checks every value (the filters' settings too, whichever estimator
    /// runs).
    ///
    /// # Errors
    /// [`ScenarioError::Invalid`] naming the first bad field.
    pub fn validate(&self) -> Result<(), ScenarioError> {
        self.setup().map(|_| ())
    }

    pub(super) fn setup(&self) -> Result<Setup, ScenarioError> {
        if self.name.trim().is_empty() {
            return Err(ScenarioError::invalid("name", "must not be empty"));
        }
        let duration_s = positive("duration_s", self.duration_s)?;
        let period_s = positive("period_s", self.period_s)?;
        let steps = (duration_s / period_s).round();
        if steps < 1.0 || steps >= f64::from(u32::MAX) {
            return Err(ScenarioError::invalid(
                "duration_s",
                format!("gives {steps} steps of {period_s} s; need 1 ..= 2^32 − 2"),
            ));
        }
        if self.plant_substeps == 0 {
            return Err(ScenarioError::invalid("plant_substeps", "must be ≥ 1"));
        }
        if self.record_every_steps == 0 {
            return Err(ScenarioError::invalid("record_every_steps", "must be ≥ 1"));
        }
        let initial = self.initial_state();
        for (key, v) in [
            ("x_m", initial.x_m),
            ("y_m", initial.y_m),
            ("heading_rad", initial.heading_rad),
            ("left_rad_s", initial.left_rad_s),
            ("right_rad_s", initial.right_rad_s),
        ] {
            finite(&format!("initial.{key}"), v)?;
        }
        let mut previous: Option<f64> = None;
        for (k, step) in self.slip.iter().enumerate() {
            let start = non_negative(&format!("slip[{k}].start_s"), step.start_s)?;
            if let Some(p) = previous.filter(|&p| start <= p) {
                return Err(ScenarioError::invalid(
                    &format!("slip[{k}].start_s"),
                    format!(
                        "must be later than slip[{}].start_s ({p} s): steps in increasing \
                         time (got {start})",
                        k - 1
                    ),
                ));
            }
            previous = Some(start);
            let i = step.slip_ratio;
            if !(i.is_finite() && (0.0..1.0).contains(&i)) {
                return Err(ScenarioError::invalid(
                    &format!("slip[{k}].slip_ratio"),
                    format!("must be in [0, 1) (got {i})"),
                ));
            }
        }
        let reference = self.reference_sampler()?;
        let r = &self.robot;
        let robot = TrackedRobot::new(
            positive("robot.wheel_radius_m", r.wheel_radius_m)? as f32,
            positive("robot.track_width_m", r.track_width_m)? as f32,
            positive("robot.mass_kg", r.mass_kg)? as f32,
            positive("robot.yaw_inertia_kg_m2", r.yaw_inertia_kg_m2)? as f32,
        )
        .map_err(|e| ScenarioError::invalid("robot", format!("refused by the core: {e}")))?;
        if robot.wheel_inertia().try_inverse().is_none() {
            return Err(ScenarioError::invalid(
                "robot",
                "the wheel inertia M0 is singular",
            ));
        }
        let g = &self.gains;
        let gains = SlipGains::new(
            positive("gains.k1", g.k1)? as f32,
            positive("gains.k2", g.k2)? as f32,
            positive("gains.k3", g.k3)? as f32,
            positive("gains.k4", g.k4)? as f32,
            positive("gains.k5", g.k5)? as f32,
            positive("gains.rho", g.rho)? as f32,
        )
        .map_err(|e| ScenarioError::invalid("gains", format!("refused by the core: {e}")))?;
        let p0 = g.initial_slip_estimate;
        if !(p0.is_finite() && (1.0..=f64::from(P_MAX)).contains(&p0)) {
            return Err(ScenarioError::invalid(
                "gains.initial_slip_estimate",
                format!("must be in [1, {P_MAX}] (got {p0})"),
            ));
        }
        let velocity = AdaptiveVelocityController::new(robot, gains, period_s as f32, p0 as f32)
            .map_err(|e| ScenarioError::invalid("period_s", format!("refused by the core: {e}")))?;
        let w = &self.windows;
        window("windows.before_slip_s", w.before_slip_s)?;
        window("windows.during_slip_s", w.during_slip_s)?;
        window("windows.after_slip_s", w.after_slip_s)?;
        window("windows.slip_estimate_during_s", w.slip_estimate_during_s)?;
        window("windows.slip_estimate_after_s", w.slip_estimate_after_s)?;
        let filter = self.filter(&initial.state())?;
        Ok(Setup {
            robot,
            velocity,
            reference,
            filter,
            initial: initial.state(),
            steps: steps as u32,
        })
    }

    pub(super) fn reference_sampler(&self) -> Result<Sampler, ScenarioError> {
        let r = &self.reference;
        let start = Pose::new(
            finite("reference.x_m", r.x_m)? as f32,
            finite("reference.y_m", r.y_m)? as f32,
            finite("reference.heading_rad", r.heading_rad)? as f32,
        );
        let n = r.segments.len();
        if n == 0 || n > MAX_SEGMENTS {
            return Err(ScenarioError::invalid(
                "reference.segments",
                format!("must have 1 to {MAX_SEGMENTS} segments (got {n})"),
            ));
        }
        let mut segments = Vec::with_capacity(n);
        for (k, s) in r.segments.iter().enumerate() {
            let field = |key: &str| format!("reference.segments[{k}].{key}");
            let start_s = finite(&field("start_s"), s.start_s)?;
            if k == 0 && start_s != 0.0 {
                return Err(ScenarioError::invalid(
                    &field("start_s"),
                    format!("the first segment must start at 0 s (got {start_s})"),
                ));
            }
            if let Some(p) = k.checked_sub(1).and_then(|j| segments.get(j)) {
                let p: &ReferenceSegment = p;
                if start_s as f32 <= p.start_s {
                    return Err(ScenarioError::invalid(
                        &field("start_s"),
                        format!(
                            "must be later than segment {}'s ({} s) (got {start_s})",
                            k - 1,
                            p.start_s
                        ),
                    ));
                }
            }
            segments.push(ReferenceSegment {
                start_s: start_s as f32,
                v_m_s: finite(&field("v_m_s"), s.v_m_s)? as f32,
                omega_rad_s: finite(&field("omega_rad_s"), s.omega_rad_s)? as f32,
            });
        }
        let built = match n {
            1 => sampler::<1>(start, &segments),
            2 => sampler::<2>(start, &segments),
            3 => sampler::<3>(start, &segments),
            4 => sampler::<4>(start, &segments),
            5 => sampler::<5>(start, &segments),
            6 => sampler::<6>(start, &segments),
            7 => sampler::<7>(start, &segments),
            _ => sampler::<MAX_SEGMENTS>(start, &segments),
        };
        built.map_err(|e| {
            ScenarioError::invalid("reference.segments", format!("refused by the core: {e}"))
        })
    }

    /// Checks every filter setting and builds the estimator that runs.
    fn filter(&self, x0: &[f64; 5]) -> Result<Filter, ScenarioError> {
        let f = &self.filter;
        let r = positive_array("measurement.variance", &self.measurement.variance)?;
        let std_r = self.measurement.variance.map(|v| v.sqrt() as f32);
        let p0 = positive_array("filter.initial_variance", &f.initial_variance)?;
        let q = non_negative_array("filter.process_noise", &f.process_noise)?;
        let p0_ukf = positive_array("filter.ukf.initial_variance", &f.ukf.initial_variance)?;
        let (alpha, beta, kappa) = (f.ukf.alpha as f32, f.ukf.beta as f32, f.ukf.kappa as f32);
        let form = match f.ukf.form {
            UkfFormSpec::Covariance => UkfForm::Covariance,
            UkfFormSpec::SquareRoot => UkfForm::SquareRoot,
        };
        let pf = &f.particle_filter;
        let count_refused = || {
            ScenarioError::invalid(
                "filter.particle_filter.particles",
                format!(
                    "must be one of {PARTICLE_COUNTS:?} (got {}): the particle count is a \
                     const generic of the core's ParticleFilter, built into the simulator for \
                     these counts only",
                    pf.particles
                ),
            )
        };
        if !PARTICLE_COUNTS.contains(&pf.particles) {
            return Err(count_refused());
        }
        let process_std =
            non_negative_array("filter.particle_filter.process_std", &pf.process_std)?;
        let gate = pf.collapse_gate;
        if gate.is_nan() || gate <= 0.0 {
            return Err(ScenarioError::invalid(
                "filter.particle_filter.collapse_gate",
                format!("must be > 0 (inf: off) (got {gate})"),
            ));
        }
        let gate = gate as f32;
        let regularization = pf.regularization;
        if !(regularization.is_finite() && regularization >= 0.0) {
            return Err(ScenarioError::invalid(
                "filter.particle_filter.regularization",
                format!("must be finite and ≥ 0 (0: off) (got {regularization})"),
            ));
        }
        let regularization = regularization as f32;
        let proposal = match pf.proposal {
            ProposalSpec::Prior => Proposal::Prior,
            ProposalSpec::Optimal => Proposal::Optimal,
        };
        let prior = p0.map(f32::sqrt);
        let x0 = x0.map(|x| x as f32);
        let ekf_field =
            |e| ScenarioError::invalid("filter", format!("the core's EKF refused P0, Q or R: {e}"));
        // Every filter is built (so that every setting is checked); the one
        // that runs is kept.
        let ekf3 = ExtendedKalmanFilter::new(
            PoseModel,
            first::<3>(x0).into(),
            diag(first::<3>(p0)).into(),
            diag(first::<3>(q)).into(),
            diag(first::<3>(r)).into(),
        )
        .map_err(ekf_field)?;
        let ekf5 = ExtendedKalmanFilter::new(
            PoseWheelModel,
            x0.into(),
            diag(p0).into(),
            diag(q).into(),
            diag(r).into(),
        )
        .map_err(ekf_field)?;
        let ukf3 = UnscentedKalmanFilter::<_, 3, 3, 7>::new(
            PoseModel,
            MerweScaledSigmaPoints::new(alpha, beta, kappa).map_err(ukf_field)?,
            first::<3>(x0).into(),
            diag(first::<3>(p0_ukf)).into(),
            diag(first::<3>(q)).into(),
            diag(first::<3>(r)).into(),
        )
        .and_then(|f| f.with_form(form))
        .map_err(ukf_field)?;
        let ukf5 = UnscentedKalmanFilter::<_, 5, 5, 11>::new(
            PoseWheelModel,
            MerweScaledSigmaPoints::new(alpha, beta, kappa).map_err(ukf_field)?,
            x0.into(),
            diag(p0_ukf).into(),
            diag(q).into(),
            diag(r).into(),
        )
        .and_then(|f| f.with_form(form))
        .map_err(ukf_field)?;
        let pf3 = Particles::<_, 3>::new(
            pf.particles,
            PoseModel,
            ParticleFilterConfig::new(first::<3>(process_std).into(), first::<3>(std_r).into())
                .and_then(|c| c.with_collapse_gate(gate))
                .and_then(|c| c.with_regularization(regularization))
                .map(|c| c.with_proposal(proposal))
                .map_err(pf_field)?,
            first::<3>(x0),
            first::<3>(prior),
            self.seed,
        )
        .ok_or_else(count_refused)?
        .map_err(pf_field)?;
        let pf5 = Particles::<_, 5>::new(
            pf.particles,
            PoseWheelModel,
            ParticleFilterConfig::new(process_std.into(), std_r.into())
                .and_then(|c| c.with_collapse_gate(gate))
                .and_then(|c| c.with_regularization(regularization))
                .map(|c| c.with_proposal(proposal))
                .map_err(pf_field)?,
            x0,
            prior,
            self.seed,
        )
        .ok_or_else(count_refused)?
        .map_err(pf_field)?;
        Ok(match (self.estimator, self.controller) {
            (Estimator::Exact, _) => Filter::Exact,
            (Estimator::Ekf, Controller::Velocity) => Filter::Ekf3(ekf3),
            (Estimator::Ekf, Controller::Torque) => Filter::Ekf5(ekf5),
            (Estimator::Ukf, Controller::Velocity) => Filter::Ukf3(ukf3),
            (Estimator::Ukf, Controller::Torque) => Filter::Ukf5(ukf5),
            (Estimator::ParticleFilter, Controller::Velocity) => Filter::Pf3(pf3),
            (Estimator::ParticleFilter, Controller::Torque) => Filter::Pf5(pf5),
        })
    }
}
