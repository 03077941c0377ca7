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
    let mut buffer = Buffer {
        bytes: Vec::with_capacity(raw as usize),
        views: Vec::new(),
        accessors: Vec::new(),
    };
    buffer.push_base_positions(n);
    let indices = buffer.push_segment_indices(&pairs, n);
    let times = buffer.push_keyframe_times(frames, dt)?;
    let weights = buffer.push_one_hot_weights(frames);
    let targets = buffer.push_frame_targets(traj)?;
    let primitives = primitives(indices, &targets);
    Ok(document(buffer, primitives, frames, times, weights).to_string())
}

/// The glTF's one binary buffer, with the buffer views and accessors into it, in the order
/// they are pushed.
struct Buffer {
    bytes: Vec<u8>,
    views: Vec<serde_json::Value>,
    accessors: Vec<serde_json::Value>,
}

impl Buffer {
    /// A buffer view over bytes[start..], index returned.
    fn view(&mut self, start: usize, target: Option<u32>) -> usize {
        let mut v =
            json!({"buffer": 0, "byteOffset": start, "byteLength": self.bytes.len() - start});
        if let Some(t) = target {
            v["target"] = t.into();
        }
        self.views.push(v);
        self.views.len() - 1
    }

    /// Accessor 0: the base positions of the `n` vertices, all zero (the targets hold the
    /// frames).
    fn push_base_positions(&mut self, n: usize) {
        let start = self.bytes.len();
        self.bytes.resize(start + 12 * n, 0);
        let base_view = self.view(start, Some(34962));
        self.accessors.push(
            json!({"bufferView": base_view, "componentType": 5126, "count": n,
            "type": "VEC3", "min": [0.0, 0.0, 0.0], "max": [0.0, 0.0, 0.0]}),
        );
    }

    /// The accessor of the segments' vertex indices (u16, u32 when the `n` particles are more
    /// than 65,535), `None` when there is no pair to draw.
    fn push_segment_indices(&mut self, pairs: &[[usize; 2]], n: usize) -> Option<usize> {
        let wide = n > usize::from(u16::MAX);
        if pairs.is_empty() {
            return None;
        }
        let buf = &mut self.bytes;
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
        self.views.push(
            json!({"buffer": 0, "byteOffset": start, "byteLength": end - start,
            "target": 34963}),
        );
        let indices_view = self.views.len() - 1;
        self.accessors.push(json!({"bufferView": indices_view,
            "componentType": if wide { 5125 } else { 5123 },
            "count": pairs.len() * 2, "type": "SCALAR"}));
        Some(self.accessors.len() - 1)
    }

    /// The accessor of the `frames` keyframe times `k dt` (s), refused unless strictly
    /// increasing in float32.
    fn push_keyframe_times(&mut self, frames: usize, dt: f64) -> Result<usize> {
        let start = self.bytes.len();
        let mut last = f32::NEG_INFINITY;
        for k in 0..frames {
            let t = (k as f64 * dt) as f32;
            if !t.is_finite() {
                return Err(CordisError::argument(
                    "dt",
                    format!(
                        "frame {k}'s time {:e} s is beyond float32 (3.4e38): use a smaller dt or fewer frames",
                        k as f64 * dt
                    ),
                ));
            }
            if t <= last {
                return Err(CordisError::argument(
                    "dt",
                    format!("frame {k}'s time {} s is not after frame {}'s in float32: use a larger dt or fewer frames", k as f64 * dt, k.saturating_sub(1)),
                ));
            }
            last = t;
            self.bytes.extend_from_slice(&t.to_le_bytes());
        }
        let times_view = self.view(start, None);
        self.accessors.push(
            json!({"bufferView": times_view, "componentType": 5126, "count": frames,
            "type": "SCALAR", "min": [0.0], "max": [last]}),
        );
        Ok(self.accessors.len() - 1)
    }

    /// The sparse accessor of the morph weights: keyframe k is the one-hot e_k, i.e. a one at
    /// k T + k of T² zeros (T = `frames`).
    fn push_one_hot_weights(&mut self, frames: usize) -> usize {
        let start = self.bytes.len();
        for k in 0..frames {
            self.bytes
                .extend_from_slice(&((k * frames + k) as u32).to_le_bytes());
        }
        let indices_view = self.view(start, None);
        let start = self.bytes.len();
        for _ in 0..frames {
            self.bytes.extend_from_slice(&1.0f32.to_le_bytes());
        }
        let ones_view = self.view(start, None);
        self.accessors.push(
            json!({"componentType": 5126, "count": frames * frames, "type": "SCALAR",
            "sparse": {"count": frames,
                "indices": {"bufferView": indices_view, "componentType": 5125},
                "values": {"bufferView": ones_view}}}),
        );
        self.accessors.len() - 1
    }

    /// One morph target per frame of `traj` (its float32 positions, m), all in one buffer
    /// view; the targets' `POSITION` entries returned, or the refusal of the first position
    /// beyond float32.
    fn push_frame_targets(&mut self, traj: &Trajectory) -> Result<Vec<serde_json::Value>> {
        let (frames, n) = (traj.frames(), traj.particles());
        let start = self.bytes.len();
        let flat = traj.as_flat();
        let mut target_accessors = Vec::with_capacity(frames);
        let first_target = self.accessors.len();
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
                    self.bytes.extend_from_slice(&f.to_le_bytes());
                }
            }
            target_accessors.push(json!({"POSITION": first_target + k}));
            // The view is pushed once every frame is in: `bufferView` is set below.
            let accessor = json!({"bufferView": 0, "byteOffset": 12 * n * k,
                "componentType": 5126, "count": n, "type": "VEC3", "min": lo, "max": hi});
            self.accessors.push(accessor);
        }
        let targets_view = self.view(start, Some(34962));
        for a in &mut self.accessors[first_target..] {
            a["bufferView"] = targets_view.into();
        }
        Ok(target_accessors)
    }
}

/// The mesh's primitives over accessor 0's vertices, both morphed by `targets`: the points,
/// and the lines when there are segment `indices`.
fn primitives(indices: Option<usize>, targets: &[serde_json::Value]) -> Vec<serde_json::Value> {
    let mut primitives = vec![json!({"attributes": {"POSITION": 0}, "mode": 0,
        "material": 0, "targets": targets})];
    if let Some(ix) = indices {
        primitives.push(
            json!({"attributes": {"POSITION": 0}, "indices": ix, "mode": 1,
            "material": 1, "targets": targets}),
        );
    }
    primitives
}

/// The glTF document: the node `cordis` with the mesh of `primitives` (showing frame 0 of
/// `frames`), the materials, the animation `motion` from the accessors `times` (s) to
/// `weights`, and the buffer embedded as base64.
fn document(
    buffer: Buffer,
    primitives: Vec<serde_json::Value>,
    frames: usize,
    times: usize,
    weights: usize,
) -> serde_json::Value {
    let Buffer {
        bytes: buf,
        views,
        accessors,
    } = buffer;
    let mut initial = vec![0.0f32; frames];
    initial[0] = 1.0;
    let names: Vec<String> = (0..frames).map(|k| format!("frame {k}")).collect();
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&buf)
    );
    json!({
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
    })
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

    /// Guards the keyframe times' two refusals, each with the advice that fits it: times that
    /// overflow float32 want a smaller dt, times float32 cannot tell apart a larger one.
    #[test]
    fn keyframe_times_beyond_or_below_float32_say_which() {
        let scene = examples::rigid();
        let traj = scene.simulate(3).unwrap();
        let e = to_gltf(&scene, &traj, 3e38).unwrap_err().to_string();
        assert!(
            e.starts_with("dt: frame 2's time 6e38 s is beyond float32")
                && e.contains("smaller dt"),
            "{e}"
        );
        let e = to_gltf(&scene, &traj, 1e-46).unwrap_err().to_string();
        assert!(
            e.starts_with("dt: frame 1's time")
                && e.contains("not after frame 0's")
                && e.contains("larger dt"),
            "{e}"
        );
    }
}
