//! The diff-drive hardware around the core: the body and the plant-side
//! handles of its virtual devices, and the devices the core drives.

use wmr_core::devices::{MotorDriver, MotorWiring};
use wmr_core::pilot::PilotCounters;
use wmr_core::pilot::robot::Robot;

use std::cell::Cell;
use std::rc::Rc;

use crate::devices::{
    EncoderGlitches, MotorSignals, VirtualDirectionPin, VirtualEncoder, VirtualPwm, VirtualUart,
    WheelShaft,
};
use crate::plant::{DiffDriveParams, DiffDrivePlant, PlantPose, RollingWheels};
use crate::report::PilotReport;

pub(super) type VirtualMotor = MotorDriver<VirtualPwm, VirtualDirectionPin>;
pub(super) type SimRobot = Robot<
    VirtualEncoder,
    VirtualEncoder,
    VirtualMotor,
    VirtualMotor,
    VirtualUart,
    crate::tags::Floor,
>;

/// The diff-drive body and its virtual devices' plant-side handles.
#[derive(Debug)]
pub(super) struct Hardware {
    pub(super) plant: DiffDrivePlant,
    pub(super) signals: (MotorSignals, MotorSignals),
    shafts: (WheelShaft, WheelShaft),
    limits: (u64, u64),
    max_abs_duty: f64,
    /// Encoder glitch bursts injected, left and right.
    glitch_bursts: (Rc<Cell<u64>>, Rc<Cell<u64>>),
    /// Wheels that slip and are mis-scaled (`[plant.wheels]`), if any.
    wheels: Option<RollingWheels>,
}

/// The devices the core drives.
pub(super) struct Devices {
    pub(super) encoders: (VirtualEncoder, VirtualEncoder),
    pub(super) motors: (VirtualMotor, VirtualMotor),
}

impl Hardware {
    pub(super) fn new(
        params: DiffDriveParams,
        pose: PlantPose,
        counts_per_rev: u32,
        bits: u32,
        pwm_max: u16,
        glitches: EncoderGlitches,
    ) -> (Self, Devices) {
        let signals = (MotorSignals::new(pwm_max), MotorSignals::new(pwm_max));
        let shafts = (WheelShaft::new(), WheelShaft::new());
        let motor = |s: &MotorSignals| {
            MotorDriver::new(
                VirtualPwm::new(s.clone()),
                VirtualDirectionPin::new(s.clone()),
                MotorWiring::default(),
            )
        };
        let (left, left_bursts) = VirtualEncoder::new(shafts.0.clone(), counts_per_rev, bits)
            .with_glitches(glitches, glitches.seed);
        let (right, right_bursts) = VirtualEncoder::new(shafts.1.clone(), counts_per_rev, bits)
            .with_glitches(glitches, glitches.seed.wrapping_add(1));
        let devices = Devices {
            encoders: (left, right),
            motors: (motor(&signals.0), motor(&signals.1)),
        };
        (
            Self {
                plant: DiffDrivePlant::new(params, pose),
                signals,
                shafts,
                limits: (0, 0),
                max_abs_duty: 0.0,
                glitch_bursts: (left_bursts, right_bursts),
                wheels: None,
            },
            devices,
        )
    }

    pub(super) fn duties(&self) -> (f64, f64) {
        (self.signals.0.signed_duty(), self.signals.1.signed_duty())
    }

    pub(super) fn note(&mut self, speed_limited: bool, accel_limited: bool) {
        self.limits.0 += u64::from(speed_limited);
        self.limits.1 += u64::from(accel_limited);
        let (l, r) = self.duties();
        self.max_abs_duty = self.max_abs_duty.max(l.abs()).max(r.abs());
    }

    /// The body on `wheels` (none: it moves as its wheels turn).
    pub(super) fn with_wheels(self, wheels: Option<RollingWheels>) -> Self {
        Self { wheels, ..self }
    }

    /// One period with the duties held. With realistic wheels the body
    /// then slides by the difference between the wheels' ground travels
    /// and their rotation over the period (`r·Δφ`), as one arc from the
    /// pose reached (first order in the slip: the slip of a period is
    /// applied at its end, not spread over it); the encoders keep seeing
    /// the rotation.
    pub(super) fn advance(&mut self, dt_s: f64) {
        let (l, r) = self.duties();
        let before = self.plant.wheel_angles_rad();
        self.plant.step(l, r, dt_s);
        let (al, ar) = self.plant.wheel_angles_rad();
        if let Some(wheels) = &mut self.wheels {
            let radius = self.plant.params().wheel_radius_m;
            let (right, left) = (radius * (ar - before.1), radius * (al - before.0));
            let (ground_right, ground_left) = wheels.ground_travels(right, left);
            let (extra_right, extra_left) = (ground_right - right, ground_left - left);
            let b = wheels.errors().track_width_m;
            self.plant.slide(
                0.5 * (extra_right + extra_left),
                (extra_right - extra_left) / b,
            );
        }
        self.shafts.0.set_angle_rad(al);
        self.shafts.1.set_angle_rad(ar);
    }

    pub(super) fn report(&self, c: PilotCounters, motor_faults: u32) -> PilotReport {
        let (l, r) = (self.signals.0.line(), self.signals.1.line());
        PilotReport {
            encoder_fault_ticks: c.encoder_fault_ticks,
            implausible_encoder_reads: c.implausible_encoder_reads,
            encoder_glitch_bursts: self.glitch_bursts.0.get() + self.glitch_bursts.1.get(),
            encoder_halt_ticks: c.encoder_halt_ticks,
            motor_faults,
            speed_limited_ticks: self.limits.0,
            accel_limited_ticks: self.limits.1,
            reversals_under_drive: l.reversals_under_drive + r.reversals_under_drive,
            out_of_range_pwm_writes: l.out_of_range_writes + r.out_of_range_writes,
            max_abs_duty: self.max_abs_duty,
        }
    }
}
