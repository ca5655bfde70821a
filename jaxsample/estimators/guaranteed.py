"""Estimates with a guaranteed error bound from lattices and digital nets: `estimate_guaranteed`.

`estimate_until` stops on a standard error: a statistical statement (the interval covers the
integral in about 95 % of keys). For a randomly shifted rank-1 lattice and a digitally shifted
Sobol' net the literature gives a deterministic one instead: Hickernell & Jiménez Rugama,
"Reliable adaptive cubature using digital sequences" (MCQMC 2014, Springer 2016) for nets, and
Jiménez Rugama & Hickernell, "Adaptive multidimensional integration based on rank-1 lattices"
(MCQMC 2014, Springer 2016) for lattices; the MATLAB toolbox GAIL implements both (cubSobol_g,
cubLattice_g), and qmcpy does as well (CubQMCNetG, CubQMCLatticeG). This module follows their
algorithm in its own code.

The idea. Expand the integrand in the basis the point set integrates exactly except for aliasing:
complex exponentials exp(2 pi i h.x) for a lattice, Walsh functions for a digital net. With
N = 2^m points, the rule's error is the sum of the Fourier (Walsh) coefficients f^(h) over the
nonzero wavenumbers h that the rule aliases onto wavenumber 0 (its dual lattice or dual net).
Those coefficients are not known, but N discrete coefficients are: the DFT (Walsh-Hadamard
transform) of the N values, y~_kappa = (1/N) sum_k y_k exp(-2 pi i k kappa / N), is exactly the
sum of the f^(h) aliased onto kappa. For integrands in a *cone* of functions whose coefficients
decay in a sensible way (the definition bounds sums of large-wavenumber coefficients by sums of
smaller ones, with constants omega), the error is at most

    err(m) = fudge(m) S~(m - r, m),   S~(l, m) = sum over kappa~ in [2^(l-1), 2^l) of |y~_kappa~|,

where kappa~ orders the N discrete coefficients so that each one's aliases at smaller m come
first (the map is built from the values: at each level l the pair kappa, kappa + 2^l that share
a coefficient at 2^l points is swapped when the later one is the larger). Defaults as GAIL's:
r = 4 (the lag), fudge(m) = 5 2^-m, m_min = 10. The *necessary condition* of the cone (sums
S~(l, m) at different m must be consistent, within factors 1 / (1 +- omega^(m - l) omega°(m - l)))
is checked at every m; when it fails, the integrand is outside the cone, the bound is not
guaranteed, and `in_cone` is False.

Stopping: after 2^m points per replicate (m = m_min, m_min + 1, ...), stop when
err <= max(atol, rtol (|q| - err)): then |I - q| <= err <= max(atol, rtol |I|) for every
integrand in the cone, since |I| >= |q| - err. (GAIL shifts q to an "optimal" estimate under a
relative tolerance so as to stop slightly sooner; we keep the plain mean, so that
mean +- error_bound is the interval the guarantee is about.)

Replicates. The sources have R >= 2 independent randomizations (`Lattice`, `Sobol`); the bound is
computed for each replicate's rule on its own, and since the estimate is the mean of the R
replicate means, its error is at most the mean of their bounds. The spread of the R means gives
`stderr` too, a statistical cross-check on the bound. Fewer replicates give tighter bounds for
the same points, so the default here is R = 2 (the fewest a source has).

Cost and limits. The loop over m runs on the host (the number of points is decided by the values
seen), so the function cannot be traced (`jit`, `vmap`, `grad` refuse it: differentiate
`jaxsample.estimate(..., n_used)` instead). The values are drawn in chunks by one compiled
program, but all of them are kept (float64, n_used x components) for the transforms: memory
O(n_used), unlike `estimate_until`'s constant memory.
"""

from __future__ import annotations

import math
import warnings
from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np

from .._core.counts import check_count
from .._core.params import resolve_float_dtype
from .._core.pytree import Pytree, static_field
from ..samplers.base import check_sampler, check_uniforms, checked
from ..uniforms import Lattice, Sobol, as_key, seed_from_key
from .diagnostics import UnreliableEstimateWarning
from .integrand import integrand_layout
from .plain import packed_values

__all__ = ["GuaranteedEstimate", "estimate_guaranteed", "lattice_coefficients", "net_coefficients"]

LAG = 4                      # r: the coefficients S~ sums lie r levels below the current m
MIN_LEVEL = 10               # m_min: 2^10 points per replicate before the first test
MAX_POINTS = 1 << 30         # the values are kept on the host (~100 bytes per point and component)


def fudge(m) -> float:
    """GAIL's default inflation factor of the cone, 5 2^-m (m may be an int or a numpy array)."""
    return 5.0 * np.exp2(-np.asarray(m, dtype=np.float64))


class GuaranteedEstimate(Pytree):
    """The result of `estimate_guaranteed`.

    `mean` (the estimate: the mean over all n_used points), `error_bound` (|integral - mean| <=
    error_bound for every integrand in the cone, see the module docstring), `stderr` (the spread of
    the R replicate means, a statistical cross-check), `n_used` (points used, R 2^m), `converged`
    (every component met the tolerance before `max_n`), `in_cone` (the necessary conditions of the
    cone held at every step: False means the integrand is outside the cone and the bound is not
    guaranteed; True is necessary, not sufficient). A complex leaf has the bound of each part as
    the real and imaginary parts of its `error_bound` (the box `interval()` holds the integral),
    and |integral - mean| <= abs(error_bound) is what its tolerance was held to.
    """

    mean: jax.Array
    error_bound: jax.Array
    stderr: jax.Array
    n_used: jax.Array
    converged: jax.Array
    in_cone: jax.Array
    max_n: int = static_field(default=0)
    replicates: int = static_field(default=2)

    @property
    def n(self) -> jax.Array:
        """The points used (`n_used`), the name `Estimate` gives it."""
        return self.n_used

    def interval(self) -> tuple[jax.Array, jax.Array]:
        """mean -+ error_bound: contains the integral for every integrand in the cone (no level: the
        bound is deterministic given the points). `in_cone` False proves the integrand is outside
        it; True does not prove it is inside (a spike no point has hit looks smooth)."""
        return self.mean - self.error_bound, self.mean + self.error_bound


# ---------------------------------------------------------------------------------------------
# The discrete transforms: values in the order the source draws them -> coefficients y~_kappa
# ---------------------------------------------------------------------------------------------

def _bit_reversed(m: int) -> np.ndarray:
    """rev_m(k) for k < 2^m: the m bits of k in reverse order."""
    k = np.arange(1 << m, dtype=np.int64)
    out = np.zeros_like(k)
    for b in range(m):
        out |= ((k >> b) & 1) << (m - 1 - b)
    return out


def lattice_coefficients(values: np.ndarray) -> np.ndarray:
    """The DFT of 2^m lattice values given in the extensible order of `uniforms.Lattice`.

    Point i < 2^m of a replicate is frac(phi_2(i) z + Delta) with phi_2(i) = rev_m(i) / 2^m, i.e.
    the lattice point k = rev_m(i) of the rule frac(k z / 2^m + Delta). So the values in lattice
    order are values[rev_m(k)], and y~_kappa = (1/N) sum_k values[rev_m(k)] exp(-2 pi i k kappa / N)
    along axis 0 (complex, same shape).
    """
    n = values.shape[0]
    m = n.bit_length() - 1
    if n != 1 << m:
        raise ValueError(f"lattice_coefficients: need 2^m values along axis 0; got {n}")
    return np.fft.fft(values[_bit_reversed(m)], axis=0) / n


def net_coefficients(values: np.ndarray) -> np.ndarray:
    """The Walsh-Hadamard transform of 2^m digital-net values in index order (`uniforms.Sobol`).

    Point i of a digitally shifted net is C i xor e (digits of i times the generator matrices), so
    a Walsh function (-1)^(h . x) takes the value (-1)^(C^T h . i) (-1)^(h . e) at point i:
    y~_kappa = (1/N) sum_i (-1)^popcount(kappa & i) values[i], along axis 0 (real, same shape).
    """
    n = values.shape[0]
    m = n.bit_length() - 1
    if n != 1 << m:
        raise ValueError(f"net_coefficients: need 2^m values along axis 0; got {n}")
    y = np.asarray(values, dtype=np.float64)
    rest = y.shape[1:]
    half = 1
    while half < n:
        # Pairs differing in bit log2(half) of the index: (a + b, a - b).
        blocks = y.reshape((n // (2 * half), 2, half) + rest)
        y = np.stack([blocks[:, 0] + blocks[:, 1], blocks[:, 0] - blocks[:, 1]], axis=1).reshape(y.shape)
        half *= 2
    return y / n


# ---------------------------------------------------------------------------------------------
# The ordering kappa~ and the cone's sums
# ---------------------------------------------------------------------------------------------

def reorder(order: np.ndarray, magnitude: np.ndarray, levels) -> np.ndarray:
    """Update the ordering `order` (N, K: column k orders component k's coefficients) at `levels`
    (descending). At level l, positions p and p + 2^l (0 < p < 2^l) hold coefficients that alias
    onto one coefficient at 2^l points; where the later one is the larger in magnitude, the two
    swap, and so do positions p + j 2^(l+1) and p + 2^l + j 2^(l+1) for every j (their aliases)."""
    n, width = order.shape
    columns = np.arange(width)
    for level in levels:
        low = 1 << level
        blocks = order.reshape(n // (2 * low), 2 * low, width)
        earlier = magnitude[blocks[0, 1:low], columns]
        later = magnitude[blocks[0, low + 1:], columns]
        swap = later > earlier
        first, second = blocks[:, 1:low].copy(), blocks[:, low + 1:].copy()
        blocks[:, 1:low] = np.where(swap, second, first)
        blocks[:, low + 1:] = np.where(swap, first, second)
        order = blocks.reshape(n, width)
    return order


def level_sum(order: np.ndarray, magnitude: np.ndarray, level: int) -> np.ndarray:
    """S~(level): the sum of |y~| over ordered positions [2^(level-1), 2^level), per column."""
    rows = order[1 << (level - 1):1 << level]
    return magnitude[rows, np.arange(order.shape[1])].sum(axis=0)


class _Cone:
    """The rule's state for K columns: the ordering and the necessary condition's running bounds."""

    def __init__(self, min_level: int, max_level: int, width: int):
        self.min_level, self.width = min_level, width
        self.first = min_level - LAG     # l*: the lowest level whose sums the necessary condition reads
        self.lower = np.full((max_level - self.first + 1, width), -np.inf)
        self.upper = np.full((max_level - self.first + 1, width), np.inf)
        self.order = None

    def update(self, coefficients: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
        """(error bound per column, necessary condition holds per column) at 2^m points."""
        magnitude = np.abs(coefficients)
        if self.order is None:
            start = np.broadcast_to(np.arange(1 << m)[:, None], (1 << m, self.width)).copy()
            self.order = reorder(start, magnitude, range(m - 1, 0, -1))
        else:
            grown = np.concatenate([self.order, self.order + (1 << (m - 1))], axis=0)
            self.order = reorder(grown, magnitude, range(m - 1, max(m - LAG, 1) - 1, -1))
        bound = fudge(m) * level_sum(self.order, magnitude, m - LAG)
        # Necessary condition: for every level l in [l*, m], the sum S~(l) at 2^m points, scaled
        # by 1 / (1 +- omega^(m - l) omega°(m - l)), brackets the same quantity at every m.
        for level in range(self.first, m + 1):
            shrink = _omega_hat(m - level) * 2.0 ** -(m - level)
            total = level_sum(self.order, magnitude, level)
            row = level - self.first
            self.lower[row] = np.maximum(self.lower[row], total / (1.0 + shrink))
            if shrink < 1.0:
                self.upper[row] = np.minimum(self.upper[row], total / (1.0 - shrink))
        holds = np.all(self.lower <= self.upper, axis=0)
        return bound, holds


def _omega_hat(k: int) -> float:
    """GAIL's omega^(k) = fudge(k) / ((1 + fudge(r)) omega°(r)), omega°(r) = 2^-r."""
    return float(fudge(k) / ((1.0 + fudge(LAG)) * 2.0 ** -LAG))


# ---------------------------------------------------------------------------------------------
# The estimator
# ---------------------------------------------------------------------------------------------

def _source_of(uniforms):
    if isinstance(uniforms, str):
        if uniforms == "lattice":
            return Lattice(replicates=2), lattice_coefficients
        if uniforms == "sobol":
            return Sobol(replicates=2, scramble="lms"), net_coefficients
    elif isinstance(uniforms, Lattice):
        return uniforms, lattice_coefficients
    elif isinstance(uniforms, Sobol) and uniforms.scramble == "lms" and not uniforms.padding:
        return uniforms, net_coefficients
    raise ValueError("estimate_guaranteed: parameter 'uniforms' must be 'lattice' (Lattice(replicates=2)), 'sobol' "
                     "(Sobol(replicates=2, scramble='lms')), a Lattice, or a Sobol(scramble='lms', padding=False): "
                     "the bound reads the Fourier coefficients of a shifted lattice or the Walsh coefficients of a "
                     f"digitally shifted net (the Owen scramble and padding are neither); got {uniforms!r}")


def _refuse_traced(sampler, key) -> None:
    if any(isinstance(leaf, jax.core.Tracer) for leaf in jax.tree_util.tree_leaves((sampler, key))):
        raise TypeError("estimate_guaranteed: cannot run under jit, vmap or grad (it decides on the host, from the "
                        "values, how many points to draw). Call it outside, then use jaxsample.estimate(..., n) "
                        "with the n_used it returned inside the transformation.")


_PROGRAMS: dict = {}      # (id(f), source, chunk, dims, dtype, layout) -> (f, compiled chunk program)
_MAX_PROGRAMS = 16        # the oldest is dropped beyond this (each holds f, its closure and a program)


def _chunk_program(f, source, chunk: int, dims: int, dtype, layout):
    """The compiled program of Y = f(x)/p(x) for the points [offset, offset + chunk) of the stream,
    with the sampler and the seed traced: a second call with the same integrand *object* and new
    parameters or a new key reuses it. Keyed on f's identity (never its hash or equality: two
    callables that compare equal may compute different things) and on its output layout."""
    key = (id(f), source, chunk, dims, dtype, layout)
    hit = _PROGRAMS.get(key)
    if hit is not None and hit[0] is f:
        return hit[1]

    @jax.jit
    def chunk_values(sampler, seed, offset):
        u = source.block(seed, offset, chunk, dims, dtype, aligned=chunk)
        return packed_values(f, sampler, u, "attached", owner="estimate_guaranteed", boundary=False)[0]

    if len(_PROGRAMS) >= _MAX_PROGRAMS:
        _PROGRAMS.pop(next(iter(_PROGRAMS)))
    _PROGRAMS[key] = (f, chunk_values)
    return chunk_values


def _moduli(layout, packed: np.ndarray) -> np.ndarray:
    """|component| of a packed float64 vector, both parts of a complex leaf getting the modulus of
    the pair (NumPy, in float64: `IntegrandLayout.magnitudes` on the host's values)."""
    if layout.plain:
        return np.abs(packed)
    out = np.abs(packed)
    for leaf in layout.leaves:
        if leaf.is_complex:
            real = slice(leaf.start, leaf.start + leaf.size)
            imaginary = slice(leaf.start + leaf.size, leaf.start + 2 * leaf.size)
            modulus = np.hypot(packed[..., real], packed[..., imaginary])
            out[..., real], out[..., imaginary] = modulus, modulus
    return out


def tolerance_met(size: np.ndarray, bound: np.ndarray, atol: float, rtol: float) -> bool:
    """Whether bound <= max(atol, rtol (size - bound)) in every component (size = |mean|): then
    |I - mean| <= bound <= max(atol, rtol |I|), since |I| >= |mean| - bound."""
    return bool(np.all(bound <= np.maximum(atol, rtol * np.maximum(size - bound, 0.0))))


def rounded(mean: np.ndarray, bound: np.ndarray, dtype) -> tuple[np.ndarray, np.ndarray]:
    """(mean, bound) in the output `dtype`: the bound grows by the rounding of the mean and is
    rounded up, so that |I - mean| <= bound still holds for the numbers returned."""
    out = mean.astype(dtype)
    widened = bound + np.abs(mean - out.astype(np.float64))
    up = widened.astype(dtype)
    up = np.where(up.astype(np.float64) < widened, np.nextafter(up, np.asarray(np.inf, dtype=dtype)), up)
    return out, up


def _refuse_closed_over_tracers(f, sampler, dims: int, dtype) -> None:
    closed = jax.make_jaxpr(lambda u: f(sampler.warp(u)))(jax.ShapeDtypeStruct((dims,), dtype)).consts
    if any(isinstance(c, jax.core.Tracer) for c in closed):
        raise TypeError("estimate_guaranteed: the integrand closes over a value being traced by jit, vmap or grad; "
                        "it cannot run under them (it decides on the host, from the values, how many points to "
                        "draw). Call it outside, then use jaxsample.estimate(..., n) with the n_used it returned "
                        "inside the transformation.")


def estimate_guaranteed(f: Callable[[jax.Array], jax.Array], sampler, key: jax.Array, *, max_n: int,
                        rtol: float | None = None, atol: float | None = None, min_n: int | None = None,
                        uniforms="lattice", dtype=None) -> GuaranteedEstimate:
    """∫ f dμ with a deterministic error bound, to max(atol, rtol |∫ f dμ|), at most `max_n` points.

    Draws R 2^m points (m = m_min, m_min + 1, ...) of a randomly shifted lattice or a digitally
    shifted Sobol' net, warps them by `sampler` (Y = f(x)/p(x), as `jaxsample.estimate`), and stops
    as soon as the bound of Hickernell and Jiménez Rugama (module docstring) meets the tolerance in
    every component. The bound holds for integrands in their cone (smooth ones; `in_cone` says
    whether the necessary condition held): |∫ f dμ - mean| <= error_bound.

    Args:
      f, sampler, key, dtype: as in `estimate` (f may return a pytree of real or complex arrays;
        each component gets its bound). The sampler must be unbatched.
      max_n: the most points, R 2^m, at most 2^30 (the host keeps about 100 bytes per point and
        component for the transforms).
      rtol, atol: relative and absolute tolerances on the error (at least one, >= 0).
      min_n: points of the first test, R 2^m_min (default R 2^10, GAIL's; m_min >= 5).
      uniforms: "lattice" (default: `Lattice(replicates=2)`, tent transform on), "sobol"
        (`Sobol(replicates=2, scramble="lms")`), or such a source with any R >= 2 (the bound is
        averaged over replicates, so fewer replicates give a tighter bound for the same points).

    Runs on the host: not under `jit`, `vmap` or `grad` (a worded TypeError, also for an integrand
    closing over a traced value). Memory grows with n_used (the values are kept for the
    transforms). The returned mean is rounded to `dtype` and the bound widened by that rounding
    (and rounded up), so the guarantee is about the numbers returned: a tolerance below the
    float32 spacing of the integral cannot be met in float32 (use float64 with x64).

    The compiled program is cached per integrand object (its identity, not its equality): pass
    the same function to reuse it; a changed global or closure variable that f reads is not seen
    by a cached program (as with `jax.jit`).
    """
    owner = "estimate_guaranteed"
    from .until import _check_tolerances

    rtol_, atol_ = _check_tolerances(rtol, atol, owner, "the error bound")
    check_sampler(owner, "sampler", sampler)
    _refuse_traced(sampler, key)
    if sampler.batch_shape:
        raise ValueError(f"{owner}: parameter 'sampler' must be unbatched (batch_shape {sampler.batch_shape} given); "
                         "call it once per member")
    source, transform = _source_of(uniforms)
    check_uniforms(sampler, source, owner)
    replicates = source.replicates
    max_n = check_count(owner, "max_n", max_n, minimum=1, maximum=MAX_POINTS)
    per = max_n // replicates
    if max_n % replicates or per & (per - 1):
        raise ValueError(f"{owner}: parameter 'max_n' must be R 2^m (R = {replicates} replicates); got {max_n}")
    max_level = per.bit_length() - 1
    if min_n is None:
        min_level = min(MIN_LEVEL, max_level)
    else:
        min_n = check_count(owner, "min_n", min_n, minimum=1, maximum=max_n)
        first = min_n // replicates
        if min_n % replicates or first & (first - 1):
            raise ValueError(f"{owner}: parameter 'min_n' must be R 2^m (R = {replicates} replicates); got {min_n}")
        min_level = first.bit_length() - 1
    if min_level < LAG + 1:
        raise ValueError(f"{owner}: 'min_n' and 'max_n' must hold at least 2^{LAG + 1} points per replicate "
                         f"(the bound reads coefficients {LAG} levels below the points); got "
                         f"{replicates << min_level} with R = {replicates}")
    dtype = resolve_float_dtype(owner, dtype)
    layout = integrand_layout(f, sampler, dtype, owner)
    dims = sampler.uniform_dims
    _refuse_closed_over_tracers(f, sampler, dims, dtype)
    sampler = checked(sampler)
    seed = seed_from_key(as_key(key, owner))
    chunk = replicates << min_level
    chunk_values = _chunk_program(f, source, chunk, dims, np.dtype(dtype), layout)

    width = layout.width
    values = np.zeros((0, replicates * width))
    cone = _Cone(min_level, max_level, replicates * width)
    agreed = True
    for m in range(min_level, max_level + 1):
        start = 0 if m == min_level else replicates << (m - 1)
        fresh = [np.asarray(chunk_values(sampler, seed, jnp.uint32(offset)), dtype=np.float64)
                 for offset in range(start, replicates << m, chunk)]
        # Global index g = i R + r is point i of replicate r: rows i, columns (r, component).
        fresh = np.concatenate(fresh).reshape(-1, replicates * width)
        if not np.all(np.isfinite(fresh)):
            raise ValueError(f"{owner}: the integrand returned a non-finite value f(x)/p(x) at some of the first "
                             f"{replicates << m} points; an error bound needs finite values")
        values = np.concatenate([values, fresh])
        bounds, holds = cone.update(transform(values), m)
        means = values.mean(axis=0).reshape(replicates, width)
        per_replicate = bounds.reshape(replicates, width)
        # The estimate is the mean of the R replicate means, so its error is at most the mean of
        # their bounds (part by part for a complex leaf, whose tolerance then reads the modulus of
        # the pair: |error| <= hypot(bound_re, bound_im)).
        mean, bound = rounded(means.mean(axis=0), per_replicate.mean(axis=0), dtype)
        # A second necessary condition, from the replicates: if every replicate's bound holds, the
        # intervals q_r -+ err_r all contain the integral, so they share a point.
        agreed &= bool(np.all(np.max(means - per_replicate, axis=0) <= np.min(means + per_replicate, axis=0)))
        met = tolerance_met(_moduli(layout, mean.astype(np.float64)), _moduli(layout, bound.astype(np.float64)),
                            atol_, rtol_)
        if met:
            break
    in_cone = bool(np.all(holds) and agreed)
    if not in_cone:
        warnings.warn(f"{owner}: the integrand failed a necessary condition of the cone (its Fourier or Walsh "
                      "coefficients do not decay consistently, or the replicates' intervals do not overlap): "
                      "error_bound is not guaranteed. A spike or a discontinuity the first points do not resolve "
                      "does this, and on Sobol' nets at tight tolerances so can a smooth integrand's irregular "
                      "Walsh coefficients (2-3 keys of 16 at 1e-5 in the benchmark); use estimate_until's "
                      "standard error, the lattice, or a larger min_n", UnreliableEstimateWarning, stacklevel=2)
    stderr = means.std(axis=0, ddof=1) / math.sqrt(replicates)
    shape = layout.out_shape

    def as_array(x):
        return jnp.asarray(np.asarray(x).reshape(shape), dtype=dtype)

    result = GuaranteedEstimate(mean=as_array(mean), error_bound=as_array(bound), stderr=as_array(stderr),
                                n_used=jnp.asarray(replicates << m), converged=jnp.asarray(met),
                                in_cone=jnp.asarray(in_cone), max_n=max_n, replicates=replicates)
    return layout.unpack_result(result, fields=("mean", "error_bound", "stderr"))
