"""Sobol' points (Joe & Kuo direction numbers) and their hash-based nested uniform (Owen) scramble."""

from __future__ import annotations

import importlib.resources

import jax
import jax.numpy as jnp
import numpy as np

from .index import Index
from .philox import _u32

# ----------------------------------------------------------------------------------------------
# Sobol' points
# ----------------------------------------------------------------------------------------------

# Joe & Kuo, new-joe-kuo-6.21201 (Joe & Kuo 2008, "Constructing Sobol sequences with better
# two-dimensional projections", SIAM J. Sci. Comput. 30(5); https://web.maths.unsw.edu.au/~fkuo/sobol/),
# dimensions 2..1024, in the package file below, one per line: d, s (degree of the primitive
# polynomial), a (its inner coefficients as an integer, leading coefficient first) and the initial
# direction integers m_1 .. m_s. Dimension 1 is van der Corput's (every m_k = 1). The direction
# numbers for all 64 index bits are generated from these below.
_JOE_KUO_FILE = "new_joe_kuo_6_21201_1024.txt"


def _joe_kuo_lines() -> list[tuple[int, int, list[int]]]:
    """(s, a, [m_1 .. m_s]) of dimensions 2..MAX_SOBOL_DIMS, read from the package data file."""
    text = importlib.resources.files(__package__).joinpath(_JOE_KUO_FILE).read_text()
    rows = []
    for line in text.splitlines():
        if line.strip() and not line.startswith("#"):
            d, s, a, *m_init = (int(v) for v in line.split())
            if d != len(rows) + 2 or len(m_init) != s:
                raise RuntimeError(f"Sobol: {_JOE_KUO_FILE} is damaged at dimension {d}")
            rows.append((s, a, m_init))
    return rows


MAX_SOBOL_DIMS = 1024
_SOBOL_BITS = 32         # bits of a Sobol' fraction (value / 2^32): the precision of every point
_SOBOL_INDEX_BITS = 64   # bits of a point index: the sequence has 2^64 points per replicate
_SOBOL_CACHE: dict = {}


def _direction_table() -> np.ndarray:
    """(MAX_SOBOL_DIMS, 64) uint32: column k holds the top 32 bits of the 64-bit direction number
    V_k = m_(k+1) 2^(63-k) (Bratley & Fox 1988), i.e. m_(k+1) 2^(31-k) for k < 32 and
    m_(k+1) >> (k - 31) beyond.

    The m_k come from the primitive polynomial x^s + a_1 x^(s-1) + ... + a_(s-1) x + 1 of each
    dimension, for k > s by the recurrence
    m_k = 2^s m_(k-s) xor m_(k-s) xor (xor over i = 1..s-1 of 2^i a_i m_(k-i)) (Joe & Kuo 2008),
    in Python integers. Since xor acts bit by bit, the top 32 bits of the 64-bit point (the only
    ones a 32-bit fraction keeps) are the xor of these columns over the set bits of the index: so
    the points with indices below 2^32 are exactly those of 32-bit direction numbers, and an index
    of up to 64 bits continues the same sequence.
    """
    if "table" not in _SOBOL_CACHE:
        bits = _SOBOL_INDEX_BITS
        lines = _joe_kuo_lines()[: MAX_SOBOL_DIMS - 1]
        # The recurrence for all dimensions at once, in uint64 (m_k < 2^k, so m_k for k <= 64 fits;
        # no term overflows), one column k at a time; dimension 1 (van der Corput) has m_k = 1.
        degree = np.array([1] + [s for s, _, _ in lines], dtype=np.int64)
        inner = np.array([0] + [a for _, a, _ in lines], dtype=np.int64)
        m = np.zeros((len(degree), bits), dtype=np.uint64)
        m[0] = 1
        for d, (s, _, m_init) in enumerate(lines, start=1):
            m[d, :s] = m_init
        for k in range(1, bits):
            grow = degree <= k                       # dimensions whose initial m's are used up
            first = m[np.arange(len(degree)), np.maximum(k - degree, 0)]
            value = first ^ (first << degree.astype(np.uint64))
            for i in range(1, int(degree.max())):
                use = (i < degree) & (((inner >> np.maximum(degree - 1 - i, 0)) & 1) == 1)
                value ^= np.where(use, m[:, k - i] << np.uint64(i), np.uint64(0)) if k >= i else 0
            m[1:, k] = np.where(grow[1:], value[1:], m[1:, k])
        columns = m << (np.uint64(bits - 1) - np.arange(bits, dtype=np.uint64))
        _SOBOL_CACHE["table"] = (columns >> np.uint64(32)).astype(np.uint32)
    return _SOBOL_CACHE["table"]


def sobol_direction_numbers(dims: int, index_bits: int = _SOBOL_BITS) -> np.ndarray:
    """(dims, index_bits) uint32: V[j, k] = the top 32 bits of m_(k+1) 2^(63-k) for dimension j + 1,
    which is m_(k+1) 2^(31-k) for k < 32 (the classical 32-bit table, the default) and
    m_(k+1) >> (k - 31) for the index bits beyond (up to 64); see `_direction_table`.
    """
    if not 1 <= dims <= MAX_SOBOL_DIMS:
        raise ValueError(f"Sobol: 'dims' must be in [1, {MAX_SOBOL_DIMS}]; got {dims}")
    if not 1 <= index_bits <= _SOBOL_INDEX_BITS:
        raise ValueError(f"Sobol: 'index_bits' must be in [1, {_SOBOL_INDEX_BITS}]; got {index_bits}")
    return _direction_table()[:dims, :index_bits]


def sobol_points(index, dims: int, index_bits: int | None = None) -> jax.Array:
    """Unscrambled Sobol' points as uint32 fractions (value / 2^32), shape index.shape + (dims,).

    Natural (not Gray-code) order: point i is the xor of V[:, k] over the set bits k of i, so every
    prefix of length 2^m is the same (0, m, s)-net the Gray-code order visits. `index` is a uint32
    array or a 64-bit `uniforms.index.Index` (two words). Only the low `index_bits` bits of the
    index are read (a static bound: fewer xors for short sequences; default 32 for a uint32 index
    or a narrow `Index`, 64 for a wide one).

    Beyond 2^32 points a coordinate, which has 32 bits, cannot tell every point apart: in
    dimension 1 (van der Corput, V_k = 2^-(k+1)) points i and i + 2^32 share their 32-bit
    fraction; the higher dimensions' columns k >= 32 are not zero, so those points differ there.
    """
    if not isinstance(index, Index):
        index = Index(None, _u32(index))
    if index_bits is None:
        index_bits = _SOBOL_INDEX_BITS if index.wide else _SOBOL_BITS
    directions = jnp.asarray(sobol_direction_numbers(dims, index_bits))
    words = [(index.lo, 0)] + ([(index.hi, 32)] if index.wide else [])
    result = jnp.zeros(index.lo.shape + (dims,), dtype=jnp.uint32)
    for word, first in words:
        word = word[..., None]
        for k in range(first, min(first + 32, index_bits)):
            bit = (word >> _u32(k - first)) & _u32(1)
            result = result ^ ((_u32(0) - bit) & directions[:, k])
    return result


def _reverse_bits(x: jax.Array) -> jax.Array:
    x = ((x >> _u32(1)) & _u32(0x55555555)) | ((x & _u32(0x55555555)) << _u32(1))
    x = ((x >> _u32(2)) & _u32(0x33333333)) | ((x & _u32(0x33333333)) << _u32(2))
    x = ((x >> _u32(4)) & _u32(0x0F0F0F0F)) | ((x & _u32(0x0F0F0F0F)) << _u32(4))
    x = ((x >> _u32(8)) & _u32(0x00FF00FF)) | ((x & _u32(0x00FF00FF)) << _u32(8))
    return (x >> _u32(16)) | (x << _u32(16))


def owen_scramble(x: jax.Array, seed: jax.Array) -> jax.Array:
    """Hash-based nested uniform (Owen) scramble of 32-bit fractions (Burley 2020, section 3).

    On the bit-reversed value, adding the seed and then x ^= x * c for even constants c (Laine &
    Karras 2011; the constants are Burley's) changes each bit as a function of the less significant
    bits only; reversed back, digit k of the fraction is flipped by a function of digits 1..k-1 and
    of the seed. The seed's own bit enters every digit through the addition, so over random seeds
    each digit is a fair coin given the digits above it: each scrambled point is uniform on the 2^32
    grid while the net structure of the whole set is kept.
    """
    return _scramble_reversed(_reverse_bits(x), seed)


def _scramble_reversed(reversed_x: jax.Array, seed: jax.Array) -> jax.Array:
    """`owen_scramble` of x given reverse_bits(x) (xor commutes with the reversal, so a table of
    reversed points saves the first reversal)."""
    x = reversed_x + seed
    x = x ^ (x * _u32(0x6C50B47C))
    x = x ^ (x * _u32(0xB82F1E52))
    x = x ^ (x * _u32(0xC7AFE638))
    x = x ^ (x * _u32(0x8D22F6E6))
    return _reverse_bits(x)


def _reverse_bits_np(x: np.ndarray) -> np.ndarray:
    x = x.astype(np.uint32)
    for shift, mask in ((1, 0x55555555), (2, 0x33333333), (4, 0x0F0F0F0F), (8, 0x00FF00FF)):
        x = ((x >> np.uint32(shift)) & np.uint32(mask)) | ((x & np.uint32(mask)) << np.uint32(shift))
    return (x >> np.uint32(16)) | (x << np.uint32(16))


def _sobol_low_table(bits: int, dims: int) -> np.ndarray:
    """(2^bits, dims) uint32: bit-reversed unscrambled Sobol' points 0 .. 2^bits - 1 (NumPy)."""
    key = ("low", bits, dims)
    if key not in _SOBOL_CACHE:
        index = np.arange(1 << bits, dtype=np.uint32)[:, None]
        directions = sobol_direction_numbers(dims)
        points = np.zeros((1 << bits, dims), dtype=np.uint32)
        for k in range(bits):
            points ^= np.where((index >> np.uint32(k)) & np.uint32(1), directions[:, k], np.uint32(0))
        _SOBOL_CACHE[key] = _reverse_bits_np(points)
    return _SOBOL_CACHE[key]


# ----------------------------------------------------------------------------------------------
# Linear matrix scrambling (Matoušek 1998) and the padded 2-D Sobol' of each dimension pair
# ----------------------------------------------------------------------------------------------

# Stream words (third Philox counter word) of these randomizations: tags far from the small
# stream numbers of `philox` (0 random, 1 jitter, 2 Owen seeds) and from those of `_replicated`,
# with room below each for the block number w added to it.
STREAM_LMS = 0x534C4D00          # "SLM": the matrices of Sobol(scramble="lms"), w = 0..8
STREAM_PADDED = 0x53504100       # "SPA": the per-pair matrices and index shuffles of padding=True
STREAM_PADDED_SHIFT = 0x53505300  # "SPS": the per-pair seeds or shifts that also depend on the
                                  # high index word (each run of 2^32 points of a pair its own)

_PASCAL_MASKS = (0x55555555, 0x33333333, 0x0F0F0F0F, 0x00FF00FF, 0x0000FFFF)


def triangular_columns(words: jax.Array) -> jax.Array:
    """(..., 32) random uint32 words -> the 32 columns of a random binary triangular matrix with
    unit diagonal: column p = 2^p + (w_p mod 2^p), so that input bit p reaches output bit p and,
    with random coefficients, the bits below it, never those above.

    Read on a 32-bit fraction (bit 31 the first digit), this is Matoušek's linear matrix scramble
    (Matoušek 1998, "On the L2-discrepancy for anchored boxes", J. Complexity 14; Owen 2003,
    "Variance with alternative scramblings of digital nets", section 2): digit k of the output is
    digit k of the input plus a random linear combination of digits 1..k-1 (lower triangular in
    digit order, nonsingular in base 2 because the diagonal is 1). Read on an index (bit 0 the
    least significant), the same form is a random linear bijection under which output bit k
    depends only on input bits >= k: it maps each aligned block [c 2^m, (c + 1) 2^m) of indices
    onto an aligned block of the same size."""
    position = jnp.arange(32, dtype=jnp.uint32)
    one = _u32(1)
    return (one << position) | (words & ((one << position) - one))


def apply_columns(x: jax.Array, columns: jax.Array) -> jax.Array:
    """The GF(2) matrix-vector product: the xor of columns[..., p] over the set bits p of x.

    `columns` (..., 32) broadcasts against x.shape + (32,); the 32 terms are formed as one array
    and xor-reduced in one operation, so a batch of products (every column of a matrix, say)
    costs one traced step, not 32 per product. For the small per-(replicate, dimension) arrays
    it is meant for; per point, the callers loop over the index bits instead."""
    position = jnp.arange(32, dtype=jnp.uint32)
    bit = (x[..., None] >> position) & _u32(1)
    terms = (_u32(0) - bit) & columns
    return jax.lax.reduce(terms, _u32(0), jax.lax.bitwise_xor, (terms.ndim - 1,))


def pascal_superset_xor(y: jax.Array) -> jax.Array:
    """z_e = xor of y_k over the k whose bits contain those of e (Lucas: C(k, e) odd), in 5 steps.

    Sobol' dimension 2 has the primitive polynomial x + 1, so m_k are the rows of Pascal's triangle
    mod 2 and its 32-bit point for index y is reverse_bits(pascal_superset_xor(y)): digit e + 1 of
    the fraction is the xor of the index bits k with C(k, e) odd. This gives dims 1 and 2 of the
    padded pairs (dimension 1 is reverse_bits(y)) without a loop over the index bits."""
    for step, mask in enumerate(_PASCAL_MASKS):
        y = y ^ ((y >> _u32(1 << step)) & _u32(mask))
    return y


def scrambled_generator_columns(columns: jax.Array, directions: jax.Array) -> jax.Array:
    """The columns L V_k of the scrambled generator matrix, for scramble columns (..., 32) and
    32-bit direction numbers V (..., K): LMS acts on a digital net by left-multiplying its
    generator matrices, so the scrambled point of index i is the xor of L V_k over the bits k of i
    (exactly L applied to the unscrambled point: the two are equal bit for bit)."""
    return apply_columns(directions, columns[..., None, :])
