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
    let mut archive = zip::ZipArchive::new(std::io::Cursor::new(bytes))
        .map_err(|e| CordisError::format(name, format!("not a .npz file (a zip archive): {e}")))?;
    let entries: Vec<String> = archive.file_names().map(str::to_string).collect();
    let key_of = |entry: &str| entry.strip_suffix(".npy").unwrap_or(entry).to_string();
    let find = |keys: &[&str]| -> Option<String> {
        keys.iter()
            .find_map(|k| entries.iter().find(|e| key_of(e) == *k).cloned())
    };
    let Some(tracks_entry) = find(TRACK_KEYS) else {
        return Err(CordisError::format(
            name,
            format!(
                "no `tracks` array (nor `points`, `pred_tracks`); the archive holds: {}",
                printable(
                    &entries
                        .iter()
                        .map(|e| key_of(e))
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            ),
        ));
    };
    let mut read = |entry: &str| -> Result<NpyArray> {
        let place = format!("{name}[{}]", key_of(entry));
        let mut file = archive
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
    };
    let tracks = read(&tracks_entry)?;
    let (visibility_entry, occluded) = match find(VISIBLE_KEYS) {
        Some(e) => (Some(e), false),
        None => (find(&[OCCLUDED_KEY]), true),
    };
    let visibility = visibility_entry.as_deref().map(&mut read).transpose()?;
    let tplace = format!("{name}[{}]", key_of(&tracks_entry));
    // (N, T, D) with index (i, t, d), or (1, T, N, D) with index (0, t, i, d).
    let (n, t, dims, batched) = match tracks.shape[..] {
        [n, t, d] if d == 2 || d == 3 => (n, t, d, false),
        [1, t, n, d] if d == 2 || d == 3 => (n, t, d, true),
        _ => {
            return Err(CordisError::format(
                &tplace,
                format!(
                    "shape {:?} is not (points, frames, 2|3) nor (1, frames, points, 2|3)",
                    tracks.shape
                ),
            ))
        }
    };
    if n == 0 || t == 0 {
        return Err(CordisError::format(
            &tplace,
            format!("shape {:?} holds no point or no frame", tracks.shape),
        ));
    }
    let track_at = |i: usize, f: usize, d: usize| -> f64 {
        if batched {
            tracks.values[(f * n + i) * dims + d]
        } else {
            tracks.values[(i * t + f) * dims + d]
        }
    };
    let visible_at: Box<dyn Fn(usize, usize) -> bool> = match &visibility {
        None => Box::new(|_, _| true),
        Some(v) => {
            let vplace = format!(
                "{name}[{}]",
                key_of(visibility_entry.as_deref().unwrap_or(""))
            );
            let expected: Vec<usize> = if batched { vec![1, t, n] } else { vec![n, t] };
            if v.shape != expected {
                return Err(CordisError::format(
                    &vplace,
                    format!(
                        "shape {:?} does not match the tracks' {:?} (expected {expected:?})",
                        v.shape, tracks.shape
                    ),
                ));
            }
            let values = &v.values;
            Box::new(move |i, f| {
                let v = if batched {
                    values[f * n + i]
                } else {
                    values[i * t + f]
                };
                (v >= 0.5) != occluded
            })
        }
    };
    let mut data = Vec::with_capacity(t * n * 3);
    let mut hidden = 0usize;
    for f in 0..t {
        for i in 0..n {
            let p = [
                track_at(i, f, 0),
                track_at(i, f, 1),
                if dims == 3 { track_at(i, f, 2) } else { 0.0 },
            ];
            if !visible_at(i, f) || p.iter().any(|v| !v.is_finite()) {
                hidden += 1;
                data.extend_from_slice(&[f64::NAN; 3]);
            } else {
                data.extend_from_slice(&p);
            }
        }
    }
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
