"""Gradients of estimates with respect to sampler parameters.

Statistical tests compare a gradient estimate with its exact mean, in units of a standard error
computed from the *exact* variance (docs/reference.md, "Gradients with respect to a sampler
parameter"). Thresholds: 5 standard errors for the fixed-integral tests (two-sided normal
false-failure rate 5.7e-7 per check), 4 for the E[cos^k] tests (6.3e-5 per check; 16 checks, so
about 1e-3 for the file as a whole). The keys are fixed, so a run is deterministic; the rates say
how unlikely a passing implementation is to have been unlucky. Each test is also run on a
deliberately wrong estimator, which the same threshold catches.
"""

from __future__ import annotations

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxsample as js
from jaxsample._core.pytree import static_field
from jaxsample.samplers.base import Sampler
from jaxsample.estimators.gradients import expectation, expectation_values, integrand_values

TWO_PI = 2.0 * math.pi


# ----------------------------------------------------------------------------------------------
# Exact means and variances (docs/reference.md; docs/literature.md §1.2-1.4)
# ----------------------------------------------------------------------------------------------


def attached_fixed_integral_variance(k, n):
    """Var of d/dn [cos^k / p_n] per sample, x ~ Phong(n); finite for n < 2k + 1."""
    b = (k + 1) / (n + 1)
    c = (2 * k + 1 - n) / (n + 1)
    return 4 * math.pi ** 2 / (n + 1) ** 4 * (2 * b * b / c ** 3 - 2 * b / c ** 2 + 1 / c)


def _f(alpha):
    """E[u^α (1 + ln u)²] for u uniform on (0, 1)."""
    s = alpha + 1.0
    return 1 / s - 2 / s ** 2 + 2 / s ** 3


def cos_power_gradient(k, n):
    """d/dn E_{Phong(n)}[cos^k]."""
    return k / (n + k + 1) ** 2


def pathwise_variance(k, n):
    a = k / (n + 1)
    return 2 * k * k / ((n + 1) ** 4 * (2 * a + 1) ** 3) - cos_power_gradient(k, n) ** 2


def score_variance(k, n, baseline=0.0):
    a = k / (n + 1)
    second = (_f(2 * a) - 2 * baseline * _f(a) + baseline ** 2) / (n + 1) ** 2
    return second - cos_power_gradient(k, n) ** 2


def cos_power(k):
    return lambda x: x[2] ** k


# ----------------------------------------------------------------------------------------------
# Deliberately wrong estimators
# ----------------------------------------------------------------------------------------------


class HalfDetached(Sampler):
    """The common bug: stop_gradient on only the sample ("sample") or only its density ("pdf")."""

    base: Sampler
    detach: str = static_field(default="sample")
    event_shape = (3,)

    @property
    def uniform_dims(self):
        return self.base.uniform_dims

    def warp(self, u):
        return self.base.warp(u)

    def pdf(self, x):
        return self.base.pdf(x)

    def warp_with_pdf(self, u):
        x, p = self.base.warp_with_pdf(u)
        if self.detach == "sample":
            x = jax.lax.stop_gradient(x)
            return x, self.base.pdf(x)
        return x, jax.lax.stop_gradient(p)
class UnnormalizedPhong(Sampler):
    """Phong samples with log p missing its normaliser log(n + 1): a wrong score function."""

    base: Sampler
    event_shape = (3,)
    uniform_dims = 2

    def warp(self, u):
        return self.base.warp(u)

    def log_pdf(self, x):
        return self.base.log_pdf(x) - jnp.log1p(self.base.exponent)


# ----------------------------------------------------------------------------------------------
# Fixed integral ∫ cos^k over the hemisphere, sampled from Phong(n): dI/dn = 0
# ----------------------------------------------------------------------------------------------

N_FIXED = 1 << 17
# (k, n) with n < (2k + 1)/2, where the attached gradient has finite moments of every order needed.
FIXED_CASES = [(3, 1.0), (10, 5.0), (1, 0.5)]


def _half_detached_sample(n):
    return HalfDetached(js.PhongLobe(n), "sample")


def _half_detached_pdf(n):
    return HalfDetached(js.PhongLobe(n), "pdf")


MAKERS = {"attached": js.PhongLobe, "sample": _half_detached_sample, "pdf": _half_detached_pdf}


@jax.jit
def _fixed_integral_gradients(k, n, key, u):
    """For each estimator: (gradient of estimate over N_FIXED samples, per-sample gradients at u).

    k is traced (cos^k with a float power), so one compilation serves every (k, n).
    """

    def f(x):
        return x[2] ** k

    out = {}
    for name, make in MAKERS.items():
        def through_estimate(n, make=make):
            return js.estimate(f, make(n), jax.random.clone(key), N_FIXED).mean

        def per_sample(n, u_row, make=make):
            return integrand_values(f, make(n), u_row[None])[0]

        out[name] = (jax.grad(through_estimate)(n), jax.vmap(jax.grad(per_sample), (None, 0))(n, u))
    return out


def test_detached_gradient_is_exactly_zero_for_every_sample_and_in_estimate():
    keys = jax.random.split(jax.random.key(100), 2)
    u = jax.random.uniform(keys[0], (4096, 2))
    n = jnp.float32(3.0)
    # estimate(mode="detached") itself, and its per-sample values.
    g = jax.jit(jax.grad(lambda n, key: js.estimate(cos_power(3), js.PhongLobe(n), key, N_FIXED,
                                                    mode="detached").mean))(n, keys[1])
    assert float(g) == 0.0
    per = jax.vmap(jax.grad(lambda n, u: integrand_values(cos_power(3), js.PhongLobe(n), u[None],
                                                          mode="detached")[0]), (None, 0))(n, u)
    assert np.all(np.asarray(per) == 0.0)


@pytest.mark.parametrize("k,n", FIXED_CASES)
def test_attached_gradient_of_a_fixed_integral_is_zero_mean_with_the_exact_variance(k, n):
    # FFR 1.1e-6 per case (two means within 5 exact standard errors; the variance check < 1e-100).
    keys = jax.random.split(jax.random.key(200 + k), 2)
    u = jax.random.uniform(keys[0], (N_FIXED, 2))
    var = attached_fixed_integral_variance(k, n)
    grad_estimate, per_sample = _fixed_integral_gradients(jnp.float32(k), jnp.float32(n), keys[1], u)["attached"]
    stderr = math.sqrt(var / N_FIXED)
    assert abs(float(grad_estimate)) < 5 * stderr, (float(grad_estimate), stderr)
    per_sample = np.asarray(per_sample, np.float64)
    assert abs(per_sample.mean()) < 5 * stderr, (per_sample.mean(), stderr)
    # The per-sample variance matches the formula: the sample variance of N values has a relative
    # sd of sqrt((κ - 1)/N), κ the kurtosis (1.8-2.3 measured for these cases on 2^21 samples):
    # 0.25-0.32 % at N_FIXED, so rtol 0.1 is more than 30 sd (normal FFR < 1e-100).
    np.testing.assert_allclose(per_sample.var(), var, rtol=0.1)


@pytest.mark.parametrize("detach", ["sample", "pdf"])
@pytest.mark.parametrize("k,n", FIXED_CASES)
def test_half_detached_estimator_is_caught(k, n, detach):
    # The same statistic as above rejects a half-detached estimator, whose mean is the known bias.
    # FFR 5.7e-7 per case: the bias check below (5 estimated sd); the rejections have wide margins.
    keys = jax.random.split(jax.random.key(300 + k), 2)
    u = jax.random.uniform(keys[0], (N_FIXED, 2))
    stderr = math.sqrt(attached_fixed_integral_variance(k, n) / N_FIXED)
    grad_estimate, per_sample = _fixed_integral_gradients(jnp.float32(k), jnp.float32(n), keys[1], u)[detach]
    if detach == "sample":
        bias = TWO_PI * (n - k) / ((n + 1) * (k + 1) ** 2)
    else:
        bias = TWO_PI * k / ((n + 1) * (k + 1) ** 2)
    assert abs(float(grad_estimate)) > 5 * stderr
    mean = float(np.mean(np.asarray(per_sample, np.float64)))
    assert abs(mean) > 5 * stderr
    # ... and its mean is the bias docs/reference.md states (within the sampling error of that mean).
    spread = float(np.std(np.asarray(per_sample, np.float64))) / math.sqrt(N_FIXED)
    assert abs(mean - bias) < 5 * spread, (mean, bias, spread)


@pytest.mark.parametrize("n", [0.0, 1.0, 20.0, 1000.0])
def test_integrand_matching_the_lobe_has_an_exact_zero_variance_attached_gradient(n):
    # f = cos^n, p = Phong(n): f/p = 2π/(n+1) for every sample, so d/dn = -2π/(n+1)² per sample.
    u = jax.random.uniform(jax.random.key(400), (2048, 2), minval=0.0, maxval=0.999)

    def per_sample(n, u_row):
        return integrand_values(lambda x: x[2] ** n, js.PhongLobe(n), u_row[None])[0]

    grads = jax.jit(jax.vmap(jax.grad(per_sample), (None, 0)))(jnp.float32(n), u)
    np.testing.assert_allclose(np.asarray(grads), -TWO_PI / (n + 1) ** 2, rtol=2e-4)


def test_estimate_mis_detached_is_exactly_zero_and_attached_unbiased():
    # ∫ cos³ with two Phong techniques sharing the exponent parameter; MIS weights move with it.
    def mis(n, key, mode):
        samplers = [js.PhongLobe(n), js.PhongLobe(2.0 * n + 1.0)]
        return js.estimate_mis(cos_power(3), samplers, key, [4096, 4096], mode=mode).mean

    keys = jax.random.split(jax.random.key(500), 65)
    n = jnp.float32(1.5)
    detached = jax.jit(jax.grad(lambda n, k: mis(n, k, "detached")))(n, keys[0])
    assert float(detached) == 0.0
    attached = np.asarray(jax.jit(jax.vmap(jax.grad(lambda n, k: mis(n, k, "attached")), (None, 0)))(n, keys[1:]),
                          np.float64)
    # Student t over 64 independent replicates: |t| > 6 has probability < 1e-6 with 63 d.o.f.
    t = attached.mean() / (attached.std(ddof=1) / math.sqrt(attached.size))
    assert abs(t) < 6.0 and attached.std() > 0, (attached.mean(), attached.std())


# ----------------------------------------------------------------------------------------------
# d/dn E_{Phong(n)}[cos^k] = k/(n+k+1)²: pathwise and score function
# ----------------------------------------------------------------------------------------------

N_EXPECT = 1 << 18
EXPECT_CASES = [(1, 1.0), (3, 1.0), (10, 10.0), (1, 100.0)]


@jax.jit
def _expectation_gradients(k, n, keys):
    """Gradients of E[cos^k] under each estimator; k traced, so one compilation serves all cases."""

    def g(x):
        return x[2] ** k

    def grad_of(gradient, baseline, sampler_of, key):
        return jax.grad(lambda n: expectation(g, sampler_of(n), key, N_EXPECT, gradient=gradient,
                                              baseline=baseline).mean)(n)

    phong = js.PhongLobe
    exact_mean = (n + 1) / (n + k + 1)
    return {
        "pathwise": grad_of("pathwise", None, phong, keys[0]),
        "score": grad_of("score", None, phong, keys[1]),
        "score_constant_baseline": grad_of("score", exact_mean, phong, keys[2]),
        "score_leave_one_out": grad_of("score", "leave_one_out", phong, keys[3]),
        # Deliberately wrong: a score function of an unnormalised density, and a pathwise
        # derivative with the sample detached (which is simply 0 for a θ-free g).
        "wrong_score": grad_of("score", None, lambda n: UnnormalizedPhong(js.PhongLobe(n)), keys[4]),
        "wrong_pathwise": jax.grad(lambda n: expectation(lambda x: g(jax.lax.stop_gradient(x)),
                                                         phong(n), keys[5], N_EXPECT).mean)(n),
    }


@pytest.mark.parametrize("k,n", EXPECT_CASES)
def test_pathwise_and_score_gradients_of_an_expectation_are_unbiased(k, n):
    keys = jax.random.split(jax.random.key(600 + int(k * 7 + n)), 6)
    grads = {name: float(v) for name, v in
             _expectation_gradients(jnp.float32(k), jnp.float32(n), keys).items()}
    exact = cos_power_gradient(k, n)
    mean = (n + 1) / (n + k + 1)
    stderr = {
        "pathwise": math.sqrt(pathwise_variance(k, n) / N_EXPECT),
        "score": math.sqrt(score_variance(k, n) / N_EXPECT),
        "score_constant_baseline": math.sqrt(score_variance(k, n, mean) / N_EXPECT),
        # leave-one-out: the constant-baseline variance at b = E[g], up to O(1/N).
        "score_leave_one_out": math.sqrt(score_variance(k, n, mean) / N_EXPECT),
    }
    for name, se in stderr.items():  # FFR 2.5e-4 per case: 4 checks at 4 exact sd (6.3e-5 each)
        assert abs(grads[name] - exact) < 4 * se, (name, grads[name], exact, se)
    # The wrong estimators are caught by the same threshold.
    assert abs(grads["wrong_score"] - exact) > 4 * stderr["score"]
    assert abs(grads["wrong_pathwise"] - exact) > 4 * stderr["pathwise"]
    # Theory: the score function's variance exceeds the pathwise one.
    assert score_variance(k, n) > pathwise_variance(k, n)


def test_measured_per_sample_variances_match_theory_and_score_exceeds_pathwise():
    k, n = 3, 1.0
    u = jax.random.uniform(jax.random.key(700), (1 << 16, 2))

    def per_sample(gradient, baseline=None):
        def one(n, row):
            return expectation_values(cos_power(k), js.PhongLobe(n), row[None], gradient=gradient,
                                      baseline=baseline)[0]
        return np.asarray(jax.jit(jax.vmap(jax.grad(one), (None, 0)))(jnp.float32(n), u), np.float64)

    pathwise, score = per_sample("pathwise"), per_sample("score")
    # Relative sd of a sample variance, sqrt((κ - 1)/N): κ = 2.05 (pathwise), 2.47 (score) on 2^21
    # samples, 0.40 % and 0.47 % at N = 2^16: rtol 0.1 is > 20 sd (normal FFR < 1e-80).
    np.testing.assert_allclose(pathwise.var(), pathwise_variance(k, n), rtol=0.1)
    np.testing.assert_allclose(score.var(), score_variance(k, n), rtol=0.1)
    assert score.var() > 3 * pathwise.var()  # exactly 7.76x; each within 0.5 % (1 sd) of its own


def test_expectation_value_is_the_plain_mean_and_leave_one_out_keeps_it():
    key = jax.random.key(800)
    phong = js.PhongLobe(4.0)

    @jax.jit
    def values(keys):
        return (expectation(cos_power(2), phong, keys[0], 4096).mean,
                expectation(cos_power(2), phong, keys[1], 4096, gradient="score").mean,
                expectation(cos_power(2), phong, keys[2], 4096, gradient="score",
                            baseline="leave_one_out").mean)

    plain, score, loo = values([jax.random.clone(key) for _ in range(3)])
    np.testing.assert_allclose([float(score), float(loo)], float(plain), rtol=1e-6)
    with pytest.raises(ValueError, match="gradient"):
        expectation(cos_power(2), phong, jax.random.key(801), 8, gradient="reinforce")
    with pytest.raises(ValueError, match="baseline"):
        expectation(cos_power(2), phong, jax.random.key(802), 8, baseline=0.5)


def test_score_function_handles_a_mixture_weight_where_pathwise_cannot():
    # d/dw E_{w p1 + (1-w) p2}[g] = E_1[g] - E_2[g]; the component choice is a jump in w, so only
    # the score function is unbiased here.
    k = 2
    e1, e2 = 21.0 / 23.0, 0.5  # E[cos²] under Phong(20) and under the cosine lobe

    def value(w, key):
        mix = js.Mixture((js.PhongLobe(20.0), js.CosineHemisphere()), jnp.stack([w, 1.0 - w]))
        return expectation(cos_power(k), mix, key, N_EXPECT, gradient="score",
                           baseline="leave_one_out").mean

    g = float(jax.jit(jax.grad(value))(jnp.float32(0.3), jax.random.key(900)))
    # Its standard error: the leave-one-out gradient has, up to O(1/N), the variance of the score
    # with the constant baseline b = E[g], whose per-sample spread is measured on 2^14 samples
    # (sd ≈ 0.31, so 5 stderrs are 0.7 % of the exact 0.413, where a worst-case bound allowed
    # 11 %). Normal FFR 5.7e-7.
    exact_mean = 0.3 * e1 + 0.7 * e2

    def per_sample(w, row):
        mix = js.Mixture((js.PhongLobe(20.0), js.CosineHemisphere()), jnp.stack([w, 1.0 - w]))
        return expectation_values(cos_power(k), mix, row[None], gradient="score", baseline=exact_mean)[0]

    rows = js.uniforms.uniform_block("random", jax.random.key(901), 0, 1 << 14, 2)
    spread = np.asarray(jax.jit(jax.vmap(jax.grad(per_sample), (None, 0)))(jnp.float32(0.3), rows), np.float64)
    stderr = spread.std(ddof=1) / math.sqrt(N_EXPECT)
    assert abs(g - (e1 - e2)) < 5 * stderr, (g, e1 - e2, stderr)
    # The pathwise derivative misses the component jumps: far outside the same bound.
    pathwise = jax.jit(jax.grad(lambda w, key: expectation(
        cos_power(k), js.Mixture((js.PhongLobe(20.0), js.CosineHemisphere()), jnp.stack([w, 1.0 - w])), key,
        1 << 14).mean))(jnp.float32(0.3), jax.random.key(902))
    assert abs(float(pathwise) - (e1 - e2)) > 5 * stderr * math.sqrt(N_EXPECT / (1 << 14)), float(pathwise)


# ----------------------------------------------------------------------------------------------
# Finite differences with common random numbers, every sampler parameter (float64)
# ----------------------------------------------------------------------------------------------


def _smooth_direction(x):
    return jnp.exp(x @ jnp.array([0.3, -0.5, 0.8], x.dtype)) + x[2] ** 2


def _smooth_scalar(t):
    return jnp.exp(-0.7 * t) * (1.0 + t)


def _smooth_planar(x):
    return jnp.exp(jnp.sum(x * jnp.linspace(0.2, 0.6, x.shape[-1], dtype=x.dtype)))


FD_CASES = [
    ("phong exponent", lambda p: js.PhongLobe(p[0]), [12.0], _smooth_direction),
    ("cone angle", lambda p: js.UniformCone.from_angle(p[0]), [0.4], _smooth_direction),
    ("cone cos", lambda p: js.UniformCone(p[0]), [0.3], _smooth_direction),
    ("vmf kappa", lambda p: js.VonMisesFisher(p[0]), [3.0], _smooth_direction),
    ("exponential rate", lambda p: js.Exponential(p[0]), [1.7], _smooth_scalar),
    ("truncated rate, t_max", lambda p: js.TruncatedExponential(p[0], p[1]), [0.8, 2.5], _smooth_scalar),
    ("power exponent", lambda p: js.Power(p[0]), [2.5], _smooth_scalar),
    ("triangle vertices", lambda p: js.UniformTriangle(p[0:3], p[3:6], p[6:9]),
     [0.0, 0.0, 0.1, 1.0, 0.2, 0.0, 0.3, 1.1, 0.4], _smooth_planar),
    ("mixture weights", lambda p: js.Mixture((js.PhongLobe(5.0), js.VonMisesFisher(2.0)), p[0:2]),
     [0.6, 0.4], _smooth_direction),
    ("oriented normal", lambda p: js.Oriented(js.PhongLobe(p[3]), p[0:3]),
     [0.3, -0.2, 0.9, 8.0], _smooth_direction),
]


@pytest.mark.parametrize("name,make,params,f", FD_CASES, ids=[c[0] for c in FD_CASES])
def test_gradient_matches_central_differences_with_common_random_numbers(name, make, params, f):
    with jax.enable_x64(True):
        theta = jnp.asarray(params, jnp.float64)
        key = jax.random.key(1000)
        # One direction per case, so that a vector parameter costs two estimates, not 2 per entry.
        direction = jnp.asarray(np.random.default_rng(len(name)).normal(size=theta.shape))
        if name == "mixture weights":
            direction = jnp.asarray([1.0, -1.0])  # keep the weight sum, stay off the CDF jumps

        # One compiled program gives the gradient and the two shifted values (its gradient output
        # unused there): one compilation per case instead of two.
        @jax.jit
        def value_and_grad(theta, key):
            return jax.value_and_grad(lambda t: js.estimate(f, make(t), key, 4096).mean)(theta)

        _, grad = value_and_grad(theta, jax.random.clone(key))
        # float64: truncation ~h² and rounding ~1e-16/h both far below rtol.
        h = 1e-7
        plus, _ = value_and_grad(theta + h * direction, jax.random.clone(key))
        minus, _ = value_and_grad(theta - h * direction, jax.random.clone(key))
        finite_difference = float(plus - minus) / (2 * h)
        np.testing.assert_allclose(float(grad @ direction), finite_difference, rtol=1e-5, atol=1e-7)
        assert np.all(np.isfinite(np.asarray(grad)))


def test_expectation_pathwise_and_score_match_central_differences():
    """Pathwise: the derivative of the same estimate with common random numbers (rtol 1e-6), and
    the exact derivative 3/(n+4)² within 5 exact standard errors. Score: its surrogate's value
    does not move the samples (finite differences of it are 0), so it is compared with the exact
    derivative only, within 5 exact standard errors (docs/reference.md's per-sample variance). Normal
    FFR 5.7e-7 per comparison, 1.1e-6 for the two."""
    with jax.enable_x64(True):
        key = jax.random.key(1100)
        k, count = 3, 4096

        @functools.partial(jax.jit, static_argnames="gradient")
        def value(n, key, gradient="pathwise"):
            return expectation(cos_power(k), js.PhongLobe(n), key, count, gradient=gradient).mean

        n, h = jnp.float64(2.0), 1e-6
        grad = jax.grad(value)(n, jax.random.clone(key))
        fd = (value(n + h, jax.random.clone(key)) - value(n - h, jax.random.clone(key))) / (2 * h)
        np.testing.assert_allclose(float(grad), float(fd), rtol=1e-6)
        exact = cos_power_gradient(k, 2.0)
        assert abs(float(grad) - exact) < 5 * math.sqrt(pathwise_variance(k, 2.0) / count), (float(grad), exact)
        score = jax.grad(value)(n, jax.random.clone(key), "score")
        assert abs(float(score) - exact) < 5 * math.sqrt(score_variance(k, 2.0) / count), (float(score), exact)
        # A score function with the wrong normaliser is outside the same bound.
        wrong = jax.jit(jax.grad(lambda n, key: expectation(cos_power(k), UnnormalizedPhong(js.PhongLobe(n)), key,
                                                            count, gradient="score").mean))(n, key)
        assert abs(float(wrong) - exact) > 5 * math.sqrt(score_variance(k, 2.0) / count), float(wrong)


# ----------------------------------------------------------------------------------------------
# Exact derivatives of expectations, every sampler parameter with a closed form
# ----------------------------------------------------------------------------------------------
#
# The finite differences above differentiate the same estimator twice, so a wrong parameter
# mapping (a cone built from the wrong cap size, say) passes them. Here d/dθ E_θ[g] from the
# pathwise per-sample gradients is held to the derivative of the closed form of E_θ[g]
# (differentiated in float64), within 5 standard errors of the mean of M per-sample gradients,
# the standard error taken from their own spread (normal FFR 5.7e-7 per component checked; 23
# components, 1.3e-5 in all).

M_EXACT = 1 << 14
AXIS = np.array([0.3, -0.5, 0.8])

# name: (sampler from a parameter vector, parameters, g of one sample, E[g] as a jnp function)
EXACT_CASES = {
    "phong exponent": (lambda p: js.PhongLobe(p[0]), [12.0], lambda x: x[2] ** 3,
                       lambda p: (p[0] + 1) / (p[0] + 4)),
    "cone angle": (lambda p: js.UniformCone.from_angle(p[0]), [0.4], lambda x: x[2],
                   lambda p: (1 + jnp.cos(p[0])) / 2),
    "cone solid angle": (lambda p: js.UniformCone.from_solid_angle(p[0]), [1.3], lambda x: x[2],
                         lambda p: 1 - p[0] / (4 * jnp.pi)),
    "cone sin2": (lambda p: js.UniformCone.from_sin2(p[0]), [0.3], lambda x: x[2],
                  lambda p: (1 + jnp.sqrt(1 - p[0])) / 2),
    "cone cos": (lambda p: js.UniformCone(p[0]), [0.3], lambda x: x[2], lambda p: (1 + p[0]) / 2),
    "vmf kappa": (lambda p: js.VonMisesFisher(p[0]), [3.0], lambda x: x[2],
                  lambda p: 1 / jnp.tanh(p[0]) - 1 / p[0]),
    "exponential rate": (lambda p: js.Exponential(p[0]), [1.7], lambda t: jnp.sum(t), lambda p: 1 / p[0]),
    "truncated rate, t_max": (lambda p: js.TruncatedExponential(p[0], p[1]), [0.8, 2.5], lambda t: jnp.sum(t),
                              lambda p: 1 / p[0] - p[1] / jnp.expm1(p[0] * p[1])),
    "power exponent": (lambda p: js.Power(p[0]), [2.5], lambda x: jnp.sum(x), lambda p: (p[0] + 1) / (p[0] + 2)),
    # E[x] is the centroid; E[x·a] moves by a/3 with each vertex.
    "triangle vertices": (lambda p: js.UniformTriangle(p[0:3], p[3:6], p[6:9]),
                          [0.0, 0.0, 0.1, 1.0, 0.2, 0.0, 0.3, 1.1, 0.4], lambda x: x @ jnp.asarray(AXIS, x.dtype),
                          lambda p: (p[0:3] + p[3:6] + p[6:9]) @ AXIS / 3),
    # A lobe symmetric about its axis n̂: E[x] = n̂ E[cos θ] = n̂ (m + 1)/(m + 2).
    "oriented normal": (lambda p: js.Oriented(js.PhongLobe(p[3]), p[0:3]), [0.3, -0.2, 0.9, 8.0],
                        lambda x: x @ jnp.asarray(AXIS, x.dtype),
                        lambda p: (p[0:3] / jnp.linalg.norm(p[0:3])) @ AXIS * (p[3] + 1) / (p[3] + 2)),
}


@pytest.mark.parametrize("name", list(EXACT_CASES))
def test_pathwise_gradient_matches_the_exact_derivative(name):
    make, params, g, closed_form = EXACT_CASES[name]
    theta = jnp.asarray(params, jnp.float32)
    u = js.uniforms.uniform_block("random", jax.random.key(1300 + list(EXACT_CASES).index(name)), 0, M_EXACT,
                                  make(theta).uniform_dims)

    @jax.jit
    def per_sample_gradients(theta, u):
        return jax.vmap(jax.grad(lambda t, row: expectation_values(g, make(t), row[None])[0]), (None, 0))(theta, u)

    grads = np.asarray(per_sample_gradients(theta, u), np.float64)
    with jax.enable_x64(True):
        exact = np.asarray(jax.grad(closed_form)(jnp.asarray(params, jnp.float64)))
    mean = grads.mean(axis=0)
    stderr = grads.std(axis=0, ddof=1) / math.sqrt(M_EXACT)
    assert np.all(np.isfinite(grads))
    assert np.all(np.abs(mean - exact) < 5 * stderr + 1e-6 * np.abs(exact)), (name, mean, exact, stderr)


# ----------------------------------------------------------------------------------------------
# jit and vmap of grad
# ----------------------------------------------------------------------------------------------


def test_vmap_of_grad_over_a_batch_of_parameters_under_jit():
    exponents = jnp.asarray([0.5, 2.0, 7.0, 30.0], jnp.float32)
    keys = jax.random.split(jax.random.key(1200), exponents.shape[0])

    def grad_one(n, key, gradient):
        return jax.grad(lambda n: expectation(cos_power(3), js.PhongLobe(n), key, 1 << 14,
                                              gradient=gradient).mean)(n)

    variances = {"pathwise": pathwise_variance, "score": score_variance}
    for gradient in ("pathwise", "score"):
        batched = jax.jit(jax.vmap(lambda n, key: grad_one(n, key, gradient)))(
            exponents, jax.vmap(jax.random.clone)(keys))
        single = jax.jit(lambda n, key: grad_one(n, key, gradient))
        looped = [single(n, jax.random.clone(k)) for n, k in zip(exponents, keys)]
        np.testing.assert_allclose(np.asarray(batched), np.asarray(looped), rtol=1e-5)
        # and each is its exact value (0.148 down to 0.0026) within 5 exact standard errors of
        # its own case (normal FFR 5.7e-7 per value, 8 values): a gradient of 0 fails every one.
        exact = np.asarray([cos_power_gradient(3, float(n)) for n in exponents])
        stderr = np.asarray([math.sqrt(variances[gradient](3, float(n)) / (1 << 14)) for n in exponents])
        assert np.all(np.abs(np.asarray(batched) - exact) < 5 * stderr), (gradient, batched, exact, stderr)
        assert np.all(5 * stderr < exact), (gradient, stderr, exact)


# ----------------------------------------------------------------------------------------------
# The measure-valued gradient is a sampler protocol method, not a special case of one class
# ----------------------------------------------------------------------------------------------


class _Power(Sampler):
    """p_n(x) = m x^n on [0, 1] (m = n + 1), warp x = u^(1/m); its measure-valued decomposition in n
    is Phong's (d/dn m x^n = (1/m)(p_n - q_n), q_n the density of the product of two draws)."""

    exponent: jax.Array = js.parameter(0.0)
    uniform_dims = 1

    def warp(self, u):
        return u ** (1.0 / (self.exponent + 1.0))

    def pdf(self, x):
        return jnp.where((x[..., 0] >= 0) & (x[..., 0] <= 1), (self.exponent + 1.0) * x[..., 0] ** self.exponent, 0.0)

    def domain(self):
        from jaxsample.domains import Interval
        return Interval(0.0, 1.0)

    def measure_valued_terms(self, u):
        m = self.exponent + 1.0
        return self.exponent, u[..., :1] ** (1.0 / m), (u[..., :1] * u[..., 1:2]) ** (1.0 / m), 1.0 / m


def test_a_user_sampler_with_a_measure_valued_decomposition_gets_that_gradient():
    """gradient="measure_valued" asks the sampler (`Sampler.measure_valued_terms`): a user's class
    that defines it gets the estimator (its per-block gradient is exactly mean(c (g(x) - g(x')))
    from the same uniforms, and E[x] = m/(m+1) has the exact derivative 1/(m+1)² within 5 standard
    errors of per-sample gradients: false failure 5.7e-7); a class that does not define it is
    refused by the default, naming the method. Catches the former special case, which refused
    every sampler but PhongLobe."""
    from keyring import next_key

    n = 2.0
    u = jax.random.uniform(next_key(), (4096, 2))
    grad = jax.grad(lambda e: jnp.mean(expectation_values(lambda x: x[0], _Power(e), u, gradient="measure_valued")))(n)
    m = n + 1.0
    direct = jnp.mean((u[:, 0] ** (1 / m) - (u[:, 0] * u[:, 1]) ** (1 / m)) / m)
    np.testing.assert_allclose(float(grad), float(direct), rtol=1e-6)
    per_sample = jax.vmap(jax.grad(lambda e, row: expectation_values(lambda x: x[0], _Power(e), row[None],
                                                                      gradient="measure_valued")[0]),
                          in_axes=(None, 0))(n, u)
    stderr = float(jnp.std(per_sample)) / np.sqrt(len(u))
    assert abs(float(jnp.mean(per_sample)) - 1.0 / (m + 1.0) ** 2) < 5.0 * stderr, (float(jnp.mean(per_sample)), stderr)
    with pytest.raises(ValueError, match="measure_valued_terms"):
        expectation(lambda w: w[2], js.UniformSphere(), next_key(), 64, gradient="measure_valued")
