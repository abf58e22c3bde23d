"""Your sampler, written in numpy: GGX visible normals by Heitz 2018 (JCGT 7(4), sec. 4), saved as an (N, 3)
.npy that `microsim validate --from` tests, or (`--validate`) validated at once by the Python module.
`--no-warp` leaves out the disk's warp (a bug the test rejects).
Run: python3 examples/numpy_sampler.py normals.npy [--alpha 0.3] [--theta 60] [--samples 200000] [--no-warp]
     PYTHONPATH=build/python python3 examples/numpy_sampler.py --validate [--no-warp]   (exit 0 pass, 1 rejected)"""
import argparse
import sys

import numpy as np


def heitz2018(wi, alpha, u, warp=True):
    """The visible normals of GGX for the view wi, one per row of u (N, 2); alpha = (ax, ay)."""
    ax, ay = alpha
    vh = np.array([ax * wi[0], ay * wi[1], wi[2]])
    vh /= np.linalg.norm(vh)                                  # the view in the hemisphere configuration
    lensq = vh[0] ** 2 + vh[1] ** 2
    t1 = np.array([-vh[1], vh[0], 0]) / np.sqrt(lensq) if lensq > 0 else np.array([1.0, 0, 0])
    t2 = np.cross(vh, t1)
    r, phi = np.sqrt(u[:, 0]), 2 * np.pi * u[:, 1]            # a uniform point of the unit disk
    p1, p2 = r * np.cos(phi), r * np.sin(phi)
    if warp:                                                  # squeeze it onto the visible projected area
        s = 0.5 * (1 + vh[2])
        p2 = (1 - s) * np.sqrt(1 - p1 ** 2) + s * p2
    p3 = np.sqrt(np.maximum(0, 1 - p1 ** 2 - p2 ** 2))
    nh = p1[:, None] * t1 + p2[:, None] * t2 + p3[:, None] * vh
    m = np.stack([ax * nh[:, 0], ay * nh[:, 1], np.maximum(0, nh[:, 2])], axis=1)  # back to the surface
    return m / np.linalg.norm(m, axis=1, keepdims=True)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("out", nargs="?", help="the .npy to write (optional with --validate)")
    p.add_argument("--validate", action="store_true", help="validate the samples with `import microsim`")
    p.add_argument("--alpha", type=float, default=0.3)
    p.add_argument("--theta", type=float, default=60.0, help="the view's angle from the normal, degrees")
    p.add_argument("--samples", type=int, default=200_000)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--no-warp", action="store_true", help="leave out the warp of the disk (a bug)")
    a = p.parse_args()
    t = np.radians(a.theta)
    wi = np.array([np.sin(t), 0.0, np.cos(t)])
    u = np.random.default_rng(a.seed).random((a.samples, 2))
    normals = heitz2018(wi, (a.alpha, a.alpha), u, warp=not a.no_warp)
    if a.out:
        np.save(a.out, normals)
        print(f"wrote {a.samples} normals to {a.out}")
    if a.validate:
        import microsim
        result = microsim.validate(normals, (a.alpha, a.alpha), a.theta)
        print(result)
        return 0 if result else 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
