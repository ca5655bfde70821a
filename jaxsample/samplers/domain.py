"""What a sampler's `domain()` returns: the set its density lives on and the measure the density is
over, as plain data.

A sampler only names its domain. The checks (`jaxsample.testing`) turn a domain into a quadrature
rule and chi-square cells with the geometry in `jaxsample.domains` (which also exports these
classes), so importing a sampler does not import the checks' rules for these six kinds — as in
Mitsuba 3's `chi2.py`, where the domains' binning lives with the test and never with the warps.
A domain of a kind of its own (a spherical polygon, the microfacet directions) brings its own
`quadrature()`, `cells()` and `contains()`, built, as `jaxsample.domains` builds its rules, from the
pieces at the end of this module: Gauss–Legendre panels (`gauss_legendre_panels`, `graded_edges`)
and cells at pilot quantiles (`quantile_edges`, `bin_index`, `Cells`), plain NumPy.

Besides the set and its measure, a domain states where its density may jump or peak (`breaks`),
because a quadrature rule is only accurate where it knows of them, and the few settings of its
rule (Gauss–Legendre `order`, panel counts) where a sampler needs other than the defaults.
"""

from __future__ import annotations

import dataclasses
import functools

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


# ---- the pieces of a rule: what `jaxsample.domains` and a domain of its own build theirs from ----


def bin_index(edges: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Index i of the bin [edges[i], edges[i+1]) holding x; points outside go to the end bins."""
    return np.clip(np.searchsorted(edges, x, side="right") - 1, 0, len(edges) - 2)


@functools.lru_cache(maxsize=None)
def gauss_legendre_rule(n: int) -> tuple[np.ndarray, np.ndarray]:
    """The n-point Gauss–Legendre rule on [-1, 1] in float64 NumPy (n >= 1): (nodes ascending,
    weights), cached per order, read-only; the package's one rule (`gauss_legendre_panels` and
    `jaxsample.quadrature.gauss_legendre_nodes_weights`, which checks n and documents the error term).

    The nodes are the roots of the Legendre polynomial P_n, the weights w_i =
    2 / ((1 - x_i²) P_n'(x_i)²) (Abramowitz & Stegun §25.4).

    The roots are found by Newton's method on P_n (evaluated by Bonnet's three-term recurrence
    (k + 1) P_{k+1} = (2k + 1) x P_k - k P_{k-1}) from Tricomi's estimate
    x_i ≈ cos(π (i - 1/4) / (n + 1/2)), as in Numerical Recipes' `gauleg`. It is an alternative to
    Golub & Welsch (1969), eigenvalues of the Jacobi matrix, and is O(n²) rather than O(n³).
    Its weights are closer than NumPy's `leggauss` (which rescales them to sum to 2): at n = 8,
    8e-16 relative against a 40-digit reference where NumPy's are off by up to 8e-15.
    """
    # Only the roots in (0, 1) (and 0 itself for odd n) are computed; the rule is symmetric.
    half = (n + 1) // 2
    i = np.arange(1, half + 1, dtype=np.float64)
    x = np.cos(np.pi * (i - 0.25) / (n + 0.5))
    for _ in range(100):
        p_n, p_prev = _legendre(n, x)
        derivative = n * (x * p_n - p_prev) / (x * x - 1.0)
        step = p_n / derivative
        x = x - step
        if np.max(np.abs(step)) <= 1e-16:
            break
    p_n, p_prev = _legendre(n, x)
    derivative = n * (x * p_n - p_prev) / (x * x - 1.0)
    w = 2.0 / ((1.0 - x * x) * derivative * derivative)
    if n % 2 == 1:
        x[-1] = 0.0  # the middle root is exactly 0
    # x is descending in (0, 1]; mirror it for the negative half.
    nodes = np.concatenate([-x, x[: n // 2][::-1]])
    weights = np.concatenate([w, w[: n // 2][::-1]])
    nodes.flags.writeable = weights.flags.writeable = False
    return nodes, weights


def _legendre(n: int, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(P_n(x), P_{n-1}(x)) by Bonnet's recurrence."""
    p_prev, p = np.zeros_like(x), np.ones_like(x)
    for k in range(n):
        p_prev, p = p, ((2 * k + 1) * x * p - k * p_prev) / (k + 1)
    return p, p_prev


def gauss_legendre_panels(edges: np.ndarray, order: int = GAUSS_ORDER) -> tuple[np.ndarray, np.ndarray]:
    """Composite Gauss–Legendre nodes and weights on consecutive panels [edges[i], edges[i+1]]."""
    edges = np.unique(np.asarray(edges, dtype=np.float64))
    x, w = gauss_legendre_rule(order)
    lo, hi = edges[:-1, None], edges[1:, None]
    half = 0.5 * (hi - lo)
    nodes = (lo + hi) * 0.5 + half * x[None, :]
    weights = half * w[None, :]
    return nodes.ravel(), weights.ravel()


def graded_edges(a: float, b: float, toward: str = "both", n_geometric: int = 60,
                 n_uniform: int = 16, smallest: float = 1e-14) -> np.ndarray:
    """Panel edges on [a, b]: uniform panels plus panels graded geometrically toward a and/or b.

    Geometric grading (ratio ~1.7 over 14 decades) resolves a density that varies on any scale
    near an end point — a Phong lobe of width 1e-7 at the pole — with a fixed number of nodes.
    """
    length = b - a
    if length <= 0:
        return np.array([a, b])
    parts = [np.linspace(a, b, n_uniform + 1)]
    ladder = length * np.geomspace(smallest, 1.0, n_geometric)
    if toward in ("both", "low"):
        parts.append(a + ladder)
    if toward in ("both", "high"):
        parts.append(b - ladder)
    edges = np.unique(np.clip(np.concatenate(parts), a, b))
    return edges


def quantile_edges(values: np.ndarray, n_bins: int, low: float, high: float) -> np.ndarray:
    """Bin edges at the pilot quantiles k/n_bins, spanning [low, high], duplicates removed."""
    interior = np.quantile(values, np.arange(1, n_bins) / n_bins) if len(values) else []
    return np.unique(np.concatenate([[low], np.clip(interior, low, high), [high]]))


@dataclasses.dataclass
class Cells:
    """A partition for the chi-square test: per-cell quadrature and a point -> cell map."""

    n_cells: int
    points: np.ndarray  # quadrature nodes, float64, shape (M, *event_shape)
    weights: np.ndarray  # (M,)
    cell_of_point: np.ndarray  # (M,) int: which cell each node integrates
    assign: callable  # samples (N, *event_shape) float64 -> (N,) int in [0, n_cells), or -1 outside
