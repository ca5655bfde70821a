"""The Duff et al. frame, `Oriented`, the checks in `jaxsample.testing` catching wrong samplers,
and the checks' geometry kept out of the samplers' imports."""

import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxsample as js
from jaxsample import testing

DUFF_BAD_NORMALS = [
    (0.00038527316, 0.00038460016, -0.99999988079),
    (-0.00019813581, -0.00008946839, -0.99999988079),
]


def orthonormality_error(frame):
    x, y, z = frame.x, frame.y, frame.z
    terms = [(jnp.linalg.norm(v, axis=-1) - 1) ** 2 for v in (x, y, z)]
    terms += [jnp.sum(a * b, -1) ** 2 for a, b in ((x, y), (y, z), (z, x))]
    return sum(terms) / 6


@pytest.mark.parametrize("normal", DUFF_BAD_NORMALS + [(0, 0, 1), (0, 0, -1), (1, 0, 0), (0, -1, 0)])
def test_frame_is_orthonormal_and_right_handed_even_near_minus_z(normal):
    frame = js.Frame.from_normal(jnp.array(normal, jnp.float32))
    assert float(orthonormality_error(frame)) < 1e-10
    np.testing.assert_allclose(jnp.cross(frame.x, frame.y), frame.z, atol=1e-6)


def test_frame_axis_normals_have_exact_zeros_in_the_axis_component():
    for axis in range(3):
        for sign in (1.0, -1.0):
            n = jnp.zeros(3).at[axis].set(sign)
            frame = js.Frame.from_normal(n)
            assert float(frame.x[axis]) == 0.0 and float(frame.y[axis]) == 0.0


def test_frame_on_random_normals_and_round_trip():
    normals = jax.random.normal(jax.random.key(0), (1000, 3))
    frame = js.Frame.from_normal(normals)
    assert float(jnp.max(orthonormality_error(frame))) < 1e-10
    v = jax.random.normal(jax.random.key(1), (1000, 3))
    np.testing.assert_allclose(frame.to_world(frame.to_local(v)), v, atol=1e-5)
    np.testing.assert_allclose(frame.to_local(frame.z), jnp.tile(jnp.array([0.0, 0, 1]), (1000, 1)), atol=1e-6)


def test_frame_to_local_is_written_out_without_a_reduction():
    """to_local's dot products are products and sums of components, not `jnp.sum(..., -1)`: XLA's CPU
    backend gives a reduction over the axis of 3 a loop of its own, and in reverse mode through
    `shade`'s boundary term those loops made its gradient in a Phong exponent 1.4-1.7x slower. The
    values: each component against the float64 dot product (batched frames and points)."""
    frame = js.Frame.from_normal(jax.random.normal(jax.random.key(2), (64, 3)))
    v = jax.random.normal(jax.random.key(3), (64, 3))
    primitives = {e.primitive.name for e in jax.make_jaxpr(frame.to_local)(v).jaxpr.eqns}
    assert not primitives & {"reduce_sum", "dot_general"}, primitives
    axes = [np.asarray(a, np.float64) for a in (frame.x, frame.y, frame.z)]
    expected = np.stack([np.sum(np.asarray(v, np.float64) * a, -1) for a in axes], -1)
    np.testing.assert_allclose(frame.to_local(v), expected, rtol=0, atol=1e-6)


def test_oriented_keeps_the_density_and_inverts_through_the_frame():
    base = js.PhongLobe(8.0)
    normal = jnp.array([0.48, -0.6, 0.64])
    oriented = js.Oriented(base, normal)
    u = jax.random.uniform(jax.random.key(2), (256, 2))
    local = base.warp(u)
    world = oriented.warp(u)
    np.testing.assert_allclose(oriented.pdf(world), base.pdf(local), rtol=1e-4)
    np.testing.assert_allclose(jnp.sum(world * oriented.normal, -1), local[:, 2], atol=1e-6)
    assert float(jnp.max(testing.inverse_error(oriented, u))) < 1e-5


def test_gradients_flow_through_the_frame_to_the_normal():
    u = jnp.array([0.3, 0.7])

    def mean_z(theta):
        normal = jnp.array([jnp.sin(theta), 0.0, jnp.cos(theta)])
        return js.Oriented(js.CosineHemisphere(), normal).warp(u)[2]

    g = jax.grad(mean_z)(0.4)
    step = 1e-3
    fd = (mean_z(0.4 + step) - mean_z(0.4 - step)) / (2 * step)
    np.testing.assert_allclose(g, fd, rtol=1e-2)


class _MisnormalizedPhong(js.PhongLobe):
    def pdf(self, x):
        return 1.01 * super().pdf(x)


class _WrongInversePhong(js.PhongLobe):
    def inverse(self, x):
        u = super().inverse(x)
        return u.at[..., 0].set(u[..., 0] ** 1.01)


def test_normalization_detects_a_one_percent_error():
    assert abs(testing.normalization(_MisnormalizedPhong(jnp.float32(30.0))) - 1.01) < 1e-6


def test_jacobian_check_detects_a_density_that_disagrees_with_its_warp():
    u = jnp.full((4, 2), 0.3)
    assert float(jnp.min(testing.jacobian_error(_MisnormalizedPhong(jnp.float32(30.0)), u))) > 5e-3
    assert float(jnp.max(testing.jacobian_error(js.PhongLobe(jnp.float32(30.0)), u))) < 1e-4


def test_inverse_check_detects_a_wrong_inverse():
    u = jnp.full((4, 2), 0.3)
    assert float(jnp.min(testing.inverse_error(_WrongInversePhong(jnp.float32(3.0)), u))) > 1e-3


def test_chi_square_rejects_a_misnormalized_density_and_samples_outside_the_support():
    # A 1 % scale error adds about N·0.01² to the statistic: at 10^6 samples that is 1 sd above
    # the threshold (rejected for 3 keys of 6), at 4·10^6 it is 7 sd (p ≈ 1e-50 for every key
    # tried), so the rejection is a property of the check, not of the key. FFR below 2e-7 (estimated:
    # a noncentral chi-square(127) whose median p is 1e-50 reaches 1e-20 that rarely).
    result = testing.chi2_test(_MisnormalizedPhong(jnp.float32(30.0)), jax.random.key(3), n_samples=4_000_000)
    assert not result.passed and result.p_value < 1e-20, result

    class Leaky(js.UniformHemisphere):
        # Mirrors 1 % of samples below the horizon, where the density is 0.
        def warp(self, u):
            x = super().warp(u)
            return jnp.where((u[..., 1:2] < 0.01), x * jnp.array([1.0, 1.0, -1.0]), x)

    # Deterministic in effect: ~1000 of the 10^5 samples land outside (none would pass unseen).
    leaky = testing.chi2_test(Leaky(), jax.random.key(4), n_samples=100_000)
    assert not leaky.passed and leaky.n_outside > 0


def test_chi_square_p_values_are_uniform_under_the_null():
    # The statistic's law: over 40 independent runs on a correct sampler, p-values spread over
    # (0, 1). Kolmogorov–Smirnov against U(0, 1) with critical D = 0.3 for n = 40: level (FFR)
    # 1.1e-3, P(D_40 >= 0.3) for exactly uniform p-values.
    keys = jax.random.split(jax.random.key(5), 40)
    p = np.sort([testing.chi2_test(js.CosineHemisphere(), k, n_samples=20_000, n_cells=32,
                                   n_pilot=4096).p_value for k in keys])
    grid = np.arange(1, 41) / 40
    d = max(np.max(grid - p), np.max(p - (grid - 1 / 40)))
    assert d < 0.3, p


def test_importing_a_sampler_does_not_import_the_checks_geometry():
    # Samplers name their domain (jaxsample.samplers.domain); the quadrature and binning on it
    # (jaxsample.domains) load with the checks, on first use of js.testing or js.domains.
    code = ("import sys, jaxsample.samplers.phong, jaxsample as js\n"
            "loaded = sorted(m for m in sys.modules if m.startswith('jaxsample.testing') or m == 'jaxsample.domains')\n"
            "assert not loaded, loaded\n"
            "js.testing.normalization\n"
            "assert 'jaxsample.domains' in sys.modules\n")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-2000:]


class _HalfLine:
    """A domain class of a user's own: [0, 1] with its own quadrature, cells and membership."""

    def quadrature(self):
        nodes, weights = np.polynomial.legendre.leggauss(40)
        return 0.5 * (nodes + 1.0), 0.5 * weights

    def cells(self, pilot, n_cells):
        return js.domains.cells(js.domains.Interval(0.0, 1.0), pilot, n_cells)

    def contains(self, x):
        return (np.asarray(x) >= 0) & (np.asarray(x) <= 1)


class _Triangular(js.Sampler):
    """p(x) = 2x on [0, 1] by inversion, x = sqrt(u), over a domain class of the user's own."""

    uniform_dims = 1

    def warp(self, u):
        return jnp.sqrt(u[..., 0])

    def pdf(self, x):
        return jnp.where((x >= 0) & (x <= 1), 2.0 * x, 0.0)

    def domain(self):
        return _HalfLine()


def test_the_checks_use_the_methods_of_a_domain_class_of_the_users_own():
    sampler = _Triangular()
    assert abs(testing.normalization(sampler) - 1.0) < 1e-12
    # False-failure rate 1e-6 (the default significance of one test).
    assert testing.chi2_test(sampler, jax.random.key(9), n_samples=50_000, n_cells=16, n_pilot=4096).passed
    assert np.array_equal(js.domains.contains(sampler.domain(), np.array([-0.5, 0.5])), [False, True])
