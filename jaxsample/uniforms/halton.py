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
  (the prefix i mod b^k), through a 64-bit hash (the splitmix64 finalizer) of the replicate and
  coordinate's seed, k and the prefix (the hashing approach of Burley 2020 for base 2, here per
  digit of base b). In base 2 it is `owen_scramble`, the Laine–Karras hash of `sobol`.

Digits and precision. An index below 2^64 has K = ceil(64 / log2 b) base-b digits; the digits
above the index's own are 0, and their scrambled values and everything below b^-K are one uniform
tail (per replicate and coordinate for "permutation", per point for "owen": what an infinite
digit expansion gives in distribution). The sum is taken in float64 by Horner's rule and cut to a
32-bit fraction, so each point is uniform on the 2^32 grid up to float64 rounding (2^-52
relative); the affine coefficients come from 32-bit words reduced mod b, a bias below b / 2^32
(< 2e-6 for the largest prime kept) in any digit's probabilities. Base 2 (coordinate 1) is
exact bit arithmetic: rev32(i) xor a random word ("permutation"; the index's bits past 32 fall
below 2^-32), Owen-scrambled van der Corput ("owen").

Replicates: global index g is point g div R of replicate g mod R (the `Source` convention), each
replicate with independent permutations, so the spread of the R replicate means is the standard
error. Dimensions: up to 1024 (primes 2 .. 8161). Halton points in high dimensions need the
scramble: unscrambled, the large-prime coordinates are strongly correlated for small n.
"""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from .._core.pytree import static_field
from .index import Index
from .philox import _u32, bits_to_unit
from .sobol import _reverse_bits, _scramble_reversed
from .sources import Source, _check_replicates
from ._replicated import STREAM_HALTON, Layout, check_dims, replicate_words, stack_lanes

__all__ = ["Halton", "halton_points", "halton_primes", "MAX_HALTON_DIMS"]

MAX_HALTON_DIMS = 1024
SCRAMBLES = ("permutation", "owen")


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
    with jax.enable_x64(True):
        i = _index64(index)
        for b in (int(p) for p in primes):
            if b == 2:
                columns.append(_reverse_bits(index.lo))
                continue
            digits, rest = [], i
            for _ in range(_digit_count(b)):
                digits.append(rest % jnp.uint64(b))
                rest = rest // jnp.uint64(b)
            v = jnp.zeros(i.shape, jnp.float64)
            for d in reversed(digits):
                v = (d.astype(jnp.float64) + v) * (1.0 / b)
            columns.append(_to_word(v))
    return jnp.stack(columns, axis=-1)


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
        words = [replicate_words(seed, self.replicates, dims, STREAM_HALTON, k) for k in range(k_max)]
        return tuple(jnp.stack([w[q] for w in words], axis=-1) for q in range(4))

    def lanes(self, seed, offset, count, dims, dtype=jnp.float32, total=None, aligned=False):
        """One group of `dims` lanes, (count / R, R) for the estimators' chunks, else (count,)."""
        primes = halton_primes(dims)
        layout = Layout(offset, count, self.replicates, aligned)
        w0, w1, w2, w3 = self.digit_words(seed, dims)
        owen = self.scramble == "owen"
        lanes = []
        with jax.enable_x64(True):
            i = _index64(layout.point)
            for j, b in enumerate(int(p) for p in primes):
                take = lambda table: layout.take(table[:, j])
                if b == 2:
                    word = (_scramble_reversed(layout.point.lo, take(w0[:, :, 0])) if owen
                            else _reverse_bits(layout.point.lo) ^ take(w0[:, :, 0]))
                    lanes.append(bits_to_unit(layout.full(word), dtype))
                    continue
                k_count = _digit_count(b)
                seed64 = (take(w0[:, :, 0]).astype(jnp.uint64) << jnp.uint64(32)) | take(w1[:, :, 0]).astype(jnp.uint64)
                digits, rest, prefix, power = [], i, jnp.zeros_like(i), 1
                for k in range(k_count):
                    d = rest % jnp.uint64(b)
                    rest = rest // jnp.uint64(b)
                    if owen:
                        h = _mix64(seed64 + jnp.uint64((k + 1) * 0x9E3779B97F4A7C15 % (1 << 64))
                                   + prefix * jnp.uint64(0xD6E8FEB86659FD93))
                        c = (h & jnp.uint64(0xFFFFFFFF)) % jnp.uint64(b)
                        a = jnp.uint64(1) + (h >> jnp.uint64(32)) % jnp.uint64(b - 1)
                        prefix = prefix + d * jnp.uint64(power % (1 << 64))
                        power *= b
                    else:
                        c = take(w2[:, :, k]).astype(jnp.uint64) % jnp.uint64(b)
                        a = jnp.uint64(1) + take(w3[:, :, k]).astype(jnp.uint64) % jnp.uint64(b - 1)
                    digits.append((a * d + c) % jnp.uint64(b))
                if owen:
                    tail_bits = _mix64(seed64 ^ jnp.uint64(0xA0761D6478BD642F) + i * jnp.uint64(0xE7037ED1A0B428DB))
                    tail = (tail_bits >> jnp.uint64(11)).astype(jnp.float64) * 2.0 ** -53
                else:
                    tail = (take(w1[:, :, k_count]).astype(jnp.float64) + 0.5) * 2.0 ** -32
                v = tail
                for d in reversed(digits):
                    v = (d.astype(jnp.float64) + v) * (1.0 / b)
                lanes.append(bits_to_unit(layout.full(_to_word(v)), dtype))
        return (tuple(lanes),)

    def block(self, seed, offset, count, dims, dtype=jnp.float32, total=None, aligned=False):
        (lanes,) = self.lanes(seed, offset, count, dims, dtype, total, aligned)
        return stack_lanes(lanes, count)

    def __repr__(self):
        return f"Halton(replicates={self.replicates}, scramble={self.scramble!r})"

    def __eq__(self, other):
        return type(self) is type(other) and (self.replicates, self.scramble) == (other.replicates, other.scramble)

    def __hash__(self):
        return hash(("Halton", self.replicates, self.scramble))
