"""`cordis export --gltf` / `--out`: a motion for Blender and three.js, and the replay as a
trajectory file (issue 18, SPEC §7.3).

The glTF is read back by pygltflib, an independent reader (scripts/python-test.sh installs
it): its structure, every accessor's count and bounds, and every frame's positions against the
trajectory at float32 rounding. The MuJoCo export is tested in test_mujoco.py.
"""

import json
import os
import shutil
import subprocess
import sys
import warnings

import numpy as np
import pytest

import cordis

pygltflib = pytest.importorskip("pygltflib")  # python-test.sh installs it: never skipped in CI
import pygltflib.validator  # noqa: E402

DTYPES = {5121: np.uint8, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
WIDTH = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}


def cordis_exe() -> str:
    exe = shutil.which("cordis", path=os.path.dirname(sys.executable))
    assert exe is not None, "the cordis console script is not installed beside python"
    return exe


def run(*args):
    return subprocess.run([cordis_exe(), *map(str, args)], capture_output=True, text=True,
                          timeout=300)


def view_values(g, blob: bytes, view_index: int, offset, dtype, count: int) -> np.ndarray:
    view = g.bufferViews[view_index]
    dtype = np.dtype(dtype)
    start = (view.byteOffset or 0) + (offset or 0)
    assert start + count * dtype.itemsize <= (view.byteOffset or 0) + view.byteLength
    return np.frombuffer(blob, dtype=dtype, count=count, offset=start)


def accessor(g, blob: bytes, index: int) -> np.ndarray:
    """An accessor's values as the spec defines them: its buffer view (or zeros), then the
    sparse substitutions (glTF 2.0 §3.6.2.3)."""
    a = g.accessors[index]
    width = WIDTH[a.type]
    dtype = DTYPES[a.componentType]
    if a.bufferView is None:
        values = np.zeros(a.count * width, dtype=dtype)
    else:
        values = view_values(g, blob, a.bufferView, a.byteOffset, dtype, a.count * width).copy()
    if a.sparse is not None:
        sp = a.sparse
        at = view_values(g, blob, sp.indices.bufferView, sp.indices.byteOffset,
                         DTYPES[sp.indices.componentType], sp.count)
        assert (np.diff(at.astype(np.int64)) > 0).all(), "sparse indices strictly increase"
        new = view_values(g, blob, sp.values.bufferView, sp.values.byteOffset, dtype,
                          sp.count * width)
        values.reshape(a.count, width)[at] = new.reshape(sp.count, width)
    return values.reshape(a.count, width) if width > 1 else values


def check_bounds(g, blob: bytes, index: int) -> None:
    a = g.accessors[index]
    values = accessor(g, blob, index).reshape(a.count, -1)
    assert a.min is not None and a.max is not None, f"accessor {index} has no bounds"
    np.testing.assert_array_equal(np.asarray(a.min, np.float32), values.min(axis=0))
    np.testing.assert_array_equal(np.asarray(a.max, np.float32), values.max(axis=0))


def linked_pairs(d):
    seen, pairs = set(), []
    for link in d.get("links", []):
        ps = link["particles"]
        for a, b in zip(ps, ps[1:]):
            if a != b and (min(a, b), max(a, b)) not in seen:
                seen.add((min(a, b), max(a, b)))
                pairs.append((a, b))
    return pairs


def test_gltf_of_the_cloth_motion_has_every_frame_at_float32(tmp_path):
    scene = cordis.example("cloth")
    frames = 400
    traj = scene.simulate(frames)
    (tmp_path / "cloth.json").write_text(scene.to_json())
    cordis.write_trajectory(tmp_path / "cloth.npy", traj)
    out = run("export", tmp_path / "cloth.json", "--trajectory", tmp_path / "cloth.npy",
              "--gltf", tmp_path / "cloth.gltf")
    assert out.returncode == 0, out.stderr

    g = pygltflib.GLTF2().load(str(tmp_path / "cloth.gltf"))
    assert g.asset.version == "2.0"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # "a provisional function"
        assert pygltflib.validator.validate(g, warning=True) == []
    assert len(g.buffers) == 1 and g.buffers[0].uri.startswith("data:"), "self-contained"
    blob = g.get_data_from_buffer_uri(g.buffers[0].uri)
    assert len(blob) == g.buffers[0].byteLength

    n = traj.shape[1]
    (mesh,) = g.meshes
    points, lines = mesh.primitives
    assert (points.mode, lines.mode) == (pygltflib.POINTS, pygltflib.LINES)
    assert points.attributes.POSITION == lines.attributes.POSITION
    base = accessor(g, blob, points.attributes.POSITION)
    assert base.shape == (n, 3) and not base.any(), "base positions are zero"
    check_bounds(g, blob, points.attributes.POSITION)

    pairs = linked_pairs(scene.to_dict())
    indices = accessor(g, blob, lines.indices)
    assert g.accessors[lines.indices].count == 2 * len(pairs) == 2 * 5826
    assert [tuple(p) for p in indices.reshape(-1, 2).tolist()] == pairs

    assert len(points.targets) == len(lines.targets) == frames
    for k, target in enumerate(points.targets):
        assert lines.targets[k]["POSITION"] == target["POSITION"]
        assert g.accessors[target["POSITION"]].count == n
        check_bounds(g, blob, target["POSITION"])
        np.testing.assert_array_equal(accessor(g, blob, target["POSITION"]),
                                      traj[k].astype(np.float32), err_msg=f"frame {k}")
    assert mesh.weights == [1.0] + [0.0] * (frames - 1), "the rest pose is frame 0"

    (anim,) = g.animations
    (channel,) = anim.channels
    assert (channel.target.node, channel.target.path) == (0, "weights")
    assert g.nodes[0].mesh == 0 and g.scenes[g.scene].nodes == [0]
    sampler = anim.samplers[channel.sampler]
    assert sampler.interpolation == "LINEAR"
    times = accessor(g, blob, sampler.input)
    check_bounds(g, blob, sampler.input)
    np.testing.assert_array_equal(times, (np.arange(frames) * scene.dt).astype(np.float32))
    weights = accessor(g, blob, sampler.output)
    assert g.accessors[sampler.output].count == frames * frames
    assert g.accessors[sampler.output].sparse.count == frames, "one stored weight a frame"
    np.testing.assert_array_equal(weights.reshape(frames, frames), np.eye(frames))


def test_export_writes_the_replay_as_npy_and_csv(tmp_path):
    scene = cordis.example("rigid")
    (tmp_path / "rigid.json").write_text(scene.to_json())
    want = scene.simulate(50)
    for ext in ("npy", "csv"):
        out = run("export", tmp_path / "rigid.json", "--frames", 50,
                  "--out", tmp_path / f"replay.{ext}", "--gltf", tmp_path / f"replay-{ext}.gltf",
                  "--json")
        assert out.returncode == 0, out.stderr
        summary = json.loads(out.stdout)
        assert summary["frames"] == 50 and summary["out"].endswith(f"replay.{ext}")
        got = cordis.read_trajectory(tmp_path / f"replay.{ext}")
        np.testing.assert_array_equal(np.asarray(got), want)


def test_bad_export_input_is_one_line_and_writes_nothing(tmp_path):
    scene = cordis.example("rigid")
    (tmp_path / "rigid.json").write_text(scene.to_json())
    cordis.write_trajectory(tmp_path / "other.npy", cordis.example("muscle").simulate(5))
    gltf, xml = tmp_path / "a.gltf", tmp_path / "a.xml"
    cases = [
        (["--trajectory", tmp_path / "other.npy", "--gltf", gltf, "--mjcf", xml],
         f"{tmp_path / 'other.npy'}: trajectory: has 3 particles, the scene has 15"),
        (["--gltf", gltf], "--gltf: needs a motion"),
        (["--frames", 5, "--gltf", tmp_path / "rigid.json"], "the same file as the input"),
        (["--mjcf", xml, "--gltf", xml, "--frames", 3], "the same file as the output"),
        (["--frames", 0, "--out", tmp_path / "r.npy"], "--frames: must be at least 1"),
        ([], "nothing to write"),
    ]
    before = (tmp_path / "rigid.json").read_bytes()
    for args, message in cases:
        out = run("export", tmp_path / "rigid.json", *args)
        assert out.returncode == 2, (args, out.stderr)
        lines = out.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("error: "), out.stderr
        assert message in lines[0], (message, lines[0])
        assert not gltf.exists() and not xml.exists() and not (tmp_path / "r.npy").exists()
    assert (tmp_path / "rigid.json").read_bytes() == before


def test_python_export_writes_the_same_files_as_the_cli(tmp_path):
    scene = cordis.example("rigid")
    traj = scene.simulate(30)
    (tmp_path / "rigid.json").write_text(scene.to_json())
    cordis.write_trajectory(tmp_path / "rigid.npy", traj)
    out = run("export", tmp_path / "rigid.json", "--trajectory", tmp_path / "rigid.npy",
              "--gltf", tmp_path / "cli.gltf", "--mjcf", tmp_path / "cli.xml")
    assert out.returncode == 0, out.stderr
    cordis.export_mjcf(scene, tmp_path / "py.xml")
    cordis.export_gltf(scene, traj, tmp_path / "py.gltf")
    assert (tmp_path / "py.xml").read_bytes() == (tmp_path / "cli.xml").read_bytes()
    assert (tmp_path / "py.gltf").read_bytes() == (tmp_path / "cli.gltf").read_bytes()
    with pytest.raises(cordis.SceneError, match="cannot express muscle"):
        cordis.export_mjcf(cordis.example("muscle"), tmp_path / "muscle.xml")
    assert not (tmp_path / "muscle.xml").exists()
    with pytest.raises(cordis.TrajectoryError, match="has 3 particles, the scene has 15"):
        cordis.export_gltf(scene, np.zeros((4, 3, 3)), tmp_path / "bad.gltf")
