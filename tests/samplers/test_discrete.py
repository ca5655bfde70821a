"""Discrete: CDF search and alias table on {0, ..., K-1}, with remainders, zero weights and huge tables.

The contract (normalization, chi-square, support, finite values and gradients, both methods, tables
of 10^6 weights) is `test_contract.py`, over the entries of `registry.py`; here what is particular
to finite sets.
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
from jaxsample.samplers.discrete import Discrete, build_alias_table
from jaxsample.testing.sampler_checks import chi2_test, normalization

METHODS = ("cdf", "alias")
SMALL = registry.WEIGHTS
HUGE = registry.HUGE_WEIGHTS  # a leading run of zeros: u = 0 must not select them

_warp_with_remainder = jax.jit(lambda s, u: s.warp_with_remainder(u))
_sample = jax.jit(lambda s, key: s.sample(key, (100_000,)))


def _huge(method, cache={}):
    if method not in cache:
        cache[method] = Discrete(HUGE, method)
    return cache[method]


def test_chi2_fails_for_wrong_weights():
    wrong = SMALL.copy()
    wrong[1] *= 1.1  # outcome 1 about 6 % too likely
    # At the contract's settings for the entry and by a margin (p < 1e-15; seen over keys: 1e-32 to 1e-51).
    # FFR about 1e-7 (estimated: a noncentral chi-square(4) whose median p is 1e-40 reaches 1e-15
    # that rarely; 8e-5 if the median were 1e-32).
    result = chi2_test(WrongWarp(Discrete(SMALL), Discrete(wrong, "alias")), jax.random.key(2),
                       **registry.chi2_settings("Discrete-cdf"))
    assert not result.passed and result.p_value < 1e-15, result


def test_alias_table_reproduces_the_pmf_exactly():
    for weights in (SMALL, HUGE[:20_000], np.array([1.0, 1e-12, 1e12, 0.0, 5.0])):
        pmf = weights / weights.sum()
        probability, alias = build_alias_table(pmf)
        k = len(pmf)
        implied = (probability + np.bincount(alias, weights=1.0 - probability, minlength=k)) / k
        np.testing.assert_allclose(implied, pmf, rtol=1e-9, atol=1e-15)
        assert np.all(probability[pmf == 0] == 0)
        assert not np.any(np.isin(alias[probability < 1], np.flatnonzero(pmf == 0)))


@pytest.mark.parametrize("method", METHODS)
def test_zero_weights_never_selected(method):
    sampler = Discrete(SMALL, method)
    # Every CDF step, every bucket edge, both sides of each, and the ends of [0, 1).
    k = len(SMALL)
    points = np.concatenate([np.cumsum(SMALL) / SMALL.sum(), np.arange(k + 1) / k,
                             (np.arange(k) + np.asarray(sampler.alias_probability if method == "alias" else 0.5)) / k])
    u = jnp.asarray(np.clip(np.concatenate([points, np.nextafter(points, 0), np.nextafter(points, 1)]),
                            0, 1 - 2.0 ** -24), jnp.float32)[:, None]
    outcome, remainder = _warp_with_remainder(sampler, u)
    assert np.all(SMALL[np.asarray(outcome)] > 0)
    assert np.all((np.asarray(remainder) >= 0) & (np.asarray(remainder) < 1))
    huge = _sample(_huge(method), jax.random.key(3))
    assert np.all(HUGE[np.asarray(huge)] > 0)
    assert huge.dtype == jnp.int32


@pytest.mark.parametrize("method", METHODS)
def test_remainder_is_uniform_within_each_outcome(method):
    # Deterministic: on an evenly spaced grid of u the remainders of each outcome are evenly spread.
    sampler = Discrete(SMALL, method)
    with jax.enable_x64(True):
        u = (jnp.arange(200_000, dtype=jnp.float64) + 0.5)[:, None] / 200_000
        outcome, remainder = _warp_with_remainder(jax.tree_util.tree_map(lambda t: t, sampler), u)
    outcome, remainder = np.asarray(outcome), np.asarray(remainder)
    for i in np.flatnonzero(SMALL):
        r = np.sort(remainder[outcome == i])
        # Kolmogorov distance to U(0, 1) of a deterministic, nearly even grid.
        assert np.max(np.abs(r - (np.arange(len(r)) + 0.5) / len(r))) < 2e-3, i


def test_invalid_weights_raise():
    for bad, message in [(np.zeros(3), "not all zero"), (np.array([1.0, -1.0]), r"\[0, inf\)"),
                         (np.array([1.0, np.nan]), r"\[0, inf\)"), (np.array([1.0, np.inf]), r"\[0, inf\)"),
                         (np.ones((2, 2)), "1 dimension"), (np.zeros(0), "non-empty")]:
        for method in METHODS:
            with pytest.raises(ValueError, match=f"Discrete: parameter 'weights'.*{message}"):
                Discrete(bad, method)
    with pytest.raises(ValueError, match="'method'"):
        Discrete(SMALL, "linear")
    with pytest.raises(ValueError, match="concrete 'weights'"):
        jax.jit(lambda w: Discrete(w, "alias").pmf)(jnp.asarray(SMALL))


def test_jit_and_vmap_over_weights():
    keys = jax.random.split(jax.random.key(4), 2)
    weights = jax.random.uniform(keys[0], (32, 8)) * (jnp.arange(8) % 3 != 0)
    u = jax.random.uniform(keys[1], (32, 5, 1))

    @jax.jit
    def run(w, u):
        s = Discrete(w)
        x, p = s.warp_with_pdf(u)
        return x, p, s.log_pdf(x)

    x, p, log_p = jax.vmap(run)(weights, u)
    w = np.asarray(weights)
    chosen = np.take_along_axis(w, np.asarray(x), axis=1)
    assert np.all(chosen > 0)
    np.testing.assert_allclose(p, chosen / w.sum(axis=1, keepdims=True), rtol=1e-5)
    np.testing.assert_allclose(np.exp(log_p), p, rtol=1e-5)
    # A sampler built outside jit (alias tables included) passes through it as a pytree.
    alias = Discrete(SMALL, "alias")
    np.testing.assert_array_equal(jax.jit(lambda s, u: s.warp(u))(alias, u[0]), alias.warp(u[0]))


@settings(derandomize=True, deadline=None, max_examples=25)
@given(st.lists(st.sampled_from([0.0, 1e-30, 1e-6, 0.3, 1.0, 7.0, 1e20]), min_size=6, max_size=6),
       st.floats(0.0, 1.0 - 2.0 ** -24))
def test_random_weights(values, u0):
    weights = np.array(values)
    if not weights.sum() > 0:
        with pytest.raises(ValueError):
            Discrete(weights)
        return
    for method in METHODS:
        sampler = Discrete(weights, method)
        assert abs(normalization(sampler) - 1.0) < 1e-6
        outcome, remainder = _warp_with_remainder(sampler, jnp.array([[u0], [0.0], [1.0 - 2.0 ** -24]], jnp.float32))
        assert np.all(weights[np.asarray(outcome)] > 0)
        assert np.all((np.asarray(remainder) >= 0) & (np.asarray(remainder) < 1))
