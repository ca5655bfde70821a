"""Integrands that return pytrees and complex values (`estimators/integrand.py`).

The rule: every leaf of f's value is averaged on its own and the result has f's structure with an
`Estimate` at every leaf; a complex leaf's statistics are complex, real part from the real parts
and imaginary part from the imaginary parts. Checked for every entry point that takes an
integrand against the same components written as one real array (same key, so the same samples:
the statistics must agree to float rounding), plus one known complex integral.

The one statistical check states its false-failure rate; the mutation records in
`tests/mutations.py` show that each check fails on a deliberately wrong estimator.
"""

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxsample as js
from jaxsample._core.pytree import Pytree

jax.config.update("jax_debug_key_reuse", True)

D = js.CosineHemisphere()
N = 1024
FIELDS = ("mean", "stderr", "variance", "max_abs", "ess")


def tree_f(w):
    """A dict with a scalar, a vector, a complex wave and an indicator (a bool)."""
    return {"cos2": w[2] ** 2, "xy": w[:2], "wave": jnp.exp(3j * w[2]), "high": w[2] > 0.5}


def flat_f(w):
    """The same components as one real array, in the order COMPONENTS names them."""
    return jnp.stack([w[2] ** 2, w[0], w[1], jnp.cos(3 * w[2]), jnp.sin(3 * w[2]),
                      (w[2] > 0.5).astype(w.dtype)])


# leaf -> (index of its real part(s) in flat_f, index of its imaginary part or None)
COMPONENTS = {"cos2": (0, None), "xy": ([1, 2], None), "wave": (3, 4), "high": (5, None)}


def key(i):
    return jax.random.key(1410 + i)


ENTRY_POINTS = {
    "estimate": lambda f, k: js.estimate(f, D, k, N),
    "estimate_mis": lambda f, k: js.estimate_mis(f, [D, js.UniformHemisphere()], k, [N, N // 2]),
    "estimate_antithetic": lambda f, k: js.estimate_antithetic(f, D, k, N),
    "estimate_ratio": lambda f, k: js.estimate_ratio(f, lambda w: 1.0 + w[0], D, k, N),
    "estimate_control_variate": lambda f, k: js.estimate_control_variate(f, lambda w: w[2], np.pi, D, k, N),
    # atol = 0 is never met: both runs stream all of max_n, so they see the same samples.
    "estimate_until": lambda f, k: js.estimate_until(f, D, k, atol=0.0, max_n=4 * N, chunk_size=N),
    "expectation-pathwise": lambda f, k: js.expectation(f, D, k, N),
    "expectation-score": lambda f, k: js.expectation(f, D, k, N, gradient="score", baseline=0.5),
    "expectation-leave-one-out": lambda f, k: js.expectation(f, D, k, N, gradient="score",
                                                              baseline="leave_one_out"),
}


def assert_leaf_matches(leaf_estimate, reference, name):
    real, imaginary = COMPONENTS[name]
    for field in FIELDS:
        got = np.asarray(getattr(leaf_estimate, field))
        want = np.asarray(getattr(reference, field))[real]
        if imaginary is None:
            assert not np.iscomplexobj(got), (name, field)
            np.testing.assert_allclose(got, want, rtol=2e-5, atol=1e-6, err_msg=f"{name}.{field}")
        else:
            assert np.iscomplexobj(got), (name, field)
            np.testing.assert_allclose(got.real, want, rtol=2e-5, atol=1e-6, err_msg=f"{name}.{field}.real")
            np.testing.assert_allclose(got.imag, np.asarray(getattr(reference, field))[imaginary], rtol=2e-5,
                                       atol=1e-6, err_msg=f"{name}.{field}.imag")
        assert np.shape(got) == np.shape(want), (name, field)


@pytest.mark.parametrize("entry", ["estimate", "estimate_ratio"])
def test_each_leaf_has_the_statistics_of_its_components(entry):
    """Every statistic of every leaf equals that of the same component in the one-array version
    (same key, same samples; to float rounding). `estimate` covers the packing shared by every
    entry point, `estimate_ratio` the per-component ratio against one scalar h."""
    run = ENTRY_POINTS[entry]
    tree = jax.jit(lambda k: run(tree_f, k))(key(0))
    flat = jax.jit(lambda k: run(flat_f, k))(key(0))
    for name in COMPONENTS:
        assert_leaf_matches(tree[name], flat, name)


@pytest.mark.parametrize("entry", list(ENTRY_POINTS))
def test_every_entry_point_follows_the_rule(entry):
    """f's structure with an Estimate (EstimateUntil) per leaf, each statistic shaped like its
    leaf and complex for the complex leaf (traced only: nothing is compiled or run)."""
    tree = jax.eval_shape(lambda k: ENTRY_POINTS[entry](tree_f, k), key(1))
    kind = js.estimators.EstimateUntil if entry == "estimate_until" else js.Estimate
    assert isinstance(tree, dict) and set(tree) == set(COMPONENTS)
    for name, shape in (("cos2", ()), ("xy", (2,)), ("wave", ()), ("high", ())):
        assert type(tree[name]) is kind
        for field in FIELDS:
            statistic = getattr(tree[name], field)
            assert statistic.shape == shape, (name, field)
            assert (statistic.dtype == jnp.complex64) == (name == "wave"), (name, field)


@pytest.mark.parametrize("which", ["integrand_values", "expectation_values"])
def test_per_sample_values_keep_the_structure(which):
    u = jax.random.uniform(key(2), (64, 2), minval=0.01, maxval=0.99)
    fn = getattr(js.estimators, which)
    tree, flat = jax.jit(lambda u: (fn(tree_f, D, u), fn(flat_f, D, u)))(u)
    flat = np.asarray(flat)
    assert set(tree) == set(COMPONENTS) and tree["xy"].shape == (64, 2) and tree["wave"].dtype == jnp.complex64
    np.testing.assert_allclose(np.asarray(tree["cos2"]), flat[:, 0], rtol=1e-6)
    np.testing.assert_allclose(np.asarray(tree["xy"]), flat[:, 1:3], rtol=1e-6)
    np.testing.assert_allclose(np.asarray(tree["wave"]).real, flat[:, 3], rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(np.asarray(tree["wave"]).imag, flat[:, 4], rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(np.asarray(tree["high"]), flat[:, 5], rtol=1e-6)
class Radiance(Pytree):
    value: Any
    weight: Any


def test_tuples_and_dataclasses_come_back_with_estimates_at_their_leaves():
    as_tuple = jax.eval_shape(lambda k: js.estimate(lambda w: (w[2], (w[0], w[1] ** 2)), D, k, N), key(3))
    assert isinstance(as_tuple, tuple) and isinstance(as_tuple[1], tuple)
    assert all(isinstance(leaf, js.Estimate) for leaf in (as_tuple[0], *as_tuple[1]))
    record = jax.eval_shape(lambda k: js.estimate(lambda w: Radiance(value=w[2] ** 3, weight=w[:2]), D, k, N),
                            key(4))
    assert isinstance(record, Radiance) and isinstance(record.value, js.Estimate)
    assert record.weight.mean.shape == (2,) and record.value.mean.shape == ()
    # A single array is still a single Estimate (nothing packed).
    assert isinstance(jax.eval_shape(lambda k: js.estimate(lambda w: w[2], D, k, N), key(5)), js.Estimate)


def test_a_complex_integral_is_right_part_by_part():
    """∫_{H²} exp(i a cos θ) dω = 2π ∫_0^1 e^{iat} dt = 2π (sin a / a + i (1 - cos a) / a).

    Each part within 5 of its own standard errors: FFR 5.7e-7 per part (normal approximation of
    the mean of 2^14 bounded values), 1.2e-6 for the test."""
    a = 3.0
    exact = 2 * np.pi * (np.sin(a) / a + 1j * (1 - np.cos(a)) / a)
    est = jax.jit(lambda k: js.estimate(lambda w: jnp.exp(1j * a * w[2]), D, k, 1 << 14))(key(5))
    mean, stderr = complex(est.mean), complex(est.stderr)
    assert stderr.real > 0 and stderr.imag > 0
    assert abs(mean.real - exact.real) < 5 * stderr.real
    assert abs(mean.imag - exact.imag) < 5 * stderr.imag
    low, high = est.interval()
    assert complex(low) == pytest.approx(mean - 1.959963984540054 * stderr.real - 1.959963984540054j * stderr.imag)
    assert complex(high) == pytest.approx(mean + 1.959963984540054 * stderr.real + 1.959963984540054j * stderr.imag)


def test_estimate_until_measures_a_complex_leaf_by_its_modulus():
    """The tolerance of a complex leaf is |stderr| <= rtol |mean|, moduli of the pairs.

    A purely imaginary integrand stops exactly where its real twin stops. And w_z³ + i w_x w_z,
    whose imaginary part has mean 0 (so rtol times that part is never met part by part), stops
    as soon as the modulus of its stderr is within 1 % of the modulus of its mean."""
    run = jax.jit(lambda k, which: js.estimate_until(
        {"real": lambda w: w[2] ** 3, "imaginary": lambda w: 1j * w[2] ** 3,
         "mixed": lambda w: w[2] ** 3 + 1j * w[0] * w[2]}[which], D, k, rtol=0.01, max_n=1 << 16,
        chunk_size=1024), static_argnums=1)
    real, imaginary = run(key(6), "real"), run(key(6), "imaginary")
    assert bool(real.converged) and bool(imaginary.converged)
    assert int(imaginary.n_used) == int(real.n_used) < 1 << 16
    np.testing.assert_allclose(complex(imaginary.mean).imag, float(real.mean), rtol=1e-6)
    mixed = run(key(7), "mixed")
    mean, stderr = complex(mixed.mean), complex(mixed.stderr)
    assert bool(mixed.converged) and int(mixed.n_used) < 1 << 16
    assert abs(stderr) <= 0.01 * abs(mean)
    assert stderr.imag > 0.01 * abs(mean.imag)   # the imaginary part alone is not within 1 %


def test_integrands_an_estimator_cannot_take_raise_a_type_error():
    k = key(8)
    with pytest.raises(TypeError, match="estimate_grad.*pytree"):
        js.estimate_grad(lambda p: (lambda w: {"a": p * w[2]}, D), 1.0, k, 64)
    with pytest.raises(TypeError, match="expectation_grad.*complex"):
        js.expectation_grad(lambda p: (lambda w: jnp.exp(1j * w[2]), js.PhongLobe(p)), 2.0, k, 64)
    with pytest.raises(TypeError, match="estimate_ratio: 'h'.*complex"):
        js.estimate_ratio(lambda w: w[2], lambda w: 1j * w[2], D, k, 64)
    with pytest.raises(TypeError, match="estimate_control_variate: 'g'.*pytree"):
        js.estimate_control_variate(lambda w: w[2], lambda w: (w[2], w[0]), 1.0, D, k, 64)
    with pytest.raises(TypeError, match="estimate: every value of the integrand must be a number"):
        js.estimate(lambda w: {"a": w[2], "key": jax.random.key(0)}, D, k, 64)
    with pytest.raises(TypeError, match="estimate_mis: the integrand must return an array"):
        js.estimate_mis(lambda w: None, [D], k, [64])
