#!/usr/bin/env python3
"""Checks that a screenshot of the identification report is drawn in the expected theme.

`report_check.py SHOT.png light|dark` (standard library only): the most frequent colour is the
page background and must be light (channel mean > 200) or dark (< 60) as asked; at least
MIN_DRAWN pixels differ clearly from it (text, tables, charts) and MIN_COLOURED of them are
saturated (the charts' x, y, z curves and bars), so a blank or an unstyled page fails.
"""

import collections
import sys

from png_check import read_png

MIN_DRAWN = 20000
MIN_COLOURED = 3000


def main():
    path, theme = sys.argv[1], sys.argv[2]
    width, height, rows = read_png(path)
    counts = collections.Counter(px for row in rows[::2] for px in row[::2])
    background = counts.most_common(1)[0][0]
    level = sum(background) / 3
    if (theme == "light") != (level > 200) or (theme == "dark") != (level < 60):
        raise SystemExit(f"{path}: background {background} is not a {theme} theme's")
    drawn = coloured = 0
    for row in rows:
        for r, g, b in row:
            if max(abs(r - background[0]), abs(g - background[1]), abs(b - background[2])) > 60:
                drawn += 1
                if max(r, g, b) - min(r, g, b) > 60:
                    coloured += 1
    print(f"{path}: {theme} background {background}, {drawn} drawn pixels, {coloured} coloured")
    if drawn < MIN_DRAWN or coloured < MIN_COLOURED:
        raise SystemExit(f"{path}: looks blank ({drawn} drawn, {coloured} coloured pixels)")


if __name__ == "__main__":
    main()
