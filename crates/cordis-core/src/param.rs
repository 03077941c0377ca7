//! A scalar of the model that is either known or to be identified.

/// Search box of an unknown parameter (SPEC §5.1: `{"min": 0.1, "max": 1000, "init": 3}`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    pub min: f64,
    pub max: f64,
    /// Starting value; when absent, [`Param::value`] uses the middle of the box.
    pub init: Option<f64>,
}

/// One scalar of a link type (stiffness, rest length…) or a particle's mass.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Param {
    Known(f64),
    Unknown(Bounds),
}

impl Param {
    /// The value used to simulate: the known value, or for an unknown its `init`, else the
    /// midpoint of its box (geometric when the box is strictly positive and spans more than a
    /// decade, as stiffness-like boxes do).
    pub fn value(&self) -> f64 {
        match *self {
            Param::Known(v) => v,
            Param::Unknown(b) => b.init.unwrap_or_else(|| {
                if b.min > 0.0 && b.max > 10.0 * b.min {
                    (b.min * b.max).sqrt()
                } else {
                    0.5 * (b.min + b.max)
                }
            }),
        }
    }

    pub fn is_unknown(&self) -> bool {
        matches!(self, Param::Unknown(_))
    }

    /// True when the parameter is known to be exactly zero, so a pass that only it feeds can be
    /// skipped by the compiled plan.
    pub fn is_known_zero(&self) -> bool {
        matches!(self, Param::Known(v) if *v == 0.0)
    }
}

impl From<f64> for Param {
    fn from(v: f64) -> Self {
        Param::Known(v)
    }
}
