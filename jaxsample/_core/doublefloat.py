"""Double-float ("float-float") arithmetic: a value carried as an unevaluated sum hi + lo.

The estimators keep the per-replicate sums of Sobol' and stratified points in this form. Their
standard error is the spread of the replicate means, which for scrambled Sobol' points shrinks
like n^-1.5: past ~2^16 points per replicate it falls below the rounding of a float32 mean of
order 1 (about 6e-8), and replicate means rounded to float32 would all come out equal (stderr 0,
which is false). With hi + lo the means, and so their spread, keep ~44 bits.

Algorithms: TwoSum (Knuth, TAOCP vol. 2, 4.2.2), and an exact product by splitting each factor
into two halves of at most 12 significant bits (Dekker 1971, "A floating-point technique for
extending the available precision"); the split here masks the low mantissa bits instead of
Veltkamp's multiply-and-subtract, so it is exact even if the compiler contracts a*b + c into
an FMA. All of this relies on IEEE round-to-nearest and no reassociation, which XLA's CPU and
GPU backends keep by default (no fast-math).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["two_sum", "two_prod", "add", "sum_axis0", "divide_by_int"]


def two_sum(a: jax.Array, b: jax.Array) -> tuple[jax.Array, jax.Array]:
    """s, e with s = fl(a + b) and a + b = s + e exactly."""
    s = a + b
    b_virtual = s - a
    a_virtual = s - b_virtual
    return s, (a - a_virtual) + (b - b_virtual)


def _split(a: jax.Array) -> tuple[jax.Array, jax.Array]:
    """a = high + low, high the top 12 significant bits of a float32 (low has at most 12)."""
    bits = jax.lax.bitcast_convert_type(a, jnp.uint32) & jnp.uint32(0xFFFFF000)
    high = jax.lax.bitcast_convert_type(bits, jnp.float32)
    return high, a - high


def two_prod(a: jax.Array, b: jax.Array) -> tuple[jax.Array, jax.Array]:
    """p, e with p = fl(a b) and a b = p + e exactly (float32, barring over/underflow)."""
    p = a * b
    a_hi, a_lo = _split(a)
    b_hi, b_lo = _split(b)
    e = ((a_hi * b_hi - p) + a_hi * b_lo + a_lo * b_hi) + a_lo * b_lo
    return p, e


def add(x: tuple[jax.Array, jax.Array], y: tuple[jax.Array, jax.Array]):
    """(hi, lo) + (hi, lo), renormalized. Where hi + hi is not finite (an inf or NaN term, or
    overflow) its error term is NaN (inf - inf); hi is then that plain IEEE sum, not NaN."""
    s, e = two_sum(x[0], y[0])
    hi, lo = two_sum(s, e + x[1] + y[1])
    return jnp.where(jnp.isfinite(s), hi, s), lo


def _float64_available() -> bool:
    # TPUs have no float64 arithmetic; CPUs and GPUs sum in it at memory speed.
    return jax.default_backend() != "tpu"


def sum_axis0(values: jax.Array, leaf: int = 4, method: str = "auto") -> tuple[jax.Array, jax.Array]:
    """Σ over axis 0 as (hi, lo). `method`: "float64", "tree" or "auto" (float64 for float32
    values where the backend has float64, else the tree).

    "float64": one float64 sum (relative error below
    count · 2^-53), split into hi = fl32(s) and lo = fl32(s - hi), which keeps ~48 bits. This is
    both more accurate and, on XLA's CPU backend, ~3x cheaper per value than the tree below, whose
    ten levels of small TwoSum kernels cost more than the points they summed (the estimator with 16
    replicates of Philox points: more than twice the time per sample with the tree; timed with
    `benchmarks/bench_estimator.py`).

    "tree": plain sums over leaves of `leaf` values, then a pairwise tree of TwoSums. The leaf
    rounding errors are independent and of size ε |leaf sum|, so the result's error is
    ~ε sqrt(leaf / count) relative instead of the ~ε of a plain tree."""
    if method not in ("auto", "float64", "tree"):
        raise ValueError(f"sum_axis0: parameter 'method' must be 'auto', 'float64' or 'tree'; got {method!r}")
    if method == "auto":
        method = "float64" if values.dtype == jnp.float32 and _float64_available() else "tree"
    if method == "float64":
        with jax.enable_x64(True):
            total = jnp.sum(values.astype(jnp.float64), axis=0)
            hi = total.astype(jnp.float32)
            lo = (total - hi.astype(jnp.float64)).astype(jnp.float32)
        return hi, lo
    count = values.shape[0]
    padded = -(-count // leaf) * leaf
    if padded != count:
        values = jnp.pad(values, [(0, padded - count)] + [(0, 0)] * (values.ndim - 1))
    hi = values.reshape((padded // leaf, leaf) + values.shape[1:]).sum(axis=1)
    lo = jnp.zeros_like(hi)
    while hi.shape[0] > 1:
        if hi.shape[0] % 2:
            hi = jnp.concatenate([hi, jnp.zeros_like(hi[:1])])
            lo = jnp.concatenate([lo, jnp.zeros_like(lo[:1])])
        hi, lo = add((hi[0::2], lo[0::2]), (hi[1::2], lo[1::2]))
    return hi[0], lo[0]


def divide_by_int(x: tuple[jax.Array, jax.Array], divisor: int):
    """(hi, lo) / divisor for a positive Python int below 2^48, to ~2^-44 relative (float32).

    The divisor is itself split as d_hi + d_lo (both exact in the float type); one correction
    step: q1 = hi/d_hi, r = hi + lo - q1 d (q1 d_hi exact by two_prod), q = q1 + r/d_hi.
    """
    hi, lo = x
    dtype = hi.dtype
    d_hi = float(np.asarray(divisor, dtype))
    d_lo = float(divisor - int(d_hi))
    q1 = hi / d_hi
    if dtype != jnp.float32:
        # float64 already carries the digits this is for; a plain correction is enough.
        return two_sum(q1, ((hi - q1 * d_hi) - q1 * d_lo + lo) / d_hi)
    p, e = two_prod(q1, jnp.asarray(d_hi, dtype))
    r = (((hi - p) - e) + lo) - q1 * d_lo
    return two_sum(q1, r / d_hi)
