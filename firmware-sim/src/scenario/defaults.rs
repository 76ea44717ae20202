//! The scenario's default values (serde needs functions): the paper's
//! section 6.3.2 values where the paper gives one.

pub fn period_s() -> f64 {
    0.01
}
pub fn k12() -> f64 {
    0.11
}
pub fn k3() -> f64 {
    0.1
}
pub fn gain_per_m() -> f64 {
    0.6
}
pub fn min_speed_m_s() -> f64 {
    core_default(
        wmr_core::estimation::heading_observer::HeadingObserverConfig::DEFAULT_MIN_SPEED_M_S,
    )
}
pub fn wheel_radius_m() -> f64 {
    0.03
}
pub fn track_width_m() -> f64 {
    0.2
}
pub fn motor_time_constant_s() -> f64 {
    0.05
}
pub fn wheel_speed_at_full_duty_rad_s() -> f64 {
    20.0
}
pub fn encoder_counts_per_rev() -> u32 {
    2048
}
pub fn encoder_bits() -> u32 {
    16
}
pub fn pwm_max_duty() -> u16 {
    1000
}
pub fn substeps() -> u32 {
    10
}
pub fn max_wheel_speed_rad_s() -> f64 {
    18.0
}
pub fn max_wheel_accel_rad_s2() -> f64 {
    50.0
}
pub fn kp_duty_per_rad_s() -> f64 {
    0.02
}
pub fn ki_duty_per_rad() -> f64 {
    0.5
}
pub fn observer_lambda_per_s() -> f64 {
    core_default(wmr_core::drive::speed_observer::WheelSpeedObserverConfig::DEFAULT_LAMBDA_PER_S)
}
pub fn observer_friction_gain() -> f64 {
    core_default(wmr_core::drive::speed_observer::WheelSpeedObserverConfig::DEFAULT_FRICTION_GAIN)
}
pub fn observer_disturbance_gain() -> f64 {
    core_default(
        wmr_core::drive::speed_observer::WheelSpeedObserverConfig::DEFAULT_DISTURBANCE_GAIN,
    )
}
pub fn spacing_m() -> f64 {
    0.1
}
pub fn margin_m() -> f64 {
    1.0
}
pub fn read_radius_m() -> f64 {
    0.05
}
pub fn baud() -> u32 {
    115_200
}
pub fn repeat_interval_s() -> f64 {
    0.1
}
pub fn seed() -> u64 {
    1
}
pub fn glitch_min_counts() -> u32 {
    1
}
pub fn fix_timeout_s() -> f64 {
    0.5
}
pub fn decel_m_s2() -> f64 {
    f64::from(wmr_core::pilot::tracker::TrackerConfig::DEFAULT_FAILSAFE_DECEL_M_S2)
}
pub fn yes() -> bool {
    true
}
/// The Black Pill's `TELEMETRY_EVERY_TICKS` (`firmware/src/board/blackpill.rs`).
pub fn telemetry_every_ticks() -> u64 {
    10
}

/// The `f64` a file writes for a default the core states in `f32`: the
/// shortest decimal that reads back as that `f32` (`0.001`, where the
/// `f32`'s own value is `0.0010000000474974513`). Validation turns it
/// back into the core's `f32`, bit for bit.
fn core_default(value: f32) -> f64 {
    value.to_string().parse().unwrap_or(f64::from(value))
}
