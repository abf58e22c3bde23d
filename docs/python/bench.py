"""Speed of microsim.validate against the command line on the same 1e6 samples (docs/records/python-speed.md).
Alternating runs: `microsim validate --from s.npy` (the whole process) and microsim.validate(np.load(s.npy))
(the call and the load) in this process; the reports' tests must be identical.
  PYTHONPATH=build/python /usr/bin/python3 docs/python/bench.py build/microsim [RUNS]"""
import json
import pathlib
import subprocess
import sys
import tempfile
import time

import numpy as np

import microsim

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from example import heitz2018  # noqa: E402  (the worked example's sampler; running it prints the example)


def main(cli, runs):
    folder = pathlib.Path(tempfile.mkdtemp())
    wi = np.array([np.sin(np.radians(60)), 0, np.cos(np.radians(60))])
    samples = folder / "s.npy"
    np.save(samples, heitz2018(wi, (0.3, 0.3), np.random.default_rng(2026).random((1_000_000, 2))))
    cli_t, py_t, cli_lib, py_lib = [], [], [], []
    for _ in range(runs):
        t0 = time.perf_counter()
        subprocess.run([cli, "validate", "--from", samples, "--alpha", "0.3", "--theta", "60", "--json",
                        folder / "cli.json"], check=True, capture_output=True)
        cli_t.append(time.perf_counter() - t0)
        cli_lib.append(json.loads((folder / "cli.json").read_text())["seconds"])
        t0 = time.perf_counter()
        r = microsim.validate(np.load(samples), 0.3, 60.0)
        py_t.append(time.perf_counter() - t0)
        py_lib.append(r.seconds)
    assert r.to_dict()["tests"] == json.loads((folder / "cli.json").read_text())["tests"]
    print("cli    ", " ".join(f"{t:.3f}" for t in cli_t))
    print("python ", " ".join(f"{t:.3f}" for t in py_t))
    print(f"median: cli {np.median(cli_t):.3f} s, python {np.median(py_t):.3f} s, "
          f"python / cli {np.median(py_t) / np.median(cli_t):.3f}")
    print(f"the validation alone (the report's seconds): cli {np.median(cli_lib):.3f} s, "
          f"python {np.median(py_lib):.3f} s, python / cli {np.median(py_lib) / np.median(cli_lib):.3f}")


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 7)
