//! The marker of a known parameter in the sensitivity columns, shared by every link kind's
//! tangent: a file of its own so that the kinds' files and the rollout in `mod.rs` depend on
//! it, not on each other.

/// No column: a known parameter.
pub(crate) const NONE: usize = usize::MAX;
