//! Settings of the thesis ES and of its `t2m` variant (the `Param.gene` keys `population`,
//! `pcross`, `pmut`, `reducer`; `generation` is a stop rule and `noise` is applied to the data).

use serde::{Deserialize, Serialize};

/// Which operators run: the text's ([`super::operators`]) or this crate's first reading
/// ([`super::t2m`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Variant {
    /// §3.2, §3.2.1 and Annexe 1 as written (`--strategy thesis`).
    Thesis,
    /// The earlier, freer reading (`--strategy t2m`).
    T2m,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ThesisConfig {
    pub variant: Variant,
    pub population: usize,
    /// `thesis`: probability (%) that an individual of the population gives rise to a
    /// crossover this generation; `t2m`: share (%) of the children from crossover.
    pub pcross: f64,
    /// `thesis`: probability (%) of a mutation per individual and generation (§3.2: "entre 1%
    /// et 5%"), shared by the four kinds; `t2m`: share (%) of children from pure mutation.
    pub pmut: f64,
    /// `thesis`: share of the mutations that are re-injections (the rest split evenly between
    /// noisy inheritance, pure and local mutation); `t2m`: share of children (fraction).
    pub reinjection: f64,
    /// Decay of unchanged individuals' mutabilities per generation (fraction; "décadence").
    pub reducer: f64,
    /// Fraction of the population protected by the global cost (`thesis`: 5 %, §3.2.1;
    /// `t2m`: 10 %, §3.2).
    pub elite: f64,
    /// `t2m` only: fraction of the population (the worst) replaced each generation.
    pub replacement: f64,
    pub crossover: Crossover,
    /// Powell's descent on the best individual from this generation, every `descent_every`.
    pub descent_start: u64,
    pub descent_every: u64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Crossover {
    /// Per type, the mean of the fathers chosen one per end particle (Annexe 1).
    Mean,
    /// Uniform n-parent: all genes of a type from one father (§3.2).
    NParent,
    /// Uniform m·n-parent: each gene from its own father (§3.2).
    MnParent,
}

impl Crossover {
    /// The `--crossover` names.
    pub const NAMES: [(Crossover, &'static str); 3] = [
        (Crossover::Mean, "mean"),
        (Crossover::NParent, "n-parent"),
        (Crossover::MnParent, "mn-parent"),
    ];

    pub fn name(self) -> &'static str {
        crate::named::name_of(&Self::NAMES, self)
    }

    /// The crossover named `s`, or a line listing the names.
    pub fn parse(s: &str) -> Result<Self, String> {
        crate::named::parse_name(&Self::NAMES, "crossover", s)
    }
}

impl ThesisConfig {
    /// The text's settings: Param.gene's `pcross=15`, `pmut=1`, `reducer=0.01`; the best 5 %
    /// protected (§3.2.1); re-injection "en doses très modérées" (a tenth of the mutations);
    /// Powell's descent from generation 400, every 100 (Annexe 1).
    pub fn thesis() -> Self {
        ThesisConfig {
            variant: Variant::Thesis,
            population: 100,
            pcross: 15.0,
            pmut: 1.0,
            reinjection: 0.1,
            reducer: 0.01,
            elite: 0.05,
            replacement: 0.6,
            crossover: Crossover::Mean,
            descent_start: 400,
            descent_every: 100,
        }
    }

    /// The `t2m` variant's settings (this crate's `thesis` until issue 19).
    pub fn t2m() -> Self {
        ThesisConfig {
            variant: Variant::T2m,
            reinjection: 0.05,
            elite: 0.1,
            ..Self::thesis()
        }
    }
}

impl Default for ThesisConfig {
    fn default() -> Self {
        Self::thesis()
    }
}
