//! # cordis-es
//!
//! Identification of Cordis-Anima networks from observed motion (the thesis' T2M): cost
//! functions ([`cost`]) and, in later issues, evolution strategies and exact solvers.
#![forbid(unsafe_code)]

pub mod cost;
pub mod descent;
pub mod discover;
pub mod error;
pub mod evaluator;
pub mod exact;
pub mod executor;
pub mod float_json;
pub mod identify;
pub mod output_error;
pub mod problem;
pub mod report;
pub mod rng;
pub mod session;
pub mod space;
pub mod stable;
pub mod strategies;
pub mod strategy;

pub use cordis_core as core;
pub use error::CostError;
