//! Where each scalar of a scene lives in a flat parameter vector.
//!
//! Compiled plans read their parameters from a `&[f64]` laid out as: every type's scalar
//! parameters in catalogue order ([`crate::LinkKind::param_specs`] order within a type), then
//! one mass per particle, then gravity (3). Identification changes this vector, never the plan.

use crate::{Param, Scene};

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ParamLayout {
    /// Offset of each type's first parameter.
    pub type_offsets: Vec<usize>,
    /// Offset of particle 0's mass.
    pub mass_offset: usize,
    /// Offset of gravity's x component.
    pub gravity_offset: usize,
    /// Length of the vector.
    pub len: usize,
}

impl ParamLayout {
    pub fn of(scene: &Scene) -> Self {
        let mut type_offsets = Vec::with_capacity(scene.types.len());
        let mut at = 0;
        for t in &scene.types {
            type_offsets.push(at);
            at += t.params.len();
        }
        let mass_offset = at;
        let gravity_offset = mass_offset + scene.particles.len();
        ParamLayout {
            type_offsets,
            mass_offset,
            gravity_offset,
            len: gravity_offset + 3,
        }
    }

    /// Offset of a named parameter of type `t`.
    pub fn param(&self, scene: &Scene, t: usize, name: &str) -> Option<usize> {
        scene.types[t]
            .kind
            .param_index(name)
            .map(|k| self.type_offsets[t] + k)
    }
}

impl Scene {
    pub fn param_layout(&self) -> ParamLayout {
        ParamLayout::of(self)
    }

    /// The scene's parameter vector (unknowns at [`Param::value`]).
    pub fn param_values(&self) -> Vec<f64> {
        let mut p = Vec::with_capacity(self.param_layout().len);
        for t in &self.types {
            p.extend(t.params.iter().map(Param::value));
        }
        p.extend(self.particles.iter().map(|q| q.mass.value()));
        p.extend_from_slice(&self.gravity);
        p
    }

    /// Writes a parameter vector back into the scene as known values (identification's output).
    pub fn set_param_values(&mut self, p: &[f64]) {
        let layout = self.param_layout();
        assert_eq!(p.len(), layout.len, "parameter vector of the wrong length");
        for (t, off) in self.types.iter_mut().zip(&layout.type_offsets) {
            for (k, q) in t.params.iter_mut().enumerate() {
                *q = Param::Known(p[off + k]);
            }
        }
        for (i, q) in self.particles.iter_mut().enumerate() {
            q.mass = Param::Known(p[layout.mass_offset + i]);
        }
        self.gravity
            .copy_from_slice(&p[layout.gravity_offset..layout.gravity_offset + 3]);
    }
}
