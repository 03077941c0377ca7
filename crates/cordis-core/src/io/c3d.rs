//! C3D motion-capture files, read with the `c3dio` crate: the markers (`POINT:LABELS`), their
//! positions, `POINT:RATE` (Hz, `dt = 1 / rate`) and `POINT:UNITS` (m, cm, mm → metres).
//! A point whose residual is negative is missing (the C3D convention for an invalid sample):
//! NaN, not its stored coordinates (often zeros).
//!
//! Why `c3dio`: it is the one pure-Rust C3D reader on crates.io (MIT/Apache-2.0; reads
//! Intel, DEC and MIPS files, integer and float data; writes C3D too, which makes the test
//! files). Its upkeep is thin — one author, 0.8.0 of April 2024 the last release — and its
//! parser indexes and subtracts header fields unchecked, so the header fields it trusts are
//! checked here first (a file that still makes it panic is reported as malformed, not a crash).

use super::markers::{list_names, to_metres, Imported, InputFormat, Units};
use crate::error::{printable, CordisError, Result};
use crate::Observations;

fn malformed(name: &str, message: impl Into<String>) -> CordisError {
    CordisError::format(name, message)
}

/// Checks the header fields `c3dio` uses as slice bounds and subtrahends.
fn check_header(name: &str, bytes: &[u8]) -> Result<()> {
    if bytes.len() < 1024 {
        return Err(malformed(
            name,
            format!(
                "not a C3D file: {} bytes, a header and a parameter block take 1024",
                bytes.len()
            ),
        ));
    }
    if bytes[1] != 0x50 {
        return Err(malformed(
            name,
            "not a C3D file: header byte 2 is not the key 0x50",
        ));
    }
    let parameter_block = bytes[0] as usize;
    if parameter_block == 0 || bytes.len() < 512 * parameter_block {
        return Err(malformed(
            name,
            format!(
                "header: the parameters start at block {parameter_block}, outside the file's {} blocks",
                bytes.len() / 512
            ),
        ));
    }
    let processor = bytes[512 * (parameter_block - 1) + 3];
    let u16_at = |k: usize| -> u16 {
        match processor {
            86 => u16::from_be_bytes([bytes[k], bytes[k + 1]]),
            _ => u16::from_le_bytes([bytes[k], bytes[k + 1]]),
        }
    };
    if !(84..=86).contains(&processor) {
        return Err(malformed(
            name,
            format!(
                "parameters: processor type {processor} is not Intel (84), DEC (85) nor MIPS (86)"
            ),
        ));
    }
    let data_block = u16_at(16) as usize;
    if data_block <= parameter_block || bytes.len() < 512 * (data_block - 1) {
        return Err(malformed(
            name,
            format!(
                "header: the data start at block {data_block}, not after the parameters (block \
                 {parameter_block}) within the file's {} blocks",
                bytes.len() / 512
            ),
        ));
    }
    let (first, last) = (u16_at(6), u16_at(8));
    if last < first {
        return Err(malformed(
            name,
            format!("header: last frame {last} is before the first frame {first}"),
        ));
    }
    Ok(())
}

/// Parses C3D bytes (module docs); `name` starts every error's place. `units` (`--units`)
/// must agree with `POINT:UNITS` when given.
pub(crate) fn parse_c3d(name: &str, bytes: &[u8], units: Option<Units>) -> Result<Imported> {
    check_header(name, bytes)?;
    // The parse error is turned into text inside the guard: c3dio's error type is large. The
    // panic hook is silenced meanwhile, so that a panic left in c3dio (1 of 512 single-byte
    // corruptions of a small file, measured) prints our one line, not a panic message; the
    // hook is process-wide, so a panic elsewhere in those microseconds would print nothing.
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let parsed = std::panic::catch_unwind(|| {
        c3dio::C3d::from_bytes(bytes).map_err(|e| format!("not a readable C3D file: {e:?}"))
    });
    std::panic::set_hook(hook);
    let parsed = parsed.map_err(|_| {
        malformed(
            name,
            "malformed C3D file: its parameters or data do not fit its header",
        )
    })?;
    let c3d = parsed.map_err(|m| malformed(name, printable(&m)))?;
    let points = &c3d.points;
    let (frames, markers) = (points.rows(), points.cols());
    if markers == 0 {
        return Err(CordisError::trajectory(
            name,
            "no markers: POINT:USED is 0 (a file of analog channels only?)",
        ));
    }
    if frames == 0 {
        return Err(CordisError::trajectory(name, "no frames of point data"));
    }
    let rate = points.frame_rate as f64;
    if !(rate.is_finite() && rate > 0.0) {
        return Err(malformed(
            name,
            format!("POINT:RATE {rate} is not a positive rate (Hz)"),
        ));
    }
    let unit_text: String = points.units.iter().collect::<String>().trim().to_string();
    let file_units = if unit_text.is_empty() {
        units.unwrap_or(Units::M)
    } else {
        Units::parse(&unit_text).ok_or_else(|| {
            malformed(
                name,
                format!(
                    "POINT:UNITS `{}` is not a length unit: m, cm or mm",
                    printable(&unit_text)
                ),
            )
        })?
    };
    if let Some(u) = units.filter(|u| *u != file_units && !unit_text.is_empty()) {
        return Err(CordisError::trajectory(
            name,
            format!(
                "mixed units: --units {} but POINT:UNITS says {}",
                u.name(),
                file_units.name()
            ),
        ));
    }
    let factor = file_units.metres();
    let mut data = Vec::with_capacity(frames * markers * 3);
    for f in 0..frames {
        for m in 0..markers {
            let p = points.points[(f, m)];
            let finite = p.point.iter().all(|v| v.is_finite());
            if p.residual < 0.0 || !finite {
                data.extend_from_slice(&[f64::NAN; 3]);
            } else {
                data.extend(p.point.iter().map(|&v| v as f64 * factor));
            }
        }
    }
    let mut labels: Vec<String> = points.labels.iter().map(|l| l.trim().to_string()).collect();
    labels.resize_with(markers, String::new);
    for (i, l) in labels.iter_mut().enumerate() {
        if l.is_empty() {
            *l = i.to_string();
        }
    }
    let mut observations = Observations::from_flat(frames, markers, data)?;
    observations.dt = Some(1.0 / rate);
    let missing = observations.missing() / 3;
    let mapping = format!(
        "{markers} markers: {}; POINT:RATE {rate} Hz → dt {} s; POINT:UNITS {}{}; \
         {missing} samples with a negative residual → NaN",
        list_names(&labels),
        1.0 / rate,
        if unit_text.is_empty() {
            format!("absent ({} assumed)", file_units.name())
        } else {
            file_units.name().to_string()
        },
        to_metres(factor)
    );
    Ok(Imported {
        observations,
        format: InputFormat::C3d,
        labels,
        mapping,
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// One parameter record: name, group id, type (-1 char, 2 int16, 4 float), dims, data.
    fn parameter(out: &mut Vec<u8>, name: &str, group: i8, kind: i8, dims: &[u8], data: &[u8]) {
        out.push(name.len() as u8);
        out.push(group as u8);
        out.extend_from_slice(name.as_bytes());
        // Offset to the next record, counted from this word: itself, type, dims, data, desc.
        let next = 2 + 1 + 1 + dims.len() + data.len() + 1;
        out.extend_from_slice(&(next as u16).to_le_bytes());
        out.push(kind as u8);
        out.push(dims.len() as u8);
        out.extend_from_slice(dims);
        out.extend_from_slice(data);
        out.push(0);
    }

    /// C3D bytes built field by field after the C3D manual (Intel, float data, mm, 100 Hz),
    /// independent of `c3dio`: `frames` × `markers` points at (10 f + m, 100 + m, 1000 m),
    /// `invalid` (frame, marker) samples with residual -1.
    pub(crate) fn c3d_bytes(frames: usize, markers: usize, invalid: &[(usize, usize)]) -> Vec<u8> {
        let mut params = vec![1u8, 0x50, 1, 84];
        // The POINT group (id 1).
        let name = "POINT";
        params.extend_from_slice(&[name.len() as u8, (-1i8) as u8]);
        params.extend_from_slice(name.as_bytes());
        params.extend_from_slice(&3u16.to_le_bytes());
        params.push(0);
        let int = |v: u16| v.to_le_bytes().to_vec();
        parameter(&mut params, "USED", 1, 2, &[], &int(markers as u16));
        parameter(&mut params, "FRAMES", 1, 2, &[], &int(frames as u16));
        parameter(&mut params, "DATA_START", 1, 2, &[], &int(3));
        parameter(&mut params, "SCALE", 1, 4, &[], &(-1.0f32).to_le_bytes());
        parameter(&mut params, "RATE", 1, 4, &[], &100.0f32.to_le_bytes());
        parameter(&mut params, "UNITS", 1, -1, &[2], b"mm");
        let labels: Vec<u8> = (0..markers)
            .flat_map(|m| format!("M{m:<3}").into_bytes())
            .collect();
        parameter(&mut params, "LABELS", 1, -1, &[4, markers as u8], &labels);
        // Zeros after the last record end the parameters.
        params.resize(512, 0);
        let mut header = vec![0u8; 512];
        header[0] = 2;
        header[1] = 0x50;
        header[2..4].copy_from_slice(&(markers as u16).to_le_bytes());
        header[6..8].copy_from_slice(&1u16.to_le_bytes());
        header[8..10].copy_from_slice(&(frames as u16).to_le_bytes());
        header[10..12].copy_from_slice(&10u16.to_le_bytes());
        header[12..16].copy_from_slice(&(-1.0f32).to_le_bytes());
        header[16..18].copy_from_slice(&3u16.to_le_bytes());
        header[20..24].copy_from_slice(&100.0f32.to_le_bytes());
        let mut bytes = header;
        bytes.extend_from_slice(&params);
        for f in 0..frames {
            for m in 0..markers {
                let p = [(10 * f + m) as f32, (100 + m) as f32, (1000 * m) as f32];
                for v in p {
                    bytes.extend_from_slice(&v.to_le_bytes());
                }
                let residual: f32 = if invalid.contains(&(f, m)) { -1.0 } else { 0.0 };
                bytes.extend_from_slice(&residual.to_le_bytes());
            }
        }
        let pad = (512 - bytes.len() % 512) % 512;
        bytes.resize((bytes.len() + pad).max(3 * 512), 0);
        bytes
    }

    #[test]
    fn markers_rate_units_and_invalid_points_are_read() {
        let bytes = c3d_bytes(3, 2, &[(1, 1)]);
        let im = parse_c3d("t.c3d", &bytes, None).unwrap();
        let o = &im.observations;
        assert_eq!((o.frames(), o.particles()), (3, 2));
        assert_eq!(im.labels, ["M0", "M1"]);
        assert!((o.dt.unwrap() - 0.01).abs() < 1e-12);
        let v = o.as_flat();
        // Frame 2, marker 1 at (21, 101, 1000) mm.
        let at = (2 * 2 + 1) * 3;
        assert!((v[at] - 0.021).abs() < 1e-9 && (v[at + 2] - 1.0).abs() < 1e-9);
        assert!(
            v[9..12].iter().all(|x| x.is_nan()),
            "residual < 0 → missing"
        );
        assert_eq!(o.missing(), 3);
        assert!(im.mapping.contains("POINT:UNITS mm → m"), "{}", im.mapping);
        let e = parse_c3d("t.c3d", &bytes, Some(Units::Cm))
            .unwrap_err()
            .to_string();
        assert_eq!(e, "t.c3d: mixed units: --units cm but POINT:UNITS says mm");
    }

    #[test]
    fn malformed_files_are_errors_not_panics() {
        let good = c3d_bytes(2, 1, &[]);
        let e = parse_c3d("t.c3d", b"short", None).unwrap_err().to_string();
        assert!(e.starts_with("t.c3d: not a C3D file"), "{e}");
        let mut b = good.clone();
        b[0] = 0;
        assert!(parse_c3d("t.c3d", &b, None).is_err());
        let mut b = good.clone();
        b[16] = 0;
        b[17] = 0;
        assert!(parse_c3d("t.c3d", &b, None).is_err());
        let mut b = good.clone();
        b[6] = 9;
        assert!(parse_c3d("t.c3d", &b, None).is_err());
        // Every truncation and a byte flipped anywhere in the header or parameters: an error
        // or a reading, never a panic.
        for cut in (0..good.len()).step_by(97) {
            let _ = parse_c3d("t.c3d", &good[..cut], None);
        }
        for k in (0..good.len().min(1536)).step_by(5) {
            let mut b = good.clone();
            b[k] ^= 0xA5;
            let _ = parse_c3d("t.c3d", &b, None);
        }
    }

    #[test]
    fn a_file_with_no_markers_is_refused() {
        let bytes = c3d_bytes(2, 0, &[]);
        let e = parse_c3d("n.c3d", &bytes, None).unwrap_err().to_string();
        assert!(e.starts_with("n.c3d: no markers"), "{e}");
    }
}
