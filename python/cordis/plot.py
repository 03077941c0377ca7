"""Pictures of scenes, motions and identification runs (needs matplotlib: the ``plot`` extra).

Install with ``pip install cordis-anima[plot]`` (or ``pip install matplotlib``). matplotlib is
imported only when a function here is called, so ``import cordis`` never needs it.

Every function draws with :mod:`matplotlib.pyplot` and returns the
:class:`~matplotlib.figure.Figure` (``plt.show()`` displays it, ``fig.savefig("x.png")``
writes it; close it with ``plt.close(fig)`` when making many). :func:`animate` returns the
path it wrote. Pass ``ax=`` to draw into axes of your own figure instead.

Example::

    import cordis, cordis.plot

    truth = cordis.example("rigid")
    traj = truth.simulate(100)
    res = cordis.identify(cordis.example("rigid", unknowns=True), traj, strategy="thesis",
                          generations=300, truth=truth)
    cordis.plot.convergence(res).savefig("convergence.png")
    cordis.plot.trajectories(truth, traj, res.scene.simulate(100)).savefig("frames.png")
    cordis.animate(truth, traj, "rigid.gif", compare=res.scene.simulate(100))

Motions are drawn in the view that shows their largest extent: a flat motion (its least
extent under a tenth of its largest) on the plane of the two axes along which it spreads
furthest, the vertical one, when gravity is along one of them, upwards; any other in 3-D,
gravity (or the least extent) upwards and the largest horizontal extent across the picture,
so that a sheet such as the cloth is never seen edge-on. ``plane="zy"`` (horizontal axis
first) or ``plane="3d"`` chooses the view.
"""

from __future__ import annotations

import json
import os
import pathlib
import shutil
from typing import (TYPE_CHECKING, Any, Dict, List, Mapping, NamedTuple, Optional, Sequence,
                    Tuple, Union)

import numpy as np

if TYPE_CHECKING:  # pragma: no cover - typing only
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from ._cordis import CostReport, IdentifyResult, Scene

__all__ = ["animate", "convergence", "local_costs", "marker_series", "pareto", "residuals",
           "trajectories"]

_INSTALL_HINT = (
    "cordis.plot needs matplotlib: install it with `pip install cordis-anima[plot]` "
    "(or `pip install matplotlib`)"
)

# HISTORY_COLUMNS of IdentifyResult.history.
_COLUMN = {"generations": 0, "evals": 1, "seconds": 2}
_BEST_COST = 3
_PARAM_ERROR = 7
_X_LABEL = {"generations": "generation", "evals": "cost evaluations", "seconds": "seconds"}

# Original motion solid and dark, the identified one in a contrasting colour.
_ORIGINAL = "#1f3b73"
_IDENTIFIED = "#d1495b"


def _pyplot() -> Any:
    try:
        import matplotlib.pyplot as plt
    except ImportError as e:
        raise ImportError(_INSTALL_HINT) from e
    return plt


# ---------------------------------------------------------------- geometry helpers


def _positions(traj: Any, name: str) -> np.ndarray:
    a = np.asarray(traj, dtype=np.float64)
    if a.ndim != 3 or a.shape[2] != 3 or a.shape[0] == 0:
        raise ValueError(f"{name}: expected positions shaped (T, N, 3) with T >= 1, got {a.shape}")
    return a


def _pairs(scene: "Scene") -> np.ndarray:
    """Particle index pairs to draw: every listed link between two particles, and the two arms
    of every angle link (conditional links are not listed, anchors join a fixed point)."""
    pairs: List[Tuple[int, int]] = []
    for link in scene.to_dict().get("links", []):
        p = list(link["particles"])
        pairs.extend(zip(p[:-1], p[1:]))
    return np.array(pairs, dtype=np.int64).reshape(-1, 2)


def _fixed(scene: "Scene") -> np.ndarray:
    return np.array([bool(p.get("fixed", False)) for p in scene.to_dict()["particles"]], dtype=bool)


# A motion whose smallest extent is below this fraction of its largest is drawn flat (the two
# largest axes); any other is drawn in 3-D, so that a sheet is never seen edge-on.
_FLAT = 0.1
# The 3-D camera: this far above the horizontal plane, and turned this far from looking
# straight along the horizontal axis of least extent (depth stays visible).
_ELEVATION = 25.0
_TURN = 30.0


class _View(NamedTuple):
    """How positions are drawn: ``axes`` are the coordinates shown, ``(horizontal, vertical)``
    in 2-D or ``(0, 1, 2)`` in 3-D, where ``vertical`` points up the page and the camera
    stands at ``azim`` degrees (matplotlib's ``view_init``) and ``_ELEVATION`` above."""

    axes: Tuple[int, ...]
    vertical: int = 2
    azim: float = -60.0

    @property
    def is_3d(self) -> bool:
        return len(self.axes) == 3


def _view(traj: np.ndarray, scene: "Scene", plane: Optional[str] = None,
          ax: Any = None) -> _View:
    """The view of ``traj``: ``plane`` names it (``"xy"``, ``"zy"``…: horizontal axis first;
    ``"3d"``), or it is chosen to show the motion's largest extent: flat on the two axes along
    which it spreads furthest when its third extent is under ``_FLAT`` of the largest (the
    vertical one, when gravity is along one of them, drawn upwards), else in 3-D with gravity
    (or the least extent) upwards and the largest horizontal extent across the picture. Axes
    ``ax`` given by the caller decide between 2-D and 3-D."""
    extent = np.ptp(traj.reshape(-1, 3), axis=0)
    extent = np.where(np.isfinite(extent), extent, 0.0)
    given_3d = ax is not None and getattr(ax, "name", "") == "3d"
    if plane is not None:
        p = str(plane).lower()
        if p == "3d":
            if ax is not None and not given_3d:
                raise ValueError("plane='3d' needs 3-D axes: "
                                 "fig.add_subplot(projection='3d')")
            return _view_3d(extent, scene)
        if len(p) != 2 or p[0] == p[1] or any(c not in "xyz" for c in p):
            raise ValueError(
                f"plane: expected two of x, y, z such as 'xy' or 'zy', or '3d', got {plane!r}")
        if given_3d:
            raise ValueError(f"plane={plane!r} is a flat view: give 2-D axes or plane='3d'")
        return _View(("xyz".index(p[0]), "xyz".index(p[1])))
    if given_3d or (ax is None and extent.min() > _FLAT * extent.max()):
        return _view_3d(extent, scene)
    a, b = sorted(int(i) for i in np.argsort(-extent, kind="stable")[:2])
    g = np.abs(np.asarray(scene.gravity, dtype=np.float64))
    if g.max() > 0 and int(np.argmax(g)) == a:
        a, b = b, a  # gravity's axis upwards on the page
    return _View((a, b))


def _view_3d(extent: np.ndarray, scene: "Scene") -> _View:
    g = np.abs(np.asarray(scene.gravity, dtype=np.float64))
    up = int(np.argmax(g)) if g.max() > 0 else int(np.argmin(extent))
    # matplotlib's camera at azim -90 looks along axis up+2 (axis up+1 across the picture), at
    # azim 0 along up+1 (up+2 across): turn from the one that puts the largest extent across.
    across_at_minus_90, across_at_0 = (up + 1) % 3, (up + 2) % 3
    if extent[across_at_minus_90] >= extent[across_at_0]:
        azim = -90.0 + _TURN
    else:
        azim = 0.0 - _TURN
    return _View((0, 1, 2), vertical=up, azim=azim)


def _limits(arrays: Sequence[np.ndarray], view: _View) -> List[Tuple[float, float]]:
    """Each shown axis' range over ``arrays``, padded by 5 % of the largest span."""
    pts = np.concatenate([x.reshape(-1, 3) for x in arrays])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = 0.05 * max(max(float(hi[k] - lo[k]) for k in view.axes), 1e-9)
    return [(float(lo[k] - pad), float(hi[k] + pad)) for k in view.axes]


def _frame_axes(ax: Any, view: _View, limits: Sequence[Tuple[float, float]]) -> None:
    """Limits, one scale on every axis, labels and (3-D) the camera."""
    ax.set_xlim(*limits[0])
    ax.set_ylim(*limits[1])
    if view.is_3d:
        ax.set_zlim(*limits[2])
        # The camera first: view_init(vertical_axis=…) re-orders a box aspect set before it.
        ax.view_init(elev=_ELEVATION, azim=view.azim, vertical_axis="xyz"[view.vertical])
        spans = np.array([hi - lo for lo, hi in limits])
        ax.set_box_aspect(np.maximum(spans, 0.05 * spans.max()))  # one scale on every axis
        ax.set_zlabel("z (m)")
        from matplotlib.ticker import MaxNLocator

        for axis in (ax.xaxis, ax.yaxis, ax.zaxis):  # few ticks: a 3-D axis is short
            axis.set_major_locator(MaxNLocator(4))
        ax.tick_params(labelsize="x-small", pad=0)
    else:
        ax.set_aspect("equal")
    ax.set_xlabel(f"{'xyz'[view.axes[0]]} (m)")
    ax.set_ylabel(f"{'xyz'[view.axes[1]]} (m)")


def _segments(frame: np.ndarray, pairs: np.ndarray, view: _View) -> np.ndarray:
    cols = list(view.axes)
    return np.stack([frame[pairs[:, 0]][:, cols], frame[pairs[:, 1]][:, cols]], axis=1)


def _draw_shape(ax: "Axes", frame: np.ndarray, pairs: np.ndarray, fixed: np.ndarray,
                view: _View, color: str, linestyle: str = "-", alpha: float = 1.0,
                label: Optional[str] = None, particles: bool = True) -> List[Any]:
    from matplotlib.collections import LineCollection

    artists: List[Any] = []
    if len(pairs):
        lw = 0.4 if len(pairs) > 1000 else 1.2
        style: Dict[str, Any] = dict(colors=color, linewidths=lw, linestyles=linestyle,
                                     alpha=alpha, label=label)
        if view.is_3d:
            from mpl_toolkits.mplot3d.art3d import Line3DCollection

            lc: Any = Line3DCollection(list(_segments(frame, pairs, view)), **style)
        else:
            lc = LineCollection(list(_segments(frame, pairs, view)), **style)
        ax.add_collection(lc)
        artists.append(lc)
        label = None
    if particles:
        size = 2.0 if len(frame) > 500 else 14.0
        for which, marker, scale, colour in ((~fixed, "o", 1.0, color),
                                             (fixed, "s", 1.5, "black")):
            if which is fixed and not fixed.any():
                continue
            pts = frame[which][:, list(view.axes)].T
            # Markers as a line without segments: Line2D / Line3D move by set_data(_3d),
            # public API in both (a 3-D scatter would need its private _offsets3d).
            (line,) = ax.plot(*pts, linestyle="none", marker=marker,
                              markersize=np.sqrt(size * scale), color=colour,
                              alpha=alpha if colour == color else 1.0, zorder=3,
                              markeredgewidth=0, label=label if colour == color else None)
            artists.append(line)
    return artists


def _move_shape(artists: List[Any], frame: np.ndarray, pairs: np.ndarray, fixed: np.ndarray,
                view: _View) -> None:
    """Moves the artists made by :func:`_draw_shape` (same order) to another frame."""
    k = 0
    if len(pairs):
        artists[0].set_segments(_segments(frame, pairs, view))
        k = 1
    for which in (~fixed, fixed):
        if which is fixed and not fixed.any():
            continue
        pts = frame[which][:, list(view.axes)].T
        if view.is_3d:
            artists[k].set_data_3d(*pts)
        else:
            artists[k].set_data(*pts)
        k += 1


# ---------------------------------------------------------------- convergence


_HISTORY_COLUMNS = ("generation", "evals", "seconds", "best_cost", "best_rmse", "mean_cost",
                    "mean_mutability", "param_error_pct")


def _read_log(path: pathlib.Path) -> np.ndarray:
    """A ``cordis identify --log`` file (.csv or .jsonl) as a history array (NaN where empty)."""
    lines = [line for line in path.read_text().splitlines() if line.strip()]
    rows: List[List[float]] = []
    if path.suffix.lower() == ".jsonl":
        for n, line in enumerate(lines, start=1):
            try:
                rec = json.loads(line)
            except json.JSONDecodeError as e:
                raise ValueError(f"{path}:{n}: not a JSON object ({e.msg})") from None
            rows.append([np.nan if rec.get(c) is None else float(rec[c])
                         for c in _HISTORY_COLUMNS])
    else:
        if not lines:
            raise ValueError(f"{path}: empty log")
        header = [h.strip() for h in lines[0].split(",")]
        missing = [c for c in _HISTORY_COLUMNS if c not in header]
        if missing:
            raise ValueError(f"{path}:1: not a convergence log (no {', '.join(missing)})")
        index = [header.index(c) for c in _HISTORY_COLUMNS]
        for n, line in enumerate(lines[1:], start=2):
            fields = line.split(",")
            try:
                rows.append([float(fields[i]) if i < len(fields) and fields[i].strip() else np.nan
                             for i in index])
            except ValueError:
                raise ValueError(f"{path}:{n}: not a number in {line!r}") from None
    return np.array(rows, dtype=np.float64).reshape(-1, len(_HISTORY_COLUMNS))


def _history(item: Any) -> Tuple[np.ndarray, Optional[str]]:
    if isinstance(item, (str, os.PathLike)):
        path = pathlib.Path(item)
        return _read_log(path), path.stem
    if hasattr(item, "history"):
        return np.asarray(item.history, dtype=np.float64), str(getattr(item, "strategy", "")) or None
    h = np.asarray(item, dtype=np.float64)
    if h.ndim != 2 or h.shape[1] < _PARAM_ERROR + 1:
        raise ValueError(
            f"expected an IdentifyResult or its history (rows of {_PARAM_ERROR + 1} columns), "
            f"got an array shaped {h.shape}"
        )
    return h, None


def convergence(
    result_or_history: Any,
    x: str = "generations",
    ax: Any = None,
    labels: Optional[Sequence[str]] = None,
) -> "Figure":
    """Best cost and, when a truth was given, the mean parameter error of one or more runs.

    ``result_or_history`` is an :class:`~cordis.IdentifyResult`, its ``history`` array, the
    path of a ``cordis identify --log`` file (``.csv`` or ``.jsonl``), a list of these (one
    curve each, labelled by strategy, file name or ``labels``) or a dict ``{label: result}``. ``x`` is ``"generations"``, ``"seconds"`` or ``"evals"``. Both panels
    are on log scales; the error panel is left out when no run knows its truth. ``ax`` may be
    one Axes (cost only) or two (cost, error).

    >>> res = cordis.identify(scene, traj, strategy="thesis", generations=300, truth=truth)
    >>> cordis.plot.convergence(res, x="seconds").savefig("convergence.png")
    """
    if x not in _COLUMN:
        raise ValueError(f"x: expected 'generations', 'seconds' or 'evals', got {x!r}")
    if isinstance(result_or_history, Mapping):
        items = list(result_or_history.values())
        names: List[Optional[str]] = [str(k) for k in result_or_history.keys()]
    elif isinstance(result_or_history, (list, tuple)):
        items = list(result_or_history)
        names = [None] * len(items)
    else:
        items = [result_or_history]
        names = [None]
    if not items:
        raise ValueError("result_or_history: nothing to plot")
    if labels is not None:
        if len(labels) != len(items):
            raise ValueError(f"labels: {len(labels)} labels for {len(items)} runs")
        names = [str(s) for s in labels]
    runs = []
    for i, (item, name) in enumerate(zip(items, names)):
        h, strategy = _history(item)
        runs.append((h, name or strategy or f"run {i}"))

    has_error = any(np.isfinite(h[:, _PARAM_ERROR]).any() for h, _ in runs)
    plt = _pyplot()
    if ax is None:
        ncols = 2 if has_error else 1
        fig, axes = plt.subplots(1, ncols, figsize=(5.2 * ncols, 3.8), squeeze=False,
                                 layout="constrained")
        axes = list(axes[0])
    else:
        axes = list(np.atleast_1d(np.asarray(ax, dtype=object)).ravel())
        fig = axes[0].figure

    # Log scales cannot show 0 (an exact fit): such points sit one decade under the least
    # positive value drawn, so they stay visible at the bottom of the panel.
    def floor(col: int) -> float:
        vals = np.concatenate([h[:, col] for h, _ in runs])
        pos = vals[np.isfinite(vals) & (vals > 0)]
        return float(pos.min()) / 10 if len(pos) else 1e-16

    panels = [(_BEST_COST, "best cost (m²)")]
    if has_error and len(axes) > 1:
        panels.append((_PARAM_ERROR, "mean parameter error (%)"))
    for axis, (col, title) in zip(axes, panels):
        low = floor(col)
        for h, name in runs:
            xs, ys = h[:, _COLUMN[x]], h[:, col]
            keep = np.isfinite(ys)
            if not keep.any():
                continue
            ys = np.where(ys > 0, ys, low)
            style = "o-" if keep.sum() < 8 else "-"
            axis.plot(xs[keep], ys[keep], style, label=name, markersize=4, linewidth=1.5)
        axis.set_yscale("log")
        if x != "generations":
            axis.set_xscale("symlog" if x == "evals" else "linear")
        axis.set_xlabel(_X_LABEL[x])
        axis.set_ylabel(title)
        axis.grid(True, which="major", alpha=0.3)
    if len(runs) > 1 or runs[0][1]:
        axes[0].legend(fontsize="small")
    return fig


# ---------------------------------------------------------------- trajectories


def trajectories(
    scene: "Scene",
    original: Any,
    identified: Any,
    frames: Optional[Sequence[int]] = None,
    ax: Any = None,
    plane: Optional[str] = None,
    labels: Sequence[str] = ("original", "identified"),
    follow: bool = False,
) -> "Figure":
    """The original motion (top row) beside the identified model's (bottom row) at a few frames.

    The thesis' Figure 4.2: ``frames`` (default five, evenly spread) of the original animation
    and of its reconstruction, links drawn, both on the same scale. ``original`` and
    ``identified`` are positions ``(T, N, 3)`` of ``scene``'s particles; ``labels`` names the
    two rows. ``follow=True`` centres each column on the shape at its frame (the scale stays the
    same everywhere), for a model that travels far. With ``ax`` (one Axes), the chosen frames
    are overlaid there instead, the reconstruction dashed.

    >>> fig = cordis.plot.trajectories(truth, traj, res.scene.simulate(len(traj)))
    >>> fig.savefig("frames.png")
    """
    orig = _positions(original, "original")
    ident = _positions(identified, "identified")
    if orig.shape[1] != ident.shape[1] or orig.shape[1] != scene.num_particles:
        raise ValueError(
            f"identified: {ident.shape[1]} particles and original {orig.shape[1]} for a scene "
            f"of {scene.num_particles}"
        )
    count = min(len(orig), len(ident))
    if frames is None:
        frames = sorted(set(np.linspace(0, count - 1, min(5, count)).round().astype(int).tolist()))
    frames = [int(f) for f in frames]
    if len(labels) != 2:
        raise ValueError(f"labels: expected two names (original, identified), got {len(labels)}")
    for f in frames:
        if not 0 <= f < count:
            raise ValueError(f"frames: frame {f} is outside 0..{count - 1}")
    pairs, fixed = _pairs(scene), _fixed(scene)
    view = _view(orig, scene, plane, ax)
    limits = _limits([orig[frames], ident[frames]], view)
    dt = scene.dt
    plt = _pyplot()

    if ax is not None:
        fig = ax.figure
        for k, f in enumerate(frames):
            _draw_shape(ax, orig[f], pairs, fixed, view, _ORIGINAL,
                        label=labels[0] if k == 0 else None)
            _draw_shape(ax, ident[f], pairs, fixed, view, _IDENTIFIED, linestyle="--",
                        alpha=0.8, label=labels[1] if k == 0 else None)
        _frame_axes(ax, view, limits)
        ax.legend(fontsize="small")
        return fig

    n = len(frames)
    windows = [limits] * n
    if follow:
        cols = list(view.axes)
        shown = [np.concatenate([orig[f], ident[f]])[:, cols] for f in frames]
        half = [max(float(np.ptp(p[:, k])) for p in shown) / 2 * 1.1 + 1e-9
                for k in range(len(cols))]
        centres = [(p.min(axis=0) + p.max(axis=0)) / 2 for p in shown]
        windows = [[(c[k] - half[k], c[k] + half[k]) for k in range(len(cols))]
                   for c in centres]
    (x0, x1), (y0, y1) = windows[0][0], windows[0][1]
    panel = 2.4
    aspect = 0.75 if view.is_3d else ((y1 - y0) / (x1 - x0) if x1 > x0 else 1.0)
    shared: Dict[str, Any] = (dict(subplot_kw={"projection": "3d"}) if view.is_3d else
                              dict(sharex="none" if follow else True,
                                   sharey="none" if follow else True))
    fig, axes = plt.subplots(2, n, figsize=(panel * n + 0.8,
                                            2 * panel * min(max(aspect, 0.25), 2.5) + 0.9),
                             squeeze=False, layout="constrained", **shared)
    for col, f in enumerate(frames):
        for row, (pos, color, name) in enumerate(
                [(orig, _ORIGINAL, labels[0]), (ident, _IDENTIFIED, labels[1])]):
            axis = axes[row][col]
            _draw_shape(axis, pos[f], pairs, fixed, view, color)
            _frame_axes(axis, view, windows[col])
            axis.tick_params(labelsize="small")
            if row == 0:
                axis.set_title(f"frame {f}  (t = {f * dt:.3g} s)", fontsize="medium")
            # Flat panels share their axes: the labels go on the outer ones only.
            if not view.is_3d:
                axis.set_xlabel(f"{'xyz'[view.axes[0]]} (m)" if row == 1 else "")
                axis.set_ylabel(f"{name}\n{'xyz'[view.axes[1]]} (m)" if col == 0 else "")
            elif col == 0:
                axis.text2D(0.0, 1.0, name, transform=axis.transAxes, fontsize="small",
                            va="top", color=color)
    return fig


# ---------------------------------------------------------------- observed against model


def _observed_and_model(observed: Any, model: Any) -> Tuple[np.ndarray, np.ndarray]:
    """``observed`` (NaN where missing) and ``model`` over their common frames and particles
    (the model may be longer, and hold particles beyond the observed ones)."""
    obs = _positions(observed, "observed")
    mod = _positions(model, "model")
    if mod.shape[1] < obs.shape[1]:
        raise ValueError(f"model: {mod.shape[1]} particles for {obs.shape[1]} observed")
    count = min(len(obs), len(mod))
    if count < 2:
        raise ValueError(f"observed and model share {count} frame(s): at least 2 are needed")
    if not np.isfinite(mod[:count, : obs.shape[1]]).all():
        raise ValueError("model: positions must be finite (a diverged replay has nothing to plot)")
    return obs[:count], mod[:count, : obs.shape[1]]


def _errors(obs: np.ndarray, mod: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """The RMS position error over the observed coordinates at each frame and per particle,
    m (NaN where nothing was observed)."""
    sq = (mod - obs) ** 2
    seen = np.isfinite(sq)
    sq = np.where(seen, sq, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        per_frame = np.sqrt(sq.sum(axis=(1, 2)) / seen.sum(axis=(1, 2)))
        per_particle = np.sqrt(sq.sum(axis=(0, 2)) / seen.sum(axis=(0, 2)))
    return per_frame, per_particle


def marker_series(
    observed: Any,
    model: Any,
    dt: float = 1.0,
    markers: Optional[Sequence[int]] = None,
    labels: Sequence[str] = ("observed", "model"),
    max_markers: int = 6,
) -> "Figure":
    """Per-marker time series: x(t), y(t), z(t) observed (dots; NaN gaps left out) against the
    model's (lines), one row per marker, one column per axis.

    ``observed`` ``(T, N, 3)`` (NaN where missing) and ``model`` ``(T', N', 3)`` hold the same
    particles in the same order (the model may be longer or hold more); ``dt`` (s) scales the
    time axis. ``markers`` lists the particles shown; by default the ``max_markers`` worst
    fitted (largest RMS error), so that a figure of a large scene stays readable.

    >>> fig = cordis.plot.marker_series(traj, res.scene.simulate(len(traj)), dt=truth.dt)
    >>> fig.savefig("markers.png")
    """
    obs, mod = _observed_and_model(observed, model)
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"dt: expected a positive time step (s), got {dt!r}")
    if len(labels) != 2:
        raise ValueError(f"labels: expected two names (observed, model), got {len(labels)}")
    _, per_particle = _errors(obs, mod)
    if markers is None:
        if max_markers < 1:
            raise ValueError(f"max_markers: expected 1 or more, got {max_markers}")
        seen = np.flatnonzero(np.isfinite(per_particle))
        if len(seen) == 0:
            raise ValueError("observed: no marker is observed at any frame")
        worst = seen[np.argsort(-per_particle[seen], kind="stable")][:max_markers]
        markers = sorted(int(i) for i in worst)
    markers = [int(m) for m in markers]
    if not markers:
        raise ValueError("markers: expected at least one particle")
    for m in markers:
        if not 0 <= m < obs.shape[1]:
            raise ValueError(f"markers: particle {m} is outside 0..{obs.shape[1] - 1}")
    t = np.arange(len(obs)) * dt
    plt = _pyplot()
    fig, axes = plt.subplots(len(markers), 3, figsize=(9.0, 1.7 * len(markers) + 0.8),
                             squeeze=False, sharex=True, layout="constrained")
    for row, m in enumerate(markers):
        for k in range(3):
            ax = axes[row][k]
            ax.plot(t, mod[:, m, k], color=_IDENTIFIED, linewidth=1.2,
                    label=labels[1] if row == 0 and k == 0 else None)
            seen = np.isfinite(obs[:, m, k])
            ax.plot(t[seen], obs[seen, m, k], ".", color=_ORIGINAL, markersize=3,
                    label=labels[0] if row == 0 and k == 0 else None)
            ax.tick_params(labelsize="small")
            if row == 0:
                ax.set_title(f"{'xyz'[k]} (m)", fontsize="medium")
            if k == 0:
                rms = per_particle[m]
                shown = f"RMS {rms:.3g} m" if np.isfinite(rms) else "never observed"
                ax.set_ylabel(f"particle {m}\n{shown}", fontsize="small")
            if row == len(markers) - 1:
                ax.set_xlabel("t (s)")
    # Outside every panel: a legend never hides a curve.
    fig.legend(loc="outside upper center", ncol=2, fontsize="small")
    return fig


def residuals(observed: Any, model: Any, dt: float = 1.0) -> "Figure":
    """The model's position error against the observation: the RMS over the observed
    coordinates at each frame (left, against time) and per particle (right), m, gaps (NaN)
    left out. ``observed``, ``model`` and ``dt`` as for :func:`marker_series`.

    >>> fig = cordis.plot.residuals(traj, res.scene.simulate(len(traj)), dt=truth.dt)
    """
    obs, mod = _observed_and_model(observed, model)
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"dt: expected a positive time step (s), got {dt!r}")
    per_frame, per_particle = _errors(obs, mod)
    plt = _pyplot()
    fig, (over_time, by_particle) = plt.subplots(1, 2, figsize=(9.0, 3.2),
                                                 layout="constrained")
    t = np.arange(len(obs)) * dt
    over_time.plot(t, per_frame, color=_IDENTIFIED)
    over_time.set_xlabel("t (s)")
    over_time.set_ylabel("RMS position error (m)")
    over_time.set_title("over time", fontsize="medium")
    shown = np.where(np.isfinite(per_particle), per_particle, 0.0)
    by_particle.bar(np.arange(len(per_particle)), shown, color=_ORIGINAL)
    by_particle.set_xlabel("particle")
    by_particle.set_ylabel("RMS position error (m)")
    by_particle.set_title("per particle", fontsize="medium")
    for ax in (over_time, by_particle):
        ax.tick_params(labelsize="small")
    return fig


# ---------------------------------------------------------------- local costs


def local_costs(
    scene: "Scene",
    traj: Any,
    report_or_per_particle: Any,
    frame: int = 0,
    ax: Any = None,
    plane: Optional[str] = None,
) -> "Figure":
    """The model's shape at ``frame`` with each particle coloured by its local cost c_i.

    ``report_or_per_particle`` is a :class:`~cordis.CostReport` (its ``per_particle``) or an
    array of N local costs (m²). The colour scale is logarithmic, with a colour bar; particles
    of cost 0 (fixed ones, or exactly predicted) are drawn as small black squares. The thesis
    uses these local costs to find the particles whose links are still wrong.

    >>> report = cordis.Objective(scene, traj).report(guess)
    >>> cordis.plot.local_costs(scene, traj, report).savefig("local.png")
    """
    pos = _positions(traj, "traj")
    per = getattr(report_or_per_particle, "per_particle", report_or_per_particle)
    per = np.asarray(per, dtype=np.float64).ravel()
    if len(per) != pos.shape[1] or pos.shape[1] != scene.num_particles:
        raise ValueError(
            f"report_or_per_particle: {len(per)} local costs, trajectory of {pos.shape[1]} "
            f"particles, scene of {scene.num_particles}"
        )
    if not 0 <= frame < len(pos):
        raise ValueError(f"frame: {frame} is outside 0..{len(pos) - 1}")
    from matplotlib.colors import LogNorm

    plt = _pyplot()
    view = _view(pos, scene, plane, ax)
    shape = pos[frame]
    limits = _limits([shape[None]], view)
    if ax is None:
        (x0, x1), (y0, y1) = limits[0], limits[1]
        aspect = 1.0 if view.is_3d else (y1 - y0) / (x1 - x0)
        fig, ax = plt.subplots(figsize=(6.4, 5.0 * min(max(aspect, 0.3), 1.5) + 1.2),
                               layout="constrained",
                               subplot_kw={"projection": "3d"} if view.is_3d else None)
    else:
        fig = ax.figure
    _draw_shape(ax, shape, _pairs(scene), np.zeros(len(shape), bool), view, "#b0b0b0",
                particles=False)
    positive = np.isfinite(per) & (per > 0)
    size = 8.0 if len(shape) > 500 else 60.0
    cols = list(view.axes)
    if positive.any():
        lo, hi = float(per[positive].min()), float(per[positive].max())
        norm = LogNorm(vmin=lo, vmax=hi if hi > lo else lo * 10)
        sc = ax.scatter(*shape[positive][:, cols].T, c=per[positive], norm=norm,
                        cmap="viridis", s=size, zorder=3, edgecolors="none")
        fig.colorbar(sc, ax=ax, label="local cost $c_i$ (m²)", shrink=0.8 if view.is_3d else 1.0)
    if (~positive).any():
        ax.scatter(*shape[~positive][:, cols].T, s=size / 3, marker="s",
                   color="black", zorder=3, label="cost 0")
        ax.legend(fontsize="small", loc="best")
    _frame_axes(ax, view, limits)
    ax.set_title(f"local costs, frame {frame}", fontsize="medium")
    return fig


# ---------------------------------------------------------------- pareto


_PARETO_KEYS = ("strategy", "scene", "seconds", "param_error_pct")


def _records(records_or_path: Any) -> List[Dict[str, Any]]:
    if isinstance(records_or_path, (str, os.PathLike)):
        path = pathlib.Path(records_or_path)
        records = []
        for n, line in enumerate(path.read_text().splitlines(), start=1):
            if line.strip():
                try:
                    records.append(json.loads(line))
                except json.JSONDecodeError as e:
                    raise ValueError(f"{path}:{n}: not a JSON object ({e.msg})") from None
    else:
        records = list(records_or_path)
    for n, r in enumerate(records):
        missing = [k for k in _PARETO_KEYS if k not in r]
        if missing:
            raise ValueError(f"records[{n}]: missing {', '.join(missing)}")
    return records


def pareto(records_or_path: Any, ax: Any = None,
           strategies: Optional[Sequence[str]] = None) -> "Figure":
    """Run time against parameter error, one marker per strategy, both on log scales.

    ``records_or_path`` is a list of dicts or a JSON-lines file, each with the keys
    ``strategy, scene, seconds, param_error_pct`` (what ``cordis bench pareto`` writes).
    Runs of several scenes are told apart by a label beside each marker; the runs that no
    other run of the same scene beats on both time and error are joined by a dotted line.
    An error of 0 is drawn one decade under the least positive error. ``strategies`` fixes
    each strategy's marker and colour by its place in that list (default: order of
    appearance), so that panels of several scenes agree.

    >>> cordis.plot.pareto([{"strategy": "thesis", "scene": "rigid", "seconds": 1.2,
    ...                      "param_error_pct": 0.01}]).savefig("pareto.png")
    """
    records = _records(records_or_path)
    if not records:
        raise ValueError("records_or_path: no runs to plot")
    plt = _pyplot()
    if ax is None:
        fig, ax = plt.subplots(figsize=(6.4, 4.6), layout="constrained")
    else:
        fig = ax.figure
    secs = np.array([float(r["seconds"]) for r in records])
    err = np.array([np.nan if r["param_error_pct"] is None else float(r["param_error_pct"])
                    for r in records])
    pos = err[np.isfinite(err) & (err > 0)]
    err = np.where(np.isfinite(err) & (err <= 0), (pos.min() / 10) if len(pos) else 1e-12, err)
    present = list(dict.fromkeys(str(r["strategy"]) for r in records))
    order = list(dict.fromkeys([str(s) for s in strategies or []] + present))
    scenes = list(dict.fromkeys(str(r["scene"]) for r in records))
    markers = "osD^vP*Xh<>p"
    for k, s in enumerate(order):
        if s not in present:
            continue
        idx = [i for i, r in enumerate(records) if str(r["strategy"]) == s]
        ax.scatter(secs[idx], err[idx], marker=markers[k % len(markers)], s=55, label=s,
                   zorder=3, color=f"C{k % 10}")
    for scene in scenes:
        idx = [i for i, r in enumerate(records)
               if str(r["scene"]) == scene and np.isfinite(err[i]) and secs[i] > 0]
        front = [i for i in idx if not any(
            secs[j] <= secs[i] and err[j] <= err[i] and (secs[j] < secs[i] or err[j] < err[i])
            for j in idx)]
        front.sort(key=lambda i: secs[i])
        if len(front) > 1:
            ax.plot(secs[front], err[front], ":", color="grey", zorder=2)
        if len(scenes) > 1:
            for i in idx:
                ax.annotate(scene, (secs[i], err[i]), textcoords="offset points", xytext=(5, 4),
                            fontsize="x-small")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("run time (s)")
    ax.set_ylabel("mean parameter error (%)")
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize="small", title="strategy")
    return fig


# ---------------------------------------------------------------- animation


def _ffmpeg() -> Optional[str]:
    """The ffmpeg program for .mp4: on PATH, else the one the ``imageio-ffmpeg`` package ships
    (``pip install imageio-ffmpeg``), else None."""
    found = shutil.which("ffmpeg")
    if found is not None:
        return found
    try:
        import imageio_ffmpeg
    except ImportError:
        return None
    try:
        return str(imageio_ffmpeg.get_ffmpeg_exe())
    except RuntimeError:  # the package without its binary for this platform
        return None


def animate(
    scene: "Scene",
    traj: Any,
    path: Union[str, "os.PathLike[str]"],
    compare: Any = None,
    fps: int = 30,
    every: int = 1,
    plane: Optional[str] = None,
    width: float = 5.0,
    dpi: int = 80,
) -> pathlib.Path:
    """Writes the motion ``traj`` ``(T, N, 3)`` of ``scene`` as an animated GIF or MP4.

    The format follows the extension: ``.gif`` (Pillow, installed with matplotlib) or
    ``.mp4`` (H.264, needs ``ffmpeg`` on PATH or the ``imageio-ffmpeg`` package). ``compare``
    is a second motion of the same scene (e.g. the identified model's), drawn dashed over the
    first. ``every`` keeps one frame in ``every``; ``fps`` is the playback rate (frames per
    second, an integer; ``round(1 / (every * scene.dt))`` plays in real time; a GIF stores
    each frame's duration in hundredths of a second, so above 50 fps it is rounded). ``plane`` chooses the view
    as in :func:`trajectories` (``"3d"``, ``"xy"``…; by default the view that shows the
    motion's largest extent, 3-D unless the motion is flat). ``width`` (inches) and ``dpi``
    set the picture's size, ``width × dpi`` pixels across (the height follows the motion's
    shape). Returns the path written.

    >>> cordis.animate(scene, scene.simulate(200), "motion.gif", every=2)
    PosixPath('motion.gif')
    """
    pos = _positions(traj, "traj")
    if pos.shape[1] != scene.num_particles:
        raise ValueError(f"traj: {pos.shape[1]} particles for a scene of {scene.num_particles}")
    other = None
    if compare is not None:
        other = _positions(compare, "compare")
        if other.shape[1] != pos.shape[1]:
            raise ValueError(f"compare: {other.shape[1]} particles, traj {pos.shape[1]}")
    for name, value in (("fps", fps), ("every", every)):
        if not (isinstance(value, (int, np.integer)) and 1 <= value <= 1000):
            raise ValueError(f"{name}: expected an integer in [1, 1000], got {value!r}")
    if not (np.isfinite(width) and 0.5 <= width <= 50):
        raise ValueError(f"width: expected inches in [0.5, 50], got {width!r}")
    if not 10 <= int(dpi) <= 1000 or int(dpi) != dpi:
        raise ValueError(f"dpi: expected an integer in [10, 1000], got {dpi!r}")
    out = pathlib.Path(path)
    ext = out.suffix.lower()
    if ext not in (".gif", ".mp4"):
        raise ValueError(f"{out}: the animation format follows the extension: .gif or .mp4")
    ffmpeg = _ffmpeg() if ext == ".mp4" else None
    if ext == ".mp4" and ffmpeg is None:
        raise RuntimeError(f"{out}: writing .mp4 needs ffmpeg (on PATH, or `pip install "
                           f"imageio-ffmpeg`); write a .gif instead")

    plt = _pyplot()
    import matplotlib
    from matplotlib.animation import FFMpegWriter, PillowWriter

    count = len(pos) if other is None else min(len(pos), len(other))
    frames = list(range(0, count, every))
    pairs, fixed = _pairs(scene), _fixed(scene)
    view = _view(pos[:count], scene, plane)
    limits = _limits([pos[:count]] + ([other[:count]] if other is not None else []), view)
    (x0, x1), (y0, y1) = limits[0], limits[1]
    aspect = 0.8 if view.is_3d else min(max((y1 - y0) / (x1 - x0) if x1 > x0 else 1.0, 0.5), 2.0)
    fig, ax = plt.subplots(figsize=(width, width * aspect + 0.6 * width / 5.0), dpi=dpi,
                           layout="constrained",
                           subplot_kw={"projection": "3d"} if view.is_3d else None)
    _frame_axes(ax, view, limits)
    motions = [(pos, _draw_shape(ax, pos[frames[0]], pairs, fixed, view, _ORIGINAL,
                                 label="motion" if other is not None else None))]
    if other is not None:
        motions.append((other, _draw_shape(ax, other[frames[0]], pairs, fixed, view,
                                           _IDENTIFIED, linestyle="--", alpha=0.8,
                                           label="compare")))
        ax.legend(fontsize="small", loc="upper right")
    title = ax.set_title(" ", fontsize="medium")
    # The layout is computed once: every frame only moves the shapes (one draw per frame).
    fig.canvas.draw()
    fig.set_layout_engine("none")
    out.parent.mkdir(parents=True, exist_ok=True)
    settings: Any = {"animation.ffmpeg_path": ffmpeg} if ffmpeg else {}
    try:
        with matplotlib.rc_context(settings):
            writer = PillowWriter(fps=fps) if ext == ".gif" else FFMpegWriter(fps=fps)
            with writer.saving(fig, str(out), dpi=dpi):
                for f in frames:
                    for motion, artists in motions:
                        _move_shape(artists, motion[f], pairs, fixed, view)
                    title.set_text(f"t = {f * scene.dt:.3f} s")
                    writer.grab_frame()
    finally:
        plt.close(fig)
    return out
