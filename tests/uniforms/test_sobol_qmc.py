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

jax.config.update("jax_debug_key_reuse", True)

KEYS = iter(jax.random.split(jax.random.key(20261203), 64))

# Unscrambled Sobol' points (32-bit fractions, natural order) in dimensions past the old 128,
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
    pairs = np.concatenate([np.stack([j, j + 1], 1), np.stack([0 * j, j + 1], 1), np.stack([0 * j[1:] + 1, j[1:] + 1], 1),
                            np.random.default_rng(7).integers(0, 1024, (2000, 2))])
    pairs = pairs[pairs[:, 0] != pairs[:, 1]]
    t = t_values(points, pairs, 8)
    assert np.all(t <= np.minimum(degree[pairs[:, 0]] + degree[pairs[:, 1]] - 2, 8))
    assert t[0] == 0
    # The check can fail: dimension 1 paired with itself puts every point on the diagonal, so only
    # the intervals of one axis are balanced (t = 7 of 8).
    assert t_values(points, np.array([[0, 0]]), 8)[0] == 7
