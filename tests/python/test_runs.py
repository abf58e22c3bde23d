"""Long calls: the traced oracle (identical to the command line's histogram), progress, the GIL released,
Ctrl-C through the cancel token with the partial result kept, and heightfields."""
import _thread
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
    timer = threading.Timer(0.5, _thread.interrupt_main)  # SIGINT's flag, as Ctrl-C sets it
    timer.start()
    start = time.monotonic()
    with pytest.raises(KeyboardInterrupt) as interrupt:
        microsim.trace_vndf(0.3, 45.0, rays=10 ** 11, seed=1)
    timer.join()
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
