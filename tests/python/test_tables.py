"""microsim.albedo_table() and microsim.stability(): the dicts `microsim albedo --json` and
`microsim stability --json` write, computed from Python (times left out: they differ run to run)."""
import json

import pytest

import microsim
from conftest import run_cli


def without_times(value):
    if isinstance(value, dict):
        return {k: without_times(v) for k, v in value.items() if "seconds" not in k}
    if isinstance(value, list):
        return [without_times(v) for v in value]
    return value


def test_albedo_table_is_the_clis(tmp_path):
    run_cli("albedo", "--model", "analytic", "--alphas", "0.3,0.6", "--mus", "4", "--material", "dielectric:1.5",
            "--out", tmp_path / "t.exr", "--json", tmp_path / "t.json")
    cli = json.loads((tmp_path / "t.json").read_text())
    py = microsim.albedo_table(model="analytic", alphas=[0.3, 0.6], mus=4, material="dielectric:1.5")
    assert without_times(py) == without_times(cli)
    assert set(py["quantities"]) == {"E1", "E1_R", "E1_T"}


def test_albedo_table_refuses_what_the_cli_refuses():
    with pytest.raises(ValueError):
        microsim.albedo_table(alphas=[0.6, 0.3])  # not increasing
    with pytest.raises(ValueError):
        microsim.albedo_table(ndf="phong")


def test_stability_is_the_clis(tmp_path):
    p = run_cli("stability", "--json", tmp_path / "s.json")
    cli = json.loads((tmp_path / "s.json").read_text())
    py = microsim.stability()
    assert without_times(py) == without_times(cli)
    assert p.returncode == (0 if py["violations"] == 0 else 1)
