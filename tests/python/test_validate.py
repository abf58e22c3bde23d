"""microsim.validate on numpy arrays: a numpy sampler passes, a broken one is rejected, results are the
command line's for the same data, and bad input raises ValueError with the command line's message."""
import numpy as np
import pytest

import microsim
from conftest import cli_json, heitz2018_numpy, run_cli, view

ALPHA, THETA = (0.3, 0.3), 60.0


def numpy_samples(n, seed, remap=True, alpha=ALPHA, theta=THETA):
    u = np.random.default_rng(seed).random((n, 2))
    return heitz2018_numpy(view(theta), alpha, u, remap=remap)


def test_numpy_heitz2018_passes():
    r = microsim.validate(numpy_samples(200_000, seed=11), ALPHA, THETA)
    assert r.passed, r.failures
    assert r.verdict == "pass" and bool(r)
    assert r.samples == 200_000
    assert set(r.p_values) >= {"chi2_sphere", "chi2_lobe"}
    assert "PASS" in repr(r)


def test_broken_numpy_sampler_is_rejected():
    """The negative control: the same sampler without its disk warp must be rejected."""
    r = microsim.validate(numpy_samples(200_000, seed=11, remap=False), ALPHA, THETA)
    assert not r.passed
    assert r.p_value < 1e-6
    assert r.failures and "REJECTED" in repr(r)
    assert r.worst_cells and r.worst_cells[0]["observed"] != r.worst_cells[0]["expected"]


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_identical_to_cli_on_the_same_npy(tmp_path, dtype):
    samples = numpy_samples(100_000, seed=5).astype(dtype)
    path = tmp_path / "samples.npy"
    np.save(path, samples)
    cli = cli_json(tmp_path, "validate", "--from", path, "--alpha", "0.3", "--theta", "60")
    py = microsim.validate(samples, 0.3, 60.0).to_dict()
    for name, test in cli["tests"].items():
        assert py["tests"][name] == test, name
    for key in ("p_value", "statistic", "dof", "verdict", "samples", "failures"):
        assert py[key] == cli[key], key


def test_layouts_read_in_place_give_the_same_result():
    c = numpy_samples(70_000, seed=3)
    reference = microsim.validate(c, ALPHA, THETA).p_values
    wide = np.zeros((c.shape[0], 5))
    wide[:, 1:4] = c
    for layout in (np.asfortranarray(c), wide[:, 1:4], c.astype(np.float32).astype(np.float64)):
        assert microsim.validate(layout, ALPHA, THETA).p_values == reference
    reversed_rows = microsim.validate(c[::-1], ALPHA, THETA)  # a negative stride: the same multiset
    assert reversed_rows.p_values["chi2_sphere"] == reference["chi2_sphere"]


def fortran_order_of(path):
    with open(path, "rb") as f:
        np.lib.format.read_magic(f)
        return np.lib.format.read_array_header_1_0(f)[1]


def fortran_layouts(table):
    """The same (N, k) table as numpy arrays that np.save writes in Fortran order: column-indexed, a transposed
    stack of columns, asfortranarray."""
    cols = [table[:, j] for j in range(table.shape[1])]
    return {"indexed": table[:, list(range(table.shape[1]))], "stacked": np.stack(cols).T,
            "asfortranarray": np.asfortranarray(table)}


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_fortran_order_files_validate_as_the_c_order_file(tmp_path, dtype):
    """A dump saved in Fortran order, columns x, z, pdf, y: the command line and validate(path) give the C-order
    file's result exactly, and so does validate() on each of those arrays."""
    m = numpy_samples(100_000, seed=6)
    table = np.column_stack([m[:, 0], m[:, 2], microsim.D_v(view(THETA), m, ALPHA), m[:, 1]]).astype(dtype)
    c_path = tmp_path / "c.npy"
    np.save(c_path, table)
    args = ("--alpha", "0.3", "--theta", "60", "--columns", "x,z,pdf,y")
    expected = cli_json(tmp_path, "validate", "--from", c_path, *args)
    assert expected["verdict"] == "pass"
    keys = ("tests", "p_value", "statistic", "dof", "verdict", "samples", "failures", "storage")
    for name, array in fortran_layouts(table).items():
        path = tmp_path / f"{name}.npy"
        np.save(path, array)
        assert fortran_order_of(path), name
        cli = cli_json(tmp_path, "validate", "--from", path, *args)
        py = microsim.validate(path, ALPHA, THETA, columns="x,z,pdf,y").to_dict()
        direct = microsim.validate(array[:, [0, 3, 1]], ALPHA, THETA, pdfs=array[:, 2]).to_dict()
        for key in keys:
            assert cli[key] == expected[key], (name, key)
            assert py[key] == expected[key], (name, key)
            if key != "storage":
                assert direct[key] == expected[key], (name, key)


@pytest.mark.parametrize("dtype", [">f8", ">f4"])
def test_big_endian_files_and_arrays_validate_as_the_native_ones(tmp_path, dtype):
    """numpy writes '>f8' for arr.astype('>f8'): the command line, validate(path) and validate(array) read such a
    file or array (C or Fortran order, a strided view) as its native twin, and a wrong pdf in it is rejected."""
    m = numpy_samples(100_000, seed=7)
    table = np.column_stack([m, microsim.D_v(view(THETA), m, ALPHA)])
    native = table.astype(dtype.replace(">", "<"))
    args = ("--alpha", "0.3", "--theta", "60", "--columns", "x,y,z,pdf")
    np.save(tmp_path / "native.npy", native)
    expected = cli_json(tmp_path, "validate", "--from", tmp_path / "native.npy", *args)
    assert expected["verdict"] == "pass"
    keys = ("tests", "p_value", "statistic", "dof", "verdict", "samples", "failures")
    for name, array in {"c": native.astype(dtype), "fortran": np.asfortranarray(native.astype(dtype))}.items():
        assert array.dtype.byteorder == ">"
        path = tmp_path / f"{name}.npy"
        np.save(path, array)
        cli = cli_json(tmp_path, "validate", "--from", path, *args)
        py = microsim.validate(path, ALPHA, THETA, columns="x,y,z,pdf").to_dict()
        direct = microsim.validate(array[:, :3], ALPHA, THETA, pdfs=array[:, 3]).to_dict()
        for key in keys:
            assert cli[key] == expected[key], (name, key)
            assert py[key] == expected[key], (name, key)
            assert direct[key] == expected[key], (name, key)
    wrong = (native * np.array([1, 1, 1, 1.05], dtype=native.dtype)).astype(dtype)
    assert not microsim.validate(wrong[:, :3], ALPHA, THETA, pdfs=wrong[:, 3]).passed
    np.save(tmp_path / "wrong.npy", wrong)
    assert run_cli("validate", "--from", tmp_path / "wrong.npy", *args, check=False).returncode == 1


def test_a_path_takes_columns_and_refuses_arrays_beside_it(tmp_path):
    m = numpy_samples(10_000, seed=1)
    path = tmp_path / "s.npy"
    np.save(path, np.column_stack([m, np.ones(10_000)]))
    with pytest.raises(ValueError, match="columns names the columns of a sample file"):
        microsim.validate(m, ALPHA, THETA, columns="x,y,z")
    with pytest.raises(ValueError, match="a file's are its own columns"):
        microsim.validate(path, ALPHA, THETA, pdfs=np.ones(10_000))
    with pytest.raises(ValueError, match="the file has 4 column"):
        microsim.validate(str(path), ALPHA, THETA)
    with pytest.raises(ValueError, match="columns: 'x,y'"):
        microsim.validate(path, ALPHA, THETA, columns="x,y")
    with pytest.raises(ValueError, match="missing.npy"):
        microsim.validate(tmp_path / "missing.npy", ALPHA, THETA)
    assert microsim.validate(path, ALPHA, THETA, columns="x,y,z,-").samples == 10_000


def test_returned_pdfs_are_checked():
    wi = view(THETA)
    m = numpy_samples(100_000, seed=4)
    pdfs = microsim.D_v(wi, m, ALPHA)
    assert microsim.validate(m, ALPHA, THETA, pdfs=pdfs).passed
    wrong = microsim.validate(m, ALPHA, THETA, pdfs=pdfs * 1.01)
    assert not wrong.passed and any("pdf" in f for f in wrong.failures)


def test_float32_data_widened_to_float64_gets_float32s_rounding():
    """A float32 sampler's normals and pdfs widened to float64 (numpy's astype) at alpha 1e-4: their weights carry
    float32's rounding (a mean 1e-8 off, se 2e-11), which the E[weight] test allows as it does for a float32 file;
    the same data with pdfs 1e-3 too high is still rejected, by the returned-pdf check (at alpha 1e-4 in float32,
    E[weight] allows D's cancellation in a renderer's pdf, far more than 1e-3 near the peak)."""
    alpha, theta, wi = (1e-4, 1e-4), 60.0, view(60.0)
    u = np.random.default_rng(3).random((200_000, 2))
    m = heitz2018_numpy(wi, alpha, u)
    pdfs = microsim.D_v(wi, m, alpha)
    m32, p32 = m.astype(np.float32).astype(np.float64), pdfs.astype(np.float32).astype(np.float64)
    widened = microsim.validate(m32, alpha, theta, pdfs=p32)
    assert widened.passed, widened.failures
    wrong = microsim.validate(m32, alpha, theta, pdfs=(pdfs * 1.001).astype(np.float32).astype(np.float64))
    assert not wrong.passed and wrong.to_dict()["tests"]["returned_pdf"]["passed"] is False


def test_identical_to_cli_for_a_zoo_sampler(tmp_path):
    cli = cli_json(tmp_path, "validate", "--sampler", "heitz2018", "--alpha", "0.05,0.5", "--theta", "75",
                   "--samples", "100000", "--seed", "9")
    py = microsim.validate_sampler("heitz2018", (0.05, 0.5), 75.0, samples=100_000, seed=9).to_dict()
    for key in ("p_value", "statistic", "dof", "verdict", "tests"):
        assert py[key] == cli[key], key
    talk = microsim.validate_sampler("heitz2018-talk", 0.3, 60.0, samples=100_000, seed=9)
    assert not talk.passed  # the zoo's negative control


def test_nan_rows_are_the_samplers_failures():
    s = numpy_samples(50_000, seed=2)
    s[[7, 100]] = np.nan
    r = microsim.validate(s, ALPHA, THETA)
    assert not r.passed
    assert any("row 7 (0-based)" in f for f in r.failures), r.failures


@pytest.mark.parametrize("bad, expected", [
    (np.zeros((10, 2)), "shape (10, 2) is not supported"),
    (np.zeros(30), "shape (30,) is not supported"),
    (np.zeros((10, 3), dtype=np.int64), "dtype int64 is not supported"),
    (np.zeros((0, 3)), "empty"),
    ([[0, 0, 1]], "expected a numpy array"),
    (np.zeros((10, 3), dtype=np.float16), "dtype float16 is not supported"),
])
def test_bad_arrays(bad, expected):
    with pytest.raises(ValueError, match=expected.replace("(", r"\(").replace(")", r"\)")):
        microsim.validate(bad, ALPHA, THETA)


@pytest.mark.parametrize("kwargs, expected", [
    (dict(alpha=0.0), "alpha"), (dict(alpha=-0.3), "alpha"), (dict(alpha=(0.3, 0.3, 0.3)), "pair"),
    (dict(theta=95.0), "theta must be in"), (dict(theta=float("nan")), "theta must be in"),
    (dict(phi=float("inf")), "phi must be finite"), (dict(pdf="foo"), "vndf"),
    (dict(rows=4), "rows must be odd"), (dict(significance=1.5), "significance"),
    (dict(above_horizon=True), "above_horizon"),
    (dict(pdf="reflection", above_horizon=True, dropped=-3), r"dropped must be a count of samples \(>= 0\), got -3"),
])
def test_bad_arguments(kwargs, expected):
    args = dict(samples=numpy_samples(1000, seed=1), alpha=ALPHA, theta=THETA) | kwargs
    with pytest.raises(ValueError, match=expected):
        microsim.validate(**args)


def test_non_unit_row_message_is_the_clis(tmp_path):
    s = numpy_samples(1000, seed=1)
    s[3] *= 2
    path = tmp_path / "bad.npy"
    np.save(path, s)
    cli = run_cli("validate", "--from", path, "--alpha", "0.3", "--theta", "60", check=False)
    assert cli.returncode == 2
    with pytest.raises(ValueError) as error:
        microsim.validate(s, ALPHA, THETA)
    message = str(error.value)
    assert message.startswith("samples: row 3 (0-based): vector")
    assert message.split(": ", 1)[1] in cli.stderr  # the same words after the name of the source


def test_too_few_samples():
    with pytest.raises(ValueError, match="samples"):
        microsim.validate(numpy_samples(5, seed=1), ALPHA, THETA)


def mirror_reflections(n, seed):
    """Reflections of VNDF-sampled normals off mirror facets: directions, returned pdfs, weights f cos / pdf."""
    wi = view(THETA)
    m = numpy_samples(n, seed)
    wo = 2 * (m @ wi)[:, None] * m - wi
    pdfs = microsim.reflection_pdf(wi, wo, ALPHA)
    weights = np.where(wo[:, 2] > 0, microsim.mirror_brdf(wi, wo, ALPHA) * np.abs(wo[:, 2]) / pdfs, 0.0)
    return wo, pdfs, weights


def test_weights_against_the_bsdf_identical_to_cli(tmp_path):
    wo, pdfs, weights = mirror_reflections(100_000, seed=8)
    path = tmp_path / "rows.npy"
    np.save(path, np.column_stack([wo, pdfs, weights]))
    cli = cli_json(tmp_path, "validate", "--from", path, "--alpha", "0.3", "--theta", "60", "--reflected",
                   "--columns", "x,y,z,pdf,weight", "--bsdf", "mirror")
    py = microsim.validate(wo, ALPHA, THETA, pdf="reflection", weights=weights, pdfs=pdfs, bsdf="mirror")
    assert py.passed and cli["verdict"] == "pass"
    assert py.to_dict()["tests"] == cli["tests"]
    from_path = microsim.validate(path, ALPHA, THETA, pdf="reflection", columns="x,y,z,pdf,weight", bsdf="mirror")
    assert from_path.to_dict()["tests"] == cli["tests"]
    assert "bsdf_albedo" in py.p_values


def test_wrong_weights_are_rejected():
    wo, pdfs, weights = mirror_reflections(100_000, seed=8)
    r = microsim.validate(wo, ALPHA, THETA, pdf="reflection", weights=1.05 * weights, bsdf="mirror")
    assert not r.passed and r.p_values["bsdf_albedo"] < 1e-6
    with pytest.raises(ValueError, match="weights need bsdf"):
        microsim.validate(wo, ALPHA, THETA, pdf="reflection", weights=weights)
    with pytest.raises(ValueError, match="pdf='bsdf' is the sampling density of a BSDF"):
        microsim.validate(wo, ALPHA, THETA, pdf="bsdf")
    with pytest.raises(ValueError, match="dielectric"):
        microsim.validate(wo, ALPHA, THETA, pdf="reflection", bsdf="dielectric:1.5", weights=weights)
    with pytest.raises(ValueError, match="channel"):
        microsim.validate(wo, ALPHA, THETA, pdf="reflection", weights=np.column_stack([weights, weights]), bsdf="mirror")


def test_against_the_traced_oracle_identical_to_cli(tmp_path):
    samples = numpy_samples(100_000, seed=12)
    path = tmp_path / "samples.npy"
    np.save(path, samples)
    cli = cli_json(tmp_path, "validate", "--from", path, "--alpha", "0.3", "--theta", "60", "--against", "ellipsoid",
                   "--rays", "400000")
    py = microsim.validate(samples, ALPHA, THETA, against="ellipsoid", oracle_rays=400_000)
    assert py.to_dict()["tests"] == cli["tests"] and py.passed
    hist = tmp_path / "h.exr"
    run_cli("trace", "vndf", "--alpha", "0.3", "--theta", "60", "--rays", "400000", "--out", hist)
    from_file = microsim.validate(samples, ALPHA, THETA, against=str(hist))
    assert from_file.passed
    broken = microsim.validate(numpy_samples(100_000, seed=12, remap=False), ALPHA, THETA, against=str(hist))
    assert not broken.passed
    with pytest.raises(ValueError, match="pdf='vndf'"):
        microsim.validate(samples, ALPHA, THETA, pdf="ndf", against="ellipsoid")


def dielectric_samples(n, seed, eta=1.5):
    """A rough dielectric's sample(): a visible normal (Heitz 2018), then reflection with the Fresnel
    probability, else refraction (Walter et al. 2007, eq. 40)."""
    rng = np.random.default_rng(seed)
    wi = view(THETA)
    m, _ = microsim.sample("heitz2018", wi, ALPHA, rng.random((n, 2)))
    c = m @ wi
    sin_t2 = (1 - c ** 2) / eta ** 2
    cos_t = np.sqrt(np.maximum(0.0, 1 - sin_t2))
    rs, rp = (c - eta * cos_t) / (c + eta * cos_t), (eta * c - cos_t) / (eta * c + cos_t)
    fresnel = np.where(sin_t2 >= 1, 1.0, 0.5 * (rs ** 2 + rp ** 2))
    reflected = 2 * c[:, None] * m - wi
    refracted = -wi / eta + (c / eta - cos_t)[:, None] * m
    is_reflected = rng.random(n) < fresnel
    wo = np.where(is_reflected[:, None], reflected, refracted)
    kept = np.where(is_reflected, wo[:, 2] > 0, wo[:, 2] < 0)  # a renderer drops the others
    return wo[kept], int(n - kept.sum())


def test_a_dielectric_dump_identical_to_cli(tmp_path):
    wo, lost = dielectric_samples(100_000, seed=21)
    path = tmp_path / "glass.npy"
    np.save(path, wo)
    cli = cli_json(tmp_path, "validate", "--from", path, "--alpha", "0.3", "--theta", "60", "--pdf", "bsdf",
                   "--bsdf", "dielectric", "--eta", "1.5", "--above-horizon", "--dropped", lost, "--rows", "15")
    py = microsim.validate(wo, ALPHA, THETA, pdf="bsdf", bsdf="dielectric:1.5", above_horizon=True, dropped=lost,
                           rows=15)  # 15 rows: a cheaper cubature of the dielectric's density
    assert py.to_dict()["tests"] == cli["tests"] and py.passed, py.failures
    wrong, wrong_lost = dielectric_samples(100_000, seed=21, eta=1.3)
    assert not microsim.validate(wrong, ALPHA, THETA, pdf="bsdf", bsdf="dielectric:1.5", above_horizon=True,
                                 dropped=wrong_lost, rows=15).passed  # the wrong index: rejected


def test_directions_printed_too_coarsely_for_the_lobe_get_a_hint(tmp_path):
    """Correct normals at alpha 0.01 printed with 4 decimals: the rounding (5e-5) is a sixth of a lobe bin, the
    chi-square rejects them (level 0.01) and the hint says to print more digits; printed with %.9g they pass."""
    wi = np.array([0.0, 0.0, 1.0])
    d, p = microsim.sample("heitz2018", wi, 0.01, np.random.default_rng(11).random((200_000, 2)))
    coarse, fine = tmp_path / "coarse.txt", tmp_path / "fine.txt"
    np.savetxt(coarse, np.column_stack([d, p]), fmt="%.4f")
    np.savetxt(fine, np.column_stack([d, p]), fmt="%.9g")
    r = microsim.validate(str(coarse), 0.01, 0.0, columns="x,y,z,pdf")
    assert not r.passed
    assert any("print them with more digits" in h and "within 5.0e-05 in most rows" in h for h in r.hints), r.hints
    assert microsim.validate(str(fine), 0.01, 0.0, columns="x,y,z,pdf").passed


@pytest.mark.parametrize("d_form", ["pbrt", "ue4"])
@pytest.mark.parametrize("alpha", [0.01, 1e-3])
def test_a_float32_dumps_pdfs_with_d_from_cos_theta_pass_and_a_planted_error_is_rejected(tmp_path, d_form, alpha):
    """A float32 renderer's reflections with the pdfs it returns, D computed from cos theta_m as pbrt-v4 and Karis
    2013 do (1 - cos^2 cancels near the peak: 0.4% at alpha 0.01, 28% at 1e-3): the returned-pdf check allows that
    loss and passes them; the same pdfs 0.1% too high are rejected."""
    import pathlib
    import sys
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "examples"))
    from renderer_eval import ggx_d

    a = np.float32(alpha)
    wi = view(40.0).astype(np.float32)
    m = numpy_samples(200_000, seed=3, alpha=(alpha, alpha), theta=40.0).astype(np.float32)
    wo = (2 * (m @ wi)[:, None] * m - wi).astype(np.float32)
    h = wi + wo
    h = h / np.linalg.norm(h, axis=1)[:, None]
    t2 = (wi[0] ** 2 + wi[1] ** 2) / wi[2] ** 2
    g1 = 2 / (1 + np.sqrt(1 + a * a * t2))
    pdf = g1 * ggx_d(h, a, d_form) / (4 * wi[2])  # D_wi(h) / (4 |wo.h|) with |wo.h| = |wi.h|
    kept = wo[:, 2] > 0
    for scale, passes in ((1.0, True), (1.001, False)):
        path = tmp_path / f"dump-{scale}.npy"
        np.save(path, np.column_stack([wo, pdf * np.float32(scale)])[kept].astype(np.float32))
        r = microsim.validate(path, (alpha, alpha), 40.0, pdf="reflection", columns="x,y,z,pdf", above_horizon=True)
        check = r.to_dict()["tests"]["returned_pdf"]
        assert check["passed"] is passes, (scale, check["detail"])


@pytest.mark.parametrize("d_form", ["pbrt", "ue4"])
def test_float32_normals_with_pdfs_from_cos_theta_pass_e_weight_and_a_planted_error_is_rejected(tmp_path, d_form):
    """The same for VNDF normals with their pdfs at alpha 0.01: Karis' form biases the mean weight D <wi, m> / pdf by
    1.6e-4 (rejected by E[weight] at p 1e-54 before it allowed D's cancellation); a pdf 0.1% too high is still
    rejected."""
    import pathlib
    import sys
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "examples"))
    from renderer_eval import ggx_d

    a = np.float32(0.01)
    wi = view(40.0).astype(np.float32)
    m = numpy_samples(1_000_000, seed=1, alpha=(0.01, 0.01), theta=40.0).astype(np.float32)
    t2 = (wi[0] ** 2 + wi[1] ** 2) / wi[2] ** 2
    g1 = 2 / (1 + np.sqrt(1 + a * a * t2))
    pdf = g1 * ggx_d(m, a, d_form) * np.maximum(m @ wi, 0) / wi[2]
    for scale, passes in ((1.0, True), (1.001, False)):
        path = tmp_path / f"normals-{scale}.npy"
        np.save(path, np.column_stack([m, pdf * np.float32(scale)]).astype(np.float32))
        r = microsim.validate(path, (0.01, 0.01), 40.0, columns="x,y,z,pdf")
        assert r.passed is passes, (scale, r.failures)
