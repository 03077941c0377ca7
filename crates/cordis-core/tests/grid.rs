//! The cell grid finds exactly the pairs a brute-force O(N²) search finds (SPEC §2.2,
//! `conditional`): every pair closer than the range once, no other pair, for one group and two
//! groups, on 1-D, 2-D and 3-D clouds, clustered or spread, with far-away particles and ranges
//! from tiny to larger than the cloud.

use std::collections::BTreeSet;

use cordis_core::forces::{conditional::ConditionalPass, grid::Grid};
use cordis_core::Vec3;
use proptest::prelude::*;

/// A point cloud: `dims` coordinates used (the others 0), `clusters` centres spread over
/// `spread` m with points within `radius` of a centre, and some points moved `far` m away.
#[derive(Debug, Clone)]
struct Cloud {
    x: Vec<Vec3>,
}

fn cloud() -> impl Strategy<Value = Cloud> {
    (
        1..=3usize,                                               // dims
        1..40usize,                                               // points
        1..6usize,                                                // clusters
        prop_oneof![Just(1e-3), Just(1.0), Just(50.0)],           // spread
        prop_oneof![Just(0.0), Just(1e-4), Just(0.3), Just(5.0)], // cluster radius
        prop_oneof![Just(0.0), Just(1e3), Just(1e9)],             // far distance
        any::<u64>(),
    )
        .prop_map(|(dims, n, k, spread, radius, far, seed)| {
            let mut rng = Rng(seed | 1);
            let centres: Vec<Vec3> = (0..k).map(|_| rng.vec(dims, spread)).collect();
            let x = (0..n)
                .map(|i| {
                    let mut p = centres[i % k] + rng.vec(dims, radius);
                    // About one point in eight flies far away.
                    if far > 0.0 && rng.next() < 0.125 {
                        p += rng.vec(dims, far);
                    }
                    p
                })
                .collect();
            Cloud { x }
        })
}

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn vec(&mut self, dims: usize, h: f64) -> Vec3 {
        let mut v = Vec3::zeros();
        for c in 0..dims {
            v[c] = h * (2.0 * self.next() - 1.0);
        }
        v
    }
}

/// Ranges log-uniform from 1e-300 m (smaller than any gap in the cloud) to 1e12 m (larger
/// than any cloud, far points included).
fn range() -> impl Strategy<Value = f64> {
    prop_oneof![
        (-300.0..-5.0f64).prop_map(|e| 10f64.powf(e)),
        (-5.0..3.0f64).prop_map(|e| 10f64.powf(e)),
        (3.0..12.0f64).prop_map(|e| 10f64.powf(e)),
    ]
}

/// Pairs from the grid, as (i, j) in visiting order; asserts `d = x_j - x_i`.
fn grid_pairs(pass: &ConditionalPass, x: &[Vec3], range: f64) -> Vec<(usize, usize)> {
    let p = [1.0, 0.5, 0.0, range];
    let mut grid = Grid::default();
    let mut out = Vec::new();
    pass.for_each_active_pair(&p, x, &mut grid, |i, j, d| {
        assert_eq!(d, x[j] - x[i]);
        out.push((i, j));
    });
    out
}

fn within(x: &[Vec3], i: usize, j: usize, range: f64) -> bool {
    (x[j] - x[i]).norm() < range
}

/// Splits particle indices: group a, group b (when `two`), and the rest in no group.
fn groups(n: usize, two: bool, seed: u64) -> (Vec<u32>, Vec<u32>) {
    let mut rng = Rng(seed | 1);
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for i in 0..n as u32 {
        let r = rng.next();
        if r < 0.5 || !two && r < 0.85 {
            a.push(i);
        } else if two && r < 0.9 {
            b.push(i);
        }
    }
    (a, b)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn one_group_finds_exactly_the_brute_force_pairs(
        c in cloud(), r in range(), seed in any::<u64>(),
    ) {
        let (a, _) = groups(c.x.len(), false, seed);
        let pass = ConditionalPass { param: 0, quadratic: None, a: a.clone(), b: None };
        let got = grid_pairs(&pass, &c.x, r);
        let set: BTreeSet<(usize, usize)> =
            got.iter().map(|&(i, j)| (i.min(j), i.max(j))).collect();
        prop_assert_eq!(set.len(), got.len(), "a pair was visited twice");
        let mut want = BTreeSet::new();
        for (k, &i) in a.iter().enumerate() {
            for &j in &a[k + 1..] {
                let (i, j) = (i as usize, j as usize);
                if within(&c.x, i, j, r) {
                    want.insert((i.min(j), i.max(j)));
                }
            }
        }
        prop_assert_eq!(set, want);
    }

    #[test]
    fn two_groups_find_exactly_the_brute_force_pairs(
        c in cloud(), r in range(), seed in any::<u64>(),
    ) {
        let (a, b) = groups(c.x.len(), true, seed);
        let pass = ConditionalPass { param: 0, quadratic: None, a: a.clone(), b: Some(b.clone()) };
        let got = grid_pairs(&pass, &c.x, r);
        let set: BTreeSet<(usize, usize)> = got.iter().copied().collect();
        prop_assert_eq!(set.len(), got.len(), "a pair was visited twice");
        let mut want = BTreeSet::new();
        for &i in &a {
            for &j in &b {
                let (i, j) = (i as usize, j as usize);
                if within(&c.x, i, j, r) {
                    want.insert((i, j));
                }
            }
        }
        // The first end is always from the first group.
        prop_assert_eq!(set, want);
    }

    #[test]
    fn a_reused_grid_gives_the_same_pairs(
        c1 in cloud(), c2 in cloud(), r1 in range(), r2 in range(),
    ) {
        // One grid across steps of different clouds and ranges (as the plan reuses scratch).
        let n = c1.x.len().min(c2.x.len());
        let a: Vec<u32> = (0..n as u32).collect();
        let pass = ConditionalPass { param: 0, quadratic: None, a, b: None };
        let mut grid = Grid::default();
        for (x, r) in [(&c1.x[..n], r1), (&c2.x[..n], r2), (&c1.x[..n], r2)] {
            let mut reused = Vec::new();
            pass.for_each_active_pair(&[1.0, 0.5, 0.0, r], x, &mut grid, |i, j, _| {
                reused.push((i, j));
            });
            prop_assert_eq!(reused, grid_pairs(&pass, x, r));
        }
    }
}

#[test]
fn empty_groups_and_single_members_give_no_pairs() {
    let x = vec![Vec3::zeros(); 3];
    for (a, b) in [
        (vec![], None),
        (vec![0], None),
        (vec![], Some(vec![1, 2])),
        (vec![0, 1], Some(vec![])),
    ] {
        let pass = ConditionalPass {
            param: 0,
            quadratic: None,
            a,
            b,
        };
        assert!(grid_pairs(&pass, &x, 1.0).is_empty());
    }
}

#[test]
fn non_finite_positions_give_no_pair_with_them_and_no_panic() {
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let x = vec![Vec3::zeros(), Vec3::new(bad, 0.0, 0.0), Vec3::zeros()];
        for b in [None, Some(vec![2])] {
            let pass = ConditionalPass {
                param: 0,
                quadratic: None,
                a: vec![0, 1],
                b: b.clone(),
            };
            let pairs = grid_pairs(&pass, &x, 1.0);
            assert!(
                pairs.iter().all(|&(i, j)| i != 1 && j != 1),
                "{bad}: {pairs:?}"
            );
        }
    }
}

#[test]
fn coincident_points_are_all_paired() {
    let x = vec![Vec3::new(1.0, 2.0, 3.0); 6];
    let pass = ConditionalPass {
        param: 0,
        quadratic: None,
        a: (0..6).collect(),
        b: None,
    };
    assert_eq!(grid_pairs(&pass, &x, 1e-300).len(), 15);
}

#[test]
fn a_scene_with_a_tiny_range_simulates() {
    // Range 1e-200 m over a 1 m cloud: the grid must neither overflow its cell count nor
    // lose the coincident pair to range² underflowing to 0.
    use cordis_core::{LinkKind, LinkType, Particle, Scene};
    let mut s = Scene::new(0.01);
    s.add_particle(Particle::new(1.0, [0.0; 3]).in_group("g"));
    s.add_particle(Particle::new(1.0, [1.0, 0.0, 0.0]).in_group("g"));
    s.add_particle(Particle::new(1.0, [1.0, 0.0, 0.0]).in_group("g"));
    let mut t = LinkType::new("c", LinkKind::Conditional)
        .with("stiffness", 1.0)
        .with("rest_length", 0.5)
        .with("range", 1e-200);
    t.groups = vec!["g".into()];
    s.add_type(t);
    let traj = s.simulate(10).unwrap();
    // Coincident ends have no direction: the pair is active but its force is 0.
    assert_eq!(traj.pos(9, 1), Vec3::new(1.0, 0.0, 0.0));
}
