"""Philox4x32-10 (Salmon et al. 2011) in jnp integer arithmetic, and its map from bits to floats.

See `jaxsample.uniforms.sources` for the streams it feeds and the float grid of `bits_to_unit`.
The key rule (`as_key`, `seed_from_key`, `SEED_WORDS`) is `jaxsample._core.keys`, exported here.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

# The key rule, exported here (explicit re-exports).
from .._core.keys import SEED_WORDS as SEED_WORDS, as_key as as_key, seed_from_key as seed_from_key
from .index import Index, as_index, floordiv, index_range

# Philox4x32 constants (Salmon et al. 2011, section 5): multipliers and Weyl key increments.
_PHILOX_M0 = 0xD2511F53
_PHILOX_M1 = 0xCD9E8D57
_PHILOX_W0 = 0x9E3779B9
_PHILOX_W1 = 0xBB67AE85

# The third counter word separates the uses of one key, so that no two draw the same block.
_STREAM_RANDOM = 0
_STREAM_JITTER = 1
_STREAM_SCRAMBLE = 2


def _u32(x) -> jax.Array:
    return jnp.asarray(x, dtype=jnp.uint32)


def philox4x32(counter, key, rounds: int = 10):
    """Philox4x32-`rounds` of a 4-word counter under a 2-word key; every word a uint32 array.

    Round: (c0, c1, c2, c3) -> (hi(M1 c2) ^ c1 ^ k0, lo(M1 c2), hi(M0 c0) ^ c3 ^ k1, lo(M0 c0)),
    with the key bumped by the Weyl constants between rounds (Salmon et al. 2011, eq. 3).

    Each 32-bit word is carried in a uint64 lane (value < 2^32) from the first round to the last,
    so that a round is one 32x32->64 multiply (`(c & mask) * M` is the pattern LLVM lowers to
    vpmuludq), a shift and a mask, with no widening or narrowing shuffles in between; on this
    project's AVX-512 CPU that made the estimator of ∫cos³ 1.3-1.4x faster than uint32 words
    widened per multiply (benchmarks/bench_estimator.py). uint64 needs the x64 flag at trace
    time: it is switched on only inside this function, whose inputs and outputs are uint32.
    """
    with jax.enable_x64(True):
        mask = jnp.uint64(0xFFFFFFFF)
        shift = jnp.uint64(32)
        c0, c1, c2, c3 = (_u32(c).astype(jnp.uint64) for c in counter)
        k0, k1 = (_u32(k).astype(jnp.uint64) for k in key)
        for round_index in range(rounds):
            if round_index:
                k0 = (k0 + jnp.uint64(_PHILOX_W0)) & mask
                k1 = (k1 + jnp.uint64(_PHILOX_W1)) & mask
            product0 = (c0 & mask) * jnp.uint64(_PHILOX_M0)
            product1 = (c2 & mask) * jnp.uint64(_PHILOX_M1)
            c0, c1, c2, c3 = ((product1 >> shift) ^ c1 ^ k0, product1 & mask,
                              (product0 >> shift) ^ c3 ^ k1, product0 & mask)
        return tuple(c.astype(jnp.uint32) for c in (c0, c1, c2, c3))


def bits_to_unit(bits: jax.Array, dtype) -> jax.Array:
    """uint32 bits -> the midpoint of one of 2^23 (float32) or 2^32 (float64) equal cells of (0, 1)."""
    dtype = jnp.dtype(dtype)
    if dtype == jnp.float64:
        return (bits.astype(jnp.float64) + 0.5) * (2.0 ** -32)
    if dtype != jnp.float32:
        raise ValueError(f"uniforms: dtype must be float32 or float64; got {dtype}")
    # The top 23 bits fit an int32, whose conversion to float is one vector instruction (the
    # unsigned one is not); (k + 1/2) 2^-23 is then exact in float32.
    top = (bits >> _u32(9)).astype(jnp.int32).astype(jnp.float32)
    return top * np.float32(2.0 ** -23) + np.float32(2.0 ** -24)


def _index_words(offset, count: int) -> Index:
    """Global indices offset + [0, count) as an `Index` (two uint32 words where the window passes
    2^32; see `jaxsample.uniforms.index`)."""
    return index_range(offset, count)


def _philox_words(seed, block_index, stream: int, word_block: int = 0):
    """Philox of the counter (i mod 2^32, word_block, stream, i div 2^32) for block index i (a
    uint32 array or an `Index`): below 2^32 the last word is 0."""
    block = block_index if isinstance(block_index, Index) else Index(None, _u32(block_index))
    low = block.lo
    high = jnp.zeros_like(low) if block.hi is None else block.hi
    return philox4x32((low, jnp.zeros_like(low) + _u32(word_block), jnp.zeros_like(low) + _u32(stream), high),
                      (seed[..., 0], seed[..., 1]))


def _samples_per_block(dims: int) -> int:
    return 4 // dims if dims <= 4 else 1


def random_bits(seed, offset, count: int, dims: int, stream: int = _STREAM_RANDOM,
                aligned: int | bool = False) -> jax.Array:
    """(count, dims) uint32 words for global sample indices [offset, offset + count).

    Layout: with g = 4 // dims samples per Philox block (dims <= 4), sample i takes words
    (i mod g) * dims ... of the block with counter (i // g mod 2^32, 0, stream, i // g div 2^32);
    with dims > 4, sample i takes the blocks (i mod 2^32, j, stream, i div 2^32), j = 0, 1, ...
    So sample i depends only on (seed, i), for any i below 2^64. `offset` may be traced (a uint32
    array, or an `Index` past 2^32). `aligned` promises that offset is a multiple of it (True: of
    4; the estimators' chunks), which lets a traced offset skip the spare block and the dynamic
    slice of the general path.
    """
    g = _samples_per_block(dims)
    if dims > 4:
        index = _index_words(offset, count)
        words = []
        for j in range(-(-dims // 4)):
            words.extend(_philox_words(seed, index, stream, j))
        return jnp.stack(words[:dims], axis=-1)
    static_offset = isinstance(offset, (int, np.integer))
    start = as_index(offset, count)
    if _alignment(aligned) % g == 0 or (static_offset and offset % g == 0):
        blocks = -(-count // g)
        first = index_range(floordiv(start, g), blocks)
        words = jnp.stack(_philox_words(seed, first, stream), axis=-1)  # (blocks, 4)
        samples = words[:, : g * dims].reshape(blocks * g, dims)
        return samples[:count]
    # A traced or unaligned offset: compute one spare block and cut the window out of it (g
    # divides 2^32, so the low word alone gives the offset's position in its block).
    blocks = count // g + 2
    first = index_range(floordiv(start, g), blocks)
    words = jnp.stack(_philox_words(seed, first, stream), axis=-1)
    samples = words[:, : g * dims].reshape(blocks * g, dims)
    return jax.lax.dynamic_slice_in_dim(samples, (start.lo % _u32(g)).astype(jnp.int32), count, axis=0)


def _alignment(aligned) -> int:
    """`aligned` as the integer the offset is known to be a multiple of (True: 4, False: 1)."""
    if isinstance(aligned, (bool, np.bool_)):
        return 4 if aligned else 1
    return max(int(aligned), 1)


# ----------------------------------------------------------------------------------------------
# Sources
# ----------------------------------------------------------------------------------------------
