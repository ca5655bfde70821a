"""Discrete distributions on {0, ..., K-1} (counting measure): CDF search and Walker/Vose alias table.

Also home of the CDF helpers that `piecewise` and `mixture` share: building a CDF in which
zero-weight entries own an empty interval, and selecting from it while keeping the unused part of
the uniform (the *remainder*) for reuse.
"""

from __future__ import annotations

import functools
from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from .base import Sampler, point_method
from .._core.params import check_choice, check_number, concrete_value, default_float_dtype
from .._core.pytree import parameter, static_field
from .domain import DiscreteSet
from .._core.numerics import clamp_rounding, one_minus_epsilon


def as_array(x):
    """Lists and tuples of numbers as float64 NumPy arrays (so they count as concrete); else `x`
    (a list that is not of numbers stays a list, for `check_number` to refuse)."""
    if not isinstance(x, (list, tuple)):
        return x
    try:
        return np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError):
        return x


_NO_BATCH = ("one table per sampler: batches of tables are not supported (build one sampler per "
             "row, or jax.vmap a function that builds it)")


def check_weights(owner: str, name: str, weights, ndim: int = 1) -> None:
    """Raise ValueError unless concrete `weights` has `ndim` dimensions, is finite, >= 0, sum > 0."""
    check_number(owner, name, weights)
    w = concrete_value(weights)
    if w is None:
        if hasattr(weights, "shape") and jnp.ndim(weights) != ndim:
            raise ValueError(f"{owner}: parameter '{name}' must have {ndim} dimension(s); got shape "
                             f"{jnp.shape(weights)}; " + _NO_BATCH)
        return
    if w.ndim != ndim or w.size == 0:
        raise ValueError(f"{owner}: parameter '{name}' must be a non-empty array with {ndim} dimension(s); "
                         f"got shape {w.shape}" + ("; " + _NO_BATCH if w.ndim > ndim else ""))
    if not np.all(np.isfinite(w)) or np.any(w < 0):
        raise ValueError(f"{owner}: parameter '{name}' must have every entry in [0, inf) (finite, no NaN)")
    if not np.sum(w) > 0:
        raise ValueError(f"{owner}: parameter '{name}' must have a positive sum (not all zero)")


def valid_tables(*pmfs) -> jax.Array:
    """Whether normalised tables are valid: every entry finite and >= 0, and some entry positive
    (weights that were all zero, negative somewhere, or not finite fail)."""
    ok = [jnp.all(jnp.isfinite(p) & (p >= 0)) & jnp.any(p > 0) for p in pmfs]
    return functools.reduce(jnp.logical_and, ok)


def _cummax(x, xp, reverse=False):
    if xp is np:
        if reverse:
            return np.flip(np.maximum.accumulate(np.flip(x, -1), axis=-1), -1)
        return np.maximum.accumulate(x, axis=-1)
    return jax.lax.cummax(x, axis=x.ndim - 1, reverse=reverse)


def cdf_from_weights(weights, xp=jnp):
    """Normalised CDF P along the last axis, built so that sampling from it is exact at the ends.

    Guarantees, whatever the rounding of the running sum (a parallel prefix sum on a device is not
    sequential): P is non-decreasing; a zero weight gets P_i = P_{i-1} exactly, so its interval
    [P_{i-1}, P_i) is empty and it is never selected; P = 1 exactly from the last positive weight
    on, so u < 1 never runs past it. A row whose weights are all zero gets the uniform CDF (it has
    probability zero of being used).
    """
    w = weights
    n = w.shape[-1]
    running = xp.cumsum(w, axis=-1)
    total = running[..., -1:]
    empty = total <= 0
    uniform = xp.broadcast_to((xp.arange(n) + 1.0) / n, w.shape).astype(running.dtype)
    cdf = running / xp.where(empty, 1.0, total)
    cdf = _cummax(xp.where(w > 0, cdf, 0.0), xp)
    positive_later = xp.concatenate([_cummax((w[..., 1:] > 0).astype(np.int32), xp, reverse=True),
                                     xp.zeros(w.shape[:-1] + (1,), np.int32)], axis=-1) > 0
    cdf = xp.where(positive_later, cdf, 1.0)
    return xp.where(empty, uniform, cdf)


def _float_array(x):
    """`x` as a JAX array of the default float dtype unless it already is a JAX float array."""
    x = jnp.asarray(x)
    return x if jnp.issubdtype(x.dtype, jnp.floating) else x.astype(default_float_dtype())


def normalized_tables(weights):
    """(pmf, cdf) from weights: in float64 NumPy when concrete (exact running sum), else in JAX."""
    w = concrete_value(weights)
    if w is None:
        w = _float_array(weights)
        total = jnp.sum(w, axis=-1, keepdims=True)
        return w / jnp.where(total > 0, total, 1.0), cdf_from_weights(w)
    dtype = _float_array(weights).dtype
    total = w.sum(axis=-1, keepdims=True)
    pmf = w / np.where(total > 0, total, 1.0)
    return jnp.asarray(pmf, dtype), jnp.asarray(cdf_from_weights(w, np), dtype)


# Up to this many entries a CDF is searched by comparing u with every entry: no loop, so the search
# fuses with the warp around it (a binary search is a loop of dependent gathers, which XLA runs as
# a separate while loop over the whole chunk), and for so few entries it is not more work.
_COMPARE_ALL_MAX = 32


def search_right(cdf, u):
    """#{k : cdf[k] <= u} for a non-decreasing 1-D `cdf` (`searchsorted(..., side="right")`)."""
    method = "compare_all" if cdf.shape[-1] <= _COMPARE_ALL_MAX else "scan"
    return jnp.searchsorted(cdf, u, side="right", method=method)


def select_with_remainder(cdf, u):
    """Index i with P_{i-1} <= u < P_i (P_{-1} = 0), and the remainder (u - P_{i-1}) / (P_i - P_{i-1}).

    The interval is closed on the left because u in [0, 1) includes 0: with P_{i-1} < u <= P_i a
    leading zero-weight entry would own u = 0. The remainder is uniform on [0, 1) given i and
    independent of it, so it can drive the next decision; it is clamped below 1.
    """
    n = cdf.shape[-1]
    index = jnp.clip(search_right(cdf, u), 0, n - 1).astype(jnp.int32)
    upper = cdf[index]
    lower = jnp.where(index > 0, cdf[jnp.maximum(index - 1, 0)], 0.0)
    width = upper - lower
    remainder = (u - lower) / jnp.where(width > 0, width, 1.0)
    return index, clamp_rounding(remainder, 0.0, one_minus_epsilon(remainder.dtype)).astype(u.dtype)


def select_rows_with_remainder(cdf_rows, row, u):
    """`select_with_remainder` in row `row` of a (R, n) table of CDFs, per sample.

    A fixed number of bisection steps, each a gather of one entry per sample, so that no sample
    gathers its whole row.
    """
    n = cdf_rows.shape[-1]
    low = jnp.zeros(u.shape, jnp.int32)
    high = jnp.full(u.shape, n, jnp.int32)
    for _ in range(int(np.ceil(np.log2(n + 1)))):
        middle = (low + high) // 2
        go_left = cdf_rows[row, jnp.minimum(middle, n - 1)] > u
        high = jnp.where(go_left, middle, high)
        low = jnp.where(go_left, low, middle + 1)
    index = jnp.clip(low, 0, n - 1)
    upper = cdf_rows[row, index]
    lower = jnp.where(index > 0, cdf_rows[row, jnp.maximum(index - 1, 0)], 0.0)
    width = upper - lower
    remainder = (u - lower) / jnp.where(width > 0, width, 1.0)
    return index, clamp_rounding(remainder, 0.0, one_minus_epsilon(remainder.dtype)).astype(u.dtype)


def build_alias_table(pmf: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Walker's alias table by Vose's pairing (Vose 1991), in float64 NumPy: (probability, alias).

    Bucket i keeps outcome i with probability `probability[i]` and otherwise gives `alias[i]`.
    Instead of pairing one small bucket at a time, each round pairs *all* current small buckets
    at once: laid end to end, the deficits 1 - K p_j of the small buckets are covered by the
    excesses K p_k - 1 of the large ones, and each small bucket takes its whole deficit from the
    large bucket in whose excess interval its deficit *ends*. That large bucket gives at most its
    excess plus one straddling deficit (< 1), so it never goes negative; if it falls below 1 it is
    small in the next round. A few rounds suffice in practice; after 64 the rest is paired one by
    one. Zero-weight entries get probability 0 and are never anyone's alias.
    """
    k = len(pmf)
    scaled = pmf.astype(np.float64) * k
    probability = np.ones(k)
    alias = np.arange(k, dtype=np.int64)
    small = np.flatnonzero(scaled < 1.0)
    large = np.flatnonzero(scaled >= 1.0)
    rounds = 0
    while len(small) and len(large) and rounds < 64:
        rounds += 1
        deficit_end = np.cumsum(1.0 - scaled[small])
        excess_end = np.cumsum(scaled[large] - 1.0)
        donor = np.minimum(np.searchsorted(excess_end, deficit_end, side="left"), len(large) - 1)
        probability[small] = scaled[small]
        alias[small] = large[donor]
        given = np.bincount(donor, weights=1.0 - scaled[small], minlength=len(large))
        scaled[large] -= given
        small, large = large[scaled[large] < 1.0], large[scaled[large] >= 1.0]
    small, large = list(small), list(large)
    while small and large:  # Vose's one-at-a-time pairing for whatever is left.
        s, l = small.pop(), large[-1]
        probability[s], alias[s] = scaled[s], l
        scaled[l] -= 1.0 - scaled[s]
        if scaled[l] < 1.0:
            small.append(large.pop())
    # What is left over is 1 up to round-off: those buckets keep their own outcome.
    probability[pmf == 0] = 0.0
    return np.clip(probability, 0.0, 1.0), alias


class Discrete(Sampler):
    """Outcome i in {0, ..., K-1} with probability p_i = w_i / Σ w (density over the counting measure).

    `method="cdf"` (default): inversion of the CDF, i with P_{i-1} <= u < P_i found by binary
    search (`jnp.searchsorted`), O(log K) per sample (PBRT-v4 `SampleDiscrete` /
    `PiecewiseConstant1D`). Zero weights own empty intervals and are never selected.

    `method="alias"`: Walker's alias method with Vose's table (PBRT-v4 `AliasTable`): bucket
    b = ⌊uK⌋, then outcome b if the fraction uK - b is below the bucket's probability, else its
    alias; O(1) per sample. The table is built in float64 NumPy at construction, so the weights
    must be concrete there: build the sampler outside `jit` and pass it in (it is a pytree; its
    tables are leaves). Building it from traced weights raises ValueError; use "cdf" there.

    `warp_with_remainder(u)` also returns the unused part of u, uniform on [0, 1) and independent
    of the choice, for the next decision. Samples are int32.

    Precision: a float32 uniform has 23 random bits, so with K near 10^6 each outcome's probability
    is resolved only to about K·2^-23 (~12 %) of itself; pass float64 uniforms when per-outcome
    accuracy matters for such tables. Concrete weights must be finite, >= 0 and not all zero
    (ValueError otherwise); such traced weights make every value NaN (`Sampler`, "Invalid
    parameters"). One table per sampler: weights with a batch dimension raise ValueError.
    """

    pmf: jax.Array = parameter(rank=1, doc="the outcomes' probabilities")
    cdf: jax.Array = parameter(rank=1)
    alias_probability: jax.Array | None = parameter(rank=1, default=None)
    alias: jax.Array | None = parameter(rank=1, default=None)
    method: str = static_field(default="cdf")
    uniform_dims: ClassVar[int] = 1
    event_shape: ClassVar = ()
    measure: ClassVar = "counting"
    batchable: ClassVar = False

    def _parameters_valid(self):
        # Traced weights are checked here, as `check_weights` checks concrete ones: a normalised
        # table with a NaN entry (all-zero, negative or non-finite weights) is invalid.
        return valid_tables(self.pmf)

    def __init__(self, weights, method: str = "cdf"):
        check_choice("Discrete", "method", method, ("cdf", "alias"))
        weights = as_array(weights)
        check_weights("Discrete", "weights", weights)
        self.method = method
        self.pmf, self.cdf = normalized_tables(weights)
        self.alias_probability = self.alias = None
        if method == "alias":
            pmf = concrete_value(self.pmf)
            if pmf is None:
                raise ValueError("Discrete: method 'alias' needs concrete 'weights' (the table is built "
                                 "in NumPy); build it outside jit, or use method='cdf' with traced weights")
            concrete = np.asarray(concrete_value(weights))
            probability, alias = build_alias_table(concrete / np.sum(concrete))
            self.alias_probability = jnp.asarray(probability, self.pmf.dtype)
            self.alias = jnp.asarray(alias, jnp.int32)

    def __repr__(self):
        return f"Discrete(size={self.size}, method={self.method!r})"

    @property
    def size(self) -> int:
        return self.pmf.shape[-1]

    @point_method(batched=False)
    def warp_with_remainder(self, u):
        """(outcome, remainder): the remainder is what is left of u[..., 0], uniform on [0, 1)."""
        u0 = jnp.asarray(u)[..., 0]
        if self.method == "cdf":
            return select_with_remainder(self.cdf, u0)
        k = self.size
        scaled = u0 * k
        bucket = jnp.clip(jnp.floor(scaled), 0, k - 1).astype(jnp.int32)
        fraction = jnp.clip(scaled - bucket, 0.0, one_minus_epsilon(u0.dtype))
        keep_probability = self.alias_probability[bucket].astype(u0.dtype)
        keep = fraction < keep_probability
        outcome = jnp.where(keep, bucket, self.alias[bucket])
        # Keeping has probability q: the fraction is uniform on [0, q) then, and on [q, 1) otherwise.
        remainder = jnp.where(keep, fraction / jnp.where(keep_probability > 0, keep_probability, 1.0),
                              (fraction - keep_probability)
                              / jnp.where(keep_probability < 1, 1.0 - keep_probability, 1.0))
        return outcome, clamp_rounding(remainder, 0.0, one_minus_epsilon(u0.dtype))

    @point_method
    def warp(self, u):
        return self.warp_with_remainder(u)[0]

    @point_method
    def warp_with_pdf(self, u):
        outcome, _ = self.warp_with_remainder(u)
        return outcome, self.pmf[outcome].astype(jnp.asarray(u).dtype)

    @point_method
    def pdf(self, x):
        x = jnp.asarray(x)
        k = self.size
        inside = (x >= 0) & (x < k)
        if jnp.issubdtype(x.dtype, jnp.floating):
            inside = inside & (x == jnp.floor(x))
        index = jnp.clip(x, 0, k - 1).astype(jnp.int32)
        return jnp.where(inside, self.pmf[index], 0.0)

    def domain(self):
        return DiscreteSet(self.size)
