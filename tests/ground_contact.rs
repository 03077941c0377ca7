//! Ground contact (`plane`, SPEC §7.2): the buffer's restitution against its analytic value,
//! the bouncing ball's energy, its contact parameters identified from its motion, and the
//! plane's bad input.

use cordis_core::examples::{self, BALL_DAMPING, BALL_FRICTION, BALL_MASS, BALL_STIFFNESS};
use cordis_core::{Bounds, LinkKind, LinkType, Param, Particle, Scene, Trajectory};
use cordis_es::cost::CostKind;
use cordis_es::executor::{self, RunConfig, StopReason, StopRules};
use cordis_es::problem::Problem;
use cordis_es::strategies::levenberg_marquardt::{LevenbergMarquardt, LmConfig};

/// Restitution of the clamped buffer `max(0, K d - Z v_n)` in continuous time (module doc of
/// `cordis_core::forces::plane`).
fn clamped_restitution(zeta: f64) -> f64 {
    let s = (1.0 - zeta * zeta).sqrt();
    let end = std::f64::consts::PI - (2.0 * zeta * s / (1.0 - 2.0 * zeta * zeta)).atan();
    (-(zeta / s) * end).exp()
}

/// Restitution of the unclamped spring-damper (it pulls at the end of the contact).
fn unclamped_restitution(zeta: f64) -> f64 {
    (-zeta * std::f64::consts::PI / (1.0 - zeta * zeta).sqrt()).exp()
}

/// One mass m = 1 kg, no gravity, arriving at 1 m/s on a plane z = 0 of stiffness 1e4 N/m
/// (ω₀ = 100 rad/s) and damping ratio ζ, with a step of `omega_dt / ω₀`, sliding at 0.5 m/s
/// along x (friction 0). Returns (exit normal speed / entry speed, final x speed).
fn one_impact(zeta: f64, omega_dt: f64) -> (f64, f64) {
    let (m, k, v0): (f64, f64, f64) = (1.0, 1e4, 1.0);
    let omega0 = (k / m).sqrt();
    let dt = omega_dt / omega0;
    let z = zeta * 2.0 * (k * m).sqrt();
    let mut s = Scene::new(dt);
    // Starts 0.05 m above: 0.05 s of approach, 0.03 s of contact, then free flight.
    s.add_particle(Particle::new(m, [0.0, 0.0, 0.05]).with_vel([0.5, 0.0, -v0]));
    s.add_type(
        LinkType::new("ground", LinkKind::Plane)
            .with("stiffness", k)
            .with("damping", z)
            .with_surface([0.0, 0.0, 0.0], [0.0, 0.0, 2.0]),
    );
    s.add_link("ground", &[0]);
    let frames = (0.12 / dt) as usize;
    let traj = s.simulate(frames).expect("simulates");
    let (a, b) = (traj.pos(frames - 2, 0), traj.pos(frames - 1, 0));
    assert!(b[2] > 0.0, "the particle left the plane");
    ((b[2] - a[2]) / dt / v0, (b[0] - a[0]) / dt)
}

#[test]
fn restitution_is_the_clamped_buffers_analytic_value() {
    for zeta in [0.02, 0.1, 0.3, 0.6] {
        let e = clamped_restitution(zeta);
        let (coarse, _) = one_impact(zeta, 1e-2);
        let (fine, vx) = one_impact(zeta, 1e-3);
        let (err_coarse, err_fine) = ((coarse - e).abs() / e, (fine - e).abs() / e);
        let unclamped = unclamped_restitution(zeta);
        eprintln!(
            "zeta {zeta}: analytic {e:.6} (unclamped {unclamped:.6}), ω dt 1e-2: {coarse:.6} \
             ({err_coarse:.2e}), 1e-3: {fine:.6} ({err_fine:.2e})"
        );
        // The scheme is first order in ω dt (measured: the relative error is 1.5 ζ ω dt to
        // 2 digits, 9.2e-4 at ζ = 0.6, ω dt = 1e-3), so the tolerance is 2.5 ζ ω dt, and ten
        // times less dt must give about ten times less error.
        assert!(err_fine < 2.5 * zeta * 1e-3, "zeta {zeta}: {err_fine}");
        let order = err_coarse / err_fine;
        assert!(
            (8.0..12.0).contains(&order),
            "zeta {zeta}: error ratio {order}"
        );
        // The unclamped spring-damper's value is another law (it pulls at the end).
        if zeta >= 0.1 {
            assert!(
                (fine - unclamped).abs() / unclamped > 10.0 * err_fine,
                "zeta {zeta}"
            );
        }
        // Friction 0: the sliding speed is untouched.
        assert!((vx - 0.5).abs() < 1e-9, "zeta {zeta}: sliding speed {vx}");
    }
}

/// Apex heights (m) of the flights of a trajectory of one particle bouncing on z = 0: the
/// largest z between two contacts (frames with z < 0), the first flight (the drop) included.
fn apexes(traj: &Trajectory) -> Vec<f64> {
    let mut out = Vec::new();
    let mut top = f64::NEG_INFINITY;
    let mut was_below = false;
    for t in 0..traj.frames() {
        let z = traj.pos(t, 0)[2];
        if z < 0.0 {
            if !was_below && top > 0.0 {
                out.push(top);
            }
            top = f64::NEG_INFINITY;
            was_below = true;
        } else {
            top = top.max(z);
            was_below = false;
        }
    }
    out
}

#[test]
fn bouncing_ball_loses_the_buffers_share_of_energy_at_each_bounce() {
    // The example at a 100 times smaller step (ω₀ dt = 2e-3): the flights' apexes fall by
    // e² per bounce. Gravity acts during the contact too, which the analytic e leaves out:
    // its impulse over a contact (m g π/ω) against the impact momentum (m v) is the size of
    // the difference, g / (ω v) ≤ 3.6 % at the fifth bounce's 1.36 m/s.
    let mut scene = examples::bouncing_ball();
    scene.dt = 1e-5;
    let traj = scene.simulate(270_000).expect("the ball simulates");
    let e = clamped_restitution(BALL_DAMPING / (2.0 * (BALL_STIFFNESS * BALL_MASS).sqrt()));
    let h = apexes(&traj);
    assert!(h.len() >= 5, "{h:?}");
    assert!(
        (h[0] - 1.0).abs() < 1e-9,
        "the drop starts at its apex: {}",
        h[0]
    );
    let omega = (BALL_STIFFNESS / BALL_MASS).sqrt();
    let mut shares = Vec::new();
    for k in 0..4 {
        let measured = (h[k + 1] / h[k]).sqrt();
        let speed = (2.0 * 9.81 * h[k]).sqrt();
        let gravity_share = 9.81 / (omega * speed);
        eprintln!(
            "bounce {k}: apex {:.6} -> {:.6} m, e {measured:.5} (analytic {e:.5}, \
             g/(ω v) {gravity_share:.4})",
            h[k],
            h[k + 1]
        );
        assert!(
            (measured - e).abs() < gravity_share,
            "bounce {k}: e {measured} against {e}"
        );
        shares.push((e - measured) / gravity_share);
    }
    // And the difference is gravity's: it grows as g / (ω v) does, bounce after bounce (a
    // discretisation error would not depend on the impact speed).
    let mean = shares.iter().sum::<f64>() / shares.len() as f64;
    assert!(mean > 0.0, "{shares:?}");
    for s in &shares {
        assert!((s / mean - 1.0).abs() < 0.15, "{shares:?}");
    }
}

/// The ball at its own step (1 ms, 16 steps per contact) with stiffness, damping and friction
/// unknown in boxes 16 times wide, off-centre.
fn ball_problem() -> (Scene, Problem) {
    let truth = examples::bouncing_ball();
    let traj = truth.simulate(examples::BALL_FRAMES).expect("simulates");
    let mut unknown = truth.clone();
    for (name, v) in [
        ("stiffness", BALL_STIFFNESS),
        ("damping", BALL_DAMPING),
        ("friction", BALL_FRICTION),
    ] {
        let k = LinkKind::Plane
            .param_index(name)
            .expect("a plane parameter");
        unknown.types[0].params[k] = Param::Unknown(Bounds {
            min: v / 3.0,
            max: v * 5.0,
            init: None,
        });
    }
    let problem = Problem::new(&unknown, &traj, CostKind::Short)
        .expect("problem")
        .with_truth(&truth)
        .expect("truth");
    (truth, problem)
}

#[test]
fn contact_parameters_identified_to_a_thousandth_from_noiseless_motion() {
    let (truth, mut problem) = ball_problem();
    assert_eq!(problem.dim(), 3);
    let config = RunConfig {
        seed: 0,
        stop: StopRules {
            generations: Some(500),
            ..StopRules::default()
        },
        ..RunConfig::default()
    };
    let mut lm = LevenbergMarquardt::new(LmConfig::default());
    let r = executor::run(&mut problem, &mut lm, &config, &mut [], None).expect("runs");
    let want = truth.param_values();
    eprintln!(
        "ball: {:?} after {} evaluations, cost {:.3e}",
        r.stopped_by, r.evals, r.cost
    );
    assert_eq!(r.stopped_by, StopReason::Converged);
    for (k, name) in ["stiffness", "damping", "friction"].iter().enumerate() {
        let err = (r.params[k] - want[k]).abs() / want[k];
        eprintln!(
            "  {name}: {} (truth {}, error {:.2e})",
            r.params[k], want[k], err
        );
        assert!(err < 1e-3, "{name}: {} against {}", r.params[k], want[k]);
    }
}

/// The error of reading `json` as a scene file, as one line. (A semantic error's place is its
/// JSON path, as for every kind; the file's name is added only to syntax errors, `file:line:col`.)
fn scene_error(json: &str) -> String {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let path = dir.path().join("ball.json");
    std::fs::write(&path, json).expect("written");
    let e = Scene::from_json_path(&path)
        .expect_err("refused")
        .to_string();
    assert!(!e.contains('\n'), "one line: {e}");
    e
}

fn plane_scene(ground: &str, link: &str) -> String {
    format!(
        r#"{{"format": "cordis-scene/1", "dt": 0.001, "gravity": [0, 0, -9.81],
            "particles": [{{"mass": 0.5, "pos": [0, 0, 1]}}, {{"mass": 0.5, "pos": [1, 0, 1]}}],
            "types": {{"ground": {{"kind": "plane", {ground}}}}},
            "links": [{link}]}}"#
    )
}

#[test]
fn bad_planes_are_refused_with_their_place() {
    let ok = r#""point": [0, 0, 0], "normal": [0, 0, 1], "stiffness": 2e4, "damping": 20, "friction": 0.2"#;
    let one = r#"{"type": "ground", "particles": [1]}"#;
    Scene::from_json_str(&plane_scene(ok, one)).expect("a valid plane");
    let cases = [
        (
            ok.replace("[0, 0, 1]", "[0, 0, 0]"),
            one.to_string(),
            "types.ground.normal: must not be the zero vector",
        ),
        (
            ok.replace("0.2", "-0.1"),
            one.to_string(),
            "types.ground.friction: must be a non-negative number, got -0.1",
        ),
        (
            ok.replace("2e4", "-5"),
            one.to_string(),
            "types.ground.stiffness: must be a non-negative number, got -5",
        ),
        (
            ok.replace(r#""normal": [0, 0, 1], "#, ""),
            one.to_string(),
            "types.ground: a `plane` type needs `normal`",
        ),
        (
            ok.replace("[0, 0, 1]", "[0, 1]"),
            one.to_string(),
            "types.ground.normal: expected 3 numbers",
        ),
        (
            ok.to_string(),
            r#"{"type": "ground", "particles": [0, 1]}"#.to_string(),
            "links[0].particles",
        ),
        (
            ok.to_string(),
            r#"{"type": "ground", "particles": [0], "point": [0, 0, 0]}"#.to_string(),
            "links[0].point: only anchor links have it",
        ),
    ];
    for (ground, link, want) in cases {
        let e = scene_error(&plane_scene(&ground, &link));
        eprintln!("{e}");
        assert!(e.contains(want), "{e}\n  wanted: {want}");
    }
}

#[test]
fn a_sliding_ball_stops_as_coulomb_says_and_never_slides_back() {
    // Resting at its equilibrium depth m g / K (the normal force is m g from the first step),
    // sliding at 2 m/s with μ = 0.4: Coulomb's deceleration μ g, stop after v0 / (μ g).
    let (m, k, g, mu, v0, dt) = (0.5, 2e4, 9.81, 0.4, 2.0, 1e-4);
    let mut s = Scene::new(dt);
    s.gravity = [0.0, 0.0, -g];
    s.add_particle(Particle::new(m, [0.0, 0.0, -m * g / k]).with_vel([v0, 0.0, 0.0]));
    s.add_type(
        LinkType::new("ground", LinkKind::Plane)
            .with("stiffness", k)
            .with("friction", mu)
            .with_surface([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
    );
    s.add_link("ground", &[0]);
    let frames = (1.0 / dt) as usize;
    let traj = s.simulate(frames).expect("simulates");
    let vx = |t: usize| (traj.pos(t, 0)[0] - traj.pos(t - 1, 0)[0]) / dt;
    let stop = (1..frames).find(|&t| vx(t) < 1e-6).expect("stops");
    let want = v0 / (mu * g);
    let got = stop as f64 * dt;
    eprintln!("stopped at {got:.4} s (Coulomb {want:.4} s)");
    // Within a few steps: the regularisation acts only below μ F_n dt / m = 4e-4 m/s.
    assert!((got - want).abs() < 5.0 * dt, "{got} against {want}");
    for t in 1..frames {
        assert!(vx(t) >= 0.0, "frame {t}: slides back at {}", vx(t));
    }
}

#[test]
fn a_plane_survives_the_json_round_trip() {
    let ball = examples::bouncing_ball();
    let text = ball.to_json_string();
    assert!(text.contains("\"normal\""), "{text}");
    assert_eq!(Scene::from_json_str(&text).expect("reads back"), ball);
}

#[test]
fn solvers_without_a_plane_refuse_it_by_name_and_auto_takes_levenberg_marquardt() {
    use cordis_es::identify::{check_strategy, make_strategy, StrategyName, StrategyOptions};
    let (_, problem) = ball_problem();
    for ran in ["least-squares", "hybrid"] {
        let e = check_strategy(ran, &problem).expect_err("refused");
        eprintln!("{ran}: {e}");
        assert!(e.contains("types.ground") && e.contains("plane"), "{e}");
    }
    // The output-error estimator differentiates the contact (output_error::tangent::plane);
    // on noiseless data `auto` does not need it.
    check_strategy("output-error", &problem).expect("a plane has exact sensitivities");
    let (_, ran) = make_strategy(StrategyName::Auto, &problem, &StrategyOptions::default());
    assert_eq!(ran, "levenberg-marquardt");
}

#[test]
fn the_horse_lands_on_the_ground_and_stays_on_it() {
    let scene = examples::horse_ground();
    let report = cordis_core::stability(&scene).expect("valid");
    assert!(report.stable, "stability ratio {}", report.max_ratio);
    let frames = examples::HORSE_GROUND_FRAMES;
    let traj = scene.simulate(frames).expect("the horse simulates");
    let ground = examples::GROUND_HEIGHT;
    let k = examples::GROUND_STIFFNESS;
    // Each marker's deepest sinking against what a lone mass m landing at the speed v it had
    // on entering the ground would reach on a spring K: v √(m/K) (damping and the short
    // contact with gravity make it less; the links to the rest of the body may push more).
    let (mut touching, mut worst) = (0, (0.0_f64, 0.0_f64, 0usize));
    for i in 0..scene.num_particles() {
        let m = scene.particles[i].mass.value();
        let (mut deepest, mut entry_speed, mut bound) = (0.0_f64, 0.0_f64, 0.0_f64);
        for t in 1..frames {
            let (y0, y1) = (traj.pos(t - 1, i)[1], traj.pos(t, i)[1]);
            if y0 >= ground && y1 < ground {
                entry_speed = (y0 - y1) / scene.dt;
            }
            let depth = ground - y1;
            if depth > deepest {
                deepest = depth;
                bound = entry_speed * (m / k).sqrt();
            }
        }
        if ground - traj.pos(frames - 1, i)[1] > 0.0 {
            touching += 1;
        }
        if deepest > worst.0 {
            worst = (deepest, bound, i);
        }
        assert!(
            deepest <= bound.max(1e-3),
            "marker {i}: sank {deepest} m, v √(m/K) = {bound} m"
        );
    }
    let (deepest, bound, marker) = worst;
    eprintln!("deepest: marker {marker}, {deepest:.4} m (v √(m/K) = {bound:.4} m)");
    let start_height: f64 = traj.pos(0, 7)[1] - ground; // midback
    let end_height: f64 = traj.pos(frames - 1, 7)[1] - ground;
    eprintln!(
        "horse: {touching} markers touching at the end, midback from {start_height:.3} to \
         {end_height:.3} m above the ground"
    );
    assert!(touching >= 3, "{touching} markers on the ground");
    assert!(
        end_height < start_height,
        "fell: {start_height} -> {end_height}"
    );
}
