//! The exception tree: one Python class per `cordis_core::CordisError` variant, all under
//! `cordis.CordisError`, so `except cordis.CordisError` catches everything the library raises.
//!
//! Each raised exception also carries the variant's fields as attributes (`place`, `message`;
//! `frame`, `particle` for divergence; `filename` and `errno` for I/O), so code can react to
//! *where* a scene is wrong without parsing the message.

use cordis_core::CordisError as CoreError;
use pyo3::exceptions::{PyException, PyOSError};
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

/// `CordisIOError(CordisError, OSError)`: `create_exception!` takes a single base, so this class
/// is made once with Python's `type()` and kept here.
static IO_ERROR: PyOnceLock<Py<PyType>> = PyOnceLock::new();

/// The `CordisIOError` class (created on first use).
pub fn io_error_type(py: Python<'_>) -> PyResult<&Bound<'_, PyType>> {
    IO_ERROR
        .get_or_try_init(py, || {
            let bases = PyTuple::new(
                py,
                [py.get_type::<CordisError>(), py.get_type::<PyOSError>()],
            )?;
            let ns = PyDict::new(py);
            ns.set_item("__module__", "cordis")?;
            ns.set_item(
                "__doc__",
                "A file could not be read or written (also an OSError: `errno`, `filename`).",
            )?;
            let cls = py
                .get_type::<PyType>()
                .call1(("CordisIOError", bases, ns))?
                .cast_into::<PyType>()?;
            Ok(cls.unbind())
        })
        .map(|t| t.bind(py))
}

/// Registers the exception classes on the extension module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("CordisError", py.get_type::<CordisError>())?;
    m.add("SceneError", py.get_type::<SceneError>())?;
    m.add("TrajectoryError", py.get_type::<TrajectoryError>())?;
    m.add("FormatError", py.get_type::<FormatError>())?;
    m.add("DivergedError", py.get_type::<DivergedError>())?;
    m.add("CordisIOError", io_error_type(py)?)?;
    Ok(())
}

/// The Python exception for a core error: its class by variant, its message the core's one-line
/// message, its fields as attributes.
pub fn to_py(err: CoreError) -> PyErr {
    Python::attach(|py| build(py, &err).unwrap_or_else(|e| e))
}

fn build(py: Python<'_>, err: &CoreError) -> PyResult<PyErr> {
    let text = err.to_string();
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
                None => {
                    let e = cls.call1((&text,))?;
                    e.setattr("filename", &filename)?;
                    e
                }
            };
            e.setattr("place", &filename)?;
            e.setattr("message", source.to_string())?;
            e
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
