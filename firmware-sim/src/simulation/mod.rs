//! Running a scenario: the simulation loop, per-tick records and the summary.
//!
//! One control tick `k` (time `t_k = k·h`, computed from `k`, never summed):
//!
//! 1. the position source looks at the plant's pose at `t_k` (exact
//!    position, nearest tag, or the virtual reader putting a frame on the
//!    line);
//! 2. the controller runs: the core's [`OutputFeedbackTracker`] or
//!    [`TrackingController`] directly (unicycle plant), or the core's
//!    [`Robot`] (diff-drive plant with the reader: encoders, UART, tag
//!    grid, pilot, motor drivers, exactly the firmware's tick) or its
//!    [`Pilot`] with the virtual encoders and motor drivers (diff-drive plant
//!    with an exact or nearest-tag position, which no device delivers);
//! 3. the tick is recorded (true pose at `t_k`, what the controller knew and
//!    commanded);
//! 4. the plant advances one period with what was commanded (unicycle: the
//!    `(v, ω)`; diff drive: the duties on the virtual PWM pins, held).

use std::time::Instant;

use rand::rngs::ChaCha8Rng;
use rand::{RngExt as _, SeedableRng as _};
use wmr_core::control::saturated::TrackingController;
use wmr_core::devices::{MotorDriver, MotorWiring, QuadratureCounter, RfidReader, TagLocator};
use wmr_core::estimation::heading_observer::{HeadingEstimate, HeadingObserver};
use wmr_core::geometry::{BodyVelocity, Pose, Vec2};
use wmr_core::odometry::OdometryStep;
use wmr_core::pilot::robot::{Motor, Robot};
use wmr_core::pilot::spec::TagGridSpec;
use wmr_core::pilot::tracker::{OutputFeedbackTracker, TagFix, TrackerMode};
use wmr_core::pilot::{Measurement, Pilot, PilotConfig, PilotCounters};
use wmr_core::reference::{TickClock, Trajectory};
use wmr_link::{
    Configure, Diagnostics, MAX_UART_BYTES_PER_TICK, MotorOutput, TickInput, TickOutput,
};

use crate::devices::{
    MotorSignals, ReaderConfig, ReaderModelCounters, VirtualDirectionPin, VirtualEncoder,
    VirtualPwm, VirtualRfidReader, VirtualUart, WheelShaft,
};
use crate::plant::{DiffDriveParams, DiffDrivePlant, PlantPose, Unicycle, wrap_angle};
use crate::report::{
    MeasurementReport, Mode, ModeTicks, PilotReport, Record, RfidReport, RunResult, SetupLabels,
    Summary, TrackerReport,
};
use crate::scenario::{
    ControllerKind, MeasurementSpec, PlantSetup, PositionSetup, Scenario, ScenarioError, Setup,
};
use crate::tags::FloorTags;

/// Ticks between two progress callbacks.
const PROGRESS_EVERY: u32 = 1000;

/// Validates and runs a scenario. `progress(done, total)` is called every
/// 1000 ticks and at the end.
///
/// # Errors
/// The scenario's validation error.
pub fn run(
    scenario: &Scenario,
    progress: impl FnMut(u64, u64),
) -> Result<RunResult, ScenarioError> {
    let setup = scenario.validate()?;
    let rig = Rig::new(&setup);
    simulate(scenario, setup, rig, progress).map_err(|e| {
        // Local rigs never fail a tick.
        ScenarioError::invalid("(run)", e.to_string())
    })
}

/// A robot whose control tick runs elsewhere (the firmware under QEMU,
/// over the HIL link): it gets the devices' readings, answers with what it
/// drove.
pub trait TargetLink {
    /// One lock-step exchange.
    ///
    /// # Errors
    /// The link failed (timeout, corrupt or unexpected answer).
    fn tick(&mut self, input: &TickInput) -> anyhow::Result<TickOutput>;

    /// Ends the run; returns the target's final counters.
    ///
    /// # Errors
    /// The link failed.
    fn finish(&mut self) -> anyhow::Result<Diagnostics>;
}

/// Runs a diff-drive + reader scenario with the control tick on `target`
/// (already configured with [`hil_configuration`]); the plant, encoders and
/// RFID reader are the same as in [`run`].
///
/// # Errors
/// A scenario this cannot run remotely, or a link failure.
pub fn run_with_target(
    scenario: &Scenario,
    target: &mut dyn TargetLink,
    progress: impl FnMut(u64, u64),
) -> anyhow::Result<RunResult> {
    let setup = scenario.validate()?;
    let rig = Rig::remote(&setup, target)?;
    simulate(scenario, setup, rig, progress)
}

/// What the firmware must be configured with to run `setup` (diff-drive
/// plant with a reader only: the firmware's devices are encoders, motors
/// and the reader's UART).
///
/// # Errors
/// A scenario whose position source or plant no device delivers.
pub fn hil_configuration(setup: &Setup) -> anyhow::Result<Configure> {
    let (
        PlantSetup::DiffDrive {
            pwm_max_duty,
            pilot_spec,
            pilot,
            ..
        },
        PositionSetup::Reader(floor, _),
    ) = (setup.plant, setup.position)
    else {
        anyhow::bail!(
            "hardware-in-the-loop runs need plant.kind = \"diff_drive\" and position.kind = \"reader\" \
             (the firmware senses through encoders and the RFID reader's UART only)"
        );
    };
    if pilot.drive().speed_observer().is_some() {
        anyhow::bail!(
            "[drive.speed_observer] is not sent over the link (protocol {}): run it on the host",
            wmr_link::PROTOCOL_VERSION
        );
    }
    Ok(Configure {
        protocol: wmr_link::PROTOCOL_VERSION,
        pilot: pilot_spec,
        grid: TagGridSpec::of(floor.grid()),
        pwm_max_duty,
    })
}

fn simulate(
    scenario: &Scenario,
    setup: Setup,
    mut rig: Rig<'_>,
    progress: impl FnMut(u64, u64),
) -> anyhow::Result<RunResult> {
    let wall = Instant::now();
    let mut records = Vec::with_capacity(setup.ticks as usize);
    let mut progress = progress;
    let total = u64::from(setup.ticks);
    for k in 0..setup.ticks {
        let t = f64::from(k) * setup.period_s;
        records.push(rig.tick(k, t)?);
        rig.advance(setup.period_s);
        if (k + 1) % PROGRESS_EVERY == 0 {
            progress(u64::from(k) + 1, total);
        }
    }
    progress(total, total);
    if let Rig::Remote { target, last, .. } = &mut rig {
        *last = target.finish()?;
    }
    let summary = summarize(
        scenario,
        &setup,
        &records,
        &rig,
        wall.elapsed().as_secs_f64(),
    );
    Ok(RunResult {
        scenario: scenario.clone(),
        setup,
        records,
        summary,
    })
}

// ---------------------------------------------------------------------------
// Position sources that do not go through the robot.

/// Exact, nearest-tag, or reader + UART + core parser + tag grid.
// One instance per run: the variants' sizes do not matter.
#[allow(clippy::large_enum_variant)]
#[derive(Debug)]
enum Source {
    Exact,
    Nearest(FloorTags),
    Reader {
        model: VirtualRfidReader,
        rfid: RfidReader<VirtualUart>,
        floor: FloorTags,
        unknown_tags: u32,
    },
}

impl Source {
    fn new(setup: &PositionSetup) -> Self {
        match *setup {
            PositionSetup::Exact => Self::Exact,
            PositionSetup::NearestTag(floor) => Self::Nearest(floor),
            PositionSetup::Reader(floor, config) => {
                let (model, uart) = VirtualRfidReader::new(config, floor);
                Self::Reader {
                    model,
                    rfid: RfidReader::new(uart),
                    floor,
                    unknown_tags: 0,
                }
            }
        }
    }

    fn measure(&mut self, t_s: f64, pose: &PlantPose) -> Option<TagFix> {
        let position = match self {
            Self::Exact => Vec2::new(pose.x_m as f32, pose.y_m as f32),
            Self::Nearest(floor) => floor.nearest(pose.x_m, pose.y_m).position,
            Self::Reader {
                model,
                rfid,
                floor,
                unknown_tags,
            } => {
                model.update(t_s, pose);
                let id = rfid.poll()?;
                match floor.locate(id) {
                    Some(p) => p,
                    None => {
                        *unknown_tags = unknown_tags.saturating_add(1);
                        return None;
                    }
                }
            }
        };
        Some(TagFix {
            position,
            age_ticks: 0,
        })
    }

    fn floor_tags(&self) -> Option<usize> {
        match self {
            Self::Exact => None,
            Self::Nearest(f) | Self::Reader { floor: f, .. } => Some(f.len()),
        }
    }

    fn report(&self) -> Option<RfidReport> {
        match self {
            Self::Reader {
                model,
                rfid,
                unknown_tags,
                ..
            } => Some(rfid_report(
                rfid.counters(),
                *unknown_tags,
                model.counters(),
            )),
            _ => None,
        }
    }
}

/// A [`Source`] with the scenario's noise and misses on its fix.
#[derive(Debug)]
struct FixSource {
    source: Source,
    faults: Option<FixFaults>,
}

/// Gaussian noise and random misses on the fix. Every tick draws, in this
/// order, the miss and a pair of normals, fix or not, so the noise a tick
/// gets does not depend on the miss probability.
#[derive(Debug)]
struct FixFaults {
    spec: MeasurementSpec,
    rng: ChaCha8Rng,
    missed: u32,
}

impl FixSource {
    fn new(setup: &Setup) -> Self {
        let spec = setup.measurement;
        Self {
            source: Source::new(&setup.position),
            faults: (!spec.is_clean()).then(|| FixFaults {
                spec,
                rng: ChaCha8Rng::seed_from_u64(spec.seed),
                missed: 0,
            }),
        }
    }

    fn measure(&mut self, t_s: f64, pose: &PlantPose) -> Option<TagFix> {
        let fix = self.source.measure(t_s, pose);
        let Some(faults) = &mut self.faults else {
            return fix;
        };
        let miss = faults.rng.random::<f64>() < faults.spec.miss_probability;
        // Box–Muller: two independent standard normals.
        let radius = (-2.0 * (1.0 - faults.rng.random::<f64>()).ln()).sqrt();
        let angle = std::f64::consts::TAU * faults.rng.random::<f64>();
        let mut fix = fix?;
        if miss {
            faults.missed = faults.missed.saturating_add(1);
            return None;
        }
        let std = faults.spec.noise_std_m;
        fix.position = Vec2::new(
            fix.position.x + (std * radius * angle.cos()) as f32,
            fix.position.y + (std * radius * angle.sin()) as f32,
        );
        Some(fix)
    }

    fn floor_tags(&self) -> Option<usize> {
        self.source.floor_tags()
    }

    fn report(&self) -> Option<RfidReport> {
        self.source.report()
    }

    fn measurement_report(&self) -> Option<MeasurementReport> {
        self.faults.as_ref().map(|f| MeasurementReport {
            noise_std_m: f.spec.noise_std_m,
            miss_probability: f.spec.miss_probability,
            missed_fixes: f.missed,
        })
    }
}

fn rfid_report(
    c: wmr_core::devices::RfidCounters,
    unknown_tags: u32,
    reader: ReaderModelCounters,
) -> RfidReport {
    RfidReport {
        frames_ok: c.frames_ok,
        bad_checksum: c.bad_checksum,
        malformed: c.malformed,
        bytes_outside_frames: c.bytes_outside_frames,
        read_errors: c.read_errors,
        superseded: c.superseded,
        unknown_tags,
        reader,
    }
}

// ---------------------------------------------------------------------------
// Diff-drive hardware around the core.

type VirtualMotor = MotorDriver<VirtualPwm, VirtualDirectionPin>;
type SimRobot = Robot<
    VirtualEncoder,
    VirtualEncoder,
    VirtualMotor,
    VirtualMotor,
    VirtualUart,
    wmr_core::devices::TagGrid,
>;

/// The diff-drive body and its virtual devices' plant-side handles.
#[derive(Debug)]
struct Hardware {
    plant: DiffDrivePlant,
    signals: (MotorSignals, MotorSignals),
    shafts: (WheelShaft, WheelShaft),
    limits: (u64, u64),
    max_abs_duty: f64,
}

/// The devices the core drives.
struct Devices {
    encoders: (VirtualEncoder, VirtualEncoder),
    motors: (VirtualMotor, VirtualMotor),
}

impl Hardware {
    fn new(
        params: DiffDriveParams,
        pose: PlantPose,
        counts_per_rev: u32,
        bits: u32,
        pwm_max: u16,
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
        let devices = Devices {
            encoders: (
                VirtualEncoder::new(shafts.0.clone(), counts_per_rev, bits),
                VirtualEncoder::new(shafts.1.clone(), counts_per_rev, bits),
            ),
            motors: (motor(&signals.0), motor(&signals.1)),
        };
        (
            Self {
                plant: DiffDrivePlant::new(params, pose),
                signals,
                shafts,
                limits: (0, 0),
                max_abs_duty: 0.0,
            },
            devices,
        )
    }

    fn duties(&self) -> (f64, f64) {
        (self.signals.0.signed_duty(), self.signals.1.signed_duty())
    }

    fn note(&mut self, speed_limited: bool, accel_limited: bool) {
        self.limits.0 += u64::from(speed_limited);
        self.limits.1 += u64::from(accel_limited);
        let (l, r) = self.duties();
        self.max_abs_duty = self.max_abs_duty.max(l.abs()).max(r.abs());
    }

    fn advance(&mut self, dt_s: f64) {
        let (l, r) = self.duties();
        self.plant.step(l, r, dt_s);
        let (al, ar) = self.plant.wheel_angles_rad();
        self.shafts.0.set_angle_rad(al);
        self.shafts.1.set_angle_rad(ar);
    }

    fn report(&self, c: PilotCounters, motor_faults: u32) -> PilotReport {
        let (l, r) = (self.signals.0.line(), self.signals.1.line());
        PilotReport {
            encoder_fault_ticks: c.encoder_fault_ticks,
            implausible_encoder_reads: c.implausible_encoder_reads,
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

// ---------------------------------------------------------------------------
// The four ways a tick runs.

/// What the controller side produced at one tick.
struct Outcome {
    reference: Vec2,
    position: Option<Vec2>,
    heading: Option<HeadingEstimate>,
    command: BodyVelocity,
    fix: bool,
    mode: Mode,
    duties: Option<(f64, f64)>,
}

impl Outcome {
    fn of_tracker(out: &wmr_core::pilot::tracker::TrackerOutput, fix: bool) -> Self {
        let awaiting = out.mode == TrackerMode::AwaitingFix;
        Self {
            reference: out.reference.position,
            position: (!awaiting).then_some(out.position),
            heading: Some(out.heading),
            command: out.command,
            fix,
            mode: out.mode.into(),
            duties: None,
        }
    }
}

// One instance per run: the variants' sizes do not matter.
#[allow(clippy::large_enum_variant)]
enum Rig<'t> {
    /// Unicycle + the core's output-feedback tracker.
    Tracker {
        plant: Unicycle,
        tracker: OutputFeedbackTracker,
        source: FixSource,
        last: BodyVelocity,
        period_s: f32,
    },
    /// Unicycle + the core's state-feedback law.
    Controller {
        plant: Unicycle,
        controller: TrackingController,
        trajectory: Trajectory,
        clock: TickClock,
        source: FixSource,
        last: BodyVelocity,
    },
    /// Diff drive + the core's Robot (reader source).
    Robot {
        hw: Hardware,
        robot: SimRobot,
        reader: VirtualRfidReader,
        floor: FloorTags,
    },
    /// Diff drive + the core's Pilot (exact / nearest-tag source).
    Pilot {
        hw: Hardware,
        devices: Devices,
        pilot: Pilot,
        source: FixSource,
        motor_faults: u32,
    },
    /// Diff drive + reader, with the robot's tick on a [`TargetLink`].
    Remote {
        hw: Hardware,
        encoders: (VirtualEncoder, VirtualEncoder),
        drivers: [(VirtualPwm, VirtualDirectionPin); 2],
        reader: VirtualRfidReader,
        uart: VirtualUart,
        floor: FloorTags,
        target: &'t mut dyn TargetLink,
        last: Diagnostics,
        pwm_refusals: u32,
    },
}

impl<'t> Rig<'t> {
    fn remote(setup: &Setup, target: &'t mut dyn TargetLink) -> anyhow::Result<Self> {
        hil_configuration(setup)?;
        let (
            PlantSetup::DiffDrive {
                params,
                encoder_counts_per_rev,
                encoder_bits,
                pwm_max_duty,
                ..
            },
            PositionSetup::Reader(floor, config),
        ) = (setup.plant, setup.position)
        else {
            anyhow::bail!("not a diff-drive reader scenario");
        };
        let (hw, devices) = Hardware::new(
            params,
            setup.initial_pose,
            encoder_counts_per_rev,
            encoder_bits,
            pwm_max_duty,
        );
        let driver = |s: &MotorSignals| {
            (
                VirtualPwm::new(s.clone()),
                VirtualDirectionPin::new(s.clone()),
            )
        };
        let drivers = [driver(&hw.signals.0), driver(&hw.signals.1)];
        let (reader, uart) = VirtualRfidReader::new(config, floor);
        Ok(Self::Remote {
            hw,
            encoders: devices.encoders,
            drivers,
            reader,
            uart,
            floor,
            target,
            last: Diagnostics::default(),
            pwm_refusals: 0,
        })
    }

    fn new(setup: &Setup) -> Self {
        let pose = setup.initial_pose;
        match (setup.plant, setup.controller) {
            (PlantSetup::Unicycle, ControllerKind::OutputFeedback) => {
                let observer = HeadingObserver::with_initial_estimate(
                    *setup.tracker.observer(),
                    setup.initial_estimate,
                )
                .unwrap_or_else(|_| HeadingObserver::new(*setup.tracker.observer()));
                Self::Tracker {
                    plant: Unicycle::new(pose),
                    tracker: OutputFeedbackTracker::with_observer(setup.tracker, observer),
                    source: FixSource::new(setup),
                    last: BodyVelocity::ZERO,
                    period_s: setup.period_s as f32,
                }
            }
            (PlantSetup::Unicycle, ControllerKind::StateFeedback) => Self::Controller {
                plant: Unicycle::new(pose),
                controller: TrackingController::new(setup.gains),
                trajectory: setup.trajectory,
                clock: *setup.tracker.clock(),
                source: FixSource::new(setup),
                last: BodyVelocity::ZERO,
            },
            (
                PlantSetup::DiffDrive {
                    params,
                    encoder_counts_per_rev,
                    encoder_bits,
                    pwm_max_duty,
                    pilot,
                    ..
                },
                _,
            ) => {
                let (hw, devices) = Hardware::new(
                    params,
                    pose,
                    encoder_counts_per_rev,
                    encoder_bits,
                    pwm_max_duty,
                );
                let pilot = new_pilot(pilot);
                match setup.position {
                    PositionSetup::Reader(floor, config) => {
                        Self::robot(hw, devices, pilot, floor, config)
                    }
                    _ => Self::Pilot {
                        hw,
                        devices,
                        pilot,
                        source: FixSource::new(setup),
                        motor_faults: 0,
                    },
                }
            }
        }
    }

    fn robot(
        hw: Hardware,
        devices: Devices,
        pilot: Pilot,
        floor: FloorTags,
        config: ReaderConfig,
    ) -> Self {
        let (reader, uart) = VirtualRfidReader::new(config, floor);
        let robot = Robot::new(
            pilot,
            devices.encoders,
            devices.motors,
            RfidReader::new(uart),
            *floor.grid(),
        );
        Self::Robot {
            hw,
            robot,
            reader,
            floor,
        }
    }

    fn pose(&self) -> PlantPose {
        match self {
            Self::Tracker { plant, .. } | Self::Controller { plant, .. } => plant.pose(),
            Self::Robot { hw, .. } | Self::Pilot { hw, .. } | Self::Remote { hw, .. } => {
                hw.plant.pose()
            }
        }
    }

    fn tick(&mut self, k: u32, t_s: f64) -> anyhow::Result<Record> {
        let pose = self.pose();
        let outcome = match self {
            Self::Tracker {
                tracker,
                source,
                last,
                period_s,
                ..
            } => {
                let h = *period_s;
                let odometry = OdometryStep {
                    ds_m: last.v_m_s * h,
                    dtheta_rad: last.omega_rad_s * h,
                    body: *last,
                    wheels: Default::default(),
                };
                let fix = source.measure(t_s, &pose);
                let out = tracker.step(&odometry, fix);
                *last = out.command;
                Outcome::of_tracker(&out, fix.is_some())
            }
            Self::Controller {
                controller,
                trajectory,
                clock,
                source,
                last,
                ..
            } => {
                let reference = trajectory.sample(clock.time_s(k));
                // Validation admits only sources with a position every tick.
                let fix = source.measure(t_s, &pose);
                let position =
                    fix.map_or(Vec2::new(pose.x_m as f32, pose.y_m as f32), |f| f.position);
                let law = controller.state_feedback(
                    &reference,
                    Pose {
                        position,
                        heading_rad: pose.wrapped_heading_rad() as f32,
                    },
                );
                *last = if law.body.is_finite() {
                    law.body
                } else {
                    BodyVelocity::ZERO
                };
                Outcome {
                    reference: reference.position,
                    position: Some(position),
                    heading: None,
                    command: *last,
                    fix: fix.is_some(),
                    mode: Mode::StateFeedback,
                    duties: None,
                }
            }
            Self::Robot {
                hw, robot, reader, ..
            } => {
                reader.update(t_s, &pose);
                let out = robot.tick();
                hw.note(out.pilot.drive.speed_limited, out.pilot.drive.accel_limited);
                Outcome {
                    duties: Some(hw.duties()),
                    ..Outcome::of_tracker(&out.pilot.tracker, out.fix.is_some())
                }
            }
            Self::Pilot {
                hw,
                devices,
                pilot,
                source,
                motor_faults,
            } => {
                let fix = source.measure(t_s, &pose);
                let measurement = Measurement {
                    left_count: devices.encoders.0.raw_count().ok(),
                    right_count: devices.encoders.1.raw_count().ok(),
                    fix,
                };
                let out = pilot.step(&measurement);
                for result in [
                    drive(&mut devices.motors.0, out.left),
                    drive(&mut devices.motors.1, out.right),
                ] {
                    *motor_faults += u32::from(!result);
                }
                hw.note(out.drive.speed_limited, out.drive.accel_limited);
                Outcome {
                    duties: Some(hw.duties()),
                    ..Outcome::of_tracker(&out.tracker, fix.is_some())
                }
            }
            Self::Remote {
                hw,
                encoders,
                drivers,
                reader,
                uart,
                target,
                pwm_refusals,
                ..
            } => {
                reader.update(t_s, &pose);
                let input = TickInput {
                    tick: k,
                    left_count: encoders.0.raw_count().ok(),
                    right_count: encoders.1.raw_count().ok(),
                    uart: drain_uart(uart),
                };
                let out = target.tick(&input)?;
                anyhow::ensure!(
                    out.tick == k,
                    "the firmware answered tick {} to tick {k}",
                    out.tick
                );
                let now = [hw.signals.0.line(), hw.signals.1.line()];
                for (((pwm, pin), motor), line) in
                    drivers.iter_mut().zip([out.left, out.right]).zip(now)
                {
                    *pwm_refusals += u32::from(!apply_motor(pwm, pin, line.direction_high, motor));
                }
                hw.note(out.speed_limited, out.accel_limited);
                let awaiting = out.mode == TrackerMode::AwaitingFix;
                let [x, y] = out.position_m;
                let [cos_theta, sin_theta] = out.heading;
                let [v_m_s, omega_rad_s] = out.command;
                let [rx, ry] = out.reference_m;
                Outcome {
                    reference: Vec2::new(rx, ry),
                    position: (!awaiting).then_some(Vec2::new(x, y)),
                    heading: Some(HeadingEstimate {
                        cos_theta,
                        sin_theta,
                    }),
                    command: BodyVelocity { v_m_s, omega_rad_s },
                    fix: out.fix,
                    mode: out.mode.into(),
                    duties: Some(hw.duties()),
                }
            }
        };
        Ok(record(k, t_s, &pose, &outcome))
    }

    fn advance(&mut self, dt_s: f64) {
        match self {
            Self::Tracker { plant, last, .. } | Self::Controller { plant, last, .. } => {
                plant.step(f64::from(last.v_m_s), f64::from(last.omega_rad_s), dt_s);
            }
            Self::Robot { hw, .. } | Self::Pilot { hw, .. } | Self::Remote { hw, .. } => {
                hw.advance(dt_s);
            }
        }
    }

    fn code_path(&self) -> &'static str {
        match self {
            Self::Tracker { .. } => "tracker",
            Self::Controller { .. } => "controller",
            Self::Robot { .. } => "robot",
            Self::Pilot { .. } => "pilot",
            Self::Remote { .. } => "firmware",
        }
    }
}

/// Every byte the UART has ready now, up to what one link frame carries
/// (the rest stays on the line for the next tick, as in a local run).
fn drain_uart(uart: &mut VirtualUart) -> heapless::Vec<u8, MAX_UART_BYTES_PER_TICK> {
    let mut bytes = heapless::Vec::new();
    let mut buf = [0_u8; MAX_UART_BYTES_PER_TICK];
    let Ok(n) = embedded_io::Read::read(uart, &mut buf);
    // `buf` holds `MAX_UART_BYTES_PER_TICK` bytes: `n` always fits.
    let _ = bytes.extend_from_slice(&buf[..n]);
    bytes
}

/// Puts what the firmware drove on a virtual motor's inputs, in the order
/// the core's `MotorDriver` does (duty to 0 before the direction changes);
/// false if the PWM refused the duty.
fn apply_motor(
    pwm: &mut VirtualPwm,
    pin: &mut VirtualDirectionPin,
    direction_high_now: bool,
    motor: MotorOutput,
) -> bool {
    use embedded_hal::digital::{OutputPin, PinState};
    use embedded_hal::pwm::SetDutyCycle;
    if motor.direction_high != direction_high_now && pwm.set_duty_cycle(0).is_err() {
        return false;
    }
    let Ok(()) = pin.set_state(PinState::from(motor.direction_high));
    pwm.set_duty_cycle(motor.duty).is_ok()
}

/// A pilot from a validated configuration.
fn new_pilot(config: PilotConfig) -> Pilot {
    // `PilotConfig::new` already checked the counter width, the only
    // thing `Pilot::new` can refuse.
    #[allow(clippy::expect_used)]
    Pilot::new(config).expect("validated pilot configuration")
}

/// Drives a motor as `Robot::tick` does (stop on a fault); false on a fault.
fn drive<M: Motor>(motor: &mut M, command: wmr_core::devices::MotorCommand) -> bool {
    if motor.drive(command).is_ok() {
        true
    } else {
        let _ = motor.drive(wmr_core::devices::MotorCommand::STOP);
        false
    }
}

fn record(k: u32, t_s: f64, pose: &PlantPose, o: &Outcome) -> Record {
    let (rx, ry) = (f64::from(o.reference.x), f64::from(o.reference.y));
    let theta = pose.wrapped_heading_rad();
    let est_theta = o.heading.map(|h| f64::from(h.heading_rad()));
    Record {
        tick: k,
        t_s,
        x_m: pose.x_m,
        y_m: pose.y_m,
        theta_rad: theta,
        ref_x_m: rx,
        ref_y_m: ry,
        est_x_m: o.position.map(|p| f64::from(p.x)),
        est_y_m: o.position.map(|p| f64::from(p.y)),
        est_cos: o.heading.map(|h| f64::from(h.cos_theta)),
        est_sin: o.heading.map(|h| f64::from(h.sin_theta)),
        est_theta_rad: est_theta,
        heading_error_rad: est_theta.map(|e| wrap_angle(e - theta)),
        v_cmd_m_s: f64::from(o.command.v_m_s),
        omega_cmd_rad_s: f64::from(o.command.omega_rad_s),
        left_duty: o.duties.map(|d| d.0),
        right_duty: o.duties.map(|d| d.1),
        fix: o.fix,
        mode: o.mode,
        error_m: (pose.x_m - rx).hypot(pose.y_m - ry),
    }
}

/// Error statistics over the records with `t ≥ from_s`:
/// `(samples, max, mean, rms)`.
#[must_use]
pub fn error_stats(records: &[Record], from_s: f64) -> (u64, f64, f64, f64) {
    let mut n = 0_u64;
    let (mut max, mut sum, mut sum_sq) = (0.0_f64, 0.0, 0.0);
    for r in records.iter().filter(|r| r.t_s >= from_s - 1e-9) {
        n += 1;
        max = max.max(r.error_m);
        sum += r.error_m;
        sum_sq += r.error_m * r.error_m;
    }
    if n == 0 {
        return (0, f64::NAN, f64::NAN, f64::NAN);
    }
    let nf = n as f64;
    (n, max, sum / nf, (sum_sq / nf).sqrt())
}

fn summarize(
    scenario: &Scenario,
    setup: &Setup,
    records: &[Record],
    rig: &Rig<'_>,
    wall_s: f64,
) -> Summary {
    let (samples, max, mean, rms) = error_stats(records, setup.transient_s);
    let mut modes = ModeTicks::default();
    for r in records {
        match r.mode {
            Mode::AwaitingFix => modes.awaiting_fix += 1,
            Mode::Tracking => modes.tracking += 1,
            Mode::FixLost => modes.fix_lost += 1,
            Mode::StateFeedback => modes.state_feedback += 1,
        }
    }
    let max_heading_error_rad = records
        .iter()
        .filter(|r| r.t_s >= setup.transient_s - 1e-9)
        .filter_map(|r| r.heading_error_rad)
        .map(f64::abs)
        .reduce(f64::max);
    let (tracker, rfid, pilot, floor_tags) = match rig {
        Rig::Tracker {
            tracker, source, ..
        } => (
            Some(TrackerReport::of(tracker)),
            source.report(),
            None,
            source.floor_tags(),
        ),
        Rig::Controller { source, .. } => (None, source.report(), None, source.floor_tags()),
        Rig::Robot {
            hw,
            robot,
            reader,
            floor,
        } => (
            Some(TrackerReport::of(robot.pilot().tracker())),
            Some(rfid_report(
                robot.rfid_counters(),
                robot.counters().unknown_tags,
                reader.counters(),
            )),
            Some(hw.report(robot.pilot().counters(), robot.counters().motor_faults)),
            Some(floor.len()),
        ),
        Rig::Remote {
            hw,
            reader,
            floor,
            last,
            pwm_refusals,
            ..
        } => (
            Some(TrackerReport::from_counters(
                last.tracker,
                last.observer_rejected_updates,
            )),
            Some(rfid_report(
                last.rfid,
                last.robot.unknown_tags,
                reader.counters(),
            )),
            Some(hw.report(last.pilot, last.robot.motor_faults + *pwm_refusals)),
            Some(floor.len()),
        ),
        Rig::Pilot {
            hw,
            pilot,
            source,
            motor_faults,
            ..
        } => (
            Some(TrackerReport::of(pilot.tracker())),
            source.report(),
            Some(hw.report(pilot.counters(), *motor_faults)),
            source.floor_tags(),
        ),
    };
    let gain_bound = match setup.controller {
        ControllerKind::OutputFeedback => setup.tracker.gain_bound(),
        ControllerKind::StateFeedback => setup.gains.check_bound(setup.trajectory.speed_bounds()),
    };
    let labels = SetupLabels::of(setup);
    Summary {
        scenario: scenario.name.clone(),
        plant: labels.plant,
        controller: labels.controller,
        position_source: labels.position_source,
        code_path: rig.code_path(),
        ticks: setup.ticks,
        period_s: setup.period_s,
        duration_s: f64::from(setup.ticks) * setup.period_s,
        transient_s: setup.transient_s,
        samples,
        max_error_m: max,
        mean_error_m: mean,
        rms_error_m: rms,
        final_error_m: records.last().map_or(f64::NAN, |r| r.error_m),
        max_heading_error_rad,
        non_finite_ticks: records.iter().filter(|r| !r.is_finite()).count() as u64,
        gain_bound: gain_bound.into(),
        mode_ticks: modes,
        tracker,
        rfid,
        pilot,
        floor_tags,
        measurement: match rig {
            Rig::Tracker { source, .. }
            | Rig::Controller { source, .. }
            | Rig::Pilot { source, .. } => source.measurement_report(),
            Rig::Robot { .. } | Rig::Remote { .. } => None,
        },
        wall_time_s: wall_s,
        hil: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::SpeedObserverSpec;

    #[test]
    fn a_speed_observer_is_refused_for_hil() {
        // The link does not carry it: a HIL run is refused, not run without it.
        let mut full = Scenario::embedded("figure_eight_rfid_full_stack").unwrap();
        assert!(hil_configuration(&full.validate().unwrap()).is_ok());
        let mut drive = full.drive.unwrap_or_default();
        drive.speed_observer = Some(SpeedObserverSpec {
            mass_kg: 4.0,
            yaw_inertia_kg_m2: 0.08,
            wheel_inertia_kg_m2: 0.0,
            stall_torque_nm: 0.6,
            lambda_per_s: 5.0,
            friction_gain: 0.01,
            disturbance_gain: 0.1,
        });
        full.drive = Some(drive);
        let e = hil_configuration(&full.validate().unwrap()).unwrap_err();
        assert!(e.to_string().contains("speed_observer"), "{e}");
    }
}
