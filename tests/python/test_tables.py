"""microsim.albedo_table() (also in a renderer's layout), microsim.grade_albedo_table() and microsim.stability():
the dicts `microsim albedo --json` (with --layout, --grade) and `microsim stability --json` write, computed from
Python (times left out: they differ run to run), and the grade's exit code."""
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


# --layout and --grade: a small tolerance keeps the uniform layout's 32 x 32 nodes and cell centres quick.
LAYOUT_TOLERANCE = "1e-6"


@pytest.fixture(scope="module")
def uniform_layout(tmp_path_factory):
    """The CLI's uniform layout table: its JSON, and its CSV as a correct table to grade."""
    d = tmp_path_factory.mktemp("layout")
    run_cli("albedo", "--layout", "uniform", "--tolerance", LAYOUT_TOLERANCE, "--out", d / "t.exr",
            "--csv", d / "t.csv", "--json", d / "t.json")
    return d, json.loads((d / "t.json").read_text())


def test_albedo_layout_is_the_clis(uniform_layout):
    _, cli = uniform_layout
    py = microsim.albedo_table(layout="uniform", tolerance=float(LAYOUT_TOLERANCE))
    assert without_times(py) == without_times(cli)
    assert py["layout"] == "uniform" and len(py["E"]["value"]) == 32 and len(py["E"]["error"][0]) == 32


def test_albedo_layout_refuses_what_the_cli_refuses():
    for bad in ({"model": "smith-walk"}, {"material": "dielectric:1.5"}, {"alphas": [0.5]}, {"mus": 4},
                {"ndf": "phong"}, {"seed": 2}):
        with pytest.raises(ValueError):
            microsim.albedo_table(layout="cycles", **bad)
    with pytest.raises(ValueError, match="cycles"):
        microsim.albedo_table(layout="unreal")  # the error lists the layouts


def grade_both(tmp_path, table, *options):
    """The CLI's grade (its JSON and exit code) and grade_albedo_table's, of the same file."""
    p = run_cli("albedo", "--grade", table, "--layout", "uniform", *options, "--json", tmp_path / "g.json")
    cli = json.loads((tmp_path / "g.json").read_text())
    kwargs = {"tolerance": 1e-4}
    if "--table-samples" in options:
        kwargs["table_samples"] = int(options[options.index("--table-samples") + 1])
    return p.returncode, cli, microsim.grade_albedo_table(table, layout="uniform", **kwargs)


def test_grade_passes_the_correct_table(uniform_layout, tmp_path):
    d, _ = uniform_layout
    code, cli, py = grade_both(tmp_path, d / "t.csv", "--tolerance", "1e-4", "--table-samples", "1000000")
    assert code == 0 and py["exit_code"] == 0 and py["passed"] and py["failed"] == 0
    assert {k: v for k, v in py.items() if k != "exit_code"} == cli


def test_grade_flags_a_planted_error(uniform_layout, tmp_path):
    d, _ = uniform_layout
    lines = (d / "t.csv").read_text().splitlines()
    header = next(line for line in lines if not line.startswith("#")).split(",")
    column = header.index("E")
    rows = [i for i, line in enumerate(lines) if not line.startswith("#") and line.split(",")[0] == "17"]
    planted = rows[9]  # node x 17, one row: a cell in the interior
    fields = lines[planted].split(",")
    fields[column] = repr(float(fields[column]) + 1e-3)
    lines[planted] = ",".join(fields)
    (tmp_path / "planted.csv").write_text("\n".join(lines) + "\n")
    code, cli, py = grade_both(tmp_path, tmp_path / "planted.csv", "--tolerance", "1e-4")
    assert code == 1 and py["exit_code"] == 1 and not py["passed"] and py["failed"] == 1
    assert py["max_abs"] == pytest.approx(1e-3, rel=1e-2)
    assert {k: v for k, v in py.items() if k != "exit_code"} == cli


def test_grade_refuses_what_the_cli_refuses(tmp_path):
    with pytest.raises(ValueError, match="cannot be read"):
        microsim.grade_albedo_table(tmp_path / "none.csv", layout="uniform")
    (tmp_path / "t.json").write_text("1\n")
    with pytest.raises(ValueError, match="an .exr, a .csv or a .txt"):
        microsim.grade_albedo_table(tmp_path / "t.json", layout="uniform")
    (tmp_path / "t.txt").write_text("1.0f\n")
    with pytest.raises(ValueError, match="1 values in the text; the uniform layout has 1024"):
        microsim.grade_albedo_table(tmp_path / "t.txt", layout="uniform")
    with pytest.raises(ValueError):
        microsim.grade_albedo_table(tmp_path / "t.txt", layout="uniform", table_samples=0)


# The anisotropic mirror's table and Cycles' glass layouts from Python: the anisotropic table is the CLI's
# (--alphas-y --json), on a few nodes; the glass layouts (16 x 16 x 16 quadratures of a dielectric, minutes) are
# checked for the arguments they refuse, and their grade for the files it refuses (its reference costs as
# much; the grade itself is tested in C++ on a small grid of the same code path, AlbedoGlassGrade).
def test_anisotropic_table_is_the_clis(tmp_path):
    run_cli("albedo", "--model", "analytic", "--alphas", "0.2", "--alphas-y", "0.05,0.5", "--mus", "3", "--phis", "2",
            "--json", tmp_path / "a.json")
    cli = json.loads((tmp_path / "a.json").read_text())
    py = microsim.anisotropic_albedo_table(alphas_x=[0.2], alphas_y=[0.05, 0.5], mus=3, phis=2)
    assert without_times(py) == without_times(cli)
    assert len(py["E"]["value"]) == 1 and len(py["E"]["value"][0]) == 2 and len(py["E"]["value"][0][1][2]) == 2
    assert 0 < py["E_avg"]["value"][0][1] < py["E_avg"]["value"][0][0] < 1  # rougher in y: more energy lost


def test_anisotropic_table_refuses_what_the_cli_refuses():
    for bad in ({"alphas_x": [3.0]}, {"alphas_y": [0.0]}, {"mus": 1}, {"phis": 0}, {"phis": 65}, {"tolerance": 0.0},
                {"threads": -1}):
        kwargs = {"alphas_x": [0.5], "alphas_y": [0.5], **bad}
        with pytest.raises(ValueError):
            microsim.anisotropic_albedo_table(**kwargs)


def test_glass_layout_refuses_what_the_cli_refuses():
    for bad in ({"model": "smith-walk"}, {"material": "dielectric:1.5"}, {"alphas": [0.5]}, {"mus": 4},
                {"inside": True}, {"tolerance": 0.0}, {"ndf": "beckmann"}):
        for layout in ("cycles-glass", "cycles-glass-inv"):
            with pytest.raises(ValueError):
                microsim.albedo_table(layout=layout, **bad)


def test_glass_grade_refuses_what_the_cli_refuses(tmp_path):
    (tmp_path / "g.csv").write_text("# a comment\nx,y,z,E\n0,0,0,0.5\n1,0,0,0.5\n")
    with pytest.raises(ValueError, match="2 nodes in the CSV; the cycles-glass layout has 4096"):
        microsim.grade_albedo_table(tmp_path / "g.csv", layout="cycles-glass")
    (tmp_path / "g.txt").write_text("0.5, 0.5\n")
    with pytest.raises(ValueError, match="2 values in the text"):
        microsim.grade_albedo_table(tmp_path / "g.txt", layout="cycles-glass-inv")
    with pytest.raises(ValueError, match="a .csv or a .txt"):
        microsim.grade_albedo_table(tmp_path / "g.exr", layout="cycles-glass")


def test_beckmann_layout_is_the_clis(tmp_path):
    """albedo_table(layout=..., ndf="beckmann") is `albedo --layout L --ndf beckmann --json`: a Beckmann mirror's E."""
    run_cli("albedo", "--layout", "uniform", "--ndf", "beckmann", "--tolerance", "1e-3", "--out", tmp_path / "b.exr",
            "--json", tmp_path / "b.json")
    cli = json.loads((tmp_path / "b.json").read_text())
    py = microsim.albedo_table(layout="uniform", ndf="beckmann", tolerance=1e-3)
    assert without_times(py) == without_times(cli)
    assert py["ndf"] == "beckmann"


def test_grade_against_beckmann_is_the_clis(uniform_layout, tmp_path):
    """The GGX table graded as a Beckmann mirror's (ndf, --ndf beckmann) fails, from Python as from the CLI."""
    d, _ = uniform_layout
    p = run_cli("albedo", "--grade", d / "t.csv", "--layout", "uniform", "--ndf", "beckmann", "--tolerance", "1e-3",
                "--json", tmp_path / "g.json")
    cli = json.loads((tmp_path / "g.json").read_text())
    py = microsim.grade_albedo_table(d / "t.csv", layout="uniform", ndf="beckmann", tolerance=1e-3)
    assert p.returncode == 1 and py["exit_code"] == 1 and py["ndf"] == "beckmann" and py["failed"] > 0
    assert {k: v for k, v in py.items() if k != "exit_code"} == cli
