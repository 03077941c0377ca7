"""cordis.plot draws every picture it promises, readable as PNG/GIF, without a display."""

import json

import numpy as np
import pytest

import cordis

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from PIL import Image  # noqa: E402  (Pillow comes with matplotlib)

import cordis.plot  # noqa: E402


@pytest.fixture(scope="module")
def rigid():
    truth = cordis.example("rigid")
    traj = truth.simulate(60)
    scene = cordis.example("rigid", unknowns=True)
    res = cordis.identify(scene, traj, strategy="thesis", generations=40, seed=2, truth=truth)
    return truth, traj, res


@pytest.fixture(autouse=True)
def close_figures():
    yield
    plt.close("all")


def assert_picture(path):
    """A non-empty image that decodes and is not one flat colour."""
    assert path.stat().st_size > 0
    with Image.open(path) as im:
        im.load()
        pixels = np.asarray(im.convert("RGB"))
    assert pixels.shape[0] > 50 and pixels.shape[1] > 50
    assert len(np.unique(pixels.reshape(-1, 3), axis=0)) > 10, "a single-colour picture"
    return pixels


def save(fig, path):
    assert isinstance(fig, matplotlib.figure.Figure)
    fig.savefig(path, dpi=60)
    return assert_picture(path)


def test_convergence_of_one_result_has_cost_and_error_panels(rigid, tmp_path):
    _, _, res = rigid
    fig = cordis.plot.convergence(res)
    assert len(fig.axes) == 2
    cost_ax, err_ax = fig.axes
    assert cost_ax.get_yscale() == "log" and err_ax.get_yscale() == "log"
    (line,) = cost_ax.get_lines()
    np.testing.assert_array_equal(line.get_ydata(), res.history[:, 3])
    save(fig, tmp_path / "conv.png")


def test_convergence_of_a_history_without_truth_has_one_panel(rigid, tmp_path):
    truth, traj, _ = rigid
    res = cordis.identify(cordis.example("rigid", unknowns=True), traj, strategy="thesis",
                          generations=10)
    fig = cordis.plot.convergence(res.history, x="seconds")
    assert len(fig.axes) == 1
    np.testing.assert_array_equal(fig.axes[0].get_lines()[0].get_xdata(), res.history[:, 2])
    save(fig, tmp_path / "conv1.png")


def test_convergence_of_several_runs_labels_each(rigid, tmp_path):
    truth, traj, res = rigid
    ls = cordis.identify(cordis.example("rigid", unknowns=True), traj, strategy="least-squares",
                         truth=truth)
    fig = cordis.plot.convergence([res, ls], x="evals")
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert labels == ["thesis", "least-squares"]
    save(fig, tmp_path / "conv2.png")
    fig = cordis.plot.convergence({"a": res, "b": ls})
    assert [t.get_text() for t in fig.axes[0].get_legend().get_texts()] == ["a", "b"]


def test_convergence_rejects_bad_input(rigid):
    with pytest.raises(ValueError, match="x:"):
        cordis.plot.convergence(rigid[2], x="hours")
    with pytest.raises(ValueError, match="history"):
        cordis.plot.convergence(np.zeros((3, 2)))
    with pytest.raises(ValueError, match="labels"):
        cordis.plot.convergence([rigid[2]], labels=["a", "b"])


def test_trajectories_draws_two_rows_of_frames(rigid, tmp_path):
    truth, traj, res = rigid
    fig = cordis.plot.trajectories(truth, traj, res.scene.simulate(len(traj)))
    assert len(fig.axes) == 10  # 2 rows x 5 frames
    assert fig.axes[0].get_title().startswith("frame 0")
    save(fig, tmp_path / "traj.png")
    fig = cordis.plot.trajectories(truth, traj, traj, frames=[0, 59], plane="xy")
    assert len(fig.axes) == 4
    with pytest.raises(ValueError, match="frames"):
        cordis.plot.trajectories(truth, traj, traj, frames=[60])
    with pytest.raises(ValueError, match="plane"):
        cordis.plot.trajectories(truth, traj, traj, plane="xx")


def test_trajectories_overlays_into_given_axes(rigid, tmp_path):
    truth, traj, _ = rigid
    fig, ax = plt.subplots()
    assert cordis.plot.trajectories(truth, traj, traj, ax=ax) is fig
    save(fig, tmp_path / "overlay.png")


def test_local_costs_colours_particles_on_a_log_scale(rigid, tmp_path):
    truth, traj, res = rigid
    scene = cordis.example("rigid", unknowns=True)
    report = cordis.Objective(scene, traj).report(cordis.Objective(scene, traj).param_vector())
    fig = cordis.plot.local_costs(truth, traj, report, frame=10)
    assert len(fig.axes) == 2  # the shape and its colour bar
    from matplotlib.colors import LogNorm
    assert isinstance(fig.axes[0].collections[-1].norm, LogNorm)
    save(fig, tmp_path / "local.png")
    fig = cordis.plot.local_costs(truth, traj, report.per_particle)
    save(fig, tmp_path / "local2.png")
    with pytest.raises(ValueError, match="local costs"):
        cordis.plot.local_costs(truth, traj, np.ones(3))


def test_pareto_from_records_and_from_a_jsonl_file(tmp_path):
    records = [
        {"strategy": "thesis", "scene": "rigid", "seconds": 1.5, "param_error_pct": 0.02},
        {"strategy": "least-squares", "scene": "rigid", "seconds": 0.01, "param_error_pct": 0.0},
        {"strategy": "cmaes", "scene": "rigid", "seconds": 0.8, "param_error_pct": 3.0},
        {"strategy": "thesis", "scene": "cloth", "seconds": 30.0, "param_error_pct": 0.5},
    ]
    save(cordis.plot.pareto(records), tmp_path / "p1.png")
    path = tmp_path / "runs.jsonl"
    path.write_text("\n".join(json.dumps(r) for r in records) + "\n")
    fig = cordis.plot.pareto(path)
    assert [t.get_text() for t in fig.axes[0].get_legend().get_texts()] == \
        ["thesis", "least-squares", "cmaes"]
    save(fig, tmp_path / "p2.png")
    # A fixed order keeps a strategy's colour across panels that lack some strategies.
    fig = cordis.plot.pareto(records[2:3], strategies=["thesis", "least-squares", "cmaes"])
    from matplotlib.colors import to_hex
    assert to_hex(fig.axes[0].collections[0].get_facecolor()[0]) == to_hex("C2")
    with pytest.raises(ValueError, match=r"records\[0\]: missing seconds"):
        cordis.plot.pareto([{"strategy": "x", "scene": "y", "param_error_pct": 1}])
    path.write_text("{nope\n")
    with pytest.raises(ValueError, match="runs.jsonl:1"):
        cordis.plot.pareto(path)


def test_animate_writes_a_gif_with_several_frames(rigid, tmp_path):
    truth, traj, res = rigid
    out = cordis.animate(truth, traj, tmp_path / "rigid.gif", compare=res.scene.simulate(60),
                         fps=10, every=6)
    assert out == tmp_path / "rigid.gif"
    assert_picture(out)
    with Image.open(out) as im:
        assert im.n_frames == 10
        im.seek(im.n_frames - 1)
        last = np.asarray(im.convert("RGB"))
    with Image.open(out) as im:
        first = np.asarray(im.convert("RGB"))
    assert (first != last).any(), "the animation does not move"
    assert cordis.animate is cordis.plot.animate


def test_animate_rejects_unknown_formats_and_bad_counts(rigid, tmp_path):
    truth, traj, _ = rigid
    with pytest.raises(ValueError, match=r"\.gif or \.mp4"):
        cordis.animate(truth, traj, tmp_path / "x.avi")
    with pytest.raises(ValueError, match="every"):
        cordis.animate(truth, traj, tmp_path / "x.gif", every=0)
    with pytest.raises(ValueError, match="particles"):
        cordis.animate(truth, traj[:, :3], tmp_path / "x.gif")


def test_mp4_without_ffmpeg_is_a_clear_error(rigid, tmp_path, monkeypatch):
    truth, traj, _ = rigid
    monkeypatch.setattr(cordis.plot, "_ffmpeg", lambda: None)
    with pytest.raises(RuntimeError, match="ffmpeg"):
        cordis.animate(truth, traj, tmp_path / "x.mp4")
    assert not (tmp_path / "x.mp4").exists()


def test_missing_matplotlib_names_the_extra(rigid, monkeypatch):
    monkeypatch.setitem(__import__("sys").modules, "matplotlib.pyplot", None)
    with pytest.raises(ImportError, match=r"pip install cordis-anima\[plot\]"):
        cordis.plot.convergence(rigid[2])


def test_convergence_reads_cli_log_files(rigid, tmp_path):
    """`cordis identify --log` files (.csv with an empty error column without --truth, .jsonl)
    plot like the result they record."""
    truth, traj, _ = rigid
    scene = cordis.example("rigid", unknowns=True)
    (tmp_path / "s.json").write_text(scene.to_json())
    cordis.write_trajectory(tmp_path / "t.npy", traj)
    from cordis import _cordis
    for log in ("run.csv", "run.jsonl"):
        assert _cordis._cli_main(["cordis", "identify", str(tmp_path / "s.json"), "-t",
                                  str(tmp_path / "t.npy"), "--strategy", "thesis",
                                  "--generations", "15", "--log", str(tmp_path / log),
                                  "-q"]) == 0
    res = cordis.identify(scene, traj, strategy="thesis", generations=15)
    fig = cordis.plot.convergence([tmp_path / "run.csv", str(tmp_path / "run.jsonl")])
    assert len(fig.axes) == 1  # no truth: no error panel
    for line in fig.axes[0].get_lines():
        np.testing.assert_allclose(line.get_ydata(), res.history[:, 3], rtol=1e-12)
    assert [t.get_text() for t in fig.axes[0].get_legend().get_texts()] == ["run", "run"]
    save(fig, tmp_path / "log.png")
    (tmp_path / "bad.csv").write_text("a,b\n1,2\n")
    with pytest.raises(ValueError, match=r"bad.csv:1: not a convergence log"):
        cordis.plot.convergence(tmp_path / "bad.csv")


def test_trajectories_follow_keeps_one_scale_per_column(tmp_path):
    truth = cordis.example("horse")
    traj = truth.simulate(53)
    fig = cordis.plot.trajectories(truth, traj, traj, frames=[0, 52], follow=True)
    (a0, a1), (b0, b1) = fig.axes[0].get_xlim(), fig.axes[1].get_xlim()
    assert b0 > a0 + 1.0, "the second column follows the horse forward"
    assert (a1 - a0) == pytest.approx(b1 - b0)
    assert fig.axes[0].get_xlim() == fig.axes[2].get_xlim()  # both rows of a column agree
    save(fig, tmp_path / "follow.png")


def test_marker_series_draws_observed_dots_against_model_lines(rigid, tmp_path):
    truth, traj, res = rigid
    model = res.scene.simulate(len(traj))
    gappy = traj.copy()
    gappy[10:20, 4, 1] = np.nan
    fig = cordis.plot.marker_series(gappy, model, dt=truth.dt)
    rows = len(fig.axes) // 3
    assert len(fig.axes) == 3 * rows and rows == 6, "the 6 worst-fitted markers by default"
    # Each panel: the model's line over every frame, the observed dots over the frames seen.
    lines = [ax.get_lines() for ax in fig.axes]
    assert all(len(ln) == 2 and len(ln[0].get_xdata()) == len(traj) for ln in lines)
    assert len(fig.legends) == 1, "one legend, outside the panels"
    save(fig, tmp_path / "markers.png")
    fig = cordis.plot.marker_series(gappy, model, dt=truth.dt, markers=[4])
    y_panel = fig.axes[1]
    assert len(y_panel.get_lines()[1].get_xdata()) == len(traj) - 10, "the gap left out"
    assert y_panel.get_lines()[0].get_xdata()[-1] == pytest.approx((len(traj) - 1) * truth.dt)
    for bad, says in [(dict(markers=[99]), "outside 0..14"), (dict(dt=0.0), "dt"),
                      (dict(markers=[]), "at least one")]:
        with pytest.raises(ValueError, match=says):
            cordis.plot.marker_series(gappy, model, **bad)
    with pytest.raises(ValueError, match="finite"):
        cordis.plot.marker_series(traj, np.full_like(model, np.inf))


def test_residuals_over_time_and_per_particle(rigid, tmp_path):
    truth, traj, res = rigid
    model = res.scene.simulate(len(traj))
    fig = cordis.plot.residuals(traj, model, dt=truth.dt)
    over_time, per_particle = fig.axes
    err = np.sqrt(((model - traj) ** 2).mean(axis=(1, 2)))
    np.testing.assert_allclose(over_time.get_lines()[0].get_ydata(), err, rtol=1e-12)
    heights = [p.get_height() for p in per_particle.patches]
    np.testing.assert_allclose(heights, np.sqrt(((model - traj) ** 2).mean(axis=(0, 2))),
                               rtol=1e-12)
    save(fig, tmp_path / "residuals.png")
    # The truth against itself: no error anywhere.
    fig = cordis.plot.residuals(traj, truth.simulate(len(traj)), dt=truth.dt)
    assert max(fig.axes[0].get_lines()[0].get_ydata()) == 0.0


def test_animate_size_follows_width_and_dpi(rigid, tmp_path):
    truth, traj, _ = rigid
    small = cordis.animate(truth, traj, tmp_path / "s.gif", every=20, width=3.0, dpi=50)
    large = cordis.animate(truth, traj, tmp_path / "l.gif", every=20, width=8.0, dpi=100)
    with Image.open(small) as s, Image.open(large) as big:
        assert s.size[0] == 150 and big.size[0] == 800, (s.size, big.size)
    for bad in [dict(width=0.0), dict(width=float("nan")), dict(dpi=5), dict(dpi=72.5)]:
        with pytest.raises(ValueError, match="width|dpi"):
            cordis.animate(truth, traj, tmp_path / "x.gif", **bad)


# ---------------------------------------------------------------- 3-D views, the automatic view


@pytest.fixture(scope="module")
def cloth():
    scene = cordis.example("cloth")
    return scene, scene.simulate(400)


def screen(ax, pts):
    """Display coordinates (pixels) of 3-D points as the axes draw them."""
    from mpl_toolkits.mplot3d import proj3d

    ax.figure.canvas.draw()
    x, y, _ = proj3d.proj_transform(pts[:, 0], pts[:, 1], pts[:, 2], ax.get_proj())
    return ax.transData.transform(np.column_stack([x, y]))


def polygon_area(p):
    x, y = p[:, 0], p[:, 1]
    return 0.5 * abs(np.dot(x, np.roll(y, 1)) - np.dot(y, np.roll(x, 1)))


def test_the_automatic_view_shows_the_cloth_face_on_in_3d(cloth, tmp_path):
    """The cloth spreads along all three axes: the automatic view is 3-D, gravity (y) up, and
    its flat start shows as a sheet, not as the line a flat projection made of it."""
    scene, traj = cloth
    fig = cordis.plot.trajectories(scene, traj, traj, frames=[0, 200])
    ax = fig.axes[0]
    assert ax.name == "3d" and len(fig.axes) == 4
    assert ax._vertical_axis == 1, "gravity's axis upwards"
    corners = [0, 31, 1023, 992]  # the 32×32 sheet, flat in x-z at frame 0
    sheet = polygon_area(screen(ax, traj[0][corners])) / (ax.bbox.width * ax.bbox.height)
    assert sheet > 0.02, f"the sheet covers {sheet:.3%} of its panel: seen edge-on"
    # The old automatic view (the two axes of largest extent) saw it as a line.
    flat = cordis.plot.trajectories(scene, traj, traj, plane="zy").axes[0]
    assert flat.name != "3d"
    assert np.ptp(traj[0][:, 1]) == 0.0
    # The drawn markers are the positions: every free particle at frame 0, in 3-D.
    free = ~cordis.plot._fixed(scene)
    xs, ys, zs = ax.get_lines()[0].get_data_3d()
    np.testing.assert_array_equal(np.column_stack([xs, ys, zs]), traj[0][free])
    pixels = save(fig, tmp_path / "cloth3d.png")
    assert (np.abs(pixels.astype(int) - [0x1F, 0x3B, 0x73]).sum(axis=2) < 40).sum() > 500, \
        "the original's colour fills the sheets"


def test_a_flat_motion_stays_a_flat_view_with_gravity_up(rigid):
    truth, traj, _ = rigid
    fig = cordis.plot.trajectories(truth, traj, traj)
    ax = fig.axes[0]
    assert ax.name != "3d"
    assert fig.axes[5].get_xlabel() == "x (m)" and ax.get_ylabel().endswith("y (m)")
    fig = cordis.plot.trajectories(truth, traj, traj, plane="3d", frames=[0, 30])
    ax = fig.axes[0]
    assert ax.name == "3d"
    xs, ys, zs = ax.get_lines()[0].get_data_3d()
    np.testing.assert_array_equal(np.column_stack([xs, ys, zs]), traj[0])


def test_the_3d_camera_puts_the_largest_horizontal_extent_across_the_picture():
    """A long bar along x (then along z) with gravity along y: its on-screen width exceeds its
    depth's, whichever horizontal axis it lies on."""
    for along in (0, 2):
        pts = np.zeros((2, 3, 3))
        pts[:, 1, along] = 4.0  # 4 m along the bar
        pts[:, 2, 2 - along] = 1.0  # 1 m across it
        pts[1, :, 1] = -1.0  # and a drop, so that the motion is not flat
        scene = cordis.Scene.from_dict({
            "dt": 0.01, "gravity": [0.0, -9.81, 0.0],
            "particles": [{"mass": 1.0, "pos": p.tolist()} for p in pts[0]]})
        view = cordis.plot._view(pts, scene)
        assert view.is_3d and view.vertical == 1
        fig = plt.figure()
        ax = fig.add_subplot(projection="3d")
        cordis.plot._frame_axes(ax, view, cordis.plot._limits([pts], view))
        p = screen(ax, pts[0])
        bar = abs(p[1, 0] - p[0, 0])
        depth = abs(p[2, 0] - p[0, 0]) * 4.0  # per metre, scaled as the bar's length
        assert bar > depth, (along, bar, depth)


def test_local_costs_in_3d(cloth, tmp_path):
    scene, traj = cloth
    per = np.linspace(1e-6, 1e-3, scene.num_particles)
    fig = cordis.plot.local_costs(scene, traj, per, frame=200, plane="3d")
    ax = fig.axes[0]
    assert ax.name == "3d" and len(fig.axes) == 2  # the shape and its colour bar
    np.testing.assert_array_equal(ax.collections[-1].get_array(), per)
    save(fig, tmp_path / "local3d.png")


def test_views_reject_a_view_their_axes_cannot_draw(rigid):
    truth, traj, _ = rigid
    fig, ax = plt.subplots()
    with pytest.raises(ValueError, match="needs 3-D axes"):
        cordis.plot.trajectories(truth, traj, traj, ax=ax, plane="3d")
    ax3 = plt.figure().add_subplot(projection="3d")
    with pytest.raises(ValueError, match="flat view"):
        cordis.plot.trajectories(truth, traj, traj, ax=ax3, plane="xy")
    assert cordis.plot.trajectories(truth, traj, traj, ax=ax3).axes[0] is ax3


def test_animate_in_3d_moves_the_cloth_and_keeps_the_fps(cloth, tmp_path):
    scene, traj = cloth
    out = cordis.animate(scene, traj, tmp_path / "cloth.gif", every=40, fps=20, width=4.0,
                         dpi=60)
    with Image.open(out) as im:
        assert im.n_frames == 10 and im.size[0] == 240
        assert im.info["duration"] == 50, "20 frames a second: 50 ms each"
        first = np.asarray(im.convert("RGB"))
        im.seek(5)
        middle = np.asarray(im.convert("RGB"))
    assert (first != middle).mean() > 0.01, "the sheet swings"
    for bad in [dict(fps=0), dict(fps=2.5), dict(every=1.5)]:
        with pytest.raises(ValueError, match="fps|every"):
            cordis.animate(scene, traj, tmp_path / "x.gif", **bad)


def test_animate_writes_an_mp4_with_ffmpeg(rigid, tmp_path):
    """H.264 through ffmpeg (on PATH or imageio-ffmpeg's, which scripts/python-test.sh
    installs): decoded back, the frames, their size and rate are what was asked."""
    if cordis.plot._ffmpeg() is None:
        pytest.skip("no ffmpeg (scripts/python-test.sh installs imageio-ffmpeg: CI runs this)")
    imageio_ffmpeg = pytest.importorskip("imageio_ffmpeg")
    truth, traj, res = rigid
    out = cordis.animate(truth, traj, tmp_path / "rigid.mp4", compare=res.scene.simulate(60),
                         every=4, fps=12, width=4.0, dpi=80)
    reader = imageio_ffmpeg.read_frames(str(out))
    meta = next(reader)
    frames = [np.frombuffer(f, np.uint8).reshape(meta["size"][1], meta["size"][0], 3)
              for f in reader]
    assert len(frames) == 15
    assert meta["fps"] == pytest.approx(12.0)
    assert meta["size"][0] == 320
    assert (frames[0] != frames[-1]).any(), "the video moves"
    assert len(np.unique(frames[7].reshape(-1, 3), axis=0)) > 10
