//! The identification report (`cordis report`, issue 18 Deliver 4): one self-contained HTML
//! page about a model and the motion it was fitted to.
//!
//! [`report_html`] replays the model (the scene from its own initial state, which an
//! output-error fit estimates) over the observed frames and shows: a data summary (frames,
//! rate, markers, gaps), the fit (position error, worst particle, and the identification's own
//! summary when given), the parameter table (with standard errors and intervals when the
//! estimator gave them: `cordis identify --json`'s line, `solver.uncertainty`), per-marker
//! observed-vs-model x(t), the residual over time and per particle, the convergence curve
//! (`identify --log`), and the 3-D replay (the viewer of `cordis render`, embedded with
//! `srcdoc`). Charts are inline SVG drawn here; light and dark themes follow the system, a
//! button or `#theme=light|dark`. The Content-Security-Policy forbids every fetch, so the page
//! works offline and cannot leak.
//!
//! The residual of particle i at frame t is `|x_model - x_obs|` over its observed coordinates;
//! "position RMS" is the root mean square of the coordinate errors over every observed
//! coordinate (m).

mod svg;

use std::fmt::Write as _;

use cordis_core::{CordisError, LinkKind, Observations, Result, Scene, Simulator, Trajectory};
use cordis_es::report::{ParamUncertainty, StderrBound, WidenedInterval};

use crate::render::{escape_html, render_html, render_html_labelled};
use svg::{bar_chart, line_chart, Chart, Series};

/// The most marker panels drawn (the worst-fitted first when there are more).
pub const MAX_MARKER_PANELS: usize = 24;
/// The most points a series of a chart carries (longer ones are thinned evenly).
const MAX_POINTS: usize = 400;

/// One row of a convergence log: the generation and its best cost.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConvergencePoint {
    pub generation: f64,
    pub best_cost: f64,
}

/// What a report is made of.
pub struct ReportInput<'a> {
    /// The model: every parameter known (an identified scene).
    pub scene: &'a Scene,
    /// The observed motion, NaN where missing; particle i is the scene's particle i (the
    /// scene may have more: hidden particles).
    pub observed: &'a Observations,
    /// The convergence log of the identification, when there is one.
    pub convergence: Option<&'a [ConvergencePoint]>,
    /// The identification's summary (`cordis identify --json`'s line), when there is one.
    pub summary: Option<&'a serde_json::Value>,
    /// Each observed coordinate's weight (1/σ relative, `observed`'s layout, 0 where no
    /// marker is), as `identify --weights` gave them: the fit is also given weighted.
    pub weights: Option<&'a [f64]>,
    pub title: &'a str,
}

/// The warning for fixed particles of `scene` observed far from where it holds them in
/// `observed` (in scene order; `place` the data as the front end names it, `markers` its
/// marker option): a file read without the markers its fit had shows a fit far worse than it
/// was (the page showed 0.235 m RMS for a 1 mm fit, silently). `cordis report` and Python's
/// `write_report` say the same.
pub fn fixed_far_warning(
    scene: &Scene,
    observed: &Observations,
    place: &str,
    markers: &str,
) -> Option<String> {
    let take =
        cordis_es::output_error::Take::from_observations(observed, scene.num_particles()).ok()?;
    cordis_es::session::fixed_far_warning(scene, &take, 0.0, place, markers)
}

/// The markers of `obs` in scene order, as `identify --markers` reads them: marker m is the
/// scene's particle `markers[m]`; particles no marker names are missing throughout. With
/// `weights` (one per marker, or three: x, y, z; positive, finite), also each coordinate's
/// weight in the same order. Errors name the option and the index, and a count that does not
/// fit the markers the trajectory too (`names`: how the front end spells markers, weights and
/// the trajectory: `--markers`, `--weights` and the file, or `markers`, `weights`,
/// `trajectory`).
pub fn in_scene_order(
    obs: &Observations,
    particles: usize,
    markers: Option<&[usize]>,
    weights: Option<&[f64]>,
    names: [&str; 3],
) -> Result<(Observations, Option<Vec<f64>>)> {
    let [markers_opt, weights_opt, source] = names;
    let count = obs.particles();
    let map: Vec<usize> = match markers {
        Some(m) if m.len() != count => {
            return Err(CordisError::argument(
                markers_opt,
                format!(
                    "names {} particles for the {count} markers of {source}",
                    m.len()
                ),
            ))
        }
        Some(m) => m.to_vec(),
        // No mapping helps: markers name distinct particles.
        None if count > particles => {
            return Err(CordisError::trajectory(
                source,
                format!("has {count} particles but the scene has {particles}"),
            ));
        }
        None => (0..count).collect(),
    };
    let mut owner = vec![None; particles];
    for (m, &p) in map.iter().enumerate() {
        let place = format!("{markers_opt}[{m}]");
        if p >= particles {
            return Err(CordisError::argument(
                place,
                format!("particle {p} does not exist (the scene has {particles}, from 0)"),
            ));
        }
        if let Some(first) = owner[p].replace(m) {
            return Err(CordisError::argument(
                place,
                format!("particle {p} is already tracked by marker {first}"),
            ));
        }
    }
    let per_axis = match weights {
        None => None,
        Some(w) => {
            if let Some((k, why)) = cordis_core::arg::bad_weight(w) {
                return Err(CordisError::argument(format!("{weights_opt}[{k}]"), why));
            }
            match w.len() {
                l if l == count => Some(w.iter().flat_map(|&v| [v; 3]).collect::<Vec<f64>>()),
                l if l == 3 * count => Some(w.to_vec()),
                l => {
                    return Err(CordisError::argument(
                        weights_opt,
                        format!(
                            "holds {l} values for the {count} markers of {source}: give one per \
                             marker or three (x, y, z)"
                        ),
                    ))
                }
            }
        }
    };
    let frames = obs.frames();
    let from = obs.as_flat();
    let mut flat = vec![f64::NAN; frames * particles * 3];
    for t in 0..frames {
        for (m, &p) in map.iter().enumerate() {
            let (src, dst) = ((t * count + m) * 3, (t * particles + p) * 3);
            flat[dst..dst + 3].copy_from_slice(&from[src..src + 3]);
        }
    }
    let mut ordered = Observations::from_flat(frames, particles, flat)?;
    ordered.dt = obs.dt;
    let weights = per_axis.map(|w| {
        let mut out = vec![0.0; particles * 3];
        for (m, &p) in map.iter().enumerate() {
            out[p * 3..p * 3 + 3].copy_from_slice(&w[m * 3..m * 3 + 3]);
        }
        out
    });
    Ok((ordered, weights))
}

/// What a JSON value given where another file was expected is, for the error: cordis' own
/// JSON files say which they are by their keys.
pub fn json_kind(v: &serde_json::Value) -> &'static str {
    let has = |k: &str| v.get(k).is_some();
    if has("particles") || v["format"].as_str() == Some(cordis_core::scene_json::FORMAT) {
        "a scene"
    } else if has("generation") && has("best_cost") {
        "a row of a convergence log (--log)"
    } else if has("strategy") && has("stopped_by") {
        "a run's summary (--json)"
    } else if v.is_object() {
        "a JSON object of another kind"
    } else {
        "a JSON value that is not an object"
    }
}

/// Reads a convergence log written by `cordis identify --log` (CSV with a header naming
/// `generation` and `best_cost`, or JSON lines with those keys); errors name `name:line`.
pub fn parse_convergence(name: &str, text: &str) -> Result<Vec<ConvergencePoint>> {
    // A whole-file JSON object (a scene, a summary) is not a log: say what it is rather than
    // fail on its first line.
    if let Ok(v) = serde_json::from_str::<serde_json::Value>(text) {
        if v.get("generation").is_none() {
            return Err(CordisError::format(
                name,
                format!(
                    "expected a convergence log (`cordis identify --log`, .csv or .jsonl), got {}",
                    json_kind(&v)
                ),
            ));
        }
    }
    let mut out = Vec::new();
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let Some((_, first)) = lines.next() else {
        return Err(CordisError::format(name, "empty convergence log"));
    };
    let value = |line: usize, what: &str, v: Option<f64>| {
        v.filter(|v| !v.is_nan()).ok_or_else(|| {
            CordisError::format(
                format!("{name}:{}", line + 1),
                format!("no number for `{what}`"),
            )
        })
    };
    if first.trim_start().starts_with('{') {
        for (k, line) in std::iter::once((0, first)).chain(lines) {
            let v: serde_json::Value = serde_json::from_str(line).map_err(|e| {
                CordisError::format(format!("{name}:{}", k + 1), format!("invalid JSON: {e}"))
            })?;
            out.push(ConvergencePoint {
                generation: value(k, "generation", v["generation"].as_f64())?,
                best_cost: value(k, "best_cost", v["best_cost"].as_f64())?,
            });
        }
    } else {
        let header: Vec<&str> = first.split(',').map(str::trim).collect();
        let col = |key: &str| {
            header.iter().position(|h| *h == key).ok_or_else(|| {
                CordisError::format(
                    format!("{name}:1"),
                    format!("the header has no `{key}` column (a `cordis identify --log` file?)"),
                )
            })
        };
        let (g, c) = (col("generation")?, col("best_cost")?);
        for (k, line) in lines {
            let cells: Vec<&str> = line.split(',').map(str::trim).collect();
            let cell = |i: usize| cells.get(i).and_then(|s| s.parse::<f64>().ok());
            out.push(ConvergencePoint {
                generation: value(k, "generation", cell(g))?,
                best_cost: value(k, "best_cost", cell(c))?,
            });
        }
    }
    Ok(out)
}

/// The unit of a type's parameter, for the table.
fn unit(kind: LinkKind, param: &str) -> &'static str {
    match (kind, param) {
        (LinkKind::Angle, "stiffness") => "N·m",
        (_, "stiffness" | "tendon_stiffness") => "N/m",
        (LinkKind::Quadripole | LinkKind::PositionTransmitter, "damping") => "N/m",
        (_, "damping" | "tendon_damping" | "z1" | "z2") => "N·s/m",
        (_, "rest_length" | "range") => "m",
        (_, "v_max") => "m/s",
        (_, "damping_quadratic") => "N·s²/m²",
        (_, "max_elongation") => "1",
        (_, "tendon_mass") => "kg",
        (LinkKind::Muscle, "gain") => "N",
        (LinkKind::Plane, "friction") => "1",
        (LinkKind::Muscle, p) if p.starts_with("w_len") => "1/m",
        (LinkKind::Muscle, p) if p.starts_with("w_rate") => "s/m",
        _ => "",
    }
}

fn num(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if (1e-3..1e6).contains(&v.abs()) {
        format!("{v:.6}")
            .trim_end_matches('0')
            .trim_end_matches('.')
            .to_string()
    } else {
        format!("{v:.5e}")
    }
}

/// Residuals of the model against the observed frames.
struct Fit {
    per_frame_rms: Vec<f64>,
    per_particle_rms: Vec<f64>,
    rms: f64,
    /// `sqrt(Σ w² e² / Σ w²)` over the observed coordinates, with the weights given.
    weighted_rms: Option<f64>,
    max: f64,
    observed_coordinates: usize,
}

fn fit(model: &Trajectory, obs: &Observations, weights: Option<&[f64]>) -> Fit {
    let (frames, n) = (obs.frames(), obs.particles());
    let flat = obs.as_flat();
    let (mut sum, mut count, mut max) = (0.0, 0usize, 0.0f64);
    let mut particle_sum = vec![(0.0, 0usize); n];
    let mut per_frame_rms = Vec::with_capacity(frames);
    let (mut weighted, mut weight) = (0.0, 0.0);
    for t in 0..frames {
        let (mut fs, mut fc) = (0.0, 0usize);
        for i in 0..n {
            let x = model.pos(t, i);
            let (mut s2, mut c) = (0.0, 0usize);
            for k in 0..3 {
                let o = flat[(t * n + i) * 3 + k];
                if o.is_finite() {
                    let e2 = (x[k] - o).powi(2);
                    s2 += e2;
                    c += 1;
                    if let Some(w) = weights {
                        let w2 = w[i * 3 + k].powi(2);
                        weighted += w2 * e2;
                        weight += w2;
                    }
                }
            }
            if c > 0 {
                max = max.max(s2.sqrt());
                fs += s2;
                fc += c;
                particle_sum[i].0 += s2;
                particle_sum[i].1 += c;
            }
        }
        per_frame_rms.push(if fc > 0 {
            (fs / fc as f64).sqrt()
        } else {
            f64::NAN
        });
        sum += fs;
        count += fc;
    }
    Fit {
        per_frame_rms,
        per_particle_rms: particle_sum
            .iter()
            .map(|&(s, c)| {
                if c > 0 {
                    (s / c as f64).sqrt()
                } else {
                    f64::NAN
                }
            })
            .collect(),
        rms: if count > 0 {
            (sum / count as f64).sqrt()
        } else {
            f64::NAN
        },
        weighted_rms: weights.map(|_| match weight > 0.0 {
            true => (weighted / weight).sqrt(),
            false => f64::NAN,
        }),
        max,
        observed_coordinates: count,
    }
}

/// Indices `0..len` thinned to at most `MAX_POINTS`, evenly, the last one kept.
fn thinned(len: usize) -> Vec<usize> {
    if len <= MAX_POINTS {
        return (0..len).collect();
    }
    let mut v: Vec<usize> = (0..MAX_POINTS)
        .map(|k| k * (len - 1) / (MAX_POINTS - 1))
        .collect();
    v.dedup();
    v
}

/// Builds the report page (see the module docs).
pub fn report_html(input: &ReportInput) -> Result<String> {
    let (scene, obs) = (input.scene, input.observed);
    scene.validate()?;
    if let Some((t, p)) = scene.types.iter().find_map(|t| {
        t.params
            .iter()
            .enumerate()
            .find(|(_, p)| p.is_unknown())
            .map(|(k, _)| (t, t.param_name(k)))
    }) {
        return Err(CordisError::scene(
            format!("types.{}.{p}", t.name),
            "is unknown: a report is about a model; give the identified scene (identify --out)",
        ));
    }
    let n = scene.num_particles();
    if obs.particles() > n {
        return Err(CordisError::trajectory(
            "trajectory",
            format!("has {} particles, the scene has {n}", obs.particles()),
        ));
    }
    if obs.frames() < 2 {
        return Err(CordisError::trajectory(
            "trajectory",
            "needs at least 2 frames",
        ));
    }
    let frames = obs.frames();
    let dt = obs.dt.unwrap_or(scene.dt);
    let model = Simulator::new(scene)?.run(frames)?.with_dt(dt);
    if let Some(w) = input.weights.filter(|w| w.len() != obs.particles() * 3) {
        return Err(CordisError::argument(
            "weights",
            format!(
                "holds {} values for {} particles × 3",
                w.len(),
                obs.particles()
            ),
        ));
    }
    let fit = fit(&model, obs, input.weights);

    let mut body = String::new();
    let _ = write!(
        body,
        "<header><h1>{}</h1><button id=\"theme\" type=\"button\">light / dark</button></header>",
        escape_html(input.title)
    );
    summary_section(&mut body, input, &fit, dt);
    parameter_section(&mut body, input);
    marker_section(&mut body, input, &model, &fit, dt);
    residual_section(&mut body, &fit, dt);
    convergence_section(&mut body, input.convergence);
    replay_section(&mut body, input, &model)?;

    let mut page = String::with_capacity(body.len() + 4096);
    page.push_str("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n");
    page.push_str("<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n");
    // No network, ever: every fetch is forbidden; the replay is an inline frame (srcdoc).
    page.push_str(
        "<meta http-equiv=\"Content-Security-Policy\" content=\"default-src 'none'; \
         script-src 'unsafe-inline'; style-src 'unsafe-inline'; img-src data:\">\n",
    );
    let _ = writeln!(page, "<title>{}</title>", escape_html(input.title));
    let _ = writeln!(
        page,
        "<style>\n{}</style>\n</head>",
        include_str!("report/report.css")
    );
    let _ = writeln!(page, "<body>\n{body}");
    let _ = writeln!(
        page,
        "<script>\n{}</script>\n</body>\n</html>",
        include_str!("report/report.js")
    );
    Ok(page)
}

/// Missing coordinates of `particles` in `obs`.
fn missing_of(obs: &Observations, particles: impl Iterator<Item = usize>) -> usize {
    let (flat, n) = (obs.as_flat(), obs.particles());
    particles
        .map(|i| {
            (0..obs.frames())
                .map(|t| {
                    flat[(t * n + i) * 3..][..3]
                        .iter()
                        .filter(|v| v.is_nan())
                        .count()
                })
                .sum::<usize>()
        })
        .sum()
}

fn summary_section(out: &mut String, input: &ReportInput, fit: &Fit, dt: f64) {
    let (scene, obs) = (input.scene, input.observed);
    let n = scene.num_particles();
    // A fixed particle the file does not track is where the scene puts it: not data the
    // motion lacks, so neither missing nor hidden (nor "in the motion").
    let untracked_fixed = |i: usize| {
        scene.particles[i].fixed && (i >= obs.particles() || fit.per_particle_rms[i].is_nan())
    };
    let counted = (0..obs.particles()).filter(|&i| !untracked_fixed(i));
    let total = counted.clone().count() * obs.frames() * 3;
    let missing = missing_of(obs, counted.clone());
    let in_motion = counted
        .clone()
        .filter(|&i| fit.per_particle_rms[i].is_finite())
        .count();
    let hidden = (0..n)
        .filter(|&i| !untracked_fixed(i))
        .filter(|&i| i >= obs.particles() || fit.per_particle_rms[i].is_nan())
        .count();
    let fixed = scene.particles.iter().filter(|p| p.fixed).count();
    let worst = fit
        .per_particle_rms
        .iter()
        .enumerate()
        .filter(|(_, v)| v.is_finite())
        .max_by(|a, b| a.1.total_cmp(b.1));
    let _ = write!(
        out,
        "<section id=\"data\"><h2>Data and fit</h2><table class=\"facts\">\
         <tr><th>frames</th><td>{} ({} s at dt = {} s)</td></tr>\
         <tr><th>particles</th><td>{n} in the scene ({fixed} fixed), {} in the motion, {hidden} never observed</td></tr>\
         <tr><th>missing</th><td>{missing} of {total} coordinates ({:.2} %)</td></tr>\
         <tr><th>links</th><td>{} in {} types</td></tr>\
         <tr><th>position RMS error</th><td>{} m over {} observed coordinates</td></tr>\
         <tr><th>largest error</th><td>{} m</td></tr>",
        obs.frames(),
        num((obs.frames() - 1) as f64 * dt),
        num(dt),
        in_motion,
        100.0 * missing as f64 / total.max(1) as f64,
        scene.links.len() + scene.couplings.len(),
        scene.types.len(),
        num(fit.rms),
        fit.observed_coordinates,
        num(fit.max),
    );
    if let Some(w) = fit.weighted_rms {
        let _ = write!(
            out,
            "<tr><th>weighted position RMS error</th><td>{} m (the --weights given, 1/σ \
             relative: sqrt(Σ w² e² / Σ w²))</td></tr>",
            num(w)
        );
    }
    if let Some((i, v)) = worst {
        let _ = write!(
            out,
            "<tr><th>worst particle</th><td>{i} (RMS {} m)</td></tr>",
            num(*v)
        );
    }
    if let Some(s) = input.summary {
        for key in [
            "strategy",
            "stopped_by",
            "cost",
            "rmse",
            "generations",
            "evals",
            "seconds",
        ] {
            let v = &s[key];
            let shown = match v {
                serde_json::Value::Null => continue,
                serde_json::Value::Number(x) => x.as_f64().map_or(x.to_string(), num),
                serde_json::Value::String(x) => escape_html(x),
                other => escape_html(&other.to_string()),
            };
            let _ = write!(out, "<tr><th>identify: {key}</th><td>{shown}</td></tr>");
        }
    }
    out.push_str("</table>");
    if let Some(solver) = input
        .summary
        .map(|s| &s["solver"])
        .filter(|v| v.is_object())
    {
        let mut solver = solver.clone();
        if let Some(o) = solver.as_object_mut() {
            o.remove("uncertainty");
        }
        let text = serde_json::to_string_pretty(&solver).unwrap_or_default();
        let _ = write!(
            out,
            "<details><summary>the solver's report</summary><pre>{}</pre></details>",
            escape_html(&text)
        );
    }
    out.push_str("</section>");
}

fn parameter_section(out: &mut String, input: &ReportInput) {
    let uncertainty: Vec<&serde_json::Value> = input
        .summary
        .and_then(|s| s["solver"]["uncertainty"].as_array())
        .map(|a| a.iter().collect())
        .unwrap_or_default();
    let not_computed: Vec<&serde_json::Value> = input
        .summary
        .and_then(|s| s["solver"]["stderr_at_least"].as_array())
        .map(|a| a.iter().collect())
        .unwrap_or_default();
    let widened: Vec<&serde_json::Value> = input
        .summary
        .and_then(|s| s["solver"]["widened_intervals"].as_array())
        .map(|a| a.iter().collect())
        .unwrap_or_default();
    // An interval widened past its Wald interval (the cost flatter there than its quadratic
    // model): said beside it, with the Wald interval it replaced.
    let widened_note = |name: &str| -> String {
        let wald = widened
            .iter()
            .find(|w| w["name"] == name)
            .and_then(|w| serde_json::from_value::<WidenedInterval>((*w).clone()).ok());
        match wald {
            Some(w) => format!(
                " <span class=\"muted\">widened from the Wald interval [{}, {}]: the cost \
                 is flatter there than its quadratic model</span>",
                num(w.wald.0),
                num(w.wald.1)
            ),
            None => String::new(),
        }
    };
    let interval = |name: &str| -> String {
        let Some(u) = uncertainty.iter().find(|u| u["name"] == name) else {
            // A standard error the solver could not compute, with its lower bound.
            return match not_computed.iter().find(|b| b["name"] == name) {
                Some(b) => {
                    let bound = serde_json::from_value::<StderrBound>((*b).clone()).ok();
                    match bound.as_ref().and_then(StderrBound::rounded_down) {
                        Some(v) => format!("not computed (at least {v})"),
                        None => "not computed".into(),
                    }
                }
                None => String::new(),
            };
        };
        // Read as identify wrote it: an infinite standard error is the string "inf".
        let Ok(u) = serde_json::from_value::<ParamUncertainty>((*u).clone()) else {
            return "not determined".into();
        };
        let (lo, hi) = (num(u.interval.0), num(u.interval.1));
        match u.std_error.is_finite() {
            true => format!(
                "± {} <span class=\"muted\">[{lo}, {hi}] ({:.0} %)</span>{}",
                num(u.std_error),
                u.level * 100.0,
                widened_note(name)
            ),
            // Its interval is the box it was searched in: the data do not narrow it.
            false => format!("not determined <span class=\"muted\">[{lo}, {hi}] (its box)</span>"),
        }
    };
    out.push_str("<section id=\"parameters\"><h2>Parameters</h2>");
    if uncertainty.is_empty() {
        out.push_str(
            "<p class=\"note\">No intervals: give <code>--summary</code> (the line of \
             <code>cordis identify --json</code>) from an estimator that computes them \
             (output-error).</p>",
        );
    }
    out.push_str("<table class=\"params\"><tr><th>type</th><th>kind</th><th>parameter</th><th>value</th><th>unit</th><th>standard error, interval</th></tr>");
    for t in &input.scene.types {
        for (k, p) in t.params.iter().enumerate() {
            let name = t.param_name(k);
            let _ = write!(
                out,
                "<tr><td>{}</td><td>{}</td><td>{}</td><td class=\"num\">{}</td><td>{}</td><td>{}</td></tr>",
                escape_html(&t.name),
                t.kind.name(),
                escape_html(&name),
                num(p.value()),
                unit(t.kind, &name),
                interval(&format!("types.{}.{name}", t.name))
            );
        }
    }
    for u in &uncertainty {
        let Some(name) = u["name"].as_str().filter(|n| n.starts_with("particles[")) else {
            continue;
        };
        let i: Option<usize> = name
            .strip_prefix("particles[")
            .and_then(|r| r.split(']').next())
            .and_then(|i| i.parse().ok());
        let Some(p) = i.and_then(|i| input.scene.particles.get(i)) else {
            continue;
        };
        let _ = write!(
            out,
            "<tr><td colspan=\"2\">{}</td><td>mass</td><td class=\"num\">{}</td><td>kg</td><td>{}</td></tr>",
            escape_html(name.trim_end_matches(".mass")),
            num(p.mass.value()),
            interval(name)
        );
    }
    out.push_str("</table></section>");
}

fn marker_section(out: &mut String, input: &ReportInput, model: &Trajectory, fit: &Fit, dt: f64) {
    let obs = input.observed;
    let n = obs.particles();
    let mut shown: Vec<usize> = (0..n)
        .filter(|&i| fit.per_particle_rms[i].is_finite() && !input.scene.particles[i].fixed)
        .collect();
    let observed_free = shown.len();
    if shown.len() > MAX_MARKER_PANELS {
        shown.sort_by(|&a, &b| fit.per_particle_rms[b].total_cmp(&fit.per_particle_rms[a]));
        shown.truncate(MAX_MARKER_PANELS);
        shown.sort_unstable();
    }
    let _ = write!(
        out,
        "<section id=\"markers\"><h2>Observed and model, per marker</h2><p class=\"note\">\
         x, y, z against time: dots observed, lines the model. {}</p>\
         <p class=\"legend\"><span class=\"k x\">x</span> <span class=\"k y\">y</span> \
         <span class=\"k z\">z</span></p><div class=\"grid\">",
        if shown.len() < observed_free {
            format!(
                "The {} worst-fitted of {observed_free} observed free particles.",
                shown.len()
            )
        } else {
            format!("Every observed free particle ({observed_free}).")
        }
    );
    let frames = thinned(obs.frames());
    let flat = obs.as_flat();
    for &i in &shown {
        let mut series = Vec::new();
        for (k, class) in ["x", "y", "z"].iter().enumerate() {
            let observed = |t: usize| flat[(t * n + i) * 3 + k];
            series.push(over_time(class, &frames, dt, true, observed));
            series.push(over_time(class, &frames, dt, false, |t| model.pos(t, i)[k]));
        }
        let title = format!("particle {i} (RMS {} m)", num(fit.per_particle_rms[i]));
        let chart = Chart {
            width: 330.0,
            height: 170.0,
            x_label: "t (s)",
            y_label: "m",
            log_y: false,
            y_from_zero: false,
            title: &title,
        };
        out.push_str(&line_chart(&chart, &series));
    }
    out.push_str("</div></section>");
}

/// A series of `value(t)` at the `frames` shown, against time `t dt` (s).
fn over_time<'a>(
    class: &'a str,
    frames: &[usize],
    dt: f64,
    dots: bool,
    value: impl Fn(usize) -> f64,
) -> Series<'a> {
    Series {
        class,
        points: frames.iter().map(|&t| (t as f64 * dt, value(t))).collect(),
        dots,
    }
}

fn residual_section(out: &mut String, fit: &Fit, dt: f64) {
    let frames = thinned(fit.per_frame_rms.len());
    let error = over_time("model", &frames, dt, false, |t| fit.per_frame_rms[t]);
    let over_time = line_chart(
        &Chart::wide(
            "position error over time (RMS over observed coordinates)",
            "t (s)",
            "RMS error (m)",
        ),
        &[error],
    );
    let per_particle = bar_chart(
        &Chart::wide(
            "position error per particle (RMS over frames)",
            "particle",
            "RMS error (m)",
        ),
        &fit.per_particle_rms,
    );
    let _ = write!(
        out,
        "<section id=\"residuals\"><h2>Residuals</h2>{over_time}{per_particle}</section>"
    );
}

fn convergence_section(out: &mut String, convergence: Option<&[ConvergencePoint]>) {
    out.push_str("<section id=\"convergence\"><h2>Convergence</h2>");
    match convergence {
        Some(rows) if !rows.is_empty() => {
            let pick = thinned(rows.len());
            out.push_str(&line_chart(
                &Chart {
                    log_y: rows.iter().all(|r| r.best_cost > 0.0),
                    ..Chart::wide("best cost per generation", "generation", "best cost")
                },
                &[Series {
                    class: "model",
                    points: pick
                        .iter()
                        .map(|&k| (rows[k].generation, rows[k].best_cost))
                        .collect(),
                    dots: false,
                }],
            ));
        }
        _ => out.push_str(
            "<p class=\"note\">No convergence log: give <code>--log</code> (the file of \
             <code>cordis identify --log</code>).</p>",
        ),
    }
    out.push_str("</section>");
}

/// `obs` with each fixed particle's missing coordinates at the scene's position (it does not
/// move: a file need not track it).
fn with_fixed_filled(obs: &Observations, scene: &Scene) -> Option<Observations> {
    let (n, mut data) = (obs.particles(), obs.as_flat().to_vec());
    for (i, p) in scene.particles.iter().enumerate().filter(|(_, p)| p.fixed) {
        for t in 0..obs.frames() {
            for (c, v) in data[(t * n + i) * 3..][..3].iter_mut().enumerate() {
                if v.is_nan() {
                    *v = p.pos[c];
                }
            }
        }
    }
    let mut filled = Observations::from_flat(obs.frames(), n, data).ok()?;
    filled.dt = obs.dt;
    Some(filled)
}

/// The 3-D replay: the viewer page in an inline frame, the observed motion solid and the model
/// dashed when the observation is complete, else the model alone.
fn replay_section(out: &mut String, input: &ReportInput, model: &Trajectory) -> Result<()> {
    let obs = input.observed;
    let complete = (obs.particles() == input.scene.num_particles())
        .then(|| with_fixed_filled(obs, input.scene))
        .flatten()
        .filter(|o| o.missing() == 0)
        .map(Observations::into_trajectory)
        .transpose()?;
    let (page, note) = match &complete {
        Some(observed) => (
            render_html_labelled(
                input.scene,
                observed,
                Some(model),
                input.title,
                ["observed", "model"],
            )?,
            "observed solid, model dashed",
        ),
        None => (
            render_html(input.scene, model, None, input.title)?,
            "the model alone (the observation has gaps or hidden particles)",
        ),
    };
    let _ = write!(
        out,
        "<section id=\"replay\"><h2>3-D replay</h2><p class=\"note\">{note}; drag to turn, \
         the controls are the viewer's (<code>cordis render</code>).</p>\
         <iframe title=\"3-D replay\" srcdoc=\"{}\"></iframe></section>",
        escape_html(&page)
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use cordis_core::examples;

    /// A fixed particle the file does not track is neither missing data nor hidden, and the
    /// replay still overlays the observed motion (the report said 33 % missing and showed
    /// the model alone for a block whose clamped layer was, rightly, not tracked).
    #[test]
    fn untracked_fixed_particles_are_not_missing_data() {
        let mut scene = examples::rigid();
        scene.particles[0].fixed = true;
        let traj = scene.simulate(40).unwrap();
        let mut data = traj.as_flat().to_vec();
        for t in 0..40 {
            data[t * 15 * 3..][..3].fill(f64::NAN);
        }
        let observed = Observations::from_flat(40, 15, data).unwrap();
        let page = report_html(&ReportInput {
            scene: &scene,
            observed: &observed,
            convergence: None,
            summary: None,
            weights: None,
            title: "clamped",
        })
        .unwrap();
        assert!(page.contains("15 in the scene (1 fixed), 14 in the motion, 0 never observed"));
        assert!(
            page.contains("<td>0 of 1680 coordinates (0.00 %)</td>"),
            "{page}"
        );
        assert!(page.contains("observed solid, model dashed"));
    }

    #[test]
    fn the_page_has_every_section_and_the_intervals_it_is_given() {
        let scene = examples::rigid();
        let observed = Observations::from_trajectory(&scene.simulate(60).unwrap());
        let summary = serde_json::json!({"strategy": "output-error", "cost": 1e-3,
            "solver": {"sigma": 1e-3, "uncertainty": [{"name": "types.h_top.stiffness",
            "std_error": 2.5, "interval": [945.1, 954.9], "level": 0.95},
            {"name": "types.v_end.stiffness", "std_error": 1.5, "interval": [700.0, 999.5],
            "level": 0.95}],
            "widened_intervals": [{"name": "types.v_end.stiffness", "wald": [900.0, 999.5],
            "rise": [0.25, "NaN"]}],
            "stderr_at_least": [{"name": "types.h_middle.stiffness", "at_least": 3.04159},
            {"name": "types.h_bottom.stiffness", "at_least": 0.0}]}});
        let log =
            parse_convergence("c.csv", "generation,evals,best_cost\n0,10,5.0\n1,20,0.5\n").unwrap();
        let page = report_html(&ReportInput {
            scene: &scene,
            observed: &observed,
            convergence: Some(&log),
            summary: Some(&summary),
            weights: None,
            title: "rigid <fit>",
        })
        .unwrap();
        for id in [
            "data",
            "parameters",
            "markers",
            "residuals",
            "convergence",
            "replay",
        ] {
            assert!(page.contains(&format!("<section id=\"{id}\">")), "{id}");
        }
        assert!(page.contains("<title>rigid &lt;fit&gt;</title>"));
        assert!(page.contains("± 2.5 <span class=\"muted\">[945.1, 954.9] (95 %)</span></td>"));
        // A widened interval says so, with the Wald interval it replaced.
        assert!(
            page.contains(
                "[700, 999.5] (95 %)</span> <span class=\"muted\">widened from the Wald \
                 interval [900, 999.5]: the cost is flatter there than its quadratic model"
            ),
            "{page}"
        );
        // Standard errors not computed are said so, with their lower bound rounded down.
        assert!(
            page.contains("<td>not computed (at least 3.04e0)</td>"),
            "{page}"
        );
        assert!(page.contains("<td>not computed</td>"));
        assert!(page.contains("Every observed free particle (15)."));
        assert!(
            page.contains("position RMS error</th><td>0 m"),
            "the model is the truth"
        );
        assert!(
            !page.contains("http://") && !page.contains("https://"),
            "no network"
        );
        assert_eq!(page.matches("<svg ").count(), 15 + 2 + 1);
    }

    #[test]
    fn gaps_are_not_errors_and_unknowns_are_refused() {
        let scene = examples::rigid();
        let mut flat = scene.simulate(30).unwrap().into_flat();
        flat[3 * 4..3 * 5].fill(f64::NAN);
        let observed = Observations::from_flat(30, 15, flat).unwrap();
        let input = |s| ReportInput {
            scene: s,
            observed: &observed,
            convergence: None,
            summary: None,
            weights: None,
            title: "t",
        };
        let page = report_html(&input(&scene)).unwrap();
        assert!(page.contains("3 of 1350 coordinates"));
        assert!(page.contains("the model alone (the observation has gaps"));
        let unknown = examples::by_name("rigid")
            .map(|mut s| {
                s.types[0].params[0] = cordis_core::Param::Unknown(cordis_core::Bounds {
                    min: 1.0,
                    max: 2.0,
                    init: None,
                });
                s
            })
            .unwrap();
        let e = report_html(&input(&unknown)).unwrap_err().to_string();
        assert!(e.starts_with("types.h_bottom.stiffness: is unknown"), "{e}");
    }

    /// Issue 18: `report` reads `--markers` and `--weights` as `identify` does. Markers 0..15
    /// given in reverse order, then mapped back: the same page as the motion in scene order.
    #[test]
    fn markers_map_to_the_scene_and_weights_weigh_the_fit() {
        const NAMES: [&str; 3] = ["--markers", "--weights", "obs.csv"];
        let scene = examples::rigid();
        let truth = scene.simulate(20).unwrap();
        let n = scene.num_particles();
        let mut reversed = Vec::with_capacity(truth.as_flat().len());
        for t in 0..20 {
            for i in (0..n).rev() {
                reversed.extend_from_slice(truth.pos(t, i).as_slice());
            }
        }
        let marked = Observations::from_flat(20, n, reversed).unwrap();
        let markers: Vec<usize> = (0..n).rev().collect();
        let (ordered, _) = in_scene_order(&marked, n, Some(&markers), None, NAMES).unwrap();
        assert_eq!(ordered.as_flat(), truth.as_flat());
        // Two markers only: the others missing throughout, never zeros.
        let two: Vec<f64> = (0..20)
            .flat_map(|t| [truth.pos(t, 5), truth.pos(t, 2)])
            .flat_map(|x| [x.x, x.y, x.z])
            .collect();
        let two = Observations::from_flat(20, 2, two).unwrap();
        let (ordered, w) =
            in_scene_order(&two, n, Some(&[5, 2]), Some(&[2.0, 0.5]), NAMES).unwrap();
        assert_eq!(ordered.missing(), 20 * (n - 2) * 3);
        let w = w.unwrap();
        assert_eq!((w[15], w[17], w[6], w[0]), (2.0, 2.0, 0.5, 0.0));
        let page = |weights| {
            report_html(&ReportInput {
                scene: &scene,
                observed: &ordered,
                convergence: None,
                summary: None,
                weights,
                title: "t",
            })
            .unwrap()
        };
        assert!(page(Some(&w)).contains("weighted position RMS error</th><td>0 m"));
        assert!(!page(None).contains("weighted position RMS"));
        for (markers, weights, says) in [
            (
                &[5, 5][..],
                None,
                "--markers[1]: particle 5 is already tracked by marker 0",
            ),
            (
                &[5, 99],
                None,
                "--markers[1]: particle 99 does not exist (the scene has 15",
            ),
            (
                &[5],
                None,
                "--markers: names 1 particles for the 2 markers of obs.csv",
            ),
            (
                &[5, 2],
                Some(&[1.0, f64::NAN][..]),
                "--weights[1]: must be a positive finite",
            ),
            (
                &[5, 2],
                Some(&[1.0, 1.0, 1.0]),
                "--weights: holds 3 values for the 2 markers of obs.csv",
            ),
        ] {
            let e = in_scene_order(&two, n, Some(markers), weights, NAMES)
                .unwrap_err()
                .to_string();
            assert!(e.contains(says), "{e}");
        }
    }

    #[test]
    fn a_log_without_best_cost_names_its_line() {
        let e = parse_convergence("c.csv", "generation,evals\n0,1\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("c.csv:1: the header has no `best_cost` column"),
            "{e}"
        );
        let e = parse_convergence(
            "c.jsonl",
            "{\"generation\": 0, \"best_cost\": 1}\n{\"generation\": 1}\n",
        )
        .unwrap_err()
        .to_string();
        assert_eq!(e, "c.jsonl:2: no number for `best_cost`");
    }
}
