//! The fusion estimator's pose filter as a particle filter: the state,
//! odometry noise model, tag measurements, gate and re-localisation of
//! [`crate::estimation::fusion`] (whose module docs this follows), on paper 004's
//! particle filter ([`crate::filters::particle_filter`]).
//!
//! # Prediction
//! Each particle `(x, y, θ, ε_R, ε_L)` drives its own wheel travels
//! `s' = (1 + ε) s + σ(s') ξ`, `σ² = α|s| + σ₀²` (the EKF's wheel noise,
//! drawn per particle and wheel), along the exact arc, and its scale
//! errors take a random-walk step of variance (scale walk)·`|s'|`
//! ([`ParticleModel::sample_transition`]). Noise that enters through the
//! wheels keeps the particles on arcs a robot can drive, where the
//! paper's additive `σ_q` per state component would not.
//!
//! # Noise level
//! The configured wheel noise is a ceiling, not a fact: on wheels that
//! slip less, particles that drive with the configured spread random-walk
//! their headings where the robot's does not, and the cells, which
//! constrain the position and hardly the heading, cannot tell them apart
//! (docs/fusion.md, "The particle filter at the template's defaults").
//! So each particle carries a discrete noise level `k` in `0…2`
//! ([`NOISE_LEVELS`]) as the mode of a jump-Markov system (Doucet,
//! Gordon & Krishnamurthy 2001, *Particle filters for state estimation of
//! jump Markov linear systems*, IEEE Trans. Signal Process.
//! 49(3):613–624; the multiple-model bootstrap filter of McGinnity & Irwin
//! 2000, *Multiple model bootstrap filter for maneuvering target
//! tracking*, IEEE Trans. AES 36(3):1006–1012; the generic filter's
//! [`ParticleModel::MODES`]): level 0 drives with the configured noise,
//! levels 1 and 2 with `10^{−4}` and `10^{−5}` of its variance
//! ([`LEVEL_STD_SCALE`], the standard deviations), the configured noise
//! the ceiling. The ladder has a gap on purpose. On wheels that slip, the
//! configured noise, even 10× above the wheels', tracks better than a
//! matched one (it keeps the cloud over-dispersed), so the particles that
//! may learn a smaller noise must not be able to settle just below it;
//! on exact wheels the quiet levels are far enough below it that the
//! cloud follows the odometry as the EKF's mean does. A particle's level
//! is drawn at the start from the prior ([`LEVEL_PRIOR_CDF`]: half at the
//! configured noise, a quarter at each quiet level, by the inverse
//! distribution function of one uniform draw), kept from step to step,
//! and jumps with probability [`LEVEL_JUMP_PROBABILITY`] = 1e-3 per
//! particle and prediction to a new draw from that prior (about ten
//! particles a second at 100 particles and 100 Hz, so that a start or a
//! resampling that lost every particle of a level does not lose it for
//! long). The level goes with its particle through resampling and is
//! never smoothed (roughening moves the pose and scale errors only). A
//! heading reset and a re-localisation redraw every level from the prior:
//! a cloud whose quiet particles took over with a wrong heading or scale
//! has too little noise left to find the right one, and the reset is
//! where the estimator has said so; a collapse keeps each slot's level.
//! The ladder, the prior and the jump rate were chosen by the starts
//! table of docs/fusion.md ("The particle filter's noise levels").
//! The ladder reaches only below the configured noise; a noise tuned
//! below the wheels' own is raised by the estimator's wheel noise
//! adaptation ([`crate::estimation::fusion::noise_adaptation`]), which
//! scales the configured noise and so every level with it, from the next
//! prediction on.
//!
//! # Correction
//! (Nearest-tag reads: see "Tag cells" below; this is for the other
//! measurements.) A fix weights every particle by its Gaussian likelihood with the fix's
//! own variance ([`ParticleFilter::update_with_std`]; an axis fix leaves
//! the other axis unmeasured, `σ = ∞`; a fix with correlated noise,
//! [`PositionMeasurement::Ellipse`], is taken with its marginal variances,
//! the correlation dropped). The gate of [`crate::estimation::fusion`]
//! runs first on the particles' weighted mean and covariance: the
//! predictive distribution of a linear measurement has exactly that mean
//! and `H P Hᵀ + R`, so the chi-square thresholds mean what they say for
//! any particle cloud that is close to Gaussian. Resampling is systematic
//! when the effective sample size falls below `P/2`; the collapse gate is
//! off (`∞`): a fix the gate let through pulls the weight onto the closest
//! particles rather than throwing them away.
//!
//! # Tag cells
//! A nearest-tag read is a quantized measurement, and a Gaussian of the
//! 1 mm variance of a boundary crossing ([`TagCellTracker::measurements`])
//! cuts 100 particles down to a few. With a nearest-tag reader the
//! estimator gives this filter every read as its exact likelihood instead
//! ([`TagCellTracker::cell`], [`PoseParticleFilter::correct_cell`]): the
//! indicator that the particle is in the read tag's cell (the square of
//! side `s` around it), softened at the edges by a Gaussian tail of 1 mm,
//! with the cell allowed to meet any point of the tick's displacement
//! behind the particle (a read over the UART is a tick old when it
//! arrives), [`TagCell::distance_sq`]: a few comparisons per particle, no
//! transcendental. Every read counts, an unchanged tag too: for a particle
//! filter "still in this cell" removes the particles that left it, where an
//! EKF must skip it. This is the particle filter for quantized
//! measurements of Karlsson & Gustafsson 2005 (*Particle filtering for
//! quantized sensor information*, EUSIPCO), whose likelihood of a
//! quantized read is the probability mass of the quantization cell. The
//! gate, re-localisation and counters of [`crate::estimation::fusion`]
//! take the cell's moments ([`TagCell::moments`]). The first read starts
//! the particles in the cell (`s²/12` per axis) rather than a metre wide.
//!
//! # Stray clouds
//! A cloud can lose its cell: on a sparse floor with nearly exact wheels
//! the cell cuts and the quiet noise levels leave many copies of one
//! particle, and a cloud of copies that drifted out of the robot's cell
//! stays out, all its particles beyond the read cell's edge. The
//! likelihood then weights them only by how far beyond the edge each is
//! ([`ParticleFilter::update_with_likelihood`] weights relative to the
//! closest particle), so each read hands the cloud to the one particle
//! that happened to move closest, mostly by its heading: on the circle
//! over 30 cm tags at 1e-6 m²/m, runs so caught read a cell more than
//! 1 cm beyond every particle in a third of their reads and held headings
//! 0.1–0.3 rad off for minutes (docs/fusion.md, "Stray clouds"). So before
//! a read is weighted, if even its closest particle is more than
//! [`STRAY_GAP_M`] (2 cm, twenty edge softenings) beyond the read cell,
//! the whole cloud is moved by the shift that brings that particle onto
//! the cell's edge ([`TagCell::shift_onto`], [`ParticleFilter::shift`]:
//! each particle keeps its weight), before the read is weighted as
//! usual: the smallest correction that makes the read possible, leaving each particle's heading, scale errors and noise
//! level and the cloud's shape as they were (the projection of a
//! constrained estimate onto its constraint, Simon 2010, *Kalman filtering
//! with state constraints: a survey of linear and nonlinear algorithms*,
//! IET Control Theory Appl. 4(8):1303–1318, applied to the cloud; the
//! EKF's edge constraint of [`crate::estimation::fusion::tag_cells`] does
//! the same to its mean). Counted ([`ParticleCore::stray_moves`]); a read
//! that is an outlier rather than a lost cloud is the gate's to refuse,
//! which runs first, on the cell's moments.
//!
//! # Read discs
//! With a range reader (a read radius `r > 0`,
//! [`crate::estimation::fusion::FusionSettings::with_read_radius`]) the
//! EKF and the UKF take the first read of each pass as the point where
//! the antenna entered the disc around the tag
//! ([`TagCellTracker::range_measurement`]: a Gaussian along and across
//! the heading). This filter takes the same read as its exact likelihood
//! instead ([`TagDisc`], [`PoseParticleFilter::correct_disc`]): the
//! reader reads on entering its range, so at the read the robot was
//! within `r` of the tag and a tick before it was not (the lag of the
//! fix's age along the heading behind it, as for the entry point): the
//! indicator of that crescent, its edges softened by Gaussian tails of
//! 1 mm as a cell's; two `sqrt` per particle. Its plain disc (within `r`
//! at the read, the entry forgotten) doubled the mean error on the full
//! stack (docs/fusion.md, "The particle filter on the robot"). The gate
//! and the re-localisation take the entry point's Gaussian (the
//! crescent's moments, near enough). Repeated reads within a pass are
//! skipped as for the other filters (counted as same-tag reads); a pass
//! whose entry read was lost starts with a read inside the disc, which
//! the crescent does not expect (its tails weight it, and the gate may
//! refuse it).
//!
//! After every resampling the particles are roughened (Gordon, Salmond &
//! Smith 1993, *Novel approach to nonlinear/non-Gaussian Bayesian state
//! estimation*, IEE Proc. F 140(2):107–113, §4:
//! [`ParticleFilterConfig::with_roughening`], `K` = [`ROUGHENING`]):
//! without it the cell cuts leave many copies of few headings. Resampling
//! stays on the effective sample size (below `P/2`).
//!
//! # Resets
//! A heading reset redraws every particle's pose from the Gaussian of the
//! new mean and covariance ([`ParticleFilter::reset`]) and every noise
//! level from its prior ([`ParticleFilter::redraw_modes`]).
//!
//! # Re-localisation
//! After consecutive gated reads the filter takes itself to be lost
//! ([`crate::estimation::fusion::gate`]): its position, which the reads
//! contradict, is redrawn, and what else its particles know is kept.
//! Every particle's position is drawn from the read's Gaussian (for a tag
//! cell its moments, [`TagCell::moments`]; for a fix its own mean and
//! covariance; an axis fix redraws that axis only), its heading, wheel
//! scale errors stay as they were, its noise level is redrawn from the
//! prior ("Noise level"), the weights become equal
//! ([`ParticleFilter::reposition`]); the ungated correction that follows
//! then weights them by the read's likelihood (the cell's). This is sensor
//! resetting (Lenser & Veloso 2000, *Sensor resetting localization for
//! poorly modelled mobile robots*, ICRA, 1225–1232: when the measurements
//! contradict the particles, replace particles by samples drawn from the
//! measurement), the injection of augmented MCL (Thrun, Burgard & Fox
//! 2005, *Probabilistic Robotics*, §8.3.5) in its extreme form (every
//! particle, on the gate's decision rather than the likelihood's running
//! averages), applied to the measured components only. The EKF and the
//! UKF restart from a Gaussian whose heading variance is at least
//! `(π/2)²` (a filter that lost its position may hold a mirrored
//! heading); a particle filter's cloud that drew its headings from such a
//! Gaussian would keep those that the position read happens to favour,
//! and lose the heading it had (a heading jump of 0.66 rad at a route's
//! start: docs/fusion.md).
//!
//! # Randomness and cost
//! The generator is seeded from the configuration
//! (`PoseFilterConfig::with_particle_seed`): a run repeats bit
//! for bit from its seed. A prediction draws `P` uniforms (the levels'
//! jumps) and `4P` Gaussians and drives `P` arcs; with [`FUSION_PARTICLES`] = 100 its whole tick on a Cortex-M4F
//! is in the bench table of docs/budgets.md.

use nalgebra::{SVector, Vector2};

use crate::estimation::fusion::config::PoseFilterConfig;
use crate::estimation::fusion::gate::{
    FixOutcome, PoseCovariance, PoseFilter, PoseFilterCore, PoseState, PositionMeasurement,
};
use crate::estimation::fusion::odometry_noise::{
    drive_wheels, odometry_transition, scale_walk_variance, wheel_travels, wheel_variance,
};
use crate::estimation::fusion::tag_cells::TagCell;
#[cfg(doc)]
use crate::estimation::fusion::tag_cells::TagCellTracker;
use crate::filters::particle_filter::{ParticleFilter, ParticleFilterConfig, ParticleModel};
use crate::geometry::Vec2;
use crate::math;
use crate::odometry::OdometryStep;

/// The roughening constant `K` after each resampling (module docs).
pub const ROUGHENING: f32 = 0.05;

/// How far beyond a read cell's edge the closest particle may be before
/// the cloud is moved onto the cell, m (module docs, "Stray clouds"):
/// twenty edge softenings, a read with a likelihood below `e^{−200}`
/// under every particle.
pub const STRAY_GAP_M: f32 = 0.02;

/// Particles of the tracker's particle-filter estimator.
pub const FUSION_PARTICLES: usize = 100;

/// The softening of a read disc's edge, m: the reader's own position
/// error, as for a tag cell's edges.
pub const DISC_EDGE_STD_M: f32 = 1e-3;

/// A range reader's read of a tag as the disc it was read in (module
/// docs, "Read discs"): the antenna was within `radius_m` of the tag when
/// it read it.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TagDisc {
    /// The read tag, m.
    pub centre: Vec2,
    /// The reader's range, m (> 0).
    pub radius_m: f32,
    /// How far the robot drove since the read, m (the fix's age times the
    /// last tick's step, along the heading).
    pub lag: Vec2,
    /// The robot's displacement during the tick of the read, m: a tick
    /// before the read it was outside the disc (the read is the first of
    /// its pass, made on entering the range).
    pub sweep: Vec2,
    /// The softening of the disc's edge, m (> 0).
    pub edge_std_m: f32,
}

impl TagDisc {
    /// Twice the entry's negative log-likelihood at the position `(x, y)`
    /// now (nats, up to a constant): the robot entered the disc during the
    /// tick of the read. With `d` the distance from the tag to where the
    /// robot was at the read (`(x, y) − lag`) and `d₀` to where it was a
    /// tick before (`(x, y) − lag − sweep`): `((d − r)/σ_e)²` if `d > r`
    /// (not in the disc at the read) plus `((r − d₀)/σ_e)²` if `d₀ < r`
    /// (already in it a tick before), each a Gaussian tail as a cell's
    /// edges; 0 on the crescent between. NaN for a non-finite position (the
    /// filter gives such a particle no weight).
    #[must_use]
    pub fn distance_sq(&self, x: f32, y: f32) -> f32 {
        let dx = x - self.lag.x - self.centre.x;
        let dy = y - self.lag.y - self.centre.y;
        let tail = |gap: f32| {
            if gap > 0.0 || gap.is_nan() {
                let g = gap / self.edge_std_m;
                g * g
            } else {
                0.0
            }
        };
        let (bx, by) = (dx - self.sweep.x, dy - self.sweep.y);
        tail(math::sqrt(dx * dx + dy * dy) - self.radius_m)
            + tail(self.radius_m - math::sqrt(bx * bx + by * by))
    }

    /// Finite, with positive sizes.
    fn is_valid(&self) -> bool {
        self.centre.is_finite()
            && self.lag.is_finite()
            && self.sweep.is_finite()
            && self.radius_m.is_finite()
            && self.radius_m > 0.0
            && self.edge_std_m.is_finite()
            && self.edge_std_m > 0.0
    }
}

/// The wheel noise levels a particle may take (module docs, "Noise
/// level"): `k = 0…NOISE_LEVELS − 1`.
pub const NOISE_LEVELS: u8 = 3;

/// Level `k`'s wheel standard deviation as a share of the configured one:
/// the configured noise, then `10^{−4}` and `10^{−5}` of its variance
/// (module docs, "Noise level", for why there is a gap).
pub const LEVEL_STD_SCALE: [f32; NOISE_LEVELS as usize] = [1.0, 0.01, 0.003_162_277_7];

/// The levels' prior as its distribution function: entry `k` is
/// `P(level ≤ k)`, half the particles at the configured noise and a
/// quarter at each quiet level (the last level takes the rest).
pub const LEVEL_PRIOR_CDF: [f32; NOISE_LEVELS as usize - 1] = [0.5, 0.75];

/// The probability that a particle's level jumps to a new draw from its
/// prior, per prediction (module docs, "Noise level").
pub const LEVEL_JUMP_PROBABILITY: f32 = 1e-3;

/// The level whose prior mass holds `uniform` (in [0, 1)): the inverse of
/// [`LEVEL_PRIOR_CDF`].
fn prior_level(uniform: f32) -> u8 {
    let below = LEVEL_PRIOR_CDF.iter().filter(|&&c| uniform >= c).count();
    u8::try_from(below).unwrap_or(NOISE_LEVELS - 1)
}

/// The pose on odometry with per-wheel noise, for the particle filter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoisyOdometryModel {
    config: PoseFilterConfig,
}

impl NoisyOdometryModel {
    /// One particle's step with its wheels' standard deviation `scale`
    /// times the configured one (module docs, "Prediction").
    fn sample_scaled(
        &self,
        scale: f32,
        x: &PoseState,
        u: &OdometryStep,
        gaussian: &mut dyn FnMut() -> f32,
    ) -> PoseState {
        let config = &self.config;
        let b = config.track_width_m();
        let (nominal_r, nominal_l) = wheel_travels(u.ds_m, u.dtheta_rad, b);
        let noisy = |travel: f32, gaussian: &mut dyn FnMut() -> f32| {
            travel + scale * math::sqrt(wheel_variance(config, travel)) * gaussian()
        };
        let right = noisy(nominal_r * (1.0 + x.w), gaussian);
        let left = noisy(nominal_l * (1.0 + x.a), gaussian);
        let mut next = drive_wheels(x, right, left, b);
        next.w += math::sqrt(scale_walk_variance(config, right)) * gaussian();
        next.a += math::sqrt(scale_walk_variance(config, left)) * gaussian();
        next
    }
}

impl ParticleModel<5, 2> for NoisyOdometryModel {
    type Input = OdometryStep;

    fn transition(&self, x: &PoseState, u: &OdometryStep, _dt_s: f32) -> PoseState {
        odometry_transition(x, u, self.config.track_width_m())
    }

    /// The configured noise (level 0).
    fn sample_transition(
        &self,
        x: &PoseState,
        u: &OdometryStep,
        _dt_s: f32,
        _process_std: &PoseState,
        gaussian: &mut dyn FnMut() -> f32,
    ) -> PoseState {
        self.sample_scaled(1.0, x, u, gaussian)
    }

    const MODES: u8 = NOISE_LEVELS;

    fn initial_mode(&self, uniform: f32) -> u8 {
        prior_level(uniform)
    }

    /// Kept, but with probability [`LEVEL_JUMP_PROBABILITY`] a new draw
    /// from the prior (module docs, "Noise level"): the one uniform
    /// serves both, as `uniform / LEVEL_JUMP_PROBABILITY` is uniform in
    /// [0, 1) below it.
    fn next_mode(&self, mode: u8, uniform: f32) -> u8 {
        if uniform < LEVEL_JUMP_PROBABILITY {
            prior_level(uniform / LEVEL_JUMP_PROBABILITY)
        } else {
            mode
        }
    }

    /// The wheels' standard deviation [`LEVEL_STD_SCALE`]`[level]` times
    /// the configured one.
    fn sample_transition_in_mode(
        &self,
        level: u8,
        x: &PoseState,
        u: &OdometryStep,
        _dt_s: f32,
        _process_std: &PoseState,
        gaussian: &mut dyn FnMut() -> f32,
    ) -> PoseState {
        let scale = LEVEL_STD_SCALE
            .get(usize::from(level))
            .copied()
            .unwrap_or(1.0);
        self.sample_scaled(scale, x, u, gaussian)
    }

    fn measure(&self, x: &PoseState) -> SVector<f32, 2> {
        Vector2::new(x.x, x.y)
    }

    fn is_angle(&self, index: usize) -> bool {
        index == 2
    }

    fn input_is_valid(&self, u: &OdometryStep) -> bool {
        u.ds_m.is_finite() && u.dtheta_rad.is_finite()
    }
}

/// The particle filter as a [`PoseFilterCore`], `P` particles.
#[derive(Debug, Clone, PartialEq)]
pub struct ParticleCore<const P: usize> {
    filter: ParticleFilter<NoisyOdometryModel, 5, 2, P, P>,
    /// Reads whose cell lay beyond [`STRAY_GAP_M`] of every particle, so
    /// that the cloud was moved onto it (module docs, "Stray clouds").
    stray_moves: u32,
}

/// The pose particle filter.
pub type PoseParticleFilter<const P: usize = FUSION_PARTICLES> = PoseFilter<ParticleCore<P>>;

impl<const P: usize> ParticleCore<P> {
    /// The particle filter inside (its counters say what it resampled,
    /// recovered or skipped).
    #[must_use]
    pub fn filter(&self) -> &ParticleFilter<NoisyOdometryModel, 5, 2, P, P> {
        &self.filter
    }
}

/// The generic filter's settings for the pose filter (module docs): the
/// noise comes from the model, so `σ_q` and `σ_r` here are unused.
fn settings() -> Option<ParticleFilterConfig<5, 2>> {
    ParticleFilterConfig::new(PoseState::zeros(), Vector2::repeat(1.0))
        .and_then(|c| c.with_collapse_gate(f32::INFINITY))
        .and_then(|c| c.with_roughening(ROUGHENING))
        .ok()
}

/// The prior's standard deviations: the roots of `covariance`'s diagonal.
fn prior_std(covariance: &PoseCovariance) -> PoseState {
    covariance.diagonal().map(|v| math::sqrt(v.max(0.0)))
}

impl<const P: usize> PoseFilterCore for ParticleCore<P> {
    fn start(
        config: &PoseFilterConfig,
        mean: &PoseState,
        covariance: &PoseCovariance,
    ) -> Option<Self> {
        let model = NoisyOdometryModel { config: *config };
        let std = prior_std(covariance);
        ParticleFilter::new(model, settings()?, *mean, std, config.particle_seed())
            .ok()
            .map(|filter| Self {
                filter,
                stray_moves: 0,
            })
    }

    /// In place ([`ParticleFilter::init`]): the 5 KB of particles are
    /// drawn where they live.
    fn start_in_place(
        &mut self,
        config: &PoseFilterConfig,
        mean: &PoseState,
        covariance: &PoseCovariance,
    ) -> bool {
        let Some(settings) = settings() else {
            return false;
        };
        let model = NoisyOdometryModel { config: *config };
        let std = prior_std(covariance);
        let started = self
            .filter
            .init(model, settings, *mean, std, config.particle_seed())
            .is_ok();
        if started {
            self.stray_moves = 0;
        }
        started
    }

    fn predict(&mut self, _config: &PoseFilterConfig, odometry: &OdometryStep) -> bool {
        let rejected = self.filter.rejected_inputs();
        self.filter.predict(odometry, 0.0);
        self.filter.rejected_inputs() == rejected
    }

    /// The motion model takes the new wheel noise (its levels scale with
    /// it) from the next prediction on.
    fn reconfigure(&mut self, config: &PoseFilterConfig) {
        self.filter.model_mut().config = *config;
    }

    fn mean(&self) -> PoseState {
        self.filter.estimate()
    }

    fn covariance(&self) -> PoseCovariance {
        self.filter.covariance()
    }

    fn update(&mut self, measurement: &PositionMeasurement) -> bool {
        let estimate = self.filter.estimate();
        let (z, std) = match *measurement {
            PositionMeasurement::Point {
                position,
                variance_m2: [vx, vy],
            } => (
                Vector2::new(position.x, position.y),
                Vector2::new(math::sqrt(vx), math::sqrt(vy)),
            ),
            // The marginal variances: the filter's diagonal noise model
            // drops the correlation (module docs).
            PositionMeasurement::Ellipse {
                position,
                covariance_m2: [vx, _, vy],
            } => (
                Vector2::new(position.x, position.y),
                Vector2::new(math::sqrt(vx), math::sqrt(vy)),
            ),
            PositionMeasurement::X {
                value_m,
                variance_m2,
            } => (
                Vector2::new(value_m, estimate.y),
                Vector2::new(math::sqrt(variance_m2), f32::INFINITY),
            ),
            PositionMeasurement::Y {
                value_m,
                variance_m2,
            } => (
                Vector2::new(estimate.x, value_m),
                Vector2::new(f32::INFINITY, math::sqrt(variance_m2)),
            ),
        };
        let rejected = self.filter.rejected_inputs();
        self.filter.update_with_std(&z, &std);
        self.filter.rejected_inputs() == rejected
    }

    /// Every particle's pose redrawn from `N(mean, covariance)` and its
    /// noise level from the prior (module docs, "Resets").
    fn reset(&mut self, mean: &PoseState, covariance: &PoseCovariance) -> bool {
        self.filter.reset(mean, covariance).is_ok()
    }

    /// Sensor resetting of the position only (module docs,
    /// "Re-localisation"): every particle's position redrawn from
    /// `measurement`'s Gaussian, its heading and wheel scale errors kept,
    /// its noise level redrawn from the prior; `mean` and `covariance`
    /// (the Gaussian restart of the other filters) are not used. `false`
    /// (nothing changed) for a measurement that is not finite with
    /// positive (definite) variances.
    fn relocalise(
        &mut self,
        _mean: &PoseState,
        _covariance: &PoseCovariance,
        measurement: &PositionMeasurement,
    ) -> bool {
        if !measurement.is_finite() {
            return false;
        }
        // `(centre, L)`: the measured axes' mean and the lower Cholesky
        // factor of their covariance; an unmeasured axis keeps the
        // particle's own coordinate (a zero row).
        let (centre, [l00, l10, l11], keep) = match *measurement {
            PositionMeasurement::Point {
                position,
                variance_m2: [vx, vy],
            } => (
                position,
                [math::sqrt(vx), 0.0, math::sqrt(vy)],
                [false, false],
            ),
            PositionMeasurement::Ellipse {
                position,
                covariance_m2: [xx, xy, yy],
            } => {
                let l00 = math::sqrt(xx);
                let l10 = xy / l00;
                // Positive definite (checked above): yy − l10² > 0 but for
                // rounding.
                (
                    position,
                    [l00, l10, math::sqrt((yy - l10 * l10).max(0.0))],
                    [false, false],
                )
            }
            PositionMeasurement::X {
                value_m,
                variance_m2,
            } => (
                Vec2::new(value_m, 0.0),
                [math::sqrt(variance_m2), 0.0, 0.0],
                [false, true],
            ),
            PositionMeasurement::Y {
                value_m,
                variance_m2,
            } => (
                Vec2::new(0.0, value_m),
                [0.0, 0.0, math::sqrt(variance_m2)],
                [true, false],
            ),
        };
        self.filter.redraw_modes();
        self.filter.reposition(|x, gaussian| {
            let (a, b) = (gaussian(), gaussian());
            if !keep[0] {
                x.x = centre.x + l00 * a;
            }
            if !keep[1] {
                x.y = centre.y + l10 * a + l11 * b;
            }
        });
        true
    }
}

impl<const P: usize> ParticleCore<P> {
    /// Weights every particle by the likelihood of the read cell
    /// ([`TagCell::distance_sq`]; module docs, "Tag cells"); `false` (and
    /// nothing changed) for a cell that is not finite with positive sizes.
    pub fn update_cell(&mut self, cell: &TagCell) -> bool {
        let valid = cell.centre.is_finite()
            && cell.sweep.is_finite()
            && cell.half_width_m.is_finite()
            && cell.half_width_m > 0.0
            && cell.edge_std_m.is_finite()
            && cell.edge_std_m > 0.0;
        if !valid {
            return false;
        }
        self.move_stray_cloud(cell);
        let rejected = self.filter.rejected_inputs();
        self.filter
            .update_with_likelihood(|x| cell.distance_sq(x.x, x.y));
        self.filter.rejected_inputs() == rejected
    }
}

impl<const P: usize> ParticleCore<P> {
    /// Reads whose cell lay beyond [`STRAY_GAP_M`] of every particle
    /// (module docs, "Stray clouds"), since the start.
    #[must_use]
    pub fn stray_moves(&self) -> u32 {
        self.stray_moves
    }

    /// Moves the whole cloud by the shift that brings its particle closest
    /// to `cell` onto the cell's edge, if that particle is more than
    /// [`STRAY_GAP_M`] beyond it (module docs, "Stray clouds"); counted.
    fn move_stray_cloud(&mut self, cell: &TagCell) {
        let mut closest = f32::INFINITY;
        let mut shift = Vec2::new(0.0, 0.0);
        for x in self.filter.particles() {
            let distance_sq = cell.distance_sq(x.x, x.y);
            if distance_sq < closest {
                closest = distance_sq;
                shift = cell.shift_onto(x.x, x.y);
            }
        }
        let limit = STRAY_GAP_M / cell.edge_std_m;
        if closest > limit * limit && shift.is_finite() {
            self.filter.shift(|x| {
                x.x += shift.x;
                x.y += shift.y;
            });
            self.stray_moves = self.stray_moves.saturating_add(1);
        }
    }

    /// Weights every particle by the likelihood of the read disc
    /// ([`TagDisc::distance_sq`]; module docs, "Read discs"); `false` (and
    /// nothing changed) for a disc that is not finite with positive sizes.
    pub fn update_disc(&mut self, disc: &TagDisc) -> bool {
        if !disc.is_valid() {
            return false;
        }
        let rejected = self.filter.rejected_inputs();
        self.filter
            .update_with_likelihood(|x| disc.distance_sq(x.x, x.y));
        self.filter.rejected_inputs() == rejected
    }
}

impl<const P: usize> PoseParticleFilter<P> {
    /// Corrects with a range reader's first read of a tag in a pass as
    /// its entry into the disc (module docs, "Read discs"): gated, counted
    /// and re-localised on `entry`, the entry point's Gaussian
    /// ([`TagCellTracker::range_measurement`]: the crescent's moments, near
    /// enough), applied with the disc's likelihood.
    pub fn correct_disc(&mut self, disc: &TagDisc, entry: &PositionMeasurement) -> FixOutcome {
        self.correct_with(entry, |core| core.update_disc(disc))
    }

    /// A filter not yet started (every particle at the origin, zero
    /// weights, a placeholder configuration): the slot that
    /// [`PoseFilter::restart`] starts in place. Built from constants
    /// alone, not inlined and without arguments, so that the compiler
    /// builds it straight in the caller's destination (a call that could
    /// read that destination, e.g. through a configuration passed by
    /// reference from beside it, is returned into a 5 KB temporary on the
    /// stack and copied).
    #[inline(never)]
    #[cfg_attr(not(feature = "fusion-particle-filter"), allow(dead_code))]
    pub(crate) fn blank() -> Self {
        const PLACEHOLDER: PoseFilterConfig = PoseFilterConfig {
            track_width_m: 1.0,
            variance_per_m: 0.0,
            variance_floor_m2: 0.0,
            gate_sigma: 0.0,
            gate_one_dof: 0.0,
            gate_two_dof: 0.0,
            scale_walk_per_m: 0.0,
            recover_after: 0,
            particle_seed: 0,
        };
        PoseFilter::with_core(
            PLACEHOLDER,
            ParticleCore {
                filter: ParticleFilter::blank(NoisyOdometryModel {
                    config: PLACEHOLDER,
                }),
                stray_moves: 0,
            },
        )
    }

    /// Corrects with a read of a tag as its cell (module docs, "Tag
    /// cells"): gated, counted and re-localised on the cell's moments
    /// ([`TagCell::moments`]), applied with the cell's likelihood.
    pub fn correct_cell(&mut self, cell: &TagCell) -> FixOutcome {
        self.correct_with(&cell.moments(), |core| core.update_cell(cell))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimation::fusion::TagCellTracker;
    use crate::estimation::fusion::test_support::stays_finite;
    use crate::geometry::{Pose, Vec2};
    use proptest::prelude::*;

    fn config(seed: u64) -> PoseFilterConfig {
        PoseFilterConfig::new(0.2, 1e-4, 1e-9, 3.0)
            .unwrap()
            .with_particle_seed(seed)
    }

    /// Drives an arc with a fix every 25 ticks from a 1 cm, 0.05 rad
    /// start; returns the worst position error of the last half and the
    /// filter.
    fn drive(seed: u64) -> (f32, PoseParticleFilter<100>) {
        let start = Pose::new(0.0, 0.0, 0.3);
        let mut pf =
            PoseParticleFilter::<100>::new(config(seed), start, [1e-4, 1e-4, 2.5e-3, 0.0]).unwrap();
        let mut truth = Pose::new(0.01, -0.005, 0.35);
        let mut worst = 0.0_f32;
        for k in 0..2000_u32 {
            let step = OdometryStep {
                ds_m: 0.002,
                dtheta_rad: if k % 200 < 100 { 0.004 } else { -0.003 },
                ..OdometryStep::default()
            };
            truth = truth.advance_arc(step.ds_m, step.dtheta_rad);
            pf.predict(&step);
            if k % 25 == 24 {
                let fix = PositionMeasurement::Point {
                    position: truth.position,
                    variance_m2: [1e-4, 1e-4],
                };
                assert_eq!(pf.correct(&fix), FixOutcome::Used);
            }
            if k >= 1000 {
                worst = worst.max((pf.pose().position - truth.position).norm());
            }
        }
        (worst, pf)
    }

    /// It tracks (within 1.5 cm, fixes of σ = 1 cm), repeats bit for bit
    /// from its seed and differs with another.
    #[test]
    fn tracks_and_repeats_from_the_seed() {
        let (worst, first) = drive(5);
        assert!(worst < 0.015, "{worst}");
        let (_, again) = drive(5);
        let (_, other) = drive(6);
        assert_eq!(first, again);
        assert_ne!(first.pose(), other.pose());
        assert!(first.core().filter().resamplings() > 0);
        assert_eq!(first.core().filter().collapses(), 0);
    }

    /// The levels: the configured noise, then `10^{−4}` and `10^{−5}` of
    /// its variance; the prior's inverse distribution function gives half
    /// the draws to level 0 and a quarter to each other, in order; a jump
    /// is rare and draws from the prior.
    #[test]
    fn the_noise_levels_and_their_prior() {
        for (scale, exponent) in LEVEL_STD_SCALE.iter().zip([0.0_f32, -4.0, -5.0]) {
            let variance = scale * scale;
            let expected = math::exp(exponent * core::f32::consts::LN_10);
            assert!(
                (variance / expected - 1.0).abs() < 1e-5,
                "{exponent}: {variance}"
            );
        }
        assert_eq!(prior_level(0.0), 0);
        assert_eq!(prior_level(0.499_999), 0);
        assert_eq!(prior_level(0.5), 1);
        assert_eq!(prior_level(0.749_999), 1);
        assert_eq!(prior_level(0.75), 2);
        assert_eq!(prior_level(0.999_999), 2);
        let model = NoisyOdometryModel { config: config(1) };
        assert_eq!(model.next_mode(1, LEVEL_JUMP_PROBABILITY), 1);
        assert_eq!(model.next_mode(1, 0.9), 1);
        assert_eq!(model.next_mode(1, 0.0), 0);
        assert_eq!(model.next_mode(0, 0.999_999 * LEVEL_JUMP_PROBABILITY), 2);
    }

    /// On wheels that do not slip (the truth drives the odometry) the
    /// particles of the quieter levels take over: at the end of the drive
    /// most particles are below the configured noise, and fewer than 30
    /// are at it where the prior (and the jumps) put half.
    #[test]
    fn quiet_levels_take_over_on_exact_wheels() {
        let (_, pf) = drive(5);
        let counts = level_counts(&pf);
        println!("particles per level after the drive: {counts:?}");
        let quiet: usize = counts[1..].iter().sum();
        assert!(quiet > 50 && counts[0] < 30, "{counts:?}");
    }

    /// Particles per level.
    fn level_counts(pf: &PoseParticleFilter<100>) -> [usize; NOISE_LEVELS as usize] {
        let mut counts = [0_usize; NOISE_LEVELS as usize];
        for &m in pf.core().filter().modes() {
            counts[usize::from(m)] += 1;
        }
        counts
    }

    /// A re-localisation redraws every level from the prior (module docs,
    /// "Noise level"): after the drive the quiet levels hold the cloud,
    /// (fewer than 30 particles at the configured noise), after fixes that
    /// re-localise it about half are back at it (the prior's half; 35 and
    /// 65 are three standard deviations of the binomial either side).
    #[test]
    fn a_relocalisation_redraws_the_levels() {
        let (_, mut pf) = drive(5);
        let before = level_counts(&pf);
        assert!(before[0] < 30, "{before:?}");
        let far = PositionMeasurement::Point {
            position: pf.pose().position + Vec2::new(0.5, 0.0),
            variance_m2: [1e-4, 1e-4],
        };
        for _ in 0..2 {
            assert_eq!(pf.correct(&far), FixOutcome::Gated);
        }
        assert_eq!(pf.correct(&far), FixOutcome::Used);
        let after = level_counts(&pf);
        println!("particles per level: {before:?} before, {after:?} after");
        assert!((35..=65).contains(&after[0]), "{after:?}");
        assert!(after[1] > 10 && after[2] > 10, "{after:?}");
    }

    /// The filter's size: the generic filter's particles, buffer, weights
    /// and log-likelihoods, a byte of level per particle with its
    /// resampling buffer (module docs of the generic filter, "Memory"),
    /// and the count of stray moves.
    #[test]
    fn memory_footprint() {
        let core = core::mem::size_of::<ParticleCore<100>>();
        println!("ParticleCore<100>: {core} B");
        assert_eq!(core, 5_248);
    }

    /// Started in place (from the blank, as the estimator does) it is the
    /// filter `new` builds, bit for bit, and it restarts in place (a
    /// second start on a used filter) to the same again; a start it
    /// cannot take leaves it as it was.
    #[test]
    fn a_filter_started_in_place_is_the_one_new_builds() {
        let start = Pose::new(0.3, -0.2, 1.0);
        let variances = [1e-3, 2e-3, 0.5, 1e-4];
        let built = PoseParticleFilter::<100>::new(config(11), start, variances).unwrap();
        let mut slot = PoseParticleFilter::<100>::blank();
        slot.restart(config(11), start, variances).unwrap();
        assert_eq!(slot, built);
        let (_, mut used) = drive(5);
        used.restart(config(11), start, variances).unwrap();
        assert_eq!(used, built);
        let bad = [f32::NAN, 1e-3, 0.5, 0.0];
        assert_eq!(
            used.restart(config(12), start, bad),
            Err(crate::estimation::fusion::config::PoseFilterError::InitialVariance)
        );
        assert_eq!(used, built);
    }

    /// An axis fix pulls the estimate along its axis (that it weights by
    /// `x` alone is `ParticleFilter::update_with_std`'s test; `y` moves
    /// only by the sampling error of the reweighted particles).
    #[test]
    fn an_axis_fix_measures_its_axis() {
        let mut pf = PoseParticleFilter::<100>::new(
            config(1),
            Pose::new(0.0, 0.0, 0.0),
            [1e-2, 1e-2, 0.01, 0.0],
        )
        .unwrap();
        let before = pf.pose();
        let fix = PositionMeasurement::X {
            value_m: 0.1,
            variance_m2: 1e-4,
        };
        assert_eq!(pf.correct(&fix), FixOutcome::Used);
        let after = pf.pose();
        assert!(
            after.position.x - before.position.x > 0.05,
            "{before:?} {after:?}"
        );
    }

    /// A read as its cell: the particles that left the cell lose their
    /// weight, the estimate moves into it, and a cell far from every
    /// particle is gated (its moments' Mahalanobis distance).
    #[test]
    fn a_cell_read_keeps_the_particles_in_the_cell() {
        let mut pf = PoseParticleFilter::<100>::new(
            config(2),
            Pose::new(0.04, 0.0, 0.0),
            [4e-4, 4e-4, 0.01, 0.0],
        )
        .unwrap();
        let mut cells = TagCellTracker::new(0.1).unwrap();
        let cell = cells
            .cell(Vec2::new(0.0, 0.0), Vec2::new(0.001, 0.0))
            .unwrap();
        assert_eq!(pf.correct_cell(&cell), FixOutcome::Used);
        let inside = pf
            .core()
            .filter()
            .particles()
            .iter()
            .zip(pf.core().filter().weights())
            // Within 3 σ of the softened edge (roughening may jitter a
            // copy just past it).
            .filter(|(x, _)| cell.distance_sq(x.x, x.y) < 9.0)
            .map(|(_, w)| w)
            .sum::<f32>();
        assert!(inside > 0.95, "{inside}");
        assert!(pf.pose().position.x < 0.05 + 0.001, "{:?}", pf.pose());
        let far = cells.cell(Vec2::new(1.0, 1.0), Vec2::ZERO).unwrap();
        assert_eq!(pf.correct_cell(&far), FixOutcome::Gated);
        let broken = TagCell {
            edge_std_m: f32::NAN,
            ..cell
        };
        assert_eq!(pf.correct_cell(&broken), FixOutcome::Invalid);
    }

    /// A cloud that lost its cell (module docs, "Stray clouds"): a tight
    /// cloud 5 cm beyond the edge of a 30 cm cell (within the gate on the
    /// cell's moments) is moved onto the cell with its heading as it was,
    /// and counted; a cloud that meets the cell, or is within
    /// [`STRAY_GAP_M`] of it, is weighted without a move.
    #[test]
    fn a_stray_cloud_is_moved_onto_the_read_cell() {
        let start = Pose::new(0.20, 0.0, 0.3);
        let mut pf =
            PoseParticleFilter::<100>::new(config(3), start, [1e-6, 1e-6, 1e-4, 0.0]).unwrap();
        let heading_before = pf.pose().heading_rad;
        let mut cells = TagCellTracker::new(0.3).unwrap();
        // The cell spans x ∈ [−0.15, 0.15]: every particle is about 5 cm
        // beyond its edge.
        let cell = cells.cell(Vec2::new(0.0, 0.0), Vec2::ZERO).unwrap();
        assert_eq!(pf.correct_cell(&cell), FixOutcome::Used);
        assert_eq!(pf.core().stray_moves(), 1);
        // The closest particle on the edge, the others behind it weighted by
        // the edge's 1 mm tail: the mean within a few mm of the edge, not
        // 5 cm beyond it.
        let x = pf.pose().position.x;
        assert!((0.14..=0.155).contains(&x), "{x}");
        // The heading as it was, but for the resampling's roughening.
        let heading = pf.pose().heading_rad;
        assert!(
            (heading - heading_before).abs() < 0.02,
            "{heading_before} → {heading}"
        );
        // Now inside: reads of the cell weight without moving.
        assert_eq!(pf.correct_cell(&cell), FixOutcome::Used);
        assert_eq!(pf.core().stray_moves(), 1);

        // 1 cm beyond the edge: weighted, not moved.
        let mut near = PoseParticleFilter::<100>::new(
            config(3),
            Pose::new(0.16, 0.0, 0.3),
            [1e-8, 1e-8, 1e-4, 0.0],
        )
        .unwrap();
        assert_eq!(near.correct_cell(&cell), FixOutcome::Used);
        assert_eq!(near.core().stray_moves(), 0);
    }

    /// `shift_onto` brings a position onto the cell: the span misses it
    /// before the move and meets it after, on either side and axis; a
    /// position inside does not move.
    #[test]
    fn the_shift_onto_a_cell_is_the_gap_to_its_nearer_edge() {
        let mut cells = TagCellTracker::new(0.1).unwrap();
        let cell = cells
            .cell(Vec2::new(1.0, 2.0), Vec2::new(0.004, -0.003))
            .unwrap();
        for (x, y) in [(1.2, 2.0), (0.8, 2.0), (1.0, 2.3), (1.0, 1.7), (1.3, 1.6)] {
            assert!(cell.distance_sq(x, y) > 100.0, "({x}, {y})");
            let shift = cell.shift_onto(x, y);
            let moved = cell.distance_sq(x + shift.x, y + shift.y);
            assert!(moved < 1e-3, "({x}, {y}) → {shift:?}: {moved}");
        }
        assert_eq!(cell.shift_onto(1.01, 2.02), Vec2::ZERO);
        assert!(!cell.shift_onto(f32::NAN, 2.0).is_finite());
    }

    /// Re-localisation keeps what the particles know: after three gated
    /// fixes 40 cm away the filter re-localises on the third, every
    /// particle's heading is the one it had (the Gaussian restart of the
    /// EKF would have spread them over `(π/2)²`), and the estimate is at
    /// the fix.
    #[test]
    fn relocalisation_keeps_each_particles_heading() {
        let mut pf = PoseParticleFilter::<100>::new(
            config(7),
            Pose::new(0.0, 0.0, 0.8),
            [1e-4, 1e-4, 1e-4, 1e-6],
        )
        .unwrap();
        let headings: [f32; 100] = core::array::from_fn(|i| pf.core().filter().particles()[i].z);
        let scales: [f32; 100] = core::array::from_fn(|i| pf.core().filter().particles()[i].w);
        let fix = PositionMeasurement::Point {
            position: Vec2::new(0.4, 0.1),
            variance_m2: [1e-4, 1e-4],
        };
        assert_eq!(pf.correct(&fix), FixOutcome::Gated);
        assert_eq!(pf.correct(&fix), FixOutcome::Gated);
        assert_eq!(pf.correct(&fix), FixOutcome::Used);
        assert_eq!(pf.counters().relocalisations, 1);
        let particles = pf.core().filter().particles();
        for (i, x) in particles.iter().enumerate() {
            assert_eq!((x.z, x.w), (headings[i], scales[i]), "particle {i}");
        }
        let pose = pf.pose();
        assert!((pose.heading_rad - 0.8).abs() < 0.01, "{pose:?}");
        assert!(
            (pose.position - Vec2::new(0.4, 0.1)).norm() < 0.01,
            "{pose:?}"
        );
    }

    /// An axis fix re-localises its axis only: every particle keeps its
    /// `y` (and heading), its `x` is redrawn at the fix.
    #[test]
    fn an_axis_relocalisation_redraws_that_axis_only() {
        let mut pf = PoseParticleFilter::<100>::new(
            config(8),
            Pose::new(0.0, 0.2, -1.0),
            [1e-4, 1e-4, 1e-4, 0.0],
        )
        .unwrap();
        let before = *pf.core().filter().particles();
        let fix = PositionMeasurement::X {
            value_m: -0.5,
            variance_m2: 1e-4,
        };
        for _ in 0..2 {
            assert_eq!(pf.correct(&fix), FixOutcome::Gated);
        }
        assert_eq!(pf.correct(&fix), FixOutcome::Used);
        for (x, old) in pf.core().filter().particles().iter().zip(before.iter()) {
            assert_eq!((x.y, x.z), (old.y, old.z));
            assert!((x.x + 0.5).abs() < 0.06, "{x:?}");
        }
    }

    /// A read disc: the particles off the entry's crescent (inside the
    /// disc at the read, outside it a tick before) lose their weight, so
    /// the estimate moves to the side the robot entered from; an entry far
    /// from every particle is gated, a broken disc refused.
    #[test]
    fn a_disc_read_keeps_the_particles_that_entered_the_disc() {
        let mut pf = PoseParticleFilter::<100>::new(
            config(9),
            Pose::new(-0.02, 0.0, 0.0),
            [1e-4, 1e-4, 0.01, 0.0],
        )
        .unwrap();
        // Entered moving +x: the crescent is the disc's left edge, 1 cm
        // deep.
        let disc = TagDisc {
            centre: Vec2::new(0.03, 0.0),
            radius_m: 0.05,
            lag: Vec2::ZERO,
            sweep: Vec2::new(0.01, 0.0),
            edge_std_m: DISC_EDGE_STD_M,
        };
        let on_crescent = pf
            .core()
            .filter()
            .particles()
            .iter()
            .filter(|x| disc.distance_sq(x.x, x.y) == 0.0)
            .count();
        assert!((5..60).contains(&on_crescent), "{on_crescent}");
        let entry = PositionMeasurement::Point {
            position: Vec2::new(-0.015, 0.0),
            variance_m2: [1e-4, 4e-4],
        };
        assert_eq!(pf.correct_disc(&disc, &entry), FixOutcome::Used);
        let filter = pf.core().filter();
        // Within 3 σ of the softened edges (roughening after a resampling
        // may jitter a copy just past one).
        let kept: f32 = filter
            .particles()
            .iter()
            .zip(filter.weights())
            .filter(|(x, _)| disc.distance_sq(x.x, x.y) < 9.0)
            .map(|(_, w)| w)
            .sum();
        assert!(kept > 0.99, "{kept}");
        let x = pf.pose().position.x;
        assert!((-0.025..-0.005).contains(&x), "{:?}", pf.pose());
        let far = PositionMeasurement::Point {
            position: Vec2::new(2.0, 0.0),
            variance_m2: [1e-4, 1e-4],
        };
        assert_eq!(pf.correct_disc(&disc, &far), FixOutcome::Gated);
        let broken = TagDisc {
            radius_m: 0.0,
            ..disc
        };
        assert_eq!(pf.correct_disc(&broken, &entry), FixOutcome::Invalid);
    }

    /// The entry's likelihood: 0 on the crescent (in the disc at the read,
    /// the lag taken off; out of it a tick before), a Gaussian tail of the
    /// edge's softening off it on either side, NaN for NaN.
    #[test]
    fn the_disc_likelihood_is_the_entry_crescent_with_soft_edges() {
        let disc = TagDisc {
            centre: Vec2::new(1.0, 2.0),
            radius_m: 0.1,
            lag: Vec2::new(0.01, 0.0),
            sweep: Vec2::new(0.0, 0.005),
            edge_std_m: 0.002,
        };
        // Entered moving +y: the crescent is the disc's lower edge.
        assert_eq!(disc.distance_sq(1.01, 1.903), 0.0);
        // Beyond the disc at the read, by 2 mm (one σ_e, squared: 1).
        let past = disc.distance_sq(1.01, 1.898);
        assert!((past - 1.0).abs() < 0.01, "{past}");
        // At the centre: in the disc a tick before too (5 mm behind the
        // centre), 9.5 cm deep: (0.095 / 0.002)².
        let deep = disc.distance_sq(1.01, 2.0);
        assert!((deep - 2256.25).abs() < 0.5, "{deep}");
        assert!(disc.distance_sq(f32::NAN, 2.0).is_nan());
    }

    proptest! {
        /// Cells of any size, place and softening, finite or not, leave the
        /// estimate finite and never panic.
        #[test]
        fn finite_out_on_any_cell(
            cells in proptest::collection::vec(
                (any::<f32>(), -1.0f32..1.0, any::<f32>(), -0.01f32..0.01, any::<f32>()),
                1..30,
            ),
        ) {
            let mut filter = PoseParticleFilter::<16>::new(config(4), Pose::new(0.0, 0.0, 0.0), [1e-2, 1e-2, 1.0, 0.0]).unwrap();
            let step = OdometryStep { ds_m: 0.002, dtheta_rad: 0.001, ..OdometryStep::default() };
            for (x, y, half, sweep, edge) in cells {
                filter.predict(&step);
                let cell = TagCell {
                    centre: Vec2::new(x, y),
                    half_width_m: half,
                    sweep: Vec2::new(sweep, -sweep),
                    lag: Vec2::new(0.5 * sweep, 0.0),
                    edge_std_m: edge,
                };
                let _ = filter.correct_cell(&cell);
                let pose = filter.pose();
                prop_assert!(pose.position.is_finite() && pose.heading_rad.is_finite());
            }
        }

        /// Finite or not, no input leaves the estimate non-finite.
        #[test]
        fn finite_out_on_any_input(
            steps in proptest::collection::vec((-1.0f32..1.0, -1.0f32..1.0, any::<bool>()), 1..40),
            fixes in proptest::collection::vec((-100.0f32..100.0, -100.0f32..100.0, 0u8..5), 1..40),
        ) {
            let mut filter = PoseParticleFilter::<16>::new(config(3), Pose::new(0.0, 0.0, 0.0), [1.0, 1.0, 9.0, 4e-4]).unwrap();
            prop_assert!(stays_finite(&mut filter, &steps, &fixes));
        }
    }
}
