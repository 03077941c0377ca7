use std::path::PathBuf;
use std::time::Instant;

use anyhow::Result;
use cordis_core::Scene;
use cordis_es::cost::{CostKind, Objective};

use super::Output;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scene file (JSON); unknown parameters are taken at their `init` or box middle.
    scene: PathBuf,
    /// Observed trajectory (.csv, .tsv, .npy, .tra, .trc, .c3d, .npz; see --columns, --units).
    #[arg(long, short = 't')]
    trajectory: PathBuf,
    /// Cost: short | horizon:H | long | progressive[:G[:START]] | harmonic[:EPS] | static.
    #[arg(long, default_value = "short")]
    cost: String,
    #[command(flatten)]
    read: super::ReadArgs,
}

pub fn run(a: Args, output: Output) -> Result<()> {
    let scene = Scene::from_json_path(&a.scene)?;
    let traj = cordis_core::io::read_trajectory_with(&a.trajectory, &a.read.options()?)?;
    super::check_dt(&scene, traj.dt, &a.trajectory)?;
    let kind: CostKind = a.cost.parse().map_err(|e| anyhow::anyhow!("--cost: {e}"))?;
    // Too short a file is bad input named by the file (as `identify` names it).
    if traj.frames() < kind.min_frames() {
        return Err(cordis_core::CordisError::trajectory(
            a.trajectory.display().to_string(),
            format!(
                "has {} frames, the {kind} cost needs at least {}",
                traj.frames(),
                kind.min_frames()
            ),
        )
        .into());
    }
    let start = Instant::now();
    let objective = Objective::new(&scene, &traj, kind)?;
    let report = objective.report(&scene.param_values())?;
    let seconds = start.elapsed().as_secs_f64();
    if output.human() {
        eprintln!(
            "{} cost over {} frames: total {:.6e}, rmse {:.6e} m ({} terms)",
            kind,
            traj.frames(),
            report.total,
            report.rmse,
            report.terms
        );
        eprintln!("{:>8}  {:>14}", "particle", "local cost");
        for (i, c) in report.per_particle.iter().enumerate() {
            eprintln!("{i:>8}  {c:>14.6e}");
        }
    }
    output.json_line(&serde_json::json!({
            "kind": kind.to_string(),
            "total": super::finite_or_string(report.total),
            "rmse": super::finite_or_string(report.rmse),
            "terms": report.terms,
            "per_particle": report.per_particle.iter().map(|c| super::finite_or_string(*c)).collect::<Vec<_>>(),
            "seconds": seconds,
    }))
}
