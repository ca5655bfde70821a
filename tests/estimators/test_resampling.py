"""Resampled importance sampling and the weighted reservoir, against closed forms.

False-failure rates (fresh keys) are stated per test; `tests/false_failures.md` sums them.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.scipy.special import gammaincc

import jaxsample as js
from jaxsample.estimators import Reservoir
from keyring import next_key

AXIS = jnp.array([0.36, -0.48, 0.8])  # a unit vector


def _lobe(w):
    return jnp.maximum(w @ AXIS, 0.0) ** 3 + 0.1


def _cosine_target(w):
    return jnp.maximum(w[2], 0.0) + 0.05


LOBE_INTEGRAL = math.pi / 2 + 0.4 * math.pi  # ∫ max(ω·a, 0)³ dω = 2π/4, plus 0.1 · 4π


def _binomial_tail(count, n, p, upper):
    """P(X >= count) (upper) or P(X <= count) for X ~ Binomial(n, p)."""
    ks = range(count, n + 1) if upper else range(0, count + 1)
    return sum(math.comb(n, k) * p ** k * (1 - p) ** (n - k) for k in ks)


def test_resampled_estimates_cover_the_integral_at_their_nominal_rate():
    """200 estimates (n = 2048 outputs of M = 8 uniform-sphere candidates resampled toward a
    cosine target that differs from f): the 95 % intervals mean ± 1.96 stderr contain the exact
    integral between 177 and 199 times. FFR: binomial tails at 0.95, P(X <= 176) + P(X = 200)
    = 7.2e-5 + 3.5e-5 ≈ 1.1e-4 (computed in the test)."""
    keys = jax.random.split(next_key(), 200)
    run = jax.jit(jax.vmap(lambda k: js.estimate_resampled(_lobe, js.UniformSphere(), _cosine_target, k, 2048, 8)))
    est = run(keys)
    covered = int(np.sum(np.abs(np.asarray(est.mean) - LOBE_INTEGRAL) < 1.96 * np.asarray(est.stderr)))
    assert _binomial_tail(176, 200, 0.95, upper=False) + _binomial_tail(200, 200, 0.95, upper=True) < 1.2e-4
    assert 177 <= covered <= 199, covered


@pytest.mark.parametrize("m", [1, 4, 16])
def test_with_the_integrand_as_target_the_variance_is_the_proposals_divided_by_m(m):
    """p̂ = f >= 0: f(y) W = (1/M) Σ_j f(x_j)/p(x_j), so the per-output variance is Var_p(f/p)/M
    exactly. f = max(z, 0)³ under the uniform sphere: Var(4π f) = 8π²/7 − π²/4 = 25π²/28. The
    sample variance of 2^16 outputs has relative sd sqrt((κ − 1)/n) <= 0.9 % (κ = 6.2 at M = 1,
    smaller for M > 1), so the 5 % band is 5.6 sd: FFR < 1e-7 per case."""
    f = lambda w: jnp.maximum(w[2], 0.0) ** 3  # noqa: E731
    est = js.estimate_resampled(f, js.UniformSphere(), f, next_key(), 1 << 16, m)
    assert abs(float(est.variance) / (25 * math.pi ** 2 / 28 / m) - 1) < 0.05, float(est.variance)


def _shared_parameter_estimate(theta, key):
    """∫ e^{θz}(2 + z) dω, proposal vMF(θ) and target e^{θz}: θ is in all three, and f/p̂ varies."""
    f = lambda w: jnp.exp(theta * w[2]) * (2.0 + w[2])  # noqa: E731
    target = lambda w: jnp.exp(theta * w[2])  # noqa: E731
    return js.estimate_resampled(f, js.VonMisesFisher(theta), target, key, 1 << 12, 8).mean


def test_the_gradient_is_the_closed_form_when_proposal_target_and_f_share_the_parameter():
    """d/dθ ∫ e^{θz}(2 + z) dω = 2A' + A'' with A(θ) = ∫ e^{θz} dω = 4π sinh θ/θ, from 64
    independent keys: |mean − exact| < 4.5 standard errors of the mean over them. FFR: Student
    t with 63 degrees of freedom beyond 4.5, 3e-5. The proposal's and the target's dependence on θ
    carry no derivative (the integral does not depend on them); differentiating them too is biased."""
    theta = 1.5
    sh, ch = math.sinh(theta), math.cosh(theta)
    first = 4 * math.pi * (ch / theta - sh / theta ** 2)
    second = 4 * math.pi * (sh / theta - 2 * ch / theta ** 2 + 2 * sh / theta ** 3)
    exact = 2 * first + second
    grads = np.asarray(jax.jit(jax.vmap(jax.grad(_shared_parameter_estimate), (None, 0)))(
        theta, jax.random.split(next_key(), 64)))
    assert abs(grads.mean() - exact) < 4.5 * grads.std(ddof=1) / 8, (grads.mean(), exact)


def _chi2_p_value(counts, probabilities):
    expected = probabilities * counts.sum()
    statistic = float(np.sum((counts - expected) ** 2 / expected))
    return float(gammaincc(0.5 * (len(counts) - 1), 0.5 * statistic))


WEIGHTS = np.array([0.5, 2.0, 0.0, 1.0, 3.0, 0.25, 1.5, 0.75], np.float32)


def _streamed(key, order):
    """A reservoir fed the candidates 0..7 in `order`, each with density 1 and target WEIGHTS[i]."""
    reservoir = Reservoir.empty(jnp.int32(0))
    for k, i in zip(jax.random.split(key, len(order)), order):
        reservoir = reservoir.add(k, jnp.int32(i), WEIGHTS[i], 1.0)
    return reservoir


def test_a_reservoir_keeps_each_candidate_in_proportion_to_its_weight_and_merges():
    """20,000 reservoirs, each streaming 8 weighted candidates (one of weight 0), in order and in
    reverse, and as two halves merged: the kept index against w/Σw by chi-square (6 cells of
    positive weight, the weight-0 one never kept), at level 1e-4 each. FFR 3e-4."""
    forward_keys, backward_keys, merged_keys = (jax.random.split(k, 20_000) for k in jax.random.split(next_key(), 3))
    forward = jax.vmap(lambda k: _streamed(k, range(8)))(forward_keys)
    backward = jax.vmap(lambda k: _streamed(k, range(7, -1, -1)))(backward_keys)

    def merged(key):
        first, second, join = jax.random.split(key, 3)
        return _streamed(first, range(4)).merge(join, _streamed(second, range(4, 8)))

    halves = jax.vmap(merged)(merged_keys)
    probabilities = WEIGHTS / WEIGHTS.sum()
    positive = probabilities > 0
    for reservoir in (forward, backward, halves):
        kept = np.asarray(reservoir.sample)
        counts = np.bincount(kept, minlength=8)
        assert counts[~positive].sum() == 0
        assert _chi2_p_value(counts[positive], probabilities[positive]) > 1e-4
        np.testing.assert_allclose(np.asarray(reservoir.weight_sum), WEIGHTS.sum(), rtol=1e-6)
        np.testing.assert_array_equal(np.asarray(reservoir.count), 8.0)
        # W = Σw / (M p̂(y)): f(y) W with f = p̂ is the mean weight, whatever was kept.
        np.testing.assert_allclose(np.asarray(reservoir.contribution_weight() * reservoir.target),
                                   WEIGHTS.mean(), rtol=1e-6)


def test_a_target_that_is_zero_everywhere_gives_zero_not_nan():
    f = lambda w: w[2] + 2.0  # noqa: E731
    with pytest.warns(js.UnreliableEstimateWarning, match="all 1024 values"):
        est = js.estimate_resampled(f, js.UniformSphere(), lambda w: 0.0 * w[2], next_key(), 1024, 4)
    assert float(est.mean) == 0.0 and float(est.stderr) == 0.0


def test_an_empty_reservoir_has_weight_zero():
    assert float(Reservoir.empty(jnp.zeros(3)).contribution_weight()) == 0.0


def test_bad_arguments_are_named():
    f = lambda w: w[2]  # noqa: E731
    with pytest.raises(ValueError, match="'m'"):
        js.estimate_resampled(f, js.UniformSphere(), f, next_key(), 1024, 0)
    with pytest.raises(ValueError, match="'target' must return a scalar"):
        js.estimate_resampled(f, js.UniformSphere(), lambda w: w, next_key(), 1024, 4)
    with pytest.raises(TypeError, match="'target'"):
        js.estimate_resampled(f, js.UniformSphere(), 3.0, next_key(), 1024, 4)
    with pytest.raises(ValueError, match="batch_shape"):
        js.estimate_resampled(f, js.PhongLobe(jnp.array([2.0, 3.0])), f, next_key(), 1024, 4)
