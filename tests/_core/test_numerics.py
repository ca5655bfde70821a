"""Layer 1: the safe functions keep value and gradient finite at their domain edges."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxsample._core import numerics as nm

EDGES = jnp.array([-2.0, -1.0, 0.0, 1e-30, 0.5, 1.0, 2.0], jnp.float32)


@pytest.mark.parametrize("fn", [nm.safe_sqrt, nm.safe_acos, nm.safe_asin, nm.safe_log])
def test_gradients_are_finite_at_the_edges(fn):
    grads = jax.vmap(jax.grad(fn))(EDGES)
    assert np.all(np.isfinite(np.asarray(grads))), grads
    fwd = jax.vmap(jax.jacfwd(fn))(EDGES)
    assert np.all(np.isfinite(np.asarray(fwd))), fwd


def test_values_match_the_plain_functions_inside_their_domain():
    x = jnp.linspace(0.01, 0.99, 50)
    np.testing.assert_allclose(nm.safe_sqrt(x), jnp.sqrt(x), rtol=1e-6)
    np.testing.assert_allclose(nm.safe_acos(x), jnp.arccos(x), rtol=1e-6)
    np.testing.assert_allclose(nm.safe_asin(x), jnp.arcsin(x), rtol=1e-6)
    np.testing.assert_allclose(nm.safe_log(x), jnp.log(x), rtol=1e-6)
    assert nm.safe_log(jnp.float32(0.0)) == -jnp.inf
    assert nm.safe_acos(jnp.float32(1.5)) == 0.0 and nm.safe_acos(jnp.float32(-1.5)) == np.float32(np.pi)


def test_safe_div_is_zero_where_the_denominator_is_zero_with_finite_gradients():
    num = jnp.array([1.0, 2.0, 0.0])
    den = jnp.array([2.0, 0.0, 0.0])
    np.testing.assert_array_equal(nm.safe_div(num, den), [0.5, 0.0, 0.0])
    g = jax.grad(lambda d: nm.safe_div(num, d).sum())(den)
    assert np.all(np.isfinite(g))


def test_safe_pow_handles_zero_base_and_zero_exponent():
    assert nm.safe_pow(0.0, 0.0) == 1.0
    assert nm.safe_pow(0.0, 3.0) == 0.0
    np.testing.assert_allclose(nm.safe_pow(0.5, 3.0), 0.125, rtol=1e-6)
    g = jax.grad(nm.safe_pow, argnums=(0, 1))(0.0, 2.0)
    assert all(np.isfinite(v) for v in g)


def test_one_minus_epsilon_is_the_float_below_one():
    assert nm.one_minus_epsilon(np.float32) == 1 - 2.0**-24
    assert nm.one_minus_epsilon(np.float64) == 1 - 2.0**-53
    u = nm.clamp_unit_interval(jnp.array([1.0, 0.3, -0.1], jnp.float32))
    assert float(u[0]) < 1.0 and float(u[2]) == 0.0


def test_one_minus_cos_theta_keeps_precision_near_the_pole():
    # θ = 1e-5: 1 - cos θ = 5e-11 is below float32 epsilon, so 1 - z would give 0.
    theta = 1e-5
    v = jnp.array([np.sin(theta), 0.0, np.cos(theta)], jnp.float32)
    assert float(1.0 - v[2]) == 0.0
    np.testing.assert_allclose(nm.one_minus_cos_theta(v), 2 * np.sin(theta / 2) ** 2, rtol=1e-5)


def test_azimuth_fraction_is_in_the_unit_interval_and_inverts_sincos():
    u = jnp.array([0.0, 0.25, 0.5, 0.75, 1 - 2.0**-24], jnp.float32)
    s, c = nm.sincos_2pi(u)
    f = nm.azimuth_fraction(s, c)
    assert np.all((np.asarray(f) >= 0) & (np.asarray(f) < 1))
    d = np.asarray(f - u)
    np.testing.assert_allclose(d - np.round(d), 0.0, atol=2e-7)
    assert np.all(np.isfinite(jax.grad(lambda y: nm.azimuth_fraction(y, 0.0))(0.0)))
