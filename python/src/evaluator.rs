//! Evaluating populations elsewhere: `PopulationEvaluator`, the compiled problem a remote worker
//! (a Ray actor) holds, and `PyEvaluator`, the [`Evaluator`] that hands each population of a
//! `cordis.identify` run to a Python executor (`executor="ray"` or any object with the same
//! protocol).
//!
//! Only genomes (internal coordinates, `dim` values per individual) and costs cross the
//! boundary: the scene and the trajectory are sent once, when the executor builds its workers.
//! Both sides compile the same `Problem` from the same scene JSON, trajectory and cost kind, so
//! a genome's cost is bit-identical wherever it is computed.

use cordis_es::evaluator::Evaluator;
use cordis_es::problem::Problem;
use cordis_es::CostError;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyUntypedArrayMethods};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyTuple;
use std::sync::Mutex;

use crate::errors::cost_to_py;
use crate::scene::Scene;
use crate::trajectory::{as_f64_array, c_order_values, shape_text, traj_from_py};

/// An identification problem compiled once — `scene` (with unknowns), the observed `traj`
/// `(T, N, 3)` in m and the `cost` kind — that evaluates populations of genomes: what a
/// remote worker of an executor holds (`cordis.RayExecutor` builds one per Ray actor).
///
/// Genomes are the strategies' internal coordinates (log for wide positive boxes), one row of
/// `dim` values per individual; the costs are those `cordis.identify` computes locally, bit for
/// bit. `threads`: this evaluator's own thread pool (default 1: one worker per core).
#[pyclass(module = "cordis", name = "PopulationEvaluator")]
pub struct PopulationEvaluator {
    problem: Problem,
    pool: rayon::ThreadPool,
}

#[pymethods]
impl PopulationEvaluator {
    #[new]
    #[pyo3(signature = (scene, traj, cost = "short", threads = 1))]
    fn new(scene: &Scene, traj: &Bound<'_, PyAny>, cost: &str, threads: usize) -> PyResult<Self> {
        if threads == 0 {
            return Err(PyValueError::new_err("threads: must be 1 or more"));
        }
        let kind = cost.parse().map_err(cost_to_py)?;
        let py = traj.py();
        let traj = traj_from_py(traj, "traj")?;
        let scene = scene.core().clone();
        let problem = py
            .detach(|| Problem::new(&scene, &traj, kind))
            .map_err(cost_to_py)?;
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .map_err(|e| PyRuntimeError::new_err(format!("threads: {e}")))?;
        Ok(PopulationEvaluator { problem, pool })
    }

    /// Number of unknowns: the length of a genome.
    #[getter]
    fn dim(&self) -> usize {
        self.problem.dim()
    }

    /// Number of particles: the length of a row of local costs.
    #[getter]
    fn num_particles(&self) -> usize {
        self.problem.num_particles
    }

    /// Costs of the genomes `(M, dim)` at run generation `generation` (a progressive cost's
    /// horizon grows with it): float64 `(M,)`, +inf for a diverging model; with `local=True`,
    /// `(costs, local)` where `local` `(M, num_particles)` holds each particle's share, m².
    /// Parallel on this evaluator's threads, GIL released.
    #[pyo3(signature = (genomes, generation = 0, local = false))]
    fn evaluate<'py>(
        &mut self,
        py: Python<'py>,
        genomes: &Bound<'py, PyAny>,
        generation: usize,
        local: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        let a = as_f64_array(genomes, "genomes")?;
        let shape = a.shape().to_vec();
        let dim = self.problem.dim();
        if shape.len() != 2 || shape[1] != dim {
            return Err(PyValueError::new_err(format!(
                "genomes: expected shape (M, {dim}), got {}",
                shape_text(&shape)
            )));
        }
        let flat = c_order_values(&a)?;
        let (m, n) = (shape[0], self.problem.num_particles);
        self.problem.objective.set_generation(generation);
        let mut costs = vec![f64::INFINITY; m];
        let mut locals = if local { vec![0.0; m * n] } else { Vec::new() };
        let (problem, pool) = (&self.problem, &self.pool);
        py.detach(|| {
            pool.install(|| {
                problem.evaluate_population(&flat, &mut costs, local.then_some(&mut locals[..]))
            })
        });
        let costs = costs.into_pyarray(py).into_any();
        if !local {
            return Ok(costs);
        }
        let locals = Array2::from_shape_vec((m, n), locals)
            .map_err(|e| PyRuntimeError::new_err(format!("local costs: {e}")))?;
        Ok(PyTuple::new(py, [costs, locals.into_pyarray(py).into_any()])?.into_any())
    }
}

/// A Python executor's evaluator (`executor.evaluator(scene_json, traj, cost)`) as the run's
/// [`Evaluator`]: called as `evaluator(genomes (M, dim), generation, local)` with the GIL taken
/// on the run's worker thread, once per population; returns the costs `(M,)`, or `(costs,
/// local (M, N))` when `local` is true.
pub struct PyEvaluator {
    callable: Py<PyAny>,
    /// The first exception the executor raised: `identify` raises it again as it is.
    error: Mutex<Option<PyErr>>,
}

impl PyEvaluator {
    pub fn new(callable: Py<PyAny>) -> Self {
        PyEvaluator {
            callable,
            error: Mutex::new(None),
        }
    }

    /// The exception that stopped the run, if the executor raised one.
    pub fn take_error(&self) -> Option<PyErr> {
        self.error.lock().unwrap_or_else(|p| p.into_inner()).take()
    }
}

impl Evaluator for PyEvaluator {
    fn evaluate(
        &self,
        problem: &Problem,
        genomes: &[f64],
        costs: &mut [f64],
        local: Option<&mut [f64]>,
    ) -> Result<(), CostError> {
        let (m, dim, n) = (costs.len(), problem.dim(), problem.num_particles);
        let generation = problem.objective.generation();
        Python::attach(|py| {
            let run = || -> PyResult<()> {
                let g = Array2::from_shape_vec((m, dim), genomes.to_vec())
                    .map_err(|e| PyRuntimeError::new_err(format!("genomes: {e}")))?;
                let out = self
                    .callable
                    .call1(py, (g.into_pyarray(py), generation, local.is_some()))?;
                let out = out.bind(py);
                let (c, l) = match &local {
                    Some(_) => {
                        let (c, l): (Bound<'_, PyAny>, Bound<'_, PyAny>) = out.extract()?;
                        (c, Some(l))
                    }
                    None => (out.clone(), None),
                };
                copy_into(&c, costs, &[m], "costs")?;
                if let (Some(l), Some(dst)) = (l, local) {
                    copy_into(&l, dst, &[m, n], "local costs")?;
                }
                Ok(())
            };
            run().map_err(|e| {
                let text = format!("executor: {}", describe(py, &e));
                // The exception itself is raised again by `identify`; a copy rides as the
                // error's source.
                let source = e.clone_ref(py);
                self.error
                    .lock()
                    .unwrap_or_else(|p| p.into_inner())
                    .get_or_insert(e);
                CostError::Evaluation {
                    message: text,
                    source: Some(Box::new(source)),
                }
            })
        })
    }
}

/// `src` (an array-like of shape `shape`) into `dst`.
fn copy_into(src: &Bound<'_, PyAny>, dst: &mut [f64], shape: &[usize], what: &str) -> PyResult<()> {
    let a = as_f64_array(src, what)?;
    if a.shape() != shape {
        return Err(PyValueError::new_err(format!(
            "{what}: expected shape {}, got {}",
            shape_text(shape),
            shape_text(a.shape())
        )));
    }
    dst.copy_from_slice(&c_order_values(&a)?);
    Ok(())
}

/// `TypeName: message` of a Python exception.
fn describe(py: Python<'_>, e: &PyErr) -> String {
    let name = e
        .get_type(py)
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "Exception".into());
    format!("{name}: {}", e.value(py))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PopulationEvaluator>()?;
    Ok(())
}
