"""Simulate the hanging cloth and look at it: an animated GIF and the 3-D HTML viewer.

    python examples/cloth_motion.py     # writes ./out/cloth.{json,npy,gif,html}

The cloth example (the thesis' §4.2, after Provot) is a 32 × 32 grid of particles about 1 m
square (structural, shear and bending springs, a 10 % elongation limit on the structural
ones), held horizontal by one pinned edge and released: it falls, swings past the vertical and
stretches against the limit. It is drawn in 3-D (cordis.plot's automatic view for a motion
that spreads along every axis: gravity up, the swing across the picture). The GIF is made with
``cordis.animate`` (matplotlib); the HTML page by the ``cordis render`` command, which needs
no Python at all to view. The output directory is ``$CORDIS_OUT`` or ``./out``. A few seconds.
"""

import os
import pathlib
import shutil
import subprocess
import sys

import cordis


def cordis_command() -> list:
    """The `cordis` console script installed beside this Python (or `python -m cordis`)."""
    exe = shutil.which("cordis", path=os.path.dirname(sys.executable))
    return [exe] if exe else [sys.executable, "-m", "cordis"]


def main() -> None:
    out = pathlib.Path(os.environ.get("CORDIS_OUT", "out"))
    out.mkdir(parents=True, exist_ok=True)
    scene = cordis.example("cloth")
    frames = 400  # dt = 2 ms: 0.8 s of motion
    traj = scene.simulate(frames)  # (400, 1024, 3), m
    (out / "cloth.json").write_text(scene.to_json())
    cordis.write_trajectory(out / "cloth.npy", traj)
    print(f"simulated {scene.num_particles} particles, {scene.num_links} links, "
          f"{frames} frames of {scene.dt} s")

    gif = cordis.animate(scene, traj, out / "cloth.gif", fps=15, every=16)
    print(f"wrote {gif}")

    html = out / "cloth.html"
    subprocess.run(cordis_command() + ["render", str(out / "cloth.json"), "--trajectory",
                                       str(out / "cloth.npy"), "--html", str(html)], check=True)
    print(f"wrote {html} (open it in a browser)")


if __name__ == "__main__":
    main()
