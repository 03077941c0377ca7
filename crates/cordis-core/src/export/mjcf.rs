//! MuJoCo's MJCF from a scene: the same motion, step for step (SPEC §7.3).
//!
//! **Why the two schemes are the same.** CORDIS steps `x(n+1) = 2x(n) - x(n-1) + dt² a(n)`
//! with `v(n) = (x(n) - x(n-1)) / dt` and `x(-1) = x(0) - v0 dt`. Writing
//! `v(n+1) = (x(n+1) - x(n)) / dt` turns it into `v(n+1) = v(n) + dt a(n)`,
//! `x(n+1) = x(n) + dt v(n+1)`: MuJoCo's semi-implicit `integrator="Euler"` whose `qvel` is
//! `v(n)` (starting at `v0`), provided the damping is explicit too (`eulerdamp="disable"`;
//! MuJoCo's default treats joint damping implicitly) and nothing but the passive forces acts
//! (`contact="disable"`). The two differ by rounding only: python/tests/test_mujoco.py measures
//! ≤ 1e-9 of the motion's extent after hundreds of steps.
//!
//! **The mapping.** Particle `i` is the body `p{i}` at its initial position, in particle order,
//! with three slide joints `p{i}_x`, `p{i}_y`, `p{i}_z` (mass `m`, so the joint-space mass
//! matrix is `m I` and `qacc = F / m` as CORDIS divides) and a site `s{i}` at its centre; a
//! fixed particle is the same body without joints. Then per link kind:
//! - `spring` (K, l0, Z): a spatial tendon between the two sites, `stiffness` K,
//!   `springlength` l0, `damping` Z: MuJoCo's tendon force `-K (L - l0) - Z L̇` along the
//!   tendon is CORDIS' `(K (L - l0) + Z s) u`.
//! - `damper` (Z, isotropic `F = Z (v_j - v_i)`): three fixed tendons, one per axis, of length
//!   `q_i,c - q_j,c` and `damping` Z (a fixed end drops out of the sum).
//! - `anchor` (K, l0, Z, point P): with `l0 = 0` the force `-K (x - P)` is linear, so it goes
//!   into the slide joints' `stiffness` with `springref = P - x(0)` (exact, and defined at the
//!   point itself); its damping, and any anchor with `l0 > 0`, is a spatial tendon from a site
//!   of the world body at P.
//! - `drag` (Z, `F = -Z v`): the slide joints' `damping`.
//! - gravity: `<option gravity>` (fixed bodies have no joint to move).
//! - initial velocities: the keyframe `cordis_start` (`mj_resetDataKeyframe(model, data, 0)`).
//! - angle, conditional and plane links, a spring's or conditional's `damping_quadratic` and
//!   Provot's `max_elongation` have no MJCF element: their data go into `<custom>` numeric
//!   fields and `cordis.mujoco` applies them while MuJoCo integrates (the passive-force
//!   callback for the forces, a projection between steps for Provot's limit): see
//!   [`super::mjcf_callback`], and a comment in the file says so.
//!
//! **What is refused** (one line naming every kind and type): muscles, TGRs, quadripoles and
//! transmitters (state and signals), nonlinear drag, extra worlds (another `dt`), signals,
//! unknown parameters, and a tendon of zero length at the start (MuJoCo gives it a direction
//! where CORDIS takes `u = 0`).

use std::collections::BTreeMap;
use std::fmt::Write;

use super::mjcf_callback::{custom_fields_of, kinds_of};
use crate::{CordisError, LinkKind, LinkType, Particle, Plan, Result, Scene};

/// Shortest text that reads back as the same f64 (`1e-9`, `0.1`, `2.0`).
pub(super) fn num(v: f64) -> String {
    format!("{v:?}")
}

fn vec3(v: [f64; 3]) -> String {
    format!("{} {} {}", num(v[0]), num(v[1]), num(v[2]))
}

const AXES: [(&str, [f64; 3]); 3] = [
    ("x", [1.0, 0.0, 0.0]),
    ("y", [0.0, 1.0, 0.0]),
    ("z", [0.0, 0.0, 1.0]),
];

/// What each particle's slide joints carry: drag damping, anchor stiffness and the
/// stiffness-weighted spring reference (Σ K r, divided by Σ K when written).
#[derive(Clone, Copy, Default)]
struct JointLoad {
    damping: f64,
    stiffness: f64,
    weighted_ref: [f64; 3],
}

/// The kinds and types a scene has that MJCF cannot express, listed in one line; `None` when
/// it has none. Extra worlds, signals and unknown parameters are named too.
pub fn mjcf_refusal(scene: &Scene) -> Option<CordisError> {
    let mut refused: BTreeMap<String, Vec<String>> = BTreeMap::new();
    let mut first_place = None;
    let mut note = |what: String, ty: &str, place: String| {
        first_place.get_or_insert(place);
        let types = refused.entry(what).or_default();
        if !types.iter().any(|t| t == ty) {
            types.push(ty.to_string());
        }
    };
    for t in &scene.types {
        let used_as = match t.kind {
            LinkKind::Spring
            | LinkKind::Damper
            | LinkKind::Anchor
            | LinkKind::Drag
            | LinkKind::Angle
            | LinkKind::Conditional
            | LinkKind::Plane => None,
            other => Some(other.name().to_string()),
        };
        if let Some(kind) = used_as {
            note(kind, &t.name, format!("types.{}.kind", t.name));
        }
        for (k, p) in t.params.iter().enumerate() {
            if p.is_unknown() {
                let name = t.param_name(k);
                note(
                    "unknown parameters (identify them first)".into(),
                    &format!("{}.{name}", t.name),
                    format!("types.{}.{name}", t.name),
                );
            }
        }
    }
    for (i, p) in scene.particles.iter().enumerate() {
        if p.mass.is_unknown() {
            note(
                "unknown parameters (identify them first)".into(),
                &format!("particles[{i}].mass"),
                format!("particles[{i}].mass"),
            );
        }
        if let Some(w) = &p.world {
            note(
                "extra worlds (their own dt)".into(),
                w,
                format!("particles[{i}].world"),
            );
        }
    }
    if let Some(s) = scene.signals.first() {
        note("signals".into(), &s.name, "signals[0]".into());
    }
    let place = first_place?;
    let mut kinds: Vec<String> = refused
        .into_iter()
        .map(|(what, types)| {
            let shown: Vec<&str> = types.iter().take(4).map(String::as_str).collect();
            let more = if types.len() > 4 {
                format!(", … {} in all", types.len())
            } else {
                String::new()
            };
            format!("{what} ({}{more})", shown.join(", "))
        })
        .collect();
    kinds.sort();
    Some(CordisError::scene(
        place,
        format!(
            "MuJoCo (MJCF) cannot express {}; MJCF export covers spring, damper, anchor and drag \
             links, fixed particles and gravity, and with cordis.mujoco angle, conditional and \
             plane links, damping_quadratic and max_elongation",
            kinds.join("; ")
        ),
    ))
}

/// The MJCF model of a scene (see the module docs), or the refusal of [`mjcf_refusal`].
pub fn to_mjcf(scene: &Scene) -> Result<String> {
    scene.validate()?;
    if let Some(e) = mjcf_refusal(scene) {
        return Err(e);
    }
    let LinkElements {
        loads,
        world_sites,
        tendons,
    } = LinkElements::of(scene)?;
    let (bodies, qvel) = bodies_and_velocities(&scene.particles, &loads);
    let plan = Plan::compile(scene)?;
    let custom = custom_fields_of(scene, &plan);
    let callbacks = kinds_of(&plan);
    let mut xml = preamble(scene, &callbacks);
    let _ = write!(xml, "<worldbody>\n{world_sites}{bodies}</worldbody>\n");
    if !tendons.is_empty() {
        let _ = write!(xml, "<tendon>\n{tendons}</tendon>\n");
    }
    xml.push_str(&start_keyframe(qvel));
    xml.push_str(&custom);
    xml.push_str("</mujoco>\n");
    Ok(xml)
}

/// What the links become in MJCF, in link order: the loads on each particle's slide joints,
/// the world body's anchor sites and the `<tendon>` elements.
struct LinkElements {
    loads: Vec<JointLoad>,
    world_sites: String,
    tendons: String,
}

impl LinkElements {
    /// The elements of every link, or the refusal of the first tendon of zero length.
    fn of(scene: &Scene) -> Result<Self> {
        let mut out = LinkElements {
            loads: vec![JointLoad::default(); scene.particles.len()],
            world_sites: String::new(),
            tendons: String::new(),
        };
        for (li, link) in scene.links.iter().enumerate() {
            let t = &scene.types[link.type_index];
            match t.kind {
                LinkKind::Spring => out.add_spring(scene, li, t)?,
                LinkKind::Damper => out.add_damper(scene, li, t),
                LinkKind::Anchor => out.add_anchor(scene, li, t)?,
                LinkKind::Drag => {
                    let i = link.particles[0];
                    if !scene.particles[i].fixed {
                        out.loads[i].damping += t.value("damping").unwrap_or(0.0);
                    }
                }
                // Forces of the state that MJCF has no element for: `<custom>` data for the
                // passive callback of cordis.mujoco (see `mjcf_callback`).
                LinkKind::Angle | LinkKind::Plane => {}
                _ => unreachable!("refused by mjcf_refusal"),
            }
        }
        Ok(out)
    }

    /// A spring's spatial tendon between its two sites (none when both ends are fixed).
    fn add_spring(&mut self, scene: &Scene, li: usize, t: &LinkType) -> Result<()> {
        let ps = &scene.particles;
        let (a, b) = (scene.links[li].particles[0], scene.links[li].particles[1]);
        if ps[a].fixed && ps[b].fixed {
            return Ok(());
        }
        if dist(ps[a].pos, ps[b].pos) < 1e-12 {
            return Err(zero_length(li, "this spring"));
        }
        spatial(
            &mut self.tendons,
            li,
            [
                t.value("stiffness").unwrap_or(0.0),
                t.value("rest_length").unwrap_or(0.0),
                t.value("damping").unwrap_or(0.0),
            ],
            &format!("s{a}"),
            &format!("s{b}"),
        );
        Ok(())
    }

    /// A damper's three fixed tendons, one per axis, over its free ends (none when both are
    /// fixed or its damping is 0).
    fn add_damper(&mut self, scene: &Scene, li: usize, t: &LinkType) {
        let lp = &scene.links[li].particles;
        let z = t.value("damping").unwrap_or(0.0);
        let ends: Vec<(usize, f64)> = [(lp[0], 1.0), (lp[1], -1.0)]
            .into_iter()
            .filter(|&(i, _)| !scene.particles[i].fixed)
            .collect();
        if ends.is_empty() || z == 0.0 {
            return;
        }
        for (axis, _) in AXES {
            let _ = write!(
                self.tendons,
                "<fixed name=\"l{li}_{axis}\" damping=\"{}\">",
                num(z)
            );
            for &(i, coef) in &ends {
                let _ = write!(
                    self.tendons,
                    "<joint joint=\"p{i}_{axis}\" coef=\"{}\"/>",
                    num(coef)
                );
            }
            self.tendons.push_str("</fixed>\n");
        }
    }

    /// An anchor of a free particle: with `l0 = 0` its stiffness on the particle's joints, and
    /// for its damping or a rest length a spatial tendon from a world site at its point.
    fn add_anchor(&mut self, scene: &Scene, li: usize, t: &LinkType) -> Result<()> {
        let link = &scene.links[li];
        let i = link.particles[0];
        let x0 = scene.particles[i].pos;
        if scene.particles[i].fixed {
            return Ok(());
        }
        let point = link.point.or(t.point).unwrap_or(x0);
        let (k, l0, z) = (
            t.value("stiffness").unwrap_or(0.0),
            t.value("rest_length").unwrap_or(0.0),
            t.value("damping").unwrap_or(0.0),
        );
        let linear = l0 == 0.0;
        if linear {
            let load = &mut self.loads[i];
            load.stiffness += k;
            for (r, (p, x)) in load.weighted_ref.iter_mut().zip(point.iter().zip(x0)) {
                *r += k * (p - x);
            }
        }
        if !linear || z != 0.0 {
            if dist(point, x0) < 1e-12 {
                return Err(zero_length(
                    li,
                    "this anchor (with damping or a rest length)",
                ));
            }
            let _ = writeln!(
                self.world_sites,
                "<site name=\"a{li}\" pos=\"{}\"/>",
                vec3(point)
            );
            let (k, l0) = if linear { (0.0, 0.0) } else { (k, l0) };
            spatial(
                &mut self.tendons,
                li,
                [k, l0, z],
                &format!("a{li}"),
                &format!("s{i}"),
            );
        }
        Ok(())
    }
}

/// The refusal of link `li`, `what`, whose tendon has zero length at the start.
fn zero_length(li: usize, what: &str) -> CordisError {
    CordisError::scene(
        format!("links[{li}]"),
        format!(
            "{what} has zero length at the start: MuJoCo's tendon then has a direction \
             where CORDIS has none (u = 0); move the particle or the point"
        ),
    )
}

/// The bodies `p{i}` in particle order (slide joints carrying `loads`, and a site), and the
/// free particles' initial velocities in joint order (m/s, the keyframe's `qvel`).
fn bodies_and_velocities(particles: &[Particle], loads: &[JointLoad]) -> (String, Vec<f64>) {
    let mut bodies = String::new();
    let mut qvel = Vec::new();
    for (i, p) in particles.iter().enumerate() {
        let _ = write!(bodies, "<body name=\"p{i}\" pos=\"{}\">", vec3(p.pos));
        if !p.fixed {
            let _ = write!(
                bodies,
                "<inertial pos=\"0 0 0\" mass=\"{}\" diaginertia=\"1 1 1\"/>",
                num(p.mass.value())
            );
            let load = loads[i];
            for (c, (axis, dir)) in AXES.iter().enumerate() {
                let _ = write!(
                    bodies,
                    "<joint name=\"p{i}_{axis}\" type=\"slide\" axis=\"{}\"",
                    vec3(*dir)
                );
                if load.damping != 0.0 {
                    let _ = write!(bodies, " damping=\"{}\"", num(load.damping));
                }
                if load.stiffness != 0.0 {
                    let _ = write!(
                        bodies,
                        " stiffness=\"{}\" springref=\"{}\"",
                        num(load.stiffness),
                        num(load.weighted_ref[c] / load.stiffness)
                    );
                }
                bodies.push_str("/>");
            }
            qvel.extend(p.vel);
        }
        let _ = writeln!(bodies, "<site name=\"s{i}\"/></body>");
    }
    (bodies, qvel)
}

/// The model's opening: the `<mujoco>` tag, the comments on how to run it (naming the
/// `callbacks` kinds, if any) and the `<option>` of the CORDIS scheme.
fn preamble(scene: &Scene, callbacks: &[&str]) -> String {
    let mut xml = String::new();
    let _ = writeln!(
        xml,
        "<mujoco model=\"cordis\">\n<!-- Written by cordis {}: the CORDIS scheme as MuJoCo's \
         semi-implicit Euler with explicit damping. Body p{{i}} is particle i; start with \
         mj_resetDataKeyframe(model, data, 0) to get the initial velocities. -->",
        env!("CARGO_PKG_VERSION")
    );
    if !callbacks.is_empty() {
        let _ = writeln!(
            xml,
            "<!-- MJCF has no element for this scene's {}: their data are in <custom>, and \
             cordis.mujoco.load(path) (Python) adds them while MuJoCo integrates (forces by \
             the passive callback, Provot's limit between steps). Plain MuJoCo leaves them out. -->",
            callbacks.join(", ")
        );
    }
    let _ = writeln!(
        xml,
        "<option timestep=\"{}\" gravity=\"{}\" integrator=\"Euler\">\
         <flag contact=\"disable\" eulerdamp=\"disable\"/></option>",
        num(scene.dt),
        vec3(scene.gravity)
    );
    xml
}

/// The keyframe `cordis_start`: every joint at its initial position, with velocities `qvel`
/// (m/s); empty when no joint moves.
fn start_keyframe(qvel: Vec<f64>) -> String {
    if qvel.is_empty() {
        return String::new();
    }
    let zeros = vec!["0"; qvel.len()].join(" ");
    let v: Vec<String> = qvel.into_iter().map(num).collect();
    format!(
        "<keyframe><key name=\"cordis_start\" qpos=\"{zeros}\" qvel=\"{}\"/></keyframe>\n",
        v.join(" ")
    )
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// A spatial tendon between two sites: `[stiffness, springlength, damping]`.
fn spatial(out: &mut String, li: usize, ksz: [f64; 3], a: &str, b: &str) {
    let [k, l0, z] = ksz;
    let _ = writeln!(
        out,
        "<spatial name=\"l{li}\" stiffness=\"{}\" springlength=\"{}\" damping=\"{}\">\
         <site site=\"{a}\"/><site site=\"{b}\"/></spatial>",
        num(k),
        num(l0),
        num(z)
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{examples, LinkType, Param, Particle};

    #[test]
    fn the_rigid_example_has_one_body_per_particle_in_order() {
        let scene = examples::rigid();
        let xml = to_mjcf(&scene).unwrap();
        let mut at = 0;
        for i in 0..scene.num_particles() {
            let tag = format!("<body name=\"p{i}\" ");
            at += xml[at..]
                .find(&tag)
                .expect("every particle has its body, in order");
        }
        assert_eq!(xml.matches("<spatial ").count(), scene.links.len());
        assert!(xml.contains("integrator=\"Euler\""));
        assert!(xml.contains("eulerdamp=\"disable\""));
    }

    #[test]
    fn refusal_names_every_kind_it_cannot_express_on_one_line() {
        let e = to_mjcf(&examples::follower()).unwrap_err().to_string();
        assert!(!e.contains('\n'), "{e}");
        for kind in ["extra worlds", "tgr", "nonlinear_drag", "signals"] {
            assert!(e.contains(kind), "{kind} missing from {e}");
        }
        let e = to_mjcf(&examples::muscle()).unwrap_err().to_string();
        assert!(
            e.starts_with("types.left.kind: MuJoCo (MJCF) cannot express muscle (left, right)"),
            "{e}"
        );
    }

    #[test]
    fn kinds_without_an_element_are_exported_with_their_callback_data_and_a_comment() {
        for (scene, kinds) in [
            (examples::horse(), "angle:"),
            (examples::cloth(4, 4), "max_elongation:"),
            (examples::fluid(6, 6), "conditional:"),
            (examples::bouncing_ball(), "plane:"),
        ] {
            let xml = to_mjcf(&scene).unwrap();
            assert!(
                xml.contains(&format!(
                    "MJCF has no element for this scene's {}",
                    &kinds[..kinds.len() - 1]
                )),
                "{xml}"
            );
            assert!(xml.contains("<numeric name=\"cordis_format\" size=\"1\" data=\"1.0\"/>"));
        }
        assert!(!to_mjcf(&examples::rigid()).unwrap().contains("<custom>"));
    }

    #[test]
    fn zero_rest_anchor_goes_to_the_joints_and_a_zero_length_tendon_is_refused() {
        let mut s = Scene::new(0.01);
        s.add_particle(Particle::new(2.0, [0.0, 1.0, 0.0]));
        s.add_type(LinkType::new("pin", LinkKind::Anchor).with("stiffness", 5.0));
        s.add_link("pin", &[0]);
        let xml = to_mjcf(&s).unwrap();
        assert!(xml.contains("stiffness=\"5.0\" springref=\"0.0\""), "{xml}");
        assert!(!xml.contains("<tendon>"));
        s.types[0] = LinkType::new("pin", LinkKind::Anchor)
            .with("stiffness", 5.0)
            .with("damping", 0.5);
        let e = to_mjcf(&s).unwrap_err().to_string();
        assert!(e.starts_with("links[0]: this anchor"), "{e}");
    }

    #[test]
    fn unknown_parameters_are_refused_by_name() {
        let mut s = examples::rigid();
        s.types[2].params[0] = Param::Unknown(crate::Bounds {
            min: 1.0,
            max: 2.0,
            init: None,
        });
        let e = to_mjcf(&s).unwrap_err().to_string();
        assert!(e.starts_with("types.h_top.stiffness: "), "{e}");
        assert!(
            e.contains("unknown parameters (identify them first) (h_top.stiffness)"),
            "{e}"
        );
    }
}
