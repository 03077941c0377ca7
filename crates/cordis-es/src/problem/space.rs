//! The search space of an identification: which scalars of a scene are unknown, their boxes,
//! and how strategies move in them.
//!
//! Strategies work in *internal* coordinates: `z = ln v` for a parameter whose box is strictly
//! positive and spans more than a decade (stiffness-, damping- and mass-like: their scale is
//! unknown, so relative steps make sense), `z = v` otherwise (rest lengths, cosines, ranges).
//! A genome is a vector of internal coordinates; [`ParameterSpace::fill_params`] turns it into
//! the flat parameter vector of [`cordis_core::ParamLayout`] that costs read.

use cordis_core::{Param, Scene};

/// What a parameter is, for heuristics (initialisation, error report).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    Stiffness,
    RestLength,
    Damping,
    RestCos,
    Range,
    /// v_max of a nonlinear drag.
    Speed,
    /// Provot's critical deformation rate τc (`max_elongation`, 1).
    Elongation,
    Mass,
    /// A component of gravity, m/s² (output-error only: `cordis discover --identify`).
    Gravity,
    /// A muscle neuron's gain, threshold or weight (SPEC §2.4): any sign for the last two.
    Neural,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Unknown {
    /// `types.NAME.PARAM` or `particles[i].mass`.
    pub name: String,
    /// Index in the flat parameter vector.
    pub slot: usize,
    /// The link type it belongs to (None for masses).
    pub type_index: Option<usize>,
    pub role: Role,
    pub min: f64,
    pub max: f64,
    pub init: Option<f64>,
    /// Searched as `ln v`.
    pub log: bool,
}

impl Unknown {
    pub fn to_internal(&self, v: f64) -> f64 {
        if self.log {
            v.ln()
        } else {
            v
        }
    }

    /// The value of an internal coordinate, clamped into the box.
    pub fn from_internal(&self, z: f64) -> f64 {
        let v = if self.log { z.exp() } else { z };
        if v.is_nan() {
            return self.min;
        }
        v.clamp(self.min, self.max)
    }

    /// Box in internal coordinates.
    pub fn internal_bounds(&self) -> (f64, f64) {
        (self.to_internal(self.min), self.to_internal(self.max))
    }

    /// Whether the internal coordinate `z` sits on an edge of the box (within 1e-9 of its
    /// width): the data pull the estimate further. A lower edge of 0 is physics (a damping
    /// found absent), not the box, so it does not count.
    pub fn on_box_edge(&self, z: f64) -> bool {
        let (lo, hi) = self.internal_bounds();
        let tol = 1e-9 * (hi - lo).abs();
        z >= hi - tol || (self.min != 0.0 && z <= lo + tol)
    }

    /// Clamps an internal coordinate into the box.
    pub fn clamp_internal(&self, z: f64) -> f64 {
        let (lo, hi) = self.internal_bounds();
        if z.is_nan() {
            return lo;
        }
        z.clamp(lo, hi)
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct ParameterSpace {
    pub unknowns: Vec<Unknown>,
    /// The scene's parameter vector with every known value in place (unknown slots hold their
    /// starting value until a genome fills them).
    pub base: Vec<f64>,
    /// Known total mass of the free particles, kg (thesis §3.3: with free masses, masses and
    /// stiffnesses are only determined up to a common scale; a fixed total removes it). Fixed
    /// particles never move, so their masses enter no cost and are not counted.
    pub total_mass: Option<f64>,
}

impl ParameterSpace {
    /// Every `{"min", "max"}` parameter of the scene, in catalogue order then particle order.
    pub fn from_scene(scene: &Scene) -> Self {
        let layout = scene.param_layout();
        let mut unknowns = Vec::new();
        for (t, ty) in scene.types.iter().enumerate() {
            for (k, p) in ty.params.iter().enumerate() {
                if let Param::Unknown(b) = p {
                    let pname = ty.param_name(k);
                    let role = match pname.as_str() {
                        "stiffness" => Role::Stiffness,
                        "rest_length" => Role::RestLength,
                        "rest_cos" => Role::RestCos,
                        "range" => Role::Range,
                        "v_max" => Role::Speed,
                        "max_elongation" => Role::Elongation,
                        "gain" | "threshold" => Role::Neural,
                        w if w.starts_with("w_") => Role::Neural,
                        _ => Role::Damping, // damping, z1, z2, damping_quadratic
                    };
                    unknowns.push(Unknown {
                        name: format!("types.{}.{}", ty.name, pname),
                        slot: layout.type_offsets[t] + k,
                        type_index: Some(t),
                        role,
                        min: b.min,
                        max: b.max,
                        init: b.init,
                        log: is_log(b.min, b.max),
                    });
                }
            }
        }
        for (i, p) in scene.particles.iter().enumerate() {
            if let Param::Unknown(b) = &p.mass {
                unknowns.push(Unknown {
                    name: format!("particles[{i}].mass"),
                    slot: layout.mass_offset + i,
                    type_index: None,
                    role: Role::Mass,
                    min: b.min,
                    max: b.max,
                    init: b.init,
                    log: is_log(b.min, b.max),
                });
            }
        }
        ParameterSpace {
            unknowns,
            base: scene.param_values(),
            total_mass: None,
        }
    }

    /// Number of unknowns (genome length).
    pub fn dim(&self) -> usize {
        self.unknowns.len()
    }

    /// Removes the named unknowns (thesis `.lock`): they keep their starting value.
    pub fn lock(&mut self, names: &[String]) {
        self.unknowns.retain(|u| !names.contains(&u.name));
    }

    /// Writes the parameter vector of a genome (internal coordinates) into `out`.
    pub fn fill_params(&self, genome: &[f64], out: &mut [f64]) {
        out.copy_from_slice(&self.base);
        for (u, &z) in self.unknowns.iter().zip(genome) {
            out[u.slot] = u.from_internal(z);
        }
    }

    /// Values (not internal coordinates) of a genome.
    pub fn values(&self, genome: &[f64]) -> Vec<f64> {
        self.unknowns
            .iter()
            .zip(genome)
            .map(|(u, &z)| u.from_internal(z))
            .collect()
    }

    /// Internal coordinates of the values read from a parameter vector (e.g. the truth).
    pub fn genome_of(&self, params: &[f64]) -> Vec<f64> {
        self.unknowns
            .iter()
            .map(|u| u.to_internal(params[u.slot]))
            .collect()
    }

    /// Mean relative error (%) of a genome's values against the truth's parameter vector.
    pub fn error_pct(&self, genome: &[f64], truth: &[f64]) -> f64 {
        if self.unknowns.is_empty() {
            return 0.0;
        }
        let sum: f64 = self
            .unknowns
            .iter()
            .zip(genome)
            .map(|(u, &z)| {
                let v = u.from_internal(z);
                let t = truth[u.slot];
                if t == 0.0 {
                    v.abs()
                } else {
                    ((v - t) / t).abs()
                }
            })
            .sum();
        100.0 * sum / self.unknowns.len() as f64
    }

    /// The scene with a genome's values written in as known numbers.
    pub fn scene_with(&self, scene: &Scene, genome: &[f64]) -> Scene {
        let mut p = vec![0.0; self.base.len()];
        self.fill_params(genome, &mut p);
        let mut out = scene.clone();
        out.set_param_values(&p);
        out
    }
}

fn is_log(min: f64, max: f64) -> bool {
    min > 0.0 && max > 10.0 * min
}
