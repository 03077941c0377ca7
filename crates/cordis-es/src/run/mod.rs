//! The framework every search runs in (argmin-style), apart from the strategies: the
//! [`strategy::Strategy`] trait, the one run loop ([`executor`]: stop rules, observers,
//! checkpoints and resume, the history), the seeded random streams ([`rng`]) and the exact-float
//! JSON forms of checkpoints and reports ([`float_json`]); CPU time for benchmarks
//! ([`cpu_time`]).

pub mod cpu_time;
pub mod executor;
pub mod float_json;
pub mod rng;
pub mod strategy;
