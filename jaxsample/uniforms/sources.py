"""Layer 2: uniform sources — maps from a PRNG key to points of the open unit hypercube (0, 1)^d.

Every source is *counter based*: the point with global index i depends only on the key and on i
(and, for the replicated sources, on the replicate count), never on how the points are chunked or
sharded. `Source.block(seed, offset, count, dims)` returns the points with global indices
[offset, offset + count), so a stream cut into chunks draws exactly the points of one big block.

Sources
-------
- `Random()` ("random", the default): independent uniforms from Philox4x32-10 (Salmon, Moraes,
  Dror & Shaw, "Parallel Random Numbers: As Easy as 1, 2, 3", SC 2011), written here in jnp integer
  arithmetic so that XLA fuses it with the warp and the integrand. Philox4x32-10 passes TestU01's
  SmallCrush, Crush and BigCrush (Salmon et al. 2011, table 2; 7 rounds are already Crush
  resistant, 10 is the recommended safety margin). Our implementation is checked against the
  Random123 known-answer vectors (`tests/test_uniforms.py`), and by our own uniformity and serial
  correlation tests.
- `Stratified(replicates)` ("stratified"): jittered sampling; see its docstring for exactly which
  dimensions are stratified.
- `Sobol(replicates)` ("sobol"): Sobol' points (Joe & Kuo direction numbers, new-joe-kuo-6.21201,
  128 dimensions embedded here), each replicate randomized by an independent hash-based nested
  uniform (Owen) scramble (Laine & Karras 2011; Burley, "Practical Hash-based Owen Scrambling",
  JCGT 2020).

From bits to floats: a float32 coordinate is (k + 1/2) 2^-23 with k the top 23 bits, so it lies
in [2^-24, 1 - 2^-24], is exactly representable, never 0 or 1, and the set is symmetric under
u -> 1 - u (antithetic pairs stay inside). A float64 coordinate is (k + 1/2) 2^-32 with k all 32
bits. Both are the midpoints of equal cells, so each coordinate is exactly uniform on that grid.

Keys: the user's typed `jax.random.key` is turned into `SEED_WORDS` uint32 words once, by
`jax.random.bits` (`seed_from_key`); the key itself is consumed there and never used again.
"""

from __future__ import annotations

import functools
from typing import Union

import jax
import jax.numpy as jnp
import numpy as np

__all__ = [
    "Random", "Stratified", "Sobol", "Source", "as_source", "seed_from_key", "uniform_block",
    "philox4x32", "sobol_direction_numbers", "sobol_points", "owen_scramble", "bits_to_unit",
    "MAX_SOBOL_DIMS",
]

SEED_WORDS = 2

# Philox4x32 constants (Salmon et al. 2011, section 5): multipliers and Weyl key increments.
_PHILOX_M0 = 0xD2511F53
_PHILOX_M1 = 0xCD9E8D57
_PHILOX_W0 = 0x9E3779B9
_PHILOX_W1 = 0xBB67AE85

# The third counter word separates the uses of one key, so that no two draw the same block.
_STREAM_RANDOM = 0
_STREAM_JITTER = 1
_STREAM_SCRAMBLE = 2
_STREAM_PADDING = 3


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


def seed_from_key(key: jax.Array) -> jax.Array:
    """The SEED_WORDS uint32 words every source derives its points from; consumes `key` once."""
    if not (isinstance(key, jax.Array) and jnp.issubdtype(key.dtype, jax.dtypes.prng_key)):
        raise ValueError("uniforms: 'key' must be a typed key from jax.random.key(...)")
    return jax.random.bits(key, (SEED_WORDS,), jnp.uint32)


def _index_words(offset, count: int):
    """Global indices offset + [0, count) as uint32 (indices wrap at 2^32 per key)."""
    return _u32(offset) + jnp.arange(count, dtype=jnp.uint32)


def _philox_words(seed, block_index, stream: int, word_block: int = 0):
    return philox4x32((block_index, jnp.zeros_like(block_index) + _u32(word_block),
                       jnp.zeros_like(block_index) + _u32(stream), jnp.zeros_like(block_index)),
                      (seed[..., 0], seed[..., 1]))


def _samples_per_block(dims: int) -> int:
    return 4 // dims if dims <= 4 else 1


def random_bits(seed, offset, count: int, dims: int, stream: int = _STREAM_RANDOM,
                aligned: int | bool = False) -> jax.Array:
    """(count, dims) uint32 words for global sample indices [offset, offset + count).

    Layout: with g = 4 // dims samples per Philox block (dims <= 4), sample i takes words
    (i mod g) * dims ... of the block with counter (i // g, 0, stream, 0); with dims > 4, sample i
    takes the blocks (i, j, stream, 0), j = 0, 1, ... So sample i depends only on (seed, i).
    `offset` may be traced. `aligned` promises that offset is a multiple of it (True: of 4; the
    estimators' chunks), which lets a traced offset skip the spare block and the dynamic slice of
    the general path.
    """
    g = _samples_per_block(dims)
    if dims > 4:
        index = _index_words(offset, count)
        words = []
        for j in range(-(-dims // 4)):
            words.extend(_philox_words(seed, index, stream, j))
        return jnp.stack(words[:dims], axis=-1)
    static_offset = isinstance(offset, (int, np.integer))
    if _alignment(aligned) % g == 0 or (static_offset and offset % g == 0):
        blocks = -(-count // g)
        first = _u32(offset) // _u32(g) + jnp.arange(blocks, dtype=jnp.uint32)
        words = jnp.stack(_philox_words(seed, first, stream), axis=-1)  # (blocks, 4)
        samples = words[:, : g * dims].reshape(blocks * g, dims)
        return samples[:count]
    # A traced or unaligned offset: compute one spare block and cut the window out of it.
    offset = _u32(offset)
    blocks = count // g + 2
    first = offset // _u32(g) + jnp.arange(blocks, dtype=jnp.uint32)
    words = jnp.stack(_philox_words(seed, first, stream), axis=-1)
    samples = words[:, : g * dims].reshape(blocks * g, dims)
    return jax.lax.dynamic_slice_in_dim(samples, (offset % _u32(g)).astype(jnp.int32), count, axis=0)


# ----------------------------------------------------------------------------------------------
# Sobol' points
# ----------------------------------------------------------------------------------------------

# Joe & Kuo, new-joe-kuo-6.21201 (https://web.maths.unsw.edu.au/~fkuo/sobol/), dimensions 2..128,
# one per line: d, s (degree of the primitive polynomial), a (its inner coefficients as an integer,
# leading coefficient first) and the initial direction integers m_1 .. m_s. Dimension 1 is van der
# Corput's (every m_k = 1). The direction numbers for all 32 bits are generated from these below.
_JOE_KUO_6_21201 = """\
2 1 0 1
3 2 1 1 3
4 3 1 1 3 1
5 3 2 1 1 1
6 4 1 1 1 3 3
7 4 4 1 3 5 13
8 5 2 1 1 5 5 17
9 5 4 1 1 5 5 5
10 5 7 1 1 7 11 19
11 5 11 1 1 5 1 1
12 5 13 1 1 1 3 11
13 5 14 1 3 5 5 31
14 6 1 1 3 3 9 7 49
15 6 13 1 1 1 15 21 21
16 6 16 1 3 1 13 27 49
17 6 19 1 1 1 15 7 5
18 6 22 1 3 1 15 13 25
19 6 25 1 1 5 5 19 61
20 7 1 1 3 7 11 23 15 103
21 7 4 1 3 7 13 13 15 69
22 7 7 1 1 3 13 7 35 63
23 7 8 1 3 5 9 1 25 53
24 7 14 1 3 1 13 9 35 107
25 7 19 1 3 1 5 27 61 31
26 7 21 1 1 5 11 19 41 61
27 7 28 1 3 5 3 3 13 69
28 7 31 1 1 7 13 1 19 1
29 7 32 1 3 7 5 13 19 59
30 7 37 1 1 3 9 25 29 41
31 7 41 1 3 5 13 23 1 55
32 7 42 1 3 7 3 13 59 17
33 7 50 1 3 1 3 5 53 69
34 7 55 1 1 5 5 23 33 13
35 7 56 1 1 7 7 1 61 123
36 7 59 1 1 7 9 13 61 49
37 7 62 1 3 3 5 3 55 33
38 8 14 1 3 1 15 31 13 49 245
39 8 21 1 3 5 15 31 59 63 97
40 8 22 1 3 1 11 11 11 77 249
41 8 38 1 3 1 11 27 43 71 9
42 8 47 1 1 7 15 21 11 81 45
43 8 49 1 3 7 3 25 31 65 79
44 8 50 1 3 1 1 19 11 3 205
45 8 52 1 1 5 9 19 21 29 157
46 8 56 1 3 7 11 1 33 89 185
47 8 67 1 3 3 3 15 9 79 71
48 8 70 1 3 7 11 15 39 119 27
49 8 84 1 1 3 1 11 31 97 225
50 8 97 1 1 1 3 23 43 57 177
51 8 103 1 3 7 7 17 17 37 71
52 8 115 1 3 1 5 27 63 123 213
53 8 122 1 1 3 5 11 43 53 133
54 9 8 1 3 5 5 29 17 47 173 479
55 9 13 1 3 3 11 3 1 109 9 69
56 9 16 1 1 1 5 17 39 23 5 343
57 9 22 1 3 1 5 25 15 31 103 499
58 9 25 1 1 1 11 11 17 63 105 183
59 9 44 1 1 5 11 9 29 97 231 363
60 9 47 1 1 5 15 19 45 41 7 383
61 9 52 1 3 7 7 31 19 83 137 221
62 9 55 1 1 1 3 23 15 111 223 83
63 9 59 1 1 5 13 31 15 55 25 161
64 9 62 1 1 3 13 25 47 39 87 257
65 9 67 1 1 1 11 21 53 125 249 293
66 9 74 1 1 7 11 11 7 57 79 323
67 9 81 1 1 5 5 17 13 81 3 131
68 9 82 1 1 7 13 23 7 65 251 475
69 9 87 1 3 5 1 9 43 3 149 11
70 9 91 1 1 3 13 31 13 13 255 487
71 9 94 1 3 3 1 5 63 89 91 127
72 9 103 1 1 3 3 1 19 123 127 237
73 9 104 1 1 5 7 23 31 37 243 289
74 9 109 1 1 5 11 17 53 117 183 491
75 9 122 1 1 1 5 1 13 13 209 345
76 9 124 1 1 3 15 1 57 115 7 33
77 9 137 1 3 1 11 7 43 81 207 175
78 9 138 1 3 1 1 15 27 63 255 49
79 9 143 1 3 5 3 27 61 105 171 305
80 9 145 1 1 5 3 1 3 57 249 149
81 9 152 1 1 3 5 5 57 15 13 159
82 9 157 1 1 1 11 7 11 105 141 225
83 9 167 1 3 3 5 27 59 121 101 271
84 9 173 1 3 5 9 11 49 51 59 115
85 9 176 1 1 7 1 23 45 125 71 419
86 9 181 1 1 3 5 23 5 105 109 75
87 9 182 1 1 7 15 7 11 67 121 453
88 9 185 1 3 7 3 9 13 31 27 449
89 9 191 1 3 1 15 19 39 39 89 15
90 9 194 1 1 1 1 1 33 73 145 379
91 9 199 1 3 1 15 15 43 29 13 483
92 9 218 1 1 7 3 19 27 85 131 431
93 9 220 1 3 3 3 5 35 23 195 349
94 9 227 1 3 3 7 9 27 39 59 297
95 9 229 1 1 3 9 11 17 13 241 157
96 9 230 1 3 7 15 25 57 33 189 213
97 9 234 1 1 7 1 9 55 73 83 217
98 9 236 1 3 3 13 19 27 23 113 249
99 9 241 1 3 5 3 23 43 3 253 479
100 9 244 1 1 5 5 11 5 45 117 217
101 9 253 1 3 3 7 29 37 33 123 147
102 10 4 1 3 1 15 5 5 37 227 223 459
103 10 13 1 1 7 5 5 39 63 255 135 487
104 10 19 1 3 1 7 9 7 87 249 217 599
105 10 22 1 1 3 13 9 47 7 225 363 247
106 10 50 1 3 7 13 19 13 9 67 9 737
107 10 55 1 3 5 5 19 59 7 41 319 677
108 10 64 1 1 5 3 31 63 15 43 207 789
109 10 69 1 1 7 9 13 39 3 47 497 169
110 10 98 1 3 1 7 21 17 97 19 415 905
111 10 107 1 3 7 1 3 31 71 111 165 127
112 10 115 1 1 5 11 1 61 83 119 203 847
113 10 121 1 3 3 13 9 61 19 97 47 35
114 10 127 1 1 7 7 15 29 63 95 417 469
115 10 134 1 3 1 9 25 9 71 57 213 385
116 10 140 1 3 5 13 31 47 101 57 39 341
117 10 145 1 1 3 3 31 57 125 173 365 551
118 10 152 1 3 7 1 13 57 67 157 451 707
119 10 158 1 1 1 7 21 13 105 89 429 965
120 10 161 1 1 5 9 17 51 45 119 157 141
121 10 171 1 3 7 7 13 45 91 9 129 741
122 10 181 1 3 7 1 23 57 67 141 151 571
123 10 194 1 1 3 11 17 47 93 107 375 157
124 10 199 1 3 3 5 11 21 43 51 169 915
125 10 203 1 1 5 3 15 55 101 67 455 625
126 10 208 1 3 5 9 1 23 29 47 345 595
127 10 227 1 3 7 7 5 49 29 155 323 589
128 10 242 1 3 3 7 5 41 127 61 261 717
"""

MAX_SOBOL_DIMS = 128
_SOBOL_BITS = 32
_SOBOL_CACHE: dict = {}


def sobol_direction_numbers(dims: int) -> np.ndarray:
    """(dims, 32) uint32: V[j, k] = m_{k+1} 2^(31-k) for dimension j + 1 (Bratley & Fox 1988).

    For k > s the recurrence of the primitive polynomial x^s + a_1 x^(s-1) + ... + a_(s-1) x + 1:
    m_k = 2^s m_(k-s) xor m_(k-s) xor (xor over i = 1..s-1 of 2^i a_i m_(k-i)).
    """
    if not 1 <= dims <= MAX_SOBOL_DIMS:
        raise ValueError(f"Sobol: 'dims' must be in [1, {MAX_SOBOL_DIMS}]; got {dims}")
    if "table" not in _SOBOL_CACHE:
        table = np.zeros((MAX_SOBOL_DIMS, _SOBOL_BITS), dtype=np.uint64)
        table[0] = [1 << (31 - k) for k in range(_SOBOL_BITS)]
        for line in _JOE_KUO_6_21201.strip().splitlines():
            d, s, a, *m_init = (int(v) for v in line.split())
            m = list(m_init)
            for k in range(s, _SOBOL_BITS):
                value = m[k - s] ^ (m[k - s] << s)
                for i in range(1, s):
                    if (a >> (s - 1 - i)) & 1:
                        value ^= m[k - i] << i
                m.append(value)
            table[d - 1] = [m[k] << (31 - k) for k in range(_SOBOL_BITS)]
        _SOBOL_CACHE["table"] = table.astype(np.uint32)
    return _SOBOL_CACHE["table"][:dims]


def sobol_points(index: jax.Array, dims: int, index_bits: int = _SOBOL_BITS) -> jax.Array:
    """Unscrambled Sobol' points as uint32 fractions (value / 2^32), shape index.shape + (dims,).

    Natural (not Gray-code) order: point i is the xor of V[:, k] over the set bits k of i, so every
    prefix of length 2^m is the same (0, m, s)-net the Gray-code order visits. Only the low
    `index_bits` bits of the index are read (a static bound: fewer xors for short sequences).
    """
    directions = jnp.asarray(sobol_direction_numbers(dims))
    index = _u32(index)[..., None]
    result = jnp.zeros(index.shape[:-1] + (dims,), dtype=jnp.uint32)
    for k in range(index_bits):
        bit = (index >> _u32(k)) & _u32(1)
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


def _alignment(aligned) -> int:
    """`aligned` as the integer the offset is known to be a multiple of (True: 4, False: 1)."""
    if isinstance(aligned, (bool, np.bool_)):
        return 4 if aligned else 1
    return max(int(aligned), 1)


# ----------------------------------------------------------------------------------------------
# Sources
# ----------------------------------------------------------------------------------------------


class Source:
    """A uniform source: `block(seed, offset, count, dims, dtype, total)` -> (count, dims) in (0, 1).

    `replicates` R > 1 means the points are R independent randomizations interleaved by index
    (global index g belongs to replicate g mod R, as its point g div R): the estimators take their
    standard error from the spread of the R replicate means, because within one replicate the
    points are not independent. `total` is the number of points the whole stream will have
    (needed where the construction depends on it, as stratification does). `aligned` is a promise
    about a traced offset: it is a multiple of this integer (True means 4), so a source may take a
    faster path that gives the same points.
    """

    replicates: int = 1
    name: str = "source"

    def block(self, seed, offset, count: int, dims: int, dtype=jnp.float32, total=None,
              aligned: int | bool = False) -> jax.Array:
        raise NotImplementedError

    def lanes(self, seed, offset, count: int, dims: int, dtype=jnp.float32, total=None,
              aligned: int | bool = False) -> tuple[tuple[jax.Array, ...], ...]:
        """The same points as `block`, as g groups of `dims` coordinate arrays of one shape (of size
        count / g): group q holds the points offset + g b + q, b = 0, 1, ... in C order over that
        shape (the default is g = 1 and shape (count,)).

        Consumers that evaluate per-point functions and reduce over the points (the estimators,
        `sample`) use this form: a generator hands over every word it computes, one array per
        coordinate, with no interleaving stack for XLA to materialize (a (count, d) stack that
        several consumers slice makes XLA store it, or recompute the generator in each).
        """
        points = self.block(seed, offset, count, dims, dtype, total, aligned)
        return (tuple(points[:, j] for j in range(dims)),)

    def __repr__(self):
        return f"{type(self).__name__}(replicates={self.replicates})"

    def __eq__(self, other):
        return type(self) is type(other) and self.replicates == other.replicates

    def __hash__(self):
        return hash((type(self).__name__, self.replicates))


class Random(Source):
    """Independent uniforms from Philox4x32-10 (see the module docstring); one replicate."""

    name = "random"

    def block(self, seed, offset, count, dims, dtype=jnp.float32, total=None, aligned=False):
        return bits_to_unit(random_bits(seed, offset, count, dims, aligned=aligned), dtype)

    def lanes(self, seed, offset, count, dims, dtype=jnp.float32, total=None, aligned=False):
        g = _samples_per_block(dims)
        if dims > 4:
            index = _index_words(offset, count)
            words = [w for j in range(-(-dims // 4)) for w in _philox_words(seed, index, _STREAM_RANDOM, j)]
            return (tuple(bits_to_unit(w, dtype) for w in words[:dims]),)
        if count % g or _alignment(aligned) % g:
            return super().lanes(seed, offset, count, dims, dtype, total, aligned)
        # Point offset + g b + q takes words q dims ... (q + 1) dims - 1 of block offset / g + b.
        first = _u32(offset) // _u32(g) + jnp.arange(count // g, dtype=jnp.uint32)
        words = _philox_words(seed, first, _STREAM_RANDOM)
        return tuple(tuple(bits_to_unit(words[q * dims + j], dtype) for j in range(dims)) for q in range(g))


def _check_replicates(owner: str, replicates) -> int:
    if not isinstance(replicates, (int, np.integer)) or replicates < 2:
        raise ValueError(f"{owner}: parameter 'replicates' must be an integer >= 2; got {replicates!r}")
    return int(replicates)


class Stratified(Source):
    """Jittered (stratified) sampling, in R independent replicates of m = total / R points.

    How the cube is stratified, honestly: for dims == 1, [0, 1) is cut into m equal strata and
    point i of a replicate is uniform in stratum i. For dims >= 2 only the first two coordinates
    are stratified: with s = floor(sqrt(m)), point i < s^2 is uniform in cell (i mod s, i div s) of
    an s x s grid, and the m - s^2 leftover points (if m is not a square) are uniform over the
    square. Coordinates 3 and up are independent uniforms (no stratification: the usual padding
    of a 2-D jittered pattern). Every point is marginally uniform, so estimates are unbiased; the
    jitter comes from the same Philox stream as `Random` (a separate stream word).

    A coordinate (cell + jitter) / s can round up to 1 in float arithmetic; it is clamped to the
    largest float below 1 (a shift of at most one ulp on one point in 2^23).
    """

    name = "stratified"

    def __init__(self, replicates: int = 16):
        self.replicates = _check_replicates("Stratified", replicates)

    def _per_replicate(self, total) -> int:
        if total is None:
            raise ValueError("Stratified: 'total' (the number of points of the whole stream) is required")
        if total % self.replicates:
            raise ValueError(f"Stratified: total={total} must be a multiple of replicates={self.replicates}")
        return total // self.replicates

    def block(self, seed, offset, count, dims, dtype=jnp.float32, total=None, aligned=False):
        per_replicate = self._per_replicate(total)
        jitter = bits_to_unit(random_bits(seed, offset, count, dims, _STREAM_JITTER, aligned=aligned), dtype)
        columns = [jitter[:, j] for j in range(dims)]
        return jnp.stack(self._place(columns, _index_words(offset, count), per_replicate, dtype), axis=-1)

    def lanes(self, seed, offset, count, dims, dtype=jnp.float32, total=None, aligned=False):
        """The same points as `block`, g = 4 // dims per Philox block of jitter (see
        `Source.lanes`), so that the estimators compute each block once."""
        per_replicate = self._per_replicate(total)
        g = _samples_per_block(dims)
        if dims > 4 or count % g or _alignment(aligned) % g or self.replicates % g:
            return super().lanes(seed, offset, count, dims, dtype, total, aligned)
        blocks = jnp.arange(count // g, dtype=jnp.uint32)
        words = _philox_words(seed, _u32(offset) // _u32(g) + blocks, _STREAM_JITTER)
        return tuple(self._place([bits_to_unit(words[q * dims + j], dtype) for j in range(dims)],
                                 _u32(offset) + _u32(g) * blocks + _u32(q), per_replicate, dtype)
                     for q in range(g))

    def _place(self, jitter, index, per_replicate: int, dtype):
        """Coordinates (a tuple) of the points with global indices `index` (uint32), given
        their jitter coordinates in (0, 1)."""
        index = index // _u32(self.replicates)
        top = np.nextafter(np.array(1.0, dtype), np.array(0.0, dtype))
        if len(jitter) == 1:
            cell = index.astype(jnp.int32).astype(dtype)
            return (jnp.minimum((cell + jitter[0]) / per_replicate, top),)
        side = int(np.floor(np.sqrt(per_replicate)))
        while (side + 1) * (side + 1) <= per_replicate:
            side += 1
        in_grid = index < _u32(side * side)
        cells = ((index % _u32(side)), (index // _u32(side)))
        first_two = tuple(jnp.where(in_grid, jnp.minimum((c.astype(jnp.int32).astype(dtype) + j) / side, top), j)
                          for c, j in zip(cells, jitter[:2]))
        return first_two + tuple(jitter[2:])


class Sobol(Source):
    """Owen-scrambled Sobol' points in R independent replicates (default 16), up to 128 dims.

    Replicate r (global indices g with g mod R = r) is the Sobol' sequence in natural order,
    point g div R, with each coordinate j passed through `owen_scramble` under its own 32-bit seed
    (Philox of (r, j) under the user's key). Each replicate is a randomized (0, m, s)-net for every
    power-of-two prefix, each point is uniform, so the estimate is unbiased, and the replicates
    are independent, so their spread gives an honest standard error. Convergence is best when
    total / R is a power of two. Only 32 bits of the scrambled fraction exist; float32 keeps 23
    (midpoint of the cell, as for `Random`).
    """

    name = "sobol"

    def __init__(self, replicates: int = 16):
        self.replicates = _check_replicates("Sobol", replicates)

    def scramble_seeds(self, seed, dims: int) -> jax.Array:
        replicate = jnp.arange(self.replicates, dtype=jnp.uint32)[:, None]
        dim = jnp.arange(dims, dtype=jnp.uint32)[None, :]
        replicate, dim = jnp.broadcast_arrays(replicate, dim)
        words = philox4x32((replicate, dim, jnp.full_like(dim, _STREAM_SCRAMBLE), jnp.zeros_like(dim)),
                           (seed[..., 0, None, None], seed[..., 1, None, None]))
        return words[0]  # (R, dims)

    def block(self, seed, offset, count, dims, dtype=jnp.float32, total=None, aligned=False):
        if dims > MAX_SOBOL_DIMS:
            raise ValueError(f"Sobol: at most {MAX_SOBOL_DIMS} dimensions; got {dims}")
        replicates = self.replicates
        index_bits = _SOBOL_BITS
        if total is not None:
            index_bits = max(1, int(-(-total // replicates) - 1).bit_length())
        glob = _index_words(offset, count)
        point = glob // _u32(replicates)
        replicate = (glob % _u32(replicates)).astype(jnp.int32)
        seeds = self.scramble_seeds(seed, dims)[replicate]  # (count, dims)
        fractions = owen_scramble(sobol_points(point, dims, index_bits), seeds)
        return bits_to_unit(fractions, dtype)

    def lanes(self, seed, offset, count, dims, dtype=jnp.float32, total=None, aligned=False):
        """The same points as `block`; fast when the chunk is a whole aligned run of points.

        If each replicate takes m = count / R consecutive points m0 .. m0 + m - 1 with m0 a
        multiple of 2^b >= m (an estimator's chunks, `aligned` a multiple of R 2^b), then point
        m0 + j is P(m0) xor P(j), j < 2^b, with disjoint bits: P(j) comes from a constant table
        (bit-reversed, so the scramble's first reversal is free) and P(m0) is one vector per chunk.
        Laid out as (j, replicate), the table is read along rows and the seeds along columns:
        no gather and no per-point loop over index bits. The points are bit-identical to `block`.
        """
        replicates = self.replicates
        per = count // replicates
        bits = max(per - 1, 0).bit_length()
        if (dims > MAX_SOBOL_DIMS or count % replicates or per == 0
                or _alignment(aligned) % (replicates << bits)):
            return super().lanes(seed, offset, count, dims, dtype, total, aligned)
        first = _u32(offset) // _u32(replicates)
        high = _reverse_bits(sobol_points(first, dims))  # (dims,)
        table = _sobol_low_table(bits, dims)[:per]        # (per, dims), NumPy constant
        seeds = self.scramble_seeds(seed, dims)           # (R, dims)
        # Lanes of shape (per, R): point j of replicate r is global index offset + j R + r, the
        # C order of the lanes, as `Source.lanes` asks. Kept 2-D (not flattened to (count,)),
        # so that XLA's loops read the table row and the seeds without index arithmetic and
        # vectorize (flattened, the fusion ran scalar: ~3x slower).
        return (tuple(bits_to_unit(_scramble_reversed(jnp.asarray(table[:, j])[:, None] ^ high[j],
                                                      seeds[None, :, j]), dtype)
                      for j in range(dims)),)


SourceLike = Union[str, Source]


def as_source(uniforms: SourceLike) -> Source:
    """"random" | "stratified" | "sobol" (default settings) or a `Source` instance."""
    if isinstance(uniforms, Source):
        return uniforms
    if uniforms == "random":
        return Random()
    if uniforms == "stratified":
        return Stratified()
    if uniforms == "sobol":
        return Sobol()
    raise ValueError(f"uniforms: must be 'random', 'stratified', 'sobol' or a Source; got {uniforms!r}")


def uniform_block(uniforms: SourceLike, key: jax.Array, offset, count: int, dims: int, *,
                  dtype=None, total=None) -> jax.Array:
    """Points with global indices [offset, offset + count) of the stream `uniforms` draws with `key`.

    Calling it on consecutive windows gives exactly the points of one call on their union.
    `key` is a typed key (consumed) or the uint32 words of `seed_from_key`; `total` is the number
    of points of the whole stream (required for "stratified", and it bounds the Sobol' index).
    """
    source = as_source(uniforms)
    seed = key if (isinstance(key, jax.Array) and key.dtype == jnp.uint32) else seed_from_key(key)
    dtype = jnp.zeros(()).dtype if dtype is None else jnp.dtype(dtype)
    return _block_jit(source, seed, _u32(offset), int(count), int(dims), dtype, total)


@functools.partial(jax.jit, static_argnums=(0, 3, 4, 5, 6))
def _block_jit(source, seed, offset, count, dims, dtype, total):
    # One compilation per (source, count, dims, dtype, total); the offset is traced.
    return source.block(seed, offset, count, dims, dtype, total=total)
