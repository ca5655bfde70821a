"""What is particular to Exponential, TruncatedExponential, Power and PiecewiseConstant1D/2D;
their contract (normalization, chi-square, inverse, Jacobian, support, finite values and gradients
at the hard cases, huge tables) is `test_contract.py`, over the entries of `registry.py`.

Here: normalization over the parameter ranges, wrong samplers the chi-square test rejects (at the
contract's settings for the entry they imitate), exact values near the ends, zero bins, parameter
errors and jit/vmap over parameters.
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
from jaxsample.samplers.exponential import Exponential, TruncatedExponential
from jaxsample.samplers.piecewise import PiecewiseConstant1D, PiecewiseConstant2D
from jaxsample.samplers.power import Power
from jaxsample.testing.sampler_checks import chi2_test, normalization

TABLE, TABLE_2D = registry.TABLE, registry.TABLE_2D


@settings(derandomize=True, deadline=None, max_examples=20)
@given(st.floats(-6.0, 6.0), st.floats(-3.0, 3.0), st.floats(0.0, 6.0))
def test_normalization_over_parameter_range(log_rate, log_t_max, log_exponent):
    rate, t_max, exponent = 10.0 ** log_rate, 10.0 ** log_t_max, 10.0 ** log_exponent - 1.0
    assert abs(normalization(Exponential(rate)) - 1.0) < 1e-6
    assert abs(normalization(TruncatedExponential(rate, t_max)) - 1.0) < 1e-6
    assert abs(normalization(Power(exponent)) - 1.0) < 1e-6


def test_chi2_fails_for_wrong_samplers():
    keys = jax.random.split(jax.random.key(3), 2)
    # Rate off by 2 %: the statistic's excess over its mean grows like N·(0.02)². At the contract's
    # sample size for these entries (10^6), the rejection has a wide margin: p below 1e-20 where
    # the Šidák threshold is 1.1e-8 (seen over keys: 1e-49 to 1e-75), so it is not one lucky key.
    # FFR below 3e-7 per check (estimated: a noncentral chi-square(63) whose median p is 1e-49).
    wrong_rate = WrongWarp(Exponential(1.0), Exponential(1.02))
    result = chi2_test(wrong_rate, keys[0], **registry.chi2_settings("Exponential"))
    assert not result.passed and result.p_value < 1e-20, result
    wrong_exponent = WrongWarp(Power(3.0), Power(3.15))
    result = chi2_test(wrong_exponent, keys[1], **registry.chi2_settings("Power"))
    assert not result.passed and result.p_value < 1e-20, result


def test_exponential_exact_near_zero_and_finite_near_one():
    u = jnp.array([[0.0], [1e-30], [1e-10], [1.0 - 2.0 ** -24]], jnp.float32)
    for rate in (1e-6, 1.0, 1e6):
        t = Exponential(rate).warp(u)
        np.testing.assert_allclose(np.asarray(t[1:3]), np.array([1e-30, 1e-10]) / rate, rtol=1e-6)
        assert t[0] == 0 and np.isfinite(t[3]) and abs(float(t[3]) * rate - 24 * np.log(2)) < 1e-4
    # The truncated form tends to a uniform distance as rate · t_max -> 0.
    t = TruncatedExponential(1e-6, 2.0).warp(jnp.array([[0.25], [0.5], [0.75]]))
    np.testing.assert_allclose(np.asarray(t), [0.5, 1.0, 1.5], rtol=1e-5)


def test_zero_bins_never_sampled():
    for sampler, key in zip([PiecewiseConstant1D(TABLE), PiecewiseConstant2D(TABLE_2D)],
                            jax.random.split(jax.random.key(6), 2)):
        x = _sample(sampler, key)
        assert np.all(np.asarray(_pdf(sampler, x)) > 0)
        # Remainders just below 1 and exactly 0 land in their own bin, never in a zero neighbour.
        edges = jnp.asarray(np.concatenate([sampler.cdf if hasattr(sampler, "cdf") else sampler.marginal_cdf]))
        u = jnp.clip(jnp.concatenate([edges, jnp.nextafter(edges, 0.0)]), 0.0, 1 - 2.0 ** -24)
        u = jnp.stack([u] * sampler.uniform_dims, axis=-1)
        assert np.all(np.asarray(_pdf(sampler, _warp(sampler, u))) > 0)


def test_invalid_parameters_raise():
    with pytest.raises(ValueError, match=r"Exponential: parameter 'rate' must be in \(0, inf\)"):
        Exponential(0.0)
    with pytest.raises(ValueError, match="'rate'"):
        Exponential(float("nan"))
    with pytest.raises(ValueError, match="'t_max'"):
        TruncatedExponential(1.0, -1.0)
    with pytest.raises(ValueError, match=r"Power: parameter 'exponent' must be in \[0, 1e\+06\]"):
        Power(-0.5)
    with pytest.raises(ValueError, match="integer 'exponent'"):
        Power(2.5, method="max")
    with pytest.raises(ValueError, match="'values'.*not all zero"):
        PiecewiseConstant1D(np.zeros(4))
    with pytest.raises(ValueError, match="'values'"):
        PiecewiseConstant1D(np.array([1.0, -1.0]))
    with pytest.raises(ValueError, match="'values'.*2 dimension"):
        PiecewiseConstant2D(np.ones(4))


def test_jit_and_vmap_over_parameters():
    keys = jax.random.split(jax.random.key(7), 2)
    rates = jnp.logspace(-6, 6, 13)
    u = jax.random.uniform(keys[0], (13, 1))

    @jax.jit
    def run(rate, exponent, values, u):
        e, t, p, c = Exponential(rate), TruncatedExponential(rate, 2.0), Power(exponent), PiecewiseConstant1D(values)
        return [s.warp_with_pdf(u) for s in (e, t, p, c)] + [e.pdf(e.warp(u)), p.pdf(p.warp(u))]

    values = jax.random.uniform(keys[1], (13, 16))
    out = jax.vmap(run)(rates, jnp.logspace(0, 6, 13) - 1.0, values, u)
    for item in jax.tree_util.tree_leaves(out):
        assert np.all(np.isfinite(np.asarray(item)))
    (e_x, e_p), (t_x, t_p), (p_x, p_p), (c_x, c_p), e_pdf, p_pdf = out
    np.testing.assert_allclose(e_pdf, e_p, rtol=1e-4)
    np.testing.assert_allclose(np.asarray(e_x) * np.asarray(rates), -np.log1p(-np.asarray(u, np.float64)[:, 0]),
                               rtol=1e-5)
    assert np.all((np.asarray(t_x) >= 0) & (np.asarray(t_x) <= 2.0))


@settings(derandomize=True, deadline=None, max_examples=20)
@given(st.floats(-6.0, 6.0), st.floats(0.0, 1.0 - 2.0 ** -24))
def test_exponential_density_from_u_matches_pdf(log_rate, u0):
    rate = 10.0 ** log_rate
    u = jnp.array([[u0]], jnp.float32)
    for sampler in (Exponential(rate), TruncatedExponential(rate, 1.0 / rate)):
        x, p = _warp_with_pdf(sampler, u)
        np.testing.assert_allclose(p, _pdf(sampler, x), rtol=2e-5)


_warp_with_pdf = jax.jit(lambda s, u: s.warp_with_pdf(u))
_pdf = jax.jit(lambda s, x: s.pdf(x))
_warp = jax.jit(lambda s, u: s.warp(u))
_sample = jax.jit(lambda s, key: s.sample(key, (200_000,)))
