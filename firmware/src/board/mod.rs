//! Board layers: each gives the core's `Robot` its devices behind the same
//! embedded-hal / embedded-io traits, and runs the control loop.

#[cfg(feature = "board-blackpill")]
pub mod blackpill;
#[cfg(feature = "board-qemu")]
pub mod qemu;

#[cfg(feature = "board-blackpill")]
pub use blackpill::run;
#[cfg(feature = "board-qemu")]
pub use qemu::run;
