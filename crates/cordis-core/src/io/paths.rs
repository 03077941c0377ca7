//! Output paths checked before any work: each one writable, none the same file as an input
//! or as another output.
//!
//! A command that writes onto its own input destroys it (`cordis render s.json -t run.csv
//! --html run.csv` used to replace the trajectory by the page, exit 0), and one that finds an
//! unwritable output only at the end loses the run. [`check_outputs`] is called first, with
//! every file the command reads and every file it will write, each under the option that
//! names it, so the error names both.
//!
//! Two paths are the same file when they resolve to the same canonical path (symlinks and
//! `..` resolved) or, on Unix, to the same inode (hard links). An output that does not exist
//! yet is compared through its canonical parent directory joined with its file name.

use std::path::{Path, PathBuf};

use crate::error::{printable, CordisError, Result};

/// A path under the option (or argument) that named it: `("--html", path)`.
pub type Named<'a> = (&'a str, &'a Path);

/// Refuses, before any work, an output that is also an input or another output, or that
/// cannot be written (its directory missing or read-only, or a directory in its place).
///
/// `inputs` may name files that do not exist: they are compared by path only (their reader
/// reports them). A same-file pair is a [`CordisError::Argument`] (bad usage, exit 2 in the
/// CLI) naming both options and paths; an unwritable output is a [`CordisError::Io`] naming
/// the path (exit 1), as a failed write at the end would have been.
pub fn check_outputs(inputs: &[Named<'_>], outputs: &[Named<'_>]) -> Result<()> {
    let keys: Vec<Key> = outputs.iter().map(|(_, p)| Key::of(p)).collect();
    for (k, (name, path)) in outputs.iter().enumerate() {
        for (in_name, in_path) in inputs {
            if keys[k].same(&Key::of(in_path)) {
                return Err(same_file(name, path, in_name, in_path, "input"));
            }
        }
        for (other_name, other_path) in &outputs[..k] {
            if keys[k].same(&Key::of(other_path)) {
                return Err(same_file(name, path, other_name, other_path, "output"));
            }
        }
    }
    for (name, path) in outputs {
        check_writable(name, path)?;
    }
    Ok(())
}

fn same_file(name: &str, path: &Path, other: &str, other_path: &Path, role: &str) -> CordisError {
    let shown = |p: &Path| printable(&p.display().to_string());
    let what = if role == "input" {
        "writing it would destroy the input"
    } else {
        "one would overwrite the other"
    };
    CordisError::argument(
        name,
        format!(
            "{} is the same file as the {role} {other} {} ({what}): give another path",
            shown(path),
            shown(other_path)
        ),
    )
}

/// What identifies a file: its canonical path, and its device and inode when it exists.
struct Key {
    path: Option<PathBuf>,
    inode: Option<(u64, u64)>,
}

impl Key {
    fn of(path: &Path) -> Key {
        let canonical = std::fs::canonicalize(path).ok().or_else(|| {
            // Not there yet (or a dangling link): its directory's canonical path and its name.
            let name = path.file_name()?;
            let dir = match path.parent() {
                Some(d) if !d.as_os_str().is_empty() => d,
                _ => Path::new("."),
            };
            Some(std::fs::canonicalize(dir).ok()?.join(name))
        });
        Key {
            path: canonical.or_else(|| Some(path.to_path_buf())),
            inode: inode(path),
        }
    }

    fn same(&self, other: &Key) -> bool {
        (self.path.is_some() && self.path == other.path)
            || (self.inode.is_some() && self.inode == other.inode)
    }
}

#[cfg(unix)]
fn inode(path: &Path) -> Option<(u64, u64)> {
    use std::os::unix::fs::MetadataExt;
    std::fs::metadata(path).ok().map(|m| (m.dev(), m.ino()))
}

#[cfg(not(unix))]
fn inode(_path: &Path) -> Option<(u64, u64)> {
    None
}

/// An output can be written where [`super::write_atomic`] will write it: a regular file or a
/// new name is replaced through a temporary in its directory, so that directory must take a
/// new file (probed by creating and removing one); a device or FIFO (`/dev/null`) is written
/// in place and not probed (opening a FIFO would block).
fn check_writable(name: &str, path: &Path) -> Result<()> {
    let fail = |e: std::io::Error| {
        CordisError::io(
            path,
            std::io::Error::new(e.kind(), format!("{name}: cannot be written here: {e}")),
        )
    };
    match std::fs::metadata(path) {
        Ok(m) if m.is_dir() => {
            return Err(fail(std::io::Error::new(
                std::io::ErrorKind::IsADirectory,
                "is a directory",
            )))
        }
        Ok(m) if !m.is_file() => return Ok(()),
        _ => {}
    }
    let file_name = path.file_name().ok_or_else(|| {
        fail(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "not a file name",
        ))
    })?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let mut probe_name = std::ffi::OsString::from(".");
    probe_name.push(file_name);
    probe_name.push(format!(".{}.probe.tmp", std::process::id()));
    let probe = dir.join(probe_name);
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)
        .map_err(fail)?;
    // The probe is empty and ours (its name has our pid): nothing to report if it stays.
    let _ = std::fs::remove_file(&probe);
    Ok(())
}
