"""Estimators called eagerly run as one compiled program (`jaxsample._core.entry`).

Run op by op, an eager `estimate` compiles ~40 small programs on its first call and its loop again
on every call, and `jax.grad` of it 158 programs. These tests count XLA compilations (JAX's
monitoring events, no clock): a repeat call with the same integrand and new parameters and key
compiles nothing, and the results are those of the same call under `jax.jit`, bit for bit.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxsample as js

N = 4096


def cos3(w):
    return w[2] ** 3


def _counting_compilations(fn):
    """(fn(), number of XLA compilations it caused)."""
    events = []

    def listener(event, duration, **kwargs):
        if event.endswith("backend_compile_duration"):
            events.append(event)

    jax.monitoring.register_event_duration_secs_listener(listener)
    try:
        result = jax.block_until_ready(fn())
    finally:
        jax.monitoring.unregister_event_duration_listener(listener)
    return result, len(events)


def test_a_repeated_eager_estimate_compiles_nothing():
    first_key, key, again_key = jax.random.key(10), jax.random.key(0), jax.random.key(0)
    first_lobe, lobe = js.PhongLobe(20.0), js.PhongLobe(35.0)
    _, first = _counting_compilations(lambda: js.estimate(cos3, first_lobe, first_key, N))
    est, again = _counting_compilations(lambda: js.estimate(cos3, lobe, key, N))
    assert first <= 4, first  # the program, and at most the key's seed words and a constant
    assert again == 0, again
    jitted = jax.jit(lambda k: js.estimate(cos3, lobe, k, N))(again_key)
    assert float(est.mean) == float(jitted.mean) and float(est.stderr) == float(jitted.stderr)


def test_a_repeated_eager_gradient_compiles_nothing():
    keys = jax.random.key(1), jax.random.key(2)

    def grad_at(exponent, key):
        return jax.grad(lambda e: js.estimate(cos3, js.PhongLobe(e), key, N).mean)(exponent)

    _, first = _counting_compilations(lambda: grad_at(5.0, keys[0]))
    value, again = _counting_compilations(lambda: grad_at(7.0, keys[1]))
    assert first <= 6, first
    assert again == 0, again
    assert np.isfinite(float(value))


class _Unhashable:
    """An integrand that cannot be a static argument (it defines __eq__ and no __hash__)."""

    def __eq__(self, other):
        return isinstance(other, _Unhashable)

    def __call__(self, w):
        return w[2] ** 3


def test_an_unhashable_integrand_runs_uncompiled_with_the_same_result():
    key = jax.random.key(2)
    plain = js.estimate(_Unhashable(), js.CosineHemisphere(), jax.random.clone(key), N)
    compiled = js.estimate(cos3, js.CosineHemisphere(), key, N)
    np.testing.assert_allclose(plain.mean, compiled.mean, rtol=1e-6)
    np.testing.assert_allclose(plain.stderr, compiled.stderr, rtol=1e-5)


def test_the_usual_errors_come_through():
    with pytest.raises(TypeError, match="parameter 'key' must be a JAX PRNG key; got int"):
        js.estimate(cos3, js.CosineHemisphere(), 3, N)
    with pytest.raises(TypeError, match="static_arg"):
        jax.jit(lambda n: js.estimate(cos3, js.CosineHemisphere(), jax.random.key(3), n))(jnp.int32(N))
    with pytest.raises(ValueError, match="mode"):
        js.estimate(cos3, js.CosineHemisphere(), jax.random.key(4), N, mode="half")


def test_every_public_estimator_is_a_compiled_entry():
    from jaxsample import scene

    entries = [js.estimate, js.expectation, js.estimate_mis, js.estimate_ratio, js.estimate_antithetic,
               js.estimate_control_variate, js.estimate_grad, js.expectation_grad, js.estimate_until,
               scene.shade, scene.shade_grad]
    assert [fn.__name__ for fn in entries if fn.__code__.co_filename != compiled_entry_file()] == []


def compiled_entry_file():
    from jaxsample._core import entry

    return entry.__file__


def test_a_repeated_eager_estimate_until_compiles_nothing():
    def run(exponent, key):
        return js.estimate_until(cos3, js.PhongLobe(exponent), key, rtol=1e-2, max_n=1 << 14, chunk_size=1 << 10)

    _, first = _counting_compilations(lambda: run(3.0, jax.random.key(5)))
    est, again = _counting_compilations(lambda: run(2.0, jax.random.key(6)))
    assert again == 0, again
    jitted = jax.jit(lambda k: run(2.0, k))(jax.random.key(6))
    assert float(est.mean) == float(jitted.mean) and int(est.n_used) == int(jitted.n_used)


def phong_cos3(exponent):
    return cos3, js.PhongLobe(exponent)


@pytest.mark.parametrize("baseline", ["leave_one_out", 0.1])
def test_a_baseline_given_as_text_or_number_compiles_once(baseline):
    """`baseline` is a string ("leave_one_out") or a traced number: the string picks the program
    (static for that call) and does not send the call op by op, which would compile hundreds of
    small programs and take a second per repeat call."""
    def run(exponent, key):
        return js.expectation_grad(phong_cos3, exponent, key, N, gradient="score", baseline=baseline)

    _, first = _counting_compilations(lambda: run(5.0, jax.random.key(7)))
    est, again = _counting_compilations(lambda: run(6.0, jax.random.key(8)))
    assert first <= 4, first
    assert again == 0, again
    # (Under an enclosing jit a numeric baseline is a constant XLA may fold: equal to rounding.)
    jitted = jax.jit(lambda k: run(6.0, k))(jax.random.key(8))
    np.testing.assert_allclose([est.mean, est.stderr], [jitted.mean, jitted.stderr], rtol=1e-6)
