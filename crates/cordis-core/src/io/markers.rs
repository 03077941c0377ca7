//! Marker trajectories as the field writes them — motion capture (C3D, OpenSim TRC), video
//! trackers (TAP-Vid / CoTracker `.npz`), tables (CSV/TSV with named columns) and cordis' own
//! `.npy`, `.csv`, `.tra` — read into one [`Observations`] (metres, NaN where a marker is
//! missing, `dt` when the file gives a rate), chosen by extension.
//!
//! [`read_markers`] is the one reader: the CLI (every command that takes a trajectory, and
//! `cordis import FILE --out traj.npy`) and Python's `cordis.read_trajectory` call it, so they
//! read the same files the same way. [`Imported`] also says what was read: the format, the
//! markers' names, and how the file's columns, units and rate were mapped.
//!
//! A missing marker is never a zero: a C3D point with a negative residual, a TRC or CSV cell
//! that is empty or `nan`, an absent row, a tracker point whose visibility is false all become
//! NaN, which the estimators treat as a mask.

use std::path::Path;

use super::{c3d, csv, npy, table, tra, tracks, trc};
use crate::error::{printable, CordisError, Result};
use crate::Observations;

/// Length units of a file's coordinates. Every reader converts to metres.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Units {
    M,
    Cm,
    Mm,
}

impl Units {
    /// `m`, `cm`, `mm` (or spelt out, `metres`, `millimeters`…), case-insensitive.
    pub fn parse(text: &str) -> Option<Units> {
        match text.trim().to_ascii_lowercase().as_str() {
            "m" | "meter" | "meters" | "metre" | "metres" => Some(Units::M),
            "cm" | "centimeter" | "centimeters" | "centimetre" | "centimetres" => Some(Units::Cm),
            "mm" | "millimeter" | "millimeters" | "millimetre" | "millimetres" => Some(Units::Mm),
            _ => None,
        }
    }

    /// [`Units::parse`], or an argument error naming `place` (`--units`).
    pub fn parse_arg(place: &str, text: &str) -> Result<Units> {
        Units::parse(text).ok_or_else(|| {
            CordisError::argument(
                place,
                format!("`{}` is not a length unit: m, cm or mm", printable(text)),
            )
        })
    }

    /// One unit in metres.
    pub fn metres(self) -> f64 {
        match self {
            Units::M => 1.0,
            Units::Cm => 0.01,
            Units::Mm => 0.001,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Units::M => "m",
            Units::Cm => "cm",
            Units::Mm => "mm",
        }
    }
}

/// How cells of a text table are separated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Delimiter {
    Char(char),
    /// Any run of spaces and tabs.
    Whitespace,
}

impl Delimiter {
    /// `,` `;` `|`, `tab` (or a tab character), `space` / `whitespace`.
    pub fn parse_arg(place: &str, text: &str) -> Result<Delimiter> {
        match text {
            "\t" | "tab" | "\\t" => Ok(Delimiter::Char('\t')),
            "space" | "whitespace" | " " => Ok(Delimiter::Whitespace),
            t if t.chars().count() == 1 && !t.chars().all(|c| c.is_alphanumeric() || c == '.') => {
                Ok(Delimiter::Char(t.chars().next().unwrap_or(',')))
            }
            _ => Err(CordisError::argument(
                place,
                format!(
                    "`{}` is not a delimiter: one character such as `,` `;` `|`, or `tab`, `space`",
                    printable(text)
                ),
            )),
        }
    }

    pub(crate) fn describe(self) -> String {
        match self {
            Delimiter::Char('\t') => "tab-separated".into(),
            Delimiter::Char(c) => format!("`{c}`-separated"),
            Delimiter::Whitespace => "whitespace-separated".into(),
        }
    }
}

/// What the readers need beyond the file: all optional.
#[derive(Clone, Debug, Default)]
pub struct ReadOptions {
    /// A column mapping for text tables (`frame=Frame,particle=Marker,x=X,y=Y,z=Z`, `time=t`,
    /// wide tables `x=*_X`): see `docs/file-formats.md`. Columns it does not name are found by
    /// their usual names.
    pub columns: Option<String>,
    /// The units of a file that does not state them (default m). A file that states other
    /// units (a TRC header, C3D `POINT:UNITS`, a `X [mm]` column) is refused: mixed units.
    pub units: Option<Units>,
    /// The delimiter of a text table; sniffed from its header when not given.
    pub delimiter: Option<Delimiter>,
}

/// The formats [`read_markers`] reads, by extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InputFormat {
    /// `.csv`, `.tsv`: a text table (cordis' `frame,particle,x,y,z`, or named columns).
    Csv,
    /// `.npy`: float64 `(T, N, 3)`, or `(T, N, 2)` for a planar scene (z = 0).
    Npy,
    /// `.npz`: tracker output, `tracks` `(N, T, 2|3)` and `visibility` `(N, T)`.
    Npz,
    /// The thesis' `.tra`.
    Tra,
    /// OpenSim `.trc`.
    Trc,
    /// Motion-capture `.c3d`.
    C3d,
}

impl InputFormat {
    /// The format a file name announces (extension, case-insensitive).
    pub fn from_path(path: &Path) -> Result<Self> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("csv" | "tsv") => Ok(Self::Csv),
            Some("npy") => Ok(Self::Npy),
            Some("npz") => Ok(Self::Npz),
            Some("tra") => Ok(Self::Tra),
            Some("trc") => Ok(Self::Trc),
            Some("c3d") => Ok(Self::C3d),
            _ => Err(CordisError::format(
                path.display().to_string(),
                "unknown trajectory format: the name must end in .csv, .npy or .tra \
                 (or, to read markers, .tsv, .trc, .c3d, .npz)",
            )),
        }
    }

    /// Whether a path names a file of one of these formats.
    pub fn is_trajectory_path(path: &Path) -> bool {
        Self::from_path(path).is_ok()
    }

    /// The format's name as printed (`C3D`, `OpenSim TRC`…).
    pub fn name(self) -> &'static str {
        match self {
            Self::Csv => "CSV table",
            Self::Npy => "NumPy .npy",
            Self::Npz => "tracker .npz",
            Self::Tra => "thesis .tra",
            Self::Trc => "OpenSim TRC",
            Self::C3d => "C3D",
        }
    }
}

/// Observed markers read from a file, and what the reader made of it.
#[derive(Clone, Debug)]
pub struct Imported {
    /// Positions in metres, NaN where missing; `dt` (s) when the file gives a rate.
    pub observations: Observations,
    pub format: InputFormat,
    /// The markers' names in particle order (their indices when the file names none).
    pub labels: Vec<String>,
    /// How the file was mapped: layout, columns, units, rate (one line, for the user).
    pub mapping: String,
}

/// Reads marker positions from a file in any [`InputFormat`], by extension.
pub fn read_markers(path: &Path, options: &ReadOptions) -> Result<Imported> {
    let format = InputFormat::from_path(path)?;
    let bytes = super::read_input(path)?;
    parse_markers(&path.display().to_string(), format, &bytes, options)
}

/// [`read_markers`] over bytes; `name` starts every error's place.
pub fn parse_markers(
    name: &str,
    format: InputFormat,
    bytes: &[u8],
    options: &ReadOptions,
) -> Result<Imported> {
    if options.columns.is_some() && format != InputFormat::Csv {
        return Err(CordisError::argument(
            "--columns",
            format!(
                "a column mapping applies to .csv/.tsv tables; {name} is a {} file",
                format.name()
            ),
        ));
    }
    if options.delimiter.is_some() && format != InputFormat::Csv {
        return Err(CordisError::argument(
            "--delimiter",
            format!(
                "a delimiter applies to .csv/.tsv tables; {name} is a {} file",
                format.name()
            ),
        ));
    }
    let text = || super::decode_text(bytes);
    // Whether the reader took `--units` into account itself (the formats that may state units).
    let mut units_read = true;
    let imported = match format {
        InputFormat::Csv => {
            let text = text();
            if options.columns.is_none()
                && options.delimiter.is_none()
                && table::is_cordis_header(&text)
            {
                units_read = false;
                let obs = csv::parse_csv_observations(name, &text)?;
                let labels = (0..obs.particles()).map(|i| i.to_string()).collect();
                unlabelled(
                    format,
                    obs,
                    labels,
                    "cordis layout frame,particle,x,y,z".into(),
                )
            } else {
                table::parse_table(name, &text, options)?
            }
        }
        InputFormat::Npy => {
            units_read = false;
            let (obs, mapping) = read_npy(name, bytes)?;
            let labels = (0..obs.particles()).map(|i| i.to_string()).collect();
            unlabelled(format, obs, labels, mapping)
        }
        InputFormat::Tra => {
            units_read = false;
            let obs = Observations::from_trajectory(&tra::parse_tra(name, &text())?);
            let labels = (0..obs.particles()).map(|i| i.to_string()).collect();
            unlabelled(format, obs, labels, "thesis layout".into())
        }
        InputFormat::Npz => {
            units_read = false;
            tracks::parse_npz(name, bytes)?
        }
        InputFormat::Trc => trc::parse_trc(name, &text(), options.units)?,
        InputFormat::C3d => c3d::parse_c3d(name, bytes, options.units)?,
    };
    // Files that never state units (cordis' own, trackers) are in `--units` (default m).
    match (options.units, units_read) {
        (Some(u), false) if u != Units::M => Ok(scaled(imported, u)),
        _ => Ok(imported),
    }
}

fn unlabelled(
    format: InputFormat,
    observations: Observations,
    labels: Vec<String>,
    mapping: String,
) -> Imported {
    Imported {
        observations,
        format,
        labels,
        mapping,
    }
}

/// The file's values read in `units`, converted to metres.
fn scaled(mut imported: Imported, units: Units) -> Imported {
    imported.observations = scale(imported.observations, units.metres());
    imported.mapping += &format!("; units {} → m (×{})", units.name(), units.metres());
    imported
}

/// Observations with every value multiplied by `factor` (NaN stays NaN).
pub(crate) fn scale(obs: Observations, factor: f64) -> Observations {
    if factor == 1.0 {
        return obs;
    }
    let (t, n, dt) = (obs.frames(), obs.particles(), obs.dt);
    let data = obs.as_flat().iter().map(|v| v * factor).collect();
    let mut out = Observations::from_flat(t, n, data).expect("same shape, finite factor");
    out.dt = dt;
    out
}

/// `.npy`: `(T, N, 3)` as cordis writes it, or `(T, N, 2)` planar (z = 0).
fn read_npy(name: &str, bytes: &[u8]) -> Result<(Observations, String)> {
    match npy::parse_npy_observations(name, bytes) {
        Ok(obs) => Ok((obs, "(frames, particles, 3)".into())),
        Err(e) => match npy::parse_npy_array(name, bytes) {
            Ok(a) if a.shape.len() == 3 && a.shape[2] == 2 && a.shape[0] * a.shape[1] > 0 => {
                let (t, n) = (a.shape[0], a.shape[1]);
                let data = a
                    .values
                    .chunks_exact(2)
                    .flat_map(|p| [p[0], p[1], if p[0].is_nan() { f64::NAN } else { 0.0 }])
                    .collect();
                let obs = Observations::from_flat(t, n, data)
                    .map_err(|e| CordisError::trajectory(name, e.to_string()))?;
                Ok((obs, "(frames, particles, 2), planar: z = 0".into()))
            }
            _ => Err(e),
        },
    }
}

/// The mapping's note of a unit conversion: empty for metres, ` → m (×factor)` otherwise.
pub(crate) fn to_metres(factor: f64) -> String {
    if factor == 1.0 {
        String::new()
    } else {
        format!(" → m (×{factor})")
    }
}

/// `names` as printed in a mapping: the first few, then how many more.
pub(crate) fn list_names(names: &[String]) -> String {
    const SHOWN: usize = 6;
    let mut s: Vec<String> = names
        .iter()
        .take(SHOWN)
        .map(|n| printable(n).to_string())
        .collect();
    if names.len() > SHOWN {
        s.push(format!("… {} more", names.len() - SHOWN));
    }
    s.join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_and_delimiters_parse_or_name_the_option() {
        assert_eq!(Units::parse("MM"), Some(Units::Mm));
        assert_eq!(Units::parse("metres"), Some(Units::M));
        assert_eq!(Units::parse("px"), None);
        let e = Units::parse_arg("--units", "inch").unwrap_err().to_string();
        assert_eq!(e, "--units: `inch` is not a length unit: m, cm or mm");
        assert_eq!(
            Delimiter::parse_arg("--delimiter", "tab").unwrap(),
            Delimiter::Char('\t')
        );
        assert!(Delimiter::parse_arg("--delimiter", "ab").is_err());
        assert!(Delimiter::parse_arg("--delimiter", "5").is_err());
    }

    #[test]
    fn formats_by_extension_name_every_readable_one() {
        for (n, f) in [
            ("a.C3D", InputFormat::C3d),
            ("a.trc", InputFormat::Trc),
            ("a.npz", InputFormat::Npz),
            ("a.tsv", InputFormat::Csv),
        ] {
            assert_eq!(InputFormat::from_path(Path::new(n)).unwrap(), f);
        }
        let e = InputFormat::from_path(Path::new("a.mas"))
            .unwrap_err()
            .to_string();
        assert!(e.contains(".trc, .c3d, .npz"), "{e}");
    }

    #[test]
    fn a_planar_npy_reads_with_z_zero_and_gaps_kept() {
        let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
        let header = "{'descr': '<f8', 'fortran_order': False, 'shape': (1, 2, 2), }\n";
        bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
        bytes.extend_from_slice(header.as_bytes());
        for v in [1.0, 2.0, f64::NAN, f64::NAN] {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
        let opts = ReadOptions {
            units: Some(Units::Cm),
            ..Default::default()
        };
        let im = parse_markers("p.npy", InputFormat::Npy, &bytes, &opts).unwrap();
        let v = im.observations.as_flat();
        assert_eq!(&v[..3], &[0.01, 0.02, 0.0]);
        assert!(v[3..].iter().all(|x| x.is_nan()));
        assert!(im.mapping.contains("planar"), "{}", im.mapping);
        assert!(im.mapping.contains("units cm"), "{}", im.mapping);
    }

    #[test]
    fn a_column_mapping_for_a_binary_format_is_refused() {
        let opts = ReadOptions {
            columns: Some("x=X".into()),
            ..Default::default()
        };
        let e = parse_markers("a.trc", InputFormat::Trc, b"", &opts)
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("--columns: a column mapping applies to"),
            "{e}"
        );
    }
}
