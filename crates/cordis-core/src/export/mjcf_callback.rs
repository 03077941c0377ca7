//! What MuJoCo has no element for, written into the MJCF's `<custom>` numeric fields and applied
//! by `cordis.mujoco` (python/cordis/mujoco.py) while MuJoCo integrates.
//!
//! **Split of the work.** MuJoCo integrates every particle (semi-implicit Euler, see
//! [`super::mjcf`]) and computes the forces its elements express: springs and anchors as
//! tendons, dampers as fixed tendons, drags as joint damping, gravity. Four things have no MJCF
//! element, so the model carries their data and `cordis.mujoco` adds them:
//! - **angle links** (a potential of a cosine), **conditional links** (pairs found anew at each
//!   step), **planes** (a penalty buffer with regularised Coulomb friction, not MuJoCo's
//!   constraint contact) and a spring's **quadratic damping** `Z₂ s|s|`: forces of the state
//!   `(x(n), v(n))`, added to `qfrc_passive` by MuJoCo's passive-force callback
//!   (`mjcb_passive`), which `mj_step` calls inside `mj_forward` before the accelerations: the
//!   same forces at the same state as CORDIS' step;
//! - **Provot's elongation limit**: not a force but a projection of the new positions after the
//!   step (thesis §4.2). MuJoCo has no hook after its integrator, so `cordis.mujoco` runs it
//!   between `mj_step` calls, moving `qpos` by the correction `Δ` and `qvel` by `Δ / dt`: CORDIS
//!   leaves `x(n)` alone, so its next velocity `(x(n+1) + Δ - x(n)) / dt` gains `Δ / dt` too.
//!
//! **The fields** (all numbers; particle indices are the bodies `p{i}`), each present only when
//! the scene has that kind:
//!
//! | name | per item |
//! |---|---|
//! | `cordis_format` | `1` (this layout) |
//! | `cordis_angle` | `i j k K c0`: the angle at `j`, stiffness N·m, rest cosine |
//! | `cordis_spring_quadratic` | `i j Z₂`: a spring's quadratic damping, N·s²/m² |
//! | `cordis_plane` | `i K Z μ px py pz nx ny nz`: the unit normal as the simulation uses it |
//! | `cordis_conditional_{t}` | one per conditional type: `K l0 Z Z₂ range na nb a… b…`; `nb = -1`: pairs within `a` |
//! | `cordis_provot` | `i j τc l0` per limited spring, in the order the projection runs |
//!
//! Values come from the compiled [`Plan`] (the simulation's own runs, normals and parameter
//! vector), so the callback reads the numbers the simulation uses, bit for bit.

use std::fmt::Write;

use super::mjcf::num;
use crate::{Plan, Result, Scene};

/// The kinds a scene has that go through `cordis.mujoco` rather than MuJoCo's own elements,
/// in a fixed order (empty when MuJoCo alone replays the scene).
pub fn callback_kinds(scene: &Scene) -> Result<Vec<&'static str>> {
    Ok(kinds_of(&Plan::compile(scene)?))
}

/// [`callback_kinds`] of a compiled plan.
pub(super) fn kinds_of(plan: &Plan) -> Vec<&'static str> {
    let mut kinds = Vec::new();
    if !plan.angles.triples.is_empty() {
        kinds.push("angle");
    }
    if !plan.conditionals.is_empty() {
        kinds.push("conditional");
    }
    if !plan.planes.is_empty() {
        kinds.push("plane");
    }
    if plan.springs.quadratic.iter().any(Option::is_some) {
        kinds.push("damping_quadratic");
    }
    if !plan.provot.links.is_empty() {
        kinds.push("max_elongation");
    }
    kinds
}

/// The `<custom>` element for the forces of [`callback_kinds`], or an empty string when the
/// scene has none of them.
pub fn custom_fields(scene: &Scene) -> Result<String> {
    Ok(custom_fields_of(scene, &Plan::compile(scene)?))
}

/// [`custom_fields`] from the scene's compiled plan (the MJCF export compiles it once for
/// this and [`kinds_of`]).
pub(super) fn custom_fields_of(scene: &Scene, plan: &Plan) -> String {
    if kinds_of(plan).is_empty() {
        return String::new();
    }
    let p = scene.param_values();
    let mut fields: Vec<(String, Vec<f64>)> = vec![("cordis_format".into(), vec![1.0])];
    let mut angles = Vec::new();
    for r in &plan.angles.runs {
        for &[i, j, k] in &plan.angles.triples[r.start..r.end] {
            angles.extend([i as f64, j as f64, k as f64, p[r.param], p[r.param + 1]]);
        }
    }
    fields.push(("cordis_angle".into(), angles));
    let mut quadratic = Vec::new();
    for (r, slot) in plan.springs.runs.iter().zip(&plan.springs.quadratic) {
        if let Some(s) = slot {
            for &[i, j] in &plan.springs.pairs[r.start..r.end] {
                quadratic.extend([i as f64, j as f64, p[*s]]);
            }
        }
    }
    fields.push(("cordis_spring_quadratic".into(), quadratic));
    let mut planes = Vec::new();
    for (r, s) in plan.planes.runs.iter().zip(&plan.planes.surfaces) {
        for &i in &plan.planes.particles[r.start..r.end] {
            planes.extend([i as f64, p[r.param], p[r.param + 1], p[r.param + 2]]);
            planes.extend(s.point.iter().chain(s.normal.iter()));
        }
    }
    fields.push(("cordis_plane".into(), planes));
    for (t, c) in plan.conditionals.iter().enumerate() {
        let z2 = c.quadratic.map_or(0.0, |s| p[s]);
        let mut data = vec![
            p[c.param],
            p[c.param + 1],
            p[c.param + 2],
            z2,
            c.range(&p),
            c.a.len() as f64,
            c.b.as_ref().map_or(-1.0, |b| b.len() as f64),
        ];
        data.extend(c.a.iter().chain(c.b.iter().flatten()).map(|&i| i as f64));
        fields.push((format!("cordis_conditional_{t}"), data));
    }
    let mut provot = Vec::new();
    for l in &plan.provot.links {
        provot.extend([l.i as f64, l.j as f64, p[l.tau], p[l.param + 1]]);
    }
    fields.push(("cordis_provot".into(), provot));
    let mut xml = String::from("<custom>\n");
    for (name, data) in fields.iter().filter(|(_, d)| !d.is_empty()) {
        let text: Vec<String> = data.iter().map(|&v| num(v)).collect();
        let _ = writeln!(
            xml,
            "<numeric name=\"{name}\" size=\"{}\" data=\"{}\"/>",
            data.len(),
            text.join(" ")
        );
    }
    xml.push_str("</custom>\n");
    xml
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{examples, LinkKind, LinkType, Particle};

    fn field<'a>(xml: &'a str, name: &str) -> Vec<&'a str> {
        let at = xml
            .find(&format!("name=\"{name}\""))
            .unwrap_or_else(|| panic!("{name} missing from {xml}"));
        let data = &xml[at..];
        let start = data.find("data=\"").unwrap() + 6;
        let end = start + data[start..].find('"').unwrap();
        data[start..end].split(' ').collect()
    }

    #[test]
    fn the_horse_carries_its_three_angles_with_their_stiffness_and_rest_cosine() {
        let scene = examples::horse();
        let xml = custom_fields(&scene).unwrap();
        let angles = field(&xml, "cordis_angle");
        assert_eq!(angles.len(), 3 * 5);
        let first = scene
            .links
            .iter()
            .find(|l| scene.types[l.type_index].kind == LinkKind::Angle)
            .unwrap();
        let t = &scene.types[first.type_index];
        let want: Vec<String> = first
            .particles
            .iter()
            .map(|&i| num(i as f64))
            .chain([t.params[0].value(), t.params[1].value()].map(num))
            .collect();
        assert_eq!(
            angles[..5],
            want.iter().map(String::as_str).collect::<Vec<_>>()[..]
        );
        assert!(!xml.contains("cordis_provot") && !xml.contains("cordis_plane"));
    }

    #[test]
    fn the_cloth_lists_its_limited_springs_in_the_projections_order() {
        let scene = examples::cloth(4, 4);
        let xml = custom_fields(&scene).unwrap();
        let provot = field(&xml, "cordis_provot");
        let limited: Vec<_> = scene
            .links
            .iter()
            .filter(|l| scene.types[l.type_index].max_elongation().is_some())
            .collect();
        assert_eq!(provot.len(), 4 * limited.len());
        assert_eq!(provot[0], num(limited[0].particles[0] as f64));
        assert_eq!(provot[1], num(limited[0].particles[1] as f64));
    }

    #[test]
    fn a_conditional_type_within_one_group_is_marked_minus_one() {
        let mut s = Scene::new(0.01);
        for x in [0.0, 0.5, 1.0] {
            s.add_particle(Particle::new(1.0, [x, 0.0, 0.0]).in_group("gas"));
        }
        let mut press = LinkType::new("press", LinkKind::Conditional)
            .with("stiffness", 2.0)
            .with("rest_length", 0.6)
            .with("damping", 0.1)
            .with("range", 0.6);
        press.groups = vec!["gas".into()];
        s.add_type(press);
        let xml = custom_fields(&s).unwrap();
        assert_eq!(
            field(&xml, "cordis_conditional_0"),
            ["2.0", "0.6", "0.1", "0.0", "0.6", "3.0", "-1.0", "0.0", "1.0", "2.0"]
        );
        assert!(custom_fields(&examples::rigid()).unwrap().is_empty());
    }
}
