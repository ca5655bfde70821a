"""What is particular to UniformDisk, UniformTriangle and UniformBox; their contract
(normalization, chi-square, inverse, Jacobian, support, finite values and gradients at the hard
cases, thin triangles in float64) is `test_contract.py`, over the entries of `registry.py`.

Here: wrong samplers the chi-square test rejects (at the contract's settings for the entry they
imitate), the concentric map's derivatives on its axes and at its centre, parameter errors,
jit/vmap over vertices, and random triangles.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import registry
from helpers import WrongWarp
from jaxsample import domains
from jaxsample.samplers import concentric
from jaxsample.samplers.box import UniformBox
from jaxsample.samplers.disk import UniformDisk
from jaxsample.samplers.triangle import UniformTriangle
from jaxsample.testing.sampler_checks import chi2_test, inverse_error, normalization
from jaxsample.samplers.transformed import Transformed
from jaxsample.domains import Disk

TRIANGLE_2D = registry.TRIANGLE_2D


def triangle(vertices, dtype=None):
    return UniformTriangle(*(jnp.asarray(v, dtype) for v in vertices))


def _shrunk_radius(p):
    # r = s^0.46 instead of s^0.5: slightly too much mass near the rim.
    return jnp.power(p[0], 0.46) * jnp.stack([jnp.cos(p[1]), jnp.sin(p[1])])


def _disk_to_polar(y):
    return jnp.stack([jnp.sum(y * y) ** (1 / 0.92), jnp.mod(jnp.arctan2(y[1], y[0]), 2 * np.pi)])


def test_chi2_fails_for_wrong_samplers():
    truth = UniformDisk("polar")
    impostor = Transformed(UniformBox(jnp.array([0.0, 0.0]), jnp.array([1.0, 2 * np.pi])),
                           _shrunk_radius, _disk_to_polar, domain=Disk())
    # At the contract's settings for the disk (10^5 samples, 1.1e-8 per test) and by a margin:
    # p < 1e-15 (seen over keys: below 1e-80 for both wrong samplers here). FFR below 1e-20 (estimated
    # from a noncentral chi-square(63) whose median p is 1e-80).
    result = chi2_test(WrongWarp(truth, impostor), jax.random.key(12), **registry.chi2_settings("UniformDisk-polar"))
    assert not result.passed and result.p_value < 1e-15, result
    # Vertex c pulled 5 % toward the centroid: samples stay inside, the density is wrong.
    a, b, c = (np.array(v) for v in TRIANGLE_2D)
    centroid = (a + b + c) / 3
    inner = triangle((a, b, c + 0.05 * (centroid - c)))
    result = chi2_test(WrongWarp(triangle(TRIANGLE_2D), inner), jax.random.key(13),
                       **registry.chi2_settings("UniformTriangle-2d"))
    assert not result.passed and result.p_value < 1e-15, result


@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_concentric_inverse_has_finite_gradients_on_the_axes_and_at_the_centre(dtype):
    # disk_to_square itself (not only UniformDisk.inverse, which guards the centre) is finite there,
    # and next to the centre at the smallest radius the float32 warp produces (2u - 1 = ±2^-24).
    with jax.enable_x64(dtype == "float64"):
        points = jnp.asarray(np.array([[0.0, 0.0], [0.5, 0.0], [0.0, 0.5], [-0.5, 0.0], [0.0, -0.5],
                                       [0.3, 0.3], [2.0 ** -24, 0.0], [0.0, -2.0 ** -24]]), dtype)

        def to_square(p):
            return concentric.disk_to_square(p[..., 0], p[..., 1])

        for transform in (jax.jacfwd, jax.jacrev):
            jac = jax.jit(jax.vmap(transform(to_square)))(points)
            assert np.all(np.isfinite(np.asarray(jac))), jac
        # UniformDisk.inverse (disk_to_square with its guard) likewise, in both modes.
        for transform in (jax.jacfwd, jax.jacrev):
            jac = jax.jit(jax.vmap(transform(UniformDisk().inverse)))(points)
            assert np.all(np.isfinite(np.asarray(jac))), jac
        u = to_square(points)
        np.testing.assert_allclose(np.asarray(u[0]), [0.5, 0.5])
        # And the map round-trips through square_to_disk on the axes.
        x, y, _ = concentric.square_to_disk(u)
        np.testing.assert_allclose(np.stack([x, y], -1), points, atol=1e-6)


def test_invalid_parameters_raise():
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
        u = registry.edge_uniforms(2, jnp.float64) * 0.998 + 0.001
        assert float(jnp.max(inverse_error(sampler, u))) < 1e-6
        x = np.asarray(sampler.warp(u))
        assert np.all(domains.contains(sampler.domain(), x))

