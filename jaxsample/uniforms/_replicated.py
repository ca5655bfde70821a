"""Shared pieces of the replicated point sets (`lattice`, `halton`, `lhs`): the layout of R
interleaved replicates, per-replicate random words, the 32-bit hash `_mix32` (Halton's digit
scrambles and the Latin hypercube's jitter), and parameter checks.

Layout (the convention of `Source`): global index g belongs to replicate g mod R, as its point
g div R. `replicate_layout` returns the point indices and replicate numbers of a window in one
of two shapes: when the window starts at a multiple of R and holds a multiple of R points (every
estimator chunk), the lanes are (count / R, R), row b holding the points offset / R + b of every
replicate, so per-replicate constants broadcast along rows (no gather); otherwise the lanes are
(count,) and the constants are gathered by replicate number.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from .index import Index, as_index, divmod_index, floordiv, index_range
from .philox import _alignment, _u32, philox4x32

# Stream words (third Philox counter word) of the point sets' randomizations. They continue the
# list in `philox` (0 random, 1 jitter, 2 Sobol' scramble) with tags far from it, so that another
# source drawing with the same key never reads the same Philox blocks.
STREAM_LATTICE = 0x4C415454   # "LATT": the lattice shifts
STREAM_HALTON = 0x48414C54    # "HALT": the digit permutations and tails
STREAM_LHS = 0x4C485321       # "LHS!": the stratum permutations and the jitter
STREAM_HAMMERSLEY = 0x48414D4D  # "HAMM": the first coordinate's shifts


def _mix32(x):
    """A bijective 32-bit mix with _mix32(0) = 0 (two multiply-xorshift rounds; the constants of
    C. Wellons' "lowbias32", found by his hash-prospector search)."""
    x = x ^ (x >> _u32(16))
    x = x * _u32(0x7FEB352D)
    x = x ^ (x >> _u32(15))
    x = x * _u32(0x846CA68B)
    return x ^ (x >> _u32(16))


def check_flag(owner: str, name: str, value) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{owner}: parameter '{name}' must be True or False; got {value!r}")
    return bool(value)


def check_dims(owner: str, dims: int, limit: int) -> int:
    if not isinstance(dims, (int, np.integer)) or not 1 <= dims <= limit:
        raise ValueError(f"{owner}: parameter 'dims' must be an integer in [1, {limit}]; got {dims!r}")
    return int(dims)


def replicate_words(seed, replicates: int, columns: int, stream: int, word: int = 0, by_column: bool = False):
    """Four (replicates, columns) uint32 arrays: Philox of (r, c, stream, word) under the seed.

    Each (replicate, column) pair reads its own counter, so the words are independent across
    replicates and columns (the property the point sets' error bars rest on). `by_column`: the
    same words laid out (columns, replicates), so that a lane reading column c's words for its
    replicates reads one contiguous row (read as a column of the other layout, the row is strided,
    and LLVM vectorizes the lanes' inner loop over replicates poorly: `lhs`)."""
    axes = (1, 0) if by_column else (0, 1)
    shape = (columns, replicates) if by_column else (replicates, columns)
    replicate = jax.lax.broadcasted_iota(jnp.uint32, shape, axes[0])
    column = jax.lax.broadcasted_iota(jnp.uint32, shape, axes[1])
    return philox4x32((replicate, column, jnp.full_like(column, _u32(stream)), jnp.full_like(column, _u32(word))),
                      (seed[..., 0, None, None], seed[..., 1, None, None]))


class Layout:
    """Point indices (`point`, an `Index`) and replicate numbers of a window; `take(table)` reads
    a per-replicate table (first axis R) at each lane's replicate, broadcastable to `shape`."""

    def __init__(self, offset, count: int, replicates: int, aligned):
        self.replicates = replicates
        start = as_index(offset, count)
        static_offset = isinstance(offset, (int, np.integer)) and not isinstance(offset, (bool, np.bool_))
        offset_ok = (static_offset and int(offset) % replicates == 0) or _alignment(aligned) % replicates == 0
        self.rows = count % replicates == 0 and offset_ok and count > 0
        if self.rows:
            per = count // replicates
            point = index_range(floordiv(start, replicates), per)
            self.point = Index(None if point.hi is None else point.hi[:, None], point.lo[:, None])
            self.replicate = None
            self.shape = (per, replicates)
        else:
            point, replicate = divmod_index(index_range(start, count), replicates)
            self.point = point
            self.replicate = replicate.astype(jnp.int32)
            self.shape = (count,)

    def take(self, table):
        if self.rows:
            return table[None, :]
        return table[self.replicate]

    def full(self, x):
        """x broadcast to the lanes' shape (what `Source.lanes` hands over)."""
        return jnp.broadcast_to(x, self.shape)


def stack_lanes(lanes, shape_count: int):
    """(count, dims) points from one group of lanes in C order (`Source.block`'s form)."""
    return jnp.stack([lane.reshape(shape_count) for lane in lanes], axis=-1)


def wide_mulhi(x: jax.Array, multiplier) -> jax.Array:
    """floor(x m / 2^32) for uint32 x and a uint32 array or constant m (exact, in uint64)."""
    with jax.enable_x64(True):
        product = x.astype(jnp.uint64) * jnp.asarray(multiplier).astype(jnp.uint64)
        return (product >> jnp.uint64(32)).astype(jnp.uint32)


__all__ = ["Layout", "replicate_words", "check_dims", "check_flag", "stack_lanes", "wide_mulhi",
           "STREAM_LATTICE", "STREAM_HALTON", "STREAM_LHS", "STREAM_HAMMERSLEY"]


def store_all_but(lanes: list, keep: int, token) -> list:
    """`lanes` with all but the last `keep` computed in loops of their own and stored
    (`computed_once`, bit for bit the same values); the last `keep` stay free to fuse with their
    consumer. Why: a chunk's single fusion that computes many coordinates reads one small buffer
    of per-replicate words per coordinate and word, and past about 128 such buffers LLVM's loop
    vectorizer declines the loop (its runtime alias checks exceed `-vectorize-memory-check-threshold`,
    128): the whole chunk then runs scalar. Measured (`estimate` of sum x^2 over a d-dim
    `UniformBox`, n = 2^22, 2-core AVX-512 CPU): the Latin hypercube went from 9.6 ns at d = 24 to
    61 ns at d = 28, Halton from 29 ns at d = 48 to 88 ns at d = 56; raising the LLVM option
    through `--xla_backend_extra_options` removed both cliffs, confirming the cause. Storing the
    leading lanes costs memory traffic but keeps every loop vectorized."""
    if len(lanes) <= keep:
        return list(lanes)
    from .._core.computed_once import computed_once

    return list(computed_once(lanes[:-keep], token)) + list(lanes[-keep:])

