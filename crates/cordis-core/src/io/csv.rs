//! CSV trajectories: header `frame,particle,x,y,z`, one row per particle per frame, in any
//! order. Frames `0..T` and particles `0..N` must each appear exactly once per pair.
//!
//! Read as [`Observations`] ([`parse_csv_observations`]), a tracker's export may have gaps: an
//! empty coordinate cell (or `nan`) is a missing coordinate, and an absent row a missing
//! marker at that frame (every coordinate NaN); a pair given twice is still an error.

use std::fmt::Write;

use crate::error::{CordisError, Result};
use crate::{Observations, Trajectory};

const HEADER: [&str; 5] = ["frame", "particle", "x", "y", "z"];

struct Row {
    frame: u64,
    particle: u64,
    line: usize,
    pos: [f64; 3],
}

/// Parses CSV text; `name` (usually the file name) starts every error's place, as `name:LINE`.
/// Blank lines are skipped; fields may carry surrounding whitespace.
pub fn parse_csv(name: &str, text: &str) -> Result<Trajectory> {
    let (frames, n, data) = parse_rows(name, text, false)?;
    Trajectory::from_flat(frames, n, data)
}

/// Parses CSV text with gaps (module docs): empty cells and `nan` are missing coordinates,
/// absent rows missing markers.
pub fn parse_csv_observations(name: &str, text: &str) -> Result<Observations> {
    let (frames, n, data) = parse_rows(name, text, true)?;
    Observations::from_flat(frames, n, data)
}

/// Rows with gaps may leave a table at most this many times larger than the rows given:
/// beyond it an index is surely a mistake, and the table would be allocated for nothing.
const SPARSE_LIMIT: u64 = 64;

/// `(frames, particles, values)`; with `gaps`, missing cells and rows are NaN.
fn parse_rows(name: &str, text: &str, gaps: bool) -> Result<(usize, usize, Vec<f64>)> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(k, l)| (k + 1, l))
        .filter(|(_, l)| !l.trim().is_empty());
    let Some((hline, header)) = lines.next() else {
        return Err(CordisError::trajectory(
            name,
            "empty file: expected the header `frame,particle,x,y,z`",
        ));
    };
    let fields: Vec<&str> = header.split(',').map(str::trim).collect();
    if fields != HEADER {
        return Err(CordisError::trajectory(
            format!("{name}:{hline}"),
            format!(
                "wrong header `{}`: expected `frame,particle,x,y,z`",
                header.trim()
            ),
        ));
    }
    let mut rows = Vec::new();
    for (line, text) in lines {
        let place = || format!("{name}:{line}");
        let fields: Vec<&str> = text.split(',').map(str::trim).collect();
        if fields.len() != 5 {
            return Err(CordisError::trajectory(
                place(),
                format!(
                    "{} row: {} fields, expected 5 (frame,particle,x,y,z)",
                    if fields.len() < 5 { "short" } else { "long" },
                    fields.len()
                ),
            ));
        }
        let frame =
            parse_index(fields[0], "frame").map_err(|m| CordisError::trajectory(place(), m))?;
        let particle =
            parse_index(fields[1], "particle").map_err(|m| CordisError::trajectory(place(), m))?;
        let mut pos = [0.0; 3];
        for k in 0..3 {
            let f = fields[2 + k];
            pos[k] = if gaps && (f.is_empty() || f.eq_ignore_ascii_case("nan")) {
                f64::NAN
            } else {
                parse_coord(f, HEADER[2 + k]).map_err(|m| CordisError::trajectory(place(), m))?
            };
        }
        rows.push(Row {
            frame,
            particle,
            line,
            pos,
        });
    }
    if rows.is_empty() {
        return Err(CordisError::trajectory(
            name,
            "no rows after the header: a trajectory needs at least one frame",
        ));
    }
    rows.sort_by_key(|r| (r.frame, r.particle, r.line));
    // Indices are checked against the sorted sequence (0,0), (0,1)… rather than used to size a
    // table, so that a huge index costs nothing before it is reported as a gap.
    let n = rows.iter().map(|r| r.particle).max().unwrap_or(0) + 1;
    if gaps {
        // Frames counted from the smallest, as the other tables' frame column: a take cropped
        // from a longer one (its frames 100–199) read as 100 empty frames before its own.
        // Messages keep the file's own frame numbers.
        let first = rows[0].frame;
        let frames = rows.last().map_or(0, |r| r.frame) - first + 1;
        return fill_gaps(name, &rows, first, frames, n);
    }
    let frames = rows.last().map_or(0, |r| r.frame) + 1;
    let mut expect = (0u64, 0u64);
    for (k, r) in rows.iter().enumerate() {
        check_unique(name, &rows, k)?;
        if (r.frame, r.particle) != expect {
            return Err(missing(name, expect));
        }
        expect = if expect.1 + 1 == n {
            (expect.0 + 1, 0)
        } else {
            (expect.0, expect.1 + 1)
        };
    }
    if expect != (frames, 0) {
        return Err(missing(name, expect));
    }
    let data = rows.iter().flat_map(|r| r.pos).collect();
    // Both counts fit in usize: their product is the number of rows held in memory.
    Ok((frames as usize, n as usize, data))
}

/// The table of sorted `rows` from frame `first` on, NaN where a row is absent; duplicates
/// refused.
fn fill_gaps(
    name: &str,
    rows: &[Row],
    first: u64,
    frames: u64,
    n: u64,
) -> Result<(usize, usize, Vec<f64>)> {
    let cells = frames
        .checked_mul(n)
        .filter(|&c| c <= SPARSE_LIMIT.saturating_mul(rows.len() as u64).max(1 << 20));
    let Some(cells) = cells else {
        let r = rows
            .iter()
            .max_by_key(|r| r.frame.max(r.particle))
            .expect("rows");
        return Err(CordisError::trajectory(
            format!("{name}:{}", r.line),
            format!(
                "frame {} / particle {} leaves the {frames} × {n} table almost empty \
                 ({} rows): an index is wrong",
                r.frame,
                r.particle,
                rows.len()
            ),
        ));
    };
    let mut data = vec![f64::NAN; cells as usize * 3];
    for (k, r) in rows.iter().enumerate() {
        check_unique(name, rows, k)?;
        let at = (((r.frame - first) * n + r.particle) * 3) as usize;
        data[at..at + 3].copy_from_slice(&r.pos);
    }
    Ok((frames as usize, n as usize, data))
}

/// Row `k` of the sorted rows names another `(frame, particle)` than the row before it.
fn check_unique(name: &str, rows: &[Row], k: usize) -> Result<()> {
    let r = &rows[k];
    if k > 0 && (rows[k - 1].frame, rows[k - 1].particle) == (r.frame, r.particle) {
        return Err(CordisError::trajectory(
            format!("{name}:{}", r.line),
            format!(
                "duplicate row for frame {}, particle {} (first given on line {})",
                r.frame,
                r.particle,
                rows[k - 1].line
            ),
        ));
    }
    Ok(())
}

fn missing(name: &str, (frame, particle): (u64, u64)) -> CordisError {
    CordisError::trajectory(
        name,
        format!("no row for frame {frame}, particle {particle}: every frame needs every particle"),
    )
}

/// A frame or particle index: a non-negative integer (`3` or `3.0`).
pub(crate) fn parse_index(field: &str, what: &str) -> std::result::Result<u64, String> {
    if let Ok(v) = field.parse::<u64>() {
        return Ok(v);
    }
    match field.parse::<f64>() {
        Err(_) => Err(format!("{what} index `{field}` is not a number")),
        Ok(v) if !v.is_finite() => Err(format!("{what} index `{field}` is not finite")),
        Ok(v) if v < 0.0 => Err(format!("{what} index {field} is negative")),
        Ok(v) if v.fract() != 0.0 => Err(format!("{what} index {field} is not a whole number")),
        // Beyond 2^53 an f64 no longer holds every integer: such an index is surely a mistake.
        Ok(v) if v > 9.007_199_254_740_992e15 => Err(format!("{what} index {field} is too large")),
        Ok(v) => Ok(v as u64),
    }
}

fn parse_coord(field: &str, what: &str) -> std::result::Result<f64, String> {
    match field.parse::<f64>() {
        // A gap, in a reader that needs complete motion (the observations' reader takes it).
        Err(_) if field.is_empty() => Err(format!(
            "{what} is empty (a gap): this command needs complete motion (`cordis identify` \
             reads gaps)"
        )),
        Ok(v) if v.is_nan() => Err(format!(
            "{what} is {field} (a gap): this command needs complete motion (`cordis identify` \
             reads gaps)"
        )),
        Err(_) => Err(format!("{what} `{field}` is not a number")),
        Ok(v) if !v.is_finite() => Err(format!("{what} is {field}: coordinates must be finite")),
        Ok(v) => Ok(v),
    }
}

/// CSV text of a trajectory, frames in order, particles in order within a frame. Values are
/// printed in Rust's shortest round-trip form, so reading the text back is bit-exact.
pub fn write_csv(traj: &Trajectory) -> String {
    write_csv_values(traj.particles(), traj.as_flat())
}

/// CSV text of row-major `(frames, particles, 3)` values; a NaN (missing) is an empty cell,
/// which [`parse_csv_observations`] reads back as missing.
pub fn write_csv_values(particles: usize, values: &[f64]) -> String {
    let n = particles.max(1);
    let mut out = String::with_capacity(32 + values.len() * 24);
    out.push_str("frame,particle,x,y,z\n");
    for (k, c) in values.chunks_exact(3).enumerate() {
        // Writing to a String cannot fail.
        let _ = write!(out, "{},{}", k / n, k % n);
        for v in c {
            if v.is_nan() {
                out.push(',');
            } else {
                let _ = write!(out, ",{v:?}");
            }
        }
        out.push('\n');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_in_any_order_are_sorted() {
        let text = "frame,particle,x,y,z\n1,0,3,0,0\n0,1,2,0,0\n 0 , 0 , 1 , 0 , 0 \n1,1,4,0,0\n";
        let t = parse_csv("a.csv", text).unwrap();
        assert_eq!((t.frames(), t.particles()), (2, 2));
        let xs: Vec<f64> = (0..2)
            .flat_map(|f| (0..2).map(move |i| (f, i)))
            .map(|(f, i)| t.pos(f, i).x)
            .collect();
        assert_eq!(xs, [1.0, 2.0, 3.0, 4.0]);
    }

    #[test]
    fn observations_count_their_frames_from_the_smallest() {
        let text = "frame,particle,x,y,z\n100,0,1,2,3\n101,0,4,5,6\n102,1,7,8,9\n";
        let o = parse_csv_observations("a.csv", text).unwrap();
        assert_eq!((o.frames(), o.particles()), (3, 2));
        assert_eq!(&o.as_flat()[..3], &[1.0, 2.0, 3.0]);
        assert_eq!(o.missing(), 9);
        // Messages keep the file's frame numbers.
        let dup = "frame,particle,x,y,z\n100,0,1,2,3\n103,0,1,2,3\n103,0,1,2,3\n";
        let e = parse_csv_observations("a.csv", dup)
            .unwrap_err()
            .to_string();
        assert!(e.contains("duplicate row for frame 103"), "{e}");
    }

    #[test]
    fn gaps_are_missing_observations_not_errors() {
        let text = "frame,particle,x,y,z\n0,0,1,2,3\n0,1,,5,nan\n1,0,7,8,9\n";
        let o = parse_csv_observations("a.csv", text).unwrap();
        assert_eq!((o.frames(), o.particles()), (2, 2));
        let v = o.as_flat();
        assert_eq!(&v[..3], &[1.0, 2.0, 3.0]);
        assert!(v[3].is_nan() && v[4] == 5.0 && v[5].is_nan());
        assert!(v[9..12].iter().all(|x| x.is_nan()), "absent row");
        assert_eq!(o.missing(), 5);
        // The complete reader still refuses the same text, naming the place.
        assert!(parse_csv("a.csv", text).is_err());
        let e = parse_csv_observations("a.csv", "frame,particle,x,y,z\n0,0,1,2,3\n0,0,1,2,3\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("a.csv:3: duplicate row"), "{e}");
        let e = parse_csv_observations("a.csv", "frame,particle,x,y,z\n0,99999999999,1,2,3\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("an index is wrong"), "{e}");
    }

    #[test]
    fn whole_float_indices_are_accepted() {
        let t = parse_csv("a.csv", "frame,particle,x,y,z\n0.0,0,1,2,3\n").unwrap();
        assert_eq!(t.pos(0, 0).z, 3.0);
    }

    #[test]
    fn a_huge_index_is_a_gap_not_an_allocation() {
        let e = parse_csv(
            "a.csv",
            "frame,particle,x,y,z\n0,0,1,2,3\n0,99999999999,1,2,3\n",
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("no row for frame 0, particle 1"), "{e}");
    }
}
