//! Tracking laws: from the reference and the estimated pose to a body
//! command `(v, ω)`. Paper 001's saturated laws (14) and (27)–(28)
//! ([`saturated`]); paper 002's cascaded controller (31) ([`cascaded`]) and
//! Proposition 7's observer of `sin θ_e` with controller (64)
//! ([`heading_error_sine`]), both on the robot-frame error (30)
//! ([`robot_frame`]).

pub mod cascaded;
pub mod heading_error_sine;
pub mod robot_frame;
pub mod saturated;
