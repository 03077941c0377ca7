//! Stage 5: links with equal parameters grouped into types (the catalogue a person would
//! write). Leader clustering, most precise links first: a link joins the first type whose
//! centre is within tolerance on each of K, l0 and Z, or founds a new type; then every link is
//! assigned again to the nearest centre (centres as precision-weighted means). O(links ×
//! types).
//!
//! Two values a, b (standard errors sa, sb) are "equal" when
//! `|a - b| ≤ rel · max(|a|, |b|, floor) + k · sqrt(sa² + sb²)`: a relative tolerance (the
//! generating model's values are equal, estimates differ by rounding or noise), a floor for
//! values near zero (an absent damping), and `k = 4` standard errors for noisy data.

/// Standard errors allowed between two values of one type.
pub const SIGMAS: f64 = 4.0;

/// One link's estimate: values and standard errors of (K, l0, Z).
#[derive(Clone, Copy, Debug)]
pub struct Estimate {
    pub value: [f64; 3],
    pub se: [f64; 3],
}

/// The catalogue: the type of every link and each type's centre.
pub struct Clusters {
    pub of: Vec<usize>,
    pub centres: Vec<Estimate>,
}

fn close(a: &Estimate, b: &Estimate, rel: f64, floor: &[f64; 3]) -> Option<f64> {
    let mut worst: f64 = 0.0;
    for (c, fl) in floor.iter().enumerate() {
        let (x, y) = (a.value[c], b.value[c]);
        let tol = rel * x.abs().max(y.abs()).max(*fl)
            + SIGMAS * (a.se[c].powi(2) + b.se[c].powi(2)).sqrt();
        let r = (x - y).abs() / tol.max(f64::MIN_POSITIVE);
        if r.is_nan() || r > 1.0 {
            return None;
        }
        worst = worst.max(r);
    }
    Some(worst)
}

fn centre(members: &[&Estimate]) -> Estimate {
    let mut value = [0.0; 3];
    let mut se = [0.0; 3];
    for c in 0..3 {
        // Precision weights, floored so that exact (zero-error) estimates do not divide by 0.
        let scale = members.iter().map(|e| e.value[c].abs()).fold(0.0, f64::max);
        let floor = (1e-12 * scale).max(f64::MIN_POSITIVE);
        let (mut sw, mut swx) = (0.0, 0.0);
        for e in members {
            let w = 1.0 / e.se[c].max(floor).powi(2);
            sw += w;
            swx += w * e.value[c];
        }
        value[c] = swx / sw;
        se[c] = (1.0 / sw).sqrt();
    }
    Estimate { value, se }
}

/// Groups `links` into types; `rel` is the relative tolerance. Types are numbered by their
/// first link.
pub fn cluster(links: &[Estimate], rel: f64) -> Clusters {
    let mut floor = [0.0; 3];
    for (c, f) in floor.iter_mut().enumerate() {
        let mean = links.iter().map(|e| e.value[c].abs()).sum::<f64>() / links.len().max(1) as f64;
        *f = mean;
    }
    let mut order: Vec<usize> = (0..links.len()).collect();
    let rel_se = |e: &Estimate| {
        (0..3)
            .map(|c| e.se[c] / e.value[c].abs().max(floor[c]).max(1e-300))
            .fold(0.0, f64::max)
    };
    order.sort_by(|&a, &b| rel_se(&links[a]).total_cmp(&rel_se(&links[b])));
    let mut centres: Vec<Estimate> = Vec::new();
    for &l in &order {
        if !centres
            .iter()
            .any(|c| close(&links[l], c, rel, &floor).is_some())
        {
            centres.push(links[l]);
        }
    }
    let mut of = vec![0; links.len()];
    for _ in 0..3 {
        for (l, e) in links.iter().enumerate() {
            let best = centres
                .iter()
                .enumerate()
                .filter_map(|(k, c)| close(e, c, rel, &floor).map(|r| (k, r)))
                .min_by(|a, b| a.1.total_cmp(&b.1));
            of[l] = match best {
                Some((k, _)) => k,
                None => {
                    centres.push(*e);
                    centres.len() - 1
                }
            };
        }
        let mut next = Vec::new();
        let mut remap = vec![usize::MAX; centres.len()];
        for l in 0..links.len() {
            let k = of[l];
            if remap[k] == usize::MAX {
                remap[k] = next.len();
                let members: Vec<&Estimate> = (0..links.len())
                    .filter(|&m| of[m] == k)
                    .map(|m| &links[m])
                    .collect();
                next.push(centre(&members));
            }
            of[l] = remap[k];
        }
        centres = next;
    }
    Clusters { of, centres }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn e(k: f64, l: f64, z: f64) -> Estimate {
        Estimate {
            value: [k, l, z],
            se: [1e-9; 3],
        }
    }

    #[test]
    fn groups_equal_values_and_separates_different_ones() {
        let links = [
            e(100.0, 0.5, 0.0),
            e(50.0, 0.5, 0.1),
            e(100.0 + 1e-6, 0.5, 1e-9),
            e(100.0, 0.6, 0.0),
            e(50.0, 0.5, 0.1 + 1e-8),
        ];
        let c = cluster(&links, 1e-3);
        assert_eq!(c.of, vec![0, 1, 0, 2, 1]);
        assert_eq!(c.centres.len(), 3);
    }
}
