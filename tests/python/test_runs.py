"""Long calls: the traced oracle (identical to the command line's histogram), progress, the GIL released,
Ctrl-C through the cancel token with the partial result kept, and heightfields."""
import _thread
import signal
import threading
import time

import numpy as np
import pytest

import microsim
from conftest import run_cli


def test_trace_vndf_identical_to_cli(tmp_path):
    out = tmp_path / "h.exr"
    run_cli("trace", "vndf", "--alpha", "0.3", "--theta", "60", "--rays", "300000", "--seed", "4", "--out", out)
    cli = microsim.read_histogram(str(out))
    py = microsim.trace_vndf(0.3, 60.0, rays=300_000, seed=4)
    assert py["hits"] == cli["hits"] and py["rays"] == cli["rays"]
    for name in ("sphere", "lobe"):
        assert np.array_equal(py["binnings"][name]["counts"], cli["binnings"][name]["counts"]), name
    other_seed = microsim.trace_vndf(0.3, 60.0, rays=300_000, seed=5)
    assert not np.array_equal(other_seed["binnings"]["lobe"]["counts"], py["binnings"]["lobe"]["counts"])


def test_trace_bin_geometry():
    h = microsim.trace_vndf(0.5, 30.0, rays=200_000, seed=1, rows=11)
    sphere, lobe = h["binnings"]["sphere"], h["binnings"]["lobe"]
    assert sphere["counts"].shape == (11, 22) and sphere["centres"].shape == (11, 22, 3)
    assert sphere["solid_angle"].sum() == pytest.approx(4 * np.pi, rel=1e-6)
    assert np.allclose(sphere["solid_angle"], 4 * np.pi / 242)
    assert lobe["solid_angle"].sum() == pytest.approx(2 * np.pi, rel=1e-4)  # the upper hemisphere of normals
    assert np.allclose(np.linalg.norm(lobe["centres"], axis=-1), 1)
    assert lobe["counts"].sum() == h["hits"]
    # The traced density against D_v at the centres of the lobe bins where it is well sampled.
    density = lobe["counts"] / (h["hits"] * lobe["solid_angle"])
    d_v = microsim.D_v([np.sin(np.radians(30)), 0, np.cos(np.radians(30))], lobe["centres"].reshape(-1, 3), 0.5)
    assert np.sum(np.abs(density.ravel() - d_v) * lobe["solid_angle"].ravel()) < 0.05


def test_progress_and_gil_released():
    reports, ticks = [], []
    stop = threading.Event()

    def ticker():
        while not stop.is_set():
            ticks.append(1)
            time.sleep(0.005)

    t = threading.Thread(target=ticker)
    t.start()
    microsim.trace_vndf(0.3, 45.0, rays=3_000_000, seed=1, progress=lambda *r: reports.append(r))
    stop.set()
    t.join()
    assert reports and reports[-1][1] == reports[-1][2]  # the last report: all done
    assert all(isinstance(stage, str) for stage, _, _ in reports)
    assert len(ticks) > 5  # another Python thread ran during the call


def test_ctrl_c_cancels_and_keeps_the_partial_result():
    # Python's own SIGINT handler for the call: a shell's background job starts with SIGINT ignored, where
    # interrupt_main does nothing and the call would run its 1e11 rays.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    timer = threading.Timer(0.5, _thread.interrupt_main)  # SIGINT's flag, as Ctrl-C sets it
    try:
        timer.start()
        start = time.monotonic()
        with pytest.raises(KeyboardInterrupt) as interrupt:
            microsim.trace_vndf(0.3, 45.0, rays=10 ** 11, seed=1)
        timer.join()
    finally:
        signal.signal(signal.SIGINT, previous)
    assert time.monotonic() - start < 30
    partial = interrupt.value.partial_result
    assert partial["partial"] and 0 < partial["rays"] < 10 ** 11
    assert partial["binnings"]["sphere"]["counts"].sum() == partial["hits"]


def test_an_exception_in_the_callback_cancels_the_run():
    def stop(stage, done, total):
        raise KeyboardInterrupt("stop")

    with pytest.raises(KeyboardInterrupt, match="stop"):
        microsim.validate_sampler("heitz2018", 0.3, 60.0, samples=10 ** 10, progress=stop)


def test_heightfield_from_numpy_and_back(tmp_path):
    heights = np.random.default_rng(0).normal(size=(32, 32)).astype(np.float32)
    f = microsim.Heightfield(heights, 2.0)
    assert f.resolution == 32 and f.tile_size == 2.0
    view = f.heights
    assert np.array_equal(view, heights) and not view.flags.writeable
    path = tmp_path / "surface.exr"
    f.save(str(path))
    g = microsim.load_heightfield(str(path))
    assert np.array_equal(g.heights, heights) and g.tile_size == 2.0
    with pytest.raises(ValueError, match="square"):
        microsim.Heightfield(np.zeros((4, 8), dtype=np.float32), 1.0)


def test_build_surface_and_trace_it_identical_to_cli(tmp_path):
    surface = tmp_path / "s.exr"
    run_cli("surface", "build", "--assembly", "smith", "--alpha", "0.3", "--res", "256", "--seed", "3", "--out", surface)
    built = microsim.build_surface("smith", 0.3, resolution=256, seed=3)
    loaded = microsim.load_heightfield(str(surface))
    assert np.array_equal(built.heights, loaded.heights)
    assert built.metadata["assembly"] == "smith"
    assert not np.array_equal(microsim.build_surface("smith", 0.3, resolution=256, seed=4).heights, built.heights)
    out = tmp_path / "h.exr"
    run_cli("trace", "vndf", "--surface", surface, "--theta", "40", "--rays", "100000", "--seed", "2", "--out", out)
    cli = microsim.read_histogram(str(out))
    py = microsim.trace_surface_vndf(built, 40.0, rays=100_000, seed=2)
    assert py["hits"] == cli["hits"] > 0
    for name in ("sphere", "lobe"):
        assert np.array_equal(py["binnings"][name]["counts"], cli["binnings"][name]["counts"]), name


def test_build_surface_refuses_what_it_cannot_build():
    with pytest.raises(ValueError, match="resolution"):
        microsim.build_surface("smith", 0.3, resolution=100)
    with pytest.raises(ValueError, match="resolution 64"):
        microsim.build_surface("smith", 0.3, resolution=64)  # outside the supported range
    assert microsim.build_surface("smith", 0.3, resolution=64, check_range=False).resolution == 64
    with pytest.raises(ValueError, match="nope"):
        microsim.build_surface("nope", 0.3, resolution=256)


def test_masking_identical_to_cli(tmp_path):
    surface = tmp_path / "s.exr"
    run_cli("surface", "build", "--assembly", "smith", "--alpha", "0.5", "--res", "256", "--seed", "1", "--out", surface)
    out = tmp_path / "m.json"
    run_cli("trace", "masking", "--surface", surface, "--theta", "70", "--samples", "50000", "--seed", "6",
            "--theta-l", "40", "--json", out)
    import json
    cli = json.loads(out.read_text())["masking"]
    py = microsim.masking(microsim.load_heightfield(str(surface)), 70.0, samples=50_000, seed=6, theta_l=40.0)
    for key in ("g1", "lambda_smith_analytic", "g1_smith_analytic", "g1_given_normal", "g1_given_height", "g2_pair"):
        assert py[key] == cli[key], key
    assert abs(py["g1"]["value"] - py["g1_smith_analytic"]) < 5 * py["g1"]["stderr"] + 0.02
    with pytest.raises(ValueError, match="theta"):
        microsim.masking(microsim.load_heightfield(str(surface)), 90.0)


def test_smith_walk_identical_to_cli(tmp_path):
    import json
    out = tmp_path / "w.json"
    run_cli("scatter", "--model", "smith-walk", "--alpha", "0.5", "--theta", "40", "--material", "conductor:0.2,3.9",
            "--rays", "50000", "--seed", "3", "--out", tmp_path / "w.exr", "--json", out)
    cli = json.loads(out.read_text())
    py = microsim.smith_walk(0.5, 40.0, material="conductor:0.2,3.9", rays=50_000, seed=3)
    assert py["summary"]["channels"] == cli["channels"]
    assert py["paths"] == 50_000 and not py["partial"]
    order1 = py["summary"]["channels"][0]["albedo"]["order1"]["both"]["value"]
    assert py["mean_weight"][0, 0].sum() == pytest.approx(order1, rel=1e-12)
    assert py["binning"]["solid_angle"].sum() == pytest.approx(4 * np.pi, rel=1e-9)
    with pytest.raises(ValueError, match="light from below needs a dielectric"):
        microsim.smith_walk(0.5, 120.0)
    with pytest.raises(ValueError, match="material"):
        microsim.smith_walk(0.5, 40.0, material="gold")


def test_smith_walk_lanes_kernel():
    # walk_kernel='lanes' runs the SIMD walk: other random numbers (another histogram for the same seed), the same
    # walk (total albedo within 4 standard errors of the difference; fixed seed); unsupported cases are refused.
    scalar = microsim.smith_walk((0.4, 0.7), 70.0, material="conductor:0.2,3.9", rays=16384, seed=5, rows=2)
    lanes = microsim.smith_walk((0.4, 0.7), 70.0, material="conductor:0.2,3.9", rays=16384, seed=5, rows=2,
                                walk_kernel="lanes")
    es = scalar["summary"]["channels"][0]["albedo"]["total"]["both"]
    el = lanes["summary"]["channels"][0]["albedo"]["total"]["both"]
    assert el["value"] != es["value"]
    assert abs(el["value"] - es["value"]) < 4 * np.hypot(el["standard_error"], es["standard_error"])
    with pytest.raises(ValueError, match="lanes"):
        microsim.smith_walk(0.5, 40.0, ndf="beckmann", rays=100, walk_kernel="lanes")
    with pytest.raises(ValueError, match="walk kernel"):
        microsim.smith_walk(0.5, 40.0, rays=100, walk_kernel="simd")
    table = microsim.albedo_table(model="smith-walk", alphas=[0.5], mus=2, paths=1000, walk_kernel="lanes")
    assert table["walk_kernel"] == "lanes"
    with pytest.raises(ValueError, match="lanes"):
        microsim.albedo_table(model="analytic", alphas=[0.5], mus=2, walk_kernel="lanes")


def test_scatter_on_a_surface_identical_to_cli(tmp_path):
    import json
    surface = tmp_path / "s.exr"
    run_cli("surface", "build", "--assembly", "smith", "--alpha", "0.5", "--res", "256", "--seed", "1", "--out", surface)
    out = tmp_path / "t.json"
    run_cli("scatter", "--surface", surface, "--theta", "60", "--rays", "20000", "--seed", "2",
            "--out", tmp_path / "t.exr", "--json", out)
    cli = json.loads(out.read_text())
    py = microsim.scatter_surface(microsim.load_heightfield(str(surface)), 60.0, rays=20_000, seed=2)
    assert py["summary"]["channels"] == cli["channels"]
    total = py["summary"]["channels"][0]["albedo"]["total"]["both"]["value"]
    assert total == pytest.approx(1, abs=1e-3)  # a mirror surface loses nothing


def test_interrupted_walk_keeps_its_blocks():
    calls = []

    def stop_after_some(stage, done, total):
        calls.append(done)
        if done > 0:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt) as interrupt:
        microsim.smith_walk(0.5, 40.0, rays=10 ** 11, seed=1, progress=stop_after_some)
    partial = interrupt.value.partial_result
    assert partial["partial"] and 0 < partial["paths"] < 10 ** 11 and partial["paths"] % 4096 == 0


def test_analytic_scatter_identical_to_cli_and_estimated_by_the_walk(tmp_path):
    import json
    out = tmp_path / "a.json"
    run_cli("scatter", "--model", "analytic", "--alpha", "0.5", "--theta", "40", "--material", "dielectric:1.5",
            "--rows", "8", "--out", tmp_path / "a.exr", "--json", out)  # 8 rows: a cheaper cubature
    cli = json.loads(out.read_text())
    exact = microsim.analytic_scatter(0.5, 40.0, material="dielectric:1.5", rows=8)
    assert exact["summary"]["channels"] == cli["channels"]
    walk = microsim.smith_walk(0.5, 40.0, material="dielectric:1.5", rays=200_000, seed=1, rows=8)
    estimate, error = walk["mean_weight"][0, 0], walk["stderr"][0, 0]
    expected = exact["order1"][0]
    busy = expected > 1e-3  # bins with enough weight for a normal approximation
    z = (estimate[busy] - expected[busy]) / np.maximum(error[busy], 1e-12)
    assert np.mean(z ** 2) < 1.5  # Monte Carlo noise only (about 1)
    wrong = microsim.analytic_scatter(0.5, 40.0, material="dielectric:1.6", rows=8)["order1"][0]
    assert np.mean(((estimate[busy] - wrong[busy]) / np.maximum(error[busy], 1e-12)) ** 2) > 1.5  # a control
