"""Uniform sources: Philox known answers, uniformity, serial correlation, Sobol' points, chunking.

Every statistical check states its false-failure rate (FFR) under a correct generator and is shown
to fail on a deliberately wrong input.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxsample import uniforms as U

from keyring import fixed_key, next_key

jax.config.update("jax_debug_key_reuse", True)


# Random123 kat_vectors, "philox4x32 10" lines: counter[4], key[2] -> output[4].
PHILOX_KAT = [
    ((0, 0, 0, 0), (0, 0), (0x6627E8D5, 0xE169C58D, 0xBC57AC4C, 0x9B00DBD8)),
    ((0xFFFFFFFF,) * 4, (0xFFFFFFFF,) * 2, (0x408F276D, 0x41C83B0E, 0xA20BC7C6, 0x6D5451FD)),
    ((0x243F6A88, 0x85A308D3, 0x13198A2E, 0x03707344), (0xA4093822, 0x299F31D0),
     (0xD16CFE09, 0x94FDCCEB, 0x5001E420, 0x24126EA1)),
]


def chi2_upper(dof, z):
    """Wilson–Hilferty: the chi-square(dof) quantile at normal quantile z."""
    return dof * (1 - 2 / (9 * dof) + z * np.sqrt(2 / (9 * dof))) ** 3


Z_1E6 = 4.753  # one-sided normal quantile for 1e-6


def chi2_uniformity(u, bins=1024):
    counts = np.bincount(np.minimum((u * bins).astype(np.int64), bins - 1), minlength=bins)
    expected = len(u) / bins
    return float(np.sum((counts - expected) ** 2 / expected)), bins - 1


def uniform_ok(u):
    """Both tails of the chi-square at 1e-6 each: FFR 2e-6 per call."""
    stat, dof = chi2_uniformity(u)
    return chi2_upper(dof, -Z_1E6) < stat < chi2_upper(dof, Z_1E6)


def correlation_ok(a, b):
    """|Pearson r| < 5.3/sqrt(N): r ~ N(0, 1/N) for independent uniforms, FFR 1.2e-7."""
    r = np.corrcoef(a, b)[0, 1]
    return abs(r) < 5.3 / np.sqrt(len(a))


@pytest.mark.parametrize("counter,key,expected", PHILOX_KAT)
def test_philox_known_answers(counter, key, expected):
    out = U.philox4x32(tuple(np.uint32(c) for c in counter), tuple(np.uint32(k) for k in key))
    assert [int(v) for v in out] == list(expected)


def test_philox_known_answers_vectorized_and_jitted():
    counters = [jnp.asarray([kat[0][i] for kat in PHILOX_KAT], jnp.uint32) for i in range(4)]
    keys = [jnp.asarray([kat[1][i] for kat in PHILOX_KAT], jnp.uint32) for i in range(2)]
    out = jax.jit(U.philox4x32)(counters, keys)
    got = np.stack([np.asarray(o) for o in out], axis=-1)
    assert (got == np.array([kat[2] for kat in PHILOX_KAT], np.uint32)).all()


def test_bits_to_unit_edges_are_strictly_inside():
    bits = jnp.asarray([0, 0xFFFFFFFF, 0x80000000], jnp.uint32)
    u = np.asarray(U.bits_to_unit(bits, jnp.float32))
    assert u[0] == 2.0 ** -24 and u[1] == np.float32(1 - 2.0 ** -24) and u[2] == 0.5 + 2.0 ** -24
    with jax.enable_x64(True):
        u64 = np.asarray(U.bits_to_unit(bits, jnp.float64))
    assert u64[0] == 2.0 ** -33 and u64[1] == 1 - 2.0 ** -33


@pytest.fixture(scope="module")
def random_points():
    return np.asarray(U.uniform_block("random", fixed_key("random_points"), 0, 1 << 20, 3))


def test_random_range_and_uniformity(random_points):
    # FFR 8e-6: four chi-square checks at 2e-6 each (the range check is exact).
    assert random_points.min() > 0 and random_points.max() < 1
    for j in range(3):
        assert uniform_ok(random_points[:, j])
    # 2-D uniformity of the pair (u0, u1) on a 32 x 32 grid.
    cell = (random_points[:, 0] * 32).astype(int) * 32 + (random_points[:, 1] * 32).astype(int)
    assert uniform_ok((cell + 0.5) / 1024)


def test_random_serial_correlation(random_points):
    # FFR 4.8e-7: four correlation checks at 1.2e-7 each.
    u = random_points
    assert correlation_ok(u[:-1, 0], u[1:, 0])   # lag 1 in the sample index
    assert correlation_ok(u[:-2, 1], u[2:, 1])   # lag 2 (the two samples sharing a Philox block)
    assert correlation_ok(u[:, 0], u[:, 1])      # across dimensions
    assert correlation_ok(u[:, 0], u[:, 2])


def test_statistical_checks_fail_on_bad_streams(random_points):
    u = random_points[:, 0]
    assert not uniform_ok(u ** 1.05)                     # a slightly non-uniform transform
    assert not uniform_ok(np.round(u * 512) / 512)       # too coarse a grid
    smoothed = 0.5 * (u[:-1] + u[1:])                    # serially dependent stream
    assert not correlation_ok(smoothed[:-1], smoothed[1:])


def test_different_keys_and_streams_differ():
    a = np.asarray(U.uniform_block("random", next_key(), 0, 4096, 2))
    b = np.asarray(U.uniform_block("random", next_key(), 0, 4096, 2))
    assert not np.any(a == b) or np.mean(a == b) < 1e-3
    assert correlation_ok(a[:, 0], b[:, 0])  # FFR 1.2e-7


@pytest.mark.parametrize("source", ["random", "stratified", "sobol"])
@pytest.mark.parametrize("dims", [1, 2, 6])
def test_chunking_never_changes_the_points(source, dims):
    key = next_key()  # one key, cloned per call: every call derives the same seed words from it
    total = 4096
    whole = U.uniform_block(source, jax.random.clone(key), 0, total, dims, total=total)
    cuts = [0, 1365, 2730, 4095, total]  # odd offsets: windows straddle Philox blocks
    pieces = [U.uniform_block(source, jax.random.clone(key), a, b - a, dims, total=total)
              for a, b in zip(cuts, cuts[1:])]
    np.testing.assert_array_equal(np.asarray(whole), np.concatenate([np.asarray(p) for p in pieces]))
    # A traced offset (as inside lax.scan) gives the same window.
    traced = jax.jit(lambda off: U.uniform_block(source, jax.random.clone(key), off, 1365, dims, total=total))(1027)
    np.testing.assert_array_equal(np.asarray(traced), np.asarray(whole)[1027:2392])
    assert float(whole.min()) > 0 and float(whole.max()) < 1


def test_random_lanes_are_the_same_points_as_block():
    seed = U.seed_from_key(next_key())
    block = np.asarray(U.Random().block(seed, 64, 1024, 2))
    groups = [np.stack(lanes, axis=-1) for lanes in U.Random().lanes(seed, 64, 1024, 2, aligned=True)]
    np.testing.assert_array_equal(block[0::2], groups[0])
    np.testing.assert_array_equal(block[1::2], groups[1])


# Unscrambled Sobol' points, natural order, new-joe-kuo-6.21201 (checked against SciPy's
# Joe–Kuo implementation, Gray-code order remapped): first 8 points of dims 1..5, times 8 ...
SOBOL_FIRST_8 = [[0, 4, 2, 6, 1, 5, 3, 7], [0, 4, 6, 2, 5, 1, 3, 7], [0, 4, 6, 2, 3, 7, 5, 1],
                 [0, 4, 6, 2, 1, 5, 7, 3], [0, 4, 2, 6, 1, 5, 3, 7]]
# ... and point 1023 in all 128 dimensions, times 1024.
SOBOL_POINT_1023 = [
    1023, 261, 749, 451, 921, 263, 753, 303, 735, 669, 333, 275, 239, 987, 677, 753, 459, 411, 237,
    429, 557, 29, 583, 499, 23, 135, 59, 989, 723, 359, 425, 731, 185, 877, 311, 215, 67, 637, 645,
    293, 113, 995, 745, 633, 619, 409, 23, 39, 437, 857, 571, 659, 737, 419, 599, 227, 675, 883, 795,
    51, 255, 315, 615, 607, 659, 255, 623, 287, 303, 231, 311, 203, 499, 519, 755, 195, 325, 245,
    565, 77, 397, 509, 325, 381, 317, 725, 5, 813, 357, 313, 953, 873, 569, 337, 497, 945, 561, 817,
    161, 737, 385, 97, 509, 937, 909, 199, 855, 783, 767, 3, 481, 301, 81, 867, 647, 775, 913, 473,
    643, 979, 299, 137, 423, 677, 11, 37, 703, 187]


def test_sobol_known_points():
    first = np.asarray(U.sobol_points(jnp.arange(8, dtype=jnp.uint32), 5)).astype(np.float64) / 2 ** 32
    np.testing.assert_array_equal(first.T * 8, np.array(SOBOL_FIRST_8, float))
    point = np.asarray(U.sobol_points(jnp.asarray([1023], jnp.uint32), 128))[0].astype(np.float64)
    np.testing.assert_array_equal(point / 2 ** 22, np.array(SOBOL_POINT_1023, float))


def test_scrambled_sobol_keeps_the_net_property():
    """Owen scrambling keeps the (0, m, 2)-net of dims 1-2 and 1-D stratification of every dim.

    Deterministic for every seed (no FFR); fails for unscrambled-but-shifted or random points.
    """
    source = U.Sobol(replicates=4)
    m = 1024
    points = np.asarray(U.uniform_block(source, next_key(), 0, 4 * m, 64, total=4 * m))
    for r in range(4):
        rep = points[r::4]
        for j in range(64):
            assert np.bincount((rep[:, j] * m).astype(int), minlength=m).max() == 1
        cells = (rep[:, 0] * 32).astype(int) * 32 + (rep[:, 1] * 32).astype(int)
        assert np.bincount(cells, minlength=m).max() == 1
    assert not np.array_equal(points[0::4], points[1::4])
    rand = np.asarray(U.uniform_block("random", next_key(), 0, m, 1))
    assert np.bincount((rand[:, 0] * m).astype(int), minlength=m).max() > 1


def test_scrambled_sobol_points_are_uniform_over_keys():
    """Point 0 of replicate 0 over 2^14 keys is uniform in each of 4 dims (chi2, FFR 8e-6)."""
    keys = jax.random.split(next_key(), 1 << 14)
    first = jax.vmap(lambda k: U.uniform_block(U.Sobol(2), k, 0, 2, 4, total=2)[0])(keys)
    first = np.asarray(first)
    for j in range(4):
        assert uniform_ok(first[:, j])
    stuck = np.asarray(U.sobol_points(jnp.zeros(1 << 14, jnp.uint32), 1))[:, 0] / 2 ** 32 + 1e-9
    assert not uniform_ok(stuck)


def test_sobol_scrambles_are_independent_across_dimensions_and_replicates():
    """Each (replicate, dimension) has its own Owen-scramble seed, so over keys the scrambled
    points of two dimensions are independent. Unscrambled, point 0 is 0 in every dimension and
    point 1 is 1/2: with one seed shared by all dimensions the scrambled coordinates would be equal
    (r = 1). Seeds: the 4 x 128 seeds of one key are all distinct (deterministic). Points: over
    2^14 keys, point 0 and point 1 of replicates 0 and 1 in dims 0..7; every pair of dimensions
    and the two replicates of a dimension are uncorrelated (|r| < 5.3/sqrt(N), FFR 1.2e-7 per
    pair; 2 x 28 + 8 pairs: 7.7e-6 in all). tests/mutations.py records that a shared seed fails."""
    seeds = np.asarray(U.Sobol(4).scramble_seeds(U.seed_from_key(next_key()), 128))
    assert seeds.shape == (4, 128) and len(np.unique(seeds)) == seeds.size
    keys = jax.random.split(next_key(), 1 << 14)
    dims = 8
    points = np.asarray(jax.jit(jax.vmap(lambda k: U.uniform_block(U.Sobol(2), k, 0, 4, dims, total=4)))(keys))
    # Global index g = 2 p + r: rows 0, 1 are point 0 of replicates 0, 1; rows 2, 3 are point 1.
    for row in (0, 2):
        for a in range(dims):
            for b in range(a + 1, dims):
                assert correlation_ok(points[:, row, a], points[:, row, b]), (row, a, b)
    for a in range(dims):
        assert correlation_ok(points[:, 0, a], points[:, 1, a]), a


def test_stratified_one_point_per_cell():
    m = 33 * 33 + 7  # not a square: 7 leftover random points per replicate
    source = U.Stratified(replicates=2)
    points = np.asarray(U.uniform_block(source, next_key(), 0, 2 * m, 3, total=2 * m))
    for r in range(2):
        rep = points[r::2][: 33 * 33]
        cells = (rep[:, 0] * 33).astype(int) * 33 + (rep[:, 1] * 33).astype(int)
        assert np.bincount(cells, minlength=33 * 33).max() == 1
    one_d = np.asarray(U.uniform_block(U.Stratified(2), next_key(), 0, 2000, 1, total=2000))
    assert np.bincount((one_d[0::2, 0] * 1000).astype(int), minlength=1000).max() == 1


def test_invalid_arguments_raise():
    with pytest.raises(ValueError, match="uniforms"):
        U.as_source("no-such-source")
    with pytest.raises(ValueError, match="replicates"):
        U.Sobol(replicates=1)
    with pytest.raises(ValueError, match="total"):
        U.uniform_block("stratified", next_key(), 0, 8, 2)
    with pytest.raises(TypeError, match="PRNG key"):
        U.seed_from_key(jnp.zeros(2, jnp.uint32) + 1.0)
