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

use super::markers::{list_names, to_metres, Imported, InputFormat, Units};
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
    let lines = Lines {
        name,
        lines: text.lines().enumerate().map(|(k, l)| (k + 1, l)).collect(),
    };
    let header = read_header(&lines, units)?;
    let num_markers = header.names.len();
    let mut data = read_rows(&lines, &header)?;
    let frames = data.len() / (3 * num_markers);
    // A marker whose X, Y or Z alone is missing is missing whole: a partial point is not one.
    for p in data.chunks_exact_mut(3) {
        if p.iter().any(|v| v.is_nan()) {
            p.fill(f64::NAN);
        }
    }
    let mut observations = Observations::from_flat(frames, num_markers, data)?;
    let rate = header.rate;
    observations.dt = Some(1.0 / rate);
    let factor = header.units.metres();
    let mapping = format!(
        "{num_markers} markers: {}; DataRate {rate} Hz → dt {} s; Units {}{}",
        list_names(&header.names),
        1.0 / rate,
        header.units.name(),
        to_metres(factor)
    );
    Ok(Imported {
        observations,
        format: InputFormat::Trc,
        labels: header.names,
        mapping,
    })
}

/// The file's lines, numbered from 1, and the places errors name (`name:line`).
struct Lines<'a> {
    name: &'a str,
    lines: Vec<(usize, &'a str)>,
}

impl<'a> Lines<'a> {
    fn place(&self, line: usize) -> String {
        format!("{}:{line}", self.name)
    }

    /// Header line `k` (from 0) with its number; an error when the file ends before it.
    fn header(&self, k: usize) -> Result<(usize, &'a str)> {
        self.lines.get(k).copied().ok_or_else(|| {
            fail(
                self.name.into(),
                format!(
                    "the file ends after {} lines: a TRC header has 5 (PathFileType, keys, values, names, axes)",
                    self.lines.len()
                ),
            )
        })
    }
}

/// What the header announces: the rate (Hz), the rows, the length unit and the markers' names.
struct Header {
    rate: f64,
    num_frames: usize,
    units: Units,
    names: Vec<String>,
}

/// Header lines 2 and 3: the keys and their values, matched case-insensitively.
struct KeyValues<'a, 'l> {
    lines: &'l Lines<'a>,
    keys: Vec<&'a str>,
    values: Vec<&'a str>,
    /// The two lines' numbers.
    at: (usize, usize),
}

impl<'a> KeyValues<'a, '_> {
    fn value(&self, key: &str) -> Option<&'a str> {
        self.keys
            .iter()
            .position(|k| k.eq_ignore_ascii_case(key))
            .map(|i| self.values[i])
    }

    fn number(&self, key: &str) -> Result<f64> {
        let (l2, l3) = self.at;
        let v = self.value(key).ok_or_else(|| {
            fail(
                self.lines.place(l2),
                format!(
                    "the header has no `{key}` key (keys: {})",
                    printable(&self.keys.join(", "))
                ),
            )
        })?;
        v.parse::<f64>().map_err(|_| {
            fail(
                self.lines.place(l3),
                format!("{key} `{}` is not a number", printable(v)),
            )
        })
    }

    fn count(&self, key: &str) -> Result<usize> {
        let v = self.number(key)?;
        if v < 0.0 || v.fract() != 0.0 || v > 1e9 {
            return Err(fail(
                self.lines.place(self.at.1),
                format!("{key} {v} is not a count"),
            ));
        }
        Ok(v as usize)
    }
}

/// The five header lines: `PathFileType`, the keys and their values (rate, counts, units,
/// checked against `units` when given), the markers' names (as many as `NumMarkers`) and the
/// axes line.
fn read_header(lines: &Lines<'_>, units: Option<Units>) -> Result<Header> {
    let (l1, first) = lines.header(0)?;
    if !first
        .trim_start()
        .to_ascii_lowercase()
        .starts_with("pathfiletype")
    {
        return Err(fail(
            lines.place(l1),
            "not a TRC file: the first line must start with `PathFileType`".into(),
        ));
    }
    let (l2, keys_line) = lines.header(1)?;
    let (l3, values_line) = lines.header(2)?;
    let kv = KeyValues {
        lines,
        keys: cells(keys_line),
        values: cells(values_line),
        at: (l2, l3),
    };
    if kv.keys.len() != kv.values.len() {
        return Err(fail(
            lines.place(l3),
            format!(
                "wrong header count: line {l2} names {} keys, line {l3} gives {} values",
                kv.keys.len(),
                kv.values.len()
            ),
        ));
    }
    let rate = kv.number("DataRate")?;
    if !(rate.is_finite() && rate > 0.0) {
        return Err(fail(
            lines.place(l3),
            format!("DataRate {rate} is not a positive rate (Hz)"),
        ));
    }
    let num_frames = kv.count("NumFrames")?;
    let num_markers = kv.count("NumMarkers")?;
    let file_units = kv.value("Units").unwrap_or("m");
    let file_units = Units::parse(file_units).ok_or_else(|| {
        fail(
            lines.place(l3),
            format!(
                "Units `{}` is not a length unit: m, cm or mm",
                printable(file_units)
            ),
        )
    })?;
    if let Some(u) = units.filter(|u| *u != file_units) {
        return Err(fail(
            lines.place(l3),
            format!(
                "mixed units: --units {} but the header says Units {}",
                u.name(),
                file_units.name()
            ),
        ));
    }
    let names = marker_names(lines, num_markers, l3)?;
    lines.header(4)?;
    Ok(Header {
        rate,
        num_frames,
        units: file_units,
        names,
    })
}

/// Header line 4's marker names (after `Frame#` and `Time`; empty cells skipped): exactly
/// `num_markers` of them, and at least one (`values_line` is where `NumMarkers` was given).
fn marker_names(lines: &Lines<'_>, num_markers: usize, values_line: usize) -> Result<Vec<String>> {
    let (l4, names_line) = lines.header(3)?;
    let names: Vec<String> = cells(names_line)
        .into_iter()
        .skip(2)
        .filter(|c| !c.is_empty())
        .map(str::to_string)
        .collect();
    if names.len() != num_markers {
        return Err(fail(
            lines.place(l4),
            format!(
                "wrong header count: NumMarkers is {num_markers} but line {l4} names {} markers",
                names.len()
            ),
        ));
    }
    if num_markers == 0 {
        return Err(fail(
            lines.place(values_line),
            "NumMarkers is 0: no markers to read".into(),
        ));
    }
    Ok(names)
}

/// The data rows after the header (blank lines skipped), frame-major, metres, NaN where a cell
/// is empty, `NaN` or absent at the row's end; exactly `NumFrames` rows.
fn read_rows(lines: &Lines<'_>, header: &Header) -> Result<Vec<f64>> {
    let (names, num_frames) = (&header.names, header.num_frames);
    let num_markers = names.len();
    let width = 2 + 3 * num_markers;
    let factor = header.units.metres();
    let mut data = Vec::with_capacity(num_frames.min(lines.lines.len()) * num_markers * 3);
    let mut frames = 0;
    for &(ln, row) in lines.lines.iter().skip(5) {
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
                lines.place(ln),
                format!(
                    "long row: {} fields, the header announces {width}",
                    fields.len()
                ),
            ));
        }
        if fields.len() < 2 {
            return Err(fail(
                lines.place(ln),
                "short row: no Frame# and Time".into(),
            ));
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
                            lines.place(ln),
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
                lines.place(ln),
                format!("wrong header count: more rows than NumFrames {num_frames}"),
            ));
        }
    }
    if frames != num_frames {
        return Err(fail(
            lines.name.into(),
            format!("wrong header count: NumFrames is {num_frames} but the file has {frames} rows"),
        ));
    }
    Ok(data)
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
