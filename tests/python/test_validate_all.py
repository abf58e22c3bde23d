"""microsim.validate_all(): the batch of `microsim validate --all` from Python, its verdict table the
command line's. Few samples and the fewest rows (--samples 20000 --rows 3) keep the two runs short; the verdict
at these settings still needs every correct sampler to pass and every negative control (the zoo's own
broken samplers) to be rejected with p < 1e-6, so the comparison covers both outcomes."""
import pytest

import microsim
from conftest import cli_json

ARGS = {"samples": 20000, "rows": 3, "seed": 3}


@pytest.fixture(scope="module")
def both(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("validate_all")
    cli = cli_json(tmp, "validate", "--all", "--samples", ARGS["samples"], "--rows", ARGS["rows"], "--seed", ARGS["seed"])
    return cli, microsim.validate_all(**ARGS)


def test_the_verdict_is_the_clis(both):
    cli, py = both
    assert py["verdict"] == cli["verdict"]
    assert py["exit_code"] == {"pass": 0, "fail": 1}[cli["verdict"]]
    for k in ("validations_requested", "validations_done", "samples", "seed", "precision", "significance",
              "per_validation_significance", "negative_control_p_threshold"):
        assert py[k] == cli[k], k


def test_the_summary_per_sampler_is_the_clis(both):
    cli, py = both
    drop = {"seconds"}
    assert [{k: v for k, v in r.items() if k not in drop} for r in py["summary"]] == \
        [{k: v for k, v in r.items() if k not in drop} for r in cli["summary"]]
    assert any(r["negative_control"] for r in py["summary"])  # the batch holds its negative controls


def test_every_row_is_the_clis(both):
    cli, py = both
    assert len(py["results"]) == len(cli["results"]) > 300
    for a, b in zip(py["results"], cli["results"]):
        for k in ("sampler", "passed", "p_value", "theta_deg", "phi_deg", "negative_control", "samples"):
            assert a.get(k) == b.get(k), (k, a.get("sampler"))
        assert {k: v for k, v in a.items() if k != "seconds"} == {k: v for k, v in b.items() if k != "seconds"}


def test_bad_arguments_are_value_errors():
    with pytest.raises(ValueError):
        microsim.validate_all(samples=10)  # too few for any test
    with pytest.raises(ValueError):
        microsim.validate_all(rows=4)
    with pytest.raises(ValueError):
        microsim.validate_all(precision="half")
