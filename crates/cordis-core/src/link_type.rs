//! Catalogue entries (thesis `.cat`): a link type shared by all its instances.
//!
//! **Muscle weights** (SPEC §2.4, thesis eq 5.5) belong to the type, like every other
//! parameter: all instances of a muscle type share one neuron design, so identification sees
//! each weight once. A muscle type with M weights per input lists, in `params`, its five
//! scalars (`stiffness, rest_length, damping, gain, threshold`), then `w_len[0..M]`, then
//! `w_rate[0..M]`; weight k applies to the k-th link its instance observes. Every instance of
//! the type must observe exactly M links. The thesis' muscle experiment (§6.2) has one type
//! per muscle, so per-type weights are also per-muscle weights there.

use crate::{LinkKind, Param};

/// A scalar parameter a type carries only when its file gives it, after the kind's
/// [`LinkKind::param_specs`] in `params` (in the order of [`LinkType::optional`]), so a scene
/// without it keeps its parameter vector — and its motion — bit for bit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OptionalParam {
    /// Provot's critical deformation rate τc (springs, thesis §4.2; 1): the limit `(1 + τc) l0`.
    MaxElongation,
    /// The quadratic viscosity Z₂ (N·s²/m², springs and conditional links, thesis §4.3's
    /// "visc n.l"): the force along the link gains `Z₂ s |s|`.
    DampingQuadratic,
    /// A TGR tendon's position at frame 0, m (relative to its anchor: 0 for a signal-driven
    /// tendon, the controller dipole's length for a controlled one); default 0, at the anchor.
    /// A take cropped mid-motion starts with its tendons where the motion left them: this and
    /// [`OptionalParam::TendonVelocity`] say where, known or as unknowns to identify.
    TendonPosition,
    /// A TGR tendon's velocity at frame 0, m/s (`y(-1) = y(0) - v dt`); default 0, at rest.
    TendonVelocity,
}

impl OptionalParam {
    pub const ALL: [OptionalParam; 4] = [
        OptionalParam::MaxElongation,
        OptionalParam::DampingQuadratic,
        OptionalParam::TendonPosition,
        OptionalParam::TendonVelocity,
    ];

    /// The key in a scene file.
    pub fn name(self) -> &'static str {
        match self {
            OptionalParam::MaxElongation => "max_elongation",
            OptionalParam::DampingQuadratic => "damping_quadratic",
            OptionalParam::TendonPosition => "tendon_position",
            OptionalParam::TendonVelocity => "tendon_velocity",
        }
    }

    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|o| o.name() == name)
    }

    /// The kinds whose types may carry it.
    pub fn kinds(self) -> &'static [LinkKind] {
        match self {
            OptionalParam::MaxElongation => &[LinkKind::Spring],
            OptionalParam::DampingQuadratic => &[LinkKind::Spring, LinkKind::Conditional],
            OptionalParam::TendonPosition | OptionalParam::TendonVelocity => &[LinkKind::Tgr],
        }
    }
}

/// A named entry of the catalogue. All links of a type share its parameters, so identification
/// works on the catalogue (SPEC §2.3).
#[derive(Clone, Debug, PartialEq)]
pub struct LinkType {
    pub name: String,
    pub kind: LinkKind,
    /// Scalar parameters in the order of [`LinkKind::param_specs`].
    pub params: Vec<Param>,
    /// The optional parameters present, in their order in `params` after the spec ones
    /// (see [`OptionalParam`]; read them with [`LinkType::optional_param`]).
    pub optional: Vec<OptionalParam>,
    /// Anchor point in m (anchors only). When absent, each anchor link uses its own `point`, or
    /// the particle's initial position. Planes: a point of the surface, m (required).
    pub point: Option<[f64; 3]>,
    /// Planes only (required): the outward normal of the surface, pointing from the solid into
    /// the free space; any non-zero length, normalised when the scene is compiled.
    pub normal: Option<[f64; 3]>,
    /// Particle groups whose pairs a conditional type links (one or two names).
    pub groups: Vec<String>,
    /// Muscles only: the link indices every instance of the type observes, in weight order
    /// (overridden by a link's own `observes`). Default: every other muscle link, file order.
    pub observes: Option<Vec<usize>>,
    /// TGR types only: the name of the scene signal that drives their tendons (optional when
    /// every coupling of the type has a `controller`).
    pub signal: Option<String>,
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
            optional: Vec::new(),
            point: None,
            normal: None,
            groups: Vec::new(),
            observes: None,
            signal: None,
        }
    }

    /// Sets a plane's surface (builder style): a point on it (m) and its outward normal (any
    /// non-zero length).
    pub fn with_surface(mut self, point: [f64; 3], normal: [f64; 3]) -> Self {
        self.point = Some(point);
        self.normal = Some(normal);
        self
    }

    /// Index in `params` of an optional parameter, when the type has it.
    pub fn optional_index(&self, which: OptionalParam) -> Option<usize> {
        let base = self.kind.param_specs().len();
        self.optional
            .iter()
            .position(|&o| o == which)
            .map(|k| base + k)
    }

    /// An optional parameter, when the type has it.
    pub fn optional_param(&self, which: OptionalParam) -> Option<&Param> {
        self.optional_index(which).map(|k| &self.params[k])
    }

    /// Provot's τc, when the type has one.
    pub fn max_elongation(&self) -> Option<&Param> {
        self.optional_param(OptionalParam::MaxElongation)
    }

    /// Sets (`Some`) or removes (`None`) an optional parameter; a new one goes last.
    pub fn set_optional(&mut self, which: OptionalParam, value: Option<Param>) {
        match (self.optional_index(which), value) {
            (Some(k), Some(v)) => self.params[k] = v,
            (Some(k), None) => {
                self.params.remove(k);
                self.optional.retain(|&o| o != which);
            }
            (None, Some(v)) => {
                let at = self.kind.param_specs().len() + self.optional.len();
                self.params.insert(at, v);
                self.optional.push(which);
            }
            (None, None) => {}
        }
    }

    /// Sets an optional parameter (builder style).
    pub fn with_optional(mut self, which: OptionalParam, value: impl Into<Param>) -> Self {
        self.set_optional(which, Some(value.into()));
        self
    }

    /// Sets the driving signal of a TGR type (builder style).
    pub fn with_signal(mut self, signal: impl Into<String>) -> Self {
        self.signal = Some(signal.into());
        self
    }

    /// Sets a muscle's weights (builder style): `w_len` in N/m-free units of 1/m, `w_rate` in
    /// s/m (the neuron's input is dimensionless). Panics unless the kind is `muscle` and both
    /// have the same length: this is for code that builds scenes.
    pub fn with_weights(mut self, w_len: &[Param], w_rate: &[Param]) -> Self {
        assert_eq!(self.kind, LinkKind::Muscle, "only muscles have weights");
        assert_eq!(
            w_len.len(),
            w_rate.len(),
            "w_len and w_rate differ in length"
        );
        self.params.truncate(self.kind.param_specs().len());
        self.params.extend_from_slice(w_len);
        self.params.extend_from_slice(w_rate);
        self
    }

    /// Number of weights per input (M): the observed links of each instance. 0 for other kinds.
    pub fn num_weights(&self) -> usize {
        if self.kind == LinkKind::Muscle {
            self.params
                .len()
                .saturating_sub(self.kind.param_specs().len())
                / 2
        } else {
            0
        }
    }

    /// A muscle's elongation weights (1/m), one per observed link; empty for other kinds.
    pub fn w_len(&self) -> &[Param] {
        let (s, m) = (self.kind.param_specs().len(), self.num_weights());
        &self.params[s.min(self.params.len())..][..m]
    }

    /// A muscle's rate weights (s/m), one per observed link; empty for other kinds.
    pub fn w_rate(&self) -> &[Param] {
        let (s, m) = (self.kind.param_specs().len(), self.num_weights());
        &self.params[(s + m).min(self.params.len())..][..m]
    }

    /// Name of parameter `k` of the type's list: a spec name, or `w_len[i]` / `w_rate[i]`.
    pub fn param_name(&self, k: usize) -> String {
        let specs = self.kind.param_specs();
        match specs.get(k) {
            Some((n, _)) => (*n).to_string(),
            None if self.kind != LinkKind::Muscle => self
                .optional
                .get(k - specs.len())
                .map_or_else(|| format!("params[{k}]"), |o| o.name().to_string()),
            None => {
                let (w, m) = (k - specs.len(), self.num_weights().max(1));
                if w < m {
                    format!("w_len[{w}]")
                } else {
                    format!("w_rate[{}]", w - m)
                }
            }
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

    /// A named parameter: a spec one, or an optional one the type has.
    pub fn param(&self, name: &str) -> Option<&Param> {
        match self.kind.param_index(name) {
            Some(i) => Some(&self.params[i]),
            None => OptionalParam::from_name(name).and_then(|o| self.optional_param(o)),
        }
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
    /// Muscles only: link indices this instance observes (overrides the type's `observes`).
    pub observes: Option<Vec<usize>>,
}

/// One instance of a coupling kind (SPEC §2.5: `tgr`…), listed in the scene's `couplings`.
/// Couplings are kept apart from [`Link`]s because they may join particles of different worlds
/// and because some of them carry state from step to step.
#[derive(Clone, Debug, PartialEq)]
pub struct Coupling {
    /// Index of the type in the scene's catalogue.
    pub type_index: usize,
    pub particles: Vec<usize>,
    /// `force_transmitter` only: index in `links` of the spring whose tension it transmits.
    pub source: Option<usize>,
    /// `tgr` only: the controller dipole `[c, d]`, two particles of another world, whose length
    /// anchors the tendon (the central-control muscle, thesis §5.4: see
    /// [`crate::forces::controlled_tgr`]).
    pub controller: Option<[usize; 2]>,
}
