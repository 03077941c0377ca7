//! The error type of `cordis-es`.
//!
//! Like [`cordis_core::CordisError`], every variant names its place (a cost-kind string, a
//! parameter vector, a trajectory field) so that a message read on a terminal says where to
//! look. Core errors (bad scene, bad trajectory file) pass through unchanged.

use cordis_core::CordisError;

/// Errors raised by `cordis-es`.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CostError {
    /// An error of the core (scene, trajectory, file), passed through.
    #[error(transparent)]
    Core(#[from] CordisError),

    /// A cost-kind string that does not parse (`horizon:x`, `harmonic:-1`, `shrt`…).
    #[error("{place}: {message}")]
    Kind { place: String, message: String },

    /// A parameter vector (or a population, or an output buffer) of the wrong length.
    #[error("{place}: has {got} values, expected {expected}")]
    Length {
        place: String,
        expected: usize,
        got: usize,
    },

    /// The trajectory does not fit the scene (particle count, too few frames, another `dt`).
    #[error("{place}: {message}")]
    Mismatch { place: String, message: String },

    /// An identification option out of its range (`--time-limit inf`, `population 1e11`),
    /// named with its unit.
    #[error("{place}: {message}")]
    Invalid { place: String, message: String },

    /// The strategy cannot run on this problem (a nonlinear cost kind for an exact solver,
    /// free masses without a total…): refused before any work, saying what to do instead.
    #[error("{place}: {message}")]
    Refused { place: String, message: String },

    /// A checkpoint that cannot resume this run (unreadable, another strategy, seed, scene,
    /// data or options — the message names which); `source`: the strategy's refusal of the
    /// state it holds, when that is why.
    #[error("{place}: {message}")]
    Resume {
        place: String,
        message: String,
        #[source]
        source: Option<Box<CostError>>,
    },

    /// A strategy's checkpointed state, or an island's migrants, that this run cannot take:
    /// not the strategy's format (`source`: the JSON error), or made for another population,
    /// dimension or configuration ([`crate::strategy::Strategy::load_state`],
    /// [`crate::strategy::Strategy::immigrate`]).
    #[error("{message}")]
    State {
        message: String,
        #[source]
        source: Option<serde_json::Error>,
    },

    /// The run failed: a solver that found no estimate, an evaluation that failed, a checkpoint
    /// that could not be written; `source`: the failed evaluation, when that is why.
    #[error("{place}: {message}")]
    Run {
        place: String,
        message: String,
        #[source]
        source: Option<Box<CostError>>,
    },

    /// A name that is not one of a fixed list (a strategy, a loss): the message quotes the name
    /// given and the list; the caller adds the option's place (`--strategy`, `loss`).
    #[error("{message}")]
    UnknownName { given: String, message: String },

    /// A population's evaluation failed ([`crate::evaluator::Evaluator`]: a remote executor
    /// that lost its workers or raised, residuals asked of a cost that has none); `source`: the
    /// executor's own error, when it has one.
    #[error("{message}")]
    Evaluation {
        message: String,
        #[source]
        source: Option<Box<dyn std::error::Error + Send + Sync>>,
    },
}

impl CostError {
    pub fn kind(place: impl Into<String>, message: impl Into<String>) -> Self {
        Self::Kind {
            place: place.into(),
            message: message.into(),
        }
    }

    pub fn length(place: impl Into<String>, expected: usize, got: usize) -> Self {
        Self::Length {
            place: place.into(),
            expected,
            got,
        }
    }

    pub fn mismatch(place: impl Into<String>, message: impl Into<String>) -> Self {
        Self::Mismatch {
            place: place.into(),
            message: message.into(),
        }
    }

    pub fn invalid(place: impl Into<String>, message: impl Into<String>) -> Self {
        Self::Invalid {
            place: place.into(),
            message: message.into(),
        }
    }

    pub fn refused(place: impl Into<String>, message: impl Into<String>) -> Self {
        Self::Refused {
            place: place.into(),
            message: message.into(),
        }
    }

    pub fn resume(place: impl Into<String>, message: impl Into<String>) -> Self {
        Self::Resume {
            place: place.into(),
            message: message.into(),
            source: None,
        }
    }

    /// A checkpoint at `place` whose state the strategy refused with `source` (its message
    /// repeated, so the one line says it all).
    pub fn resume_from(place: impl Into<String>, source: CostError) -> Self {
        Self::Resume {
            place: place.into(),
            message: source.to_string(),
            source: Some(Box::new(source)),
        }
    }

    /// A strategy state (or migrant) this run cannot take, saying why.
    pub fn state(message: impl Into<String>) -> Self {
        Self::State {
            message: message.into(),
            source: None,
        }
    }

    /// A strategy state (or migrant) that is not JSON of the strategy's format; `what` names
    /// it when more than the state is read (`migrant 3`).
    pub fn state_json(what: Option<&str>, source: serde_json::Error) -> Self {
        Self::State {
            message: match what {
                Some(w) => format!("{w}: {source}"),
                None => source.to_string(),
            },
            source: Some(source),
        }
    }

    /// This state error with `prefix` before its message (`islands[2]: …`), its source kept.
    pub fn within(self, prefix: impl std::fmt::Display) -> Self {
        match self {
            Self::State { message, source } => Self::State {
                message: format!("{prefix}: {message}"),
                source,
            },
            other => Self::State {
                message: format!("{prefix}: {other}"),
                source: None,
            },
        }
    }

    pub fn run(place: impl Into<String>, message: impl Into<String>) -> Self {
        Self::Run {
            place: place.into(),
            message: message.into(),
            source: None,
        }
    }

    /// The run stopped at `place` by `source` (a failed evaluation), its message repeated.
    pub fn run_from(place: impl Into<String>, source: CostError) -> Self {
        Self::Run {
            place: place.into(),
            message: source.to_string(),
            source: Some(Box::new(source)),
        }
    }

    /// `given` is not one of the names listed in `message`.
    pub fn unknown_name(given: impl Into<String>, message: impl Into<String>) -> Self {
        Self::UnknownName {
            given: given.into(),
            message: message.into(),
        }
    }

    /// A failed evaluation, saying why.
    pub fn evaluation(message: impl Into<String>) -> Self {
        Self::Evaluation {
            message: message.into(),
            source: None,
        }
    }
}
