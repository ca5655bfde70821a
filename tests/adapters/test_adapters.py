"""The bridges to NumPyro, distrax and TFP on JAX (`jaxsample.adapters`), both ways.

Statistical checks here run on fixed keys, so each outcome is deterministic; the bounds are 4
standard errors (a false failure of about 6e-5 per check for a draw of a fresh key) unless stated.
"""

from __future__ import annotations

import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxsample as js
from jaxsample import adapters
from jaxsample.samplers.domain import Interval

# The libraries are in the test extra (jaxsample[adapters]); a missing one fails here, never skips.
import distrax  # noqa: E402
import numpyro  # noqa: E402
import numpyro.distributions as nd  # noqa: E402
from tensorflow_probability.substrates import jax as tfp  # noqa: E402

tfd = tfp.distributions


def key(i: int = 0):
    """A fresh key per use (the suite checks that no key is consumed twice)."""
    return jax.random.key(20261203 + i)


def _vmf(kappa=4.0, axis=(0.0, 0.6, 0.8)):
    return js.Oriented(js.VonMisesFisher(kappa), jnp.asarray(axis))


SAMPLERS = {
    "vmf": lambda: _vmf(),
    "phong": lambda: js.PhongLobe(30.0),
    "normal": lambda: js.Normal(1.0, 0.5),
    "exponential": lambda: js.Exponential(2.0),
    "disk": lambda: js.UniformDisk(),
    "discrete": lambda: js.Discrete(jnp.array([0.1, 0.6, 0.3])),
    "batched-vmf": lambda: js.VonMisesFisher(jnp.array([0.5, 5.0, 50.0])),
}
CONVERT = {"numpyro": adapters.to_numpyro, "distrax": adapters.to_distrax, "tfp": adapters.to_tfp}


def _sample(dist, library, key, sample_shape):
    if library == "numpyro":
        return dist.sample(key, sample_shape)
    if library == "distrax":
        return dist.sample(seed=key, sample_shape=sample_shape)
    return dist.sample(sample_shape, seed=key)


def test_importing_the_adapters_imports_none_of_the_libraries():
    code = ("import sys, jaxsample, jaxsample.adapters; "
            "print(sorted(m for m in ('numpyro', 'distrax', 'tensorflow_probability') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


@pytest.mark.parametrize("library", CONVERT)
@pytest.mark.parametrize("name", SAMPLERS)
def test_each_adapter_samples_and_scores_as_the_sampler(library, name):
    """Shapes are sample_shape + batch_shape + event_shape, the samples are the sampler's own for
    the same key, and log_prob is the sampler's log_pdf at them and at other points."""
    sampler = SAMPLERS[name]()
    dist = CONVERT[library](sampler)
    assert tuple(dist.batch_shape) == sampler.batch_shape and tuple(dist.event_shape) == sampler.event_shape
    key = jax.random.PRNGKey(7)
    x = _sample(dist, library, key, (5, 2))
    assert x.shape == (5, 2) + sampler.batch_shape + sampler.event_shape
    np.testing.assert_array_equal(x, sampler.sample(key, (5, 2)))
    other = sampler.sample(jax.random.PRNGKey(8), (4,))
    for points in (x, other):
        np.testing.assert_allclose(dist.log_prob(points), sampler.log_pdf(points), rtol=1e-6, atol=1e-6)
    assert np.all(np.isfinite(dist.log_prob(x)))


@pytest.mark.parametrize("library", CONVERT)
def test_adapters_pass_through_jit_and_are_reparameterized(library):
    """The converted distribution is a pytree (an argument of `jit`), and the gradient of a
    sample mean with respect to the sampler's parameter flows through it: d/dκ E[cos θ] of the
    von Mises–Fisher lobe, E[cos θ] = coth κ - 1/κ, so the derivative is 1/κ² - 1/sinh² κ."""
    dist = CONVERT[library](js.VonMisesFisher(3.0))
    point = jnp.array([0.0, 0.6, 0.8])
    np.testing.assert_allclose(jax.jit(lambda d, x: d.log_prob(x))(dist, point), dist.log_prob(point), rtol=1e-6)

    def mean_cos(kappa):
        d = CONVERT[library](js.VonMisesFisher(kappa))
        return _sample(d, library, jax.random.PRNGKey(3), (200_000,))[:, 2].mean()

    kappa = 3.0
    exact = 1.0 / kappa ** 2 - 1.0 / np.sinh(kappa) ** 2
    assert abs(float(jax.grad(mean_cos)(kappa)) - exact) < 0.1 * exact
    if library == "numpyro":
        assert dist.has_rsample and not CONVERT[library](js.Discrete(jnp.array([0.5, 0.5]))).has_rsample
    if library == "tfp":
        assert dist.reparameterization_type == tfd.FULLY_REPARAMETERIZED
        assert CONVERT[library](js.Discrete(jnp.array([0.5, 0.5]))).reparameterization_type == tfd.NOT_REPARAMETERIZED
        assert tfd.Sample(dist, 4).sample(seed=jax.random.PRNGKey(0)).shape == (4, 3)


def test_numpyro_support_is_read_from_the_domain():
    constraints = numpyro.distributions.constraints
    assert adapters.to_numpyro(_vmf()).support is constraints.sphere
    assert adapters.to_numpyro(js.Discrete(jnp.array([0.2, 0.8]))).support.upper_bound == 1
    exponential = adapters.to_numpyro(js.Exponential(2.0)).support
    assert bool(exponential(1.0)) and not bool(exponential(-1.0))
    assert adapters.to_numpyro(js.Normal(0.0, 1.0)).support is constraints.real


def test_sample_and_log_prob_is_sample_and_the_log_density():
    for sampler in (js.PhongLobe(200.0), js.Discrete(jnp.array([0.25, 0.75])), js.VonMisesFisher(jnp.array([1.0, 9.0])),
                    js.Mixture([js.CosineHemisphere(), js.PhongLobe(20.0)], jnp.array([0.5, 0.5]))):
        x, log_p = sampler.sample_and_log_prob(key(1), (64,))
        np.testing.assert_array_equal(x, sampler.sample(key(1), (64,)))
        np.testing.assert_allclose(log_p, np.log(sampler.sample_with_pdf(key(1), (64,))[1]), rtol=1e-6)
        np.testing.assert_allclose(log_p, sampler.log_prob(x), rtol=2e-5, atol=2e-5)


FOREIGN = {
    "numpyro": lambda loc, scale: nd.Normal(loc, scale),
    "distrax": lambda loc, scale: distrax.Normal(loc, scale),
    "tfp": lambda loc, scale: tfd.Normal(loc, scale),
}


def _within(est, exact, sigmas=4.0):
    return abs(float(est.mean) - exact) <= sigmas * float(est.stderr)


@pytest.mark.parametrize("library", FOREIGN)
def test_estimators_take_a_foreign_distribution(library):
    """E[x²] = μ² + σ² by `expectation`, ∫ exp(-x²) dx = √π by `estimate` (importance sampled by
    the foreign normal), the same under `jit`, and `estimate_until` stopping at its tolerance.
    FFR 1.9e-4 per case (three checks at 4 standard errors)."""
    sampler = adapters.from_distribution(FOREIGN[library](0.5, 1.5), measure="length")
    assert sampler.event_shape == () and sampler.measure == "length"
    moment = js.expectation(lambda x: x ** 2, sampler, key(4), 2 ** 16)
    assert _within(moment, 0.25 + 2.25) and float(moment.stderr) < 0.03
    integral = jax.jit(lambda k: js.estimate(lambda x: jnp.exp(-x ** 2), sampler, k, 2 ** 16))(key(5))
    assert _within(integral, np.sqrt(np.pi)) and float(integral.stderr) < 0.01
    until = js.estimate_until(lambda x: jnp.exp(-x ** 2), sampler, key(6), max_n=2 ** 20, rtol=5e-3)
    assert until.converged and _within(until, np.sqrt(np.pi)) and until.n_used < 2 ** 20


def test_a_foreign_distribution_is_unbiased_over_keys():
    """The key made of each point's uniforms gives independent draws: over 200 keys the mean of
    E[x²] estimates under a NumPyro normal is within 4 of its standard errors of σ² (a key
    construction that repeated draws across points would inflate the spread of the z-scores,
    which must stay near 1). FFR 1.3e-4: the mean z and the spread 0.8-1.2 (sd about 0.05) are
    each 4 sd from failing (6.3e-5 each); the distinct keys below fail with probability 1e-10."""
    sampler = adapters.from_distribution(nd.Normal(0.0, 2.0))
    run = jax.jit(jax.vmap(lambda k: js.expectation(lambda x: x ** 2, sampler, k, 2 ** 10)))
    est = run(jax.random.split(key(7), 200))
    z = (np.asarray(est.mean) - 4.0) / np.asarray(est.stderr)
    assert abs(z.mean()) * np.sqrt(len(z)) < 4.0
    assert 0.8 < z.std() < 1.2
    # The keys of 2^16 points of the stream are distinct (a key of only 23 bits, one float32
    # uniform's, would repeat about 128 of them; 64 bits repeat one with probability 1e-10). The
    # samples themselves cannot show it: float32 normals take only about 2^23 values.
    from jaxsample.adapters.foreign import key_from_uniforms
    u = js.uniforms.Random().block(js.uniforms.seed_from_key(key(17)), 0, 2 ** 16, sampler.uniform_dims)
    words = np.asarray(jax.vmap(key_from_uniforms)(u)).astype(np.uint64)
    assert len(np.unique(words[:, 0] << np.uint64(32) | words[:, 1])) == 2 ** 16


def test_gradients_through_a_foreign_distribution():
    """d/dσ E[x²] = 2σ for N(0, σ), through NumPyro's reparameterized sample (pathwise) and
    through its log_prob (score), each with its standard error: FFR 1.3e-4 (2 x 6.3e-5)."""
    def make(sigma):
        return (lambda x: x ** 2), adapters.from_distribution(nd.Normal(0.0, sigma))

    for gradient in ("pathwise", "score"):
        est = js.expectation_grad(make, 1.5, key(8), 2 ** 16, gradient=gradient)
        assert _within(est, 3.0), (gradient, est)


def test_mis_weighs_a_foreign_density_against_a_jaxsample_one():
    """∫ exp(-x²) dx by MIS of a NumPyro normal and jaxsample's, both over length: FFR 6.3e-5."""
    foreign = adapters.from_distribution(nd.Normal(1.0, 1.0), measure="length")
    est = js.estimate_mis(lambda x: jnp.exp(-x ** 2), [foreign, js.Normal(-1.0, 1.0)], key(9), [2 ** 14, 2 ** 14])
    assert _within(est, np.sqrt(np.pi))
    with pytest.raises(ValueError, match="measure"):
        js.estimate_mis(lambda x: x, [adapters.from_distribution(nd.Normal(0.0, 1.0)), js.Normal(0.0, 1.0)],
                        key(10), [16, 16])


def test_the_checks_run_on_a_foreign_distribution_given_its_domain():
    # FFR 1e-6 (chi2_test at its default significance).
    domain = Interval(-np.inf, np.inf, quadrature_low=-12.0, quadrature_high=12.0)
    sampler = adapters.from_distribution(nd.Normal(0.0, 1.0), measure="length", domain=domain)
    result = js.testing.chi2_test(sampler, key(11), n_samples=100_000, n_cells=32, n_pilot=16_384)
    assert result.passed
    with pytest.raises(ValueError, match="domain="):
        adapters.from_distribution(nd.Normal(0.0, 1.0)).domain()


def test_estimators_that_need_uniforms_refuse_a_foreign_distribution():
    sampler = adapters.from_distribution(nd.Normal(0.0, 1.0), measure="length")
    f = lambda x: jnp.exp(-x ** 2)  # noqa: E731
    with pytest.raises(ValueError, match="antithetic pairs"):
        js.estimate_antithetic(f, sampler, key(12), 64)
    for uniforms in ("sobol", "stratified", js.uniforms.Sobol(replicates=4)):
        with pytest.raises(ValueError, match="parameter 'uniforms' must be 'random'"):
            js.estimate(f, sampler, key(13), 64, uniforms=uniforms)
    with pytest.raises(ValueError, match="parameter 'uniforms' must be 'random'"):
        js.estimate_until(f, sampler, key(14), max_n=1024, rtol=0.1, uniforms="sobol")
    with pytest.raises(ValueError, match="parameter 'uniforms' must be 'random'"):
        js.expectation(f, sampler, key(15), 64, uniforms="sobol")
    mixture = js.Mixture([sampler, js.Normal(0.0, 1.0)], jnp.array([0.5, 0.5]))
    with pytest.raises(ValueError, match="DistributionSampler"):
        js.estimate(f, mixture, key(16), 64, uniforms="sobol")


def test_from_distribution_refuses_what_it_cannot_wrap():
    with pytest.raises(ValueError, match="batch_shape"):
        adapters.from_distribution(nd.Normal(jnp.zeros(3), 1.0))
    with pytest.raises(TypeError, match="sample"):
        adapters.from_distribution(object())
    with pytest.raises(TypeError, match="log_prob"):
        adapters.from_distribution(type("OnlySamples", (), {"sample": lambda self, key: 0.0})())
    with pytest.raises(ValueError, match="already a jaxsample sampler"):
        adapters.from_distribution(js.Normal(0.0, 1.0))


def test_numpyro_nuts_with_a_jaxsample_von_mises_fisher_prior():
    """A direction μ with a vMF(κ₀ = 4, +z) prior and five observations x_i ~ vMF(κ = 2, μ): the
    posterior is vMF with resultant r = κ₀ z + κ Σ x_i, so E[μ] = A(|r|) r / |r| with
    A(k) = coth k - 1/k. NUTS (400 warm-up steps, 400 draws, one chain, fixed key) on the jaxsample
    prior through `SphereReparam` and the likelihood through `to_numpyro` must match E[μ] to 0.06
    per component (about 4 Monte Carlo errors of the chain's mean at its effective sample size;
    dropping the prior's factor moves the answer by more than 0.2). FFR about 2e-4 (3 components
    at about 4 Monte Carlo errors, 6.3e-5 each; the chain's error is itself an estimate)."""
    from numpyro.infer import MCMC, NUTS
    from numpyro.handlers import reparam

    kappa0, kappa = 4.0, 2.0
    data = _vmf(kappa, (1.0, 0.0, 0.0)).sample(jax.random.key(5), (5,))

    def model(obs):
        mu = numpyro.sample("mu", adapters.to_numpyro(js.VonMisesFisher(kappa0)))
        with numpyro.plate("data", obs.shape[0]):
            numpyro.sample("x", adapters.to_numpyro(js.Oriented(js.VonMisesFisher(kappa), mu)), obs=obs)

    kernel = NUTS(reparam(model, config={"mu": adapters.SphereReparam()}))
    mcmc = MCMC(kernel, num_warmup=400, num_samples=400, progress_bar=False)
    mcmc.run(jax.random.PRNGKey(0), data)
    mu = np.asarray(mcmc.get_samples()["mu"])
    np.testing.assert_allclose(np.linalg.norm(mu, axis=-1), 1.0, rtol=1e-5)
    r = kappa0 * np.array([0.0, 0.0, 1.0]) + kappa * np.asarray(data, np.float64).sum(axis=0)
    k = np.linalg.norm(r)
    expected = (1.0 / np.tanh(k) - 1.0 / k) * r / k
    np.testing.assert_allclose(mu.mean(axis=0), expected, atol=0.06)
