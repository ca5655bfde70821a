"""Sobol' breadth: 1024 Joe–Kuo dimensions, linear matrix scrambling, padded 2-D Sobol'.

Deterministic checks (net counts, known values) have no false-failure rate; every statistical
check states its false-failure rate (FFR) under a correct generator, and tests/mutations.py
records a deliberately wrong generator for each that the check catches.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxsample import uniforms as U
from jaxsample.uniforms import sobol as S

from keyring import next_key

jax.config.update("jax_debug_key_reuse", True)


# Unscrambled Sobol' points (32-bit fractions, natural order) in dimensions past 128,
# computed once with SciPy 1.17.1: scipy.stats.qmc.Sobol(d=1024, scramble=False, bits=32)
# .random(2**20) * 2**32, whose rows are in Gray-code order (row n is natural point n ^ (n >> 1)),
# remapped to natural order.
SOBOL_1023_DIMS = [129, 256, 512, 700, 1000, 1024]
SOBOL_1023 = [297795584, 742391808, 2394947584, 1933574144, 1589641216, 641728512]
SOBOL_777777_DIMS = list(range(1017, 1025))
SOBOL_777777 = [1755394048, 2178994176, 3491958784, 2600538112, 3447861248, 1982410752, 2739859456, 2521640960]


def t_values(points: np.ndarray, pairs: np.ndarray, m: int) -> np.ndarray:
    """For each pair of columns, the least t such that the first 2^m points hold exactly 2^t
    points in every elementary interval [a 2^-d1, (a+1) 2^-d1) x [b 2^-d2, (b+1) 2^-d2) with
    d1 + d2 = m - t: the t of the (t, m, 2)-net they form (points: uint32 fractions)."""
    x = points[: 1 << m].astype(np.uint64)
    a, b = x[:, pairs[:, 0]], x[:, pairs[:, 1]]
    result = np.full(len(pairs), m)
    for t in range(m, -1, -1):
        k = m - t
        ok = np.ones(len(pairs), bool)
        for d1 in range(k + 1):
            d2 = k - d1
            cell = ((a >> np.uint64(32 - d1)) << np.uint64(d2)) | (b >> np.uint64(32 - d2))
            cell = cell.astype(np.int64) + (np.arange(len(pairs)) << k)[None, :]
            counts = np.bincount(cell.ravel(), minlength=len(pairs) << k).reshape(len(pairs), 1 << k)
            ok &= (counts == 1 << t).all(axis=1)
        result = np.where(ok, t, result)
    return result


def one_d_nets(points: np.ndarray, m: int) -> bool:
    """Whether the first 2^m points of every column hold one point in each [a 2^-m, (a+1) 2^-m)."""
    cells = (points[: 1 << m] >> np.uint32(32 - m)).astype(np.int64)
    cells = cells + (np.arange(points.shape[1]) << m)[None, :]
    return bool((np.bincount(cells.ravel(), minlength=points.shape[1] << m) == 1).all())


# ---- 1. 1024 dimensions ------------------------------------------------------------------------

def test_sobol_has_1024_joe_kuo_dimensions():
    """Known points in dimensions 129..1024 (SciPy's Joe–Kuo table, see above); the first 128
    dimensions are pinned by test_uniforms.py::test_sobol_known_points."""
    assert U.MAX_SOBOL_DIMS == 1024
    points = np.asarray(U.sobol_points(jnp.asarray([1023, 777777], jnp.uint32), 1024))
    assert points[0, np.array(SOBOL_1023_DIMS) - 1].tolist() == SOBOL_1023
    assert points[1, np.array(SOBOL_777777_DIMS) - 1].tolist() == SOBOL_777777
    with pytest.raises(ValueError, match=r"'dims' must be in \[1, 1024\]"):
        U.sobol_direction_numbers(1025)


def test_every_joe_kuo_dimension_is_a_net_with_the_sobol_t_bound():
    """Each of the 1024 one-dimensional projections of the first 2^12 points is a (0, 12, 1)-net
    (every generator matrix is nonsingular); every pair of dimensions i, j, over 2^8 points,
    is a (t, 8, 2)-net with t <= (s_i - 1) + (s_j - 1), s the degree of the dimension's primitive
    polynomial (Sobol' 1967; dimension 1 counts as degree 1), checked for all adjacent pairs, all
    pairs with dimension 1 or 2, and 2000 further pairs; the pair (1, 2) has t = 0."""
    # The NumPy table of the first 2^12 points (bit-reversed, as the fast path keeps it), the same
    # points as `sobol_points`.
    points = S._reverse_bits_np(S._sobol_low_table(12, 1024))
    np.testing.assert_array_equal(points[:256], np.asarray(U.sobol_points(jnp.arange(256, dtype=jnp.uint32), 1024)))
    assert one_d_nets(points, 12)
    degree = np.array([1] + [s for s, _, _ in S._joe_kuo_lines()])
    j = np.arange(1023)
    pairs = np.concatenate([np.stack([j, j + 1], 1), np.stack([0 * j, j + 1], 1),
                            np.stack([0 * j[1:] + 1, j[1:] + 1], 1),
                            np.random.default_rng(7).integers(0, 1024, (2000, 2))])
    pairs = pairs[pairs[:, 0] != pairs[:, 1]]
    t = t_values(points, pairs, 8)
    assert np.all(t <= np.minimum(degree[pairs[:, 0]] + degree[pairs[:, 1]] - 2, 8))
    assert t[0] == 0
    # The check can fail: dimension 1 paired with itself puts every point on the diagonal, so only
    # the intervals of one axis are balanced (t = 7 of 8).
    assert t_values(points, np.array([[0, 0]]), 8)[0] == 7


# ---- 2, 3. linear matrix scrambling and padding ----------------------------------------------

VARIANTS = {"lms": dict(scramble="lms"), "owen-padded": dict(padding=True),
            "lms-padded": dict(scramble="lms", padding=True)}


def fractions(source, seed, count, dims):
    """The 32-bit fractions behind `source.block` (before the float grid)."""
    if source.padding:
        return np.asarray(source._padded_block(seed, 0, count, dims))
    return np.asarray(source._lms_block(seed, 0, count, dims, None))


@pytest.mark.parametrize("name", VARIANTS)
def test_lanes_block_and_chunks_give_the_same_points(name):
    source = U.Sobol(4, **VARIANTS[name])
    seed = U.seed_from_key(next_key())
    for dims, offset in ((1, 0), (3, 1024), (6, 1 << 40)):
        block = np.asarray(source.block(seed, offset, 1024, dims))
        lanes = source.lanes(seed, offset, 1024, dims, aligned=1024)
        np.testing.assert_array_equal(block, np.stack([c.reshape(-1) for c in lanes[0]], -1))
        pieces = [np.asarray(source.block(seed, offset + a, b - a, dims)) for a, b in ((0, 333), (333, 1024))]
        np.testing.assert_array_equal(block, np.concatenate(pieces))
        assert block.min() > 0 and block.max() < 1


def test_lms_keeps_every_t_and_padding_makes_each_pair_a_0_m_2_net():
    """Deterministic for every seed: LMS + digital shift keeps the t-value of every pair of the 8
    first dimensions and the (0, 10, 1)-net of every coordinate; with padding each pair (2k,
    2k + 1) of every replicate is a (0, 10, 2)-net (counts of every elementary interval). Only the
    last check (coordinates of two pairs are not a net) is random: FFR 5e-6, see there."""
    seed = U.seed_from_key(next_key())
    R, m = 4, 10
    pairs = np.array([[a, b] for a in range(8) for b in range(a + 1, 8)])
    plain = np.asarray(U.sobol_points(jnp.arange(1 << m, dtype=jnp.uint32), 8))
    expected = t_values(plain, pairs, m)
    lms = fractions(U.Sobol(R, scramble="lms"), seed, R << m, 8)
    for r in range(R):
        assert one_d_nets(lms[r::R], m)
        np.testing.assert_array_equal(t_values(lms[r::R], pairs, m), expected)
    for name in ("owen-padded", "lms-padded"):
        padded = fractions(U.Sobol(R, **VARIANTS[name]), seed, R << m, 8)
        for r in range(R):
            assert one_d_nets(padded[r::R], m)
            assert np.all(t_values(padded[r::R], np.array([[0, 1], [2, 3], [4, 5], [6, 7]]), m) == 0)
    # The check can fail: coordinates of two different pairs are not a 2-D net. Two independent
    # linear scrambles do make one by chance (LMS padding: t = 0 for coordinates 0 and 2 of one
    # replicate under 3 of 64 keys), so the check asks it of any of the R replicates:
    # all four at t = 0 has probability about (3/64)^4 = 5e-6.
    assert max(t_values(padded[r::R], np.array([[0, 2]]), m)[0] for r in range(R)) > 0


def chi2_ok(u, bins=64):
    """Two-sided chi-square at 1e-6 per tail (Wilson–Hilferty): FFR 2e-6 per call."""
    counts = np.bincount(np.minimum((u * bins).astype(np.int64), bins - 1), minlength=bins)
    expected = len(u) / bins
    stat, dof = float(np.sum((counts - expected) ** 2 / expected)), bins - 1
    q = lambda z: dof * (1 - 2 / (9 * dof) + z * np.sqrt(2 / (9 * dof))) ** 3
    return q(-4.753) < stat < q(4.753)


@pytest.mark.parametrize("name", VARIANTS)
def test_points_are_uniform_and_independent_across_dimensions_and_replicates(name):
    """Over 2^13 keys, points 0 and 1 of replicates 0 and 1 in 6 dimensions: every coordinate is
    uniform (chi-square, 64 bins, FFR 2e-6 each: 24 calls, 4.8e-5) and every pair of coordinates
    is uncorrelated (|r| < 5.3 / sqrt(N), FFR 1.2e-7 each; 2 x 15 + 12 pairs: 5e-6). Unscrambled,
    points 0 and 1 are 0 and 1/2 in every dimension, so a scramble shared by the dimensions (or
    the pairs) makes the coordinates equal: tests/mutations.py records that this fails."""
    source = U.Sobol(2, **VARIANTS[name])
    keys = jax.random.split(next_key(), 1 << 13)
    points = np.asarray(jax.jit(jax.vmap(lambda k: U.uniform_block(source, k, 0, 4, 6, total=4)))(keys))
    limit = 5.3 / np.sqrt(len(keys))
    for row in range(4):
        for a in range(6):
            assert chi2_ok(points[:, row, a]), (row, a)
    for row in (0, 2):
        for a in range(6):
            for b in range(a + 1, 6):
                assert abs(np.corrcoef(points[:, row, a], points[:, row, b])[0, 1]) < limit, (row, a, b)
    for a in range(6):
        assert abs(np.corrcoef(points[:, 0, a], points[:, 1, a])[0, 1]) < limit, a
        assert abs(np.corrcoef(points[:, 2, a], points[:, 3, a])[0, 1]) < limit, a
    # The check can fail: u^1.5 has density (2/3) u^(-1/3), a noncentrality of ~2000 at these
    # 8192 keys (u^1.1, ~80, is rejected only ~70% of the time: too weak a canary to be stable).
    assert not chi2_ok(points[:, 0, 0] ** 1.5)


@pytest.mark.parametrize("name", VARIANTS)
def test_randomized_estimates_are_unbiased(name):
    """∫ sum_j x_j^2 over [0,1]^5 = 5/3: the mean over 400 keys of the 2^8-point estimate of
    one replicate lies within 3.3 standard errors of it (the spread of the 400, FFR 1e-3)."""
    source = U.Sobol(2, **VARIANTS[name])
    keys = jax.random.split(next_key(), 400)
    points = jax.vmap(lambda k: U.uniform_block(source, k, 0, 512, 5, total=512)[0::2])(keys)
    estimates = np.asarray(jnp.mean(jnp.sum(points * points, axis=-1), axis=-1), np.float64)
    assert abs(estimates.mean() - 5 / 3) < 3.3 * estimates.std(ddof=1) / np.sqrt(len(estimates))


def test_variants_in_estimators_and_their_parameters():
    # FFR at most 4.8e-4: three means within 5 stderrs of 16 replicates (|t_15| > 5: 1.6e-4 each for
    # normal replicate means; the 1e-6 allowance is 0.2-1 stderr here, and no key of 8000 failed).
    import jaxsample as js

    box = js.UniformBox(jnp.zeros(3), jnp.ones(3))
    for name, options in VARIANTS.items():
        est = js.estimate(lambda x: jnp.sum(x * x), box, next_key(), 1 << 14, uniforms=U.Sobol(16, **options))
        assert abs(float(est.mean) - 1.0) < 5 * float(est.stderr) + 1e-6, name
    wide = U.uniform_block(U.Sobol(4, padding=True), next_key(), 0, 64, 2000, total=64)
    assert wide.shape == (64, 2000)
    assert U.Sobol(4) == U.Sobol(4, scramble="owen", padding=False) != U.Sobol(4, scramble="lms")
    with pytest.raises(ValueError, match="'scramble'"):
        U.Sobol(4, scramble="xor")
    with pytest.raises(ValueError, match="'padding'"):
        U.Sobol(4, padding=1)
    with pytest.raises(ValueError, match=r"'dims' must be in \[1, 1024\]"):
        U.uniform_block(U.Sobol(4), next_key(), 0, 8, 1025, total=8)


@pytest.mark.parametrize("name", ["lms", "lms-padded"])
def test_lms_lanes_split_tables_equal_the_per_point_scramble(name):
    """The lanes' high[j_hi] xor low[j_lo] split (odd bit counts, a per that is not a power of
    two, a 64-bit offset) gives the points of the per-point L P(i) + e of `block`."""
    source = U.Sobol(3, **VARIANTS[name])
    seed = U.seed_from_key(next_key())
    for per, dims, offset in ((5, 2, 0), (100, 3, 3 << 7), (1000, 5, (3 << 40) + (3 << 10))):
        count = per * 3
        block = np.asarray(source.block(seed, offset, count, dims))
        lanes = source.lanes(seed, offset, count, dims, aligned=3 << (per - 1).bit_length())
        assert lanes[0][0].shape == (per, 3)
        np.testing.assert_array_equal(block, np.stack([c.reshape(-1) for c in lanes[0]], -1))
