#!/usr/bin/env python3
"""Checks that a viewer screenshot is not blank (standard library only: zlib + PNG chunks).

`png_check.py SHOT.png [MIN_PIXELS [any]]` counts, inside the drawing area (the middle of the
window, away from the panels), the pixels that differ clearly from the dark background, and
among them the coloured ones (links are drawn in saturated colours). It fails when either
count is below its threshold, or when the picture is not the expected size.
"""

import struct
import sys
import zlib


def read_png(path):
    """(width, height, rows of RGB tuples) of an 8-bit RGB or RGBA, non-interlaced PNG."""
    data = open(path, "rb").read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise SystemExit(f"{path}: not a PNG file")
    pos, idat, header = 8, b"", None
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos:pos + 4])
        kind = data[pos + 4:pos + 8]
        body = data[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    width, height, depth, colour, _, _, interlace = header
    if depth != 8 or colour not in (2, 6) or interlace:
        raise SystemExit(f"{path}: unsupported PNG (depth {depth}, colour type {colour})")
    bpp = 3 if colour == 2 else 4
    raw = zlib.decompress(idat)
    stride = width * bpp
    rows, prev = [], bytearray(stride)
    for y in range(height):
        f = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - bpp] if i >= bpp else 0
            b = prev[i]
            c = prev[i - bpp] if i >= bpp else 0
            if f == 1:
                line[i] = (line[i] + a) & 255
            elif f == 2:
                line[i] = (line[i] + b) & 255
            elif f == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append([tuple(line[x * bpp:x * bpp + 3]) for x in range(width)])
        prev = line
    return width, height, rows


def main():
    path = sys.argv[1]
    min_pixels = int(sys.argv[2]) if len(sys.argv) > 2 else 800
    # `any`: a picture the page made itself (the PNG export: the canvas at the window's
    # inner size), not a 1000x700 screenshot.
    any_size = len(sys.argv) > 3 and sys.argv[3] == "any"
    width, height, rows = read_png(path)
    if (width, height) != (1000, 700) and not (any_size and width >= 800 and height >= 500):
        raise SystemExit(f"{path}: {width}x{height}, expected 1000x700")
    # The drawing area between the info panel (top left), the legend (top right) and the
    # controls (bottom); the whole canvas of an exported frame (no panels on it).
    x0, x1, y0, y1 = (0, width, 0, height) if any_size else (180, 760, 130, 600)
    drawn = coloured = 0
    for y in range(y0, y1):
        for x in range(x0, x1):
            r, g, b = rows[y][x]
            hi, lo = max(r, g, b), min(r, g, b)
            if hi > 90:
                drawn += 1
                if hi - lo > 60:
                    coloured += 1
    print(f"{path}: {drawn} drawn pixels, {coloured} coloured, in the drawing area")
    if drawn < min_pixels or coloured < min_pixels // 2:
        raise SystemExit(f"{path}: looks blank ({drawn} drawn, {coloured} coloured pixels)")


if __name__ == "__main__":
    main()
