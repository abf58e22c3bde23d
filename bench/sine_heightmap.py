#!/usr/bin/env python3
# Usage: /usr/bin/python3 bench/sine_heightmap.py N OUT.exr (then --tile-size 1 where the heightmap is read).
# Writes a periodic N x N heightmap (sum of random integer-frequency sinusoids, rms slope ~0.5) as an
# uncompressed single-channel FLOAT scanline EXR ("height"), for tracing-size tests.
import struct, sys
import numpy as np
n = int(sys.argv[1]); out = sys.argv[2]
rng = np.random.default_rng(1)
terms = 40
fx = rng.integers(-64, 65, terms); fy = rng.integers(-64, 65, terms); ph = rng.uniform(0, 2 * np.pi, terms)
k = np.sqrt(fx.astype(float) ** 2 + fy ** 2) + 1
amp = 1.0 / k ** 2
# slope of term: amp * 2 pi k_f / N * N (tile 1): scale to rms slope 0.5
slope_rms = np.sqrt(np.sum((amp * 2 * np.pi * np.sqrt(fx ** 2 + fy ** 2)) ** 2) / 2)
amp *= 0.5 / slope_rms
x = np.arange(n) / n
def attr(name, typ, data):
    return name.encode() + b"\0" + typ.encode() + b"\0" + struct.pack("<i", len(data)) + data
ch = b"height\0" + struct.pack("<iB3xii", 2, 0, 1, 1) + b"\0"
box = struct.pack("<iiii", 0, 0, n - 1, n - 1)
header = (struct.pack("<ii", 20000630, 2) + attr("channels", "chlist", ch) + attr("compression", "compression", b"\0")
          + attr("dataWindow", "box2i", box) + attr("displayWindow", "box2i", box) + attr("lineOrder", "lineOrder", b"\0")
          + attr("pixelAspectRatio", "float", struct.pack("<f", 1.0))
          + attr("screenWindowCenter", "v2f", struct.pack("<ff", 0, 0)) + attr("screenWindowWidth", "float", struct.pack("<f", 1.0))
          + b"\0")
row_bytes = 8 + 4 * n
start = len(header) + 8 * n
with open(out, "wb") as f:
    f.write(header)
    f.write(np.array([start + y * row_bytes for y in range(n)], dtype="<u8").tobytes())
    cx = [np.cos(2 * np.pi * fx[t] * x + ph[t]) for t in range(terms)]
    sx = [np.sin(2 * np.pi * fx[t] * x + ph[t]) for t in range(terms)]
    for y in range(n):
        row = np.zeros(n)
        for t in range(terms):
            a = 2 * np.pi * fy[t] * y / n
            row += amp[t] * (sx[t] * np.cos(a) + cx[t] * np.sin(a))
        f.write(struct.pack("<ii", y, 4 * n))
        f.write(row.astype("<f4").tobytes())
