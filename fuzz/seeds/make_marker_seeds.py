"""Writes the seeds of the marker-reader fuzz targets (fuzz/seeds/markers_*): small valid
files of each format, as python/tests/test_markers.py writes them. Needs numpy and c3d.

    python fuzz/seeds/make_marker_seeds.py
"""

import pathlib

import c3d
import numpy as np

HERE = pathlib.Path(__file__).resolve().parent


def positions(frames, markers):
    t = np.arange(frames)[:, None, None]
    i = np.arange(markers)[None, :, None]
    k = np.arange(3)[None, None, :]
    return 0.1 * t + 0.01 * i + 1.0 * k + 0.5


def c3d_seed(path, frames=4, markers=3):
    pos = positions(frames, markers)
    writer = c3d.Writer(point_rate=200.0, point_units="mm  ")
    writer.set_point_labels([f"M{i}" for i in range(markers)])
    out = []
    for f in range(frames):
        points = np.zeros((markers, 5), dtype=np.float32)
        points[:, :3] = pos[f] * 1000.0
        if f == 2:
            points[1, 3] = -1.0
        out.append((points, np.zeros((0, 0), dtype=np.float32)))
    writer.add_frames(out)
    with open(path, "wb") as h:
        writer.write(h)


def trc_seed(path, units="mm", frames=4, markers=2):
    pos = positions(frames, markers)
    scale = {"mm": 1000.0, "m": 1.0}[units]
    lines = [
        f"PathFileType\t4\t(X/Y/Z)\t{path.name}",
        "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames",
        f"120.00\t120.00\t{frames}\t{markers}\t{units}\t120.00\t1\t{frames}",
        "Frame#\tTime\t" + "\t".join(f"M{i}\t\t" for i in range(markers)),
        "\t\t" + "\t".join(f"X{i + 1}\tY{i + 1}\tZ{i + 1}" for i in range(markers)),
        "",
    ]
    for f in range(frames):
        cells = [str(f + 1), f"{f / 120.0:.5f}"]
        for i in range(markers):
            cells += ["", "", ""] if (f, i) == (2, 0) else [repr(float(v * scale)) for v in pos[f, i]]
        lines.append("\t".join(cells))
    path.write_text("\n".join(lines) + "\n")


def main():
    c3d_seed(HERE / "markers_c3d" / "walk.c3d")
    trc_seed(HERE / "markers_trc" / "walk_mm.trc")
    trc_seed(HERE / "markers_trc" / "walk_m.trc", units="m", frames=3, markers=1)
    rng = np.random.default_rng(0)
    tracks = rng.uniform(0, 640, size=(3, 4, 2)).astype(np.float32)
    seen = rng.uniform(size=(3, 4)) > 0.3
    np.savez(HERE / "markers_npz" / "tapvid.npz", tracks=tracks, visibility=seen)
    np.savez_compressed(HERE / "markers_npz" / "tapvid_compressed.npz", tracks=tracks, visibility=seen)
    np.savez(HERE / "markers_npz" / "cotracker.npz", pred_tracks=tracks.transpose(1, 0, 2)[None],
             pred_visibility=seen.T[None])
    pos = positions(3, 2)
    rows = ["Time;Marker;X;Y;Z"]
    for f in range(3):
        for i, m in enumerate(["knee", "hip"]):
            rows.append(";".join([f"{f * 0.005}", m] + [f"{v:.4f}".replace(".", ",") for v in pos[f, i]]))
    (HERE / "markers_table" / "long.csv").write_text("\n".join(rows) + "\n")
    rows = ["frame\tknee_X\tknee_Y\tknee_Z\thip X [mm]\thip Y [mm]\thip Z [mm]"]
    for f in range(3):
        rows.append("\t".join([str(f)] + [repr(float(v)) for v in pos[f].ravel()]))
    (HERE / "markers_table" / "wide.tsv").write_text("\n".join(rows) + "\n")
    (HERE / "markers_table" / "cordis.csv").write_text("frame,particle,x,y,z\n0,0,1,2,3\n1,0,1,2,3.5\n")


if __name__ == "__main__":
    main()
