"""Latin hypercube sampling (McKay, Beckman & Conover 1979), counter based, in R replicates.

Construction. A stream of `total` points in R replicates gives each replicate m = total / R
points. In replicate r, point p (global index g = R p + r, the `Source` convention) has
coordinate j = (pi_(r,j)(p) + U_(g,j)) / m, where pi_(r,j) is a random permutation of the m
strata [0, m) and U a uniform jitter. So every coordinate of every replicate has exactly one
point in each stratum [k / m, (k + 1) / m), every point is uniform (the estimate is unbiased),
and the replicates are independent (the spread of their means is the standard error). For an
additive integrand the variance falls faster than 1/n (the 1-D strata remove the additive part's
variance: RMSE ~ n^-1.5 for smooth additive parts); otherwise the rate stays n^-0.5 with a
smaller constant (Stein 1987; Owen 1992).

Counter based. pi_(r,j)(p) is computed from p alone: a keyed bijection of the k-bit integers
(2^k the power of two at or above m) by two rounds of x ^= key, x *= odd key, x ^= x >> ceil(k/2),
x += key, x *= odd key, x ^= x >> ceil(k/2), all mod 2^k (each step a bijection of [0, 2^k)), then
cycle walking (Black & Rogaway
2002; Kensler 2013, "Correlated multi-jittered sampling", uses the same scheme): apply it again
until the value falls below m. Cycle walking restricts a bijection of [0, 2^k) to one of
[0, m); since m > 2^(k-1), fewer than two steps are needed on average (a `lax.while_loop`, no
step at all when m is a power of two). The keys are Philox words per (replicate, coordinate), the
jitter the 32-bit hash `_mix32` (lowbias32) of the permuted stratum xor another such word, a
uniform 32-bit word per (replicate, coordinate, stratum), hence per point: point g coordinate j
depends only on the key, j, g and m. (The stratum and the jitter's word are independent draws in
distribution, the hash of distinct strata being distinct words.) The permutations are pseudo-random,
not uniformly random over all m! orders: the
tests check the strata, uniformity and independence across coordinates and replicates.

Floats: in float64 every coordinate lies in its stratum. In float32, cell + jitter is kept below
cell + 1, but the division by m rounds, so a coordinate within a float32 ulp of a stratum's upper
edge may land on it (the point is then counted in the next stratum).

Needs `total` (as `Stratified`): a multiple of R, with m = total / R at most 2^32.
`estimate_until` cannot use it (its total is not known in advance).
"""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from .philox import _u32, bits_to_unit
from .sources import Source, _check_replicates, register_source
from ._replicated import STREAM_LHS, Layout, _mix32, replicate_words, stack_lanes, store_all_but

__all__ = ["LatinHypercube", "stratum_permutation"]

STORE_PAST = 24    # more coordinates than this: all but FUSED_LANES are stored (`_replicated.store_all_but`)
FUSED_LANES = 16


def _bijection(x, keys, bits: int):
    """A keyed bijection of [0, 2^bits): rounds of xor/add, odd multiply and xorshift, mod 2^bits."""
    mask = _u32((1 << bits) - 1)
    shift = _u32(max(1, (bits + 1) // 2))
    for add, mul in keys:
        x = x ^ (add & mask)
        x = (x * (mul | _u32(1))) & mask
        x = x ^ (x >> shift)
        # The key's high bits enter too (a small k would see only its low bits otherwise).
        x = (x + (add >> _u32(16))) & mask
        x = (x * ((mul >> _u32(16)) | _u32(1))) & mask
        x = x ^ (x >> shift)
    return x


def _below_float(x):
    """nextafter(x, 0) for positive finite floats: the bit pattern minus one (as nextafter(x, y)
    for any y < x, in three vector operations)."""
    bits = jax.lax.bitcast_convert_type(x, jnp.int32 if x.dtype == jnp.float32 else jnp.int64)
    return jax.lax.bitcast_convert_type(bits - 1, x.dtype)


def stratum_permutation(p, keys, m: int):
    """pi(p) for p in [0, m) (uint32): `_bijection` on the next power of two, cycle-walked into [0, m)."""
    bits = max(0, (m - 1).bit_length())
    if bits == 0:
        return jnp.zeros_like(p)
    y = _bijection(p, keys, bits)
    if m == 1 << bits:
        return y
    return jax.lax.while_loop(lambda y: jnp.any(y >= _u32(m)),
                              lambda y: jnp.where(y >= _u32(m), _bijection(y, keys, bits), y), y)


@register_source
class LatinHypercube(Source):
    """Latin hypercube points (see the module docstring), R independent replicates (default 16).

    Args:
      replicates: an integer in [2, 2^32). `total` (the stream's points) must be a multiple of it,
        with total / replicates at most 2^32.
    """

    name: ClassVar[str] = "lhs"

    def __init__(self, replicates: int = 16):
        self.replicates = _check_replicates("LatinHypercube", replicates)

    def _per_replicate(self, total) -> int:
        if total is None:
            raise ValueError("LatinHypercube: 'total' (the number of points of the whole stream) is required")
        if total % self.replicates or not 1 <= total // self.replicates <= 1 << 32:
            raise ValueError(f"LatinHypercube: parameter 'total' must be a multiple of replicates={self.replicates} "
                             f"with total / replicates in [1, 2^32]; got {total}")
        return total // self.replicates

    def lanes(self, seed, offset, count, dims, dtype=jnp.float32, total=None, aligned=False):
        m = self._per_replicate(total)
        layout = Layout(offset, count, self.replicates, aligned)
        # (dims, R): each coordinate's words one contiguous row (read as columns of (R, dims), the
        # 3-d and 4-d programs vectorize worse and run about twice as slow as Random:
        # benchmarks/results/point-sets-paths-cpu-2core-2026-12-05.md).
        words = [replicate_words(seed, self.replicates, dims, STREAM_LHS, w, by_column=True) for w in range(2)]
        top = np.nextafter(np.array(1.0, dtype), np.array(0.0, dtype))
        p = layout.full(layout.point.lo)
        lanes = []
        for j in range(dims):
            keys = [(layout.take(words[0][0][j]), layout.take(words[0][1][j])),
                    (layout.take(words[0][2][j]), layout.take(words[0][3][j]))]
            cell = stratum_permutation(p, keys, m)
            jitter = bits_to_unit(_mix32(cell ^ layout.take(words[1][0][j])), dtype)
            # cell + jitter may round up to cell + 1 in float32 (cell above 2^(24 - 23) ...): kept below it.
            stratum = cell.astype(dtype)
            within = jnp.minimum(stratum + jitter, _below_float(stratum + 1))
            lanes.append(jnp.minimum(within / float(m), top))
        # Past STORE_PAST coordinates one fused loop is not vectorized (`store_all_but`).
        return (tuple(store_all_but(lanes, FUSED_LANES, seed[..., 0]) if dims > STORE_PAST else lanes),)

    def block(self, seed, offset, count, dims, dtype=jnp.float32, total=None, aligned=False):
        (lanes,) = self.lanes(seed, offset, count, dims, dtype, total, aligned)
        return stack_lanes(lanes, count)
