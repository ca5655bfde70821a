"""Rejection, Transformed and Mixture: what is particular to them. Their contract
(normalization, chi-square, inverse, Jacobian, support, finite values and gradients at the hard
cases) is `test_contract.py`, over the entries of `registry.py`.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import registry
from helpers import WrongWarp
from jaxsample.samplers.box import UniformBox
from jaxsample.samplers.disk import UniformDisk
from jaxsample.samplers.exponential import Exponential
from jaxsample.samplers.mixture import Mixture
from jaxsample.samplers.phong import PhongLobe
from jaxsample.samplers.power import Power
from jaxsample.samplers.rejection import Rejection
from jaxsample.samplers.sphere import UniformHemisphere, UniformSphere
from jaxsample.testing.sampler_checks import chi2_test
from jaxsample.samplers.transformed import Transformed

# Two-sided normal quantile for a false-failure rate of 1e-6 over the 4 binomial checks below
# (Šidák: 2.5e-7 each): |z| < 5.16. The counts are binomial with known p, and N p (1 - p) > 100,
# so the normal approximation is accurate far into the tail used here (exact binomial tails: FFR
# 6.1e-7 for dimension 2, whose fall-through count has N p (1 - p) = 423, and 4.9e-7 for 3).
Z_LIMIT = 5.16


def ball_density(x):
    return jnp.where(jnp.sum(x * x, axis=-1) < 1.0, 3.0 / (4.0 * np.pi), 0.0)


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
    sampler = Rejection(square(dimension), registry._disk_density if dimension == 2 else ball_density,
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


def test_rejection_without_fallback_fails_against_the_target_alone():
    # Three tries without a fallback: the fall-through (ε = 0.42) is visible. The contract passes
    # the sampler against the density it states, (1 - ε) p + ε q; against the target p alone the
    # chi-square test fails, at the contract's settings for the entry and by a margin (p < 1e-15;
    # seen over keys: p = 0 in float64).
    target_only = WrongWarp(Power(3.0), registry.rejection_loose(4.0))
    result = chi2_test(target_only, jax.random.key(6), **registry.chi2_settings("Rejection-without-fallback"))
    assert not result.passed and result.p_value < 1e-15, result


def test_rejection_invalid_parameters():
    with pytest.raises(ValueError, match=r"'bound' must be in \[1, inf\)"):
        Rejection(square(2), registry._disk_density, 0.5)
    with pytest.raises(ValueError, match="'tries'"):
        Rejection(square(2), registry._disk_density, 2.0, tries=0)


def ball_forward(p):
    # (s, μ, φ) -> r = s^{1/3} times a direction: the uniform ball, density 3/(4π).
    return jnp.cbrt(p[0]) * registry._sphere_forward(p[1:])


def ball_inverse(y):
    r = jnp.sqrt(jnp.sum(y * y))
    return jnp.concatenate([r[None] ** 3, registry._sphere_inverse(y / r)])


def polar_disk():
    return registry.transformed_polar(jnp.array([1.0, 2 * np.pi]))


def spherical():
    return registry.transformed_spherical(jnp.array([-1.0, 0.0]), jnp.array([1.0, 2 * np.pi]))


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
    # Where the transform is singular (the centre, det J = 0 by the guarded sqrt) the density is 0, not NaN.
    assert np.isfinite(float(transformed.pdf(jnp.zeros((1, 2)))[0]))


def test_transformed_spherical_coordinates():
    keys = jax.random.split(jax.random.key(8), 3)
    sphere = spherical()
    assert sphere.event_shape == (3,)
    y = UniformSphere().sample(keys[0], (4096,))
    np.testing.assert_allclose(_pdf(sphere, y), 1 / (4 * np.pi), rtol=1e-4)
    ball = Transformed(UniformBox(jnp.array([0.0, -1.0, 0.0]), jnp.array([1.0, 1.0, 2 * np.pi])),
                       ball_forward, ball_inverse)
    points, p = _sample_with_pdf(ball, keys[2])
    np.testing.assert_allclose(p, 3 / (4 * np.pi), rtol=1e-4)
    np.testing.assert_allclose(_pdf(ball, points * 0.999), 3 / (4 * np.pi), rtol=1e-3)


def test_mixture_chi2_rejects_wrong_weights():
    """Weights 0.55 / 0.45 where the density says 0.5 / 0.5 fail the chi-square test at the
    contract's cells, pilot and level for the mixture entries, with twice its samples (200000),
    by a margin: p < 1e-15.

    FFR below 1e-10 (a power check): over 3000 simulated keys the statistic (63 dof) had mean
    481 and sd 44 (right-skewed; median p 1e-65), and p >= 1e-15 needs it below 197, 6.5 sd down
    (normal tail 4e-11). At the contract's 100000 samples the mean is 272 and sd 32, and p >= 1e-15
    for 0.8 % of keys."""
    wrong = WrongWarp(Mixture((Exponential(1.0), Exponential(3.0)), [0.5, 0.5]),
                      Mixture((Exponential(1.0), Exponential(3.0)), [0.55, 0.45]))
    settings = registry.chi2_settings("Mixture-exponentials")
    settings["n_samples"] *= 2
    result = chi2_test(wrong, jax.random.key(11), **settings)
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


def test_mixture_jit_vmap_and_invalid():
    weights = jax.random.uniform(jax.random.key(13), (16, 2))
    u = jnp.full((16, 1), 0.5)
    x, p = jax.vmap(jax.jit(lambda w, u: registry.mixture_of_exponentials(w, 10.0).warp_with_pdf(u)))(weights, u)
    assert np.all(np.isfinite(np.asarray(p))) and np.all(np.asarray(p) > 0)
    with pytest.raises(ValueError, match="'weights'.*one entry per component"):
        Mixture((Exponential(1.0), Exponential(2.0)), [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="'weights'.*not all zero"):
        Mixture((Exponential(1.0), Exponential(2.0)), [0.0, 0.0])
    with pytest.raises(ValueError, match="'components'.*event shape"):
        Mixture((Exponential(1.0), UniformDisk()), [1.0, 1.0])


def test_a_mixture_on_the_real_line_integrates_over_every_component():
    """Components on an unbounded line: the merged domain's quadrature spans the lowest component
    too (not only the first one's range), so the mixture's density integrates to 1."""
    from jaxsample.samplers.normal import Normal
    from jaxsample.testing import normalization

    far_apart = Mixture((Normal(20.0, 1.0), Normal(-20.0, 1.0)), [0.5, 0.5])
    assert abs(float(normalization(far_apart)) - 1.0) < 1e-9
