"""The programs a gradient compiles to: their size, not their time, and the forward derivative of
a stream against the reverse one (`engine._differentiable_stream`).

Run times are measured in `benchmarks/gradient_cost.py`; here the optimized HLO is read, so that a
change that brings back a cause of gradients many times slower than their value fails: the
reverse pass through the streaming loop (the loop transposed, the per-point program split into
dozens of loops), loop invariants hoisted out of the loop into arrays, a boundary term evaluated
with the value, or a per-point program that leaves the lanes. All deterministic (no false failures).
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxsample as js
from jaxsample import scene
from jaxsample._core.lanes import lane_map
from jaxsample.estimators import engine
from jaxsample.scene import direct

from keyring import next_key

POINT = jnp.zeros(3)
NORMAL = jnp.array([0.0, 0.0, 1.0])
WO = jnp.array([0.3, 0.1, 1.0])
LIGHT = scene.SphereLight(jnp.array([0.4, 0.3, 2.0]), 0.5, 3.0)
N = 1 << 17  # two chunks: a real loop


def _shade_mean(strategy, mode="attached", n=N):
    # A fresh key per trace: the same stream each time, and no key consumed twice.
    return lambda log_n: scene.shade(POINT, NORMAL, WO, scene.Phong(jnp.exp(log_n), 0.8), LIGHT, jax.random.key(3),
                                     n, strategy=strategy, mode=mode).mean


def _hlo(fn, x):
    return jax.jit(fn).lower(x).compile().as_text()


def _chunk_arrays_outside_loops(jaxpr, inside=False):
    """Equations that make a chunk-sized array (a per-point value over the lanes) outside every loop:
    loop invariants JAX hoisted out of a loop traced in a derivative rule, which the loop then reads
    from memory (hundreds of them when the derivative's loop is not a while loop, which slows the
    gradient of MIS-shaded Phong down)."""
    found = 0
    for eqn in jaxpr.eqns:
        if not inside and any(getattr(v.aval, "shape", ())[:1] in ((32768,), (65536,)) for v in eqn.outvars):
            found += eqn.primitive.name == "broadcast_in_dim"
        loop = inside or eqn.primitive.name in ("scan", "while")
        for param in eqn.params.values():
            for sub in param if isinstance(param, (tuple, list)) else (param,):
                inner = getattr(sub, "jaxpr", sub)
                if hasattr(inner, "eqns"):
                    found += _chunk_arrays_outside_loops(inner, loop)
    return found


def _transposed_loops(text):
    """The while loops of reverse mode (JAX names their operations transpose(...))."""
    return [line for line in text.splitlines() if " while(" in line and "transpose(" in line]


def _assert_a_forward_gradient(value, x):
    """jax.grad(value) at x: no transposed loop, no chunk-sized arrays made outside the loops, an
    optimized HLO at most 3x the value's. Returns the gradient's HLO text."""
    grad = jax.grad(value)
    value_text, grad_text = _hlo(value, x), _hlo(grad, x)
    assert _transposed_loops(grad_text) == [], "a loop is transposed: the reverse pass is back"
    assert len(grad_text) <= 3.0 * len(value_text), (len(grad_text), len(value_text))
    assert _chunk_arrays_outside_loops(jax.make_jaxpr(grad)(x).jaxpr) == 0
    return grad_text


@pytest.mark.parametrize("strategy", ["mis", "brdf"])
def test_the_shade_gradient_is_a_forward_pass_of_bounded_size(strategy):
    """jax.grad of `shade` (Phong exponent, a sphere light: the boundary term included) compiles to
    forward loops only: no transposed loop, no chunk-sized arrays made outside the loops, and an
    optimized HLO at most 3x the value's (a reverse pass through the loop is well over that)."""
    grad_text = _assert_a_forward_gradient(_shade_mean(strategy), jnp.float32(np.log(25.0)))
    assert grad_text.count(" while(") <= 3


def test_the_estimate_gradient_is_a_forward_pass_of_bounded_size():
    """The same for `estimate`'s gradient over a Phong lobe turned by `Oriented` (d/dn)."""
    def mean(exponent):
        lobe = js.Oriented(js.PhongLobe(exponent), jnp.array([0.0, 0.6, 0.8]))
        return js.estimate(lambda w: jnp.maximum(w[2], 0.0) ** 2, lobe, jax.random.key(4), N).mean

    _assert_a_forward_gradient(mean, jnp.float32(20.0))


def _loop_equations(jaxpr, inside=False):
    """Equations inside the streaming loop (every nested jaxpr of a scan or while body counted)."""
    total = 0
    for eqn in jaxpr.eqns:
        total += inside
        loop = inside or eqn.primitive.name in ("scan", "while")
        for param in eqn.params.values():
            for sub in param if isinstance(param, (tuple, list)) else (param,):
                inner = getattr(sub, "jaxpr", sub)
                if hasattr(inner, "eqns"):
                    total += _loop_equations(inner, loop)
    return total


def test_the_value_of_shade_does_not_evaluate_the_boundary_term():
    """The silhouettes' boundary term is a derivative only: the value's program is the one without
    it, equation for equation (with the term, attached BRDF sampling's value cost 14-27 % more)."""
    brdf = scene.Phong(25.0, 0.8)

    def value(boundary):
        def run(k):
            fn, dims, count, _ = direct._program(POINT, NORMAL, WO, brdf, [LIGHT], "brdf", "attached", "power", N,
                                              jnp.float32, boundary=boundary)
            return engine.run_stream(fn, dims, k, count, owner="shade").mean
        return run

    with_term, without = (_loop_equations(jax.make_jaxpr(value(b))(jax.random.key(5)).jaxpr) for b in (True, False))
    assert with_term == without > 100
    fn = direct._program(POINT, NORMAL, WO, brdf, [LIGHT], "brdf", "attached", "power", N, jnp.float32)[0]
    assert hasattr(fn, "derivative")


@pytest.mark.parametrize("strategy", ["brdf", "light", "mis"])
def test_the_shading_programs_stay_on_the_lanes(strategy):
    """The per-point value and derivative programs of `shade` (sphere and quad lights, Phong and a
    rough conductor) use only primitives the lanes evaluate: a custom derivative rule (as
    `safe_sqrt` had) or a missing rule leaves the lanes, and the gradient's loops multiply."""
    quad = scene.QuadLight(jnp.array([-0.5, -0.5, 2.0]), jnp.array([0.0, 1.0, 0.0]), jnp.array([1.0, 0.0, 0.0]), 3.0)
    for brdf, light in ((scene.Phong(25.0, 0.8), LIGHT), (scene.RoughConductor(0.3, 0.2, 3.0), quad)):
        fn, dims, _, _ = direct._program(POINT, NORMAL, WO, brdf, [light], strategy, "attached", "power", N,
                                         jnp.float32)
        u = tuple(jnp.linspace(0.05, 0.95, 8) * (0.9 + 0.01 * i) for i in range(dims))
        for program in (fn, getattr(fn, "derivative", fn)):
            lane_map(lambda one: program(one[None])[0], 8, strict=True)(u)


def _estimate_statistics(source, width):
    def statistics(exponent):
        lobe = js.Oriented(js.PhongLobe(exponent), jnp.array([0.0, 0.6, 0.8]))
        est = js.estimate(lambda w: jnp.maximum(w[2], 0.0) ** 3 + 0.1 * w[0], lobe, jax.random.key(6), 1 << 15,
                          uniforms=source, chunk_size=1 << 13)
        return est.mean, est.stderr, est.variance, est.ess

    previous = engine.FORWARD_WIDTH
    engine.FORWARD_WIDTH = width
    try:
        return [np.asarray(g) for g in jax.jacrev(statistics)(jnp.float32(12.0))]
    finally:
        engine.FORWARD_WIDTH = previous


@pytest.mark.parametrize("source", ["random", "sobol"])
def test_the_forward_derivative_of_a_stream_is_the_reverse_one(source):
    """d/dn of an estimate's mean, stderr, variance and ess by the forward stream (S = ∂y/∂θ summed
    with y S and sign(y) S) against the reverse pass through the loop (`FORWARD_WIDTH = 0`), the same
    samples: equal to float32 rounding (rtol 2e-3; the M2 tangent is a difference of two sums). With
    Sobol' points the stderr is the replicate means' spread, so per-replicate sums are checked too."""
    forward, reverse = _estimate_statistics(source, engine.FORWARD_WIDTH), _estimate_statistics(source, 0)
    for name, f, r in zip(("mean", "stderr", "variance", "ess"), forward, reverse):
        np.testing.assert_allclose(f, r, rtol=2e-3, atol=1e-7, err_msg=name)
    assert abs(float(forward[1])) > 0  # the stderr's derivative is not identically zero here


def test_a_forward_derivative_of_shade_matches_forward_mode_and_the_per_sample_gradients():
    """jax.jvp, jax.grad and `shade_grad` (per-sample gradients, a program of its own) give the same
    d/d(log n) on the same samples, to float32 rounding."""
    mean = _shade_mean("mis")
    x = jnp.float32(np.log(25.0))
    by_grad = float(jax.grad(mean)(x))
    by_jvp = float(jax.jvp(mean, (x,), (jnp.float32(1.0),))[1])
    make = lambda log_n: (POINT, NORMAL, WO, scene.Phong(jnp.exp(log_n), 0.8), LIGHT)
    by_samples = float(scene.shade_grad(make, x, jax.random.key(3), N).mean)
    np.testing.assert_allclose(by_jvp, by_grad, rtol=1e-5)
    np.testing.assert_allclose(by_samples, by_grad, rtol=1e-4)


def test_lanes_unstack_a_vector_into_scalars():
    """`jnp.unstack` of a 3-vector gives three scalars on the lanes (strict), equal to vmap; and a
    per-point reverse-mode gradient of the same function (its cotangent sums, `add_any`, are
    evaluated by vmap) equals vmap's too."""
    def f(v):
        a, b, c = jnp.unstack(v)
        return a * b + b * c + jnp.sin(a) * c

    x = jax.random.uniform(next_key(), (16, 3))
    columns = tuple(x[:, i] for i in range(3))
    np.testing.assert_allclose(np.asarray(lane_map(f, 16, strict=True)(columns)), np.asarray(jax.vmap(f)(x)),
                               rtol=1e-6)
    np.testing.assert_allclose(np.asarray(lane_map(jax.grad(f), 16)(columns)), np.asarray(jax.vmap(jax.grad(f))(x)),
                               rtol=1e-6)
