pub mod bench;
pub mod check;
pub mod cost;
pub mod discover;
pub mod example;
pub mod export;
pub mod identify;
pub mod import;
pub mod render;
pub mod report;
pub mod scene;
pub mod simulate;

use std::path::{Path, PathBuf};

use anyhow::Result;
use cordis_core::Scene;

/// The global output switches, shared by every subcommand.
///
/// stdout carries results: a command's JSON summary line (simulate, identify, cost, check,
/// bench), or a scene when it is written to stdout (example, import, discover without
/// `--out`). With `--json` stdout carries only JSON objects, one per line, for every command
/// (a scene is then embedded in the summary object). The human-readable report, progress
/// bars and "wrote …" lines go to stderr unless `--quiet`; warnings and errors always do.
#[derive(Clone, Copy, Debug, Default)]
pub struct Output {
    /// `--json`: stdout holds JSON objects only, one per line.
    pub json: bool,
    /// `--quiet`: no human-readable report or progress on stderr.
    pub quiet: bool,
}

impl Output {
    /// Whether to write the human-readable report on stderr.
    pub fn human(&self) -> bool {
        !self.quiet
    }

    /// Prints one JSON object on one line of stdout.
    pub fn json_line(&self, v: &serde_json::Value) -> Result<()> {
        print_stdout(&format!("{v}\n"))
    }

    /// Ends a command that writes a scene (example, import, discover): to `out` when given,
    /// else to stdout; then with `--json`, `summary` as one line (with the scene embedded as
    /// `"scene"` when it had no file to go to, and the file as `"out"`).
    pub fn scene_result(
        &self,
        scene: &Scene,
        out: Option<&Path>,
        mut summary: serde_json::Value,
    ) -> Result<()> {
        if self.json {
            if let Some(path) = out {
                write_scene(scene, Some(path))?;
            }
            summary["out"] = out.map(|p| p.display().to_string()).into();
            if out.is_none() {
                summary["scene"] = scene.to_json_value();
            }
            self.json_line(&summary)
        } else {
            write_scene(scene, out)
        }
    }
}

/// Raised by Ctrl-C once [`catch_ctrl_c`] is called: the run stops at its next step and
/// keeps what it has (the commands that run long read it).
pub static INTERRUPTED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// From now on Ctrl-C raises [`INTERRUPTED`] instead of killing the process.
pub fn catch_ctrl_c() {
    let _ = ctrlc::set_handler(|| INTERRUPTED.store(true, std::sync::atomic::Ordering::Relaxed));
}

/// A run stopped by Ctrl-C: exit code 130 (128 + SIGINT), as shells expect, so that
/// `cordis identify … && next-step` does not go on. The message says what was kept.
#[derive(Debug)]
pub struct Interrupted(pub String);

impl std::fmt::Display for Interrupted {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "interrupted (Ctrl-C); {}", self.0)
    }
}

impl std::error::Error for Interrupted {}

/// Refuses a trajectory whose time step (from its file, or `--dt`) is not the scene's: the
/// costs predict with the scene's dt.
pub fn check_dt(scene: &Scene, traj_dt: Option<f64>, traj_path: &Path) -> Result<()> {
    if let Some(dt) = traj_dt {
        // NaN differs from nothing by the test below: refuse it (and 0, inf) first.
        cordis_core::arg::number("--dt", dt, cordis_core::arg::Low::Above(0.0), f64::MAX, "s")?;
        if (dt - scene.dt).abs() > 1e-12 * scene.dt {
            anyhow::bail!(
                "{}: trajectory dt {dt} differs from the scene's dt {}",
                traj_path.display(),
                scene.dt
            );
        }
    }
    Ok(())
}

/// Refuses, before any work, an output that is an input or another output, or that cannot be
/// written (`cordis_core::io::check_outputs`); each path is named by its option (`None`: not
/// given). A same-file pair exits 2 (usage), an unwritable output 1 (I/O).
pub fn guard_outputs(
    inputs: &[(&str, Option<&Path>)],
    outputs: &[(&str, Option<&Path>)],
) -> Result<()> {
    fn given<'a>(v: &[(&'a str, Option<&'a Path>)]) -> Vec<(&'a str, &'a Path)> {
        v.iter().filter_map(|&(n, p)| p.map(|p| (n, p))).collect()
    }
    cordis_core::io::check_outputs(&given(inputs), &given(outputs))?;
    Ok(())
}

/// What `render` and `report` share: a scene, a motion, the one HTML page they write and its
/// title, and how to read the motion.
#[derive(clap::Args, Debug)]
pub struct PageArgs {
    /// Scene file (JSON, cordis-scene/1): its links are drawn, its time step used (`report`:
    /// the identified model, every parameter known).
    pub scene: PathBuf,
    /// The motion (.csv, .tsv, .npy, .tra, .trc, .c3d, .npz): `render` draws it solid,
    /// `report` takes it as the observed motion (gaps allowed).
    #[arg(long, short = 't')]
    pub trajectory: PathBuf,
    /// The page to write: one self-contained HTML file, nothing loaded from the network.
    #[arg(long)]
    pub html: PathBuf,
    /// Page title (default: the file names).
    #[arg(long)]
    pub title: Option<String>,
    #[command(flatten)]
    pub read: ReadArgs,
}

impl PageArgs {
    /// The scene, read once the page is checked off it, the motion and `inputs` (the
    /// command's others), before any work.
    pub fn guarded_scene(&self, inputs: &[(&str, Option<&Path>)]) -> Result<Scene> {
        let mut all = vec![
            ("scene", Some(self.scene.as_path())),
            ("--trajectory", Some(self.trajectory.as_path())),
        ];
        all.extend_from_slice(inputs);
        guard_outputs(&all, &[("--html", Some(&self.html))])?;
        Ok(Scene::from_json_path(&self.scene)?)
    }

    /// `--title`, else `default(scene's file name, motion's file name)`.
    pub fn title_or(&self, default: impl FnOnce(&str, &str) -> String) -> String {
        self.title
            .clone()
            .unwrap_or_else(|| default(&file_name(&self.scene), &file_name(&self.trajectory)))
    }
}

/// A path's file name for a title (the whole path when it has none).
pub fn file_name(p: &Path) -> String {
    p.file_name().map_or_else(
        || p.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}

/// How to read a trajectory file beyond its extension: a table's columns, its delimiter, the
/// units of a file that does not state them. Every command that takes a trajectory has these.
#[derive(clap::Args, Clone, Debug, Default)]
pub struct ReadArgs {
    /// Columns of a .csv/.tsv table, e.g. `frame=Frame,particle=Marker,x=X,y=Y,z=Z`, `time=t`,
    /// or a wide table `time=Time,x=*_X` (`*` is the marker's name). Keys not given are found
    /// by their usual names.
    #[arg(long, value_name = "KEY=COLUMN,...")]
    pub columns: Option<String>,
    /// Units of a trajectory file that does not state them: m, cm or mm (default m). A file
    /// that states others (TRC, C3D, `X [mm]`) is refused.
    #[arg(long)]
    pub units: Option<String>,
    /// Delimiter of a .csv/.tsv table: `,` `;` `tab` `space` (default: from its header).
    #[arg(long)]
    pub delimiter: Option<String>,
}

impl ReadArgs {
    /// The reader's options, each option's value checked.
    pub fn options(&self) -> Result<cordis_core::io::ReadOptions> {
        use cordis_core::io::markers::{Delimiter, Units};
        Ok(cordis_core::io::ReadOptions {
            columns: self.columns.clone(),
            units: self
                .units
                .as_deref()
                .map(|u| Units::parse_arg("--units", u))
                .transpose()?,
            delimiter: self
                .delimiter
                .as_deref()
                .map(|d| Delimiter::parse_arg("--delimiter", d))
                .transpose()?,
        })
    }
}

/// Writes a scene as JSON (atomically) or to stdout when no path is given.
pub fn write_scene(scene: &Scene, out: Option<&Path>) -> Result<()> {
    let text = scene.to_json_string();
    match out {
        Some(path) => cordis_core::io::write_atomic(path, text.as_bytes())?,
        None => print_stdout(&text)?,
    }
    Ok(())
}

/// Writes to stdout; a closed pipe (`cordis example fluid | head`) ends the output quietly
/// instead of panicking like `print!` does.
pub fn print_stdout(text: &str) -> Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(e.into()),
        _ => Ok(()),
    }
}

/// One `--markers` entry: a particle index, spaces around it allowed (`--markers "11, 0, 4"`
/// was refused as "invalid digit" for ` 0`).
fn particle_index(s: &str) -> std::result::Result<usize, String> {
    s.trim()
        .parse()
        .map_err(|_| format!("expected a particle index (an integer from 0), got `{s}`"))
}

/// A comma-separated list of particle indices (`--markers 4,0,7`, spaces after the commas
/// allowed), read as one value so that a bad entry is named by its index (clap read the
/// entries one by one and named the value only).
#[derive(Clone, Debug)]
pub(crate) struct ParticleIndices(pub Vec<usize>);

pub(crate) fn particle_indices(s: &str) -> std::result::Result<ParticleIndices, String> {
    s.split(',')
        .enumerate()
        .map(|(k, entry)| particle_index(entry).map_err(|m| format!("entry {k}: {m}")))
        .collect::<std::result::Result<_, _>>()
        .map(ParticleIndices)
}

/// A number for a JSON summary line: JSON has no infinity nor NaN, so a non-finite one (a
/// diverged cost, a Ctrl-C before any finite cost) is the string `"inf"` / `"NaN"`, as the
/// solvers' reports write it, never `null`.
pub(crate) fn finite_or_string(v: f64) -> serde_json::Value {
    if v.is_finite() {
        v.into()
    } else {
        v.to_string().into()
    }
}
