//! `thesis`: the evolution strategy of thesis §3.2, §3.2.1 and Annexe 1, operators as the text
//! states them ([`operators`]); `t2m`: the same population, selection schedule and descent
//! with this crate's earlier, freer operators ([`t2m`]), kept because it measures better.

mod config;
mod operators;
mod population;
mod strategy;
mod t2m;
#[cfg(test)]
mod tests;

pub use config::{Crossover, ThesisConfig, Variant};
pub use strategy::Thesis;
