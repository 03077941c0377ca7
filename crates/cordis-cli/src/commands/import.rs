use std::path::PathBuf;

use anyhow::Result;

use super::Output;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Base name of the thesis files: NAME.mas, NAME.cat, NAME.ini, NAME.tra, NAME.lock.
    name: PathBuf,
    /// Time step in s (the thesis files do not carry it).
    #[arg(long, default_value_t = 0.01)]
    dt: f64,
    /// Output scene (default: stdout).
    #[arg(long, short = 'o')]
    out: Option<PathBuf>,
    /// Also write NAME.tra's trajectory here (.csv, .npy or .tra).
    #[arg(long)]
    trajectory: Option<PathBuf>,
}

pub fn run(a: Args, output: Output) -> Result<()> {
    let read = cordis_core::thesis::model_files(&a.name);
    let inputs: Vec<_> = read.iter().map(|p| ("NAME", Some(p.as_path()))).collect();
    super::guard_outputs(
        &inputs,
        &[
            ("--out", a.out.as_deref()),
            ("--trajectory", a.trajectory.as_deref()),
        ],
    )?;
    let model = cordis_core::thesis::import(&a.name, a.dt)?;
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
