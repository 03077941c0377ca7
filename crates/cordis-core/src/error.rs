//! The one error type of `cordis-core`.
//!
//! Every variant carries a `place` — a JSON path (`links[12].particles[1]`), a file and line
//! (`run.csv:14`), or a frame and particle — so that a message read on a terminal says where to
//! look. The Python bindings map each variant to its own exception class under `CordisError`.

use std::path::PathBuf;

/// Errors raised by `cordis-core`.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CordisError {
    /// The scene is malformed or inconsistent (bad key, wrong kind, index out of range…).
    #[error("{place}: {message}")]
    Scene { place: String, message: String },

    /// A trajectory is malformed (bad header, short row, NaN, missing particle…) or does not
    /// fit the scene it is used with.
    #[error("{place}: {message}")]
    Trajectory { place: String, message: String },

    /// A file is not in the format its name or content announce (JSON syntax, `.npy` header,
    /// thesis files).
    #[error("{place}: {message}")]
    Format { place: String, message: String },

    /// The simulation left the finite numbers: the model is unstable for this `dt`.
    #[error("simulation diverged at frame {frame}, particle {particle}: {message}")]
    Diverged {
        frame: usize,
        particle: usize,
        message: String,
    },

    /// A file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
}

impl CordisError {
    pub fn scene(place: impl Into<String>, message: impl Into<String>) -> Self {
        Self::Scene {
            place: place.into(),
            message: message.into(),
        }
    }

    pub fn trajectory(place: impl Into<String>, message: impl Into<String>) -> Self {
        Self::Trajectory {
            place: place.into(),
            message: message.into(),
        }
    }

    pub fn format(place: impl Into<String>, message: impl Into<String>) -> Self {
        Self::Format {
            place: place.into(),
            message: message.into(),
        }
    }

    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Self::Io {
            path: path.into(),
            source,
        }
    }
}

pub type Result<T, E = CordisError> = std::result::Result<T, E>;
