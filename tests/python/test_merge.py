"""microsim.merge(): the shards of one run made by the command line (`trace vndf --shard` on the ellipsoid and
on a heightfield, `scatter --shard`, `trace masking --shard`, `validate --shard`, `stability --shard`) joined
from Python are the single run bit for bit: the dict equals the merged JSON of `microsim merge --json` (but
for what measures the machine) and the single run's counts and statistics; the written histogram is the CLI
merge's file byte for byte. Negative controls: a missing or a repeated block is a ValueError naming the
blocks, a missing part or an EXR part (the form of earlier versions) is named, and an output that is one of
the parts is refused before anything is written."""
import json

import pytest

import microsim
from conftest import run_cli

VNDF = ("trace", "vndf", "--alpha", "0.3,0.6", "--theta", 50, "--phi", 20, "--rays", 300000, "--seed", 7)
SCATTER = ("scatter", "--model", "smith-walk", "--alpha", 0.5, "--theta", 40, "--rays", 200000, "--rows", 8,
           "--seed", 3)
# What differs between a single run and its merge, or between two merges: timing, threads, memory, the file
# named.
VOLATILE = {"seconds", "rays_per_second", "cpu_seconds", "cpu_ns_per_ray", "threads", "output", "peak_rss_mib"}


def shards(tmp_path, run, name, n, ext=".json", out_option="--out"):
    paths = [tmp_path / f"{name}{k}{ext}" for k in range(1, n + 1)]
    for k, p in enumerate(paths, 1):
        run_cli(*run, "--shard", f"{k}/{n}", out_option, p)
    return [str(p) for p in paths]


def stable(report):
    """The report without what measures the machine, at every depth."""
    if isinstance(report, dict):
        return {k: stable(v) for k, v in report.items() if k not in VOLATILE}
    if isinstance(report, list):
        return [stable(v) for v in report]
    return report


def test_vndf_shards_merge_as_the_single_run_and_the_cli_merge(tmp_path):
    parts = shards(tmp_path, VNDF, "v", 2)
    run_cli(*VNDF, "--out", tmp_path / "one.exr", "--json", tmp_path / "one.json")
    single = json.loads((tmp_path / "one.json").read_text())
    run_cli("merge", *parts, "--out", tmp_path / "cli.exr", "--json", tmp_path / "cli.json")
    cli = json.loads((tmp_path / "cli.json").read_text())
    py = microsim.merge(parts, out=tmp_path / "py.exr", json=tmp_path / "py.json")
    assert py == json.loads((tmp_path / "py.json").read_text())
    assert stable(py) == stable(cli)
    assert py["output"] == str(tmp_path / "py.exr")
    assert (tmp_path / "py.exr").read_bytes() == (tmp_path / "cli.exr").read_bytes()
    assert stable(microsim.merge(parts[::-1])) == stable(cli)  # any order; the timing sums follow it
    for key in ("rays", "hits", "p_value", "total_variation", "analysis", "blocks", "seed"):
        assert py[key] == single[key], key


def test_scatter_shards_merge_as_the_single_run(tmp_path):
    parts = shards(tmp_path, SCATTER, "s", 3)
    run_cli(*SCATTER, "--out", tmp_path / "one.exr", "--json", tmp_path / "one.json")
    single = json.loads((tmp_path / "one.json").read_text())
    run_cli("merge", *parts, "--out", tmp_path / "cli.exr", "--json", tmp_path / "cli.json")
    py = microsim.merge(parts, out=tmp_path / "py.exr")
    assert py == json.loads((tmp_path / "cli.json").read_text())
    assert (tmp_path / "py.exr").read_bytes() == (tmp_path / "cli.exr").read_bytes()
    assert py["channels"] == single["channels"] and py["paths"] == single["paths"]


def test_stability_shards_merge_as_the_cli_merge(tmp_path):
    run = ("stability", "--random-u", 2)
    parts = shards(tmp_path, run, "t", 2, out_option="--json")
    run_cli("merge", *parts, "--json", tmp_path / "cli.json")
    assert microsim.merge(parts) == json.loads((tmp_path / "cli.json").read_text())


def test_missing_or_repeated_blocks_are_value_errors_naming_them(tmp_path):
    parts = shards(tmp_path, VNDF, "v", 3)
    with pytest.raises(ValueError, match=r"blocks .* are missing"):
        microsim.merge(parts[:2], out=tmp_path / "m.exr")
    with pytest.raises(ValueError, match=r"blocks .* are in more than one part"):
        microsim.merge([parts[0], parts[1], parts[2], parts[1]], out=tmp_path / "m.exr")
    assert not (tmp_path / "m.exr").exists()
    with pytest.raises(ValueError, match="no such file"):
        microsim.merge([parts[0], str(tmp_path / "absent.json")])
    with pytest.raises(ValueError, match="same file"):
        microsim.merge(parts, out=parts[0])
    run_cli(*VNDF[:-4], "--rays", 5000, "--out", tmp_path / "old.exr")
    with pytest.raises(ValueError, match="is an EXR file: parts are JSON now"):
        microsim.merge([parts[0], tmp_path / "old.exr"], out=tmp_path / "m.exr")
    assert not (tmp_path / "m.exr").exists()


@pytest.fixture(scope="module")
def surface(tmp_path_factory):
    """A small heightfield (a Smith assembly, 256 x 256) for the heightfield kinds."""
    path = tmp_path_factory.mktemp("surface") / "s.exr"
    run_cli("surface", "build", "--assembly", "smith", "--res", 256, "--alpha", 0.4, "--seed", 1, "--out", path,
            "--quiet")
    return path


def cli_merge(tmp_path, parts, *options):
    run_cli("merge", *parts, *options, "--json", tmp_path / "cli.json")
    return json.loads((tmp_path / "cli.json").read_text())


def test_heightfield_vndf_shards_merge_as_the_cli_merge(tmp_path, surface):
    run = ("trace", "vndf", "--surface", surface, "--theta", 40, "--rays", 20000, "--rows", 9, "--seed", 3)
    parts = shards(tmp_path, run, "h", 2)
    run_cli(*run, "--out", tmp_path / "one.exr", "--json", tmp_path / "one.json")
    cli = cli_merge(tmp_path, parts, "--out", tmp_path / "cli.exr")
    py = microsim.merge(parts[::-1], out=tmp_path / "py.exr", surface=surface)
    assert stable(py) == stable(cli)
    assert (tmp_path / "py.exr").read_bytes() == (tmp_path / "cli.exr").read_bytes()
    assert stable(py) == stable(json.loads((tmp_path / "one.json").read_text()))


def test_masking_shards_merge_as_the_cli_merge(tmp_path, surface):
    run = ("trace", "masking", "--surface", surface, "--theta", 60, "--samples", 12288, "--seed", 2)
    parts = shards(tmp_path, run, "m", 3, out_option="--json")
    cli = cli_merge(tmp_path, parts)
    py = microsim.merge(parts[::-1], json=tmp_path / "py.json")
    assert py == json.loads((tmp_path / "py.json").read_text())
    assert stable(py) == stable(cli)
    with pytest.raises(ValueError, match=r"blocks .* are missing"):
        microsim.merge(parts[1:], json=tmp_path / "m.json")
    with pytest.raises(ValueError, match="same file"):
        microsim.merge(parts, json=parts[1])
    with pytest.raises(ValueError, match="no such file"):
        microsim.merge(parts, surface=tmp_path / "absent.exr")
    assert not (tmp_path / "m.json").exists()


def test_validate_shards_merge_as_the_cli_merge(tmp_path):
    run = ("validate", "--sampler", "heitz2018", "--alpha", 0.3, "--theta", 30, "--samples", 140000, "--rows", 9,
           "--seed", 4)
    parts = shards(tmp_path, run, "v", 2, out_option="--json")
    cli = cli_merge(tmp_path, parts)
    py = microsim.merge(parts[::-1])
    assert stable(py) == stable(cli)
    assert py["verdict"] == cli["verdict"] == "pass" and py["p_value"] == cli["p_value"]
    with pytest.raises(ValueError, match=r"blocks .* are in more than one part"):
        microsim.merge([parts[0], parts[1], parts[0]])
    with pytest.raises(ValueError, match="merge into a JSON report"):
        microsim.merge(parts, out=tmp_path / "m.exr")
    assert not (tmp_path / "m.exr").exists()
