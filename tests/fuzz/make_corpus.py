#!/usr/bin/python3
"""Writes the seed corpora of the fuzz targets (tests/fuzz/corpus/<target>/): a few valid and a few broken
inputs each, all small. Histogram seeds are edits of HIST.exr files made by `microsim trace vndf --rows 1`
and `--rows 3` (given on the command line); heightmap seeds are written here, uncompressed. Scatter seeds
(with --scatter) are edits of a measured scatter histogram of 1 row per hemisphere (the tests' synthetic
run, tests/scatter_samples.h) and of `microsim scatter --model analytic --rows 1 --material conductor:...`.
Usage: /usr/bin/python3 tests/fuzz/make_corpus.py HIST_ROWS1.exr HIST_ROWS3.exr HEIGHTMAP_ZIP.exr
       /usr/bin/python3 tests/fuzz/make_corpus.py --scatter SCATTER_HISTOGRAM.exr SCATTER_EXPECTATION.exr
"""
import os
import struct
import sys

HERE = os.path.dirname(os.path.abspath(__file__))


def put(target, name, data):
    d = os.path.join(HERE, "corpus", target)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name), "wb") as f:
        f.write(data)


# ---- .npy ----------------------------------------------------------------------------------------------
def npy(header, data, major=1, newline=True):
    pre = 8 + (2 if major == 1 else 4)
    body = header + " " * ((64 - (pre + len(header) + 1) % 64) % 64) + ("\n" if newline else " ")
    n = struct.pack("<H", len(body)) if major == 1 else struct.pack("<I", len(body))
    return b"\x93NUMPY" + bytes([major, 0]) + n + body.encode("latin1") + data


ROWS = [(0.0, 0.0, 1.0), (0.6, 0.0, -0.8), (0.0, 1.0, 0.0)]
f8 = b"".join(struct.pack("<3d", *r) for r in ROWS)
f4 = b"".join(struct.pack("<3f", *r) for r in ROWS)
put("npy", "good_f8", npy("{'descr': '<f8', 'fortran_order': False, 'shape': (3, 3), }", f8))
put("npy", "good_f4", npy("{'descr': '<f4', 'fortran_order': False, 'shape': (3, 3), }", f4))
put("npy", "good_v2", npy("{'descr': '<f8', 'fortran_order': False, 'shape': (3, 3), }", f8, major=2))
put("npy", "good_fortran", npy("{'descr': '<f8', 'fortran_order': True, 'shape': (3, 3), }",
                               b"".join(struct.pack("<3d", *column) for column in zip(*ROWS))))
put("npy", "good_odd", npy('{"shape": (3L, 3L), "fortran_order": False, "descr": "<f8"}', f8, major=3))
put("npy", "bad_no_newline", npy("{'descr': '<f8', 'fortran_order': False, 'shape': (3, 3), }", f8, newline=False))
put("npy", "bad_truncated", npy("{'descr': '<f8', 'fortran_order': False, 'shape': (3, 3), }", f8)[:-7])
put("npy", "bad_shape", npy("{'descr': '<f8', 'fortran_order': False, 'shape': (18446744073709551615, 3), }", f8))
put("npy", "bad_dtype", npy("{'descr': '\x01\xff', 'fortran_order': True, 'shape': (3,), }", f8))
put("npy", "bad_not_unit", npy("{'descr': '<f8', 'fortran_order': False, 'shape': (1, 3), }", struct.pack("<3d", 0, 0, 2)))

# ---- text ----------------------------------------------------------------------------------------------
put("text", "good_plain", b"0 0 1\n0.6 0 -0.8\n0 1 0\n")
put("text", "good_mixed", b"\xef\xbb\xbf# comment\r\n0, 0, 1\r\n\r\n  +0.6,0 , -8e-1 # x\n1e0 0 0")
put("text", "bad_columns", b"0 0 1 0\n")
put("text", "bad_nan", b"nan 0 1\n0x1 0 0\n")
put("text", "bad_comma", b"0, 0, 1,\n0,,1\n")
put("text", "bad_binary", bytes(range(256)))
put("text", "bad_long", b"0 0 " + b"1" * 400 + b"\n0 0 1e999\n")


# ---- EXR -----------------------------------------------------------------------------------------------
def exr_split(data):
    """(magic+version, [(name, type, value)], offset of the line offset table)."""
    pos, attrs = 8, []
    while data[pos] != 0:
        a = data.index(b"\0", pos)
        b = data.index(b"\0", a + 1)
        (size,) = struct.unpack_from("<i", data, b + 1)
        attrs.append((data[pos:a], data[a + 1:b], data[b + 5:b + 5 + size]))
        pos = b + 5 + size
    return data[:8], attrs, pos + 1


def exr_edit(data, edit):
    """The file with its header attributes replaced by edit(attrs), line offsets shifted to match."""
    head, attrs, end = exr_split(data)
    dw = dict((n, v) for n, t, v in attrs)[b"dataWindow"]
    comp = dict((n, v) for n, t, v in attrs)[b"compression"][0]
    lines = {0: 1, 1: 1, 2: 1, 3: 16, 4: 32, 5: 16, 6: 32, 7: 32, 8: 32, 9: 256}[comp]
    ymin, ymax = struct.unpack_from("<i", dw, 4)[0], struct.unpack_from("<i", dw, 12)[0]
    chunks = (ymax - ymin + lines) // lines
    offsets = struct.unpack_from("<%dQ" % chunks, data, end)
    new = head + b"".join(n + b"\0" + t + b"\0" + struct.pack("<i", len(v)) + v for n, t, v in edit(attrs)) + b"\0"
    shift = len(new) - end
    return new + struct.pack("<%dQ" % chunks, *[o + shift for o in offsets]) + data[end + 8 * chunks:]


def set_string(name, value):
    return lambda attrs: [a for a in attrs if a[0] != name.encode()] + [(name.encode(), b"string", value.encode("latin1"))]


def set_window(w, h):
    box = struct.pack("<iiii", 0, 0, w - 1, h - 1)
    return lambda attrs: [(n, t, box if n in (b"dataWindow", b"displayWindow") else v) for n, t, v in attrs]


def set_compression(c):
    return lambda attrs: [(n, t, bytes([c]) if n == b"compression" else v) for n, t, v in attrs]


def heightmap(n, tile_size="1", channel=b"height", ptype=2):
    """An uncompressed single-channel heightmap of n x n (FLOAT: ptype 2, HALF: 1)."""
    def attr(name, typ, value):
        return name + b"\0" + typ + b"\0" + struct.pack("<i", len(value)) + value
    chlist = channel + b"\0" + struct.pack("<iB3xii", ptype, 0, 1, 1) + b"\0"
    box = struct.pack("<iiii", 0, 0, n - 1, n - 1)
    header = b"\x76\x2f\x31\x01" + struct.pack("<i", 2) + b"".join([
        attr(b"channels", b"chlist", chlist), attr(b"compression", b"compression", b"\0"),
        attr(b"dataWindow", b"box2i", box), attr(b"displayWindow", b"box2i", box),
        attr(b"lineOrder", b"lineOrder", b"\0"), attr(b"pixelAspectRatio", b"float", struct.pack("<f", 1)),
        attr(b"screenWindowCenter", b"v2f", struct.pack("<ff", 0, 0)),
        attr(b"screenWindowWidth", b"float", struct.pack("<f", 1)),
        attr(b"microsim.tile_size", b"string", tile_size.encode())]) + b"\0"
    size = 4 if ptype == 2 else 2
    first = len(header) + 8 * n
    lines = []
    for y in range(n):
        row = [0.01 * ((x * 7 + y * 3) % 5) for x in range(n)]
        px = struct.pack("<%d%s" % (n, "f" if ptype == 2 else "e"), *row)
        lines.append(struct.pack("<ii", y, len(px)) + px)
    offsets, at = [], first
    for line in lines:
        offsets.append(at)
        at += len(line)
    return header + struct.pack("<%dQ" % n, *offsets) + b"".join(lines)


if len(sys.argv) == 4 and sys.argv[1] == "--scatter":
    sh, se = (open(p, "rb").read() for p in sys.argv[2:])
    put("scatter_exr", "good_histogram_rows1", sh)
    put("scatter_exr", "good_expectation_rows1", se)
    put("scatter_exr", "bad_blocks", exr_edit(sh, set_string("blocks", "1,0")))
    put("scatter_exr", "bad_sum", exr_edit(sh, set_string("c0.unfinished.w", "9223372036854775808,0")))
    put("scatter_exr", "bad_channel_names", exr_edit(se, set_string("channel_names", '["a"]')))
    put("scatter_exr", "bad_binning", exr_edit(se, set_string("binning", '{"kind":"hemispheres","rows":1e300}')))
    put("scatter_exr", "bad_huge_header", exr_edit(sh, set_window(46340, 46340)))
elif len(sys.argv) == 4:
    r1, r3, hz = (open(p, "rb").read() for p in sys.argv[1:])
    put("histogram_exr", "good_rows1", r1)
    put("histogram_exr", "good_rows3", r3)
    put("histogram_exr", "bad_hits_negative", exr_edit(r1, set_string("hits", "-1")))
    put("histogram_exr", "bad_hits_over_rays", exr_edit(r3, set_string("hits", "99999999")))
    put("histogram_exr", "bad_binnings_twice", exr_edit(r1, set_string("binnings", "sphere,sphere")))
    put("histogram_exr", "bad_binning_json", exr_edit(r3, set_string("binning.lobe", '{"kind":"lobe","rows":1e300}')))
    put("histogram_exr", "bad_huge_header", exr_edit(r1, set_window(46340, 46340)))
    put("heightmap_exr", "good_zip", hz)
    put("heightmap_exr", "bad_huge_header", exr_edit(hz, set_window(46340, 46340)))
    put("heightmap_exr", "bad_tile_size", exr_edit(hz, set_string("microsim.tile_size", "1e-300x")))
put("heightmap_exr", "good_float", heightmap(4))
put("heightmap_exr", "good_half_y", heightmap(3, "2.5", channel=b"Y", ptype=1))
put("heightmap_exr", "bad_nan_tile_size", heightmap(2, "nan"))
put("heightmap_exr", "bad_not_square", exr_edit(heightmap(4), set_window(2, 4)))
# One scan line of 12 MiB: within the fuzz targets' limit of pixel data, but DWAA and B44 decode 32 lines
# at a time and DWAB 256, and OpenEXR sizes its buffers for a whole chunk.
for name, c in (("dwaa", 8), ("b44", 6), ("dwab", 9)):
    put("heightmap_exr", "bad_wide_line_" + name,
        exr_edit(heightmap(4), lambda a, c=c: set_compression(c)(set_window(3 << 20, 1)(a))))

# ---- numbers -------------------------------------------------------------------------------------------
for i, token in enumerate([b"0", b"18446744073709551615", b"18446744073709551616", b"-1", b"0.3,0.25",
                           b"1e-3", b"-.5e+2", b"nan", b"1e999", b" 1", b"1x", b"0x10", b"4.9e-324",
                           b"\x01\xff" * 30]):
    put("numbers", "seed_%02d" % i, token)
