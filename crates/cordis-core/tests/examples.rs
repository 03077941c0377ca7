//! The shipped examples (SPEC §6): counts from the thesis, stability, no explosion, every
//! type excited, exact JSON round trip.

use cordis_core::examples::{self, by_name, cloth, default_frames, NAMES};
use cordis_core::{LinkKind, Plan, Scene, Trajectory, Vec3};

/// Per particle, `(dt² ΣK_i + 2 dt ΣZ_i) / (4 m_i)` over the links acting on it (0 for fixed
/// particles): the explicit scheme is stable when this stays below 1. Conditional pairs count
/// when they are in range at frame 0. An angle link's stiffness K (N·m, on a cosine) acts on
/// an outer particle like a spring of K/|a|² (its arm a), on the vertex like K(1/|a| + 1/|b|)².
pub fn stability_ratio(scene: &Scene) -> Vec<f64> {
    let n = scene.particles.len();
    let (mut k_sum, mut z_sum) = (vec![0.0; n], vec![0.0; n]);
    let pos: Vec<Vec3> = scene.particles.iter().map(|p| Vec3::from(p.pos)).collect();
    for l in &scene.links {
        let t = &scene.types[l.type_index];
        let k = t.value("stiffness").unwrap_or(0.0);
        let z = t.value("damping").unwrap_or(0.0);
        if t.kind == LinkKind::Angle {
            let [i, j, m] = [l.particles[0], l.particles[1], l.particles[2]];
            let (a, b) = ((pos[i] - pos[j]).norm(), (pos[m] - pos[j]).norm());
            k_sum[i] += k / (a * a);
            k_sum[m] += k / (b * b);
            k_sum[j] += k * (1.0 / a + 1.0 / b).powi(2);
            continue;
        }
        for &i in &l.particles {
            k_sum[i] += k;
            z_sum[i] += z;
        }
    }
    for (t, i, j) in conditional_pairs(scene, &pos) {
        let ty = &scene.types[t];
        for e in [i, j] {
            k_sum[e] += ty.value("stiffness").unwrap();
            z_sum[e] += ty.value("damping").unwrap();
        }
    }
    let dt = scene.dt;
    scene
        .particles
        .iter()
        .enumerate()
        .map(|(i, p)| {
            if p.fixed {
                0.0
            } else {
                (dt * dt * k_sum[i] + 2.0 * dt * z_sum[i]) / (4.0 * p.mass.value())
            }
        })
        .collect()
}

/// Every (type, i, j), i < j, of a conditional type closer than its range, by brute force over
/// all pairs (independent of the library's grid). Pairs are swept in order of x so that only
/// pairs closer than the largest range in x are measured.
fn conditional_pairs(scene: &Scene, x: &[Vec3]) -> Vec<(usize, usize, usize)> {
    let group = |i: usize| scene.particles[i].group.as_deref();
    let conds: Vec<(usize, &str, &str, f64)> = scene
        .types
        .iter()
        .enumerate()
        .filter(|(_, t)| t.kind == LinkKind::Conditional)
        .map(|(k, t)| {
            let r = t.value("range").unwrap();
            (
                k,
                t.groups[0].as_str(),
                t.groups.last().unwrap().as_str(),
                r,
            )
        })
        .collect();
    let reach = conds.iter().map(|c| c.3).fold(0.0, f64::max);
    let mut order: Vec<usize> = (0..x.len()).collect();
    order.sort_by(|&a, &b| x[a].x.total_cmp(&x[b].x));
    let mut out = Vec::new();
    for (k, &a) in order.iter().enumerate() {
        for &b in &order[k + 1..] {
            if x[b].x - x[a].x >= reach {
                break;
            }
            let d = (x[b] - x[a]).norm();
            let (i, j) = (a.min(b), a.max(b));
            for &(t, g0, g1, r) in &conds {
                let (gi, gj) = (group(i), group(j));
                let pair = (gi == Some(g0) && gj == Some(g1)) || (gi == Some(g1) && gj == Some(g0));
                if pair && d < r {
                    out.push((t, i, j));
                }
            }
        }
    }
    out.sort_unstable();
    out
}

fn simulate(name: &str) -> (Scene, Trajectory) {
    let scene = by_name(name).unwrap();
    let traj = scene.simulate(default_frames(name)).unwrap();
    (scene, traj)
}

/// Per link: relative variation of its length over the trajectory, `(max L - min L) / mean L`
/// (angle links: the range of their cosine).
fn link_variation(scene: &Scene, traj: &Trajectory) -> Vec<f64> {
    scene
        .links
        .iter()
        .map(|l| {
            let mut vals = Vec::with_capacity(traj.frames());
            for t in 0..traj.frames() {
                let p: Vec<Vec3> = l.particles.iter().map(|&i| traj.pos(t, i)).collect();
                vals.push(match p.len() {
                    2 => (p[1] - p[0]).norm(),
                    _ => {
                        let (a, b) = (p[0] - p[1], p[2] - p[1]);
                        a.dot(&b) / (a.norm() * b.norm())
                    }
                });
            }
            let (lo, hi) = vals
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
                    (lo.min(v), hi.max(v))
                });
            let scale = if l.particles.len() == 2 {
                vals.iter().sum::<f64>() / vals.len() as f64
            } else {
                1.0
            };
            (hi - lo) / scale
        })
        .collect()
}

/// Largest ratio of (distance between a particle and a reference point at frame t) to (its
/// reference distance), for a check that a shape has not blown apart.
fn max_by<F: Fn(usize, usize) -> f64>(traj: &Trajectory, n: usize, f: F) -> f64 {
    (0..traj.frames())
        .flat_map(|t| (0..n).map(move |i| (t, i)))
        .map(|(t, i)| f(t, i))
        .fold(0.0, f64::max)
}

/// Every coordinate of every frame is finite.
fn assert_finite(name: &str, traj: &Trajectory) {
    for t in 0..traj.frames() {
        for i in 0..traj.particles() {
            let p = traj.pos(t, i);
            assert!(
                p.iter().all(|c| c.is_finite()),
                "{name}: frame {t}, particle {i}: {p:?}"
            );
        }
    }
}

/// Mass-weighted centre of the free particles at frame t.
fn centre(scene: &Scene, traj: &Trajectory, t: usize) -> Vec3 {
    let mut c = Vec3::zeros();
    let mut total = 0.0;
    for (i, p) in scene.particles.iter().enumerate() {
        c += traj.pos(t, i) * p.mass.value();
        total += p.mass.value();
    }
    c / total
}

/// The centre of mass of a scene with no fixed particle follows the integrator's parabola
/// `c(n) = c0 + v0 n dt + g dt² n(n+1)/2` (link forces cancel in pairs): checks that no link
/// injects momentum.
fn assert_free_centre_of_mass(name: &str, scene: &Scene, traj: &Trajectory) {
    let total: f64 = scene.particles.iter().map(|p| p.mass.value()).sum();
    let v0 = scene
        .particles
        .iter()
        .map(|p| Vec3::from(p.vel) * p.mass.value())
        .sum::<Vec3>()
        / total;
    let (c0, g, dt) = (centre(scene, traj, 0), Vec3::from(scene.gravity), scene.dt);
    for n in 0..traj.frames() {
        let nf = n as f64;
        let want = c0 + v0 * (nf * dt) + g * (dt * dt * nf * (nf + 1.0) / 2.0);
        let got = centre(scene, traj, n);
        assert!(
            (got - want).norm() < 1e-9,
            "{name}: frame {n}: centre {got:?} vs {want:?}"
        );
    }
}

/// Each link type's instances (those with a free end) all vary by at least `min` over the
/// trajectory: relative length for binary links, cosine for angles.
fn assert_every_type_excited(name: &str, scene: &Scene, traj: &Trajectory, min: f64) {
    let var = link_variation(scene, traj);
    let mut seen = vec![false; scene.types.len()];
    for (k, (l, v)) in scene.links.iter().zip(&var).enumerate() {
        if l.particles.iter().all(|&i| scene.particles[i].fixed) {
            continue;
        }
        let t = &scene.types[l.type_index].name;
        assert!(
            *v >= min,
            "{name}: link {k} of type {t} varies by only {v:e}"
        );
        seen[l.type_index] = true;
    }
    for (t, s) in scene.types.iter().zip(&seen) {
        assert!(s, "{name}: type {} has no moving instance", t.name);
    }
}

fn assert_json_round_trip(name: &str, scene: &Scene) {
    let back = Scene::from_json_str(&scene.to_json_string()).unwrap();
    assert!(back == *scene, "{name}: the scene read back differs");
}

fn max_ratio(scene: &Scene) -> f64 {
    stability_ratio(scene).into_iter().fold(0.0, f64::max)
}

fn count_kind(scene: &Scene, kind: LinkKind) -> usize {
    scene
        .links
        .iter()
        .filter(|l| scene.types[l.type_index].kind == kind)
        .count()
}

#[test]
fn names_resolve_to_valid_deterministic_scenes() {
    for name in NAMES {
        let scene = by_name(name).unwrap();
        scene.validate().unwrap();
        assert!(default_frames(name) >= 50, "{name}");
        assert!(by_name(name) == Some(scene), "{name}: two builds differ");
    }
    assert!(by_name("tadpol").is_none());
    assert_eq!(default_frames("tadpol"), 0);
}

#[test]
fn rigid_object_is_thrown_spinning_and_stays_rigid() {
    let (scene, traj) = simulate("rigid");
    assert_eq!(scene.particles.len(), 15);
    assert_eq!(scene.types.len(), 10);
    assert_eq!(scene.links.len(), 31);
    assert_eq!(count_kind(&scene, LinkKind::Spring), 31);
    for t in &scene.types {
        assert!(t.param("damping").unwrap().is_known_zero(), "{}", t.name);
        assert!(t.value("stiffness").unwrap() > 0.0 && t.value("rest_length").unwrap() > 0.0);
    }
    let m0 = scene.particles[0].mass.value();
    assert!(scene.particles.iter().any(|p| p.mass.value() != m0));
    assert_eq!(traj.frames(), 100);
    assert_finite("rigid", &traj);
    assert_free_centre_of_mass("rigid", &scene, &traj);
    // Spinning: the angle of the first row turns by more than a radian over the run.
    let heading = |t: usize| {
        let d = traj.pos(t, 4) - traj.pos(t, 0);
        d.y.atan2(d.x)
    };
    assert!((heading(99) - heading(0)).abs() > 1.0);
    // Quasi-rigid: every distance to the centre of mass stays within 5 % of its initial value.
    let r = |t: usize, i: usize| (traj.pos(t, i) - centre(&scene, &traj, t)).norm();
    let worst = max_by(&traj, 15, |t, i| (r(t, i) / r(0, i) - 1.0).abs());
    assert!(worst < 0.05, "rigid deforms by {worst}");
    assert_every_type_excited("rigid", &scene, &traj, 1e-3);
    assert!(max_ratio(&scene) < 0.3, "{}", max_ratio(&scene));
    assert_json_round_trip("rigid", &scene);
}

/// Springs of an `nx` × `ny` Provot mesh.
fn mesh_links(nx: usize, ny: usize) -> usize {
    ny * (nx - 1) + nx * (ny - 1) + 2 * (nx - 1) * (ny - 1) + ny * (nx - 2) + nx * (ny - 2)
}

#[test]
fn cloth_has_provot_mesh_counts() {
    for (nx, ny) in [(3, 3), (5, 4), (4, 9), (32, 32)] {
        let s = cloth(nx, ny);
        s.validate().unwrap();
        assert_eq!(s.particles.len(), nx * ny);
        assert_eq!(s.particles.iter().filter(|p| p.fixed).count(), nx);
        assert_eq!(s.types.len(), 6);
        assert_eq!(s.links.len(), mesh_links(nx, ny), "{nx}x{ny}");
        assert!(max_ratio(&s) < 0.3);
    }
    assert_eq!(mesh_links(32, 32), 2 * 32 * 31 + 2 * 31 * 31 + 2 * 32 * 30);
    assert_json_round_trip("cloth", &cloth(32, 32));
    // Degenerate sizes build (types without instances), never panic.
    for (nx, ny) in [(0, 0), (1, 1), (2, 1), (1, 5)] {
        cloth(nx, ny).validate().unwrap();
    }
}

/// Largest length / rest length of a Provot-limited spring over the trajectory.
fn max_structural_stretch(scene: &Scene, traj: &Trajectory) -> f64 {
    scene
        .links
        .iter()
        .filter(|l| scene.types[l.type_index].max_elongation().is_some())
        .map(|l| {
            let l0 = scene.types[l.type_index].value("rest_length").unwrap();
            let [i, j] = [l.particles[0], l.particles[1]];
            (0..traj.frames())
                .map(|t| (traj.pos(t, j) - traj.pos(t, i)).norm() / l0)
                .fold(0.0, f64::max)
        })
        .fold(0.0, f64::max)
}

#[test]
#[cfg_attr(
    debug_assertions,
    ignore = "two 400-frame runs of 5,800 springs: run with --release"
)]
fn cloth_swings_stretches_and_holds_its_elongation_limit() {
    let (scene, traj) = simulate("cloth");
    assert!(scene == cloth(32, 32));
    let limited: Vec<_> = scene
        .types
        .iter()
        .filter(|t| t.max_elongation().is_some())
        .collect();
    assert_eq!(limited.len(), 2);
    assert!(scene
        .types
        .iter()
        .any(|t| t.value("damping").unwrap() > 0.0));
    assert_finite("cloth", &traj);
    let n = scene.particles.len();
    // Pinned edge still; the free edge falls well below it.
    for i in 0..32 {
        assert_eq!(traj.pos(traj.frames() - 1, i), traj.pos(0, i));
    }
    let lowest = max_by(&traj, n, |t, i| -traj.pos(t, i).y);
    assert!(lowest > 0.9, "lowest point {}", -lowest);
    // Stretched visibly by its weight, and held near the Provot limit (one pass per step, so
    // the limit is approached rather than met exactly).
    let stretch = max_structural_stretch(&scene, &traj);
    assert!(
        stretch > 1.05 && stretch < 1.3,
        "structural stretch up to {stretch}"
    );
    // The limit is what holds it: without it the same cloth stretches much further.
    let mut free = scene.clone();
    for t in &mut free.types {
        t.set_optional(cordis_core::OptionalParam::MaxElongation, None);
    }
    let loose = max_structural_stretch(&scene, &free.simulate(traj.frames()).unwrap());
    assert!(
        loose > 1.4,
        "without the Provot limit, stretch only {loose}"
    );
    // No explosion: a particle j rows from the pinned edge stays within reach of it.
    let pitch = scene.particles[32].pos[2] - scene.particles[0].pos[2];
    let reach = max_by(&traj, n, |t, i| {
        let j = i / 32;
        if j == 0 {
            return 0.0;
        }
        (traj.pos(t, i) - traj.pos(0, i % 32)).norm() / (j as f64 * pitch)
    });
    assert!(
        reach < 1.5,
        "a particle is {reach} × its rest distance from the edge"
    );
    assert_every_type_excited("cloth", &scene, &traj, 1e-3);
    assert!(max_ratio(&scene) < 0.3, "{}", max_ratio(&scene));
    assert_json_round_trip("cloth", &scene);
}

/// Members of a group, in particle order.
fn members(scene: &Scene, g: &str) -> Vec<usize> {
    (0..scene.particles.len())
        .filter(|&i| scene.particles[i].group.as_deref() == Some(g))
        .collect()
}

#[test]
fn fluid_has_tens_of_thousands_of_pairs_in_range() {
    let scene = by_name("fluid").unwrap();
    assert!(scene.links.is_empty());
    let x0: Vec<Vec3> = scene.particles.iter().map(|p| Vec3::from(p.pos)).collect();
    assert!(x0.iter().all(|p| p.z == 0.0));
    let pairs = conditional_pairs(&scene, &x0);
    assert!(
        pairs.len() >= 10_000,
        "only {} pairs in range at frame 0",
        pairs.len()
    );
    // The library's grid finds exactly the brute-force pairs.
    let plan = Plan::compile(&scene).unwrap();
    let p = scene.param_values();
    let mut grid = Default::default();
    let mut found = Vec::new();
    for c in &plan.conditionals {
        let t = (0..scene.types.len())
            .find(|&t| plan.layout.type_offsets[t] == c.param)
            .unwrap();
        c.for_each_active_pair(&p, &x0, &mut grid, |i, j, _| {
            found.push((t, i.min(j), i.max(j)))
        });
    }
    found.sort_unstable();
    assert_eq!(found, pairs);
    let (gas, jet, wall) = (
        members(&scene, "gas"),
        members(&scene, "jet"),
        members(&scene, "wall"),
    );
    assert!(gas.len() > 2000 && jet.len() > 100 && !wall.is_empty());
    assert!(wall.iter().all(|&i| scene.particles[i].fixed));
    assert!(jet.iter().all(|&i| scene.particles[i].vel[0] > 0.0));
    assert!(max_ratio(&scene) < 0.3, "{}", max_ratio(&scene));
    assert_json_round_trip("fluid", &scene);
    // Small boxes build too, down to an empty one.
    for (c, r) in [(0, 0), (1, 1), (8, 5)] {
        examples::fluid(c, r).validate().unwrap();
    }
}

#[test]
#[cfg_attr(
    debug_assertions,
    ignore = "400 frames of 4,300 particles: run with --release"
)]
fn fluid_jet_penetrates_the_gas_inside_its_walls() {
    let (scene, traj) = simulate("fluid");
    let x0: Vec<Vec3> = scene.particles.iter().map(|p| Vec3::from(p.pos)).collect();
    let pairs = conditional_pairs(&scene, &x0).len();
    let (jet, wall) = (members(&scene, "jet"), members(&scene, "wall"));
    assert_finite("fluid", &traj);
    // Everything stays inside the walls (within half a pitch of them).
    let (mut lo, mut hi) = (Vec3::repeat(f64::INFINITY), Vec3::repeat(f64::NEG_INFINITY));
    for &i in &wall {
        lo = lo.inf(&x0[i]);
        hi = hi.sup(&x0[i]);
    }
    let last = traj.frames() - 1;
    for t in [last / 4, last / 2, last] {
        for i in 0..x0.len() {
            let p = traj.pos(t, i);
            assert!(
                p.x > lo.x - 0.5 && p.x < hi.x + 0.5 && p.y > lo.y - 0.5 && p.y < hi.y + 0.5,
                "frame {t}: particle {i} left the box: {p:?}"
            );
            assert_eq!(p.z, 0.0);
        }
    }
    // The jet travels a good part of the box, and the gas neither clumps nor disperses.
    let mean_x = |t: usize| jet.iter().map(|&i| traj.pos(t, i).x).sum::<f64>() / jet.len() as f64;
    let travelled = mean_x(last) - mean_x(0);
    assert!(
        travelled > 0.15 * (hi.x - lo.x),
        "the jet moved only {travelled} m"
    );
    let mut end = scene.clone();
    for (i, p) in end.particles.iter_mut().enumerate() {
        p.pos = traj.pos(last, i).into();
    }
    let end_pairs = conditional_pairs(
        &end,
        &(0..x0.len()).map(|i| traj.pos(last, i)).collect::<Vec<_>>(),
    )
    .len();
    assert!(
        end_pairs as f64 > 0.8 * pairs as f64 && (end_pairs as f64) < 1.5 * pairs as f64,
        "{pairs} → {end_pairs} pairs"
    );
    assert!(max_ratio(&end) < 0.5, "{}", max_ratio(&end));
}

#[test]
fn horse_has_annexe_2_size_and_gallops_stably() {
    let (scene, traj) = simulate("horse");
    assert_eq!(scene.particles.len(), 35);
    let binary = count_kind(&scene, LinkKind::Spring) + count_kind(&scene, LinkKind::Damper);
    assert_eq!(binary, 53);
    assert_eq!(count_kind(&scene, LinkKind::Angle), 3);
    assert_eq!(scene.links.len(), 56);
    assert_eq!(scene.types.len(), 56, "one type per link");
    assert_eq!((scene.dt, traj.frames()), (0.02, 53));
    assert_finite("horse", &traj);
    assert_free_centre_of_mass("horse", &scene, &traj);
    // It moves forward and keeps its size: no marker strays beyond 1.5 × the horse's initial
    // radius from the centre of mass.
    assert!(centre(&scene, &traj, 52).x - centre(&scene, &traj, 0).x > 5.0);
    let r0 = (0..35)
        .map(|i| (traj.pos(0, i) - centre(&scene, &traj, 0)).norm())
        .fold(0.0, f64::max);
    let r = max_by(&traj, 35, |t, i| {
        (traj.pos(t, i) - centre(&scene, &traj, t)).norm()
    });
    assert!(
        r < 1.5 * r0,
        "a marker is {r} m from the centre (initial radius {r0} m)"
    );
    assert_every_type_excited("horse", &scene, &traj, 1e-3);
    assert!(max_ratio(&scene) < 0.35, "{}", max_ratio(&scene));
    assert_json_round_trip("horse", &scene);
}

/// Largest swing (max - min length over frames `from..to`, m) of each muscle link of
/// `horse-gait`, measured on a trajectory of either horse (same links, same order).
fn leg_swings(gait: &Scene, traj: &cordis_core::Trajectory, from: usize, to: usize) -> Vec<f64> {
    gait.links
        .iter()
        .filter(|l| gait.types[l.type_index].kind == LinkKind::Muscle)
        .map(|l| {
            let len = |t: usize| (traj.pos(t, l.particles[1]) - traj.pos(t, l.particles[0])).norm();
            let (lo, hi) = (from..to).fold((f64::INFINITY, 0.0_f64), |(lo, hi), t| {
                (lo.min(len(t)), hi.max(len(t)))
            });
            hi - lo
        })
        .collect()
}

#[test]
fn horse_gait_sustains_a_bounded_leg_cycle_the_passive_horse_damps_out() {
    let gait = examples::horse_gait();
    assert_eq!(count_kind(&gait, LinkKind::Muscle), 4);
    // Its passive counterpart is exactly the passive horse.
    let passive = examples::passive(&gait);
    assert_eq!(passive.param_values(), examples::horse().param_values());
    assert_eq!(count_kind(&passive, LinkKind::Muscle), 0);
    // 10× the horse's frames: the neurons keep the legs swinging, the passive horse's swings
    // decay; the active horse stays in one piece (its size within 30% of the initial one).
    let frames = 10 * examples::HORSE_FRAMES;
    let active = gait.simulate(frames).unwrap();
    let still = examples::horse().simulate(frames).unwrap();
    assert_finite("horse-gait", &active);
    let last = frames - examples::HORSE_FRAMES;
    let a = leg_swings(&gait, &active, last, frames);
    let p = leg_swings(&gait, &still, last, frames);
    for (leg, (a, p)) in a.iter().zip(&p).enumerate() {
        assert!(
            *a > 0.05 && *a > 3.0 * p,
            "leg {leg}: active {a} m, passive {p} m"
        );
    }
    let size = |t: usize| {
        let n = gait.particles.len();
        let c = (0..n).fold(Vec3::zeros(), |c, i| c + active.pos(t, i)) / n as f64;
        (0..n)
            .map(|i| (active.pos(t, i) - c).norm())
            .fold(0.0, f64::max)
    };
    let s0 = size(0);
    for t in 0..frames {
        assert!(
            (size(t) - s0).abs() < 0.3 * s0,
            "frame {t}: size {} vs {s0}",
            size(t)
        );
    }
}
