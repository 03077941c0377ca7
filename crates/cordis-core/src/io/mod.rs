//! Trajectory files (SPEC §5.2): CSV, NumPy `.npy` and the thesis' `.tra`, chosen by
//! extension, plus atomic writes that the other writers (scene JSON, thesis files) reuse.
//! Marker files of the field — C3D, OpenSim TRC, tracker `.npz`, tables with named columns —
//! are read through [`markers::read_markers`], which [`read_trajectory`] and
//! [`read_observations`] call for every format but cordis' own.
//!
//! Each format has a pure parser over text or bytes (`parse_*`, for tests, fuzzing and
//! in-memory data) and a pure writer; the functions here add the file system. Formats are
//! described in `docs/file-formats.md`.

pub(crate) mod c3d;
pub mod csv;
pub mod markers;
pub mod npy;
pub mod paths;
pub mod table;
pub(crate) mod tokens;
pub mod tra;
pub(crate) mod tracks;
pub(crate) mod trc;

use std::borrow::Cow;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::{CordisError, Result};
use crate::Trajectory;

pub use markers::{read_markers, Imported, InputFormat, ReadOptions, Units};
pub use paths::check_outputs;

/// The trajectory formats, by file extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TrajectoryFormat {
    Csv,
    Npy,
    Tra,
}

impl TrajectoryFormat {
    /// The format a file name announces (extension, case-insensitive).
    pub fn from_path(path: &Path) -> Result<Self> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("csv") => Ok(Self::Csv),
            Some("npy") => Ok(Self::Npy),
            Some("tra") => Ok(Self::Tra),
            _ => Err(CordisError::format(
                path.display().to_string(),
                "unknown trajectory format: the name must end in .csv, .npy or .tra",
            )),
        }
    }
}

/// Reads a complete trajectory file; the format comes from the extension. cordis' own
/// formats (`.npy`, `.tra`, a `.csv` with the header `frame,particle,x,y,z`) leave `dt` unset;
/// the others are read by [`read_markers`], which sets it when the file gives a rate, and
/// must have no missing marker (the first one is named).
pub fn read_trajectory(path: &Path) -> Result<Trajectory> {
    read_trajectory_with(path, &ReadOptions::default())
}

/// [`read_trajectory`] with a table's columns, a delimiter or units (`--columns`, `--units`).
pub fn read_trajectory_with(path: &Path, options: &ReadOptions) -> Result<Trajectory> {
    let format = InputFormat::from_path(path)?;
    let bytes = read_input(path)?;
    let name = path.display().to_string();
    let plain = options.columns.is_none() && options.delimiter.is_none() && options.units.is_none();
    let own = match format {
        _ if !plain => None,
        InputFormat::Npy => Some(TrajectoryFormat::Npy),
        InputFormat::Tra => Some(TrajectoryFormat::Tra),
        InputFormat::Csv if table::is_cordis_header(&decode_text(&bytes)) => {
            Some(TrajectoryFormat::Csv)
        }
        _ => None,
    };
    if let Some(own) = own {
        return parse_trajectory(&name, own, &bytes);
    }
    let imported = markers::parse_markers(&name, format, &bytes, options)?;
    imported
        .observations
        .into_trajectory()
        .map_err(|e| match e {
            CordisError::Trajectory { place, message } => CordisError::trajectory(
                format!("{name}: {place}"),
                format!("{message} (a missing marker: this command needs every position)"),
            ),
            e => e,
        })
}

/// Reads observed positions with gaps (see [`crate::Observations`]) in any format
/// [`read_markers`] reads: NaN in `.npy`, empty cells, `nan` and absent rows in tables, C3D
/// points with a negative residual, hidden tracker points; a `.tra` file has no gaps.
pub fn read_observations(path: &Path) -> Result<crate::Observations> {
    read_observations_with(path, &ReadOptions::default())
}

/// [`read_observations`] with a table's columns, a delimiter or units.
pub fn read_observations_with(path: &Path, options: &ReadOptions) -> Result<crate::Observations> {
    Ok(read_markers(path, options)?.observations)
}

/// Writes observed positions (NaN where missing) atomically: `.npy` keeps NaN, `.csv` writes
/// an empty cell; `.tra` has no gaps, so observations with a missing one are refused there.
pub fn write_observations(path: &Path, obs: &crate::Observations) -> Result<()> {
    let format = TrajectoryFormat::from_path(path)?;
    if obs.missing() == 0 || format == TrajectoryFormat::Tra {
        let traj = obs.clone().into_trajectory().map_err(|e| {
            CordisError::trajectory(
                path.display().to_string(),
                format!("{e}: a .tra file cannot hold a missing marker; write .npy or .csv"),
            )
        })?;
        return write_trajectory(path, &traj);
    }
    let bytes = match format {
        TrajectoryFormat::Npy => {
            npy::write_npy_values(obs.frames(), obs.particles(), obs.as_flat())
        }
        _ => csv::write_csv_values(obs.particles(), obs.as_flat()).into_bytes(),
    };
    write_atomic(path, &bytes)
}

/// Parses trajectory bytes in `format`; `name` starts every error's place.
pub fn parse_trajectory(name: &str, format: TrajectoryFormat, bytes: &[u8]) -> Result<Trajectory> {
    match format {
        TrajectoryFormat::Csv => csv::parse_csv(name, &decode_text(bytes)),
        TrajectoryFormat::Npy => npy::parse_npy(name, bytes),
        TrajectoryFormat::Tra => tra::parse_tra(name, &decode_text(bytes)),
    }
}

/// Writes a trajectory atomically in the format its extension names. An empty trajectory (no
/// frame or no particle) is refused: the readers would not take it back.
pub fn write_trajectory(path: &Path, traj: &Trajectory) -> Result<()> {
    if traj.frames() == 0 || traj.particles() == 0 {
        return Err(CordisError::trajectory(
            path.display().to_string(),
            format!(
                "{} frames × {} particles: an empty trajectory cannot be written",
                traj.frames(),
                traj.particles()
            ),
        ));
    }
    let bytes = match TrajectoryFormat::from_path(path)? {
        TrajectoryFormat::Csv => csv::write_csv(traj).into_bytes(),
        TrajectoryFormat::Npy => npy::write_npy(traj),
        TrajectoryFormat::Tra => tra::write_tra(traj).into_bytes(),
    };
    write_atomic(path, &bytes)
}

/// Writes `bytes` to `path` so that a reader sees either the old file or the whole new one,
/// never a half-written file: a temporary file in the same directory (so the rename stays on
/// one file system), flushed to disk, then renamed over `path` ([`AtomicFile`]).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let mut f = AtomicFile::create(path)?;
    f.file()
        .write_all(bytes)
        .map_err(|e| CordisError::io(path, e))?;
    f.commit()
}

/// A file written in the open, that replaces `path` only when [committed](AtomicFile::commit):
/// until then `path` keeps its old content, whatever happens to the writer. Written to a
/// temporary `.NAME.PID.N.tmp` beside `path`, removed when dropped uncommitted (a failed run's
/// streamed log must not replace the last good one); a path that exists and is not a regular
/// file (`/dev/null`, `/dev/stdout`, a FIFO) is written in place, since renaming a temporary
/// over it would replace the device itself.
pub struct AtomicFile {
    path: PathBuf,
    /// The temporary, `None` when writing in place.
    tmp: Option<PathBuf>,
    file: std::fs::File,
}

impl AtomicFile {
    /// Opens the temporary beside `path` (or `path` itself, a device); an error names `path`.
    pub fn create(path: &Path) -> Result<AtomicFile> {
        static COUNTER: AtomicU64 = AtomicU64::new(0);
        if written_in_place(path) {
            let file = std::fs::OpenOptions::new()
                .write(true)
                .open(path)
                .map_err(|e| CordisError::io(path, e))?;
            return Ok(AtomicFile {
                path: path.to_path_buf(),
                tmp: None,
                file,
            });
        }
        let (dir, file_name) = dir_and_name(path)?;
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let mut tmp_name = std::ffi::OsString::from(".");
        tmp_name.push(file_name);
        tmp_name.push(format!(".{}.{n}.tmp", std::process::id()));
        let tmp = dir.join(tmp_name);
        let file = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&tmp)
            .map_err(|e| CordisError::io(path, e))?;
        Ok(AtomicFile {
            path: path.to_path_buf(),
            tmp: Some(tmp),
            file,
        })
    }

    /// The file being written (the temporary).
    pub fn file(&mut self) -> &mut std::fs::File {
        &mut self.file
    }

    /// The path the file replaces when committed.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Flushes the file to disk and renames it over `path`; an error names `path` (and
    /// leaves it as it was).
    pub fn commit(mut self) -> Result<()> {
        let Some(tmp) = self.tmp.take() else {
            return Ok(());
        };
        let path = self.path.clone();
        let result = self
            .file
            .sync_all()
            .and_then(|()| std::fs::rename(&tmp, &path));
        if let Err(e) = result {
            // Nothing more to report if the temporary cannot be removed.
            let _ = std::fs::remove_file(&tmp);
            return Err(CordisError::io(&path, e));
        }
        if let Ok((dir, name)) = dir_and_name(&path) {
            remove_stale_temporaries(&dir, name);
        }
        Ok(())
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if let Some(tmp) = &self.tmp {
            // Uncommitted: `path` keeps its old content. Best effort, as in `commit`.
            let _ = std::fs::remove_file(tmp);
        }
    }
}

/// Whether `path` exists and is neither a regular file nor a directory (`/dev/null`,
/// `/dev/stdout`, a FIFO): [`AtomicFile`] writes it in place, and nothing is to be written
/// beside it.
pub fn written_in_place(path: &Path) -> bool {
    std::fs::metadata(path).is_ok_and(|meta| !meta.is_file() && !meta.is_dir())
}

/// The directory (`.` for a bare name) and the file name of an output path.
fn dir_and_name(path: &Path) -> Result<(PathBuf, &std::ffi::OsStr)> {
    let file_name = path
        .file_name()
        .ok_or_else(|| CordisError::format(path.display().to_string(), "not a file name"))?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    Ok((dir, file_name))
}

/// Removes the temporaries that a killed writer of `file_name` left in `dir` (kill -9 or
/// Ctrl-C during a large write: `.NAME.PID.N.tmp`, or a `.NAME.PID.probe.tmp` of
/// [`paths::check_outputs`]), once the file is written again. Only on Linux, where a process
/// that no longer exists has no `/proc/PID`: a live writer's temporary is never touched.
fn remove_stale_temporaries(dir: &Path, file_name: &std::ffi::OsStr) {
    let proc = Path::new("/proc");
    if !proc.join("self").exists() {
        return;
    }
    let (Some(name), Ok(entries)) = (file_name.to_str(), std::fs::read_dir(dir)) else {
        return;
    };
    let prefix = format!(".{name}.");
    for entry in entries.flatten() {
        let entry_name = entry.file_name();
        let Some(rest) = entry_name
            .to_str()
            .and_then(|n| n.strip_prefix(&prefix))
            .and_then(|n| n.strip_suffix(".tmp"))
        else {
            continue;
        };
        let Some((pid, n)) = rest.split_once('.') else {
            continue;
        };
        let ours = pid.parse::<u32>().ok();
        let numbered = n == "probe" || (!n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()));
        if let (Some(pid), true) = (ours, numbered) {
            if pid != std::process::id() && !proc.join(pid.to_string()).exists() {
                // Best effort: a temporary that cannot be removed harms nothing more than before.
                let _ = std::fs::remove_file(entry.path());
            }
        }
    }
}

/// Text of a file: UTF-8 (a leading byte-order mark dropped), or else Latin-1, which the
/// thesis' files (French, written around 2000) may well be in. Every byte sequence decodes,
/// so a parser only ever sees text.
pub(crate) fn decode_text(bytes: &[u8]) -> Cow<'_, str> {
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    match std::str::from_utf8(bytes) {
        Ok(s) => Cow::Borrowed(s),
        Err(_) => Cow::Owned(bytes.iter().map(|&b| b as char).collect()),
    }
}

/// Reads a text file (see [`decode_text`]), bounded as [`read_input`].
pub fn read_text(path: &Path) -> Result<String> {
    let bytes = read_input(path)?;
    Ok(decode_text(&bytes).into_owned())
}

/// The largest regular file an input may be, bytes (2 GiB: a 10⁵-particle `.npy` of 1,000
/// frames is 2.4 GB, a scene of 10⁶ links ~100 MB).
pub const MAX_INPUT_BYTES: u64 = 2 << 30;

/// The most read from an input that is not a regular file (a pipe, `/dev/stdin`, a device),
/// bytes: its size is unknown until it ends, and `/dev/zero` never does.
pub const MAX_STREAM_BYTES: u64 = 256 << 20;

/// The bytes of an input file, refused with its size beyond [`MAX_INPUT_BYTES`] or the memory
/// available (before reading: a regular file's size is known), or beyond [`MAX_STREAM_BYTES`]
/// read from a stream. Reading without a bound, a symlink to `/dev/zero` ran until memory ran
/// out. The error is an [`CordisError::Io`] of kind `FileTooLarge` naming the file.
pub fn read_input(path: &Path) -> Result<Vec<u8>> {
    use std::io::Read;
    let too_large = |msg: String| {
        CordisError::io(
            path,
            std::io::Error::new(std::io::ErrorKind::FileTooLarge, msg),
        )
    };
    let file = std::fs::File::open(path).map_err(|e| CordisError::io(path, e))?;
    let meta = file.metadata().map_err(|e| CordisError::io(path, e))?;
    if meta.is_dir() {
        return Err(CordisError::io(
            path,
            std::io::Error::new(
                std::io::ErrorKind::IsADirectory,
                "is a directory, not a file",
            ),
        ));
    }
    let limit = if meta.is_file() {
        let len = meta.len();
        if len > MAX_INPUT_BYTES {
            return Err(too_large(format!(
                "{len} bytes, larger than the {MAX_INPUT_BYTES} bytes (2 GiB) an input may be"
            )));
        }
        if let Some(free) = crate::arg::available_memory() {
            if len > free {
                return Err(too_large(format!(
                    "{len} bytes, more than the {free} bytes of memory available"
                )));
            }
        }
        len.clamp(MAX_STREAM_BYTES, MAX_INPUT_BYTES)
    } else {
        MAX_STREAM_BYTES
    };
    let mut bytes = Vec::with_capacity(if meta.is_file() {
        meta.len() as usize
    } else {
        0
    });
    file.take(limit + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| CordisError::io(path, e))?;
    if bytes.len() as u64 > limit {
        return Err(too_large(format!(
            "not a regular file, and more than the {limit} bytes (256 MiB) read from a stream \
             (a device such as /dev/zero?)"
        )));
    }
    Ok(bytes)
}
