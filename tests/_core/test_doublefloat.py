"""Double-float accumulation: exactness of the building blocks against float64/fsum, and the
property it exists for — replicate standard errors below a float32 ulp of the mean survive."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jaxsample._core import doublefloat
from jaxsample import uniforms as U
from jaxsample.estimators.engine import run_stream

# Away from over/underflow (XLA flushes subnormals, so an error term below 2^-126 is lost).
finite32 = st.floats(min_value=-2.0 ** 30, max_value=2.0 ** 30, allow_nan=False, width=32).filter(
    lambda x: x == 0 or abs(x) > 2.0 ** -30)


@settings(max_examples=200, deadline=None)
@given(finite32, finite32)
def test_two_sum_and_two_prod_are_exact(a, b):
    a32, b32 = np.float32(a), np.float32(b)
    s, e = jax.jit(doublefloat.two_sum)(a32, b32)
    assert float(s) + float(e) == float(a32) + float(b32)  # exact in float64 (48 bits suffice)
    p, e = jax.jit(doublefloat.two_prod)(a32, b32)
    assert float(p) + float(e) == float(a32) * float(b32)  # a 48-bit product is exact in float64


@pytest.mark.parametrize("method", ["tree", "float64"])
def test_sum_and_divide_to_44_bits(method):
    """Both ways of summing replicates: the TwoSum tree (backends without float64) and the
    float64 sum (CPU, GPU; what "auto" picks there)."""
    rng = np.random.default_rng(1)
    x = (rng.random(1 << 16) * 3 + 0.1).astype(np.float32)
    exact = math.fsum(x.astype(np.float64))
    for leaf, tolerance in ((1, 1e-13), (4, 3e-9)):
        hi, lo = jax.jit(doublefloat.sum_axis0, static_argnums=(1, 2))(jnp.asarray(x), leaf, method)
        assert abs(float(hi) + float(lo) - exact) < tolerance * exact
        # What the double-float form guarantees beyond float32: hi is the sum rounded to float32
        # (hi = fl(hi + lo), renormalized), and lo carries the rest.
        half_ulp = 0.5 * float(np.spacing(np.float32(hi)))
        assert abs(float(hi) - exact) <= half_ulp + tolerance * exact
        assert abs(float(lo)) <= half_ulp
    # (No claim about XLA's plain float32 sum: a more accurate reduction elsewhere is welcome.)
    total = float(hi) + float(lo)
    for divisor in (3, 1 << 16, 99_991, (1 << 26) + 5):
        q_hi, q_lo = doublefloat.divide_by_int((hi, lo), divisor)
        assert abs(float(q_hi) + float(q_lo) - total / divisor) < 2e-13 * total / divisor


def test_sobol_stderr_below_float32_resolution_is_floored_at_rounding():
    """∫₀¹ u du with 16 scrambles of 2^17 Sobol' points: the replicate means differ by ~1e-9, below
    a float32 ulp of 0.5 (6e-8); float64 resolves that spread. In float32 the mean is computed in
    double-float (it is within an ulp of 0.5) and the stderr is the floor at the values' rounding,
    two ulps of mean |Y|, not a spread finer than the float32 mean can carry."""
    n = 16 << 17
    key = jax.random.key(3)

    def run():
        return run_stream(lambda u: u[:, 0], 1, key, n, uniforms=U.Sobol(16))

    est32 = jax.jit(run)()
    key = jax.random.clone(key)  # the same points again, on purpose
    with jax.enable_x64(True):
        est64 = jax.jit(run)()
    assert est64.stderr.dtype == jnp.float64 and est32.stderr.dtype == jnp.float32
    assert 1e-10 < float(est64.stderr) < 3e-8
    floor = 2 * np.finfo(np.float32).eps * 0.5
    assert float(est32.stderr) == pytest.approx(floor, rel=1e-3)
    assert abs(float(est32.mean) - float(est64.mean)) < float(est32.stderr)
    assert abs(float(est32.mean) - 0.5) < 6e-8
