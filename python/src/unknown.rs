//! `cordis.Unknown`: a parameter still to be identified, with its search box (the JSON
//! format's `{"min": …, "max": …, "init": …}`, `cordis_core::Param::Unknown`).

use cordis_core::{Bounds, Param};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyMapping, PyTuple};

/// A parameter to identify, searched in `[min, max]` (its units are the parameter's), starting
/// from `init` (default: the middle of the box, geometric when the box is positive and spans
/// more than a decade). Assign it where a number goes:
///
/// >>> scene.types["rib"]["stiffness"] = cordis.Unknown(1.0, 1000.0)
/// >>> scene.particles[2].mass = cordis.Unknown(0.1, 10.0, init=1.0)
/// >>> scene.types["rib"]["stiffness"]
/// Unknown(1.0, 1000.0)
#[pyclass(frozen, eq, module = "cordis", name = "Unknown")]
#[derive(Clone, PartialEq)]
pub struct Unknown {
    bounds: Bounds,
}

#[pymethods]
impl Unknown {
    /// `min <= max`, both finite; `init`, when given, inside the box. Whether the box suits the
    /// parameter (a positive mass…) is checked when it is assigned.
    #[new]
    #[pyo3(signature = (min, max, init = None))]
    fn new(min: f64, max: f64, init: Option<f64>) -> PyResult<Self> {
        if !(min.is_finite() && max.is_finite()) {
            return Err(PyValueError::new_err(format!(
                "Unknown: min and max must be finite numbers, got {min} and {max}"
            )));
        }
        if min > max {
            return Err(PyValueError::new_err(format!(
                "Unknown: min {min} is above max {max}"
            )));
        }
        if let Some(i) = init {
            if !(i >= min && i <= max) {
                return Err(PyValueError::new_err(format!(
                    "Unknown: init {i} is outside [{min}, {max}]"
                )));
            }
        }
        Ok(Unknown {
            bounds: Bounds { min, max, init },
        })
    }

    /// Lower end of the box.
    #[getter]
    fn min(&self) -> f64 {
        self.bounds.min
    }

    /// Upper end of the box.
    #[getter]
    fn max(&self) -> f64 {
        self.bounds.max
    }

    /// The starting value given, or None.
    #[getter]
    fn init(&self) -> Option<f64> {
        self.bounds.init
    }

    /// The value a simulation uses before identification: `init`, else the box's middle.
    #[getter]
    fn value(&self) -> f64 {
        Param::Unknown(self.bounds).value()
    }

    /// `{"min": …, "max": …}` (and `"init"` when given), as in the JSON format.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("min", self.bounds.min)?;
        d.set_item("max", self.bounds.max)?;
        if let Some(i) = self.bounds.init {
            d.set_item("init", i)?;
        }
        Ok(d)
    }

    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        let f = |v: f64| -> PyResult<String> { Ok(PyFloat::new(py, v).repr()?.to_string()) };
        let init = match self.bounds.init {
            Some(i) => format!(", init={}", f(i)?),
            None => String::new(),
        };
        Ok(format!(
            "Unknown({}, {}{init})",
            f(self.bounds.min)?,
            f(self.bounds.max)?
        ))
    }

    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyTuple>)> {
        let b = slf.get().bounds;
        let args = (b.min, b.max, b.init).into_pyobject(slf.py())?;
        Ok((slf.get_type().into_any(), args))
    }
}

/// A parameter as Python sees it: a float when known, an [`Unknown`] otherwise.
pub fn param_to_py(py: Python<'_>, p: &Param) -> PyResult<Py<PyAny>> {
    Ok(match *p {
        Param::Known(v) => PyFloat::new(py, v).into_any().unbind(),
        Param::Unknown(bounds) => Py::new(py, Unknown { bounds })?.into_any(),
    })
}

/// A value assigned to a parameter: a number (int, float, numpy scalar), a `cordis.Unknown`,
/// or a `{"min", "max"[, "init"]}` mapping as in the JSON format. `place` names the parameter
/// in the `TypeError`; the value's range is checked by the scene's validation.
pub fn param_from_py(value: &Bound<'_, PyAny>, place: &str) -> PyResult<Param> {
    if let Ok(u) = value.cast::<Unknown>() {
        return Ok(Param::Unknown(u.get().bounds));
    }
    if let Ok(m) = value.cast::<PyMapping>() {
        let get = |k: &str| -> PyResult<Option<f64>> {
            match m.get_item(k) {
                Ok(v) if v.is_none() => Ok(None),
                Ok(v) => Ok(Some(crate::scene_edit::number(
                    &v,
                    &format!("{place}.{k}"),
                )?)),
                Err(_) => Ok(None),
            }
        };
        let (Some(min), Some(max)) = (get("min")?, get("max")?) else {
            return Err(PyTypeError::new_err(format!(
                "{place}: an unknown needs \"min\" and \"max\" (or use cordis.Unknown(min, max))"
            )));
        };
        let init = get("init")?;
        return Ok(Param::Unknown(Bounds { min, max, init }));
    }
    if value.is_instance_of::<PyBool>() {
        return Err(PyTypeError::new_err(format!(
            "{place}: expected a number or cordis.Unknown(min, max), got bool"
        )));
    }
    value.extract::<f64>().map(Param::Known).map_err(|_| {
        PyTypeError::new_err(format!(
            "{place}: expected a number or cordis.Unknown(min, max), got {}",
            crate::scene_edit::type_name(value)
        ))
    })
}
