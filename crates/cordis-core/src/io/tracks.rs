//! Video-tracker output in `.npz` (NumPy's zip of `.npy` arrays), as TAP-Vid and CoTracker
//! save it: point tracks and their visibility.
//!
//! - `tracks` (or `points`, `pred_tracks`): `(N, T, 2|3)` — TAP-Vid's layout, N points over
//!   T frames — or `(1, T, N, 2|3)` — CoTracker's batched `pred_tracks`.
//! - `visibility` (or `visibles`, `visible`, `pred_visibility`): `(N, T)` or `(1, T, N)`,
//!   boolean or numeric (visible when ≥ 0.5); or TAP-Vid's `occluded`, its negation.
//!   Without one, every point whose coordinates are not NaN is visible.
//!
//! A point that is not visible is a missing observation (NaN), never its stored (often
//! extrapolated) position. 2-D tracks are planar: z = 0. Coordinates are taken as they are
//! (a video tracker's are pixels: `--units` scales m/cm/mm only); the archive gives no rate.

use std::io::Read;

use super::markers::{Imported, InputFormat};
use super::npy::{parse_npy_array, NpyArray};
use crate::error::{printable, CordisError, Result};
use crate::Observations;

const TRACK_KEYS: &[&str] = &["tracks", "points", "pred_tracks"];
const VISIBLE_KEYS: &[&str] = &["visibility", "visibles", "visible", "pred_visibility"];
const OCCLUDED_KEY: &str = "occluded";

/// No array of an archive is read beyond this many bytes (a zip bomb must not fill memory).
const MAX_ENTRY_BYTES: u64 = 4 << 30;

/// Parses `.npz` bytes (module docs); `name` starts every error's place.
pub(crate) fn parse_npz(name: &str, bytes: &[u8]) -> Result<Imported> {
    let mut archive = Archive::open(name, bytes)?;
    let Some(tracks_entry) = archive.find(TRACK_KEYS) else {
        return Err(CordisError::format(
            name,
            format!(
                "no `tracks` array (nor `points`, `pred_tracks`); the archive holds: {}",
                printable(
                    &archive
                        .entries
                        .iter()
                        .map(|e| key_of(e))
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            ),
        ));
    };
    let tracks = archive.read(&tracks_entry)?;
    let (visibility_entry, occluded) = match archive.find(VISIBLE_KEYS) {
        Some(e) => (Some(e), false),
        None => (archive.find(&[OCCLUDED_KEY]), true),
    };
    let visibility = visibility_entry
        .as_deref()
        .map(|e| archive.read(e))
        .transpose()?;
    let layout = Layout::of(&format!("{name}[{}]", key_of(&tracks_entry)), &tracks)?;
    let visible = match (&visibility, &visibility_entry) {
        (Some(v), Some(entry)) => {
            Some(layout.visible(&format!("{name}[{}]", key_of(entry)), &tracks, v, occluded)?)
        }
        _ => None,
    };
    let (data, hidden) = layout.points(&tracks, visible.as_deref());
    let Layout {
        n,
        t,
        dims,
        batched,
    } = layout;
    let observations = Observations::from_flat(t, n, data)
        .map_err(|e| CordisError::trajectory(name, e.to_string()))?;
    let layout = if batched {
        "CoTracker (1, frames, points, D)"
    } else {
        "TAP-Vid (points, frames, D)"
    };
    let vis = match (&visibility_entry, occluded) {
        (None, _) => "no visibility array: every finite point visible".to_string(),
        (Some(e), false) => format!("visibility from `{}`", key_of(e)),
        (Some(e), true) => format!("visibility = not `{}`", key_of(e)),
    };
    let mapping = format!(
        "{layout} from `{}`; {n} points × {t} frames, {dims}-D{}; {vis}; {hidden} hidden points → NaN; \
         coordinates as stored (no rate in the file)",
        key_of(&tracks_entry),
        if dims == 2 { " (planar: z = 0)" } else { "" },
    );
    Ok(Imported {
        observations,
        format: InputFormat::Npz,
        labels: (0..n).map(|i| i.to_string()).collect(),
        mapping,
    })
}

/// An entry's array name: the entry without its `.npy`.
fn key_of(entry: &str) -> String {
    entry.strip_suffix(".npy").unwrap_or(entry).to_string()
}

/// The zip archive of a `.npz` and its entries' names.
struct Archive<'a> {
    name: &'a str,
    zip: zip::ZipArchive<std::io::Cursor<&'a [u8]>>,
    entries: Vec<String>,
}

impl<'a> Archive<'a> {
    fn open(name: &'a str, bytes: &'a [u8]) -> Result<Self> {
        let zip = zip::ZipArchive::new(std::io::Cursor::new(bytes)).map_err(|e| {
            CordisError::format(name, format!("not a .npz file (a zip archive): {e}"))
        })?;
        let entries = zip.file_names().map(str::to_string).collect();
        Ok(Archive { name, zip, entries })
    }

    /// The first of `keys` (in their order) that names an entry.
    fn find(&self, keys: &[&str]) -> Option<String> {
        keys.iter()
            .find_map(|k| self.entries.iter().find(|e| key_of(e) == *k).cloned())
    }

    /// An entry's array, inflated to at most [`MAX_ENTRY_BYTES`].
    fn read(&mut self, entry: &str) -> Result<NpyArray> {
        let place = format!("{}[{}]", self.name, key_of(entry));
        let mut file = self
            .zip
            .by_name(entry)
            .map_err(|e| CordisError::format(&place, format!("cannot be read: {e}")))?;
        let mut data = Vec::new();
        (&mut file)
            .take(MAX_ENTRY_BYTES + 1)
            .read_to_end(&mut data)
            .map_err(|e| CordisError::format(&place, format!("cannot be read: {e}")))?;
        if data.len() as u64 > MAX_ENTRY_BYTES {
            return Err(CordisError::format(
                &place,
                format!("larger than {MAX_ENTRY_BYTES} bytes once inflated"),
            ));
        }
        parse_npy_array(&place, &data)
    }
}

/// The tracks' layout: `n` points over `t` frames in `dims` (2 or 3) coordinates, TAP-Vid's
/// `(N, T, D)` or CoTracker's batched `(1, T, N, D)`.
struct Layout {
    n: usize,
    t: usize,
    dims: usize,
    batched: bool,
}

impl Layout {
    /// The layout of `tracks` (`place` names it in errors); at least one point and one frame.
    fn of(place: &str, tracks: &NpyArray) -> Result<Layout> {
        // (N, T, D) with index (i, t, d), or (1, T, N, D) with index (0, t, i, d).
        let (n, t, dims, batched) = match tracks.shape[..] {
            [n, t, d] if d == 2 || d == 3 => (n, t, d, false),
            [1, t, n, d] if d == 2 || d == 3 => (n, t, d, true),
            _ => {
                return Err(CordisError::format(
                    place,
                    format!(
                        "shape {:?} is not (points, frames, 2|3) nor (1, frames, points, 2|3)",
                        tracks.shape
                    ),
                ))
            }
        };
        if n == 0 || t == 0 {
            return Err(CordisError::format(
                place,
                format!("shape {:?} holds no point or no frame", tracks.shape),
            ));
        }
        Ok(Layout {
            n,
            t,
            dims,
            batched,
        })
    }

    /// Index of point `i` at frame `f` in a per-point array of this layout.
    fn at(&self, i: usize, f: usize) -> usize {
        if self.batched {
            f * self.n + i
        } else {
            i * self.t + f
        }
    }

    /// Whether each point is visible at each frame (frame-major), from a visibility array of
    /// the matching shape (`(N, T)` or `(1, T, N)`; visible when ≥ 0.5, or < 0.5 when it is
    /// `occluded`).
    fn visible(
        &self,
        place: &str,
        tracks: &NpyArray,
        v: &NpyArray,
        occluded: bool,
    ) -> Result<Vec<bool>> {
        let (n, t) = (self.n, self.t);
        let expected: Vec<usize> = if self.batched {
            vec![1, t, n]
        } else {
            vec![n, t]
        };
        if v.shape != expected {
            return Err(CordisError::format(
                place,
                format!(
                    "shape {:?} does not match the tracks' {:?} (expected {expected:?})",
                    v.shape, tracks.shape
                ),
            ));
        }
        Ok((0..t)
            .flat_map(|f| (0..n).map(move |i| (i, f)))
            .map(|(i, f)| (v.values[self.at(i, f)] >= 0.5) != occluded)
            .collect())
    }

    /// The points frame-major (z = 0 for 2-D tracks), NaN where a point is not visible or not
    /// finite, and how many points are hidden so.
    fn points(&self, tracks: &NpyArray, visible: Option<&[bool]>) -> (Vec<f64>, usize) {
        let (n, t, dims) = (self.n, self.t, self.dims);
        let track_at = |i: usize, f: usize, d: usize| tracks.values[self.at(i, f) * dims + d];
        let mut data = Vec::with_capacity(t * n * 3);
        let mut hidden = 0usize;
        for f in 0..t {
            for i in 0..n {
                let p = [
                    track_at(i, f, 0),
                    track_at(i, f, 1),
                    if dims == 3 { track_at(i, f, 2) } else { 0.0 },
                ];
                let seen = visible.is_none_or(|v| v[f * n + i]);
                if !seen || p.iter().any(|v| !v.is_finite()) {
                    hidden += 1;
                    data.extend_from_slice(&[f64::NAN; 3]);
                } else {
                    data.extend_from_slice(&p);
                }
            }
        }
        (data, hidden)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use std::io::Write;

    /// `.npy` bytes of `values` with `shape` and dtype `descr` (`<f4`, `|b1`).
    pub(crate) fn npy(descr: &str, shape: &[usize], values: &[f64]) -> Vec<u8> {
        let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
        let shape = if dims.len() == 1 {
            format!("({},)", dims[0])
        } else {
            format!("({})", dims.join(", "))
        };
        let header =
            format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}\n");
        let mut out = b"\x93NUMPY\x01\x00".to_vec();
        out.extend_from_slice(&(header.len() as u16).to_le_bytes());
        out.extend_from_slice(header.as_bytes());
        for &v in values {
            match descr {
                "<f4" => out.extend_from_slice(&(v as f32).to_le_bytes()),
                "|b1" => out.push(u8::from(v != 0.0)),
                _ => out.extend_from_slice(&v.to_le_bytes()),
            }
        }
        out
    }

    pub(crate) fn npz(entries: &[(&str, Vec<u8>)], deflate: bool) -> Vec<u8> {
        let mut zip = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
        let method = if deflate {
            zip::CompressionMethod::Deflated
        } else {
            zip::CompressionMethod::Stored
        };
        let options = zip::write::SimpleFileOptions::default().compression_method(method);
        for (name, bytes) in entries {
            zip.start_file(*name, options).unwrap();
            zip.write_all(bytes).unwrap();
        }
        zip.finish().unwrap().into_inner()
    }

    #[test]
    fn tap_vid_tracks_with_visibility_become_planar_observations() {
        // 2 points × 3 frames, 2-D; point 1 hidden at frame 2.
        let tracks = [
            0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 10.0, 11.0, 12.0, 13.0, 99.0, 99.0,
        ];
        let visible = [1.0, 1.0, 1.0, 1.0, 1.0, 0.0];
        for deflate in [false, true] {
            let bytes = npz(
                &[
                    ("tracks.npy", npy("<f4", &[2, 3, 2], &tracks)),
                    ("visibility.npy", npy("|b1", &[2, 3], &visible)),
                ],
                deflate,
            );
            let im = parse_npz("v.npz", &bytes).unwrap();
            let o = &im.observations;
            assert_eq!((o.frames(), o.particles()), (3, 2));
            let v = o.as_flat();
            // Frame 1: point 0 at (2, 3), point 1 at (12, 13).
            assert_eq!(&v[6..12], &[2.0, 3.0, 0.0, 12.0, 13.0, 0.0]);
            assert!(v[15..18].iter().all(|x| x.is_nan()), "hidden → NaN, not 99");
            assert_eq!(o.missing(), 3);
            assert!(im.mapping.contains("planar"), "{}", im.mapping);
        }
    }

    #[test]
    fn cotracker_batches_and_tapvid_occlusion_are_read() {
        // (1, T=2, N=1, 3) and occluded (1, 2, 1)... CoTracker names it pred_visibility.
        let bytes = npz(
            &[
                (
                    "pred_tracks.npy",
                    npy("<f8", &[1, 2, 1, 3], &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]),
                ),
                ("pred_visibility.npy", npy("|b1", &[1, 2, 1], &[0.0, 1.0])),
            ],
            false,
        );
        let im = parse_npz("c.npz", &bytes).unwrap();
        let v = im.observations.as_flat();
        assert!(v[..3].iter().all(|x| x.is_nan()));
        assert_eq!(&v[3..], &[4.0, 5.0, 6.0]);
        let bytes = npz(
            &[
                ("points.npy", npy("<f4", &[1, 2, 2], &[1.0, 2.0, 3.0, 4.0])),
                ("occluded.npy", npy("|b1", &[1, 2], &[1.0, 0.0])),
            ],
            true,
        );
        let v = parse_npz("t.npz", &bytes).unwrap().observations;
        assert!(v.as_flat()[0].is_nan());
        assert_eq!(&v.as_flat()[3..], &[3.0, 4.0, 0.0]);
    }

    #[test]
    fn bad_archives_name_the_array() {
        let e = parse_npz("x.npz", b"not a zip").unwrap_err().to_string();
        assert!(e.starts_with("x.npz: not a .npz file"), "{e}");
        let bytes = npz(&[("other.npy", npy("<f8", &[1], &[1.0]))], false);
        let e = parse_npz("x.npz", &bytes).unwrap_err().to_string();
        assert!(
            e.contains("no `tracks` array") && e.contains("holds: other"),
            "{e}"
        );
        let bytes = npz(
            &[
                ("tracks.npy", npy("<f8", &[1, 2, 2], &[1.0; 4])),
                ("visibility.npy", npy("|b1", &[2, 1], &[1.0; 2])),
            ],
            false,
        );
        let e = parse_npz("x.npz", &bytes).unwrap_err().to_string();
        assert!(
            e.starts_with("x.npz[visibility]: shape [2, 1] does not match"),
            "{e}"
        );
        let bytes = npz(&[("tracks.npy", npy("<f8", &[2, 2], &[1.0; 4]))], false);
        let e = parse_npz("x.npz", &bytes).unwrap_err().to_string();
        assert!(e.starts_with("x.npz[tracks]: shape [2, 2] is not"), "{e}");
    }
}
