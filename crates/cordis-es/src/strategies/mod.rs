//! The identification strategies, one file each, all behind [`crate::run::strategy::Strategy`].

pub mod annealing;
pub mod cmaes;
pub(crate) mod common;
pub mod hybrid;
pub mod islands;
pub mod least_squares;
pub mod levenberg_marquardt;
pub mod output_error;
pub mod parisian;
pub mod registry;
pub mod self_adaptive;
#[cfg(test)]
pub(crate) mod test_scenes;
pub mod thesis;

pub use common::reflect;
// The linear-solver library moved to `crate::exact`; its old paths stay valid.
pub use crate::exact;
pub use crate::exact::{provot_rows, range_sweep};
