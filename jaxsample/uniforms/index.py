"""64-bit sample indices as two uint32 words: `Index(hi, lo)` is the index hi 2^32 + lo.

Why. A GPU draws 2^32 samples in well under a second, so the global sample index i (on which
every point of a counter-based source depends) must not wrap at 2^32. JAX without x64 has no
uint64 array type, so an index travels as two uint32 words: through the estimators' `lax.scan`
carry, across a device mesh and into the sources. Where an index is turned into a Philox counter,
the high word fills the fourth counter word, so an index below 2^32 (high word 0) gives bit for
bit the counter, and the point, of a 32-bit index.

Narrow indices. `hi` is None when every index of a stream is known, at trace time, to lie below
2^32 (the estimators know n statically: that is every stream with n <= 2^32). The arithmetic is
then the plain uint32 arithmetic, exactly the operations of a 32-bit counter, so ordinary streams
pay nothing for the wider range. A bare uint32 array given as an offset is read as narrow.

Wide arithmetic (carries, division by the replicate count) is done in uint64 inside
`jax.enable_x64(True)`, the same local switch `philox4x32` uses; only uint32 words go in and
come out, so nothing outside sees a 64-bit type.
"""

from __future__ import annotations

from typing import NamedTuple, Optional

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["Index", "NARROW_LIMIT", "MAX_INDEX", "as_index", "index_range", "offset_at",
           "floordiv", "divmod_index", "less_than", "index_value", "token"]

NARROW_LIMIT = 1 << 32   # indices below this fit one uint32 word
MAX_INDEX = 1 << 64      # indices below this fit two


class Index(NamedTuple):
    """Sample indices hi 2^32 + lo (uint32 arrays of one shape); `hi` None: known below 2^32."""

    hi: Optional[jax.Array]
    lo: jax.Array

    @property
    def wide(self) -> bool:
        return self.hi is not None


def _u32(x) -> jax.Array:
    return jnp.asarray(x, dtype=jnp.uint32)


def _is_static_int(x) -> bool:
    return isinstance(x, (int, np.integer)) and not isinstance(x, (bool, np.bool_))


def as_index(offset, count: int = 1) -> Index:
    """The first index of a window of `count` indices, as an `Index`.

    `offset` may be an `Index`, a (hi, lo) pair of uint32 words, a Python or NumPy integer below
    2^64 (narrow when offset + count <= 2^32), or an integer array: a uint32 or 32-bit one is
    narrow (the caller promises its window stays below 2^32), a 64-bit one (under x64) is split.
    """
    if isinstance(offset, Index):
        return offset
    if isinstance(offset, tuple):
        hi, lo = offset
        return Index(_u32(hi), _u32(lo))
    if _is_static_int(offset):
        value = int(offset)
        if not 0 <= value <= MAX_INDEX - max(int(count), 1):
            raise ValueError(f"uniforms: parameter 'offset' must be in [0, 2^64 - count]; got {value}")
        if value + int(count) <= NARROW_LIMIT:
            return Index(None, _u32(value))
        return Index(_u32(value >> 32), _u32(value & 0xFFFFFFFF))
    offset = jnp.asarray(offset)
    if offset.dtype.itemsize == 8 and jnp.issubdtype(offset.dtype, jnp.integer):
        with jax.enable_x64(True):
            wide = offset.astype(jnp.uint64)
            return Index((wide >> jnp.uint64(32)).astype(jnp.uint32),
                         (wide & jnp.uint64(0xFFFFFFFF)).astype(jnp.uint32))
    return Index(None, offset.astype(jnp.uint32))


def _to_u64(index: Index) -> jax.Array:
    """hi 2^32 + lo as uint64; call inside `jax.enable_x64(True)`."""
    lo = index.lo.astype(jnp.uint64)
    if index.hi is None:
        return lo
    return (index.hi.astype(jnp.uint64) << jnp.uint64(32)) | lo


def _from_u64(value: jax.Array) -> Index:
    """A uint64 array back to two uint32 words; call inside `jax.enable_x64(True)`."""
    return Index((value >> jnp.uint64(32)).astype(jnp.uint32),
                 (value & jnp.uint64(0xFFFFFFFF)).astype(jnp.uint32))


def index_range(offset, count: int) -> Index:
    """The indices offset, offset + 1, ..., offset + count - 1 (shape (count,))."""
    start = as_index(offset, count)
    if not start.wide:
        return Index(None, start.lo + jnp.arange(count, dtype=jnp.uint32))
    with jax.enable_x64(True):
        return _from_u64(_to_u64(start) + jnp.arange(count, dtype=jnp.uint64))


def offset_at(base, step, stride: int, wide: bool) -> Index:
    """base + step * stride for a uint32 `step` (traced) and a static `stride`.

    `wide` is the caller's static knowledge: False promises every result is below 2^32 (the
    operations are then those of a uint32 counter)."""
    base = as_index(base)
    if not wide:
        return Index(None, base.lo + _u32(step) * _u32(stride))
    with jax.enable_x64(True):
        product = _u32(step).astype(jnp.uint64) * jnp.uint64(stride)
        return _from_u64(_to_u64(base) + product)


def floordiv(index: Index, divisor: int) -> Index:
    """index // divisor for a static positive divisor below 2^32."""
    if not index.wide:
        return Index(None, index.lo // _u32(divisor))
    with jax.enable_x64(True):
        return _from_u64(_to_u64(index) // jnp.uint64(divisor))


def divmod_index(index: Index, divisor: int) -> tuple[Index, jax.Array]:
    """(index // divisor, index mod divisor as uint32) for a static positive divisor below 2^32."""
    if not index.wide:
        return Index(None, index.lo // _u32(divisor)), index.lo % _u32(divisor)
    with jax.enable_x64(True):
        value = _to_u64(index)
        divisor64 = jnp.uint64(divisor)
        return _from_u64(value // divisor64), (value % divisor64).astype(jnp.uint32)


def less_than(index: Index, bound: int) -> jax.Array:
    """index < bound for a static bound below 2^64."""
    if not index.wide:
        return index.lo < _u32(bound) if bound < NARROW_LIMIT else jnp.ones(index.lo.shape, bool)
    with jax.enable_x64(True):
        return _to_u64(index) < jnp.uint64(bound)


def index_value(index: Index, dtype) -> jax.Array:
    """The index as a float of `dtype` (rounded to nearest where it has more than its digits)."""
    if not index.wide:
        # The narrow form's indices are below 2^32; int32 conversion is one vector instruction
        # where the unsigned one is not, and is exact below 2^31 (the callers' range).
        return index.lo.astype(jnp.int32).astype(dtype)
    with jax.enable_x64(True):
        return _to_u64(index).astype(dtype)


def token(offset) -> jax.Array:
    """A traced uint32 scalar from an offset, for `computed_once` (any value will do)."""
    return offset.lo if isinstance(offset, Index) else offset
