//! OpenSim `.trc` marker files (text, tab-separated):
//!
//! ```text
//! PathFileType  4  (X/Y/Z)  walk.trc
//! DataRate  CameraRate  NumFrames  NumMarkers  Units  OrigDataRate  OrigDataStartFrame  OrigNumFrames
//! 100       100         3          2           mm     100           1                   3
//! Frame#  Time  LASI        RASI
//!               X1  Y1  Z1  X2  Y2  Z2
//!
//! 1       0     1   2   3   4   5   6
//! ```
//!
//! Line 2 names the keys of line 3, in any order (matched case-insensitively); `DataRate`
//! (Hz) gives `dt = 1 / DataRate`, `Units` (m, cm, mm) the scale to metres, `NumFrames` and
//! `NumMarkers` are checked against the rows and the names of line 4. A marker's cells that
//! are empty (or absent at the end of a row, as some writers leave them) are missing.

use super::markers::{list_names, Imported, InputFormat, Units};
use crate::error::{printable, CordisError, Result};
use crate::Observations;

fn fail(place: String, message: String) -> CordisError {
    CordisError::trajectory(place, message)
}

/// Cells of a line: split on tabs when it has any, else on whitespace.
fn cells(line: &str) -> Vec<&str> {
    if line.contains('\t') {
        line.split('\t').map(str::trim).collect()
    } else {
        line.split_whitespace().collect()
    }
}

/// Parses `.trc` text; `name` starts every error's place. `units` (`--units`) must agree with
/// the header's when given.
pub(crate) fn parse_trc(name: &str, text: &str, units: Option<Units>) -> Result<Imported> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let lines: Vec<(usize, &str)> = text.lines().enumerate().map(|(k, l)| (k + 1, l)).collect();
    let place = |line: usize| format!("{name}:{line}");
    let line = |k: usize| -> Result<(usize, &str)> {
        lines.get(k).copied().ok_or_else(|| {
            fail(
                name.into(),
                format!(
                    "the file ends after {} lines: a TRC header has 5 (PathFileType, keys, values, names, axes)",
                    lines.len()
                ),
            )
        })
    };
    let (l1, first) = line(0)?;
    if !first
        .trim_start()
        .to_ascii_lowercase()
        .starts_with("pathfiletype")
    {
        return Err(fail(
            place(l1),
            "not a TRC file: the first line must start with `PathFileType`".into(),
        ));
    }
    let (l2, keys_line) = line(1)?;
    let (l3, values_line) = line(2)?;
    let keys = cells(keys_line);
    let values = cells(values_line);
    if keys.len() != values.len() {
        return Err(fail(
            place(l3),
            format!(
                "wrong header count: line {l2} names {} keys, line {l3} gives {} values",
                keys.len(),
                values.len()
            ),
        ));
    }
    let value = |key: &str| -> Option<&str> {
        keys.iter()
            .position(|k| k.eq_ignore_ascii_case(key))
            .map(|i| values[i])
    };
    let number = |key: &str| -> Result<f64> {
        let v = value(key).ok_or_else(|| {
            fail(
                place(l2),
                format!(
                    "the header has no `{key}` key (keys: {})",
                    printable(&keys.join(", "))
                ),
            )
        })?;
        v.parse::<f64>().map_err(|_| {
            fail(
                place(l3),
                format!("{key} `{}` is not a number", printable(v)),
            )
        })
    };
    let rate = number("DataRate")?;
    if !(rate.is_finite() && rate > 0.0) {
        return Err(fail(
            place(l3),
            format!("DataRate {rate} is not a positive rate (Hz)"),
        ));
    }
    let count = |key: &str| -> Result<usize> {
        let v = number(key)?;
        if v < 0.0 || v.fract() != 0.0 || v > 1e9 {
            return Err(fail(place(l3), format!("{key} {v} is not a count")));
        }
        Ok(v as usize)
    };
    let num_frames = count("NumFrames")?;
    let num_markers = count("NumMarkers")?;
    let file_units = value("Units").unwrap_or("m");
    let file_units = Units::parse(file_units).ok_or_else(|| {
        fail(
            place(l3),
            format!(
                "Units `{}` is not a length unit: m, cm or mm",
                printable(file_units)
            ),
        )
    })?;
    if let Some(u) = units.filter(|u| *u != file_units) {
        return Err(fail(
            place(l3),
            format!(
                "mixed units: --units {} but the header says Units {}",
                u.name(),
                file_units.name()
            ),
        ));
    }
    let (l4, names_line) = line(3)?;
    let names: Vec<String> = cells(names_line)
        .into_iter()
        .skip(2)
        .filter(|c| !c.is_empty())
        .map(str::to_string)
        .collect();
    if names.len() != num_markers {
        return Err(fail(
            place(l4),
            format!(
                "wrong header count: NumMarkers is {num_markers} but line {l4} names {} markers",
                names.len()
            ),
        ));
    }
    if num_markers == 0 {
        return Err(fail(
            place(l3),
            "NumMarkers is 0: no markers to read".into(),
        ));
    }
    line(4)?;
    let width = 2 + 3 * num_markers;
    let factor = file_units.metres();
    let mut data = Vec::with_capacity(num_frames.min(lines.len()) * num_markers * 3);
    let mut frames = 0;
    for &(ln, row) in lines.iter().skip(5) {
        if row.trim().is_empty() {
            continue;
        }
        let fields: Vec<&str> = row.split('\t').map(str::trim).collect();
        let fields = if fields.len() == 1 {
            row.split_whitespace().collect()
        } else {
            fields
        };
        if fields.len() > width && fields[width..].iter().any(|f| !f.is_empty()) {
            return Err(fail(
                place(ln),
                format!(
                    "long row: {} fields, the header announces {width}",
                    fields.len()
                ),
            ));
        }
        if fields.len() < 2 {
            return Err(fail(place(ln), "short row: no Frame# and Time".into()));
        }
        for k in 0..3 * num_markers {
            let cell = fields.get(2 + k).copied().unwrap_or("");
            let v = if cell.is_empty() || cell.eq_ignore_ascii_case("nan") {
                f64::NAN
            } else {
                match cell.parse::<f64>() {
                    Ok(v) if v.is_finite() => v * factor,
                    _ => {
                        return Err(fail(
                            place(ln),
                            format!(
                                "marker `{}` {} (field {}): `{}` is not a number",
                                printable(&names[k / 3]),
                                ["X", "Y", "Z"][k % 3],
                                3 + k,
                                printable(cell)
                            ),
                        ))
                    }
                }
            };
            data.push(v);
        }
        frames += 1;
        if frames > num_frames {
            return Err(fail(
                place(ln),
                format!("wrong header count: more rows than NumFrames {num_frames}"),
            ));
        }
    }
    if frames != num_frames {
        return Err(fail(
            name.into(),
            format!("wrong header count: NumFrames is {num_frames} but the file has {frames} rows"),
        ));
    }
    // A marker whose X, Y or Z alone is missing is missing whole: a partial point is not one.
    for p in data.chunks_exact_mut(3) {
        if p.iter().any(|v| v.is_nan()) {
            p.fill(f64::NAN);
        }
    }
    let mut observations = Observations::from_flat(frames, num_markers, data)?;
    observations.dt = Some(1.0 / rate);
    let mapping = format!(
        "{num_markers} markers: {}; DataRate {rate} Hz → dt {} s; Units {}{}",
        list_names(&names),
        1.0 / rate,
        file_units.name(),
        if factor == 1.0 {
            String::new()
        } else {
            format!(" → m (×{factor})")
        }
    );
    Ok(Imported {
        observations,
        format: InputFormat::Trc,
        labels: names,
        mapping,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const TRC: &str = "PathFileType\t4\t(X/Y/Z)\twalk.trc\n\
        DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n\
        100.00\t100.00\t3\t2\tmm\t100.00\t1\t3\n\
        Frame#\tTime\tLASI\t\t\tRASI\t\t\n\
        \t\tX1\tY1\tZ1\tX2\tY2\tZ2\n\
        \n\
        1\t0.00\t1000\t2000\t3000\t4000\t5000\t6000\n\
        2\t0.01\t1100\t2100\t3100\t\t\t\n\
        3\t0.02\t1200\t2200\t3200\n";

    #[test]
    fn reads_markers_rate_units_and_gaps() {
        let im = parse_trc("walk.trc", TRC, None).unwrap();
        let o = &im.observations;
        assert_eq!((o.frames(), o.particles()), (3, 2));
        assert_eq!(im.labels, ["LASI", "RASI"]);
        assert!((o.dt.unwrap() - 0.01).abs() < 1e-15);
        let v = o.as_flat();
        assert_eq!(&v[..6], &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
        assert!(
            v[9..12].iter().all(|x| x.is_nan()),
            "RASI missing at frame 1"
        );
        assert!(
            v[15..18].iter().all(|x| x.is_nan()),
            "absent trailing cells"
        );
        assert_eq!(o.missing(), 6);
        assert!(im.mapping.contains("Units mm → m"), "{}", im.mapping);
    }

    #[test]
    fn wrong_header_counts_and_mixed_units_name_the_line() {
        let e = parse_trc("w.trc", &TRC.replace("\t3\t2\tmm", "\t3\t3\tmm"), None)
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "w.trc:4: wrong header count: NumMarkers is 3 but line 4 names 2 markers"
        );
        let e = parse_trc("w.trc", &TRC.replace("\t3\t2\tmm", "\t4\t2\tmm"), None)
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "w.trc: wrong header count: NumFrames is 4 but the file has 3 rows"
        );
        let e = parse_trc("w.trc", TRC, Some(Units::M))
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "w.trc:3: mixed units: --units m but the header says Units mm"
        );
        let e = parse_trc("w.trc", &TRC.replace("1100", "x"), None)
            .unwrap_err()
            .to_string();
        assert_eq!(e, "w.trc:8: marker `LASI` X (field 3): `x` is not a number");
        let e = parse_trc("w.trc", "hello\n", None).unwrap_err().to_string();
        assert!(e.starts_with("w.trc:1: not a TRC file"), "{e}");
        let e = parse_trc("w.trc", "PathFileType\t4\n", None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("a TRC header has 5"), "{e}");
    }
}
