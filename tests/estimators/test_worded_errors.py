"""Mistakes a user makes in the first hour, each answered in the library's words: the error
names the parameter and what is allowed, where JAX or Python internals would speak otherwise (an
`int()` of a property, a ZeroDivisionError, "'int' object is not iterable", a broadcasting error,
float32 behind four warnings, NaN everywhere). Each test raises before anything is compiled,
except the two that call a sampler (one small program each).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxsample as js
from jaxsample._core.params import resolve_float_dtype

KEY = jax.random.key(29)
N = 64


def z(w):
    return w[2]


def test_a_sampler_class_for_an_instance_is_named_by_every_entry_point():
    sphere = js.UniformSphere
    calls = {
        "estimate": lambda: js.estimate(z, sphere, KEY, N),
        "expectation": lambda: js.expectation(z, sphere, KEY, N),
        "estimate_mis": lambda: js.estimate_mis(z, [js.UniformSphere(), sphere], KEY, [N, N]),
        "estimate_until": lambda: js.estimate_until(z, sphere, KEY, rtol=0.1, max_n=N),
        "estimate_grad": lambda: js.estimate_grad(lambda p: (lambda w: p * w[2], sphere), 1.0, KEY, N),
        "chi2_test": lambda: js.testing.chi2_test(sphere, KEY),
    }
    for owner, call in calls.items():
        with pytest.raises(ValueError, match=r"parameter 'sampler' must be a sampler instance; got the class "
                                             r"UniformSphere: call it, UniformSphere\(\)"):
            call()
    with pytest.raises(ValueError, match=r"^estimate_mis: parameter 'sampler'"):
        calls["estimate_mis"]()
    with pytest.raises(ValueError, match=r"Oriented: parameter 'base' must be a sampler instance"):
        js.Oriented(sphere, [0.0, 0.0, 1.0])
    with pytest.raises(ValueError, match=r"Mixture: parameter 'components' must be a sampler instance"):
        js.Mixture([js.UniformSphere(), sphere], [1.0, 1.0])
    with pytest.raises(ValueError, match=r"Rejection: parameter 'proposal'.*call it, UniformSphere\(\)"):
        js.Rejection(sphere, lambda x: x[..., 2], 2.0)
    with pytest.raises(ValueError, match=r"got the class PhongLobe: call it, PhongLobe\(\.\.\.\)"):
        js.estimate(z, js.PhongLobe, KEY, N)  # a class that needs parameters
    with pytest.raises(TypeError, match=r"estimate_until: parameter 'sampler' must be a jaxsample.Sampler"):
        js.estimate_until(z, "sphere", KEY, rtol=0.1, max_n=N)


def test_an_integrand_with_no_values_is_refused_before_it_runs():
    empty = lambda w: w[:0]  # noqa: E731
    for owner, call in {
        "estimate": lambda: js.estimate(empty, js.UniformSphere(), KEY, N),
        "expectation": lambda: js.expectation(empty, js.UniformSphere(), KEY, N),
        "estimate_until": lambda: js.estimate_until(empty, js.UniformSphere(), KEY, rtol=0.1, max_n=N),
        "estimate_mis": lambda: js.estimate_mis(lambda w: {"a": w[:0]}, [js.UniformSphere()] * 2, KEY, [N, N]),
    }.items():
        with pytest.raises(ValueError, match=rf"^{owner}: the integrand must return at least one number per sample"):
            call()


def test_mis_counts_must_be_one_count_per_sampler():
    samplers = [js.UniformSphere(), js.UniformSphere()]
    with pytest.raises(ValueError, match=r"estimate_mis: parameter 'counts' must be a sequence of one count per "
                                         r"sampler \(2 here; for 4096 in all, e\.g\. \[2048, 2048\]\); got int 4096"):
        js.estimate_mis(z, samplers, KEY, 4096)
    with pytest.raises(ValueError, match=r"estimate_mis: parameter 'counts' must be a sequence"):
        js.estimate_mis(z, samplers, KEY, jnp.int32(N))
    with pytest.raises(ValueError, match=r"'samplers' and 'counts' must be non-empty and of equal length"):
        js.estimate_mis(z, samplers, KEY, [N])


def test_an_oriented_batch_must_broadcast_with_its_normals():
    lobes = js.PhongLobe(jnp.array([1.0, 2.0, 3.0, 4.0]))
    with pytest.raises(ValueError, match=r"Oriented: the batch shapes of 'base' \(4,\) and 'normal' \(3,\) "
                                         r"\(normal of shape \(3, 3\)\) must broadcast.*normals of shape \(4, 3\)"):
        js.Oriented(lobes, jnp.ones((3, 3)))
    assert js.Oriented(lobes, jnp.ones((4, 3))).batch_shape == (4,)
    assert js.Oriented(lobes, [0.0, 0.0, 1.0]).batch_shape == (4,)
    # Rebuilt from leaves (no constructor ran), the batch shape itself names the parameters.
    leaves, treedef = jax.tree_util.tree_flatten(js.Oriented(js.PhongLobe(jnp.ones(3)), jnp.ones((3, 3))))
    rebuilt = jax.tree_util.tree_unflatten(treedef, [jnp.ones(4)] + leaves[1:])
    with pytest.raises(ValueError, match=r"Oriented: the batch shapes of its parameters must broadcast .*"
                                         r"base\.exponent \(4,\), frame\.x \(3,\)"):
        rebuilt.batch_shape


def test_float64_without_x64_is_refused_not_truncated():
    """Refused with x64 off (switched off here, so the test runs under either setting)."""
    with jax.enable_x64(False):
        need = r"parameter 'dtype' is float64, which needs jax_enable_x64: call jax\.config\.update"
        sphere = js.UniformSphere()
        for owner, call in {
            "estimate": lambda: js.estimate(z, sphere, KEY, N, dtype=jnp.float64),
            "expectation": lambda: js.expectation(z, sphere, KEY, N, dtype="float64"),
            "estimate_mis": lambda: js.estimate_mis(z, [sphere, sphere], KEY, [N, N], dtype=np.float64),
            "estimate_until": lambda: js.estimate_until(z, sphere, KEY, rtol=0.1, max_n=N, dtype=jnp.float64),
            "estimate_antithetic": lambda: js.estimate_antithetic(z, sphere, KEY, N, dtype=jnp.float64),
            "sample": lambda: sphere.sample(KEY, (2,), jnp.float64),
        }.items():
            with pytest.raises(ValueError, match=rf"^{owner}: {need}"):
                call()
        assert resolve_float_dtype("estimate", None) == resolve_float_dtype("estimate", float) == np.float32
        assert resolve_float_dtype("estimate", "float32") == np.float32
        with pytest.raises(ValueError, match=r"estimate: parameter 'dtype' must be float32 or float64"):
            resolve_float_dtype("estimate", jnp.int32)


def test_the_tfp_spelling_of_sample_draws_the_same_points():
    sphere, key = js.UniformSphere(), lambda: jax.random.key(6)  # a key is consumed once per draw
    expected = sphere.sample(key(), (5,))
    np.testing.assert_array_equal(sphere.sample((5,), seed=key()), expected)
    np.testing.assert_array_equal(sphere.sample(5, seed=key()), expected)
    np.testing.assert_array_equal(sphere.sample(seed=key(), sample_shape=(5,)), expected)
    with pytest.raises(TypeError, match=r"sample: the key comes first: sample\(key, \(5,\)\), or with the key by "
                                        r"name as in TFP, sample\(\(5,\), seed=key\)"):
        sphere.sample((5,), key())


def test_a_concrete_normal_too_short_to_normalise_is_refused():
    for normal in ([0.0, 0.0, 1e-30], [1e20, 0.0, 0.0], [[0.0, 0.0, 1.0], [0.0, 1e-25, 0.0]]):
        with pytest.raises(ValueError, match=r"Frame\.from_normal: parameter 'normal' must have a length in "
                                             r"\[1\.08e-19, 1\.84e\+19\] to be normalised in float32"):
            js.Oriented(js.UniformSphere(), jnp.asarray(normal, jnp.float32))
    frame = js.Oriented(js.UniformSphere(), jnp.asarray([0.0, 0.0, 1e-15], jnp.float32)).frame  # normalisable
    np.testing.assert_allclose(frame.z, [0.0, 0.0, 1.0])


class UserSampler(js.Sampler):
    """A user's sampler that has not written `inverse`."""

    uniform_dims = 1
    measure = "length"

    def warp(self, u):
        return u[..., 0]

    def pdf(self, x):
        return jnp.ones_like(x)


def test_a_user_sampler_without_inverse_is_not_told_its_warp_is_not_a_bijection():
    with pytest.raises(NotImplementedError, match=r"^UserSampler does not define inverse\(x\); write one"):
        UserSampler().inverse(jnp.zeros((3,)))
    mixture = js.Mixture([js.UniformSphere(), js.UniformSphere()], [1.0, 1.0])
    with pytest.raises(NotImplementedError, match=r"^Mixture has no inverse: its warp is not a bijection"):
        mixture.inverse(jnp.zeros((3,)))
