//! Python objects ⇄ `serde_json::Value`, walked by hand so that a bad value in a dict names its
//! place the way the core's JSON reader does (`particles[2].mass`), and numpy scalars and arrays
//! are accepted where numbers and lists are.

use cordis_core::CordisError as CoreError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyMapping, PyString, PyTuple};
use serde_json::{Map, Number, Value};

/// Deeper than any scene: also stops a list that contains itself.
const MAX_DEPTH: usize = 64;

/// Converts a Python object made of dicts, lists, tuples, strings, numbers, booleans and None
/// (numpy values through `tolist()`) into JSON. Errors are `Scene` errors naming the place.
pub fn to_value(obj: &Bound<'_, PyAny>) -> Result<Value, ConvertError> {
    walk(obj, "", 0)
}

/// A conversion failure: either the object is not JSON-like (a core `Scene` error with its
/// place), or Python raised while we looked at it.
pub enum ConvertError {
    Core(CoreError),
    Py(PyErr),
}

impl From<PyErr> for ConvertError {
    fn from(e: PyErr) -> Self {
        ConvertError::Py(e)
    }
}

impl From<ConvertError> for PyErr {
    fn from(e: ConvertError) -> Self {
        match e {
            ConvertError::Core(e) => crate::errors::to_py(e),
            ConvertError::Py(e) => e,
        }
    }
}

fn fail(place: &str, message: String) -> ConvertError {
    let place = if place.is_empty() { "scene" } else { place };
    ConvertError::Core(CoreError::scene(place, message))
}

fn key_place(place: &str, key: &str) -> String {
    if place.is_empty() {
        key.to_string()
    } else {
        format!("{place}.{key}")
    }
}

use crate::scene_edit::type_name;

fn walk(obj: &Bound<'_, PyAny>, place: &str, depth: usize) -> Result<Value, ConvertError> {
    if depth > MAX_DEPTH {
        return Err(fail(
            place,
            format!("nested deeper than {MAX_DEPTH} levels"),
        ));
    }
    if obj.is_none() {
        return Ok(Value::Null);
    }
    if let Ok(b) = obj.cast::<PyBool>() {
        return Ok(Value::Bool(b.is_true()));
    }
    if obj.is_instance_of::<PyInt>() {
        if let Ok(i) = obj.extract::<i64>() {
            return Ok(Value::from(i));
        }
        if let Ok(u) = obj.extract::<u64>() {
            return Ok(Value::from(u));
        }
        return match obj.extract::<f64>() {
            Ok(v) => number(v, place),
            Err(_) => Err(fail(place, "integer too large for a number".into())),
        };
    }
    if let Ok(f) = obj.cast::<PyFloat>() {
        return number(f.value(), place);
    }
    if let Ok(s) = obj.cast::<PyString>() {
        return Ok(Value::String(s.to_cow()?.into_owned()));
    }
    if let Ok(d) = obj.cast::<PyDict>() {
        return object(d.items().iter(), place, depth);
    }
    if let Ok(l) = obj.cast::<PyList>() {
        return array(l.iter(), place, depth);
    }
    if let Ok(t) = obj.cast::<PyTuple>() {
        return array(t.iter(), place, depth);
    }
    if let Ok(m) = obj.cast::<PyMapping>() {
        return object(m.items()?.iter(), place, depth);
    }
    // numpy arrays and scalars (np.float64 is a float already; np.int64, np.bool_ and arrays
    // are not): their `tolist()` gives plain Python values.
    if obj.hasattr("tolist")? {
        let plain = obj.call_method0("tolist")?;
        if !plain.is(obj) {
            return walk(&plain, place, depth + 1);
        }
    }
    Err(fail(
        place,
        format!(
            "expected a JSON value (dict, list, str, number, bool or None), got {}",
            type_name(obj)
        ),
    ))
}

fn number(v: f64, place: &str) -> Result<Value, ConvertError> {
    Number::from_f64(v)
        .map(Value::Number)
        .ok_or_else(|| fail(place, format!("must be a finite number, got {v}")))
}

fn object<'py>(
    items: impl Iterator<Item = Bound<'py, PyAny>>,
    place: &str,
    depth: usize,
) -> Result<Value, ConvertError> {
    let mut out = Map::new();
    for item in items {
        let (k, v): (Bound<'py, PyAny>, Bound<'py, PyAny>) = item.extract()?;
        let Ok(k) = k.cast::<PyString>() else {
            return Err(fail(
                place,
                format!("keys must be strings, got {}", type_name(&k)),
            ));
        };
        let k = k.to_cow()?.into_owned();
        let at = key_place(place, &k);
        out.insert(k, walk(&v, &at, depth + 1)?);
    }
    Ok(Value::Object(out))
}

fn array<'py>(
    items: impl Iterator<Item = Bound<'py, PyAny>>,
    place: &str,
    depth: usize,
) -> Result<Value, ConvertError> {
    items
        .enumerate()
        .map(|(i, v)| walk(&v, &format!("{place}[{i}]"), depth + 1))
        .collect::<Result<Vec<_>, _>>()
        .map(Value::Array)
}

/// JSON → plain Python values (dict, list, str, int, float, bool, None); key order is kept.
pub fn to_py<'py>(py: Python<'py>, v: &Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match v {
        Value::Null => py.None().into_bound(py),
        Value::Bool(b) => PyBool::new(py, *b).to_owned().into_any(),
        Value::Number(n) => {
            if let Some(i) = n.as_i64() {
                i.into_pyobject(py)?.into_any()
            } else if let Some(u) = n.as_u64() {
                u.into_pyobject(py)?.into_any()
            } else {
                PyFloat::new(py, n.as_f64().unwrap_or_default()).into_any()
            }
        }
        Value::String(s) => PyString::new(py, s).into_any(),
        Value::Array(a) => {
            let items = a
                .iter()
                .map(|x| to_py(py, x))
                .collect::<PyResult<Vec<_>>>()?;
            PyList::new(py, items)?.into_any()
        }
        Value::Object(o) => {
            let d = PyDict::new(py);
            for (k, x) in o {
                d.set_item(k, to_py(py, x)?)?;
            }
            d.into_any()
        }
    })
}
