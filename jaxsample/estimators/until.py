"""Estimates to a requested accuracy: `estimate_until` (issue 15, part 2).

Users ask for "this integral to three digits", not "with 2^20 samples". `estimate_until` streams
chunks of samples (the same counter-based points as `estimate`: sample i depends only on the key
and i) inside a `lax.while_loop`, and stops as soon as the standard error is at most
max(atol, rtol·|mean|), or when `max_n` samples are used. It runs under `jit` and `vmap` (each
batch member stops on its own; under vmap the loop runs until all have stopped, the stopped ones
unchanged). With Sobol' points the test is made only when each replicate holds a power of two of
points, so every stopping point is a (0, m, s)-net of every replicate.

Sequential stopping is a mild bias: the estimate is most likely to stop when its stderr happens
to be small, so the interval mean ± 1.96 stderr covers the integral slightly less often than 95 %.
`min_n` (default: 8 chunks) keeps that small; the coverage measured over many keys is in
`tests/test_until.py` and the closing note of issue 15.

Integrands follow the rule of `integrand.py` (a pytree of real or complex arrays gives the same
pytree of `EstimateUntil`); the stream stops when every component meets the tolerance, a complex
leaf by the modulus of its stderr against rtol times the modulus of its mean.

Sample indices have 64 bits (`jaxsample.uniforms.index`): past 2^32 points the chunk offsets are
two-word indices. `n_used` is an int32 array, so max_n must be below 2^31 unless
`jax_enable_x64` is on (then it is an int64 array and max_n may reach 2^31 chunks).

Not differentiable: reverse mode cannot go through a while loop, and the number of samples is
itself random. Under `jax.grad` it raises, naming the n to use: differentiate
`jaxsample.estimate(..., n)` with the `n_used` this returned.
"""

from __future__ import annotations

import math
from typing import Callable

import jax
import jax.numpy as jnp

from .._core.counts import check_count
from ..samplers.base import check_unbatched, checked
from .._core.doublefloat import _float64_available
from .._core.numerics import safe_div, safe_sqrt
from .._core.params import check_choice, default_float_dtype, resolve_float_dtype
from .._core.pytree import pytree_dataclass
from ..uniforms import Random, Sobol, as_source, seed_from_key
from ..uniforms.index import MAX_INDEX, NARROW_LIMIT, offset_at
from .diagnostics import MAX_TAIL, largest, pareto_khat, tail_bins, tail_size, verdict, warn_if_unreliable
from .engine import _MAX_STEPS, _chunk_moments, _empty_moments, _lane_values, _merge, _Moments, stderr_floor
from .integrand import integrand_layout
from .plain import packed_values
from .result import interval, interval_quantile

__all__ = ["EstimateUntil", "estimate_until"]


@pytree_dataclass(static=("max_n", "replicates"))
class EstimateUntil:
    """The result of `estimate_until`: an estimate from a data-dependent number of samples.

    `mean`, `stderr`, `variance`, `max_abs`, `ess`, `khat`, `nonzero`, `reliable` and `diagnostics` as in
    `Estimate`; `n_used` (an int32 array, int64 for max_n >= 2^31 under x64: it is known only at run
    time) samples were used; `converged` says whether the tolerance was met (False: `max_n` was
    reached first).
    """

    mean: jax.Array
    stderr: jax.Array
    variance: jax.Array
    max_abs: jax.Array
    ess: jax.Array
    khat: jax.Array
    nonzero: jax.Array
    n_used: jax.Array
    converged: jax.Array
    max_n: int = 0
    replicates: int = 1

    @property
    def reliable(self) -> jax.Array:
        """As `Estimate.reliable`: finite, enough nonzero Y, Pareto k-hat below 0.5."""
        return verdict(self.mean, self.stderr, self.khat, self.nonzero, self.n_used)

    @property
    def diagnostics(self) -> dict:
        """As `Estimate.diagnostics` (`ess_fraction` is ess / n_used)."""
        return {"khat": self.khat, "nonzero": self.nonzero,
                "ess_fraction": self.ess / self.n_used.astype(self.ess.dtype), "reliable": self.reliable}

    @property
    def n(self) -> jax.Array:
        """The samples used (`n_used`), the name `Estimate` gives it."""
        return self.n_used

    def interval(self, level: float = 0.95):
        """mean ± q stderr: q normal for independent points, Student's t with R - 1 degrees of
        freedom for R replicates (see the module docstring on coverage after sequential stopping)."""
        return interval(self.mean, self.stderr, level, self.replicates)


def _statistics(m: _Moments, count, replicates: int):
    """mean, stderr, variance, ess of the moments of `count` points (count traced, a float)."""
    count = count.astype(m.m2.dtype)
    if _float64_available() and m.sums.dtype == jnp.float32:
        with jax.enable_x64(True):
            sums = m.sums.astype(jnp.float64) + m.compensation.astype(jnp.float64)
            per_replicate = sums / (count.astype(jnp.float64) / replicates)
            mean64 = jnp.mean(per_replicate, axis=0)
            spread = jnp.sum((per_replicate - mean64) ** 2, axis=0)
            mean, spread = mean64.astype(jnp.float32), spread.astype(jnp.float32)
    else:
        per_replicate = (m.sums + m.compensation) / (count / replicates)
        mean = jnp.mean(per_replicate, axis=0)
        spread = jnp.sum((per_replicate - mean) ** 2, axis=0)
    variance = m.m2 / jnp.maximum(count - 1.0, 1.0)
    if replicates == 1:
        stderr = safe_sqrt(variance / count)
    else:
        stderr = safe_sqrt(spread / (replicates - 1) / replicates)
    ess = safe_div(m.sum_abs * m.sum_abs, m.m2 + count * mean * mean)
    stderr = jnp.maximum(stderr, stderr_floor(m.sum_abs, count))
    # A NaN or infinite mean (an invalid traced parameter, a non-finite value) has no error bar.
    stderr = jnp.where(jnp.isfinite(mean), stderr, jnp.inf)
    return mean, stderr, variance, ess


def _tail_count(count):
    """`diagnostics.tail_size` of a traced count: min(n / 5, ⌈3 √n⌉, MAX_TAIL), at least 1."""
    m = jnp.minimum(jnp.floor(count / 5.0), jnp.ceil(3.0 * jnp.sqrt(count)))
    return jnp.clip(m, 1, MAX_TAIL).astype(jnp.int32)


def _refuse_gradients(closed_consts):
    for c in closed_consts:
        if type(c).__name__ in ("JVPTracer", "LinearizeTracer"):
            raise TypeError("estimate_until: cannot be differentiated (the number of samples is chosen at "
                            "run time, and reverse mode cannot go through a while loop). Run estimate_until "
                            "outside jax.grad, then differentiate jaxsample.estimate(..., n) with the "
                            "n_used it returned.")


def estimate_until(f: Callable[[jax.Array], jax.Array], sampler, key: jax.Array, *, max_n: int,
                   rtol: float | None = None, atol: float | None = None, min_n: int | None = None,
                   uniforms="random", mode: str = "attached", chunk_size: int | None = None,
                   dtype=None) -> EstimateUntil:
    """∫ f dμ (as `jaxsample.estimate`) with as many samples as it takes for
    stderr <= max(atol, rtol·|mean|) (elementwise over f's value: every component must meet it),
    at most `max_n`.

    Args:
      f, sampler, key, mode, dtype: as in `estimate`.
      max_n: the most samples to use (a multiple of `chunk_size`).
      rtol, atol: relative and absolute tolerances on the standard error (at least one, >= 0).
        With R > 1 replicates (Sobol') the test is t_{R-1} stderr / 1.96 <= tolerance (the spread
        of R means is itself uncertain: Student's t with R - 1 degrees of freedom), so that the
        95 % interval is as wide as with independent points at that tolerance.
      min_n: stop no earlier than this (default 8 chunks; a multiple of `chunk_size`).
      uniforms: "random" (default) or "sobol" (the test is made at power-of-two points per
        replicate); "stratified" needs the total count in advance, so it is refused.
      chunk_size: samples per step of the loop (default min(2^16, max_n)).
    """
    check_choice("estimate_until", "mode", mode, ("attached", "detached"))
    if rtol is None and atol is None:
        raise ValueError("estimate_until: give 'rtol' or 'atol' (a tolerance on the standard error)")
    for name, value in (("rtol", rtol), ("atol", atol)):
        if value is not None and not (isinstance(value, (int, float)) and value >= 0 and math.isfinite(value)):
            raise ValueError(f"estimate_until: parameter '{name}' must be a finite number >= 0; got {value!r}")
    source = as_source(uniforms)
    if not isinstance(source, (Random, Sobol)):
        raise ValueError("estimate_until: parameter 'uniforms' must be 'random' or 'sobol' (stratified "
                         "points need the total count in advance)")
    replicates = source.replicates
    max_n = check_count("estimate_until", "max_n", max_n, minimum=2, maximum=MAX_INDEX)
    count_dtype = jnp.int32
    if max_n > _MAX_STEPS:
        if not jax.config.jax_enable_x64:
            raise ValueError(f"estimate_until: parameter 'max_n' must be below 2^31 ({max_n} given): n_used is an "
                             f"int32 array without jax_enable_x64. Enable x64 (n_used is then int64), or use "
                             f"jaxsample.estimate(..., n) with a fixed n, which takes n up to 2^64")
        count_dtype = jnp.int64
    chunk = (check_count("estimate_until", "chunk_size", chunk_size, minimum=1) if chunk_size is not None
             else min(1 << 16, max_n))
    step = math.lcm(4, replicates)
    if chunk < step or chunk % step or max_n % chunk:
        raise ValueError(f"estimate_until: 'chunk_size' ({chunk}) must be a positive multiple of {step} "
                         f"that divides 'max_n' ({max_n})")
    if max_n // chunk > _MAX_STEPS:
        raise ValueError(f"estimate_until: max_n / chunk_size ({max_n // chunk}) must be below 2^31 (the loop "
                         f"counts chunks in int32); raise 'chunk_size' (now {chunk})")
    min_n = 8 * chunk if min_n is None else check_count("estimate_until", "min_n", min_n, minimum=1)
    if min_n % chunk or min_n < chunk:
        raise ValueError(f"estimate_until: parameter 'min_n' must be a positive multiple of chunk_size ({chunk}); got {min_n}")
    min_n = min(min_n, max_n)
    max_steps, min_steps = max_n // chunk, min_n // chunk
    wide = max_n > NARROW_LIMIT   # offsets past 2^32 are two-word indices
    dtype = resolve_float_dtype("estimate_until", dtype)
    check_unbatched(sampler, "estimate_until")
    sampler = checked(sampler)
    dims = sampler.uniform_dims
    layout = integrand_layout(f, sampler, dtype, "estimate_until")

    def values_fn(u):
        return packed_values(f, sampler, u, mode, boundary=False)[0]

    point = jax.make_jaxpr(lambda one: values_fn(one[None])[0])(jax.ShapeDtypeStruct((dims,), dtype))
    _refuse_gradients(point.consts)
    out_shape = tuple(point.out_avals[0].shape)
    seed = seed_from_key(key)
    rtol_, atol_ = float(rtol or 0.0), float(atol or 0.0)
    # With R replicates the stderr is the spread of R means: the test widens it by t_{R-1} / z, so
    # that the 95 % Student-t interval is no wider than the normal one the tolerance means.
    widening = interval_quantile(0.95, replicates) / interval_quantile(0.95, 1)

    def chunk_moments(steps):
        offset = offset_at(0, steps.astype(jnp.uint32), chunk, wide)
        at = offset if offset.wide else offset.lo
        groups = source.lanes(seed, at, chunk, dims, dtype, total=None, aligned=chunk)
        return _chunk_moments([_lane_values(values_fn, lanes) for lanes in groups], replicates, out_shape, bins)

    per_chunk = chunk // replicates

    def at_net(steps):
        # Sobol': test only when every replicate holds a power of two of points, steps x per_chunk:
        # never if per_chunk is not a power of two, else exactly when the number of steps is one.
        if replicates == 1:
            return jnp.bool_(True)
        if per_chunk & (per_chunk - 1):
            return jnp.bool_(False)
        per = steps
        return (per & (per - 1)) == 0

    def cond(state):
        moments, steps, done = state
        return (~done) & (steps < max_steps)

    def body(state):
        moments, steps, _ = state
        moments = _merge(moments, chunk_moments(steps))
        steps = steps + 1
        mean, stderr, _, _ = _statistics(moments, steps.astype(dtype) * float(chunk), replicates)
        # Sizes compared with the tolerance: |component|, the modulus for both parts of a complex leaf.
        tolerance = jnp.maximum(atol_, rtol_ * layout.magnitudes(mean))
        stderr = layout.magnitudes(stderr) * widening
        met = jnp.all(stderr <= tolerance) & (steps >= min_steps) & at_net(steps)
        return moments, steps, met

    bins = tail_bins(max_n, chunk)
    init = (_empty_moments(replicates, out_shape, dtype, bins), jnp.int32(0), jnp.bool_(False))
    moments, steps, converged = jax.lax.while_loop(cond, body, init)
    used = steps.astype(dtype) * float(chunk)
    mean, stderr, variance, ess = _statistics(moments, used, replicates)
    khat = pareto_khat(largest(moments.tail, tail_size(max_n) + 1), _tail_count(used))
    n_used = steps.astype(count_dtype) * jnp.asarray(chunk, count_dtype)   # int64: x64 is on
    result = EstimateUntil(mean=mean, stderr=stderr, variance=variance, max_abs=moments.max_abs, ess=ess,
                           khat=khat, nonzero=moments.nonzero / jnp.maximum(used, 1.0),
                           n_used=n_used, converged=converged, max_n=max_n, replicates=replicates)
    result = layout.unpack_result(result)
    warn_if_unreliable(result, "estimate_until")
    return result
