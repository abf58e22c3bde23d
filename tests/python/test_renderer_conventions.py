"""Renderers' BSDF dumps, written from the math the way each renderer convention writes them, through the command
line and Python alike: every correct dump passes, every bug is rejected by a test its correct twin passes, and
the two front ends give the same verdict.

A renderer samples wo from the direction wg it was given (the camera side on camera paths) and returns the pdf
and the weight f |cos wo| / pdf; the samples it loses (a reflection below the horizon, a refraction back up) it
drops (pbrt-v4's Sample_f returns no sample) or returns with weight 0 (Mitsuba 3's sample(): G1(wo, m) is 0 on
the wrong side). Conventions (src/microfacet/bsdf_convention.h):
- transport: radiance (camera paths; a refraction's f holds (n_g / n_s)^2, pbrt-v4 DielectricBxDF and Mitsuba 3
  roughdielectric in radiance mode) or importance (light paths: no such factor);
- masking: height-correlated G2 = 1 / (1 + Lambda_g + Lambda_o) (pbrt-v4) or separable G1(wg) G1(wo) (Mitsuba 3).
Walter et al. 2007 eq. 20-21 (f), eq. 14 and 17 (the half-vector Jacobians); Heitz 2018 (VNDF sampling,
conftest.heitz2018_numpy). Each case is one seed, 100000 samples, the verdict at the level 0.01."""
import numpy as np
import pytest

import microsim
from conftest import heitz2018_numpy, run_cli, view

N = 100_000
GOLD = (0.2, 3.9)  # a conductor's eta, k


# ---- GGX from the math (Heitz 2014 eq. 85-86; Walter 2007 eq. 33) ----------------------------------------------
def ggx_d(m, ax, ay):
    e = (m[:, 0] / ax) ** 2 + (m[:, 1] / ay) ** 2 + m[:, 2] ** 2
    return np.where(m[:, 2] > 0, 1 / (np.pi * ax * ay * e ** 2), 0.0)


def ggx_lambda(w, ax, ay):
    t2 = ((ax * w[..., 0]) ** 2 + (ay * w[..., 1]) ** 2) / w[..., 2] ** 2
    return (-1 + np.sqrt(1 + t2)) / 2


def fresnel_dielectric(c, eta):
    """Unpolarised Fresnel reflectance for cos c > 0 on the side of index 1, eta across (1 beyond TIR)."""
    s2 = (1 - c ** 2) / eta ** 2
    ct = np.sqrt(np.maximum(0.0, 1 - s2))
    rs = (c - eta * ct) / (c + eta * ct)
    rp = (eta * c - ct) / (eta * c + ct)
    return np.where(s2 >= 1, 1.0, (rs ** 2 + rp ** 2) / 2)


def fresnel_conductor(c, eta, k):
    n = complex(eta, k)
    ct = np.sqrt(1 - (1 - c ** 2) / n ** 2 + 0j)
    rs = (c - n * ct) / (c + n * ct)
    rp = (n * c - ct) / (n * c + ct)
    return (np.abs(rs) ** 2 + np.abs(rp) ** 2) / 2


# ---- a renderer's sample(): the conventions and the bugs ---------------------------------------------------------
def renderer_dump(kind, wg, alpha, transport="radiance", masking="height-correlated", bug=None, eta=1.5, seed=7,
                  lost="dropped", n=N, normals="vndf"):
    """Samples of a rough conductor (kind 'conductor', GOLD) or dielectric of index eta from wg (either side):
    (directions (K, 3), pdfs (K,), weights (K,), dropped); the lost samples are dropped (lost='dropped', as pbrt-v4)
    or kept with their pdf and weight 0 (lost='zero-weight', as Mitsuba 3). normals='ndf': the microfacet normals
    drawn from D(m) cos (Walter et al. 2007 eq. 35-36, isotropic alpha), a normal facing away from wg lost."""
    ax, ay = alpha
    u = np.random.default_rng(seed).random((n, 3))
    up = wg[2] > 0
    flip = np.array([1.0, 1.0, 1.0 if up else -1.0])
    g = wg * flip  # the given direction on the upper side; mirrored back at the end
    eta_r = eta if up else 1 / eta  # the index across over the index on wg's side
    if normals == "ndf":  # tan^2 theta_m = alpha^2 u / (1 - u), phi_m = 2 pi u'
        t2 = ax * ax * u[:, 0] / (1 - u[:, 0])
        cz = 1 / np.sqrt(1 + t2)
        sz = np.sqrt(np.maximum(0.0, 1 - cz * cz))
        ph = 2 * np.pi * u[:, 1]
        m = np.stack([sz * np.cos(ph), sz * np.sin(ph), cz], axis=1)
    else:
        m = heitz2018_numpy(g, alpha, u[:, :2])
    c = m @ g
    facing = c > 0
    c = np.where(facing, c, 1e-300)  # a normal facing away: lost below
    if kind == "conductor":
        F = fresnel_conductor(c, *GOLD)
        reflect = np.ones(n, bool)
    else:
        F = fresnel_dielectric(c, eta_r)
        reflect = u[:, 2] < F
    wr = 2 * c[:, None] * m - g
    ct = np.sqrt(np.maximum(0.0, 1 - (1 - c ** 2) / eta_r ** 2))
    wt = -g / eta_r + (c / eta_r - ct)[:, None] * m
    wo = np.where(reflect[:, None], wr, wt)
    kept = np.where(reflect, wo[:, 2] > 0, wo[:, 2] < 0) & facing
    if lost == "dropped":
        wo, m, c, F, reflect = wo[kept], m[kept], c[kept], F[kept], reflect[kept]
    om = np.einsum("ij,ij->i", wo, m)
    D = ggx_d(m, ax, ay)
    lg, lo = ggx_lambda(g, ax, ay), ggx_lambda(wo, ax, ay)
    g1g = 1 / (1 + lg)
    dv = D * m[:, 2] if normals == "ndf" else g1g * c * D / g[2]
    p_lobe = F if kind == "dielectric" else np.ones_like(F)
    denom = (c + eta_r * om) ** 2
    jac = np.where(reflect, 1 / (4 * np.abs(om)), eta_r ** 2 * np.abs(om) / denom)
    pdf = np.where(reflect, p_lobe, 1 - p_lobe) * dv * jac
    G = 1 / (1 + lg + lo) if masking == "height-correlated" else g1g / (1 + lo)
    if bug == "g1_for_g2":
        G = g1g * np.ones_like(lo)
    f_r = F * D * G / (4 * g[2] * np.abs(wo[:, 2]))
    f_t = (1 - F) * D * G * eta_r ** 2 * c * np.abs(om) / (g[2] * np.abs(wo[:, 2]) * denom)
    s = 1 / eta_r ** 2 if transport == "radiance" else 1.0  # radiance compression of a refraction
    f = np.where(reflect, f_r * (s if bug == "eta2_on_reflection" else 1.0),
                 f_t * (s * s if bug == "eta2_twice" else s))
    if bug == "pdf_and_f_eta2":  # f and pdf of a refraction both off by eta^2: the weight stays right
        f, pdf = np.where(reflect, f, f * eta_r ** 2), np.where(reflect, pdf, pdf * eta_r ** 2)
    weight = f * np.abs(wo[:, 2]) / pdf
    if lost == "zero-weight":
        return wo * flip, pdf, np.where(kept, weight, 0.0), 0
    return wo * flip, pdf, weight, n - int(kept.sum())


# ---- the cases: (name, dump arguments, claims, layout, passes) ---------------------------------------------------
# claims: what the user tells microsim (the bsdf and, where not the default, transport and masking).
GLASS = {"bsdf": "dielectric:1.5"}
CASES = [
    ("pbrt-v4 glass, radiance (camera paths)", dict(kind="dielectric", theta=50), GLASS, "c32", True),
    ("pbrt-v4 glass, importance (light paths)", dict(kind="dielectric", theta=50, transport="importance"),
     {**GLASS, "transport": "importance"}, "c64", True),
    ("pbrt-v4 glass, light from inside", dict(kind="dielectric", theta=130), GLASS, "c32", True),
    ("pbrt-v4 glass, anisotropic, y-up renderer frame", dict(kind="dielectric", theta=40, phi=30, alpha=(0.15, 0.5)),
     {**GLASS, "frame": "y-up"}, "text", True),
    ("Mitsuba 3 glass, separable masking", dict(kind="dielectric", theta=70, masking="separable", lost="zero-weight"),
     {**GLASS, "masking": "separable"}, "c64", True),
    ("Mitsuba 3 glass from inside", dict(kind="dielectric", theta=120, masking="separable", lost="zero-weight"),
     {**GLASS, "masking": "separable"}, "c32", True),
    ("Mitsuba 3 gold, separable masking, 80 deg", dict(kind="conductor", theta=80, masking="separable",
                                                        lost="zero-weight"),
     {"bsdf": "conductor:0.2,3.9", "masking": "separable"}, "c32", True),
    ("Mitsuba 3 glass, the dump filtering its rows of weight 0", dict(kind="dielectric", theta=70, masking="separable"),
     {**GLASS, "masking": "separable"}, "c64", True),
    ("pbrt-v4 gold, 80 deg", dict(kind="conductor", theta=80), {"bsdf": "conductor:0.2,3.9"}, "c32", True),
    ("pbrt-v4 gold, alpha 0.01, float32 values printed %.9g", dict(kind="conductor", theta=60, alpha=(0.01, 0.01)),
     {"bsdf": "conductor:0.2,3.9"}, "text-f32", True),
    ("glass without a pdf column", dict(kind="dielectric", theta=50), GLASS, "c32-nopdf", True),
    ("Mitsuba 3 gold, sample_visible=false (normals from D(m) cos)",
     dict(kind="conductor", theta=60, masking="separable", lost="zero-weight", normals="ndf"),
     {"bsdf": "conductor:0.2,3.9", "masking": "separable", "sampling": "ndf"}, "c32", True),
    ("pbrt-v4 gold, Fortran-order float32 .npy", dict(kind="conductor", theta=30), {"bsdf": "conductor:0.2,3.9"},
     "f32", True),
    # The other convention's correct dump, and real bugs wrong in both conventions.
    ("radiance glass claimed as importance", dict(kind="dielectric", theta=50), {**GLASS, "transport": "importance"},
     "c32", False),
    ("importance glass claimed as radiance", dict(kind="dielectric", theta=50, transport="importance"), GLASS, "c32",
     False),
    ("Mitsuba 3 gold claimed height-correlated", dict(kind="conductor", theta=80, masking="separable",
                                                       lost="zero-weight"),
     {"bsdf": "conductor:0.2,3.9"}, "c32", False),
    ("Mitsuba 3 glass, G1 for G2", dict(kind="dielectric", theta=60, masking="separable", bug="g1_for_g2",
                                        lost="zero-weight"), {**GLASS, "masking": "separable"}, "c32", False),
    ("glass, eta^2 factor applied twice", dict(kind="dielectric", theta=50, bug="eta2_twice"), GLASS, "c32", False),
    ("glass from inside, eta^2 factor twice", dict(kind="dielectric", theta=130, bug="eta2_twice"), GLASS, "c32",
     False),
    ("glass, eta^2 factor on reflection", dict(kind="dielectric", theta=50, bug="eta2_on_reflection"), GLASS, "c32",
     False),
    ("glass, G1 for G2", dict(kind="dielectric", theta=60, bug="g1_for_g2"), GLASS, "c32", False),
    ("gold, G1 for G2", dict(kind="conductor", theta=60, bug="g1_for_g2"), {"bsdf": "conductor:0.2,3.9"}, "c32",
     False),
    ("glass, f and pdf both off by eta^2", dict(kind="dielectric", theta=50, bug="pdf_and_f_eta2"), GLASS, "c32",
     False),
    ("gold sampling D(m) cos, claimed as VNDF sampling", dict(kind="conductor", theta=60, normals="ndf"),
     {"bsdf": "conductor:0.2,3.9"}, "c32", False),
]


def write_dump(path, layout, directions, pdfs, weights, frame):
    if frame == "y-up":  # a renderer whose normal is +y stores (x, z, -y) for microsim's (x, y, z)
        directions = np.stack([directions[:, 0], directions[:, 2], -directions[:, 1]], axis=1)
    cols = [directions, weights[:, None]] if layout.endswith("nopdf") else [directions, pdfs[:, None], weights[:, None]]
    rows = np.concatenate(cols, axis=1)
    if layout == "text":
        np.savetxt(path, rows, fmt="%.17g")
    elif layout == "text-f32":  # a float32 renderer printing every float's digits (ties included: 969.1953125)
        np.savetxt(path, rows.astype(np.float32).astype(np.float64), fmt="%.9g")
    elif layout == "f32":  # numpy writes Fortran order for a column-indexed or transposed array
        np.save(path, np.asfortranarray(rows.astype(np.float32)))
    else:
        np.save(path, rows.astype(np.float32 if layout.startswith("c32") else np.float64))
    return "x,y,z,weight" if layout.endswith("nopdf") else "x,y,z,pdf,weight"


@pytest.mark.parametrize("name,dump,claims,layout,passes", CASES, ids=[c[0] for c in CASES])
def test_renderer_dump_verdicts_agree_in_cli_and_python(tmp_path, name, dump, claims, layout, passes):
    theta, phi, alpha = dump.pop("theta"), dump.pop("phi", 0.0), dump.pop("alpha", (0.3, 0.3))
    kind = dump.pop("kind")
    zero_weight = dump.get("lost") == "zero-weight"
    directions, pdfs, weights, dropped = renderer_dump(kind, view(theta, phi), alpha, **dump)
    claims = dict(claims)
    frame = claims.pop("frame", None)
    path = tmp_path / ("dump.txt" if layout.startswith("text") else "dump.npy")
    columns = write_dump(path, layout, directions, pdfs, weights, frame)
    cli = ["validate", "--from", path, "--alpha", f"{alpha[0]},{alpha[1]}", "--theta", theta, "--phi", phi,
           "--columns", columns, "--rows", 11]
    cli += ["--lost-as-zero-weight"] if zero_weight else ["--above-horizon", "--dropped", dropped]
    for key, value in claims.items():
        cli += [f"--{key}", value]
    if frame:
        cli += ["--frame", frame]
    p = run_cli(*cli)
    assert p.returncode == (0 if passes else 1), f"{name}: exit {p.returncode}\n{p.stdout}\n{p.stderr}"
    loaded = np.loadtxt(path) if layout.startswith("text") else np.load(path)
    d = loaded[:, :3]
    lost = dict(lost_as_zero_weight=True) if zero_weight else dict(above_horizon=True, dropped=dropped)
    kwargs = dict(claims, rows=11, **lost, frame=frame or "z-up", weights=loaded[:, -1])
    if not layout.endswith("nopdf"):
        kwargs["pdfs"] = loaded[:, 3]
    r = microsim.validate(d, alpha, theta, phi, **kwargs)
    assert r.passed == passes, f"{name}: Python {r!r}"
    if layout.endswith("nopdf"):
        assert any("returned pdfs were not checked" in n for n in r.notes)
        assert "returned pdfs were not checked" in p.stdout
    if "bsdf" in claims and claims["bsdf"].startswith("dielectric"):
        mode = claims.get("transport", "radiance")
        assert f"{mode} transport" in p.stdout
        assert any(f"{mode} transport" in n for n in r.notes)


def test_the_pdf_bug_is_caught_only_with_the_pdf_column(tmp_path):
    """f and pdf off by the same factor leave the weights right: only the returned pdf shows it, and a dump without
    the pdf column passes, with the report saying the pdfs were not checked."""
    directions, pdfs, weights, dropped = renderer_dump("dielectric", view(50), (0.3, 0.3), bug="pdf_and_f_eta2")
    common = dict(bsdf="dielectric:1.5", rows=11, above_horizon=True, dropped=dropped, weights=weights)
    with_pdf = microsim.validate(directions, 0.3, 50, pdfs=pdfs, **common)
    assert not with_pdf.passed and with_pdf.to_dict()["tests"]["returned_pdf"]["passed"] is False
    without = microsim.validate(directions, 0.3, 50, **common)
    assert without.passed and any("returned pdfs were not checked" in n for n in without.notes)


def test_a_dump_that_drops_its_lost_samples_gets_the_hint(tmp_path):
    """Without above_horizon the lost samples' share is missing: rejected, with the hint naming the fix."""
    directions, pdfs, weights, _ = renderer_dump("dielectric", view(50), (0.3, 0.3))
    r = microsim.validate(directions, 0.3, 50, pdfs=pdfs, weights=weights, bsdf="dielectric:1.5", rows=11)
    assert not r.passed
    assert any("above_horizon=True" in h for h in r.hints), r.hints


def test_a_dump_that_keeps_its_lost_samples_with_weight_0_gets_the_hint(tmp_path):
    """Mitsuba 3 returns a lost sample with weight 0: without lost_as_zero_weight such a dump is rejected (its rows
    fall where the claimed pdf is zero), with the hint naming the fix; the same dump passes with it, in the command
    line too, whose report says how many rows were counted as lost."""
    directions, pdfs, weights, _ = renderer_dump("dielectric", view(70), (0.3, 0.3), masking="separable",
                                                 lost="zero-weight")
    common = dict(pdfs=pdfs, weights=weights, bsdf="dielectric:1.5", masking="separable", rows=11)
    r = microsim.validate(directions, 0.3, 70, **common)
    assert not r.passed
    assert any("lost_as_zero_weight=True" in h for h in r.hints), r.hints
    assert microsim.validate(directions, 0.3, 70, lost_as_zero_weight=True, **common).passed
    path = tmp_path / "mitsuba.npy"
    np.save(path, np.column_stack([directions, pdfs, weights]))
    p = run_cli("validate", "--from", path, "--alpha", 0.3, "--theta", 70, "--columns", "x,y,z,pdf,weight", "--bsdf",
                "dielectric:1.5", "--masking", "separable", "--rows", 11, "--lost-as-zero-weight")
    assert p.returncode == 0, p.stdout + p.stderr
    lost = int((weights == 0).sum())
    assert f"rows of weight 0 counted as the sampler's lost samples: {lost} of {N}" in p.stdout
    # The same through `microsim run` (lost_as_zero_weight = true in the spec), and without the key: rejected.
    for lost_key, code in (("lost_as_zero_weight = true\n", 0), ("", 1)):
        (tmp_path / "spec.toml").write_text(
            '[[material]]\nname = "glass"\nalpha = 0.3\ntype = "dielectric"\neta = 1.5\n'
            '[[quantity]]\nkind = "validation"\nmaterial = "glass"\ndump = "mitsuba.npy"\npdf = "bsdf"\n'
            'columns = "x,y,z,pdf,weight"\nmasking = "separable"\ntheta = [70]\nrows = 11\n' + lost_key)
        out = tmp_path / f"run{code}"
        p = run_cli("run", tmp_path / "spec.toml", "--out", out, check=False)
        assert p.returncode == code, p.stdout + p.stderr


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_grazing_glass_from_inside_with_its_lost_samples_kept_passes(seed):
    """Mitsuba 3 glass seen from inside near the normal (170 deg, alpha 1): about half its samples are lost and kept
    with weight 0, many in bins beyond the refraction cone where the flux is 0. Those bins' mean weight is 0, the
    likeliest outcome: at the default rows and 2e5 samples the dump passes at every seed (the flux-per-bin test once
    rejected it at all of them). The same dump with the radiance factor twice is rejected."""
    common = dict(bsdf="dielectric:1.5", masking="separable", lost_as_zero_weight=True)
    d, pdfs, weights, _ = renderer_dump("dielectric", view(170), (1.0, 1.0), masking="separable", lost="zero-weight",
                                        seed=seed, n=200_000)
    r = microsim.validate(d.astype(np.float32), 1.0, 170, pdfs=pdfs.astype(np.float32),
                          weights=weights.astype(np.float32), **common)
    assert r.passed, r
    if seed == 1:
        d, pdfs, weights, _ = renderer_dump("dielectric", view(170), (1.0, 1.0), masking="separable",
                                            lost="zero-weight", seed=seed, n=200_000, bug="eta2_twice")
        assert not microsim.validate(d, 1.0, 170, pdfs=pdfs, weights=weights, **common).passed


def test_light_from_inside_at_normal_incidence_is_a_view(tmp_path):
    """theta 180 (light from inside along the normal) is accepted as every other view from inside, by the command line
    and Python alike, and the correct dump passes."""
    d, pdfs, weights, _ = renderer_dump("dielectric", view(180), (1.0, 1.0), masking="separable", lost="zero-weight",
                                        seed=5, n=100_000)
    path = tmp_path / "inside.npy"
    np.save(path, np.column_stack([d, pdfs, weights]).astype(np.float32))
    p = run_cli("validate", "--from", path, "--alpha", 1, "--theta", 180, "--columns", "x,y,z,pdf,weight", "--bsdf",
                "dielectric:1.5", "--masking", "separable", "--lost-as-zero-weight")
    assert p.returncode == 0, p.stdout + p.stderr
    assert microsim.validate(str(path), 1.0, 180, columns="x,y,z,pdf,weight", bsdf="dielectric:1.5",
                             masking="separable", lost_as_zero_weight=True).passed


def test_a_glass_dump_in_the_wrong_frame_gets_the_frame_hint(tmp_path):
    """A dielectric's density covers the whole sphere, so a glass dump written with z flipped puts few samples where
    it is zero: the frame is still named, as the reading in which the dump passes; the correct dump gets no such
    hint."""
    d, pdfs, weights, dropped = renderer_dump("dielectric", view(50), (0.3, 0.3), seed=3)
    claims = dict(pdfs=pdfs, weights=weights, bsdf="dielectric:1.5", above_horizon=True, dropped=dropped)
    flipped = microsim.validate(d * np.array([1.0, 1.0, -1.0]), 0.3, 50, **claims)
    assert not flipped.passed
    assert any("read with z flipped" in h and "they pass" in h for h in flipped.hints), flipped.hints
    right = microsim.validate(d, 0.3, 50, **claims)
    assert right.passed and not any("frame" in h for h in right.hints), right.hints


def test_a_glass_sampling_its_normals_from_the_ndf(tmp_path):
    """A rough glass whose sample() draws m from D(m) cos (Walter et al. 2007; pbrt-v3-style, its lost samples
    dropped): its directions and pdfs pass with sampling='ndf' and are rejected claimed as VNDF sampling; its weights
    (heavy-tailed near the horizon) are refused, not tested, by the command line (exit 2) and Python alike."""
    d, pdfs, weights, dropped = renderer_dump("dielectric", view(50), (0.3, 0.3), seed=11, normals="ndf")
    path = tmp_path / "glass.npy"
    np.save(path, np.column_stack([d, pdfs, weights]).astype(np.float32))
    common = ["validate", "--from", path, "--alpha", 0.3, "--theta", 50, "--bsdf", "dielectric:1.5", "--above-horizon",
              "--dropped", dropped]
    p = run_cli(*common, "--columns", "x,y,z,pdf,-", "--sampling", "ndf")
    assert p.returncode == 0, p.stdout + p.stderr
    assert run_cli(*common, "--columns", "x,y,z,pdf,-").returncode == 1  # claimed as VNDF sampling
    p = run_cli(*common, "--columns", "x,y,z,pdf,weight", "--sampling", "ndf", check=False)
    assert p.returncode == 2 and "--sampling ndf with --columns x,y,z,pdf,weight: a dielectric sampling" in p.stderr, p.stderr
    kwargs = dict(pdfs=pdfs, bsdf="dielectric:1.5", above_horizon=True, dropped=dropped)
    assert microsim.validate(d, 0.3, 50, sampling="ndf", **kwargs).passed
    assert not microsim.validate(d, 0.3, 50, **kwargs).passed
    with pytest.raises(ValueError, match="heavy-tailed"):
        microsim.validate(d, 0.3, 50, sampling="ndf", weights=weights, **kwargs)
    # The same through `microsim run`: its directions pass with sampling = "ndf", fail without; its weights are refused.
    for key, columns, code in (('sampling = "ndf"\n', "x,y,z,pdf,-", 0), ("", "x,y,z,pdf,-", 1),
                               ('sampling = "ndf"\n', "x,y,z,pdf,weight", 2)):
        (tmp_path / "spec.toml").write_text(
            '[[material]]\nname = "glass"\nalpha = 0.3\ntype = "dielectric"\neta = 1.5\n'
            '[[quantity]]\nkind = "validation"\nmaterial = "glass"\ndump = "glass.npy"\npdf = "bsdf"\n'
            f'columns = "{columns}"\ntheta = [50]\nrows = 11\nabove_horizon = true\ndropped = {dropped}\n' + key)
        p = run_cli("run", tmp_path / "spec.toml", "--out", tmp_path / f"run{code}", check=False)
        assert p.returncode == code, p.stdout + p.stderr
