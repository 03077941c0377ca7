//! `cordis check SCENE`: the stability report (`cordis_core::stability`), readable on stderr,
//! one JSON line on stdout. An unstable scene is a finding, not an error: the exit code is 0.

use std::path::PathBuf;

use anyhow::Result;
use cordis_core::stability::{degenerate_angles, max_stable_dt, stability};
use cordis_core::Scene;
use serde_json::json;

use super::Output;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scene file (JSON, cordis-scene/1).
    scene: PathBuf,
    /// Particles listed in the readable report, worst first.
    #[arg(long, default_value_t = 5)]
    top: usize,
}

pub fn run(a: Args, output: Output) -> Result<()> {
    let scene = Scene::from_json_path(&a.scene)?;
    let r = stability(&scene)?;
    let dt_max = max_stable_dt(&scene)?;
    let free = r.per_particle.iter().flatten().count();
    let degenerate = degenerate_angles(&scene);
    if output.human() {
        let verdict = if r.stable {
            "stable: every particle is inside the bound"
        } else {
            "UNSTABLE: the bound is exceeded, the simulation may diverge"
        };
        eprintln!(
            "{}: {} particles ({free} free), dt = {} s",
            a.scene.display(),
            scene.num_particles(),
            scene.dt
        );
        eprintln!(
            "  stability ratio q = (dt² K + 2 dt Z) / 4m per particle (neighbours' motion \
             counted); q < 1 guarantees stability"
        );
        eprintln!("  max q = {} → {verdict}", shown(r.max_ratio));
        eprintln!(
            "  with every neighbour held fixed (classical CORDIS 4M > K + 2Z): max q = {}",
            shown(r.local_max_ratio)
        );
        if !degenerate.is_empty() {
            let shown: Vec<String> = degenerate
                .iter()
                .take(10)
                .map(|&l| format!("links[{l}] {:?}", scene.links[l].particles))
                .collect();
            eprintln!(
                "  {} degenerate angle link(s), an arm under 1% of the other (particles at one \
                 point: the angle is barely defined, its force the stiffest): {}{}",
                degenerate.len(),
                shown.join(", "),
                if degenerate.len() > 10 { ", …" } else { "" }
            );
        }
        match dt_max {
            Some(d) => eprintln!("  the bound holds for dt < {d:.6e} s"),
            None => eprintln!("  no free particle has a stiffness or damping: any dt passes"),
        }
        let mut ranked: Vec<(usize, f64)> = r
            .per_particle
            .iter()
            .enumerate()
            .filter_map(|(i, q)| q.map(|q| (i, q)))
            .collect();
        ranked.sort_by(|x, y| y.1.total_cmp(&x.1).then(x.0.cmp(&y.0)));
        if !ranked.is_empty() && a.top > 0 {
            eprintln!("  worst particles:   particle        q     mass (kg)");
            for (i, q) in ranked.iter().take(a.top) {
                eprintln!(
                    "                     {i:>8} {:>8} {:>13.6e}",
                    shown(*q),
                    scene.particles[*i].mass.value()
                );
            }
        }
    }
    output.json_line(&json!({
            "max_stability_ratio": finite(r.max_ratio),
            "stable": r.stable,
            "worst_particle": r.worst_particle,
            "local_max_ratio": finite(r.local_max_ratio),
            "max_stable_dt": dt_max,
            "dt": scene.dt,
            "particles": scene.num_particles(),
            "free_particles": free,
            "degenerate_angles": degenerate,
    }))
}

/// A ratio for reading: four decimals, in scientific notation from 1e6 on (a ratio of 6.8e303
/// was printed as 300 digits), or `inf`.
pub fn shown(q: f64) -> String {
    if !q.is_finite() {
        "inf".into()
    } else if q.abs() >= 1e6 {
        format!("{q:.4e}")
    } else {
        format!("{q:.4}")
    }
}

/// JSON has no infinity: a ratio that overflowed is written as null.
fn finite(q: f64) -> Option<f64> {
    q.is_finite().then_some(q)
}
