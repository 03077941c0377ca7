//! `cordis._cordis`: the compiled half of the `cordis` Python package (pyo3 + numpy).
//!
//! One Rust module per core module, each with a `register` function, in the manner of
//! `tokenizers`: the methods are thin wrappers that convert arguments, release the GIL around
//! the core call and map errors with [`errors::to_py`]. The pure-Python package `cordis`
//! (python/cordis/) re-exports everything from here and adds Python-only helpers.
//!
//! Modules: `scene.rs` (core `Scene`), `scene_edit.rs` (its editing views), `unknown.rs`
//! (`Param::Unknown`), `trajectory.rs` (`cordis_core::io`), `examples.rs`
//! (`cordis_core::examples`), `export.rs` (`cordis_core::export`: MJCF, glTF), `cost.rs` (`cordis_es::cost`), `identify.rs` (`cordis_es::problem`,
//! `identify`, `executor`), `evaluator.rs` (`cordis_es::evaluator`: populations evaluated by
//! a Python executor such as Ray), `discover.rs` (`cordis_es::discover`), `cli.rs` (`cordis_cli`), `errors.rs` (both error enums).

use pyo3::prelude::*;

pub mod cli;
pub mod cost;
pub mod discover;
pub mod errors;
pub mod evaluator;
pub mod examples;
pub mod export;
pub mod from_markers;
pub mod identify;
pub mod json;
pub mod scene;
pub mod scene_edit;
pub mod signals;
pub mod trajectory;
pub mod unknown;

#[pymodule]
fn _cordis(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    errors::register(m)?;
    m.add_class::<scene::Scene>()?;
    m.add_class::<unknown::Unknown>()?;
    m.add_class::<scene_edit::Particles>()?;
    m.add_class::<scene_edit::ParticleView>()?;
    m.add_class::<scene_edit::Types>()?;
    m.add_class::<scene_edit::TypeView>()?;
    trajectory::register(m)?;
    examples::register(m)?;
    export::register(m)?;
    cost::register(m)?;
    identify::register(m)?;
    evaluator::register(m)?;
    discover::register(m)?;
    from_markers::register(m)?;
    cli::register(m)?;
    Ok(())
}
