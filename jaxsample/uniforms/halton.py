"""Scrambled Halton points: radical inverses in the first d primes, randomized digit by digit.

Construction (Halton 1960). Coordinate j of point i is the radical inverse of i in the j-th prime
b: with i = sum_k d_k b^k, phi_b(i) = sum_k d_k b^-(k+1). Scrambling replaces digit d_k by
pi_k(d_k) for random permutations pi_k of {0 .. b-1} (Owen 1995, "Randomly permuted
(t, m, s)-nets and (t, s)-sequences"; Owen 2017, "A randomized Halton algorithm in R"):

- scramble="permutation": one permutation per (replicate, coordinate, digit position k). Each
  pi_k is the random affine map d -> (a d + c) mod b, a uniform in {1 .. b-1}, c in {0 .. b-1}
  (from Philox words). For prime b the affine maps are sharply 2-transitive: for digits
  d != d' the pair (pi(d), pi(d')) is uniform over the ordered distinct pairs, as under a
  uniformly random permutation, so every point is uniform and every pair of points has the joint
  law (hence the estimator's variance) of the uniformly random digit permutation.
- scramble="owen": nested permutations: pi_k also depends on the digits d_0 .. d_(k-1) below it
  (the prefix i mod b^k): its coefficients come from a bijective 32-bit hash h (the "lowbias32"
  multiply-xorshift) of the prefix xor a Philox word of (replicate, coordinate, k), the hashing
  approach of Burley 2020 for base 2, here per digit of base b. For b (b - 1) <= 2^13 (bases up
  to 89) one hash gives both: t = floor(h b (b - 1) / 2^32) = c (b - 1) + (a - 1), a value drawn
  as floor(h m / 2^32) having relative bias at most m / 2^32 per value (< 2e-6 per (c, a) pair);
  larger bases hash h again with a second Philox word for a. In base 2 it is `owen_scramble`,
  the Laine–Karras hash of `sobol`.

Digits and precision. The output is `bits_to_unit` of a 2^-23 (float32) or 2^-32 (float64) cell,
so only the K = ceil(bits / log2 b) most significant digit positions can move a point by a cell
(b^-K <= 2^-bits); the positions below them and everything past the index's own digits are one
uniform tail: per replicate and coordinate for "permutation" (the permuted zeros pi_k(0) summed
with a uniform word, as for an index below 2^32 the positions up to 2^64 give exactly), per point
for "owen" (hashed from the whole index): what an infinite digit expansion gives in
distribution. Digits are extracted in uint32 for an index below 2^32 (each straight from the
index, (i div b^k) mod b, so XLA fuses every digit into its consumer), in uint64 above, with the
same values. The sum is exact in uint32 for the leading positions (b^m < 2^31) and finished in
float64 (two roundings, 2^-52 relative), so each point is uniform on its output grid; the
affine coefficients come from 32-bit words reduced mod b, a bias below b / 2^32 (< 2e-6 for the
largest prime kept) in any digit's probabilities. The affine maps' t = a d + c < b^2 is divided
by b exactly with one uint32 multiply and a shift (q = t div b, `_mod_square`, bases up to 251),
and the digit t - q b folded into the sum's multiply. Digit permutations of bases up to 5 are a
chain of selects among the b values pi(0) .. pi(b - 1) computed per replicate. Base 2
(coordinate 1) is exact bit arithmetic: rev32(i) xor a random word ("permutation"; the index's
bits past 32 fall below 2^-32), Owen-scrambled van der Corput ("owen").

Runs of digits. The permutation scramble sums the K positions in runs of m digits (b^m <= 1024,
`_digit_groups`): a run of a point is one integer e < b^m, and its permuted value
sum_j pi_j(e_j) b^(m-1-j) is read from a table of every replicate's permuted run (b^m rows of R,
built per call) where the table is small beside the lanes it serves (`_tabled`), so a lane costs a
row read and a multiply-add per run instead of a permutation and a multiply-add per digit; small
calls permute each lane's digits to the same integer, so every call gives the same points. Owen's
nested permutations depend on the whole prefix, so only the leading run (whose prefixes are its
own digits) can be a table; the positions after it are hashed per lane.

Cost: the "point sets" rows of `python -m jaxsample.report.paths` (`quasi_random`: `estimate` of a
2-d cosine integral and of sum x^2 over a 3-d and an 8-d `UniformBox`) time both scrambles against
`Random` (`benchmarks/results/point-sets-paths-cpu-2core-2026-12-05.md`). The leading run's table is
cheaper than permuting digit by digit; "owen" adds a 32-bit hash and two multiply-highs per digit
after the leading run.

Replicates: global index g is point g div R of replicate g mod R (the `Source` convention), each
replicate with independent permutations, so the spread of the R replicate means is the standard
error. Dimensions: up to 1024 (primes 2 .. 8161). Halton points in high dimensions need the
scramble: unscrambled, the large-prime coordinates are strongly correlated for small n.
"""

from __future__ import annotations

import functools
from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from .._core.pytree import static_field
from .index import Index
from .philox import _u32, bits_to_unit, philox4x32
from .sobol import _reverse_bits, _scramble_reversed
from .sources import Source, _check_replicates, register_source
from ._replicated import STREAM_HALTON, Layout, _mix32, check_dims, stack_lanes, store_all_but

__all__ = ["Halton", "halton_points", "halton_primes", "MAX_HALTON_DIMS"]

MAX_HALTON_DIMS = 1024
SCRAMBLES = ("permutation", "owen")
STORE_PAST = 48     # more coordinates than this: all but FUSED_LANES are stored (`_replicated.store_all_but`)
FUSED_LANES = 32


def _primes(count: int) -> np.ndarray:
    limit = 8200
    sieve = np.ones(limit, bool)
    sieve[:2] = False
    for p in range(2, int(limit ** 0.5) + 1):
        if sieve[p]:
            sieve[p * p::p] = False
    primes = np.flatnonzero(sieve)[:count]
    assert len(primes) == count
    return primes


_PRIMES = _primes(MAX_HALTON_DIMS)


def halton_primes(dims: int) -> np.ndarray:
    """The bases of the first `dims` coordinates: the first `dims` primes."""
    check_dims("Halton", dims, MAX_HALTON_DIMS)
    return _PRIMES[:dims].copy()


def _digit_count(base: int) -> int:
    """K: the fewest base-b digits that hold every index below 2^64."""
    k, power = 0, 1
    while power < 1 << 64:
        power *= base
        k += 1
    return k


def _digit_count32(base: int, bits: int = 32) -> int:
    """The fewest base-b digits that hold every index below 2^bits (b^K >= 2^bits): below them
    the radical inverse moves by less than 2^-bits, one cell of a `bits`-bit output."""
    k, power = 0, 1
    while power < 1 << bits:
        power *= base
        k += 1
    return k


def _output_bits(dtype) -> int:
    """The resolution of `bits_to_unit`'s output: 2^-23 cells for float32, 2^-32 for float64."""
    return 32 if jnp.dtype(dtype) == jnp.float64 else 23


# Bases whose digit permutation is evaluated as a chain of selects on the digit (b - 1 selects of
# per-replicate constants) instead of (a d + c) mod b (a multiply, an add and a remainder).
SELECT_BASES = 5


def _permuted(d, c_table, a_table, base: int, take):
    """pi(d) = (a d + c) mod b for digits d < b; a and c are per-replicate tables (R,) read at each
    lane's replicate by `take`. For b <= SELECT_BASES the b values pi(0) .. pi(b - 1) are computed
    on the tables and the lane selects among them."""
    c = c_table % _u32(base)
    a = _u32(1) + a_table % _u32(base - 1)
    if base <= SELECT_BASES:
        out = take((a * _u32(base - 1) + c) % _u32(base))
        for v in reversed(range(base - 1)):
            out = jnp.where(d == _u32(v), take((a * _u32(v) + c) % _u32(base)), out)
        return out
    return _mod_square(take(a) * d + take(c), base)


@functools.lru_cache(maxsize=None)
def _square_magic(base: int):
    """(s, M) with floor(t M / 2^s) = t div b for every t < b^2 and t M < 2^32, checked on every
    such t; None where no shift works (bases above 251)."""
    t = np.arange(base * base, dtype=np.uint64)
    for shift in range(1, 33):
        mul = -(-(1 << shift) // base)
        if (base * base - 1) * mul >= 1 << 32:
            return None
        if np.array_equal((t * np.uint64(mul)) >> np.uint64(shift), t // np.uint64(base)):
            return shift, mul
    return None


def _mod_square(t, base: int):
    """t mod b for uint32 t < b^2 (an affine digit map a d + c) as the pair (t, q), q = t div b =
    floor(t M / 2^s) (`_square_magic`): the digit is t - q b, which `_horner` folds into its
    multiply, (H - q) b + t, so a digit costs three uint32 multiplies with the map and the sum,
    where the generic remainder by a constant needs a 32 x 32 -> 64-bit multiply-high. A plain
    remainder for bases with no such (s, M)."""
    magic = _square_magic(base)
    if magic is None:
        return t % _u32(base)
    shift, mul = magic
    return t, (t * _u32(mul)) >> _u32(shift)


def _digit_value(d, base: int):
    """A digit as one uint32 array (`_mod_square`'s pair (t, q) is t - q b)."""
    if isinstance(d, tuple):
        t, q = d
        return t - q * _u32(base)
    return d


def _below(h, m: int):
    """floor(h m / 2^32) for uint32 h: a value in [0, m), bias below m / 2^32 per value."""
    with jax.enable_x64(True):
        return ((h.astype(jnp.uint64) * jnp.uint64(m)) >> jnp.uint64(32)).astype(jnp.uint32)


# Bases whose Owen coefficients (c, a) both come from one hash h: t = floor(h b (b - 1) / 2^32) =
# c (b - 1) + (a - 1), relative bias at most b (b - 1) / 2^32 < 2e-6 per (c, a) pair.
ONE_HASH_PAIRS = 1 << 13


def _owen_coefficients(h, word, base: int):
    """(c, a) of the affine digit permutation d -> (a d + c) mod b from the hash h of a digit's
    prefix: c in [0, b), a in [1, b). For b (b - 1) <= ONE_HASH_PAIRS both are the mixed-radix
    digits of t = floor(h b (b - 1) / 2^32): c = floor(h b / 2^32) and a - 1 = floor(r (b - 1) / 2^32)
    with r = h b mod 2^32 (h b (b - 1) = c (b - 1) 2^32 + r (b - 1)). Larger bases hash again with
    the per-replicate `word` for a, so each coefficient keeps a bias below b / 2^32."""
    if base * (base - 1) <= ONE_HASH_PAIRS:
        return _below(h, base), _u32(1) + _below(h * _u32(base), base - 1)
    return _below(h, base), _u32(1) + _below(_mix32(h ^ word), base - 1)


def _digits(point: Index, base: int, count: int):
    """The `count` lowest base-b digits of the index (uint32 arrays), lowest first, and the
    prefixes i mod b^k before each digit as (lo, hi) uint32 words (hi None for a narrow index).
    A narrow index (below 2^32) is divided in uint32, which vectorizes; a wide one in uint64."""
    digits, prefixes = [], []
    if point.hi is None:
        # Each digit straight from the index, (i // b^k) % b, and each prefix as i % b^k: no value
        # is shared along a chain of divisions, so XLA fuses every digit into its consumer instead
        # of writing the digits to memory (a shared chain becomes one multi-output fusion).
        i = point.lo
        for k in range(count):
            power = base ** k
            prefixes.append((i % _u32(power) if k else jnp.zeros_like(i), None))
            digits.append((i // _u32(power) if k else i) % _u32(base))
        return digits, prefixes
    with jax.enable_x64(True):
        rest = _index64(point)
        prefix, power = jnp.zeros_like(rest), 1
        for k in range(count):
            prefixes.append(((prefix & jnp.uint64(0xFFFFFFFF)).astype(jnp.uint32),
                             (prefix >> jnp.uint64(32)).astype(jnp.uint32)))
            d = rest % jnp.uint64(base)
            rest = rest // jnp.uint64(base)
            digits.append(d.astype(jnp.uint32))
            if k + 1 < count:
                prefix = prefix + d * jnp.uint64(power % (1 << 64))
                power *= base
    return digits, prefixes


def _exact_digits(base: int) -> int:
    """m: the most base-b digits whose integer b^(m-1) d_0 + ... + d_(m-1) fits a non-negative
    int32 (b^m < 2^31), whose conversion to float64 is one vector instruction."""
    m = 0
    while base ** (m + 1) < 1 << 31:
        m += 1
    return m


def _horner(digits, start, base: int, lead=None):
    """sum_k digit_k b^-(k+1) + start b^-K (digits lowest position first, K of them) in float64.

    The m most significant positions are summed exactly as the integer H = d_0 b^(m-1) + ... +
    d_(m-1) by Horner's rule in uint32 (b^m < 2^32), the positions below them by Horner's rule in
    float64 from `start`, and v = (H + w) b^-m: two float64 roundings in all, and uint32
    arithmetic (which vectorizes at twice the float64 width) for the digits that matter most.
    `lead` = (L, l): the first l positions given as their integer L = d_0 b^(l-1) + ... + d_(l-1)
    (l <= m), `digits` then the positions after them: the same H, so the same value."""
    value, done = lead if lead is not None else (None, 0)
    m = min(_exact_digits(base), done + len(digits))
    high = value if value is not None else jnp.zeros_like(_digit_value(digits[0], base))
    for d in digits[:m - done]:
        if isinstance(d, tuple):
            t, q = d
            high = (high - q) * _u32(base) + t
        else:
            high = high * _u32(base) + d
    with jax.enable_x64(True):
        w = start
        for d in reversed([_digit_value(d, base) for d in digits[m - done:]]):
            w = (d.astype(jnp.int32).astype(jnp.float64) + w) * (1.0 / base)
        return (high.astype(jnp.int32).astype(jnp.float64) + w) * (1.0 / base ** m)


# The permutation scramble sums the K32 digit positions in runs of m (the most with b^m <= RUN_ROWS):
# one exact integer per run, the same runs whichever way a run's value is found (so every path
# rounds alike). A run's value is read from a table of every replicate's permuted run (b^m rows of
# R) when the table costs at most TABLE_SHARE of the lanes it serves and TABLE_ENTRIES in all;
# otherwise each lane permutes the run's digits itself.
RUN_ROWS = 1024
TABLE_SHARE = 2
TABLE_ENTRIES = 1 << 15


def _digit_groups(base: int, count: int):
    """(first position, length) of the runs of m digits (m the most with b^m <= RUN_ROWS, at least
    1) that cover positions 0 .. count - 1, most significant first."""
    m = 1
    while base ** (m + 1) <= RUN_ROWS:
        m += 1
    return [(s, min(m, count - s)) for s in range(0, count, m)]


def _group_table(c_words, a_words, first: int, size: int, base: int):
    """(b^size, R) uint32: row e holds, per replicate, the permuted run sum_j pi_(first+j)(e_j)
    b^(size-1-j), e_j = (e div b^j) mod b the run's digits (lowest position first)."""
    e = jnp.arange(base ** size, dtype=jnp.uint32)[:, None]
    table = jnp.zeros((base ** size, c_words.shape[0]), jnp.uint32)
    for j in range(size):
        digit = (e // _u32(base ** j)) % _u32(base)
        pi = _permuted(digit, c_words[:, first + j], a_words[:, first + j], base, lambda t: t[None, :])
        table = table * _u32(base) + _digit_value(pi, base)
    return table


def _owen_table(w2, w3, size: int, base: int):
    """(b^size, R) uint32: row e holds, per replicate, the Owen-scrambled leading run
    sum_j pi_j(e_j) b^(size-1-j), pi_j's coefficients hashed from the prefix e mod b^j as in
    `Halton.lanes` (the leading run's prefixes are the run's own digits)."""
    e = jnp.arange(base ** size, dtype=jnp.uint32)[:, None]
    table = jnp.zeros((base ** size, w2.shape[0]), jnp.uint32)
    for j in range(size):
        digit = (e // _u32(base ** j)) % _u32(base)
        prefix = e % _u32(base ** j) if j else jnp.zeros_like(e)
        c, a = _owen_coefficients(_mix32(prefix ^ w2[None, :, j]), w3[None, :, j], base)
        table = table * _u32(base) + _digit_value(_mod_square(a * digit + c, base), base)
    return table


def _tabled(base: int, size: int, layout: Layout) -> bool:
    """Whether a run's table (b^size rows of R) is cheap beside the lanes it serves."""
    entries = base ** size * layout.replicates
    return entries * TABLE_SHARE <= int(np.prod(layout.shape)) and entries <= TABLE_ENTRIES


def _read_table(table, e, layout: Layout):
    """Each lane's entry of a (rows, R) run table at its point's run integer e and its replicate."""
    if layout.rows:
        return jnp.take(table, e[:, 0], axis=0, mode="clip")
    flat = e * _u32(layout.replicates) + layout.replicate.astype(jnp.uint32)
    return jnp.take(table.reshape(-1), flat, mode="clip")


def _group_indices(point: Index, groups, base: int):
    """Per point, each run's digits as one integer e = sum_j d_(first+j) b^j (uint32, < b^size): a
    division and a remainder of a narrow index, the uint64 digits combined for a wide one."""
    if point.hi is None:
        i = point.lo
        return [(i // _u32(base ** first) if first else i) % _u32(base ** size) for first, size in groups]
    digits, _ = _digits(point, base, groups[-1][0] + groups[-1][1])
    out = []
    for first, size in groups:
        e = digits[first + size - 1]
        for d in reversed(digits[first:first + size - 1]):
            e = e * _u32(base) + d
        out.append(e)
    return out


def _permuted_sum(point: Index, layout: Layout, w1, w2, w3, base: int, bits: int):
    """The permutation-scrambled radical inverse of each lane's point (float64 in [0, 1]) from the
    per-replicate words (R, K + 1) of one coordinate.

    Positions 0 .. K32 - 1 (K32 = `_digit_count32(b, bits)`) go in runs of m digits
    (`_digit_groups`), each run one integer below b^m. Where it is cheap beside the lanes
    (`_tabled`), a table of every replicate's permuted run (`_group_table`, b^m rows, built per
    call) is read at the point's run integer, so a lane costs one table read and one multiply-add
    per run instead of a permutation and a multiply-add per digit; otherwise the lane permutes the
    run's digits itself, to the same integer. The runs inside the leading `_exact_digits`
    positions are summed exactly in uint32 (as `_horner` does digit by digit), the others by
    Horner's rule in float64 from the tail: the positions up to K64 and the tail word, one
    constant per replicate summed on the table (R,)."""
    k_count, k64 = _digit_count32(base, bits), _digit_count(base)
    exact = _exact_digits(base)
    with jax.enable_x64(True):
        start = (w1[:, k64].astype(jnp.float64) + 0.5) * 2.0 ** -32
        for k in reversed(range(k_count, k64)):
            start = ((w2[:, k] % _u32(base)).astype(jnp.int32).astype(jnp.float64) + start) * (1.0 / base)
        groups = _digit_groups(base, k_count)
        rows = []
        for (first, size), e in zip(groups, _group_indices(point, groups, base)):
            if _tabled(base, size, layout):
                rows.append(_read_table(_group_table(w2, w3, first, size, base), e, layout))
                continue
            row = jnp.zeros_like(layout.take(w2[:, 0]) + e)
            for j in range(size):
                digit = (e // _u32(base ** j)) % _u32(base) if j else e % _u32(base)
                pi = _permuted(digit, w2[:, first + j], w3[:, first + j], base, layout.take)
                row = row * _u32(base) + _digit_value(pi, base)
            rows.append(row)
        # The leading runs inside the exact positions (at least the first: b^m <= RUN_ROWS < 2^31).
        lead = sum(first + size <= exact for first, size in groups)
        high = rows[0]
        for (_, size), row in zip(groups[1:lead], rows[1:lead]):
            high = high * _u32(base ** size) + row
        w = layout.take(start)
        for (_, size), row in reversed(list(zip(groups[lead:], rows[lead:]))):
            w = (row.astype(jnp.int32).astype(jnp.float64) + w) * (1.0 / base ** size)
        done = groups[lead - 1][0] + groups[lead - 1][1]
        return (high.astype(jnp.int32).astype(jnp.float64) + w) * (1.0 / base ** done)


def _index64(point: Index):
    """The index as uint64 (call inside enable_x64)."""
    lo = point.lo.astype(jnp.uint64)
    if point.hi is None:
        return lo
    return (point.hi.astype(jnp.uint64) << jnp.uint64(32)) | lo


def _mix64(x):
    """splitmix64's finalizer (Steele, Lea & Flood 2014): a bijective 64-bit mix."""
    x = x ^ (x >> jnp.uint64(30))
    x = x * jnp.uint64(0xBF58476D1CE4E5B9)
    x = x ^ (x >> jnp.uint64(27))
    x = x * jnp.uint64(0x94D049BB133111EB)
    return x ^ (x >> jnp.uint64(31))


def _to_unit(v, dtype):
    """A float64 fraction v in [0, 1] -> `bits_to_unit(floor(v 2^32))`: for float32 the cell
    floor(v 2^23) in int32 (vector conversions both ways), the same value as through the word."""
    if jnp.dtype(dtype) == jnp.float64:
        return bits_to_unit(_to_word(v), dtype)
    cell = jnp.minimum((v * 2.0 ** 23).astype(jnp.int32), (1 << 23) - 1)
    return cell.astype(jnp.float32) * np.float32(2.0 ** -23) + np.float32(2.0 ** -24)


def _to_word(v):
    """A float64 fraction in [0, 1] -> a uint32 fraction floor(v 2^32), at most 2^32 - 1."""
    return jnp.minimum(v * 2.0 ** 32, 4294967295.0).astype(jnp.uint32)


def halton_points(index, dims: int) -> jax.Array:
    """Unscrambled Halton points phi_b(i) as uint32 fractions floor(phi_b(i) 2^32), shape
    index.shape + (dims,); `index` a uint32 array or an `index.Index`."""
    primes = halton_primes(dims)
    if not isinstance(index, Index):
        index = Index(None, _u32(index))
    columns = []
    for b in (int(p) for p in primes):
        if b == 2:
            columns.append(_reverse_bits(index.lo))
            continue
        digits, _ = _digits(index, b, _digit_count32(b) if index.hi is None else _digit_count(b))
        with jax.enable_x64(True):
            columns.append(_to_word(_horner(digits, jnp.zeros(index.lo.shape, jnp.float64), b)))
    return jnp.stack(columns, axis=-1)


@register_source
class Halton(Source):
    """Scrambled Halton points (see the module docstring) in R independent replicates, up to 1024 dims.

    Args:
      replicates: R independent scrambles, an integer in [2, 2^32) (default 16).
      scramble: "permutation" (random digit permutations, the default) or "owen" (nested).
    """

    name: ClassVar[str] = "halton"
    scramble: str = static_field(default="permutation")

    def __init__(self, replicates: int = 16, scramble: str = "permutation"):
        self.replicates = _check_replicates("Halton", replicates)
        if scramble not in SCRAMBLES:
            raise ValueError(f"Halton: parameter 'scramble' must be 'permutation' or 'owen'; got {scramble!r}")
        self.scramble = scramble

    def digit_words(self, seed, dims: int):
        """Philox words per (replicate, coordinate, digit position): four arrays (R, dims, K + 1)."""
        k_max = max(_digit_count(int(b)) for b in halton_primes(dims)) + 1
        # One Philox call over the whole (R, dims, K + 1) grid of counters (r, j, stream, k): the
        # words `replicate_words(seed, R, dims, STREAM_HALTON, k)` gives, without K + 1 programs.
        shape = (self.replicates, dims, k_max)
        r, j, k = (jax.lax.broadcasted_iota(jnp.uint32, shape, axis) for axis in range(3))
        return philox4x32((r, j, jnp.full(shape, _u32(STREAM_HALTON)), k),
                          (seed[..., 0, None, None, None], seed[..., 1, None, None, None]))

    def lane_words(self, seed, dims: int):
        """`digit_words` laid out (dims, K + 1, R) for the lanes' own reads: each (coordinate,
        position) word one contiguous row of R. Read from (R, dims, K + 1) the row is strided,
        and LLVM runs part of it as a scalar epilogue, which slows Owen Halton's lanes down.
        The tables (`_group_table`, `_owen_table`) keep `digit_words`: this layout gives them no
        measurable gain."""
        k_max = max(_digit_count(int(b)) for b in halton_primes(dims)) + 1
        shape = (dims, k_max, self.replicates)
        j, k, r = (jax.lax.broadcasted_iota(jnp.uint32, shape, axis) for axis in range(3))
        return philox4x32((r, j, jnp.full(shape, _u32(STREAM_HALTON)), k),
                          (seed[..., 0, None, None, None], seed[..., 1, None, None, None]))

    def lanes(self, seed, offset, count, dims, dtype=jnp.float32, total=None, aligned=False):
        """One group of `dims` lanes, (count / R, R) for the estimators' chunks, else (count,)."""
        primes = halton_primes(dims)
        layout = Layout(offset, count, self.replicates, aligned)
        w0, w1, w2, w3 = self.digit_words(seed, dims)
        v0, _, v2, v3 = self.lane_words(seed, dims)
        owen = self.scramble == "owen"
        point = layout.point
        narrow = point.hi is None
        lanes = []
        for j, b in enumerate(int(p) for p in primes):
            if b == 2:
                word = (_scramble_reversed(point.lo, layout.take(v0[j, 0])) if owen
                        else _reverse_bits(point.lo) ^ layout.take(v0[j, 0]))
                lanes.append(bits_to_unit(layout.full(word), dtype))
                continue
            k_count = _digit_count32(b, _output_bits(dtype))
            if not owen:
                with jax.enable_x64(True):
                    v = _permuted_sum(point, layout, w1[:, j], w2[:, j], w3[:, j], b, _output_bits(dtype))
                    lanes.append(layout.full(_to_unit(v, dtype)))
                continue
            digits, prefixes = _digits(point, b, k_count)
            # The leading run of digits from a table where that is cheap (its prefixes lie in the run).
            (_, size), = _digit_groups(b, k_count)[:1]
            lead = None
            if _tabled(b, size, layout):
                (e,) = _group_indices(point, [(0, size)], b)
                lead = (_read_table(_owen_table(w2[:, j], w3[:, j], size, b), e, layout), size)
            scrambled = []
            for k, (d, (lo, hi)) in enumerate(zip(digits, prefixes)):
                if lead is not None and k < size:
                    continue
                key = lo ^ layout.take(v2[j, k]) if hi is None else lo ^ layout.take(v2[j, k]) ^ _mix32(hi)
                c, a = _owen_coefficients(_mix32(key), layout.take(v3[j, k]), b)
                scrambled.append(_mod_square(a * d + c, b))
            with jax.enable_x64(True):
                # One uniform tail per point below b^-K32, hashed from the whole index.
                key = point.lo ^ layout.take(v2[j, k_count])
                if not narrow:
                    key = key ^ _mix32(point.hi)
                bits = _mix32(_mix32(key) ^ layout.take(v3[j, k_count]))
                start = (bits.astype(jnp.float64) + 0.5) * 2.0 ** -32
                lanes.append(layout.full(_to_unit(_horner(scrambled, start, b, lead), dtype)))
        # Past STORE_PAST coordinates one fused loop is not vectorized (`store_all_but`).
        return (tuple(store_all_but(lanes, FUSED_LANES, seed[..., 0]) if dims > STORE_PAST else lanes),)

    def block(self, seed, offset, count, dims, dtype=jnp.float32, total=None, aligned=False):
        (lanes,) = self.lanes(seed, offset, count, dims, dtype, total, aligned)
        return stack_lanes(lanes, count)

    def __repr__(self):
        return f"Halton(replicates={self.replicates}, scramble={self.scramble!r})"

    def __eq__(self, other):
        return type(self) is type(other) and (self.replicates, self.scramble) == (other.replicates, other.scramble)

    def __hash__(self):
        return hash(("Halton", self.replicates, self.scramble))
