//! `cordis.Scene`: a Cordis-Anima network (particles, link catalogue, links) and its time step.
//!
//! Immutable from Python (`frozen`): methods that change a scene (identification) return a new
//! one. That is also what lets `simulate` run without the GIL while other threads hold the
//! same scene.

use std::path::PathBuf;

use cordis_core::Scene as CoreScene;
use numpy::PyArray3;
use pyo3::exceptions::{PyMemoryError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString, PyTuple, PyType};

use crate::errors::to_py;
use crate::json;

/// A Cordis-Anima network: particles, a catalogue of link types and the links between
/// particles, with its time step `dt` (s) and `gravity` (m/s²). Read one with
/// `Scene.from_json` or `Scene.from_dict`; run it with `simulate`.
#[pyclass(frozen, eq, module = "cordis", name = "Scene")]
#[derive(Clone, PartialEq)]
pub struct Scene {
    inner: CoreScene,
}

impl Scene {
    pub fn from_core(inner: CoreScene) -> Self {
        Scene { inner }
    }

    pub fn core(&self) -> &CoreScene {
        &self.inner
    }
}

#[pymethods]
impl Scene {
    /// Reads a scene from JSON text (a `str` whose first non-blank character is `{`) or from a
    /// file (any other `str`, or an `os.PathLike`).
    #[classmethod]
    #[pyo3(signature = (path_or_text, /))]
    fn from_json(
        _cls: &Bound<'_, PyType>,
        py: Python<'_>,
        path_or_text: &Bound<'_, PyAny>,
    ) -> PyResult<Self> {
        let source = match path_or_text.cast::<PyString>() {
            Ok(s) => {
                let s = s.to_cow()?;
                if looks_like_json(&s) {
                    let text = s.into_owned();
                    return py
                        .detach(move || CoreScene::from_json_str(&text))
                        .map(Scene::from_core)
                        .map_err(to_py);
                }
                PathBuf::from(s.as_ref())
            }
            Err(_) => path_or_text.extract::<PathBuf>().map_err(|_| {
                PyTypeError::new_err(format!(
                    "path_or_text: expected JSON text, a path str or an os.PathLike, got {}",
                    path_or_text
                        .get_type()
                        .name()
                        .map(|n| n.to_string())
                        .unwrap_or_default()
                ))
            })?,
        };
        py.detach(move || CoreScene::from_json_path(&source))
            .map(Scene::from_core)
            .map_err(to_py)
    }

    /// Reads a scene from a dict shaped like the JSON format (`cordis-scene/1`). Numbers may be
    /// numpy scalars and vectors numpy arrays.
    #[classmethod]
    #[pyo3(signature = (d, /))]
    fn from_dict(_cls: &Bound<'_, PyType>, d: &Bound<'_, PyAny>) -> PyResult<Self> {
        let value = json::to_value(d)?;
        CoreScene::from_json_value(&value)
            .map(Scene::from_core)
            .map_err(to_py)
    }

    /// The scene as pretty-printed JSON text (`cordis-scene/1`), ending with a newline.
    fn to_json(&self) -> String {
        self.inner.to_json_string()
    }

    /// The scene as a dict of plain Python values (the JSON format's structure).
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json::to_py(py, &self.inner.to_json_value())
    }

    /// Simulates `frames` frames from the initial state and returns the positions as a
    /// C-contiguous float64 array of shape `(frames, num_particles, 3)`, in m; frame 0 is the
    /// initial positions. Raises `DivergedError` if the motion leaves the finite numbers.
    #[pyo3(signature = (frames))]
    fn simulate<'py>(
        &self,
        py: Python<'py>,
        frames: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray3<f64>>> {
        let n = self.inner.num_particles();
        let frames = frames_arg(frames)?;
        let frames = check_frames(frames, n).map_err(FramesError::into_py)?;
        let scene = &self.inner;
        let traj = py.detach(|| scene.simulate(frames)).map_err(to_py)?;
        crate::trajectory::traj_to_py(py, traj)
    }

    /// The stability report (`cordis check`): a dict with `max_stability_ratio` (the largest
    /// per-particle ratio q = (dt² K + 2 dt Z) / 4m to the bound, neighbours' motion counted),
    /// `stable` (q < 1: the scheme cannot explode), `worst_particle` (int or None),
    /// `local_max_ratio` (neighbours held fixed), `max_stable_dt` (s, or None when any step
    /// passes) and `per_particle` (a list of floats, None for fixed particles).
    fn stability<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let scene = &self.inner;
        let (r, dt_max) = py
            .detach(|| -> cordis_core::Result<_> {
                Ok((
                    cordis_core::stability(scene)?,
                    cordis_core::stability::max_stable_dt(scene)?,
                ))
            })
            .map_err(to_py)?;
        let d = PyDict::new(py);
        d.set_item("max_stability_ratio", r.max_ratio)?;
        d.set_item("stable", r.stable)?;
        d.set_item("worst_particle", r.worst_particle)?;
        d.set_item("local_max_ratio", r.local_max_ratio)?;
        d.set_item("max_stable_dt", dt_max)?;
        d.set_item("per_particle", r.per_particle)?;
        Ok(d)
    }

    /// Time step, s.
    #[getter]
    fn dt(&self) -> f64 {
        self.inner.dt
    }

    /// Acceleration of every free particle, m/s², as `(gx, gy, gz)`.
    #[getter]
    fn gravity(&self) -> (f64, f64, f64) {
        let [x, y, z] = self.inner.gravity;
        (x, y, z)
    }

    #[getter]
    fn num_particles(&self) -> usize {
        self.inner.num_particles()
    }

    /// Number of listed links (pairs of conditional types are found while simulating and are
    /// not counted).
    #[getter]
    fn num_links(&self) -> usize {
        self.inner.links.len()
    }

    /// Number of link types in the catalogue.
    #[getter]
    fn num_types(&self) -> usize {
        self.inner.types.len()
    }

    /// Names of the catalogue's link types, in file order.
    #[getter]
    fn type_names(&self) -> Vec<String> {
        self.inner.types.iter().map(|t| t.name.clone()).collect()
    }

    /// True when some parameter or mass is still to be identified (`{"min", "max"}`).
    #[getter]
    fn has_unknowns(&self) -> bool {
        self.inner.has_unknowns()
    }

    fn __repr__(&self) -> String {
        format!(
            "Scene(particles={}, types={}, links={}, dt={})",
            self.inner.num_particles(),
            self.inner.types.len(),
            self.inner.links.len(),
            self.inner.dt
        )
    }

    /// Pickles as its JSON text.
    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyTuple>)> {
        let ctor = slf.get_type().getattr("from_json")?;
        let args = PyTuple::new(slf.py(), [slf.get().to_json()])?;
        Ok((ctor, args))
    }

    /// Scenes are immutable: a copy is the scene itself.
    fn __copy__(slf: Bound<'_, Self>) -> Bound<'_, Self> {
        slf
    }

    fn __deepcopy__<'py>(slf: Bound<'py, Self>, _memo: &Bound<'py, PyAny>) -> Bound<'py, Self> {
        slf
    }
}

/// An integer frame count; one beyond i64 is a `ValueError` (not an `OverflowError`), as any
/// other absurd count is.
fn frames_arg(frames: &Bound<'_, PyAny>) -> PyResult<i64> {
    let index = frames.call_method0("__index__").map_err(|_| {
        PyTypeError::new_err(format!(
            "frames: expected an integer, got {}",
            frames
                .get_type()
                .name()
                .map(|n| n.to_string())
                .unwrap_or_default()
        ))
    })?;
    index
        .extract::<i64>()
        .map_err(|_| PyValueError::new_err(format!("frames: {index} is far too many")))
}

/// A `str` argument is JSON text when its first non-blank character opens an object.
pub fn looks_like_json(s: &str) -> bool {
    s.trim_start().starts_with('{')
}

/// Why a frame count was refused.
#[derive(Debug, PartialEq)]
pub enum FramesError {
    Negative(i64),
    Overflow(i64, usize),
    TooLarge(usize),
}

impl FramesError {
    fn into_py(self) -> PyErr {
        match self {
            FramesError::Negative(f) => {
                PyValueError::new_err(format!("frames: must be 0 or more, got {f}"))
            }
            FramesError::Overflow(f, n) => PyValueError::new_err(format!(
                "frames: {f} frames × {n} particles × 3 values do not fit in memory"
            )),
            FramesError::TooLarge(bytes) => PyMemoryError::new_err(format!(
                "frames: the trajectory needs {:.1} GiB, which cannot be allocated",
                bytes as f64 / (1u64 << 30) as f64
            )),
        }
    }
}

/// Checks a frame count from Python before the core allocates `frames × n × 3` f64 (an
/// allocation failure there would abort the interpreter): the memory is reserved once here and
/// released, so an impossible request becomes a `MemoryError` instead.
pub fn check_frames(frames: i64, n: usize) -> Result<usize, FramesError> {
    let f = usize::try_from(frames).map_err(|_| FramesError::Negative(frames))?;
    let values = f
        .checked_mul(n)
        .and_then(|v| v.checked_mul(3))
        .filter(|v| v.checked_mul(8).is_some_and(|b| b <= isize::MAX as usize))
        .ok_or(FramesError::Overflow(frames, n))?;
    let mut probe: Vec<f64> = Vec::new();
    probe
        .try_reserve_exact(values)
        .map_err(|_| FramesError::TooLarge(values * 8))?;
    Ok(f)
}
