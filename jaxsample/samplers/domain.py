"""What a sampler's `domain()` returns: the set its density lives on and the measure the density is
over, as plain data.

A sampler only names its domain. The checks (`jaxsample.testing`) turn a domain into a quadrature
rule and chi-square cells with the geometry in `jaxsample.domains` (which also exports these
classes), so importing a sampler does not import the checks' grids and binning — as in Mitsuba 3's `chi2.py`, where the domains' binning lives with the
test and never with the warps.

Besides the set and its measure, a domain states where its density may jump or peak (`breaks`),
because a quadrature rule is only accurate where it knows of them, and the few settings of its
rule (Gauss–Legendre `order`, panel counts) where a sampler needs other than the defaults.
"""

from __future__ import annotations

import dataclasses

import numpy as np

GAUSS_ORDER = 8  # nodes per Gauss–Legendre panel in the checks' rules


@dataclasses.dataclass(frozen=True)
class Directions:
    """The unit sphere with the solid-angle measure; event_shape (3,).

    Parametrised about `axis` by t = 1 - cos θ in [0, 2] and the azimuth φ, where dω = dt dφ.
    `breaks` are values of t where the density may jump (a cone's edge; t = 1, the horizon); the
    checks grade their panels toward t = 0 (where lobes peak) and toward every break.
    """

    axis: tuple = (0.0, 0.0, 1.0)
    breaks: tuple = ()
    n_azimuth_quadrature: int = 64
    event_shape = (3,)
    measure = "solid angle"


@dataclasses.dataclass(frozen=True, eq=False)
class Interval:
    """The interval [low, high] (low may be -inf, high +inf) with the length measure; event_shape ().

    `breaks` are points where the density may jump or peak (bin edges, a truncation point): the
    quadrature splits there. With `graded=True` each piece gets panels graded geometrically toward
    both of its ends (sharp exponentials and power laws); with `graded=False` the pieces are the
    panels themselves (a piecewise-constant density with `order=1` is then integrated exactly by
    the midpoint rule, even with 10^6 bins). For high = inf the quadrature stops at
    `quadrature_high`, which the sampler chooses so that the mass beyond it is negligible (below
    1e-30); chi-square cells still extend to infinity. Likewise, for low = -inf it starts at
    `quadrature_low`.
    """

    low: float = 0.0
    high: float = 1.0
    breaks: tuple | np.ndarray = ()
    graded: bool = True
    order: int = GAUSS_ORDER
    quadrature_high: float | None = None
    quadrature_low: float | None = None
    event_shape = ()
    measure = "length"


@dataclasses.dataclass(frozen=True, eq=False)
class Box:
    """The axis-aligned box prod_k [low_k, high_k] with the volume measure; event_shape (d,).

    Each axis is an `Interval` (with its own breaks, grading and order).
    """

    axes: tuple  # of Interval

    @classmethod
    def from_bounds(cls, low, high, breaks=None, graded: bool = True, order: int = GAUSS_ORDER):
        low = np.asarray(low, np.float64).ravel()
        high = np.asarray(high, np.float64).ravel()
        breaks = [()] * len(low) if breaks is None else breaks
        return cls(tuple(Interval(float(a), float(b), k, graded, order) for a, b, k in zip(low, high, breaks)))

    @property
    def event_shape(self):
        return (len(self.axes),)

    @property
    def measure(self) -> str:
        """Lebesgue measure on R^d: length, area, volume, or "d-volume"."""
        d = len(self.axes)
        return {1: "length", 2: "area", 3: "volume"}.get(d, f"{d}-volume")


@dataclasses.dataclass(frozen=True)
class Disk:
    """The unit disk with the area measure; event_shape (2,).

    Parametrised by s = r² in [0, 1] and the azimuth φ, where dA = ½ ds dφ.
    """

    n_azimuth_quadrature: int = 64
    event_shape = (2,)
    measure = "area"


@dataclasses.dataclass(frozen=True, eq=False)
class Triangle:
    """The triangle with vertices a, b, c in R² or R³, with the area measure; event_shape (dim,).

    Parametrised by v in [0, 1] (from a toward the edge bc) and w in [0, 1] (along that edge):
    x = a + v((1 - w)(b - a) + w(c - a)), dA = 2·area·v dv dw; `n_panels` panels of `order`
    Gauss–Legendre nodes per coordinate.
    """

    a: tuple
    b: tuple
    c: tuple
    order: int = GAUSS_ORDER
    n_panels: int = 8

    measure = "area"

    @property
    def event_shape(self):
        return (len(self.a),)


@dataclasses.dataclass(frozen=True)
class DiscreteSet:
    """The outcomes {0, ..., size - 1} with the counting measure; event_shape ()."""

    size: int
    event_shape = ()
    measure = "counting"
