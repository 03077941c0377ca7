use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Result;
use cordis_core::io::TrajectoryFormat;
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
    check_frames(a.frames, scene.num_particles(), a.out.as_deref())?;
    let r = stability(&scene)?;
    if !r.stable {
        // A warning, not an error: the bound is sufficient, not necessary.
        eprintln!(
            "warning: stability ratio {} ≥ 1 at particle {} (bound 4m > K dt² + 2 Z dt): the \
             simulation may diverge; reduce dt or see `cordis check {}`",
            super::check::shown(r.max_ratio),
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

/// Refuses, before anything is allocated, a frame count whose trajectory (3 × 8 bytes per
/// particle and frame) and encoded output do not fit in the machine's memory: an allocation
/// failure aborts the process, and on Linux an allocation that succeeds on paper can still
/// exhaust the memory when the frames are written.
pub(crate) fn check_frames(frames: usize, particles: usize, out: Option<&Path>) -> Result<()> {
    // Bytes per particle and frame of the encoded file, an upper estimate (CSV: the frame and
    // particle numbers and three shortest-round-trip numbers; `.tra`: three numbers).
    let encoded = match out.and_then(|p| TrajectoryFormat::from_path(p).ok()) {
        Some(TrajectoryFormat::Csv) => 80.0,
        Some(TrajectoryFormat::Tra) => 72.0,
        Some(TrajectoryFormat::Npy) => 24.0,
        None => 0.0,
    };
    let per = 24.0 + encoded;
    let bytes = frames as f64 * particles as f64 * per;
    cordis_core::arg::fits_in_memory(
        "--frames",
        bytes,
        &format!(
            "{} frames × {particles} particles × {per} bytes",
            cordis_core::arg::short(frames as f64)
        ),
    )?;
    Ok(())
}
