//! `cordis._cordis`: the compiled half of the `cordis` Python package (pyo3 + numpy).
//!
//! One Rust module per core module, each with a `register` function, in the manner of
//! `tokenizers`: the methods are thin wrappers that convert arguments, release the GIL around
//! the core call and map errors with [`errors::to_py`]. The pure-Python package `cordis`
//! (python/cordis/) re-exports everything from here and adds Python-only helpers.
//!
//! Later modules (costs, identification, trajectory files) slot in as `cost.rs`,
//! `identify.rs`, `trajectory.rs` with their own `register`.

use pyo3::prelude::*;

pub mod errors;
pub mod json;
pub mod scene;

#[pymodule]
fn _cordis(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    errors::register(m)?;
    m.add_class::<scene::Scene>()?;
    Ok(())
}
