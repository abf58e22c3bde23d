"""microsim.check_bsdf_files: one BSDF's consistency with itself from a sample dump and its eval file at the same
rows, as `microsim check-bsdf-files` and a `bsdf` experiment naming the files check them. The files are those of
the pbrt-v4-style rough glass of examples/renderer_eval.py (alpha 0.3, eta 1.5) sampled by the numpy sampler of
test_check_bsdf.py at 60 deg (20000 draws, fixed seed, level 0.01), with its eval file at the cell points of
`bsdf-queries --cells`: they pass every test, with the same verdict, tests and p-values from Python (paths and
arrays), from the command line's JSON and in a run's results.json. The same files whose eval applies the radiance
factor twice on refraction (the planted eta^2 bug; the dump's weights stay the sampler's) are rejected by the
consistency test everywhere: exit 1, "fail", passed False."""
import json
import pathlib
import sys

import numpy as np
import pytest

import microsim
from conftest import run_cli, view
from test_check_bsdf import glass

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "examples"))
from renderer_eval import renderer_eval  # noqa: E402

THETA = 60
DRAWS = 20_000


def write_files(tmp_path, eval_bug=None):
    """The glass's dump (x y z pdf weight), its eval file at the dump's rows and at the view's cell points (.npy
    float64, as a renderer writes them): the arrays, and the samples lost (not in the dump)."""
    sample, _, _ = glass()
    wi = np.tile(view(THETA), (DRAWS, 1))
    wo, pdf, weight = sample(wi, np.random.default_rng(3).random((DRAWS, 3)))
    kept = pdf > 0
    wi, wo, pdf, weight = wi[kept], wo[kept], pdf[kept], weight[kept]
    value, epdf = renderer_eval(np.column_stack([wi, wo]), "dielectric", dtype=np.float64, bug=eval_bug)
    dump, evals = np.column_stack([wo, pdf, weight]), np.column_stack([wi, wo, value, epdf])
    run_cli("bsdf-queries", "--cells", "--theta", THETA, "--points-per-cell", 16, "--out", tmp_path / "q.npy")
    q = np.load(tmp_path / "q.npy")
    cvalue, cpdf = renderer_eval(q, "dielectric", dtype=np.float64, bug=eval_bug)
    cells = np.column_stack([q, cvalue, cpdf])
    for name, rows in (("d.npy", dump), ("e.npy", evals), ("c.npy", cells)):
        np.save(tmp_path / name, rows)
    return dump, evals, cells, int(DRAWS - kept.sum())


def outcome(report):
    return report["verdict"], [(t["test"], t["view"], t["p"], t["passed"]) for t in report["tests"]]


def cli_report(tmp_path, lost):
    out = tmp_path / "cli.json"
    p = run_cli("check-bsdf-files", tmp_path / "d.npy", tmp_path / "e.npy", "--theta", THETA, "--lost", lost,
                "--cells", tmp_path / "c.npy", "--json", out)
    return p.returncode, json.loads(out.read_text())


def run_spec(tmp_path, lost, extra=""):
    """`microsim run` on a bsdf spec naming the files: the exit code, the process and its run directory."""
    (tmp_path / "bsdf.toml").write_text(f"""seed = 7
[[material]]
name = "glass"
alpha = 0.3
type = "dielectric"
eta = 1.5
[[quantity]]
kind = "bsdf"
material = "glass"
dump = "d.npy"
eval = "e.npy"
cells = "c.npy"
theta = {THETA}
lost = {lost}
{extra}
""")
    out = tmp_path / "run"
    p = run_cli("run", tmp_path / "bsdf.toml", "--out", out, check=False)
    return p, out


@pytest.mark.parametrize("eval_bug", [None, "eta2_twice"])
def test_the_same_verdict_from_python_the_command_line_and_a_run(tmp_path, eval_bug):
    dump, evals, cells, lost = write_files(tmp_path, eval_bug)
    code, cli = cli_report(tmp_path, lost)
    files = microsim.check_bsdf_files(tmp_path / "d.npy", str(tmp_path / "e.npy"), theta=THETA, lost=lost,
                                      cells=tmp_path / "c.npy")
    arrays = microsim.check_bsdf_files(dump, evals, theta=THETA, lost=lost, cells=cells)
    assert outcome(files) == outcome(cli) == outcome(arrays)
    assert files["passed"] == (cli["verdict"] == "pass") == (code == 0)
    assert arrays["dump"] == f"array ({len(dump)}, 5)" and files["dump"] == str(tmp_path / "d.npy")
    assert {t["test"] for t in files["tests"]} == {"consistency", "density", "integral", "furnace"}
    p, out = run_spec(tmp_path, lost)
    battery = json.loads((out / "results.json").read_text())["results"]["measurements"][0]["values"]["battery"]
    assert outcome(battery) == outcome(cli)
    assert "check-bsdf-files" in (out / "index.html").read_text()
    if eval_bug is None:
        assert files["passed"] and code == 0 and p.returncode == 0, [t for t in files["tests"] if not t["passed"]]
    else:
        assert not files["passed"] and files["verdict"] == "fail" and code == 1 and p.returncode == 1, p.stderr
        assert ("consistency", False) in {(t["test"], t["passed"]) for t in files["tests"]}


@pytest.mark.parametrize("eval_bug", [None, "eta2_twice"])
def test_float32_and_fortran_order_arrays_and_files_give_the_same_verdict(tmp_path, eval_bug):
    """A renderer's float32 rows, in any layout numpy writes (Fortran order here), as arrays and as .npy files."""
    dump, evals, cells, lost = write_files(tmp_path, eval_bug)
    f32 = [np.asfortranarray(a.astype(np.float32)) for a in (dump, evals, cells)]
    for name, rows in zip(("d32.npy", "e32.npy", "c32.npy"), f32):
        np.save(tmp_path / name, rows)
    arrays = microsim.check_bsdf_files(*f32[:2], theta=THETA, lost=lost, cells=f32[2])
    files = microsim.check_bsdf_files(tmp_path / "d32.npy", tmp_path / "e32.npy", theta=THETA, lost=lost,
                                      cells=tmp_path / "c32.npy")
    assert arrays["verdict"] == files["verdict"] == ("pass" if eval_bug is None else "fail")
    if eval_bug is not None:
        assert ("consistency", False) in {(t["test"], t["passed"]) for t in arrays["tests"]}


def test_bad_arguments_and_rows_that_do_not_match_raise_naming_them(tmp_path):
    dump, evals, _, _ = write_files(tmp_path)
    with pytest.raises(ValueError, match="theta 200"):
        microsim.check_bsdf_files(dump, evals, theta=200)
    with pytest.raises(ValueError, match="columns 'x,y,z'"):
        microsim.check_bsdf_files(dump, evals, theta=THETA, columns="x,y,z")
    with pytest.raises(ValueError, match="eval"):
        microsim.check_bsdf_files(dump, evals[:, :7], theta=THETA)
    with pytest.raises(ValueError, match="level 2"):
        microsim.check_bsdf_files(dump, evals, theta=THETA, level=2)
    with pytest.raises(ValueError, match="is not the view"):
        microsim.check_bsdf_files(tmp_path / "d.npy", tmp_path / "e.npy", theta=30)
    with pytest.raises(ValueError, match="fewer rows"):
        microsim.check_bsdf_files(dump, evals[:-1], theta=THETA)


def test_a_runs_bad_keys_exit_2_naming_the_key(tmp_path):
    write_files(tmp_path)
    p, _ = run_spec(tmp_path, 0, 'samples = 1000')
    assert p.returncode == 2 and "quantity[0].samples" in p.stderr, p.stderr
    p, _ = run_spec(tmp_path, 0, 'colour = "red"')
    assert p.returncode == 2 and "quantity[0].colour" in p.stderr, p.stderr


@pytest.mark.parametrize("scale", [1e3, 1e5])
def test_fireflies_in_a_small_dump_are_rejected(tmp_path, scale):
    """Three fireflies among about 190 rows (200 draws, no albedo claimed): each holds a third of the spread, above
    the limit for so few rows (10 ln(n) / n, 0.28); the 190 honest rows alone pass."""
    sample, _, _ = glass()
    wi = np.tile(view(THETA), (200, 1))
    wo, pdf, weight = sample(wi, np.random.default_rng(5).random((200, 3)))
    kept = pdf > 0
    wi, wo, pdf, weight = wi[kept], wo[kept], pdf[kept], weight[kept]
    value, epdf = renderer_eval(np.column_stack([wi, wo]), "dielectric", dtype=np.float64)
    dump, evals = np.column_stack([wo, pdf, weight]), np.column_stack([wi, wo, value, epdf])
    honest = microsim.check_bsdf_files(dump, evals, theta=THETA, lost=int(200 - kept.sum()))
    assert honest["passed"], honest["tests"]
    dump[[3, 60, 120], 4] *= scale
    evals[[3, 60, 120], 6] *= scale
    report = microsim.check_bsdf_files(dump, evals, theta=THETA, lost=int(200 - kept.sum()))
    furnace = {t["test"]: t for t in report["tests"]}["furnace"]
    assert not report["passed"] and "firefly" in furnace["detail"], furnace


@pytest.mark.parametrize("scale", [1e3, 1e5])
def test_fireflies_that_eval_agrees_with_are_rejected(tmp_path, scale):
    """Three samples whose weight and eval() are both `scale` times too large (an eval spike where the sampler
    rarely goes; consistency holds): they raise the mean weight and its standard error together, so the furnace's
    z stays near sqrt(3) whatever the scale. The furnace names the sample holding the weights' spread and fails;
    the same files without them pass (above)."""
    dump, evals, cells, lost = write_files(tmp_path)
    rows = [10, 2000, 9000]
    dump[rows, 4] *= scale
    evals[rows, 6] *= scale
    report = microsim.check_bsdf_files(dump, evals, theta=THETA, lost=lost, cells=cells)
    tests = {t["test"]: t for t in report["tests"]}
    assert tests["consistency"]["passed"]
    assert not report["passed"] and not tests["furnace"]["passed"], tests["furnace"]
    assert "firefly" in tests["furnace"]["detail"]
