"""A renderer's BSDF dump, as pbrt-v4's rough conductor writes it on camera paths: for the view wi, each row is
the sampled direction wo, the pdf returned with it and the weight f |cos wo| / pdf (one channel), for a gold-like
conductor (eta 0.2, k 3.9) sampled by GGX visible normals (Heitz 2018) with the height-correlated masking G2.
Reflections below the horizon are dropped, as renderers drop them; their number is printed (--dropped N).
`--bug no-g1-wo` leaves G1(wo) out of the weight, a bug the weight test rejects.
Run: python3 examples/renderer_dump.py gold.npy [--alpha 0.3] [--theta 60] [--samples 200000] [--bug no-g1-wo]
References: Walter et al. 2007 eq. 14 (the reflection's Jacobian), 20 (f); Heitz 2014 eq. 86 (Lambda), 99 (G2)."""
import argparse

import numpy as np

from numpy_sampler import heitz2018

ETA, K = 0.2, 3.9


def fresnel_conductor(c):
    n = complex(ETA, K)
    ct = np.sqrt(1 - (1 - c ** 2) / n ** 2 + 0j)
    rs, rp = (c - n * ct) / (c + n * ct), (n * c - ct) / (n * c + ct)
    return (np.abs(rs) ** 2 + np.abs(rp) ** 2) / 2


def ggx_lambda(w, a):
    return (-1 + np.sqrt(1 + a * a * (w[..., 0] ** 2 + w[..., 1] ** 2) / w[..., 2] ** 2)) / 2


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("out")
    p.add_argument("--alpha", type=float, default=0.3)
    p.add_argument("--theta", type=float, default=60.0)
    p.add_argument("--samples", type=int, default=200_000)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--bug", choices=["no-g1-wo"])
    a = p.parse_args()
    t = np.radians(a.theta)
    wi = np.array([np.sin(t), 0.0, np.cos(t)])
    m = heitz2018(wi, (a.alpha, a.alpha), np.random.default_rng(a.seed).random((a.samples, 2)))
    c = m @ wi
    wo = 2 * c[:, None] * m - wi                              # the mirror reflection about m
    kept = wo[:, 2] > 0
    wo, m, c = wo[kept], m[kept], c[kept]
    g1_wi = 1 / (1 + ggx_lambda(wi, a.alpha))
    e = (m[:, 0] ** 2 + m[:, 1] ** 2) / a.alpha ** 2 + m[:, 2] ** 2
    d = 1 / (np.pi * a.alpha ** 2 * e ** 2)                  # GGX D(m)
    pdf = g1_wi * c * d / wi[2] / (4 * c)                     # D_v(wi, m) / (4 <wi, m>)
    g2 = 1 / (1 + ggx_lambda(wi, a.alpha) + ggx_lambda(wo, a.alpha))
    weight = fresnel_conductor(c) * (g1_wi if a.bug == "no-g1-wo" else g2) / g1_wi
    np.save(a.out, np.column_stack([wo, pdf, weight]).astype(np.float32))
    print(f"wrote {kept.sum()} samples to {a.out}; dropped below the horizon: {a.samples - kept.sum()}")


if __name__ == "__main__":
    main()
