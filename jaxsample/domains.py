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
        t_edges = quantile_edges(t_pilot, n_t, 0.0, 2.0)
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
            it = np.clip(np.searchsorted(t_edges, t, side="right") - 1, 0, len(t_edges) - 2)
            ip = np.minimum((phi / (2.0 * np.pi) * n_phi).astype(np.int64), n_phi - 1)
            return it * n_phi + ip

        return Cells((len(t_edges) - 1) * n_phi, np.concatenate(pts), np.concatenate(wts),
                     np.concatenate(ids), assign)

    def contains(self, x: np.ndarray, tolerance: float = 1e-5) -> np.ndarray:
        return np.abs(np.linalg.norm(np.asarray(x, np.float64), axis=-1) - 1.0) <= tolerance
