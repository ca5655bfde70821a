"""Estimates to a requested accuracy: `estimate_until`.

Users ask for "this integral to three digits", not "with 2^20 samples". `estimate_until` streams
chunks of samples through the engine's chunk step (`engine.py`: the same counter-based points as
`estimate`, sample i depending only on the key and i) inside a `lax.while_loop`, finishes the
statistics with the engine's finishing step after every chunk, and stops as soon as the standard
error is at most max(atol, rtol·|mean|), or when `max_n` samples are used. So it returns, for the
n_used it stopped at, what `estimate(..., n_used, chunk_size=...)` returns for the random source.
It runs under `jit` and `vmap` (each batch member stops on its own; under vmap the loop runs until
all have stopped, the stopped ones unchanged), on a batched sampler (each member stops on its own)
and over a device mesh (`mesh=`: every step draws one chunk on each device, and the stopping test
sees all of them). With Sobol' (or lattice) points the test is made only when each replicate
holds a power of two of points, so every stopping point is a (0, m, s)-net (a lattice rule) of
every replicate; Halton prefixes are tested after every step.

Sequential stopping is a mild bias: the estimate is most likely to stop when its stderr happens
to be small, so the interval mean ± 1.96 stderr covers the integral slightly less often than 95 %.
`min_n` (default: 8 chunks) keeps that small; the coverage measured over many keys is in
`tests/estimators/test_until.py`.

Integrands follow the rule of `integrand.py` (a pytree of real or complex arrays gives the same
pytree of `EstimateUntil`); the stream stops when every component meets the tolerance, a complex
leaf by the modulus of its stderr against rtol times the modulus of its mean.

Sample indices have 64 bits (`jaxsample.uniforms.index`): past 2^32 points the chunk offsets are
two-word indices. `n_used` is an int32 array, so max_n must be below 2^31 unless
`jax_enable_x64` is on (then it is an int64 array and max_n may reach 2^31 chunks).

The stopping test here is statistical. For lattices and digitally shifted Sobol' nets,
`estimate_guaranteed` (`guaranteed.py`) stops instead on a deterministic bound for integrands in a
cone of smooth functions (Hickernell & Jiménez Rugama 2016); it runs on the host, not under `jit`.

Not differentiable: reverse mode cannot go through a while loop, and the number of samples is
itself random. Under `jax.grad` (or `jax.jvp`) it raises, naming the n to use: differentiate
`jaxsample.estimate(..., n)` with the `n_used` this returned.
"""

from __future__ import annotations

import math
from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np

from .._core.counts import check_count
from .._core.entry import compiled_entry
from ..samplers.base import check_sampler, check_uniforms, checked
from .._core.params import resolve_float_dtype
from .._core.pytree import static_field
from ..uniforms import Halton, Lattice, Random, Sobol, as_source, seed_from_key
from ..uniforms.index import MAX_INDEX, NARROW_LIMIT, offset_at
from .diagnostics import tail_bins, verdict
from .engine import (MAX_STEPS, check_chunk_size, chunk_step, empty_moments, merge_moments, combine_devices, finish,
                     shard_over)
from .integrand import integrand_layout
from .plain import check_mode, over_batch, packed_values
from .result import Statistics, interval, interval_quantile

__all__ = ["EstimateUntil", "estimate_until"]


class EstimateUntil(Statistics):
    """The result of `estimate_until`: an estimate from a data-dependent number of samples.

    `mean`, `stderr`, `variance`, `max_abs`, `ess`, `khat`, `nonzero`, `reliable` and `diagnostics` as in
    `Estimate`; `n_used` (an int32 array, int64 for max_n >= 2^31 under x64: it is known only at run
    time) samples were used; `converged` says whether the tolerance was met (False: `max_n` was
    reached first).
    """

    n_used: jax.Array
    converged: jax.Array
    max_n: int = static_field(default=0)
    replicates: int = static_field(default=1)

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


_NOT_DIFFERENTIABLE = ("estimate_until: cannot be differentiated (the number of samples is chosen at run time, "
                       "and reverse mode cannot go through a while loop). Run estimate_until outside jax.grad, "
                       "then differentiate jaxsample.estimate(..., n) with the n_used it returned.")


@jax.custom_jvp
def _refuse_derivatives(tree):
    """`tree` itself; differentiating through it is a TypeError (under `jit` too: the rule runs
    when the derivative is traced). Inputs whose derivative is zero never reach the rule."""
    return tree


@_refuse_derivatives.defjvp
def _refuse_derivatives_jvp(primals, tangents):
    raise TypeError(_NOT_DIFFERENTIABLE)


def _refuse_closed_over(closed_consts):
    """TypeError for an integrand that closes over a value being differentiated."""
    for c in closed_consts:
        if type(c).__name__ in ("JVPTracer", "LinearizeTracer"):
            raise TypeError(_NOT_DIFFERENTIABLE)


def _check_tolerances(rtol, atol, owner: str = "estimate_until",
                      what: str = "the standard error") -> tuple[float, float]:
    if rtol is None and atol is None:
        raise ValueError(f"{owner}: give 'rtol' or 'atol' (a tolerance on {what})")
    numbers = {}
    for name, value in (("rtol", rtol), ("atol", atol)):
        number = _real_number(value)
        if value is not None and not (number is not None and number >= 0 and math.isfinite(number)):
            raise ValueError(f"{owner}: parameter '{name}' must be a finite number >= 0; got {value!r}")
        numbers[name] = number or 0.0
    return numbers["rtol"], numbers["atol"]


def _real_number(value) -> float | None:
    """`value` as a float if it is a concrete real number (Python, NumPy or a JAX array of shape ()),
    else None; a bool is not a tolerance."""
    if isinstance(value, (bool, np.bool_)) or isinstance(value, jax.core.Tracer):
        return None
    if isinstance(value, (int, float, np.integer, np.floating)):
        return float(value)
    if isinstance(value, (jax.Array, np.ndarray)) and value.shape == () and value.dtype.kind in "iuf":
        return float(value)
    return None


@compiled_entry("f", "max_n", "rtol", "atol", "min_n", "uniforms", "mode", "mesh", "chunk_size", "dtype")
def estimate_until(f: Callable[[jax.Array], jax.Array], sampler, key: jax.Array, *, max_n: int,
                   rtol: float | None = None, atol: float | None = None, min_n: int | None = None,
                   uniforms="random", mode: str = "attached", mesh=None, chunk_size: int | None = None,
                   dtype=None) -> EstimateUntil:
    """∫ f dμ (as `jaxsample.estimate`) with as many samples as it takes for
    stderr <= max(atol, rtol·|mean|) (elementwise over f's value: every component must meet it),
    at most `max_n`.

    Args:
      f, sampler, key, mode, dtype: as in `estimate`. A sampler with a `batch_shape` gives an
        `EstimateUntil` with that leading shape: each member stops on its own (`jax.vmap` over
        the members, all drawing with the same key).
      max_n: the most samples to use (a multiple of `chunk_size` x the mesh's devices).
      rtol, atol: relative and absolute tolerances on the standard error (at least one, >= 0).
        With R > 1 replicates (Sobol') the test is t_{R-1} stderr / 1.96 <= tolerance (the spread
        of R means is itself uncertain: Student's t with R - 1 degrees of freedom), so that the
        95 % interval is as wide as with independent points at that tolerance.
      min_n: stop no earlier than this (default 8 steps; a multiple of `chunk_size` x devices).
      uniforms: "random" (default), "sobol" or "lattice" (the test is made at power-of-two points
        per replicate: only there is each replicate a net or a lattice rule), or "halton" (tested
        after every step); "stratified" and "lhs" need the total count in advance, so they are refused.
      mesh: a `jax.sharding.Mesh`; every step draws the next chunk of the stream on each of its
        devices (step s, device d: chunk s x devices + d), so the points used are the first
        n_used of the stream, as without a mesh.
      chunk_size: samples per step of the loop and device (default min(2^16, max_n / devices)).
    """
    owner = "estimate_until"
    check_mode(owner, mode)
    rtol_, atol_ = _check_tolerances(rtol, atol)
    check_sampler(owner, "sampler", sampler)
    if sampler.batch_shape:
        return over_batch(lambda member, k: estimate_until(f, member, k, max_n=max_n, rtol=rtol, atol=atol,
                                                           min_n=min_n, uniforms=uniforms, mode=mode, mesh=mesh,
                                                           chunk_size=chunk_size, dtype=dtype),
                          sampler, key, owner)
    check_uniforms(sampler, uniforms, owner)
    source = as_source(uniforms)
    if not isinstance(source, (Random, Sobol, Lattice, Halton)):
        raise ValueError("estimate_until: parameter 'uniforms' must be 'random', 'sobol', 'lattice' or 'halton' "
                         "(stratified and Latin hypercube points need the total count in advance)")
    replicates = source.replicates
    # Sobol' nets and extensible lattices are whole rules only at powers of two per replicate;
    # every prefix of a Halton sequence is as good as any other count.
    powers_of_two = isinstance(source, (Sobol, Lattice))
    devices = 1 if mesh is None else mesh.size
    max_n = check_count(owner, "max_n", max_n, minimum=2, maximum=MAX_INDEX)
    count_dtype = jnp.int32
    if max_n > MAX_STEPS:
        if not jax.config.jax_enable_x64:
            raise ValueError(f"estimate_until: parameter 'max_n' must be below 2^31 ({max_n} given): n_used is an "
                             f"int32 array without jax_enable_x64. Enable x64 (n_used is then int64), or use "
                             f"jaxsample.estimate(..., n) with a fixed n, which takes n up to 2^64")
        count_dtype = jnp.int64
    chunk = check_chunk_size(owner, max(1, min(1 << 16, max_n // devices)) if chunk_size is None else chunk_size,
                              replicates)
    step = chunk * devices    # the samples of one step of the loop
    if max_n % step:
        across = "" if devices == 1 else f" x {devices} devices"
        raise ValueError(f"estimate_until: 'chunk_size' ({chunk}){across} must be a positive multiple of "
                         f"{math.lcm(4, replicates)} that divides 'max_n' ({max_n})")
    if max_n // step > MAX_STEPS:
        raise ValueError(f"estimate_until: max_n / chunk_size ({max_n // step}) must be below 2^31 (the loop "
                         f"counts chunks in int32); raise 'chunk_size' (now {chunk})")
    min_n = 8 * step if min_n is None else check_count(owner, "min_n", min_n, minimum=1)
    if min_n % step or min_n < step:
        raise ValueError(f"estimate_until: parameter 'min_n' must be a positive multiple of chunk_size ({chunk})"
                         + ("" if devices == 1 else f" x {devices} devices") + f"; got {min_n}")
    min_n = min(min_n, max_n)
    max_steps, min_steps = max_n // step, min_n // step
    wide = max_n > NARROW_LIMIT   # offsets past 2^32 are two-word indices
    dtype = resolve_float_dtype(owner, dtype)
    sampler = checked(_refuse_derivatives(sampler))
    dims = sampler.uniform_dims
    layout = integrand_layout(f, sampler, dtype, owner)

    def values_fn(u):
        return packed_values(f, sampler, u, mode, boundary=False)[0]

    point = jax.make_jaxpr(lambda one: values_fn(one[None])[0])(jax.ShapeDtypeStruct((dims,), dtype))
    _refuse_closed_over(point.consts)
    out_shape = tuple(point.out_avals[0].shape)
    seed = seed_from_key(key)
    # With R replicates the stderr is the spread of R means: the test widens it by t_{R-1} / z, so
    # that the 95 % Student-t interval is no wider than the normal one the tolerance means.
    widening = interval_quantile(0.95, replicates) / interval_quantile(0.95, 1)
    per_step = step // replicates   # points of each replicate per step
    bins = tail_bins(max_n, chunk)
    axes = () if mesh is None else tuple(mesh.axis_names)

    def used(steps):
        return steps.astype(count_dtype) * jnp.asarray(step, count_dtype)

    def at_net(steps):
        # Sobol': test only when every replicate holds a power of two of points, steps x per_step:
        # never if per_step is not a power of two, else exactly when the number of steps is one.
        if replicates == 1 or not powers_of_two:
            return jnp.bool_(True)
        if per_step & (per_step - 1):
            return jnp.bool_(False)
        return (steps & (steps - 1)) == 0

    def loop(seed):
        device = None if mesh is None else jax.lax.axis_index(axes).astype(jnp.uint32)

        def step_moments(steps):
            index = steps.astype(jnp.uint32)
            if mesh is not None:
                index = index * jnp.uint32(devices) + device
            m = chunk_step(values_fn, source, seed, dims, dtype, offset_at(0, index, chunk, wide), chunk, out_shape,
                       bins, total=None, aligned=chunk)
            return m if mesh is None else combine_devices(m, axes, chunk, step, dtype)

        def cond(state):
            moments, steps, done = state
            return (~done) & (steps < max_steps)

        def body(state):
            moments, steps, _ = state
            moments = merge_moments(moments, step_moments(steps))
            steps = steps + 1
            statistics = finish(moments, used(steps), replicates, most=max_n)
            # Sizes compared with the tolerance: |component|, the modulus for both parts of a complex leaf.
            tolerance = jnp.maximum(atol_, rtol_ * layout.magnitudes(statistics["mean"]))
            stderr = layout.magnitudes(statistics["stderr"]) * widening
            met = jnp.all(stderr <= tolerance) & (steps >= min_steps) & at_net(steps)
            return moments, steps, met

        init = (empty_moments(replicates, out_shape, dtype, bins * devices), jnp.int32(0), jnp.bool_(False))
        return jax.lax.while_loop(cond, body, init)

    moments, steps, converged = loop(seed) if mesh is None else shard_over(mesh, loop, seed)
    n_used = used(steps)
    result = EstimateUntil(**finish(moments, n_used, replicates, most=max_n), n_used=n_used,
                           converged=converged, max_n=max_n, replicates=replicates)
    return layout.unpack_result(result)
