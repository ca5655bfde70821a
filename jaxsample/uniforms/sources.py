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
  Random123 known-answer vectors (`tests/uniforms/test_uniforms.py`), and by our own uniformity and serial
  correlation tests.
- `Stratified(replicates)` ("stratified"): jittered sampling; see its docstring for exactly which
  dimensions are stratified.
- `Sobol(replicates)` ("sobol"): Sobol' points (Joe & Kuo direction numbers, new-joe-kuo-6.21201,
  1024 dimensions, `sobol.MAX_SOBOL_DIMS`), each replicate randomized by an independent hash-based nested
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
import math
from typing import ClassVar, Union

import jax
import jax.numpy as jnp
import numpy as np

from .._core.params import resolve_float_dtype
from .._core.pytree import Pytree, static_field
from .index import Index, as_index, divmod_index, floordiv, index_range, index_value, less_than
from .philox import (_STREAM_JITTER, _alignment, _STREAM_RANDOM, _STREAM_SCRAMBLE, _index_words, _philox_words,
                     _samples_per_block, _u32, bits_to_unit, philox4x32, random_bits, seed_from_key)
from .sobol import (_SOBOL_BITS, _SOBOL_INDEX_BITS, MAX_SOBOL_DIMS, STREAM_LMS, STREAM_PADDED,
                    STREAM_PADDED_SHIFT, _reverse_bits, _scramble_reversed, _sobol_low_table, apply_columns,
                    owen_scramble, pascal_superset_xor, scrambled_generator_columns, sobol_direction_numbers,
                    sobol_points, triangular_columns)


class Source(Pytree):
    """A uniform source: `block(seed, offset, count, dims, dtype, total)` -> (count, dims) in (0, 1).

    `replicates` R > 1 means the points are R independent randomizations interleaved by index
    (global index g belongs to replicate g mod R, as its point g div R): the estimators take their
    standard error from the spread of the R replicate means, because within one replicate the
    points are not independent. `total` is the number of points the whole stream will have
    (needed where the construction depends on it, as stratification does). `aligned` is a promise
    about a traced offset: it is a multiple of this integer (True means 4), so a source may take a
    faster path that gives the same points.

    Offsets: a Python or NumPy integer (any index below 2^64), a uint32 array (a traced offset of
    a window that stays below 2^32: what the estimators pass for n <= 2^32) or an `index.Index` (two
    uint32 words: the estimators' offsets for n > 2^32). A
    subclass handles all three by reading them with `index.as_index(offset, count)`.
    """

    replicates: int = static_field(default=1)
    name: ClassVar[str] = "source"

    def __init__(self):
        self.replicates = 1

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

    name: ClassVar[str] = "random"

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
        first = index_range(floordiv(as_index(offset, count), g), count // g)
        words = _philox_words(seed, first, _STREAM_RANDOM)
        return tuple(tuple(bits_to_unit(words[q * dims + j], dtype) for j in range(dims)) for q in range(g))


def _check_replicates(owner: str, replicates) -> int:
    if (not isinstance(replicates, (int, np.integer)) or isinstance(replicates, (bool, np.bool_))
            or not 2 <= replicates < 1 << 32):
        raise ValueError(f"{owner}: parameter 'replicates' must be an integer in [2, 2^32); got {replicates!r}")
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

    name: ClassVar[str] = "stratified"

    def __init__(self, replicates: int = 16):
        self.replicates = _check_replicates("Stratified", replicates)

    def _per_replicate(self, total) -> int:
        if total is None:
            raise ValueError("Stratified: 'total' (the number of points of the whole stream) is required")
        if total % self.replicates:
            raise ValueError(f"Stratified: total={total} must be a multiple of replicates={self.replicates}; "
                             f"change the count, or the replicate count with Stratified(replicates=...)")
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
        if dims > 4:
            # One Philox block per point and group of four coordinates, as `Random` (measured:
            # 14x Random at 5-d through the generic path's (count, dims) block, 1.1x here).
            index = _index_words(offset, count)
            words = [w for j in range(-(-dims // 4)) for w in _philox_words(seed, index, _STREAM_JITTER, j)]
            return (self._place([bits_to_unit(w, dtype) for w in words[:dims]], index, per_replicate, dtype),)
        g = _samples_per_block(dims)
        start = as_index(offset, count)
        if count % g or _alignment(aligned) % g or self.replicates % g or start.wide:
            # (A window past 2^32 takes the general path: `block` handles two-word indices.)
            return super().lanes(seed, offset, count, dims, dtype, total, aligned)
        offset = start.lo
        blocks = jnp.arange(count // g, dtype=jnp.uint32)
        words = _philox_words(seed, _u32(offset) // _u32(g) + blocks, _STREAM_JITTER)
        return tuple(self._place([bits_to_unit(words[q * dims + j], dtype) for j in range(dims)],
                                 _u32(offset) + _u32(g) * blocks + _u32(q), per_replicate, dtype)
                     for q in range(g))

    def _place(self, jitter, index, per_replicate: int, dtype):
        """Coordinates (a tuple) of the points with global indices `index` (a uint32 array or an
        `Index`), given their jitter coordinates in (0, 1)."""
        point = floordiv(index if isinstance(index, Index) else Index(None, _u32(index)), self.replicates)
        top = np.nextafter(np.array(1.0, dtype), np.array(0.0, dtype))
        if len(jitter) == 1:
            cell = index_value(point, dtype)
            return (jnp.minimum((cell + jitter[0]) / float(per_replicate), top),)
        side = math.isqrt(per_replicate)
        in_grid = less_than(point, side * side)
        row, column = divmod_index(point, side)
        # column < side: below 2^16 in a narrow stream, where the int32 conversion (one vector
        # instruction) is exact; below 2^32 in a wide one, converted from uint32.
        cells = (column.astype(jnp.int32).astype(dtype) if not point.wide else column.astype(dtype),
                 index_value(row, dtype))
        first_two = tuple(jnp.where(in_grid, jnp.minimum((c + j) / float(side), top), j)
                          for c, j in zip(cells, jitter[:2]))
        return first_two + tuple(jitter[2:])


class Sobol(Source):
    """Scrambled Sobol' points in R independent replicates (default 16): up to 1024 dims, or any
    number with `padding=True`.

    Replicate r (global indices g with g mod R = r) is the Sobol' sequence in natural order,
    point g div R (Joe & Kuo's new-joe-kuo-6.21201 direction numbers), randomized by one of:

    - `scramble="owen"` (the default): each coordinate j passed through `owen_scramble` under its
      own 32-bit seed (Philox of (r, j) under the user's key): a hash-based nested uniform
      scramble (Burley 2020).
    - `scramble="lms"`: each coordinate j multiplied by its own random lower-triangular binary
      matrix with unit diagonal and xored with a random digital shift, x -> L x + e over GF(2)
      (the linear matrix scramble of Matoušek 1998 plus a digital shift; see
      `sobol.triangular_columns`). L and e come from Philox of (r, j, w) under the key. Since L
      is linear, L P(i) is the xor of the scrambled direction numbers L V_k over the bits of i, so
      a point costs about what the unscrambled one does. LMS keeps the t of every projection
      exactly (the scrambled generator matrices have the same ranks), and with the shift every
      point is uniform; its variance is that of the Owen scramble for the integrands whose
      variance involves pairs of points only through their first common digits (Owen 2003,
      "Variance with alternative scramblings of digital nets", ACM TOMACS 13), and it costs no
      hash per point.

    Each replicate is a randomized (t, m, s)-net for every power-of-two prefix (t = 0 in
    dimensions 1-2), each point is uniform, so the estimate is unbiased, and the replicates are
    independent, so their spread gives an honest standard error. Convergence is best when
    total / R is a power of two. Only 32 bits of the scrambled fraction exist; float32 keeps 23
    (midpoint of the cell, as for `Random`).

    `padding=True` pads with 2-D Sobol' instead, as renderers do (PBRT-v4's PaddedSobolSampler;
    Burley 2020, section 4): coordinates 2k and 2k + 1 are Sobol' dimensions 1 and 2 (a (0, 2)-
    sequence) at a shuffled index pi_(r,k)(i), each coordinate scrambled on its own, with the
    shuffle and the scrambles independent for every pair k and replicate r; an odd last
    coordinate is the pair's first. Any number of dimensions works, and each pair's power-of-two
    prefixes are (0, m, 2)-nets, because the shuffle maps each aligned run [c 2^m, (c + 1) 2^m)
    of indices onto an aligned run, and every such run of a (0, 2)-sequence is a (0, m, 2)-net.
    Across pairs there is no net structure (the shuffle decorrelates them): the price of padding
    next to the full Sobol' net, which also stratifies higher-dimensional projections. With
    "owen" the shuffle is Burley's nested uniform shuffle, `owen_scramble` applied to the index
    (bit k of the index flipped by a hash of the bits above it, under a seed of its own); with
    "lms" it is the linear analogue, i -> M i with M a random binary upper-triangular matrix
    with unit diagonal (bit k of the result depends on the bits >= k of i), so each pair is a
    randomly scrambled digital net with generator matrices L_a J M and L_b P M (J the bit
    reversal of dimension 1, P Pascal's matrix of dimension 2). The shuffle acts on the low 32
    bits of the point index; the seeds (owen) or the digital shifts (lms) also depend on its
    high word, so past 2^32 points per replicate each run of 2^32 points of a pair (in 32-bit
    fractions, a complete (0, 32, 2)-net: one point per 2^-32 elementary box) is independently
    randomized.

    Point indices have 64 bits (`sobol.sobol_direction_numbers`: Joe & Kuo's recurrence carried to
    64 index bits), so a stream may have up to 2^64 points; the first 2^32 of each replicate are
    those of the classical 32-bit generator. Past 2^32 points per replicate the 32-bit fractions
    repeat in dimension 1 (points i and i + 2^32 share theirs; see `sobol_points`), so more
    points then mostly serve the other dimensions: prefer more replicates (`replicates=`).
    """

    name: ClassVar[str] = "sobol"
    scramble: str = static_field(default="owen")
    padding: bool = static_field(default=False)

    SCRAMBLES: ClassVar[tuple[str, ...]] = ("owen", "lms")

    def __init__(self, replicates: int = 16, scramble: str = "owen", padding: bool = False):
        self.replicates = _check_replicates("Sobol", replicates)
        if not isinstance(scramble, str) or scramble not in self.SCRAMBLES:
            raise ValueError(f"Sobol: parameter 'scramble' must be one of {self.SCRAMBLES}; got {scramble!r}")
        self.scramble = scramble
        if not isinstance(padding, (bool, np.bool_)):
            raise ValueError(f"Sobol: parameter 'padding' must be True or False; got {padding!r}")
        self.padding = bool(padding)

    def __repr__(self):
        return f"Sobol(replicates={self.replicates}, scramble={self.scramble!r}, padding={self.padding})"

    def __eq__(self, other):
        return (type(self) is type(other) and self.replicates == other.replicates
                and self.scramble == other.scramble and self.padding == other.padding)

    def __hash__(self):
        return hash(("Sobol", self.replicates, self.scramble, self.padding))

    def _check_dims(self, dims: int) -> None:
        if not self.padding and dims > MAX_SOBOL_DIMS:
            raise ValueError(f"Sobol: parameter 'dims' must be in [1, {MAX_SOBOL_DIMS}]; got {dims} "
                             "(Sobol(padding=True) takes any number)")

    def scramble_seeds(self, seed, dims: int) -> jax.Array:
        replicate = jnp.arange(self.replicates, dtype=jnp.uint32)[:, None]
        dim = jnp.arange(dims, dtype=jnp.uint32)[None, :]
        replicate, dim = jnp.broadcast_arrays(replicate, dim)
        words = philox4x32((replicate, dim, jnp.full_like(dim, _STREAM_SCRAMBLE), jnp.zeros_like(dim)),
                           (seed[..., 0, None, None], seed[..., 1, None, None]))
        return words[0]  # (R, dims)

    def _points_of(self, offset, count, total):
        """(point indices, replicate numbers as int32, index bits) of a window: global index g is
        point g div R of replicate g mod R; the index bits are 64 past 2^32 points, else 32, fewer
        when `total` bounds the points per replicate."""
        glob = _index_words(offset, count)
        index_bits = _SOBOL_INDEX_BITS if glob.wide else _SOBOL_BITS
        if total is not None:
            index_bits = min(index_bits, max(1, int(-(-total // self.replicates) - 1).bit_length()))
        point, replicate = divmod_index(glob, self.replicates)
        return point, replicate.astype(jnp.int32), index_bits

    def block(self, seed, offset, count, dims, dtype=jnp.float32, total=None, aligned=False):
        self._check_dims(dims)
        if self.padding:
            return bits_to_unit(self._padded_block(seed, offset, count, dims), dtype)
        if self.scramble == "lms":
            return bits_to_unit(self._lms_block(seed, offset, count, dims, total), dtype)
        point, replicate, index_bits = self._points_of(offset, count, total)
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
        self._check_dims(dims)
        replicates = self.replicates
        per = count // replicates
        bits = max(per - 1, 0).bit_length()
        if count % replicates or per == 0 or _alignment(aligned) % (replicates << bits):
            return super().lanes(seed, offset, count, dims, dtype, total, aligned)
        first = floordiv(as_index(offset, count), replicates)
        if self.padding or self.scramble == "lms":
            fast = self._padded_lanes if self.padding else self._lms_lanes
            return (tuple(bits_to_unit(c, dtype) for c in fast(seed, first, per, bits, dims)),)
        high = _reverse_bits(sobol_points(first, dims))  # (dims,)
        table = _sobol_low_table(bits, dims)[:per]        # (per, dims), NumPy constant
        seeds = self.scramble_seeds(seed, dims)           # (R, dims)
        # Lanes of shape (per, R): point j of replicate r is global index offset + j R + r, the
        # C order of the lanes, as `Source.lanes` asks. Kept 2-D (not flattened to (count,)),
        # so that XLA's loops read the table row and the seeds without index arithmetic and
        # vectorize (flattened, the fusion runs scalar: ~3x slower in the uniforms= rows of benchmarks/paths.py).
        return (tuple(bits_to_unit(_scramble_reversed(jnp.asarray(table[:, j])[:, None] ^ high[j],
                                                      seeds[None, :, j]), dtype)
                      for j in range(dims)),)


    # ---- scramble="lms": linear matrix scrambling plus a digital shift -------------------------

    def lms_matrices(self, seed, dims: int) -> tuple[jax.Array, jax.Array]:
        """(columns (R, dims, 32), shifts (R, dims)): the lower-triangular matrix L of each
        replicate and dimension as its 32 columns (`sobol.triangular_columns`) and its digital
        shift e, from the 36 words of Philox (r, j, STREAM_LMS + w, 0), w = 0..8, under the seed:
        every (replicate, dimension) reads counters of its own."""
        replicate = jnp.arange(self.replicates, dtype=jnp.uint32)[:, None]
        dim = jnp.arange(dims, dtype=jnp.uint32)[None, :]
        words = [w for block in range(9) for w in _grid_words(seed, replicate, dim, STREAM_LMS + block)]
        return triangular_columns(jnp.stack(words[:32], axis=-1)), words[32]

    def _lms_block(self, seed, offset, count, dims, total):
        point, replicate, index_bits = self._points_of(offset, count, total)
        columns, shifts = self.lms_matrices(seed, dims)
        # L P(i) + e = e xor (the xor of L V_k over the set bits k of i): the scrambled generator
        # matrix's columns (R, dims, index_bits), then one gathered (count, dims) slice per index
        # bit, as `sobol_points` does with V itself (the same bits as L applied to P(i)).
        directions = jnp.asarray(sobol_direction_numbers(dims, index_bits))[None]
        generator = scrambled_generator_columns(columns, directions)
        result = shifts[replicate]
        words = [(point.lo, 0)] + ([(point.hi, 32)] if point.wide else [])
        for word, first in words:
            word = word[:, None]
            for k in range(first, min(first + 32, index_bits)):
                bit = (word >> _u32(k - first)) & _u32(1)
                result = result ^ ((_u32(0) - bit) & generator[:, :, k][replicate])
        return result

    def _lms_lanes(self, seed, first: Index, per: int, bits: int, dims: int) -> list:
        """(per, R) lanes of point m0 + j = m0 xor j of every replicate (m0 = `first`, a
        multiple of 2^bits > j): L P(m0) + e per (replicate, dimension), then the xor of the
        scrambled direction numbers L V_k over the bits k < bits of j (linearity: the same bits
        as `_lms_block`)."""
        columns, shifts = self.lms_matrices(seed, dims)                        # (R, dims, 32), (R, dims)
        high = apply_columns(sobol_points(first, dims), columns) ^ shifts       # (R, dims)
        directions = jnp.asarray(sobol_direction_numbers(dims, max(bits, 1)))[None, :, :bits]
        generator = scrambled_generator_columns(columns, directions)            # (R, dims, bits)
        return [_xor_over_row_bits(high[None, :, j], generator[None, :, j], per, bits) for j in range(dims)]

    # ---- padding=True: a shuffled, scrambled 2-D Sobol' per dimension pair -----------------------

    def _padded_words(self, seed, replicate, pair, high):
        """Philox (r, k, STREAM_PADDED_SHIFT, high) per replicate r and pair k (broadcast arrays):
        the shuffle and coordinate seeds ("owen", words 0-2) or the two digital shifts ("lms",
        words 0-1) of the pair's run of 2^32 points whose high index word is `high`."""
        return _grid_words(seed, replicate, pair, STREAM_PADDED_SHIFT, high)

    def padded_matrices(self, seed, pairs: int):
        """("lms") the columns (R, pairs, 32) of M (the index shuffle), L_a and L_b (the two
        coordinates' scrambles) of each replicate and pair, from Philox (r, k, STREAM_PADDED + w, 0),
        w = 0..23."""
        replicate = jnp.arange(self.replicates, dtype=jnp.uint32)[:, None]
        pair = jnp.arange(pairs, dtype=jnp.uint32)[None, :]
        words = [w for block in range(24) for w in _grid_words(seed, replicate, pair, STREAM_PADDED + block)]
        return tuple(triangular_columns(jnp.stack(words[32 * q: 32 * q + 32], axis=-1)) for q in range(3))

    def _padded_block(self, seed, offset, count, dims):
        replicates, pairs = self.replicates, -(-dims // 2)
        point, replicate = divmod_index(_index_words(offset, count), replicates)
        high = jnp.zeros_like(point.lo) if point.hi is None else point.hi
        pair = jnp.arange(pairs, dtype=jnp.uint32)[None, :]
        words = self._padded_words(seed, replicate[:, None], pair, high[:, None])  # 4 x (count, pairs)
        i = point.lo[:, None]
        if self.scramble == "owen":
            first, second = _padded_owen_pair(i, *words[:3])
        else:
            shuffle, scramble_a, scramble_b = self.padded_matrices(seed, pairs)
            replicate = replicate.astype(jnp.int32)
            gen_a, gen_b = _padded_generator(shuffle, scramble_a, scramble_b, 32)   # (R, pairs, 32)
            first, second = words[0], words[1]
            for k in range(32):
                bit = _u32(0) - ((i >> _u32(k)) & _u32(1))
                first, second = first ^ (bit & gen_a[:, :, k][replicate]), second ^ (bit & gen_b[:, :, k][replicate])
        return jnp.stack([first, second], axis=-1).reshape(count, 2 * pairs)[:, :dims]

    def _padded_lanes(self, seed, first: Index, per: int, bits: int, dims: int) -> list:
        """(per, R) lanes (the chunk lies in one run of 2^32 points: m0 is a multiple of
        2^bits > j); bit-identical to `_padded_block`."""
        replicates, pairs = self.replicates, -(-dims // 2)
        replicate = jnp.arange(replicates, dtype=jnp.uint32)[None, :]
        high = _u32(0) if first.hi is None else first.hi
        # Laid out (pairs, R), so that each pair's seeds are one contiguous row: as (R, pairs)
        # columns, a pair whose second coordinate is dropped (odd dims) leaves a gap in the
        # strided read, and LLVM then runs half the replicates of the lanes' loop as a scalar
        # epilogue, which makes the 3-d estimate of `jaxsample.report.paths.quasi_random` several
        # times slower. The words: 4 x (pairs, R).
        words = self._padded_words(seed, replicate, jnp.arange(pairs, dtype=jnp.uint32)[:, None], high)
        if self.scramble == "owen":
            i = first.lo + jnp.arange(per, dtype=jnp.uint32)[:, None]            # (per, 1)
            lanes = [c for k in range(pairs) for c in _padded_owen_pair(i, *(w[None, k, :] for w in words[:3]))]
        else:
            shuffle, scramble_a, scramble_b = self.padded_matrices(seed, pairs)
            # The pair's point at m0 (the high bits), then the generator columns of the low bits.
            shuffled = apply_columns(first.lo, shuffle)
            top = (apply_columns(_reverse_bits(shuffled), scramble_a) ^ words[0].T,                    # (R, pairs)
                   apply_columns(_reverse_bits(pascal_superset_xor(shuffled)), scramble_b) ^ words[1].T)
            low = _padded_generator(shuffle, scramble_a, scramble_b, bits) if bits else (None, None)
            lanes = [_xor_over_row_bits(top[c][None, :, k], None if low[c] is None else low[c][None, :, k], per, bits)
                     for k in range(pairs) for c in (0, 1)]
        return [jnp.broadcast_to(c, (per, replicates)) for c in lanes[:dims]]


def _grid_words(seed, replicate, column, stream: int, high=0):
    """Philox4x32 of the counter (replicate, column, stream, high) under the seed, broadcast
    over the shapes of replicate, column and high (uint32 arrays)."""
    replicate, column, high = jnp.broadcast_arrays(_u32(replicate), _u32(column), _u32(high))
    return philox4x32((replicate, column, jnp.full_like(column, _u32(stream)), high), (seed[..., 0], seed[..., 1]))


def _xor_over_row_bits(start, generator, per: int, bits: int) -> jax.Array:
    """start xor (xor of generator[..., k] over the bits k < bits of the row index j), on
    (per, R) lanes: the low-index part of a digital net's point, m0 xor j.

    Per lane this is one xor of two small per-replicate tables, not a loop over the bits of j.
    Xor is linear, so with j = j_hi 2^h + j_lo (h = ceil(bits / 2)) the value splits as
    high[j_hi] xor low[j_lo]: high[a] = start xor (the xor of generator[..., h + k] over the bits
    k of a) and low[b] = the xor of generator[..., k] over the bits k < h of b, tables of
    2^(bits - h) and 2^h rows by R (for an estimator chunk of 2^16 points per replicate, 256 x R
    words each). Laid out as (2^(bits - h), 2^h, R) the lanes are a broadcast xor of the two
    (no gather); flattened in C order to (2^bits, R) they are rows j of the same value, bit for
    bit (xor is associative). This is what makes LMS cheap (Matoušek 1998: the scramble is linear
    over GF(2), so L P(m0 xor j) = L P(m0) xor the xor of L V_k over the bits of j; see
    `_lms_lanes`): about one xor per coordinate, cheaper than the Owen path's hash."""
    start = jnp.asarray(start)
    tail = start.shape[1:]
    if bits <= 1:
        row = jnp.arange(per, dtype=jnp.uint32)[:, None]
        value = jnp.broadcast_to(start, (per,) + tail)
        for k in range(bits):
            value = value ^ ((_u32(0) - ((row >> _u32(k)) & _u32(1))) & generator[..., k])
        return value
    low_bits = (bits + 1) // 2
    high = _xor_table(start, generator[..., low_bits:], bits - low_bits)            # (2^(bits-h), *tail)
    low = _xor_table(jnp.zeros_like(start), generator[..., :low_bits], low_bits)    # (2^h, *tail)
    # Materialized once per chunk (small): fused into the lanes' loop they would be recomputed
    # per lane.
    high, low = jax.lax.optimization_barrier((high, low))
    value = high[:, None] ^ low[None, :]                                             # (2^(bits-h), 2^h, *tail)
    return value.reshape((1 << bits,) + tail)[:per]


def _xor_table(start, generator, bits: int) -> jax.Array:
    """(2^bits, *start.shape[1:]): row a = start xor (xor of generator[..., k] over the bits k of a)."""
    row = jnp.arange(1 << bits, dtype=jnp.uint32).reshape((1 << bits,) + (1,) * (start.ndim - 1))
    value = jnp.broadcast_to(start, (1 << bits,) + start.shape[1:])
    for k in range(bits):
        value = value ^ ((_u32(0) - ((row >> _u32(k)) & _u32(1))) & generator[..., k])
    return value


def _padded_owen_pair(index, shuffle_seed, seed_a, seed_b):
    """Sobol' dimensions 1 and 2 at Burley's nested uniform shuffle of the index, each
    Owen-scrambled: dimension 1 of index y is reverse_bits(y) and dimension 2 is
    reverse_bits(pascal_superset_xor(y)), so the scramble's first reversal cancels."""
    shuffled = owen_scramble(index, shuffle_seed)
    return _scramble_reversed(shuffled, seed_a), _scramble_reversed(pascal_superset_xor(shuffled), seed_b)


def _padded_generator(shuffle, scramble_a, scramble_b, bits: int):
    """("lms" padding) the generator columns (..., bits) of the pair's two coordinates for index
    bits k < bits: L_a J M e_k and L_b P M e_k, M e_k being column k of the shuffle M
    (`triangular_columns`), J the bit reversal (dimension 1), P Pascal's matrix (dimension 2)."""
    column = shuffle[..., :bits]
    return (apply_columns(_reverse_bits(column), scramble_a[..., None, :]),
            apply_columns(_reverse_bits(pascal_superset_xor(column)), scramble_b[..., None, :]))

SourceLike = Union[str, Source]

# The sources `as_source` makes from a name, in the order they were registered: each class
# registers itself where it is defined (`register_source`), so this module needs none of the
# point sets that subclass `Source` in their own modules.
_BY_NAME: dict[str, type[Source]] = {}


def register_source(cls: type[Source]) -> type[Source]:
    """Class decorator: `as_source(cls.name)` makes `cls()` (the source with default settings)."""
    _BY_NAME[cls.name] = cls
    return cls


register_source(Random)
register_source(Stratified)
register_source(Sobol)


def as_source(uniforms: SourceLike) -> Source:
    """A registered name ("random" | "stratified" | "sobol" | "lattice" | "halton" | "lhs" |
    "hammersley": the source with default settings) or a `Source` instance."""
    if isinstance(uniforms, Source):
        return uniforms
    if isinstance(uniforms, str) and uniforms in _BY_NAME:
        return _BY_NAME[uniforms]()
    raise ValueError(f"uniforms: must be {', '.join(map(repr, _BY_NAME))} or a Source; got {uniforms!r}")


def uniform_block(uniforms: SourceLike, key: jax.Array, offset, count: int, dims: int, *,
                  dtype=None, total=None) -> jax.Array:
    """Points with global indices [offset, offset + count) of the stream `uniforms` draws with `key`.

    Calling it on consecutive windows gives exactly the points of one call on their union.
    `offset` is any index below 2^64 - count (a Python int, a traced integer below 2^32, or an
    `index.Index` of two uint32 words).
    `key` is a JAX key (`as_key`'s rule: typed, or a legacy uint32 key); `total` is the number
    of points of the whole stream (required for "stratified", and it bounds the Sobol' index).
    """
    source = as_source(uniforms)
    seed = seed_from_key(key, "uniform_block")
    dtype = resolve_float_dtype("uniform_block", dtype)
    return _block_jit(source, seed, as_index(offset, int(count)), int(count), int(dims), dtype, total)


@functools.partial(jax.jit, static_argnums=(0, 3, 4, 5, 6))
def _block_jit(source, seed, offset, count, dims, dtype, total):
    # One compilation per (source, count, dims, dtype, total); the offset is traced.
    return source.block(seed, offset, count, dims, dtype, total=total)
