//! The hardware boundary: encoders, motor drivers, the RFID reader and the
//! floor-tag map.
//!
//! Everything above this module is pure arithmetic on `f32`; everything in it
//! talks to peripherals through traits, so that the same code runs against a
//! microcontroller HAL, the simulator's virtual devices and test fakes:
//!
//! - PWM and GPIO come from [`embedded_hal`] 1.0
//!   ([`embedded_hal::pwm::SetDutyCycle`], [`embedded_hal::digital::OutputPin`]).
//! - Tag ids become floor positions through a [`TagLocator`]: a table
//!   ([`TagMap`]) or a computed grid ([`TagGrid`]).
//! - The RFID reader's UART comes from [`embedded_io`]
//!   ([`embedded_io::Read`] + [`embedded_io::ReadReady`]), used without
//!   blocking.
//! - embedded-hal 1.0 has **no encoder trait** (the 0.2 `Qei` trait was
//!   dropped), so this module defines the minimal one the core needs,
//!   [`QuadratureCounter`]: a raw, wrapping hardware count, turned into
//!   signed increments by [`crate::odometry::WrappingCounter`].
//!
//! Fault policy: the control loop must keep its period whatever a device
//! does. Devices never panic and never block; faults are either returned as
//! small `Copy` error values ([`MotorFault`]) for the caller to count and act
//! on (e.g. stop the robot), or counted in place ([`RfidCounters`]) when the
//! right reaction is simply to carry on with the next byte. Nothing here
//! allocates.

pub mod encoder;
pub mod motor;
pub mod rfid;
pub mod tag_grid;
pub mod tag_map;

pub use encoder::QuadratureCounter;
pub use motor::{Direction, MotorCommand, MotorDriver, MotorFault, MotorWiring};
pub use rfid::{FrameParser, RfidCounters, RfidReader, TagId, TagRead, encode_frame};
pub use tag_grid::{TagGrid, TagGridError, TagLocator};
pub use tag_map::{TagMap, TagMapError};
