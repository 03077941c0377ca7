//! Scenes shared by the strategies' unit tests.

use cordis_core::{LinkKind, LinkType, Particle, Scene};

/// Eight particles of group `gas` at `pts` (masses 0.5–1.2 kg, assorted velocities) held by
/// anchors towards the origin, one conditional type `pair` between them (K 40, l0 0.3, range
/// 0.45) and, with `visc`, a damped one reaching further (`visc`: Z 0.8, range 0.6): pairs come
/// in and out of the ranges all the time.
pub(crate) fn anchored_gas(pts: &[[f64; 3]], visc: bool) -> Scene {
    let mut s = Scene::new(0.005);
    for (n, p) in pts.iter().enumerate() {
        let a = n as f64;
        s.add_particle(
            Particle::new(0.5 + 0.1 * a, *p)
                .with_vel([(1.3 * a).sin(), (0.7 * a).cos(), (2.1 * a).sin() * 0.5])
                .in_group("gas"),
        );
    }
    let mut pair = LinkType::new("pair", LinkKind::Conditional)
        .with("stiffness", 40.0)
        .with("rest_length", 0.3)
        .with("range", 0.45);
    pair.groups = vec!["gas".into()];
    s.add_type(pair);
    if visc {
        let mut visc = LinkType::new("visc", LinkKind::Conditional)
            .with("stiffness", 0.0)
            .with("rest_length", 0.0)
            .with("damping", 0.8)
            .with("range", 0.6);
        visc.groups = vec!["gas".into()];
        s.add_type(visc);
    }
    let mut hold = LinkType::new("hold", LinkKind::Anchor).with("stiffness", 6.0);
    hold.point = Some([0.0, 0.0, 0.0]);
    s.add_type(hold);
    for i in 0..pts.len() {
        s.add_link("hold", &[i]);
    }
    s
}
