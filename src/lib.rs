//! `cordis-suite`: the workspace's root package. It holds no code of its own; it exists so that
//! cross-crate integration tests live in `tests/` and criterion benches in `benches/`, as the
//! layout of SPEC §1 asks.
