"""Domains: what the checks in `jaxsample.testing` integrate over and bin samples on.

A sampler's `domain()` returns one of these. Each domain provides, in float64 NumPy:

- `quadrature()` -> (points, weights): a deterministic rule with sum_i w_i g(x_i) ≈ ∫ g dμ over the
  whole domain, accurate (to ~1e-10) for densities that are smooth between the domain's `breaks`
  even when they are sharply peaked (lobes of width 1e-7) — it uses panels that are geometrically
  graded toward each break and toward the domain's "centre" (the pole for directions).
- `cells(pilot, n_cells)` -> `Cells`: a partition of the domain into about `n_cells` cells of
  roughly equal probability, chosen from *pilot* samples drawn independently of the samples under
  test (so the chi-square statistic keeps its distribution), with a quadrature rule per cell for
  the expected counts and an `assign` function for observed counts.
- `contains(x)`: whether points lie in the domain (to float tolerance).
"""

from __future__ import annotations

import dataclasses

import numpy as np

GAUSS_ORDER = 8


def bin_index(edges: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Index i of the bin [edges[i], edges[i+1]) holding x; points outside go to the end bins."""
    return np.clip(np.searchsorted(edges, x, side="right") - 1, 0, len(edges) - 2)


def gauss_legendre_panels(edges: np.ndarray, order: int = GAUSS_ORDER) -> tuple[np.ndarray, np.ndarray]:
    """Composite Gauss–Legendre nodes and weights on consecutive panels [edges[i], edges[i+1]]."""
    edges = np.unique(np.asarray(edges, dtype=np.float64))
    x, w = np.polynomial.legendre.leggauss(order)
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


def _split_at_breaks(a: float, b: float, breaks) -> np.ndarray:
    inner = [float(t) for t in np.ravel(breaks) if a < t < b]
    return np.array(sorted({a, b, *inner}))


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


def _frame_from_axis(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    # The Duff et al. basis in float64 NumPy, for the checks only.
    nx, ny, nz = axis
    s = np.copysign(1.0, nz)
    a = -1.0 / (s + nz)
    b = nx * ny * a
    return np.array([1.0 + s * nx * nx * a, s * b, -s * nx]), np.array([b, s + ny * ny * a, -ny])


@dataclasses.dataclass(frozen=True)
class Directions:
    """The unit sphere with the solid-angle measure, parametrised about `axis` by
    t = 1 - cos θ in [0, 2] and azimuth φ, where dω = dt dφ.

    `breaks` are values of t where the density may jump (a cone's edge, the horizon); quadrature
    panels are graded toward t = 0 (where lobes peak) and toward every break.
    """

    axis: tuple = (0.0, 0.0, 1.0)
    breaks: tuple = ()
    n_azimuth_quadrature: int = 64
    event_shape = (3,)

    def _axes(self):
        axis = np.asarray(self.axis, dtype=np.float64)
        axis = axis / np.linalg.norm(axis)
        tangent, bitangent = _frame_from_axis(axis)
        return tangent, bitangent, axis

    def _to_world(self, t: np.ndarray, phi: np.ndarray) -> np.ndarray:
        tangent, bitangent, axis = self._axes()
        t, phi = np.broadcast_arrays(t, phi)
        sin_theta = np.sqrt(np.maximum(t * (2.0 - t), 0.0))
        local = np.stack([sin_theta * np.cos(phi), sin_theta * np.sin(phi), 1.0 - t], axis=-1)
        return local[..., 0:1] * tangent + local[..., 1:2] * bitangent + local[..., 2:3] * axis

    def _polar(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        tangent, bitangent, axis = self._axes()
        x = np.asarray(x, dtype=np.float64)
        # 1 - cos θ = |x - axis|² / 2 for unit x: no cancellation near the axis.
        t = 0.5 * np.sum((x - axis) ** 2, axis=-1)
        phi = np.mod(np.arctan2(x @ bitangent, x @ tangent), 2.0 * np.pi)
        return t, phi

    def _t_edges(self, a: float, b: float) -> np.ndarray:
        pieces = _split_at_breaks(a, b, self.breaks)
        edges = [graded_edges(lo, hi) for lo, hi in zip(pieces[:-1], pieces[1:])]
        return np.unique(np.concatenate(edges))

    def quadrature(self):
        t, wt = gauss_legendre_panels(self._t_edges(0.0, 2.0))
        m = self.n_azimuth_quadrature
        # The trapezoid rule is spectrally accurate for smooth periodic functions of φ.
        phi = (np.arange(m) + 0.5) * (2.0 * np.pi / m)
        wphi = np.full(m, 2.0 * np.pi / m)
        points = self._to_world(t[:, None], phi[None, :]).reshape(-1, 3)
        weights = (wt[:, None] * wphi[None, :]).ravel()
        return points, weights

    def cells(self, pilot: np.ndarray, n_cells: int) -> Cells:
        n_phi = 4 if n_cells >= 32 else 1
        n_t = max(n_cells // n_phi, 2)
        t_pilot, _ = self._polar(pilot)
        # Breaks are cell edges too, so that a region of zero density (below the horizon, beyond
        # a cone's edge) is a cell of its own and any sample landing there fails the test.
        t_edges = np.unique(np.concatenate([quantile_edges(t_pilot, n_t, 0.0, 2.0),
                                            _split_at_breaks(0.0, 2.0, self.breaks)]))
        phi_edges = np.linspace(0.0, 2.0 * np.pi, n_phi + 1)
        pts, wts, ids = [], [], []
        phi_nodes, phi_weights = gauss_legendre_panels(phi_edges, GAUSS_ORDER)
        phi_cell = np.repeat(np.arange(n_phi), GAUSS_ORDER)
        for i, (lo, hi) in enumerate(zip(t_edges[:-1], t_edges[1:])):
            t, wt = gauss_legendre_panels(self._t_edges(lo, hi))
            pts.append(self._to_world(t[:, None], phi_nodes[None, :]).reshape(-1, 3))
            wts.append((wt[:, None] * phi_weights[None, :]).ravel())
            ids.append(np.broadcast_to(i * n_phi + phi_cell[None, :], (len(t), len(phi_nodes))).ravel())

        def assign(x):
            t, phi = self._polar(x)
            it = bin_index(t_edges, t)
            ip = np.minimum((phi / (2.0 * np.pi) * n_phi).astype(np.int64), n_phi - 1)
            return it * n_phi + ip

        return Cells((len(t_edges) - 1) * n_phi, np.concatenate(pts), np.concatenate(wts),
                     np.concatenate(ids), assign)

    def contains(self, x: np.ndarray, tolerance: float = 1e-5) -> np.ndarray:
        return np.abs(np.linalg.norm(np.asarray(x, np.float64), axis=-1) - 1.0) <= tolerance


# ---------------------------------------------------------------------------------------------
# Flat domains: intervals, boxes, the disk, triangles and finite sets (issue 3).
# ---------------------------------------------------------------------------------------------


def _interval_panel_edges(low: float, high: float, breaks, graded: bool) -> np.ndarray:
    """Panel edges on [low, high]: split at every break; graded toward each piece's ends if asked."""
    breaks = np.asarray(breaks, dtype=np.float64).ravel()
    inner = breaks[(breaks > low) & (breaks < high)]
    pieces = np.unique(np.concatenate([[low, high], inner]))
    if not graded:
        return pieces
    edges = [graded_edges(lo, hi) for lo, hi in zip(pieces[:-1], pieces[1:])]
    return np.unique(np.concatenate(edges))


def _cell_rule(panel_edges: np.ndarray, cell_edges: np.ndarray, order: int):
    """Gauss–Legendre nodes on the common refinement of panels and cells, with each node's cell."""
    edges = np.unique(np.concatenate([panel_edges, cell_edges[np.isfinite(cell_edges)]]))
    edges = edges[(edges >= panel_edges[0]) & (edges <= panel_edges[-1])]
    nodes, weights = gauss_legendre_panels(edges, order)
    cell = bin_index(cell_edges, nodes)
    return nodes, weights, cell


@dataclasses.dataclass(frozen=True, eq=False)
class Interval:
    """The interval [low, high] (high may be +inf) with the length measure; event_shape ().

    `breaks` are points where the density may jump or peak (bin edges, a truncation point); the
    quadrature splits there. With `graded=True` each piece gets panels graded geometrically toward
    both of its ends (sharp exponentials and power laws); with `graded=False` the pieces are the
    panels themselves (a piecewise-constant density with `order=1` is then integrated exactly by
    the midpoint rule, even with 10^6 bins).

    For high = inf the quadrature stops at `quadrature_high`, which the sampler chooses so that
    the mass beyond it is negligible (below 1e-30); cells still extend to infinity.
    """

    low: float = 0.0
    high: float = 1.0
    breaks: tuple | np.ndarray = ()
    graded: bool = True
    order: int = GAUSS_ORDER
    quadrature_high: float | None = None
    event_shape = ()

    def _finite_high(self) -> float:
        if np.isfinite(self.high):
            return float(self.high)
        if self.quadrature_high is None:
            raise ValueError("Interval: an infinite interval needs 'quadrature_high'")
        return float(self.quadrature_high)

    def panel_edges(self) -> np.ndarray:
        return _interval_panel_edges(float(self.low), self._finite_high(), self.breaks, self.graded)

    def quadrature(self):
        return gauss_legendre_panels(self.panel_edges(), self.order)

    def cells(self, pilot: np.ndarray, n_cells: int) -> Cells:
        edges = quantile_edges(np.asarray(pilot, np.float64).ravel(), n_cells, self.low, self.high)
        nodes, weights, cell = _cell_rule(self.panel_edges(), edges, self.order)

        def assign(x):
            x = np.asarray(x, np.float64)
            index = bin_index(edges, x)
            return np.where(self.contains(x), index, -1)

        return Cells(len(edges) - 1, nodes, weights, cell, assign)

    def contains(self, x: np.ndarray, tolerance: float = 1e-6) -> np.ndarray:
        x = np.asarray(x, np.float64)
        slack = tolerance * max(1.0, abs(self.low), abs(self._finite_high()))
        return np.isfinite(x) & (x >= self.low - slack) & (x <= self.high + slack)


@dataclasses.dataclass(frozen=True, eq=False)
class Box:
    """The axis-aligned box prod_k [low_k, high_k] with the volume measure; event_shape (d,).

    Each axis is an `Interval` (with its own breaks, grading and order); the quadrature is their
    tensor product, and chi-square cells are products of per-axis quantile edges of the pilot.
    """

    axes: tuple  # of Interval

    @classmethod
    def from_bounds(cls, low, high, breaks=None, graded: bool = True, order: int = GAUSS_ORDER):
        low = np.asarray(low, np.float64).ravel()
        high = np.asarray(high, np.float64).ravel()
        breaks = [()] * len(low) if breaks is None else breaks
        return cls(tuple(Interval(float(a), float(b), k, graded, order)
                         for a, b, k in zip(low, high, breaks)))

    @property
    def event_shape(self):
        return (len(self.axes),)

    @staticmethod
    def _tensor(rules):
        grids = np.meshgrid(*[r[0] for r in rules], indexing="ij")
        weights = np.ones(1)
        for r in rules:
            weights = np.multiply.outer(weights, r[1])
        return np.stack([g.ravel() for g in grids], axis=-1), weights.ravel()

    def quadrature(self):
        return self._tensor([axis.quadrature() for axis in self.axes])

    def cells(self, pilot: np.ndarray, n_cells: int) -> Cells:
        pilot = np.asarray(pilot, np.float64)
        d = len(self.axes)
        per_axis = max(int(round(n_cells ** (1.0 / d))), 2)
        edges = [quantile_edges(pilot[:, k], per_axis, axis.low, axis.high) for k, axis in enumerate(self.axes)]
        rules = [_cell_rule(axis.panel_edges(), e, axis.order) for axis, e in zip(self.axes, edges)]
        points, weights = self._tensor([(r[0], r[1]) for r in rules])
        counts = [len(e) - 1 for e in edges]
        cell_grids = np.meshgrid(*[r[2] for r in rules], indexing="ij")
        cell = np.ravel_multi_index([g.ravel() for g in cell_grids], counts)

        def assign(x):
            x = np.asarray(x, np.float64)
            index = [bin_index(e, x[:, k]) for k, e in enumerate(edges)]
            return np.where(self.contains(x), np.ravel_multi_index(index, counts), -1)

        return Cells(int(np.prod(counts)), points, weights, cell, assign)

    def contains(self, x: np.ndarray, tolerance: float = 1e-6) -> np.ndarray:
        x = np.asarray(x, np.float64)
        inside = [axis.contains(x[..., k], tolerance) for k, axis in enumerate(self.axes)]
        return np.logical_and.reduce(inside)


@dataclasses.dataclass(frozen=True)
class Disk:
    """The unit disk with the area measure; event_shape (2,).

    Parametrised by s = r² in [0, 1] and azimuth φ, where dA = ½ ds dφ: uniform points have
    uniform s, so chi-square cells are pilot quantiles of s times equal sectors of φ.
    """

    n_azimuth_quadrature: int = 64
    event_shape = (2,)

    @staticmethod
    def _to_plane(s, phi):
        r = np.sqrt(np.maximum(s, 0.0))
        return np.stack(np.broadcast_arrays(r * np.cos(phi), r * np.sin(phi)), axis=-1)

    @staticmethod
    def _polar(x):
        x = np.asarray(x, np.float64)
        s = np.sum(x * x, axis=-1)
        phi = np.mod(np.arctan2(x[..., 1], x[..., 0]), 2.0 * np.pi)
        return s, phi

    def _rule(self, s_edges, phi_edges):
        s, ws = gauss_legendre_panels(s_edges)
        phi, wphi = gauss_legendre_panels(phi_edges)
        points = self._to_plane(s[:, None], phi[None, :]).reshape(-1, 2)
        return points, 0.5 * np.multiply.outer(ws, wphi).ravel(), s, phi

    def quadrature(self):
        m = self.n_azimuth_quadrature
        s, ws = gauss_legendre_panels(graded_edges(0.0, 1.0, n_geometric=24))
        # Trapezoid in φ: spectrally accurate for smooth periodic integrands.
        phi = (np.arange(m) + 0.5) * (2.0 * np.pi / m)
        points = self._to_plane(s[:, None], phi[None, :]).reshape(-1, 2)
        return points, (0.5 * ws[:, None] * np.full(m, 2.0 * np.pi / m)[None, :]).ravel()

    def cells(self, pilot: np.ndarray, n_cells: int) -> Cells:
        n_phi = 8 if n_cells >= 64 else 2
        n_s = max(n_cells // n_phi, 2)
        s_pilot, _ = self._polar(pilot)
        s_edges = quantile_edges(s_pilot, n_s, 0.0, 1.0)
        phi_edges = np.linspace(0.0, 2.0 * np.pi, n_phi + 1)
        panel_s = np.unique(np.concatenate([graded_edges(0.0, 1.0, n_geometric=24), s_edges]))
        points, weights, s, phi = self._rule(panel_s, phi_edges)
        i_s = bin_index(s_edges, s)
        i_phi = bin_index(phi_edges, phi)
        cell = (i_s[:, None] * n_phi + i_phi[None, :]).ravel()

        def assign(x):
            s, phi = self._polar(x)
            i = bin_index(s_edges, s)
            j = np.minimum((phi / (2.0 * np.pi) * n_phi).astype(np.int64), n_phi - 1)
            return np.where(self.contains(x), i * n_phi + j, -1)

        return Cells((len(s_edges) - 1) * n_phi, points, weights, cell, assign)

    def contains(self, x: np.ndarray, tolerance: float = 1e-6) -> np.ndarray:
        s, _ = self._polar(x)
        return s <= 1.0 + tolerance


@dataclasses.dataclass(frozen=True, eq=False)
class Triangle:
    """The triangle with vertices a, b, c in R² or R³, with the area measure; event_shape (dim,).

    Parametrised by v = 1 - b_a in [0, 1] (distance from a toward the edge bc) and w in [0, 1]
    (position along that edge): x = a + v((1 - w)(b - a) + w(c - a)), dA = 2·area·v dv dw. Uniform
    points have v² and w uniform, so chi-square cells are quantiles of v² times equal steps of w.
    Barycentrics are computed from cross products in float64, which keeps thin triangles (area
    1e-12 of |edge|²) usable.
    """

    a: tuple
    b: tuple
    c: tuple
    order: int = GAUSS_ORDER
    n_panels: int = 8

    @property
    def event_shape(self):
        return (len(self.a),)

    def _vertices(self):
        return (np.asarray(self.a, np.float64), np.asarray(self.b, np.float64), np.asarray(self.c, np.float64))

    def _twice_area_normal(self):
        a, b, c = self._vertices()
        e1, e2 = b - a, c - a
        if len(a) == 2:
            return np.array([0.0, 0.0, e1[0] * e2[1] - e1[1] * e2[0]])
        return np.cross(e1, e2)

    def _from_vw(self, v, w):
        a, b, c = self._vertices()
        v, w = np.broadcast_arrays(v, w)
        bb, bc = v * (1.0 - w), v * w
        return a + bb[..., None] * (b - a) + bc[..., None] * (c - a)

    def barycentric(self, x):
        """(b_b, b_c, distance to the plane) of points x, by cross products in float64."""
        a, b, c = self._vertices()
        x = np.asarray(x, np.float64)
        n = self._twice_area_normal()
        nn = float(n @ n)

        def cross(p, q):
            if p.shape[-1] == 2:
                z = p[..., 0] * q[..., 1] - p[..., 1] * q[..., 0]
                return np.stack([np.zeros_like(z), np.zeros_like(z), z], axis=-1)
            return np.cross(p, q)

        d = x - a
        bb = cross(d, np.broadcast_to(c - a, d.shape)) @ n / nn
        bc = cross(np.broadcast_to(b - a, d.shape), d) @ n / nn
        plane = np.abs(d @ n[: d.shape[-1]]) / np.sqrt(nn) if len(a) == 3 else np.zeros(d.shape[:-1])
        return bb, bc, plane

    def _vw(self, x):
        bb, bc, _ = self.barycentric(x)
        v = bb + bc
        w = np.where(v > 0, bc / np.where(v > 0, v, 1.0), 0.0)
        return v, w

    def _rule(self, v_edges, w_edges):
        v, wv = gauss_legendre_panels(v_edges, self.order)
        w, ww = gauss_legendre_panels(w_edges, self.order)
        twice_area = np.linalg.norm(self._twice_area_normal())
        points = self._from_vw(v[:, None], w[None, :]).reshape(-1, len(self.a))
        weights = (twice_area * (v * wv)[:, None] * ww[None, :]).ravel()
        return points, weights, v, w

    def quadrature(self):
        edges = np.linspace(0.0, 1.0, self.n_panels + 1)
        points, weights, _, _ = self._rule(edges, edges)
        return points, weights

    def cells(self, pilot: np.ndarray, n_cells: int) -> Cells:
        n_w = 4 if n_cells >= 32 else 2
        n_v = max(n_cells // n_w, 2)
        v_pilot, _ = self._vw(pilot)
        # v² is uniform for uniform points; its quantiles give equal-probability rings.
        s_edges = quantile_edges(np.clip(v_pilot, 0.0, 1.0) ** 2, n_v, 0.0, 1.0)
        v_edges = np.sqrt(s_edges)
        w_edges = np.linspace(0.0, 1.0, n_w + 1)
        base = np.linspace(0.0, 1.0, self.n_panels + 1)
        points, weights, v, w = self._rule(np.unique(np.concatenate([base, v_edges])),
                                           np.unique(np.concatenate([base, w_edges])))
        i_v = bin_index(v_edges, v)
        i_w = bin_index(w_edges, w)
        cell = (i_v[:, None] * n_w + i_w[None, :]).ravel()

        def assign(x):
            v, w = self._vw(x)
            i = bin_index(v_edges, v)
            j = bin_index(w_edges, w)
            return np.where(self.contains(x), i * n_w + j, -1)

        return Cells((len(v_edges) - 1) * n_w, points, weights, cell, assign)

    def contains(self, x: np.ndarray, tolerance: float = 1e-5) -> np.ndarray:
        a, b, c = self._vertices()
        size = max(np.max(np.abs(np.stack([a, b, c]))), np.max(np.abs(b - a)), np.max(np.abs(c - a)))
        bb, bc, plane = self.barycentric(x)
        # Tolerances in distance units: a barycentric coordinate times 2·area / |edge| is a distance.
        twice_area = np.linalg.norm(self._twice_area_normal())
        slack = tolerance * size
        to_b = slack * np.linalg.norm(c - a) / twice_area
        to_c = slack * np.linalg.norm(b - a) / twice_area
        to_a = slack * np.linalg.norm(c - b) / twice_area
        return (bb >= -to_b) & (bc >= -to_c) & (bb + bc <= 1.0 + to_a) & (plane <= slack)


@dataclasses.dataclass(frozen=True)
class DiscreteSet:
    """The outcomes {0, ..., size - 1} with the counting measure; event_shape ().

    The quadrature is the sum over all outcomes. Chi-square cells are runs of consecutive outcomes
    of roughly equal pilot probability (every outcome its own cell when size <= n_cells), so tables
    of 10^6 entries are tested in about n_cells pooled cells.
    """

    size: int
    event_shape = ()

    def quadrature(self):
        return np.arange(self.size, dtype=np.int64), np.ones(self.size)

    def cells(self, pilot: np.ndarray, n_cells: int) -> Cells:
        if self.size <= n_cells:
            starts = np.arange(self.size)
        else:
            probs = np.arange(1, n_cells) / n_cells
            interior = np.quantile(np.asarray(pilot).ravel(), probs, method="inverted_cdf")
            starts = np.unique(np.concatenate([[0], np.clip(interior.astype(np.int64), 0, self.size - 1)]))
        points = np.arange(self.size, dtype=np.int64)
        cell = np.searchsorted(starts, points, side="right") - 1

        def assign(x):
            x = np.asarray(x)
            index = np.searchsorted(starts, np.clip(x, 0, self.size - 1), side="right") - 1
            return np.where(self.contains(x), index, -1)

        return Cells(len(starts), points, np.ones(self.size), cell, assign)

    def contains(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x)
        return (x >= 0) & (x < self.size) & (x == np.floor(x))
