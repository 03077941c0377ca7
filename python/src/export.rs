//! `cordis_core::export`: a scene to MuJoCo's MJCF and a motion to glTF 2.0, written
//! atomically (the same files as `cordis export --mjcf / --gltf`).

use std::path::PathBuf;

use pyo3::prelude::*;

use crate::errors::to_py;
use crate::scene::Scene;
use crate::trajectory::{check_dt, traj_from_py};

/// Writes the MJCF model of `scene` (kinds without an MJCF element as `<custom>` data for
/// `cordis.mujoco`; refused, naming them, for kinds it cannot replay).
#[pyfunction]
pub fn export_mjcf(py: Python<'_>, scene: &Scene, path: PathBuf) -> PyResult<()> {
    let scene = scene.core();
    py.detach(|| {
        let xml = cordis_core::export::to_mjcf(&scene)?;
        cordis_core::io::write_atomic(&path, xml.as_bytes())
    })
    .map_err(to_py)
}

/// Writes the glTF 2.0 animation of `trajectory` `(T, N, 3)`, a motion of `scene`, frames
/// `dt` s apart (default the scene's).
#[pyfunction]
#[pyo3(signature = (scene, trajectory, path, dt = None))]
pub fn export_gltf(
    py: Python<'_>,
    scene: &Scene,
    trajectory: &Bound<'_, PyAny>,
    path: PathBuf,
    dt: Option<f64>,
) -> PyResult<()> {
    let traj = traj_from_py(trajectory, "trajectory")?;
    let scene = scene.core();
    let dt = match dt {
        Some(dt) => check_dt(dt, "dt")?,
        None => scene.dt,
    };
    py.detach(|| {
        let text = cordis_core::export::to_gltf(&scene, &traj, dt)?;
        cordis_core::io::write_atomic(&path, text.as_bytes())
    })
    .map_err(to_py)
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(export_mjcf, m)?)?;
    m.add_function(wrap_pyfunction!(export_gltf, m)?)?;
    Ok(())
}
