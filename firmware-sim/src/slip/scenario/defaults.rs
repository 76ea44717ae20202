//! Serde defaults: the paper's values.

use super::super::filter::PARTICLES;
use super::paper::{SLIP_RATIO, SLIP_WINDOW_S};
use super::schedule::{SegmentSpec, SlipStep};

pub fn seed() -> u64 {
    1
}
pub fn duration_s() -> f64 {
    super::DURATION_S
}
pub fn period_s() -> f64 {
    super::PERIOD_S
}
pub fn plant_substeps() -> u32 {
    10
}
pub fn record_every_steps() -> u32 {
    10
}
pub fn slip() -> Vec<SlipStep> {
    vec![
        SlipStep {
            start_s: SLIP_WINDOW_S.0,
            slip_ratio: SLIP_RATIO,
        },
        SlipStep {
            start_s: SLIP_WINDOW_S.1,
            slip_ratio: 0.0,
        },
    ]
}
pub fn segments() -> Vec<SegmentSpec> {
    let segment = |start_s, v_m_s, omega_rad_s| SegmentSpec {
        start_s,
        v_m_s,
        omega_rad_s,
    };
    vec![
        segment(0.0, 0.5, 0.0),
        segment(15.0, 0.5, -0.4),
        segment(33.0, 0.5, 0.4),
        segment(51.0, 0.7, 0.0),
    ]
}
pub fn wheel_radius_m() -> f64 {
    0.35
}
pub fn track_width_m() -> f64 {
    0.65
}
pub fn mass_kg() -> f64 {
    0.80
}
pub fn yaw_inertia_kg_m2() -> f64 {
    0.0608
}
pub fn k1() -> f64 {
    6.0
}
pub fn k2() -> f64 {
    8.0
}
pub fn k3() -> f64 {
    6.0
}
pub fn k45() -> f64 {
    4.0
}
pub fn rho() -> f64 {
    3.0
}
pub fn initial_slip_estimate() -> f64 {
    1.0
}
pub fn measurement_variance() -> [f64; 5] {
    super::MEASUREMENT_VARIANCE
}
pub fn initial_variance() -> [f64; 5] {
    super::INITIAL_VARIANCE
}
pub fn process_noise() -> [f64; 5] {
    super::PROCESS_NOISE
}
pub fn alpha() -> f64 {
    0.01
}
pub fn beta() -> f64 {
    2.0
}
pub fn ukf_initial_variance() -> [f64; 5] {
    super::UKF_INITIAL_VARIANCE
}
pub fn particles() -> usize {
    PARTICLES
}
pub fn particle_process_std() -> [f64; 5] {
    // `PARTICLE_PROCESS_STD` as decimals, not `f64::from` of its `f32`s
    // (the file form prints them as written; a test checks that they
    // round to the constant).
    [0.005, 0.005, 0.007, 5.0, 5.0]
}
pub fn collapse_gate() -> f64 {
    f64::INFINITY
}
pub fn regularization() -> f64 {
    f64::from(super::PARTICLE_REGULARIZATION)
}
pub fn before_slip_s() -> [f64; 2] {
    [15.0, 22.5]
}
pub fn during_slip_s() -> [f64; 2] {
    [25.0, 45.0]
}
pub fn after_slip_s() -> [f64; 2] {
    [50.0, 60.0]
}
pub fn slip_estimate_during_s() -> [f64; 2] {
    [35.0, 45.0]
}
pub fn slip_estimate_after_s() -> [f64; 2] {
    [55.0, 60.0]
}
