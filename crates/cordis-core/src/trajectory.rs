//! Trajectories: positions of every particle at every frame, `(T, N, 3)` row-major.

use crate::error::{CordisError, Result};
use crate::Vec3;

#[derive(Clone, Debug, PartialEq)]
pub struct Trajectory {
    frames: usize,
    particles: usize,
    /// `data[(t * N + i) * 3 + k]` = coordinate k of particle i at frame t, m.
    data: Vec<f64>,
    /// Time between frames in s, when the source says (scene files, `--dt`).
    pub dt: Option<f64>,
}

impl Trajectory {
    /// Wraps row-major `(frames, particles, 3)` data; every value must be finite.
    pub fn from_flat(frames: usize, particles: usize, data: Vec<f64>) -> Result<Self> {
        if data.len() != frames * particles * 3 {
            return Err(CordisError::trajectory(
                "trajectory",
                format!(
                    "{} values do not fill {frames} frames × {particles} particles × 3",
                    data.len()
                ),
            ));
        }
        if let Some(k) = data.iter().position(|v| !v.is_finite()) {
            let (t, i, c) = (k / (3 * particles), (k / 3) % particles, k % 3);
            return Err(CordisError::trajectory(
                format!("frame {t}, particle {i}, {}", ["x", "y", "z"][c]),
                format!("not a finite number: {}", data[k]),
            ));
        }
        Ok(Trajectory {
            frames,
            particles,
            data,
            dt: None,
        })
    }

    /// An all-zero trajectory to fill.
    pub fn zeros(frames: usize, particles: usize) -> Self {
        Trajectory {
            frames,
            particles,
            data: vec![0.0; frames * particles * 3],
            dt: None,
        }
    }

    pub fn with_dt(mut self, dt: f64) -> Self {
        self.dt = Some(dt);
        self
    }

    pub fn frames(&self) -> usize {
        self.frames
    }

    pub fn particles(&self) -> usize {
        self.particles
    }

    /// Row-major `(T, N, 3)` values.
    pub fn as_flat(&self) -> &[f64] {
        &self.data
    }

    pub fn into_flat(self) -> Vec<f64> {
        self.data
    }

    /// Position of particle `i` at frame `t`.
    pub fn pos(&self, t: usize, i: usize) -> Vec3 {
        let k = (t * self.particles + i) * 3;
        Vec3::new(self.data[k], self.data[k + 1], self.data[k + 2])
    }

    /// Positions of frame `t` into `out` (length N).
    pub fn frame_into(&self, t: usize, out: &mut [Vec3]) {
        let row = &self.data[t * self.particles * 3..(t + 1) * self.particles * 3];
        for (o, c) in out.iter_mut().zip(row.chunks_exact(3)) {
            *o = Vec3::new(c[0], c[1], c[2]);
        }
    }

    /// Overwrites frame `t` with `pos` (length N).
    pub fn set_frame(&mut self, t: usize, pos: &[Vec3]) {
        let row = &mut self.data[t * self.particles * 3..(t + 1) * self.particles * 3];
        for (c, p) in row.chunks_exact_mut(3).zip(pos) {
            c.copy_from_slice(p.as_slice());
        }
    }

    /// Checks that the trajectory fits a scene of `n` particles and has at least `min_frames`.
    pub fn check_fits(&self, n: usize, min_frames: usize) -> Result<()> {
        if self.particles != n {
            return Err(CordisError::trajectory(
                "trajectory",
                format!("has {} particles, the scene has {n}", self.particles),
            ));
        }
        if self.frames < min_frames {
            return Err(CordisError::trajectory(
                "trajectory",
                format!(
                    "has {} frames, at least {min_frames} are needed",
                    self.frames
                ),
            ));
        }
        Ok(())
    }

    /// The largest extent of the bounding box over all frames (the motion's scale), m.
    pub fn scale(&self) -> f64 {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for c in self.data.chunks_exact(3) {
            for k in 0..3 {
                lo[k] = lo[k].min(c[k]);
                hi[k] = hi[k].max(c[k]);
            }
        }
        (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max)
    }
}
