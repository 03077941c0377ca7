//! Discovered graph → identified model (issue 20, `cordis discover --identify`): the scene
//! [`super::discover`] proposed, its link parameters (and the masses it found) made unknown in
//! boxes around the discovered values, fitted by the output-error estimator
//! ([`crate::output_error`]) to the same motion.
//!
//! Discovery's parameters come from the short cost on smoothed positions: under noise they are
//! biased by the smoothing (a few % at 1e-4 of the size). The output-error fit never
//! differentiates the data, so it starts from the discovered values and moves to the
//! maximum-likelihood estimate, with standard errors and 95 % intervals.
//!
//! - **Refused** when the discovery named anything as not determined (a mass group, a damper's
//!   end): the graph or the mass scale is then not what the data say, and a fit on it would
//!   be a confident answer to the wrong question. The error names each item.
//! - **Boxes**: every positive link parameter in `[v / 2, 2 v]` ([`BOX_WIDTH`] = 4, max/min)
//!   around its discovered value, which is the fit's start; a damping discovery judged 0
//!   stays known at 0. Discovered masses likewise, but one (the first moving particle's,
//!   [`Identified::reference`]) is held: masses and force parameters share one scale (thesis
//!   §3.3), and the output-error fit has no constraint `Σm = M`. The held mass fixes the scale
//!   (the gauge); the fit's optimum is then rescaled so that the moving masses sum to the
//!   given total — stiffnesses, dampings and masses times `M / Σm`, rest lengths unchanged.
//!   Scaling masses and forces together leaves every acceleration, hence the motion and the
//!   likelihood, unchanged: this is the maximum-likelihood estimate under the total, and its
//!   covariance is the gauge fit's carried through the rescaling (first order, the delta
//!   method), the held mass included.
//! - **Gravity** is fitted too, in a box around the discovered value ([`GRAVITY_BOX`]): the
//!   discovered one reads smoothed accelerations and is biased under noise (1.6 % on a
//!   generated network at 1e-4), and a fit held at it stays above the noise (seeds 6, 13, 34:
//!   every fit `above_noise`; fitted: every one converged). Held when none was found (0),
//!   when given (`gravity_given`), or when the fit is too large for the dense path.
//! - **Noise level**: a given one (`--noise-level`, `opt.noise_level`) is the estimator's
//!   too: its windows are judged clean against it, and it is the level reported; otherwise the
//!   estimator reads its own from the take's third differences.
//! - **Status**: `converged` only when the estimator's last window met its own criterion.

use cordis_core::{Param, Scene};
use nalgebra::DMatrix;
use serde::Serialize;

use super::{DiscoverOptions, Discovery};
use crate::error::CostError;
use crate::output_error::{self, box_interval, interval95, Config, Estimate, Take};
use crate::report::undetermined_lines;
use crate::space::{ParameterSpace, Role, Unknown};
use cordis_core::Trajectory;

/// Ratio max/min of the boxes around the discovered values: `[v/2, 2v]`. Discovery's
/// parameters at noise 1e-4 of the size are within a few % (docs/discover.md), at 1e-3 within
/// ~20 % (BENCHMARKS.md): a factor 2 holds the truth with room, and keeps a stiffness within
/// 2× of one the discovered network ran stably at.
pub const BOX_WIDTH: f64 = 4.0;

/// Half-width of gravity's box around the discovered value, relative to its norm: discovery's
/// gravity at noise 1e-4 of the size is ~2 % off (its intercepts read smoothed accelerations),
/// at 1e-3 ~10 % (BENCHMARKS.md).
pub const GRAVITY_BOX: f64 = 0.25;

/// One identified unknown.
#[derive(Clone, Debug, Serialize)]
pub struct IdentifiedParam {
    /// `types.NAME.PARAM` or `particles[i].mass`.
    pub name: String,
    /// The discovered value (the fit's start), and the identified one, in the unit of the
    /// parameter (N/m, m, N·s/m, kg).
    pub discovered: f64,
    pub value: f64,
    /// Standard error (inf: not determined) and the 95 % interval (`value ± 1.96 se`, on
    /// `ln value` for a positive log-searched one: `output_error::interval95`); a not
    /// determined unknown's interval is its box (the data do not narrow it), as
    /// `cordis identify` reports it; the held reference mass, which has no box, `[0, inf]`.
    /// Non-finite values are written `"inf"` in JSON, as
    /// `identify`'s `std_error`, never `null`.
    #[serde(with = "crate::run::float_json::lossless")]
    pub stderr: f64,
    #[serde(with = "crate::run::float_json::lossless")]
    pub low: f64,
    #[serde(with = "crate::run::float_json::lossless")]
    pub high: f64,
    /// The fit ended on the edge of this unknown's box (a damping's floor 0 excepted): the
    /// box, not the data, stopped it (the interval says nothing about the values beyond).
    pub at_bound: bool,
}

/// What [`identify_discovered`] found.
#[derive(Clone, Debug, Serialize)]
pub struct Identified {
    /// The identified scene: every value known, the estimated initial state.
    #[serde(skip)]
    pub scene: Scene,
    pub params: Vec<IdentifiedParam>,
    /// The estimator's own status: `converged` only when its criterion held; else `budget`,
    /// `stalled`, `above_noise`.
    pub end: &'static str,
    pub converged: bool,
    /// Weighted sum of squared position residuals (m²), σ̂ (m), and the noise level the fit
    /// was judged against (m): the given one, else read from the data before the fit.
    pub position_cost: f64,
    pub sigma: f64,
    pub noise_level: f64,
    /// Directions the data do not determine, by the names of the variables each moves.
    pub undetermined: Vec<Vec<String>>,
    /// Gravity was fitted (its three components are among `params`).
    pub gravity_fitted: bool,
    /// The moving particle whose mass fixed the scale before the rescaling to the total.
    pub reference: Option<usize>,
    pub windows: Vec<usize>,
    pub iterations: usize,
    pub evaluations: usize,
    pub start: String,
}

impl Identified {
    /// The summary's `identify` object (CLI JSON line, Python `res.identification`): every
    /// field, with `warnings` (its [`Identified::warnings`], computed once by the caller, who
    /// also prints or raises them).
    pub fn to_json(&self, warnings: &[String]) -> serde_json::Value {
        let mut v = serde_json::to_value(self).unwrap_or_default();
        v["warnings"] = warnings.into();
        v
    }

    /// What a user must read before trusting the identified scene, one line each (the CLI's
    /// `warning:` lines, Python's `warnings.warn`): unknowns on their box's edge, what the
    /// motion does not determine, a model beyond the stability bound, a fit that did not
    /// converge.
    pub fn warnings(&self) -> Vec<String> {
        let mut w = Vec::new();
        let edge: Vec<&str> = self
            .params
            .iter()
            .filter(|p| p.at_bound)
            .map(|p| p.name.as_str())
            .collect();
        if !edge.is_empty() {
            w.push(format!(
                "ended on the edge of its box (the discovered value was off by 2x or more, or \
                 the graph is wrong): {}",
                edge.join(", ")
            ));
        }
        w.extend(undetermined_lines(&self.undetermined, |n| {
            self.params.iter().any(|p| p.name == n)
        }));
        w.extend(crate::stable::beyond_bound_warning(&self.scene));
        if !self.converged {
            w.push(format!(
                "the identification did not converge (end {}): its parameters are the best \
                 point reached, not an estimate",
                self.end
            ));
        }
        w
    }
}

/// Fits the discovered scene `d`'s link parameters, gravity and masses to `traj` by
/// output-error (module docs). `opt` are the options `d` was discovered with: masses it was
/// given (`opt.masses`) and a given gravity stay known; discovered masses are fitted under
/// `opt.total_mass`.
pub fn identify_discovered(
    traj: &Trajectory,
    d: &Discovery,
    opt: &DiscoverOptions,
) -> Result<Identified, CostError> {
    identify_discovered_until(traj, d, opt, &|| false)
        .map(|id| id.expect("a fit that is never halted finishes"))
}

/// [`identify_discovered`], stopped between two of the fit's steps when `halt()` turns true
/// (Ctrl-C): `None` then. A stopped fit has not reached the whole take, so it has no estimate
/// to report (the output-error fit's windows before the last see part of the motion only).
pub fn identify_discovered_until(
    traj: &Trajectory,
    d: &Discovery,
    opt: &DiscoverOptions,
    halt: &dyn Fn() -> bool,
) -> Result<Option<Identified>, CostError> {
    let total_mass = opt.total_mass;
    let masses_discovered = opt.masses.is_none();
    if !d.undetermined.is_empty() {
        let what: Vec<String> = d.undetermined.iter().map(|u| u.line()).collect();
        return Err(CostError::invalid(
            "identify",
            format!(
                "the discovery did not determine everything ({}): refused rather than fit a \
                 graph the data do not decide",
                what.join("; ")
            ),
        ));
    }
    let (scene, reference) = with_boxes(&d.scene, masses_discovered && total_mass.is_some())?;
    let mut space = ParameterSpace::from_scene(&scene);
    let gravity_unknown = opt.gravity.is_none()
        && with_gravity(
            &scene,
            &mut space,
            crate::output_error::matrix_free::DENSE_MAX_COLUMNS,
        );
    let config = Config {
        start: Some(space.genome_of(&d.scene.param_values())),
        noise_level: opt.noise_level,
        ..Config::default()
    };
    let take = Take::complete(&traj.clone().with_dt(d.scene.dt));
    let Some(e) = output_error::estimate_until(&scene, &space, &[take], &config, halt)? else {
        return Ok(None);
    };
    let discovered = d.scene.param_values();
    let (params, cov, slot_scale) = match (reference, total_mass) {
        (Some(r), Some(m)) => rescaled(&scene, &space, &e, r, m),
        _ => (
            e.params.clone(),
            e.covariance.clone(),
            vec![1.0; e.params.len()],
        ),
    };
    let mut out = output_error::identified_scene(&scene, &e, 0);
    out.set_param_values(&params);
    let mut rows: Vec<IdentifiedParam> = space
        .unknowns
        .iter()
        .enumerate()
        .map(|(a, u)| {
            let mut r = row(
                &u.name,
                discovered[u.slot],
                params[u.slot],
                cov[(a, a)],
                u.log,
            );
            // Not determined: the box, in the reported unit (rescaled as the value is).
            let k = slot_scale[u.slot];
            (r.low, r.high) = box_interval((r.low, r.high), r.stderr, (u.min * k, u.max * k));
            r.at_bound = u.on_box_edge(e.genome[a]);
            r
        })
        .collect();
    if let Some(r) = reference {
        let slot = scene.param_layout().mass_offset + r;
        let k = space.dim();
        rows.push(row(
            &format!("particles[{r}].mass"),
            discovered[slot],
            params[slot],
            cov[(k, k)],
            true,
        ));
    }
    Ok(Some(Identified {
        scene: out,
        params: rows,
        end: e.end,
        converged: e.converged,
        position_cost: e.cost,
        sigma: e.sigma,
        noise_level: e.noise_level.first().copied().unwrap_or(0.0),
        undetermined: e.undetermined.clone(),
        gravity_fitted: gravity_unknown,
        reference,
        windows: e.windows.clone(),
        iterations: e.iterations,
        evaluations: e.evaluations,
        start: e.start.clone(),
    }))
}

/// Makes gravity's three components unknown in `g ± GRAVITY_BOX |g|` around the discovered
/// value (the start), unless it is 0 (none found) or the fit would have more than
/// `max_columns` variables (the dense path is the only one with gravity's sensitivities):
/// returns whether it did.
pub(super) fn with_gravity(scene: &Scene, space: &mut ParameterSpace, max_columns: usize) -> bool {
    let g = scene.gravity;
    let norm = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
    let free = scene.particles.iter().filter(|p| !p.fixed).count();
    let columns = space.dim() + 3 + 6 * free;
    if norm == 0.0 || columns > max_columns {
        return false;
    }
    let go = scene.param_layout().gravity_offset;
    for (c, axis) in ["x", "y", "z"].iter().enumerate() {
        space.unknowns.push(Unknown {
            name: format!("gravity.{axis}"),
            slot: go + c,
            type_index: None,
            role: Role::Gravity,
            min: g[c] - GRAVITY_BOX * norm,
            max: g[c] + GRAVITY_BOX * norm,
            init: Some(g[c]),
            log: false,
        });
    }
    true
}

/// `log`: the value is positive and searched in log coordinates (its interval on `ln value`).
fn row(name: &str, discovered: f64, value: f64, var: f64, log: bool) -> IdentifiedParam {
    let se = if var.is_nan() {
        f64::INFINITY
    } else {
        var.sqrt()
    };
    let (low, high) = interval95(value, se, log);
    IdentifiedParam {
        name: name.to_string(),
        discovered,
        value,
        stderr: se,
        low,
        high,
        at_bound: false,
    }
}

/// The discovered scene with its positive link parameters unknown in [`BOX_WIDTH`] boxes and,
/// when `masses`, every moving particle's mass but the first one's (the reference, returned).
fn with_boxes(found: &Scene, masses: bool) -> Result<(Scene, Option<usize>), CostError> {
    let mut scene = cordis_core::from_markers::with_unknowns(found, BOX_WIDTH)?;
    let m_min = found
        .particles
        .iter()
        .filter(|p| !p.fixed)
        .map(|p| p.mass.value())
        .fold(f64::INFINITY, f64::min);
    for ty in &mut scene.types {
        let names: Vec<String> = (0..ty.params.len()).map(|k| ty.param_name(k)).collect();
        let k = names
            .iter()
            .position(|n| n == "stiffness")
            .map(|s| ty.params[s].value());
        for (p, name) in ty.params.iter_mut().zip(&names) {
            if let (Param::Known(z), "damping", Some(k)) = (*p, name.as_str(), k) {
                if z == 0.0 && k > 0.0 && m_min.is_finite() {
                    *p = Param::Unknown(cordis_core::Bounds {
                        min: 0.0,
                        max: 2.0 * (k * BOX_WIDTH.sqrt() * m_min).sqrt(),
                        init: Some(0.0),
                    });
                }
            }
        }
    }
    let mut reference = None;
    if masses {
        let sw = BOX_WIDTH.sqrt();
        for (i, p) in scene.particles.iter_mut().enumerate() {
            let m = p.mass.value();
            if p.fixed || m.is_nan() || m <= 0.0 {
                continue;
            }
            if reference.is_none() {
                reference = Some(i);
                continue;
            }
            p.mass = Param::Unknown(cordis_core::Bounds {
                min: m / sw,
                max: m * sw,
                init: Some(m),
            });
        }
    }
    Ok((scene, reference))
}

/// The sum of `scene`'s moving masses in the parameter vector `params`, kg.
pub(super) fn moving_mass(scene: &Scene, params: &[f64]) -> f64 {
    let offset = scene.param_layout().mass_offset;
    (0..scene.num_particles())
        .filter(|&i| !scene.particles[i].fixed)
        .map(|i| params[offset + i])
        .sum()
}

/// The estimate rescaled so that the moving masses sum to `total` (module docs), and the
/// covariance carried through: the unknowns' block, then one more row and column for the
/// reference mass `r`. A variance that depends on an undetermined one is infinite. Last, each
/// parameter slot's factor (`total / Σm` for the masses, stiffnesses and dampings, else 1).
fn rescaled(
    scene: &Scene,
    space: &ParameterSpace,
    e: &Estimate,
    r: usize,
    total: f64,
) -> (Vec<f64>, DMatrix<f64>, Vec<f64>) {
    let layout = scene.param_layout();
    let sum = moving_mass(scene, &e.params);
    let c = total / sum;
    // Which slots scale with the masses: every stiffness and damping, every moving mass.
    let mut scales = vec![false; layout.len];
    for (t, ty) in scene.types.iter().enumerate() {
        for k in 0..ty.params.len() {
            let name = ty.param_name(k);
            scales[layout.type_offsets[t] + k] = name == "stiffness" || name == "damping";
        }
    }
    for (i, p) in scene.particles.iter().enumerate() {
        scales[layout.mass_offset + i] = !p.fixed;
    }
    let params: Vec<f64> = e
        .params
        .iter()
        .zip(&scales)
        .map(|(v, &s)| if s { v * c } else { *v })
        .collect();
    // J: rows the unknowns then the reference mass, columns the unknowns.
    let dim = space.dim();
    let dc: Vec<f64> = space
        .unknowns
        .iter()
        .map(|u| {
            if u.role == Role::Mass {
                -total / (sum * sum)
            } else {
                0.0
            }
        })
        .collect();
    let mut j = DMatrix::zeros(dim + 1, dim);
    for (a, u) in space.unknowns.iter().enumerate() {
        let s = scales[u.slot];
        for b in 0..dim {
            let own = if a == b {
                if s {
                    c
                } else {
                    1.0
                }
            } else {
                0.0
            };
            j[(a, b)] = own + if s { e.params[u.slot] * dc[b] } else { 0.0 };
        }
    }
    let m_ref = e.params[layout.mass_offset + r];
    for b in 0..dim {
        j[(dim, b)] = m_ref * dc[b];
    }
    let finite = DMatrix::from_fn(dim, dim, |a, b| {
        let v = e.covariance[(a, b)];
        if v.is_finite() {
            v
        } else {
            0.0
        }
    });
    let mut cov = &j * finite * j.transpose();
    for a in 0..=dim {
        let through_undetermined =
            (0..dim).any(|b| j[(a, b)] != 0.0 && !e.covariance[(b, b)].is_finite());
        if through_undetermined {
            cov[(a, a)] = f64::INFINITY;
        }
    }
    let slot_scale = scales.iter().map(|&s| if s { c } else { 1.0 }).collect();
    (params, cov, slot_scale)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What `discover --identify` and Python's discover warn of, each once, in order: the
    /// unknowns on their box's edge, the undetermined directions (8 lines, then one for the
    /// rest: the soft block's degenerate budget end printed 117), a model beyond the
    /// stability bound, an unconverged end.
    #[test]
    fn a_discovered_fits_warnings_name_the_edge_the_directions_the_bound_and_the_end() {
        let mut scene = cordis_core::examples::rigid();
        let mut edge = row("types.a.stiffness", 10.0, 20.0, 0.5, true);
        edge.at_bound = true;
        let names: Vec<String> = (0..12).map(|k| format!("types.t{k}.stiffness")).collect();
        let id = |scene: Scene| Identified {
            scene,
            params: std::iter::once(edge.clone())
                .chain(names.iter().map(|n| row(n, 1.0, 1.0, f64::NAN, true)))
                .collect(),
            end: "budget",
            converged: false,
            position_cost: 1.0,
            sigma: 1e-2,
            noise_level: 1e-3,
            undetermined: names.iter().map(|n| vec![n.clone()]).collect(),
            gravity_fitted: false,
            reference: None,
            windows: vec![],
            iterations: 0,
            evaluations: 0,
            start: String::new(),
        };
        let w = id(scene.clone()).warnings();
        assert_eq!(w.len(), 1 + 9 + 1, "{w:?}");
        assert!(
            w[0].starts_with("ended on the edge of its box") && w[0].ends_with("types.a.stiffness")
        );
        assert!(
            w[9].starts_with("not determined by the data: 4 more directions"),
            "{}",
            w[9]
        );
        assert!(w[10].starts_with("the identification did not converge (end budget)"));
        for p in &mut scene.particles {
            p.mass = Param::Known(p.mass.value() / 3.0);
        }
        let w = id(scene).warnings();
        assert!(
            w[10].starts_with("the identified model is beyond the stability bound"),
            "{w:?}"
        );
    }

    /// An undetermined unknown's JSON once read `"stderr": null, "high": null` (serde writes
    /// infinities as null, which reads back as "missing", and Python got None).
    #[test]
    fn a_not_determined_rows_infinities_are_written_as_strings_not_null() {
        let mut r = row("types.a.stiffness", 10.0, 12.0, f64::NAN, true);
        assert!(r.stderr.is_infinite() && r.high.is_infinite());
        let v = serde_json::to_value(&r).unwrap();
        assert_eq!(v["stderr"], "inf");
        assert_eq!(v["high"], "inf");
        (r.low, r.high) = (1.0, 100.0);
        let v = serde_json::to_value(&r).unwrap();
        assert_eq!(
            (v["low"].as_f64(), v["high"].as_f64()),
            (Some(1.0), Some(100.0))
        );
    }
}
