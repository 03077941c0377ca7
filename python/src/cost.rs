//! Costs (SPEC §3): `cordis.cost` for one report, `cordis.Objective` as the fast path for an
//! external optimiser (compiled once, then a call per parameter vector).
//!
//! `Objective.__call__` keeps the GIL on the precomputed linear path (its O(θ²) evaluation is
//! shorter than releasing and taking back the GIL) and releases it otherwise.

use std::hash::Hasher;
use std::sync::{Arc, Mutex};

use cordis_core::{Scene as CoreScene, Trajectory};
use cordis_es::cost::{CostKind, CostScratch, Objective as CoreObjective};
use numpy::{IntoPyArray, PyArray1, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::errors::cost_to_py;
use crate::scene::Scene;
use crate::trajectory::{as_f64_array, c_order_values, shape_text, traj_from_py};

/// Everything a cost says about one parameter vector.
#[pyclass(frozen, module = "cordis", name = "CostReport")]
pub struct CostReport {
    /// The global cost C = Σ_i c_i (m²; for `harmonic`, 1 / Σ 1/(e + ε)).
    #[pyo3(get)]
    total: f64,
    /// sqrt(Σ e / terms): RMS prediction error of a particle, m (`inf` when diverged).
    #[pyo3(get)]
    rmse: f64,
    /// Local cost c_i of every particle, float64 `(N,)` (0 for fixed particles).
    #[pyo3(get)]
    per_particle: Py<PyArray1<f64>>,
    /// Number of (predicted frame, free particle) pairs.
    #[pyo3(get)]
    terms: usize,
    /// The cost kind, as text (`short`, `horizon:5`…).
    #[pyo3(get)]
    kind: String,
}

#[pymethods]
impl CostReport {
    fn __repr__(&self, py: Python<'_>) -> String {
        let per: Vec<f64> = self.per_particle.bind(py).to_vec().unwrap_or_default();
        let worst = per
            .iter()
            .enumerate()
            .fold((0usize, f64::NEG_INFINITY), |b, (i, &c)| {
                if c > b.1 {
                    (i, c)
                } else {
                    b
                }
            });
        format!(
            "CostReport(kind='{}', total={:.6e}, rmse={:.6e} m, terms={}, worst particle {} \
             (c={:.3e}))",
            self.kind, self.total, self.rmse, self.terms, worst.0, worst.1
        )
    }
}

fn report_to_py(py: Python<'_>, r: cordis_es::cost::CostReport, kind: &CostKind) -> CostReport {
    CostReport {
        total: r.total,
        rmse: r.rmse,
        per_particle: r.per_particle.into_pyarray(py).unbind(),
        terms: r.terms,
        kind: kind.to_string(),
    }
}

fn parse_kind(kind: &str) -> PyResult<CostKind> {
    kind.parse::<CostKind>().map_err(cost_to_py)
}

/// A cost compiled once for a scene, an observed trajectory and a kind; call it on parameter
/// vectors laid out as `param_names()` (every type's parameters in catalogue order, then one
/// mass per particle, then gravity). This is the fast path for an external optimiser: a call
/// on a linear-in-parameter scene's short cost costs a few microseconds whatever the size of
/// the trajectory.
///
/// >>> truth = cordis.example("rigid")
/// >>> f = cordis.Objective(truth, truth.simulate(100))
/// >>> p = f.param_vector()
/// >>> f(p) < 1e-20
/// True
/// >>> costs = f.evaluate_batch(np.stack([p, 1.1 * p]))   # parallel, GIL released
#[pyclass(frozen, module = "cordis", name = "Objective")]
pub struct Objective {
    inner: Arc<CoreObjective>,
    scene: CoreScene,
    /// Buffers reused by single calls; a call that finds them busy (another thread) makes its
    /// own.
    scratch: Mutex<Option<CostScratch>>,
}

impl Objective {
    fn with_scratch<R>(&self, f: impl FnOnce(&mut CostScratch) -> R) -> R {
        if let Ok(mut guard) = self.scratch.try_lock() {
            let s = guard.get_or_insert_with(|| self.inner.scratch());
            return f(s);
        }
        f(&mut self.inner.scratch())
    }
}

/// A 1-D float64 parameter vector from any array-like (copied only when it is not already a
/// contiguous float64 vector).
fn params_from_py(x: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
    let a = as_f64_array(x, "params")?;
    if a.ndim() != 1 {
        return Err(PyValueError::new_err(format!(
            "params: expected a vector (1-D), got shape {}",
            shape_text(a.shape())
        )));
    }
    c_order_values(&a)
}

#[pymethods]
impl Objective {
    /// Compiles the cost of `kind` (`short`, `horizon:H`, `long`, `progressive[:G[:START]]`,
    /// `harmonic[:EPS]`, `static`: equilibrium poses) for `scene` and the observed positions
    /// `traj` `(T, N, 3)`, m.
    /// `generation` sets the progressive horizon's generation counter (other kinds ignore it).
    /// `precompute=False` forces the generic path (for checks and benchmarks) where the short
    /// cost could be a precomputed quadratic form.
    #[new]
    #[pyo3(signature = (scene, traj, kind = "short", generation = 0, precompute = true))]
    fn new(
        py: Python<'_>,
        scene: &Scene,
        traj: &Bound<'_, PyAny>,
        kind: &str,
        generation: usize,
        precompute: bool,
    ) -> PyResult<Self> {
        let kind = parse_kind(kind)?;
        let traj = traj_from_py(traj, "traj")?;
        let core = scene.core();
        let mut inner = py
            .detach(|| CoreObjective::new(&core, &traj, kind))
            .map_err(cost_to_py)?;
        inner.set_generation(generation);
        inner.set_linear(precompute);
        Ok(Objective {
            inner: Arc::new(inner),
            scene: (*core).clone(),
            scratch: Mutex::new(None),
        })
    }

    /// The global cost of `params` (a float64 vector of `num_params` values).
    fn __call__(&self, py: Python<'_>, params: &Bound<'_, PyAny>) -> PyResult<f64> {
        // Fast path: a contiguous float64 vector is read in place, no copy.
        if let Ok(ro) = params
            .cast::<PyArray1<f64>>()
            .map_err(PyErr::from)
            .and_then(|a| {
                a.try_readonly()
                    .map_err(|e| PyValueError::new_err(e.to_string()))
            })
        {
            if let Ok(p) = ro.as_slice() {
                if self.inner.uses_linear(p) {
                    return self
                        .with_scratch(|s| self.inner.total(p, s))
                        .map_err(cost_to_py);
                }
            }
        }
        let p = params_from_py(params)?;
        let inner = &self.inner;
        py.detach(|| self.with_scratch(|s| inner.total(&p, s)))
            .map_err(cost_to_py)
    }

    /// Cost, RMSE, local costs and term count of `params`.
    fn report(&self, py: Python<'_>, params: &Bound<'_, PyAny>) -> PyResult<CostReport> {
        let p = params_from_py(params)?;
        let r = py.detach(|| self.inner.report(&p)).map_err(cost_to_py)?;
        Ok(report_to_py(py, r, &self.inner.kind()))
    }

    /// Global costs of every row of `params` `(M, num_params)`, float64 `(M,)`: evaluated in
    /// parallel (rayon) with the GIL released; equal to calling the objective on each row.
    fn evaluate_batch<'py>(
        &self,
        py: Python<'py>,
        params: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let a = as_f64_array(params, "params")?;
        let shape = a.shape().to_vec();
        if shape.len() != 2 {
            return Err(PyValueError::new_err(format!(
                "params: expected a matrix (M, {}) with one parameter vector per row, got shape {}",
                self.inner.param_len(),
                shape_text(&shape)
            )));
        }
        let pop = c_order_values(&a)?;
        let mut out = vec![0.0; shape[0]];
        let inner = &self.inner;
        py.detach(|| inner.evaluate_batch(&pop, &mut out))
            .map_err(cost_to_py)?;
        Ok(out.into_pyarray(py))
    }

    /// The scene's own parameter vector, float64 `(num_params,)` (unknowns at their starting
    /// value).
    fn param_vector<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.scene.param_values().into_pyarray(py)
    }

    /// The name of every slot of a parameter vector: `types.NAME.PARAM`, `particles[i].mass`,
    /// `gravity[k]`.
    fn param_names(&self) -> Vec<String> {
        param_names(&self.scene)
    }

    /// Length of the parameter vectors.
    #[getter]
    fn num_params(&self) -> usize {
        self.inner.param_len()
    }

    /// Number of observed frames T.
    #[getter]
    fn frames(&self) -> usize {
        self.inner.frames()
    }

    /// Number of particles N.
    #[getter]
    fn particles(&self) -> usize {
        self.inner.particles()
    }

    /// Number of (predicted frame, free particle) pairs: rmse = sqrt(cost / terms).
    #[getter]
    fn terms(&self) -> usize {
        self.inner.terms()
    }

    /// The cost kind, as text.
    #[getter]
    fn kind(&self) -> String {
        self.inner.kind().to_string()
    }

    /// True when the short cost is precomputed as a quadratic form (scene linear in its
    /// parameters): calls then cost O(θ²), independent of N and T.
    #[getter]
    fn linear(&self) -> bool {
        self.inner.uses_linear(&self.scene.param_values())
    }

    fn __repr__(&self) -> String {
        format!(
            "Objective(kind='{}', params={}, frames={}, particles={}, linear={})",
            self.inner.kind(),
            self.inner.param_len(),
            self.inner.frames(),
            self.inner.particles(),
            if self.inner.linear().is_some() {
                "True"
            } else {
                "False"
            }
        )
    }
}

/// Names of the slots of a scene's parameter vector (`cordis_core::ParamLayout` order).
pub fn param_names(scene: &CoreScene) -> Vec<String> {
    let mut names = Vec::with_capacity(scene.param_layout().len);
    for t in &scene.types {
        for k in 0..t.params.len() {
            names.push(format!("types.{}.{}", t.name, t.param_name(k)));
        }
    }
    names.extend((0..scene.particles.len()).map(|i| format!("particles[{i}].mass")));
    names.extend((0..3).map(|k| format!("gravity[{k}]")));
    names
}

/// Objectives that `cordis.cost` compiled recently, most recent last.
static CACHE: Mutex<Vec<CacheEntry>> = Mutex::new(Vec::new());
const CACHE_SIZE: usize = 4;

struct CacheEntry {
    scene: CoreScene,
    traj: TrajKey,
    kind: String,
    objective: Arc<CoreObjective>,
}

/// Shape and a 64-bit hash of a trajectory's values: a different trajectory (even one value in
/// one frame) gives another key.
#[derive(Clone, Copy, PartialEq, Eq)]
struct TrajKey(usize, usize, u64);

impl TrajKey {
    fn of(t: &Trajectory) -> Self {
        // FxHash-style: each step (rotate, xor the word, multiply by an odd constant) is a
        // bijection of the state, so changing any one value always changes the hash.
        let mut h = FxLike(0);
        for v in t.as_flat() {
            h.write_u64(v.to_bits());
        }
        TrajKey(t.frames(), t.particles(), h.finish())
    }
}

struct FxLike(u64);

impl Hasher for FxLike {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for b in bytes {
            self.write_u64(u64::from(*b));
        }
    }
    fn write_u64(&mut self, w: u64) {
        self.0 = (self.0.rotate_left(5) ^ w).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
}

fn cached_objective(
    scene: &CoreScene,
    traj: &Trajectory,
    kind: CostKind,
) -> Result<Arc<CoreObjective>, cordis_es::CostError> {
    let key = TrajKey::of(traj);
    let kind_text = kind.to_string();
    let lock = || CACHE.lock().unwrap_or_else(|e| e.into_inner());
    {
        let mut cache = lock();
        if let Some(at) = cache
            .iter()
            .position(|e| e.traj == key && e.kind == kind_text && e.scene == *scene)
        {
            let entry = cache.remove(at);
            let objective = entry.objective.clone();
            cache.push(entry);
            return Ok(objective);
        }
    }
    // Compiled outside the lock: another thread's lookup need not wait for it.
    let objective = Arc::new(CoreObjective::new(scene, traj, kind)?);
    let mut cache = lock();
    if cache.len() >= CACHE_SIZE {
        cache.remove(0);
    }
    cache.push(CacheEntry {
        scene: scene.clone(),
        traj: key,
        kind: kind_text,
        objective: objective.clone(),
    });
    Ok(objective)
}

/// The cost of `kind` of `scene` (at its own parameter values) against the observed positions
/// `traj` `(T, N, 3)`, m. The compiled cost of the last few (scene, trajectory, kind) triples is
/// kept, so repeated calls skip compiling; an optimiser should still use `Objective`, which
/// also skips converting and hashing the trajectory.
///
/// >>> scene = cordis.example("rigid")
/// >>> cordis.cost(scene, scene.simulate(100)).total < 1e-20
/// True
#[pyfunction]
#[pyo3(signature = (scene, traj, kind = "short"))]
pub fn cost(
    py: Python<'_>,
    scene: &Scene,
    traj: &Bound<'_, PyAny>,
    kind: &str,
) -> PyResult<CostReport> {
    let kind = parse_kind(kind)?;
    let traj = traj_from_py(traj, "traj")?;
    let core = scene.core();
    let report = py
        .detach(|| cached_objective(&core, &traj, kind)?.report(&core.param_values()))
        .map_err(cost_to_py)?;
    Ok(report_to_py(py, report, &kind))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<CostReport>()?;
    m.add_class::<Objective>()?;
    m.add_function(wrap_pyfunction!(cost, m)?)?;
    Ok(())
}
