//! The horse of §4.4 and Annexe 2: 35 markers (15 on the head, body and tail, 5 on each leg),
//! 53 binary links (one type each, as the thesis' chromosome gave each link its own genes) and
//! 3 angle links, at the 50 Hz of the recorded gallop. The thesis split its binary links into
//! 39 springs and 14 dampers; here 51 are springs (each with its own damping) and 2 are
//! dampers, because a passive network with only 39 position links leaves the legs free to
//! spin about their tops (see `binary_links`).

use super::{dist, q, q3, SplitMix64};
use crate::{LinkKind, LinkType, Particle, Scene};

/// The horse is meant to be simulated for 53 frames (1.06 s at 50 Hz), the length of the
/// thesis' recorded sequence.
pub const HORSE_FRAMES: usize = 53;

/// Head, neck, trunk and tail markers (x forward, y up), m, with their masses, kg. The horse is
/// a silhouette in the plane z = 0, as the thesis' markers were recorded from the side: in the
/// plane, a leg's top held by two springs is as firm as a triangle.
const BODY: [(&str, [f64; 3], f64); 15] = [
    ("muzzle", [2.65, 1.30, 0.0], 8.0),
    ("jaw", [2.40, 1.25, 0.0], 10.0),
    ("poll", [2.35, 1.72, 0.0], 10.0),
    ("throat", [2.12, 1.28, 0.0], 14.0),
    ("crest", [1.98, 1.70, 0.0], 16.0),
    ("withers", [1.55, 1.62, 0.0], 30.0),
    ("chest", [1.95, 1.08, 0.0], 30.0),
    ("midback", [1.05, 1.52, 0.0], 40.0),
    ("girth", [1.45, 0.92, 0.0], 40.0),
    ("belly", [0.95, 0.90, 0.0], 40.0),
    ("croup", [0.40, 1.60, 0.0], 35.0),
    ("buttock", [0.05, 1.30, 0.0], 30.0),
    ("tail_root", [0.00, 1.50, 0.0], 3.0),
    ("tail_mid", [-0.20, 1.15, 0.0], 2.0),
    ("tail_tip", [-0.28, 0.80, 0.0], 1.5),
];

/// Leg markers from the top (shoulder or hip joint) down to the hoof, offsets in m from the
/// leg's top, masses in kg.
const FRONT_LEG: [([f64; 3], f64); 5] = [
    ([0.0, 0.0, 0.0], 12.0),
    ([-0.10, -0.30, 0.0], 8.0),
    ([-0.05, -0.72, 0.0], 5.0),
    ([-0.02, -1.05, 0.0], 3.0),
    ([0.04, -1.22, 0.0], 2.0),
];
const HIND_LEG: [([f64; 3], f64); 5] = [
    ([0.0, 0.0, 0.0], 14.0),
    ([0.18, -0.38, 0.0], 9.0),
    ([-0.12, -0.78, 0.0], 5.0),
    ([-0.06, -1.16, 0.0], 3.0),
    ([0.00, -1.33, 0.0], 2.0),
];
/// Top of each leg, m: front left, front right, hind left, hind right (the far legs drawn a
/// little behind and below, as a side view shows them).
const LEG_TOPS: [[f64; 3]; 4] = [
    [1.80, 1.22, 0.0],
    [1.70, 1.17, 0.0],
    [0.35, 1.35, 0.0],
    [0.25, 1.30, 0.0],
];
pub(super) const LEG_NAMES: [&str; 4] = ["front_left", "front_right", "hind_left", "hind_right"];
/// Phase of each leg's swing in the transverse gallop, in cycles (hind left leads).
const LEG_PHASE: [f64; 4] = [0.55, 0.75, 0.0, 0.2];
/// Forward speed of the whole horse (m/s), peak swing of a leg (rad/s), head nod (m/s).
const SPEED: f64 = 6.0;
const SWING: f64 = 1.0;
const NOD: f64 = 0.4;

/// Binary links by marker name: (from, to, is_spring). Legs are named `<leg>_<k>`,
/// k = 0 (top) … 4 (hoof).
///
/// 53 links and 3 angles cannot hold 35 markers stiff (the plane leaves 67 internal degrees
/// of freedom), so the links go where a floppy mode would spoil the gallop: the head and neck
/// are triangulated, each leg's upper part (top, elbow, knee) is a triangle held to the trunk
/// at two points (so the leg swings back and forth about its top instead of spinning), and
/// the loose ends are the lower legs, the trunk's shear and the tail.
fn binary_links() -> Vec<(String, String, bool)> {
    let mut out: Vec<(String, String, bool)> = Vec::new();
    let mut link = |a: &str, b: &str, spring: bool| out.push((a.into(), b.into(), spring));
    // Head and neck (7), neck to trunk (2), trunk (9), tail root (1): 19 springs.
    for (a, b) in [
        ("muzzle", "jaw"),
        ("muzzle", "poll"),
        ("jaw", "poll"),
        ("poll", "crest"),
        ("jaw", "throat"),
        ("crest", "throat"),
        ("poll", "throat"),
        ("crest", "withers"),
        ("throat", "chest"),
        ("withers", "chest"),
        ("withers", "midback"),
        ("midback", "croup"),
        ("croup", "buttock"),
        ("belly", "buttock"),
        ("girth", "belly"),
        ("chest", "girth"),
        ("withers", "girth"),
        ("croup", "belly"),
        ("croup", "tail_root"),
    ] {
        link(a, b, true);
    }
    // Each leg (8 springs): the chain top → hoof, a brace top–knee, the top to two trunk
    // markers, and the elbow (stifle) to a third, which gives the swing its restoring force.
    for (l, leg) in LEG_NAMES.iter().enumerate() {
        for k in 0..4 {
            link(&format!("{leg}_{k}"), &format!("{leg}_{}", k + 1), true);
        }
        link(&format!("{leg}_0"), &format!("{leg}_2"), true);
        let [a, b, c] = if l < 2 {
            ["withers", "chest", "girth"]
        } else {
            ["croup", "buttock", "belly"]
        };
        link(&format!("{leg}_0"), a, true);
        link(&format!("{leg}_0"), b, true);
        link(&format!("{leg}_1"), c, true);
    }
    // Dampers (2): the tail swishes behind its root.
    link("tail_root", "tail_mid", false);
    link("tail_mid", "tail_tip", false);
    out
}

/// Angle links (i, vertex j, k): the neck's bend, the back's line and the tail's carriage.
const ANGLES: [[&str; 3]; 3] = [
    ["poll", "crest", "withers"],
    ["withers", "midback", "croup"],
    ["croup", "tail_root", "tail_mid"],
];

/// A passive horse in mid-gallop, in the plane z = 0 (dt = 0.02 s; no gravity: with no ground
/// it would only add a uniform fall). The whole horse moves forward at 6 m/s; each upper leg
/// starts swinging about its top with a phase-shifted angular velocity (transverse gallop,
/// hind left leading) and the head nods. Every spring has its own type, with a rest length
/// 1–2 % off its initial length so the trunk and neck vibrate while the legs swing; the two
/// dampers let the tail trail. Meant for [`HORSE_FRAMES`] frames: it stays stable over them
/// (unlike the thesis' identified model, which exploded), though by the end the lower legs,
/// hinged at the knee with nothing to straighten them, start to fold.
pub fn horse() -> Scene {
    let mut rng = SplitMix64::new(0x0048_4F52_5345); // "HORSE"
    let mut scene = Scene::new(0.02);
    let mut names: Vec<String> = Vec::with_capacity(35);
    for (name, pos, mass) in BODY {
        // The head nods down as the gallop's forehand lands.
        let nod = match name {
            "muzzle" | "jaw" | "poll" => -NOD,
            "throat" | "crest" => -0.5 * NOD,
            _ => 0.0,
        };
        scene.add_particle(Particle::new(mass, pos).with_vel([SPEED, nod, 0.0]));
        names.push(name.to_string());
    }
    for (l, top) in LEG_TOPS.iter().enumerate() {
        let shape = if l < 2 { &FRONT_LEG } else { &HIND_LEG };
        let omega = SWING * (2.0 * std::f64::consts::PI * LEG_PHASE[l]).cos();
        for (k, (off, mass)) in shape.iter().enumerate() {
            let pos = [top[0] + off[0], top[1] + off[1], top[2] + off[2]];
            // The upper leg (top, elbow, knee) swings about the lateral axis through the top,
            // v = ω ẑ × r; the lower leg, hinged at the knee with nothing to bring it back,
            // starts moving with the knee so it is only dragged along, not spun.
            let r = shape[k.min(2)].0;
            let vel = [SPEED - omega * r[1], omega * r[0], 0.0];
            scene.add_particle(Particle::new(*mass, q3(pos)).with_vel(q3(vel)));
            names.push(format!("{}_{k}", LEG_NAMES[l]));
        }
    }
    let index = |n: &str| {
        names
            .iter()
            .position(|m| m == n)
            .expect("a marker of the horse")
    };

    let mut springs = 0;
    let mut dampers = 0;
    for (a, b, spring) in binary_links() {
        let (i, j) = (index(&a), index(&b));
        let name = format!("{a}-{b}");
        let t = if spring {
            springs += 1;
            let l = dist(scene.particles[i].pos, scene.particles[j].pos);
            // Stiffer on the heavy trunk, softer toward the hooves and the head.
            let m = scene.particles[i]
                .mass
                .value()
                .min(scene.particles[j].mass.value());
            let stretch =
                rng.uniform(0.01, 0.02) * if rng.next_u64() % 2 == 0 { 1.0 } else { -1.0 };
            LinkType::new(&name, LinkKind::Spring)
                .with("stiffness", q(600.0 * m))
                .with("rest_length", q(l * (1.0 + stretch)))
                .with("damping", q(0.4 * m))
        } else {
            dampers += 1;
            LinkType::new(&name, LinkKind::Damper).with("damping", q(rng.uniform(4.0, 12.0)))
        };
        scene.add_type(t);
        scene.add_link(&name, &[i, j]);
    }
    debug_assert_eq!((springs, dampers), (51, 2));
    for [a, b, c] in ANGLES {
        let (i, j, k) = (index(a), index(b), index(c));
        let p = |n: usize| scene.particles[n].pos;
        let (pa, pb, pc) = (p(i), p(j), p(k));
        let u = [pa[0] - pb[0], pa[1] - pb[1], pa[2] - pb[2]];
        let v = [pc[0] - pb[0], pc[1] - pb[1], pc[2] - pb[2]];
        let cos = (u[0] * v[0] + u[1] * v[1] + u[2] * v[2]) / (dist(pa, pb) * dist(pc, pb));
        let name = format!("{a}-{b}-{c}");
        scene.add_type(
            LinkType::new(&name, LinkKind::Angle)
                .with("stiffness", 200.0)
                .with("rest_cos", q(cos)),
        );
        scene.add_link(&name, &[i, j, k]);
    }
    scene
}
