"""How much GGX's D loses when a renderer computes it from cos theta_m (docs/records/validation.md): the forms of
examples/renderer_eval.py (pbrt-v4's, Karis 2013's) in float32 and float64 against D in double at the same rounded
half vectors, over 2e5 normals drawn from the slope distribution (Student-t, nu = 2) and reflected from one view;
each error also as a multiple of eps / 2 / (alpha^2 cos^2 + sin^2), the bound check-eval allows 32 times.
Run: /usr/bin/python3 scripts/ndf_cancellation.py"""
import pathlib
import sys

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "examples"))
from renderer_eval import ggx_d  # noqa: E402


def half_vectors(alpha, n, rng, dtype):
    s = rng.standard_t(2, (n, 2)) * alpha / np.sqrt(2)
    m = np.column_stack([-s, np.ones(n)])
    m /= np.linalg.norm(m, axis=1)[:, None]
    wi = np.array([0.5, 0.2, 0.8]) / np.linalg.norm([0.5, 0.2, 0.8])
    wo = 2 * (m @ wi)[:, None] * m - wi
    wi_r, wo_r = np.tile(wi, (n, 1)).astype(dtype), wo.astype(dtype)
    h = wi_r + wo_r
    h64 = wi_r.astype(np.float64) + wo_r.astype(np.float64)
    return h / np.linalg.norm(h, axis=1)[:, None], h64 / np.linalg.norm(h64, axis=1)[:, None]


def main():
    rng = np.random.default_rng(1)
    print("| arithmetic | alpha | form | median relative error | worst | worst / (eps/2 / (alpha^2 cos^2 + sin^2)) |")
    print("|---|---|---|---|---|---|")
    for dtype in (np.float32, np.float64):
        for alpha in (1e-3, 1e-2, 0.1):
            h, h64 = half_vectors(alpha, 200_000, rng, dtype)
            keep = (h64[:, 2] > 0) & (h[:, 2] > 0)  # half vectors below the surface: D is 0 both ways
            h, h64 = h[keep], h64[keep]
            exact = ggx_d(h64, alpha)
            bound = np.finfo(dtype).eps / 2 / (alpha ** 2 * h64[:, 2] ** 2 + h64[:, 0] ** 2 + h64[:, 1] ** 2)
            for form in ("pbrt", "ue4"):
                with np.errstate(all="ignore"):
                    rel = np.abs(ggx_d(h, dtype(alpha), form) / exact - 1)
                print(f"| {dtype.__name__} | {alpha:g} | {form} | {np.median(rel):.2g} | {rel.max():.2g} | {(rel / bound).max():.3g} |")


if __name__ == "__main__":
    main()
