use std::path::PathBuf;

use anyhow::Result;
use cordis_core::io::{read_trajectory_with, write_atomic};
use cordis_core::CordisError;

use super::Output;

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    page: super::PageArgs,
    /// A second motion of the same scene (e.g. the identified model's), drawn pale and dashed
    /// under the first, or side by side.
    #[arg(long, short = 'c')]
    compare: Option<PathBuf>,
}

pub fn run(a: Args, output: Output) -> Result<()> {
    let scene = a
        .page
        .guarded_scene(&[("--compare", a.compare.as_deref())])?;
    let options = a.page.read.options()?;
    let traj = read_trajectory_with(&a.page.trajectory, &options)?;
    let compare = a
        .compare
        .as_deref()
        .map(|c| read_trajectory_with(c, &options))
        .transpose()?;
    let title = a.page.title_or(|scene, motion| match &a.compare {
        Some(c) => format!("{scene} — {motion} vs {}", super::file_name(c)),
        None => format!("{scene} — {motion}"),
    });
    let labels = [
        super::file_name(&a.page.trajectory),
        a.compare
            .as_deref()
            .map_or_else(|| "compared".into(), super::file_name),
    ];
    let labels = [labels[0].as_str(), labels[1].as_str()];
    let page = crate::render::render_html_labelled(&scene, &traj, compare.as_ref(), &title, labels)
        .map_err(|e| name_files(e, &a))?;
    write_atomic(&a.page.html, page.as_bytes())?;
    let size = if page.len() < 1_000_000 {
        format!("{} KB", page.len().div_ceil(1000))
    } else {
        format!("{:.1} MB", page.len() as f64 / 1e6)
    };
    if output.human() {
        eprintln!(
            "wrote {} ({size}; {} frames of {} particles{})",
            a.page.html.display(),
            traj.frames(),
            traj.particles(),
            if compare.is_some() { ", 2 motions" } else { "" }
        );
    }
    if output.json {
        output.json_line(&serde_json::json!({
            "html": a.page.html.display().to_string(),
            "bytes": page.len(),
            "frames": traj.frames(),
            "particles": traj.particles(),
            "motions": if compare.is_some() { 2 } else { 1 },
        }))?;
    }
    Ok(())
}

/// `render_html` calls the motions "trajectory A" and "trajectory B": name their files instead.
fn name_files(e: CordisError, a: &Args) -> CordisError {
    match e {
        CordisError::Trajectory { place, message } => {
            let mut place =
                place.replacen("trajectory A", &a.page.trajectory.display().to_string(), 1);
            if let Some(c) = &a.compare {
                place = place.replacen("trajectory B (--compare)", &c.display().to_string(), 1);
            }
            CordisError::trajectory(place, message)
        }
        other => other,
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use cordis_core::{LinkKind, LinkType, Particle, Scene};

    fn cordis(args: &[&Path]) -> i32 {
        let mut all = vec![std::ffi::OsString::from("cordis")];
        all.extend(args.iter().map(|a| a.as_os_str().to_owned()));
        crate::run(all)
    }

    #[test]
    fn writes_a_page_and_names_the_file_that_does_not_fit() {
        let dir = tempfile::tempdir().unwrap();
        let p = |name: &str| dir.path().join(name);
        let mut s = Scene::new(0.01);
        s.add_particle(Particle::new(1.0, [0.0, 0.0, 0.0]).fixed());
        s.add_particle(Particle::new(1.0, [1.2, 0.0, 0.0]));
        s.add_type(
            LinkType::new("rib", LinkKind::Spring)
                .with("stiffness", 20.0)
                .with("rest_length", 1.0),
        );
        s.add_link("rib", &[0, 1]);
        std::fs::write(p("s.json"), s.to_json_string()).unwrap();
        cordis_core::io::write_trajectory(&p("a.csv"), &s.simulate(20).unwrap()).unwrap();
        let three = cordis_core::Trajectory::zeros(2, 3);
        cordis_core::io::write_trajectory(&p("three.npy"), &three).unwrap();

        let (render, traj, compare, html) = (
            Path::new("render"),
            Path::new("--trajectory"),
            Path::new("--compare"),
            Path::new("--html"),
        );
        let code = cordis(&[
            render,
            &p("s.json"),
            traj,
            &p("a.csv"),
            compare,
            &p("a.csv"),
            html,
            &p("v.html"),
        ]);
        assert_eq!(code, 0);
        let page = std::fs::read_to_string(p("v.html")).unwrap();
        assert!(page.starts_with("<!DOCTYPE html>"));
        assert!(page.contains("<title>s.json — a.csv vs a.csv</title>"));

        // A motion of another scene: refused (exit 2), and no page is written.
        let code = cordis(&[
            render,
            &p("s.json"),
            traj,
            &p("three.npy"),
            html,
            &p("w.html"),
        ]);
        assert_eq!(code, 2);
        assert!(!p("w.html").exists());
        let e = crate::render::render_html(&s, &three, None, "t").unwrap_err();
        let args = super::Args {
            page: crate::commands::PageArgs {
                scene: p("s.json"),
                trajectory: p("three.npy"),
                html: p("w.html"),
                title: None,
                read: Default::default(),
            },
            compare: None,
        };
        let named = super::name_files(e, &args).to_string();
        assert!(
            named.starts_with(&format!("{}: has 3 particles", p("three.npy").display())),
            "{named}"
        );
    }
}
