//! The local-control muscle (SPEC §2.4): a silent neuron is a spring bit for bit, forces match
//! a hand computation, scene errors name their place, and the shipped example's neurons
//! sustain an oscillation that passive springs damp out.

use approx::assert_relative_eq;
use cordis_core::examples::{muscle, MUSCLE_FRAMES};
use cordis_core::{LinkKind, LinkType, Param, Particle, Plan, Scene, Trajectory, Vec3};

fn known(v: &[f64]) -> Vec<Param> {
    v.iter().map(|&x| Param::Known(x)).collect()
}

/// A 3-D chain of four particles and three binary links of two types, as `kind`.
fn chain(kind: LinkKind) -> Scene {
    let mut s = Scene::new(0.005);
    s.add_particle(Particle::new(1.0, [0.0, 0.0, 0.0]).fixed());
    s.add_particle(Particle::new(0.5, [1.3, 0.2, 0.0]));
    s.add_particle(Particle::new(0.8, [2.1, -0.4, 0.3]).with_vel([0.0, 0.5, -0.2]));
    s.add_particle(Particle::new(1.2, [2.5, 0.6, -0.5]));
    for (name, k, l0, z) in [("a", 40.0, 1.0, 0.3), ("b", 25.0, 0.7, 0.0)] {
        let mut t = LinkType::new(name, kind)
            .with("stiffness", k)
            .with("rest_length", l0)
            .with("damping", z);
        if kind == LinkKind::Muscle {
            t = t
                .with("gain", 3.0)
                .with_weights(&known(&[0.0, 0.0]), &known(&[0.0, 0.0]));
        }
        s.add_type(t);
    }
    s.add_link("a", &[0, 1]);
    s.add_link("b", &[1, 2]);
    s.add_link("a", &[2, 3]);
    s
}

#[test]
fn a_silent_muscle_is_a_spring_bit_for_bit() {
    let springs = chain(LinkKind::Spring).simulate(500).unwrap();
    let muscles = chain(LinkKind::Muscle).simulate(500).unwrap();
    let bits = |t: &Trajectory| t.as_flat().iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&springs), bits(&muscles));
    // And the chain really moves, so the comparison means something.
    assert!((springs.pos(499, 3) - springs.pos(0, 3)).norm() > 1e-2);
}

#[test]
fn forces_match_a_hand_computation() {
    let mut s = chain(LinkKind::Muscle);
    let mut w = |t: &str, wl: [f64; 2], wr: [f64; 2], theta: f64| {
        let i = s.type_index(t).unwrap();
        s.types[i] = s.types[i]
            .clone()
            .with("threshold", theta)
            .with_weights(&known(&wl), &known(&wr));
    };
    w("a", [1.5, -0.5], [0.3, 0.8], 0.2);
    w("b", [-2.0, 0.7], [0.4, -0.6], -0.1);
    let plan = Plan::compile(&s).unwrap();
    let p = s.param_values();
    let x: Vec<Vec3> = s.particles.iter().map(|q| Vec3::from(q.pos)).collect();
    let v = [
        [0.1, 0.0, 0.2],
        [0.3, -0.2, 0.1],
        [-0.4, 0.5, 0.0],
        [0.2, 0.1, -0.3],
    ]
    .map(Vec3::from)
    .to_vec();
    let mut scratch = plan.scratch();
    let mut f = vec![Vec3::zeros(); 4];
    plan.forces(&p, &x, &v, &mut f, &mut scratch.grids, &mut scratch.muscles);

    // By hand: link (i, j, K, l0, Z, G, θ, w_len, w_rate); link 0 observes links 1, 2, link 1
    // observes 0, 2 and link 2 observes 0, 1 (every other muscle, file order).
    let geo = |i: usize, j: usize, l0: f64| {
        let d = x[j] - x[i];
        let u = d / d.norm();
        (d.norm() - l0, (v[j] - v[i]).dot(&u), u)
    };
    let links = [(0, 1, "a"), (1, 2, "b"), (2, 3, "a")];
    let par = |t: &str, n: &str| s.types[s.type_index(t).unwrap()].value(n).unwrap();
    let es: Vec<_> = links
        .iter()
        .map(|&(i, j, t)| geo(i, j, par(t, "rest_length")))
        .collect();
    let mut want = vec![Vec3::zeros(); 4];
    for (m, &(i, j, t)) in links.iter().enumerate() {
        let ty = &s.types[s.type_index(t).unwrap()];
        let others: Vec<usize> = (0..3).filter(|&k| k != m).collect();
        let h: f64 = others
            .iter()
            .enumerate()
            .map(|(k, &o)| ty.w_len()[k].value() * es[o].0 + ty.w_rate()[k].value() * es[o].1)
            .sum();
        let out = (h - par(t, "threshold")).tanh();
        let (e, rate, u) = es[m];
        let mag = par(t, "stiffness") * e + par(t, "damping") * rate + par(t, "gain") * out;
        want[i] += u * mag;
        want[j] -= u * mag;
    }
    for (a, b) in f.iter().zip(&want) {
        for k in 0..3 {
            assert_relative_eq!(a[k], b[k], epsilon = 1e-12, max_relative = 1e-12);
        }
    }
    // The neurons matter here: the silent chain's forces differ.
    let silent = Plan::compile(&chain(LinkKind::Muscle)).unwrap();
    let mut g = vec![Vec3::zeros(); 4];
    let ps = chain(LinkKind::Muscle).param_values();
    silent.forces(
        &ps,
        &x,
        &v,
        &mut g,
        &mut scratch.grids,
        &mut scratch.muscles,
    );
    assert!((g[1] - f[1]).norm() > 0.1);
}

fn err(s: &Scene) -> String {
    s.validate().unwrap_err().to_string()
}

#[test]
fn scene_errors_name_their_place() {
    let mut s = chain(LinkKind::Muscle);
    s.types[1] = s.types[1]
        .clone()
        .with_weights(&known(&[1.0]), &known(&[1.0]));
    assert!(err(&s).contains("links[1]"), "{}", err(&s));
    assert!(err(&s).contains("1 weight"), "{}", err(&s));

    let mut s = chain(LinkKind::Muscle);
    s.links[0].observes = Some(vec![0, 1]);
    assert!(err(&s).contains("links[0].observes[0]"), "{}", err(&s));

    let mut s = chain(LinkKind::Muscle);
    s.types[0].observes = Some(vec![1, 7]);
    assert!(err(&s).contains("types.a.observes[1]"), "{}", err(&s));

    let mut s = chain(LinkKind::Spring);
    s.links[0].observes = Some(vec![1]);
    assert!(err(&s).contains("links[0].observes"), "{}", err(&s));

    let mut s = chain(LinkKind::Muscle);
    s.types[0].params[6] = Param::Known(f64::NAN);
    assert!(err(&s).contains("types.a.w_len[1]"), "{}", err(&s));
    s.types[0].params[6] = Param::Known(-3.0); // weights may be negative
    s.validate().unwrap();
    s.types[0].params.pop();
    assert!(err(&s).contains("types.a.w_rate"), "{}", err(&s));
}

#[test]
fn json_weights_observes_and_defaults() {
    let text = r#"{"dt": 0.01,
        "particles": [{"mass": 1, "pos": [0,0,0]}, {"mass": 1, "pos": [1,0,0]},
                      {"mass": 1, "pos": [2,0,0]}],
        "types": {"m": {"kind": "muscle", "stiffness": 10, "rest_length": 1,
                        "w_len": [0.5], "w_rate": [{"min": -2, "max": 1}]},
                  "q": {"kind": "muscle", "stiffness": 10, "rest_length": 1}},
        "links": [{"type": "m", "particles": [0, 1]},
                  {"type": "q", "particles": [1, 2], "observes": [0]}]}"#;
    let s = Scene::from_json_str(text).unwrap();
    let (m, q) = (&s.types[0], &s.types[1]);
    assert_eq!(m.w_len(), &[Param::Known(0.5)]);
    assert!(m.w_rate()[0].is_unknown());
    assert_eq!(m.value("gain"), Some(1.0));
    // Weights omitted: zeros, one per observed link.
    assert_eq!(q.w_len(), &[Param::Known(0.0)]);
    assert_eq!(s.links[1].observes, Some(vec![0]));
    assert_eq!(s.param_layout().len, 7 + 7 + 3 + 3);
    assert_eq!(Scene::from_json_str(&s.to_json_string()).unwrap(), s);

    let bad = text.replace(r#""w_len": [0.5], "#, "");
    let e = Scene::from_json_str(&bad).unwrap_err().to_string();
    assert!(e.contains("types.m") && e.contains("w_len"), "{e}");
    let bad = text.replace("[0.5]", "[0.5, 1]");
    let e = Scene::from_json_str(&bad).unwrap_err().to_string();
    assert!(e.contains("types.m.w_rate"), "{e}");
}

/// Peak-to-peak length of link `l` over frames `range`, m.
fn swing(s: &Scene, t: &Trajectory, l: usize, range: std::ops::Range<usize>) -> f64 {
    let [i, j] = [s.links[l].particles[0], s.links[l].particles[1]];
    let lens: Vec<f64> = range.map(|f| (t.pos(f, j) - t.pos(f, i)).norm()).collect();
    lens.iter().cloned().fold(f64::MIN, f64::max) - lens.iter().cloned().fold(f64::MAX, f64::min)
}

#[test]
fn example_neurons_sustain_what_springs_damp() {
    let s = muscle();
    assert_eq!(s.particles.len(), 3);
    assert_eq!(s.links.len(), 2);
    assert!(s.types.iter().all(|t| t.kind == LinkKind::Muscle));
    assert_eq!(
        s.types.iter().map(|t| 2 * t.num_weights()).sum::<usize>(),
        4
    );
    assert_eq!(Scene::from_json_str(&s.to_json_string()).unwrap(), s);

    let n = MUSCLE_FRAMES;
    let active = s.simulate(n).unwrap();
    let mut passive = s.clone();
    for t in &mut passive.types {
        *t = t.clone().with("gain", 0.0);
    }
    let passive = passive.simulate(n).unwrap();
    for l in 0..2 {
        let (a0, a1) = (
            swing(&s, &active, l, 0..50),
            swing(&s, &active, l, n - 100..n),
        );
        let (p0, p1) = (
            swing(&s, &passive, l, 0..50),
            swing(&s, &passive, l, n - 100..n),
        );
        eprintln!("link {l}: active {a0:.4} -> {a1:.4}, passive {p0:.4} -> {p1:.4}");
        assert!(
            a1 > 2.0 * a0,
            "link {l}: the neurons do not grow the motion"
        );
        assert!(a1 > 0.02 && a1 < 0.5, "link {l}: swing {a1} m");
        assert!(
            p1 < 0.2 * p0,
            "link {l}: passive springs do not damp it out"
        );
        assert!(a1 > 20.0 * p1, "link {l}: the neurons barely matter");
    }
    // The neurons keep the motion up to the end: the last two seconds' swings are alike.
    let late = swing(&s, &active, 0, n - 100..n);
    let mid = swing(&s, &active, 0, n - 200..n - 100);
    assert_relative_eq!(late, mid, max_relative = 0.2);
}

/// The cloth (large enough to split its force work in two halves) with three muscles added
/// across it: the split step is bit-identical on 1 and 2 threads and equals the sequential one
/// up to summation order.
#[test]
fn muscles_in_a_split_scene() {
    use cordis_core::{examples, Simulator};
    let mut scene = examples::cloth(32, 32);
    scene.add_type(
        LinkType::new("m", LinkKind::Muscle)
            .with("stiffness", 5.0)
            .with("rest_length", 0.3)
            .with("gain", 0.5)
            .with_weights(&known(&[2.0, -1.0]), &known(&[-0.5, 0.3])),
    );
    for ends in [[100, 400], [500, 800], [300, 900]] {
        scene.add_link("m", &ends);
    }
    let run = |threads: usize, split: bool| {
        let mut plan = Plan::compile(&scene).unwrap();
        assert!(plan.split.is_some(), "large enough to split");
        if !split {
            plan.split = None;
        }
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            Simulator::from_plan(plan, scene.param_values())
                .run(40)
                .unwrap()
        })
    };
    let bits = |t: &Trajectory| t.as_flat().iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    let (one, two, seq) = (run(1, true), run(2, true), run(1, false));
    assert_eq!(bits(&one), bits(&two));
    let scale = seq.scale();
    for (a, b) in one.as_flat().iter().zip(seq.as_flat()) {
        assert!((a - b).abs() <= 1e-9 * scale, "{a} vs {b}");
    }
    // The muscles act: without them the cloth moves differently.
    let plain = examples::cloth(32, 32).simulate(40).unwrap();
    let moved = (0..plain.particles()).any(|i| (plain.pos(39, i) - seq.pos(39, i)).norm() > 1e-6);
    assert!(moved);
}
