//! `cordis.Scene`: a Cordis-Anima network (particles, link catalogue, links) and its time step.
//!
//! Editable from Python, one validated value at a time (`scene.dt = …`,
//! `scene.types["rib"]["stiffness"] = …`, `scene.particles[3].mass = …`; the views are in
//! `scene_edit.rs`): an edit that would make the scene invalid is refused with a `SceneError`
//! naming the place and leaves the scene unchanged, so a `Scene` is always simulable.
//!
//! The core scene sits behind an `RwLock<Arc<…>>`: a reader (simulate, identify, cost) takes
//! a snapshot (an `Arc` clone) and runs on it without the GIL; an edit made meanwhile by another
//! thread copies the scene first (`Arc::make_mut`), so a running simulation never sees a
//! half-edited scene. The lock is only held to swap values, never while Python code runs.

use std::path::PathBuf;
use std::sync::{Arc, PoisonError, RwLock, RwLockWriteGuard};

use cordis_core::Scene as CoreScene;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3};
use pyo3::exceptions::{PyMemoryError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString, PyTuple, PyType};

use crate::errors::to_py;
use crate::json;
use crate::scene_edit::{self, Particles, Types};

/// A Cordis-Anima network: particles, a catalogue of link types and the links between
/// particles, with its time step `dt` (s) and `gravity` (m/s²). Read one with
/// `Scene.from_json` or `Scene.from_dict`; run it with `simulate`; edit it in place
/// (`scene.dt`, `scene.gravity`, `scene.types[NAME][PARAM]`, `scene.particles[i].mass`,
/// `scene.masses`, `scene.positions`, `scene.velocities`), every edit validated: a refused
/// value raises `SceneError` naming the place and leaves the scene unchanged.
///
/// >>> scene = cordis.example("rigid")
/// >>> scene.dt = 0.005
/// >>> scene.types["brace"]["stiffness"] = 120.0
/// >>> scene.types["brace"]["damping"] = cordis.Unknown(0.0, 2.0)
/// >>> scene.particles[3].mass = 2.0
/// >>> print(scene)
/// Scene: 15 particles (0 fixed), 31 links, 10 types; dt = 0.005 s, …
/// >>> open("edited.json", "w").write(scene.to_json())
#[pyclass(frozen, eq, module = "cordis", name = "Scene")]
pub struct Scene {
    inner: RwLock<Arc<CoreScene>>,
}

impl PartialEq for Scene {
    fn eq(&self, other: &Self) -> bool {
        *self.core() == *other.core()
    }
}

impl Scene {
    pub fn from_core(inner: CoreScene) -> Self {
        Scene {
            inner: RwLock::new(Arc::new(inner)),
        }
    }

    /// A snapshot of the scene as it is now: later edits do not change it.
    pub fn core(&self) -> Arc<CoreScene> {
        self.inner
            .read()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }

    fn write(&self) -> RwLockWriteGuard<'_, Arc<CoreScene>> {
        self.inner.write().unwrap_or_else(PoisonError::into_inner)
    }

    /// Runs `edit` on the scene, then `check` (the validation of what `edit` touched); when
    /// either fails, restores the scene as it was and raises. `edit` returns the undo.
    pub fn edit<U: FnOnce(&mut CoreScene)>(
        &self,
        edit: impl FnOnce(&mut CoreScene) -> Result<U, cordis_core::CordisError>,
        check: impl FnOnce(&CoreScene) -> cordis_core::Result<()>,
    ) -> PyResult<()> {
        let result = {
            let mut guard = self.write();
            let scene = Arc::make_mut(&mut guard);
            match edit(scene) {
                Err(e) => Err(e),
                Ok(undo) => check(scene).inspect_err(|_| undo(scene)),
            }
        };
        // The guard is dropped before the exception is built (that runs Python code).
        result.map_err(to_py)
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
        self.core().to_json_string()
    }

    /// The scene as a dict of plain Python values (the JSON format's structure).
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json::to_py(py, &self.core().to_json_value())
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
        let scene = self.core();
        let n = scene.num_particles();
        let frames = frames_arg(frames)?;
        let frames = check_frames(frames, n).map_err(FramesError::into_py)?;
        let traj = py.detach(|| scene.simulate(frames)).map_err(to_py)?;
        crate::trajectory::traj_to_py(py, traj)
    }

    /// The stability report (`cordis check`): a dict with `max_stability_ratio` (the largest
    /// per-particle ratio q = (dt² K + 2 dt Z) / 4m to the bound, neighbours' motion counted),
    /// `stable` (q < 1: the scheme cannot explode), `worst_particle` (int or None),
    /// `local_max_ratio` (neighbours held fixed), `max_stable_dt` (s, or None when any step
    /// passes) and `per_particle` (a list of floats, None for fixed particles).
    fn stability<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let scene = self.core();
        let (r, dt_max) = py
            .detach(|| -> cordis_core::Result<_> {
                Ok((
                    cordis_core::stability(&scene)?,
                    cordis_core::stability::max_stable_dt(&scene)?,
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

    /// Time step, s. Settable: `scene.dt = 0.001` (a positive number, else `SceneError`).
    #[getter]
    fn dt(&self) -> f64 {
        self.core().dt
    }

    #[setter]
    fn set_dt(&self, dt: &Bound<'_, PyAny>) -> PyResult<()> {
        let dt = scene_edit::number(dt, "dt")?;
        self.edit(
            |s| {
                let old = std::mem::replace(&mut s.dt, dt);
                Ok(move |s: &mut CoreScene| s.dt = old)
            },
            CoreScene::validate_globals,
        )
    }

    /// Acceleration of every free particle, m/s², as `(gx, gy, gz)`. Settable from any
    /// sequence of 3 finite numbers: `scene.gravity = (0, 0, -9.81)`.
    #[getter]
    fn gravity(&self) -> (f64, f64, f64) {
        let [x, y, z] = self.core().gravity;
        (x, y, z)
    }

    #[setter]
    fn set_gravity(&self, g: &Bound<'_, PyAny>) -> PyResult<()> {
        let g = scene_edit::vec3(g, "gravity")?;
        self.edit(
            |s| {
                let old = std::mem::replace(&mut s.gravity, g);
                Ok(move |s: &mut CoreScene| s.gravity = old)
            },
            CoreScene::validate_globals,
        )
    }

    /// The particles as a sequence of views that write through:
    /// `scene.particles[3].mass = 2.0`, `scene.particles[-1].pos = (0, 0, 1)`.
    #[getter]
    fn particles(slf: &Bound<'_, Self>) -> Particles {
        Particles::new(slf.clone().unbind())
    }

    /// The catalogue as a mapping from type name to a view of its parameters that writes
    /// through: `scene.types["rib"]["stiffness"] = 120.0`, or
    /// `= cordis.Unknown(1.0, 1000.0)` to make it identifiable.
    #[getter]
    fn types(slf: &Bound<'_, Self>) -> Types {
        Types::new(slf.clone().unbind())
    }

    /// Masses, kg, float64 `(N,)`, read-only (an unknown mass shows its starting value).
    /// Assign a whole array to change them: `scene.masses = 2 * scene.masses`.
    #[getter]
    fn masses<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        let values: Vec<f64> = self
            .core()
            .particles
            .iter()
            .map(|p| p.mass.value())
            .collect();
        read_only(PyArray1::from_vec(py, values))
    }

    #[setter]
    fn set_masses(&self, m: &Bound<'_, PyAny>) -> PyResult<()> {
        let n = self.core().num_particles();
        let values = scene_edit::array(m, "masses", &[n])?;
        self.edit(
            |s| {
                let old: Vec<_> = s.particles.iter().map(|p| p.mass).collect();
                for (p, v) in s.particles.iter_mut().zip(values) {
                    p.mass = cordis_core::Param::Known(v);
                }
                Ok(move |s: &mut CoreScene| {
                    for (p, m) in s.particles.iter_mut().zip(old) {
                        p.mass = m;
                    }
                })
            },
            |s| (0..s.num_particles()).try_for_each(|i| s.validate_particle(i)),
        )
    }

    /// Initial positions x(0), m, float64 `(N, 3)`, read-only; assign an `(N, 3)` array to
    /// change them.
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        rows(py, &self.core(), |p| p.pos)
    }

    #[setter]
    fn set_positions(&self, x: &Bound<'_, PyAny>) -> PyResult<()> {
        self.set_rows(x, "positions", |p| &mut p.pos)
    }

    /// Initial velocities v(0), m/s, float64 `(N, 3)`, read-only; assign an `(N, 3)` array
    /// to change them.
    #[getter]
    fn velocities<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        rows(py, &self.core(), |p| p.vel)
    }

    #[setter]
    fn set_velocities(&self, v: &Bound<'_, PyAny>) -> PyResult<()> {
        self.set_rows(v, "velocities", |p| &mut p.vel)
    }

    #[getter]
    fn num_particles(&self) -> usize {
        self.core().num_particles()
    }

    /// Number of listed links (pairs of conditional types are found while simulating and are
    /// not counted).
    #[getter]
    fn num_links(&self) -> usize {
        self.core().links.len()
    }

    /// Number of link types in the catalogue.
    #[getter]
    fn num_types(&self) -> usize {
        self.core().types.len()
    }

    /// Names of the catalogue's link types, in file order.
    #[getter]
    fn type_names(&self) -> Vec<String> {
        self.core().types.iter().map(|t| t.name.clone()).collect()
    }

    /// True when some parameter or mass is still to be identified (`{"min", "max"}`).
    #[getter]
    fn has_unknowns(&self) -> bool {
        self.core().has_unknowns()
    }

    /// A copy whose positive known link-type parameters are unknown, each in a box `width`
    /// times wide (max/min) centred geometrically on its value (its start); zeros (an absent
    /// damping) stay known, as do a muscle's weights, gain and threshold and a TGR's tendon.
    ///
    /// >>> guess = cordis.example("rigid").with_unknowns(width=4.0)   # doctest: +SKIP
    #[pyo3(signature = (width = 4.0))]
    fn with_unknowns(&self, width: f64) -> PyResult<Scene> {
        cordis_core::from_markers::with_unknowns(&self.core(), width)
            .map(Scene::from_core)
            .map_err(crate::errors::to_py)
    }

    /// A copy on the clock of a take cropped to start at this scene's frame `k`: every
    /// signal's phase advanced by `k dt / period` (its TGRs' world's dt), so the TGRs are
    /// driven by the same commands at the take's frames. The tendons' start is the TGR types'
    /// `tendon_position` / `tendon_velocity`. SceneError (naming the signal) when TGRs in
    /// worlds of different time steps read one signal.
    ///
    /// >>> take_scene = cordis.example("tadpole").from_frame(150)   # doctest: +SKIP
    // Named as the Rust `Scene::from_frame` it wraps: "the scene as seen from frame k".
    #[allow(clippy::wrong_self_convention)]
    fn from_frame(&self, k: usize) -> PyResult<Scene> {
        self.core()
            .from_frame(k)
            .map(Scene::from_core)
            .map_err(crate::errors::to_py)
    }

    /// A copy of the scene (edits to one do not change the other).
    fn copy(&self) -> Scene {
        Scene::from_core((*self.core()).clone())
    }

    fn __repr__(&self) -> String {
        let s = self.core();
        let unknowns = scene_edit::count_unknowns(&s);
        format!(
            "Scene(particles={}, types={}, links={}, dt={}{})",
            s.num_particles(),
            s.types.len(),
            s.links.len(),
            s.dt,
            if unknowns > 0 {
                format!(", unknowns={unknowns}")
            } else {
                String::new()
            }
        )
    }

    /// A readable summary: sizes, dt, gravity, each type with its parameters and link count,
    /// the masses.
    fn __str__(&self, py: Python<'_>) -> PyResult<String> {
        scene_edit::summary(py, &self.core())
    }

    /// Pickles as its JSON text.
    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyTuple>)> {
        let ctor = slf.get_type().getattr("from_json")?;
        let args = PyTuple::new(slf.py(), [slf.get().to_json()])?;
        Ok((ctor, args))
    }

    /// A copy (scenes are editable): shares nothing with the original.
    fn __copy__(&self) -> Scene {
        self.copy()
    }

    fn __deepcopy__(&self, _memo: &Bound<'_, PyAny>) -> Scene {
        self.copy()
    }
}

impl Scene {
    /// Sets one 3-vector per particle (`positions`, `velocities`) from an `(N, 3)` array.
    fn set_rows(
        &self,
        x: &Bound<'_, PyAny>,
        what: &str,
        field: fn(&mut cordis_core::Particle) -> &mut [f64; 3],
    ) -> PyResult<()> {
        let n = self.core().num_particles();
        let values = scene_edit::array(x, what, &[n, 3])?;
        self.edit(
            |s| {
                let mut old = Vec::with_capacity(n);
                for (p, row) in s.particles.iter_mut().zip(values.chunks_exact(3)) {
                    old.push(std::mem::replace(field(p), [row[0], row[1], row[2]]));
                }
                Ok(move |s: &mut CoreScene| {
                    for (p, o) in s.particles.iter_mut().zip(old) {
                        *field(p) = o;
                    }
                })
            },
            |s| (0..s.num_particles()).try_for_each(|i| s.validate_particle(i)),
        )
    }
}

/// One 3-vector per particle as a read-only `(N, 3)` array.
fn rows<'py>(
    py: Python<'py>,
    scene: &CoreScene,
    field: fn(&cordis_core::Particle) -> [f64; 3],
) -> Bound<'py, PyArray2<f64>> {
    let flat: Vec<f64> = scene.particles.iter().flat_map(field).collect();
    let n = scene.num_particles();
    let array = numpy::ndarray::Array2::from_shape_vec((n, 3), flat)
        .expect("3 values per particle make an (N, 3) array");
    read_only(array.into_pyarray(py))
}

/// Marks an array read-only, so that `scene.masses[3] = 2.0` raises instead of changing a copy.
fn read_only<'py, D: numpy::ndarray::Dimension>(
    a: Bound<'py, numpy::PyArray<f64, D>>,
) -> Bound<'py, numpy::PyArray<f64, D>> {
    // Clearing WRITEABLE on an array we own cannot fail.
    let _ = a.call_method1("setflags", (false,));
    a
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
