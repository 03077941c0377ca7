use std::path::PathBuf;

use anyhow::{anyhow, bail, Result};
use cordis_core::examples;

use super::Output;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Example name: rigid | cloth | fluid | horse | muscle | horse-gait | tadpole | frog
    /// | follower | central-muscle | bouncing-ball | horse-ground.
    name: String,
    /// Replace every muscle by a spring with its stiffness, rest length and damping (the
    /// passive model of thesis §6.2; applied before `--unknowns`).
    #[arg(long)]
    passive: bool,
    /// Write the scene with its positive parameters unknown, in boxes `--width` times wide
    /// around the true values (the truth is the scene written without this flag).
    #[arg(long)]
    unknowns: bool,
    /// With --unknowns: only these link types (comma-separated names) get unknowns; every
    /// other value stays known (e.g. identify a horse's four leg muscles only).
    #[arg(long, value_delimiter = ',')]
    unknown_types: Option<Vec<String>>,
    /// Width (max/min) of the unknown boxes: above 1, at most 1e100.
    #[arg(long, default_value_t = 25.0)]
    width: f64,
    /// Seed placing the truth inside each box.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Output file (default: stdout).
    #[arg(long, short = 'o')]
    out: Option<PathBuf>,
}

pub fn run(a: Args, output: Output) -> Result<()> {
    super::guard_outputs(&[], &[("--out", a.out.as_deref())])?;
    let scene = examples::by_name(&a.name).ok_or_else(|| {
        anyhow!(
            "example `{}` does not exist (expected one of: {})",
            a.name,
            examples::NAMES.join(", ")
        )
    })?;
    let scene = if a.passive {
        examples::passive(&scene)
    } else {
        scene
    };
    let scene = if a.unknowns {
        cordis_core::arg::box_width("--width", a.width)?;
        let mut out = cordis_es::identify::with_unknown_boxes(&scene, a.width, a.seed);
        if let Some(names) = &a.unknown_types {
            if let Some(bad) = names.iter().find(|n| scene.type_index(n).is_none()) {
                bail!(
                    "--unknown-types: `{bad}` is not a link type of example `{}`",
                    a.name
                );
            }
            for (t, known) in out.types.iter_mut().zip(&scene.types) {
                if !names.contains(&known.name) {
                    *t = known.clone();
                }
            }
        }
        out
    } else {
        if a.unknown_types.is_some() {
            bail!("--unknown-types needs --unknowns");
        }
        scene
    };
    let frames = examples::default_frames(&a.name);
    let summary = serde_json::json!({
        "example": a.name,
        "unknowns": a.unknowns,
        "passive": a.passive,
        "particles": scene.num_particles(),
        "types": scene.types.len(),
        "links": scene.links.len(),
        "couplings": scene.couplings.len(),
        "frames": frames,
    });
    output.scene_result(&scene, a.out.as_deref(), summary)?;
    if let (Some(out), true) = (&a.out, output.human()) {
        let couplings = match scene.couplings.len() {
            0 => String::new(),
            n => format!(", {n} couplings"),
        };
        eprintln!(
            "wrote {} ({} particles, {} types, {} links{couplings}; simulate {} frames)",
            out.display(),
            scene.num_particles(),
            scene.types.len(),
            scene.links.len(),
            frames
        );
    }
    Ok(())
}
