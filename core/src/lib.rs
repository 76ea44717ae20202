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

pub mod builds;
pub mod control;
pub mod devices;
pub mod drive;
pub mod estimation;
pub mod filters;
#[cfg(feature = "arbitrary")]
pub mod fuzzing;
pub mod geometry;
pub mod math;
pub mod odometry;
pub mod pilot;
pub mod plausible;
pub mod reference;
