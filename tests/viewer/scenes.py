#!/usr/bin/env python3
"""Scenes for the viewer's screenshot test: `scenes.py OUTDIR` writes

- spring.json: a small 3-D spring structure (a cube of springs and dampers hanging from a
  fixed point, thrown sideways so that it swings and tumbles);
- cloth.json and cloth_b.json: a 20 x 20 cloth, flat at first and held at two corners, that
  falls and swings (Provot's structural, shear and bending springs); cloth_b.json has
  stiffnesses 30 % lower, standing in for an identified model to compare with the original;
- big.json: the cloth at 51 x 51 (2,601 particles, 14,898 links), to check the file size and
  the drawing time of a large scene;
- fluid.json: a 2-D swirling blob of two particle groups held together by conditional links
  (pairs closer than a range, found every step), drawn as coloured particles.
"""

import json
import sys
from pathlib import Path


def spring_scene():
    particles = [{"mass": 0.05, "pos": [0.0, 1.0, 0.0], "fixed": True}]
    corners = [(x, y, z) for x in (0, 1) for y in (0, 1) for z in (0, 1)]
    for x, y, z in corners:
        particles.append(
            {"mass": 0.1, "pos": [0.6 + 0.4 * x, 0.2 + 0.4 * y, -0.2 + 0.4 * z],
             "vel": [0.0, 0.0, 1.2]}
        )
    links = []
    for a in range(8):
        for b in range(a + 1, 8):
            diff = sum(ca != cb for ca, cb in zip(corners[a], corners[b]))
            kind = {1: "edge", 2: "diagonal"}.get(diff)
            if kind:
                links.append({"type": kind, "particles": [a + 1, b + 1]})
                links.append({"type": "goo", "particles": [a + 1, b + 1]})
    links.append({"type": "hanger", "particles": [0, 1 + corners.index((0, 1, 0))]})
    links.append({"type": "hanger", "particles": [0, 1 + corners.index((0, 1, 1))]})
    types = {
        "edge": {"kind": "spring", "stiffness": 60.0, "rest_length": 0.4, "damping": 0.02},
        "diagonal": {"kind": "spring", "stiffness": 30.0, "rest_length": 0.565685},
        "hanger": {"kind": "spring", "stiffness": 40.0, "rest_length": 0.5, "damping": 0.01},
        "goo": {"kind": "damper", "damping": 0.01},
        "air": {"kind": "drag", "damping": 0.002},
    }
    links += [{"type": "air", "particles": [i]} for i in range(1, 9)]
    return {"format": "cordis-scene/1", "dt": 0.005, "gravity": [0, -9.81, 0],
            "particles": particles, "types": types, "links": links}


def cloth_scene(softer=1.0, side=20, h=0.05):
    particles, links = [], []
    for r in range(side):
        for c in range(side):
            fixed = r == side - 1 and c in (0, side - 1)
            particles.append({"mass": 0.01, "pos": [c * h, r * h, 0.0], "fixed": fixed})
    idx = lambda r, c: r * side + c  # noqa: E731
    for r in range(side):
        for c in range(side):
            if c + 1 < side:
                links.append({"type": "structural", "particles": [idx(r, c), idx(r, c + 1)]})
            if r + 1 < side:
                links.append({"type": "structural", "particles": [idx(r, c), idx(r + 1, c)]})
            if r + 1 < side and c + 1 < side:
                links.append({"type": "shear", "particles": [idx(r, c), idx(r + 1, c + 1)]})
                links.append({"type": "shear", "particles": [idx(r, c + 1), idx(r + 1, c)]})
            if c + 2 < side:
                links.append({"type": "bend", "particles": [idx(r, c), idx(r, c + 2)]})
            if r + 2 < side:
                links.append({"type": "bend", "particles": [idx(r, c), idx(r + 2, c)]})
    types = {
        "structural": {"kind": "spring", "stiffness": 60.0 * softer, "rest_length": h,
                       "damping": 0.01},
        "shear": {"kind": "spring", "stiffness": 20.0 * softer, "rest_length": h * 2 ** 0.5,
                  "damping": 0.005},
        "bend": {"kind": "spring", "stiffness": 5.0 * softer, "rest_length": 2 * h},
    }
    return {"format": "cordis-scene/1", "dt": 0.003, "gravity": [0, 0, -9.81],
            "particles": particles, "types": types, "links": links}


def fluid_scene(side=16, h=0.1):
    particles = []
    c0 = (side - 1) * h / 2
    for r in range(side):
        for c in range(side):
            x, y = c * h - c0, r * h - c0
            if x * x + y * y > (c0 + 0.05) ** 2:
                continue
            group = "ink" if x > 0.15 and abs(y) < 0.35 else "water"
            # A vortex: velocity around the centre, faster near it.
            particles.append({"mass": 0.01, "pos": [x, y, 0.0], "vel": [-1.2 * y, 1.2 * x, 0.0],
                              "group": group})
    types = {
        "cohesion": {"kind": "conditional", "groups": ["water"], "stiffness": 4.0,
                     "rest_length": 0.1, "damping": 0.002, "range": 0.14},
        "mixing": {"kind": "conditional", "groups": ["water", "ink"], "stiffness": 2.0,
                   "rest_length": 0.1, "damping": 0.002, "range": 0.14},
        "ink": {"kind": "conditional", "groups": ["ink"], "stiffness": 6.0,
                "rest_length": 0.1, "damping": 0.002, "range": 0.14},
    }
    return {"format": "cordis-scene/1", "dt": 0.005, "gravity": [0, 0, 0],
            "particles": particles, "types": types, "links": []}


def main():
    out = Path(sys.argv[1])
    out.mkdir(parents=True, exist_ok=True)
    for name, scene in [("spring", spring_scene()), ("cloth", cloth_scene()),
                        ("cloth_b", cloth_scene(softer=0.7)), ("fluid", fluid_scene()),
                        ("big", cloth_scene(side=51, h=0.02))]:
        (out / f"{name}.json").write_text(json.dumps(scene, indent=1))


if __name__ == "__main__":
    main()
