//! What a run reports: the per-tick [`Record`], the [`Summary`] and its
//! parts, and the [`RunResult`] that carries them, shared by every stage
//! after the simulation (the HIL run, the sweeps, the output files).
//!
//! These are plain data built from the scenario's [`Setup`] and the core's
//! counters; nothing here runs a simulation.

pub mod link_faults;
pub mod mavlink_bridge;

use serde::Serialize;
use wmr_core::control::LawChoice;
use wmr_core::control::saturated::GainBound;
use wmr_core::estimation::EstimatorChoice;
use wmr_core::pilot::tracker::{OutputFeedbackTracker, TrackerCounters, TrackerMode};
use wmr_link::LinkCounters;

use crate::devices::ReaderModelCounters;
use crate::scenario::{ControllerKind, PlantSetup, PositionSetup, Scenario, Setup};

/// What the controller was doing at a tick.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Mode {
    /// Output feedback, no fix yet: standing still.
    AwaitingFix,
    /// Output feedback, tracking.
    Tracking,
    /// Output feedback, fixes lost: failsafe ramp-down.
    FixLost,
    /// State feedback (always tracking).
    StateFeedback,
}

impl From<TrackerMode> for Mode {
    fn from(m: TrackerMode) -> Self {
        match m {
            TrackerMode::AwaitingFix => Self::AwaitingFix,
            TrackerMode::Tracking => Self::Tracking,
            TrackerMode::FixLost => Self::FixLost,
        }
    }
}

/// One control tick (one CSV row).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Record {
    /// Tick index `k`.
    pub tick: u32,
    /// `t = k·h`, s.
    pub t_s: f64,
    /// True x, m.
    pub x_m: f64,
    /// True y, m.
    pub y_m: f64,
    /// True heading, rad, wrapped to (−π, π].
    pub theta_rad: f64,
    /// Reference x at `t`, m.
    pub ref_x_m: f64,
    /// Reference y at `t`, m.
    pub ref_y_m: f64,
    /// Position the controller used (fix or dead-reckoned), m; empty before
    /// the first fix.
    pub est_x_m: Option<f64>,
    /// Position the controller used, y, m.
    pub est_y_m: Option<f64>,
    /// Observer's `ẑ3` (estimate of cos θ); empty for state feedback.
    pub est_cos: Option<f64>,
    /// Observer's `ẑ4` (estimate of sin θ).
    pub est_sin: Option<f64>,
    /// `θ̂ = atan2(ẑ4, ẑ3)`, rad.
    pub est_theta_rad: Option<f64>,
    /// `θ̂ − θ`, wrapped, rad.
    pub heading_error_rad: Option<f64>,
    /// Commanded forward speed, m/s.
    pub v_cmd_m_s: f64,
    /// Commanded yaw rate, rad/s.
    pub omega_cmd_rad_s: f64,
    /// Signed duty of the left motor as its driver inputs show it (diff drive).
    pub left_duty: Option<f64>,
    /// Signed duty of the right motor (diff drive).
    pub right_duty: Option<f64>,
    /// A position fix reached the controller this tick.
    pub fix: bool,
    /// Controller mode after this tick.
    pub mode: Mode,
    /// Tracking error `|p_true − p_ref|`, m.
    pub error_m: f64,
}

impl Record {
    /// Whether every number in the record is finite.
    #[must_use]
    pub fn is_finite(&self) -> bool {
        let opt = |v: Option<f64>| v.is_none_or(f64::is_finite);
        [
            self.x_m,
            self.y_m,
            self.theta_rad,
            self.ref_x_m,
            self.ref_y_m,
            self.v_cmd_m_s,
            self.omega_cmd_rad_s,
            self.error_m,
        ]
        .iter()
        .all(|v| v.is_finite())
            && [
                self.est_x_m,
                self.est_y_m,
                self.est_cos,
                self.est_sin,
                self.est_theta_rad,
                self.heading_error_rad,
                self.left_duty,
                self.right_duty,
            ]
            .into_iter()
            .all(opt)
    }
}

/// The gain bound (15) for the scenario's gains and reference.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GainBoundReport {
    /// Whether (15) holds (then `min/max_speed_m_s` are guaranteed).
    pub satisfied: bool,
    /// The `γ` the gains need (< 1 when satisfied); `None` when the
    /// reference can stop.
    pub gamma: Option<f64>,
    /// Guaranteed lower bound on the commanded speed, m/s.
    pub min_speed_m_s: Option<f64>,
    /// Guaranteed upper bound on the commanded speed, m/s.
    pub max_speed_m_s: Option<f64>,
}

impl From<GainBound> for GainBoundReport {
    fn from(b: GainBound) -> Self {
        match b {
            GainBound::Satisfied {
                gamma,
                min_speed_m_s,
                max_speed_m_s,
            } => Self {
                satisfied: true,
                gamma: Some(f64::from(gamma)),
                min_speed_m_s: Some(f64::from(min_speed_m_s)),
                max_speed_m_s: Some(f64::from(max_speed_m_s)),
            },
            GainBound::Violated { gamma } => Self {
                satisfied: false,
                gamma: Some(f64::from(gamma)),
                min_speed_m_s: None,
                max_speed_m_s: None,
            },
            GainBound::ReferenceNotExciting => Self {
                satisfied: false,
                gamma: None,
                min_speed_m_s: None,
                max_speed_m_s: None,
            },
        }
    }
}

/// Ticks spent in each mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub struct ModeTicks {
    /// No fix yet.
    pub awaiting_fix: u64,
    /// Tracking (output feedback).
    pub tracking: u64,
    /// Failsafe.
    pub fix_lost: u64,
    /// State feedback.
    pub state_feedback: u64,
}

/// The output-feedback tracker's counters (mirrors the core's
/// `TrackerCounters`, plus the observer's rejected updates).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub struct TrackerReport {
    /// Valid fixes used.
    pub fixes_used: u32,
    /// Fixes with a non-finite position.
    pub invalid_fixes: u32,
    /// Fixes older than the maximum age.
    pub stale_fixes: u32,
    /// Steps whose position was dead-reckoned.
    pub dead_reckoned_steps: u32,
    /// Times the failsafe engaged.
    pub failsafe_entries: u32,
    /// Non-finite commands replaced by zero.
    pub non_finite_commands: u32,
    /// Ticks a paper 002 law commanded zero for a standing reference.
    pub reference_standstill_ticks: u32,
    /// Observer updates skipped for non-finite input.
    pub observer_rejected_updates: u32,
    /// Fix measurements the fusion EKF's gate rejected.
    pub fixes_gated: u32,
    /// Fusion EKF re-localisations.
    pub relocalisations: u32,
    /// Fusion EKF heading resets to its guide observer.
    pub heading_resets: u32,
}

impl TrackerReport {
    pub(crate) fn of(tracker: &OutputFeedbackTracker) -> Self {
        Self::from_counters(tracker.counters(), tracker.observer_rejected_updates())
    }

    pub(crate) fn from_counters(c: TrackerCounters, observer_rejected_updates: u32) -> Self {
        Self {
            fixes_used: c.fixes_used,
            invalid_fixes: c.invalid_fixes,
            stale_fixes: c.stale_fixes,
            dead_reckoned_steps: c.dead_reckoned_steps,
            failsafe_entries: c.failsafe_entries,
            non_finite_commands: c.non_finite_commands,
            reference_standstill_ticks: c.reference_standstill_ticks,
            observer_rejected_updates,
            fixes_gated: c.fixes_gated,
            relocalisations: c.relocalisations,
            heading_resets: c.heading_resets,
        }
    }
}

/// RFID link counters: the core parser's (mirrors `RfidCounters`), the
/// tag lookup's and the reader model's.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub struct RfidReport {
    /// Frames with a valid checksum.
    pub frames_ok: u32,
    /// Frames with a bad checksum.
    pub bad_checksum: u32,
    /// Aborted frames.
    pub malformed: u32,
    /// Bytes outside frames.
    pub bytes_outside_frames: u32,
    /// UART errors.
    pub read_errors: u32,
    /// Valid tags replaced by a later one in the same poll.
    pub superseded: u32,
    /// Polls that stopped at the reader's byte bound with bytes still
    /// waiting (the next poll's tag is aged accordingly).
    pub backlogged_polls: u32,
    /// Valid frames whose tag the locator did not know.
    pub unknown_tags: u32,
    /// What the virtual reader sent, skipped and damaged.
    pub reader: ReaderModelCounters,
}

/// The pilot's and the robot's device-fault counters (diff drive).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct PilotReport {
    /// Ticks with a missing encoder read.
    pub encoder_fault_ticks: u32,
    /// Encoder reads rejected as implausible.
    pub implausible_encoder_reads: u32,
    /// Encoder glitch bursts the simulation injected (both encoders;
    /// `[plant.encoder_glitches]`).
    pub encoder_glitch_bursts: u64,
    /// Ticks with the motors stopped for encoder faults.
    pub encoder_halt_ticks: u32,
    /// Failed motor writes.
    pub motor_faults: u32,
    /// Ticks on which the drive's speed limit scaled the command.
    pub speed_limited_ticks: u64,
    /// Ticks on which the drive's acceleration limit acted.
    pub accel_limited_ticks: u64,
    /// Direction-pin changes under non-zero duty (expect 0).
    pub reversals_under_drive: u32,
    /// PWM writes above full scale (expect 0).
    pub out_of_range_pwm_writes: u32,
    /// Largest duty magnitude applied.
    pub max_abs_duty: f64,
}

/// The faults put on the position fix
/// ([`MeasurementSpec`](crate::scenario::MeasurementSpec)).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MeasurementReport {
    /// Std of the Gaussian noise on each axis, m.
    pub noise_std_m: f64,
    /// Probability a tick's fix is missing.
    pub miss_probability: f64,
    /// Fixes removed.
    pub missed_fixes: u32,
}

/// The figures of a run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Summary {
    /// Scenario name.
    pub scenario: String,
    /// `unicycle` or `diff_drive`.
    pub plant: &'static str,
    /// `state_feedback`, or `output_feedback` with its estimator and law
    /// ([`SetupLabels::controller`]).
    pub controller: String,
    /// `exact`, `nearest_tag` or `reader`.
    pub position_source: &'static str,
    /// Which core entry point ran: `tracker`, `controller`, `robot` or `pilot`.
    pub code_path: &'static str,
    /// Control ticks run.
    pub ticks: u32,
    /// Control period, s.
    pub period_s: f64,
    /// Simulated time, s.
    pub duration_s: f64,
    /// Statistics window start, s.
    pub transient_s: f64,
    /// Ticks in the statistics window.
    pub samples: u64,
    /// Largest tracking error over `t ≥ transient_s`, m.
    pub max_error_m: f64,
    /// Mean tracking error over `t ≥ transient_s`, m.
    pub mean_error_m: f64,
    /// RMS tracking error over `t ≥ transient_s`, m.
    pub rms_error_m: f64,
    /// Tracking error at the last tick, m.
    pub final_error_m: f64,
    /// Largest `|θ̂ − θ|` over `t ≥ transient_s`, rad (output feedback).
    pub max_heading_error_rad: Option<f64>,
    /// Ticks whose record holds a non-finite number (expect 0).
    pub non_finite_ticks: u64,
    /// The gain bound (15).
    pub gain_bound: GainBoundReport,
    /// Ticks per mode.
    pub mode_ticks: ModeTicks,
    /// Tracker counters (output feedback).
    pub tracker: Option<TrackerReport>,
    /// RFID link counters (reader source).
    pub rfid: Option<RfidReport>,
    /// Drive and device counters (diff drive).
    pub pilot: Option<PilotReport>,
    /// Tags on the simulated floor.
    pub floor_tags: Option<usize>,
    /// Noise and misses put on the fix (when the scenario asks for them).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub measurement: Option<MeasurementReport>,
    /// Wall-clock time of the run, s.
    pub wall_time_s: f64,
    /// Hardware-in-the-loop figures (`hil` runs only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub hil: Option<HilReport>,
    /// The route's figures (`reference.kind = "route"` only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub route: Option<RouteReport>,
}

/// What a route run adds to the summary. Every error here is the
/// simulator's ground truth (the plant's true pose, its axle midpoint),
/// not the estimate the robot steers by (that is what
/// `counters.stop_errors` counts).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RouteReport {
    /// The route was finished (at rest on its last waypoint, settled).
    pub done: bool,
    /// `as_given` or `from_first_fix`.
    pub start: &'static str,
    /// The run's plan's duration (the reference's, from its first tick
    /// to rest on the last waypoint), s.
    pub planned_duration_s: f64,
    /// Time from the tick the route started (planned) to the tick it was
    /// done (the robot settled on the last waypoint), s; `None` if not done.
    pub time_taken_s: Option<f64>,
    /// `time_taken_s / planned_duration_s`.
    pub time_ratio: Option<f64>,
    /// When the route started, s of simulated time.
    pub started_at_s: Option<f64>,
    /// When it was done, s of simulated time.
    pub done_at_s: Option<f64>,
    /// Each stop after the first waypoint (where the route starts), in
    /// order.
    pub stops: Vec<StopReport>,
    /// Largest `position_error_m` over the stops reached, m.
    pub max_stop_position_error_m: Option<f64>,
    /// Largest `heading_error_deg` over the stops facing a heading, degrees.
    pub max_stop_heading_error_deg: Option<f64>,
    /// Stops never settled at.
    pub stops_missed: usize,
    /// Largest true distance from the planned path while the reference
    /// moves, m (`cross_track` in docs/routes.md).
    pub max_cross_track_error_m: Option<f64>,
    /// RMS of the same, m.
    pub rms_cross_track_error_m: Option<f64>,
    /// Ticks the cross-track figures cover (the reference moving).
    pub moving_ticks: u64,
    /// The core's route counters.
    pub counters: wmr_core::pilot::route::RouteCounters,
    /// Why the planner refused the route at its start, if it did.
    pub refused: Option<String>,
    /// The run's planned path, the plan's position every tick, m (the
    /// plot's), as far as the run went (its ticks and 3 s more).
    #[serde(skip)]
    pub path_m: Vec<[f64; 2]>,
}

/// One stop of a route run, as the robot truly stood there.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StopReport {
    /// The waypoint, 1-based in file order.
    pub waypoint: usize,
    /// Its position, m.
    pub x_m: f64,
    /// Its position, m.
    pub y_m: f64,
    /// The heading it faces, degrees, if it faces one.
    pub face_heading_deg: Option<f64>,
    /// When the robot last settled there (after any pivot), s.
    pub settled_at_s: Option<f64>,
    /// True distance of the robot from the stop then, m.
    pub position_error_m: Option<f64>,
    /// True `|wrap(θ − face)|` then, degrees, where the stop faces a heading.
    pub heading_error_deg: Option<f64>,
}

/// What the HIL run adds to the summary.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct HilReport {
    /// Ticks the firmware ran.
    pub firmware_ticks: u32,
    /// The firmware's deepest stack use since reset, bytes.
    pub peak_stack_bytes: u32,
    /// The link as the firmware saw it.
    pub firmware_link: LinkCounters,
    /// The link as the simulator saw it.
    pub host_link: LinkCounters,
    /// UART bytes the firmware's proxy buffer lost.
    pub uart_overruns: u32,
    /// Ticks the firmware answered again (their first answer was lost).
    pub repeated_ticks: u32,
    /// Ticks the firmware refused as older than its last answer.
    pub stale_ticks: u32,
    /// The firmware's route was done at the end of the run
    /// (`Finished::route_done`; false without a route).
    pub route_done: bool,
    /// The faults injected on the link (`--link-faults`), and what each
    /// side must have counted.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub link_faults: Option<link_faults::LinkFaultReport>,
    /// The ground station bridged to the run (`--mavlink`): the UDP side,
    /// the channel, and the host's copy of the session against the
    /// firmware.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mavlink: Option<mavlink_bridge::MavlinkBridgeReport>,
}

/// Everything a run produced.
#[derive(Debug, Clone)]
pub struct RunResult {
    /// The scenario run.
    pub scenario: Scenario,
    /// Its validated setup.
    pub setup: Setup,
    /// One record per tick.
    pub records: Vec<Record>,
    /// The figures.
    pub summary: Summary,
}

/// How a run's summary names its setup.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SetupLabels {
    /// `unicycle` or `diff_drive`.
    pub plant: &'static str,
    /// `state_feedback`, or `output_feedback` with its estimator and law
    /// as they name themselves.
    pub controller: String,
    /// `exact`, `nearest_tag` or `reader`.
    pub position_source: &'static str,
}

impl SetupLabels {
    /// The labels of a validated setup.
    #[must_use]
    pub fn of(setup: &Setup) -> Self {
        Self {
            plant: match setup.plant {
                PlantSetup::Unicycle => "unicycle",
                PlantSetup::DiffDrive { .. } => "diff_drive",
            },
            controller: match (
                setup.controller,
                setup.tracker.estimator(),
                setup.tracker.law(),
            ) {
                (ControllerKind::StateFeedback, ..) => "state_feedback".to_string(),
                // Paper 001's own pair is the plain output feedback.
                (_, EstimatorChoice::HeadingObserver(_), LawChoice::Saturated(_)) => {
                    "output_feedback".to_string()
                }
                (_, estimator, law) => {
                    format!("output_feedback ({}, {})", estimator.label(), law.label())
                }
            },
            position_source: match setup.position {
                PositionSetup::Exact => "exact",
                PositionSetup::NearestTag(_) => "nearest_tag",
                PositionSetup::Reader(..) => "reader",
            },
        }
    }
}
