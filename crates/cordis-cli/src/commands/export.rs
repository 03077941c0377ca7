//! `cordis export`: a scene for MuJoCo (`--mjcf`), a motion for Blender and three.js
//! (`--gltf`), and the motion itself as a trajectory file (`--out`, .npy / .csv / .tra).
//!
//! The motion is `--trajectory T` (any format the readers take) or the scene's own replay over
//! `--frames N`. Every output is built in memory first and then written atomically, so a
//! refusal (a kind MJCF cannot express, a trajectory of another scene) writes nothing, and no
//! output may be an input or another output.

use std::path::PathBuf;

use anyhow::{Context, Result};
use cordis_core::export::{callback_kinds, to_gltf, to_mjcf};
use cordis_core::io::{read_trajectory_with, write_atomic, write_trajectory};
use cordis_core::{Scene, Simulator, Trajectory};

use super::Output;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scene file (JSON, cordis-scene/1).
    scene: PathBuf,
    /// MuJoCo model to write (MJCF XML): body `p{i}` per particle, slide joints, tendons,
    /// semi-implicit Euler equal to the CORDIS step. Angle, conditional and plane links,
    /// damping_quadratic and max_elongation go into <custom> data that Python's
    /// `cordis.mujoco.load` applies; muscles, TGRs, transmitters, nonlinear drags, signals,
    /// worlds and unknowns are refused, naming them.
    #[arg(long)]
    mjcf: Option<PathBuf>,
    /// glTF 2.0 animation to write (.gltf, self-contained): points and links, one morph target
    /// per frame. Needs --trajectory or --frames.
    #[arg(long)]
    gltf: Option<PathBuf>,
    /// The motion to export (.csv, .tsv, .npy, .tra, .trc, .c3d, .npz).
    #[arg(long, short = 't', conflicts_with = "frames")]
    trajectory: Option<PathBuf>,
    /// Export the scene's own replay over this many frames (frame 0 included) instead.
    #[arg(long, short = 'n')]
    frames: Option<usize>,
    /// Also write the exported motion as a trajectory file (.npy, .csv or .tra).
    #[arg(long, short = 'o')]
    out: Option<PathBuf>,
    #[command(flatten)]
    read: super::ReadArgs,
}

pub fn run(a: Args, output: Output) -> Result<()> {
    super::guard_outputs(
        &[
            ("scene", Some(&a.scene)),
            ("--trajectory", a.trajectory.as_deref()),
        ],
        &[
            ("--mjcf", a.mjcf.as_deref()),
            ("--gltf", a.gltf.as_deref()),
            ("--out", a.out.as_deref()),
        ],
    )?;
    if a.mjcf.is_none() && a.gltf.is_none() && a.out.is_none() {
        anyhow::bail!("export: nothing to write; give --mjcf, --gltf or --out");
    }
    let wants_motion = a.gltf.is_some() || a.out.is_some();
    if wants_motion && a.trajectory.is_none() && a.frames.is_none() {
        anyhow::bail!(
            "{}: needs a motion: --trajectory T, or --frames N for the scene's replay",
            if a.gltf.is_some() { "--gltf" } else { "--out" }
        );
    }
    if !wants_motion && (a.trajectory.is_some() || a.frames.is_some()) {
        anyhow::bail!("--trajectory/--frames: only with --gltf or --out (MJCF holds no motion)");
    }
    let scene = Scene::from_json_path(&a.scene)?;
    let scene_name = a.scene.display().to_string();
    let mjcf = a
        .mjcf
        .as_ref()
        .map(|_| to_mjcf(&scene))
        .transpose()
        .with_context(|| scene_name.clone())?;
    let callbacks = match &mjcf {
        Some(_) => callback_kinds(&scene)?,
        None => Vec::new(),
    };
    let motion = if wants_motion {
        Some(motion(&a, &scene)?)
    } else {
        None
    };
    let gltf = match (&a.gltf, &motion) {
        (Some(_), Some(traj)) => Some(
            to_gltf(&scene, traj, traj.dt.unwrap_or(scene.dt)).with_context(|| {
                a.trajectory
                    .as_ref()
                    .map_or(scene_name.clone(), |t| t.display().to_string())
            })?,
        ),
        _ => None,
    };
    // Everything is built: only now write, each file atomically.
    let mut wrote = Vec::new();
    if let (Some(path), Some(xml)) = (&a.mjcf, &mjcf) {
        write_atomic(path, xml.as_bytes())?;
        wrote.push(("mjcf", path, xml.len()));
    }
    if let (Some(path), Some(text)) = (&a.gltf, &gltf) {
        write_atomic(path, text.as_bytes())?;
        wrote.push(("gltf", path, text.len()));
    }
    if let (Some(path), Some(traj)) = (&a.out, &motion) {
        write_trajectory(path, traj)?;
        wrote.push(("out", path, 0));
    }
    if output.human() {
        for (_, path, bytes) in &wrote {
            let size = if *bytes > 0 {
                format!(" ({} KB)", bytes.div_ceil(1000))
            } else {
                String::new()
            };
            eprintln!("wrote {}{size}", path.display());
        }
        if let (Some(path), false) = (&a.mjcf, callbacks.is_empty()) {
            eprintln!(
                "note: {}: MJCF has no element for: {}; cordis.mujoco.load(path) (Python) adds \
                 them while MuJoCo integrates, plain MuJoCo leaves them out",
                path.display(),
                callbacks.join(", ")
            );
        }
    }
    if output.json {
        let mut summary = serde_json::json!({
            "particles": scene.num_particles(),
            "frames": motion.as_ref().map(Trajectory::frames),
        });
        for (key, path, _) in &wrote {
            summary[*key] = path.display().to_string().into();
        }
        if a.mjcf.is_some() {
            summary["mjcf_callbacks"] = callbacks.into();
        }
        output.json_line(&summary)?;
    }
    Ok(())
}

/// The motion to export: the trajectory file (checked against the scene), or the replay.
fn motion(a: &Args, scene: &Scene) -> Result<Trajectory> {
    if let Some(path) = &a.trajectory {
        let traj = read_trajectory_with(path, &a.read.options()?)?;
        traj.check_fits(scene.num_particles(), 1)
            .with_context(|| path.display().to_string())?;
        return Ok(traj);
    }
    let frames = a.frames.unwrap_or(0);
    if frames == 0 {
        anyhow::bail!("--frames: must be at least 1 (frame 0 is the initial state)");
    }
    super::simulate::check_frames(frames, scene.num_particles(), a.out.as_deref())?;
    Ok(Simulator::new(scene)?.run(frames)?.with_dt(scene.dt))
}
