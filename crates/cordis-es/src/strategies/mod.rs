//! The identification strategies, one file each, all behind [`crate::strategy::Strategy`].

pub mod cmaes;
mod common;
pub mod self_adaptive;
pub mod thesis;

pub use common::reflect;
