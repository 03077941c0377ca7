//! Trajectories between numpy and the core: `read_trajectory`, `write_trajectory`, and the
//! conversions every other module uses (`(T, N, 3)` float64 arrays, metres).

use std::path::PathBuf;

use cordis_core::{Observations, Trajectory};
use numpy::ndarray::Array3;
use numpy::{IntoPyArray, PyArray3, PyArrayDyn, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;

use crate::errors::to_py;

/// Any array-like of numbers as a float64 numpy array: a float64 array as it is, anything else
/// through `numpy.asarray(x, dtype=float64)`. `what` names the argument in errors.
pub fn as_f64_array<'py>(
    x: &Bound<'py, PyAny>,
    what: &str,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    if let Ok(a) = x.cast::<PyArrayDyn<f64>>() {
        return Ok(a.clone());
    }
    let np = x.py().import("numpy")?;
    let converted = np
        .call_method1("asarray", (x, np.getattr("float64")?))
        .map_err(|e| {
            PyTypeError::new_err(format!(
                "{what}: expected an array of numbers (float64-convertible): {}",
                e.value(x.py())
            ))
        })?;
    Ok(converted.cast_into::<PyArrayDyn<f64>>()?)
}

/// The values of a float64 array in C (row-major) order, whatever its strides.
pub fn c_order_values(a: &Bound<'_, PyArrayDyn<f64>>) -> PyResult<Vec<f64>> {
    let ro = a.try_readonly().map_err(borrow_error)?;
    let view = ro.as_array();
    Ok(match view.as_slice() {
        Some(s) => s.to_vec(),
        None => view.iter().copied().collect(),
    })
}

fn borrow_error(e: numpy::BorrowError) -> PyErr {
    PyValueError::new_err(format!("array is being written by another thread: {e}"))
}

/// The `ArgumentError` (a `ValueError` too) of an array `what` not shaped `(T, N, 3)`.
fn not_positions(what: &str, shape: &[usize]) -> PyErr {
    crate::errors::argument_error(
        what,
        &format!(
            "expected an array of shape (T, N, 3) (frames, particles, xyz), got shape {}",
            shape_text(shape)
        ),
    )
}

/// A `(T, N, 3)` array-like as a core trajectory. A wrong shape is an `ArgumentError` (also a
/// `ValueError`) naming the expected one; a value that is not finite is a `TrajectoryError` naming frame, particle and
/// coordinate.
pub fn traj_from_py(x: &Bound<'_, PyAny>, what: &str) -> PyResult<Trajectory> {
    let a = as_f64_array(x, what)?;
    let shape = a.shape().to_vec();
    if shape.len() != 3 || shape[2] != 3 {
        return Err(not_positions(what, &shape));
    }
    let data = c_order_values(&a)?;
    Trajectory::from_flat(shape[0], shape[1], data).map_err(to_py)
}

/// An array `(T, N, 3)` of observed positions in which NaN marks a missing coordinate; with
/// `visible` (a boolean array `(T, N)`, named `mask_name` in errors: `visible`, `visible[1]`), a
/// particle is also missing where it is False.
pub fn observations_from_py(
    x: &Bound<'_, PyAny>,
    visible: Option<&Bound<'_, PyAny>>,
    what: &str,
    mask_name: &str,
) -> PyResult<Observations> {
    let a = as_f64_array(x, what)?;
    let shape = a.shape().to_vec();
    if shape.len() != 3 || shape[2] != 3 {
        return Err(not_positions(what, &shape));
    }
    let mut data = c_order_values(&a)?;
    // None is "every particle visible": one take of several without a mask (`[None, mask]`).
    if let Some(v) = visible.filter(|v| !v.is_none()) {
        let mask: numpy::PyReadonlyArrayDyn<'_, bool> = v.extract().map_err(|_| {
            PyTypeError::new_err(format!(
                "{mask_name}: expected a boolean array of shape ({}, {}) or None (all visible), got {}",
                shape[0],
                shape[1],
                crate::scene_edit::type_name(v)
            ))
        })?;
        let m = mask.as_array();
        if m.shape() != [shape[0], shape[1]] {
            return Err(crate::errors::argument_error(
                mask_name,
                &format!(
                    "shape {} does not match {what}'s ({}, {})",
                    shape_text(m.shape()),
                    shape[0],
                    shape[1]
                ),
            ));
        }
        for ((t, i), &seen) in m.indexed_iter().map(|(ix, v)| ((ix[0], ix[1]), v)) {
            if !seen {
                let at = (t * shape[1] + i) * 3;
                data[at..at + 3].fill(f64::NAN);
            }
        }
    }
    Observations::from_flat(shape[0], shape[1], data)
        .map_err(|e| PyValueError::new_err(format!("{what}: {e}")))
}

/// The reader's messages with its options as `read_trajectory` spells them: the core names
/// the CLI's (`--columns`, `--units`, `--delimiter`), which a Python user does not have.
fn python_spelling(e: cordis_core::CordisError) -> cordis_core::CordisError {
    use cordis_core::CordisError as E;
    let spell = |text: &str| {
        ["columns", "units", "delimiter"]
            .iter()
            .fold(text.to_string(), |t, o| {
                t.replace(&format!("--{o}:"), &format!("{o}:"))
                    .replace(&format!("--{o}"), &format!("{o}="))
            })
    };
    match e {
        E::Argument { place, message } => {
            E::argument(place.trim_start_matches("--").to_string(), spell(&message))
        }
        E::Trajectory { place, message } => E::trajectory(place, spell(&message)),
        E::Format { place, message } => E::format(place, spell(&message)),
        other => other,
    }
}

/// A core trajectory as a C-contiguous float64 array `(T, N, 3)`.
pub fn traj_to_py(py: Python<'_>, traj: Trajectory) -> PyResult<Bound<'_, PyArray3<f64>>> {
    let shape = (traj.frames(), traj.particles(), 3);
    let array = Array3::from_shape_vec(shape, traj.into_flat())
        .map_err(|e| PyValueError::new_err(format!("trajectory shape: {e}")))?;
    Ok(array.into_pyarray(py))
}

/// `(a, b, c)` as Python prints a shape.
pub fn shape_text(shape: &[usize]) -> String {
    match shape {
        [one] => format!("({one},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(|d| d.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// A positive, finite time step (s), or a `ValueError` naming `what`.
pub fn check_dt(dt: f64, what: &str) -> PyResult<f64> {
    if dt.is_finite() && dt > 0.0 {
        Ok(dt)
    } else {
        Err(PyValueError::new_err(format!(
            "{what}: must be a positive number of seconds, got {dt}"
        )))
    }
}

/// Reads a trajectory or marker file, chosen by extension — cordis' `.csv`, `.npy`, `.tra`;
/// motion capture `.c3d`, OpenSim `.trc`; tracker `.npz` (TAP-Vid / CoTracker); `.csv`/`.tsv`
/// tables with named columns — as a float64 array `(T, N, 3)` in m, NaN where a marker is
/// missing (never zero). The same reader as the CLI's (`cordis_core::io::read_markers`).
///
/// `columns` maps a table's columns (`"frame=Frame,particle=Marker,x=X,y=Y,z=Z"`, `"time=t"`,
/// wide `"time=Time,x=*_X"`); `units` (`"m"`, `"cm"`, `"mm"`) are those of a file that does not
/// state them; `delimiter` a table's (default: sniffed). With `with_dt=True` the result is
/// `(array, dt)`, `dt` in s from the file's rate (TRC `DataRate`, C3D `POINT:RATE`, a time
/// column), or None when it gives none.
///
/// >>> traj = cordis.read_trajectory("rigid.csv")   # doctest: +SKIP
/// >>> markers, dt = cordis.read_trajectory("walk.trc", with_dt=True)   # doctest: +SKIP
#[pyfunction]
#[pyo3(signature = (path, /, *, columns = None, units = None, delimiter = None, with_dt = false))]
pub fn read_trajectory<'py>(
    py: Python<'py>,
    path: PathBuf,
    columns: Option<String>,
    units: Option<String>,
    delimiter: Option<String>,
    with_dt: bool,
) -> PyResult<Bound<'py, PyAny>> {
    use cordis_core::io::markers::{Delimiter, Units};
    let options = cordis_core::io::ReadOptions {
        columns,
        units: units
            .as_deref()
            .map(|u| Units::parse_arg("units", u))
            .transpose()
            .map_err(to_py)?,
        delimiter: delimiter
            .as_deref()
            .map(|d| Delimiter::parse_arg("delimiter", d))
            .transpose()
            .map_err(to_py)?,
    };
    let imported = py
        .detach(|| cordis_core::io::read_markers(&path, &options))
        .map_err(|e| to_py(python_spelling(e)))?;
    let obs = imported.observations;
    let shape = (obs.frames(), obs.particles(), 3);
    let array = Array3::from_shape_vec(shape, obs.as_flat().to_vec())
        .map_err(|e| PyValueError::new_err(format!("trajectory shape: {e}")))?
        .into_pyarray(py)
        .into_any();
    if with_dt {
        Ok((array, obs.dt).into_pyobject(py)?.into_any())
    } else {
        Ok(array)
    }
}

/// Writes positions `(T, N, 3)` (any float64-convertible array, m) atomically, in the format
/// the extension names (`.csv`, `.npy`, `.tra`). `dt` (s), when given, is checked; none of the
/// three formats stores it, so a reader gives it again (the scene's `dt` by default).
///
/// >>> cordis.write_trajectory("rigid.npy", scene.simulate(100))   # doctest: +SKIP
#[pyfunction]
#[pyo3(signature = (path, array, dt = None))]
pub fn write_trajectory(
    py: Python<'_>,
    path: PathBuf,
    array: &Bound<'_, PyAny>,
    dt: Option<f64>,
) -> PyResult<()> {
    let mut traj = traj_from_py(array, "array")?;
    if let Some(dt) = dt {
        traj.dt = Some(check_dt(dt, "dt")?);
    }
    py.detach(|| cordis_core::io::write_trajectory(&path, &traj))
        .map_err(to_py)
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(read_trajectory, m)?)?;
    m.add_function(wrap_pyfunction!(write_trajectory, m)?)?;
    Ok(())
}
