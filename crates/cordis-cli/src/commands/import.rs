//! `cordis import`: the thesis' model files into a JSON scene (`cordis import NAME`), or a
//! marker file of the field into a trajectory (`cordis import FILE --out traj.npy`).
//!
//! The argument decides: a path whose extension is a trajectory format (`.c3d`, `.trc`,
//! `.npz`, `.csv`, `.tsv`, `.npy`, `.tra`) is converted; anything else is the thesis' base
//! name `NAME` (`NAME.mas`, `NAME.cat`, …, which carry no such extension), as before.

use std::path::{Path, PathBuf};

use anyhow::Result;
use cordis_core::io::{InputFormat, TrajectoryFormat};

use super::{Output, ReadArgs};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Base name of the thesis files (NAME.mas, NAME.cat, NAME.ini, NAME.tra, NAME.lock), or a
    /// trajectory file to convert (.c3d, .trc, .npz, .csv, .tsv, .npy, .tra).
    name: PathBuf,
    /// Time step in s: the thesis files do not carry it (default 0.01); for a trajectory file
    /// without a rate, the dt to report (one with a rate must agree).
    #[arg(long)]
    dt: Option<f64>,
    /// Output: the scene (default: stdout); for a trajectory file, the converted trajectory
    /// (.npy or .csv keep missing markers as NaN / empty cells; .tra has no gaps).
    #[arg(long, short = 'o')]
    out: Option<PathBuf>,
    /// Also write NAME.tra's trajectory here (.csv, .npy or .tra). Thesis files only.
    #[arg(long)]
    trajectory: Option<PathBuf>,
    #[command(flatten)]
    read: ReadArgs,
}

pub fn run(a: Args, output: Output) -> Result<()> {
    if InputFormat::is_trajectory_path(&a.name) {
        return convert(a, output);
    }
    let given = [
        ("--columns", a.read.columns.is_some()),
        ("--units", a.read.units.is_some()),
        ("--delimiter", a.read.delimiter.is_some()),
    ];
    if let Some((option, _)) = given.iter().find(|(_, g)| *g) {
        anyhow::bail!(
            "{option}: only for a trajectory file (.c3d, .trc, .npz, .csv, .tsv, .npy, .tra); {} names the thesis files",
            a.name.display()
        );
    }
    import_thesis(a, output)
}

/// `cordis import FILE --out traj.npy`: reads any marker format, writes NaN where missing.
fn convert(a: Args, output: Output) -> Result<()> {
    if a.trajectory.is_some() {
        anyhow::bail!(
            "--trajectory: only for the thesis files; to convert {}, give --out",
            a.name.display()
        );
    }
    let Some(out) = a.out.as_deref() else {
        anyhow::bail!(
            "--out: required to convert {} (a trajectory file): --out traj.npy (or .csv)",
            a.name.display()
        );
    };
    TrajectoryFormat::from_path(out)?;
    let options = a.read.options()?;
    if let Some(dt) = a.dt {
        cordis_core::arg::number("--dt", dt, cordis_core::arg::Low::Above(0.0), f64::MAX, "s")?;
    }
    super::guard_outputs(&[("FILE", Some(&a.name))], &[("--out", Some(out))])?;
    let imported = cordis_core::io::read_markers(&a.name, &options)?;
    let obs = &imported.observations;
    let dt = match (obs.dt, a.dt) {
        (Some(file), Some(given)) if (file - given).abs() > 1e-9 * file => anyhow::bail!(
            "--dt: {given} s, but {} gives a rate of dt {file} s",
            a.name.display()
        ),
        (file, given) => file.or(given),
    };
    cordis_core::io::write_observations(out, obs)?;
    report(&a.name, out, &imported, dt, output)
}

fn report(
    input: &Path,
    out: &Path,
    imported: &cordis_core::io::Imported,
    dt: Option<f64>,
    output: Output,
) -> Result<()> {
    let obs = &imported.observations;
    let missing = obs.missing();
    if output.human() {
        eprintln!(
            "read {} {}: {} frames × {} markers; {}\n{} missing coordinates → NaN{}; wrote {}",
            imported.format.name(),
            input.display(),
            obs.frames(),
            obs.particles(),
            imported.mapping,
            missing,
            dt.map(|d| format!("; dt {d} s (the output does not store it: give it to the scene)"))
                .unwrap_or_else(|| "; no rate: give --dt to the commands that need one".into()),
            out.display()
        );
    }
    output.json_line(&serde_json::json!({
        "format": imported.format.name(),
        "input": input.display().to_string(),
        "frames": obs.frames(),
        "particles": obs.particles(),
        "labels": imported.labels,
        "dt": dt,
        "missing": missing,
        "mapping": imported.mapping,
        "out": out.display().to_string(),
    }))
}

/// `cordis import NAME`: the thesis' model files into a scene (and `--trajectory`).
fn import_thesis(a: Args, output: Output) -> Result<()> {
    let read = cordis_core::thesis::model_files(&a.name);
    let inputs: Vec<_> = read.iter().map(|p| ("NAME", Some(p.as_path()))).collect();
    super::guard_outputs(
        &inputs,
        &[
            ("--out", a.out.as_deref()),
            ("--trajectory", a.trajectory.as_deref()),
        ],
    )?;
    let model = cordis_core::thesis::import(&a.name, a.dt.unwrap_or(0.01))?;
    // The trajectory is checked before anything is written: a failed import writes nothing.
    let traj = match (&a.trajectory, &model.trajectory) {
        (Some(_), None) => anyhow::bail!("{}.tra: no trajectory to write", a.name.display()),
        (Some(path), Some(t)) => Some((path, t)),
        (None, _) => None,
    };
    let s = &model.scene;
    let summary = serde_json::json!({
        "particles": s.num_particles(),
        "types": s.types.len(),
        "links": s.links.len(),
        "unknowns": s.has_unknowns(),
        "dt": s.dt,
        "trajectory": traj.map(|(p, _)| p.display().to_string()),
        "frames": model.trajectory.as_ref().map(|t| t.frames()),
    });
    if let Some((path, t)) = traj {
        cordis_core::io::write_trajectory(path, t)?;
    }
    output.scene_result(s, a.out.as_deref(), summary)?;
    if let (Some(out), true) = (&a.out, output.human()) {
        eprintln!(
            "wrote {} ({} particles, {} types, {} links){}",
            out.display(),
            s.num_particles(),
            s.types.len(),
            s.links.len(),
            traj.map(|(p, _)| format!(" and {}", p.display()))
                .unwrap_or_default()
        );
    }
    Ok(())
}
