//! Estimators of the robot's pose from odometry and tag fixes: the
//! heading observer (5) of paper 001 ([`heading_observer`]), paper 002's
//! Proposition 4 pose observer ([`pose_observer`]) and the encoder + tag
//! fusion estimator ([`fusion`], on the EKF, UKF or particle filter of
//! [`crate::filters`]).

pub mod fusion;
pub mod heading_observer;
pub mod pose_observer;
