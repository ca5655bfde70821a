"""The replicated point sets: rank-1 lattice (`Lattice`), scrambled Halton (`Halton`) and Latin
hypercube (`LatinHypercube`).

For each: the points equal their closed form (computed here in NumPy with Python integers), the
randomization makes every point uniform (chi-square over keys) and is independent across
replicates and dimensions (correlation over keys), the estimate is unbiased, and the error falls
at about the literature's rate on a smooth integrand. Every statistical check states its
false-failure rate (FFR) for a correct source; tests/mutations.py records defects they catch.
"""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxsample as js
from jaxsample import uniforms as U
from jaxsample.uniforms import lattice as lattice_module

from keyring import next_key

jax.config.update("jax_debug_key_reuse", True)



def chi2_upper(dof, z):
    """Wilson–Hilferty: the chi-square(dof) quantile at normal quantile z."""
    return dof * (1 - 2 / (9 * dof) + z * np.sqrt(2 / (9 * dof))) ** 3


Z_1E6 = 4.753  # one-sided normal quantile for 1e-6


def chi2_stat(u, bins):
    counts = np.bincount(np.minimum((u * bins).astype(np.int64), bins - 1), minlength=bins)
    expected = len(u) / bins
    return float(np.sum((counts - expected) ** 2 / expected)), bins - 1


def uniform_ok(u, bins=64):
    """Both tails of the chi-square at 1e-6 each: FFR 2e-6 per call (independent uniforms)."""
    stat, dof = chi2_stat(u, bins)
    return chi2_upper(dof, -Z_1E6) < stat < chi2_upper(dof, Z_1E6)


def correlation_ok(a, b):
    """|Pearson r| < 5.3/sqrt(N): r ~ N(0, 1/N) for independent variables, FFR 1.2e-7."""
    return abs(np.corrcoef(a, b)[0, 1]) < 5.3 / np.sqrt(len(a))


def rev(value, bits):
    return int(format(value, f"0{bits}b")[::-1], 2)


def unit32(words):
    """bits_to_unit's float32 grid from uint32 words (NumPy): (top 23 bits + 1/2) 2^-23."""
    return ((np.asarray(words, np.uint64) >> 9).astype(np.float64) + 0.5) * 2.0 ** -23


# ------------------------------------------------------------------------------------------------
# Lattice
# ------------------------------------------------------------------------------------------------

def _shortest_dual(z, m: int, reach: int = 40) -> int:
    """min over nonzero h in the dual lattice {h : h.z = 0 mod 2^m} of prod_j max(1, |h_j|)
    (Zaremba's index), searching |h_2|, |h_3| <= reach with h_1 solved for."""
    n = 1 << m
    h2, h3 = np.meshgrid(np.arange(-reach, reach + 1), np.arange(-reach, reach + 1))
    h1 = -(h2 * int(z[1]) + h3 * int(z[2])) % n
    h1 = np.where(h1 > n // 2, h1 - n, h1)
    weight = np.maximum(1, np.abs(h1)) * np.maximum(1, np.abs(h2)) * np.maximum(1, np.abs(h3))
    return int(weight[(h2 != 0) | (h3 != 0)].min())


def test_lattice_vector_has_no_short_dual_vector_in_three_dimensions():
    """The generating vector's first three coordinates make a good rule at every 2^m it was built
    for. Kuo's order-2-weight vector lattice-32001-1024-1048576.3600 has index 20 .. 22 for
    m = 10 .. 16 (h = (-1, -11, -2), in its dual lattice for every m <= 16, is the shortest for
    m = 13 .. 16): smooth 3-d integrands stall near 1e-5 error there. This one's index is
    30 .. 21788 over m = 10 .. 20. The bound 90 from m = 12 on fails lattice-32001 at m = 12 .. 16."""
    z = U.lattice_generating_vector(3).astype(np.int64)
    index = {m: _shortest_dual(z, m) for m in range(10, 21)}
    assert all(index[m] >= 90 for m in range(12, 21)), index
    assert min(index.values()) >= 30, index


def test_lattice_points_are_the_rank1_rule_in_radical_inverse_order():
    """Point i of the unshifted sequence is frac(phi_2(i) z): for i < 2^m, (rev_m(i) z mod 2^m) / 2^m
    (Python integers); each prefix of 2^m points is the whole rule {k z / 2^m mod 1}; a 64-bit
    index gives the top 32 bits of frac(rev64(i) z / 2^64)."""
    dims, m = 6, 7
    z = [int(v) for v in U.lattice_generating_vector(dims)]
    assert z[:4] == [1, 182667, 279195, 223491]   # Kuo's lattice-39101-1024-1048576.3600
    points = np.asarray(U.lattice_points(jnp.arange(1 << m, dtype=jnp.uint32), dims)).astype(np.int64)
    for i in range(1 << m):
        expected = [((rev(i, m) * zj) % (1 << m)) << (32 - m) for zj in z]
        assert list(points[i]) == expected, i
    rule = {tuple(((k * zj) % (1 << m)) << (32 - m) for zj in z) for k in range(1 << m)}
    assert {tuple(p) for p in points} == rule
    wide = [(1 << 32) + 5, (1 << 40) + (3 << 33) + 12345, (1 << 64) - 1]
    index = U.index.Index(jnp.asarray([w >> 32 for w in wide], jnp.uint32),
                          jnp.asarray([w & 0xFFFFFFFF for w in wide], jnp.uint32))
    got = np.asarray(U.lattice_points(index, dims)).astype(np.int64)
    for row, i in zip(got, wide):
        assert list(row) == [((rev(i, 64) * zj) % (1 << 64)) >> 32 for zj in z]


@pytest.mark.parametrize("tent", [True, False])
def test_lattice_source_is_the_shifted_rule_with_the_tent(tent):
    """Global index g = R p + r is frac(phi_2(p) z + Delta_r), then the tent as a bijection of the
    32-bit grid; checked word for word through bits_to_unit's float32 grid, on a narrow window
    and on one past 2^32."""
    source, dims = U.Lattice(replicates=4, tent=tent), 5
    seed = U.seed_from_key(next_key())
    shifts = np.asarray(source.shifts(seed, dims)).astype(np.int64)
    z = [int(v) for v in U.lattice_generating_vector(dims)]
    for offset in (8, (1 << 34) + 4):
        got = np.asarray(source.block(seed, offset, 64, dims)).astype(np.float64)
        expected = np.empty_like(got)
        for row, g in enumerate(range(offset, offset + 64)):
            p, r = divmod(g, 4)
            for j in range(dims):
                w = (((rev(p, 64) * z[j]) % (1 << 64) >> 32) + shifts[r, j]) % (1 << 32)
                if tent:
                    w = 2 * w if w < 1 << 31 else (1 << 33) - 1 - 2 * w
                expected[row, j] = unit32(w)
        np.testing.assert_array_equal(got, expected)


def test_lattice_tent_is_a_bijection_of_the_grid_close_to_the_tent():
    w = np.arange(0, 1 << 32, 4099, dtype=np.uint64)
    t = np.asarray(lattice_module.tent_bits(jnp.asarray(w, jnp.uint32))).astype(np.float64)
    x = w.astype(np.float64) / 2 ** 32
    assert np.abs(t / 2 ** 32 - (1 - np.abs(2 * x - 1))).max() <= 2.0 ** -32
    small = np.asarray(lattice_module.tent_bits(jnp.arange(1 << 16, dtype=jnp.uint32) << 16))
    assert len(np.unique(small >> 16)) == 1 << 16 and set(small & 0xFFFF) <= {0, 0xFFFF}


def test_lattice_prefixes_are_lattices_in_every_replicate():
    """Every power-of-two prefix of every replicate has one point in each of 2^m cells of every
    coordinate (deterministic: z_j odd); with the tent each cell of 2^(m-1) holds two."""
    source = U.Lattice(replicates=3, tent=False)
    points = np.asarray(U.uniform_block(source, next_key(), 0, 3 * 1024, 32))
    for r in range(3):
        for m in (4, 10):
            cells = (points[r::3][: 1 << m] * (1 << m)).astype(int)
            for j in range(32):
                assert np.bincount(cells[:, j], minlength=1 << m).max() == 1


# ------------------------------------------------------------------------------------------------
# Halton
# ------------------------------------------------------------------------------------------------

def radical_inverse_word(i, b):
    """floor(phi_b(i) 2^32) with exact rationals (Python integers)."""
    from fractions import Fraction
    v, scale = Fraction(0), Fraction(1, b)
    while i:
        i, d = divmod(i, b)
        v += d * scale
        scale /= b
    return int(v * 2 ** 32)


def test_unscrambled_halton_points_are_the_radical_inverses():
    dims = 10
    assert list(U.halton_primes(dims)) == [2, 3, 5, 7, 11, 13, 17, 19, 23, 29]
    indices = list(range(40)) + [12345, 999983, (1 << 32) - 1]
    got = np.asarray(U.halton_points(jnp.asarray(indices, jnp.uint32), dims)).astype(np.int64)
    for row, i in zip(got, indices):
        expected = [radical_inverse_word(i, int(b)) for b in U.halton_primes(dims)]
        # float64 Horner: within one unit of the 32-bit fraction (exact in base 2).
        assert row[0] == expected[0] and np.abs(row - np.array(expected)).max() <= 1, i


@pytest.mark.parametrize("scramble", ["permutation", "owen"])
def test_scrambled_halton_keeps_the_digit_stratification(scramble):
    """A digit scramble maps the b^k points of each run [c b^k, (c + 1) b^k) of one replicate onto
    one point per b-adic interval of length b^-k in each coordinate (deterministic)."""
    source = U.Halton(replicates=2, scramble=scramble)
    points = np.asarray(U.uniform_block(source, next_key(), 0, 2 * 2 * 243, 5))
    for r in range(2):
        rep = points[r::2]
        for j, b in enumerate(U.halton_primes(5)):
            k = int(math.log(243) // math.log(int(b)))
            n = int(b) ** k
            assert np.bincount((rep[:n, j] * n).astype(int), minlength=n).max() == 1, (j, b)


@pytest.mark.parametrize("scramble", ["permutation", "owen"])
def test_halton_run_tables_give_the_points_each_lane_permutes_itself(scramble):
    """A large call (2^14 + 2 points) reads each digit run's permuted value from a per-replicate
    table (Owen: the leading run's); windows of 64 points are too small for tables, and each lane
    permutes its digits. Deterministic: both give the same points bit for bit, in both dtypes, in
    the row layout (offset 0) and the one-lane-a-point layout (odd offset 1, the table read at row
    e and the lane's replicate). And the tabled float64 points keep the b-adic stratification of
    two runs of b^k <= 243 points of one replicate in each of 12 coordinates: a point within one
    2^-32 output cell of an interval's edge could cross it, FFR below 24 * 243^2 * 2^-32 ~ 3e-4
    for Owen's random tail (the permutation scramble is fixed by the key)."""
    source, dims, count = U.Halton(replicates=2, scramble=scramble), 12, (1 << 14) + 2
    key = next_key()
    for dtype in (jnp.float32, jnp.float64):
        with jax.enable_x64(dtype == jnp.float64):
            block = lambda offset, n: np.asarray(U.uniform_block(source, jax.random.clone(key), offset, n, dims,
                                                                 dtype=dtype))
            big, shifted = block(0, count), block(1, count)     # one program (offset is traced)
            assert np.array_equal(shifted[:count - 1], big[1:]), dtype
            for offset in (0, 64 * 37, 8192, count - 64):
                assert np.array_equal(block(offset, 64), big[offset:offset + 64]), (dtype, offset)
            assert np.array_equal(block(count - 63, 64), shifted[count - 64:]), dtype
    rep = big[1::2]
    for j, b in enumerate(int(p) for p in U.halton_primes(dims)):
        n = b ** int(math.log(243) // math.log(b))
        for start in (0, (len(rep) // n - 1) * n):
            assert np.bincount((rep[start:start + n, j] * n).astype(int), minlength=n).max() == 1, (j, b)


def test_owen_halton_permutes_each_digit_by_its_prefix_and_permutation_halton_does_not():
    """Base 3 (coordinate 2), points i = 3 d_1 + d_0 of one replicate, output digit 1 =
    floor(9 y) mod 3. "permutation": pi_1(d_1) whatever d_0 (deterministic). "owen": pi_1 also
    depends on d_0, so for some d_1 the three prefixes give different digits: all three affine
    permutations coincide with probability 1/36 per key, so requiring nesting for some key fails
    for a correct Owen scramble with probability 36^-4 < 1e-6 over the 4 keys (requiring it for
    every key would fail with probability 1 - (35/36)^4 ~ 0.11)."""
    index = np.arange(9)
    d1 = index // 3
    nested = []
    for _ in range(4):
        for scramble in ("permutation", "owen"):
            y = np.asarray(U.uniform_block(U.Halton(replicates=2, scramble=scramble), next_key(), 0, 18, 2))[0::2, 1]
            digit1 = (np.floor(y * 9).astype(int)) % 3
            assert sorted((np.floor(y * 3).astype(int))[d1 == 0].tolist()) == [0, 1, 2]
            by_prefix = [len(set(digit1[d1 == v].tolist())) for v in range(3)]
            if scramble == "permutation":
                assert by_prefix == [1, 1, 1], by_prefix
            else:
                nested.append(max(by_prefix) > 1)
    assert any(nested), nested


# ------------------------------------------------------------------------------------------------
# Latin hypercube
# ------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("m", [1000, 1024])
def test_latin_hypercube_has_one_point_per_stratum_in_every_coordinate(m):
    """Deterministic: each of 3 replicates has exactly one point in each of m strata of each of 6
    coordinates (float64 points; m = 1000 walks cycles, m = 1024 does not)."""
    points = float64_points(U.LatinHypercube(replicates=3), next_key(), 3 * m, 6)
    for r in range(3):
        for j in range(6):
            assert np.bincount((points[r::3, j] * m).astype(int), minlength=m).max() == 1, (r, j)
    assert not np.array_equal(points[0::3, 0], points[1::3, 0])


def test_stratum_permutation_is_a_bijection_for_every_size():
    keys = [(jnp.uint32(0x1234567), jnp.uint32(0x89ABCDEF)), (jnp.uint32(77), jnp.uint32(0xDEADBEEF)),
            (jnp.uint32(0xC0FFEE), jnp.uint32(12345))]
    for m in (1, 2, 3, 5, 17, 100, 129, 4096):
        got = np.asarray(U.lhs.stratum_permutation(jnp.arange(m, dtype=jnp.uint32), keys, m))
        assert sorted(got.tolist()) == list(range(m)), m


@pytest.mark.parametrize("integrand,low,high", [("additive", -1.9, -1.2), ("product", -0.7, -0.35)])
def test_latin_hypercube_rates(integrand, low, high):
    """RMSE over 32 replicates at m = 64 .. 4096 per replicate (separate streams: an LHS prefix is
    not an LHS), 4 dimensions: additive integrand about m^-1.5, the product about m^-0.5.
    The fitted slope has sd 0.04 (each log RMSE about 0.125, over 40 keys: -1.51 ± 0.04 and
    -0.50 ± 0.04): FFR 1e-13 (additive) and 4e-5 (product, 3.9 sd inside -0.35)."""
    f = {"product": smooth_product, "additive": additive}[integrand]
    ns, rmse = [], []
    for m in (64, 256, 1024, 4096):
        points = float64_points(U.LatinHypercube(replicates=32), next_key(), 32 * m, 4)
        means = f(points).reshape(m, 32).mean(axis=0)
        ns.append(m)
        rmse.append(np.sqrt(np.mean((means - 1.0) ** 2)))
    slope = float(np.polyfit(np.log(ns), np.log(rmse), 1)[0])
    assert low < slope < high, (slope, rmse)


# ------------------------------------------------------------------------------------------------
# Every source
# ------------------------------------------------------------------------------------------------

SOURCES = {
    "lattice": lambda r: U.Lattice(replicates=r),
    "halton": lambda r: U.Halton(replicates=r),
    "halton-owen": lambda r: U.Halton(replicates=r, scramble="owen"),
    "lhs": lambda r: U.LatinHypercube(replicates=r),
    "hammersley": lambda r: U.Hammersley(replicates=r),
}
# The t statistic of 32 replicate means was simulated for these sets (see the test); Hammersley's
# is checked over keys instead (`test_hammersley_estimates_under_jit_and_vmap_are_unbiased_over_keys`).
STREAMED = sorted(set(SOURCES) - {"hammersley"})


@pytest.mark.parametrize("name", sorted(SOURCES))
def test_chunking_and_lanes_never_change_the_points(name):
    """Windows, traced offsets and the estimators' lanes give the points of one big block."""
    source, dims, total = SOURCES[name](4), 3, 4096
    key = next_key()
    whole = np.asarray(U.uniform_block(source, jax.random.clone(key), 0, total, dims, total=total))
    cuts = [0, 1365, 2730, 4095, total]
    pieces = [np.asarray(U.uniform_block(source, jax.random.clone(key), a, b - a, dims, total=total))
              for a, b in zip(cuts, cuts[1:])]
    np.testing.assert_array_equal(whole, np.concatenate(pieces))
    traced = jax.jit(lambda off: U.uniform_block(source, jax.random.clone(key), off, 1365, dims, total=total))(1027)
    np.testing.assert_array_equal(np.asarray(traced), whole[1027:2392])
    seed = U.seed_from_key(jax.random.clone(key))
    lanes = jax.jit(lambda off: source.lanes(seed, off, 1024, dims, total=total, aligned=1024))(jnp.uint32(2048))
    flat = np.concatenate([np.stack([np.asarray(c).reshape(-1) for c in group], -1) for group in lanes])
    assert len(lanes) == 1
    np.testing.assert_array_equal(flat, whole[2048:3072])
    assert whole.min() > 0 and whole.max() < 1


@pytest.mark.parametrize("name", sorted(SOURCES))
def test_every_point_is_uniform_over_keys(name):
    """Points 0 and 5 of replicate 0 over 2^13 keys are uniform in each of 4 coordinates
    (two-sided chi-square, 64 bins: FFR 2e-6 each, 1.6e-5 in all). Point 0 of an unshifted lattice
    is 0 in every coordinate, and every unrandomized set is one fixed point over keys."""
    keys = jax.random.split(next_key(), 1 << 13)
    source = SOURCES[name](2)
    points = np.asarray(jax.jit(jax.vmap(lambda k: U.uniform_block(source, k, 0, 12, 4, total=12)))(keys))
    for row in (0, 10):
        for j in range(4):
            assert uniform_ok(points[:, row, j]), (row, j)
    assert not uniform_ok(np.sqrt(points[:, 0, 0]))


@pytest.mark.parametrize("name", sorted(SOURCES))
def test_randomizations_are_independent_across_replicates_and_dimensions(name):
    """Over 2^13 keys, point 0 of replicates 0 and 1 in 6 coordinates: every pair of coordinates
    and the two replicates of a coordinate are uncorrelated (|r| < 5.3/sqrt(N): FFR 1.2e-7 a pair,
    21 pairs, 2.5e-6 in all). Shared across coordinates, the lattice's shifts make point 0 the same
    in every coordinate (r = 1); tests/mutations.py records that this test catches it."""
    keys = jax.random.split(next_key(), 1 << 13)
    source, dims = SOURCES[name](2), 6
    points = np.asarray(jax.jit(jax.vmap(lambda k: U.uniform_block(source, k, 0, 8, dims, total=8)))(keys))
    for a in range(dims):
        for b in range(a + 1, dims):
            assert correlation_ok(points[:, 0, a], points[:, 0, b]), (a, b)
        assert correlation_ok(points[:, 0, a], points[:, 1, a]), a


def smooth_product(x):
    """prod_j (1 + (e^(x_j) - e + 1) / 2): smooth, not periodic, integral exactly 1."""
    return np.prod(1.0 + 0.5 * (np.exp(x) - (np.e - 1.0)), axis=-1)


def additive(x):
    """sum_j (x_j^2 - 1/3) + 1: additive, integral exactly 1."""
    return np.sum(x * x - 1.0 / 3.0, axis=-1) + 1.0


def float64_points(source, key, count, dims):
    with jax.enable_x64(True):
        return np.asarray(U.uniform_block(source, key, 0, count, dims, dtype=jnp.float64, total=count))


@pytest.mark.parametrize("name", sorted(SOURCES))
def test_estimates_are_unbiased_over_keys(name):
    """The mean over 400 keys of the R = 4 replicate estimate (64 points each) of the smooth product
    in 3 dimensions is within 4 standard errors of its integral 1 (FFR 6e-5; the brief's 3-sigma
    rule would be 2.7e-3 per source): float64 points, so that the check sees the estimator's bias,
    not float32's rounding."""
    source = SOURCES[name](4)
    keys = jax.random.split(next_key(), 400)
    with jax.enable_x64(True):
        points = np.asarray(jax.jit(jax.vmap(
            lambda k: U.uniform_block(source, k, 0, 256, 3, dtype=jnp.float64, total=256)))(keys))
    estimates = smooth_product(points).mean(axis=1)
    spread = estimates.std(ddof=1) / np.sqrt(len(estimates))
    assert spread > 0
    assert abs(estimates.mean() - 1.0) < 4 * spread, (estimates.mean() - 1.0, spread)


# (source, dims, integrand, slope bound, per-replicate sizes): the fitted log-log slope of the RMSE
# must be at most the bound; literature slopes in the comments (docs/literature.md 3.1, 3.2).
SLOPES = [
    ("lattice", 2, "product", -1.6, (64, 4096)),   # tent lattice, smooth: about N^-2
    ("lattice", 4, "product", -1.3, (64, 4096)),
    ("halton", 2, "product", -0.8, (64, 4096)),    # scrambled Halton: about N^-1
    ("halton", 4, "product", -0.7, (64, 4096)),
    ("halton-owen", 2, "product", -0.8, (64, 4096)),
]


def fitted_slope(points, replicates, integrand, sizes):
    """Slope of log RMSE against log n over the replicates' prefixes of n points (powers of two
    from sizes[0] to sizes[1]), with the RMSE over the R independent replicates."""
    f = {"product": smooth_product, "additive": additive}[integrand]
    values = f(points).reshape(-1, replicates)            # (points per replicate, R)
    ns, rmse = [], []
    n = sizes[0]
    while n <= sizes[1]:
        means = values[:n].mean(axis=0)
        ns.append(n)
        rmse.append(np.sqrt(np.mean((means - 1.0) ** 2)))
        n *= 4
    return float(np.polyfit(np.log(ns), np.log(rmse), 1)[0]), rmse


@pytest.mark.parametrize("name,dims,integrand,bound,sizes", SLOPES)
def test_error_falls_at_the_literature_rate(name, dims, integrand, bound, sizes):
    """RMSE over 32 replicates against the prefix size n: the fitted slope is at most `bound`
    (tolerant bounds below the literature's rates; a change of rate, not of constant, fails).
    Over 40 keys the slopes were -1.72 ± 0.03 (lattice, d = 2), -1.66 ± 0.03 (lattice, 4), -0.95 ±
    0.03 (halton, 2), -0.96 ± 0.04 (halton, 4) and -1.00 ± 0.02 (halton-owen, 2): FFR about 5e-6
    for lattice d = 2 (4.5 sd), below 2e-8 for the others."""
    replicates = 32
    source = SOURCES[name](replicates)
    points = float64_points(source, next_key(), replicates * sizes[1], dims)
    slope, rmse = fitted_slope(points, replicates, integrand, sizes)
    assert slope < bound, (slope, rmse)


def test_lattice_without_the_tent_converges_at_first_order():
    """The plain shifted lattice on the (non-periodic) product: slope about -1, far from the tent's.
    Over 40 keys -0.96 ± 0.03, more than 7 sd inside (-1.4, -0.7): FFR below 1e-12."""
    points = float64_points(U.Lattice(replicates=32, tent=False), next_key(), 32 * 4096, 2)
    slope, _ = fitted_slope(points, 32, "product", (64, 4096))
    assert -1.4 < slope < -0.7


@pytest.mark.parametrize("name", STREAMED)
def test_estimators_stream_the_source_under_jit_and_vmap(name):
    """js.estimate with the source inside jit and vmap over keys: each estimate within 5 of its
    stderr of pi/2 (the cosine-cubed integral over the hemisphere), the stderr from R = 32
    replicates of 512 points.

    FFR 4.6e-4 for the 4 cases (4 keys each): |t_31| > 5 has probability 2.1e-5 for normal
    replicate means; these point sets' replicate means are far from normal (Halton's nearly
    uniform), and t statistics of 32 drawn from 2^16 simulated replicate means of each set (2e7
    per set; their tails at 3 and 4 matched 16384 keys of this estimator) exceeded 5 for 1.3e-5
    (lattice), 5.1e-5 (halton), 3.0e-5 (halton-owen) and 2.0e-5
    (lhs) of them. With R = 8 the same simulation gives 5.5e-3, 4.2e-3, 2.9e-3 and 1.5e-3, as
    8000 keys of the estimator did (6e-3, 4.6e-3, 3.1e-3, 4e-4)."""
    source = SOURCES[name](32)
    f = lambda w: w[2] ** 3
    d = js.UniformHemisphere()
    keys = jax.random.split(next_key(), 4)
    est = jax.jit(jax.vmap(lambda k: js.estimate(f, d, k, 32 * 512, uniforms=source)))(keys)
    error = np.abs(np.asarray(est.mean) - np.pi / 2)
    stderr = np.asarray(est.stderr)
    assert np.all(stderr > 0) and np.all(error < 5 * stderr + 2e-6), (error, stderr)


def test_hammersley_is_a_shifted_grid_beside_the_halton_coordinates():
    """Deterministic: in every replicate the first coordinate has one point in each of the m strata
    [k/m, (k + 1)/m), at one common offset (a shifted grid), and the other coordinates are the
    Halton points of the same seed and scramble."""
    key = next_key()
    for scramble in ("permutation", "owen"):
        points = np.asarray(U.uniform_block(U.Hammersley(replicates=4, scramble=scramble), jax.random.clone(key),
                                            0, 256, 4, total=256))
        halton = np.asarray(U.uniform_block(U.Halton(replicates=4, scramble=scramble), jax.random.clone(key),
                                            0, 256, 3, total=256))
        np.testing.assert_array_equal(points[:, 1:], halton)
        for r in range(4):
            first = points[r::4, 0] * 64
            np.testing.assert_array_equal(np.sort(np.floor(first)), np.arange(64))
            offsets = first - np.floor(first)
            assert np.ptp(offsets) < 1e-4, offsets


def test_hammersley_estimates_under_jit_and_vmap_are_unbiased_over_keys():
    """js.estimate of ∫cos³ over the hemisphere with `uniforms="hammersley"` inside jit and vmap over 64
    keys: the mean of the estimates within 5 standard errors (over keys) of π/2, and the reported
    stderrs the size of that spread (their rms within 0.5x to 2x of it). FFR: Student t with 63
    degrees of freedom beyond 5, 5e-6; the rms of 64 stderrs, each from 16 replicates, is that far
    from the spread of the estimates with probability below 1e-6."""
    f = lambda w: w[2] ** 3  # noqa: E731
    keys = jax.random.split(next_key(), 64)
    est = jax.jit(jax.vmap(lambda k: js.estimate(f, js.UniformHemisphere(), k, 16 * 256, uniforms="hammersley")))(keys)
    means, stderrs = np.asarray(est.mean, np.float64), np.asarray(est.stderr, np.float64)
    spread = means.std(ddof=1)
    assert abs(means.mean() - np.pi / 2) < 5 * spread / 8, (means.mean(), spread)
    assert 0.5 < np.sqrt(np.mean(stderrs ** 2)) / spread < 2.0, (stderrs, spread)


def test_registered_names_and_invalid_parameters():
    assert U.as_source("lattice") == U.Lattice()
    assert U.as_source("lhs") == U.LatinHypercube()
    assert U.as_source("hammersley") == U.Hammersley() and U.Hammersley(scramble="owen") != U.Hammersley()
    with pytest.raises(ValueError, match="total"):
        U.uniform_block(U.Hammersley(4), next_key(), 0, 8, 2)
    with pytest.raises(ValueError, match="total"):
        U.uniform_block(U.LatinHypercube(4), next_key(), 0, 8, 2, total=10)
    assert U.as_source("halton") == U.Halton() and U.Halton(scramble="owen") != U.Halton()
    with pytest.raises(ValueError, match="scramble"):
        U.Halton(scramble="random")
    with pytest.raises(ValueError, match=r"dims.*\[1, 1024\]"):
        U.Halton().block(U.seed_from_key(next_key()), 0, 16, 1025)
    with pytest.raises(ValueError, match="replicates"):
        U.Lattice(replicates=1)
    with pytest.raises(ValueError, match="tent"):
        U.Lattice(tent="yes")
    with pytest.raises(ValueError, match=r"dims.*\[1, 1024\]"):
        U.Lattice().block(U.seed_from_key(next_key()), 0, 16, 1025)


@pytest.mark.parametrize("replicates, tent, offset", [(2, True, 2 * 256 * 5), (16, False, 16 * 256 * 3),
                                                      (4, True, (1 << 34) + 4 * 256 * 7)])
def test_lattice_chunk_fast_path_is_bit_identical_to_the_block(replicates, tent, offset):
    # The estimators' aligned chunks take the table path of Lattice.lanes (rev32(m0 + j) split into
    # disjoint bits); a wrong split or a dropped chunk term would move the points off the lattice.
    from jaxsample.uniforms.index import as_index
    source = U.Lattice(replicates, tent=tent)
    seed = U.seed_from_key(jax.random.key(41 + replicates))
    count = replicates * 256
    (fast,) = source.lanes(seed, as_index(offset, count), count, 5, aligned=count)
    slow = source.block(seed, as_index(offset, count), count, 5)
    assert np.array_equal(np.stack([np.asarray(lane).reshape(-1) for lane in fast], -1), np.asarray(slow))


def test_latin_hypercube_jitter_is_uniform_in_each_stratum_and_independent():
    """One key, 2 replicates of m = 4096 points in 3 coordinates (float64): the position within the
    stratum, frac(m x), is uniform over each replicate's m points (chi-square, 64 bins: FFR 2e-6
    each) and uncorrelated with the stratum, with the other coordinates and with the same point
    of the other replicate (|r| < 5.3/sqrt(m): FFR 1.2e-7 a pair): 6 and 15 checks, 1.4e-5 in all.
    The jitter hashes the permuted stratum: one that ignored it would sit at one place in every
    stratum; one drawn by point index with a key shared by the replicates would repeat across them."""
    m, replicates, dims = 4096, 2, 3
    points = float64_points(U.LatinHypercube(replicates=replicates), next_key(), replicates * m, dims)
    cells = points.reshape(m, replicates, dims) * m
    frac = cells - np.floor(cells)
    for r in range(replicates):
        for j in range(dims):
            assert uniform_ok(frac[:, r, j]), (r, j)
            assert correlation_ok(frac[:, r, j], np.floor(cells[:, r, j])), (r, j)
            for k in range(j + 1, dims):
                assert correlation_ok(frac[:, r, j], frac[:, r, k]), (r, j, k)
    for j in range(dims):
        assert correlation_ok(frac[:, 0, j], frac[:, 1, j]), j


@pytest.mark.parametrize("name", ["lhs", "halton"])
def test_many_coordinates_are_stored_in_groups_without_changing_a_point(name, monkeypatch):
    """Past `STORE_PAST` coordinates (24 for the Latin hypercube, 48 for Halton) all but the last
    `FUSED_LANES` lanes are computed in loops of their own and stored (`_replicated.store_all_but`:
    one fused loop over every coordinate is not vectorized, and makes the Latin hypercube many times
    slower than Random at 28-d). The program then holds the `lax.cond` boundary that stores them, and the points
    are bit for bit those of the fused form: the first coordinates equal those of a block with
    fewer (fused, no boundary). The Latin hypercube at its own threshold (24 vs 26 coordinates);
    Halton's threshold lowered to 4 here (a 52-d Halton program takes about 50 s to compile)."""
    from jaxsample.uniforms import halton, lhs

    module, source = {"lhs": (lhs, U.LatinHypercube(replicates=4)), "halton": (halton, U.Halton(replicates=4))}[name]
    if name == "halton":
        monkeypatch.setattr(halton, "STORE_PAST", 4)
        monkeypatch.setattr(halton, "FUSED_LANES", 2)
    below, above = module.STORE_PAST, module.STORE_PAST + 2
    seed = U.seed_from_key(jax.random.key(3))

    def program(dims):
        return jax.jit(lambda s: source.block(s, 0, 256, dims, jnp.float32, total=256)).lower(seed).compile()

    fused, stored = program(below), program(above)
    assert "conditional" not in fused.as_text()
    assert "conditional" in stored.as_text()
    np.testing.assert_array_equal(np.asarray(stored(seed))[:, :below], np.asarray(fused(seed)))
