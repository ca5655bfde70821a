"""Rejection, Transformed and Mixture."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from helpers import WrongWarp, check_finite_at_edges, run_chi2
from jaxsample.samplers.box import UniformBox
from jaxsample.samplers.disk import UniformDisk
from jaxsample.checks.domains import Directions, Disk
from jaxsample.samplers.exponential import Exponential
from jaxsample.samplers.mixture import Mixture
from jaxsample.samplers.phong import PhongLobe
from jaxsample.samplers.power import Power
from jaxsample.samplers.rejection import Rejection
from jaxsample.samplers.sphere import UniformHemisphere, UniformSphere
from jaxsample.checks.sampler_checks import normalization
from jaxsample.samplers.transformed import Transformed

# Chi-square tests in this file, run as one family at overall false-failure rate 1e-6.
N_CHI2 = 7
# Two-sided normal quantile for a false-failure rate of 1e-6 over the 4 binomial checks below
# (Šidák: 2.5e-7 each): |z| < 5.16. The counts are binomial with known p, and N p (1 - p) > 100,
# so the normal approximation is accurate far into the tail used here.
Z_LIMIT = 5.16


def disk_density(x):
    return jnp.where(jnp.sum(x * x, axis=-1) < 1.0, 1.0 / np.pi, 0.0)


def ball_density(x):
    return jnp.where(jnp.sum(x * x, axis=-1) < 1.0, 3.0 / (4.0 * np.pi), 0.0)


def cubic_density(x):
    return jnp.where((x >= 0) & (x <= 1), 4.0 * x ** 3, 0.0)


def square(d):
    return UniformBox(-jnp.ones(d), jnp.ones(d))


_pdf = jax.jit(lambda s, x: s.pdf(x))
_log_pdf = jax.jit(lambda s, x: s.log_pdf(x))
_sample_with_pdf = jax.jit(lambda s, key: s.sample_with_pdf(key, (1024,)))


def _binomial_z(count, n, p):
    return (count - n * p) / np.sqrt(n * p * (1 - p))


@pytest.mark.parametrize("dimension,acceptance", [(2, np.pi / 4), (3, np.pi / 6)])
def test_rejection_acceptance_and_fall_through_match_theory(dimension, acceptance):
    tries, n = 4, 200_000
    sampler = Rejection(square(dimension), disk_density if dimension == 2 else ball_density,
                        bound=1.0 / acceptance, tries=tries)
    x, info = jax.jit(lambda s, k: s.sample_with_info(k, (n,)))(sampler, jax.random.key(dimension))
    passed = int(jnp.sum(info.n_passed))
    assert abs(_binomial_z(passed, n * tries, acceptance)) < Z_LIMIT
    fell_through = int(jnp.sum(~info.accepted))
    epsilon = (1 - acceptance) ** tries
    assert float(sampler.fall_through_probability) == pytest.approx(epsilon, rel=1e-6)
    assert abs(_binomial_z(fell_through, n, epsilon)) < Z_LIMIT
    inside = np.sum(np.asarray(x) ** 2, axis=-1) < 1
    assert np.all(inside[np.asarray(info.accepted)])


def test_rejection_chi2_with_fallback_and_mixture_density_without():
    keys = jax.random.split(jax.random.key(5), 2)
    exact = Rejection(square(2), disk_density, 4.0 / np.pi, tries=2, fallback=UniformDisk("polar"), support=Disk())
    assert abs(normalization(exact) - 1.0) < 1e-6
    assert run_chi2(exact, keys[0], N_CHI2).passed
    # Without a fallback and with few tries the fall-through (ε = 0.42) is visible: pdf reports
    # (1 - ε) p + ε q, and the test passes against it.
    loose = Rejection(Power(0.0), cubic_density, 4.0, tries=3)
    assert abs(normalization(loose) - 1.0) < 1e-6
    assert run_chi2(loose, keys[1], N_CHI2).passed
    # ... and fails against the target alone.
    target_only = WrongWarp(Power(3.0), loose)
    result = run_chi2(target_only, jax.random.key(6), N_CHI2)
    assert not result.passed and result.p_value < 1e-15, result  # seen over keys: p = 0 in float64


def test_rejection_invalid_parameters():
    with pytest.raises(ValueError, match=r"'bound' must be in \[1, inf\)"):
        Rejection(square(2), disk_density, 0.5)
    with pytest.raises(ValueError, match="'tries'"):
        Rejection(square(2), disk_density, 2.0, tries=0)


def polar_forward(p):
    # (s, θ) -> sqrt(s)(cos θ, sin θ); |det J| = ½, so a uniform (s, θ) box gives 1/π.
    return jnp.sqrt(p[0]) * jnp.stack([jnp.cos(p[1]), jnp.sin(p[1])])


def polar_inverse(y):
    return jnp.stack([jnp.sum(y * y), jnp.mod(jnp.arctan2(y[1], y[0]), 2 * np.pi)])


def sphere_forward(p):
    # (μ, φ) -> the unit sphere; the surface Jacobian sqrt(det JᵀJ) is 1.
    sin_theta = jnp.sqrt(1.0 - p[0] ** 2)
    return jnp.stack([sin_theta * jnp.cos(p[1]), sin_theta * jnp.sin(p[1]), p[0]])


def sphere_inverse(y):
    return jnp.stack([y[2], jnp.mod(jnp.arctan2(y[1], y[0]), 2 * np.pi)])


def ball_forward(p):
    # (s, μ, φ) -> r = s^{1/3} times a direction: the uniform ball, density 3/(4π).
    return jnp.cbrt(p[0]) * sphere_forward(p[1:])


def ball_inverse(y):
    r = jnp.sqrt(jnp.sum(y * y))
    return jnp.concatenate([r[None] ** 3, sphere_inverse(y / r)])


def polar_disk():
    return Transformed(UniformBox(jnp.array([0.0, 0.0]), jnp.array([1.0, 2 * np.pi])), polar_forward, polar_inverse,
                       domain=Disk())


def spherical():
    return Transformed(UniformBox(jnp.array([-1.0, 0.0]), jnp.array([1.0, 2 * np.pi])), sphere_forward,
                       sphere_inverse, domain=Directions())


def test_transformed_polar_agrees_with_uniform_disk():
    keys = jax.random.split(jax.random.key(7), 3)
    transformed, disk = polar_disk(), UniformDisk("polar")
    y = disk.sample(keys[0], (4096,))
    np.testing.assert_allclose(_pdf(transformed, y), disk.pdf(y), rtol=1e-5)
    outside = 1.5 * y / jnp.linalg.norm(y, axis=-1, keepdims=True)
    np.testing.assert_array_equal(_pdf(transformed, outside), 0.0)
    np.testing.assert_array_equal(_log_pdf(transformed, outside), -np.inf)
    x, p = _sample_with_pdf(transformed, keys[1])
    np.testing.assert_allclose(p, 1 / np.pi, rtol=1e-5)
    assert abs(normalization(transformed) - 1.0) < 1e-6
    assert run_chi2(transformed, keys[2], N_CHI2).passed
    # Where the transform is singular (the centre, det J = 0 by the guarded sqrt) the density is 0, not NaN.
    assert np.isfinite(float(transformed.pdf(jnp.zeros((1, 2)))[0]))


def test_transformed_spherical_coordinates():
    keys = jax.random.split(jax.random.key(8), 3)
    sphere = spherical()
    assert sphere.event_shape == (3,)
    y = UniformSphere().sample(keys[0], (4096,))
    np.testing.assert_allclose(_pdf(sphere, y), 1 / (4 * np.pi), rtol=1e-4)
    assert abs(normalization(sphere) - 1.0) < 1e-6
    assert run_chi2(sphere, keys[1], N_CHI2).passed
    ball = Transformed(UniformBox(jnp.array([0.0, -1.0, 0.0]), jnp.array([1.0, 1.0, 2 * np.pi])),
                       ball_forward, ball_inverse)
    points, p = _sample_with_pdf(ball, keys[2])
    np.testing.assert_allclose(p, 3 / (4 * np.pi), rtol=1e-4)
    np.testing.assert_allclose(_pdf(ball, points * 0.999), 3 / (4 * np.pi), rtol=1e-3)


def test_transformed_inverse_round_trip():
    u = jax.random.uniform(jax.random.key(9), (2048, 2), minval=1e-3, maxval=1 - 1e-3)
    transformed = polar_disk()
    np.testing.assert_allclose(transformed.inverse(transformed.warp(u)), u, atol=1e-4)


def _mixtures():
    return {
        "exponentials": Mixture((Exponential(1.0), Exponential(1e3)), [0.3, 0.7]),
        "directions": Mixture((PhongLobe(50.0), UniformHemisphere(), PhongLobe(1e4)), [1.0, 2.0, 1.0]),
        "disks": Mixture((UniformDisk("polar"), UniformDisk("concentric")), [1.0, 0.0]),
    }


@pytest.mark.parametrize("name", list(_mixtures()))
def test_mixture_normalization(name):
    assert abs(normalization(_mixtures()[name]) - 1.0) < 1e-6


def test_mixture_chi2():
    mixtures = _mixtures()
    keys = jax.random.split(jax.random.key(10), 2)
    assert run_chi2(mixtures["exponentials"], keys[0], N_CHI2).passed
    assert run_chi2(mixtures["directions"], keys[1], N_CHI2).passed
    wrong = WrongWarp(Mixture((Exponential(1.0), Exponential(3.0)), [0.5, 0.5]),
                      Mixture((Exponential(1.0), Exponential(3.0)), [0.55, 0.45]))
    # At the suite's sample size and by a margin (p < 1e-15; seen over keys: 1e-20 to 1e-26).
    result = run_chi2(wrong, jax.random.key(11), N_CHI2)
    assert not result.passed and result.p_value < 1e-15, result


def test_mixture_density_is_the_balance_heuristic_denominator():
    a, b = PhongLobe(10.0), UniformHemisphere()
    mixture = Mixture((a, b), [1.0, 3.0])
    assert mixture.uniform_dims == 2
    x = mixture.sample(jax.random.key(12), (1000,))
    np.testing.assert_allclose(mixture.pdf(x), 0.25 * a.pdf(x) + 0.75 * b.pdf(x), rtol=1e-6)
    # The component is chosen by u₀ and its remainder is reused: u₀ in the first quarter gives
    # the Phong lobe's warp of (4 u₀, u₁).
    u = jnp.array([[0.1, 0.3], [0.2, 0.9]])
    np.testing.assert_allclose(mixture.warp(u), a.warp(u.at[:, 0].multiply(4.0)), rtol=1e-5, atol=1e-6)


def _mixture_of_exponentials(weights, rate):
    return Mixture((Exponential(rate), Exponential(1.0)), weights)


@pytest.mark.parametrize("dtype", [jnp.float32, jnp.float64])
def test_mixture_finite_at_edges(dtype):
    with jax.enable_x64(dtype == jnp.float64):
        check_finite_at_edges(_mixture_of_exponentials, ([0.5, 0.5], 1e6), dtype, point=0.5)
        check_finite_at_edges(_mixture_of_exponentials, ([1.0, 0.0], 1e-6), dtype, point=0.5)


def test_mixture_jit_vmap_and_invalid():
    weights = jax.random.uniform(jax.random.key(13), (16, 2))
    u = jnp.full((16, 1), 0.5)
    x, p = jax.vmap(jax.jit(lambda w, u: _mixture_of_exponentials(w, 10.0).warp_with_pdf(u)))(weights, u)
    assert np.all(np.isfinite(np.asarray(p))) and np.all(np.asarray(p) > 0)
    with pytest.raises(ValueError, match="'weights'.*one entry per component"):
        Mixture((Exponential(1.0), Exponential(2.0)), [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="'weights'.*not all zero"):
        Mixture((Exponential(1.0), Exponential(2.0)), [0.0, 0.0])
    with pytest.raises(ValueError, match="'components'.*event shape"):
        Mixture((Exponential(1.0), UniformDisk()), [1.0, 1.0])
