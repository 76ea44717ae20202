//! The drive's plain-data description ([`DriveSpec`]), validated into a
//! [`DriveConfig`] by the same constructors whatever writes it (a robot
//! file, a scenario, the firmware's compiled-in spec); see
//! [`crate::pilot::spec`] for why specs are plain data.

use crate::builds::{self, OptionalBuild};
use crate::drive::momenta_observer::MomentaObserverError;
use crate::drive::{DriveConfig, DriveConfigError, SpeedLoopGains};
use crate::geometry::{DiffDriveGeometry, GeometryError};

/// Why a [`DriveSpec`] was refused: the part, and that part's own error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DriveSpecError {
    /// The robot's geometry.
    Geometry(GeometryError),
    /// The drive (limits, speed loop).
    Drive(DriveConfigError),
    /// Paper 003's wheel-speed observer ([`SpeedObserverSpec`]).
    SpeedObserver(MomentaObserverError),
    /// A speed observer in a build without the cargo feature
    /// `wheel-speed-observer`.
    NotInThisBuild,
}

/// The drive: geometry, wheel limits and the speed loop.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct DriveSpec {
    /// Wheel radius, m, in [`crate::plausible::WHEEL_RADIUS_M`].
    pub wheel_radius_m: f32,
    /// Distance between the wheels' contact points, m, in
    /// [`crate::plausible::TRACK_WIDTH_M`].
    pub track_width_m: f32,
    /// Encoder counts per wheel revolution (after quadrature decoding), in
    /// [`crate::plausible::COUNTS_PER_REV`].
    pub encoder_counts_per_rev: u32,
    /// Wheel speed limit, rad/s, in [`crate::plausible::WHEEL_SPEED_RAD_S`].
    pub max_wheel_speed_rad_s: f32,
    /// Wheel acceleration limit, rad/s², in [`crate::plausible::WHEEL_ACCEL_RAD_S2`].
    pub max_wheel_accel_rad_s2: f32,
    /// Feed-forward duty per rad/s, in [`crate::plausible::SPEED_LOOP_GAIN`].
    pub feedforward_duty_per_rad_s: f32,
    /// Proportional gain, duty per rad/s, in [`crate::plausible::SPEED_LOOP_GAIN`].
    pub kp_duty_per_rad_s: f32,
    /// Integral gain, duty per rad, in [`crate::plausible::SPEED_LOOP_GAIN`].
    pub ki_duty_per_rad: f32,
    /// Run the speed loops on paper 003's wheel-speed observer instead of
    /// the counts differenced over a tick (`None`: differenced counts;
    /// `Some` needs the cargo feature `wheel-speed-observer`, else
    /// [`DriveSpecError::NotInThisBuild`]).
    pub speed_observer: Option<SpeedObserverSpec>,
}

/// Paper 003's wheel-speed observer on the robot's wheels (Romero &
/// Ortega, *Two globally convergent adaptive speed observers for mechanical
/// systems*, Proposition 1 applied in section 6.1;
/// [`crate::drive::speed_observer`]): the robot as the observer models it.
/// The wheel radius and track are the drive's ([`DriveSpec`]).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct SpeedObserverSpec {
    /// Robot mass, kg, in [`crate::plausible::MASS_KG`].
    pub mass_kg: f32,
    /// Yaw inertia about the axle midpoint, kg m², in
    /// [`crate::plausible::YAW_INERTIA_KG_M2`].
    pub yaw_inertia_kg_m2: f32,
    /// Each wheel's drive-train inertia at the wheel, kg m² (may be 0), in
    /// [`crate::plausible::WHEEL_INERTIA_KG_M2`].
    pub wheel_inertia_kg_m2: f32,
    /// Motor torque at the wheel at full duty and standstill, N·m, in
    /// [`crate::plausible::TORQUE_NM`].
    pub stall_torque_nm: f32,
    /// The motors' no-load wheel speed at full duty, rad/s, in
    /// [`crate::plausible::WHEEL_SPEED_RAD_S`].
    pub no_load_speed_rad_s: f32,
    /// `λ`, 1/s, in [`crate::plausible::GAIN`].
    pub lambda_per_s: f32,
    /// Damping adaptation gain `γ_r`, in [`crate::plausible::GAIN`].
    pub friction_gain: f32,
    /// Load adaptation gain `γ_d`, in [`crate::plausible::GAIN`].
    pub disturbance_gain: f32,
}

impl SpeedObserverSpec {
    /// The validated observer configuration for the drive `drive` and the
    /// control period `period_s`.
    ///
    /// # Errors
    /// [`DriveSpecError::SpeedObserver`].
    #[cfg(feature = "wheel-speed-observer")]
    pub fn build(
        &self,
        drive: &DriveSpec,
        period_s: f32,
    ) -> Result<crate::drive::speed_observer::WheelSpeedObserverConfig, DriveSpecError> {
        use crate::drive::momenta_observer::WheelInertia;
        use crate::drive::speed_observer::WheelSpeedObserverConfig;
        WheelInertia::new(
            self.mass_kg,
            self.yaw_inertia_kg_m2,
            drive.wheel_radius_m,
            drive.track_width_m,
            self.wheel_inertia_kg_m2,
        )
        .and_then(|inertia| {
            WheelSpeedObserverConfig::new(
                inertia,
                self.stall_torque_nm,
                self.no_load_speed_rad_s,
                period_s,
            )
        })
        .and_then(|c| c.with_gains(self.lambda_per_s, self.friction_gain, self.disturbance_gain))
        .map_err(DriveSpecError::SpeedObserver)
    }
}

impl DriveSpec {
    /// The optional build ([`crate::builds`]) this drive needs: paper
    /// 003's wheel-speed observer when its speed loops run on it.
    #[must_use]
    pub fn required_build(&self) -> Option<OptionalBuild> {
        self.speed_observer.map(|_| builds::WHEEL_SPEED_OBSERVER)
    }

    /// The validated drive configuration for control period `period_s`.
    ///
    /// # Errors
    /// The first part refused.
    pub fn build(&self, period_s: f32) -> Result<DriveConfig, DriveSpecError> {
        let geometry = DiffDriveGeometry::new(
            self.wheel_radius_m,
            self.track_width_m,
            self.encoder_counts_per_rev,
        )
        .map_err(DriveSpecError::Geometry)?;
        DriveConfig::new(
            geometry,
            period_s,
            self.max_wheel_speed_rad_s,
            self.max_wheel_accel_rad_s2,
            SpeedLoopGains {
                feedforward_duty_per_rad_s: self.feedforward_duty_per_rad_s,
                kp_duty_per_rad_s: self.kp_duty_per_rad_s,
                ki_duty_per_rad: self.ki_duty_per_rad,
            },
        )
        .map_err(DriveSpecError::Drive)
        .and_then(|drive| self.with_speed_observer(drive, period_s))
    }

    #[cfg(feature = "wheel-speed-observer")]
    fn with_speed_observer(
        &self,
        drive: DriveConfig,
        period_s: f32,
    ) -> Result<DriveConfig, DriveSpecError> {
        match &self.speed_observer {
            None => Ok(drive),
            Some(o) => drive
                .with_speed_observer(o.build(self, period_s)?)
                .map_err(DriveSpecError::Drive),
        }
    }

    #[cfg(not(feature = "wheel-speed-observer"))]
    fn with_speed_observer(
        &self,
        drive: DriveConfig,
        _period_s: f32,
    ) -> Result<DriveConfig, DriveSpecError> {
        match self.speed_observer {
            None => Ok(drive),
            Some(_) => Err(DriveSpecError::NotInThisBuild),
        }
    }
}

/// A drive drawn from a fuzzer's bytes, near a 2048-count, 0.3 m robot
/// ([`crate::fuzzing`]), on differenced counts.
#[cfg(feature = "arbitrary")]
impl<'a> arbitrary::Arbitrary<'a> for DriveSpec {
    fn arbitrary(u: &mut arbitrary::Unstructured<'a>) -> arbitrary::Result<Self> {
        use crate::fuzzing::{count, float};
        Ok(Self {
            wheel_radius_m: float(u, 0.05)?,
            track_width_m: float(u, 0.3)?,
            encoder_counts_per_rev: count(u, 2048)?,
            max_wheel_speed_rad_s: float(u, 20.0)?,
            max_wheel_accel_rad_s2: float(u, 40.0)?,
            feedforward_duty_per_rad_s: float(u, 0.05)?,
            kp_duty_per_rad_s: float(u, 0.05)?,
            ki_duty_per_rad: float(u, 0.5)?,
            speed_observer: None,
        })
    }
}
