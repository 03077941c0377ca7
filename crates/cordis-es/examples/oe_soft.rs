//! Probe: the soft block with the output-error defaults.
use cordis_core::io::read_trajectory;
use cordis_core::Scene;
use cordis_es::output_error::{estimate, identified_scene, Config, Take};
use cordis_es::space::ParameterSpace;

fn main() {
    let dir = std::path::Path::new("../shared/data/soft-block");
    let guess = Scene::from_json_path(dir.join("guess.json")).unwrap();
    let truth = Scene::from_json_path(dir.join("truth.json")).unwrap();
    let obs = read_trajectory(&dir.join("markers.csv")).unwrap();
    let space = ParameterSpace::from_scene(&guess);
    let t0 = std::time::Instant::now();
    let e = estimate(&guess, &space, &[Take::complete(&obs)], &Config::default()).unwrap();
    let tv = truth.param_values();
    for (k, u) in space.unknowns.iter().enumerate() {
        println!(
            "{:28} {:10.5} ± {:8.5}  truth {:10.5}",
            u.name, e.params[u.slot], e.stderr[k], tv[u.slot]
        );
    }
    println!(
        "error {:.3} % σ̂ {:.3e} {} it {} {:.2} s start: {}",
        space.error_pct(&e.genome, &tv),
        e.sigma,
        e.end,
        e.iterations,
        t0.elapsed().as_secs_f64(),
        e.start
    );
    let rms = |s: &Scene| {
        let sim = s.simulate(obs.frames()).unwrap();
        let d: f64 = sim
            .as_flat()
            .iter()
            .zip(obs.as_flat())
            .map(|(a, b)| (a - b) * (a - b))
            .sum();
        (d / obs.as_flat().len() as f64).sqrt()
    };
    let id = identified_scene(&guess, &e, 0);
    // The true model replayed from the same (estimated) observed start: the yardstick.
    let mut true_from_est = truth.clone();
    for (i, p) in true_from_est.particles.iter_mut().enumerate() {
        p.pos = id.particles[i].pos;
        p.vel = id.particles[i].vel;
    }
    println!("replay rms: identified {:.3e} m, true model (its own state) {:.3e}, true model from estimated state {:.3e}", rms(&id), rms(&truth), rms(&true_from_est));
}
