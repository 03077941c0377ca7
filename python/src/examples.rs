//! The shipped example scenes: `cordis.example(name)` and `cordis.EXAMPLES`.

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyTuple;

use crate::scene::Scene;

/// The shipped example `name` (one of `cordis.EXAMPLES`) at its default size. With
/// `unknowns=True`, every positive link-type parameter becomes unknown, in a box `width` times
/// wide (max/min) that holds the true value at a place drawn from `seed` (not its centre);
/// zero dampings stay known. Simulate the plain example to get a trajectory to identify.
///
/// >>> truth = cordis.example("rigid")
/// >>> traj = truth.simulate(100)
/// >>> scene = cordis.example("rigid", unknowns=True)
/// >>> scene.has_unknowns
/// True
#[pyfunction]
#[pyo3(signature = (name, unknowns = false, width = 25.0, seed = 0))]
pub fn example(name: &str, unknowns: bool, width: f64, seed: u64) -> PyResult<Scene> {
    let scene = cordis_core::examples::by_name(name).ok_or_else(|| {
        PyValueError::new_err(format!(
            "name: unknown example `{name}` (expected one of: {})",
            cordis_core::examples::NAMES.join(", ")
        ))
    })?;
    if !unknowns {
        return Ok(Scene::from_core(scene));
    }
    cordis_core::arg::box_width("width", width).map_err(crate::errors::to_py)?;
    Ok(Scene::from_core(cordis_es::identify::with_unknown_boxes(
        &scene, width, seed,
    )))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(example, m)?)?;
    m.add(
        "EXAMPLES",
        PyTuple::new(m.py(), cordis_core::examples::NAMES)?,
    )?;
    Ok(())
}
