//! The self-contained HTML motion viewer (`cordis render`).
//!
//! [`render_html`] turns a scene and one or two trajectories into a single page: the viewer's
//! JavaScript and CSS (`render/viewer.js`, `render/viewer.css`, compiled in) and the data as
//! JSON in a `<script type="application/json">` element. The page loads nothing from the
//! network, so it can be mailed, archived, or opened offline years later.
//!
//! Positions are stored as integers on a grid of step `extent × 1e-6` (about six significant
//! digits at the scene's scale), each frame as the difference from the previous one: small
//! motions give short numbers, which keeps a 5,000-link × 200-frame scene at a few MB. The
//! differences are exact integers, so decoding accumulates no error.

use std::fmt::Write as _;

use cordis_core::{CordisError, LinkKind, Result, Scene, Trajectory};
use serde_json::{json, Value};

const VIEWER_JS: &str = include_str!("render/viewer.js");
const VIEWER_CSS: &str = include_str!("render/viewer.css");

/// Grid step of the stored positions, relative to the largest extent of the motion.
const RELATIVE_STEP: f64 = 1e-6;

/// Builds the viewer page for trajectory `a` (drawn solid) and optionally `b` (the compared
/// motion, e.g. the identified model: drawn dashed in a lighter shade, or side by side).
///
/// Both trajectories must have the scene's particle count and at least one frame; they may
/// differ in length (the shorter one holds its last frame). Time is `frame × dt`, with `dt`
/// from `a` when it carries one, else the scene's.
pub fn render_html(
    scene: &Scene,
    a: &Trajectory,
    b: Option<&Trajectory>,
    title: &str,
) -> Result<String> {
    render_html_labelled(scene, a, b, title, ["trajectory", "compared"])
}

/// The longest motion label kept whole, in characters (a longer one is cut with `…`).
const MAX_LABEL: usize = 48;

/// [`render_html`] with the two motions named `labels` (A, B) in the legend and the
/// side-by-side panels: `cordis render` passes their file names.
pub fn render_html_labelled(
    scene: &Scene,
    a: &Trajectory,
    b: Option<&Trajectory>,
    title: &str,
    labels: [&str; 2],
) -> Result<String> {
    scene.validate()?;
    let labels = labels.map(|l| match l.chars().count() > MAX_LABEL {
        true => l
            .chars()
            .take(MAX_LABEL - 1)
            .chain(['…'])
            .collect::<String>(),
        false => l.to_string(),
    });
    check("trajectory A", scene, a)?;
    if let Some(b) = b {
        check("trajectory B (--compare)", scene, b)?;
    }
    let grid = Grid::new(a, b);
    let frames = a.frames().max(b.map_or(0, Trajectory::frames));
    let meta = json!({
        "format": "cordis-viewer/1",
        "title": title,
        "labels": labels,
        "dt": a.dt.unwrap_or(scene.dt),
        "frames": frames,
        "particles": scene.num_particles(),
        "up": up_vector(scene.gravity),
        "gravity": scene.gravity.iter().any(|&g| g != 0.0),
        "fixed": scene.particles.iter().enumerate()
            .filter(|(_, p)| p.fixed).map(|(i, _)| i).collect::<Vec<_>>(),
        "groups": groups(scene),
        "types": types(scene),
        "quant": { "origin": grid.origin.map(round6), "step": grid.step },
    });
    // The metadata goes through serde_json; the position arrays (millions of numbers) are
    // written straight into the text to avoid a `Value` per number.
    let mut data = meta.to_string();
    data.pop(); // the closing brace; the trajectories follow
    data.push_str(",\"a\":");
    grid.encode(a, &mut data);
    data.push_str(",\"b\":");
    match b {
        Some(b) => grid.encode(b, &mut data),
        None => data.push_str("null"),
    }
    data.push('}');

    let mut page = String::with_capacity(data.len() + VIEWER_JS.len() + VIEWER_CSS.len() + 4096);
    page.push_str("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n");
    page.push_str("<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n");
    // No network: forbid every fetch outright, so a future edit cannot add one by accident.
    page.push_str(
        "<meta http-equiv=\"Content-Security-Policy\" content=\"default-src 'none'; \
         script-src 'unsafe-inline'; style-src 'unsafe-inline'; img-src data:\">\n",
    );
    let _ = writeln!(page, "<title>{}</title>", escape_html(title));
    page.push_str("<style>\n");
    page.push_str(VIEWER_CSS);
    page.push_str("</style>\n</head>\n<body>\n");
    page.push_str("<script id=\"cordis-data\" type=\"application/json\">");
    page.push_str(&escape_script_json(&data));
    page.push_str("</script>\n<script>\n");
    page.push_str(VIEWER_JS);
    page.push_str("</script>\n</body>\n</html>\n");
    Ok(page)
}

/// The trajectory fits the scene: same particle count, at least one frame, finite values.
fn check(place: &str, scene: &Scene, t: &Trajectory) -> Result<()> {
    let n = scene.num_particles();
    if t.particles() != n {
        return Err(CordisError::trajectory(
            place,
            format!(
                "has {} particles, the scene has {n}: it is not a motion of this scene",
                t.particles()
            ),
        ));
    }
    if t.frames() == 0 || n == 0 {
        return Err(CordisError::trajectory(
            place,
            "is empty: there is nothing to show",
        ));
    }
    if let Some(k) = t.as_flat().iter().position(|v| !v.is_finite()) {
        return Err(CordisError::trajectory(
            format!("{place}, frame {}, particle {}", k / (3 * n), (k / 3) % n),
            "not a finite number: the motion diverged",
        ));
    }
    Ok(())
}

/// The integer grid the positions are stored on, shared by both trajectories.
struct Grid {
    origin: [f64; 3],
    step: f64,
}

impl Grid {
    fn new(a: &Trajectory, b: Option<&Trajectory>) -> Self {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for t in std::iter::once(a).chain(b) {
            for c in t.as_flat().chunks_exact(3) {
                for k in 0..3 {
                    lo[k] = lo[k].min(c[k]);
                    hi[k] = hi[k].max(c[k]);
                }
            }
        }
        let extent = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
        // A motionless scene has no extent: use its distance from 0, or 1 m. Coordinates near
        // f64::MAX overflow the extent: the largest finite one still gives a usable grid.
        let size = if extent > 0.0 {
            extent.min(f64::MAX)
        } else {
            lo.iter().map(|v| v.abs()).fold(1.0, f64::max)
        };
        // The centre, rounded, so that the origin written in the page is the one used here.
        let origin = [0, 1, 2].map(|k| round6(0.5 * lo[k] + 0.5 * hi[k]));
        Grid {
            origin,
            step: round6(size * RELATIVE_STEP),
        }
    }

    /// `{"frames":T,"data":[…]}`: frame-major integer positions, each frame minus the previous.
    fn encode(&self, t: &Trajectory, out: &mut String) {
        let n = t.particles();
        let _ = write!(out, "{{\"frames\":{},\"data\":[", t.frames());
        let mut prev = vec![0i64; n * 3];
        let mut first = true;
        for (k, &v) in t.as_flat().iter().enumerate() {
            // |v - origin| ≤ extent / 2, so q stays within ±5e5: exact in f64 and in JS.
            let q = ((v - self.origin[k % 3]) / self.step).round() as i64;
            let slot = &mut prev[k % (n * 3)];
            if !first {
                out.push(',');
            }
            first = false;
            let _ = write!(out, "{}", q - *slot);
            *slot = q;
        }
        out.push_str("]}");
    }
}

/// The direction drawn upwards: against gravity, or +y in a weightless scene.
fn up_vector(g: [f64; 3]) -> [f64; 3] {
    let norm = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
    if norm > 0.0 && norm.is_finite() {
        g.map(|c| round6(-c / norm))
    } else {
        [0.0, 1.0, 0.0]
    }
}

/// Group names, and each particle's group index (-1: none); `null` when no particle has one.
fn groups(scene: &Scene) -> Value {
    let mut names: Vec<&str> = Vec::new();
    let mut index = Vec::with_capacity(scene.num_particles());
    for p in &scene.particles {
        index.push(match &p.group {
            Some(g) => match names.iter().position(|n| n == g) {
                Some(i) => i as i64,
                None => {
                    names.push(g);
                    names.len() as i64 - 1
                }
            },
            None => -1,
        });
    }
    if names.is_empty() {
        Value::Null
    } else {
        json!({ "names": names, "of": index })
    }
}

/// The catalogue with what to draw for each type: segments (particle index pairs) for binary
/// and angle links, particle–point pairs for anchors, group pairs and range for conditionals,
/// the surface (a point and the unit normal) and the touching particles for planes.
fn types(scene: &Scene) -> Vec<Value> {
    let group_names = {
        let mut names: Vec<&str> = Vec::new();
        for g in scene.particles.iter().filter_map(|p| p.group.as_deref()) {
            if !names.contains(&g) {
                names.push(g);
            }
        }
        names
    };
    scene
        .types
        .iter()
        .enumerate()
        .map(|(t, ty)| {
            let links = scene.links.iter().filter(|l| l.type_index == t);
            let mut v = json!({
                "name": ty.name,
                "kind": ty.kind.name(),
                "count": links.clone().count()
                    + scene.couplings.iter().filter(|c| c.type_index == t).count(),
            });
            match ty.kind {
                LinkKind::Spring | LinkKind::Damper | LinkKind::Muscle => {
                    let seg: Vec<usize> = links.flat_map(|l| l.particles.clone()).collect();
                    v["segments"] = json!(seg);
                }
                LinkKind::Tgr => {
                    // A TGR's link is drawn as a segment between its two masses.
                    let seg: Vec<usize> = scene
                        .couplings
                        .iter()
                        .filter(|c| c.type_index == t)
                        .flat_map(|c| c.particles.clone())
                        .collect();
                    v["segments"] = json!(seg);
                }
                LinkKind::Angle => {
                    // The angle sits at the middle particle: draw both arms.
                    let seg: Vec<usize> = links
                        .flat_map(|l| {
                            let p = &l.particles;
                            [p[0], p[1], p[1], p[2]]
                        })
                        .collect();
                    v["segments"] = json!(seg);
                }
                LinkKind::Anchor => {
                    let (mut idx, mut pts) = (Vec::new(), Vec::new());
                    for l in links {
                        let i = l.particles[0];
                        let p = l.point.or(ty.point).unwrap_or(scene.particles[i].pos);
                        idx.push(i);
                        pts.extend(p.map(round6));
                    }
                    v["anchors"] = json!(idx);
                    v["points"] = json!(pts);
                }
                LinkKind::Conditional => {
                    let gi: Vec<i64> = ty
                        .groups
                        .iter()
                        .map(|g| {
                            group_names
                                .iter()
                                .position(|n| n == g)
                                .map_or(-1, |i| i as i64)
                        })
                        .collect();
                    v["groups"] = json!(gi);
                    v["range"] = json!(ty.value("range").map(round6));
                }
                LinkKind::Plane => {
                    let members: Vec<usize> = links.map(|l| l.particles[0]).collect();
                    let normal = ty
                        .normal
                        .and_then(cordis_core::forces::plane::unit_normal)
                        .map(|n| [n.x, n.y, n.z].map(round6));
                    v["plane"] = json!({
                        "point": ty.point.map(|p| p.map(round6)),
                        "normal": normal,
                        "members": members,
                    });
                }
                // Drags act on velocities only: nothing to draw; the legend lists them.
                _ => {}
            }
            v
        })
        .collect()
}

/// `v` rounded to 6 significant digits (non-finite values are left alone: serde writes null).
fn round6(v: f64) -> f64 {
    if v == 0.0 || !v.is_finite() {
        return v;
    }
    format!("{v:.5e}").parse().unwrap_or(v)
}

pub(crate) fn escape_html(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            _ => out.push(c),
        }
    }
    out
}

/// JSON made safe inside `<script>`: `<`, `>` and `&` only occur in strings there, where the
/// `\u00XX` escapes mean the same to `JSON.parse`; so no `</script>` or `<!--` survives.
fn escape_script_json(json: &str) -> String {
    let mut out = String::with_capacity(json.len());
    for c in json.chars() {
        match c {
            '<' => out.push_str("\\u003c"),
            '>' => out.push_str("\\u003e"),
            '&' => out.push_str("\\u0026"),
            '\u{2028}' => out.push_str("\\u2028"),
            '\u{2029}' => out.push_str("\\u2029"),
            _ => out.push(c),
        }
    }
    out
}

#[cfg(test)]
mod tests;
