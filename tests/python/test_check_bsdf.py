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
