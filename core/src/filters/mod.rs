//! Generic state estimators, sized by const generics, that know nothing of
//! robots: the extended Kalman filter ([`ekf`]), the unscented Kalman filter
//! ([`ukf`]) and the particle filter ([`particle_filter`]) of paper 004.
//!
//! A model implements the filter's trait (transition, measurement and, for
//! the Gaussian filters, Jacobians or angle hooks); the robot's estimators in
//! [`crate::estimation`] are such models.

pub mod ekf;
pub mod particle_filter;
pub mod ukf;
