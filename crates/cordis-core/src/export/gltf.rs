//! glTF 2.0 of a motion: the particles as points and the links as line segments, animated
//! frame by frame, in one self-contained `.gltf` (its buffer embedded as a base64 data URI).
//!
//! **Layout.** One node `cordis` holds one mesh with a `POINTS` primitive (every particle, in
//! particle order) and a `LINES` primitive (one segment per particle pair the scene links:
//! springs, dampers, muscles, an angle's two arms, binary couplings, a quadripole's two
//! dipoles; conditional pairs change every step and are not drawn). Both primitives share one
//! vertex per particle and one **morph target per frame** holding that frame's positions, and
//! the base positions are zero, so the shape at frame k is `0 + 1 · target_k`: every frame's
//! positions are the trajectory's rounded to float32, exactly, not a sum of two roundings. The
//! animation `motion` drives the node's morph weights with keyframe k at `t = k dt` being the
//! one-hot vector `e_k` and linear interpolation between keyframes, i.e. linear
//! interpolation of positions. The node's default weights show frame 0.
//!
//! **Why morph targets.** Skinning the segments to one joint per particle would store no more
//! than the joints' translations, but three.js skins triangle meshes only, so its lines would
//! stay still; morph targets animate points and lines in both three.js and Blender (shape
//! keys). The weights are `T²` floats, all zero but one per keyframe, so they are a **sparse
//! accessor** (glTF 2.0 §3.6.2.3, read by three.js and Blender): `T` indices `k (T + 1)` and
//! `T` ones over an implicit zero array, 8 bytes a frame instead of `4 T` (positions take
//! `12 N` a frame); the memory is checked first. More than 65,535 frames are refused (the
//! indices are u32). A reader that ignores morph
//! targets altogether (trimesh loads the two primitives as a point cloud and a path) sees every
//! vertex at the zero base; base positions at frame 0 with displacements would fix that, but a
//! reader's `base + displacement` in float32 is then no longer the trajectory's float32 value.
//!
//! Coordinates are written as they are (glTF's +Y is up; the shipped examples' gravity is -Y).

use std::collections::HashSet;

use base64::Engine;
use serde_json::json;

use crate::{CordisError, Result, Scene, Trajectory};

/// The particle pairs drawn as segments, in link order, each pair once.
pub fn drawn_pairs(scene: &Scene) -> Vec<[usize; 2]> {
    let mut seen = HashSet::new();
    let mut pairs = Vec::new();
    let mut add = |a: usize, b: usize| {
        if a != b && seen.insert((a.min(b), a.max(b))) {
            pairs.push([a, b]);
        }
    };
    for link in &scene.links {
        for w in link.particles.windows(2) {
            add(w[0], w[1]);
        }
    }
    for c in &scene.couplings {
        for w in c.particles.chunks_exact(2) {
            add(w[0], w[1]);
        }
    }
    pairs
}

/// Bytes the glTF of `frames` frames of `particles` particles holds before base64 encoding.
fn raw_bytes(frames: usize, particles: usize, pairs: usize) -> f64 {
    let (t, n) = (frames as f64, particles as f64);
    12.0 * n * (t + 1.0) + 12.0 * t + 8.0 * pairs as f64
}

/// The glTF JSON text of `traj`, a motion of `scene`, with frames `dt` seconds apart.
pub fn to_gltf(scene: &Scene, traj: &Trajectory, dt: f64) -> Result<String> {
    let (frames, n) = (traj.frames(), traj.particles());
    traj.check_fits(scene.num_particles(), 1)?;
    crate::arg::number("dt", dt, crate::arg::Low::Above(0.0), f64::MAX, "s")?;
    let pairs = drawn_pairs(scene);
    let raw = raw_bytes(frames, n, pairs.len());
    crate::arg::fits_in_memory(
        "--gltf",
        raw * (1.0 + 4.0 / 3.0 * 2.0),
        &format!("a glTF of {frames} frames × {n} particles"),
    )?;
    if n == 0 {
        return Err(CordisError::scene("particles", "no particle to draw"));
    }
    if frames > usize::from(u16::MAX) {
        return Err(CordisError::trajectory(
            "trajectory",
            format!("has {frames} frames, a glTF animation here takes at most 65535"),
        ));
    }
    let mut buf: Vec<u8> = Vec::with_capacity(raw as usize);
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    // A buffer view over buf[start..], index returned.
    fn view(
        views: &mut Vec<serde_json::Value>,
        buf: &[u8],
        start: usize,
        target: Option<u32>,
    ) -> usize {
        let mut v = json!({"buffer": 0, "byteOffset": start, "byteLength": buf.len() - start});
        if let Some(t) = target {
            v["target"] = t.into();
        }
        views.push(v);
        views.len() - 1
    }

    // 0: the base positions, all zero (the targets hold the frames).
    let start = buf.len();
    buf.resize(start + 12 * n, 0);
    let base_view = view(&mut views, &buf, start, Some(34962));
    accessors.push(
        json!({"bufferView": base_view, "componentType": 5126, "count": n,
        "type": "VEC3", "min": [0.0, 0.0, 0.0], "max": [0.0, 0.0, 0.0]}),
    );

    // 1: the segments' vertex indices.
    let wide = n > usize::from(u16::MAX);
    let indices = if pairs.is_empty() {
        None
    } else {
        let start = buf.len();
        for &i in pairs.iter().flatten() {
            if wide {
                buf.extend_from_slice(&(i as u32).to_le_bytes());
            } else {
                buf.extend_from_slice(&(i as u16).to_le_bytes());
            }
        }
        while buf.len() % 4 != 0 {
            buf.push(0);
        }
        let end = start + pairs.len() * 2 * if wide { 4 } else { 2 };
        views.push(
            json!({"buffer": 0, "byteOffset": start, "byteLength": end - start,
            "target": 34963}),
        );
        accessors.push(json!({"bufferView": views.len() - 1,
            "componentType": if wide { 5125 } else { 5123 },
            "count": pairs.len() * 2, "type": "SCALAR"}));
        Some(accessors.len() - 1)
    };

    // The keyframe times, strictly increasing in float32.
    let start = buf.len();
    let mut last = f32::NEG_INFINITY;
    for k in 0..frames {
        let t = (k as f64 * dt) as f32;
        if t <= last || !t.is_finite() {
            return Err(CordisError::argument(
                "dt",
                format!("frame {k}'s time {} s is not after frame {}'s in float32: use a larger dt or fewer frames", k as f64 * dt, k.saturating_sub(1)),
            ));
        }
        last = t;
        buf.extend_from_slice(&t.to_le_bytes());
    }
    let times_view = view(&mut views, &buf, start, None);
    accessors.push(
        json!({"bufferView": times_view, "componentType": 5126, "count": frames,
        "type": "SCALAR", "min": [0.0], "max": [last]}),
    );
    let times = accessors.len() - 1;

    // The weights: keyframe k is the one-hot e_k, i.e. a one at k T + k of T² zeros.
    let start = buf.len();
    for k in 0..frames {
        buf.extend_from_slice(&((k * frames + k) as u32).to_le_bytes());
    }
    let indices_view = view(&mut views, &buf, start, None);
    let start = buf.len();
    for _ in 0..frames {
        buf.extend_from_slice(&1.0f32.to_le_bytes());
    }
    let ones_view = view(&mut views, &buf, start, None);
    accessors.push(
        json!({"componentType": 5126, "count": frames * frames, "type": "SCALAR",
        "sparse": {"count": frames,
            "indices": {"bufferView": indices_view, "componentType": 5125},
            "values": {"bufferView": ones_view}}}),
    );
    let weights = accessors.len() - 1;

    // One target per frame, in one buffer view.
    let start = buf.len();
    let flat = traj.as_flat();
    let mut target_accessors = Vec::with_capacity(frames);
    let first_target = accessors.len();
    for k in 0..frames {
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for i in 0..n {
            for c in 0..3 {
                let v = flat[(k * n + i) * 3 + c];
                let f = v as f32;
                if !f.is_finite() {
                    return Err(CordisError::trajectory(
                        format!("frame {k}, particle {i}, {}", ["x", "y", "z"][c]),
                        format!("{v} does not fit in a float32"),
                    ));
                }
                lo[c] = lo[c].min(f);
                hi[c] = hi[c].max(f);
                buf.extend_from_slice(&f.to_le_bytes());
            }
        }
        target_accessors.push(json!({"POSITION": first_target + k}));
        accessors.push(json!({"bufferView": 0, "byteOffset": 12 * n * k,
            "componentType": 5126, "count": n, "type": "VEC3", "min": lo, "max": hi}));
    }
    let targets_view = view(&mut views, &buf, start, Some(34962));
    for a in &mut accessors[first_target..] {
        a["bufferView"] = targets_view.into();
    }

    let mut primitives = vec![json!({"attributes": {"POSITION": 0}, "mode": 0,
        "material": 0, "targets": target_accessors})];
    if let Some(ix) = indices {
        primitives.push(
            json!({"attributes": {"POSITION": 0}, "indices": ix, "mode": 1,
            "material": 1, "targets": target_accessors}),
        );
    }
    let mut initial = vec![0.0f32; frames];
    initial[0] = 1.0;
    let names: Vec<String> = (0..frames).map(|k| format!("frame {k}")).collect();
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&buf)
    );
    let doc = json!({
        "asset": {"version": "2.0", "generator": format!("cordis {}", env!("CARGO_PKG_VERSION"))},
        "scene": 0,
        "scenes": [{"name": "cordis", "nodes": [0]}],
        "nodes": [{"name": "cordis", "mesh": 0}],
        "meshes": [{"name": "network", "primitives": primitives, "weights": initial,
            "extras": {"targetNames": names}}],
        "materials": [
            {"name": "particles", "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.35, 0.2, 1.0]}},
            {"name": "links", "pbrMetallicRoughness": {"baseColorFactor": [0.2, 0.45, 0.8, 1.0]}},
        ],
        "animations": [{"name": "motion",
            "samplers": [{"input": times, "output": weights, "interpolation": "LINEAR"}],
            "channels": [{"sampler": 0, "target": {"node": 0, "path": "weights"}}]}],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": buf.len(), "uri": uri}],
    });
    Ok(doc.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::examples;

    fn decode(doc: &serde_json::Value) -> Vec<u8> {
        let uri = doc["buffers"][0]["uri"].as_str().unwrap();
        let b64 = uri
            .strip_prefix("data:application/octet-stream;base64,")
            .unwrap();
        base64::engine::general_purpose::STANDARD
            .decode(b64)
            .unwrap()
    }

    #[test]
    fn each_frame_is_a_morph_target_with_the_float32_positions() {
        let scene = examples::rigid();
        let traj = scene.simulate(7).unwrap();
        let doc: serde_json::Value =
            serde_json::from_str(&to_gltf(&scene, &traj, scene.dt).unwrap()).unwrap();
        let buf = decode(&doc);
        assert_eq!(doc["buffers"][0]["byteLength"], buf.len());
        let targets = doc["meshes"][0]["primitives"][0]["targets"]
            .as_array()
            .unwrap();
        assert_eq!(targets.len(), 7);
        let n = scene.num_particles();
        for (k, t) in targets.iter().enumerate() {
            let a = &doc["accessors"][t["POSITION"].as_u64().unwrap() as usize];
            let v = &doc["bufferViews"][a["bufferView"].as_u64().unwrap() as usize];
            let off =
                (v["byteOffset"].as_u64().unwrap() + a["byteOffset"].as_u64().unwrap()) as usize;
            for i in 0..n {
                for c in 0..3 {
                    let at = off + 12 * i + 4 * c;
                    let got = f32::from_le_bytes(buf[at..at + 4].try_into().unwrap());
                    assert_eq!(got, traj.pos(k, i)[c] as f32);
                }
            }
        }
        let lines = &doc["meshes"][0]["primitives"][1];
        assert_eq!(lines["mode"], 1);
        let ix = &doc["accessors"][lines["indices"].as_u64().unwrap() as usize];
        assert_eq!(ix["count"], 2 * scene.links.len());
    }

    #[test]
    fn a_motion_of_another_scene_is_refused_by_its_particle_count() {
        let scene = examples::rigid();
        let e = to_gltf(&scene, &Trajectory::zeros(3, 2), 0.01)
            .unwrap_err()
            .to_string();
        assert_eq!(e, "trajectory: has 2 particles, the scene has 15");
    }

    #[test]
    fn a_position_beyond_float32_names_its_frame_and_particle() {
        let scene = examples::rigid();
        let mut traj = scene.simulate(3).unwrap();
        let mut frame = vec![crate::Vec3::zeros(); 15];
        traj.frame_into(2, &mut frame);
        frame[4].y = 1e39;
        traj.set_frame(2, &frame);
        let e = to_gltf(&scene, &traj, 0.01).unwrap_err().to_string();
        assert!(e.starts_with("frame 2, particle 4, y: "), "{e}");
    }
}
