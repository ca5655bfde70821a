"""UniformDisk, UniformTriangle and UniformBox: normalization, chi-square, inverses, Jacobians, edges."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from helpers import WrongWarp, assert_finite, check_finite_at_edges, edge_uniforms, run_chi2
from jaxsample.samplers.box import UniformBox
from jaxsample.samplers.disk import UniformDisk
from jaxsample.checks.sampler_checks import inverse_error, jacobian_error, normalization
from jaxsample.samplers.transformed import Transformed
from jaxsample.checks.domains import Disk
from jaxsample import domains as js_domains

# Chi-square tests in this file, run as one family at overall false-failure rate 1e-6.
N_CHI2 = 8

TRIANGLE_2D = ([0.0, 0.0], [1.0, 0.2], [0.3, 1.0])
TRIANGLE_3D = ([0.0, 0.0, 1.0], [1.0, 0.2, 0.0], [0.3, 1.0, 2.0])
# Area 1e-12 of |edge|², tilted so that no coordinate axis helps.
THIN_2D = ([0.0, 0.0], [1.0, 1.0], [0.5, 0.5 + 2e-12])
THIN_3D = ([0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [0.5, 0.5 + 2e-12, 0.5])


def triangle(vertices, dtype=None):
    from jaxsample.samplers.triangle import UniformTriangle
    return UniformTriangle(*(jnp.asarray(v, dtype) for v in vertices))


def _shrunk_radius(p):
    # r = s^0.46 instead of s^0.5: slightly too much mass near the rim.
    return jnp.power(p[0], 0.46) * jnp.stack([jnp.cos(p[1]), jnp.sin(p[1])])


def _disk_to_polar(y):
    return jnp.stack([jnp.sum(y * y) ** (1 / 0.92), jnp.mod(jnp.arctan2(y[1], y[0]), 2 * np.pi)])


def _concentric():
    return UniformDisk("concentric")


def _polar():
    return UniformDisk("polar")


def _rejection():
    return UniformDisk("rejection", tries=3)


_DISK_MAKERS = {"concentric": _concentric, "polar": _polar, "rejection": _rejection}

SAMPLERS = {
    "disk-concentric": lambda: UniformDisk(),
    "disk-polar": lambda: UniformDisk("polar"),
    "disk-rejection": lambda: UniformDisk("rejection", tries=4),
    "triangle-2d": lambda: triangle(TRIANGLE_2D),
    "triangle-3d": lambda: triangle(TRIANGLE_3D),
    "box": lambda: UniformBox(jnp.array([-1.0, 0.5]), jnp.array([2.0, 0.75])),
}


@pytest.mark.parametrize("name", SAMPLERS)
def test_normalization(name):
    assert abs(normalization(SAMPLERS[name]()) - 1.0) < 1e-6


@pytest.mark.parametrize("vertices", [THIN_2D, THIN_3D])
def test_thin_triangle_normalization_and_samples(vertices):
    with jax.enable_x64(True):
        sampler = triangle(vertices, jnp.float64)
        assert abs(normalization(sampler) - 1.0) < 1e-6
        x, p = sampler.sample_with_pdf(jax.random.key(3), (2000,))
        assert np.all(js_domains.contains(sampler.domain(), np.asarray(x)))
        np.testing.assert_allclose(sampler.pdf(x), p, rtol=1e-12)


def test_chi2_passes():
    keys = jax.random.split(jax.random.key(10), 6)
    for key, name in zip(keys, SAMPLERS):
        result = run_chi2(SAMPLERS[name](), key, N_CHI2)
        assert result.passed, (name, result)


def test_chi2_thin_triangle_float64():
    with jax.enable_x64(True):
        result = run_chi2(triangle(THIN_3D, jnp.float64), jax.random.key(11), N_CHI2)
    assert result.passed, result


def test_chi2_fails_for_wrong_samplers():
    truth = UniformDisk("polar")
    impostor = Transformed(UniformBox(jnp.array([0.0, 0.0]), jnp.array([1.0, 2 * np.pi])),
                           _shrunk_radius, _disk_to_polar, domain=Disk())
    # At the suite's sample size (run_chi2's 10^5) and by a margin: p < 1e-15 where the threshold is
    # 1.3e-7 (seen over keys: below 1e-80 for both wrong samplers here).
    result = run_chi2(WrongWarp(truth, impostor), jax.random.key(12), N_CHI2)
    assert not result.passed and result.p_value < 1e-15, result
    # Vertex c pulled 5 % toward the centroid: samples stay inside, the density is wrong.
    a, b, c = (np.array(v) for v in TRIANGLE_2D)
    centroid = (a + b + c) / 3
    inner = triangle((a, b, c + 0.05 * (centroid - c)))
    result = run_chi2(WrongWarp(triangle(TRIANGLE_2D), inner), jax.random.key(13), N_CHI2)
    assert not result.passed and result.p_value < 1e-15, result


@pytest.mark.parametrize("name", ["disk-concentric", "disk-polar", "triangle-2d", "triangle-3d", "box"])
def test_inverse_round_trip(name):
    sampler = SAMPLERS[name]()
    u = jax.random.uniform(jax.random.key(20), (4096, 2), minval=1e-3, maxval=1 - 1e-3)
    assert float(jnp.max(inverse_error(sampler, u))) < 2e-4
    with jax.enable_x64(True):
        u64 = jnp.asarray(np.asarray(u), jnp.float64)
        assert float(jnp.max(inverse_error(jax.tree_util.tree_map(lambda t: jnp.asarray(t, jnp.float64), sampler), u64))) < 1e-9


@pytest.mark.parametrize("name", ["disk-concentric", "disk-polar", "triangle-2d", "triangle-3d", "box"])
def test_jacobian_matches_density(name):
    u = jax.random.uniform(jax.random.key(21), (2048, 2), minval=1e-3, maxval=1 - 1e-3)
    assert float(jnp.max(jacobian_error(SAMPLERS[name](), u))) < 1e-3


def test_concentric_gradient_finite_on_axes_and_centre():
    disk = UniformDisk()
    u = jnp.array([[0.5, 0.5], [0.5, 0.2], [0.5, 0.9], [0.2, 0.5], [0.9, 0.5], [0.3, 0.3], [0.0, 0.5]])

    @jax.jit
    def everything(v):
        return (disk.warp(v), jax.vmap(jax.jacrev(disk.warp))(v), jax.grad(lambda w: jnp.sum(disk.warp(w) ** 3))(v),
                jax.vmap(jax.jacrev(disk.inverse))(disk.warp(v)))

    for dtype in (jnp.float32, jnp.float64):
        with jax.enable_x64(dtype == jnp.float64):
            assert_finite(everything(u.astype(dtype)), "concentric map, its gradients and its inverse's")


@pytest.mark.parametrize("dtype", [jnp.float32, jnp.float64])
@pytest.mark.parametrize("method", ["concentric", "polar", "rejection"])
def test_disk_finite_at_edges(method, dtype):
    with jax.enable_x64(dtype == jnp.float64):
        check_finite_at_edges(_DISK_MAKERS[method], (), dtype)


@pytest.mark.parametrize("dtype", [jnp.float32, jnp.float64])
@pytest.mark.parametrize("vertices", [TRIANGLE_2D, TRIANGLE_3D])
def test_triangle_finite_at_edges(vertices, dtype):
    from jaxsample.samplers.triangle import UniformTriangle
    centroid = np.mean(np.array(vertices), axis=0)
    with jax.enable_x64(dtype == jnp.float64):
        check_finite_at_edges(UniformTriangle, vertices, dtype, point=centroid)


def test_thin_triangle_finite_float64():
    from jaxsample.samplers.triangle import UniformTriangle
    with jax.enable_x64(True):
        check_finite_at_edges(UniformTriangle, THIN_3D, jnp.float64)


def test_samples_inside_domain():
    keys = jax.random.split(jax.random.key(30), len(SAMPLERS))
    for key, name in zip(keys, SAMPLERS):
        sampler = SAMPLERS[name]()
        x = np.asarray(sampler.sample(key, (20_000,)))
        assert np.all(js_domains.contains(sampler.domain(), x)), name
        assert np.all(np.asarray(sampler.pdf(x)) > 0), name


def test_rejection_disk_is_exactly_uniform_with_one_try():
    # With one try the fall-through (probability 1 - π/4) uses the independent polar sample.
    result = run_chi2(UniformDisk("rejection", tries=1), jax.random.key(31), N_CHI2)
    assert result.passed, result


def test_invalid_parameters_raise():
    from jaxsample.samplers.triangle import UniformTriangle
    with pytest.raises(ValueError, match="'a', 'b', 'c'.*degenerate"):
        UniformTriangle(np.array([0.0, 0.0]), np.array([1.0, 1.0]), np.array([2.0, 2.0]))
    with pytest.raises(ValueError, match="degenerate"):
        UniformTriangle(np.array([1.0, 2.0, 3.0]), np.array([1.0, 2.0, 3.0]), np.array([0.0, 0.0, 1.0]))
    with pytest.raises(ValueError, match="finite"):
        UniformTriangle(np.array([np.nan, 0.0]), np.array([1.0, 0.0]), np.array([0.0, 1.0]))
    with pytest.raises(ValueError, match=r"shape \(2,\) or \(3,\)"):
        UniformTriangle(np.zeros(4), np.ones(4), np.arange(4.0))
    with pytest.raises(ValueError, match="'method'"):
        UniformDisk("square")
    with pytest.raises(ValueError, match=r"'tries' must be in \[1, 4096\]"):
        UniformDisk("rejection", tries=0)
    with pytest.raises(ValueError, match="'low' and 'high'"):
        UniformBox(np.array([0.0, 1.0]), np.array([1.0, 1.0]))


def test_jit_and_vmap_over_vertices():
    from jaxsample.samplers.triangle import UniformTriangle
    keys = jax.random.split(jax.random.key(40), 2)
    c = jax.random.uniform(keys[0], (16, 3)) + jnp.array([0.0, 1.0, 0.0])
    u = jax.random.uniform(keys[1], (16, 2))

    @jax.jit
    def warp_and_density(c, u):
        s = UniformTriangle(jnp.zeros(3), jnp.array([1.0, 0.0, 0.0]), c)
        x, p = s.warp_with_pdf(u)
        return x, p, s.pdf(x)

    x, p, q = jax.vmap(warp_and_density)(c, u)
    np.testing.assert_allclose(p, q, rtol=1e-5)
    area = 0.5 * np.linalg.norm(np.cross(np.array([1.0, 0, 0]), np.asarray(c)), axis=-1)
    np.testing.assert_allclose(p, 1.0 / area, rtol=1e-5)


@settings(derandomize=True, deadline=None, max_examples=15)
@given(st.lists(st.floats(-10.0, 10.0), min_size=9, max_size=9))
def test_random_triangles(coordinates):
    from jaxsample.samplers.triangle import UniformTriangle
    a, b, c = np.array(coordinates).reshape(3, 3)
    twice_area = np.linalg.norm(np.cross(b - a, c - a))
    longest = max(np.sum((b - a) ** 2), np.sum((c - a) ** 2), np.sum((c - b) ** 2))
    if not twice_area > 64 * np.finfo(np.float64).eps * longest:
        with pytest.raises(ValueError, match="degenerate"):
            UniformTriangle(a, b, c)
        return
    with jax.enable_x64(True):
        sampler = UniformTriangle(jnp.asarray(a), jnp.asarray(b), jnp.asarray(c))
        assert abs(normalization(sampler) - 1.0) < 1e-6
        u = edge_uniforms(2, jnp.float64) * 0.998 + 0.001
        assert float(jnp.max(inverse_error(sampler, u))) < 1e-6
        x = np.asarray(sampler.warp(u))
        assert np.all(js_domains.contains(sampler.domain(), x))

