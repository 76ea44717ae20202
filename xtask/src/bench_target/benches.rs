//! What the bench measures: the math backends, the bench names and row
//! labels of each table, and the particle filter's own build.

/// The math backends: name and the firmware features that select it.
/// `f32` is the default (the core's `f32`-native functions), `libm` every
/// function from the `libm` crate (its `sinf`/`cosf` in software `f64`).
pub const BACKENDS: [(&str, &[&str]); 3] = [
    ("f32", &[]),
    ("libm", &["libm"]),
    ("micromath", &["micromath"]),
];

/// Stages of the main table: the bench's name and the row label.
pub(super) const STAGES: [(&str, &str); 16] = [
    (
        "odometry",
        "odometry (2 counter deltas + `OdometryStep::from_counts`)",
    ),
    (
        "heading_observer",
        "heading observer (`HeadingObserver::update`)",
    ),
    (
        "output_feedback",
        "output-feedback law (`TrackingController::output_feedback`)",
    ),
    (
        "wheel_speed_loop",
        "wheel speed loop (`WheelSpeedLoop::update`, one wheel)",
    ),
    ("pilot_step", "`Pilot::step`"),
    (
        "robot_tick",
        "whole tick (`Robot::tick` over the HIL proxies, one RFID frame)",
    ),
    (
        "robot_tick_fusion_fix",
        "whole tick, fusion EKF estimator, tick with a tag fix (one RFID frame; corrections included)",
    ),
    (
        "robot_tick_fusion_dead_reckoned",
        "whole tick, fusion EKF estimator, dead-reckoned tick (no frame)",
    ),
    (
        "robot_tick_fusion_pf_fix",
        "whole tick, fusion particle filter (100 particles; a build with `fusion-particle-filter`), tick with a tag fix (the read tag's cell likelihood)",
    ),
    (
        "robot_tick_fusion_pf_dead_reckoned",
        "whole tick, fusion particle filter (100 particles; a build with `fusion-particle-filter`), dead-reckoned tick (no frame)",
    ),
    (
        "route_plan",
        "planning a route of 64 waypoints in place (`RoutePlan::replan`; 20 plans)",
    ),
    (
        "route_sample",
        "sampling that route at a tick (`RoutePlan::sample`)",
    ),
    (
        "mavlink_tick",
        "MAVLink's part of a tick as the Black Pill runs it (its receive ring read, `MavlinkRun::before_tick`, the frames queued on its transmit ring, `after_tick`; telemetry at 10 Hz, a ground station's heartbeat at 1 Hz; mean over 2 s of 10 ms ticks)",
    ),
    (
        "mavlink_usart_interrupt",
        "the MAVLink USART's interrupt handler, per interrupt (`rx_ring::on_interrupt`: a byte received or sent, or the transmit interrupt turned off; registers in RAM, the exception entry not counted)",
    ),
    (
        "mavlink_tick_with_interrupts",
        "MAVLink's whole cost a tick: the tick above and the USART interrupts of the bytes it read and sent (goal: 1,500, `[targets]`)",
    ),
    (
        ROUTE_TICK,
        "whole tick on a route (the whole tick above, through `Pilot::step_route` on a 64-waypoint route through the figure-eight; a build with `bench-route-tick` of its own)",
    ),
];

/// Stack lines of the fusion estimator's whole ticks and the row label's
/// estimator.
pub(super) const FUSION_STACKS: [(&str, &str); 2] = [
    ("robot_tick_fusion", "fusion EKF"),
    (PF_TICK[2], "fusion particle filter"),
];

/// The fusion particle filter's whole-tick stages and stack, measured by a
/// build of their own (each backend's, with [`PF_FEATURES`]) and reported in
/// that backend's column: compiled into the main build, the particle
/// filter's arm of the estimator would set the frame of every fusion tick
/// (the EKF's then takes 10 KB of stack, not 2.5 KB) and move the other
/// rows, which are what a firmware without it runs.
pub(super) const PF_TICK: [&str; 3] = [
    "robot_tick_fusion_pf_fix",
    "robot_tick_fusion_pf_dead_reckoned",
    "robot_tick_fusion_pf",
];

/// Features of the particle filter's own build (added to the backend's).
pub(super) const PF_FEATURES: [&str; 1] = [wmr_core::builds::FUSION_PARTICLE_FILTER.feature];

/// The whole tick on a route, measured by a build of its own (each
/// backend's, with [`ROUTE_FEATURES`]) and reported in that backend's
/// column: linked beside the analytic tick, `Pilot::step_route` moves the
/// analytic rows (the whole tick 2,852 → 2,966 instructions, its stack
/// 756 → 980 B), which are what a firmware without routes runs.
pub(super) const ROUTE_TICK: &str = "robot_tick_route";

/// Features of the route tick's own build (added to the backend's).
pub(super) const ROUTE_FEATURES: [&str; 1] = ["bench-route-tick"];

/// Math backend calls, per call.
pub(super) const MATH: [(&str, &str); 7] = [
    ("math_sin", "`sin`"),
    ("math_cos", "`cos`"),
    ("math_sincos", "`sincos` (and one `f32` add of the pair)"),
    ("math_atan", "`atan`"),
    ("math_atan2", "`atan2`"),
    ("math_exp", "`exp`"),
    ("math_sqrt", "`sqrt`"),
];

/// Paper 004's filters: the bench's name and the row label. Each has the
/// stages `<name>_predict` and `<name>_update`.
pub(super) const FILTERS: [(&str, &str); 13] = [
    ("ekf3", "EKF, N = M = 3 (`PoseModel`)"),
    ("ekf5", "EKF, N = M = 5 (`PoseWheelModel`)"),
    ("ukf3", "UKF, N = M = 3 (7 sigma points)"),
    ("ukf5", "UKF, N = M = 5 (11 sigma points)"),
    ("srukf3", "square-root UKF, N = M = 3"),
    ("srukf5", "square-root UKF, N = M = 5"),
    (
        "pf3",
        "particle filter, N = M = 3, 100 particles (prior proposal)",
    ),
    (
        "pf5",
        "particle filter, N = M = 5, 100 particles (prior proposal)",
    ),
    (
        "pf3o",
        "particle filter, N = M = 3, 100 particles (optimal proposal, regularized: the slip scenarios')",
    ),
    (
        "pf5o",
        "particle filter, N = M = 5, 100 particles (optimal proposal, regularized: the slip scenarios')",
    ),
    ("fusion_ekf", "fusion EKF (`PoseEkf`: odometry, 2-D fix)"),
    ("fusion_ukf", "fusion UKF (`PoseUkf`: odometry, 2-D fix)"),
    (
        "fusion_pf",
        "fusion particle filter (`PoseParticleFilter`, 100 particles)",
    ),
];
