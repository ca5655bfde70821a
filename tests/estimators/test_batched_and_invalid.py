"""A JAX user's first hour with the estimators: keys, batched estimates, MIS inputs that cannot
be combined, and invalid traced parameters. All are exact or structural but one 6-stderr check
(FFR 2e-9, stated beside it).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxsample as js

N = 1 << 12
EXPONENTS = jnp.array([1.0, 10.0, 100.0])


def cos3(w):
    return w[2] ** 3


def test_every_estimator_takes_a_legacy_key_as_the_typed_key_it_holds():
    lobe = js.PhongLobe(20.0)
    calls = {
        "estimate": lambda k: js.estimate(cos3, lobe, k, N).mean,
        "estimate_mis": lambda k: js.estimate_mis(cos3, [js.CosineHemisphere(), lobe], k, [N, N]).mean,
        "estimate_until": lambda k: js.estimate_until(cos3, lobe, k, max_n=N, chunk_size=1024,
                                                      rtol=0.0, atol=0.0).mean,
    }  # the three ways a key enters: the engine's seed, MIS's split, the adaptive loop's seed
    for name, call in calls.items():
        typed = float(call(jax.random.key(11)))
        legacy = float(call(jax.random.PRNGKey(11)))
        assert typed == legacy, name


def test_a_batched_estimate_is_vmap_over_the_batch():
    key = jax.random.key(12)
    batched = js.estimate(cos3, js.PhongLobe(EXPONENTS), key, N)
    mapped = jax.vmap(lambda n: js.estimate(cos3, js.PhongLobe(n), jax.random.clone(key), N))(EXPONENTS)
    assert batched.mean.shape == (3,) and batched.stderr.shape == (3,)
    np.testing.assert_array_equal(np.asarray(batched.mean), np.asarray(mapped.mean))
    np.testing.assert_array_equal(np.asarray(batched.stderr), np.asarray(mapped.stderr))
    # Member 0 (n = 1, a light-tailed weight) estimates ∫ cos³ = π/2 (6 stderr: false failure 2e-9).
    assert abs(float(batched.mean[0]) - np.pi / 2) < 6 * float(batched.stderr[0])


def test_a_two_dimensional_batch_keeps_its_shape_and_members():
    key = jax.random.key(13)
    lobe = js.PhongLobe(jnp.array([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]))
    est = js.estimate(cos3, lobe, key, N)
    assert est.mean.shape == (2, 3)
    alone = js.estimate(cos3, js.PhongLobe(5.0), jax.random.clone(key), N)
    # vmap and one program round differently (1 ulp): equal to float rounding.
    np.testing.assert_allclose(np.asarray(est.mean)[1, 1], np.asarray(alone.mean), rtol=1e-6)


def test_a_batched_expectation_differentiates_per_member():
    key = jax.random.key(14)

    def total(n):
        return jnp.sum(js.expectation(cos3, js.PhongLobe(n), key, N).mean)

    grads = jax.grad(total)(EXPONENTS)
    one = jax.grad(lambda n: js.expectation(cos3, js.PhongLobe(n), jax.random.clone(key), N).mean)(10.0)
    assert grads.shape == (3,)
    np.testing.assert_allclose(float(grads[1]), float(one), rtol=1e-5)


def test_entry_points_that_take_one_distribution_refuse_a_batch():
    with pytest.raises(ValueError, match="batch_shape"):
        js.estimate_mis(cos3, [js.PhongLobe(EXPONENTS), js.CosineHemisphere()], jax.random.key(0), [64, 64])
    with pytest.raises(ValueError, match="batch_shape"):
        js.estimate_antithetic(cos3, js.PhongLobe(EXPONENTS), jax.random.key(0), 64)


def test_mis_refuses_samplers_of_different_event_shapes_or_measures():
    key = jax.random.key(15)
    with pytest.raises(ValueError, match="event shape"):
        js.estimate_mis(lambda x: 1.0, [js.CosineHemisphere(), js.UniformDisk()], key, [64, 64])
    triangle = js.UniformTriangle(jnp.array([0.0, 0, 1]), jnp.array([1.0, 0, 1]), jnp.array([0.0, 1, 1]))
    with pytest.raises(ValueError, match="measure"):
        js.estimate_mis(lambda x: 1.0, [js.CosineHemisphere(), triangle], key, [64, 64])
    # Mixture, the one-sample MIS, follows the same rule.
    with pytest.raises(ValueError, match="measure"):
        js.Mixture((js.CosineHemisphere(), triangle), [1.0, 1.0])
    # Two samplers over the same measure are fine.
    js.estimate_mis(lambda x: 1.0, [js.UniformDisk(), js.UniformBox(-jnp.ones(2), jnp.ones(2))], key, [64, 64])


@pytest.mark.parametrize("name,build,bad", [
    ("phong", lambda t: js.PhongLobe(t), -1.0),
    ("discrete", lambda t: js.Discrete(t * jnp.ones(4)), 0.0),
    ("oriented", lambda t: js.Oriented(js.PhongLobe(3.0), t * jnp.array([0.0, 0.0, 1.0])), 0.0),
], ids=["phong-negative", "discrete-all-zero", "oriented-zero-normal"])
def test_an_invalid_traced_parameter_gives_a_nan_estimate_with_infinite_stderr(name, build, bad):
    key = jax.random.key(16)

    def mean_of(t):
        return js.estimate(lambda x: jnp.sum(jnp.asarray(x, jnp.float32)), build(t), jax.random.clone(key), 256)

    est = jax.jit(mean_of)(bad)
    assert np.isnan(float(est.mean)) and float(est.stderr) == np.inf
    assert np.isnan(float(jax.jit(jax.grad(lambda t: mean_of(t).mean))(bad)))
    until = jax.jit(lambda t: js.estimate_until(lambda x: jnp.sum(jnp.asarray(x, jnp.float32)), build(t),
                                                jax.random.clone(key), max_n=256, chunk_size=64, min_n=64,
                                                rtol=0.1))(bad)
    assert np.isnan(float(until.mean)) and float(until.stderr) == np.inf


def test_the_measure_valued_gradient_obeys_the_invalid_parameter_rule():
    mean = jax.jit(lambda e: js.expectation(lambda x: x[2], js.PhongLobe(e), jax.random.key(17), 256,
                                            gradient="measure_valued").mean)
    assert np.isnan(float(mean(-0.5))) and np.isnan(float(jax.grad(mean)(-0.5)))
    assert np.isfinite(float(jax.grad(mean)(2.0)))
