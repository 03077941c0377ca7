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

    /// An argument out of its domain (a command-line option, a Python keyword, a `Param.gene`
    /// key: `--width NaN`, `--frames` beyond memory) or two paths that must differ (an output
    /// that is also an input). `place` names the option (`--width`, `--html`).
    #[error("{place}: {message}")]
    Argument { place: String, message: String },

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

    pub fn argument(place: impl Into<String>, message: impl Into<String>) -> Self {
        Self::Argument {
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

/// Words longer than this (in characters) are cut in [`printable`].
const LONG_WORD: usize = 200;
/// How much of a cut word [`printable`] keeps.
const KEPT: usize = 60;

/// A message as it may be printed on a terminal or a log line: control characters (terminal
/// escapes, newlines, NUL) and the bidirectional overrides escaped as `\u{1b}`, `\n`, and every
/// word (a run without spaces: a CSV cell, a JSON value, a path) longer than 200 characters
/// cut to its first 60 followed by `…(N characters)`. Errors echo input bytes: a hostile file
/// must not drive the terminal nor bury the message under a 10 MB line.
pub fn printable(text: &str) -> String {
    let mut out = String::with_capacity(text.len().min(4 * LONG_WORD));
    for (k, word) in text.split(' ').enumerate() {
        if k > 0 {
            out.push(' ');
        }
        let n = word.chars().count();
        let kept = if n > LONG_WORD { KEPT } else { n };
        for c in word.chars().take(kept) {
            let bidi = matches!(c, '\u{202a}'..='\u{202e}' | '\u{2066}'..='\u{2069}');
            if c.is_control() || bidi || c == '\u{2028}' || c == '\u{2029}' {
                out.extend(c.escape_default());
            } else {
                out.push(c);
            }
        }
        if n > kept {
            out.push_str(&format!("…({n} characters)"));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::printable;

    #[test]
    fn printable_escapes_controls_and_cuts_long_words_with_their_length() {
        assert_eq!(printable("plain `text`: 1.5 m"), "plain `text`: 1.5 m");
        assert_eq!(
            printable("a\x1b[2Jb\nc\u{202e}d"),
            "a\\u{1b}[2Jb\\nc\\u{202e}d"
        );
        let long = format!("x `{}` y", "é".repeat(201));
        let cut = printable(&long);
        assert_eq!(cut, format!("x `{}…(203 characters) y", "é".repeat(59)));
        // 200 characters are kept whole.
        let edge = "b".repeat(200);
        assert_eq!(printable(&edge), edge);
    }
}
