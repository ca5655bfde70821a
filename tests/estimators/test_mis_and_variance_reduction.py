"""MIS (balance, power), the self-normalized ratio estimator, antithetic pairs, control variates.

FFRs: a mean checked against the exact value within 6 estimated stderrs fails with probability
~2e-9 (normal; the estimated stderr from >= 2^16 samples is within a few % of the true one).
Variance ratios: each bound is stated with the mean ± sd of the same ratio over 64 keys (measured
once, same estimator and n); every bound is at least 12 such sd away (normal FFR < 1e-30).
The weights themselves are checked deterministically against hand computations (no FFR), and
tests/estimators/test_calibration.py holds every error bar to the spread of its estimates.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxsample as js
from jaxsample.estimators.plain import estimate
from jaxsample.estimators import (estimate_antithetic, estimate_control_variate,
    estimate_mis, estimate_ratio)

from keyring import next_key

jax.config.update("jax_debug_key_reuse", True)

HALF_PI = np.pi / 2


def cos3(w):
    return w[2] ** 3


def close(est, truth, k=6.0):
    return abs(float(est.mean) - truth) <= k * float(est.stderr)


@pytest.mark.parametrize("heuristic", ["balance", "power"])
def test_mis_unbiased(heuristic):
    run = jax.jit(lambda k: estimate_mis(cos3, [js.CosineHemisphere(), js.UniformHemisphere()], k,
                                         [1 << 16, 1 << 15], heuristic=heuristic))
    est = run(next_key())
    assert close(est, HALF_PI) and est.n == 3 << 15
    # Wrong: both techniques with weight 1 (no MIS weights) counts the integral twice.
    a = estimate(cos3, js.CosineHemisphere(), next_key(), 1 << 16)
    b = estimate(cos3, js.UniformHemisphere(), next_key(), 1 << 15)
    mean, stderr = float(a.mean + b.mean), float(jnp.hypot(a.stderr, b.stderr))
    assert not abs(mean - HALF_PI) <= 6 * stderr


MIS_COUNTS = [3 << 10, 1 << 10]   # unequal on purpose: the weights must see n_k


def _mis_samplers():
    return [js.CosineHemisphere(), js.PhongLobe(8.0)]


def test_balance_heuristic_with_unequal_counts_is_exact_for_the_count_weighted_mixture():
    """With w_i = n_i p_i / Σ_k n_k p_k, each sample contributes f / Σ_k n_k p_k; for
    f = Σ_k n_k p_k / N (∫f = 1) every sample contributes exactly 1/N: the estimate is 1 with no
    variance, up to float32 rounding (deterministic, no FFR). Weights that ignore the counts
    (p_i / Σ p_k, which still sum to 1) leave a spread and miss 1 on these samples."""
    samplers = _mis_samplers()
    total = sum(MIS_COUNTS)

    def f(w):
        return sum(n * s.pdf(w[None])[0] for n, s in zip(MIS_COUNTS, samplers)) / total

    est = jax.jit(lambda k: estimate_mis(f, samplers, k, MIS_COUNTS, heuristic="balance"))(next_key())
    assert abs(float(est.mean) - 1.0) < 1e-5 and float(est.stderr) < 1e-6, (est.mean, est.stderr)


@pytest.mark.parametrize("heuristic,beta", [("power", 2.0), ("power", 3.0), ("balance", 1.0)])
def test_mis_weights_are_the_count_weighted_heuristic_on_the_same_samples(heuristic, beta):
    """estimate_mis against a hand computation from the same points (each technique draws the
    stream of its own key, split from `key`): w_i = (n_i p_i)^β / Σ_j (n_j p_j)^β with unequal
    n_j. Deterministic (no FFR): the two differ only by float32 rounding (rtol 2e-6), while
    weights without the counts give a value 100x farther off on these samples."""
    samplers = _mis_samplers()
    # A fixed key chosen for its margin: the gap to the count-free weights is random, 21 to 7000
    # times the rtol over keys 0-7 (key 0: 21 for power-2); on key 3 it is over 1600 for all three heuristics.
    key = jax.random.key(3)
    est = jax.jit(lambda k: estimate_mis(cos3, samplers, k, MIS_COUNTS, heuristic=heuristic, beta=beta))(
        jax.random.clone(key))

    def by_hand(counts_in_weights):
        total = 0.0
        for i, (sampler, key_i) in enumerate(zip(samplers, jax.random.split(key if counts_in_weights
                                                                           else jax.random.clone(key), 2))):
            u = js.uniforms.uniform_block("random", key_i, 0, MIS_COUNTS[i], 2)
            x, own = sampler.warp_with_pdf(u)
            pdfs = [np.asarray(own if k == i else other.pdf(x), np.float64) for k, other in enumerate(samplers)]
            scale = MIS_COUNTS if counts_in_weights else [1, 1]
            scaled = [(c * p) ** beta for c, p in zip(scale, pdfs)]
            weight = scaled[i] / sum(scaled)
            total += np.mean(weight * np.asarray(x[:, 2], np.float64) ** 3 / pdfs[i])
        return total

    without_counts = by_hand(False)
    expected = by_hand(True)
    np.testing.assert_allclose(float(est.mean), expected, rtol=2e-6)
    assert abs(without_counts - expected) > 100 * 2e-6 * abs(expected), (without_counts, expected)


def test_power_heuristic_beats_balance_on_glossy_lobe_times_small_light():
    """f = Phong(50) lobe restricted to a small cone light (half-angle 0.05, tilted by 0.1 rad);
    techniques: lobe sampling and cone sampling. Over 64 keys power/balance's variance was
    0.284 ± 0.026 (1/3.5): the bound 0.6 is 12 sd away."""
    axis = jnp.array([np.sin(0.1), 0.0, np.cos(0.1)], jnp.float32)
    cos_max = float(np.cos(0.05))
    lobe = js.PhongLobe(exponent=50.0)
    cone = js.Oriented(js.UniformCone(cos_theta_max=cos_max), axis)

    def f(w):
        return jnp.where(jnp.dot(w, axis) >= cos_max, lobe.pdf(w), 0.0)

    run = jax.jit(lambda k, h: estimate_mis(f, [lobe, cone], k, [1 << 17, 1 << 17], heuristic=h),
                  static_argnums=1)
    balance = run(next_key(), "balance")
    power = run(next_key(), "power")
    assert float(power.variance) < 0.6 * float(balance.variance)
    gap = abs(float(power.mean) - float(balance.mean))
    assert gap <= 6 * np.hypot(float(power.stderr), float(balance.stderr))


def test_ratio_estimator_bias_shrinks_like_one_over_n():
    """(∫cos³)/(∫cos) = 1/2 with uniform hemisphere sampling. Delta method: bias ≈ c/n with
    c = (R Var Z - Cov(Y, Z))/E[Z]² = 1/6 - 3/10 = -2/15. Means over 2^16 estimates each.
    Measured over 3 seeds: the biases are 18-40 sd from 0, the ratio bias_8/bias_32 is 4.2 ± 0.25
    (its bounds 2.5 and 6 are 7 sd away) and 32 bias_32 + 2/15 is within ±0.014 of 0 with sd
    0.0072 (the bound 0.047 is > 4.5 sd away even with that O(1/n²) offset): FFR below 1e-5."""
    def mean_ratio(n):
        keys = jax.random.split(next_key(), 1 << 16)
        est = jax.jit(jax.vmap(lambda k: estimate_ratio(cos3, lambda w: w[2], js.UniformHemisphere(), k, n)))(keys)
        return float(jnp.mean(est.mean)), float(jnp.std(est.mean)) / 256.0

    bias_8, sd_8 = mean_ratio(8)
    bias_32, sd_32 = mean_ratio(32)
    bias_8, bias_32 = bias_8 - 0.5, bias_32 - 0.5
    assert bias_8 < -6 * sd_8 and bias_32 < -6 * sd_32   # really biased ...
    assert 2.5 < bias_8 / bias_32 < 6.0                   # ... like 1/n (4 expected)
    assert abs(32 * bias_32 + 2 / 15) < 0.35 * 2 / 15     # and with the predicted constant
    big = estimate_ratio(cos3, lambda w: w[2], js.UniformHemisphere(), next_key(), 1 << 18)
    assert close(big, 0.5)                                # consistent


def test_antithetic_reduces_variance_and_stays_unbiased():
    n = 1 << 16
    plain = estimate(cos3, js.UniformHemisphere(), next_key(), n)
    anti = estimate_antithetic(cos3, js.UniformHemisphere(), next_key(), n)
    assert close(anti, HALF_PI)
    assert float(anti.variance) < 0.5 * float(plain.variance)   # 0.3115 ± 0.0023 over 64 keys: 81 sd
    # Where the reflection maps u to a point with the same value, pairs are copies: no gain.
    same = estimate_antithetic(cos3, js.CosineHemisphere(), next_key(), n)
    # ρ = 1: twice the plain variance (2.002 ± 0.013 over 64 keys; the bound 1.5 is 39 sd away).
    assert float(same.variance) > 1.5 * float(estimate(cos3, js.CosineHemisphere(), next_key(), n).variance)


def test_control_variate_reduces_variance_and_stays_unbiased():
    n = 1 << 16
    plain = estimate(cos3, js.UniformHemisphere(), next_key(), n)
    cv = estimate_control_variate(cos3, lambda w: w[2], np.pi, js.UniformHemisphere(), next_key(), n)
    assert close(cv, HALF_PI)
    assert float(cv.variance) < 0.3 * float(plain.variance)   # 1 - ρ² ≈ 0.160 ± 0.0011: 133 sd
    # A wrong "known" integral biases it visibly.
    wrong = estimate_control_variate(cos3, lambda w: w[2], 1.05 * np.pi, js.UniformHemisphere(), next_key(), n)
    assert not close(wrong, HALF_PI)


def test_chebyshev_interval_is_wider_than_normal():
    est = estimate(cos3, js.CosineHemisphere(), next_key(), 1 << 12)
    lo, hi = est.interval(0.95)
    clo, chi = est.chebyshev_interval(0.95)
    np.testing.assert_allclose(float(chi - clo) / float(hi - lo), (1 / np.sqrt(0.05)) / 1.959964, rtol=1e-5)


def test_estimate_mis_accepts_a_traced_beta():
    """beta may be traced (jit over it); an integer-valued concrete beta becomes an int power."""
    f = lambda w: jnp.maximum(w[2], 0.0) ** 3  # noqa: E731
    samplers = [js.UniformHemisphere(), js.CosineHemisphere()]
    key = jax.random.key(12)
    traced = jax.jit(lambda b: js.estimate_mis(f, samplers, jax.random.clone(key), [1024, 1024],
                                               heuristic="power", beta=b).mean)(2.0)
    concrete = js.estimate_mis(f, samplers, key, [1024, 1024], heuristic="power", beta=2.0).mean
    np.testing.assert_allclose(traced, concrete, rtol=1e-5)


def test_both_mis_paths_check_heuristic_and_beta_alike():
    """`estimate_mis` and `scene.shade(strategy="mis")` share `heuristic` and `beta`, checked by one
    rule: beta is the power heuristic's exponent (balance is beta = 1), a number > 0."""
    from jaxsample import scene

    samplers = [js.CosineHemisphere(), js.PhongLobe(3.0)]
    lit = (jnp.zeros(3), jnp.array([0.0, 0.0, 1.0]), jnp.array([0.0, 0.0, 1.0]), scene.Lambertian(0.5),
           scene.ConstantSky(1.0))
    calls = {"estimate_mis": lambda **kw: estimate_mis(cos3, samplers, jax.random.key(41), [64, 64], **kw),
             "shade": lambda **kw: scene.shade(*lit, jax.random.key(43), 64, **kw)}
    for owner, call in calls.items():
        with pytest.raises(ValueError, match=rf"^{owner}: parameter 'beta' applies to heuristic='power'"):
            call(heuristic="balance", beta=3.0)
        with pytest.raises(ValueError, match=rf"^{owner}: parameter 'beta' must be a finite number > 0"):
            call(heuristic="power", beta=-1.0)
        with pytest.raises(ValueError, match=rf"^{owner}: parameter 'heuristic' must be one of"):
            call(heuristic="cutoff")
    with pytest.raises(ValueError, match=r"^shade: parameter 'beta' applies to strategy='mis' only"):
        calls["shade"](strategy="brdf", beta=2.0)
    # beta = 2 is the power heuristic's default, in both paths: the same program, the same bits.
    assert float(calls["estimate_mis"](heuristic="power", beta=2.0).mean) == float(
        calls["estimate_mis"](heuristic="power").mean)
    assert float(calls["shade"](beta=2.0).mean) == float(calls["shade"]().mean)

