//! A scene built on tracked markers (`cordis scene from-markers`): one particle per marker, a
//! spring network on the markers' first positions, every spring parameter unknown in a box,
//! ready for `cordis identify`.
//!
//! - Particles: each marker's first observed position; its initial velocity the finite
//!   difference `(x1 − x0) / dt` of its first two frames when both are observed (else 0; the
//!   output-error estimator estimates the initial state anyway). A marker that never moves —
//!   every observation within `still` of its median position — is `fixed` (a clamp, a
//!   marker on the frame) at the mean of its observations (at one frame's noisy position it
//!   was an error no parameter could absorb). Masses: the total shared equally.
//! - Links (springs): the `k` nearest neighbours of every marker (made mutual), or every pair
//!   closer than a radius, in the first positions. Delaunay meshes are not built (yet).
//! - Types: one per *link family* — links whose observed lengths (in the first positions)
//!   follow each other, in increasing order, with gaps under `family_tolerance` (relative):
//!   noise spreads a family, a gap separates two — or one per link.
//! - Unknown boxes: rest length `[L/√w, L·√w]` around the family's observed length `L`
//!   (init `L`, the family's median); stiffness `[K/1000, K]` and damping `[0, Z]` with `K = 4 m / (dt² d)`,
//!   `Z = 2 m / (dt d)`, `m` the smallest free mass and `d` the largest number of links on
//!   one particle: the stability bound `4m > K dt² + 2 Z dt` (SPEC) shared among a particle's
//!   links, so that any stiffness in the box alone keeps the network stable.
//!
//! [`with_unknowns`] turns any scene's positive link-type parameters unknown in boxes `w`
//! times wide centred (geometrically) on their values.

use crate::error::{CordisError, Result};
use crate::{Bounds, Observations, Param, Scene};

/// How the links are chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LinkRule {
    /// Each marker to its `k` nearest others (a pair chosen by either end is one link).
    Nearest(usize),
    /// Every pair closer than this, m.
    Radius(f64),
}

/// One type per family of equal lengths, or one per link.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TypeRule {
    Family,
    PerLink,
}

/// What [`scene_from_markers`] needs beyond the markers.
#[derive(Clone, Debug)]
pub struct MarkerScene {
    pub links: LinkRule,
    pub types: TypeRule,
    /// Ratio max/min of the rest-length boxes (> 1).
    pub width: f64,
    /// Total mass of the particles, kg.
    pub total_mass: f64,
    /// Time step, s.
    pub dt: f64,
    /// Gravity, m/s².
    pub gravity: [f64; 3],
    /// A marker whose observations all lie within this distance of its median is fixed, m
    /// (None: 2 % of the markers' extent).
    pub still: Option<f64>,
    /// Relative tolerance under which two lengths are of one family.
    pub family_tolerance: f64,
}

fn arg(place: &str, message: String) -> CordisError {
    CordisError::argument(place, message)
}

/// The scene (module docs) for `obs`; errors name the option or the marker.
pub fn scene_from_markers(obs: &Observations, o: &MarkerScene) -> Result<Scene> {
    let (t, n) = (obs.frames(), obs.particles());
    crate::arg::box_width("--width", o.width)?;
    crate::arg::number("--dt", o.dt, crate::arg::Low::Above(0.0), 1e6, "s")?;
    crate::arg::number(
        "--total-mass",
        o.total_mass,
        crate::arg::Low::Above(0.0),
        1e30,
        "kg",
    )?;
    if n < 2 {
        return Err(arg(
            "TRAJ",
            format!("{n} marker: a network needs at least 2"),
        ));
    }
    let first = first_observed(obs)?;
    let mut pos: Vec<[f64; 3]> = first.iter().map(|(_, p)| *p).collect();
    let still = match o.still {
        Some(s) => crate::arg::number("--still", s, crate::arg::Low::AtLeast(0.0), 1e30, "m")?,
        None => 0.02 * extent(&pos),
    };
    let rest_at: Vec<Option<[f64; 3]>> = (0..n).map(|i| still_position(obs, i, still)).collect();
    let fixed: Vec<bool> = rest_at.iter().map(Option::is_some).collect();
    // A fixed particle never moves in the simulation, so it must sit where its marker is on
    // average, not at its first (noisy) frame: one frame's noise there was a constant error
    // no parameter could absorb, and the soft block's fit from this scene ended above the
    // noise in a wrong basin (σ̂ 1.21 mm against 0.99 mm; at the mean: converged at 1.00 mm).
    for (p, at) in pos.iter_mut().zip(&rest_at) {
        if let Some(at) = at {
            *p = *at;
        }
    }
    let pairs = choose_pairs(&pos, o.links)?;
    if pairs.is_empty() {
        return Err(arg(
            "--radius",
            "no pair of markers is that close: no link".into(),
        ));
    }
    // Observed length of each pair: its distance in the first positions (the reference the
    // network starts from; later frames are deformed by the motion and by gravity).
    let lengths: Vec<f64> = pairs.iter().map(|&(a, b)| dist(&pos[a], &pos[b])).collect();
    let mass = o.total_mass / n as f64;
    let mut scene = Scene::new(o.dt);
    scene.gravity = o.gravity;
    for i in 0..n {
        let vel = match (first[i].0, fixed[i]) {
            (_, true) => [0.0; 3],
            (f, false) => match (
                observed(obs, f, i),
                (f + 1 < t).then(|| observed(obs, f + 1, i)).flatten(),
            ) {
                (Some(a), Some(b)) => [0, 1, 2].map(|k| (b[k] - a[k]) / o.dt),
                _ => [0.0; 3],
            },
        };
        let mut p = crate::Particle::new(mass, pos[i]);
        p.vel = vel;
        p.fixed = fixed[i];
        scene.particles.push(p);
    }
    let (family_of, families) = families(&lengths, o.types, o.family_tolerance);
    let (k_max, z_max) = stable_boxes(mass, o.dt, n, &pairs);
    let sw = o.width.sqrt();
    let prefix = match o.types {
        TypeRule::Family => "family",
        TypeRule::PerLink => "link",
    };
    for (k, members) in families.iter().enumerate() {
        let mut l: Vec<f64> = members.iter().map(|&m| lengths[m]).collect();
        l.sort_by(f64::total_cmp);
        let rest = l[l.len() / 2];
        let unknown =
            |min: f64, max: f64, init: Option<f64>| Param::Unknown(Bounds { min, max, init });
        let params = vec![
            unknown(k_max / 1000.0, k_max, None),
            unknown(rest / sw, rest * sw, Some(rest)),
            unknown(0.0, z_max, None),
        ];
        let mut ty = crate::LinkType::new(format!("{prefix}_{k}"), crate::LinkKind::Spring);
        ty.params = params;
        scene.types.push(ty);
    }
    for (l, &(a, b)) in pairs.iter().enumerate() {
        scene.links.push(crate::Link {
            type_index: family_of[l],
            particles: vec![a, b],
            point: None,
            observes: None,
        });
    }
    // The parser's checks (indices, boxes, kinds) on what was built.
    Scene::from_json_str(&scene.to_json_string())
}

/// Marker `i`'s position at frame `f`, if observed (every coordinate finite).
fn observed(obs: &Observations, f: usize, i: usize) -> Option<[f64; 3]> {
    let n = obs.particles();
    let v = &obs.as_flat()[(f * n + i) * 3..(f * n + i) * 3 + 3];
    v.iter().all(|x| x.is_finite()).then(|| [v[0], v[1], v[2]])
}

/// Each marker's first observed frame and position; an error names a marker never observed.
fn first_observed(obs: &Observations) -> Result<Vec<(usize, [f64; 3])>> {
    (0..obs.particles())
        .map(|i| {
            (0..obs.frames())
                .find_map(|f| observed(obs, f, i).map(|p| (f, p)))
                .ok_or_else(|| {
                    CordisError::trajectory(
                        format!("marker {i}"),
                        "never observed: it has no position to start from",
                    )
                })
        })
        .collect()
}

/// The diagonal of the positions' bounding box, m.
pub fn extent(pos: &[[f64; 3]]) -> f64 {
    extent_of(pos.iter().copied())
}

/// [`extent`] of points as they come (a take's flat positions, without a copy); NaN
/// coordinates (missing observations) are left out.
pub fn extent_of(pos: impl IntoIterator<Item = [f64; 3]>) -> f64 {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in pos {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    dist(&lo, &hi)
}

/// The links' families (module docs): sorted by length, a new family where the gap to the
/// next length is more than `tolerance` (relative) — noise spreads a family's lengths, a gap
/// separates them — or one per link. Returns each link's family and each family's links.
fn families(lengths: &[f64], rule: TypeRule, tolerance: f64) -> (Vec<usize>, Vec<Vec<usize>>) {
    let mut order: Vec<usize> = (0..lengths.len()).collect();
    order.sort_by(|&x, &y| lengths[x].total_cmp(&lengths[y]));
    let mut family_of = vec![0usize; lengths.len()];
    let mut families: Vec<Vec<usize>> = Vec::new();
    for &l in &order {
        let new = match (rule, families.last()) {
            (TypeRule::PerLink, _) | (_, None) => true,
            (TypeRule::Family, Some(f)) => {
                let last = lengths[*f.last().expect("non-empty")];
                lengths[l] > last * (1.0 + tolerance)
            }
        };
        if new {
            families.push(Vec::new());
        }
        families.last_mut().expect("one").push(l);
        family_of[l] = families.len() - 1;
    }
    (family_of, families)
}

/// The stiffness and damping boxes' tops (module docs): `K = 4 m / (dt² d)` (N/m) and
/// `Z = 2 m / (dt d)` (N·s/m), `d` the most links on one of the `n` particles.
fn stable_boxes(mass: f64, dt: f64, n: usize, pairs: &[(usize, usize)]) -> (f64, f64) {
    let mut degree = vec![0usize; n];
    for &(a, b) in pairs {
        degree[a] += 1;
        degree[b] += 1;
    }
    let d = degree.iter().copied().max().unwrap_or(1).max(1) as f64;
    (4.0 * mass / (dt * dt * d), 2.0 * mass / (dt * d))
}

fn dist(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Where marker `i` rests if it never moves — every observation within `still` of its
/// per-axis median —: the mean of its observations (the maximum-likelihood position of a
/// fixed point under Gaussian noise: [`rest_position`]). `None` if it moves or is
/// seen in fewer than 2 frames.
fn still_position(obs: &Observations, i: usize, still: f64) -> Option<[f64; 3]> {
    let seen: Vec<[f64; 3]> = (0..obs.frames())
        .filter_map(|f| observed(obs, f, i))
        .collect();
    if seen.len() < 2 {
        return None;
    }
    let median = [0, 1, 2].map(|k| {
        let mut c: Vec<f64> = seen.iter().map(|p| p[k]).collect();
        c.sort_by(f64::total_cmp);
        c[c.len() / 2]
    });
    if !seen.iter().all(|p| dist(p, &median) <= still) {
        return None;
    }
    rest_position(&seen)
}

/// The position of a point that does not move, from observations with independent noise of
/// one σ: their mean, the maximum-likelihood estimate (error σ/√count against σ for any one),
/// summed as the first plus the mean offset from it, so that a noiseless point keeps its
/// position to the bit. `None` without observations. Discovery's fixed particles too.
pub fn rest_position(points: &[[f64; 3]]) -> Option<[f64; 3]> {
    let x0 = *points.first()?;
    let count = points.len() as f64;
    Some([0, 1, 2].map(|k| x0[k] + points.iter().map(|p| p[k] - x0[k]).sum::<f64>() / count))
}

/// The unordered pairs the rule links, each once, in increasing (a, b) order.
fn choose_pairs(pos: &[[f64; 3]], rule: LinkRule) -> Result<Vec<(usize, usize)>> {
    let n = pos.len();
    let mut pairs = Vec::new();
    match rule {
        LinkRule::Radius(r) => {
            crate::arg::number("--radius", r, crate::arg::Low::Above(0.0), 1e30, "m")?;
            for a in 0..n {
                for b in a + 1..n {
                    if dist(&pos[a], &pos[b]) <= r {
                        pairs.push((a, b));
                    }
                }
            }
        }
        LinkRule::Nearest(k) => {
            if k == 0 || k >= n {
                return Err(arg(
                    "--neighbours",
                    format!(
                        "{k}: must be between 1 and the number of markers − 1 ({})",
                        n - 1
                    ),
                ));
            }
            for a in 0..n {
                let mut others: Vec<usize> = (0..n).filter(|&b| b != a).collect();
                others.sort_by(|&x, &y| {
                    dist(&pos[a], &pos[x])
                        .total_cmp(&dist(&pos[a], &pos[y]))
                        .then(x.cmp(&y))
                });
                for &b in &others[..k] {
                    pairs.push((a.min(b), a.max(b)));
                }
            }
            pairs.sort_unstable();
            pairs.dedup();
        }
    }
    Ok(pairs)
}

/// A copy of `scene` whose positive known link-type parameters are unknown, each in a box
/// `width` times wide (max/min) centred geometrically on its value, which is its `init`. Zero
/// parameters (an absent damping) stay known, and so do those the examples' unknown boxes
/// keep known: a muscle's weights, gain and threshold, a TGR's tendon, `rest_cos`.
pub fn with_unknowns(scene: &Scene, width: f64) -> Result<Scene> {
    crate::arg::box_width("width", width)?;
    let mut out = scene.clone();
    let sw = width.sqrt();
    for t in &mut out.types {
        let names: Vec<String> = (0..t.params.len()).map(|k| t.param_name(k)).collect();
        for (p, name) in t.params.iter_mut().zip(&names) {
            let Param::Known(v) = *p else { continue };
            // Optional parameters (τc, Z₂) stay known, as before they were parameters.
            let kept = name.starts_with("w_")
                || name.starts_with("tendon_")
                || crate::OptionalParam::from_name(name).is_some()
                || matches!(name.as_str(), "gain" | "threshold" | "rest_cos");
            if v <= 0.0 || kept {
                continue;
            }
            *p = Param::Unknown(Bounds {
                min: v / sw,
                max: v * sw,
                init: Some(v),
            });
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// τc stays a known number (it was not a parameter before issue 19); the stiffnesses
    /// become unknown as before.
    #[test]
    fn with_unknowns_leaves_provots_limit_known() {
        let cloth = crate::examples::cloth(4, 4);
        let u = with_unknowns(&cloth, 4.0).unwrap();
        let limited: Vec<_> = u.types.iter().filter_map(|t| t.max_elongation()).collect();
        assert_eq!(limited.len(), 2);
        assert!(limited.iter().all(|tau| !tau.is_unknown()));
        assert!(u
            .types
            .iter()
            .all(|t| t.param("stiffness").unwrap().is_unknown()));
    }

    /// A 2 × 2 square of markers, pitch 0.1 m, the left column still, the right one moving.
    fn square(frames: usize) -> Observations {
        let mut data = Vec::new();
        for f in 0..frames {
            let dx = 0.01 * f as f64;
            for p in [
                [0.0, 0.0, 0.0],
                [0.1, 0.0, 0.0],
                [0.0, 0.1, 0.0],
                [0.1, 0.1, 0.0],
            ] {
                let moving = p[0] > 0.0;
                data.extend_from_slice(&[p[0] + if moving { dx } else { 0.0 }, p[1], p[2]]);
            }
        }
        Observations::from_flat(frames, 4, data).unwrap()
    }

    fn options(links: LinkRule, types: TypeRule) -> MarkerScene {
        MarkerScene {
            links,
            types,
            width: 4.0,
            total_mass: 0.4,
            dt: 0.01,
            gravity: [0.0, -9.81, 0.0],
            still: None,
            family_tolerance: 0.05,
        }
    }

    #[test]
    fn a_radius_links_sides_and_diagonals_in_two_families() {
        let s = scene_from_markers(
            &square(5),
            &options(LinkRule::Radius(0.15), TypeRule::Family),
        )
        .unwrap();
        assert_eq!(s.links.len(), 6);
        assert_eq!(s.types.len(), 2, "sides and diagonals");
        assert_eq!(
            s.particles.iter().map(|p| p.fixed).collect::<Vec<_>>(),
            [true, false, true, false]
        );
        assert!((s.particles[1].vel[0] - 1.0).abs() < 1e-9, "(x1 - x0) / dt");
        assert!(s.particles.iter().all(|p| p.mass == Param::Known(0.1)));
        let Param::Unknown(rest) = s.types[0].params[1] else {
            panic!("rest length unknown")
        };
        assert!(rest.min < 0.1 && rest.max > 0.1 && (rest.max / rest.min - 4.0).abs() < 1e-9);
        let per_link = scene_from_markers(
            &square(5),
            &options(LinkRule::Radius(0.15), TypeRule::PerLink),
        )
        .unwrap();
        assert_eq!(per_link.types.len(), 6);
    }

    /// A still marker jittering by ±1 mm around its rest (the first frame 1 mm off) is fixed
    /// at the mean of its frames, not at its first: a soft block from this scene ended in a
    /// wrong basin above the noise (the tester's finding, 2026-12-07).
    #[test]
    fn a_fixed_marker_sits_at_the_mean_of_its_frames_not_its_first() {
        let frames = 8;
        let mut obs = square(frames);
        let n = obs.particles();
        let flat: Vec<f64> = obs
            .as_flat()
            .iter()
            .enumerate()
            .map(|(a, &x)| {
                let (f, i, c) = (a / (3 * n), (a / 3) % n, a % 3);
                let jitter = if f % 2 == 0 { 1e-3 } else { -1e-3 };
                if i == 0 && c == 0 {
                    x + jitter
                } else {
                    x
                }
            })
            .collect();
        obs = Observations::from_flat(frames, n, flat).unwrap();
        let s =
            scene_from_markers(&obs, &options(LinkRule::Radius(0.15), TypeRule::Family)).unwrap();
        assert!(s.particles[0].fixed);
        assert_eq!(obs.as_flat()[0], 1e-3, "the first frame is 1 mm off");
        assert!(
            s.particles[0].pos[0].abs() < 1e-15,
            "{:?}",
            s.particles[0].pos
        );
    }

    #[test]
    fn nearest_neighbours_are_mutual_and_bad_options_are_named() {
        let s = scene_from_markers(&square(3), &options(LinkRule::Nearest(2), TypeRule::Family))
            .unwrap();
        assert_eq!(s.links.len(), 4, "the four sides");
        let e = scene_from_markers(&square(3), &options(LinkRule::Nearest(9), TypeRule::Family))
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("--neighbours: 9"), "{e}");
        let e = scene_from_markers(
            &square(3),
            &options(LinkRule::Radius(0.01), TypeRule::Family),
        )
        .unwrap_err()
        .to_string();
        assert!(e.starts_with("--radius: no pair"), "{e}");
    }

    #[test]
    fn with_unknowns_boxes_every_positive_parameter_around_its_value() {
        let s = scene_from_markers(
            &square(3),
            &options(LinkRule::Radius(0.15), TypeRule::Family),
        )
        .unwrap();
        let mut known = s.clone();
        for t in &mut known.types {
            for p in &mut t.params {
                *p = Param::Known(p.value());
            }
        }
        known.types[0].params[2] = Param::Known(0.0);
        let u = with_unknowns(&known, 9.0).unwrap();
        let Param::Unknown(b) = u.types[0].params[0] else {
            panic!("stiffness unknown")
        };
        let v = known.types[0].params[0].value();
        assert!((b.min - v / 3.0).abs() < 1e-12 && (b.max - 3.0 * v).abs() < 1e-9);
        assert_eq!(b.init, Some(v));
        assert_eq!(
            u.types[0].params[2],
            Param::Known(0.0),
            "a zero stays known"
        );
        assert!(with_unknowns(&known, 1.0).is_err());
    }
}
