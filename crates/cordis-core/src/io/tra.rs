//! The thesis' `.tra` trajectories (Annexe 1):
//!
//! ```text
//! Nombre de particules:3
//! Nombre de pas de temps:10
//! Points de l'image 1
//! 1.1111 1.1111 1.1111
//! …                        (N lines `x y z`, then the next `Points de l'image K`)
//! ```
//!
//! Read as tokens (line breaks and spacing are free, as the thesis' own printed example
//! shows), strictly on counts: exactly T frames of exactly N points. Frame numbers `K` count
//! up by one from 0 or 1 (the thesis starts at 1).

use std::fmt::Write;

use super::tokens::Cursor;
use crate::error::{CordisError, Result};
use crate::Trajectory;

fn mk(place: String, message: String) -> CordisError {
    CordisError::trajectory(place, message)
}

/// Parses `.tra` text; `name` (usually the file name) starts every error's place.
pub fn parse_tra(name: &str, text: &str) -> Result<Trajectory> {
    let mut c = Cursor::new(name, text, mk);
    if c.at_end() {
        return Err(mk(
            name.into(),
            "empty file: expected `Nombre de particules:N`".into(),
        ));
    }
    c.expect_label("nombre de particules", "Nombre de particules:N")?;
    let n = c.index(|| "the particle count".into())?;
    c.expect_label("nombre de pas de temps", "Nombre de pas de temps:T")?;
    let t = c.index(|| "the frame count".into())?;
    if n == 0 || t == 0 {
        return Err(c.error_here(format!(
            "{n} particles × {t} frames: a trajectory needs at least one of each"
        )));
    }
    let Some(total) = n.checked_mul(t).and_then(|v| v.checked_mul(3)) else {
        return Err(c.error_here(format!("{n} particles × {t} frames is too large")));
    };
    let mut data = Vec::with_capacity(total.min(c.remaining()));
    let mut base = 0;
    for f in 0..t {
        let line = c
            .expect_label("points de l'image", "Points de l'image K")
            .map_err(|e| {
                if c.at_end() {
                    mk(
                        c.here(),
                        format!("the file ends after {f} frames; the header says {t}"),
                    )
                } else {
                    e
                }
            })?;
        let k = c.index(|| format!("the number K of frame {}", f + 1))?;
        if f == 0 {
            if k > 1 {
                return Err(c.error(
                    line,
                    format!("the first frame is numbered {k}: expected 1 (or 0)"),
                ));
            }
            base = k;
        } else if k != base + f {
            return Err(c.error(
                line,
                format!(
                    "frame numbered {k}, expected {}: frames must follow each other",
                    base + f
                ),
            ));
        }
        for i in 0..n {
            for axis in ["x", "y", "z"] {
                let v = c.number(|| format!("{axis} of point {} (of {n}) in frame {k}", i + 1))?;
                data.push(v);
            }
        }
    }
    c.expect_end(&format!(
        "the last frame (the header says {t} frames of {n} points)"
    ))?;
    Trajectory::from_flat(t, n, data)
}

/// `.tra` text of a trajectory, frames numbered from 1 as in the thesis. Values are printed in
/// shortest round-trip form, so reading back is bit-exact.
pub fn write_tra(traj: &Trajectory) -> String {
    let n = traj.particles();
    let mut out = String::with_capacity(64 + traj.as_flat().len() * 24);
    let _ = writeln!(out, "Nombre de particules:{n}");
    let _ = writeln!(out, "Nombre de pas de temps:{}", traj.frames());
    for (f, frame) in traj.as_flat().chunks_exact(3 * n.max(1)).enumerate() {
        let _ = writeln!(out, "Points de l'image {}", f + 1);
        for c in frame.chunks_exact(3) {
            let _ = writeln!(out, "{:?} {:?} {:?}", c[0], c[1], c[2]);
        }
    }
    out
}
