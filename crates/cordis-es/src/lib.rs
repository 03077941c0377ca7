//! # cordis-es
//!
//! Identification of Cordis-Anima networks from observed motion (the thesis' T2M): cost
//! functions ([`cost`]) and, in later issues, evolution strategies and exact solvers.
#![forbid(unsafe_code)]

pub mod cost;
pub mod error;

pub use cordis_core as core;
pub use error::CostError;
