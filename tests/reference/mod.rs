//! A naive simulator written straight from SPEC §2.1–2.2, independent of `cordis_core::Plan`
//! and `cordis_core::forces`: it reads only the public `Scene` data, loops over links in file
//! order with a `match` on the kind, finds conditional pairs by brute force (O(N²)) and uses
//! plain `[f64; 3]` arithmetic. It is slow on purpose: its only job is to be obviously right,
//! so that the fast core can be checked against it.
//!
//! Choices where the SPEC is silent (the same as the core's documented ones):
//! - an anchor's point is the link's `point`, else its type's `point`, else the particle's
//!   initial position;
//! - a fixed particle never moves, so its x(-1) = x(0) whatever its `vel` (v = 0 throughout).

#![allow(dead_code)] // each test binary uses a different subset

use cordis_core::{LinkKind, Scene};

pub type V = [f64; 3];

fn add(a: V, b: V) -> V {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
fn sub(a: V, b: V) -> V {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn scale(a: V, s: f64) -> V {
    [a[0] * s, a[1] * s, a[2] * s]
}
fn dot(a: V, b: V) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn norm(a: V) -> f64 {
    dot(a, a).sqrt()
}

/// `u = d / |d|`, or 0 when `|d| < 1e-12` (SPEC §2.2: no NaN ever).
fn unit(d: V) -> (V, f64) {
    let l = norm(d);
    if l < 1e-12 {
        ([0.0; 3], l)
    } else {
        (scale(d, 1.0 / l), l)
    }
}

/// SPEC §2.2 spring: force on i, `(K (L - l0) + Z s) u`, `s = (v_j - v_i)·u`.
fn spring(xi: V, xj: V, vi: V, vj: V, k: f64, l0: f64, z: f64) -> V {
    let (u, l) = unit(sub(xj, xi));
    let s = dot(sub(vj, vi), u);
    scale(u, k * (l - l0) + z * s)
}

/// SPEC §2.2 angle: `-∇` of `½K(cosθ - c0)²` on (i, k); the vertex j gets minus their sum.
/// Derived by hand: `∂cosθ/∂a = b/(|a||b|) - cosθ a/|a|²`, and symmetrically for b.
fn angle(xi: V, xj: V, xk: V, k: f64, c0: f64) -> Option<(V, V)> {
    let a = sub(xi, xj);
    let b = sub(xk, xj);
    let (la, lb) = (norm(a), norm(b));
    if la < 1e-12 || lb < 1e-12 {
        return None;
    }
    let c = dot(a, b) / (la * lb);
    let dcda = sub(scale(b, 1.0 / (la * lb)), scale(a, c / (la * la)));
    let dcdb = sub(scale(a, 1.0 / (la * lb)), scale(b, c / (lb * lb)));
    let g = -k * (c - c0);
    Some((scale(dcda, g), scale(dcdb, g)))
}

/// Positions of every particle at frames 0…frames-1.
pub fn simulate(scene: &Scene, frames: usize) -> Vec<Vec<V>> {
    let n = scene.particles.len();
    let dt = scene.dt;
    let mass: Vec<f64> = scene.particles.iter().map(|p| p.mass.value()).collect();
    let mut x: Vec<V> = scene.particles.iter().map(|p| p.pos).collect();
    let mut xp: Vec<V> = scene
        .particles
        .iter()
        .map(|p| {
            if p.fixed {
                p.pos
            } else {
                sub(p.pos, scale(p.vel, dt))
            }
        })
        .collect();
    let mut out = Vec::with_capacity(frames);
    if frames == 0 {
        return out;
    }
    out.push(x.clone());
    for _ in 1..frames {
        let v: Vec<V> = (0..n).map(|i| scale(sub(x[i], xp[i]), 1.0 / dt)).collect();
        let mut f: Vec<V> = vec![[0.0; 3]; n];
        for link in &scene.links {
            let ty = &scene.types[link.type_index];
            let p = |name: &str| ty.value(name).expect("parameter of the kind");
            let ps = &link.particles;
            match ty.kind {
                LinkKind::Spring => {
                    let (i, j) = (ps[0], ps[1]);
                    let fi = spring(
                        x[i],
                        x[j],
                        v[i],
                        v[j],
                        p("stiffness"),
                        p("rest_length"),
                        p("damping"),
                    );
                    f[i] = add(f[i], fi);
                    f[j] = sub(f[j], fi);
                }
                LinkKind::Damper => {
                    let (i, j) = (ps[0], ps[1]);
                    let fi = scale(sub(v[j], v[i]), p("damping"));
                    f[i] = add(f[i], fi);
                    f[j] = sub(f[j], fi);
                }
                LinkKind::Anchor => {
                    let i = ps[0];
                    let point = link.point.or(ty.point).unwrap_or(scene.particles[i].pos);
                    let fi = spring(
                        x[i],
                        point,
                        v[i],
                        [0.0; 3],
                        p("stiffness"),
                        p("rest_length"),
                        p("damping"),
                    );
                    f[i] = add(f[i], fi);
                }
                LinkKind::Drag => {
                    let i = ps[0];
                    f[i] = sub(f[i], scale(v[i], p("damping")));
                }
                LinkKind::NonlinearDrag => {
                    let i = ps[0];
                    let z = if norm(v[i]) < p("v_max") {
                        p("z1")
                    } else {
                        p("z2")
                    };
                    f[i] = sub(f[i], scale(v[i], z));
                }
                LinkKind::Angle => {
                    let (i, j, k) = (ps[0], ps[1], ps[2]);
                    if let Some((fi, fk)) = angle(x[i], x[j], x[k], p("stiffness"), p("rest_cos")) {
                        f[i] = add(f[i], fi);
                        f[k] = add(f[k], fk);
                        f[j] = sub(f[j], add(fi, fk));
                    }
                }
                LinkKind::Muscle => {
                    // SPEC §2.4: spring + G tanh(Σ w_len e + w_rate s - θ) u, the neuron seeing
                    // the listed links, else every other muscle link in file order.
                    let (i, j) = (ps[0], ps[1]);
                    let mut fi = spring(
                        x[i],
                        x[j],
                        v[i],
                        v[j],
                        p("stiffness"),
                        p("rest_length"),
                        p("damping"),
                    );
                    let seen: Vec<usize> = match link.observes.as_ref().or(ty.observes.as_ref()) {
                        Some(list) => list.clone(),
                        None => (0..scene.links.len())
                            .filter(|&k| {
                                let other = &scene.links[k];
                                !std::ptr::eq(other, link)
                                    && scene.types[other.type_index].kind == LinkKind::Muscle
                            })
                            .collect(),
                    };
                    let weight = |k: usize| ty.params[k].value();
                    let m = seen.len();
                    let mut h = 0.0;
                    for (k, &o) in seen.iter().enumerate() {
                        let ol = &scene.links[o];
                        let (a, b) = (ol.particles[0], ol.particles[1]);
                        let (u, l) = unit(sub(x[b], x[a]));
                        let l0 = scene.types[ol.type_index].value("rest_length").unwrap();
                        let rate = dot(sub(v[b], v[a]), u);
                        h += weight(5 + k) * (l - l0) + weight(5 + m + k) * rate;
                    }
                    let out = (h - p("threshold")).tanh();
                    let (u, _) = unit(sub(x[j], x[i]));
                    fi = add(fi, scale(u, p("gain") * out));
                    f[i] = add(f[i], fi);
                    f[j] = sub(f[j], fi);
                }
                other => panic!("reference: a listed link of kind {other}"),
            }
        }
        // Conditional types: every pair with one end in each group (both in the group when one
        // is named), found by brute force.
        for ty in scene
            .types
            .iter()
            .filter(|t| t.kind == LinkKind::Conditional)
        {
            let p = |name: &str| ty.value(name).expect("parameter of the kind");
            let (k, l0, z, r) = (p("stiffness"), p("rest_length"), p("damping"), p("range"));
            let in_group = |i: usize, g: &str| scene.particles[i].group.as_deref() == Some(g);
            let g0 = ty.groups[0].as_str();
            let g1 = ty.groups.get(1).map_or(g0, |g| g.as_str());
            for i in 0..n {
                for j in i + 1..n {
                    let pair = (in_group(i, g0) && in_group(j, g1))
                        || (in_group(i, g1) && in_group(j, g0));
                    if pair && norm(sub(x[j], x[i])) < r {
                        let fi = spring(x[i], x[j], v[i], v[j], k, l0, z);
                        f[i] = add(f[i], fi);
                        f[j] = sub(f[j], fi);
                    }
                }
            }
        }
        let mut next = x.clone();
        for i in 0..n {
            if !scene.particles[i].fixed {
                let acc = add(scale(f[i], 1.0 / mass[i]), scene.gravity);
                next[i] = add(sub(scale(x[i], 2.0), xp[i]), scale(acc, dt * dt));
            }
        }
        // Provot: one pass over the limited springs in file order, each correction seen by
        // the next; x(n) is left alone.
        for link in &scene.links {
            let ty = &scene.types[link.type_index];
            let Some(tau) = ty.max_elongation().map(|p| p.value()) else {
                continue;
            };
            let (i, j) = (link.particles[0], link.particles[1]);
            let limit = (1.0 + tau) * ty.value("rest_length").unwrap();
            let (u, l) = unit(sub(next[j], next[i]));
            let excess = l - limit;
            if excess <= 0.0 {
                continue;
            }
            let (fi, fj) = (!scene.particles[i].fixed, !scene.particles[j].fixed);
            let (si, sj) = match (fi, fj) {
                (true, true) => (0.5, 0.5),
                (true, false) => (1.0, 0.0),
                (false, true) => (0.0, 1.0),
                (false, false) => (0.0, 0.0),
            };
            next[i] = add(next[i], scale(u, si * excess));
            next[j] = sub(next[j], scale(u, sj * excess));
        }
        xp = std::mem::replace(&mut x, next);
        out.push(x.clone());
    }
    out
}
