//! The identification strategies, one file each, all behind [`crate::strategy::Strategy`].

pub mod annealing;
pub mod cmaes;
pub(crate) mod common;
mod design;
pub mod exact;
pub mod hybrid;
pub mod islands;
pub mod least_squares;
pub mod levenberg_marquardt;
pub mod output_error;
pub mod parisian;
mod profile;
pub mod provot_rows;
pub mod range_sweep;
pub mod self_adaptive;
#[cfg(test)]
mod test_scenes;
mod tgr_cols;
pub mod thesis;

pub use common::reflect;
