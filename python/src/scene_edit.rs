//! Editing a `cordis.Scene` from Python: views that read and write through to the scene.
//!
//! * `scene.particles` — a sequence of `Particle` views (`mass`, `pos`, `vel`, `fixed`,
//!   `group`), `scene.particles[3].mass = 2.0`;
//! * `scene.types` — a mapping from type name to a `LinkType` view, itself a mapping from
//!   parameter name to value: `scene.types["rib"]["stiffness"] = 120.0`.
//!
//! Every write goes through `Scene::edit`: the value is set, the part of the scene it belongs
//! to is validated with the core's own rules (`Scene::validate_particle`, `validate_type`), and
//! a refused value is undone before the `SceneError` (which names the place, e.g.
//! `types.rib.stiffness: must be a non-negative number, got -1`) is raised. Views hold the
//! scene and an index: the catalogue and the particle list cannot change length from Python,
//! so an index stays valid.

use cordis_core::{LinkType as CoreType, Param, Particle as CoreParticle, Scene as CoreScene};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyFloat, PyList, PyString};

use crate::errors::{scene_index_error, scene_key_error};
use crate::scene::Scene;
use crate::trajectory::{as_f64_array, c_order_values, shape_text};
use crate::unknown::{param_from_py, param_to_py};

pub fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "?".into())
}

/// A real number (int, float, numpy scalar; not a bool). `place` names it in the `TypeError`.
pub fn number(value: &Bound<'_, PyAny>, place: &str) -> PyResult<f64> {
    if value.is_instance_of::<PyBool>() {
        return Err(PyTypeError::new_err(format!(
            "{place}: expected a number, got bool"
        )));
    }
    value.extract::<f64>().map_err(|_| {
        PyTypeError::new_err(format!(
            "{place}: expected a number, got {}",
            type_name(value)
        ))
    })
}

/// An array-like of float64 of exactly `shape`, in C order; a wrong shape is a `ValueError`
/// naming both shapes.
pub fn array(value: &Bound<'_, PyAny>, what: &str, shape: &[usize]) -> PyResult<Vec<f64>> {
    let a = as_f64_array(value, what)?;
    let got = numpy::PyUntypedArrayMethods::shape(&a).to_vec();
    if got != shape {
        return Err(PyValueError::new_err(format!(
            "{what}: expected an array of shape {}, got shape {}",
            shape_text(shape),
            shape_text(&got)
        )));
    }
    c_order_values(&a)
}

/// Three numbers (a tuple, list or array of shape (3,)).
pub fn vec3(value: &Bound<'_, PyAny>, what: &str) -> PyResult<[f64; 3]> {
    let v = array(value, what, &[3])?;
    Ok([v[0], v[1], v[2]])
}

/// Unknown scalars of the scene (type parameters and masses).
pub fn count_unknowns(s: &CoreScene) -> usize {
    let params = s.types.iter().flat_map(|t| &t.params);
    let masses = s.particles.iter().map(|p| &p.mass);
    params.chain(masses).filter(|p| p.is_unknown()).count()
}

/// A parameter for reading: Python's float repr, or `Unknown(min, max)`.
fn shown(py: Python<'_>, p: &Param) -> PyResult<String> {
    Ok(param_to_py(py, p)?.bind(py).repr()?.to_string())
}

/// The multi-line `str(scene)`.
pub fn summary(py: Python<'_>, s: &CoreScene) -> PyResult<String> {
    use std::fmt::Write;
    let fixed = s.particles.iter().filter(|p| p.fixed).count();
    let [gx, gy, gz] = s.gravity;
    let mut out = format!(
        "Scene: {} particles ({fixed} fixed), {} links, {} types; dt = {} s, \
         gravity = ({gx}, {gy}, {gz}) m/s²\n",
        s.num_particles(),
        s.links.len(),
        s.types.len(),
        s.dt
    );
    let width = s.types.iter().map(|t| t.name.len()).max().unwrap_or(0);
    for (ti, t) in s.types.iter().enumerate() {
        let count = s.links.iter().filter(|l| l.type_index == ti).count();
        let mut params = Vec::with_capacity(t.params.len());
        for (k, p) in t.params.iter().enumerate() {
            params.push(format!("{}={}", t.param_name(k), shown(py, p)?));
        }
        let links = if t.kind == cordis_core::LinkKind::Conditional {
            "pairs found while simulating".to_string()
        } else if t.kind.is_coupling() {
            let n = s.couplings.iter().filter(|c| c.type_index == ti).count();
            format!("{n} coupling{}", if n == 1 { "" } else { "s" })
        } else {
            format!("{count} link{}", if count == 1 { "" } else { "s" })
        };
        let _ = writeln!(
            out,
            "  {:<width$}  {:<11} {}  ({links})",
            t.name,
            t.kind.name(),
            params.join(", ")
        );
    }
    let known: Vec<f64> = s
        .particles
        .iter()
        .filter(|p| !p.mass.is_unknown())
        .map(|p| p.mass.value())
        .collect();
    let unknown = s.num_particles() - known.len();
    if !known.is_empty() {
        let lo = known.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = known.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let total: f64 = known.iter().sum();
        let _ = write!(out, "  masses: {lo} to {hi} kg, {total} kg in all");
    } else {
        out.push_str("  masses:");
    }
    if unknown > 0 {
        let _ = write!(out, " ({unknown} unknown)");
    }
    let unknowns = count_unknowns(s);
    if unknowns > 0 {
        let _ = write!(out, "\n  {unknowns} unknown(s) to identify");
    }
    Ok(out)
}

// ------------------------------------------------------------------------------- particles

/// `scene.particles`: a sequence of [`ParticleView`]s (indexable, negative indices too).
#[pyclass(frozen, sequence, module = "cordis", name = "ParticleList")]
pub struct Particles {
    scene: Py<Scene>,
}

impl Particles {
    pub fn new(scene: Py<Scene>) -> Self {
        Particles { scene }
    }
}

/// A Python index (negative from the end) into `len` items, or `SceneIndexError` naming it.
fn index(i: isize, len: usize, what: &str) -> PyResult<usize> {
    let k = if i < 0 { i + len as isize } else { i };
    if k < 0 || k as usize >= len {
        return Err(scene_index_error(
            &format!("{what}[{i}]"),
            &format!("index out of range: the scene has {len} {what}"),
        ));
    }
    Ok(k as usize)
}

#[pymethods]
impl Particles {
    fn __len__(&self, py: Python<'_>) -> usize {
        self.scene.bind(py).get().core().num_particles()
    }

    fn __getitem__(&self, py: Python<'_>, i: isize) -> PyResult<ParticleView> {
        let index = index(i, self.__len__(py), "particles")?;
        Ok(ParticleView {
            scene: self.scene.clone_ref(py),
            index,
        })
    }

    fn __iter__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let views = (0..self.__len__(py)).map(|index| ParticleView {
            scene: self.scene.clone_ref(py),
            index,
        });
        let list = PyList::empty(py);
        for v in views {
            list.append(Py::new(py, v)?)?;
        }
        Ok(list.into_any().try_iter()?.into_any())
    }

    fn __repr__(&self, py: Python<'_>) -> String {
        format!("ParticleList({} particles)", self.__len__(py))
    }
}

/// One particle of a scene: `mass` (kg, or `Unknown`), `pos` = x(0) (m), `vel` = v(0) (m/s),
/// `fixed`, `group`. Every attribute can be set; a value the scene refuses raises `SceneError`
/// (`particles[3].mass: must be a positive number, got 0`) and changes nothing.
///
/// >>> p = scene.particles[3]
/// >>> p.mass = 2.0
/// >>> p.pos = (0.0, 0.0, 1.5)
/// >>> p
/// Particle(3, mass=2.0, pos=(0.0, 0.0, 1.5))
#[pyclass(frozen, module = "cordis", name = "Particle")]
pub struct ParticleView {
    scene: Py<Scene>,
    index: usize,
}

impl ParticleView {
    fn read<R>(&self, py: Python<'_>, f: impl FnOnce(&CoreParticle) -> R) -> R {
        f(&self.scene.bind(py).get().core().particles[self.index])
    }

    /// Sets one field of this particle and validates the particle.
    fn write<T: 'static + Send>(
        &self,
        py: Python<'_>,
        value: T,
        field: fn(&mut CoreParticle) -> &mut T,
    ) -> PyResult<()> {
        let i = self.index;
        self.scene.bind(py).get().edit(
            |s| {
                let old = std::mem::replace(field(&mut s.particles[i]), value);
                Ok(move |s: &mut CoreScene| *field(&mut s.particles[i]) = old)
            },
            |s| s.validate_particle(i),
        )
    }
}

#[pymethods]
impl ParticleView {
    /// Position of the particle in the scene's list.
    #[getter]
    fn index(&self) -> usize {
        self.index
    }

    /// Mass, kg: a float, or `cordis.Unknown(min, max)` when it is to be identified.
    #[getter]
    fn mass(&self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        let m = self.read(py, |p| p.mass);
        param_to_py(py, &m)
    }

    #[setter]
    fn set_mass(&self, py: Python<'_>, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let m = param_from_py(value, &format!("particles[{}].mass", self.index))?;
        self.write(py, m, |p| &mut p.mass)
    }

    /// Initial position x(0), m, `(x, y, z)`.
    #[getter]
    fn pos(&self, py: Python<'_>) -> (f64, f64, f64) {
        let [x, y, z] = self.read(py, |p| p.pos);
        (x, y, z)
    }

    #[setter]
    fn set_pos(&self, py: Python<'_>, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let v = vec3(value, &format!("particles[{}].pos", self.index))?;
        self.write(py, v, |p| &mut p.pos)
    }

    /// Initial velocity v(0), m/s, `(vx, vy, vz)`.
    #[getter]
    fn vel(&self, py: Python<'_>) -> (f64, f64, f64) {
        let [x, y, z] = self.read(py, |p| p.vel);
        (x, y, z)
    }

    #[setter]
    fn set_vel(&self, py: Python<'_>, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let v = vec3(value, &format!("particles[{}].vel", self.index))?;
        self.write(py, v, |p| &mut p.vel)
    }

    /// A fixed particle never moves.
    #[getter]
    fn fixed(&self, py: Python<'_>) -> bool {
        self.read(py, |p| p.fixed)
    }

    #[setter]
    fn set_fixed(&self, py: Python<'_>, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let b = value.cast::<PyBool>().map_err(|_| {
            PyTypeError::new_err(format!(
                "particles[{}].fixed: expected a bool, got {}",
                self.index,
                type_name(value)
            ))
        })?;
        self.write(py, b.is_true(), |p| &mut p.fixed)
    }

    /// Group name (conditional link types pair particles by group), or None.
    #[getter]
    fn group(&self, py: Python<'_>) -> Option<String> {
        self.read(py, |p| p.group.clone())
    }

    #[setter]
    fn set_group(&self, py: Python<'_>, value: Option<String>) -> PyResult<()> {
        self.write(py, value, |p| &mut p.group)
    }

    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        let p = self.read(py, Clone::clone);
        let f = |v: f64| -> PyResult<String> { Ok(PyFloat::new(py, v).repr()?.to_string()) };
        let v3 = |v: [f64; 3]| -> PyResult<String> {
            Ok(format!("({}, {}, {})", f(v[0])?, f(v[1])?, f(v[2])?))
        };
        let mut s = format!(
            "Particle({}, mass={}, pos={}",
            self.index,
            shown(py, &p.mass)?,
            v3(p.pos)?
        );
        if p.vel != [0.0; 3] {
            s += &format!(", vel={}", v3(p.vel)?);
        }
        if p.fixed {
            s += ", fixed=True";
        }
        if let Some(g) = &p.group {
            s += &format!(", group={}", PyString::new(py, g).repr()?);
        }
        s.push(')');
        Ok(s)
    }
}

// ----------------------------------------------------------------------------------- types

/// `scene.types`: the catalogue as a mapping from type name to [`TypeView`] (in file order;
/// an int index works too).
#[pyclass(frozen, mapping, module = "cordis", name = "LinkTypes")]
pub struct Types {
    scene: Py<Scene>,
}

impl Types {
    pub fn new(scene: Py<Scene>) -> Self {
        Types { scene }
    }

    fn names(&self, py: Python<'_>) -> Vec<String> {
        let s = self.scene.bind(py).get().core();
        s.types.iter().map(|t| t.name.clone()).collect()
    }

    fn view(&self, py: Python<'_>, index: usize) -> TypeView {
        TypeView {
            scene: self.scene.clone_ref(py),
            index,
        }
    }

    fn lookup(&self, py: Python<'_>, key: &Bound<'_, PyAny>) -> PyResult<usize> {
        let names = self.names(py);
        if let Ok(name) = key.extract::<String>() {
            return names.iter().position(|n| *n == name).ok_or_else(|| {
                scene_key_error(
                    &format!("types.{name}"),
                    &format!(
                        "no link type of this name (the scene has: {})",
                        names.join(", ")
                    ),
                )
            });
        }
        if !key.is_instance_of::<PyBool>() {
            if let Ok(i) = key.extract::<isize>() {
                return index(i, names.len(), "types");
            }
        }
        Err(PyTypeError::new_err(format!(
            "types: expected a type name (str) or an index (int), got {}",
            type_name(key)
        )))
    }
}

#[pymethods]
impl Types {
    fn __len__(&self, py: Python<'_>) -> usize {
        self.names(py).len()
    }

    fn __getitem__(&self, py: Python<'_>, key: &Bound<'_, PyAny>) -> PyResult<TypeView> {
        let i = self.lookup(py, key)?;
        Ok(self.view(py, i))
    }

    fn __contains__(&self, py: Python<'_>, name: &Bound<'_, PyAny>) -> bool {
        name.extract::<String>()
            .is_ok_and(|n| self.names(py).contains(&n))
    }

    /// Iterates over the type names, as a dict does.
    fn __iter__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        Ok(PyList::new(py, self.names(py))?.try_iter()?.into_any())
    }

    /// The type names, in file order.
    fn keys(&self, py: Python<'_>) -> Vec<String> {
        self.names(py)
    }

    /// The type views, in file order.
    fn values(&self, py: Python<'_>) -> Vec<TypeView> {
        (0..self.__len__(py)).map(|i| self.view(py, i)).collect()
    }

    /// `(name, view)` pairs, in file order.
    fn items(&self, py: Python<'_>) -> Vec<(String, TypeView)> {
        self.names(py)
            .into_iter()
            .enumerate()
            .map(|(i, n)| (n, self.view(py, i)))
            .collect()
    }

    /// The view of type `name`, or `default` when there is none.
    #[pyo3(signature = (name, default = None))]
    fn get(&self, py: Python<'_>, name: &str, default: Option<Py<PyAny>>) -> PyResult<Py<PyAny>> {
        match self.names(py).iter().position(|n| n == name) {
            Some(i) => Ok(Py::new(py, self.view(py, i))?.into_any()),
            None => Ok(default.unwrap_or_else(|| py.None())),
        }
    }

    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        Ok(format!(
            "LinkTypes({})",
            PyList::new(py, self.names(py))?.repr()?
        ))
    }
}

/// One entry of the catalogue: a mapping from parameter name (`stiffness`, `rest_length`,
/// `damping`…, and a muscle's `w_len[k]`, `w_rate[k]`) to its value, shared by every link of
/// the type. Values are floats, or `cordis.Unknown(min, max)` for parameters to identify;
/// assignments write through to the scene and are validated.
///
/// >>> rib = scene.types["rib"]
/// >>> rib["stiffness"] = 120.0
/// >>> rib["damping"] = cordis.Unknown(0.0, 5.0)
/// >>> dict(rib)
/// {'stiffness': 120.0, 'rest_length': 1.0, 'damping': Unknown(0.0, 5.0)}
/// >>> rib["stifness"]   # SceneKeyError (a KeyError) listing the type's parameters
#[pyclass(frozen, mapping, module = "cordis", name = "LinkType")]
pub struct TypeView {
    scene: Py<Scene>,
    index: usize,
}

impl TypeView {
    fn read<R>(&self, py: Python<'_>, f: impl FnOnce(&CoreType) -> R) -> R {
        f(&self.scene.bind(py).get().core().types[self.index])
    }

    fn names(&self, py: Python<'_>) -> Vec<String> {
        self.read(py, |t| {
            (0..t.params.len()).map(|k| t.param_name(k)).collect()
        })
    }

    /// The slot of parameter `key`, or a `SceneKeyError` naming the type and the key.
    fn slot(&self, py: Python<'_>, key: &str) -> PyResult<usize> {
        let names = self.names(py);
        names.iter().position(|n| n == key).ok_or_else(|| {
            let (name, kind) = self.read(py, |t| (t.name.clone(), t.kind));
            scene_key_error(
                &format!("types.{name}.{key}"),
                &format!(
                    "`{kind}` types have no parameter `{key}` (they have: {})",
                    names.join(", ")
                ),
            )
        })
    }
}

#[pymethods]
impl TypeView {
    /// The type's name in the catalogue.
    #[getter]
    fn name(&self, py: Python<'_>) -> String {
        self.read(py, |t| t.name.clone())
    }

    /// The kind of link (`spring`, `anchor`, `angle`, `muscle`…).
    #[getter]
    fn kind(&self, py: Python<'_>) -> &'static str {
        self.read(py, |t| t.kind.name())
    }

    /// Number of listed links of this type.
    #[getter]
    fn num_links(&self, py: Python<'_>) -> usize {
        let s = self.scene.bind(py).get().core();
        s.links
            .iter()
            .filter(|l| l.type_index == self.index)
            .count()
    }

    /// Provot's critical deformation rate τc (springs only; None: no limit; an unknown τc
    /// reads as its starting value, `scene.types["rib"]["max_elongation"]` gives its box).
    /// Settable: `scene.types["rib"].max_elongation = None` removes the limit.
    #[getter]
    fn max_elongation(&self, py: Python<'_>) -> Option<f64> {
        self.read(py, |t| t.max_elongation().map(|p| p.value()))
    }

    #[setter]
    fn set_max_elongation(&self, py: Python<'_>, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let tau = if value.is_none() {
            None
        } else {
            let place = format!("types.{}.max_elongation", self.name(py));
            Some(number(value, &place)?)
        };
        let ti = self.index;
        let which = cordis_core::OptionalParam::MaxElongation;
        self.scene.bind(py).get().edit(
            |s| {
                let old = s.types[ti].optional_param(which).copied();
                s.types[ti].set_optional(which, tau.map(Into::into));
                Ok(move |s: &mut CoreScene| s.types[ti].set_optional(which, old))
            },
            |s| s.validate_type(ti),
        )
    }

    fn __len__(&self, py: Python<'_>) -> usize {
        self.read(py, |t| t.params.len())
    }

    fn __getitem__(&self, py: Python<'_>, key: &str) -> PyResult<Py<PyAny>> {
        let k = self.slot(py, key)?;
        let p = self.read(py, |t| t.params[k]);
        param_to_py(py, &p)
    }

    /// Sets a parameter: a number, or `cordis.Unknown(min, max[, init])` (or the JSON
    /// format's `{"min": …, "max": …}`) to make it identifiable.
    fn __setitem__(&self, py: Python<'_>, key: &str, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let k = self.slot(py, key)?;
        let place = format!("types.{}.{key}", self.name(py));
        let p = param_from_py(value, &place)?;
        let ti = self.index;
        self.scene.bind(py).get().edit(
            |s| {
                let old = std::mem::replace(&mut s.types[ti].params[k], p);
                Ok(move |s: &mut CoreScene| s.types[ti].params[k] = old)
            },
            |s| s.validate_type(ti),
        )
    }

    fn __contains__(&self, py: Python<'_>, key: &Bound<'_, PyAny>) -> bool {
        key.extract::<String>()
            .is_ok_and(|k| self.names(py).contains(&k))
    }

    /// Iterates over the parameter names, as a dict does.
    fn __iter__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        Ok(PyList::new(py, self.names(py))?.try_iter()?.into_any())
    }

    /// The parameter names, in parameter-vector order.
    fn keys(&self, py: Python<'_>) -> Vec<String> {
        self.names(py)
    }

    /// The values (floats or `Unknown`), in the order of `keys()`.
    fn values(&self, py: Python<'_>) -> PyResult<Vec<Py<PyAny>>> {
        let params = self.read(py, |t| t.params.clone());
        params.iter().map(|p| param_to_py(py, p)).collect()
    }

    /// `(name, value)` pairs, in the order of `keys()`.
    fn items(&self, py: Python<'_>) -> PyResult<Vec<(String, Py<PyAny>)>> {
        self.names(py)
            .into_iter()
            .zip(self.values(py)?)
            .map(Ok)
            .collect()
    }

    /// The value of `key`, or `default` when the type has no such parameter.
    #[pyo3(signature = (key, default = None))]
    fn get(&self, py: Python<'_>, key: &str, default: Option<Py<PyAny>>) -> PyResult<Py<PyAny>> {
        match self.names(py).iter().position(|n| n == key) {
            Some(k) => {
                let p = self.read(py, |t| t.params[k]);
                param_to_py(py, &p)
            }
            None => Ok(default.unwrap_or_else(|| py.None())),
        }
    }

    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        let (name, kind, params) = self.read(py, |t| (t.name.clone(), t.kind, t.params.clone()));
        let mut s = format!(
            "LinkType({}, kind='{kind}'",
            PyString::new(py, &name).repr()?
        );
        for (n, p) in self.names(py).iter().zip(&params) {
            s += &format!(", {n}={}", shown(py, p)?);
        }
        s.push(')');
        Ok(s)
    }
}
