//! The bench robot's pilot on paper 001's figure-eight, the tag grid it
//! drives over, and the world that gives each tick's readings.

use wmr_core::devices::tag_grid::TagGridSpec;
use wmr_core::devices::{TagGrid, TagId};
use wmr_core::drive::spec::DriveSpec;
use wmr_core::geometry::{BodyVelocity, DiffDriveGeometry, Vec2};
use wmr_core::pilot::spec::{PilotSpec, TrackerSpec};
use wmr_core::reference::TrajectorySpec;
use wmr_core::reference::{ReferenceSample, Trajectory};

use super::stage::nearest;

/// The control period, s.
pub(super) const PERIOD_S: f32 = 0.01;

/// Paper 001's figure-eight and observer gain, on a small robot (as
/// `host_tests::paper_pilot` and the simulator's defaults).
pub(super) fn pilot_spec(estimator: wmr_core::estimation::spec::EstimatorSpec) -> PilotSpec {
    PilotSpec {
        tracker: TrackerSpec {
            period_s: PERIOD_S,
            trajectory: TrajectorySpec::FigureEight {
                h1_m: 5.0,
                h2_rad_s: 0.02,
                phase_rad: -core::f32::consts::FRAC_PI_2,
            },
            gains: [0.11, 0.11, 0.1],
            observer_gain_per_m: 0.6,
            observer_min_speed_m_s: 1.0e-3,
            fix_timeout_ticks: 100,
            failsafe_decel_m_s2: 0.5,
            max_fix_age_ticks: 2,
            estimator,
            law: wmr_core::control::spec::LawSpec::Saturated,
            sensors: wmr_core::estimation::spec::SensorSpec {
                track_width_m: 0.2,
                // Count quantum q = 2π·0.03 m / 2048: q²/12.
                wheel_variance_floor_m2: 7.06e-10,
                tag_spacing_m: 0.1,
                read_radius_m: 0.0,
                antenna_offset_m: [0.0; 2],
            },
        },
        drive: DriveSpec {
            wheel_radius_m: 0.03,
            track_width_m: 0.2,
            encoder_counts_per_rev: 2048,
            max_wheel_speed_rad_s: 20.0,
            max_wheel_accel_rad_s2: 100.0,
            feedforward_duty_per_rad_s: 0.05,
            kp_duty_per_rad_s: 0.02,
            ki_duty_per_rad: 0.1,
            speed_observer: None,
        },
        encoder_bits: 16,
        max_encoder_fault_ticks: 5,
    }
}

/// Tags every 10 cm over the figure-eight (±5 m) with a 1 m margin.
pub(super) const GRID: TagGridSpec = TagGridSpec {
    origin_m: [-6.0, -6.0],
    spacing_m: 0.1,
    rows: 121,
    columns: 121,
};

/// One tick of the world: the robot on the reference, its encoders, the
/// tag under it.
pub(super) struct Reading {
    pub(super) tick: u32,
    pub(super) reference: ReferenceSample,
    pub(super) counts: [u32; 2],
    pub(super) tag: TagId,
    pub(super) tag_position: Vec2,
}

/// A robot driving exactly along the reference (its wheels integrate
/// the reference's `v`, `ω`), reading the nearest floor tag every tick.
pub(super) struct World {
    trajectory: Trajectory,
    geometry: DiffDriveGeometry,
    pub(super) grid: TagGrid,
    wheel_angle_rad: [f32; 2],
}

/// Encoder counters start here, so that they wrap at 16 bits early on.
const COUNTER_START: i32 = 65_000;

impl World {
    /// The world of a bench pilot's `config` on the tag `grid`.
    pub(super) fn new(config: &wmr_core::pilot::PilotConfig, grid: TagGrid) -> Self {
        Self {
            trajectory: *config.tracker().trajectory(),
            geometry: *config.drive().geometry(),
            grid,
            wheel_angle_rad: [0.0; 2],
        }
    }

    pub(super) fn reading(&mut self, tick: u32) -> Reading {
        let reference = self.trajectory.sample(tick as f32 * PERIOD_S);
        let vel = reference.velocity;
        let acc = reference.acceleration;
        let v = vel.norm();
        let omega = if v > 1e-6 {
            (vel.x * acc.y - vel.y * acc.x) / (v * v)
        } else {
            0.0
        };
        let wheels = self.geometry.wheels_from_body(BodyVelocity {
            v_m_s: v,
            omega_rad_s: omega,
        });
        let [left, right] = &mut self.wheel_angle_rad;
        *left += wheels.left_rad_s * PERIOD_S;
        *right += wheels.right_rad_s * PERIOD_S;
        let count = |angle: f32| {
            let counts = nearest(angle / self.geometry.rad_per_count());
            COUNTER_START.wrapping_add(counts).cast_unsigned() & 0xFFFF
        };
        let counts = [count(*left), count(*right)];
        let origin = self.grid.origin();
        let spacing = self.grid.spacing_m();
        let cell = |x: f32, n: u16| nearest(x / spacing).clamp(0, i32::from(n) - 1) as u16;
        let column = cell(reference.position.x - origin.x, self.grid.columns());
        let row = cell(reference.position.y - origin.y, self.grid.rows());
        let tag = TagGrid::id(row, column);
        let tag_position = self.grid.position(tag).unwrap_or(reference.position);
        Reading {
            tick,
            reference,
            counts,
            tag,
            tag_position,
        }
    }
}
