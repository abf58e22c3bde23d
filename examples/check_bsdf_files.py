"""A renderer's BSDF checked against itself from Python: microsim.check_bsdf_files, what `microsim check-bsdf-files`
runs, on arrays. The dump is examples/renderer_dump.py's (x y z pdf weight of a rough gold conductor, one view); the
eval file at its rows is the renderer's eval() and pdf() of examples/renderer_eval.py at each (wi, wo), written here
as the rows wi wo value pdf. Each weight must be eval / pdf and each pdf the eval's (1e-3 relative); the white
furnace is reported (the mean weight with its error). Exit 0 when every test passed, 1 when one rejected.
`--save-eval E.npy` also writes the eval rows, for `microsim check-bsdf-files gold.npy E.npy --theta 60`.
Run: PYTHONPATH=build/python python3 examples/check_bsdf_files.py gold.npy --theta 60 [--save-eval E.npy]"""
import argparse
import sys

import numpy as np

import microsim
from renderer_eval import renderer_eval


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("dump")
    p.add_argument("--theta", type=float, default=60.0)
    p.add_argument("--save-eval", help="write the eval rows (wi wo value pdf, float32 .npy) here")
    a = p.parse_args()
    dump = np.load(a.dump)                                     # x y z pdf weight, a row per kept sample
    t = np.radians(a.theta)
    wi = np.tile([np.sin(t), 0.0, np.cos(t)], (len(dump), 1))  # the view, on every row
    value, pdf = renderer_eval(np.column_stack([wi, dump[:, :3]]), "conductor")  # f |cos wo| and pdf at (wi, wo)
    evals = np.column_stack([wi, dump[:, :3], value, pdf]).astype(np.float32)
    if a.save_eval:
        np.save(a.save_eval, evals)
    r = microsim.check_bsdf_files(dump, evals, theta=a.theta)  # paths work too, as the command line takes them
    for test in r["tests"]:
        print(f'{test["test"]:<12} {"pass" if test["passed"] else "REJECTED":<9} {test["detail"]}')
    print(r["verdict"])
    return 0 if r["passed"] else 1


if __name__ == "__main__":
    sys.exit(main())
