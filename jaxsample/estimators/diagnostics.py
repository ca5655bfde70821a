"""Diagnostics computed in the estimators' streaming pass: when an estimate cannot be trusted.

A Monte Carlo mean with its standard error is only as good as the variance behind it. Three
numbers, kept in constant memory as the samples stream by, say when it is not:

- **Pareto k-hat** of the upper tail of |Y|, Y = f/p (`pareto_khat`). The largest values of |Y|
  are streamed as the top two of each of `BINS` bins (`chunk_tail`, `merge_tails`: elementwise
  maxima, fused into the pass that sums Y), the M + 1 largest taken from those at the end
  (`largest`, one top-k); a generalized Pareto
  distribution is fitted to their exceedances over the (M+1)-th largest by the method of Zhang and
  Stephens (2009), as PSIS does (Vehtari, Simpson, Gelman, Yao and Gabry 2024, "Pareto smoothed
  importance sampling", JMLR 25(72)), with M = min(n/5, 3 √n) capped at `MAX_TAIL`. The GPD's
  shape ξ is the tail index: |Y| has finite moments of order below 1/ξ. k-hat >= 0.5 means the
  variance is infinite, so the standard error means nothing; k-hat >= 0.7 means the mean itself
  converges too slowly to be trusted at any practical n (Vehtari et al. 2024, sec. 3). A bounded
  |Y| gives k-hat < 0; a tail with no spread (the largest M + 1 values equal to 0.1 %, as for
  f/p constant up to rounding) gives -inf.
- **The fraction of nonzero Y**: 0 means no sample reached where f is nonzero (the integral may be
  0, or the sampler may miss the integrand's support); a handful means the estimate rests on them.
- **ess / n**, from the `ess` field (Kong 1992).

`reliable` (`verdict`) is True when the mean and stderr are finite, at least M + 1 of the Y are
nonzero (the values the tail fit needs; a gradient component may also be 0 throughout) and k-hat is
below 0.5 (or could not be fitted: n below 25).
An estimate computed eagerly (outside `jit`, `vmap` and `grad`) that is not reliable emits an
`UnreliableEstimateWarning` naming what failed and what to try (`problems`; the warning is given by
`result.warn_if_unreliable`); under a transformation the flags are all there is (no Python code
runs on the values). Everything here works on arrays: nothing needs the result types.

The standard error has a floor at the float rounding of the values averaged: each Y = f/p carries
a relative rounding error of a few ulps, partly systematic (the same error for every sample of a
constant Y), so the error bar is never below `ROUNDING_ULPS` ulps of the mean |Y| (see `engine.py`).
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["UnreliableEstimateWarning", "tail_size", "tail_bins", "chunk_tail", "merge_tails", "empty_tail", "largest",
           "pareto_khat",
           "verdict", "problems", "KHAT_VARIANCE", "KHAT_MEAN", "MAX_TAIL", "ROUNDING_ULPS"]

KHAT_VARIANCE = 0.5   # k-hat at or above: infinite variance, the stderr means nothing
KHAT_MEAN = 0.7       # k-hat at or above: the mean itself is unreliable
MAX_TAIL = 256        # the most tail values fitted (M); the M + 1 largest |Y| are used
BINS = 8192           # the streamed tail state: the two largest |Y| of each of BINS bins
MIN_TAIL = 5          # fewer exceedances than this: no tail to fit
FLAT_TAIL = 1e-3      # the M + 1 largest within this relative spread: no tail (k-hat -inf)
ROUNDING_ULPS = 2.0   # the stderr floor, in ulps of mean |Y|
_PRIOR_WEIGHT = 10.0  # PSIS's weakly informative prior on ξ: 10 pseudo-observations at 0.5
_PRIOR_SHAPE = 0.5
_GRID_MIN = 30        # Zhang and Stephens: m = 30 + floor(√M) grid points for θ


class UnreliableEstimateWarning(UserWarning):
    """An estimate whose standard error (or mean) cannot be trusted; see `Estimate.diagnostics`."""


def tail_size(n):
    """M, the number of tail values fitted for n samples: min(n/5, 3 √n, MAX_TAIL) (PSIS's rule,
    capped so that the streamed top-k stays cheap), at least 1. An int for an int n; an int32
    array for a traced count (`estimate_until`'s, known only at run time)."""
    if isinstance(n, (int, np.integer)):
        return int(max(1, min(n // 5, math.ceil(3.0 * math.sqrt(n)), MAX_TAIL)))
    return _tail_count(n, jnp).astype(jnp.int32)


def _tail_count(n, xp):
    """min(n/5, 3 √n) clipped to [1, MAX_TAIL], in NumPy (`xp = np`: concrete counts, no device
    programs) or JAX (`xp = jnp`: traced counts)."""
    return xp.clip(xp.minimum(xp.floor(n / 5.0), xp.ceil(3.0 * xp.sqrt(n))), 1, MAX_TAIL)


def _pair_merge(a1, a2, b1, b2):
    """The two largest of {a1, a2, b1, b2} elementwise, given a1 >= a2 and b1 >= b2."""
    return jnp.maximum(a1, b1), jnp.maximum(jnp.minimum(a1, b1), jnp.maximum(a2, b2))


def tail_bins(n: int, chunk_size: int) -> int:
    """The bins of a stream of n points in chunks of `chunk_size`: `BINS`, or the largest power of two
    not above the chunk size or n when either is smaller (a small estimate under `vmap` over many
    keys carries a small state)."""
    bins = BINS
    while bins > 1 and (bins > chunk_size or bins // 2 >= n):
        bins //= 2
    return bins


def chunk_tail(values: jax.Array, bins: int = BINS) -> jax.Array:
    """A chunk's tail state: the two largest |Y| in each of `bins` bins, per component,
    (count, *out) -> (2, bins, *out) (bin b holds the points b, b + bins, ...; -1 marks an empty
    slot). Elementwise maxima and minima only, in a tree over the chunk's rows: no sort.

    The streamed state is the bins' top two; the M + 1 largest of all values are taken from it at
    the end (`largest`). That is exact unless three of those M + 1 values share a bin: for values
    whose order does not depend on their index, probability about C(M+1, 3) / BINS² (0.04 at
    M = 256, BINS = 8192; 4e-5 at M = 64), and then the third is replaced by the next largest
    value, which changes k-hat by far less than its own spread.
    """
    out = values.shape[1:]
    a = jnp.abs(jax.lax.stop_gradient(values)).reshape((values.shape[0], -1))
    rows = -(-a.shape[0] // bins)
    if rows * bins != a.shape[0]:
        a = jnp.pad(a, ((0, rows * bins - a.shape[0]), (0, 0)), constant_values=-1.0)
    first = a.reshape((rows, bins, a.shape[1]))
    second = jnp.full_like(first, -1.0)
    while first.shape[0] > 1:
        if first.shape[0] % 2:
            pad = jnp.full((1,) + first.shape[1:], -1.0, first.dtype)
            first, second = jnp.concatenate([first, pad]), jnp.concatenate([second, pad])
        half = first.shape[0] // 2
        first, second = _pair_merge(first[:half], second[:half], first[half:], second[half:])
    return jnp.concatenate([first, second]).reshape((2, bins) + out)


def merge_tails(a: jax.Array, b: jax.Array) -> jax.Array:
    """Two tail states (2, bins, *out) -> the bins' top two of both."""
    first, second = _pair_merge(a[0], a[1], b[0], b[1])
    return jnp.stack([first, second])


def empty_tail(out_shape, dtype, bins: int = BINS) -> jax.Array:
    """The tail state of no values."""
    return jnp.full((2, bins) + tuple(out_shape), -1.0, dtype)


def largest(tail: jax.Array, keep: int) -> jax.Array:
    """The `keep` largest values held by a tail state (2, bins, *out) -> (keep, *out), descending
    (padded with -1 when it holds fewer slots)."""
    out = tail.shape[2:]
    flat = tail.reshape((-1, math.prod(out) if out else 1)).T
    if flat.shape[1] < keep:
        flat = jnp.pad(flat, ((0, 0), (0, keep - flat.shape[1])), constant_values=-1.0)
    return jax.lax.top_k(flat, keep)[0].T.reshape((keep,) + out)


def pareto_khat(tail: jax.Array, m) -> jax.Array:
    """k-hat, the generalized Pareto shape fitted to the m largest of `tail` (keep >= m + 1 values
    of |Y| per component, descending) over the (m+1)-th: shape `tail.shape[1:]`.

    Zhang and Stephens (2009): with exceedances x (only those > 0 count: ties with the threshold
    carry no tail information), x* their first quartile and G = 30 + ⌊√m⌋, the grid
    θ_j = 1/max x + (1 - √(G / (j - 1/2))) / (3 x*), j = 1..G, weighs each θ by its profile
    likelihood ℓ(θ) = m (log(-θ / ξ(θ)) - ξ(θ) - 1), ξ(θ) = mean log(1 - θ x); θ̂ is the weighted
    mean and k-hat = ξ(θ̂), shrunk towards 0.5 by 10 pseudo-observations (Vehtari et al. 2024).
    `m` may be traced (it is the count of exceedances used); computed in float64 when available.
    """
    from .._core.doublefloat import _float64_available

    keep = tail.shape[0]
    grid = _GRID_MIN + int(math.isqrt(keep - 1))
    if _float64_available() and tail.dtype == jnp.float32:
        with jax.enable_x64(True):
            return _fit(tail.astype(jnp.float64), m, grid).astype(jnp.float32)
    return _fit(tail, m, grid)


def _fit(tail, m, grid):
    keep = tail.shape[0]
    flat = tail.reshape((keep, -1))                                   # (keep, P)
    m = jnp.asarray(m, jnp.int32)
    threshold = jax.lax.dynamic_index_in_dim(flat, m, axis=0, keepdims=False)
    position = jnp.arange(keep)[:, None]
    x = flat - threshold
    used = (position < m) & (x > 0)
    count = jnp.sum(used, axis=0)                                     # exceedances > 0, (P,)
    x = jnp.where(used, x, 0.0)
    x_max = x[0]
    # First quartile of the used exceedances (ascending rank ⌊count/4 + 1/2⌋, 1-based); they are
    # the first `count` rows, descending.
    rank = jnp.floor(count / 4.0 + 0.5).astype(jnp.int32)
    quartile_row = jnp.clip(count - jnp.maximum(rank, 1), 0, keep - 1)
    x_star = jnp.take_along_axis(x, quartile_row[None], axis=0)[0]
    safe_max = jnp.where(x_max > 0, x_max, 1.0)
    safe_star = jnp.where(x_star > 0, x_star, safe_max)
    j = jnp.arange(1, grid + 1, dtype=x.dtype)[:, None]
    theta = 1.0 / safe_max + (1.0 - jnp.sqrt(grid / (j - 0.5))) / (3.0 * safe_star)   # (G, P)
    n_used = jnp.maximum(count, 1).astype(x.dtype)

    def shape_at(t):   # ξ(θ) = mean over the used exceedances of log(1 - θ x); t (..., P)
        logs = jnp.log1p(-t[..., None, :] * x)                        # (..., keep, P)
        return jnp.sum(jnp.where(used, logs, 0.0), axis=-2) / n_used

    xi = shape_at(theta)
    ratio = -theta / xi
    profile = n_used * (jnp.log(jnp.where(ratio > 0, ratio, 1.0)) - xi - 1.0)
    profile = jnp.where((ratio > 0) & jnp.isfinite(profile), profile, -jnp.inf)
    weights = jax.nn.softmax(profile, axis=0)
    theta_hat = jnp.sum(jnp.where(jnp.isfinite(profile), weights * theta, 0.0), axis=0)
    xi_hat = shape_at(theta_hat)
    shrunk = (n_used * xi_hat + _PRIOR_WEIGHT * _PRIOR_SHAPE) / (n_used + _PRIOR_WEIGHT)
    # Fewer than MIN_TAIL distinct exceedances (ties at the threshold), or the largest values
    # agreeing to `FLAT_TAIL`: f/p is constant up to the rounding of f and p (VonMisesFisher(10)
    # against e^{10 cos θ} spreads by 1e-4), and a tail that narrow cannot dominate the mean.
    spread = x_max > FLAT_TAIL * flat[0]
    khat = jnp.where((count >= MIN_TAIL) & spread, shrunk, -jnp.inf)
    khat = jnp.where(m >= MIN_TAIL, khat, jnp.nan)   # n too small to fit a tail
    return khat.reshape(tail.shape[1:])


def required_nonzero(n):
    """The fewest nonzero values an estimate of n samples must have to be judged: the M + 1 its
    tail fit uses (`tail_size`; n may be a traced count)."""
    if isinstance(n, (int, float, np.integer, np.floating, np.ndarray)):
        return _tail_count(np.asarray(n, np.float32), np) + 1.0
    return _tail_count(jnp.asarray(n, jnp.float32), jnp) + 1.0


def verdict(mean, stderr, khat, nonzero, n, gradient: bool = False) -> jax.Array:
    """reliable: finite mean and stderr, at least M + 1 nonzero values (`required_nonzero`; a
    gradient may instead be exactly 0 everywhere, as for a parameter f does not depend on), and
    k-hat below 0.5 (or not fitted: n too small).

    A complex leaf (its statistics are complex: real part from the real parts) is reliable when
    neither part's tail is heavy and either part has enough nonzero values."""
    finite = jnp.isfinite(mean) & jnp.isfinite(stderr)
    if jnp.iscomplexobj(khat):
        heavy = (khat.real >= KHAT_VARIANCE) | (khat.imag >= KHAT_VARIANCE)
        nonzero = jnp.maximum(nonzero.real, nonzero.imag)
    else:
        heavy = khat >= KHAT_VARIANCE
    n = jnp.asarray(n, jnp.result_type(nonzero))
    n = n.reshape(n.shape + (1,) * (jnp.ndim(nonzero) - n.ndim))   # a batch's n_used, one per member
    count = nonzero * n
    enough = count >= required_nonzero(n) - 0.5
    if gradient:
        enough = enough | (count == 0)
    return finite & enough & ~heavy


def problems(mean, stderr, khat, nonzero, n, gradient: bool = False) -> list[str]:
    """The one-line reasons a concrete estimate is not reliable (empty when it is): its fields
    (`mean`, `stderr`, `khat`, `nonzero`: arrays or pytrees of them, as an estimate holds them),
    `n` its sample count (one, or a batch's own count per member) and whether it is a gradient."""
    def flat(field):   # a field may be a pytree (a gradient shaped like the parameters)
        leaves = [np.ravel(np.asarray(leaf)) for leaf in jax.tree_util.tree_leaves(field)]
        return np.concatenate(leaves) if leaves else np.zeros(0)

    sample_count = np.asarray(n, np.float64)

    def counts_of(leaf):   # the sample count of every value: n, or a batch's own n_used per member
        return np.broadcast_to(sample_count.reshape(sample_count.shape + (1,) * (np.ndim(leaf) - sample_count.ndim)),
                               np.shape(leaf))

    n = flat(jax.tree_util.tree_map(counts_of, nonzero))
    mean, stderr, khat, nonzero = (flat(field) for field in (mean, stderr, khat, nonzero))
    if np.iscomplexobj(khat):
        khat = np.fmax(khat.real, khat.imag)
        nonzero = np.maximum(nonzero.real, nonzero.imag)
    reasons = []
    finite = np.isfinite(mean) & np.isfinite(stderr)
    if not finite.all():
        reasons.append("the mean or its stderr is not finite (f returned inf or NaN, a parameter is "
                       "out of range, or the sum overflowed)")
    counts = np.rint(nonzero * n)
    required = np.asarray(required_nonzero(n), np.float64)
    empty = finite & (counts == 0)
    if empty.any() and not gradient:
        reasons.append(f"all {n[empty].max():.0f} values f/p are 0: either the integral is 0 or the sampler never "
                       "reaches where f is nonzero (orient or widen the proposal)")
    few = finite & (counts > 0) & (counts < required - 0.5)
    if few.any():
        worst = np.argmin(np.where(few, counts, np.inf))
        reasons.append(f"only {counts[worst]:.0f} of {n[worst]:.0f} values f/p are nonzero (at least "
                       f"{required[worst]:.0f} are needed to judge the estimate): the sampler rarely reaches where f "
                       "is nonzero (orient or widen the proposal, or take more samples)")
    heavy = finite & (khat >= KHAT_VARIANCE)
    if heavy.any():
        worst = float(np.max(np.where(heavy, khat, -np.inf)))
        what = ("the mean itself is unreliable, and more samples barely help" if worst >= KHAT_MEAN
                else "the variance is infinite, so the stderr means nothing")
        reasons.append(f"Pareto k-hat of the tail of |f/p| is {worst:.2f} (>= {KHAT_VARIANCE}: {what}); "
                       "the proposal's tails are lighter than the integrand's: orient the lobe to the "
                       "integrand, widen the proposal or mix in a broader one")
    return reasons
