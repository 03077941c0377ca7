"""cordis.read_trajectory on the field's marker formats: C3D written by a third-party library
(the `c3d` package), OpenSim TRC, tracker .npz (TAP-Vid / CoTracker), tables with named
columns; rates, units and gaps (NaN, never zeros); bad input names its place."""

import numpy as np
import pytest

import cordis

import c3d  # noqa: E402  (the c3d package from PyPI, installed by scripts/python-test.sh)


def _positions(frames, markers):
    """(T, N, 3) positions in m, distinct everywhere."""
    t = np.arange(frames)[:, None, None]
    i = np.arange(markers)[None, :, None]
    k = np.arange(3)[None, None, :]
    return 0.1 * t + 0.01 * i + 1.0 * k + 0.5


def test_a_c3d_written_by_the_c3d_package_reads_markers_rate_and_gaps(tmp_path):
    pos = _positions(5, 3)
    writer = c3d.Writer(point_rate=200.0, point_units="mm  ")
    writer.set_point_labels(["LASI", "RASI", "SACR"])
    frames = []
    for f in range(5):
        points = np.zeros((3, 5), dtype=np.float32)
        points[:, :3] = pos[f] * 1000.0
        if f == 2:
            points[1, 3] = -1.0  # residual < 0: an invalid sample
        frames.append((points, np.zeros((0, 0), dtype=np.float32)))
    writer.add_frames(frames)
    path = tmp_path / "walk.c3d"
    with open(path, "wb") as h:
        writer.write(h)
    markers, dt = cordis.read_trajectory(path, with_dt=True)
    assert markers.shape == (5, 3, 3)
    assert dt == pytest.approx(1 / 200.0)
    assert np.isnan(markers[2, 1]).all(), "an invalid sample is missing, not its coordinates"
    mask = ~np.isnan(markers)
    assert mask.sum() == 5 * 3 * 3 - 3
    np.testing.assert_allclose(markers[mask], pos[mask], rtol=0, atol=1e-6)  # float32 mm


def _write_trc(path, pos, rate, units="mm", gaps=(), num_frames=None):
    """A TRC as OpenSim writes it: tabs, two header lines of keys and values, names, axes."""
    t, n, _ = pos.shape
    scale = {"mm": 1000.0, "cm": 100.0, "m": 1.0}[units]
    lines = [
        f"PathFileType\t4\t(X/Y/Z)\t{path.name}",
        "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames",
        f"{rate:.2f}\t{rate:.2f}\t{num_frames or t}\t{n}\t{units}\t{rate:.2f}\t1\t{t}",
        "Frame#\tTime\t" + "\t".join(f"M{i}\t\t" for i in range(n)),
        "\t\t" + "\t".join(f"X{i + 1}\tY{i + 1}\tZ{i + 1}" for i in range(n)),
        "",
    ]
    for f in range(t):
        cells = [str(f + 1), f"{f / rate:.5f}"]
        for i in range(n):
            if (f, i) in gaps:
                cells += ["", "", ""]
            else:
                cells += [repr(float(v * scale)) for v in pos[f, i]]
        lines.append("\t".join(cells))
    path.write_text("\n".join(lines) + "\n")


def test_a_trc_reads_with_its_rate_units_and_gaps(tmp_path):
    pos = _positions(6, 2)
    path = tmp_path / "walk.trc"
    _write_trc(path, pos, rate=120.0, units="cm", gaps={(3, 0)})
    markers, dt = cordis.read_trajectory(path, with_dt=True)
    assert dt == pytest.approx(1 / 120.0)
    assert np.isnan(markers[3, 0]).all()
    expected = pos.copy()
    expected[3, 0] = np.nan
    np.testing.assert_allclose(markers, expected, rtol=0, atol=1e-12)
    _write_trc(path, pos, rate=120.0, num_frames=7)
    with pytest.raises(cordis.TrajectoryError, match=r"wrong header count: NumFrames is 7"):
        cordis.read_trajectory(path)
    _write_trc(path, pos, rate=120.0, units="mm")
    with pytest.raises(cordis.TrajectoryError, match=r"mixed units: units= cm but the header says Units mm"):
        cordis.read_trajectory(path, units="cm")


def test_tracker_npz_hidden_points_are_nan_and_2d_is_planar(tmp_path):
    rng = np.random.default_rng(0)
    tracks = rng.uniform(0, 640, size=(4, 7, 2)).astype(np.float32)  # TAP-Vid (N, T, 2)
    visibility = rng.uniform(size=(4, 7)) > 0.3
    path = tmp_path / "tracks.npz"
    np.savez_compressed(path, tracks=tracks, visibility=visibility)
    markers, dt = cordis.read_trajectory(path, with_dt=True)
    assert dt is None and markers.shape == (7, 4, 3)
    seen = visibility.T
    np.testing.assert_array_equal(np.isnan(markers[..., 0]), ~seen)
    np.testing.assert_array_equal(markers[seen][:, :2], tracks.transpose(1, 0, 2)[seen])
    assert (markers[seen][:, 2] == 0).all()
    # CoTracker's batched layout, (1, T, N, 2) with (1, T, N) visibility, reads the same.
    np.savez(path, pred_tracks=tracks.transpose(1, 0, 2)[None], pred_visibility=seen[None])
    np.testing.assert_array_equal(cordis.read_trajectory(path), markers)


def test_tables_in_other_layouts_read_to_the_same_array(tmp_path):
    pos = _positions(4, 2)
    names = ["knee", "hip"]
    long = tmp_path / "long.csv"
    rows = ["Time;Marker;X;Y;Z"]
    for f in range(4):
        for i, m in enumerate(names):
            if (f, i) != (2, 1):  # an absent row: a missing marker
                rows.append(";".join([f"{f * 0.005}", m] + [f"{v * 1000:.6f}".replace(".", ",") for v in pos[f, i]]))
    long.write_text("\n".join(rows) + "\n")
    wide = tmp_path / "wide.tsv"
    rows = ["frame\t" + "\t".join(f"{m}_{a}" for m in names for a in "XYZ")]
    for f in range(4):
        cells = [str(f + 100)]
        for i in range(2):
            cells += ["nan"] * 3 if (f, i) == (2, 1) else [repr(float(v * 1000)) for v in pos[f, i]]
        rows.append("\t".join(cells))
    wide.write_text("\n".join(rows) + "\n")
    a, dt = cordis.read_trajectory(long, units="mm", with_dt=True)
    b = cordis.read_trajectory(wide, columns="x=*_X", units="mm")
    assert dt == pytest.approx(0.005)
    expected = pos.copy()
    expected[2, 1] = np.nan
    np.testing.assert_allclose(a, expected, rtol=0, atol=1e-9)
    np.testing.assert_allclose(b, expected, rtol=0, atol=1e-12)


def test_bad_input_names_the_place(tmp_path):
    path = tmp_path / "m.csv"
    path.write_text("Frame,Marker,X,Y,Z\n0,A,1,2,3\n")
    # The options as read_trajectory spells them, not the CLI's `--columns`.
    with pytest.raises(cordis.TrajectoryError, match=r"m\.csv:1: columns= names particle=Label, but the header has no such column"):
        cordis.read_trajectory(path, columns="particle=Label")
    path.write_text("Frame,Marker,X,Y,Z,Extra\n0,A,1,2,3,4\n")
    with pytest.raises(cordis.TrajectoryError, match=r"map the columns with columns= \(the others"):
        cordis.read_trajectory(path)
    path.write_text("Frame,Marker,X,Y,Z\n0,A,1,2,3\n")
    with pytest.raises(cordis.ArgumentError, match=r"units: `inch` is not a length unit"):
        cordis.read_trajectory(path, units="inch")
    _write_trc(tmp_path / "x.trc", _positions(2, 1), rate=100.0)
    with pytest.raises(cordis.ArgumentError, match=r"a column mapping applies to \.csv/\.tsv tables"):
        cordis.read_trajectory(tmp_path / "x.trc", columns="x=X")
    empty = tmp_path / "none.c3d"
    empty.write_bytes(b"\x02\x50" + bytes(2000))
    with pytest.raises(cordis.CordisError, match=r"none\.c3d"):
        cordis.read_trajectory(empty)


def test_a_column_that_is_not_read_is_refused_as_by_the_cli(tmp_path):
    # A `w` column was dropped without a word (the CLI reads tables through the same reader).
    path = tmp_path / "w.csv"
    path.write_text("frame,particle,x,y,z,w\n0,0,1,2,3,4\n")
    with pytest.raises(cordis.TrajectoryError, match=r"w\.csv:1: column `w` \(field 6\) is not "
                       r"read \(read: frame, particle, x, y, z\): remove it, or map the columns"):
        cordis.read_trajectory(path)
    mapped = cordis.read_trajectory(path, columns="frame=frame,particle=particle,x=x,y=y,z=z")
    np.testing.assert_array_equal(mapped, [[[1.0, 2.0, 3.0]]])


def test_cordis_own_formats_read_as_before(tmp_path):
    traj = cordis.example("rigid").simulate(5)
    cordis.write_trajectory(tmp_path / "r.csv", traj)
    back, dt = cordis.read_trajectory(tmp_path / "r.csv", with_dt=True)
    np.testing.assert_array_equal(back, traj)
    assert dt is None


SOFT_BLOCK = __import__("pathlib").Path(__file__).resolve().parents[2] / "examples/data/soft-block"


def test_scene_from_markers_on_the_soft_block_is_fitted_as_it_is():
    markers = cordis.read_trajectory(SOFT_BLOCK / "markers.csv")
    scene = cordis.scene_from_markers(markers, 0.01, 0.54, radius=0.18)
    d = scene.to_dict()
    assert len(d["links"]) == 158 and len(d["types"]) == 3
    assert [bool(p.get("fixed")) for p in d["particles"]] == [i < 9 for i in range(27)]
    assert scene.has_unknowns
    res = cordis.identify(scene, markers)
    # The fixed markers sit at their mean position (at their first, noisy frame the fit ended
    # above the noise): the network is the truth's and the fit converges at the 1 mm noise,
    # each true value within 3 standard errors.
    assert res.strategy == "output-error" and res.stopped_by == "converged"
    assert res.report is not None and res.report["end"] == "converged"
    assert 0.00095 < res.rmse < 0.00105
    truth = cordis.Scene.from_json(SOFT_BLOCK / "truth.json").to_dict()["types"]
    fitted = res.scene.to_dict()["types"]
    for k, name in enumerate(["edge", "face", "body"]):
        for key in ["stiffness", "rest_length", "damping"]:
            want, got = truth[name][key], fitted[f"family_{k}"][key]
            se = res.stderr[f"types.family_{k}.{key}"]
            assert abs(got - want) < 3 * se, (name, key, got, se, want)
    per_link = cordis.scene_from_markers(markers, 0.01, 0.54, neighbours=6, types="link")
    d = per_link.to_dict()
    assert len(d["types"]) == len(d["links"])
    with pytest.raises(ValueError, match="neighbours or radius"):
        cordis.scene_from_markers(markers, 0.01, 0.54, neighbours=3, radius=0.1)
    with pytest.raises(cordis.ArgumentError, match="--radius: no pair"):
        cordis.scene_from_markers(markers, 0.01, 0.54, radius=1e-4)


def test_with_unknowns_boxes_a_known_scene_around_its_values():
    scene = cordis.example("rigid")
    guess = scene.with_unknowns(width=9.0)
    assert not scene.has_unknowns and guess.has_unknowns
    with pytest.raises(cordis.ArgumentError, match="width"):
        scene.with_unknowns(width=1.0)
