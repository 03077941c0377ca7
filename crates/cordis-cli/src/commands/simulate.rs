use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Result};
use cordis_core::{stability::stability, Scene, Simulator};

use super::Output;

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
}

pub fn run(a: Args, output: Output) -> Result<()> {
    super::guard_outputs(&[("scene", Some(&a.scene))], &[("--out", a.out.as_deref())])?;
    let scene = Scene::from_json_path(&a.scene)?;
    check_frames(a.frames, scene.num_particles())?;
    let r = stability(&scene)?;
    if !r.stable {
        // A warning, not an error: the bound is sufficient, not necessary.
        eprintln!(
            "warning: stability ratio {:.4} ≥ 1 at particle {} (bound 4m > K dt² + 2 Z dt): the \
             simulation may diverge; reduce dt or see `cordis check {}`",
            r.max_ratio,
            r.worst_particle.map_or("?".into(), |i| i.to_string()),
            a.scene.display()
        );
    }
    let mut sim = Simulator::new(&scene)?;
    let start = Instant::now();
    let traj = sim.run(a.frames)?;
    let seconds = start.elapsed().as_secs_f64();
    if let Some(out) = &a.out {
        cordis_core::io::write_trajectory(out, &traj)?;
    }
    let link_steps = (sim.plan().num_links() * a.frames.saturating_sub(1)) as f64;
    if output.human() {
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
    output.json_line(&serde_json::json!({
            "frames": a.frames,
            "particles": scene.num_particles(),
            "links": sim.plan().num_links(),
            "seconds": seconds,
            "scale": traj.scale(),
            "out": a.out.as_ref().map(|p| p.display().to_string()),
    }))
}

/// Refuses a frame count whose trajectory cannot be held in memory, before anything is
/// allocated (an allocation failure would abort the process).
fn check_frames(frames: usize, particles: usize) -> Result<()> {
    let values = frames
        .checked_mul(particles)
        .and_then(|v| v.checked_mul(3))
        .filter(|v| v.checked_mul(8).is_some_and(|b| b <= isize::MAX as usize));
    let Some(values) = values else {
        bail!("--frames {frames}: {frames} frames × {particles} particles do not fit in memory");
    };
    let mut probe: Vec<f64> = Vec::new();
    if probe.try_reserve_exact(values).is_err() {
        bail!(
            "--frames {frames}: the trajectory needs {:.3e} bytes, more than can be allocated",
            values as f64 * 8.0
        );
    }
    Ok(())
}
