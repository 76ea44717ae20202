//! The ways a tick runs ([`Rig`]): the core's tracker or controller on the
//! unicycle, its `Robot` or `Pilot` on the diff drive, or the firmware's
//! tick over a [`super::TargetLink`], and the record of a tick.

use wmr_core::control::saturated::TrackingController;
use wmr_core::devices::{QuadratureCounter, RfidCounters, RfidReader};
use wmr_core::geometry::HeadingEstimate;
use wmr_core::geometry::{BodyVelocity, Pose, Vec2};
use wmr_core::odometry::OdometryStep;
use wmr_core::pilot::robot::{Motor, Robot};
use wmr_core::pilot::route::RouteFollower;
use wmr_core::pilot::tracker::{OutputFeedbackTracker, TrackerCounters, TrackerMode};
use wmr_core::pilot::tuning::{Tuning, TuningSpec};
use wmr_core::pilot::{Measurement, Pilot, PilotConfig};
use wmr_core::reference::{TickClock, Trajectory};
use wmr_link::{Diagnostics, MAX_UART_BYTES_PER_TICK, MotorOutput, TickInput};

use crate::devices::{
    MotorSignals, ReaderConfig, VirtualDirectionPin, VirtualEncoder, VirtualPwm, VirtualRfidReader,
    VirtualUart,
};
use crate::plant::{PlantPose, RollingWheels, Unicycle, wrap_angle};
use crate::report::{Mode, Record};
use crate::scenario::{ControllerKind, PlantSetup, PositionSetup, Setup};
use crate::tags::Floor;

use super::hardware::{Devices, Hardware, SimRobot};
use super::sources::FixSource;
use super::target::{RouteShadow, TargetLink, hil_configuration};

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
    fn of_tracker(out: &wmr_core::pilot::tracker::TrackerOutput) -> Self {
        let awaiting = out.mode == TrackerMode::AwaitingFix;
        Self {
            reference: out.reference.position,
            position: (!awaiting).then_some(out.position),
            heading: Some(out.heading),
            command: out.command,
            fix: out.fix_used,
            mode: out.mode.into(),
            duties: None,
        }
    }
}

// One instance per run: the variants' sizes do not matter.
#[allow(clippy::large_enum_variant)]
pub(super) enum Rig<'t> {
    /// Unicycle + the core's output-feedback tracker.
    Tracker {
        plant: Unicycle,
        wheels: Option<RollingWheels>,
        tracker: OutputFeedbackTracker,
        source: FixSource,
        last: BodyVelocity,
        period_s: f32,
        route: Option<Box<RouteFollower>>,
    },
    /// Unicycle + the core's state-feedback law.
    Controller {
        plant: Unicycle,
        wheels: Option<RollingWheels>,
        controller: TrackingController,
        trajectory: Trajectory,
        clock: TickClock,
        source: FixSource,
        last: BodyVelocity,
    },
    /// Diff drive + the core's Robot (reader source), on its trajectory
    /// or on a route: the same robot tick the firmware runs.
    Robot {
        hw: Hardware,
        robot: SimRobot,
        reader: VirtualRfidReader,
        floor: Floor,
        route: Option<Box<RouteFollower>>,
    },
    /// Diff drive + the core's Pilot (exact / nearest-tag source).
    Pilot {
        hw: Hardware,
        devices: Devices,
        pilot: Pilot,
        source: FixSource,
        motor_faults: u32,
        route: Option<Box<RouteFollower>>,
    },
    /// Diff drive + reader, with the robot's tick on a [`TargetLink`].
    Remote {
        hw: Hardware,
        encoders: (VirtualEncoder, VirtualEncoder),
        drivers: [(VirtualPwm, VirtualDirectionPin); 2],
        reader: VirtualRfidReader,
        uart: VirtualUart,
        floor: Floor,
        target: &'t mut dyn TargetLink,
        last: Diagnostics,
        pwm_refusals: u32,
        /// On a route: the firmware's session on the host, for the
        /// route's status (`Ticked` does not carry it).
        shadow: Option<RouteShadow<'t>>,
    },
}

impl<'t> Rig<'t> {
    pub(super) fn remote(
        setup: &Setup,
        target: &'t mut dyn TargetLink,
        shadow: Option<RouteShadow<'t>>,
    ) -> anyhow::Result<Self> {
        hil_configuration(setup)?;
        let (
            PlantSetup::DiffDrive {
                params,
                encoder_counts_per_rev,
                encoder_bits,
                pwm_max_duty,
                encoder_glitches,
                ..
            },
            PositionSetup::Reader(floor, config),
        ) = (setup.plant, setup.position.clone())
        else {
            anyhow::bail!("not a diff-drive reader scenario");
        };
        let (hw, devices) = Hardware::new(
            params,
            setup.initial_pose,
            encoder_counts_per_rev,
            encoder_bits,
            pwm_max_duty,
            encoder_glitches,
        );
        let hw = hw.with_wheels(setup.wheels.map(RollingWheels::new));
        let driver = |s: &MotorSignals| {
            (
                VirtualPwm::new(s.clone()),
                VirtualDirectionPin::new(s.clone()),
            )
        };
        let drivers = [driver(&hw.signals.0), driver(&hw.signals.1)];
        let (reader, uart) = VirtualRfidReader::new(config, floor.clone());
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
            shadow,
        })
    }

    pub(super) fn new(setup: &Setup) -> Self {
        let pose = setup.initial_pose;
        match (setup.plant, setup.controller) {
            (PlantSetup::Unicycle, ControllerKind::OutputFeedback) => Self::Tracker {
                plant: Unicycle::new(pose),
                wheels: setup.wheels.map(RollingWheels::new),
                tracker: OutputFeedbackTracker::with_initial_heading(
                    setup.tracker,
                    setup.initial_estimate,
                )
                .unwrap_or_else(|_| OutputFeedbackTracker::new(setup.tracker)),
                source: FixSource::new(setup),
                last: BodyVelocity::ZERO,
                period_s: setup.period_s as f32,
                route: follower(setup),
            },
            (PlantSetup::Unicycle, ControllerKind::StateFeedback) => Self::Controller {
                plant: Unicycle::new(pose),
                wheels: setup.wheels.map(RollingWheels::new),
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
                    encoder_glitches,
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
                    encoder_glitches,
                );
                let hw = hw.with_wheels(setup.wheels.map(RollingWheels::new));
                let pilot = new_pilot(pilot);
                match (&setup.position, follower(setup)) {
                    (PositionSetup::Reader(floor, config), route) => {
                        Self::robot(hw, devices, pilot, floor.clone(), *config, route)
                    }
                    (_, route) => Self::Pilot {
                        hw,
                        devices,
                        pilot,
                        source: FixSource::new(setup),
                        motor_faults: 0,
                        route,
                    },
                }
            }
        }
    }

    fn robot(
        hw: Hardware,
        devices: Devices,
        pilot: Pilot,
        floor: Floor,
        config: ReaderConfig,
        route: Option<Box<RouteFollower>>,
    ) -> Self {
        let (reader, uart) = VirtualRfidReader::new(config, floor.clone());
        let robot = Robot::new(
            pilot,
            devices.encoders,
            devices.motors,
            RfidReader::new(uart),
            floor.clone(),
        );
        Self::Robot {
            hw,
            robot,
            reader,
            floor,
            route,
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

    pub(super) fn tick(&mut self, k: u32, t_s: f64) -> anyhow::Result<Record> {
        let pose = self.pose();
        let outcome = match self {
            Self::Tracker {
                tracker,
                source,
                last,
                period_s,
                route,
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
                let out = match route {
                    Some(route) => tracker.step_route(&odometry, fix, route),
                    None => tracker.step(&odometry, fix),
                };
                *last = out.command;
                Outcome::of_tracker(&out)
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
                hw,
                robot,
                reader,
                route,
                ..
            } => {
                reader.update(t_s, &pose);
                let out = robot.tick_on(route.as_deref_mut());
                hw.note(out.pilot.drive.speed_limited, out.pilot.drive.accel_limited);
                Outcome {
                    duties: Some(hw.duties()),
                    ..Outcome::of_tracker(&out.pilot.tracker)
                }
            }
            Self::Pilot {
                hw,
                devices,
                pilot,
                source,
                motor_faults,
                route,
            } => {
                let fix = source.measure(t_s, &pose);
                let measurement = Measurement {
                    left_count: devices.encoders.0.raw_count().ok(),
                    right_count: devices.encoders.1.raw_count().ok(),
                    fix,
                };
                let out = match route {
                    Some(route) => pilot.step_route(&measurement, route),
                    None => pilot.step(&measurement),
                };
                for result in [
                    drive(&mut devices.motors.0, out.left),
                    drive(&mut devices.motors.1, out.right),
                ] {
                    *motor_faults += u32::from(!result);
                }
                hw.note(out.drive.speed_limited, out.drive.accel_limited);
                Outcome {
                    duties: Some(hw.duties()),
                    ..Outcome::of_tracker(&out.tracker)
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
                shadow,
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
                // The MAVLink messages the firmware got before this tick,
                // then the tick: the copy sees what it saw (a run without
                // a route has no copy: each answer counts as differing).
                if let Some(log) = target.mavlink_log() {
                    for (message, answer) in std::mem::take(&mut log.exchanges) {
                        log.compared += 1;
                        let copy = shadow.as_mut().and_then(|s| s.mavlink(&message));
                        if copy != Some(answer) {
                            log.mismatches = log.mismatches.saturating_add(1);
                            log.first_mismatch_tick.get_or_insert(k);
                        }
                    }
                }
                if let Some(shadow) = shadow {
                    shadow.tick(&input);
                }
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

    pub(super) fn advance(&mut self, dt_s: f64) {
        match self {
            Self::Tracker {
                plant,
                wheels,
                last,
                ..
            }
            | Self::Controller {
                plant,
                wheels,
                last,
                ..
            } => {
                let (v, omega) = (f64::from(last.v_m_s), f64::from(last.omega_rad_s));
                match wheels {
                    // The odometry (the command) is what the wheels
                    // measured; the body moves on their ground travels.
                    Some(wheels) => {
                        let (ds, dtheta) = wheels.ground_motion(v * dt_s, omega * dt_s);
                        plant.advance_arc(ds, dtheta);
                    }
                    None => plant.step(v, omega, dt_s),
                }
            }
            Self::Robot { hw, .. } | Self::Pilot { hw, .. } | Self::Remote { hw, .. } => {
                hw.advance(dt_s);
            }
        }
    }

    /// Whether the remote target asks the run to end now.
    pub(super) fn stop_requested(&self) -> bool {
        match self {
            Self::Remote { target, .. } => target.stop_requested(),
            _ => false,
        }
    }

    /// The route's follower, on a route run.
    pub(super) fn route(&self) -> Option<&RouteFollower> {
        match self {
            Self::Tracker { route, .. } | Self::Pilot { route, .. } | Self::Robot { route, .. } => {
                route.as_deref()
            }
            Self::Remote { shadow, .. } => shadow.as_ref().and_then(RouteShadow::follower),
            Self::Controller { .. } => None,
        }
    }

    /// Puts `follower` in place of the route's follower and returns the
    /// one it replaces; `Err(follower)` back where the rig runs no route
    /// of its own (state feedback, the firmware's tick).
    pub(super) fn swap_route(
        &mut self,
        follower: Box<RouteFollower>,
    ) -> Result<Option<Box<RouteFollower>>, Box<RouteFollower>> {
        match self {
            Self::Tracker { route, .. } | Self::Pilot { route, .. } | Self::Robot { route, .. } => {
                Ok(route.replace(follower))
            }
            Self::Remote { .. } | Self::Controller { .. } => Err(follower),
        }
    }

    /// The gains and failsafe times the core's tracker runs with now
    /// (`PilotConfig::tuning`; the tracker alone has no encoder fault
    /// ticks: 0); `None` where the tick is not the core's tracker.
    pub(super) fn tuning(&self) -> Option<TuningSpec> {
        match self {
            Self::Tracker { tracker, .. } => Some(tracker.config().tuning()),
            Self::Pilot { pilot, .. } => Some(pilot.config().tuning()),
            Self::Robot { robot, .. } => Some(robot.pilot().config().tuning()),
            Self::Remote { .. } | Self::Controller { .. } => None,
        }
    }

    /// Takes `tuning` from the next tick on (`Pilot::retune`); `false`
    /// where the tick is not the core's tracker.
    pub(super) fn retune(&mut self, tuning: &Tuning) -> bool {
        match self {
            Self::Tracker { tracker, .. } => tracker.retune(tuning),
            Self::Pilot { pilot, .. } => pilot.retune(tuning),
            Self::Robot { robot, .. } => robot.retune(tuning),
            Self::Remote { .. } | Self::Controller { .. } => return false,
        }
        true
    }

    /// The tracker's counters, and the RFID reader's with the count of
    /// tags not on the floor where there is a reader; `None` where the
    /// tick is not the core's tracker.
    pub(super) fn counters(&self) -> Option<(TrackerCounters, Option<(RfidCounters, u32)>)> {
        match self {
            Self::Tracker {
                tracker, source, ..
            } => Some((tracker.counters(), source.rfid_counters())),
            Self::Pilot { pilot, source, .. } => {
                Some((pilot.tracker().counters(), source.rfid_counters()))
            }
            Self::Robot { robot, .. } => Some((
                robot.pilot().tracker().counters(),
                Some((robot.rfid_counters(), robot.counters().unknown_tags)),
            )),
            Self::Remote { .. } | Self::Controller { .. } => None,
        }
    }

    /// The route's follower, mutable, on a route run.
    pub(super) fn route_mut(&mut self) -> Option<&mut RouteFollower> {
        match self {
            Self::Tracker { route, .. } | Self::Pilot { route, .. } | Self::Robot { route, .. } => {
                route.as_deref_mut()
            }
            Self::Remote { .. } | Self::Controller { .. } => None,
        }
    }

    pub(super) fn code_path(&self) -> &'static str {
        match self {
            Self::Tracker { .. } => "tracker",
            Self::Controller { .. } => "controller",
            Self::Robot { .. } => "robot",
            Self::Pilot { .. } => "pilot",
            Self::Remote { .. } => "firmware",
        }
    }
}

/// A route's follower for `setup`, loaded with its route (none for an
/// analytic reference): allocated once, on the heap (about 22 KB).
fn follower(setup: &Setup) -> Option<Box<RouteFollower>> {
    let route = setup.route.as_ref()?;
    let mut follower = Box::new(RouteFollower::new(route.options));
    follower.load(&route.waypoints, &route.limits, route.start);
    Some(follower)
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
