"""A renderer's eval() and pdf(), written from the math the way pbrt-v4 and Mitsuba 3 write them, at the query set
of `microsim bsdf-queries`, checked by `microsim check-eval`: every correct eval file passes (float32 and float64
arithmetic, .npy and text, both transport modes, both masking forms), and each bug a sampling test cannot see is
rejected by the check its correct twin passes.

The renderer evaluates f(wg, ws) |cos ws| for the direction wg it was given and ws (pbrt-v4 DielectricBxDF::f and
::PDF, ConductorBxDF; Mitsuba 3 roughdielectric, roughconductor): the lobe by the sides of the pair, the generalised
half vector of Walter et al. 2007 (eq. 13, 16), backfacing microfacets 0, a refraction's f divided by etap^2 in
radiance mode, pdf = D_wg(h) (F or 1 - F) times the half-vector Jacobian (eq. 14, 17) with the visible normals of
Heitz 2018. The arithmetic is float32 unless said, as in a renderer."""
import pathlib
import sys

import numpy as np
import pytest

from conftest import run_cli

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "examples"))
from renderer_eval import ALPHA, ETA, GOLD, renderer_eval  # noqa: E402  (the renderer of the guide's example)


@pytest.fixture(scope="module")
def queries(tmp_path_factory):
    d = tmp_path_factory.mktemp("queries")
    out = {}
    for kind, bsdf in (("dielectric", f"dielectric:{ETA}"), ("conductor", f"conductor:{GOLD[0]},{GOLD[1]}")):
        path = d / f"{kind}.npy"
        assert run_cli("bsdf-queries", "--bsdf", bsdf, "--alpha", ALPHA, "--per-view", 256, "--out", path).returncode == 0
        out[kind] = np.load(path)
    return out


def check(tmp_path, q, kind, layout="c32", claims=(), **renderer):
    value, pdf = renderer_eval(q, kind, **renderer)
    rows = np.column_stack([q, value, pdf])
    path = tmp_path / ("eval.txt" if layout.startswith("text") else "eval.npy")
    if layout.startswith("text"):  # "text" %.9g, "text:FMT" another printf format
        np.savetxt(path, rows, fmt=layout[5:] or "%.9g")
    else:
        np.save(path, rows.astype(np.float32 if layout == "c32" else np.float64))
    bsdf = f"dielectric:{ETA}" if kind == "dielectric" else f"conductor:{GOLD[0]},{GOLD[1]}"
    p = run_cli("check-eval", path, "--alpha", ALPHA, "--bsdf", bsdf, "--columns", "wi,wo,value,pdf", *claims)
    return p.returncode, p.stdout


CORRECT = [
    ("pbrt-v4 glass, radiance, float32", "dielectric", "c32", (), {}),
    ("pbrt-v4 glass, importance, float64 arithmetic", "dielectric", "c64", ("--transport", "importance", "--arithmetic", "float64"),
     dict(transport="importance", dtype=np.float64)),
    ("Mitsuba 3 glass, separable masking, text", "dielectric", "text", ("--masking", "separable"), dict(masking="separable")),
    ("pbrt-v4 gold, float32", "conductor", "c32", (), {}),
    ("glass printed with 4 decimals", "dielectric", "text:%.4f", ("--arithmetic", "float64"), dict(dtype=np.float64)),
    ("gold printed with %g", "conductor", "text:%g", (), {}),
    ("Mitsuba 3 gold, sample_visible=false (pdf of D(m) cos)", "conductor", "c32",
     ("--masking", "separable", "--sampling", "ndf"), dict(masking="separable", normals="ndf")),
    ("glass whose sample() draws D(m) cos", "dielectric", "c32", ("--sampling", "ndf"), dict(normals="ndf")),
]

BUGS = [
    ("importance glass claimed radiance (f off by eta^2)", "dielectric", (), dict(transport="importance"), "value"),
    ("glass, the radiance factor applied twice", "dielectric", (), dict(bug="eta2_twice"), "value"),
    ("glass, the lobe chosen by ws alone (same-hemisphere check forgotten)", "dielectric", (), dict(bug="lobe_by_ws_only"),
     "value"),
    ("Mitsuba 3 glass claimed height-correlated", "dielectric", (), dict(masking="separable"), "value"),
    ("glass, reflection pdf without its Fresnel choice", "dielectric", (), dict(bug="pdf_without_fresnel"), "pdf"),
    ("gold without the same-hemisphere check", "conductor", (), dict(bug="no_hemisphere_check"), "value"),
    ("gold's pdf of D(m) cos claimed as VNDF sampling", "conductor", (), dict(normals="ndf"), "pdf"),
    ("glass's VNDF pdf claimed as D(m) cos", "dielectric", ("--sampling", "ndf"), {}, "pdf"),
]


@pytest.mark.parametrize("name,kind,layout,claims,renderer", CORRECT, ids=[c[0] for c in CORRECT])
def test_a_correct_eval_passes(tmp_path, queries, name, kind, layout, claims, renderer):
    code, out = check(tmp_path, queries[kind], kind, layout, claims, **renderer)
    assert code == 0, out


@pytest.mark.parametrize("name,kind,claims,renderer,what", BUGS, ids=[b[0] for b in BUGS])
def test_a_buggy_eval_is_rejected(tmp_path, queries, name, kind, claims, renderer, what):
    code, out = check(tmp_path, queries[kind], kind, "c32", claims, **renderer)
    assert code == 1, out
    worst = out.split("excess")[1].splitlines()[1]  # the first listed pair
    assert what in worst, out


@pytest.mark.parametrize("fmt", ["%.4f", "%g"])
def test_a_buggy_eval_printed_with_few_digits_is_rejected(tmp_path, queries, fmt):
    """Each number is allowed the rounding of its own printed digits, no more: the radiance factor applied twice
    is still rejected at 4 decimals and at 6 significant digits."""
    code, out = check(tmp_path, queries["dielectric"], "dielectric", f"text:{fmt}", ("--arithmetic", "float64"),
                      dtype=np.float64, bug="eta2_twice")
    assert code == 1, out


@pytest.mark.parametrize("d_form", ["pbrt", "ue4"])
@pytest.mark.parametrize("alpha", [0.01, 1e-3])
@pytest.mark.parametrize("dtype,arithmetic,planted", [(np.float32, "float32", 1e-2), (np.float64, "float64", 1e-8)])
def test_an_ndf_from_cos_theta_passes_at_low_roughness(tmp_path, d_form, alpha, dtype, arithmetic, planted):
    """pbrt-v4 and Karis 2013's real-time form compute D from cos theta_m (1 - cos^2 cancels near the peak, losing
    about eps / alpha^2 relative: pbrt-v4 where its clamp of cos phi binds, up to 28% at alpha 1e-3 in float32;
    Karis' form everywhere, 3% typical): a correct eval written so passes; the same scaled by 1 + planted (an
    error above that loss) is rejected."""
    q_path = tmp_path / "q.npy"
    assert run_cli("bsdf-queries", "--bsdf", f"conductor:{GOLD[0]},{GOLD[1]}", "--alpha", alpha, "--per-view", 256,
                   "--out", q_path).returncode == 0
    q = np.load(q_path)
    value, pdf = renderer_eval(q, "conductor", dtype=dtype, alpha=alpha, d_form=d_form)
    for scale, expected in ((1.0, 0), (1 + planted, 1)):
        np.save(tmp_path / "e.npy", np.column_stack([q.astype(dtype), value * dtype(scale), pdf]).astype(dtype))
        p = run_cli("check-eval", tmp_path / "e.npy", "--alpha", alpha, "--bsdf", f"conductor:{GOLD[0]},{GOLD[1]}",
                    "--columns", "wi,wo,value,pdf", "--arithmetic", arithmetic, check=False)
        assert p.returncode == expected, (scale, p.stdout)


def test_without_a_pdf_column_the_report_says_so(tmp_path, queries):
    q = queries["conductor"]
    value, _ = renderer_eval(q, "conductor")
    np.save(tmp_path / "e.npy", np.column_stack([q, value]).astype(np.float32))
    p = run_cli("check-eval", tmp_path / "e.npy", "--alpha", ALPHA, "--bsdf", f"conductor:{GOLD[0]},{GOLD[1]}")
    assert p.returncode == 0, p.stdout
    assert "the pdfs were not checked" in p.stdout


def test_bad_usage_exits_2(tmp_path, queries):
    np.save(tmp_path / "e.npy", queries["conductor"])  # 6 columns, no value
    for args, message in (((), "columns"), (("--transport", "flux"), "transport"), (("--arithmetic", "half"), "arithmetic")):
        p = run_cli("check-eval", tmp_path / "e.npy", "--alpha", ALPHA, "--bsdf", "conductor:0.2,3.9", *args, check=False)
        assert p.returncode == 2, (args, p.stdout, p.stderr)
        assert message in p.stderr, p.stderr
