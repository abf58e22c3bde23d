"""microsim.check_bsdf on a BSDF given as numpy callables: the pbrt-v4-style rough glass of examples/renderer_eval.py
(eval and pdf) with its sampler (Heitz 2018 visible normals, reflection with probability F, else refraction; weight
= eval / pdf) passes the whole battery, as `check-bsdf` passes the C plugin; the same BSDF whose eval() applies the
radiance factor twice is rejected by the eval and consistency tests while its samples pass; the verdict is the
command line's (the same report keys)."""
import pathlib
import sys

import numpy as np
import pytest

import microsim
from conftest import heitz2018_numpy

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "examples"))
from renderer_eval import ALPHA, ETA, renderer_eval  # noqa: E402


def glass(eval_bug=None):
    def evaluate(wi, wo):
        return renderer_eval(np.column_stack([wi, wo]), "dielectric", dtype=np.float64, bug=eval_bug)[0]

    def pdf(wi, wo):
        return renderer_eval(np.column_stack([wi, wo]), "dielectric", dtype=np.float64)[1]

    def sample(wi, u):
        g = wi[0]
        side = 1.0 if g[2] > 0 else -1.0
        flip = np.array([1.0, 1.0, side])
        up = g * flip
        eta = ETA if side > 0 else 1 / ETA
        m = heitz2018_numpy(up, (ALPHA, ALPHA), u[:, :2])
        c = m @ up
        s2 = (1 - c ** 2) / eta ** 2
        ct = np.sqrt(np.maximum(0, 1 - s2))
        rs, rp = (c - eta * ct) / (c + eta * ct), (eta * c - ct) / (eta * c + ct)
        F = np.where(s2 >= 1, 1.0, (rs ** 2 + rp ** 2) / 2)
        reflect = u[:, 2] < F
        wr = 2 * c[:, None] * m - up
        wt = -up / eta + (c / eta - ct)[:, None] * m
        wo = np.where(reflect[:, None], wr, wt)
        wo = wo / np.linalg.norm(wo, axis=1, keepdims=True)
        kept = np.where(reflect, wo[:, 2] > 0, wo[:, 2] < 0)
        wo = wo * flip
        value, p = renderer_eval(np.column_stack([wi, wo]), "dielectric", dtype=np.float64)
        p = np.where(kept, p, 0.0)
        weight = np.where(p > 0, value / np.where(p > 0, p, 1), 0.0)
        return wo, p, weight

    return sample, evaluate, pdf


def run(eval_bug=None):
    sample, evaluate, pdf = glass(eval_bug)
    return microsim.check_bsdf(sample, evaluate, pdf, bsdf=f"dielectric:{ETA}", alpha=ALPHA, samples=50_000,
                               arithmetic="float64")


def test_a_correct_numpy_glass_passes_the_battery():
    r = run()
    assert r["passed"] and r["verdict"] == "pass", [t for t in r["tests"] if not t["passed"]]
    views = {t["view"] for t in r["tests"] if t["test"] == "sampling"}
    assert views == {"0 deg", "30 deg", "60 deg", "80 deg", "89.9 deg", "120 deg", "150 deg"}


def test_an_eval_bug_is_rejected_by_eval_and_consistency():
    r = run(eval_bug="eta2_twice")
    assert not r["passed"] and r["verdict"] == "fail"
    failed = {(t["test"], t["view"]) for t in r["tests"] if not t["passed"]}
    assert ("eval", "bsdf-queries") in failed
    assert ("consistency", "60 deg") in failed
    assert all(t["passed"] for t in r["tests"] if t["test"] == "sampling")


def test_bad_arguments_raise():
    sample, evaluate, pdf = glass()
    with pytest.raises(ValueError):
        microsim.check_bsdf(sample, evaluate, pdf, bsdf="dielectric:1.5", alpha=0.3, transport="flux")
    with pytest.raises(ValueError):
        microsim.check_bsdf(sample, evaluate, lambda wi, wo: np.zeros(3), bsdf="dielectric:1.5", alpha=0.3, samples=1000)


def test_the_command_line_options_views_reference_and_html(tmp_path):
    """check-bsdf's options from Python: views (THETA or (THETA, PHI)), reference 'none' (only the tests against
    itself: no sampling or eval line), an HTML report; the planted eval bug is still rejected by consistency."""
    sample, evaluate, pdf = glass()
    page = tmp_path / "r.html"
    r = microsim.check_bsdf(sample, evaluate, pdf, bsdf=f"dielectric:{ETA}", alpha=ALPHA, samples=20_000,
                            arithmetic="float64", views=[60, (120, 30)], reference="none", html=page)
    assert r["passed"], [t for t in r["tests"] if not t["passed"]]
    assert {t["view"] for t in r["tests"]} == {"60 deg", "120 deg phi 30", "bsdf-queries"}
    assert not {"sampling", "eval"} & {t["test"] for t in r["tests"]}
    assert (r["bsdf"], r["level"]) == (f"dielectric:{ETA}", 0.01)
    assert page.read_text().startswith("<!DOCTYPE html>")
    sample, evaluate, pdf = glass(eval_bug="eta2_twice")
    r = microsim.check_bsdf(sample, evaluate, pdf, bsdf=f"dielectric:{ETA}", alpha=ALPHA, samples=20_000,
                            arithmetic="float64", views=[60], reference="none")
    assert not r["passed"]
    assert ("consistency", "60 deg") in {(t["test"], t["view"]) for t in r["tests"] if not t["passed"]}


def test_a_stochastic_eval_is_averaged_when_declared():
    """An eval() that returns 4/3 of the value with probability 3/4, else 0 (unbiased, noisy), and no pdf: passes
    with stochastic_eval=True (reciprocity by a chi-square over repeated calls, the cell integrals with its noise);
    the same eval not declared stochastic is held to reciprocity pointwise and rejected. Without a pdf, the exact
    reference is refused."""
    sample, evaluate, _ = glass()
    rng = np.random.default_rng(5)

    def noisy(wi, wo):
        return evaluate(wi, wo) * (4 / 3) * (rng.random(len(wi)) < 0.75)

    kwargs = dict(bsdf=f"dielectric:{ETA}", alpha=ALPHA, samples=20_000, arithmetic="float64", views=[30],
                  reference="none")
    r = microsim.check_bsdf(sample, noisy, None, stochastic_eval=True, **kwargs)
    assert r["passed"], [t for t in r["tests"] if not t["passed"]]
    assert {t["test"] for t in r["tests"]} == {"integral", "furnace", "reciprocity"}
    r = microsim.check_bsdf(sample, noisy, None, **kwargs)
    assert not r["passed"]
    assert [t["test"] for t in r["tests"] if not t["passed"]] == ["reciprocity"]
    with pytest.raises(ValueError):
        microsim.check_bsdf(sample, noisy, None, stochastic_eval=True, bsdf=f"dielectric:{ETA}", alpha=ALPHA)


def smith_walk_mirror(alpha, eval_orders=100, paths=4):
    """A Smith multiple-scattering GGX mirror in numpy, by the stochastic evaluation of Heitz et al. 2016 (the math of
    examples/plugins/smith_walk.c): heights uniform on [-1, 1], C1(h) = (h + 1) / 2; going up a ray leaves with
    probability C1(h)^Lambda(d) (eq. 8), else meets the surface where (C1(h) / C1(h'))^Lambda = 1 - U; going down it
    meets it at C1(h') = C1(h) (1 - U)^(1 / (1 + Lambda(-d))) (eq. 9); the facet from the visible normals of -d (the
    spherical cap of Dupuy & Benyoub 2023, either side of the horizon). sample(): one walk per row (weight 1, or 0
    after 100 meeting points: lost); eval(): the next-event estimate of f |cos wo| (sec. 6) from `paths` walks, each
    meeting point adding D(m) / (4 sigma(v)) C1(h)^Lambda(wo) (orders past `eval_orders` left out: a planted bug)."""
    gen = np.random.default_rng(11)

    def lam(w):  # w above the horizon
        return (-1 + np.sqrt(1 + alpha ** 2 * (w[:, 0] ** 2 + w[:, 1] ** 2) / w[:, 2] ** 2)) / 2

    def sigma(v):
        up = np.where(v[:, 2:] > 0, v, -v)
        return np.where(v[:, 2] > 0, v[:, 2] * (1 + lam(up)), -v[:, 2] * lam(up))

    def visible_normal(v, rng):
        w = v * [alpha, alpha, 1]
        w /= np.linalg.norm(w, axis=1, keepdims=True)
        z = -w[:, 2] + rng.random(len(v)) * (1 + w[:, 2])
        phi, r = 2 * np.pi * rng.random(len(v)), np.sqrt(np.maximum(0, 1 - z * z))
        m = np.column_stack([alpha * (r * np.cos(phi) + w[:, 0]), alpha * (r * np.sin(phi) + w[:, 1]), z + w[:, 2]])
        return m / np.linalg.norm(m, axis=1, keepdims=True)

    def next_event(v, wo, h):
        m = v + wo
        m /= np.maximum(np.linalg.norm(m, axis=1, keepdims=True), 1e-300)
        vm = np.sum(v * m, axis=1)
        e = (m[:, 0] ** 2 + m[:, 1] ** 2) / alpha ** 2 + m[:, 2] ** 2
        d = 1 / (np.pi * alpha ** 2 * e * e)
        ok = (wo[:, 2] > 0) & (m[:, 2] > 0) & (vm > 0)
        leave = ((h + 1) / 2) ** lam(np.where(ok[:, None], wo, [0, 0, 1]))
        return np.where(ok, d / (4 * sigma(v)) * leave, 0.0)

    def next_height(d, h, rng):
        u, up = 1 - rng.random(len(d)), d[:, 2] > 0
        c = np.where(np.isinf(h), 1.0, (h + 1) / 2)
        lu = lam(np.where(up[:, None], d, -d))
        with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
            rise = np.where(u <= c ** lu, np.inf, 2 * c / u ** (1 / lu) - 1)
            return np.where(up, rise, 2 * c * u ** (1 / (1 + lu)) - 1)

    def walk(wi, rng, wo=None):
        n = len(wi)
        d, h, out = -wi.copy(), np.full(n, np.inf), np.zeros((n, 3))
        weight, estimate, alive = np.zeros(n), np.zeros(n), np.arange(n)
        for order in range(100):
            if alive.size == 0:
                break
            h[alive] = next_height(d[alive], h[alive], rng)
            left = np.isinf(h[alive])
            out[alive[left]], weight[alive[left]] = d[alive[left]], 1.0
            alive = alive[~left]
            v = -d[alive]
            if wo is not None and order < eval_orders:
                estimate[alive] += next_event(v, wo[alive], h[alive])
            m = visible_normal(v, rng)
            d[alive] = 2 * np.sum(v * m, axis=1, keepdims=True) * m - v
        return out, weight, estimate

    def sample(wi, u):
        wo, weight, _ = walk(wi, np.random.default_rng(int(u[0, 0] * 2 ** 53)))
        return wo, np.zeros(len(wi)), weight

    def evaluate(wi, wo):
        return walk(np.repeat(wi, paths, axis=0), gen, np.repeat(wo, paths, axis=0))[2].reshape(-1, paths).mean(axis=1)

    return sample, evaluate


def test_a_numpy_smith_walk_passes_against_the_walk_reference():
    """check_bsdf with reference='smith-walk': the numpy Smith multiple-scattering mirror (alpha 0.8; stochastic eval,
    no pdf) passes against microsim's walk (its samples and its next-event eval, 20000 samples at 0 and 60 deg,
    level 0.01); the same whose eval() keeps the first order only (an eval that is not the integral its sampler
    implies) is rejected by the integral, furnace and eval tests while its samples pass."""
    kwargs = dict(bsdf="mirror", alpha=0.8, samples=20_000, arithmetic="float64", views=[0, 60],
                  reference="smith-walk", stochastic_eval=True)
    sample, evaluate = smith_walk_mirror(0.8)
    r = microsim.check_bsdf(sample, evaluate, None, **kwargs)
    assert r["passed"], [t for t in r["tests"] if not t["passed"]]
    assert {t["test"] for t in r["tests"]} == {"sampling", "integral", "furnace", "eval", "reciprocity"}
    sample, evaluate = smith_walk_mirror(0.8, eval_orders=1)
    r = microsim.check_bsdf(sample, evaluate, None, **kwargs)
    failed = {t["test"] for t in r["tests"] if not t["passed"]}
    assert {"integral", "furnace", "eval"} <= failed, failed
    assert "sampling" not in failed


# ---- a conductor drawing its normals from D(m) cos (Walter et al. 2007 eq. 35-36; Mitsuba 3's sample_visible=false) ----
def ndf_gold(alpha=0.3, n_k=(0.2, 3.9)):
    """eval (f |cos wo|), pdf and sample of a rough GGX conductor whose sampler draws m from D(m) cos: a normal facing
    away from wi, or a reflection below the horizon, is a lost sample (pdf 0)."""
    def d(m):
        e = (m[:, 0] ** 2 + m[:, 1] ** 2) / alpha ** 2 + m[:, 2] ** 2
        return np.where(m[:, 2] > 0, 1 / (np.pi * alpha ** 2 * np.maximum(e, 1e-150) ** 2), 0.0)

    def lam(w):
        return (-1 + np.sqrt(1 + alpha ** 2 * (w[:, 0] ** 2 + w[:, 1] ** 2) / w[:, 2] ** 2)) / 2

    def fresnel(c):
        n = complex(*n_k)
        ct = np.sqrt(1 - (1 - c ** 2) / n ** 2 + 0j)
        return (np.abs((c - n * ct) / (c + n * ct)) ** 2 + np.abs((n * c - ct) / (n * c + ct)) ** 2) / 2

    def value_and_pdf(wi, wo):
        h = wi + wo
        h = h / np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-300)
        c, oh = np.einsum("ij,ij->i", wi, h), np.einsum("ij,ij->i", wo, h)
        ok = (wi[:, 2] > 0) & (wo[:, 2] > 0) & (c > 0)
        dm = d(h)
        g2 = 1 / (1 + lam(wi) + lam(np.where(ok[:, None], wo, wi)))
        value = np.where(ok, fresnel(np.clip(c, 0, 1)) * dm * g2 / (4 * np.where(ok, wi[:, 2], 1)), 0.0)
        pdf = np.where(ok, dm * h[:, 2] / (4 * np.where(ok, oh, 1)), 0.0)
        return value, pdf

    def sample(wi, u):
        r, phi = np.sqrt(u[:, 0] / (1 - u[:, 0])), 2 * np.pi * u[:, 1]
        m = np.stack([-alpha * r * np.cos(phi), -alpha * r * np.sin(phi), np.ones(len(u))], axis=1)
        m /= np.linalg.norm(m, axis=1, keepdims=True)
        c = np.einsum("ij,ij->i", wi, m)
        wo = 2 * c[:, None] * m - wi
        value, p = value_and_pdf(wi, wo)
        p = np.where((c > 0) & (wo[:, 2] > 0), p, 0.0)
        return wo, p, np.where(p > 0, value / np.where(p > 0, p, 1), 0.0)

    return sample, (lambda wi, wo: value_and_pdf(wi, wo)[0]), (lambda wi, wo: value_and_pdf(wi, wo)[1])


def test_a_conductor_sampling_its_normals_from_the_ndf_passes_when_it_says_so():
    sample, evaluate, pdf = ndf_gold()
    args = dict(bsdf="conductor:0.2,3.9", alpha=0.3, samples=50_000, arithmetic="float64")
    said = microsim.check_bsdf(sample, evaluate, pdf, sampling="ndf", **args)
    assert said["passed"], [t for t in said["tests"] if not t["passed"]]
    assert "D(m) cos" in said["convention"] and not any(t["view"] == "89.9 deg" for t in said["tests"])
    unsaid = microsim.check_bsdf(sample, evaluate, pdf, **args)  # claimed as visible-normal sampling: rejected
    assert not unsaid["passed"]
    assert any(t["test"] == "sampling" and not t["passed"] for t in unsaid["tests"])
    with pytest.raises(ValueError, match="heavy-tailed"):  # a dielectric so sampled: its weights are not judged
        microsim.check_bsdf(sample, evaluate, pdf, sampling="ndf", bsdf="dielectric:1.5", alpha=0.3)
    with pytest.raises(ValueError, match="sampling"):
        microsim.check_bsdf(sample, evaluate, pdf, sampling="visible", **args)
