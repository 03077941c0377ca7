//! A token reader for the thesis' loosely laid out text files (`.tra`, `.mas`, `.cat`, `.ini`).
//!
//! The thesis' printed examples lost line breaks, so these files are read as a stream of
//! whitespace-separated tokens, each remembering its line: *words* (runs of them form a
//! header label such as `Nombre de particules`), `:` (which ends a label) and *numbers*.

use crate::error::{CordisError, Result};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Kind {
    Word,
    Colon,
    Num,
}

#[derive(Clone, Copy, Debug)]
pub(crate) struct Tok<'a> {
    pub text: &'a str,
    pub line: usize,
    pub kind: Kind,
}

pub(crate) fn tokenize(text: &str) -> Vec<Tok<'_>> {
    let mut out = Vec::new();
    for (k, line) in text.lines().enumerate() {
        for piece in line.split_whitespace() {
            for (j, part) in piece.split(':').enumerate() {
                if j > 0 {
                    out.push(Tok {
                        text: ":",
                        line: k + 1,
                        kind: Kind::Colon,
                    });
                }
                if !part.is_empty() {
                    out.push(Tok {
                        text: part,
                        line: k + 1,
                        kind: classify(part),
                    });
                }
            }
        }
    }
    out
}

/// Anything that looks meant as a number is one (so `1.2.3` or `nan` is reported as a bad
/// number, not taken for a header word).
fn classify(s: &str) -> Kind {
    let starts_numeric = s
        .as_bytes()
        .first()
        .is_some_and(|c| c.is_ascii_digit() || matches!(c, b'+' | b'-' | b'.'));
    if starts_numeric || s.parse::<f64>().is_ok() {
        Kind::Num
    } else {
        Kind::Word
    }
}

/// Lower-cased words of a label, single-spaced, for comparisons.
pub(crate) fn normalize(label: &str) -> String {
    label
        .split_whitespace()
        .collect::<Vec<_>>()
        .join(" ")
        .to_lowercase()
}

/// Reads tokens in order; errors are built by `mk` (the trajectory or format error kind) with
/// the place `name:LINE`.
pub(crate) struct Cursor<'a> {
    toks: Vec<Tok<'a>>,
    pos: usize,
    name: &'a str,
    last_line: usize,
    mk: fn(String, String) -> CordisError,
}

impl<'a> Cursor<'a> {
    pub fn new(name: &'a str, text: &'a str, mk: fn(String, String) -> CordisError) -> Self {
        Cursor {
            toks: tokenize(text),
            pos: 0,
            name,
            last_line: text.lines().count().max(1),
            mk,
        }
    }

    pub fn peek(&self) -> Option<Tok<'a>> {
        self.toks.get(self.pos).copied()
    }

    pub fn at_end(&self) -> bool {
        self.pos >= self.toks.len()
    }

    /// Tokens left, an upper bound for reserving memory.
    pub fn remaining(&self) -> usize {
        self.toks.len().saturating_sub(self.pos)
    }

    pub fn place(&self, line: usize) -> String {
        format!("{}:{line}", self.name)
    }

    /// The place of the next token, or of the file's last line at the end.
    pub fn here(&self) -> String {
        self.place(self.peek().map_or(self.last_line, |t| t.line))
    }

    pub fn error(&self, line: usize, message: impl Into<String>) -> CordisError {
        (self.mk)(self.place(line), message.into())
    }

    pub fn error_here(&self, message: impl Into<String>) -> CordisError {
        (self.mk)(self.here(), message.into())
    }

    fn found(&self) -> String {
        match self.peek() {
            Some(t) => format!("found `{}`", t.text),
            None => "found the end of the file".into(),
        }
    }

    /// A header label: the next run of words, then an optional `:`. Returns the label as
    /// written (single-spaced) and its line, or `None` (consuming nothing) when the next token is not a word.
    pub fn label(&mut self) -> Option<(String, usize)> {
        let first = self.peek().filter(|t| t.kind == Kind::Word)?;
        let mut words = Vec::new();
        while let Some(t) = self.peek().filter(|t| t.kind == Kind::Word) {
            words.push(t.text);
            self.pos += 1;
        }
        if self.peek().is_some_and(|t| t.kind == Kind::Colon) {
            self.pos += 1;
        }
        Some((words.join(" "), first.line))
    }

    /// Consumes the label `want` (normalized form) or fails saying it was expected.
    pub fn expect_label(&mut self, want: &str, shown: &str) -> Result<usize> {
        let here = self.here();
        match self.label() {
            Some((l, line)) if normalize(&l) == want => Ok(line),
            Some((l, _)) => Err((self.mk)(here, format!("expected `{shown}`, found `{l}`"))),
            None => Err(self.error_here(format!("expected `{shown}`, {}", self.found()))),
        }
    }

    /// The next token as a finite number; `what` says what it should be, for the error.
    pub fn number(&mut self, what: impl FnOnce() -> String) -> Result<f64> {
        match self.peek() {
            Some(t) if t.kind == Kind::Num => match t.text.parse::<f64>() {
                Ok(v) if v.is_finite() => {
                    self.pos += 1;
                    Ok(v)
                }
                Ok(_) => Err(self.error(
                    t.line,
                    format!("{} is {}: it must be finite", what(), t.text),
                )),
                Err(_) => {
                    Err(self.error(t.line, format!("{}: `{}` is not a number", what(), t.text)))
                }
            },
            _ => Err(self.error_here(format!("expected {}, {}", what(), self.found()))),
        }
    }

    /// The next token as a non-negative integer (a count, an index).
    pub fn index(&mut self, what: impl FnOnce() -> String) -> Result<usize> {
        match self.peek() {
            Some(t) if t.kind == Kind::Num => match t.text.parse::<usize>() {
                Ok(v) => {
                    self.pos += 1;
                    Ok(v)
                }
                Err(_) => Err(self.error(
                    t.line,
                    format!("{}: `{}` is not a non-negative integer", what(), t.text),
                )),
            },
            _ => Err(self.error_here(format!("expected {}, {}", what(), self.found()))),
        }
    }

    /// Fails unless every token was read.
    pub fn expect_end(&self, after: &str) -> Result<()> {
        match self.peek() {
            None => Ok(()),
            Some(t) => Err(self.error(t.line, format!("unexpected `{}` after {after}", t.text))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colons_split_and_kinds() {
        let toks = tokenize("Nombre de particules:3 1\n  -1.5e3 nan x\n:7");
        let kinds: Vec<_> = toks.iter().map(|t| (t.text, t.line, t.kind)).collect();
        assert_eq!(
            kinds,
            [
                ("Nombre", 1, Kind::Word),
                ("de", 1, Kind::Word),
                ("particules", 1, Kind::Word),
                (":", 1, Kind::Colon),
                ("3", 1, Kind::Num),
                ("1", 1, Kind::Num),
                ("-1.5e3", 2, Kind::Num),
                ("nan", 2, Kind::Num),
                ("x", 2, Kind::Word),
                (":", 3, Kind::Colon),
                ("7", 3, Kind::Num),
            ]
        );
    }
}
