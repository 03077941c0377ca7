"""Every shipped passive example, exported to MJCF and replayed in MuJoCo (issue 18).

For each example: `cordis example NAME` (its default length), `cordis export --mjcf`, then
MuJoCo integrating every step through `cordis.mujoco.load` (the kinds MJCF lacks applied by
the passive callback and Provot's projection between steps), against `Scene.simulate`. Prints
one Markdown row per example: the largest coordinate difference relative to the motion's
extent over the frames in which one ulp at the start moves cordis' own motion by at most 1e-10
of its extent ("determined"), that window, the difference over the whole length, that one-ulp
sensitivity at the end, and MuJoCo's CPU seconds. python/tests/test_mujoco.py asserts the
bound (1e-9) on the same quantities.

    pip install ./python "mujoco>=4,<5" && python benches/mujoco_replay.py
"""

import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

import cordis
import cordis.mujoco

PASSIVE = ("rigid", "cloth", "fluid", "horse", "bouncing-ball", "horse-ground")


def cordis_command() -> list:
    exe = shutil.which("cordis", path=os.path.dirname(sys.executable))
    return [exe] if exe else [sys.executable, "-m", "cordis"]


def extent(traj: np.ndarray) -> float:
    flat = traj.reshape(-1, 3)
    return float((flat.max(axis=0) - flat.min(axis=0)).max())


def one_ulp_sensitivity(scene: cordis.Scene, frames: int, draws: int = 3) -> np.ndarray:
    """Per frame, the largest move of cordis' motion when every start coordinate moves by one
    ulp (random directions, `draws` of them, seed 7)."""
    got = scene.simulate(frames)
    rng = np.random.default_rng(7)
    worst = np.zeros(frames)
    for _ in range(draws):
        d = scene.to_dict()
        for p in d["particles"]:
            p["pos"] = [float(np.nextafter(c, np.inf if rng.random() < 0.5 else -np.inf))
                        for c in p["pos"]]
        moved = cordis.Scene.from_dict(d).simulate(frames)
        worst = np.maximum(worst, np.abs(moved - got).max(axis=(1, 2)))
    return worst


def main() -> None:
    tmp = tempfile.mkdtemp()
    print("| example | particles | frames | extent (m) | error, determined frames | determined "
          "| error, all frames | one-ulp sensitivity at the end | MuJoCo CPU s |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name in PASSIVE:
        scene_path = os.path.join(tmp, name + ".json")
        xml = os.path.join(tmp, name + ".xml")
        made = subprocess.run(cordis_command() + ["example", name, "--out", scene_path,
                                                  "--json", "-q"],
                              capture_output=True, text=True, check=True)
        frames = json.loads(made.stdout)["frames"]
        subprocess.run(cordis_command() + ["export", scene_path, "--mjcf", xml, "-q"],
                       check=True)
        scene = cordis.Scene.from_json(scene_path)
        start = time.process_time()
        with cordis.mujoco.load(xml) as sim:
            want = sim.run(frames)
        cpu = time.process_time() - start
        got = scene.simulate(frames)
        scale = extent(got)
        err = np.abs(got - want).max(axis=(1, 2)) / scale
        sensitivity = one_ulp_sensitivity(scene, frames) / scale
        loose = np.flatnonzero(sensitivity > 1e-10)
        window = int(loose[0]) if loose.size else frames
        print(f"| {name} | {scene.num_particles} | {frames} | {scale:.3f} | "
              f"{err[:window].max():.1e} | {window} | {err.max():.1e} | "
              f"{sensitivity[-1]:.1e} | {cpu:.1f} |")


if __name__ == "__main__":
    main()
