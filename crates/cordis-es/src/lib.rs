//! # cordis-es
//!
//! Identification of Cordis-Anima networks from observed motion (the thesis' T2M): cost
//! functions and evolution strategies. This crate is being built up issue by issue; for now it
//! re-exports the core so that dependants compile against their final paths.
#![forbid(unsafe_code)]

pub use cordis_core as core;
