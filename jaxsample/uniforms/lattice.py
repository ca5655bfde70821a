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

Generating vector. The first 1024 coordinates of "lattice-32001-1024-1048576.3600" from
F. Y. Kuo's page (https://web.maths.unsw.edu.au/~fkuo/lattice/; the copy read was
QMCSoftware/LDData, lattice/kuo.lattice-32001-1024-1048576.3600.txt): an embedded (extensible)
base-2 lattice sequence built by the component-by-component construction of Cools, Kuo & Nuyens
("Constructing embedded lattice rules for multivariate integration", SIAM J. Sci. Comput. 28(6),
2006) with order-2 weights, for 3600 dimensions. It is optimized for point counts 2^10 .. 2^20
per replicate. Every entry is odd, so for any 2^m points (m <= 32) each one-dimensional
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
from .sources import Source, _check_replicates
from ._replicated import (STREAM_LATTICE, Layout, check_dims, check_flag, replicate_words, stack_lanes,
                          wide_mulhi)

__all__ = ["Lattice", "lattice_points", "lattice_generating_vector", "MAX_LATTICE_DIMS"]

# Kuo, lattice-32001-1024-1048576.3600, coordinates 1 .. 1024 of the generating vector (see the
# module docstring for the source and the point range it is built for).
_KUO_32001 = """\
1 182667 469891 498753 110745 446247 250185 118627 245333 283199 408519 391023
246327 126539 399185 461527 300343 69681 516695 436179 106383 238523 413283 70841
47719 300129 113029 123925 410745 211325 17489 511893 40767 186077 519471 255369
101819 243573 66189 152143 503455 113217 132603 463967 297717 157383 224015 502917
36237 94049 170665 79397 123963 223451 323871 303633 98567 318855 494245 477137
177975 64483 26695 88779 94497 239429 381007 110205 339157 73397 407559 181791
442675 301397 32569 147737 189949 138655 350241 63371 511925 515861 434045 383435
249187 492723 479195 84589 99703 239831 269423 182241 61063 130789 143095 471209
139019 172565 487045 304803 45669 380427 19547 425593 337729 237863 428453 291699
238587 110653 196113 465711 141583 224183 266671 169063 317617 68143 291637 263355
427191 200211 365773 254701 368663 248047 209221 279201 323179 80217 122791 316633
118515 14253 129509 410941 402601 511437 10469 366469 463959 442841 54641 44167
19703 209585 69037 33317 433373 55879 245295 10905 468881 128617 417919 45067
442243 359529 51109 290275 168691 212061 217775 405485 313395 256763 152537 326437
332981 406755 423147 412621 362019 279679 169189 107405 251851 5413 316095 247945
422489 2555 282267 121027 369319 204587 445191 337315 322505 388411 102961 506099
399801 254381 452545 309001 147013 507865 32283 320511 264647 417965 227069 341461
466581 386241 494585 201479 151243 481337 68195 75401 58359 448107 459499 9873
365117 350845 181873 7917 436695 43899 348367 423927 437399 385089 21693 268793
49257 250211 125071 341631 310163 94631 108795 21175 142847 383599 71105 65989
446433 177457 107311 295679 442763 40729 322721 420175 430359 480757 221417 460963
263529 263625 16919 289121 243609 414769 147195 326731 277925 185497 29735 11185
212811 371743 33547 250809 390965 486257 348223 263649 241785 425685 240127 447899
182195 306733 465107 434787 239361 437289 183495 75179 431157 376487 141253 293903
399797 325045 277541 215657 263115 193361 478441 299477 319217 176929 279451 32237
346181 374911 443279 319283 306211 70449 88145 272219 178705 159715 177793 164999
16833 49379 83863 223583 22615 225323 111767 361309 182521 154685 426543 482481
122871 250773 324031 227329 465853 165123 163615 245155 192403 364635 276575 195289
439767 386711 472741 6385 435121 299865 151695 344227 505437 130021 254671 165583
129277 513679 155197 147197 161911 408721 134261 56599 410699 110337 18283 393383
222965 244381 89807 198515 219643 467277 69251 227483 90213 405587 225651 349029
365859 448277 284285 85247 8363 235701 168505 11797 326593 482271 181411 424383
486111 136879 467187 523659 357769 102621 120121 253107 11107 410147 315347 1551
60525 265467 404483 174571 303643 12741 486785 382527 264167 438949 73635 149281
482205 150185 256827 108249 38907 511485 437613 401415 196935 228179 207375 366367
55589 84509 108335 371355 384565 35521 175225 111363 61861 183569 406605 71801
211703 132611 241903 215337 235709 415963 274405 4703 240525 416779 243755 157423
286867 227441 254477 462447 276941 111189 144789 368511 321515 355653 330037 193619
172623 357807 255105 265789 348989 399829 88709 147959 397901 25605 426447 223367
281913 109421 354737 97901 221801 483127 331811 284329 200029 472285 161795 142317
521093 375505 103755 166279 57527 161091 215319 485895 25887 89591 240303 253535
491933 137349 26775 1729 409481 468105 114849 396207 131517 179647 82499 270263
507511 126811 392021 290691 144999 409189 25557 217529 292351 418783 192003 162237
300457 283151 244869 372931 245703 124071 1135 286385 256437 277087 351965 88117
379293 177055 5879 372417 277241 204087 28287 510057 509695 148637 173693 18863
410971 490307 158579 180629 292825 56021 161863 391107 441385 41333 88349 248261
414605 250945 258519 519295 428331 82417 297583 236509 193353 521611 252473 8615
315077 356463 168977 225931 471707 523789 283671 107083 338195 64035 422417 114519
179967 228957 249611 300357 414135 316269 482363 349081 247739 257763 514731 459623
273057 190725 16075 225093 263631 304121 456955 185759 447357 463223 507381 91535
293531 336195 338591 233527 475567 202419 497965 427305 292097 87701 46525 425127
162119 91059 509853 439515 193197 489889 247123 72951 19091 32249 175185 401645
481103 156391 461987 274743 258789 363861 329821 441411 494409 523681 275133 476635
356313 301287 370055 223247 474385 235885 464331 100449 154789 354597 46075 509469
293887 118997 94605 130853 62381 446211 110775 441749 11647 441327 518019 266745
303321 428073 439511 327309 370317 99099 92823 47303 508365 122925 371521 413947
381997 128693 338147 68609 298361 142827 78791 110299 74983 399743 248095 446313
211653 42373 380463 305563 287069 174685 350981 87739 118153 130365 288001 85703
370809 261363 243289 127027 450185 230997 96425 165333 329901 166631 451049 124935
425907 187583 426405 407503 481683 436815 36701 230675 142295 384337 97869 174277
105907 411309 442025 420455 275357 36543 399931 369307 300069 198191 275635 74869
395981 154569 425805 209447 511999 311137 401091 114095 123237 409775 313845 411497
307259 252635 486853 415967 393585 252305 248807 429869 19877 238767 465765 251435
31931 9375 394037 482327 226155 276901 145515 515957 58865 432665 317515 202675
194919 363725 167451 496379 88081 429401 193909 464257 21783 255519 173419 4525
396301 323707 301965 58913 181921 392791 517181 199121 150613 498367 353209 362387
426477 30755 481743 79335 242545 193489 154217 152365 248003 160629 450905 119515
312019 221569 470791 42569 305501 107903 322337 40815 2239 45407 377109 222897
408051 334611 102593 474007 449755 395473 183207 445655 359145 480015 506445 415163
459765 240993 348643 311311 301277 506281 478109 106897 475519 295603 329847 177575
127243 272713 304281 50573 349417 131487 502907 412417 397071 147315 235781 255885
421135 161223 77175 331995 78655 211715 301259 219035 127701 83493 61371 300739
312513 466155 314441 345733 156889 487233 146325 73709 23791 469019 429905 210955
512205 237585 38469 380697 299875 275393 388021 354889 266469 293501 186931 124695
432785 242425 107199 57331 200461 371767 159645 217483 299463 443487 387823 288247
231339 69451 167207 474283 288285 35023 310071 52017 377933 184317 236333 100811
6867 225535 495413 237521 165557 466251 494583 41971 325869 497911 107613 261385
254175 420485 345119 271503 474889 79655 131139 494331 204103 56679 30945 103137
387471 375569 347443 84925 109079 121365 28371 23283 402765 45085 203239 332045
280521 511521 420779 457787 308723 213891 340515 6077 469349 317283 193051 84615
26411 111133 384309 89225 15061 451299 253109 283983 272139 224493 457497 198591
60857 170653 516063 63655 176635 496653 142945 181199 271031 262767 431349 82049
441275 496297 469933 413335 194583 105247 500683 139889 100381 440753 193069 5979
193247 301363 33843 221103 132691 130351 367705 132071 410455 5763 280417 359827
30087 290263 357573 86205 65473 144355 146417 84499 5649 518281 65049 42149
145689 314395 235127 205711
"""

MAX_LATTICE_DIMS = 1024
_VECTOR = np.array([int(v) for v in _KUO_32001.split()], dtype=np.uint32)
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
