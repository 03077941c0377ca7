//! # cordis-es
//!
//! Identification of Cordis-Anima networks from observed motion (the thesis' T2M): the problem
//! and its unknowns ([`problem`]), the costs ([`cost`]), the run framework ([`run`]), the search
//! strategies ([`strategies`]), the exact linear solvers ([`exact`]) on their linear algebra
//! ([`linalg`]), the output-error estimator ([`output_error`]), link discovery ([`discover`])
//! and the one identification session the CLI, Python and the benches share ([`session`]).
#![forbid(unsafe_code)]

pub mod cost;
pub mod discover;
pub mod error;
pub mod exact;
pub mod identify;
pub mod linalg;
mod named;
pub mod output_error;
pub mod problem;
pub mod report;
pub mod run;
pub mod session;
pub mod strategies;

// The modules' paths before the `problem/` and `run/` folders, kept for the CLI, the Python
// bindings and the tests.
pub use problem::{evaluator, space, stable};
pub use run::{executor, float_json, rng, strategy};

pub use cordis_core as core;
pub use error::CostError;
