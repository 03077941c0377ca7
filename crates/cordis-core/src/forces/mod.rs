//! Force passes, one file per link kind. Each pass holds the instances of its kind grouped in
//! runs of one type, so a kernel reads its type's parameters once per run and its inner loop
//! has no dispatch on kinds or types.

pub mod anchor;
pub mod angle;
pub mod conditional;
pub mod controlled_tgr;
pub mod damper;
pub mod drag;
pub mod force_transmitter;
pub mod grid;
pub mod muscle;
pub mod nonlinear_drag;
pub mod plane;
pub mod provot;
pub mod quadripole;
pub mod spring;
pub mod stateful;
pub mod tgr;

use crate::Vec3;

/// Below this length a link has no direction: `u = 0` (SPEC §2.2), never a NaN.
pub const MIN_LENGTH: f64 = 1e-12;

/// Instances `start..end` of a pass's index array share the type whose parameters start at
/// `param` in the parameter vector.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Run {
    pub param: usize,
    pub start: usize,
    pub end: usize,
}

/// Groups instances by type: returns runs over the returned index array, in catalogue order of
/// the types and file order within a type.
pub(crate) fn runs_by_type<T: Copy>(
    items: &[(usize, T)],
    type_offsets: &[usize],
) -> (Vec<Run>, Vec<T>) {
    let mut order: Vec<usize> = (0..items.len()).collect();
    order.sort_by_key(|&k| items[k].0); // stable: file order within a type
    let mut runs: Vec<Run> = Vec::new();
    let mut out = Vec::with_capacity(items.len());
    for k in order {
        let (t, item) = items[k];
        let param = type_offsets[t];
        match runs.last_mut() {
            Some(r) if r.param == param => r.end += 1,
            _ => runs.push(Run {
                param,
                start: out.len(),
                end: out.len() + 1,
            }),
        }
        out.push(item);
    }
    (runs, out)
}

/// [`runs_by_type`] for kinds whose kernels read their world's time step (a TGR's tendon, its
/// signal's clock): instances keyed by `(type, world)` and grouped by both, so that each run
/// has one `dt`. Returns the runs, each run's world, and the items. With every instance in one
/// world the runs and the order are [`runs_by_type`]'s.
pub(crate) fn runs_by_type_and_world<T: Copy>(
    items: &[((usize, usize), T)],
    type_offsets: &[usize],
) -> (Vec<Run>, Vec<usize>, Vec<T>) {
    let mut order: Vec<usize> = (0..items.len()).collect();
    order.sort_by_key(|&k| items[k].0); // stable: file order within a (type, world)
    let mut runs: Vec<Run> = Vec::new();
    let mut worlds: Vec<usize> = Vec::new();
    let mut out = Vec::with_capacity(items.len());
    let mut last = None;
    for k in order {
        let ((t, w), item) = items[k];
        match runs.last_mut() {
            Some(r) if last == Some((t, w)) => r.end += 1,
            _ => {
                runs.push(Run {
                    param: type_offsets[t],
                    start: out.len(),
                    end: out.len() + 1,
                });
                worlds.push(w);
            }
        }
        last = Some((t, w));
        out.push(item);
    }
    (runs, worlds, out)
}

/// Unit vector and length of `d`, with `u = 0` for a degenerate link.
#[inline(always)]
pub fn unit_and_length(d: &Vec3) -> (Vec3, f64) {
    let l = d.norm();
    let inv = if l >= MIN_LENGTH { 1.0 / l } else { 0.0 };
    (d * inv, l)
}
