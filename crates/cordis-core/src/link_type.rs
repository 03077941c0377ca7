//! Catalogue entries (thesis `.cat`): a link type shared by all its instances.

use crate::{LinkKind, Param};

/// A named entry of the catalogue. All links of a type share its parameters, so identification
/// works on the catalogue (SPEC §2.3).
#[derive(Clone, Debug, PartialEq)]
pub struct LinkType {
    pub name: String,
    pub kind: LinkKind,
    /// Scalar parameters in the order of [`LinkKind::param_specs`].
    pub params: Vec<Param>,
    /// Provot's critical deformation rate τc (springs only, thesis §4.2).
    pub max_elongation: Option<f64>,
    /// Anchor point in m (anchors only). When absent, each anchor link uses its own `point`, or
    /// the particle's initial position.
    pub point: Option<[f64; 3]>,
    /// Particle groups whose pairs a conditional type links (one or two names).
    pub groups: Vec<String>,
}

impl LinkType {
    /// A type with every parameter at its default (required ones at 0), to be filled in.
    pub fn new(name: impl Into<String>, kind: LinkKind) -> Self {
        LinkType {
            name: name.into(),
            kind,
            params: kind
                .param_specs()
                .iter()
                .map(|(_, d)| Param::Known(d.unwrap_or(0.0)))
                .collect(),
            max_elongation: None,
            point: None,
            groups: Vec::new(),
        }
    }

    /// Sets a named scalar parameter (builder style). Panics on a name the kind lacks: this is
    /// for code that builds scenes, not for parsing user input.
    pub fn with(mut self, name: &str, value: impl Into<Param>) -> Self {
        let i = self
            .kind
            .param_index(name)
            .unwrap_or_else(|| panic!("{} has no parameter {name}", self.kind));
        self.params[i] = value.into();
        self
    }

    pub fn param(&self, name: &str) -> Option<&Param> {
        self.kind.param_index(name).map(|i| &self.params[i])
    }

    pub fn value(&self, name: &str) -> Option<f64> {
        self.param(name).map(Param::value)
    }
}

/// One instance of a link type between particles (1, 2 or 3 of them by kind).
#[derive(Clone, Debug, PartialEq)]
pub struct Link {
    /// Index of the type in the scene's catalogue.
    pub type_index: usize,
    pub particles: Vec<usize>,
    /// Anchor point of this instance (anchors only), overriding the type's.
    pub point: Option<[f64; 3]>,
}
