//! What the fuzz targets share: specs and values drawn from the fuzzer's
//! bytes.
//!
//! The core's spec types do not derive `Arbitrary` (the core does not
//! depend on `arbitrary`), so they are drawn here, field by field. Each
//! value is most often a typical one (so that most specs build and the
//! targets reach the control loop) and otherwise a scaled, raw or special
//! one: NaN, ±∞, ±0, subnormal, huge. When the bytes run out every draw
//! gives its typical value, so a short input is a valid spec.

use arbitrary::{Result, Unstructured};
use wmr_core::pilot::spec::{PilotSpec, TrackerSpec};
use wmr_core::drive::spec::DriveSpec;
use wmr_core::estimation::spec::{EstimatorSpec, FusionFilterSpec, FusionSpec, SensorSpec};
use wmr_core::control::spec::LawSpec;
use wmr_core::devices::tag_grid::TagGridSpec;
use wmr_core::reference::TrajectorySpec;

/// Values a validation must refuse, or must take at their edge.
pub const SPECIAL_F32: [f32; 14] = [
    f32::NAN,
    f32::INFINITY,
    f32::NEG_INFINITY,
    0.0,
    -0.0,
    f32::MAX,
    f32::MIN,
    f32::MIN_POSITIVE,
    1e-45, // smallest subnormal
    f32::EPSILON,
    1e30,
    -1e30,
    1.0,
    -1.0,
];

/// A float: `typical` most of the time, otherwise `typical` scaled, a
/// special value, or any bit pattern.
///
/// # Errors
/// Never in practice (`Unstructured` gives defaults when empty).
pub fn float(u: &mut Unstructured, typical: f32) -> Result<f32> {
    Ok(match u.int_in_range(0_u8..=15)? {
        0..=9 => typical,
        10 => typical * *u.choose(&[0.0, -1.0, 0.5, 2.0, 10.0, 1e3, 1e-3, 1e6])?,
        11 => *u.choose(&SPECIAL_F32)?,
        12 => f32::from_bits(u.arbitrary()?),
        _ => typical * (1.0 + f32::from(u.arbitrary::<i8>()?) / 64.0),
    })
}

/// A count: `typical` most of the time, otherwise small or any.
///
/// # Errors
/// Never in practice.
pub fn count(u: &mut Unstructured, typical: u32) -> Result<u32> {
    Ok(match u.int_in_range(0_u8..=7)? {
        0..=4 => typical,
        5 => u.int_in_range(0..=3)?,
        6 => *u.choose(&[u32::MAX, u32::MAX - 1, 1 << 31, 1 << 16, 65_535])?,
        _ => u.arbitrary()?,
    })
}

fn trajectory(u: &mut Unstructured) -> Result<TrajectorySpec> {
    Ok(match u.int_in_range(0_u8..=2)? {
        0 => TrajectorySpec::Line {
            start_m: [float(u, 0.0)?, float(u, 0.0)?],
            heading_rad: float(u, 0.0)?,
            speed_m_s: float(u, 0.2)?,
        },
        1 => TrajectorySpec::FigureEight {
            h1_m: float(u, 5.0)?,
            h2_rad_s: float(u, 0.02)?,
            phase_rad: float(u, -core::f32::consts::FRAC_PI_2)?,
        },
        _ => TrajectorySpec::Circle {
            center_m: [float(u, 0.0)?, float(u, 0.0)?],
            radius_m: float(u, 1.0)?,
            rate_rad_s: float(u, 0.2)?,
            phase_rad: float(u, 0.0)?,
        },
    })
}

fn estimator(u: &mut Unstructured) -> Result<EstimatorSpec> {
    Ok(match u.int_in_range(0_u8..=3)? {
        0 => EstimatorSpec::HeadingObserver,
        1 => {
            let [a1, a2, a3, a4] = EstimatorSpec::DEFAULT_POSE_OBSERVER_GAINS;
            EstimatorSpec::PoseObserver {
                gains: [float(u, a1)?, float(u, a2)?, float(u, a3)?, float(u, a4)?],
            }
        }
        _ => {
            let d = FusionSpec::default();
            EstimatorSpec::Fusion(FusionSpec {
                // Chosen by the caller.
                filter: FusionFilterSpec::Ekf,
                wheel_variance_per_m: float(u, d.wheel_variance_per_m)?,
                gate_sigma: float(u, d.gate_sigma)?,
                scale_prior: float(u, 4e-4)?,
                max_blind_distance_m: if u.arbitrary()? {
                    Some(float(u, 3.2)?)
                } else {
                    None
                },
                edge_constraint: u.arbitrary()?,
                particle_seed: u.arbitrary()?,
            })
        }
    })
}

fn law(u: &mut Unstructured) -> Result<LawSpec> {
    Ok(match u.int_in_range(0_u8..=2)? {
        0 => LawSpec::Saturated,
        1 => LawSpec::Cascaded {
            c1_per_s: float(u, LawSpec::DEFAULT_C_PER_S)?,
            c2_per_s: float(u, LawSpec::DEFAULT_C_PER_S)?,
        },
        _ => LawSpec::HeadingErrorSine {
            a_s_per_m2: float(u, LawSpec::DEFAULT_SINE_A_S_PER_M2)?,
            c2_per_s: float(u, LawSpec::DEFAULT_C_PER_S)?,
            gamma: float(u, LawSpec::DEFAULT_GAMMA)?,
        },
    })
}

/// A pilot spec around a typical 2048-count, 0.3 m robot at 100 Hz.
///
/// # Errors
/// Never in practice.
pub fn pilot_spec(u: &mut Unstructured) -> Result<PilotSpec> {
    let mut spec = any_pilot_spec(u)?;
    if let EstimatorSpec::Fusion(f) = &mut spec.tracker.estimator {
        f.filter = *u.choose(&[
            FusionFilterSpec::Ekf,
            FusionFilterSpec::Ukf,
            FusionFilterSpec::ParticleFilter,
        ])?;
    }
    Ok(spec)
}

/// As [`pilot_spec`], but the fusion estimator is never the particle
/// filter (100 particles: ten times the EKF's work per tick), for the
/// targets that fuzz what is around the pilot rather than the pilot.
///
/// # Errors
/// Never in practice.
pub fn light_pilot_spec(u: &mut Unstructured) -> Result<PilotSpec> {
    let mut spec = any_pilot_spec(u)?;
    if let EstimatorSpec::Fusion(f) = &mut spec.tracker.estimator {
        f.filter = *u.choose(&[FusionFilterSpec::Ekf, FusionFilterSpec::Ukf])?;
    }
    Ok(spec)
}

fn any_pilot_spec(u: &mut Unstructured) -> Result<PilotSpec> {
    let period_s = float(u, 0.01)?;
    let drive = DriveSpec {
        wheel_radius_m: float(u, 0.05)?,
        track_width_m: float(u, 0.3)?,
        encoder_counts_per_rev: count(u, 2048)?,
        max_wheel_speed_rad_s: float(u, 20.0)?,
        max_wheel_accel_rad_s2: float(u, 40.0)?,
        feedforward_duty_per_rad_s: float(u, 0.05)?,
        kp_duty_per_rad_s: float(u, 0.05)?,
        ki_duty_per_rad: float(u, 0.5)?,
        speed_observer: None,
    };
    // The sensors' track width must equal the drive's (bit for bit): keep
    // it so most of the time.
    let sensor_track_width_m = if u.ratio(1, 8)? {
        float(u, 0.3)?
    } else {
        drive.track_width_m
    };
    let tracker = TrackerSpec {
        period_s,
        trajectory: trajectory(u)?,
        gains: [float(u, 0.5)?, float(u, 0.5)?, float(u, 1.0)?],
        observer_gain_per_m: float(u, 10.0)?,
        observer_min_speed_m_s: float(u, 1e-3)?,
        fix_timeout_ticks: count(u, 50)?,
        failsafe_decel_m_s2: float(u, 0.5)?,
        max_fix_age_ticks: count(u, 2)?,
        estimator: estimator(u)?,
        law: law(u)?,
        sensors: SensorSpec {
            track_width_m: sensor_track_width_m,
            wheel_variance_floor_m2: float(u, 1.96e-9)?,
            tag_spacing_m: float(u, 0.1)?,
            read_radius_m: float(u, 0.0)?,
            antenna_offset_m: [float(u, 0.1)?, float(u, 0.0)?],
        },
    };
    Ok(PilotSpec {
        tracker,
        drive,
        encoder_bits: count(u, 16)?,
        max_encoder_fault_ticks: count(u, 5)?,
    })
}

/// A tag grid around the origin, 0.1 m spacing.
///
/// # Errors
/// Never in practice.
pub fn tag_grid_spec(u: &mut Unstructured) -> Result<TagGridSpec> {
    Ok(TagGridSpec {
        origin_m: [float(u, -1.0)?, float(u, -1.0)?],
        spacing_m: float(u, 0.1)?,
        rows: if u.ratio(1, 8)? { u.arbitrary()? } else { 21 },
        columns: if u.ratio(1, 8)? { u.arbitrary()? } else { 21 },
    })
}

/// The next raw encoder counter after `previous`: mostly a small move,
/// sometimes a failed read (`None`) or any value (a jump).
///
/// # Errors
/// Never in practice.
pub fn encoder_count(u: &mut Unstructured, previous: u32) -> Result<Option<u32>> {
    Ok(match u.int_in_range(0_u8..=15)? {
        0 => None,
        1 => Some(u.arbitrary()?),
        _ => Some(previous.wrapping_add_signed(i32::from(u.arbitrary::<i8>()?))),
    })
}
