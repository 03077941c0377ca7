//! `horse-gait`: the horse of [`super::horse`] driven by four local-control muscles (SPEC §2.4),
//! the data of thesis §6.2's claim that living motion needs energy injected under control.
//!
//! Each leg's swing spring (elbow or stifle to the trunk, the link that gives the swing its
//! restoring force) becomes a muscle with the same stiffness, rest length and damping, whose
//! neuron observes the other leg of its pair (front left ↔ front right, hind left ↔ hind
//! right). A negative rate weight makes each muscle push when its partner lengthens, a negative
//! damping `G |w_rate|` on the pair's common swing: the small swings the passive horse damps
//! out grow instead until `tanh` saturates, a limit cycle of the legs (elongation swings of
//! 0.08–0.2 m per second over 10 s, where the passive horse's decay to 0.01–0.02 m). Every
//! other link, the masses and the initial state are the passive horse's, so a passive model of
//! the same topology ([`super::passive`] of this scene, or `horse` itself) is the thesis'
//! passive model.

use super::horse::{horse, LEG_NAMES};
use crate::{LinkKind, LinkType, Param, Scene};

/// Gain G of every leg neuron, N: the largest force a neuron adds, about what a front leg's
/// swing spring (4800 N/m) pulls with at 1 cm of stretch.
pub const GAIT_GAIN: f64 = 60.0;

/// Rate weight of every neuron on its partner's elongation rate, s/m: negative, so the pair's
/// common swing is undamped by `G |w| = 300 N·s/m` at small amplitude, far above the springs'
/// 3–4 N·s/m: the swing is 2–3× the passive horse's within the first 53 frames.
pub const GAIT_RATE_WEIGHT: f64 = -5.0;

/// The trunk marker each leg's swing spring joins (front legs: girth; hind legs: belly).
fn swing_anchor(leg: usize) -> &'static str {
    if leg < 2 {
        "girth"
    } else {
        "belly"
    }
}

/// The muscle-driven horse: [`horse`] with each leg's swing spring replaced by a muscle (gain
/// [`GAIT_GAIN`], threshold 0, elongation weight 0, rate weight [`GAIT_RATE_WEIGHT`] on the
/// paired leg's muscle). Meant for the horse's 53 frames; it stays bounded over 10× as many.
pub fn horse_gait() -> Scene {
    let mut scene = horse();
    let link_of = |scene: &Scene, name: &str| {
        let t = scene.type_index(name).expect("a swing spring of the horse");
        scene
            .links
            .iter()
            .position(|l| l.type_index == t)
            .expect("one instance per horse type")
    };
    let names: Vec<String> = (0..4)
        .map(|l| format!("{}_1-{}", LEG_NAMES[l], swing_anchor(l)))
        .collect();
    let links: Vec<usize> = names.iter().map(|n| link_of(&scene, n)).collect();
    for (leg, name) in names.iter().enumerate() {
        // Legs pair up left–right: 0 ↔ 1 (front), 2 ↔ 3 (hind).
        let partner = leg ^ 1;
        let t = scene.type_index(name).expect("checked above");
        let spring = &scene.types[t];
        let muscle = LinkType::new(name.clone(), LinkKind::Muscle)
            .with("stiffness", *spring.param("stiffness").expect("a spring"))
            .with(
                "rest_length",
                *spring.param("rest_length").expect("a spring"),
            )
            .with("damping", *spring.param("damping").expect("a spring"))
            .with("gain", GAIT_GAIN)
            .with_weights(&[Param::Known(0.0)], &[Param::Known(GAIT_RATE_WEIGHT)]);
        scene.types[t] = muscle;
        scene.links[links[leg]].observes = Some(vec![links[partner]]);
    }
    scene
}
