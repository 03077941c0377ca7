//! Observations as they come from a tracker: positions with gaps, only some particles tracked,
//! per-marker noise weights.
//!
//! A [`Take`] holds one recording of the object: for every frame and scene particle, three
//! coordinates and a weight each. A weight of 0 is a missing observation (a hidden marker, an
//! untracked particle, a NaN in the file); otherwise it is `1/σ` relative to the others (a
//! marker tracked twice as precisely gets weight 2). Missing values are a mask, never a number:
//! the stored value of a missing coordinate is 0 and is never read.

use cordis_core::{Observations, Trajectory, Vec3};

use crate::error::CostError;

/// One recording: `(frames, particles, 3)` positions (m) with a weight per coordinate.
#[derive(Clone, Debug, PartialEq)]
pub struct Take {
    frames: usize,
    particles: usize,
    /// `values[(t * N + i) * 3 + c]`, m; 0 where missing.
    values: Vec<f64>,
    /// Same layout; 0 = missing, else the coordinate's weight (1/σ relative).
    weights: Vec<f64>,
}

impl Take {
    /// A complete trajectory: every coordinate observed with weight 1.
    pub fn complete(traj: &Trajectory) -> Self {
        Take {
            frames: traj.frames(),
            particles: traj.particles(),
            values: traj.as_flat().to_vec(),
            weights: vec![1.0; traj.as_flat().len()],
        }
    }

    /// Builds a take from row-major `(frames, markers, 3)` data in which NaN marks a missing
    /// coordinate. `markers[m]` is the scene particle that marker `m` tracks (`None`: marker m
    /// is particle m); particles no marker tracks are hidden. `marker_weights[m]` is the
    /// marker's weight (1/σ relative; `None`: all 1), or `marker_weights[3m + c]` its
    /// coordinate c's when three per marker are given. `visible`, when given, is a
    /// `(frames, markers)` mask that hides a marker at a frame whatever its value.
    pub fn from_markers(
        frames: usize,
        data: &[f64],
        particles: usize,
        markers: Option<&[usize]>,
        marker_weights: Option<&[f64]>,
        visible: Option<&[bool]>,
    ) -> Result<Self, CostError> {
        if frames == 0 {
            return Err(CostError::mismatch("trajectory", "has no frame"));
        }
        if data.len() % (3 * frames) != 0 {
            return Err(CostError::mismatch(
                "trajectory",
                format!("{} values do not fill {frames} frames × 3", data.len()),
            ));
        }
        let count = data.len() / (3 * frames);
        let map = marker_particles(count, particles, markers)?;
        let per_coordinate = weights_per_coordinate(count, marker_weights)?;
        if let Some(v) = visible {
            if v.len() != frames * count {
                return Err(CostError::length("visible", frames * count, v.len()));
            }
        }
        let mut values = vec![0.0; frames * particles * 3];
        let mut weights = vec![0.0; frames * particles * 3];
        for t in 0..frames {
            for (m, &p) in map.iter().enumerate() {
                if visible.is_some_and(|v| !v[t * count + m]) {
                    continue;
                }
                for c in 0..3 {
                    let w = match (marker_weights, per_coordinate) {
                        (None, _) => 1.0,
                        (Some(w), false) => w[m],
                        (Some(w), true) => w[3 * m + c],
                    };
                    let x = data[(t * count + m) * 3 + c];
                    if x.is_nan() {
                        continue;
                    }
                    if !x.is_finite() {
                        return Err(CostError::mismatch(
                            format!("frame {t}, marker {m}, {}", ["x", "y", "z"][c]),
                            format!("not a finite number: {x}"),
                        ));
                    }
                    values[(t * particles + p) * 3 + c] = x;
                    weights[(t * particles + p) * 3 + c] = w;
                }
            }
        }
        let take = Take {
            frames,
            particles,
            values,
            weights,
        };
        if take.observed() == 0 {
            return Err(CostError::mismatch(
                "trajectory",
                "every coordinate is missing",
            ));
        }
        Ok(take)
    }

    /// A take from observations read from a file ([`cordis_core::io::read_observations`]):
    /// the file's particle `i` is the scene's particle `i`; particles beyond the file's (and
    /// any whose every coordinate is NaN) are hidden.
    pub fn from_observations(obs: &Observations, particles: usize) -> Result<Self, CostError> {
        if obs.particles() > particles {
            return Err(CostError::mismatch(
                "trajectory",
                format!(
                    "has {} particles but the scene has {particles}",
                    obs.particles()
                ),
            ));
        }
        Take::from_markers(obs.frames(), obs.as_flat(), particles, None, None, None)
    }

    /// Whether some observed coordinate has a weight other than 1.
    pub fn weighted(&self) -> bool {
        self.weights.iter().any(|&w| w != 0.0 && w != 1.0)
    }

    /// The root mean square of the observed coordinates' weights (1 unweighted; 0 when nothing
    /// is observed): a weight-1 noise level over it is the positions' typical noise, m.
    pub fn rms_weight(&self) -> f64 {
        let (sum, count) = self
            .weights
            .iter()
            .filter(|w| **w > 0.0)
            .fold((0.0, 0usize), |(s, n), w| (s + w * w, n + 1));
        match count {
            0 => 0.0,
            n => (sum / n as f64).sqrt(),
        }
    }

    pub fn frames(&self) -> usize {
        self.frames
    }

    pub fn particles(&self) -> usize {
        self.particles
    }

    /// Number of observed coordinates.
    pub fn observed(&self) -> usize {
        self.weights.iter().filter(|w| **w > 0.0).count()
    }

    /// Coordinate `c` of particle `i` at frame `t` and its weight (0: missing).
    #[inline]
    pub fn at(&self, t: usize, i: usize, c: usize) -> (f64, f64) {
        let k = (t * self.particles + i) * 3 + c;
        (self.values[k], self.weights[k])
    }

    /// The weight of coordinate `k` of the flat layout (0: missing).
    pub(crate) fn weight_at(&self, k: usize) -> f64 {
        self.weights[k]
    }

    /// The positions of frame `t` (m), NaN where a coordinate is missing.
    pub fn positions(&self, t: usize) -> Vec<Vec3> {
        (0..self.particles)
            .map(|i| {
                Vec3::from_fn(|c, _| match self.at(t, i, c) {
                    (y, w) if w > 0.0 => y,
                    _ => f64::NAN,
                })
            })
            .collect()
    }

    /// Whether particle `i` is observed at some frame (any coordinate).
    pub fn tracks(&self, i: usize) -> bool {
        (0..self.frames).any(|t| (0..3).any(|c| self.at(t, i, c).1 > 0.0))
    }

    /// The take with every weight multiplied by `mult` (same layout; a robust loss's
    /// multipliers, [`super::loss`]).
    pub fn reweighted(&self, mult: &[f64]) -> Take {
        let mut out = self.clone();
        for (w, m) in out.weights.iter_mut().zip(mult) {
            *w *= m;
        }
        out
    }

    /// The take truncated to its first `frames` frames.
    pub fn head(&self, frames: usize) -> Take {
        let frames = frames.min(self.frames);
        let len = frames * self.particles * 3;
        Take {
            frames,
            particles: self.particles,
            values: self.values[..len].to_vec(),
            weights: self.weights[..len].to_vec(),
        }
    }

    /// Frames `from..to` of the take (clamped to its length), renumbered from 0.
    pub fn frame_range(&self, from: usize, to: usize) -> Take {
        let to = to.min(self.frames);
        let from = from.min(to);
        let row = self.particles * 3;
        Take {
            frames: to - from,
            particles: self.particles,
            values: self.values[from * row..to * row].to_vec(),
            weights: self.weights[from * row..to * row].to_vec(),
        }
    }

    /// The take with coordinates hidden where `keep(t, i, c)` is false.
    pub fn masked(&self, keep: impl Fn(usize, usize, usize) -> bool) -> Take {
        let mut out = self.clone();
        for t in 0..self.frames {
            for i in 0..self.particles {
                for c in 0..3 {
                    if !keep(t, i, c) {
                        let k = (t * self.particles + i) * 3 + c;
                        out.values[k] = 0.0;
                        out.weights[k] = 0.0;
                    }
                }
            }
        }
        out
    }

    /// A complete trajectory for the short-cost start: every gap of a tracked coordinate filled
    /// by linear interpolation between its neighbouring observations (held constant before the
    /// first and after the last), untracked particles at `fallback` (their scene position).
    pub fn filled(&self, fallback: &[Vec3]) -> Trajectory {
        let (frames, n) = (self.frames, self.particles);
        let mut data = vec![0.0; frames * n * 3];
        for i in 0..n {
            for c in 0..3 {
                let seen: Vec<usize> = (0..frames).filter(|&t| self.at(t, i, c).1 > 0.0).collect();
                for t in 0..frames {
                    data[(t * n + i) * 3 + c] = match seen.binary_search(&t) {
                        _ if seen.is_empty() => fallback[i][c],
                        Ok(_) => self.at(t, i, c).0,
                        Err(0) => self.at(seen[0], i, c).0,
                        Err(k) if k == seen.len() => self.at(seen[k - 1], i, c).0,
                        Err(k) => {
                            let (a, b) = (seen[k - 1], seen[k]);
                            let s = (t - a) as f64 / (b - a) as f64;
                            (1.0 - s) * self.at(a, i, c).0 + s * self.at(b, i, c).0
                        }
                    };
                }
            }
        }
        Trajectory::from_flat(frames, n, data).unwrap_or_else(|_| Trajectory::zeros(frames, n))
    }
}

/// The scene particle each of `count` markers tracks (`markers`, or marker m as particle m),
/// refused when the mapping does not fit the markers or names a particle that does not exist
/// or twice.
fn marker_particles(
    count: usize,
    particles: usize,
    markers: Option<&[usize]>,
) -> Result<Vec<usize>, CostError> {
    let map: Vec<usize> = match markers {
        Some(m) if m.len() != count => {
            return Err(CostError::mismatch(
                "markers",
                format!(
                    "names {} particles for the {count} markers of the trajectory",
                    m.len()
                ),
            ))
        }
        Some(m) => m.to_vec(),
        None if count > particles => {
            return Err(CostError::mismatch(
                "trajectory",
                format!(
                    "has {count} markers but the scene has {particles} particles \
                     (pass a marker → particle mapping)"
                ),
            ))
        }
        None => (0..count).collect(),
    };
    let mut owner = vec![usize::MAX; particles];
    for (m, &p) in map.iter().enumerate() {
        if p >= particles {
            return Err(CostError::mismatch(
                format!("markers[{m}]"),
                format!("particle {p} does not exist (the scene has {particles})"),
            ));
        }
        if owner[p] != usize::MAX {
            return Err(CostError::mismatch(
                format!("markers[{m}]"),
                format!("particle {p} is already tracked by marker {}", owner[p]),
            ));
        }
        owner[p] = m;
    }
    Ok(map)
}

/// Whether `marker_weights` gives three weights per marker (x, y, z) rather than one, refused
/// when it holds neither count or a weight that is not positive and finite.
fn weights_per_coordinate(count: usize, marker_weights: Option<&[f64]>) -> Result<bool, CostError> {
    let per_coordinate = match marker_weights {
        Some(w) if w.len() == 3 * count && count > 0 && w.len() != count => true,
        Some(w) if w.len() != count => {
            return Err(CostError::mismatch(
                "weights",
                format!(
                    "holds {} values for {count} markers: give one per marker or three \
                     (x, y, z)",
                    w.len()
                ),
            ))
        }
        _ => false,
    };
    if let Some((m, why)) = marker_weights.and_then(cordis_core::arg::bad_weight) {
        return Err(CostError::mismatch(format!("weights[{m}]"), why));
    }
    Ok(per_coordinate)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nan_is_a_missing_coordinate_not_a_value() {
        let data = [0.0, 1.0, 2.0, f64::NAN, 4.0, 5.0];
        let take = Take::from_markers(2, &data, 1, None, None, None).unwrap();
        assert_eq!(take.observed(), 5);
        assert_eq!(take.at(1, 0, 0), (0.0, 0.0));
        assert_eq!(take.at(1, 0, 1), (4.0, 1.0));
    }

    #[test]
    fn a_marker_on_a_missing_or_taken_particle_is_refused_by_name() {
        let data = [0.0; 6];
        let e = Take::from_markers(1, &data, 3, Some(&[0, 5]), None, None).unwrap_err();
        assert!(e.to_string().starts_with("markers[1]: particle 5"), "{e}");
        let e = Take::from_markers(1, &data, 3, Some(&[2, 2]), None, None).unwrap_err();
        assert!(e.to_string().contains("already tracked by marker 0"), "{e}");
    }

    #[test]
    fn bad_weights_and_empty_data_are_refused() {
        let data = [0.0; 3];
        for w in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let e = Take::from_markers(1, &data, 1, None, Some(&[w]), None).unwrap_err();
            assert!(e.to_string().starts_with("weights[0]"), "{e}");
        }
        let e = Take::from_markers(1, &[f64::NAN; 3], 1, None, None, None).unwrap_err();
        assert!(e.to_string().contains("every coordinate is missing"), "{e}");
    }

    #[test]
    fn gaps_are_interpolated_for_the_start_only() {
        let data = [0.0, 0.0, 0.0, f64::NAN, 0.0, 0.0, 2.0, 0.0, 0.0];
        let take = Take::from_markers(3, &data, 2, None, None, None).unwrap();
        let f = take.filled(&[Vec3::zeros(), Vec3::new(7.0, 7.0, 7.0)]);
        assert_eq!(f.pos(1, 0)[0], 1.0);
        assert_eq!(f.pos(2, 1)[1], 7.0);
    }
}
