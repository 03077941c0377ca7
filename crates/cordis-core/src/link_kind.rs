//! The link kinds of SPEC §2.2 (the thesis' LIA: "liaisons").

/// What a link type computes. Each kind has a fixed arity and a fixed list of scalar
/// parameters ([`LinkKind::param_names`]), which is also their order in a parameter vector.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum LinkKind {
    /// Binary position link: `F_i = (K (L - l0) + Z s) u`.
    Spring,
    /// Binary velocity link: `F_i = Z w` (isotropic).
    Damper,
    /// Unary position link: a spring to a fixed point.
    Anchor,
    /// Unary velocity link: `F_i = -Z v_i` (viscosity of the environment).
    Drag,
    /// Unary velocity link with two regimes: `z1` below `v_max`, `z2` above (thesis §6.1.1).
    NonlinearDrag,
    /// Ternary position link on the angle at the middle particle: energy `½K(cosθ - c0)²`.
    Angle,
    /// Unary contact with a half-space (ground, table): a visco-elastic buffer pushing along
    /// the plane's normal while the particle is below it, with regularised Coulomb friction
    /// (see [`crate::forces::plane`]).
    Plane,
    /// Spring between every pair of particles of one or two groups closer than `range`.
    Conditional,
    /// Binary local-control muscle (thesis §5.5): a spring plus `G · out · u`, where a neuron's
    /// `out = tanh(Σ w_len e + w_rate s - θ)` observes the other muscle links (SPEC §2.4).
    Muscle,
    /// Coupling (thesis §5.4.1, SPEC §2.5): a sensori-motor link between M1 and M2 whose rest
    /// length `l0 + y` follows a tendon (a 1-D mass at y, m) driven by a command signal; the
    /// tendon feels the link's tension as feedback. Listed in `couplings`, stateful.
    Tgr,
    /// Coupling of two dipoles (a, b) and (c, d), usually in two worlds (thesis eq 5.1-5.2):
    /// `Δ = L1 - r L2`, `F = -K Δ - Z (Δ(n) - Δ(n-1))` on both dipoles. Stateful (Δ(n-1)).
    Quadripole,
    /// A quadripole whose force on dipole 1 is cut: dipole 2's length follows dipole 1's.
    PositionTransmitter,
    /// A dipole (a, b) that receives `gain` × the tension of a `source` spring link.
    ForceTransmitter,
}

impl LinkKind {
    pub const ALL: [LinkKind; 13] = [
        LinkKind::Spring,
        LinkKind::Damper,
        LinkKind::Anchor,
        LinkKind::Drag,
        LinkKind::NonlinearDrag,
        LinkKind::Angle,
        LinkKind::Plane,
        LinkKind::Conditional,
        LinkKind::Muscle,
        LinkKind::Tgr,
        LinkKind::Quadripole,
        LinkKind::PositionTransmitter,
        LinkKind::ForceTransmitter,
    ];

    /// The name used in scene files.
    pub fn name(self) -> &'static str {
        match self {
            LinkKind::Spring => "spring",
            LinkKind::Damper => "damper",
            LinkKind::Anchor => "anchor",
            LinkKind::Drag => "drag",
            LinkKind::NonlinearDrag => "nonlinear_drag",
            LinkKind::Angle => "angle",
            LinkKind::Plane => "plane",
            LinkKind::Conditional => "conditional",
            LinkKind::Muscle => "muscle",
            LinkKind::Tgr => "tgr",
            LinkKind::Quadripole => "quadripole",
            LinkKind::PositionTransmitter => "position_transmitter",
            LinkKind::ForceTransmitter => "force_transmitter",
        }
    }

    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }

    /// Number of particles a link instance names (0 for `conditional`: pairs are found).
    pub fn arity(self) -> usize {
        match self {
            LinkKind::Spring
            | LinkKind::Damper
            | LinkKind::Muscle
            | LinkKind::Tgr
            | LinkKind::ForceTransmitter => 2,
            LinkKind::Quadripole | LinkKind::PositionTransmitter => 4,
            LinkKind::Anchor | LinkKind::Drag | LinkKind::NonlinearDrag | LinkKind::Plane => 1,
            LinkKind::Angle => 3,
            LinkKind::Conditional => 0,
        }
    }

    /// Scalar parameters of the kind, in parameter-vector order, with their default when the
    /// scene omits them (`None`: required). Units: stiffness N/m (angle: N·m, on a cosine),
    /// lengths m, damping N·s/m, speeds m/s, muscle gain N, threshold dimensionless, tendon
    /// mass kg, a plane's friction coefficient dimensionless.
    ///
    /// A `muscle` type's parameter list is longer than its specs: the five scalars are followed
    /// by its neural weights (see [`crate::LinkType::w_len`]).
    pub fn param_specs(self) -> &'static [(&'static str, Option<f64>)] {
        match self {
            LinkKind::Spring => &[
                ("stiffness", None),
                ("rest_length", None),
                ("damping", Some(0.0)),
            ],
            LinkKind::Damper => &[("damping", None)],
            LinkKind::Anchor => &[
                ("stiffness", None),
                ("rest_length", Some(0.0)),
                ("damping", Some(0.0)),
            ],
            LinkKind::Drag => &[("damping", None)],
            LinkKind::NonlinearDrag => &[("z1", None), ("z2", None), ("v_max", None)],
            LinkKind::Angle => &[("stiffness", None), ("rest_cos", None)],
            LinkKind::Plane => &[
                ("stiffness", None),
                ("damping", Some(0.0)),
                ("friction", Some(0.0)),
            ],
            LinkKind::Conditional => &[
                ("stiffness", None),
                ("rest_length", None),
                ("damping", Some(0.0)),
                ("range", None),
            ],
            LinkKind::Muscle => &[
                ("stiffness", None),
                ("rest_length", None),
                ("damping", Some(0.0)),
                ("gain", Some(1.0)),
                ("threshold", Some(0.0)),
            ],
            LinkKind::Tgr => &[
                ("stiffness", None),
                ("rest_length", None),
                ("damping", Some(0.0)),
                ("tendon_mass", None),
                ("tendon_stiffness", Some(0.0)),
                ("tendon_damping", Some(0.0)),
            ],
            LinkKind::Quadripole | LinkKind::PositionTransmitter => &[
                ("stiffness", None),
                ("damping", Some(0.0)),
                ("ratio", Some(1.0)),
            ],
            LinkKind::ForceTransmitter => &[("gain", Some(1.0))],
        }
    }

    pub fn param_names(self) -> impl Iterator<Item = &'static str> {
        self.param_specs().iter().map(|(n, _)| *n)
    }

    /// Index of a named parameter in [`LinkKind::param_specs`].
    pub fn param_index(self, name: &str) -> Option<usize> {
        self.param_specs().iter().position(|(n, _)| *n == name)
    }

    /// Coupling kinds (SPEC §2.5) are listed in the scene's `couplings`, not in `links`: they
    /// may join worlds and some carry state between steps.
    pub fn is_coupling(self) -> bool {
        matches!(
            self,
            LinkKind::Tgr
                | LinkKind::Quadripole
                | LinkKind::PositionTransmitter
                | LinkKind::ForceTransmitter
        )
    }

    /// Keys a type of this kind may carry besides its scalar parameters.
    pub fn extra_keys(self) -> &'static [&'static str] {
        match self {
            LinkKind::Spring => &["max_elongation", "damping_quadratic"],
            LinkKind::Anchor => &["point"],
            LinkKind::Plane => &["point", "normal"],
            LinkKind::Conditional => &["groups", "damping_quadratic"],
            LinkKind::Muscle => &["w_len", "w_rate", "observes"],
            LinkKind::Tgr => &["signal", "tendon_position", "tendon_velocity"],
            _ => &[],
        }
    }
}

impl std::fmt::Display for LinkKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}
