//! Text tables of marker positions with named columns: any column order, headers matched
//! case-insensitively, long (one row per frame × marker) or wide (one row per frame,
//! `M_x, M_y, M_z` per marker), a frame and/or a time column (the time gives `dt`), any
//! delimiter (sniffed from the header: tab, `;`, `,`, else whitespace), units m/cm/mm.
//!
//! Columns are named by a mapping (`--columns frame=Frame,particle=Marker,x=X,y=Y,z=Z`; wide
//! tables with `*` for the marker's name, `x=*_X`); a key it does not give is found by its
//! usual names (below). A header cell may carry its unit, `X [mm]` or `X (mm)`; cells of one
//! table must agree, and with `--units` too (mixed units are refused, not guessed).
//!
//! Missing values — an empty cell, `nan`, an absent row — are NaN (missing observations),
//! never zeros. With no z column the scene is planar: z = 0 where x is observed.
//!
//! A time column gives `dt` as the step of the frame grid `t0 + k dt` it fits: every row's
//! time must lie within 1 % of `dt` of its grid point (times printed with few decimals still
//! fit; a jitter of a whole frame does not).

use std::collections::HashMap;

use super::csv::parse_index;
use super::markers::{list_names, Delimiter, Imported, InputFormat, ReadOptions, Units};
use crate::error::{printable, CordisError, Result};
use crate::Observations;

/// The usual names of each key, lower case, tried when the mapping does not name one.
const FRAME_NAMES: &[&str] = &["frame", "frame#", "frames", "frame_index", "frame_number"];
const TIME_NAMES: &[&str] = &["time", "t", "timestamp", "time_s", "seconds"];
const PARTICLE_NAMES: &[&str] = &[
    "particle",
    "marker",
    "marker_name",
    "point",
    "track",
    "track_id",
    "id",
    "name",
    "label",
];
const AXES: [&str; 3] = ["x", "y", "z"];

/// Rows with gaps may leave a table at most this many times larger than the cells given.
const SPARSE_LIMIT: u64 = 64;

/// A `--columns` mapping: header names (or `*` patterns, wide) for each key.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ColumnMap {
    pub frame: Option<String>,
    pub time: Option<String>,
    pub particle: Option<String>,
    pub axes: [Option<String>; 3],
}

impl ColumnMap {
    /// Parses `key=Column,key=Column…`; keys `frame`, `time`, `particle` (or `marker`), `x`,
    /// `y`, `z`. Errors name `--columns` and the entry.
    pub fn parse(spec: &str) -> Result<ColumnMap> {
        let err = |m: String| CordisError::argument("--columns", m);
        let mut map = ColumnMap::default();
        for entry in spec.split(',').map(str::trim).filter(|e| !e.is_empty()) {
            let Some((key, column)) = entry.split_once('=') else {
                return Err(err(format!(
                    "`{}` is not key=Column (keys: frame, time, particle, x, y, z)",
                    printable(entry)
                )));
            };
            let (key, column) = (key.trim().to_ascii_lowercase(), column.trim());
            if column.is_empty() {
                return Err(err(format!("`{}` names no column", printable(entry))));
            }
            let slot = match key.as_str() {
                "frame" => &mut map.frame,
                "time" | "t" => &mut map.time,
                "particle" | "marker" => &mut map.particle,
                "x" => &mut map.axes[0],
                "y" => &mut map.axes[1],
                "z" => &mut map.axes[2],
                _ => {
                    return Err(err(format!(
                        "unknown key `{}` (keys: frame, time, particle, x, y, z)",
                        printable(&key)
                    )))
                }
            };
            if slot.is_some() {
                return Err(err(format!("key `{key}` is given twice")));
            }
            *slot = Some(column.to_string());
        }
        let wide = map
            .axes
            .iter()
            .flatten()
            .filter(|c| c.contains('*'))
            .count();
        if wide > 0 && wide != map.axes.iter().flatten().count() {
            return Err(err(
                "either every coordinate is a `*` pattern (wide table) or none is (long)".into(),
            ));
        }
        if wide > 0 && map.particle.is_some() {
            return Err(err(
                "a wide table (`*` patterns) has no particle column: the marker's name is the `*`"
                    .into(),
            ));
        }
        Ok(map)
    }

    fn is_wide(&self) -> bool {
        self.axes.iter().flatten().any(|c| c.contains('*'))
    }
}

/// Whether `text` starts with cordis' own header `frame,particle,x,y,z` (read by
/// [`super::csv`], whose rules it keeps).
pub(crate) fn is_cordis_header(text: &str) -> bool {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    text.lines()
        .find(|l| !l.trim().is_empty())
        .is_some_and(|h| {
            h.split(',')
                .map(str::trim)
                .eq(["frame", "particle", "x", "y", "z"])
        })
}

/// One header cell: its text, its name without a unit, and the unit it states.
struct Column {
    text: String,
    base: String,
    unit: Option<String>,
}

impl Column {
    fn new(text: &str) -> Column {
        let text = unquote(text).to_string();
        let (base, unit) = split_unit(&text);
        Column {
            base: base.to_ascii_lowercase(),
            unit,
            text,
        }
    }

    fn is(&self, name: &str) -> bool {
        self.base == name.to_ascii_lowercase() || self.text.eq_ignore_ascii_case(name)
    }
}

/// `X [mm]` / `X (mm)` → (`X`, `mm`); anything else is its own name.
fn split_unit(text: &str) -> (String, Option<String>) {
    for (open, close) in [('[', ']'), ('(', ')')] {
        if let (Some(start), true) = (text.rfind(open), text.ends_with(close)) {
            let unit = text[start + 1..text.len() - 1].trim();
            let base = text[..start].trim();
            if !base.is_empty() && !unit.is_empty() {
                return (base.to_string(), Some(unit.to_string()));
            }
        }
    }
    (text.trim().to_string(), None)
}

fn unquote(cell: &str) -> &str {
    let c = cell.trim();
    c.strip_prefix('"')
        .and_then(|c| c.strip_suffix('"'))
        .unwrap_or(c)
        .trim()
}

fn split(line: &str, d: Delimiter) -> Vec<&str> {
    match d {
        Delimiter::Char(c) => line.split(c).map(unquote).collect(),
        Delimiter::Whitespace => line.split_whitespace().map(unquote).collect(),
    }
}

/// The delimiter a header line uses: tab, then `;`, then `,`, else whitespace.
fn sniff(header: &str) -> Delimiter {
    for c in ['\t', ';', ','] {
        if header.contains(c) {
            return Delimiter::Char(c);
        }
    }
    Delimiter::Whitespace
}

/// Where each key's values are, in header indices.
struct Layout {
    frame: Option<usize>,
    time: Option<usize>,
    kind: LayoutKind,
}

enum LayoutKind {
    /// One row per frame × marker; no particle column: one marker.
    Long {
        particle: Option<usize>,
        axes: [Option<usize>; 3],
    },
    /// One row per frame; per marker its name and its coordinate columns.
    Wide {
        markers: Vec<(String, [Option<usize>; 3])>,
    },
}

/// Parses a table of markers (module docs); `name` starts every error's place.
pub(crate) fn parse_table(name: &str, text: &str, options: &ReadOptions) -> Result<Imported> {
    let map = match &options.columns {
        Some(spec) => ColumnMap::parse(spec)?,
        None => ColumnMap::default(),
    };
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(k, l)| (k + 1, l))
        .filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
    let Some((hline, header)) = lines.next() else {
        return Err(CordisError::trajectory(
            name,
            "empty file: expected a header naming the columns",
        ));
    };
    let hplace = format!("{name}:{hline}");
    let delimiter = options.delimiter.unwrap_or_else(|| sniff(header));
    let columns: Vec<Column> = split(header, delimiter)
        .into_iter()
        .map(Column::new)
        .collect();
    let layout = resolve(&hplace, &columns, &map)?;
    let unread = unread_columns(&columns, &layout);
    // A column the guessed layout does not read (`frame,particle,x,y,z,w`) was dropped without
    // a word: the user's data may be in it. A mapping says which columns are meant, so with
    // `--columns` the rest are left unread on purpose (the mapping line lists them).
    if let (None, Some(&k)) = (&options.columns, unread.first()) {
        return Err(CordisError::trajectory(
            &hplace,
            format!(
                "column `{}` (field {}) is not read (read: {}): remove it, or map the columns \
                 with --columns (the others are then left unread)",
                printable(&columns[k].text),
                k + 1,
                read_columns(&layout)
                    .iter()
                    .map(|&c| printable(&columns[c].text))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        ));
    }
    let (factor, units_note) = units(&hplace, &columns, &layout, options.units)?;
    let time_factor = time_units(&hplace, &columns, layout.time)?;
    let rows: Vec<(usize, Vec<&str>)> = lines.map(|(k, l)| (k, split(l, delimiter))).collect();
    if rows.is_empty() {
        return Err(CordisError::trajectory(
            name,
            "no rows after the header: a trajectory needs at least one frame",
        ));
    }
    let decimal_comma = delimiter == Delimiter::Char(';');
    let cells = Cells {
        name,
        columns: &columns,
        decimal_comma,
    };
    for (line, fields) in &rows {
        let trailing = fields.len() == columns.len() + 1 && fields.last() == Some(&"");
        if fields.len() != columns.len() && !trailing {
            return Err(CordisError::trajectory(
                format!("{name}:{line}"),
                format!(
                    "{} row: {} fields, the header has {}",
                    if fields.len() < columns.len() {
                        "short"
                    } else {
                        "long"
                    },
                    fields.len(),
                    columns.len()
                ),
            ));
        }
    }
    let (frame_of_row, dt) = frames(&cells, &rows, &layout, time_factor)?;
    let (observations, labels) = fill(&cells, &rows, &layout, &frame_of_row, factor)?;
    let mut observations = observations;
    observations.dt = dt;
    let mut mapping = describe(&columns, &layout, delimiter, &labels, units_note, dt);
    if !unread.is_empty() {
        let names: Vec<String> = unread
            .iter()
            .map(|&k| format!("`{}`", printable(&columns[k].text)))
            .collect();
        mapping += &format!("; not read: {}", names.join(", "));
    }
    Ok(Imported {
        observations,
        format: InputFormat::Csv,
        labels,
        mapping,
    })
}

/// The header indices of each key, from the mapping and else the usual names.
fn resolve(place: &str, columns: &[Column], map: &ColumnMap) -> Result<Layout> {
    let find_named = |key: &str, column: &str| -> Result<usize> {
        columns.iter().position(|c| c.is(column)).ok_or_else(|| {
            CordisError::trajectory(
                place,
                format!(
                    "--columns names {key}={}, but the header has no such column (columns: {})",
                    printable(column),
                    header_list(columns)
                ),
            )
        })
    };
    let find = |key: &str, given: &Option<String>, usual: &[&str]| -> Result<Option<usize>> {
        match given {
            Some(c) => find_named(key, c).map(Some),
            None => Ok(usual
                .iter()
                .find_map(|u| columns.iter().position(|c| c.is(u)))),
        }
    };
    let frame = find("frame", &map.frame, FRAME_NAMES)?;
    let time = find("time", &map.time, TIME_NAMES)?;
    if map.is_wide() {
        return Ok(Layout {
            frame,
            time,
            kind: LayoutKind::Wide {
                markers: wide_markers(place, columns, &map.axes)?,
            },
        });
    }
    let particle = find("particle", &map.particle, PARTICLE_NAMES)?;
    let mut axes = [None; 3];
    for (k, axis) in AXES.iter().enumerate() {
        axes[k] = find(axis, &map.axes[k], &[axis])?;
    }
    if axes[0].is_some() && axes[1].is_some() {
        return Ok(Layout {
            frame,
            time,
            kind: LayoutKind::Long { particle, axes },
        });
    }
    if particle.is_none() {
        let patterns = [Some("*_x".into()), None, None];
        if let Ok(markers) = wide_markers(place, columns, &patterns) {
            return Ok(Layout {
                frame,
                time,
                kind: LayoutKind::Wide { markers },
            });
        }
    }
    Err(CordisError::trajectory(
        place,
        format!(
            "cannot tell the columns of header `{}`: name them with --columns, e.g. \
             frame=Frame,particle=Marker,x=X,y=Y,z=Z (long) or time=Time,x=*_X,y=*_Y,z=*_Z (wide)",
            header_list(columns)
        ),
    ))
}

/// The header indices the layout reads, in header order.
fn read_columns(layout: &Layout) -> Vec<usize> {
    let mut read: Vec<usize> = [layout.frame, layout.time].into_iter().flatten().collect();
    match &layout.kind {
        LayoutKind::Long { particle, axes } => {
            read.extend(particle.iter().chain(axes.iter().flatten()));
        }
        LayoutKind::Wide { markers } => {
            read.extend(markers.iter().flat_map(|(_, axes)| axes.iter().flatten()));
        }
    }
    read.sort_unstable();
    read.dedup();
    read
}

/// The named header cells the layout does not read (an empty cell, a trailing delimiter,
/// names nothing).
fn unread_columns(columns: &[Column], layout: &Layout) -> Vec<usize> {
    let read = read_columns(layout);
    (0..columns.len())
        .filter(|k| !read.contains(k) && !columns[*k].text.is_empty())
        .collect()
}

fn header_list(columns: &[Column]) -> String {
    printable(
        &columns
            .iter()
            .map(|c| c.text.as_str())
            .collect::<Vec<_>>()
            .join(", "),
    )
}

/// The markers of a wide table: every column that fits the x pattern names a marker, whose y
/// (and z) columns must exist. Patterns not given follow x's (`*_X` → `*_Y`, `*_Z`). When
/// sniffing (`*_x`), `.x`, ` x`, `:x` and `-x` separators fit as well.
fn wide_markers(
    place: &str,
    columns: &[Column],
    patterns: &[Option<String>; 3],
) -> Result<Vec<(String, [Option<usize>; 3])>> {
    let x = patterns[0].clone().ok_or_else(|| {
        CordisError::argument("--columns", "a wide table needs the x pattern (x=*_X)")
    })?;
    let derive = |axis: char| -> String {
        match x.rfind(['x', 'X']) {
            Some(at) => {
                let upper = x[at..].starts_with('X');
                let a = if upper {
                    axis.to_ascii_uppercase()
                } else {
                    axis
                };
                format!("{}{a}{}", &x[..at], &x[at + 1..])
            }
            None => x.clone(),
        }
    };
    let y = patterns[1].clone().unwrap_or_else(|| derive('y'));
    let z = patterns[2].clone().or_else(|| Some(derive('z')));
    let z_given = patterns[2].is_some();
    let sniffing = x == "*_x";
    let seps: &[&str] = if sniffing {
        &["_", ".", " ", ":", "-"]
    } else {
        &[""]
    };
    let matches = |pattern: &str, column: &Column| -> Option<String> {
        for sep in seps {
            let p = if sniffing {
                pattern.replacen('_', sep, 1)
            } else {
                pattern.to_string()
            };
            let (pre, post) = p.split_once('*')?;
            let t = &column.text;
            let (tl, pl, sl) = (
                t.to_ascii_lowercase(),
                pre.to_ascii_lowercase(),
                post.to_ascii_lowercase(),
            );
            if tl.len() > pl.len() + sl.len() && tl.starts_with(&pl) && tl.ends_with(&sl) {
                let name = &t[pre.len()..t.len() - post.len()];
                if !name.trim().is_empty() {
                    return Some(name.to_string());
                }
            }
        }
        None
    };
    let column_of = |pattern: &str, marker: &str| -> Option<usize> {
        columns
            .iter()
            .position(|c| matches(pattern, c).is_some_and(|m| m.eq_ignore_ascii_case(marker)))
    };
    let mut markers = Vec::new();
    for c in columns {
        let Some(marker) = matches(&x, c) else {
            continue;
        };
        if markers
            .iter()
            .any(|(m, _): &(String, _)| m.eq_ignore_ascii_case(&marker))
        {
            return Err(CordisError::trajectory(
                place,
                format!("marker `{}` has two x columns", printable(&marker)),
            ));
        }
        let xi = column_of(&x, &marker);
        let yi = column_of(&y, &marker).ok_or_else(|| {
            CordisError::trajectory(
                place,
                format!(
                    "marker `{}` has an x column but no y column (pattern `{}`)",
                    printable(&marker),
                    printable(&y)
                ),
            )
        })?;
        let zi = z.as_deref().and_then(|z| column_of(z, &marker));
        if z_given && zi.is_none() {
            return Err(CordisError::trajectory(
                place,
                format!("marker `{}` has no z column", printable(&marker)),
            ));
        }
        markers.push((marker, [xi, Some(yi), zi]));
    }
    if markers.is_empty() {
        return Err(CordisError::trajectory(
            place,
            format!(
                "no column fits the x pattern `{}` (columns: {})",
                printable(&x),
                header_list(columns)
            ),
        ));
    }
    let with_z = markers.iter().filter(|(_, a)| a[2].is_some()).count();
    if with_z != 0 && with_z != markers.len() {
        let (m, _) = markers.iter().find(|(_, a)| a[2].is_none()).expect("one");
        return Err(CordisError::trajectory(
            place,
            format!(
                "marker `{}` has no z column while others have one",
                printable(m)
            ),
        ));
    }
    Ok(markers)
}

/// The factor to metres of the coordinate columns, and a note for the mapping.
fn units(
    place: &str,
    columns: &[Column],
    layout: &Layout,
    given: Option<Units>,
) -> Result<(f64, Option<String>)> {
    let coords: Vec<usize> = match &layout.kind {
        LayoutKind::Long { axes, .. } => axes.iter().flatten().copied().collect(),
        LayoutKind::Wide { markers } => markers
            .iter()
            .flat_map(|(_, a)| a.iter().flatten().copied())
            .collect(),
    };
    let mut stated: Option<(Units, usize)> = None;
    for &k in &coords {
        let Some(text) = &columns[k].unit else {
            continue;
        };
        let Some(u) = Units::parse(text) else {
            return Err(CordisError::trajectory(
                place,
                format!(
                    "column `{}`: unit `{}` is not a length unit (m, cm, mm)",
                    printable(&columns[k].text),
                    printable(text)
                ),
            ));
        };
        match stated {
            Some((v, first)) if v != u => {
                return Err(CordisError::trajectory(
                    place,
                    format!(
                        "mixed units: column `{}` is in {}, column `{}` in {}",
                        printable(&columns[first].text),
                        v.name(),
                        printable(&columns[k].text),
                        u.name()
                    ),
                ))
            }
            Some(_) => {}
            None => stated = Some((u, k)),
        }
    }
    if let (Some((s, k)), Some(g)) = (stated, given) {
        if s != g {
            return Err(CordisError::trajectory(
                place,
                format!(
                    "mixed units: --units {} but column `{}` is in {}",
                    g.name(),
                    printable(&columns[k].text),
                    s.name()
                ),
            ));
        }
    }
    let (u, from) = match (stated, given) {
        (Some((s, _)), _) => (s, "the header"),
        (None, Some(g)) => (g, "--units"),
        (None, None) => return Ok((1.0, None)),
    };
    let note = (u != Units::M)
        .then(|| format!("units {} ({from}) → m (×{})", u.name(), u.metres()))
        .or_else(|| Some(format!("units m ({from})")));
    Ok((u.metres(), note))
}

/// The factor to seconds of the time column (`[s]`, `[ms]`, or none: s).
fn time_units(place: &str, columns: &[Column], time: Option<usize>) -> Result<f64> {
    let Some(k) = time else { return Ok(1.0) };
    match columns[k]
        .unit
        .as_deref()
        .map(str::to_ascii_lowercase)
        .as_deref()
    {
        None | Some("s") | Some("sec") => Ok(1.0),
        Some("ms") => Ok(1e-3),
        Some(other) => Err(CordisError::trajectory(
            place,
            format!(
                "time column `{}`: unit `{}` is not s or ms",
                printable(&columns[k].text),
                printable(other)
            ),
        )),
    }
}

/// Reads the cells of one table, with its file name for places.
struct Cells<'a> {
    name: &'a str,
    columns: &'a [Column],
    decimal_comma: bool,
}

impl Cells<'_> {
    fn error(&self, line: usize, k: usize, message: String) -> CordisError {
        CordisError::trajectory(
            format!("{}:{line}", self.name),
            format!(
                "column `{}` (field {}): {message}",
                printable(&self.columns[k].text),
                k + 1
            ),
        )
    }

    /// A number that must be there and finite.
    fn number(&self, line: usize, k: usize, cell: &str) -> Result<f64> {
        match self.value(line, k, cell)? {
            Some(v) => Ok(v),
            None => Err(self.error(line, k, "empty: a value is needed here".into())),
        }
    }

    /// A coordinate: a finite number, or None when empty or `nan` (missing).
    fn value(&self, line: usize, k: usize, cell: &str) -> Result<Option<f64>> {
        if cell.is_empty() || cell.eq_ignore_ascii_case("nan") {
            return Ok(None);
        }
        let owned;
        let text = if self.decimal_comma && cell.contains(',') {
            owned = cell.replace(',', ".");
            owned.as_str()
        } else {
            cell
        };
        match text.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(Some(v)),
            Ok(_) => Err(self.error(line, k, format!("{cell} is not finite"))),
            Err(_) => Err(self.error(line, k, format!("`{}` is not a number", printable(cell)))),
        }
    }
}

/// Each row's frame index (from the frame column, the time column, or row order) and `dt`.
fn frames(
    cells: &Cells<'_>,
    rows: &[(usize, Vec<&str>)],
    layout: &Layout,
    time_factor: f64,
) -> Result<(Vec<u64>, Option<f64>)> {
    let given: Option<Vec<u64>> = match layout.frame {
        Some(k) => Some(
            rows.iter()
                .map(|(line, f)| {
                    parse_index(f[k], "frame")
                        .map_err(|m| CordisError::trajectory(format!("{}:{line}", cells.name), m))
                })
                .collect::<Result<_>>()?,
        ),
        None => None,
    };
    let times: Option<Vec<f64>> = match layout.time {
        Some(k) => Some(
            rows.iter()
                .map(|(line, f)| Ok(cells.number(*line, k, f[k])? * time_factor))
                .collect::<Result<_>>()?,
        ),
        None => None,
    };
    let frame_of_row: Vec<u64> = match (&given, &times) {
        (Some(f), _) => {
            let first = *f.iter().min().expect("rows");
            f.iter().map(|v| v - first).collect()
        }
        (None, Some(t)) => time_grid(t),
        (None, None) => match layout.kind {
            LayoutKind::Wide { .. } => (0..rows.len() as u64).collect(),
            LayoutKind::Long {
                particle: Some(_), ..
            } => {
                return Err(CordisError::trajectory(
                    cells.name,
                    "one row per frame × marker needs a frame or a time column \
                     (--columns frame=… or time=…)",
                ))
            }
            LayoutKind::Long { particle: None, .. } => (0..rows.len() as u64).collect(),
        },
    };
    let dt = match &times {
        Some(t) => dt_of(cells, rows, t, &frame_of_row, layout.time.expect("time"))?,
        None => None,
    };
    Ok((frame_of_row, dt))
}

/// Frame indices `round((t - t0) / step)` of rows that have a time column and no frame
/// column, `step` the median step between distinct times (robust to absent frames); [`dt_of`]
/// then fits `dt` over the whole grid and checks every row against it.
fn time_grid(times: &[f64]) -> Vec<u64> {
    let mut distinct = times.to_vec();
    distinct.sort_by(f64::total_cmp);
    distinct.dedup();
    if distinct.len() == 1 {
        return vec![0; times.len()];
    }
    let mut steps: Vec<f64> = distinct.windows(2).map(|w| w[1] - w[0]).collect();
    steps.sort_by(f64::total_cmp);
    let step = steps[steps.len() / 2];
    let t0 = distinct[0];
    times
        .iter()
        .map(|t| ((t - t0) / step).round() as u64)
        .collect()
}

/// The frame grid's `dt`, fitted from the first and last frames, with every row checked.
fn dt_of(
    cells: &Cells<'_>,
    rows: &[(usize, Vec<&str>)],
    times: &[f64],
    frame_of_row: &[u64],
    k: usize,
) -> Result<Option<f64>> {
    let (lo, hi) = (0..rows.len()).fold((0, 0), |(lo, hi), r| {
        (
            if frame_of_row[r] < frame_of_row[lo] {
                r
            } else {
                lo
            },
            if frame_of_row[r] > frame_of_row[hi] {
                r
            } else {
                hi
            },
        )
    });
    if frame_of_row[hi] == frame_of_row[lo] {
        return Ok(None);
    }
    let dt = (times[hi] - times[lo]) / (frame_of_row[hi] - frame_of_row[lo]) as f64;
    if !(dt.is_finite() && dt > 0.0) {
        return Err(cells.error(
            rows[hi].0,
            k,
            format!("time does not increase with the frame (step {dt} s)"),
        ));
    }
    for (r, (line, _)) in rows.iter().enumerate() {
        let expect = times[lo] + (frame_of_row[r] as f64 - frame_of_row[lo] as f64) * dt;
        if (times[r] - expect).abs() > 0.01 * dt {
            return Err(cells.error(
                *line,
                k,
                format!(
                    "time {} s is off the frame grid (frame {} is at {expect} s with dt {dt} s): \
                     the frames are not evenly spaced",
                    times[r], frame_of_row[r]
                ),
            ));
        }
    }
    Ok(Some(dt))
}

/// (frame, particle, line, axes columns) of one marker observation a row holds.
type Entry = (u64, u64, usize, [Option<usize>; 3]);

/// The table of observations and the markers' names.
fn fill(
    cells: &Cells<'_>,
    rows: &[(usize, Vec<&str>)],
    layout: &Layout,
    frame_of_row: &[u64],
    factor: f64,
) -> Result<(Observations, Vec<String>)> {
    let mut entries: Vec<Entry> = Vec::new();
    let labels: Vec<String> = match &layout.kind {
        LayoutKind::Wide { markers } => {
            for (r, (line, _)) in rows.iter().enumerate() {
                for (i, (_, axes)) in markers.iter().enumerate() {
                    entries.push((frame_of_row[r], i as u64, *line, *axes));
                }
            }
            markers.iter().map(|(m, _)| m.clone()).collect()
        }
        LayoutKind::Long { particle, axes } => {
            let (index, labels) = long_markers(cells, rows, *particle)?;
            for (r, (line, _)) in rows.iter().enumerate() {
                entries.push((frame_of_row[r], index[r], *line, *axes));
            }
            labels
        }
    };
    let data = place_entries(cells, rows, frame_of_row, &labels, entries, factor)?;
    let frames = frame_of_row.iter().max().map_or(0, |m| m + 1);
    let obs = Observations::from_flat(frames as usize, labels.len(), data)
        .map_err(|e| CordisError::trajectory(cells.name, e.to_string()))?;
    Ok((obs, labels))
}

/// A long table's marker of each row (its index) and the markers' names: the particle
/// column's numbers as indices when every one is a number (refused when the largest would
/// leave the table almost empty), else its names in order of first appearance; one marker
/// `0` without a particle column.
fn long_markers(
    cells: &Cells<'_>,
    rows: &[(usize, Vec<&str>)],
    particle: Option<usize>,
) -> Result<(Vec<u64>, Vec<String>)> {
    let ids: Vec<&str> = match particle {
        Some(k) => rows.iter().map(|(_, f)| f[k]).collect(),
        None => vec!["0"; rows.len()],
    };
    if let Some(k) = particle {
        if let Some(r) = ids.iter().position(|id| id.is_empty()) {
            return Err(cells.error(rows[r].0, k, "empty: a marker is needed here".into()));
        }
    }
    let numeric: Option<Vec<u64>> = ids.iter().map(|id| parse_index(id, "").ok()).collect();
    Ok(match numeric {
        Some(v) => {
            let n = v.iter().max().map_or(0, |m| m + 1);
            if n > SPARSE_LIMIT.saturating_mul(rows.len() as u64).max(1 << 16) {
                let r = v.iter().position(|&i| i + 1 == n).expect("max");
                return Err(cells.error(
                    rows[r].0,
                    particle.unwrap_or(0),
                    format!(
                        "particle {} leaves the table almost empty: an index is wrong",
                        n - 1
                    ),
                ));
            }
            (v, (0..n).map(|i| i.to_string()).collect())
        }
        None => {
            let mut seen: HashMap<&str, u64> = HashMap::new();
            let mut labels = Vec::new();
            let index = ids
                .iter()
                .map(|id| {
                    *seen.entry(id).or_insert_with(|| {
                        labels.push(id.to_string());
                        labels.len() as u64 - 1
                    })
                })
                .collect();
            (index, labels)
        }
    })
}

/// The frames × markers table (frame-major, 3 per cell, metres after `factor`, NaN where no
/// row gives the cell; z = 0 for a planar table's observed cells), refused when the frames
/// would leave it almost empty or a cell is given twice.
fn place_entries(
    cells: &Cells<'_>,
    rows: &[(usize, Vec<&str>)],
    frame_of_row: &[u64],
    labels: &[String],
    entries: Vec<Entry>,
    factor: f64,
) -> Result<Vec<f64>> {
    let n = labels.len() as u64;
    let frames = frame_of_row.iter().max().map_or(0, |m| m + 1);
    let cells_count = frames.checked_mul(n).filter(|&c| {
        c <= SPARSE_LIMIT
            .saturating_mul(entries.len() as u64)
            .max(1 << 20)
    });
    let Some(count) = cells_count else {
        let r = (0..rows.len())
            .max_by_key(|&r| frame_of_row[r])
            .expect("rows");
        return Err(CordisError::trajectory(
            format!("{}:{}", cells.name, rows[r].0),
            format!(
                "frame {} leaves the {frames} × {n} table almost empty ({} rows): a frame or time is wrong",
                frame_of_row[r],
                rows.len()
            ),
        ));
    };
    let mut data = vec![f64::NAN; count as usize * 3];
    let mut line_of = vec![0usize; count as usize];
    let row_of_line: HashMap<usize, usize> =
        rows.iter().enumerate().map(|(r, (l, _))| (*l, r)).collect();
    for (frame, particle, line, axes) in entries {
        let cell = (frame * n + particle) as usize;
        if line_of[cell] != 0 {
            return Err(CordisError::trajectory(
                format!("{}:{line}", cells.name),
                format!(
                    "duplicate row for frame {frame}, marker `{}` (first given on line {})",
                    printable(&labels[particle as usize]),
                    line_of[cell]
                ),
            ));
        }
        line_of[cell] = line;
        let fields = &rows[row_of_line[&line]].1;
        let mut pos = [f64::NAN; 3];
        for (a, col) in axes.iter().enumerate() {
            if let Some(k) = *col {
                if let Some(v) = cells.value(line, k, fields[k])? {
                    pos[a] = v * factor;
                }
            }
        }
        if axes[2].is_none() && !pos[0].is_nan() {
            pos[2] = 0.0;
        }
        data[cell * 3..cell * 3 + 3].copy_from_slice(&pos);
    }
    Ok(data)
}

/// The mapping as one line: layout, delimiter, columns, markers, units, rate.
fn describe(
    columns: &[Column],
    layout: &Layout,
    delimiter: Delimiter,
    labels: &[String],
    units: Option<String>,
    dt: Option<f64>,
) -> String {
    let col = |k: usize| format!("`{}`", printable(&columns[k].text));
    let mut parts = Vec::new();
    let mut keys = Vec::new();
    if let Some(k) = layout.frame {
        keys.push(format!("frame={}", col(k)));
    }
    if let Some(k) = layout.time {
        keys.push(format!("time={}", col(k)));
    }
    let planar = match &layout.kind {
        LayoutKind::Long { particle, axes } => {
            parts.push(format!("long table ({})", delimiter.describe()));
            if let Some(k) = particle {
                keys.push(format!("particle={}", col(*k)));
            }
            for (a, k) in axes.iter().enumerate() {
                if let Some(k) = k {
                    keys.push(format!("{}={}", AXES[a], col(*k)));
                }
            }
            axes[2].is_none()
        }
        LayoutKind::Wide { markers } => {
            parts.push(format!("wide table ({})", delimiter.describe()));
            if let Some((_, a)) = markers.first() {
                let shown: Vec<String> = a
                    .iter()
                    .enumerate()
                    .filter_map(|(i, k)| k.map(|k| format!("{}={}", AXES[i], col(k))))
                    .collect();
                keys.push(format!("{} for the first marker", shown.join(", ")));
            }
            markers.first().is_some_and(|(_, a)| a[2].is_none())
        }
    };
    parts.push(keys.join(", "));
    parts.push(format!("{} markers: {}", labels.len(), list_names(labels)));
    if planar {
        parts.push("no z column: planar, z = 0".into());
    }
    if let Some(u) = units {
        parts.push(u);
    }
    match (dt, layout.time) {
        (Some(dt), Some(k)) => parts.push(format!("dt {dt} s from {}", col(k))),
        _ => parts.push("no rate in the file".into()),
    }
    parts.join("; ")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(text: &str, columns: Option<&str>, units: Option<Units>) -> Result<Imported> {
        let o = ReadOptions {
            columns: columns.map(str::to_string),
            units,
            delimiter: None,
        };
        parse_table("m.csv", text, &o)
    }

    fn err(text: &str, columns: Option<&str>, units: Option<Units>) -> String {
        read(text, columns, units).unwrap_err().to_string()
    }

    /// Two markers A, B over three frames, dt 0.01 s; B is missing at frame 1.
    fn expected() -> Vec<f64> {
        let n = f64::NAN;
        vec![
            1.0, 2.0, 3.0, 4.0, 5.0, 6.0, //
            1.5, 2.5, 3.5, n, n, n, //
            2.0, 3.0, 4.0, 5.0, 6.0, 7.0,
        ]
    }

    fn same(a: &[f64], b: &[f64]) -> bool {
        a.len() == b.len()
            && a.iter()
                .zip(b)
                .all(|(x, y)| (x.is_nan() && y.is_nan()) || (x - y).abs() < 1e-12)
    }

    #[test]
    fn six_layouts_read_to_the_same_array() {
        let layouts: [(&str, &str, Option<&str>, Option<Units>); 6] = [
            (
                "named columns",
                "Frame,Marker,X,Y,Z\n0,A,1,2,3\n0,B,4,5,6\n1,A,1.5,2.5,3.5\n2,A,2,3,4\n2,B,5,6,7\n",
                None,
                None,
            ),
            (
                "another order, mapped",
                "Z,Y,Name,F,X\n3,2,A,10,1\n6,5,B,10,4\n3.5,2.5,A,11,1.5\n,,B,11,\n4,3,A,12,2\n7,6,B,12,5\n",
                Some("frame=F,particle=Name"),
                None,
            ),
            (
                "a time column",
                "time,marker,x,y,z\n0.00,A,1,2,3\n0.00,B,4,5,6\n0.01,A,1.5,2.5,3.5\n0.02,A,2,3,4\n0.02,B,5,6,7\n",
                None,
                None,
            ),
            (
                "wide",
                "Time;A_X;A_Y;A_Z;B_X;B_Y;B_Z\n0;1;2;3;4;5;6\n0,01;1,5;2,5;3,5;nan;nan;nan\n0,02;2;3;4;5;6;7\n",
                Some("time=Time,x=*_X"),
                None,
            ),
            (
                "tabs",
                "frame\tparticle\tx\ty\tz\n0\tA\t1\t2\t3\n0\tB\t4\t5\t6\n1\tA\t1.5\t2.5\t3.5\n2\tA\t2\t3\t4\n2\tB\t5\t6\t7\n",
                None,
                None,
            ),
            (
                "millimetres",
                "frame marker x y z\n0 A 1000 2000 3000\n0 B 4000 5000 6000\n1 A 1500 2500 3500\n2 A 2000 3000 4000\n2 B 5000 6000 7000\n",
                None,
                Some(Units::Mm),
            ),
        ];
        for (what, text, columns, units) in layouts {
            let im = read(text, columns, units).unwrap_or_else(|e| panic!("{what}: {e}"));
            assert!(
                same(im.observations.as_flat(), &expected()),
                "{what}: {:?}",
                im.observations.as_flat()
            );
            assert_eq!(im.labels, ["A", "B"], "{what}");
            let has_time = text.to_ascii_lowercase().starts_with("time");
            if has_time {
                let dt = im.observations.dt.expect("dt from the time column");
                assert!((dt - 0.01).abs() < 1e-12, "{what}: {dt}");
            }
        }
    }

    #[test]
    fn units_in_the_header_are_read_and_mixed_units_refused() {
        let im = read(
            "t [ms],marker,x [mm],y [mm]\n0,0,1000,0\n10,0,2000,0\n",
            None,
            None,
        )
        .unwrap();
        assert_eq!(im.observations.dt, Some(0.01));
        assert_eq!(&im.observations.as_flat()[3..], &[2.0, 0.0, 0.0]);
        assert!(im.mapping.contains("planar"), "{}", im.mapping);
        let e = err("frame,marker,x [mm],y [cm]\n0,0,1,2\n", None, None);
        assert!(
            e.starts_with("m.csv:1: mixed units: column `x [mm]` is in mm, column `y [cm]` in cm"),
            "{e}"
        );
        let e = err(
            "frame,marker,x [mm],y [mm]\n0,0,1,2\n",
            None,
            Some(Units::Cm),
        );
        assert!(
            e.starts_with("m.csv:1: mixed units: --units cm but column `x [mm]` is in mm"),
            "{e}"
        );
    }

    #[test]
    fn bad_input_names_file_line_and_column() {
        let e = err(
            "Frame,Marker,X,Y,Z\n0,A,1,2,3\n",
            Some("particle=Label"),
            None,
        );
        assert!(
            e.starts_with("m.csv:1: --columns names particle=Label, but the header has no such column (columns: Frame, Marker, X, Y, Z)"),
            "{e}"
        );
        let e = err("frame,marker,x,y,z\n0,A,1,2,3\n1,A,1,oops,3\n", None, None);
        assert_eq!(e, "m.csv:3: column `y` (field 4): `oops` is not a number");
        let e = err("frame,marker,x,y,z\n0,A,1,2,3\n1,A,1,2\n", None, None);
        assert_eq!(e, "m.csv:3: short row: 4 fields, the header has 5");
        let e = err("frame,marker,x,y,z\n0,A,1,2,3\n0,A,1,2,3\n", None, None);
        assert!(
            e.starts_with("m.csv:3: duplicate row for frame 0, marker `A` (first given on line 2)"),
            "{e}"
        );
        let e = err(
            "time,marker,x,y,z\n0,A,1,2,3\n0.01,A,1,2,3\n0.025,A,1,2,3\n",
            None,
            None,
        );
        assert!(e.contains("off the frame grid"), "{e}");
        let e = err("a,b,c\n1,2,3\n", None, None);
        assert!(
            e.starts_with("m.csv:1: cannot tell the columns of header `a, b, c`"),
            "{e}"
        );
        let e = err("marker,x,y,z\nA,1,2,3\n", None, None);
        assert!(e.contains("needs a frame or a time column"), "{e}");
        assert!(ColumnMap::parse("x=*_X,y=Y").is_err());
        let e = ColumnMap::parse("speed=v").unwrap_err().to_string();
        assert!(e.starts_with("--columns: unknown key `speed`"), "{e}");
    }

    #[test]
    fn a_column_the_layout_does_not_read_is_refused_unless_mapped() {
        // `w` was dropped without a word: the user's data may be in it.
        let e = err("frame,particle,x,y,z,w\n0,0,1,2,3,4\n", None, None);
        assert_eq!(
            e,
            "m.csv:1: column `w` (field 6) is not read (read: frame, particle, x, y, z): \
             remove it, or map the columns with --columns (the others are then left unread)"
        );
        let e = err("Time;K_X;K_Y;K_Z;Quality\n0;1;2;3;9\n", None, None);
        assert!(
            e.starts_with("m.csv:1: column `Quality` (field 5) is not read (read: Time, K_X"),
            "{e}"
        );
        // Mapped: the rest is left unread on purpose, and the mapping line says so.
        let im = read(
            "frame,particle,x,y,z,w\n0,0,1,2,3,4\n",
            Some("frame=frame,particle=particle,x=x,y=y,z=z"),
            None,
        )
        .unwrap();
        assert_eq!(im.observations.as_flat(), &[1.0, 2.0, 3.0]);
        assert!(im.mapping.ends_with("; not read: `w`"), "{}", im.mapping);
        // A trailing delimiter names no column.
        let im = read("frame,particle,x,y,z,\n0,0,1,2,3,\n", None, None).unwrap();
        assert_eq!(im.observations.as_flat(), &[1.0, 2.0, 3.0]);
    }

    #[test]
    fn numeric_marker_ids_are_indices_and_names_keep_their_order() {
        let im = read("frame,id,x,y,z\n0,1,1,1,1\n0,0,0,0,0\n", None, None).unwrap();
        assert_eq!(im.labels, ["0", "1"]);
        assert_eq!(&im.observations.as_flat()[..3], &[0.0, 0.0, 0.0]);
        let im = read(
            "frame,marker,x,y,z\n0,zeta,1,1,1\n0,alpha,0,0,0\n",
            None,
            None,
        )
        .unwrap();
        assert_eq!(im.labels, ["zeta", "alpha"]);
    }

    #[test]
    fn sniffed_wide_tables_take_the_usual_separators() {
        let im = read(
            "frame,knee.x,knee.y,knee.z,hip.x,hip.y,hip.z\n1,1,2,3,4,5,6\n",
            None,
            None,
        )
        .unwrap();
        assert_eq!(im.labels, ["knee", "hip"]);
        assert_eq!(im.observations.as_flat(), &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
        assert!(
            im.mapping.starts_with("wide table (`,`-separated)"),
            "{}",
            im.mapping
        );
    }
}
