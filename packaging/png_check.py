"""Whether a PNG screenshot shows something: the spread of its brightness and its count of colours.

Standard library only, so the smoke test runs it with any system ``python3`` (no numpy, no venv).
Usage: ``python3 packaging/png_check.py IMAGE.png [MIN_STD] [MIN_COLOURS]``; exit 0 when the image is
not blank, 1 when it is, 2 when it is not an 8-bit RGB(A) PNG.
"""
from __future__ import annotations

import math
import struct
import sys
import zlib

SIGNATURE = b"\x89PNG\r\n\x1a\n"
CHANNELS = {2: 3, 6: 4}   # colour type: RGB, RGBA


def read_png(path: str) -> tuple[int, int, int, list[bytearray]]:
    """Width, height, channels and the unfiltered rows of an 8-bit, non-interlaced RGB(A) PNG."""
    with open(path, "rb") as f:
        data = f.read()
    if not data.startswith(SIGNATURE):
        raise ValueError("not a PNG file")
    pos, idat, header = len(SIGNATURE), [], None
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat.append(body)
        pos += 12 + length
    width, height, depth, colour, _, _, interlace = header
    if depth != 8 or colour not in CHANNELS or interlace:
        raise ValueError(f"unsupported PNG (bit depth {depth}, colour type {colour}, interlace {interlace})")
    n = CHANNELS[colour]
    raw, stride = zlib.decompress(b"".join(idat)), width * n
    rows, prev = [], bytearray(stride)
    for y in range(height):
        kind, row = raw[y * (stride + 1)], bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            left = row[i - n] if i >= n else 0
            if kind == 1:
                row[i] = (row[i] + left) & 255
            elif kind == 2:
                row[i] = (row[i] + prev[i]) & 255
            elif kind == 3:
                row[i] = (row[i] + ((left + prev[i]) >> 1)) & 255
            elif kind == 4:
                up, up_left = prev[i], prev[i - n] if i >= n else 0
                p = left + up - up_left
                pa, pb, pc = abs(p - left), abs(p - up), abs(p - up_left)
                row[i] = (row[i] + (left if pa <= pb and pa <= pc else up if pb <= pc else up_left)) & 255
        rows.append(row)
        prev = row
    return width, height, n, rows


def stats(path: str) -> tuple[float, int]:
    """Standard deviation of the brightness (0-255) and the number of distinct RGB colours."""
    width, height, n, rows = read_png(path)
    total = total_sq = 0.0
    colours = set()
    for row in rows:
        for x in range(0, width * n, n):
            r, g, b = row[x], row[x + 1], row[x + 2]
            v = 0.299 * r + 0.587 * g + 0.114 * b
            total += v
            total_sq += v * v
            colours.add((r, g, b))
    count = width * height
    return math.sqrt(max(total_sq / count - (total / count) ** 2, 0.0)), len(colours)


def main(argv: list[str]) -> int:
    path = argv[0]
    min_std = float(argv[1]) if len(argv) > 1 else 10.0
    min_colours = int(argv[2]) if len(argv) > 2 else 64
    try:
        std, colours = stats(path)
    except (OSError, ValueError, zlib.error, struct.error, TypeError) as exc:
        print(f"{path}: cannot be checked: {exc}", file=sys.stderr)
        return 2
    blank = std < min_std or colours < min_colours
    print(f"{path}: brightness std {std:.1f}, {colours} colours: {'BLANK' if blank else 'not blank'}")
    return 1 if blank else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
