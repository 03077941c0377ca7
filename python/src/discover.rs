//! Structure discovery (`cordis_es::discover`): `cordis.discover(traj, dt, total_mass=…)`
//! proposes a spring network — links, masses, gravity, a catalogue of types — from positions
//! alone, with a score per link.

use std::sync::atomic::{AtomicBool, Ordering};

use cordis_es::discover::identify::{identify_discovered_until, Identified};
use cordis_es::discover::link_test::{link_test as core_link_test, LinkTestReport};
use cordis_es::discover::{discover as core_discover, DiscoverOptions, Discovery, Kinds};
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;

use crate::errors::cost_to_py;
use crate::scene::Scene;
use crate::trajectory::{check_dt, traj_from_py};

/// What `cordis.discover` found.
#[pyclass(frozen, module = "cordis", name = "DiscoverResult")]
pub struct DiscoverResult {
    /// The proposed scene (every value known; initial state from the first frames).
    #[pyo3(get)]
    scene: Py<Scene>,
    /// Per link of `scene` (same order): `particles`, `kind` (`spring`, `anchor`, `damper`),
    /// `type`, this link's own `stiffness`,
    /// `rest_length`, `damping` and their standard errors (`…_se`), and its `score` (Wald
    /// statistic: cost increase when removed over the noise floor) and `threshold`.
    #[pyo3(get)]
    links: Py<PyAny>,
    /// The rejected candidates closest to the threshold: `particles`, `score`, `threshold`.
    #[pyo3(get)]
    near_misses: Py<PyAny>,
    /// Candidate radius, m.
    #[pyo3(get)]
    radius: f64,
    /// Number of candidate pairs.
    #[pyo3(get)]
    candidates: usize,
    /// Short cost of the proposed scene on the trajectory (m²) and its rmse (m).
    #[pyo3(get)]
    cost: f64,
    #[pyo3(get)]
    rmse: f64,
    /// The exact solver's report of the catalogue refit (dict).
    #[pyo3(get)]
    solver: Py<PyAny>,
    /// How the answer was reached.
    #[pyo3(get)]
    notes: Vec<String>,
    /// The position noise used, m: given, or estimated when `noise_estimated`.
    #[pyo3(get)]
    noise_level: f64,
    #[pyo3(get)]
    noise_estimated: bool,
    /// What the data cannot decide, by name: `what` (`masses`, `gravity`…), `particles`,
    /// `links`, `why` (also raised as warnings).
    #[pyo3(get)]
    undetermined: Py<PyAny>,
    /// With `identify=True`: the identified scene (every value known, the estimated initial
    /// state), else None.
    #[pyo3(get)]
    identified: Option<Py<Scene>>,
    /// With `identify=True`: `params` (each unknown's `name`, `discovered`, `value`, `stderr`,
    /// `low`, `high`, `at_bound`), `end` and `converged` (the estimator's own status), `sigma`,
    /// `noise_level`, `undetermined`, `gravity_fitted`, `reference`…, as the CLI's summary
    /// `identify`; else None.
    #[pyo3(get)]
    identification: Option<Py<PyAny>>,
    /// With `link_test=True`: whether it decided the graph (`applied`: false, with a warning,
    /// when its fit stayed above the noise), the output-error link test's fit (`end`, `converged`, `sigma`,
    /// `noise_level`, `variables`, `iterations`), `kept`, and every candidate pair's verdict
    /// (`pairs`: `particles`, `kind`, estimates and standard errors, `score`, `threshold`,
    /// `kept`), as the CLI's summary `link_test`; else None.
    #[pyo3(get)]
    link_test: Option<Py<PyAny>>,
}

#[pymethods]
impl DiscoverResult {
    fn __repr__(&self, py: Python<'_>) -> String {
        let s = self.scene.borrow(py);
        let core = s.core();
        format!(
            "DiscoverResult({} particles, {} links of {} types from {} candidates, rmse={:.3e} m)",
            core.num_particles(),
            core.links.len(),
            core.types.len(),
            self.candidates,
            self.rmse
        )
    }
}

fn to_py(
    py: Python<'_>,
    d: Discovery,
    id: Option<Identified>,
    tested: Option<LinkTestReport>,
) -> PyResult<DiscoverResult> {
    crate::identify::warn_all(py, &d.warnings())?;
    // The identification's warnings, computed once: raised, and kept in its summary.
    let summary = match &id {
        Some(id) => {
            let warnings = id.warnings();
            crate::identify::warn_all(py, &warnings)?;
            Some(id.to_json(&warnings))
        }
        None => None,
    };
    let json =
        |v: serde_json::Value| -> PyResult<Py<PyAny>> { Ok(crate::json::to_py(py, &v)?.unbind()) };
    Ok(DiscoverResult {
        links: json(serde_json::to_value(&d.links).unwrap_or_default())?,
        near_misses: json(serde_json::to_value(&d.near_misses).unwrap_or_default())?,
        solver: json(serde_json::to_value(&d.solver).unwrap_or_default())?,
        undetermined: json(serde_json::to_value(&d.undetermined).unwrap_or_default())?,
        scene: Py::new(py, Scene::from_core(d.scene))?,
        radius: d.radius,
        candidates: d.candidates,
        cost: d.cost,
        rmse: d.rmse,
        noise_level: d.noise_level,
        noise_estimated: d.estimated_noise,
        notes: d.notes,
        identification: summary
            .map(|v| {
                let dict = json(v)?;
                infinities_as_floats(dict.bind(py))?;
                Ok::<_, PyErr>(dict)
            })
            .transpose()?,
        identified: id
            .map(|id| Py::new(py, Scene::from_core(id.scene)))
            .transpose()?,
        link_test: tested
            .map(|t| json(serde_json::to_value(t).unwrap_or_default()))
            .transpose()?,
    })
}

/// Proposes a spring network from positions alone: `traj` `(T, N, 3)` (m) sampled every `dt`
/// s. Give `total_mass` (kg, of the moving particles) or every particle's `masses`: masses and
/// stiffnesses share one scale. `max_range` (m) bounds the candidate pairs (default 2.2 × the
/// median nearest-neighbour distance); `noise_level` (m) > 0 smooths the positions first
/// (default `None`: estimated from the data, with a warning when they look noisy; 0:
/// noiseless);
/// `threshold_scale` multiplies the selection threshold; `type_tolerance` is the relative
/// tolerance under which two links are of one type; `gravity` (m/s², `[x, y, z]`) when known,
/// else it is estimated; `kinds` (e.g. `["spring", "damper"]`) the link kinds looked for
/// (`spring`, `anchor`: to a fixed particle, `damper`: isotropic; default all three; an unknown
/// name is a `ValueError`). `identify=True` then fits the discovered network by output-error
/// on the same motion (`cordis discover --identify`): `res.identified` (Scene) and
/// `res.identification` (dict); Ctrl-C during that fit raises `KeyboardInterrupt` whose
/// `result` is the discovery without it. `link_test=True` first tests every candidate pair again by
/// output error (`cordis discover --link-test`: each pair a spring of its own, kept when its
/// stiffness stands clear of 0 against its standard error; slower, more powerful under
/// noise): the graph is then the test's, its fit in `res.link_test` (dict). Each link's `kind` is in `res.links`. `res.undetermined` names what the data cannot decide (also raised as
/// warnings). See docs/discover.md.
///
/// >>> truth = cordis.random_network(1, 12, 3)
/// >>> traj = truth.simulate(300)
/// >>> res = cordis.discover(traj, truth.dt, total_mass=12.3)   # doctest: +SKIP
#[pyfunction]
#[pyo3(signature = (traj, dt, total_mass = None, masses = None, max_range = None, noise_level = None, threshold_scale = 1.0, type_tolerance = 1e-3, gravity = None, kinds = None, identify = false, link_test = false))]
#[allow(clippy::too_many_arguments)]
pub fn discover(
    py: Python<'_>,
    traj: &Bound<'_, PyAny>,
    dt: f64,
    total_mass: Option<f64>,
    masses: Option<Vec<f64>>,
    max_range: Option<f64>,
    noise_level: Option<f64>,
    threshold_scale: f64,
    type_tolerance: f64,
    gravity: Option<[f64; 3]>,
    kinds: Option<Vec<String>>,
    identify: bool,
    link_test: bool,
) -> PyResult<DiscoverResult> {
    let dt = check_dt(dt, "dt")?;
    let traj = traj_from_py(traj, "traj")?;
    let kinds = match &kinds {
        Some(k) => Some(Kinds::parse(k).map_err(cost_to_py)?),
        None => None,
    };
    let opt = DiscoverOptions {
        total_mass,
        masses,
        max_range,
        noise_level,
        threshold_scale,
        type_tolerance,
        gravity,
        kinds,
        style: cordis_es::session::Style::Python,
    };
    let interrupt = AtomicBool::new(false);
    let halt = || interrupt.load(Ordering::Relaxed);
    let work = || -> Result<_, cordis_es::CostError> {
        let d = core_discover(&traj, dt, &opt)?;
        let (d, tested) = match link_test {
            true => {
                let t = core_link_test(&traj, &d, &opt)?;
                (t.discovery, Some(t.report))
            }
            false => (d, None),
        };
        let id = match identify {
            true => identify_discovered_until(&traj, &d, &opt, &halt)?,
            false => None,
        };
        Ok((d, id, tested))
    };
    let (outcome, signal) = crate::signals::with_signals(py, &interrupt, work);
    let (d, id, tested) = outcome
        .map_err(|_| PyRuntimeError::new_err("discover: the run panicked (a bug in cordis)"))?
        .map_err(cost_to_py)?;
    let result = to_py(py, d, id, tested)?;
    match signal {
        // Ctrl-C: whatever was done rides on the exception (the discovery, and the
        // identification when it had finished; `identified` None when it was stopped).
        Some(e) => {
            e.value(py).setattr("result", Py::new(py, result)?)?;
            Err(e)
        }
        None => Ok(result),
    }
}

/// A seed-generated random spring network of `masses` particles and `types` spring types
/// (cordis_core::examples::random_network): particle 0 fixed, gravity, random velocities.
#[pyfunction]
pub fn random_network(seed: u64, masses: usize, types: usize) -> Scene {
    Scene::from_core(cordis_core::examples::random_network(seed, masses, types))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<DiscoverResult>()?;
    m.add_function(wrap_pyfunction!(discover, m)?)?;
    m.add_function(wrap_pyfunction!(random_network, m)?)?;
    Ok(())
}

/// The identification's rows with the JSON line's `"inf"` (JSON has no infinity: a not
/// determined unknown's standard error, a log interval's end) back as Python floats, as
/// `identify`'s `res.stderr` gives them: `stderr * 2` works on every row.
fn infinities_as_floats(identification: &Bound<'_, PyAny>) -> PyResult<()> {
    for row in identification.get_item("params")?.try_iter()? {
        let row = row?;
        for key in ["stderr", "low", "high"] {
            let value = row.get_item(key)?;
            if let Ok(text) = value.extract::<String>() {
                if let Ok(x) = text.parse::<f64>() {
                    row.set_item(key, x)?;
                }
            }
        }
    }
    Ok(())
}
