//! The exception tree: one Python class per `cordis_core::CordisError` variant, all under
//! `cordis.CordisError`, so `except cordis.CordisError` catches everything the library raises.
//!
//! Each raised exception also carries the variant's fields as attributes (`place`, `message`;
//! `frame`, `particle` for divergence; `filename` and `errno` for I/O), so code can react to
//! *where* a scene is wrong without parsing the message.

use cordis_core::CordisError as CoreError;
use cordis_es::CostError;
use pyo3::exceptions::{
    PyException, PyIndexError, PyKeyError, PyOSError, PyRuntimeError, PyValueError,
};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyTuple, PyType};

pyo3::create_exception!(
    cordis,
    CordisError,
    PyException,
    "Base class of every error raised by cordis."
);
pyo3::create_exception!(
    cordis,
    SceneError,
    CordisError,
    "The scene is malformed or inconsistent. `place` names the field (`links[3].particles[1]`)."
);
pyo3::create_exception!(
    cordis,
    TrajectoryError,
    CordisError,
    "A trajectory is malformed or does not fit its scene. `place` names the frame or row."
);
pyo3::create_exception!(
    cordis,
    FormatError,
    CordisError,
    "A file or text is not in the format it announces (JSON syntax, `.npy` header…)."
);
pyo3::create_exception!(
    cordis,
    DivergedError,
    CordisError,
    "The simulation left the finite numbers (unstable for this dt). Has `frame` and `particle`."
);

pyo3::create_exception!(
    cordis,
    CheckpointError,
    CordisError,
    "A checkpoint could not be read, written, or does not fit the run it should resume."
);

/// Classes with two bases (`CordisError` and a built-in one, so that `except ValueError` or
/// `except OSError` also catch them): `create_exception!` takes a single base, so each is made
/// once with Python's `type()` and kept here.
static IO_ERROR: PyOnceLock<Py<PyType>> = PyOnceLock::new();
static COST_KIND_ERROR: PyOnceLock<Py<PyType>> = PyOnceLock::new();
static PARAM_LENGTH_ERROR: PyOnceLock<Py<PyType>> = PyOnceLock::new();
static SCENE_KEY_ERROR: PyOnceLock<Py<PyType>> = PyOnceLock::new();
static SCENE_INDEX_ERROR: PyOnceLock<Py<PyType>> = PyOnceLock::new();
static ARGUMENT_ERROR: PyOnceLock<Py<PyType>> = PyOnceLock::new();
static REFUSED_ERROR: PyOnceLock<Py<PyType>> = PyOnceLock::new();
static RUN_ERROR: PyOnceLock<Py<PyType>> = PyOnceLock::new();

fn dual_type<'py, B: pyo3::PyTypeInfo>(
    py: Python<'py>,
    cell: &'static PyOnceLock<Py<PyType>>,
    name: &str,
    doc: &str,
) -> PyResult<&'py Bound<'py, PyType>> {
    dual_type_of::<CordisError, B>(py, cell, name, doc)
}

/// A class deriving from cordis' `A` and the built-in `B`.
fn dual_type_of<'py, A: pyo3::PyTypeInfo, B: pyo3::PyTypeInfo>(
    py: Python<'py>,
    cell: &'static PyOnceLock<Py<PyType>>,
    name: &str,
    doc: &str,
) -> PyResult<&'py Bound<'py, PyType>> {
    cell.get_or_try_init(py, || {
        let bases = PyTuple::new(py, [py.get_type::<A>(), py.get_type::<B>()])?;
        let ns = PyDict::new(py);
        ns.set_item("__module__", "cordis")?;
        ns.set_item("__doc__", doc)?;
        let cls = py
            .get_type::<PyType>()
            .call1((name, bases, ns))?
            .cast_into::<PyType>()?;
        Ok(cls.unbind())
    })
    .map(|t| t.bind(py))
}

/// The `CordisIOError(CordisError, OSError)` class (created on first use).
pub fn io_error_type(py: Python<'_>) -> PyResult<&Bound<'_, PyType>> {
    dual_type::<PyOSError>(
        py,
        &IO_ERROR,
        "CordisIOError",
        "A file could not be read or written (also an OSError: `errno`, `filename`).",
    )
}

/// `CostKindError(CordisError, ValueError)`: a cost-kind string that does not parse.
pub fn cost_kind_error_type(py: Python<'_>) -> PyResult<&Bound<'_, PyType>> {
    dual_type::<PyValueError>(
        py,
        &COST_KIND_ERROR,
        "CostKindError",
        "A cost kind that does not parse (`horizon:x`, `shrt`…); `place` is the text.",
    )
}

/// `ParamLengthError(CordisError, ValueError)`: a parameter vector of the wrong length.
pub fn param_length_error_type(py: Python<'_>) -> PyResult<&Bound<'_, PyType>> {
    dual_type::<PyValueError>(
        py,
        &PARAM_LENGTH_ERROR,
        "ParamLengthError",
        "A parameter vector or population of the wrong length; has `expected` and `got`.",
    )
}

/// `ArgumentError(CordisError, ValueError)`: a keyword argument out of its domain.
pub fn argument_error_type(py: Python<'_>) -> PyResult<&Bound<'_, PyType>> {
    dual_type::<PyValueError>(
        py,
        &ARGUMENT_ERROR,
        "ArgumentError",
        "An argument out of its domain (`width=nan`); `place` names it, `message` the range.",
    )
}

/// `RefusedError(CordisError, ValueError)`: a strategy that cannot run on the problem, refused
/// before any work.
pub fn refused_error_type(py: Python<'_>) -> PyResult<&Bound<'_, PyType>> {
    dual_type::<PyValueError>(
        py,
        &REFUSED_ERROR,
        "RefusedError",
        "The strategy cannot run on this problem (a muscle for an exact solver, free masses \
         without total_mass…): refused before any work; `message` says what to do instead.",
    )
}

/// `RunError(CordisError, RuntimeError)`: a run that found no estimate or could not finish.
pub fn run_error_type(py: Python<'_>) -> PyResult<&Bound<'_, PyType>> {
    dual_type::<PyRuntimeError>(
        py,
        &RUN_ERROR,
        "RunError",
        "The run failed: the solver found no estimate, an evaluation failed, or a checkpoint \
         could not be written; `place` and `message` say which.",
    )
}

/// A `RunError` with `place` and `message` set.
pub fn run_error(place: &str, message: &str) -> PyErr {
    Python::attach(|py| {
        let make = || -> PyResult<PyErr> {
            let cls = run_error_type(py)?;
            Ok(PyErr::from_value(placed_of(cls, place, message)?))
        };
        make().unwrap_or_else(|e| e)
    })
}

/// An `ArgumentError` with `place` and `message` set.
pub fn argument_error(place: &str, message: &str) -> PyErr {
    Python::attach(|py| {
        let make = || -> PyResult<PyErr> {
            let cls = argument_error_type(py)?;
            Ok(PyErr::from_value(placed_of(cls, place, message)?))
        };
        make().unwrap_or_else(|e| e)
    })
}

/// `SceneKeyError(SceneError, KeyError)`: a link type or parameter name the scene lacks.
pub fn scene_key_error_type(py: Python<'_>) -> PyResult<&Bound<'_, PyType>> {
    dual_type_of::<SceneError, PyKeyError>(
        py,
        &SCENE_KEY_ERROR,
        "SceneKeyError",
        "A link-type or parameter name the scene does not have (`scene.types[\"rib\"][\"stifness\"]`); `place` names it.",
    )
}

/// `SceneIndexError(SceneError, IndexError)`: a particle or type index out of range.
pub fn scene_index_error_type(py: Python<'_>) -> PyResult<&Bound<'_, PyType>> {
    dual_type_of::<SceneError, PyIndexError>(
        py,
        &SCENE_INDEX_ERROR,
        "SceneIndexError",
        "A particle or type index out of range (`scene.particles[99]`); `place` names it.",
    )
}

/// A `SceneKeyError` with `place` and `message` set (as every placed error has).
pub fn scene_key_error(place: &str, message: &str) -> PyErr {
    Python::attach(|py| {
        let make = || -> PyResult<PyErr> {
            let cls = scene_key_error_type(py)?;
            Ok(PyErr::from_value(placed_of(cls, place, message)?))
        };
        make().unwrap_or_else(|e| e)
    })
}

/// A `SceneIndexError` with `place` and `message` set.
pub fn scene_index_error(place: &str, message: &str) -> PyErr {
    Python::attach(|py| {
        let make = || -> PyResult<PyErr> {
            let cls = scene_index_error_type(py)?;
            Ok(PyErr::from_value(placed_of(cls, place, message)?))
        };
        make().unwrap_or_else(|e| e)
    })
}

fn placed_of<'py>(
    cls: &Bound<'py, PyType>,
    place: &str,
    message: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let e = cls.call1((format!("{place}: {message}"),))?;
    e.setattr("place", place)?;
    e.setattr("message", message)?;
    Ok(e)
}

/// Registers the exception classes on the extension module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("CordisError", py.get_type::<CordisError>())?;
    m.add("SceneError", py.get_type::<SceneError>())?;
    m.add("TrajectoryError", py.get_type::<TrajectoryError>())?;
    m.add("FormatError", py.get_type::<FormatError>())?;
    m.add("DivergedError", py.get_type::<DivergedError>())?;
    m.add("CheckpointError", py.get_type::<CheckpointError>())?;
    m.add("CordisIOError", io_error_type(py)?)?;
    m.add("CostKindError", cost_kind_error_type(py)?)?;
    m.add("ParamLengthError", param_length_error_type(py)?)?;
    m.add("SceneKeyError", scene_key_error_type(py)?)?;
    m.add("SceneIndexError", scene_index_error_type(py)?)?;
    m.add("ArgumentError", argument_error_type(py)?)?;
    m.add("RefusedError", refused_error_type(py)?)?;
    m.add("RunError", run_error_type(py)?)?;
    Ok(())
}

/// The Python exception for a core error: its class by variant, its message the core's one-line
/// message, its fields as attributes.
pub fn to_py(err: CoreError) -> PyErr {
    Python::attach(|py| build(py, &err).unwrap_or_else(|e| e))
}

fn build(py: Python<'_>, err: &CoreError) -> PyResult<PyErr> {
    // The message as a terminal may show it: input bytes escaped, long values cut.
    let text = cordis_core::error::printable(&err.to_string());
    let value = match err {
        CoreError::Scene { place, message } => placed::<SceneError>(py, &text, place, message)?,
        CoreError::Trajectory { place, message } => {
            placed::<TrajectoryError>(py, &text, place, message)?
        }
        CoreError::Format { place, message } => placed::<FormatError>(py, &text, place, message)?,
        CoreError::Diverged {
            frame,
            particle,
            message,
        } => {
            let e = py.get_type::<DivergedError>().call1((&text,))?;
            e.setattr("frame", frame)?;
            e.setattr("particle", particle)?;
            e.setattr("message", message)?;
            e
        }
        CoreError::Io { path, source } => {
            let cls = io_error_type(py)?;
            let filename = path.display().to_string();
            // OSError(errno, strerror, filename) fills `errno`/`strerror`/`filename` the way
            // the standard library's own errors do.
            let e = match source.raw_os_error() {
                Some(code) => {
                    let strerror = py.import("os")?.call_method1("strerror", (code,))?;
                    cls.call1((code, strerror, &filename))?
                }
                // No errno (a file too large, a directory): the message alone. Setting
                // `filename` here would make OSError print `[Errno None] None: 'path'`.
                None => cls.call1((&text,))?,
            };
            e.setattr("place", &filename)?;
            e.setattr("message", source.to_string())?;
            e
        }
        CoreError::Argument { place, message } => {
            placed_of(argument_error_type(py)?, place, message)?
        }
        // `CordisError` is non-exhaustive: a variant added later still maps to the base class.
        other => py.get_type::<CordisError>().call1((other.to_string(),))?,
    };
    Ok(PyErr::from_value(value))
}

fn placed<'py, T: pyo3::PyTypeInfo>(
    py: Python<'py>,
    text: &str,
    place: &str,
    message: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let e = py.get_type::<T>().call1((text,))?;
    e.setattr("place", place)?;
    e.setattr("message", message)?;
    Ok(e)
}

/// The Python exception for an error of `cordis-es`: core errors as [`to_py`], a bad cost kind
/// as `CostKindError`, a wrong length as `ParamLengthError`, a trajectory that does not fit
/// its scene as `TrajectoryError`, an option out of its range as `ArgumentError`, a refused
/// strategy as `RefusedError`, a checkpoint that cannot resume as `CheckpointError`, a failed
/// run as `RunError` — each with `place` and `message`.
pub fn cost_to_py(err: CostError) -> PyErr {
    match err {
        CostError::Core(e) => to_py(e),
        other => Python::attach(|py| build_cost(py, &other).unwrap_or_else(|e| e)),
    }
}

fn build_cost(py: Python<'_>, err: &CostError) -> PyResult<PyErr> {
    let text = err.to_string();
    let value = match err {
        CostError::Kind { place, message } => {
            let e = cost_kind_error_type(py)?.call1((&text,))?;
            e.setattr("place", place)?;
            e.setattr("message", message)?;
            e
        }
        CostError::Length {
            place,
            expected,
            got,
        } => {
            let e = param_length_error_type(py)?.call1((&text,))?;
            e.setattr("place", place)?;
            e.setattr("expected", expected)?;
            e.setattr("got", got)?;
            e
        }
        CostError::Mismatch { place, message } => {
            placed::<TrajectoryError>(py, &text, place, message)?
        }
        CostError::Invalid { place, message } => {
            placed_of(argument_error_type(py)?, place, message)?
        }
        CostError::Refused { place, message } => {
            placed_of(refused_error_type(py)?, place, message)?
        }
        CostError::Resume { place, message, .. } => {
            placed::<CheckpointError>(py, &text, place, message)?
        }
        CostError::State { message, .. } => placed::<CheckpointError>(py, &text, "state", message)?,
        CostError::Run { place, message, .. } => placed_of(run_error_type(py)?, place, message)?,
        CostError::Evaluation { message, .. } => {
            placed_of(run_error_type(py)?, "evaluation", message)?
        }
        // Non-exhaustive: a variant added later still maps to the base class.
        other => py.get_type::<CordisError>().call1((other.to_string(),))?,
    };
    Ok(PyErr::from_value(value))
}
