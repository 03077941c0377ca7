//! Observed positions as a tracker gives them: a NaN is a missing coordinate (a hidden marker,
//! an empty CSV cell, an absent row), never a value. Estimators that handle gaps read these;
//! everything else takes a complete [`Trajectory`] ([`Observations::into_trajectory`] says
//! where the first gap is).

use crate::error::{CordisError, Result};
use crate::Trajectory;

/// `(frames, particles, 3)` row-major positions, m; NaN where missing.
#[derive(Clone, Debug, PartialEq)]
pub struct Observations {
    frames: usize,
    particles: usize,
    data: Vec<f64>,
    /// Time between frames in s, when the source says.
    pub dt: Option<f64>,
}

impl Observations {
    /// Wraps row-major data; NaN is a missing coordinate, ±inf is refused (naming its place).
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
        if let Some(k) = data.iter().position(|v| v.is_infinite()) {
            let (t, i, c) = (k / (3 * particles), (k / 3) % particles, k % 3);
            return Err(CordisError::trajectory(
                format!("frame {t}, particle {i}, {}", ["x", "y", "z"][c]),
                format!("not a finite number: {}", data[k]),
            ));
        }
        Ok(Observations {
            frames,
            particles,
            data,
            dt: None,
        })
    }

    /// Every coordinate of a complete trajectory.
    pub fn from_trajectory(traj: &Trajectory) -> Self {
        Observations {
            frames: traj.frames(),
            particles: traj.particles(),
            data: traj.as_flat().to_vec(),
            dt: traj.dt,
        }
    }

    pub fn frames(&self) -> usize {
        self.frames
    }

    pub fn particles(&self) -> usize {
        self.particles
    }

    /// Row-major values, NaN where missing.
    pub fn as_flat(&self) -> &[f64] {
        &self.data
    }

    /// Number of missing coordinates.
    pub fn missing(&self) -> usize {
        self.data.iter().filter(|v| v.is_nan()).count()
    }

    /// The complete trajectory, or an error naming the first missing coordinate.
    pub fn into_trajectory(self) -> Result<Trajectory> {
        let dt = self.dt;
        let mut t = Trajectory::from_flat(self.frames, self.particles, self.data)?;
        t.dt = dt;
        Ok(t)
    }
}
