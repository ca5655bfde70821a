"""Layer 4: the streaming engine behind every estimator: ∫ f dμ ≈ (1/n) Σ f(x_i) / p(x_i), in constant memory.

`run_stream` averages per-sample values over a counter-based uniform stream; `estimate(f, sampler,
key, n)` (`plain.py`) draws x_i = sampler.warp(u_i) from a uniform source
(`jaxsample.uniforms`), averages Y_i = f(x_i)/p(x_i) (0 where p = 0, in value and gradient) and
returns an `Estimate` with the mean, its standard error and diagnostics. Every estimator is built
from the same pure pieces, an (init, update, finish) triple over the moments: `empty_moments` (init),
`chunk_step` (the moments of one chunk of the stream) folded in by `merge_moments` (update),
`combine_devices` (the moments of a device mesh) and `finish` (mean, stderr with its floor, variance,
ess, k-hat and the nonzero fraction from the moments), which `run_stream` calls once and
`estimate_until` (`until.py`) after every chunk of its while loop.

Streaming: the n samples are processed in chunks of `chunk_size` inside `lax.scan`, so memory does
not grow with n. Sample indices have 64 bits (`jaxsample.uniforms.index`): a stream of more than
2^32 points carries its chunk offsets as two uint32 words; shorter streams keep the uint32
offsets, and so the very program, of a 32-bit counter. The point with global index i is the same
whatever the chunk size, the device count or the jit/vmap context (counter-based sources), so the
estimate changes only by float rounding between chunkings and shardings.

Accumulation, and why it is careful: within a chunk the sums are taken in a tree of blocks of
`_BLOCK` values (error ~ (log n) ε rather than n ε); across chunks the running sums are
compensated (TwoSum: the rounding error of each addition is kept), and the sum of squared deviations M2 is
merged by Chan, Golub & LeVeque's pairwise update M2 = M2_a + M2_b + δ² n_a n_b / n (Chan et al.
1979). For a constant integrand every chunk sum is exact and so is the mean, for any n. With
replicates (Sobol', stratified) the per-replicate sums are kept in double-float (hi + lo,
`jaxsample._core.doublefloat`), and every mean is divided in double-float before it is rounded: the
stderr is the spread of the replicate means, which for Sobol' points drops below a float32 ulp of
the mean (means rounded first would give a stderr of 0).

Speed: the per-sample work (warp, density, f) is evaluated on one array per coordinate
(`jaxsample._core.lanes`), so XLA fuses it into one loop however f is written (`x @ a`, `jnp.sum(x * a)`,
components); the g points a generator call yields (two 2-d points per Philox block) are computed
in that loop and stored once per chunk (`jaxsample._core.computed_once`), so the generator runs once
per block. Both are for XLA's CPU backend, where they were measured; elsewhere, or with
JAXSAMPLE_LANES=0, the per-sample work is `jax.vmap`-ed and nothing is packed (`jaxsample._core.cpu_paths`).

Standard error: with independent points (the "random" source) it is sqrt(s²/n), s² the sample
variance of Y. With R > 1 replicates (stratified, Sobol'), points within a replicate are
dependent; the stderr is then the standard deviation of the R replicate means over sqrt(R).

Gradients (`mode`, Zeltner et al. 2021): "attached" differentiates through the sample and its
density (pathwise); "detached" applies `stop_gradient` to the sample and its density *together*,
so only f carries the derivative. The derivative of a stream is a second forward stream
(`_differentiable_stream`): the sums of the per-point sensitivities ∂Y/∂θ_k, one per moving
coordinate, computed by forward mode on the lanes; it needs no residuals and no reverse pass
through the loop, so its memory does not grow with n, and it costs about one JVP of the per-point
program. With many moving coordinates (more than `FORWARD_WIDTH`, or a device mesh) the loop is
differentiated as written, its chunks `jax.checkpoint`ed: reverse mode recomputes a chunk instead
of storing it.
"""

from __future__ import annotations

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np

from .._core.counts import check_count
from .._core.params import resolve_float_dtype
from .._core.pytree import Pytree
from .._core import doublefloat
from .._core.computed_once import computed_once, stored_once
from .._core.lanes import lane_map
from jax.custom_derivatives import SymbolicZero
from jax.extend.core import ClosedJaxpr, jaxpr_as_fun
from .._core.numerics import safe_div, safe_sqrt
from ..uniforms import Source, as_source, seed_from_key
from ..uniforms.index import MAX_INDEX, NARROW_LIMIT, Index, offset_at, token
from .diagnostics import ROUNDING_ULPS, chunk_tail, empty_tail, largest, merge_tails, pareto_khat, tail_bins, tail_size
from .result import Estimate

__all__ = ["run_stream", "tree_sum", "DEFAULT_CHUNK_SIZE"]

DEFAULT_CHUNK_SIZE = 1 << 16
_BLOCK = 256


# ----------------------------------------------------------------------------------------------
# Accumulation
# ----------------------------------------------------------------------------------------------


def tree_sum(values: jax.Array) -> jax.Array:
    """Sum over axis 0 in a tree of blocks of `_BLOCK` (zero-padded): error ~ log_B(n) levels."""
    while values.shape[0] > _BLOCK:
        length = values.shape[0]
        padded = -(-length // _BLOCK) * _BLOCK
        if padded != length:
            pad = [(0, padded - length)] + [(0, 0)] * (values.ndim - 1)
            values = jnp.pad(values, pad)
        values = values.reshape((padded // _BLOCK, _BLOCK) + values.shape[1:]).sum(axis=1)
    return values.sum(axis=0)


class _Moments(Pytree):
    """Running statistics of a stream: per-replicate compensated sums, M2, max |Y|, Σ|Y|, the
    largest |Y| (the tail the diagnostics fit), the count of nonzero Y, count."""

    sums: jax.Array          # (R, *out): Σ Y per replicate (high part)
    compensation: jax.Array  # (R, *out): the low part lost by the additions (TwoSum)
    m2: jax.Array            # (*out): Σ (Y - mean)²
    max_abs: jax.Array
    sum_abs: jax.Array
    tail: jax.Array          # (2, bins, *out): the two largest |Y| of each bin (diagnostics.py)
    nonzero: jax.Array       # (*out): how many Y are nonzero (a float)
    count: jax.Array         # float: exact for the chunk multiples we use


def _chunk_moments(groups: tuple[jax.Array, ...], replicates: int, out_shape, bins: int,
                   diagnostics: bool = True) -> _Moments:
    """Statistics of one chunk given as g arrays of values (*lanes, *out) (see Source.lanes:
    group q holds the points g b + q of the chunk, b the C-order index over the lanes), with the
    tail state of the diagnostics in `bins` bins (`diagnostics=False`, for measuring their cost only: no tail,
    every Y counted nonzero; "sums": the per-replicate sums only, M2 and the rest 0).

    With replicates R > 1, g divides R and the chunk's offset is a multiple of R.
    """
    out_shape = tuple(out_shape)
    groups = [y.reshape((-1,) + out_shape) for y in groups]
    first = groups[0]
    g = len(groups)
    count = first.shape[0] * g
    if replicates > 1:
        # Replicate means are compared with each other (their spread is the stderr), so they are
        # summed in double-float: see jaxsample._core.doublefloat. Group q holds the points g b + q of
        # a chunk whose offset is a multiple of R (and g divides R): replicates q, q + g, ...
        width = replicates // g
        parts = [doublefloat.sum_axis0(y.reshape((count // replicates, width) + out_shape)) for y in groups]
        per_replicate, low = (jnp.stack([part[i] for part in parts], axis=1)
                              .reshape((replicates,) + out_shape) for i in (0, 1))
    else:
        per_replicate = tree_sum(sum(groups))[None]
        low = jnp.zeros_like(per_replicate)
    if diagnostics == "sums":
        # The sums alone (the forward derivative's stream: `_differentiable_stream`).
        zeros = jnp.zeros(out_shape, first.dtype)
        return _Moments(per_replicate, low, zeros, zeros, zeros, empty_tail(out_shape, first.dtype, bins),
                        jnp.full(out_shape, float(count), first.dtype), jnp.asarray(count, first.dtype))
    chunk_mean = per_replicate.sum(axis=0) / count
    m2 = tree_sum(sum((y - chunk_mean) * (y - chunk_mean) for y in groups))
    max_abs = functools.reduce(jnp.maximum, [jnp.max(jnp.abs(y), axis=0) for y in groups])
    if diagnostics:
        tail = functools.reduce(merge_tails, [chunk_tail(y, bins) for y in groups])
        nonzero = sum(jnp.sum(jax.lax.stop_gradient(y) != 0, axis=0, dtype=first.dtype) for y in groups)
    else:
        tail = empty_tail(out_shape, first.dtype, bins)
        nonzero = jnp.full(out_shape, float(count), first.dtype)
    return _Moments(
        sums=per_replicate,
        compensation=low,
        m2=m2,
        max_abs=max_abs,
        sum_abs=tree_sum(sum(jnp.abs(y) for y in groups)),
        tail=tail,
        nonzero=nonzero,
        count=jnp.asarray(count, first.dtype),
    )


def merge_moments(a: _Moments, b: _Moments) -> _Moments:
    """Chan et al. (1979) pairwise merge of M2; compensated sums; a.count may be 0."""
    count = a.count + b.count
    mean_a = jnp.sum(a.sums + a.compensation, axis=0) / jnp.maximum(a.count, 1.0)
    mean_b = jnp.sum(b.sums + b.compensation, axis=0) / b.count
    delta = mean_b - mean_a
    m2 = a.m2 + b.m2 + delta * delta * (a.count * b.count / count)
    sums, lost = doublefloat.two_sum(a.sums, b.sums)
    compensation = a.compensation + b.compensation + lost
    return _Moments(sums, compensation, m2, jnp.maximum(a.max_abs, b.max_abs),
                    a.sum_abs + b.sum_abs, merge_tails(a.tail, b.tail), a.nonzero + b.nonzero, count)


def empty_moments(replicates: int, out_shape, dtype, bins: int) -> _Moments:
    zeros = jnp.zeros((replicates,) + out_shape, dtype)
    scalar = jnp.zeros(out_shape, dtype)
    return _Moments(zeros, zeros, scalar, scalar, scalar, empty_tail(out_shape, dtype, bins), scalar,
                    jnp.zeros((), dtype))


def stderr_floor(sum_abs, count):
    """The float rounding of the values averaged: `ROUNDING_ULPS` ulps of mean |Y| = sum_abs / count
    (see `diagnostics.py`); the stderr is never reported below it."""
    return ROUNDING_ULPS * float(jnp.finfo(sum_abs.dtype).eps) * (sum_abs / count)


def _divide_by_count(x: tuple[jax.Array, jax.Array], count):
    """(hi, lo) / count in double-float: `doublefloat.divide_by_int` for a Python int; for a traced
    integer (`estimate_until`'s count, known only at run time) the same steps, with count split
    as d_hi + d_lo at run time (d_lo from the unsigned difference, which does not overflow when
    d_hi rounds up to 2^31)."""
    if isinstance(count, int):
        return doublefloat.divide_by_int(x, count)
    hi, lo = x
    dtype = hi.dtype
    unsigned = jnp.uint32 if count.dtype.itemsize == 4 else jnp.uint64
    d_hi = count.astype(dtype)
    d_lo = jax.lax.bitcast_convert_type(count.astype(unsigned) - d_hi.astype(unsigned), count.dtype).astype(dtype)
    q1 = hi / d_hi
    if dtype != jnp.float32:
        return doublefloat.two_sum(q1, ((hi - q1 * d_hi) - q1 * d_lo + lo) / d_hi)
    p, e = doublefloat.two_prod(q1, d_hi)
    r = (((hi - p) - e) + lo) - q1 * d_lo
    return doublefloat.two_sum(q1, r / d_hi)


@jax.custom_jvp
def _finite_or(finite, compensated, plain):
    """`compensated` where the stream's sums are finite, else `plain` (the IEEE verdict)."""
    return jnp.where(finite, compensated, plain)


@_finite_or.defjvp
def _finite_or_jvp(primals, tangents):
    # The derivative of the mean is the compensated form's whatever `finite` says (a non-finite
    # mean has no derivative to give, and its tangent is then not finite either). Not reading
    # `finite` keeps the gradient of a mean from needing the value's stream at all: the forward
    # derivative stream (`_differentiable_stream`) is then the whole gradient program, and XLA
    # drops the value's loop.
    return _finite_or(*primals), tangents[1]


def finish(m: _Moments, count, replicates: int, most: int | None = None) -> dict:
    """The statistics of a stream from its moments: the one finishing step of every estimator
    (`run_stream`, and `estimate_until` after its loop and at every stopping test).

    `count`: the points summed, a Python int, or a traced integer array when the count is known
    only at run time (`estimate_until`; `most` is then the largest it can be, which sizes the tail
    the diagnostics fit). Returns the fields of `Estimate` that have f's shape (`mean`, `stderr`,
    `variance`, `max_abs`, `ess`, `khat`, `nonzero`); the caller adds the count it reports.
    """
    static = isinstance(count, int)
    dtype = m.m2.dtype
    # Every mean is formed in double-float (sums and compensations as hi + lo), divided before
    # it is rounded; with replicates the spread is taken from the hi + lo means, whose differences
    # are far below a float32 ulp of the mean once Sobol' points converge.
    replicate_hi, replicate_lo = _divide_by_count((m.sums, m.compensation), count // replicates)
    # n as a float: a Python int beyond 2^31 in array arithmetic overflows JAX's weak int32.
    n = float(count) if static else count.astype(dtype)
    total = doublefloat.sum_axis0(replicate_hi, leaf=1)
    mean_hi, mean_lo = doublefloat.divide_by_int(
        (total[0], total[1] + jnp.sum(replicate_lo, axis=0)), replicates)
    # A non-finite Y (f returned ±inf or NaN, or the sum overflowed) makes the compensation
    # inf - inf = NaN; the plain sum of the high parts is then the IEEE verdict (±inf, or NaN
    # for a NaN value or infinities of both signs), and the error bars are unbounded.
    plain_total = jnp.sum(m.sums, axis=0)
    finite = jnp.all(jnp.isfinite(m.sums), axis=0)
    mean = _finite_or(finite, mean_hi + mean_lo, plain_total / n)
    variance = m.m2 / (max(n - 1, 1) if static else jnp.maximum(n - 1.0, 1.0))
    if replicates == 1:
        stderr = safe_sqrt(variance / n)
    else:
        spread = (replicate_hi - mean_hi) + (replicate_lo - mean_lo)
        stderr = safe_sqrt(jnp.sum(spread * spread, axis=0) / (replicates - 1) / replicates)
    sum_squares = m.m2 + n * mean * mean
    ess = jnp.where(finite, safe_div(m.sum_abs * m.sum_abs, sum_squares), 0.0)
    variance = jnp.where(finite, variance, jnp.inf)
    stderr = jnp.maximum(stderr, stderr_floor(m.sum_abs, n))
    stderr = jnp.where(finite, stderr, jnp.inf)
    keep = tail_size(count if most is None else most) + 1
    return dict(mean=mean, stderr=stderr, variance=variance, max_abs=m.max_abs, ess=ess,
                khat=pareto_khat(largest(jax.lax.stop_gradient(m.tail), keep), tail_size(count)), nonzero=m.nonzero / n)


# ----------------------------------------------------------------------------------------------
# The streaming engine: values_fn(u) -> Y, summed over [base, base + count) in chunks
# ----------------------------------------------------------------------------------------------


def _hoist_traced(fn, example):
    """(point, consts): fn(x) == point(x, *consts), with consts every tracer fn closes over.

    `jax.closure_convert` hoists only the float tracers; a traced integer, bool or key stays a
    constant of the per-point jaxpr, and the lazily traced JVP rule of `group_values` would meet
    it outside its trace (a `jit(grad(...))` whose integrand closes over a traced int failed with
    "No constant handler"). Here every tracer becomes an argument; concrete constants stay.
    """
    closed, out_shape = jax.make_jaxpr(fn, return_shape=True)(example)
    out_tree = jax.tree.structure(out_shape)
    traced = [isinstance(c, jax.core.Tracer) for c in closed.consts]

    def point(x, *hoisted):
        it = iter(hoisted)
        consts = [next(it) if t else c for c, t in zip(closed.consts, traced)]
        return jax.tree.unflatten(out_tree, jaxpr_as_fun(ClosedJaxpr(closed.jaxpr, consts))(x))

    return point, [c for c, t in zip(closed.consts, traced) if t]


def group_values(values_fn, groups, tok, stored: bool, derivative_fn=None):
    """values_fn on every group of lanes (d arrays of one shape, the points in C order), with a
    derivative rule of its own. Each group's result is a tuple of columns: the elements of
    values_fn's output shape in C order, one array of the lanes' shape each (`lane_map`'s
    `columns`: never stacked into a (points, *out) array inside the program's loop).

    `values_fn` is elementwise over the points, so values_fn(u[None])[0] is its per-point form;
    `lanes.lane_map` evaluates that on one array per coordinate, which XLA fuses into one loop
    whatever shape of program the integrand is (see `jaxsample._core.lanes` for why vmap is not).
    The values' derivative with respect to what values_fn closes over (the sampler's parameters,
    f's) is the JVP of the same lanes program evaluated on the chunk's uniforms stored once
    (`computed_once`). Differentiated,
    the chunk is recomputed in the backward pass, where each residual of the warp is a consumer
    of the uniforms of its own, and XLA's CPU fusion copies the generator into every one of them
    (seen in the optimized HLO of `jax.grad` of the 3-lobe environment estimate of
    `benchmarks/compile_and_outputs.py`: 8 Philox copies in the backward loop, 2 with this rule).
    The values are the lanes program's bit for bit, the tangents to float rounding (fusion may
    contract a multiply-add differently).

    `stored`: the lanes are already stored once (many outputs). `derivative_fn`: a function of the
    same values whose derivative is the one to take (values_fn plus surrogates of value 0, such as
    `shade`'s boundary term); only the derivative evaluates it, so the value never pays for it.
    """
    sizes = [len(lanes) for lanes in groups]
    flat = [lane for lanes in groups for lane in lanes]
    shape = flat[0].shape

    def regroup(flat):
        it = iter(flat)
        return [tuple(next(it) for _ in range(k)) for k in sizes]

    example = jnp.zeros((sizes[0],), flat[0].dtype)

    def lanes_program(fn):
        """fn's lanes program as a replayable jaxpr, with every traced value fn closes over as an
        argument (traced once, on one point; the rule below needs it again)."""
        point, consts = _hoist_traced(lambda one: fn(one[None])[0], example)

        def by_lanes(flat, consts, tok):
            return [lane_map(lambda one: point(one, *consts), shape, token=tok, columns=True)(lanes)
                    for lanes in regroup(flat)]

        return by_lanes, consts, point

    by_lanes, consts, point = lanes_program(values_fn)
    d_by_lanes, d_consts, d_point, refusal = by_lanes, consts, point, None
    if derivative_fn is not None:
        try:
            d_by_lanes, d_consts, d_point = lanes_program(derivative_fn)
        except ValueError as error:
            # A derivative the caller refuses (no way to make it unbiased) is an error when it is
            # asked for, not when the value is.
            refusal, d_consts = error, []
    if not any(jnp.issubdtype(c.dtype, jnp.inexact) for c in list(consts) + list(d_consts)):
        return by_lanes(flat, consts, tok)  # nothing values_fn reads can carry a derivative
    lanes_jaxpr, out_tree = jax.make_jaxpr(by_lanes, return_shape=True)(flat, list(consts), tok)
    out_tree = jax.tree_util.tree_structure(out_tree)
    replay = lambda flat, consts, tok: jax.tree_util.tree_unflatten(
        out_tree, jaxpr_as_fun(lanes_jaxpr)(*flat, *consts, tok))

    @jax.custom_jvp
    def values(flat, tok, consts, d_consts):
        return replay(flat, consts, tok)

    def values_jvp(primals, tangents):
        flat, tok, consts, d_consts = primals
        once = flat if stored else computed_once(flat, tok)
        # The derivative program reads everything values_fn reads (the same closure): its
        # constants' tangents are the derivative, and the value's own constants' are not needed.
        if refusal is not None:
            raise refusal
        if derivative_fn is None:
            d_consts, d_tangents = consts, tangents[2]
        else:
            d_tangents = tangents[3]
        # Only the constants with a tangent are differentiated: a zero tangent pushed through a
        # partial derivative that is infinite at some sample (sqrt or a fractional power at 0,
        # arccos at ±1) would be 0 · inf = NaN in the output tangent.
        live = [not isinstance(t, SymbolicZero) for t in d_tangents]
        moving = [c for c, m in zip(d_consts, live) if m]
        per_point = math.prod(jax.eval_shape(lambda: d_point(example, *d_consts)).shape)
        width = sum(int(np.size(c)) for c in moving) * per_point
        if 0 < width <= FORWARD_WIDTH and all(jnp.issubdtype(jnp.result_type(c), jnp.floating) for c in moving):
            d_out = _forward_tangents(d_point, example, d_consts, live, once,
                                      [t for t, m in zip(d_tangents, live) if m], regroup, shape, tok)
            return replay(flat, consts, tok), d_out

        def on_live(moving):
            it = iter(moving)
            program = replay if derivative_fn is None else d_by_lanes
            return program(once, [next(it) if m else c for c, m in zip(d_consts, live)], tok)

        _, d_out = jax.jvp(on_live, ([c for c, m in zip(d_consts, live) if m],),
                           ([t for t, m in zip(d_tangents, live) if m],))
        return replay(flat, consts, tok), d_out

    values.defjvp(values_jvp, symbolic_zeros=True)
    return values(flat, tok, list(consts), [] if derivative_fn is None else list(d_consts))


# The derivative is pushed forward along every coordinate of the moving constants while they times
# the values per point are at most this many (`_differentiable_stream`, `_forward_tangents`); past it,
# one reverse sweep per point is cheaper: `benchmarks/compile_and_outputs.py` times both ways for
# spherical-harmonics projections of 9 and 16 values per point and for one value per point.
FORWARD_WIDTH = 8


def _forward_tangents(point, example, consts, live, once, tangents, regroup, shape, tok):
    """The tangent of the lanes program, Σ_k t_k S_k, with S_k = ∂Y/∂c_k the per-point
    sensitivities to the k-th coordinate of the moving constants, computed by forward mode (the
    per-point JVP along each coordinate, on the lanes) and stored once per chunk.

    Why. The JVP rule of `group_values` is linear in the tangents; under reverse mode JAX
    transposes it, and each primal value that transposition needs becomes its own loop in XLA's CPU
    fusion, each recomputing the warp from the uniforms (for BRDF-sampled `shade`, some 20 loops of
    170-320 operations per group: `docs/xla-cpu-paths.md`). Here the
    residuals are the few arrays S_k, computed together in loops that share the warp (pairs packed by
    `computed_once`), and the transposed rule is a sum of products with them. Worth it while
    the moving coordinates are few (one per scalar parameter differentiated: an exponent, the
    three of a light's centre); with more, `group_values` keeps the plain rule."""
    out_size = math.prod(jax.eval_shape(lambda: point(example, *consts)).shape)

    def sensitivities(one, *values):
        s = _pushforward(point, one, values, live)
        return tuple(s.reshape(-1)[i] for i in range(s.size))

    per_group = [lane_map(lambda one: sensitivities(one, *consts), shape, token=tok)(lanes) for lanes in regroup(once)]
    stored = iter(computed_once([a for group in per_group for a in group], tok, alone=True))
    t = _ravel(tangents)[0]
    k = t.size
    out = []
    for group in per_group:
        # S is (*out, k) per point, its elements in C order: output column j is Σ_i S[j, i] t_i.
        s = [next(stored) for _ in group]
        out.append(tuple(sum(s[j * k + i] * t[i].astype(s[0].dtype) for i in range(k)) for j in range(out_size)))
    return out


def _pushforward(point, one, values, live):
    """(*out, k): the JVP of point(one, *values) along each of the k coordinates of the values marked
    `live` (the others held), by `vmap` over the basis: the primal is computed once."""
    start, unravel = _ravel([v for v, m in zip(values, live) if m])

    def f(coords):
        it = iter(unravel(coords))
        return point(one, *[next(it) if m else v for v, m in zip(values, live)])

    basis = jnp.eye(start.size, dtype=start.dtype)
    return jax.vmap(lambda e: jax.jvp(f, (start,), (e,))[1], out_axes=-1)(basis)


def _ravel(arrays):
    """The arrays' coordinates as one vector, and the map back."""
    from jax.flatten_util import ravel_pytree
    return ravel_pytree(list(arrays))


# An integrand with more values per point than this has its uniforms stored once per chunk (and
# `plain.packed_values` its warped sample): XLA computes each output in its own loop, and would
# re-run the generator and the warp in every one of them.
MANY_OUTPUTS = 1


def _uniforms_stored_once(groups, tok):
    """The chunk's uniforms (every coordinate of every group) through `computed_once`."""
    flat = [lane for lanes in groups for lane in lanes]
    stored = iter(computed_once(flat, tok))
    return tuple(tuple(next(stored) for _ in lanes) for lanes in groups)


def _chunk_token(seed, offset) -> jax.Array:
    """The chunk's `computed_once` token: its offset mixed with a word of the seed. The offset alone
    is a constant where the stream is one chunk (no loop), and XLA then folds every `computed_once`
    boundary of the chunk away (`docs/xla-cpu-paths.md`). The seed comes from the key, traced in any
    program that takes its key as an argument (`seed_from_key`: SEED_WORDS uint32 words)."""
    return token(offset) ^ seed[0]


def chunk_step(values_fn, source: Source, seed, dims: int, dtype, offset: Index, size: int, out_shape, bins: int, *,
           total, aligned: int, diagnostics: bool = True) -> _Moments:
    """Moments of values_fn over the `size` points from global index `offset`: one step of every
    streaming loop (`_stream`'s scan, `estimate_until`'s while loop).

    `total`: the points of the whole stream when it is known in advance (the sources may use it:
    stratified cells, Sobol' index bits), else None. `aligned`: the offset is a multiple of it."""
    # A narrow stream hands the sources a bare uint32 offset: the program of a 32-bit counter.
    at = offset if offset.wide else offset.lo
    groups = source.lanes(seed, at, size, dims, dtype, total=total, aligned=aligned)
    tok = _chunk_token(seed, offset)
    stored = math.prod(out_shape) > MANY_OUTPUTS
    if stored:
        groups = _uniforms_stored_once(groups, tok)
    # The g groups share each generator call: computed in one loop, stored once per chunk. One
    # group is stored too: else XLA's CPU reduction fusion (YNNPACK) takes the integrand's last
    # elementwise ops (the sum of x, y, z) into the replicate sums and leaves each operand its own
    # loop, each re-running the generator and the warp (Sobol' with UniformSphere: 3 such loops).
    derivative_fn = getattr(values_fn, "derivative", None)
    columns = group_values(values_fn, groups, tok, stored, derivative_fn)
    kept = iter(computed_once([c for group in columns for c in group], tok, alone=True))
    columns = [tuple(next(kept) for _ in group) for group in columns]
    return _column_moments(columns, source.replicates, out_shape, bins, diagnostics)


def _column_moments(columns, replicates: int, out_shape, bins: int, diagnostics) -> _Moments:
    """`_chunk_moments` of values given per group as columns (the elements of out_shape in C order,
    each an array over the group's points), taken column by column and stacked once reduced. The
    values are never stacked into a (points, *out) array: XLA's CPU backend would compute that
    array in one concatenate fusion, element by element, and where the `computed_once` boundary
    folds (a single chunk: its offset is a constant) take the whole per-point program into it."""
    out_shape = tuple(out_shape)
    width = len(columns[0])
    if width == 1 and not out_shape:
        return _chunk_moments([c[0] for c in columns], replicates, (), bins, diagnostics)
    per_column = [_chunk_moments([group[j] for group in columns], replicates, (), bins, diagnostics)
                  for j in range(width)]

    def stacked(name):
        array = jnp.stack([getattr(m, name) for m in per_column], axis=-1)
        return array.reshape(array.shape[:-1] + out_shape)

    names = ("sums", "compensation", "m2", "max_abs", "sum_abs", "tail", "nonzero")
    return _Moments(**{name: stacked(name) for name in names}, count=per_column[0].count)


def _stream(values_fn, source: Source, seed, dims: int, dtype, base, count: int, total: int,
            chunk_size: int, out_shape, aligned: int, diagnostics: bool = True, carried=None) -> _Moments:
    """Moments of values_fn over the points with global indices [base, base + count).

    `aligned`: every chunk offset is a multiple of it (it lets the sources take fast paths).
    Offsets are 64-bit `Index`es when the stream passes 2^32 points (`total` > 2^32); below, they
    are the plain uint32 offsets of a 32-bit counter (the same program, and the same points).

    `carried`: arrays threaded through the loop, with values_fn(carried) the block function, and the
    loop a `while_loop`: for a stream traced inside a derivative rule (`_differentiable_stream`).
    There, JAX's partial evaluation of a `scan` (its rule runs even when every input is known)
    hoists each loop-invariant value out of the loop, a scan's unchanged carry included: the
    per-point program's constants, broadcast to the chunk's lanes, turn into hundreds of
    chunk-sized arrays that the loop reads from memory (`docs/xla-cpu-paths.md`). A while loop keeps
    them inside, as scalars."""
    replicates = source.replicates
    wide = total > NARROW_LIMIT

    def chunk(offset: Index, size, carried):
        fn = values_fn if carried is None else values_fn(carried)
        return chunk_step(fn, source, seed, dims, dtype, offset, size, out_shape, bins, total=total,
                      aligned=aligned, diagnostics=diagnostics)

    bins = tail_bins(total, chunk_size)
    moments = empty_moments(replicates, out_shape, dtype, bins)
    steps, tail = divmod(count, chunk_size)
    if steps and carried is not None:
        def step_of(state):
            step, moments, carried = state
            offset = offset_at(base, step, chunk_size, wide)
            return step + 1, merge_moments(moments, chunk(offset, chunk_size, carried)), carried

        _, moments, _ = jax.lax.while_loop(lambda state: state[0] < steps, step_of,
                                           (jnp.uint32(0), moments, carried))
    elif steps:
        chunk_body = jax.checkpoint(lambda offset, carried: chunk(offset, chunk_size, carried))

        def body(state, step):
            moments, carried = state
            offset = offset_at(base, step, chunk_size, wide)
            return (merge_moments(moments, chunk_body(offset, carried)), carried), None

        (moments, _), _ = jax.lax.scan(body, (moments, carried), jnp.arange(steps, dtype=jnp.uint32))
    if tail:
        moments = merge_moments(moments, chunk(offset_at(base, steps, chunk_size, wide), tail, carried))
    return moments


def _per_point(fn, example):
    """(point, consts): fn on one point with every tracer it closes over as an argument."""
    return _hoist_traced(lambda one: fn(one[None])[0], example)


def _block(point, consts):
    """The block function of a per-point program: (count, dims) uniforms -> (count, *out) values.
    On the one point the engine traces it with (`group_values`), it is the per-point program itself,
    without a batch axis of size 1 through every operation."""
    def block(u):
        if u.shape[0] == 1:
            return point(u[0], *consts)[None]
        return jax.vmap(lambda one: point(one, *consts))(u)

    return block


def _differentiable_stream(values_fn, source: Source, seed, dims: int, dtype, n: int, chunk_size: int, out_shape,
                           diagnostics: bool) -> _Moments:
    """`_stream` over [0, n), whose derivative, when few coordinates move, is a second forward
    stream instead of the reverse pass through the loop.

    d/dθ of the moments: the sums' tangent is Σ_i ẏ_i, the M2's 2 Σ_i (y_i - ȳ) ẏ_i, Σ|Y|'s
    Σ_i sign(y_i) ẏ_i (per replicate where the sums are), with ẏ_i = Σ_k t_k S_ik and S_ik = ∂y_i/∂c_k
    the sensitivity of the value to the k-th moving coordinate of what values_fn closes over
    (forward mode on one point, `_sensitivities`). So the tangent needs Σ S, Σ y S and Σ sign(y) S
    over the stream: one streamed pass of a per-point program about the size of the value's JVP,
    in constant memory, with no residuals and no loop to transpose. The diagnostics (max |Y|, the
    tail, k-hat, the nonzero fraction) have zero derivative.

    Why not the reverse pass. Differentiated in reverse, the loop is rematerialized chunk by chunk
    and each primal value the transposed per-point program needs becomes its own loop in XLA's
    CPU fusion, recomputing the warp: the gradient of a shading point costs 10-90x its value that
    way (`docs/xla-cpu-paths.md`). With more moving coordinates than `FORWARD_WIDTH` (times the
    values per point), the forward pass would cost more than that, and the derivative is the
    reverse pass.
    """
    example = jnp.zeros((dims,), dtype)
    point, consts = _per_point(values_fn, example)
    derivative_fn = getattr(values_fn, "derivative", None)
    d_point, d_consts, refusal = point, consts, None
    if derivative_fn is not None:
        try:
            d_point, d_consts = _per_point(derivative_fn, example)
        except ValueError as error:
            # A derivative that cannot be made unbiased is an error when it is asked for.
            refusal, d_consts = error, []
    if not any(jnp.issubdtype(jnp.result_type(c), jnp.inexact) for c in list(consts) + list(d_consts)):
        return _stream(values_fn, source, seed, dims, dtype, 0, n, n, chunk_size, out_shape, chunk_size, diagnostics)

    def program(consts, d_consts, differentiated):
        fn = _block(point, consts)
        if differentiated and derivative_fn is not None and refusal is None:
            fn.derivative = _block(d_point, d_consts)
        return fn

    def plain(consts, d_consts, seed, differentiated=True):
        return _stream(program(consts, d_consts, differentiated), source, seed, dims, dtype, 0, n, n, chunk_size,
                       out_shape, chunk_size, diagnostics)

    @jax.custom_jvp
    def moments(consts, d_consts, seed):
        # The value: the rule below is its only derivative, so no derivative program is traced here.
        return plain(consts, d_consts, seed, differentiated=False)

    def moments_jvp(primals, tangents):
        consts, d_consts, seed = primals
        if refusal is not None:
            raise refusal
        own, own_tangents, own_point = (consts, tangents[0], point) if derivative_fn is None else \
            (d_consts, tangents[1], d_point)
        live = [not isinstance(t, SymbolicZero) for t in own_tangents]
        moving = [c for c, m in zip(own, live) if m]
        width = sum(int(np.size(c)) for c in moving) * math.prod(out_shape)
        if not (0 < width <= FORWARD_WIDTH and all(jnp.issubdtype(jnp.result_type(c), jnp.floating) for c in moving)):
            full = [[_instantiate(p, t) for p, t in zip(ps, ts)] for ps, ts in zip((consts, d_consts), tangents[:2])]
            return jax.jvp(lambda c, d: plain(c, d, seed), (list(consts), list(d_consts)), tuple(full))
        primal = moments(consts, d_consts, seed)
        k = sum(int(np.size(c)) for c in moving)
        aux = _stream(lambda carried: _sensitivities(point, carried[0], own_point, carried[1], live),
                      source, seed, dims, dtype, 0, n, n, chunk_size, (4,) + out_shape + (k,), chunk_size,
                      diagnostics="sums", carried=(list(consts), list(own)))
        t = _ravel([t for t, m in zip(own_tangents, live) if m])[0].astype(dtype)
        per_replicate = aux.sums + aux.compensation                       # (R, 4, *out, k)
        total = jnp.sum(per_replicate, axis=0)
        # ȳ from this stream too: the tangent then needs nothing of the value's stream, which a
        # gradient alone (jax.grad) leaves out.
        mean = total[3, ..., 0] / float(n)  # a float: n past 2^31 would overflow JAX's weak int32
        zero = jax.tree.map(jnp.zeros_like, primal)
        return primal, _Moments(
            sums=per_replicate[:, 0] @ t, compensation=zero.compensation,
            m2=2.0 * ((total[1] - mean[..., None] * total[0]) @ t), max_abs=zero.max_abs,
            sum_abs=total[2] @ t, tail=zero.tail, nonzero=zero.nonzero, count=zero.count)

    moments.defjvp(moments_jvp, symbolic_zeros=True)
    return moments(list(consts), list(d_consts), seed)


def _instantiate(primal, tangent):
    if not isinstance(tangent, SymbolicZero):
        return tangent
    if not jnp.issubdtype(jnp.result_type(primal), jnp.inexact):
        return np.zeros(np.shape(primal), jax.dtypes.float0)
    return jnp.zeros_like(primal)


def _sensitivities(value_point, value_consts, point, consts, live):
    """The block function u -> (4, *out, k): S, y S, sign(y) S and y per point, S_k = ∂y/∂c_k the JVP
    of the per-point program `point` along the k-th coordinate of its moving constants (see
    `_differentiable_stream`), y the value (`value_point`: a derivative program's surrogates of value
    0 are not evaluated for it, and where their tangent is zero XLA drops them). y and S are marked
    `stored_once`, so that the lanes program computes them in shared loops and the products read
    them."""
    def one(u):
        s = _pushforward(point, u, consts, live)
        y = value_point(u, *value_consts)
        y, s = stored_once((y, s.astype(y.dtype)))
        return jnp.stack([s, y[..., None] * s, jnp.sign(y)[..., None] * s, jnp.broadcast_to(y[..., None], s.shape)])

    return lambda u: one(u[0])[None] if u.shape[0] == 1 else jax.vmap(one)(u)


def combine_devices(m: _Moments, axes, per_device: int, n: int, dtype) -> _Moments:
    """Inside `shard_over`: the moments of every device's `per_device` points, combined into those
    of all n of them (the same on every device).

    Compensated sums are added, M2 merged about the global mean. The per-replicate sums are
    gathered and added in double-float (a psum would round them)."""
    sums, low = doublefloat.sum_axis0(jax.lax.all_gather(m.sums, axes), leaf=1)
    low = low + jnp.sum(jax.lax.all_gather(m.compensation, axes), axis=0)
    local_mean = jnp.sum(m.sums + m.compensation, axis=0) / float(per_device)
    global_mean = jnp.sum(sums + low, axis=0) / float(n)
    shift = local_mean - global_mean
    m2 = jax.lax.psum(m.m2 + float(per_device) * shift * shift, axes)
    # max |Y| is a diagnostic with no derivative (and pmax has no differentiation rule, so
    # without the stop a gradient of a sharded estimate fails).
    # The devices' tail states side by side: (2, devices x bins, *out).
    tails = jax.lax.all_gather(jax.lax.stop_gradient(m.tail), axes, axis=1, tiled=True)
    return _Moments(sums, low, m2, jax.lax.pmax(jax.lax.stop_gradient(m.max_abs), axes),
                    jax.lax.psum(m.sum_abs, axes), tails,
                    jax.lax.psum(jax.lax.stop_gradient(m.nonzero), axes), jnp.asarray(float(n), dtype))


def shard_over(mesh, local, *args):
    """`local(*args)` on every device of `mesh` (`jax.shard_map`, every argument and result replicated)."""
    from jax.sharding import PartitionSpec

    return jax.shard_map(local, mesh=mesh, in_specs=PartitionSpec(), out_specs=PartitionSpec(),
                         check_vma=False)(*args)


def _check_n(owner: str, n, replicates: int, devices: int, source: Source) -> int:
    """n as an int: any concrete integer (see `_core.counts`), a multiple of replicates x devices,
    below 2^64 (sample indices have 64 bits)."""
    n = check_count(owner, "n", n, minimum=2, maximum=MAX_INDEX)
    multiple = replicates * devices
    if n % multiple:
        parts = [f"{replicates} replicates" if replicates > 1 else None,
                 f"{devices} devices" if devices > 1 else None]
        why = " x ".join(p for p in parts if p)
        advice = f"use n = {n - n % multiple + multiple}"
        if replicates > 1:
            divisor = "R" if devices == 1 else f"R x {devices}"
            advice += (f", or choose the replicate count: uniforms=jaxsample.uniforms."
                       f"{type(source).__name__}(replicates=R), with {divisor} dividing n")
        raise ValueError(f"{owner}: parameter 'n' must be a multiple of {multiple} ({why}); got {n}: {advice}")
    return n


def check_chunk_size(owner: str, chunk_size, replicates: int) -> int:
    if chunk_size is None:
        chunk_size = DEFAULT_CHUNK_SIZE
    step = math.lcm(4, replicates)
    chunk_size = check_count(owner, "chunk_size", chunk_size, minimum=1)
    if chunk_size < step or chunk_size % step:
        raise ValueError(f"{owner}: parameter 'chunk_size' must be a positive multiple of {step} "
                         f"(4 and the source's {replicates} replicates); got {chunk_size!r}")
    return int(chunk_size)


MAX_STEPS = (1 << 31) - 1  # lax.scan counts its steps in int32


def _check_steps(owner: str, per_device: int, chunk_size: int) -> None:
    if per_device // chunk_size > MAX_STEPS:
        raise ValueError(f"{owner}: n / chunk_size ({per_device // chunk_size} chunks per device) must be "
                         f"below 2^31 (the streaming loop counts chunks in int32); raise 'chunk_size' "
                         f"(now {chunk_size})")


def run_stream(values_fn, dims: int, key, n: int, *, uniforms="random", mesh=None,
               chunk_size=None, out_shape=(), dtype=None, owner="estimate",
               diagnostics: bool = True) -> Estimate:
    """The engine behind every estimator: the Estimate of values_fn(u) over n points.

    `values_fn` maps a (count, dims) block of uniforms to (count, *out_shape) values; it must be
    elementwise over the block (point i's value depends on u_i only). `diagnostics=False` leaves
    out the streamed tail and nonzero count (k-hat -inf, nonzero 1): only to measure their cost.
    """
    source = as_source(uniforms)
    replicates = source.replicates
    dtype = resolve_float_dtype(owner, dtype)
    devices = 1 if mesh is None else mesh.size
    n = _check_n(owner, n, replicates, devices, source)
    chunk_size = check_chunk_size(owner, chunk_size, replicates)
    _check_steps(owner, n // devices, chunk_size)
    seed = seed_from_key(key)

    if mesh is None:
        moments = _differentiable_stream(values_fn, source, seed, dims, dtype, n, chunk_size, tuple(out_shape),
                                         diagnostics)
        return Estimate(**finish(moments, n, replicates), n=n, replicates=replicates)

    per_device = n // devices
    axes = tuple(mesh.axis_names)

    def local(seed):
        device = jax.lax.axis_index(axes)
        base = offset_at(0, device.astype(jnp.uint32), per_device, n > NARROW_LIMIT)
        m = _stream(values_fn, source, seed, dims, dtype, base, per_device, n, chunk_size,
                    out_shape, math.gcd(per_device, chunk_size), diagnostics)
        return combine_devices(m, axes, per_device, n, dtype)

    moments = shard_over(mesh, local, seed)
    return Estimate(**finish(moments, n, replicates), n=n, replicates=replicates)
