"""The analytic GGX functions and the zoo's samplers on arrays."""
import numpy as np
import pytest

import microsim
from conftest import heitz2018_numpy, view


def sphere_grid(n=400):
    """Midpoint quadrature of the unit sphere in (cos theta, phi): directions and their solid angles."""
    z = -1 + (np.arange(n) + 0.5) * 2 / n
    phi = (np.arange(2 * n) + 0.5) * np.pi / n
    zz, pp = np.meshgrid(z, phi, indexing="ij")
    r = np.sqrt(1 - zz ** 2)
    w = np.stack([r * np.cos(pp), r * np.sin(pp), zz], axis=-1).reshape(-1, 3)
    return w, (2 / n) * (np.pi / n)


@pytest.mark.parametrize("alpha", [0.5, (0.4, 0.8)])
def test_normalisations(alpha):
    m, dw = sphere_grid()
    upper = m[:, 2] > 0
    assert np.sum(microsim.D(m[upper], alpha) * m[upper, 2]) * dw == pytest.approx(1, abs=2e-3)
    wi = view(50.0, 30.0)
    assert np.sum(microsim.D_v(wi, m, alpha)) * dw == pytest.approx(1, abs=2e-3)
    assert np.sum(microsim.reflection_pdf(wi, m, alpha)) * dw == pytest.approx(1, abs=2e-2)


def test_smith_relations():
    w = np.array([view(t, 20.0) for t in (0.0, 30.0, 60.0, 85.0)])
    assert np.allclose(microsim.G1(w, 0.3), 1 / (1 + microsim.Lambda(w, 0.3)))
    assert microsim.Lambda(view(0.0), 0.3)[0] == 0.0
    g2 = microsim.G2(w, w[::-1], 0.3)
    assert np.all(g2 <= np.minimum(microsim.G1(w, 0.3), microsim.G1(w[::-1], 0.3)) + 1e-15)


def test_brdfs_on_arrays():
    wi, wo = view(40.0), np.array([view(t, 180.0) for t in (10.0, 40.0, 70.0)])
    mirror = microsim.mirror_brdf(wi, wo, 0.3)
    assert mirror.shape == (3,) and np.all(mirror > 0)
    gold = microsim.conductor_brdf(wi, wo, 0.3, complex(0.2, 3.9))
    assert np.all(gold < mirror) and np.all(gold > 0.5 * mirror)
    below = np.array([view(t, 180.0) for t in (10.0, 20.0, 25.0)]) * [1, 1, -1]  # around the refracted 25 deg
    assert np.all(microsim.dielectric_bsdf(wi, below, 0.3, 1.5) > 0)


def test_shapes_and_broadcasting():
    with pytest.raises(ValueError, match="shape"):
        microsim.D(np.zeros((4, 2)), 0.3)
    with pytest.raises(ValueError, match="rows"):
        microsim.G2(np.zeros((2, 3)), np.zeros((3, 3)), 0.3)
    with pytest.raises(ValueError, match="alpha"):
        microsim.G1(view(10.0), 0.0)
    assert microsim.D(np.array([[0, 0, 1]], dtype=np.float32), 0.5).dtype == np.float64


def test_sample_matches_numpy_and_claims_D_v():
    wi, alpha = view(60.0, 10.0), (0.2, 0.6)
    u = np.random.default_rng(1).random((10_000, 2))
    m, pdf = microsim.sample("heitz2018", wi, alpha, u)
    assert m.shape == (10_000, 3) and pdf.shape == (10_000,)
    assert np.allclose(m, heitz2018_numpy(wi, alpha, u), atol=1e-9)
    assert np.allclose(pdf, microsim.D_v(wi, m, alpha), rtol=1e-9)
    assert microsim.validate(microsim.sample("dupuy2023", wi, alpha, np.random.default_rng(2).random((100_000, 2)))[0],
                             alpha, 60.0, 10.0).passed


def test_sample_errors():
    with pytest.raises(ValueError, match="unknown sampler 'nope'"):
        microsim.sample("nope", view(0.0), 0.3, np.zeros((1, 2)))
    with pytest.raises(ValueError, match="shape"):
        microsim.sample("heitz2018", view(0.0), 0.3, np.zeros((5, 3)))
    assert "heitz2018" in microsim.sampler_names()


def test_lists_are_converted_and_checked():
    assert microsim.D([0, 0, 1], 0.5)[0] == pytest.approx(1 / (np.pi * 0.25))  # D(n) = 1 / (pi alpha^2)
    with pytest.raises(ValueError, match="shape"):
        microsim.sample("heitz2018", [0, 0, 1], 0.3, [0.5, 0.5])  # u must be (N, 2)
    with pytest.raises(ValueError, match="not supported"):  # a string: a numpy array of text
        microsim.G1("up", 0.3)


def test_float_samplers():
    wi, u = view(30.0), np.random.default_rng(3).random((1000, 2))
    m64, _ = microsim.sample("dupuy2023", wi, 0.4, u)
    m32, pdf32 = microsim.sample("dupuy2023", wi, 0.4, u, precision="float")
    assert np.allclose(m32, m64, atol=1e-5) and not np.array_equal(m32, m64)
    assert np.allclose(pdf32, microsim.D_v(wi, m64, 0.4), rtol=1e-3)
