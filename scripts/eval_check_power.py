"""The power of `microsim check-eval`: the correct float32 and float64 pbrt-v4-style glass of examples/renderer_eval.py
at the pairs of `microsim bsdf-queries --bsdf dielectric:1.5 --alpha 0.3`, its values or its pdfs scaled by 1 + d:
the smallest d rejected. Run from the repository: /usr/bin/python3 scripts/eval_check_power.py [BUILD]."""
import json
import pathlib
import subprocess
import sys
import tempfile

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "examples"))
from renderer_eval import renderer_eval  # noqa: E402

M = str(pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else ROOT / "build") / "microsim")
tmp = pathlib.Path(tempfile.mkdtemp())
subprocess.run([M, "bsdf-queries", "--bsdf", "dielectric:1.5", "--alpha", "0.3", "--out", tmp / "q.npy"], check=True,
               capture_output=True)
q = np.load(tmp / "q.npy")
print("| arithmetic | scaled | d | exit | numbers outside their tolerance |")
print("|---|---|---|---|---|")
for arith, dtype in (("float32", np.float32), ("float64", np.float64)):
    v, p = renderer_eval(q, "dielectric", dtype=dtype)
    for d in (0, 1e-12, 1e-11, 1e-5, 1e-4, 3e-4, 1e-3, 3e-3):
        for what in ("value", "pdf"):
            vv, pp = (v * (1 + d), p) if what == "value" else (v, p * (1 + d))
            np.save(tmp / "e.npy", np.column_stack([q, vv, pp]).astype(dtype))
            r = subprocess.run([M, "check-eval", tmp / "e.npy", "--alpha", "0.3", "--bsdf", "dielectric:1.5", "--columns",
                                "wi,wo,value,pdf", "--arithmetic", arith, "--json", tmp / "e.json"], capture_output=True)
            j = json.loads((tmp / "e.json").read_text())
            bad = j["value_failures"] if what == "value" else j["pdf_failures"]
            print(f"| {arith} | {what} | {d:g} | {r.returncode} | {bad} of {j['values_checked']} |")
for f in tmp.iterdir():
    f.unlink()
tmp.rmdir()
