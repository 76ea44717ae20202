#![doc = include_str!("../README.md")]
#![cfg_attr(not(any(test, feature = "std")), no_std)]
#![forbid(unsafe_code)]
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::indexing_slicing,
        clippy::unreachable,
        clippy::todo,
        clippy::unimplemented
    )
)]

pub mod chained_form;
pub mod devices;
pub mod drive;
pub mod ekf;
pub mod geometry;
pub mod heading_observer;
pub mod math;
pub mod momenta_observer;
pub mod odometry;
pub mod output_feedback;
pub mod particle_filter;
pub mod pilot;
pub mod pose_ekf;
pub mod pose_observer;
pub mod pose_particle_filter;
pub mod pose_ukf;
pub mod reference;
pub mod robot;
pub mod robot_frame;
pub mod robot_frame_observers;
pub mod scaled_momenta_observer;
pub mod slip_tracking;
pub mod spec;
pub mod tracking;
pub mod ukf;
pub mod wheel_speed_observer;
