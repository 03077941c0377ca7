//! The identification strategies, one file each, all behind [`crate::strategy::Strategy`].

pub mod annealing;
pub mod cmaes;
mod common;
pub mod exact;
pub mod hybrid;
pub mod islands;
pub mod least_squares;
pub mod levenberg_marquardt;
pub mod parisian;
pub mod provot_rows;
pub mod range_sweep;
pub mod self_adaptive;
pub mod thesis;

pub use common::reflect;
