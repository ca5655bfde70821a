"""Rank-1 lattice points in their extensible base-2 form, randomly shifted, with the tent transform.

Construction. A rank-1 lattice rule with N = 2^m points and generating vector z in Z^d is
x_k = frac(k z / 2^m), k = 0 .. 2^m - 1. Enumerating k in radical-inverse order makes the rule
extensible (Hickernell & Hong 1997; Hickernell, Hong, L'Ecuyer & Lemieux, "Extensible lattice
sequences for quasi-Monte Carlo quadrature", SIAM J. Sci. Comput. 22(3), 2000): point i is

    x_i = frac(phi_2(i) z + Delta),

with phi_2(i) = sum_k i_k 2^-(k+1) the van der Corput radical inverse of i = sum_k i_k 2^k. For
every m, the first 2^m points {phi_2(i) : i < 2^m} = {k / 2^m : k < 2^m}, so every power-of-two
prefix is the full lattice rule with 2^m points (shifted by Delta): a stream may stop at any 2^m.

Exact arithmetic. For i < 2^32, phi_2(i) = rev32(i) / 2^32 (rev32 reverses the 32 bits), so
phi_2(i) z mod 1 = (rev32(i) z mod 2^32) / 2^32: one wrapping uint32 multiply per coordinate,
exact, never a float. For a 64-bit index i = hi 2^32 + lo, phi_2(i) = (rev32(lo) 2^32 + rev32(hi))
/ 2^64 and the top 32 bits of the fraction are rev32(lo) z + floor(rev32(hi) z / 2^32) mod 2^32
(the second term exact in uint64). The shift Delta is a uniform 32-bit fraction added mod 2^32.

Randomization and error bars. Each replicate r (global indices g with g mod R = r, point g div R,
the convention of `Source`) has its own shift Delta_r, one independent uniform 32-bit word per
(replicate, coordinate) from Philox. With a uniform shift, each point is uniform on the 2^32 grid,
so the estimate is unbiased, and the R replicates are independent, so the spread of their means
is an honest standard error (Cranley & Patterson 1976; L'Ecuyer & Lemieux 2000).

Tent (baker's) transform. x -> 1 - |2x - 1| after the shift (Hickernell 2002, "Obtaining
O(N^(-2+eps)) convergence for lattice quadrature rules"; Dick, Nuyens & Pillichshammer 2014):
the tent-transformed shifted lattice integrates smooth non-periodic integrands as if they were
periodic, with RMSE O(N^(-2+eps)) for N = 2^m points in low dimension (docs/literature.md 3.1 and
3.2: measured slope -2.0 for a Fibonacci lattice on cos^3). On the 32-bit fraction w it is
t = 2w for w < 2^31 and t = 2^33 - 1 - 2w beyond, i.e. (w << 1) xor (all ones if the top bit is
set): a bijection of the 2^32 grid (even t from the first half, odd t from the second), within
2^-32 of the exact tent of w / 2^32. So a uniform point stays exactly uniform on the grid.
`tent=False` gives the plain shifted lattice (RMSE ~ N^-1 on non-periodic integrands).

Generating vector. The first 1024 coordinates of "lattice-39101-1024-1048576.3600" from
F. Y. Kuo's page (https://web.maths.unsw.edu.au/~fkuo/lattice/; the copy read was
QMCSoftware/LDData, lattice/kuo.lattice-39101-1024-1048576.3600.txt): an embedded (extensible)
base-2 lattice sequence built by the component-by-component construction of Cools, Kuo & Nuyens
("Constructing embedded lattice rules for multivariate integration", SIAM J. Sci. Comput. 28(6),
2006) with decaying product weights, for 3600 dimensions. It is optimized for point counts
2^10 .. 2^20 per replicate. Why this one (`benchmarks/lattice_vectors.py`, results in
`benchmarks/results/lattice-vectors-cpu-2core-2026-12-05.md`): Kuo's order-2-weight vector
lattice-32001-1024-1048576.3600 (z = 1, 182667, 469891, ...) has the short dual vector
h = (-1, -11, -2) (h.z = -45 2^16: in the dual lattice for every m <= 16, and the shortest one
for m = 13 .. 16), so a smooth 3-d integrand's error stalls near 1e-5 from 2^10 to 2^16 points
with it; this vector's shortest dual vector in the first three coordinates has
prod max(1, |h_j|) = 96 .. 21788 for m = 12 .. 20, and of Kuo's four 2^20 vectors it has the
smallest RMS error (4 shifts) in 14 of the 24 (d, m) cells of that file at m >= 14 (17 of 36
overall; lattice-32001 in none).
Every entry is odd, so for any 2^m points (m <= 32) each one-dimensional
projection is the full grid {k / 2^m}; beyond 2^20 points (and below 2^10) the rule is still a
valid lattice with that property, just not one the construction optimized. Beyond 2^32 points
per replicate the 32-bit fractions of points i and i + 2^32 differ only through the
floor(rev32(hi) z / 2^32) term (in coordinate 1, z_1 = 1, not at all): use more replicates.
"""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from .index import Index, as_index, floordiv
from .philox import _alignment, _u32, bits_to_unit
from .sobol import _reverse_bits, _reverse_bits_np
from .._core.pytree import static_field
from .sources import Source, _check_replicates, register_source
from ._replicated import (STREAM_LATTICE, Layout, check_dims, check_flag, replicate_words, stack_lanes,
                          wide_mulhi)

__all__ = ["Lattice", "lattice_points", "lattice_generating_vector", "MAX_LATTICE_DIMS"]

# Kuo, lattice-39101-1024-1048576.3600, coordinates 1 .. 1024 of the generating vector (see the
# module docstring for the source and the point range it is built for).
_KUO_39101 = """\
1 182667 279195 223491 205755 359329 198937 246491 466233 379083 36369 64937
66771 316939 133085 123053 117393 150849 249011 84523 488607 302459 166527 320003
389385 167853 500963 29137 272065 191127 236801 33547 493351 287131 123975 144279
469429 303333 241475 464325 222725 461957 36889 302837 375867 330661 317387 251717
204691 448709 230903 332451 199565 505759 183713 259639 252645 399425 263827 335179
122001 461335 404323 105409 66413 311477 175313 279735 394009 17815 53097 38027
472745 410105 68809 473045 165945 267937 55141 62791 285995 126173 176985 427547
454863 424625 240079 78133 409009 115825 430717 382943 375529 515661 426131 456381
219683 316389 259059 84999 275415 304479 409707 420535 40537 385491 518771 167559
34663 130747 248377 104613 91679 490637 155525 80879 294657 383837 10835 208567
305071 308645 516997 266997 512799 174311 424585 128073 195057 237501 125311 338563
380199 116405 436269 454173 265837 463933 480925 227027 88187 6497 38863 462129
213739 345055 263405 474909 183125 37731 121641 254439 299429 517895 54023 42101
249273 410233 77471 362157 434577 364387 90051 501895 161773 97223 377405 89045
100783 171781 201015 496317 375069 143075 228303 321907 120085 230031 99207 465275
104317 499999 24531 464037 201809 494815 72657 335957 245969 148673 94087 121875
129677 180341 519361 119379 322575 354793 258519 484809 98843 73253 394657 471803
492369 90557 430259 93761 522833 221917 158575 261395 112329 377149 217515 198073
75717 477551 435439 284929 55347 139209 252695 167221 358873 497693 428953 468787
408703 367823 405757 444591 235183 416013 66009 271273 341093 343443 166341 63021
197067 175515 466911 413481 365193 8263 185349 196911 498843 141121 135583 486891
382525 9063 352399 283599 315551 250563 96993 439847 136091 122787 203509 65351
187257 27769 427271 504637 191661 198269 394483 25177 83859 30345 215055 380913
230161 479181 108969 428919 126755 220703 510299 59911 114963 248543 37939 79295
364755 302091 80313 422925 197755 500403 101531 419123 271697 502003 312361 514831
521401 185055 129339 59165 114625 215711 63075 89761 320147 325119 57131 94267
91433 363963 286515 363251 401965 440515 104899 153825 278581 416851 236221 321839
247525 500365 441647 37373 12319 268763 316051 71955 514707 453643 323493 128445
78293 184279 107867 396051 171839 362571 259205 25101 268495 237747 47979 272407
191595 171981 42021 247787 491947 320915 80579 157853 258825 359873 433855 44673
161663 182079 389495 366571 453023 468271 413995 426689 151245 326401 366697 147595
227185 387605 248899 476075 339543 113653 314071 295563 393417 120633 163665 73853
467443 507309 216283 333613 372967 432743 157767 85517 455655 242613 322455 25163
370943 430493 292603 189657 291811 181135 207599 492047 6053 353161 125759 514021
423021 466607 232713 207657 130225 135877 392103 379395 476243 134231 25945 369449
131503 472207 511859 514887 77995 47653 133207 84845 20441 102367 138477 487849
224589 294717 109759 11619 368801 395915 425041 442875 466719 454977 72281 277871
159921 303087 244501 973 60543 370197 17679 489259 365419 22953 297023 22671
108539 85689 362371 386935 472617 334103 106459 100587 469771 322173 336187 67711
22869 50965 435003 28367 264497 366641 106841 220997 206503 495937 453679 137489
246043 484323 184559 238477 300211 274035 297761 38895 315033 231841 163567 169615
104565 394295 250265 295669 187311 444711 403003 243195 276421 162165 367729 309171
198663 7271 218409 5983 247915 172293 17573 325043 270827 32945 118549 36997
369399 263483 423215 368077 497581 258921 460685 61743 301617 113157 327921 124941
297323 145877 54709 38929 27339 128757 76771 238359 83565 355027 476807 285225
472113 65087 372319 221281 195207 350389 415559 56815 380817 143789 335599 489931
398779 282373 159847 350679 160827 279455 193221 230783 178137 353601 89131 372527
306613 187635 285943 213411 178247 116839 355263 437211 478175 235229 93181 256077
177767 349129 483023 484377 54149 402791 411761 473191 302665 414165 391943 215413
42439 164179 478661 213699 145967 444679 342919 212673 273953 251103 515897 318935
229211 511509 450425 133341 477953 154761 63629 38241 459731 175653 292523 401697
464209 81013 492621 50661 152797 248287 239605 51385 3995 206337 504387 6897
265993 480881 487651 365977 17007 497063 33017 518381 353339 334697 31837 477683
60229 50521 27711 513291 502955 115989 436395 423777 375133 495757 280685 338207
295325 234961 58219 286889 228337 322029 473911 442473 307413 272747 145539 441983
470407 107473 151113 248115 170119 404949 264353 87883 307267 324999 268229 256873
80671 199761 354715 21373 352653 225405 433479 61055 113889 85071 78983 17469
376889 261557 79723 305367 113291 231557 460795 138085 343379 373633 135091 95143
416939 1867 163033 315087 104749 206771 20523 282333 464727 140291 165519 41495
413679 315671 459185 179753 135905 455265 131877 423681 109311 415037 266789 491689
493251 238009 443517 222871 33431 12013 208609 471445 363403 170271 176697 180717
477707 422793 151921 414663 309501 366117 495637 477065 262635 211351 519309 415943
400885 91777 119437 123309 437735 250837 378947 345941 309463 515587 202835 412869
280297 224391 370787 134435 239103 266605 163713 71279 76743 470977 251523 326495
293343 325467 51321 55723 135025 459611 291687 173839 393501 114527 52317 367845
225941 32665 440195 261525 407707 236641 376465 389157 217829 29189 377825 41749
179179 37589 186701 90007 395815 521441 176571 310985 183271 195219 35251 97913
250955 20787 291487 327111 88079 295131 424357 267469 258175 148467 288319 495589
289443 122673 418069 298821 459515 174257 291885 498655 111895 224215 320387 432019
66591 170297 388675 459079 221401 211777 79255 222239 273591 293041 305967 109451
213281 362061 243813 446129 253825 25213 488773 515477 190121 497957 215113 322645
208811 474059 357415 152143 498349 510633 323631 409179 272657 463553 81323 224157
374547 143541 154893 154197 120599 67741 395209 253363 482161 321509 466093 150295
190977 330313 135939 399093 227589 447823 502057 198185 149417 135051 159355 510597
412727 186807 39281 131465 42761 268121 437971 71183 438315 275503 264179 276861
342383 486597 449347 311777 388497 164553 217097 175749 47951 31523 297375 299179
37835 270757 389697 245537 363457 268861 413151 475105 348137 364063 492357 117265
464109 250715 239433 264203 447969 279911 132605 333703 69165 57627 112067 371633
39183 315421 273391 324063 143161 194707 419699 24075 267023 308889 247465 77197
506681 211631 222895 192329 243105 195475 113055 390153 310785 61017 289467 401727
53805 461517 14427 24715 56663 168371 207193 475777 193161 122377 429559 222127
346177 107321 179577 141691 183241 250423 487073 174197 44187 311549 440989 322729
283979 519819 449753 242449 410373 264071 107951 228971 269389 221149 44121 523673
173437 144953 278889 103969 349365 29649 465625 95867 406545 188777 519193 40241
513425 145087 390337 451845 29779 434803 217143 18357 361835 145719 49927 200599
473709 105611 174227 470341
"""

MAX_LATTICE_DIMS = 1024
_VECTOR = np.array([int(v) for v in _KUO_39101.split()], dtype=np.uint32)
assert _VECTOR.shape == (MAX_LATTICE_DIMS,) and bool(np.all(_VECTOR % 2 == 1))


def lattice_generating_vector(dims: int) -> np.ndarray:
    """The first `dims` coordinates of the generating vector (uint32; see the module docstring)."""
    check_dims("Lattice", dims, MAX_LATTICE_DIMS)
    return _VECTOR[:dims].copy()


def _coordinate(point: Index, z) -> jax.Array:
    """frac(phi_2(i) z) as a 32-bit fraction for point indices i (an `Index`) and one z."""
    w = _reverse_bits(point.lo) * _u32(z)
    if point.wide:
        w = w + wide_mulhi(_reverse_bits(point.hi), z)
    return w


_LOW_TABLES: dict = {}


def _low_table(bits: int, dims: int) -> np.ndarray:
    """(2^bits, dims) uint32 NumPy constant: rev32(j) z_c mod 2^32 for j < 2^bits, the part of a
    point's fraction that comes from the low `bits` bits of its index (see `Lattice.lanes`)."""
    key = (bits, dims)
    if key not in _LOW_TABLES:
        j = _reverse_bits_np(np.arange(1 << bits, dtype=np.uint32))[:, None].astype(np.uint64)
        _LOW_TABLES[key] = ((j * lattice_generating_vector(dims)[None, :].astype(np.uint64))
                            & np.uint64(0xFFFFFFFF)).astype(np.uint32)
    return _LOW_TABLES[key]


def lattice_points(index, dims: int) -> jax.Array:
    """Unshifted lattice points frac(phi_2(i) z) as uint32 fractions (value / 2^32), shape
    index.shape + (dims,); `index` is a uint32 array or an `index.Index` (64-bit indices)."""
    z = lattice_generating_vector(dims)
    if not isinstance(index, Index):
        index = Index(None, _u32(index))
    return jnp.stack([_coordinate(index, int(z[j])) for j in range(dims)], axis=-1)


def tent_bits(w: jax.Array) -> jax.Array:
    """The tent transform x -> 1 - |2x - 1| on 32-bit fractions, as a bijection of the grid:
    2w for w < 2^31, 2^33 - 1 - 2w beyond (see the module docstring)."""
    return (w << _u32(1)) ^ (_u32(0) - (w >> _u32(31)))


@register_source
class Lattice(Source):
    """A randomly shifted, extensible rank-1 lattice (Cools–Kuo–Nuyens vector), R replicates.

    Replicate r is x_i = frac(phi_2(i) z + Delta_r), i the point index within the replicate,
    followed by the tent transform when `tent` (the default); see the module docstring for the
    construction, the exact integer arithmetic, the generating vector and its point range.
    Up to 1024 dimensions. Every power-of-two prefix of a replicate is a lattice rule, so the
    best counts are n = R 2^m (`estimate_until` tests its tolerance at those counts).

    Args:
      replicates: R independent shifts, an integer in [2, 2^32) (default 16).
      tent: apply the tent (baker's) transform (True or False; default True).
    """

    name: ClassVar[str] = "lattice"
    tent: bool = static_field(default=True)

    def __init__(self, replicates: int = 16, tent: bool = True):
        self.replicates = _check_replicates("Lattice", replicates)
        self.tent = check_flag("Lattice", "tent", tent)

    def shifts(self, seed, dims: int) -> jax.Array:
        """(R, dims) uint32: Delta_r as 32-bit fractions, one Philox word per (replicate, coordinate)."""
        return replicate_words(seed, self.replicates, dims, STREAM_LATTICE)[0]

    def lanes(self, seed, offset, count, dims, dtype=jnp.float32, total=None, aligned=False):
        """The points as one group of `dims` lanes: (count / R, R) when the window starts at a
        multiple of R and holds a multiple of R points (the estimators' chunks), else (count,)."""
        check_dims("Lattice", dims, MAX_LATTICE_DIMS)
        replicates = self.replicates
        per = count // replicates
        bits = max(per - 1, 0).bit_length()
        if count % replicates == 0 and per > 0 and _alignment(aligned) % (replicates << bits) == 0:
            # An estimator's chunk: each replicate takes points m0 .. m0 + per - 1 with m0 a multiple
            # of 2^bits >= per, so rev32(m0 + j) = rev32(m0) | rev32(j) with disjoint bits, and the
            # fraction is (rev32(j) z mod 2^32) + (the chunk's part, m0's, plus the shift): a
            # constant table read along rows plus one word per (replicate, coordinate), the same
            # bits as below without a per-point bit reversal or multiply.
            first = floordiv(as_index(offset, count), replicates)
            table = _low_table(bits, dims)[:per]
            shifts = self.shifts(seed, dims)
            z = lattice_generating_vector(dims)
            lanes = []
            for j in range(dims):
                w = jnp.asarray(table[:, j])[:, None] + (_coordinate(first, int(z[j])) + shifts[None, :, j])
                if self.tent:
                    w = tent_bits(w)
                lanes.append(bits_to_unit(w, dtype))
            return (tuple(lanes),)
        layout = Layout(offset, count, replicates, aligned)
        shifts = self.shifts(seed, dims)
        z = lattice_generating_vector(dims)
        lanes = []
        for j in range(dims):
            w = _coordinate(layout.point, int(z[j])) + layout.take(shifts[:, j])
            if self.tent:
                w = tent_bits(w)
            lanes.append(bits_to_unit(layout.full(w), dtype))
        return (tuple(lanes),)

    def block(self, seed, offset, count, dims, dtype=jnp.float32, total=None, aligned=False):
        (lanes,) = self.lanes(seed, offset, count, dims, dtype, total, aligned)
        return stack_lanes(lanes, count)

    def __repr__(self):
        return f"Lattice(replicates={self.replicates}, tent={self.tent})"

    def __eq__(self, other):
        return type(self) is type(other) and (self.replicates, self.tent) == (other.replicates, other.tent)

    def __hash__(self):
        return hash(("Lattice", self.replicates, self.tent))
