"""The worked example of docs/guide/python.md: a sampler written in numpy validated, a broken variant rejected,
and the traced VNDF against D_v. Run: PYTHONPATH=build/python /usr/bin/python3 docs/python/example.py"""
import numpy as np

import microsim


def heitz2018(wi, alpha, u, warp=True):
    """Heitz 2018, JCGT 7(4), sec. 4: the visible normals of GGX for view wi, one per row of u (N, 2)."""
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
    alpha, theta = (0.3, 0.3), 60.0
    wi = np.array([np.sin(np.radians(theta)), 0, np.cos(np.radians(theta))])
    u = np.random.default_rng(1).random((1_000_000, 2))

    good = microsim.validate(heitz2018(wi, alpha, u), alpha, theta)
    print(good)
    print({k: round(v, 4) for k, v in good.p_values.items()})

    broken = microsim.validate(heitz2018(wi, alpha, u, warp=False), alpha, theta)
    print(broken)
    print(broken.worst_cells[0])

    # The exact oracle: trace the GGX ellipsoid, histogram the visible normals, compare with D_v.
    h = microsim.trace_vndf(alpha, theta, rays=10_000_000, seed=1)
    lobe = h["binnings"]["lobe"]
    density = lobe["counts"] / (h["hits"] * lobe["solid_angle"])   # traced D_v per unit solid angle
    d_v = microsim.D_v(wi, lobe["centres"].reshape(-1, 3), alpha).reshape(density.shape)
    expected = h["hits"] * lobe["expected_probability"]              # the analytic bin integrals of D_v
    seen = expected > 0                                                # bins the view can see
    print(f"{h['hits']} hits; Pearson chi-square per visible lobe bin: "
          f"{np.sum((lobe['counts'] - expected)[seen] ** 2 / expected[seen]) / seen.sum():.3f} ({seen.sum()} bins)")

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cols = [0, lobe["counts"].shape[1] // 2]   # the plane of incidence: the columns at phi = 0 and 180 degrees
    theta_m = np.degrees(np.arccos(lobe["centres"][..., 2]))
    fig, ax = plt.subplots(figsize=(6, 4))
    for c, sign in zip(cols, (1, -1)):
        ax.plot(sign * theta_m[:, c], density[:, c], "o", ms=3, label=f"traced, column {c}")
        ax.plot(sign * theta_m[:, c], d_v[:, c], "-", lw=1, label=f"D_v, column {c}")
    ax.set_xlabel("signed angle of the bin centre from the normal (degrees)")
    ax.set_ylabel("visible normals per steradian")
    ax.set_title(f"GGX alpha {alpha[0]}, view {theta} deg: traced ellipsoid vs D_v")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig("vndf.png", dpi=110)
    print("wrote vndf.png")


if __name__ == "__main__":
    main()
