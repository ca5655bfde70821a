"""estimate: unbiasedness, chunking invariance, accumulation, jit/vmap/grad, coverage, sharding.

Statistical checks state their false-failure rate (FFR) and are shown to fail on a wrong input.
Exact values from docs/reference.md: ∫_{H²} cos³ dω = π/2; Var[f/p] = π²/12 for cosine sampling,
9π²/28 for uniform hemisphere sampling.
"""

import os
import subprocess
import sys
import textwrap
from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxsample as js
from jaxsample.samplers.base import Sampler
from jaxsample.estimators.diagnostics import empty_tail
from jaxsample.estimators.engine import empty_moments, merge_moments, _Moments
from jaxsample.estimators.plain import estimate
from jaxsample.estimators.result import Estimate

from keyring import next_key

jax.config.update("jax_debug_key_reuse", True)

HALF_PI = np.pi / 2
VAR_COSINE = np.pi ** 2 / 12
VAR_UNIFORM = 9 * np.pi ** 2 / 28
K_SIGMA = 5.0  # |N(0,1)| > 5: FFR 5.7e-7 per check, with the exact sigma


def cos3(w):
    return w[2] ** 3
class MisreportedCosine(Sampler):
    """A deliberately wrong sampler: cosine-distributed directions, density reported 1% high."""

    scale: float = 1.01
    uniform_dims: ClassVar[int] = 2
    event_shape: ClassVar = (3,)

    def warp(self, u):
        return js.CosineHemisphere().warp(u)

    def pdf(self, x):
        return self.scale * js.CosineHemisphere().pdf(x)


N = 1 << 20
estimate_n = jax.jit(lambda key, sampler: estimate(cos3, sampler, key, N))


def unbiased(mean, sigma):
    return abs(float(mean) - HALF_PI) <= K_SIGMA * sigma


def test_unbiased_cosine_and_uniform_and_fails_when_biased():
    # FFR 1.1e-6: two means within 5 exact sigmas (5.7e-7 each); the rtol checks below < 1e-27.
    e = estimate_n(next_key(), js.CosineHemisphere())
    assert unbiased(e.mean, np.sqrt(VAR_COSINE / N))
    # Y = π cos² θ is uniform on [0, π] here (kurtosis 1.8): the sample variance of N values has a
    # relative sd of sqrt(0.8/N) = 8.7e-4, so rtol 0.01 is 11 sd on the variance and 23 on the
    # stderr (normal FFR < 1e-27).
    np.testing.assert_allclose(e.stderr, np.sqrt(VAR_COSINE / N), rtol=0.01)  # stderr itself
    np.testing.assert_allclose(e.variance, VAR_COSINE, rtol=0.01)
    u = jax.jit(lambda key: estimate(cos3, js.UniformHemisphere(), key, N))(next_key())
    assert unbiased(u.mean, np.sqrt(VAR_UNIFORM / N))
    wrong = estimate_n(next_key(), MisreportedCosine())
    assert not unbiased(wrong.mean, np.sqrt(VAR_COSINE / N))


@pytest.mark.parametrize("uniforms", ["stratified", "sobol"])
def test_unbiased_replicated_sources(uniforms):
    """stderr from 16 replicates: the t statistic (15 dof) exceeds 7 with probability 4e-6.

    The stderr is far below plain MC's: over 64 keys its true value (the mean reported stderr
    over c4(16)) is 0.0219 (stratified) and 0.0039 (Sobol') of plain MC's; a reported stderr is
    that times sqrt(χ²₁₅/15), which exceeds the bound 0.05 with probability 1.3e-10 (stratified)
    and < 1e-100 (Sobol'). Its calibration is in tests/estimators/test_calibration.py."""
    e = jax.jit(lambda key: estimate(cos3, js.CosineHemisphere(), key, 1 << 18, uniforms=uniforms))(next_key())
    assert e.replicates == 16
    assert abs(float(e.mean) - HALF_PI) <= 7 * float(e.stderr) + 2e-6
    assert float(e.stderr) < 0.05 * np.sqrt(VAR_COSINE / (1 << 18))  # far below plain MC
    bad = jax.jit(lambda key: estimate(cos3, MisreportedCosine(), key, 1 << 18, uniforms=uniforms))(next_key())
    assert abs(float(bad.mean) - HALF_PI) > 7 * float(bad.stderr) + 2e-6


def test_chunking_and_tails_do_not_change_the_samples():
    key = next_key()
    n = 50_000  # not a multiple of any chunk size: exercises the tail
    # The same samples on purpose: jax.random.clone is the sanctioned way to use a key again.
    results = [jax.jit(lambda k, c=c: estimate(cos3, js.CosineHemisphere(), k, n, chunk_size=c))(
        jax.random.clone(key)) for c in (4096, 12_288, 1 << 16)]
    for r in results[1:]:
        np.testing.assert_allclose(r.mean, results[0].mean, rtol=2e-7)
        np.testing.assert_allclose(r.stderr, results[0].stderr, rtol=1e-5)
        assert float(r.max_abs) == float(results[0].max_abs)  # same samples: same largest value
    # The same samples, drawn as one block and averaged directly.
    u = js.uniforms.uniform_block("random", key, 0, n, 2)
    x, p = js.CosineHemisphere().warp_with_pdf(u)
    direct = np.mean(np.asarray(x[:, 2] ** 3 / p, np.float64))
    np.testing.assert_allclose(results[0].mean, direct, rtol=1e-6)


def test_accumulator_exact_for_constant_over_2_to_30_samples():
    """The cross-chunk merge over 2^14 chunks of 2^16 constant samples (2^30 in all), synthetic.

    A naive float32 running sum of the same chunk sums is off by more than 1e-6 relative, ours
    is exact; the whole estimator on 2^20 samples of a constant is exact too, and its stderr is the
    floor at float rounding (not 0).
    """
    value = np.float32(4 * np.pi * 0.3)
    chunk = 1 << 16
    chunk_sum = jnp.float32(value) * chunk  # exact: a power-of-two multiple

    def body(state, _):
        naive, moments = state
        new = _Moments(chunk_sum[None], jnp.zeros(1), jnp.float32(0), jnp.float32(value),
                       chunk_sum, empty_tail((), jnp.float32, 2), jnp.float32(chunk), jnp.float32(chunk))
        return (naive + chunk_sum, merge_moments(moments, new)), None

    (naive, moments), _ = jax.jit(lambda: jax.lax.scan(
        body, (jnp.float32(0), empty_moments(1, (), jnp.float32, 2)), None, length=1 << 14))()
    ours = (moments.sums[0] + moments.compensation[0]) / np.float32(2.0 ** 30)
    assert abs(float(ours) / value - 1) < 1e-6
    assert float(moments.m2) <= 1e-12 * 2.0 ** 30 * value ** 2  # M2 stays at rounding level
    assert abs(float(naive) / (value * 2.0 ** 30) - 1) > 1e-6
    constant = jax.jit(lambda k: estimate(lambda w: jnp.float32(0.3), js.UniformSphere(), k, 1 << 20))(next_key())
    assert float(constant.mean) == pytest.approx(float(value), rel=1e-7)
    assert float(constant.ess) == pytest.approx(2.0 ** 20, rel=1e-6)
    # Zero variance: the stderr is the floor at the values' rounding, two ulps of mean |Y|.
    assert float(constant.stderr) == pytest.approx(2 * np.finfo(np.float32).eps * float(value), rel=1e-5)


def test_vmap_over_keys_and_phong_exponents():
    """E over Phong(n) sampling of cos³: variance 4π²(n-3)²/(16(16-(n-3)²)) (docs/reference.md).
    Three of the four means are random (n = 3 has zero variance), each within 5 exact sigmas: FFR 1.7e-6."""
    exponents = jnp.array([0.0, 1.0, 3.0, 5.0])
    keys = jax.random.split(next_key(), 4)
    n = 1 << 16
    est = jax.jit(jax.vmap(lambda e, k: estimate(cos3, js.PhongLobe(exponent=e), k, n)))(exponents, keys)
    assert est.mean.shape == (4,)
    for i, e in enumerate(np.asarray(exponents)):
        var = 4 * np.pi ** 2 * (e - 3) ** 2 / (16 * (16 - (e - 3) ** 2))
        assert abs(float(est.mean[i]) - HALF_PI) <= K_SIGMA * np.sqrt(var / n) + 1e-6
    assert float(est.stderr[2]) < 1e-6  # n = k: zero variance


def test_grad_attached_exact_and_detached_zero():
    """cos^n sampled from Phong(n): the attached derivative is -2π/(n+1)² for every sample;
    a fixed integrand (cos³) has a detached derivative of exactly 0 (docs/reference.md)."""
    key_a, key_b = jax.random.split(next_key())

    def own_lobe(n, key):
        return estimate(lambda w: js.PhongLobe(exponent=n).pdf(w) * 2 * jnp.pi / (n + 1), js.PhongLobe(exponent=n),
                        key, 1 << 12).mean

    def power(n, key):
        return estimate(lambda w: jnp.maximum(w[2], 0.0) ** n, js.PhongLobe(exponent=n), key, 1 << 12).mean

    key_a, key_own = jax.random.split(key_a)
    g = jax.jit(jax.grad(power))(4.0, key_a)
    np.testing.assert_allclose(g, -2 * np.pi / 25, rtol=1e-3)
    # The same through the lobe's own density: f = p_n 2π/(n+1), so f/p = 2π/(n+1) per sample.
    g_own = jax.jit(jax.grad(own_lobe))(4.0, key_own)
    np.testing.assert_allclose(g_own, -2 * np.pi / 25, rtol=1e-3)
    gd = jax.jit(jax.grad(lambda n, k: estimate(cos3, js.PhongLobe(exponent=n), k, 1 << 12,
                                                mode="detached").mean))(4.0, key_b)
    assert float(gd) == 0.0


def test_grad_finite_where_pdf_is_zero():
    class HalfZero(Sampler):
        width: jax.Array
        uniform_dims: ClassVar[int] = 2
        event_shape: ClassVar = (3,)

        def warp(self, u):
            return js.UniformSphere().warp(u) * self.width

        def pdf(self, x):
            return jnp.where(x[..., 2] > 0, 1 / (2 * jnp.pi), 0.0) * self.width

    grad = jax.jit(jax.grad(lambda w, k: estimate(lambda x: 1.0 / x[2], HalfZero(w), k, 4096).mean))(1.0, next_key())
    assert np.isfinite(float(grad))


def test_coverage_of_95_percent_intervals():
    """4000 independent estimates (n = 1024): coverage ~ Binomial(4000, 0.95)/4000, sd 0.0034, so
    [0.93, 0.97] fails with probability ~1e-8; halving the stderr (68% coverage) or a 1% biased
    sampler (mean off by 3.4 sigma at this n... coverage ~ 8%) fails it."""
    keys = jax.random.split(next_key(), 4000)
    run = jax.jit(jax.vmap(lambda k, s: estimate(cos3, s, k, 1024), in_axes=(0, None)))
    est = run(keys, js.CosineHemisphere())
    lo, hi = est.interval(0.95)
    covered = float(jnp.mean((lo <= HALF_PI) & (HALF_PI <= hi)))
    assert 0.93 <= covered <= 0.97
    half = float(jnp.mean(jnp.abs(est.mean - HALF_PI) <= 1.96 * est.stderr / 2))
    assert not 0.93 <= half <= 0.97
    cheb_lo, cheb_hi = est.chebyshev_interval(0.95)
    assert float(jnp.mean((cheb_lo <= HALF_PI) & (HALF_PI <= cheb_hi))) >= 0.97  # conservative
    bad = run(jax.random.split(next_key(), 4000), MisreportedCosine(scale=1.1))
    blo, bhi = bad.interval(0.95)
    assert float(jnp.mean((blo <= HALF_PI) & (HALF_PI <= bhi))) < 0.93


def test_estimate_is_a_pytree_and_vector_valued_f_works():
    e = jax.jit(lambda k: estimate(lambda w: w, js.CosineHemisphere(), k, 1 << 14))(next_key())
    assert isinstance(e, Estimate) and e.mean.shape == (3,) and e.n == 1 << 14
    leaves, tree = jax.tree_util.tree_flatten(e)
    assert len(leaves) == 7 and jax.tree_util.tree_unflatten(tree, leaves).n == e.n
    # ∫ ω dω over H² = (0, 0, π), each component within 6 estimated stderrs: FFR 6e-9 (3 x 2e-9).
    assert np.all(np.abs(np.asarray(e.mean) - [0, 0, np.pi]) <= 6 * np.asarray(e.stderr) + 1e-6)


@pytest.mark.parametrize("uniforms", ["random", "sobol"])
def test_non_finite_values_give_inf_or_nan_means_and_unbounded_error_bars(uniforms):
    # Y = f/p per component: +inf on the cap z > 0.9, else 1 | +inf there and -inf below z < 0.1 |
    # NaN on the cap | 1 everywhere. A compensated sum can turn an inf into NaN (inf - inf): this
    # checks that the sums keep an inf an inf.
    def f(w):
        cap, rim = w[2] > 0.9, w[2] < 0.1
        y = jnp.stack([jnp.where(cap, jnp.inf, 1.0), jnp.where(cap, jnp.inf, jnp.where(rim, -jnp.inf, 1.0)),
                       jnp.where(cap, jnp.nan, 1.0), jnp.ones_like(w[2])])
        return y * w[2] / np.pi

    e = jax.jit(lambda k: estimate(f, js.CosineHemisphere(), k, 1 << 12, uniforms=uniforms,
                                   chunk_size=1 << 10))(jax.random.key(11))
    mean, stderr = np.asarray(e.mean), np.asarray(e.stderr)
    assert mean[0] == np.inf and np.isnan(mean[1]) and np.isnan(mean[2])
    np.testing.assert_allclose(mean[3], 1.0, rtol=1e-6)
    assert np.all(stderr[:3] == np.inf) and np.all(np.asarray(e.variance)[:3] == np.inf)
    assert np.all(np.asarray(e.ess)[:3] == 0) and np.asarray(e.max_abs)[0] == np.inf
    assert np.isfinite(stderr[3]) and np.asarray(e.ess)[3] > 0


def test_float64():
    with jax.enable_x64(True):
        e = jax.jit(lambda k: estimate(cos3, js.CosineHemisphere(), k, 1 << 14, dtype=jnp.float64))(next_key())
        assert e.mean.dtype == jnp.float64
        assert unbiased(e.mean, np.sqrt(VAR_COSINE / (1 << 14)))  # FFR 5.7e-7 (|z| < 5, exact sigma)


def test_invalid_arguments():
    with pytest.raises(ValueError, match="mode"):
        estimate(cos3, js.CosineHemisphere(), next_key(), 64, mode="half")
    with pytest.raises(ValueError, match="'n'"):
        estimate(cos3, js.CosineHemisphere(), next_key(), 100, uniforms="sobol")  # not a multiple of 16
    with pytest.raises(ValueError, match="chunk_size"):
        estimate(cos3, js.CosineHemisphere(), next_key(), 64, chunk_size=6)


SHARDED_SCRIPT = textwrap.dedent("""
    import os
    os.environ["XLA_FLAGS"] = os.environ.get("XLA_FLAGS", "") + " --xla_force_host_platform_device_count=4"
    import jax, jax.numpy as jnp, numpy as np
    import jaxsample as js
    from jaxsample.estimators.plain import estimate
    assert jax.device_count() == 4
    mesh = jax.make_mesh((4,), ("samples",))
    f = lambda w: jnp.maximum(w[0] + 0.5 * w[1] + w[2], 0.0) ** 3
    for uniforms in ("random", "sobol"):
        key = jax.random.key(3)
        one = jax.jit(lambda k: estimate(f, js.PhongLobe(exponent=3.0), k, 1 << 18, uniforms=uniforms,
                                         chunk_size=1 << 14))(jax.random.clone(key))
        sharded = jax.jit(lambda k: estimate(f, js.PhongLobe(exponent=3.0), k, 1 << 18, uniforms=uniforms,
                                             chunk_size=1 << 14, mesh=mesh))(key)
        np.testing.assert_allclose(sharded.mean, one.mean, rtol=1e-6)
        np.testing.assert_allclose(sharded.stderr, one.stderr, rtol=1e-4)
        assert float(sharded.max_abs) == float(one.max_abs)
    print("SHARDED-OK")
""")


def test_sharded_matches_single_device_in_subprocess():
    # The caller's compiler options (tests/conftest.py), without a device count it may have forced.
    env = dict(os.environ, XLA_FLAGS=" ".join(flag for flag in os.environ.get("XLA_FLAGS", "").split()
                                              if "device_count" not in flag))
    out = subprocess.run([sys.executable, "-c", SHARDED_SCRIPT], capture_output=True, text=True,
                         env=env, timeout=300)
    assert "SHARDED-OK" in out.stdout, out.stderr[-3000:]
