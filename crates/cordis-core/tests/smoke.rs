use cordis_core::{LinkKind, LinkType, Particle, Scene};

#[test]
fn spring_oscillator_runs_and_round_trips_json() {
    let mut scene = Scene::new(0.01);
    scene.add_particle(Particle::new(1.0, [0.0, 0.0, 0.0]).fixed());
    scene.add_particle(Particle::new(2.0, [1.5, 0.0, 0.0]));
    scene.add_type(
        LinkType::new("rib", LinkKind::Spring)
            .with("stiffness", 20.0)
            .with("rest_length", 1.0),
    );
    scene.add_link("rib", &[0, 1]);
    let traj = scene.simulate(50).unwrap();
    // Hand-computed first step: F = -20 * 0.5 = -10 N on particle 1, x1 = 1.5 + 1e-4 * (-10/2).
    assert_eq!(
        traj.pos(1, 1).x,
        2.0 * 1.5 - 1.5 + 0.01 * 0.01 * (-10.0 / 2.0)
    );
    assert_eq!(traj.pos(49, 0).x, 0.0);
    let back = Scene::from_json_str(&scene.to_json_string()).unwrap();
    assert_eq!(back, scene);
}
