"""Every reported error bar is calibrated: the spread of estimates over keys matches their stderr.

"|mean - truth| < k stderr" passes more easily when the stderr is too large, so it cannot see an
inflated error bar. Here each estimator path runs on K independent keys at a small n (one `jit` of
a `vmap` over the keys: one compilation per path), and the observed standard deviation of the K
means is compared with the mean of the K reported stderrs:

    ratio = sd(means) / mean(stderr), which is 1 for an honest stderr.

Tolerance, and the false-failure rate (FFR). The sample standard deviation of K values has a
relative standard deviation of sqrt((κ - 1) / (4 (K - 1))), κ the kurtosis of the means (3 for
normal means: 1/sqrt(2(K - 1)) = 0.031 for K = 512); κ is estimated from the same means and never
taken below 3. The mean of the K stderrs adds a relative sd of sd(stderr)/(mean(stderr) sqrt(K)).
The bound is 5 combined sigmas (two-sided normal FFR 5.7e-7 per path, 15 paths) plus the O(1/m) bias
of a standard deviation taken from m terms: for R replicates E[stderr] = c4(R) σ (normal replicate
means; c4(16) = 0.9835), which is divided out, and 1/m is added to the bound for the paths whose
stderr comes from m >= 256 independent terms. A stderr 3x or 4x too large gives a ratio of 0.33 or
0.25, far outside the bound (tests/mutations.py records that each of these tests fails on such a
break). Where the exact value is known, the mean of the K means is also held to it within 5 sd /
sqrt(K) (FFR 5.7e-7 per path, 11 paths): 26 checks, 1.5e-5 for the file.

Gradient estimators (`expectation(..., gradient=...)`, `estimate(..., mode=...)`) report no
spread of their own (the stderr they return is the value's, checked here for the leave-one-out
path); their per-sample variances are held to the exact ones in tests/estimators/test_gradients.py.
"""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxsample as js
from jaxsample import scene
from jaxsample.estimators import (estimate_antithetic, estimate_control_variate,
    estimate_mis, estimate_ratio)

K = 512
K_SIGMA = 5.0
HALF_PI = math.pi / 2


def cos3(w):
    return w[2] ** 3


def c4(m):
    """E[s]/σ for the sample sd of m normal values."""
    return math.sqrt(2.0 / (m - 1)) * math.exp(math.lgamma(m / 2) - math.lgamma((m - 1) / 2))


def phong_cos3(exponent):
    return cos3, js.PhongLobe(exponent)


LIGHT = scene.SphereLight(jnp.array([0.5, 0.2, 2.0]), 0.8, 3.0)

# name: (estimator of one key, exact value or None, replicates R or terms m, "replicates"|"terms")
PATHS = {
    "random": (lambda k: js.estimate(cos3, js.UniformHemisphere(), k, 256), HALF_PI, 256, "terms"),
    "stratified": (lambda k: js.estimate(cos3, js.UniformHemisphere(), k, 1024, uniforms="stratified"),
                   HALF_PI, 16, "replicates"),
    "sobol": (lambda k: js.estimate(cos3, js.UniformHemisphere(), k, 1024, uniforms="sobol"),
              HALF_PI, 16, "replicates"),
    "mis": (lambda k: estimate_mis(cos3, [js.CosineHemisphere(), js.UniformHemisphere()], k, [256, 64],
                                   heuristic="power"), HALF_PI, 64, "terms"),
    # Self-normalized ∫cos³/∫cos = 1/2: biased by O(1/n), so no check of the mean.
    "ratio": (lambda k: estimate_ratio(cos3, lambda w: w[2], js.UniformHemisphere(), k, 1024), None, 1024,
              "terms"),
    "antithetic": (lambda k: estimate_antithetic(cos3, js.UniformHemisphere(), k, 512), HALF_PI, 256, "terms"),
    "control-variate": (lambda k: estimate_control_variate(cos3, lambda w: w[2], math.pi, js.UniformHemisphere(),
                                                           k, 1024), None, 1024, "terms"),
    "shade-mis": (lambda k: scene.shade(jnp.zeros(3), jnp.array([0.0, 0.0, 1.0]), jnp.array([0.3, 0.0, 1.0]),
                                        scene.Phong(5.0, 0.8), LIGHT, k, 512), None, 256, "terms"),
    "shade-light-sobol": (lambda k: scene.shade(jnp.zeros(3), jnp.array([0.0, 0.0, 1.0]), jnp.array([0.3, 0.0, 1.0]),
                                                scene.Lambertian(0.8), LIGHT, k, 1024, strategy="light",
                                                uniforms="sobol"), None, 16, "replicates"),
    # estimate_until run to max_n (a tolerance no key meets): its stderr is the finishing step's
    # for each source, with the sequential loop around it.
    "until-random": (lambda k: js.estimate_until(cos3, js.UniformHemisphere(), k, rtol=1e-9, max_n=1024,
                                                 chunk_size=256), HALF_PI, 1024, "terms"),
    "until-sobol": (lambda k: js.estimate_until(cos3, js.UniformHemisphere(), k, atol=1e-12, max_n=1 << 12,
                                                chunk_size=1 << 10, uniforms="sobol"), HALF_PI, 16, "replicates"),
    # Gradients' stderrs from their per-replicate terms (Sobol', stratified): d/dn ∫ cos³ dω under
    # Phong(n) samples (exactly 0: a fixed integral), and d/dn E_Phong(n)[cos³] = 3/(n + 4)² by the
    # score function.
    "estimate-grad-sobol": (lambda k: js.estimate_grad(phong_cos3, 3.0, k, 1024, uniforms="sobol"), 0.0, 16,
                            "replicates"),
    "estimate-grad-stratified": (lambda k: js.estimate_grad(phong_cos3, 3.0, k, 1024, uniforms="stratified"), 0.0,
                                 16, "replicates"),
    "expectation-grad-score-sobol": (lambda k: js.expectation_grad(phong_cos3, 3.0, k, 1024, gradient="score",
                                                                   uniforms="sobol"), 3.0 / 49.0, 16, "replicates"),
    "expectation-leave-one-out": (lambda k: js.expectation(cos3, js.PhongLobe(3.0), k, 256, gradient="score",
                                                           baseline="leave_one_out"), 4.0 / 7.0, 256, "terms"),
}


def calibration(means, stderrs, size, kind):
    """(ratio corrected for the c4 bias, its bound) for K means and their reported stderrs."""
    means, stderrs = np.asarray(means, np.float64), np.asarray(stderrs, np.float64)
    count = means.size
    centred = means - means.mean()
    kurtosis = max(float(np.mean(centred ** 4) / np.mean(centred ** 2) ** 2), 3.0)
    relative_sd = math.sqrt((kurtosis - 1) / (4 * (count - 1))
                            + (stderrs.std() / stderrs.mean()) ** 2 / count)
    ratio = means.std(ddof=1) / stderrs.mean()
    if kind == "replicates":
        return ratio * c4(size), K_SIGMA * relative_sd
    return ratio, K_SIGMA * relative_sd + 1.0 / size


@pytest.mark.parametrize("name", list(PATHS))
def test_stderr_matches_the_spread_of_estimates_over_keys(name):
    estimator, exact, size, kind = PATHS[name]
    keys = jax.random.split(jax.random.key(4242 + list(PATHS).index(name)), K)
    est = jax.jit(jax.vmap(estimator))(keys)
    means = np.asarray(est.mean, np.float64)
    assert means.shape == (K,) and np.all(np.isfinite(means)) and np.all(np.asarray(est.stderr) > 0)
    ratio, bound = calibration(means, est.stderr, size, kind)
    assert abs(ratio - 1.0) < bound, (name, ratio, bound)
    if exact is not None:
        assert abs(means.mean() - exact) < K_SIGMA * means.std(ddof=1) / math.sqrt(K), (name, means.mean(), exact)


def test_calibration_rejects_an_error_bar_off_by_half():
    """The same statistic on a stderr deliberately scaled by 1.5 and by 1/1.5 (synthetic normal
    means, exact stderr 1): both fail, while the honest one passes (FFR 5.7e-7 as above)."""
    rng = np.random.default_rng(0)
    means = rng.normal(size=K)
    stderrs = np.ones(K)
    ratio, bound = calibration(means, stderrs, 10 ** 6, "terms")
    assert abs(ratio - 1) < bound
    for scale in (1.5, 1 / 1.5):
        ratio, bound = calibration(means, scale * stderrs, 10 ** 6, "terms")
        assert abs(ratio - 1) > bound, scale


def test_mis_variance_is_per_evaluation_at_the_calibrated_stderr():
    """`estimate_mis`'s variance is stated per evaluation, stderr² (n₁ + n₂), so that strategies
    compare at equal cost; with the stderr calibrated above, that pins the variance too."""
    est = estimate_mis(cos3, [js.CosineHemisphere(), js.UniformHemisphere()], jax.random.key(77), [256, 64],
                       heuristic="power")
    np.testing.assert_allclose(float(est.variance), float(est.stderr) ** 2 * 320, rtol=1e-5)
