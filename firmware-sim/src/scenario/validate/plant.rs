//! The plant: the unicycle, or the differential drive with the core's
//! pilot, its wheel dynamics and its wheel-speed observer.

use wmr_core::drive::spec as drive_spec;
use wmr_core::pilot::PilotConfig;
use wmr_core::pilot::spec::{PilotSpec, TrackerSpec};

use crate::devices::EncoderGlitches;
use crate::plant::{DiffDriveParams, LoadTorque, WheelDynamics, WheelErrors};

use crate::scenario::defaults;
use crate::scenario::error::shown;
use crate::scenario::error::{ScenarioError, in_range, non_negative, positive, probability};
use crate::scenario::schema::Scenario;
use crate::scenario::tables::{DynamicsSpec, PlantSpec, SpeedObserverSpec, WheelErrorSpec};
use wmr_core::plausible::{
    GAIN, MASS_KG, SPEED_LOOP_GAIN, TORQUE_NM, TRACK_WIDTH_M, WHEEL_ACCEL_RAD_S2,
    WHEEL_INERTIA_KG_M2, WHEEL_RADIUS_M, WHEEL_SPEED_RAD_S, YAW_INERTIA_KG_M2,
};

use super::{PlantSetup, f, spec_refusal};

/// The core's spec of the wheel-speed observer `o` (its keys checked one
/// by one, to name the key; the core checks the whole when it builds it).
pub(super) fn speed_observer_spec(
    o: &SpeedObserverSpec,
    params: &DiffDriveParams,
) -> Result<drive_spec::SpeedObserverSpec, ScenarioError> {
    let field = |key: &str| format!("drive.speed_observer.{key}");
    Ok(drive_spec::SpeedObserverSpec {
        mass_kg: f(in_range(&field("mass_kg"), o.mass_kg, MASS_KG, "kg")?),
        yaw_inertia_kg_m2: f(in_range(
            &field("yaw_inertia_kg_m2"),
            o.yaw_inertia_kg_m2,
            YAW_INERTIA_KG_M2,
            "kg m²",
        )?),
        wheel_inertia_kg_m2: f(in_range(
            &field("wheel_inertia_kg_m2"),
            o.wheel_inertia_kg_m2,
            WHEEL_INERTIA_KG_M2,
            "kg m²",
        )?),
        stall_torque_nm: f(in_range(
            &field("stall_torque_nm"),
            o.stall_torque_nm,
            TORQUE_NM,
            "N·m",
        )?),
        no_load_speed_rad_s: f(params.wheel_speed_at_full_duty_rad_s),
        lambda_per_s: f(in_range(
            &field("lambda_per_s"),
            o.lambda_per_s,
            GAIN,
            "1/s",
        )?),
        friction_gain: f(in_range(
            &field("friction_gain"),
            o.friction_gain,
            GAIN,
            "",
        )?),
        disturbance_gain: f(in_range(
            &field("disturbance_gain"),
            o.disturbance_gain,
            GAIN,
            "",
        )?),
    })
}

/// The largest slip-noise variance the simulator takes, m²/m: a metre
/// rolled with a standard deviation of a metre.
const MAX_TRAVEL_VARIANCE_M2_PER_M: f64 = 1.0;
/// The largest wheel scale error the simulator takes (either sign).
const MAX_SCALE_ERROR: f64 = 0.5;

/// The plant's realistic wheels from `[plant.wheels]`, each key checked
/// and refused by name with its value; `None` when the table is absent.
pub(super) fn wheel_errors(
    spec: Option<&WheelErrorSpec>,
    track_width_m: f64,
    seed: u64,
) -> Result<Option<WheelErrors>, ScenarioError> {
    let Some(w) = spec else {
        return Ok(None);
    };
    let q = w.travel_variance_m2_per_m;
    if !(q.is_finite() && (0.0..=MAX_TRAVEL_VARIANCE_M2_PER_M).contains(&q)) {
        return Err(ScenarioError::invalid(
            "plant.wheels.travel_variance_m2_per_m",
            format!(
                "must be in [0, {MAX_TRAVEL_VARIANCE_M2_PER_M}] m²/m (got {})",
                shown(q)
            ),
        ));
    }
    for (e, wheel) in w.scale_error.iter().zip(["right", "left"]) {
        if !(e.is_finite() && e.abs() <= MAX_SCALE_ERROR) {
            return Err(ScenarioError::invalid(
                "plant.wheels.scale_error",
                format!(
                    "the {wheel} wheel's must be in [−{MAX_SCALE_ERROR}, {MAX_SCALE_ERROR}] \
                     (got {}; [right, left])",
                    shown(*e)
                ),
            ));
        }
    }
    Ok(Some(WheelErrors {
        travel_variance_m2_per_m: q,
        scale_error: w.scale_error,
        track_width_m,
        seed,
    }))
}

impl Scenario {
    /// The plant's realistic wheels (`[plant.wheels]`, [`wheel_errors`]):
    /// on the unicycle, with the default robot's track width (the fusion
    /// filter's geometry for it); seeded from `measurement.seed`.
    pub(super) fn wheels_setup(&self) -> Result<Option<WheelErrors>, ScenarioError> {
        let seed = self.measurement.seed;
        match &self.plant {
            PlantSpec::Unicycle { wheels } => {
                wheel_errors(wheels.as_ref(), defaults::track_width_m(), seed)
            }
            PlantSpec::DiffDrive {
                wheels,
                track_width_m,
                ..
            } => wheel_errors(wheels.as_ref(), *track_width_m, seed),
        }
    }

    pub(super) fn plant_setup(&self, tracker: TrackerSpec) -> Result<PlantSetup, ScenarioError> {
        match self.plant {
            PlantSpec::Unicycle { .. } => {
                if self.drive.is_some() {
                    return Err(ScenarioError::invalid(
                        "drive",
                        "only used with plant.kind = \"diff_drive\"; remove the [drive] table",
                    ));
                }
                Ok(PlantSetup::Unicycle)
            }
            PlantSpec::DiffDrive {
                wheel_radius_m,
                track_width_m,
                motor_time_constant_s,
                wheel_speed_at_full_duty_rad_s,
                encoder_counts_per_rev,
                encoder_bits,
                pwm_max_duty,
                substeps,
                dynamics,
                encoder_glitches,
                ..
            } => {
                let encoder_glitches = match encoder_glitches {
                    None => EncoderGlitches::default(),
                    Some(g) => {
                        if g.min_counts == 0 {
                            return Err(ScenarioError::invalid(
                                "plant.encoder_glitches.min_counts",
                                "must be ≥ 1",
                            ));
                        }
                        if g.max_counts < g.min_counts {
                            return Err(ScenarioError::invalid(
                                "plant.encoder_glitches.max_counts",
                                format!("must be ≥ min_counts ({})", g.min_counts),
                            ));
                        }
                        EncoderGlitches {
                            probability_per_read: probability(
                                "plant.encoder_glitches.probability_per_read",
                                g.probability_per_read,
                            )?,
                            min_counts: g.min_counts,
                            max_counts: g.max_counts,
                            seed: g.seed,
                        }
                    }
                };
                let params = DiffDriveParams {
                    wheel_radius_m: in_range(
                        "plant.wheel_radius_m",
                        wheel_radius_m,
                        WHEEL_RADIUS_M,
                        "m",
                    )?,
                    track_width_m: in_range(
                        "plant.track_width_m",
                        track_width_m,
                        TRACK_WIDTH_M,
                        "m",
                    )?,
                    motor_time_constant_s: positive(
                        "plant.motor_time_constant_s",
                        motor_time_constant_s,
                    )?,
                    wheel_speed_at_full_duty_rad_s: positive(
                        "plant.wheel_speed_at_full_duty_rad_s",
                        wheel_speed_at_full_duty_rad_s,
                    )?,
                    substeps,
                    dynamics: dynamics.as_ref().map(DynamicsSpec::build).transpose()?,
                };
                if substeps == 0 {
                    return Err(ScenarioError::invalid("plant.substeps", "must be ≥ 1"));
                }
                if encoder_counts_per_rev == 0 {
                    return Err(ScenarioError::invalid(
                        "plant.encoder_counts_per_rev",
                        "must be ≥ 1",
                    ));
                }
                if !(2..=32).contains(&encoder_bits) {
                    return Err(ScenarioError::invalid(
                        "plant.encoder_bits",
                        format!("must be in 2 ..= 32 (got {encoder_bits})"),
                    ));
                }
                if pwm_max_duty == 0 {
                    return Err(ScenarioError::invalid("plant.pwm_max_duty", "must be ≥ 1"));
                }
                let d = self.drive.unwrap_or_default();
                let feedforward = match d.feedforward_duty_per_rad_s {
                    Some(v) => v,
                    None => 1.0 / params.wheel_speed_at_full_duty_rad_s,
                };
                let pilot_spec = PilotSpec {
                    tracker,
                    drive: drive_spec::DriveSpec {
                        wheel_radius_m: f(params.wheel_radius_m),
                        track_width_m: f(params.track_width_m),
                        encoder_counts_per_rev,
                        max_wheel_speed_rad_s: f(in_range(
                            "drive.max_wheel_speed_rad_s",
                            d.max_wheel_speed_rad_s,
                            WHEEL_SPEED_RAD_S,
                            "rad/s",
                        )?),
                        max_wheel_accel_rad_s2: f(in_range(
                            "drive.max_wheel_accel_rad_s2",
                            d.max_wheel_accel_rad_s2,
                            WHEEL_ACCEL_RAD_S2,
                            "rad/s²",
                        )?),
                        feedforward_duty_per_rad_s: f(in_range(
                            "drive.feedforward_duty_per_rad_s",
                            feedforward,
                            SPEED_LOOP_GAIN,
                            "duty/(rad/s)",
                        )?),
                        kp_duty_per_rad_s: f(in_range(
                            "drive.kp_duty_per_rad_s",
                            d.kp_duty_per_rad_s,
                            SPEED_LOOP_GAIN,
                            "duty/(rad/s)",
                        )?),
                        ki_duty_per_rad: f(in_range(
                            "drive.ki_duty_per_rad",
                            d.ki_duty_per_rad,
                            SPEED_LOOP_GAIN,
                            "duty/rad",
                        )?),
                        speed_observer: d
                            .speed_observer
                            .map(|o| speed_observer_spec(&o, &params))
                            .transpose()?,
                    },
                    encoder_bits,
                    max_encoder_fault_ticks: PilotConfig::DEFAULT_MAX_ENCODER_FAULT_TICKS,
                };
                let pilot = pilot_spec.build().map_err(|e| spec_refusal(e, self))?;
                Ok(PlantSetup::DiffDrive {
                    params,
                    encoder_counts_per_rev,
                    encoder_bits,
                    pwm_max_duty,
                    encoder_glitches,
                    pilot,
                    pilot_spec,
                })
            }
        }
    }
}

impl DynamicsSpec {
    /// The plant's wheel dynamics, checked key by key.
    ///
    /// # Errors
    /// [`ScenarioError::Invalid`] naming the first bad
    /// `plant.dynamics.*` key.
    pub fn build(&self) -> Result<WheelDynamics, ScenarioError> {
        let mass_kg = positive("plant.dynamics.mass_kg", self.mass_kg)?;
        let yaw_inertia_kg_m2 =
            positive("plant.dynamics.yaw_inertia_kg_m2", self.yaw_inertia_kg_m2)?;
        let wheel_inertia_kg_m2 = non_negative(
            "plant.dynamics.wheel_inertia_kg_m2",
            self.wheel_inertia_kg_m2,
        )?;
        let viscous_friction_nm_s_per_rad = non_negative(
            "plant.dynamics.viscous_friction_nm_s_per_rad",
            self.viscous_friction_nm_s_per_rad,
        )?;
        let stall_torque_nm = positive("plant.dynamics.stall_torque_nm", self.stall_torque_nm)?;
        let start_s = non_negative("plant.dynamics.load_start_s", self.load_start_s)?;
        let ramp_s = non_negative("plant.dynamics.load_ramp_s", self.load_ramp_s)?;
        let grade_percent = self.load_grade_percent;
        if !(grade_percent > -100.0 && grade_percent < 100.0) {
            return Err(ScenarioError::invalid(
                "plant.dynamics.load_grade_percent",
                format!("must be in (−100, 100) (got {grade_percent})"),
            ));
        }
        Ok(WheelDynamics {
            mass_kg,
            yaw_inertia_kg_m2,
            wheel_inertia_kg_m2,
            viscous_friction_nm_s_per_rad,
            stall_torque_nm,
            load: LoadTorque {
                start_s,
                ramp_s,
                grade_percent,
            },
        })
    }
}
