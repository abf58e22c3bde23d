"""microsim.compare_scattering(): the verdict and the dict of `microsim compare-scattering --json`, from Python.
Two Smith-walk runs of one configuration (seeds 1 and 2) must pass at the family-wise level 0.01; the same
walk at another roughness (0.5 against 0.3) is the negative control and must be rejected."""
import json

import pytest

import microsim
from conftest import run_cli


def walk(tmp_path, name, alpha, seed):
    path = tmp_path / name
    run_cli("scatter", "--model", "smith-walk", "--alpha", alpha, "--theta", 40, "--rays", 200000, "--rows", 8,
            "--seed", seed, "--out", path)
    return str(path)


def test_one_verdict_with_the_cli(tmp_path):
    a, b = walk(tmp_path, "a.exr", 0.5, 1), walk(tmp_path, "b.exr", 0.5, 2)
    other = walk(tmp_path, "c.exr", 0.3, 3)
    for files, rejected in (([a, b], False), ([a, other], True)):
        p = run_cli("compare-scattering", *files, "--orders", "1,2,total", "--json", tmp_path / "cli.json")
        cli = json.loads((tmp_path / "cli.json").read_text())
        py = microsim.compare_scattering(files, orders="1,2,total")
        assert py["rejected"] is rejected and py["passed"] is (not rejected)
        assert p.returncode == (1 if rejected else 0)
        assert {k: v for k, v in py.items() if k != "passed"} == cli


def test_analytic_third_input(tmp_path):
    a = walk(tmp_path, "a.exr", 0.5, 1)
    py = microsim.compare_scattering([a], analytic=True, orders="1")
    assert [i["label"] for i in py["inputs"]] == ["A", "B"] and py["inputs"][1]["kind"] == "expectation"
    assert py["passed"]


def test_bad_inputs_are_value_errors_never_a_pass(tmp_path):
    a = walk(tmp_path, "a.exr", 0.5, 1)
    with pytest.raises(ValueError, match="no such file"):
        microsim.compare_scattering([a, str(tmp_path / "missing.exr")])
    with pytest.raises(ValueError, match="--orders"):
        microsim.compare_scattering([a, a], orders="6")
    with pytest.raises(ValueError, match="level"):
        microsim.compare_scattering([a, a], level=1.5)
    tiny = str(tmp_path / "tiny.exr")
    run_cli("scatter", "--model", "smith-walk", "--alpha", 0.5, "--theta", 40, "--rays", 64, "--rows", 8, "--out", tiny)
    with pytest.raises(ValueError, match="too little data"):
        microsim.compare_scattering([a, tiny])
