"""A JAX user's first hour with the samplers: keys, batch shapes, the names TFP and distrax users
type, and invalid parameters that must never give a confident number.

Each test guards one way this can go wrong: legacy keys drawing another stream, a batched
PhongLobe raising a broadcasting TypeError, `log_prob`/`seed=`/`batch_shape` missing, a string
exponent accepted, a traced negative exponent giving a finite gradient. All checks are
exact or structural but one comparison of sample means, whose false-failure rate (5e-6) is stated
beside it.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxsample as js

EXPONENTS = jnp.array([1.0, 10.0, 100.0])


# ---- keys: one rule for every entry point ------------------------------------------------------

def test_a_legacy_key_draws_exactly_the_stream_of_the_typed_key_it_holds():
    lobe = js.PhongLobe(20.0)
    typed = lobe.sample(jax.random.key(7), (9,))
    legacy = lobe.sample(jax.random.PRNGKey(7), (9,))
    wrapped = lobe.sample(jax.random.wrap_key_data(jax.random.PRNGKey(7)), (9,))
    np.testing.assert_array_equal(np.asarray(legacy), np.asarray(typed))
    np.testing.assert_array_equal(np.asarray(wrapped), np.asarray(typed))
    x, p = lobe.sample_with_pdf(jax.random.PRNGKey(7), (9,))
    np.testing.assert_array_equal(np.asarray(x), np.asarray(typed))
    # Under jit too (the legacy key arrives as a uint32 tracer).
    jitted = jax.jit(lambda k: lobe.sample(k, (9,)))(jax.random.PRNGKey(7))
    np.testing.assert_array_equal(np.asarray(jitted), np.asarray(typed))


@pytest.mark.parametrize("bad", [0, 1.5, "key", np.zeros(2, np.float32), jnp.zeros(3, jnp.uint32),
                                 jnp.zeros((2, 2), jnp.uint32)], ids=["int", "float", "str", "float-array",
                                                                     "uint32-3", "uint32-2x2"])
def test_anything_that_is_not_a_key_is_a_type_error_saying_what_a_key_is(bad):
    with pytest.raises(TypeError, match="PRNG key.*jax.random.key"):
        js.PhongLobe(20.0).sample(bad, (4,))
    with pytest.raises(TypeError, match="PRNG key"):
        js.estimate(lambda w: w[2], js.CosineHemisphere(), bad, 64)


def test_an_array_of_typed_keys_is_refused_with_the_vmap_advice():
    with pytest.raises(TypeError, match="vmap"):
        js.CosineHemisphere().sample(jax.random.split(jax.random.key(0), 3), (4,))


# ---- batch shapes --------------------------------------------------------------------------

def test_batch_shape_is_the_broadcast_of_the_parameters_leading_dimensions():
    assert js.PhongLobe(20.0).batch_shape == ()
    assert js.CosineHemisphere().batch_shape == ()
    assert js.PhongLobe(EXPONENTS).batch_shape == (3,)
    assert js.PhongLobe([1.0, 10.0, 100.0]).batch_shape == (3,)  # a list is one parameter, not three
    assert js.TruncatedExponential(jnp.ones((2, 1)), jnp.ones(5)).batch_shape == (2, 5)
    # A vector parameter's own dimension is not a batch dimension.
    normals = jnp.array([[0.0, 0, 1], [0, 1, 0], [1, 0, 0], [1, 1, 1]])
    assert js.Oriented(js.PhongLobe(3.0), normals).batch_shape == (4,)
    assert js.Oriented(js.PhongLobe(EXPONENTS[:, None]), normals).batch_shape == (3, 4)
    assert js.UniformTriangle(jnp.zeros((5, 3)), jnp.array([1.0, 0, 0]), jnp.array([0.0, 1, 0])).batch_shape == (5,)
    assert js.UniformBox(jnp.zeros(3), jnp.ones(3)).batch_shape == ()
    assert js.Discrete(jnp.ones(6)).batch_shape == ()
    assert js.PhongLobe(EXPONENTS).event_shape == (3,)


@pytest.mark.parametrize("sample_shape", [(), 5, (5, 2)], ids=["scalar", "int", "pair"])
def test_sample_returns_sample_shape_plus_batch_shape_plus_event_shape(sample_shape):
    lobe = js.PhongLobe(EXPONENTS)
    leading = (sample_shape,) if isinstance(sample_shape, int) else tuple(sample_shape)
    x = lobe.sample(jax.random.key(1), sample_shape)
    assert x.shape == leading + (3, 3)
    x, p = lobe.sample_with_pdf(jax.random.key(1), sample_shape)
    assert x.shape == leading + (3, 3) and p.shape == leading + (3,)


def test_each_batch_member_warps_its_own_stream_points():
    # Sample (s, b) is member b's warp of stream point s * 3 + b (C order over sample + batch).
    key = jax.random.key(2)
    lobe = js.PhongLobe(EXPONENTS)
    x = np.asarray(lobe.sample(key, (4,)))
    u = js.uniforms.uniform_block("random", jax.random.clone(key), 0, 12, 2).reshape(4, 3, 2)
    for b, n in enumerate(np.asarray(EXPONENTS)):
        expected = np.asarray(js.PhongLobe(float(n)).warp(u[:, b]))
        np.testing.assert_allclose(x[:, b], expected, rtol=1e-6, atol=1e-7)
    # Members differ (a batch that ignored its exponents would repeat one lobe). FFR 5e-6: four
    # Phong(1) cosines average more than four Phong(100) ones that rarely (simulated).
    assert np.mean(x[:, 2, 2]) > np.mean(x[:, 0, 2])


def test_pdf_and_log_pdf_broadcast_points_against_the_batch():
    lobe = js.PhongLobe(EXPONENTS)
    x = lobe.sample(jax.random.key(3), (5,))
    p = np.asarray(lobe.pdf(x))
    assert p.shape == (5, 3)
    for b, n in enumerate(np.asarray(EXPONENTS)):
        np.testing.assert_allclose(p[:, b], np.asarray(js.PhongLobe(float(n)).pdf(x[:, b])), rtol=1e-6)
    # One point, every member: shape batch_shape.
    one = jnp.array([0.0, 0.6, 0.8])
    expected = [(n + 1) / (2 * np.pi) * 0.8 ** n for n in np.asarray(EXPONENTS, np.float64)]
    np.testing.assert_allclose(np.asarray(lobe.pdf(one)), expected, rtol=1e-5)
    np.testing.assert_allclose(np.asarray(lobe.log_pdf(one)), np.log(expected), rtol=1e-5)
    np.testing.assert_allclose(np.asarray(lobe.inverse(x))[..., 0],
                               np.asarray(jax.vmap(lambda xs: lobe.inverse(xs))(x))[..., 0], rtol=1e-6)


def test_a_batch_of_rotated_lobes_matches_each_lobe_alone():
    normals = jnp.array([[0.0, 0, 1], [0, 1, 0], [1, 1, 1]])
    batch = js.Oriented(js.PhongLobe(5.0), normals)
    x, p = batch.sample_with_pdf(jax.random.key(4), (6,))
    assert x.shape == (6, 3, 3)
    for b in range(3):
        alone = js.Oriented(js.PhongLobe(5.0), normals[b])
        np.testing.assert_allclose(np.asarray(p[:, b]), np.asarray(alone.pdf(x[:, b])), rtol=1e-5)
        # Each member's samples lie in its own lobe (cosine to its normal above 0).
        axis = np.asarray(normals[b]) / np.linalg.norm(np.asarray(normals[b]))
        assert np.all(np.asarray(x[:, b]) @ axis > 0)


def test_tables_that_cannot_batch_say_so():
    with pytest.raises(ValueError, match="one table per sampler"):
        js.Discrete(np.ones((2, 3)))
    with pytest.raises(ValueError, match="one table per sampler"):
        js.PiecewiseConstant1D(np.ones((2, 3)))


def test_a_two_dimensional_batch_maps_the_same_way_for_points_samples_and_estimates():
    """One batch map (`samplers.base.over_members`) serves the point methods, `sample` and the
    estimators: for a (2, 3) batch of lobes, `prob` at (4, 2, 3, 3) points, `sample` (the stream's
    points in C order over sample and batch shape) and `estimate` give each member's own values at
    its own index, bit for bit. Catches the map putting the flat
    batch at the wrong axis, or unflattening it in the wrong order, on any of the three paths."""
    from keyring import next_key

    exponents = jnp.arange(6.0).reshape(2, 3) * 7.0 + 1.0
    batch = js.PhongLobe(exponents)
    x = js.UniformHemisphere().sample(next_key(), (4, 2, 3))
    density = np.asarray(batch.prob(x))
    key = next_key()
    means = np.asarray(js.estimate(lambda w: w[2] ** 40, batch, jax.random.clone(key), 256).mean)
    sample_key = next_key()
    samples = np.asarray(batch.sample(jax.random.clone(sample_key), (5,)))
    assert density.shape == (4, 2, 3) and means.shape == (2, 3) and samples.shape == (5, 2, 3, 3)
    for i in range(2):
        for j in range(3):
            member = js.PhongLobe(exponents[i, j])
            assert np.array_equal(density[:, i, j], np.asarray(member.prob(x[:, i, j])))
            estimate = js.estimate(lambda w: w[2] ** 40, member, jax.random.clone(key), 256)
            assert np.array_equal(means[i, j], np.asarray(estimate.mean))
            # The batch's samples at [:, i, j] are member (i, j)'s warp of the stream's points there.
            seed = js.uniforms.seed_from_key(jax.random.clone(sample_key))
            u = js.uniforms.Random().block(seed, jnp.uint32(0), 30, 2, jnp.float32)
            assert np.array_equal(samples[:, i, j], np.asarray(member.warp(u.reshape(5, 2, 3, 2)[:, i, j])))


# ---- the names a TFP, distrax or NumPyro user types first ------------------------------------

def test_log_prob_prob_seed_and_sample_shape_are_the_same_functions():
    lobe = js.PhongLobe(20.0)
    key = jax.random.key(5)
    x = lobe.sample(jax.random.clone(key), (8,))
    np.testing.assert_array_equal(np.asarray(lobe.sample(seed=jax.random.clone(key), sample_shape=(8,))),
                                  np.asarray(x))
    np.testing.assert_array_equal(np.asarray(lobe.sample(jax.random.clone(key), shape=(8,))), np.asarray(x))
    np.testing.assert_array_equal(np.asarray(lobe.log_prob(x)), np.asarray(lobe.log_pdf(x)))
    np.testing.assert_array_equal(np.asarray(lobe.prob(x)), np.asarray(lobe.pdf(x)))
    # Today's keyword spellings keep working through the batching wrapper.
    np.testing.assert_array_equal(np.asarray(lobe.pdf(x=x)), np.asarray(lobe.pdf(x)))
    np.testing.assert_array_equal(np.asarray(lobe.inverse(x=x)), np.asarray(lobe.inverse(x)))
    with pytest.raises(TypeError, match="once"):
        lobe.sample(key, (8,), shape=(8,))
    with pytest.raises(TypeError, match="once"):
        lobe.sample(key, (8,), seed=key)
    with pytest.raises(TypeError, match="missing the key"):
        lobe.sample(sample_shape=(8,))


# ---- no confident wrong answers ----------------------------------------------------------------

@pytest.mark.parametrize("make", [lambda: js.PhongLobe("20"), lambda: js.Exponential("1"),
                                  lambda: js.VonMisesFisher(None), lambda: js.Discrete(["a", "b"]),
                                  lambda: js.UniformBox("0", "1"), lambda: js.PhongLobe(True),
                                  lambda: js.Oriented(js.PhongLobe(2.0), "001")],
                         ids=["phong-str", "exponential-str", "vmf-none", "discrete-str", "box-str", "phong-bool",
                              "oriented-str"])
def test_a_parameter_that_is_not_a_number_is_a_type_error_at_construction(make):
    with pytest.raises(TypeError, match="must be a number"):
        make()


def uniform_sphere_density(x):
    return jnp.full(x.shape[:-1], 1.0 / (4.0 * np.pi))


# (name, build from one traced parameter, an invalid value, a valid value)
INVALID_UNDER_JIT = [
    ("rejection-bound-below-1", lambda t: js.Rejection(js.UniformSphere(), uniform_sphere_density, t), 0.5, 1.5),
    ("phong-negative", lambda t: js.PhongLobe(t), -1.0, 3.0),
    ("exponential-zero-rate", lambda t: js.Exponential(t), 0.0, 2.0),
    ("vmf-negative", lambda t: js.VonMisesFisher(t), -5.0, 5.0),
    ("cone-empty", lambda t: js.UniformCone(one_minus_cos_theta_max=t), 0.0, 0.5),
    ("discrete-all-zero", lambda t: js.Discrete(t * jnp.ones(4)), 0.0, 1.0),
    ("mixture-all-zero", lambda t: js.Mixture((js.CosineHemisphere(), js.PhongLobe(3.0)), t * jnp.ones(2)), 0.0, 1.0),
    ("oriented-zero-normal", lambda t: js.Oriented(js.PhongLobe(3.0), t * jnp.array([0.0, 0.0, 1.0])), 0.0, 1.0),
]


@pytest.mark.parametrize("name,build,bad,good", INVALID_UNDER_JIT, ids=[c[0] for c in INVALID_UNDER_JIT])
def test_a_traced_invalid_parameter_gives_nan_samples_densities_and_gradients(name, build, bad, good):
    key = jax.random.key(6)

    def first_value(t):
        sampler = build(t)
        x, p = sampler.sample_with_pdf(jax.random.clone(key), (8,))
        return jnp.sum(jnp.asarray(x, jnp.float32)) + jnp.sum(p)

    value = jax.jit(first_value)
    grad = jax.jit(jax.grad(first_value))
    assert np.isnan(float(value(bad))) and np.isnan(float(grad(bad)))
    # The valid value stays finite: the rule poisons only invalid parameters.
    assert np.isfinite(float(value(good))) and np.isfinite(float(grad(good)))


def test_a_rebuilt_sampler_with_invalid_concrete_parameters_gives_nan_outside_jit():
    # tree_map (an optimizer step) rebuilds a sampler without its constructor's ValueError.
    bad = jax.tree_util.tree_map(lambda p: p - 5.0, js.PhongLobe(2.0))
    x, p = bad.sample_with_pdf(jax.random.key(8), (4,))
    assert np.all(np.isnan(np.asarray(x))) and np.all(np.isnan(np.asarray(p)))
    assert np.isnan(float(js.estimate(lambda w: w[2], bad, jax.random.key(9), 256).mean))
