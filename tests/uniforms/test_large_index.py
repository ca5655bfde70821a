"""Sample counts and 64-bit sample indices.

`n` is any concrete integer; a traced n is a TypeError that says how to make it static; the
replicated sources say how to change their replicate count. Sample indices have 64 bits: the point
with global index 2^33 + 5 is computed here from the documented counter layout (Philox, whose
known answers `test_uniforms.py` checks; Sobol' direction numbers xored in Python integers) and
must be the point every route gives: a window that starts at it, a window that contains it, the
generator lanes the estimators read, and the estimators' own streaming loop. Nothing here streams
2^33 points: the routes are called at 64-bit offsets directly.

No statistical checks here: every comparison is exact (bit for bit) or of a sum to float rounding.
"""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxsample as js
from jaxsample import uniforms as U

jax.config.update("jax_debug_key_reuse", True)

BIG = (1 << 33) + 5          # the index the checks are about
TOTAL = 1 << 40              # a stream length past 2^32 (stratification and the Sobol' bits use it)


def cos3(w):
    return w[2] ** 3


def key_of(i=0):
    """A fresh typed key (each call a new key object: uniform_block consumes the key it gets)."""
    return jax.random.key(1400 + i)


def seed_words(i=0):
    return U.seed_from_key(key_of(i))


# ---------------------------------------------------------------------------------------------
# The counter formulas, in Python integers and NumPy (independent of the library's index code)
# ---------------------------------------------------------------------------------------------


def philox_words(seed, counter):
    """The four output words of Philox4x32-10 for a counter of four Python ints."""
    out = U.philox4x32(tuple(np.uint32(c) for c in counter), (seed[0], seed[1]))
    return [int(w) for w in out]


def unit(word: int) -> np.float32:
    """bits_to_unit for float32: (top 23 bits + 1/2) 2^-23."""
    return np.float32(((word >> 9) + 0.5) * 2.0 ** -23)


def random_point_words(seed, i: int, dims: int, stream: int = 0) -> list[int]:
    """The documented layout: g = 4 // dims points per block (dims <= 4), point i takes words
    (i mod g) dims ... of the block with counter (b mod 2^32, 0, stream, b div 2^32), b = i div g;
    for dims > 4 the blocks (i mod 2^32, j, stream, i div 2^32), j = 0, 1, ..."""
    if dims > 4:
        words = []
        for j in range(-(-dims // 4)):
            words += philox_words(seed, (i & 0xFFFFFFFF, j, stream, i >> 32))
        return words[:dims]
    g = 4 // dims
    block, q = divmod(i, g)
    words = philox_words(seed, (block & 0xFFFFFFFF, 0, stream, block >> 32))
    return words[q * dims:(q + 1) * dims]


def expected_random(seed, i, dims):
    return np.array([unit(w) for w in random_point_words(seed, i, dims)], np.float32)


def expected_stratified(seed, i, dims, replicates, total):
    """Jitter from the Philox jitter stream (stream word 1); point p = i div R of its replicate is
    in cell (p mod s, p div s) of the s x s grid, s = isqrt(total / R) (p < s² here)."""
    jitter = np.array([unit(w) for w in random_point_words(seed, i, dims, stream=1)], np.float32)
    point = i // replicates
    side = math.isqrt(total // replicates)
    assert point < side * side
    top = np.nextafter(np.float32(1), np.float32(0))
    cells = [np.float32(point % side), np.float32(point // side)]
    first_two = [min((c + j) / np.float32(side), top) for c, j in zip(cells, jitter[:2])]
    return np.array(first_two + list(jitter[2:]), np.float32)


def sobol_fraction(point: int, dims: int) -> list[int]:
    """Unscrambled Sobol' point `point` (any index below 2^64): xor of the direction-number
    columns over its set bits, in Python integers."""
    table = U.sobol_direction_numbers(dims, 64)
    out = [0] * dims
    for k in range(64):
        if (point >> k) & 1:
            out = [o ^ int(table[d, k]) for d, o in enumerate(out)]
    return out


def expected_sobol(seed, i, dims, replicates):
    """Replicate i mod R, point i div R, each coordinate Owen-scrambled under its replicate's seed."""
    source = U.Sobol(replicates)
    seeds = np.asarray(source.scramble_seeds(seed, dims))[i % replicates]
    fraction = jnp.asarray(sobol_fraction(i // replicates, dims), jnp.uint32)
    return np.asarray(U.bits_to_unit(U.owen_scramble(fraction, jnp.asarray(seeds)), jnp.float32))


CASES = [  # (id, source, dims, formula)
    ("random-2d", U.Random(), 2, lambda s, i: expected_random(s, i, 2)),
    ("random-3d", U.Random(), 3, lambda s, i: expected_random(s, i, 3)),
    ("random-6d", U.Random(), 6, lambda s, i: expected_random(s, i, 6)),
    ("stratified-2d", U.Stratified(16), 2, lambda s, i: expected_stratified(s, i, 2, 16, TOTAL)),
    ("stratified-1d", U.Stratified(4), 1, None),
    # With 2 replicates, point 2^33 + 5 is point 2^32 + 2 of replicate 1: both index words count.
    ("sobol-2-replicates", U.Sobol(2), 3, lambda s, i: expected_sobol(s, i, 3, 2)),
    ("sobol-16-replicates", U.Sobol(16), 2, lambda s, i: expected_sobol(s, i, 2, 16)),
]


def _expected_stratified_1d(seed, i):
    jitter = unit(random_point_words(seed, i, 1, stream=1)[0])
    per_replicate = TOTAL // 4
    top = np.nextafter(np.float32(1), np.float32(0))
    return np.array([min((np.float32(i // 4) + jitter) / np.float32(per_replicate), top)], np.float32)


@pytest.mark.parametrize("name,source,dims,formula", CASES, ids=[c[0] for c in CASES])
def test_the_point_past_2_to_the_33_is_the_one_its_counter_formula_gives(name, source, dims, formula):
    """The point with global index 2^33 + 5 drawn alone (`uniform_block`, a 64-bit offset) is the
    counter formula's point, and so is that index reached as offset + k in a window that starts
    at 2^33 and in one that straddles 2^33; so is index 1000 (below 2^32 the points are those of
    the 32-bit counter, bit for bit)."""
    seed = seed_words()
    formula = formula or _expected_stratified_1d
    alone = np.asarray(U.uniform_block(source, key_of(), BIG, 1, dims, total=TOTAL))[0]
    np.testing.assert_array_equal(alone, formula(seed, BIG))
    # The other routes in one program (static offsets: each window is narrow or wide as it is).
    small, window, straddling = jax.jit(lambda s: (
        source.block(s, 1000, 1, dims, total=TOTAL), source.block(s, BIG - 5, 32, dims, total=TOTAL),
        source.block(s, BIG - 37, 48, dims, total=TOTAL)))(seed)
    np.testing.assert_array_equal(np.asarray(small)[0], formula(seed, 1000))
    np.testing.assert_array_equal(np.asarray(window)[5], formula(seed, BIG))
    np.testing.assert_array_equal(np.asarray(straddling)[37], formula(seed, BIG))
    np.testing.assert_array_equal(np.asarray(straddling)[32:], np.asarray(window)[:16])


@pytest.mark.parametrize("name,source,dims,formula", CASES, ids=[c[0] for c in CASES])
def test_lanes_at_a_64_bit_offset_are_the_block_points(name, source, dims, formula):
    """The form the estimators read (g groups of coordinate arrays, aligned chunks) at a two-word
    traced offset: the same points as `block`, in the documented interleaving."""
    from jaxsample.uniforms.index import Index

    seed = seed_words(1)
    count = 64
    both = jax.jit(lambda s, at: (source.lanes(s, at, count, dims, total=TOTAL, aligned=64),
                                  source.block(s, at, count, dims, total=TOTAL)))
    for offset in (BIG - 5, (1 << 33) + (1 << 31)):   # chunks aligned to 64, both index words used
        groups, block = both(seed, Index(jnp.uint32(offset >> 32), jnp.uint32(offset & 0xFFFFFFFF)))
        np.testing.assert_array_equal(np.asarray(block)[5 if offset == BIG - 5 else 0],
                                      (formula or _expected_stratified_1d)(
                                          seed, offset + (5 if offset == BIG - 5 else 0)))
        g = len(groups)
        points = np.empty((count, dims), np.float32)
        for q, lanes in enumerate(groups):
            points[q::g] = np.stack([np.asarray(c).reshape(-1) for c in lanes], axis=-1)
        np.testing.assert_array_equal(points, np.asarray(block))


@pytest.mark.parametrize("source", [U.Random(), U.Stratified(16), U.Sobol(16)], ids=["random", "stratified", "sobol"])
def test_the_streaming_loop_carries_its_offset_across_2_to_the_33(source):
    """The engine's chunk loop started just below 2^33 (64 points in chunks of 16, so one chunk
    begins at 2^33 and the high index word changes inside the loop): the per-replicate sums of
    the points equal those of the block of the same indices."""
    from jaxsample.estimators.engine import _stream
    from jaxsample.uniforms.index import as_index

    seed = seed_words(2)
    dims, base, count = 2, (1 << 33) - 32, 64
    moments = jax.jit(lambda s: _stream(lambda u: u, source, s, dims, jnp.float32, as_index(base, count),
                                        count, TOTAL, 16, (dims,), 16))(seed)
    block = np.asarray(U.uniform_block(source, key_of(2), base, count, dims, total=TOTAL), np.float64)
    replicates = source.replicates
    per_replicate = block.reshape(count // replicates, replicates, dims).sum(axis=0)
    got = np.asarray(moments.sums, np.float64) + np.asarray(moments.compensation, np.float64)
    np.testing.assert_allclose(got, per_replicate, rtol=1e-6)


def test_index_arithmetic_matches_python_integers():
    """The two-word helpers against Python integers, at the word boundary and far past it."""
    from jaxsample.uniforms.index import (as_index, divmod_index, floordiv, index_range, index_value,
                                          less_than, offset_at)

    def value(index):
        hi = 0 if index.hi is None else np.asarray(index.hi, np.uint64)
        return (np.uint64(hi) << np.uint64(32)) + np.asarray(index.lo, np.uint64)

    start = (1 << 32) - 3
    assert value(index_range(start, 6)).tolist() == list(range(start, start + 6))
    steps = jnp.asarray([0, 1, 5, 70_000], jnp.uint32)
    stride, base = 1 << 16, (1 << 38) + 12345
    assert value(offset_at(base, steps, stride, wide=True)).tolist() == [base + int(s) * stride for s in steps]
    # The mesh's device bases: device d starts at d x per_device.
    per_device = (1 << 36) + (1 << 16)
    assert value(offset_at(0, jnp.arange(4, dtype=jnp.uint32), per_device, wide=True)).tolist() == [
        d * per_device for d in range(4)]
    big = as_index(np.uint64((1 << 45) + 987_654_321))
    for divisor in (2, 3, 16, 1000, (1 << 32) - 1):
        quotient, remainder = divmod_index(big, divisor)
        assert int(value(quotient)) == ((1 << 45) + 987_654_321) // divisor
        assert int(remainder) == ((1 << 45) + 987_654_321) % divisor
        assert int(value(floordiv(big, divisor))) == ((1 << 45) + 987_654_321) // divisor
    assert bool(less_than(big, (1 << 45) + 987_654_322)) and not bool(less_than(big, (1 << 45) + 987_654_321))
    assert float(index_value(big, jnp.float32)) == float(np.float32((1 << 45) + 987_654_321))


# Sobol' past 2^32 points: the top 32 bits of the 64-bit Joe–Kuo points (new-joe-kuo-6.21201),
# from SciPy 1.17's direction numbers (scipy.stats._sobol._initialize_v(v, 128, bits=64), the
# xor over the index's bits done in Python, v >> 32), dimensions 1..8.
SOBOL_POINT_2_40_PLUS_1023 = [4290772992, 3250585600, 1405151360, 147816608, 1019216120, 3913318400,
                              2721605248, 3521413120]
SOBOL_POINT_2_32_PLUS_7 = [3758096384, 1610612736, 1216380928, 2551152856, 403144922, 3229614080,
                           1090020992, 614990626]


def test_sobol_points_past_2_to_the_32_continue_the_joe_kuo_sequence():
    from jaxsample.uniforms.index import as_index

    for index, expected in (((1 << 40) + 1023, SOBOL_POINT_2_40_PLUS_1023),
                            ((1 << 32) + 7, SOBOL_POINT_2_32_PLUS_7)):
        point = np.asarray(U.sobol_points(as_index(index), 8))
        assert point.tolist() == expected
    # The first 32 columns are the classical table; in dimension 1 (van der Corput) the columns
    # past 32 have no bits in a 32-bit fraction, so points i and i + 2^32 share theirs there only.
    assert np.array_equal(U.sobol_direction_numbers(8, 64)[:, :32], U.sobol_direction_numbers(8))
    low = np.asarray(U.sobol_points(jnp.asarray([7], jnp.uint32), 8))[0]
    assert low[0] == SOBOL_POINT_2_32_PLUS_7[0] and np.all(low[1:] != SOBOL_POINT_2_32_PLUS_7[1:])


@pytest.mark.parametrize("uniforms", ["random", "stratified", "sobol"])
def test_estimators_take_n_up_to_2_to_the_40(uniforms):
    """The whole program for n = 2^40 traces and lowers (nothing runs): no count or index
    overflows; `sample` past 2^32 elements too."""
    lowered = jax.jit(lambda k: js.estimate(cos3, js.CosineHemisphere(), k, 1 << 40, uniforms=uniforms)).lower(
        jax.random.key(3))
    assert lowered.out_info.n == 1 << 40 and "while" in lowered.as_text()
    # The device-mesh path (its device bases are 64-bit offsets), on a mesh of this one device.
    mesh = jax.make_mesh((1,), ("samples",))
    sharded = jax.jit(lambda k: js.estimate(cos3, js.CosineHemisphere(), k, 1 << 40, uniforms=uniforms,
                                            mesh=mesh)).lower(jax.random.key(4))
    assert sharded.out_info.n == 1 << 40
    drawn = jax.eval_shape(lambda k: js.UniformDisk().sample(k, ((1 << 32) + 4,)), jax.random.key(5))
    assert drawn.shape == ((1 << 32) + 4, 2)


def test_estimate_until_past_2_to_the_31_needs_x64_and_keeps_the_stream():
    """max_n >= 2^31 makes n_used int64 (under x64) and the offsets two-word indices; the samples
    are the same points, so a run that stops early equals the one with a small max_n."""
    d = js.CosineHemisphere()
    with pytest.raises(ValueError, match="max_n.*x64"):
        js.estimate_until(cos3, d, jax.random.key(5), rtol=0.5, max_n=1 << 33)
    with jax.enable_x64(True):
        wide = js.estimate_until(cos3, d, jax.random.key(5), rtol=0.5, max_n=1 << 33, chunk_size=1024,
                                 dtype=jnp.float32)
        narrow = js.estimate_until(cos3, d, jax.random.key(5), rtol=0.5, max_n=1 << 20, chunk_size=1024,
                                   dtype=jnp.float32)
    assert wide.n_used.dtype == jnp.int64 and int(wide.n_used) == int(narrow.n_used) == 8 * 1024
    assert float(wide.mean) == float(narrow.mean)


# ---------------------------------------------------------------------------------------------
# n: any concrete integer
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("n", [np.int64(4096), np.uint16(4096), jnp.int32(4096), jnp.asarray(4096, jnp.uint32),
                               4096.0, np.float32(4096)],
                         ids=["np.int64", "np.uint16", "jnp.int32", "jnp.uint32", "float", "np.float32"])
def test_n_accepts_any_concrete_integer(n):
    """The count becomes the Python int 4096 (traced only: the program is the one for 4096)."""
    est = jax.eval_shape(lambda k: js.estimate(cos3, js.CosineHemisphere(), k, n), jax.random.key(6))
    assert est.n == 4096 and type(est.n) is int


def test_bad_n_raises_a_clear_error():
    d = js.CosineHemisphere()
    with pytest.raises(TypeError, match="'n'.*bool"):
        js.estimate(cos3, d, jax.random.key(7), True)
    with pytest.raises(ValueError, match="'n' must be an integer"):
        js.estimate(cos3, d, jax.random.key(7), 4096.5)
    with pytest.raises(TypeError, match="'n'.*shape"):
        js.estimate(cos3, d, jax.random.key(7), jnp.asarray([4096]))
    with pytest.raises(TypeError, match="'n'"):
        js.estimate(cos3, d, jax.random.key(7), "4096")
    with pytest.raises(ValueError, match="'n' must be an integer >= 2"):
        js.estimate(cos3, d, jax.random.key(7), 1)
    with pytest.raises(TypeError, match="static_argnums.*static_argnames"):
        jax.jit(lambda n: js.estimate(cos3, d, jax.random.key(7), n).mean)(4096)
    with pytest.raises(TypeError, match="static_argnums"):
        jax.jit(lambda n: js.estimate_antithetic(cos3, d, jax.random.key(7), n).mean)(4096)
    # Counts that are fine as n can still exceed the loop's 2^31 chunks: raise chunk_size.
    with pytest.raises(ValueError, match="chunk_size"):
        js.estimate(cos3, d, jax.random.key(7), 1 << 40, chunk_size=4)


@pytest.mark.parametrize("uniforms,name", [("sobol", "Sobol"), ("stratified", "Stratified")])
def test_replicated_sources_say_how_to_change_the_replicate_count(uniforms, name):
    d = js.CosineHemisphere()
    with pytest.raises(ValueError, match=rf"multiple of 16 \(16 replicates\).*n = 1008.*{name}\(replicates=R\)"):
        js.estimate(cos3, d, jax.random.key(8), 1000, uniforms=uniforms)
    # ... and another replicate count accepts that n.
    source = getattr(U, name)(replicates=8)
    assert jax.eval_shape(lambda k: js.estimate(cos3, d, k, 1000, uniforms=source), jax.random.key(8)).n == 1000
    with pytest.raises(ValueError, match=r"Stratified\(replicates=\.\.\.\)"):
        U.uniform_block("stratified", key_of(3), 0, 8, 2, total=1000)


@pytest.mark.parametrize("scramble", ["permutation", "owen"])
def test_halton_points_agree_across_index_widths(scramble):
    """Halton digits come from uint32 arithmetic below 2^32 and uint64 above: the same points
    drawn through a 64-bit (two-word) offset equal the 32-bit ones, in both output dtypes."""
    from jaxsample.uniforms.index import Index

    source = U.Halton(replicates=3, scramble=scramble)
    seed = seed_words(7)
    for dtype in (jnp.float32, jnp.float64):
        with jax.enable_x64(dtype == jnp.float64):
            narrow = np.asarray(source.block(seed, 3000, 3 * 200, 6, dtype))
            wide = np.asarray(jax.jit(lambda s, at: source.block(s, at, 3 * 200, 6, dtype))(
                seed, Index(jnp.uint32(0), jnp.uint32(3000))))
        np.testing.assert_array_equal(wide, narrow)
