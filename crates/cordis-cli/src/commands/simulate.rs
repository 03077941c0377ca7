use std::path::PathBuf;
use std::time::Instant;

use anyhow::Result;
use cordis_core::{Scene, Simulator};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scene file (JSON, cordis-scene/1).
    scene: PathBuf,
    /// Number of frames to write, including frame 0 (the initial positions).
    #[arg(long, short = 'n')]
    frames: usize,
    /// Output trajectory; the format follows the extension: .csv, .npy or .tra.
    #[arg(long, short = 'o')]
    out: Option<PathBuf>,
    /// Print only the JSON summary line.
    #[arg(long, short = 'q')]
    quiet: bool,
}

pub fn run(a: Args) -> Result<()> {
    let scene = Scene::from_json_path(&a.scene)?;
    let mut sim = Simulator::new(&scene)?;
    let start = Instant::now();
    let traj = sim.run(a.frames)?;
    let seconds = start.elapsed().as_secs_f64();
    if let Some(out) = &a.out {
        cordis_core::io::write_trajectory(out, &traj)?;
    }
    let link_steps = (sim.plan().num_links() * a.frames.saturating_sub(1)) as f64;
    if !a.quiet {
        eprintln!(
            "simulated {} frames of {} particles and {} links in {:.3} s ({:.1} M link-steps/s){}",
            a.frames,
            scene.num_particles(),
            sim.plan().num_links(),
            seconds,
            link_steps / seconds.max(1e-12) / 1e6,
            a.out
                .as_ref()
                .map(|p| format!(", wrote {}", p.display()))
                .unwrap_or_default()
        );
    }
    println!(
        "{}",
        serde_json::json!({
            "frames": a.frames,
            "particles": scene.num_particles(),
            "links": sim.plan().num_links(),
            "seconds": seconds,
            "scale": traj.scale(),
        })
    );
    Ok(())
}
