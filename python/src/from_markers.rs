//! A scene built on tracked markers (`cordis_core::from_markers`):
//! `cordis.scene_from_markers(markers, dt, total_mass, …)`, as `cordis scene from-markers`.

use cordis_core::from_markers::{scene_from_markers as build, LinkRule, MarkerScene, TypeRule};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::errors::to_py;
use crate::scene::Scene;
use crate::trajectory::observations_from_py;

/// A spring network on tracked markers `(T, N, 3)` (NaN where missing), every parameter
/// unknown in a box: one particle per marker at its first observed position, fixed when it
/// never moves (within `still` m of its median; default 2 % of the markers' extent; then at
/// the mean of its observations), masses
/// `total_mass / N`; springs to the `neighbours` nearest markers (default 6) or between every
/// pair closer than `radius` m; one type per family of equal first-frame lengths
/// (`types="family"`) or per link (`"link"`); rest lengths in boxes `width` times wide around
/// them, stiffness and damping under the shared stability bound; `gravity` (m/s²) defaults to
/// `(0, -9.81, 0)` (y up). `cordis.identify` fits it.
///
/// >>> markers, dt = cordis.read_trajectory("markers.csv", with_dt=True)   # doctest: +SKIP
/// >>> scene = cordis.scene_from_markers(markers, 0.01, 0.54, radius=0.18)   # doctest: +SKIP
#[pyfunction]
#[pyo3(signature = (markers, dt, total_mass, *, neighbours = None, radius = None, types = "family", width = 4.0, gravity = None, still = None, family_tolerance = 0.05))]
#[allow(clippy::too_many_arguments)]
pub fn scene_from_markers(
    py: Python<'_>,
    markers: &Bound<'_, PyAny>,
    dt: f64,
    total_mass: f64,
    neighbours: Option<usize>,
    radius: Option<f64>,
    types: &str,
    width: f64,
    gravity: Option<(f64, f64, f64)>,
    still: Option<f64>,
    family_tolerance: f64,
) -> PyResult<Scene> {
    let obs = observations_from_py(markers, None, "markers", "visible")?;
    let links = match (neighbours, radius) {
        (Some(_), Some(_)) => {
            return Err(PyValueError::new_err("give neighbours or radius, not both"))
        }
        (_, Some(r)) => LinkRule::Radius(r),
        (k, None) => LinkRule::Nearest(k.unwrap_or(6)),
    };
    let types = match types {
        "family" => TypeRule::Family,
        "link" => TypeRule::PerLink,
        other => {
            return Err(PyValueError::new_err(format!(
                "types: `{other}` is not \"family\" or \"link\""
            )))
        }
    };
    if !(family_tolerance.is_finite() && family_tolerance >= 0.0) {
        return Err(PyValueError::new_err(format!(
            "family_tolerance: {family_tolerance} is not a tolerance >= 0"
        )));
    }
    let options = MarkerScene {
        links,
        types,
        width,
        total_mass,
        dt,
        gravity: gravity.map_or([0.0, -9.81, 0.0], |g| [g.0, g.1, g.2]),
        still,
        family_tolerance,
    };
    let scene = py.detach(|| build(&obs, &options)).map_err(to_py)?;
    Ok(Scene::from_core(scene))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(scene_from_markers, m)?)?;
    Ok(())
}
