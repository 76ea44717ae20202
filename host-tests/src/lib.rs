//! Integration tests of `wmr-core` live in `tests/`: reproductions of the
//! papers' simulations (`paper_001_*.rs`) and whole-stack properties
//! (`robustness.rs`). This library only holds what they share.

pub mod fusion;
pub mod paper_002;
pub mod paper_003;
pub mod paper_004;

use wmr_core::control::LawChoice;
use wmr_core::control::saturated::TrackingGains;
use wmr_core::drive::{DriveConfig, SpeedLoopGains};
use wmr_core::estimation::EstimatorChoice;
use wmr_core::estimation::heading_observer::HeadingObserverConfig;
use wmr_core::geometry::DiffDriveGeometry;
use wmr_core::pilot::tracker::TrackerConfig;
use wmr_core::pilot::{Pilot, PilotConfig};
use wmr_core::reference::{FigureEight, ReferenceSample};

/// Control period of [`paper_pilot`], s.
pub const PAPER_PILOT_PERIOD_S: f32 = 0.01;

/// A pilot with paper 001 §6.3.2's observer and gains on its figure-eight,
/// driving a small robot (wheel radius 3 cm, track 20 cm, 2048 counts/rev,
/// 16-bit counters, 20 rad/s top wheel speed, 10 ms tick).
#[must_use]
pub fn paper_pilot() -> Pilot {
    let h = PAPER_PILOT_PERIOD_S;
    let tracker = TrackerConfig::new(
        EstimatorChoice::HeadingObserver(
            HeadingObserverConfig::new(0.6, h).expect("valid observer"),
        ),
        LawChoice::Saturated(TrackingGains::new(0.11, 0.11, 0.1).expect("valid gains")),
        FigureEight::paper_001().into(),
        100,
    )
    .expect("valid tracker");
    let drive = DriveConfig::new(
        DiffDriveGeometry::new(0.03, 0.2, 2048).expect("valid geometry"),
        h,
        20.0,
        100.0,
        SpeedLoopGains {
            feedforward_duty_per_rad_s: 0.05,
            kp_duty_per_rad_s: 0.02,
            ki_duty_per_rad: 0.1,
        },
    )
    .expect("valid drive");
    Pilot::new(PilotConfig::new(tracker, drive, 16).expect("valid pilot")).expect("valid pilot")
}

/// Start offsets of an ensemble, m: the same run from starts 0, 1, …, 15 µm
/// apart along x (and, in a scenario, headings 0, 10, …, 150 µrad apart:
/// a plant behind encoders and a tag reader quantizes a µm away).
///
/// Some closed loops amplify the last bit: the fusion EKF's largest error
/// on paper 001's figure-eight is 0.0037–0.0069 m over these starts with
/// libm's `sinf`/`cosf`, and a 1-ulp change of one `sin` moves a single
/// run as far. A single run of such a loop is one sample of that spread,
/// so its tests assert the ensemble's median and print its range.
pub const ENSEMBLE_OFFSETS_M: [f64; ENSEMBLE] = {
    let mut offsets = [0.0; ENSEMBLE];
    let mut k = 0;
    while k < ENSEMBLE {
        offsets[k] = k as f64 * 1e-6;
        k += 1;
    }
    offsets
};

/// Runs in an ensemble.
pub const ENSEMBLE: usize = 32;

/// The median of `values` (the mean of the middle two for an even count;
/// NaN for none).
#[must_use]
pub fn median(values: &[f64]) -> f64 {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    match sorted.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => sorted[n / 2],
        n => 0.5 * (sorted[n / 2 - 1] + sorted[n / 2]),
    }
}

/// `min / median / max` of `values`, for the test output.
#[must_use]
pub fn spread(values: &[f64]) -> String {
    let min = values.iter().copied().fold(f64::INFINITY, f64::min);
    let max = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    format!("{min:.4} / {:.4} / {max:.4}", median(values))
}

/// The largest and mean tracking errors of each run of an ensemble, m.
#[derive(Debug, Clone, PartialEq)]
pub struct EnsembleErrors {
    /// Each run's largest error.
    pub maxima: Vec<f64>,
    /// Each run's mean error.
    pub means: Vec<f64>,
}

impl EnsembleErrors {
    /// From each run's `(max, mean)`, printing `label: max …, mean …` with
    /// the spreads ([`spread`]).
    #[must_use]
    pub fn new(label: &str, runs: impl IntoIterator<Item = (f64, f64)>) -> Self {
        let (maxima, means) = runs.into_iter().unzip();
        let errors = Self { maxima, means };
        println!(
            "{label}: max {} m, mean {} m (min / median / max)",
            spread(&errors.maxima),
            spread(&errors.means)
        );
        errors
    }

    /// The median run's largest error.
    #[must_use]
    pub fn median_max(&self) -> f64 {
        median(&self.maxima)
    }

    /// The median run's mean error.
    #[must_use]
    pub fn median_mean(&self) -> f64 {
        median(&self.means)
    }

    /// The worst run's largest error.
    #[must_use]
    pub fn worst_max(&self) -> f64 {
        self.maxima.iter().copied().fold(0.0, f64::max)
    }
}

/// [`run_scenario_variant`] from each start of [`ENSEMBLE_OFFSETS_M`],
/// the `k`-th also turned by `k · 10 µrad`.
///
/// # Panics
/// As [`run_scenario_variant`].
pub fn run_scenario_ensemble(
    name: &str,
    edit: impl Fn(&mut firmware_sim::Scenario),
) -> Vec<firmware_sim::Summary> {
    ENSEMBLE_OFFSETS_M
        .iter()
        .map(|offset| {
            run_scenario_variant(name, |scenario| {
                edit(scenario);
                scenario.initial.x_m += offset;
                // 1 µm ↦ 10 µrad.
                scenario.initial.heading_rad += offset * 10.0;
            })
        })
        .collect()
}

/// Runs an embedded scenario of the simulator after `edit` changes it,
/// going through the scenario file form (serialise, parse, validate) as a
/// user's edited file would; prints and returns the run's summary.
///
/// # Panics
/// If the scenario is unknown, the edited scenario does not validate, or
/// the run fails.
#[must_use]
pub fn run_scenario_variant(
    name: &str,
    edit: impl FnOnce(&mut firmware_sim::Scenario),
) -> firmware_sim::Summary {
    let mut scenario = firmware_sim::Scenario::embedded(name).expect("embedded scenario");
    edit(&mut scenario);
    let toml = scenario.to_toml_string().expect("serializable");
    let scenario = firmware_sim::Scenario::from_toml_str(&toml).expect("the file form validates");
    let s = firmware_sim::run(&scenario, |_, _| {})
        .expect("runs")
        .summary;
    println!(
        "{name}, {}: after {} s max {:.4} m, mean {:.4} m, RMS {:.4} m",
        s.controller, s.transient_s, s.max_error_m, s.mean_error_m, s.rms_error_m
    );
    s
}

/// Heading of the reference's velocity, `θ_r = atan2(ẏ_r, ẋ_r)` (paper 001, (52)).
#[must_use]
pub fn reference_heading(r: &ReferenceSample) -> f32 {
    libm::atan2f(r.velocity.y, r.velocity.x)
}

/// Turn rate of the reference, `θ̇_r = (ẋ_r ÿ_r − ẏ_r ẍ_r)/v_r²`.
#[must_use]
pub fn reference_turn_rate(r: &ReferenceSample) -> f32 {
    let v2 = r.velocity.x * r.velocity.x + r.velocity.y * r.velocity.y;
    (r.velocity.x * r.acceleration.y - r.velocity.y * r.acceleration.x) / v2
}
