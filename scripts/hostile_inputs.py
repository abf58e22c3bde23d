#!/usr/bin/python3
"""microsim: the hostile-input battery of docs/records/reliability.md.

Runs the `microsim` binary on several hundred bad inputs (every numeric flag of every command, broken
.npy/text sample files, broken heightmap and histogram EXRs, output paths that collide with inputs or
with each other) and on a few valid edge values, and tallies the outcomes:

  clear error   exit 2, a short message on stderr that names the flag, the file or the value, nothing
                created or changed in the working directory
  rejected      (a sample file whose rows hold a sampler's NaNs) exit 1, the rows named on stdout
  unclear       exit 2 but a message that names nothing, or is longer than 1000 bytes
  accepted      a bad input that ran as if it were good (exit 0 or 1)
  crash         killed by a signal, exit 3 (internal error) or a sanitizer report
  hang          still running after --timeout seconds
  file lost     an input file changed or vanished
  half-written  a failed run that left a file behind

Each case runs in a fresh copy of the fixtures. Usage:
  /usr/bin/python3 scripts/hostile_inputs.py [--binary build/microsim] [--json out/hostile.json]
      [--timeout 60] [--only SUBSTRING] [--list]
Exit status 0 when every bad input got a clear error and every valid edge value ran, 1 otherwise.
"""
import argparse
import json
import os
import shutil
import struct
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)


# ---- fixtures ------------------------------------------------------------------------------------------

def npy_bytes(array, header_override=None, newline=True, magic=b"\x93NUMPY", version=(1, 0)):
    """An .npy file written by hand, so that every part of it can be broken on purpose."""
    arr = np.ascontiguousarray(array)
    header = header_override if header_override is not None else "{'descr': '%s', 'fortran_order': False, 'shape': %s, }" % (
        arr.dtype.str, repr(tuple(arr.shape)))
    pre = len(magic) + 2 + (2 if version[0] == 1 else 4)
    body = header + (" " * ((64 - (pre + len(header) + 1) % 64) % 64))
    body += "\n" if newline else " "
    hlen = struct.pack("<H", len(body)) if version[0] == 1 else struct.pack("<I", len(body))
    return magic + bytes(version) + hlen + body.encode("latin1") + arr.tobytes()


def unit_vectors(n, seed=1):
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(n, 3))
    v[:, 2] = np.abs(v[:, 2])
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def exr_attributes(data):
    """Splits a single-part scanline EXR into (magic+version, [(name, type, value)], rest)."""
    pos = 8
    attrs = []
    while data[pos] != 0:
        name_end = data.index(b"\0", pos)
        type_end = data.index(b"\0", name_end + 1)
        (size,) = struct.unpack_from("<i", data, type_end + 1)
        value = data[type_end + 5:type_end + 5 + size]
        attrs.append((data[pos:name_end].decode(), data[name_end + 1:type_end].decode(), value))
        pos = type_end + 5 + size
    return data[:8], attrs, pos + 1


def exr_rewrite(data, edit):
    """Rewrites the header of an EXR written by microsim: `edit(attrs)` returns new attributes. The line
    offset table (absolute file offsets) is shifted by the change in header length."""
    head, attrs, end = exr_attributes(data)
    dw = next(v for n, t, v in attrs if n == "dataWindow")
    comp = next(v for n, t, v in attrs if n == "compression")[0]
    lines_per_chunk = {0: 1, 1: 1, 2: 1, 3: 16, 4: 32, 5: 16, 6: 32, 7: 32, 8: 16, 9: 256}.get(comp, 1)
    ymin, ymax = struct.unpack_from("<i", dw, 4)[0], struct.unpack_from("<i", dw, 12)[0]
    chunks = (ymax - ymin + lines_per_chunk) // lines_per_chunk
    offsets = list(struct.unpack_from("<%dQ" % chunks, data, end))
    rest = data[end + 8 * chunks:]
    new = b"".join(n.encode() + b"\0" + t.encode() + b"\0" + struct.pack("<i", len(v)) + v for n, t, v in edit(attrs))
    new = head + new + b"\0"
    shift = len(new) - end
    return new + struct.pack("<%dQ" % chunks, *[o + shift for o in offsets]) + rest


def set_string_attr(name, value):
    def edit(attrs):
        out = [(n, t, v) for n, t, v in attrs if n != name]
        out.append((name, "string", value.encode("latin1")))
        return out
    return edit


def set_data_window(w, h):
    def edit(attrs):
        box = struct.pack("<iiii", 0, 0, w - 1, h - 1)
        return [(n, t, box if n in ("dataWindow", "displayWindow") else v) for n, t, v in attrs]
    return edit


# Bad experiment specs (docs/reference/experiments.md): name -> (TOML text, the key the message must name). Each is
# tried with `plan` and `run --out out` (nothing may be run or created).
SPEC_MATERIAL = '[[material]]\nname = "m"\nalpha = 0.3\ntype = "mirror"\n'
SPEC_VNDF = '[[quantity]]\nkind = "vndf"\nmaterial = "m"\ntheta = [30]\ntarget_tv = 0.05\n'
SPEC_VALIDATION = '[[quantity]]\nkind = "validation"\nmaterial = "m"\ntheta = [30]\ndetect_tv = 0.05\n'
BAD_SPECS = {
    "spec_syntax": (SPEC_MATERIAL + "[[quantity]\n", "(syntax)"),
    "spec_unknown_key": (SPEC_MATERIAL + SPEC_VNDF + "rays = 5\n", "quantity[0].rays"),
    "spec_target_zero": (SPEC_MATERIAL + SPEC_VNDF.replace("0.05", "0"), "quantity[0].target_tv"),
    "spec_target_nan": (SPEC_MATERIAL + SPEC_VNDF.replace("0.05", "nan"), "quantity[0].target_tv"),
    "spec_unknown_material": (SPEC_MATERIAL + SPEC_VNDF.replace('"m"\ntheta', '"gold"\ntheta'), "quantity[0].material"),
    "spec_below_horizon": (SPEC_MATERIAL + SPEC_VNDF.replace("[30]", "[30, 120]"), "quantity[0].theta"),
    "spec_alpha_huge": (SPEC_MATERIAL.replace("0.3", "1e300") + SPEC_VNDF, "material[0].alpha"),
    "spec_seed_negative": ("seed = -1\n" + SPEC_MATERIAL + SPEC_VNDF, "seed"),
    "spec_no_quantity": (SPEC_MATERIAL, "quantity"),
    "spec_huge_token": (SPEC_MATERIAL + SPEC_VNDF.replace('"vndf"', '"' + "v" * 100000 + '"'), "quantity[0].kind"),
    "spec_dump_missing": (SPEC_MATERIAL + SPEC_VALIDATION + 'dump = "no_such_dump.npy"\n', "quantity[0].dump"),
    "spec_dump_not_samples": (SPEC_MATERIAL + SPEC_VALIDATION + 'dump = "npy_bad_magic.npy"\n', "quantity[0].dump"),
    "spec_dump_and_sampler": (SPEC_MATERIAL + SPEC_VALIDATION + 'sampler = "heitz2018"\ndump = "npy_f2.npy"\n',
                              "quantity[0].sampler"),
}


def write_spec_fixtures(w):
    for name, (text, _) in BAD_SPECS.items():
        w(name + ".toml", text.encode())
    w("spec_binary.toml", bytes(range(256)) * 4)


def make_fixtures(binary, fixtures):
    """Valid inputs made by microsim itself, and broken variants of them."""
    os.makedirs(fixtures, exist_ok=True)
    run = lambda *a: subprocess.run([binary, *a], cwd=fixtures, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                    check=True, timeout=600)
    run("surface", "build", "--assembly", "smith", "--alpha", "0.5", "--res", "256", "--seed", "1", "--out", "hf.exr",
        "--quiet")
    run("trace", "vndf", "--surface", "ellipsoid", "--alpha", "0.3", "--theta", "30", "--rays", "200000",
        "--out", "hist.exr")
    w = lambda name, data: open(os.path.join(fixtures, name), "wb").write(data)
    write_spec_fixtures(w)
    # A finished experiment run (seed 1) and a run directory whose results.json is broken: a rerun resumes
    # only the same spec at the same seed (docs/reference/experiments.md).
    w("run_spec.toml", (SPEC_MATERIAL + '[[quantity]]\nkind = "albedo"\nmaterial = "m"\nmus = 2\n'
                        'target_relative_error = 0.01\n').encode())
    run("run", "run_spec.toml", "--out", "run_done", "--seed", "1")
    os.makedirs(os.path.join(fixtures, "run_broken"), exist_ok=True)
    w(os.path.join("run_broken", "results.json"), b'{"spec": {"digest": ')
    good = unit_vectors(20000)
    w("good.npy", npy_bytes(good))
    w("good.txt", "\n".join("%r %r %r" % tuple(r) for r in good).encode())
    # .npy variants
    w("npy_no_newline.npy", npy_bytes(good, newline=False))
    w("npy_bad_magic.npy", npy_bytes(good, magic=b"\x93NUMPX"))
    w("npy_v9.npy", npy_bytes(good, version=(9, 0)))
    w("npy_truncated.npy", npy_bytes(good)[:-100])
    w("npy_extra.npy", npy_bytes(good) + b"\0" * 24)
    w("npy_shape4.npy", npy_bytes(np.hstack([good, good[:, :1]])))
    w("npy_shape1d.npy", npy_bytes(good.reshape(-1)))
    w("npy_shape3d.npy", npy_bytes(good.reshape(-1, 3, 1)))
    w("npy_int.npy", npy_bytes((good * 100).astype("<i4")))
    w("npy_f2.npy", npy_bytes(good.astype("<f2")))
    w("npy_c16.npy", npy_bytes(good.astype("<c16")))
    w("npy_huge_shape.npy", npy_bytes(good, header_override="{'descr': '<f8', 'fortran_order': False, "
                                                            "'shape': (4611686018427387904, 3), }"))
    w("npy_overflow_shape.npy", npy_bytes(good, header_override="{'descr': '<f8', 'fortran_order': False, "
                                                                "'shape': (99999999999999999999999, 3), }"))
    w("npy_neg_shape.npy", npy_bytes(good, header_override="{'descr': '<f8', 'fortran_order': False, 'shape': (-5, 3), }"))
    w("npy_bad_dict.npy", npy_bytes(good, header_override="{'descr': '<f8', 'fortran_order': Maybe, 'shape': (20000, 3), }"))
    w("npy_extra_key.npy", npy_bytes(good, header_override="{'descr': '<f8', 'fortran_order': False, 'shape': (20000, 3), 'x': 1}"))
    w("npy_unterminated.npy", npy_bytes(good, header_override="{'descr': '<f8"))
    w("npy_struct.npy", npy_bytes(good, header_override="{'descr': [('x', '<f8')], 'fortran_order': False, 'shape': (20000, 3), }"))
    w("npy_empty.npy", npy_bytes(np.zeros((0, 3))))
    w("npy_one_row.npy", npy_bytes(good[:1]))
    w("npy_binary_header.npy", npy_bytes(good, header_override="{'descr': '\x01\x02\xff\xfe', 'fortran_order': False, 'shape': (20000, 3), }"))
    w("npy_long_key.npy", npy_bytes(good, header_override="{'" + "k" * 60000 + "': 1}"))
    w("npy_zero_len.npy", b"\x93NUMPY\x01\x00\x00\x00")
    w("npy_4bytes.npy", b"\x93NUM")
    w("empty.npy", b"")
    w("npy_not_unit.npy", npy_bytes(good * 2))
    # text variants
    w("text_empty.txt", b"")
    w("text_one_line.txt", b"0 0 1\n")
    w("text_two_cols.txt", b"0 0\n0 1\n")
    w("text_four_cols.txt", b"0 0 1 0\n")
    w("text_words.txt", b"zero zero one\n")
    w("text_binary.txt", bytes(range(256)) * 64)
    w("text_huge_token.txt", b"0 0 " + b"1" * (10 * 1024 * 1024) + b"\n")
    w("text_huge_garbage.txt", b"0 0 " + b"x\x01" * (5 * 1024 * 1024) + b"\n")
    # A sampler's failures (NaN rows, the zero vector) among good rows: a rejection (exit 1), not bad input.
    garbage = good.copy()
    garbage[3] = np.nan
    garbage[77] = 0.0
    w("nan_rows.npy", npy_bytes(garbage.astype("<f4")))
    lines = ["%r %r %r" % tuple(r) for r in good]
    lines[5], lines[9] = "-nan 0 1", "0 inf 0"
    w("nan_rows.txt", "\n".join(lines).encode())
    w("text_not_unit.txt", b"0 0 2\n" * 10)
    w("text_trailing_comma.txt", b"0, 0, 1,\n" * 10)
    w("text_hex.txt", b"0x0 0x0 0x1\n" * 10)
    w("text_overflow.txt", b"0 0 1e999\n" * 10)
    w("text_nul.txt", b"0 0 1\0\n" * 10)
    # EXR variants
    hf = open(os.path.join(fixtures, "hf.exr"), "rb").read()
    hist = open(os.path.join(fixtures, "hist.exr"), "rb").read()
    w("not_exr.exr", b"this is not an EXR file\n" * 10)
    w("empty.exr", b"")
    w("hf_truncated.exr", hf[: len(hf) // 2])
    w("hf_header_only.exr", hf[:400])
    w("hf_huge_header.exr", exr_rewrite(hf, set_data_window(46340, 46340)))
    w("hf_wide_header.exr", exr_rewrite(hf, set_data_window(2 ** 30, 1)))
    w("hf_bad_tile_size.exr", exr_rewrite(hf, set_string_attr("microsim.tile_size", "-1")))
    w("hf_nan_tile_size.exr", exr_rewrite(hf, set_string_attr("microsim.tile_size", "nan")))
    w("hf_junk_tile_size.exr", exr_rewrite(hf, set_string_attr("microsim.tile_size", "1x")))
    w("hf_bad_alpha.exr", exr_rewrite(hf, set_string_attr("microsim.alpha", "0.5,")))
    w("hist_hits_neg.exr", exr_rewrite(hist, set_string_attr("hits", "-1")))
    w("hist_hits_gt_rays.exr", exr_rewrite(hist, set_string_attr("hits", "99999999")))
    w("hist_rays_overflow.exr", exr_rewrite(hist, set_string_attr("rays", "99999999999999999999999")))
    w("hist_rays_junk.exr", exr_rewrite(hist, set_string_attr("rays", "12abc")))
    w("hist_binnings_dup.exr", exr_rewrite(hist, set_string_attr("binnings", "sphere,sphere")))
    w("hist_binnings_unknown.exr", exr_rewrite(hist, set_string_attr("binnings", "sphere,cube")))
    w("hist_binnings_empty.exr", exr_rewrite(hist, set_string_attr("binnings", "")))
    w("hist_format.exr", exr_rewrite(hist, set_string_attr("format", "microsim-histogram-9")))
    w("hist_binning_json.exr", exr_rewrite(hist, set_string_attr("binning.sphere", "{not json")))
    w("hist_binning_rows.exr", exr_rewrite(hist, set_string_attr("binning.sphere", '{"kind":"sphere","rows":-3}')))
    w("hist_huge_header.exr", exr_rewrite(hist, set_data_window(46340, 46340)))
    w("hist_truncated.exr", hist[: len(hist) * 2 // 3])


# ---- cases ---------------------------------------------------------------------------------------------

# Bad values for each kind of numeric flag. Every one must be refused with exit 2.
COMMON_BAD = ["", "abc", "nan", "inf", "-inf", "1e400", "0x10", "1,", " ", "1 2", "\x01\x7f", "Z" * 100000]
KIND_BAD = {
    "theta": ["-1", "90", "91", "1e30", "-0.0000001"],
    "angle": ["1e400"],  # phi: any finite value is allowed
    "count": ["0", "-1", "99999999999999999999", "18446744073709551616", "1.5", "1e30"],
    "seed": ["-1", "18446744073709551616", "99999999999999999999", "1.5"],
    "rows": ["0", "2", "-1", "46341", "1048577", "2147483647", "16383", "4095"],
    "prob": ["0", "1", "-0.5", "2"],
    "alpha": ["0", "-0.3", "1e30", "0.3,", ",0.3", "0.3,,0.5", "0.3,0.5,0.7", "1e-9", "0.0001,1"],
    "positive": ["0", "-1", "1e400"],
    "nonneg": ["-1", "-0.5", "1e400"],               # 0 means "from the file" or "the default"
    "count0": ["-1", "99999999999999999999", "18446744073709551616", "1.5", "1e30"],  # 0 means "off"
    "threads": ["-1", "99999999999999999999", "1.5"],
    "level": ["-1", "10", "1.5"],
    "small_count": ["0", "-1", "99999999999999999999", "1.5"],
    "small_count0": ["-1", "99999999999999999999", "1.5"],
    "res": ["0", "-16", "17", "100", "99999999999999999999", "16384"],
    "uint_range": ["-1", "1000001", "99999999999999999999"],
    "cone": ["0", "-1", "91"],
    "hemisphere_rows": ["0", "-1", "251", "2147483647", "1.5"],  # scatter --rows: rows per hemisphere
    "order_cap": ["0", "-1", "100001", "1.5", "99999999999999999999"],
}
VAL = "validate --sampler heitz2018 --alpha 0.3 --theta 30 --samples 20000 --rows 11"
TRACE = "trace vndf --surface ellipsoid --alpha 0.3 --theta 30 --rays 20000 --out o.exr"
MASK = "trace masking --surface hf.exr --theta 60 --samples 2000"
BUILD = "surface build --assembly smith --alpha 0.5 --res 256 --out s.exr --quiet"
WALK = "scatter --model smith-walk --alpha 0.3 --theta 30 --rays 20000 --rows 4 --out o.exr"
SURF = "scatter --surface hf.exr --theta 30 --rays 5000 --rows 4 --out o.exr"
ANALYTIC = "scatter --model analytic --alpha 0.3 --theta 30 --rows 4 --out o.exr"
FLAGS = [  # (command with a default for the flag, flag, kind)
    (VAL, "--alpha", "alpha"), (VAL, "--theta", "theta"), (VAL, "--phi", "angle"), (VAL, "--samples", "count"),
    (VAL, "--seed", "seed"), (VAL, "--rows", "rows"), (VAL, "--significance", "prob"),
    ("validate --sampler heitz2018 --alpha 0.3 --theta 30 --samples 20000 --against ellipsoid --rays 20000", "--rays",
     "count"),
    ("validate --from good.npy --reflected --above-horizon --alpha 0.3 --theta 30 --dropped 10", "--dropped", "count0"),
    (TRACE, "--alpha", "alpha"), (TRACE, "--theta", "theta"), (TRACE, "--phi", "angle"), (TRACE, "--rays", "count"),
    (TRACE, "--seed", "seed"), (TRACE, "--threads", "threads"), (TRACE, "--rows", "rows"),
    (TRACE, "--mesh-level", "level"),
    (MASK, "--theta", "theta"), (MASK, "--phi", "angle"), (MASK, "--samples", "count"), (MASK, "--seed", "seed"),
    (MASK, "--threads", "threads"), (MASK, "--bins", "small_count"), (MASK, "--vndf-rays", "count0"),
    (MASK, "--grazing-share", "prob"), (MASK + " --theta-l 30", "--cone", "cone"), (MASK, "--theta-l", "theta"),
    (MASK, "--tile-size", "positive"),
    (BUILD, "--alpha", "alpha"), (BUILD, "--res", "res"), (BUILD, "--seed", "seed"),
    (BUILD, "--corr-cells", "nonneg"), (BUILD, "--tile-size", "positive"), (BUILD, "--iterations", "small_count0"),
    ("surface stats hf.exr", "--tile-size", "nonneg"), ("surface stats hf.exr", "--alpha", "alpha"),
    ("surface stats hf.exr", "--corr-cells", "nonneg"),
    ("stability --failures-only", "--random-u", "uint_range"), ("stability --failures-only", "--seed", "seed"),
    (WALK, "--alpha", "alpha"), (WALK, "--theta", "theta"), (WALK, "--phi", "angle"), (WALK, "--rays", "count"),
    (WALK, "--seed", "seed"), (WALK, "--threads", "threads"), (WALK, "--rows", "hemisphere_rows"),
    (WALK, "--max-order", "order_cap"),
    (SURF, "--theta", "theta"), (SURF, "--rays", "count"), (SURF, "--tile-size", "positive"),
    (SURF, "--max-order", "order_cap"),
    (ANALYTIC, "--alpha", "alpha"), (ANALYTIC, "--theta", "theta"), (ANALYTIC, "--rows", "hemisphere_rows"),
]
# Well-formed files whose rows hold a sampler's failures: rejected (exit 1), the first rows named on stdout.
SAMPLER_FAILURES = [
    ("validate --from nan_rows.npy --alpha 0.3 --theta 30", "row 3 (0-based), row 77 (0-based)"),
    ("validate --from nan_rows.txt --alpha 0.3 --theta 30", "line 6, line 10"),
]
# Valid edge values: they must run (exit 0 or 1), quickly.
VALID = [
    VAL.replace("--theta 30", "--theta 0"), VAL.replace("--theta 30", "--theta 89.999"),
    VAL.replace("--alpha 0.3", "--alpha 1e-4"), VAL.replace("--alpha 0.3", "--alpha 10"),
    VAL.replace("--alpha 0.3", "--alpha 0.001,1"), VAL + " --phi -720", VAL + " --seed 18446744073709551615",
    VAL + " --seed 0", VAL.replace("--rows 11", "--rows 3"), TRACE + " --threads 1", TRACE + " --seed 0",
    "validate --from good.npy --alpha 0.3 --theta 30", "validate --from good.txt --alpha 0.3 --theta 30",
]
# Bad files: (command, a word the message must contain)
FILES = []
for f in ["npy_no_newline", "npy_bad_magic", "npy_v9", "npy_truncated", "npy_extra", "npy_shape4", "npy_shape1d",
          "npy_shape3d", "npy_int", "npy_f2", "npy_c16", "npy_huge_shape", "npy_overflow_shape", "npy_neg_shape",
          "npy_bad_dict", "npy_extra_key", "npy_unterminated", "npy_struct", "npy_empty", "npy_one_row",
          "npy_binary_header", "npy_long_key", "npy_zero_len", "npy_4bytes", "empty", "npy_not_unit"]:
    FILES.append(("validate --from %s.npy --alpha 0.3 --theta 30" % f, f))
for f in ["text_empty", "text_one_line", "text_two_cols", "text_four_cols", "text_words", "text_binary",
          "text_huge_token", "text_huge_garbage", "text_not_unit", "text_trailing_comma", "text_hex",
          "text_overflow", "text_nul"]:
    FILES.append(("validate --from %s.txt --alpha 0.3 --theta 30" % f, f))
for f, (_, key) in BAD_SPECS.items():
    FILES += [("plan %s.toml" % f, key), ("run %s.toml --out out" % f, key)]
FILES += [("plan spec_binary.toml", "spec_binary.toml"), ("plan missing_spec.toml", "missing_spec.toml"),
          ("run spec_unknown_key.toml", "--out")]
FILES += [("run run_spec.toml --out run_done --seed 2", "seed 1"),   # resume refused: another seed
          ("run run_spec.toml --out run_broken", "results.json")]   # a results.json that cannot be read
FILES += [("validate --from missing.npy --alpha 0.3 --theta 30", "missing"),
          ("validate --from . --alpha 0.3 --theta 30", "."),
          ("validate --from /dev/null --alpha 0.3 --theta 30", "/dev/null")]
for f in ["not_exr", "empty", "hf_truncated", "hf_header_only", "hf_huge_header", "hf_wide_header", "hf_bad_tile_size",
          "hf_nan_tile_size", "hf_junk_tile_size", "hist", "missing"]:
    FILES.append(("surface stats %s.exr" % f, f))
    FILES.append(("trace vndf --surface %s.exr --theta 30 --rays 2000 --out o.exr" % f, f))
    FILES.append(("trace masking --surface %s.exr --theta 60 --samples 2000" % f, f))
for f in ["not_exr", "empty", "hf_truncated", "hf_huge_header", "hf_wide_header", "hist"]:
    FILES.append(("surface import %s.exr --tile-size 1 --out imp.exr" % f, f))
for f in ["not_exr", "empty", "hf_truncated", "hf_header_only", "hf_huge_header", "hf_wide_header", "hf_bad_tile_size",
          "hf_nan_tile_size", "hf_junk_tile_size", "hist", "missing"]:
    FILES.append(("scatter --surface %s.exr --theta 30 --rays 2000 --out o.exr" % f, f))
for f in ["not_exr", "empty", "hf", "hist", "missing"]:
    FILES.append(("compare-scattering %s.exr %s.exr" % (f, f), f))
for f in ["not_exr", "empty", "hf", "missing"]:  # (a complete trace histogram is a valid single part)
    FILES.append(("merge %s.exr --out m.exr" % f, f))
for f in ["hist_hits_neg", "hist_hits_gt_rays", "hist_rays_overflow", "hist_rays_junk", "hist_binnings_dup",
          "hist_binnings_unknown", "hist_binnings_empty", "hist_format", "hist_binning_json", "hist_binning_rows",
          "hist_huge_header", "hist_truncated", "hf", "not_exr", "empty", "missing"]:
    FILES.append(("plot %s.exr --out fig.svg" % f, f))
    FILES.append(("validate --sampler heitz2018 --alpha 0.3 --theta 30 --samples 20000 --against %s.exr" % f, f))
# Output paths that collide with an input or with another output (nothing may be overwritten), and
# outputs that cannot be written.
PATHS = [
    ("validate --from good.txt --alpha 0.3 --theta 30 --json good.txt", "good.txt"),
    ("validate --from good.npy --alpha 0.3 --theta 30 --json ./sub/../good.npy", "good.npy"),
    ("validate --from good.npy --alpha 0.3 --theta 30 --json link.npy", "link.npy"),
    ("validate --from good.npy --alpha 0.3 --theta 30 --json hard.npy", "hard.npy"),
    ("validate --from good.npy --alpha 0.3 --theta 30 --plot good.npy", "good.npy"),
    ("validate --sampler heitz2018 --alpha 0.3 --theta 30 --samples 20000 --json f.svg --plot f.svg", "f.svg"),
    ("validate --sampler heitz2018 --alpha 0.3 --theta 30 --samples 20000 --against hist.exr --json hist.exr", "hist.exr"),
    ("trace vndf --surface hf.exr --theta 30 --rays 2000 --out hf.exr", "hf.exr"),
    ("trace vndf --surface hf.exr --theta 30 --rays 2000 --out link.exr", "link.exr"),
    ("trace vndf --surface ellipsoid --alpha 0.3 --theta 30 --rays 2000 --out o.exr --json o.exr", "o.exr"),
    ("trace vndf --surface ellipsoid --alpha 0.3 --theta 30 --rays 2000 --mesh-level 2 --out o.exr --mesh-out o.exr",
     "o.exr"),
    ("trace masking --surface hf.exr --theta 60 --samples 2000 --json hf.exr", "hf.exr"),
    ("trace masking --surface hf.exr --theta 60 --samples 2000 --json ./hf.exr", "hf.exr"),
    ("surface stats hf.exr --json hf.exr", "hf.exr"),
    ("surface stats hf.exr --normals hf.exr", "hf.exr"),
    ("surface stats hf.exr --json n.exr --normals n.exr", "n.exr"),
    ("surface import hf.exr --tile-size 1 --out hf.exr", "hf.exr"),
    ("surface build --assembly smith --alpha 0.5 --res 256 --out s.exr --normals s.exr --quiet", "s.exr"),
    ("surface build --assembly smith --alpha 0.5 --res 256 --out s.exr --json s.exr --quiet", "s.exr"),
    ("surface build --assembly smith --alpha 0.5 --res 256 --out s.exr --mesh s.exr --quiet", "s.exr"),
    ("plot hist.exr --out hist.exr", "hist.exr"),
    ("validate --sampler heitz2018 --alpha 0.3 --theta 30 --samples 20000 --json nodir/r.json", "nodir"),
    ("trace vndf --surface ellipsoid --alpha 0.3 --theta 30 --rays 2000 --out nodir/o.exr", "nodir"),
    ("trace vndf --surface ellipsoid --alpha 0.3 --theta 30 --rays 2000 --out adir", "adir"),
    ("surface build --assembly smith --alpha 0.5 --res 256 --out adir --quiet", "adir"),
    ("validate --sampler heitz2018 --alpha 0.3 --theta 30 --samples 20000 --plot fig.png", "fig.png"),
    ("scatter --surface hf.exr --theta 30 --rays 2000 --out hf.exr", "hf.exr"),
    ("scatter --surface hf.exr --theta 30 --rays 2000 --out link.exr", "link.exr"),
    ("scatter --surface hf.exr --theta 30 --rays 2000 --out o.exr --json hf.exr", "hf.exr"),
    ("scatter --surface hf.exr --theta 30 --rays 2000 --out o.exr --json o.exr", "o.exr"),
    (WALK + " --json nodir/w.json", "nodir"),
    (WALK.replace("--out o.exr", "--out adir"), "adir"),
    (WALK.replace("--out o.exr", "--out o.png"), "o.png"),
]
# Usage errors that are not numbers or files.
USAGE = [
    ("validate --from good.npy --reflected --alpha 0.3 --theta 30 --columns x,y,z --bsdf mirror", "--bsdf"),
    ("validate --from good.npy --reflected --alpha 0.3 --theta 30 --bsdf conductor --eta 0.2 --k nan", "--k"),
    ("validate --from good.npy --reflected --alpha 0.3 --theta 30 --bsdf conductor --eta -1 --k 3", "--eta"),
    ("validate --from good.npy --reflected --alpha 0.3 --theta 30 --bsdf lambertian:0.5", "--bsdf"),
    ("validate --from good.npy --pdf bsdf --alpha 0.3 --theta 30", "--pdf bsdf"),
    ("validate --from good.npy --pdf bsdf --alpha 0.3 --theta 30 --bsdf dielectric", "--eta"),
    ("validate --from good.npy --pdf bsdf --alpha 0.3 --theta 30 --bsdf dielectric --eta 1.5 --k 2", "--k"),
    ("validate --from good.npy --pdf bsdf --alpha 0.3 --theta 30 --bsdf dielectric --eta 0", "--eta"),
    ("validate --from good.npy --reflected --alpha 0.3 --theta 30 --bsdf dielectric:1.5", "--pdf bsdf"),
    ("validate --from good.npy --alpha 0.3 --theta 30 --columns x,y", "--columns"),
    ("validate --from good.npy --alpha 0.3 --theta 30 --columns x,y,z,x", "--columns"),
    ("validate --sampler heitz2018 --alpha 0.3 --theta 30 --columns x,y,z,pdf", "--columns"),
    ("validate --from good.npy --alpha 0.3 --theta 30 --columns x,y,z,pdf", "good.npy"),
    ("validate --from good.txt --alpha 0.3 --theta 30 --columns x,y,z,pdf,weight --bsdf mirror", "good.txt"),
    ("validate --from good.npy --alpha 0.3 --theta 30 --columns x,y,z,pdf,weight", "--bsdf"),
    ("validate --from good.npy --alpha 0.3 --theta 30 --pdf ggx", "ggx"),
    ("validate --from good.npy --alpha 0.3 --theta 30 --frame x-up", "x-up"),
    ("validate --sampler heitz2018 --alpha 0.3 --theta 30 --frame y-up", "--frame"),
    ("validate --sampler heitz2018 --alpha 0.3 --theta 30 --pdf ndf", "--pdf"),
    ("validate --from good.npy --alpha 0.3 --theta 30 --above-horizon", "--above-horizon"),
    ("validate --from good.npy --alpha 0.3 --theta 30 --pdf ndf --above-horizon", "--above-horizon"),
    ("validate --from good.npy --reflected --alpha 0.3 --theta 30 --dropped 5", "--dropped"),
    ("validate --from good.npy --reflected --pdf bounded --alpha 0.3 --theta 30", "--reflected"),
    ("validate --sampler nosuch --alpha 0.3 --theta 30", "nosuch"),
    ("validate --alpha 0.3 --theta 30", "--sampler"),
    ("validate --sampler heitz2018 --from good.npy --alpha 0.3 --theta 30", "--from"),
    ("validate --sampler heitz2018 --theta 30", "--alpha"),
    ("validate --sampler heitz2018 --alpha 0.3", "--theta"),
    ("validate --all --alpha 0.3", "--all"),
    ("validate --all --samples 1", "samples"),
    ("validate --sampler heitz2018 --alpha 0.3 --theta 30 --samples 1", "samples"),
    ("validate --sampler heitz2018 --alpha 0.3 --theta 30 --samples 2", "samples"),
    ("validate --sampler heitz2018 --alpha 0.3 --theta 30 --against moon", "moon"),
    ("trace vndf --surface moon.exr --theta 30 --out o.exr", "moon"),
    ("trace vndf --surface ellipsoid --theta 30 --out o.exr", "--alpha"),
    ("trace vndf --surface ellipsoid --alpha 0.3 --theta 30 --mesh-out m.ply --out o.exr", "--mesh-out"),
    ("trace masking --surface hf.exr --theta 60 --geometry cubes", "cubes"),
    ("surface build --assembly nosuch --alpha 0.5 --res 256 --out s.exr", "nosuch"),
    ("surface build --assembly smith --alpha 0.5 --res 256 --ndf-match angular --out s.exr", "angular"),
    ("surface build --assembly smith --alpha 0.5 --res 256 --ndf-match JOINT --out s.exr", "JOINT"),
    ("trace masking --table --assemblies smith --ndf-match exact", "exact"),
    ("surface stats hf.exr --reference gaussian", "gaussian"),
    ("trace nosuch", "nosuch"),
    (WALK + " --material gold", "gold"),
    (WALK + " --material dielectric:0", "'0'"),
    (WALK + " --material dielectric:-1.5", "'-1.5'"),
    (WALK + " --material dielectric:nan", "'nan'"),
    (WALK + " --material dielectric:inf", "'inf'"),
    (WALK + " --material conductor:0.2,-1", "'-1'"),
    (WALK + " --material conductor:0.2", "'0.2'"),
    (WALK + " --material conductor:0,3", "'0'"),
    (WALK + " --material conductor:0.2,3;", "channel 2"),
    (WALK + " --material lambertian:2", "'2'"),
    (WALK + " --ndf phong", "phong"),
    (WALK + " --heights normal", "normal"),
    (WALK + " --surface hf.exr", "exclude"),
    (WALK + " --tile-size 1", "--tile-size"),
    (WALK.replace("--theta 30", "--theta 120"), "--theta 120"),
    (WALK.replace("--alpha 0.3", "--alpha 0.3,1000"), "--alpha"),
    (WALK + " --shard 3/2", "--shard"),
    (WALK + " --shard 0/2", "--shard"),
    (SURF + " --alpha 0.5", "--alpha"),
    (SURF + " --ndf beckmann", "--ndf"),
    (SURF.replace("--theta 30", "--theta 150"), "--theta 150"),
    (ANALYTIC + " --rays 1000", "--rays"),
    (ANALYTIC + " --material lambertian", "lambertian"),
    ("scatter --model walk --alpha 0.3 --theta 30 --out o.exr", "walk"),
    ("scatter --alpha 0.3 --theta 30 --out o.exr", "--model"),
    ("compare-scattering hist.exr", "hist.exr"),
    # an experiment in the shards of a job array (docs/guide/experiments-and-clusters.md): bad K/N, a merge of what is not a shard
    ("run run_spec.toml --out p --shard 0/2", "--shard"),
    ("run run_spec.toml --out p --shard 3/2", "--shard"),
    ("run run_spec.toml --out p --shard 1/0", "--shard"),
    ("run run_spec.toml --out p --shard two", "--shard"),
    ("run run_spec.toml --out p --shard 1/2 --merge run_done", "--merge"),
    ("run run_spec.toml --out p --shard 1/2 --dry-run", "--dry-run"),
    ("run run_spec.toml --out run_done --shard 1/2", "run_done"),
    ("run run_spec.toml --out m --merge run_done", "run_done"),
    ("run run_spec.toml --out m --merge no_such_shard", "no_such_shard"),
    ("nosuch", "nosuch"),
]


def all_cases(common_once=False):
    """Every case; with common_once, the values bad for any number (COMMON_BAD) are tried on the first flag
    of each command only (the sanitizer gate: they all reach the one number parser, which fuzz_numbers
    fuzzes, and the kind-specific values still reach every command's own checks)."""
    cases, commands_seen = [], set()
    for cmd, flag, kind in FLAGS:
        command = " ".join(cmd.split()[:2])
        common = COMMON_BAD if not common_once or command not in commands_seen else []
        commands_seen.add(command)
        for value in KIND_BAD[kind] + common:
            parts = cmd.split()
            if flag in parts:
                i = parts.index(flag)
                args = parts[:i + 1] + [value] + parts[i + 2:]
            else:
                args = parts + [flag, value]
            short = value if len(value) <= 20 else value[:8] + "...(%d)" % len(value)
            cases.append({"name": "%s %s %r" % (parts[0] + (" " + parts[1] if not parts[1].startswith("-") else ""),
                                                flag, short),
                          "args": args, "expect": "reject", "names": [flag]})
    for cmd, word in FILES + PATHS + USAGE:
        cases.append({"name": cmd if len(cmd) < 100 else cmd[:97] + "...", "args": cmd.split(), "expect": "reject",
                      "names": [word]})
    for cmd, word in SAMPLER_FAILURES:
        cases.append({"name": "sampler failures: " + cmd, "args": cmd.split(), "expect": "fail", "names": [word]})
    for cmd in VALID:
        cases.append({"name": "valid: " + cmd, "args": cmd.split(), "expect": "run", "names": []})
    return cases


# ---- running -------------------------------------------------------------------------------------------

def snapshot(d):
    """Every regular file under d by its identity and change times (inode, size, mtime and ctime in ns): a
    run that writes a file in place changes its mtime and ctime, one that replaces it its inode, and ctime
    cannot be set back from user space. (Hashing the contents found nothing more and took two thirds of the
    battery's time.)"""
    out = {}
    for root, _, files in os.walk(d):
        for f in files:
            p = os.path.join(root, f)
            if os.path.islink(p):
                continue
            st = os.stat(p)
            out[os.path.relpath(p, d)] = (st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)
    return out


def prepare_workdir(fixtures, pristine, work):
    """A fresh working directory whose inputs are hard links to the fixtures (fast, even for the 10 MB
    files); a fixture that a run changed in place is restored from its pristine copy."""
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    for f in os.listdir(fixtures):
        src = os.path.join(fixtures, f)
        if os.path.isdir(src):  # an experiment's run directory: small, copied
            shutil.copytree(src, os.path.join(work, f))
        else:
            os.link(src, os.path.join(work, f))
    os.symlink("good.npy", os.path.join(work, "link.npy"))
    os.symlink("hf.exr", os.path.join(work, "link.exr"))
    os.link(os.path.join(work, "good.npy"), os.path.join(work, "hard.npy"))
    os.makedirs(os.path.join(work, "sub"))
    os.makedirs(os.path.join(work, "adir"))


def restore_fixtures(fixtures, pristine, changed):
    for f in changed:
        name = "good.npy" if f == "hard.npy" else f
        if os.path.exists(os.path.join(pristine, name)):
            dst = os.path.join(fixtures, name)
            if os.path.exists(dst):
                os.remove(dst)
            shutil.copy(os.path.join(pristine, name), dst)


def classify(case, proc, timed_out, before, after, elapsed):
    err = proc.stderr.decode("utf-8", "replace") if proc is not None else ""
    changed = [f for f in before if f not in after or after[f] != before[f]]
    created = [f for f in after if f not in before]
    if timed_out:
        return "hang", err
    if changed:
        return "file lost", err
    code = proc.returncode
    if code < 0 or code == 3 or "Sanitizer" in err or "runtime error:" in err:
        return "crash", err
    if case["expect"] == "run":
        return ("ran" if code in (0, 1) else "refused valid input"), err
    if case["expect"] == "fail":
        out = proc.stdout.decode("utf-8", "replace")
        if code == 1 and all(n in out for n in case["names"]) and not created:
            return "rejected", err
        return ("accepted" if code == 0 else "unclear" if code == 1 else "unexpected exit %d" % code), err
    if code in (0, 1):
        return "accepted", err
    if created:
        return "half-written", err
    if code != 2:
        return "unexpected exit %d" % code, err
    if len(err) > 1000 or not any(n in err for n in case["names"]):
        return "unclear", err
    return "clear error", err


def run_case(command, case, fixtures, pristine, work, timeout):
    """One case in a fresh working directory: (outcome, stderr, the process or None, seconds)."""
    prepare_workdir(fixtures, pristine, work)
    before = snapshot(work)
    start = time.time()
    try:
        proc = subprocess.run(command + case["args"], cwd=work, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              timeout=timeout)
        timed_out = False
    except subprocess.TimeoutExpired:
        proc, timed_out = None, True
    elapsed = time.time() - start
    after = snapshot(work)
    outcome, err = classify(case, proc, timed_out, before, after, elapsed)
    restore_fixtures(fixtures, pristine, [f for f in before if after.get(f) != before[f]])
    return outcome, err, proc, elapsed


# A stand-in for a broken binary (the self-test): each action is one way a command can mistreat its inputs.
FAKE_BINARY = r"""
import os, sys
action = sys.argv[1]
if action == "rewrite-same-size":          # an input written in place, same length, same bytes but one
    data = bytearray(open("good.npy", "rb").read()); data[-1] ^= 1
    open("good.npy", "r+b").write(data)
elif action == "rewrite-through-hard-link":
    open("hard.npy", "ab").write(b"x")
elif action == "replace":                   # an input replaced by another file (rename over it)
    open("tmp", "wb").write(open("hf.exr", "rb").read()); os.replace("tmp", "hf.exr")
elif action == "half-written":
    open("out.exr", "wb").write(b"partial")
elif action == "accept":
    sys.exit(0)
elif action == "mute":
    sys.stderr.write("error\n"); sys.exit(2)
sys.stderr.write("error: --theta is bad\n")
sys.exit(2)
"""


def self_test():
    """The battery's verdicts on a fake binary that does each wrong thing once: every one must be caught
    (a battery that cannot see a lost input or a half-written file would pass anything)."""
    tmp = tempfile.mkdtemp(prefix="microsim_hostile_selftest_")
    fixtures, pristine = os.path.join(tmp, "fixtures"), os.path.join(tmp, "pristine")
    os.makedirs(fixtures)
    for name in ("good.npy", "hf.exr"):
        open(os.path.join(fixtures, name), "wb").write(os.urandom(4096))
    shutil.copytree(fixtures, pristine)
    fake = os.path.join(tmp, "fake.py")
    open(fake, "w").write(FAKE_BINARY)
    expected = {"rewrite-same-size": "file lost", "rewrite-through-hard-link": "file lost", "replace": "file lost",
                "half-written": "half-written", "accept": "accepted", "mute": "unclear", "clear": "clear error"}
    failures = 0
    for action, want in expected.items():
        case = {"name": action, "args": [action], "expect": "reject", "names": ["--theta"]}
        got = run_case([sys.executable, fake], case, fixtures, pristine, os.path.join(tmp, "work"), 30)[0]
        print("%-26s %-12s %s" % (action, got, "ok" if got == want else "WRONG (expected %s)" % want))
        failures += got != want
    shutil.rmtree(tmp, ignore_errors=True)
    return 1 if failures else 0


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--binary", default=os.path.join(ROOT, "build", "microsim"))
    ap.add_argument("--json", default=None, help="write every case and its outcome as JSON")
    ap.add_argument("--timeout", type=float, default=60.0)
    ap.add_argument("--only", default=None, help="run only the cases whose name contains this")
    ap.add_argument("--list", action="store_true", help="list the cases and exit")
    ap.add_argument("--self-test", action="store_true",
                    help="check the battery's verdicts on a fake binary that mistreats its inputs, and exit")
    ap.add_argument("--common-values-once", action="store_true",
                    help="try the values bad for any number on one flag per command only (the sanitizer gate)")
    a = ap.parse_args()
    if a.self_test:
        return self_test()
    cases = all_cases(a.common_values_once)
    if a.only:
        cases = [c for c in cases if a.only in c["name"]]
    if a.list:
        for c in cases:
            print(c["name"])
        print("%d cases" % len(cases))
        return 0
    binary = os.path.abspath(a.binary)
    tmp = tempfile.mkdtemp(prefix="microsim_hostile_")
    fixtures, pristine = os.path.join(tmp, "fixtures"), os.path.join(tmp, "pristine")
    make_fixtures(binary, fixtures)
    shutil.copytree(fixtures, pristine)
    results, tally = [], {}
    t0 = time.time()
    for i, c in enumerate(cases):
        outcome, err, proc, elapsed = run_case([binary], c, fixtures, pristine, os.path.join(tmp, "work"), a.timeout)
        tally[outcome] = tally.get(outcome, 0) + 1
        last = err.strip().splitlines()[-1] if err.strip() else ""
        results.append({"case": c["name"], "args": c["args"][:40] if len(" ".join(c["args"])) < 2000 else "(long)",
                        "expect": c["expect"], "outcome": outcome, "exit": None if proc is None else proc.returncode,
                        "seconds": round(elapsed, 3), "stderr_bytes": len(err), "message": last[:300]})
        good = outcome in ("clear error", "rejected", "ran")
        if not good:
            print("%-14s %s\n               %s" % (outcome, c["name"], last[:200]), file=sys.stderr)
        if (i + 1) % 50 == 0:
            print("hostile inputs: %d/%d (%.0f s)" % (i + 1, len(cases), time.time() - t0), file=sys.stderr)
    shutil.rmtree(tmp, ignore_errors=True)
    bad = [c for c in cases if c["expect"] == "reject"]
    failing = [c for c in cases if c["expect"] == "fail"]
    print("hostile-input battery: %d cases (%d bad inputs, %d sampler failures, %d valid edge values), %.0f s" % (
        len(cases), len(bad), len(failing), len(cases) - len(bad) - len(failing), time.time() - t0))
    print("| outcome | cases |\n|---|---|")
    for k in ["clear error", "rejected", "ran", "unclear", "accepted", "crash", "hang", "file lost", "half-written",
              "refused valid input"] + sorted(k for k in tally if k.startswith("unexpected")):
        print("| %s | %d |" % (k, tally.get(k, 0)))
    if a.json:
        with open(a.json + ".partial", "w") as fh:
            json.dump({"tally": tally, "cases": results}, fh, indent=1)
        os.replace(a.json + ".partial", a.json)
    ok = tally.get("clear error", 0) + tally.get("rejected", 0) + tally.get("ran", 0) == len(cases)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
