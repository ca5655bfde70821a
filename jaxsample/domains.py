"""Domains and the geometry the checks compute on them: quadrature rules, chi-square cells, membership.

A sampler's `domain()` returns a plain description of the set its density lives on and the measure
the density is over (`Directions`, `Interval`, `Box`, `Disk`, `Triangle`, `DiscreteSet`, defined in
`jaxsample.samplers.domain` and exported here, with the pieces every rule is built from:
`gauss_legendre_panels`, `graded_edges`, `quantile_edges`, `bin_index` and `Cells`). This module
does the numerical work on a domain, in float64 NumPy. The checks (`jaxsample.testing`) import it
and the samplers do not, so importing a sampler never loads it:

- `quadrature(domain)` -> (points, weights): a deterministic rule with sum_i w_i g(x_i) ≈ ∫ g dμ over
  the whole domain, accurate (to ~1e-10) for densities that are smooth between the domain's
  `breaks` even when they are sharply peaked (lobes of width 1e-7) — it uses panels that are
  geometrically graded toward each break and toward the domain's "centre" (the pole for directions).
- `cells(domain, pilot, n_cells)` -> `Cells`: a partition of the domain into about `n_cells` cells of
  roughly equal probability, chosen from *pilot* samples drawn independently of the samples under
  test (so the chi-square statistic keeps its distribution), with a quadrature rule per cell for
  the expected counts and an `assign` function for observed counts.
- `contains(domain, x)`: whether points lie in the domain (to float tolerance).

A domain class of a user's own (not one of the six) is used through its own methods of the same
names: `domain.quadrature()`, `domain.cells(pilot, n_cells)`, `domain.contains(x)` (the samplers'
spherical polygons and microfacet directions are such classes).
"""

from __future__ import annotations

import functools

import numpy as np

from .samplers.domain import (GAUSS_ORDER, Box, Cells, Directions, DiscreteSet, Disk, Interval, Triangle, bin_index,
                               gauss_legendre_panels, graded_edges, quantile_edges)


def _split_at_breaks(a: float, b: float, breaks) -> np.ndarray:
    inner = [float(t) for t in np.ravel(breaks) if a < t < b]
    return np.array(sorted({a, b, *inner}))


@functools.singledispatch
def quadrature(domain) -> tuple[np.ndarray, np.ndarray]:
    """(points, weights) of a float64 rule for ∫ g dμ over the whole domain."""
    return domain.quadrature()


@functools.singledispatch
def cells(domain, pilot: np.ndarray, n_cells: int) -> Cells:
    """About `n_cells` cells of roughly equal pilot probability, with a quadrature rule per cell."""
    return domain.cells(pilot, n_cells)


@functools.singledispatch
def contains(domain, x: np.ndarray, *tolerance) -> np.ndarray:
    """Whether each point of `x` lies in the domain, to float tolerance."""
    return domain.contains(x, *tolerance)


# ---------------------------------------------------------------------------------------------
# Directions: t = 1 - cos θ about the axis and the azimuth φ, dω = dt dφ.
# ---------------------------------------------------------------------------------------------


def _frame_from_axis(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    # The Duff et al. basis in float64 NumPy, for the checks only.
    nx, ny, nz = axis
    s = np.copysign(1.0, nz)
    a = -1.0 / (s + nz)
    b = nx * ny * a
    return np.array([1.0 + s * nx * nx * a, s * b, -s * nx]), np.array([b, s + ny * ny * a, -ny])


def _direction_axes(domain: Directions):
    axis = np.asarray(domain.axis, dtype=np.float64)
    axis = axis / np.linalg.norm(axis)
    tangent, bitangent = _frame_from_axis(axis)
    return tangent, bitangent, axis


def _direction_from_polar(domain: Directions, t: np.ndarray, phi: np.ndarray) -> np.ndarray:
    tangent, bitangent, axis = _direction_axes(domain)
    t, phi = np.broadcast_arrays(t, phi)
    sin_theta = np.sqrt(np.maximum(t * (2.0 - t), 0.0))
    local = np.stack([sin_theta * np.cos(phi), sin_theta * np.sin(phi), 1.0 - t], axis=-1)
    return local[..., 0:1] * tangent + local[..., 1:2] * bitangent + local[..., 2:3] * axis


def _polar_of_direction(domain: Directions, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    tangent, bitangent, axis = _direction_axes(domain)
    x = np.asarray(x, dtype=np.float64)
    # 1 - cos θ = |x - axis|² / 2 for unit x: no cancellation near the axis.
    t = 0.5 * np.sum((x - axis) ** 2, axis=-1)
    phi = np.mod(np.arctan2(x @ bitangent, x @ tangent), 2.0 * np.pi)
    return t, phi


def _t_edges(domain: Directions, a: float, b: float) -> np.ndarray:
    pieces = _split_at_breaks(a, b, domain.breaks)
    edges = [graded_edges(lo, hi) for lo, hi in zip(pieces[:-1], pieces[1:])]
    return np.unique(np.concatenate(edges))


@quadrature.register
def _(domain: Directions):
    t, wt = gauss_legendre_panels(_t_edges(domain, 0.0, 2.0))
    m = domain.n_azimuth_quadrature
    # The trapezoid rule is spectrally accurate for smooth periodic functions of φ.
    phi = (np.arange(m) + 0.5) * (2.0 * np.pi / m)
    wphi = np.full(m, 2.0 * np.pi / m)
    points = _direction_from_polar(domain, t[:, None], phi[None, :]).reshape(-1, 3)
    weights = (wt[:, None] * wphi[None, :]).ravel()
    return points, weights


@cells.register
def _(domain: Directions, pilot, n_cells):
    n_phi = 4 if n_cells >= 32 else 1
    n_t = max(n_cells // n_phi, 2)
    t_pilot, _ = _polar_of_direction(domain, pilot)
    # Breaks are cell edges too, so that a region of zero density (below the horizon, beyond
    # a cone's edge) is a cell of its own and any sample landing there fails the test.
    t_edges = np.unique(np.concatenate([quantile_edges(t_pilot, n_t, 0.0, 2.0),
                                        _split_at_breaks(0.0, 2.0, domain.breaks)]))
    phi_edges = np.linspace(0.0, 2.0 * np.pi, n_phi + 1)
    pts, wts, ids = [], [], []
    phi_nodes, phi_weights = gauss_legendre_panels(phi_edges, GAUSS_ORDER)
    phi_cell = np.repeat(np.arange(n_phi), GAUSS_ORDER)
    for i, (lo, hi) in enumerate(zip(t_edges[:-1], t_edges[1:])):
        t, wt = gauss_legendre_panels(_t_edges(domain, lo, hi))
        pts.append(_direction_from_polar(domain, t[:, None], phi_nodes[None, :]).reshape(-1, 3))
        wts.append((wt[:, None] * phi_weights[None, :]).ravel())
        ids.append(np.broadcast_to(i * n_phi + phi_cell[None, :], (len(t), len(phi_nodes))).ravel())

    def assign(x):
        t, phi = _polar_of_direction(domain, x)
        it = bin_index(t_edges, t)
        ip = np.minimum((phi / (2.0 * np.pi) * n_phi).astype(np.int64), n_phi - 1)
        return it * n_phi + ip

    return Cells((len(t_edges) - 1) * n_phi, np.concatenate(pts), np.concatenate(wts), np.concatenate(ids), assign)


@contains.register
def _(domain: Directions, x, tolerance: float = 1e-5):
    return np.abs(np.linalg.norm(np.asarray(x, np.float64), axis=-1) - 1.0) <= tolerance


# ---------------------------------------------------------------------------------------------
# Intervals and boxes (products of intervals)
# ---------------------------------------------------------------------------------------------


def _finite_high(interval: Interval) -> float:
    if np.isfinite(interval.high):
        return float(interval.high)
    if interval.quadrature_high is None:
        raise ValueError("Interval: an infinite interval needs 'quadrature_high'")
    return float(interval.quadrature_high)


def _finite_low(interval: Interval) -> float:
    if np.isfinite(interval.low):
        return float(interval.low)
    if interval.quadrature_low is None:
        raise ValueError("Interval: an interval unbounded below needs 'quadrature_low'")
    return float(interval.quadrature_low)


def panel_edges(interval: Interval) -> np.ndarray:
    """Quadrature panel edges on [low, high]: split at every break; graded toward each piece's
    ends if the interval asks for it."""
    low, high = _finite_low(interval), _finite_high(interval)
    breaks = np.asarray(interval.breaks, dtype=np.float64).ravel()
    pieces = np.unique(np.concatenate([[low, high], breaks[(breaks > low) & (breaks < high)]]))
    if not interval.graded:
        return pieces
    return np.unique(np.concatenate([graded_edges(lo, hi) for lo, hi in zip(pieces[:-1], pieces[1:])]))


def _cell_rule(panel_edges: np.ndarray, cell_edges: np.ndarray, order: int):
    """Gauss–Legendre nodes on the common refinement of panels and cells, with each node's cell."""
    edges = np.unique(np.concatenate([panel_edges, cell_edges[np.isfinite(cell_edges)]]))
    edges = edges[(edges >= panel_edges[0]) & (edges <= panel_edges[-1])]
    nodes, weights = gauss_legendre_panels(edges, order)
    cell = bin_index(cell_edges, nodes)
    return nodes, weights, cell


@quadrature.register
def _(domain: Interval):
    return gauss_legendre_panels(panel_edges(domain), domain.order)


@cells.register
def _(domain: Interval, pilot, n_cells):
    edges = quantile_edges(np.asarray(pilot, np.float64).ravel(), n_cells, domain.low, domain.high)
    nodes, weights, cell = _cell_rule(panel_edges(domain), edges, domain.order)

    def assign(x):
        x = np.asarray(x, np.float64)
        return np.where(contains(domain, x), bin_index(edges, x), -1)

    return Cells(len(edges) - 1, nodes, weights, cell, assign)


@contains.register
def _(domain: Interval, x, tolerance: float = 1e-6):
    x = np.asarray(x, np.float64)
    slack = tolerance * max(1.0, abs(_finite_low(domain)), abs(_finite_high(domain)))
    return np.isfinite(x) & (x >= domain.low - slack) & (x <= domain.high + slack)


def _tensor(rules):
    grids = np.meshgrid(*[r[0] for r in rules], indexing="ij")
    weights = np.ones(1)
    for r in rules:
        weights = np.multiply.outer(weights, r[1])
    return np.stack([g.ravel() for g in grids], axis=-1), weights.ravel()


@quadrature.register
def _(domain: Box):
    return _tensor([quadrature(axis) for axis in domain.axes])


@cells.register
def _(domain: Box, pilot, n_cells):
    # Products of per-axis quantile edges of the pilot.
    pilot = np.asarray(pilot, np.float64)
    per_axis = max(int(round(n_cells ** (1.0 / len(domain.axes)))), 2)
    edges = [quantile_edges(pilot[:, k], per_axis, axis.low, axis.high) for k, axis in enumerate(domain.axes)]
    rules = [_cell_rule(panel_edges(axis), e, axis.order) for axis, e in zip(domain.axes, edges)]
    points, weights = _tensor([(r[0], r[1]) for r in rules])
    counts = [len(e) - 1 for e in edges]
    cell_grids = np.meshgrid(*[r[2] for r in rules], indexing="ij")
    cell = np.ravel_multi_index([g.ravel() for g in cell_grids], counts)

    def assign(x):
        x = np.asarray(x, np.float64)
        index = [bin_index(e, x[:, k]) for k, e in enumerate(edges)]
        return np.where(contains(domain, x), np.ravel_multi_index(index, counts), -1)

    return Cells(int(np.prod(counts)), points, weights, cell, assign)


@contains.register
def _(domain: Box, x, tolerance: float = 1e-6):
    x = np.asarray(x, np.float64)
    return np.logical_and.reduce([contains(axis, x[..., k], tolerance) for k, axis in enumerate(domain.axes)])


# ---------------------------------------------------------------------------------------------
# The disk: s = r² and the azimuth φ, dA = ½ ds dφ (uniform points have uniform s).
# ---------------------------------------------------------------------------------------------


def _disk_point(s, phi):
    r = np.sqrt(np.maximum(s, 0.0))
    return np.stack(np.broadcast_arrays(r * np.cos(phi), r * np.sin(phi)), axis=-1)


def _disk_polar(x):
    x = np.asarray(x, np.float64)
    s = np.sum(x * x, axis=-1)
    phi = np.mod(np.arctan2(x[..., 1], x[..., 0]), 2.0 * np.pi)
    return s, phi


@quadrature.register
def _(domain: Disk):
    m = domain.n_azimuth_quadrature
    s, ws = gauss_legendre_panels(graded_edges(0.0, 1.0, n_geometric=24))
    # Trapezoid in φ: spectrally accurate for smooth periodic integrands.
    phi = (np.arange(m) + 0.5) * (2.0 * np.pi / m)
    points = _disk_point(s[:, None], phi[None, :]).reshape(-1, 2)
    return points, (0.5 * ws[:, None] * np.full(m, 2.0 * np.pi / m)[None, :]).ravel()


@cells.register
def _(domain: Disk, pilot, n_cells):
    # Pilot quantiles of s times equal sectors of φ.
    n_phi = 8 if n_cells >= 64 else 2
    n_s = max(n_cells // n_phi, 2)
    s_edges = quantile_edges(_disk_polar(pilot)[0], n_s, 0.0, 1.0)
    phi_edges = np.linspace(0.0, 2.0 * np.pi, n_phi + 1)
    s, ws = gauss_legendre_panels(np.unique(np.concatenate([graded_edges(0.0, 1.0, n_geometric=24), s_edges])))
    phi, wphi = gauss_legendre_panels(phi_edges)
    points = _disk_point(s[:, None], phi[None, :]).reshape(-1, 2)
    weights = 0.5 * np.multiply.outer(ws, wphi).ravel()
    cell = (bin_index(s_edges, s)[:, None] * n_phi + bin_index(phi_edges, phi)[None, :]).ravel()

    def assign(x):
        s, phi = _disk_polar(x)
        j = np.minimum((phi / (2.0 * np.pi) * n_phi).astype(np.int64), n_phi - 1)
        return np.where(contains(domain, x), bin_index(s_edges, s) * n_phi + j, -1)

    return Cells((len(s_edges) - 1) * n_phi, points, weights, cell, assign)


@contains.register
def _(domain: Disk, x, tolerance: float = 1e-6):
    return _disk_polar(x)[0] <= 1.0 + tolerance


# ---------------------------------------------------------------------------------------------
# Triangles: v (from a toward bc) and w (along bc), dA = 2·area·v dv dw. Uniform points have v²
# and w uniform. Barycentrics come from cross products in float64, which keeps thin triangles
# (area 1e-12 of |edge|²) usable.
# ---------------------------------------------------------------------------------------------


def _vertices(domain: Triangle):
    return tuple(np.asarray(v, np.float64) for v in (domain.a, domain.b, domain.c))


def _twice_area_normal(domain: Triangle):
    a, b, c = _vertices(domain)
    e1, e2 = b - a, c - a
    if len(a) == 2:
        return np.array([0.0, 0.0, e1[0] * e2[1] - e1[1] * e2[0]])
    return np.cross(e1, e2)


def _triangle_point(domain: Triangle, v, w):
    a, b, c = _vertices(domain)
    v, w = np.broadcast_arrays(v, w)
    return a + (v * (1.0 - w))[..., None] * (b - a) + (v * w)[..., None] * (c - a)


def barycentric(domain: Triangle, x):
    """(b_b, b_c, distance to the plane) of points x, by cross products in float64."""
    a, b, c = _vertices(domain)
    x = np.asarray(x, np.float64)
    n = _twice_area_normal(domain)
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


def _triangle_vw(domain: Triangle, x):
    bb, bc, _ = barycentric(domain, x)
    v = bb + bc
    w = np.where(v > 0, bc / np.where(v > 0, v, 1.0), 0.0)
    return v, w


def _triangle_rule(domain: Triangle, v_edges, w_edges):
    v, wv = gauss_legendre_panels(v_edges, domain.order)
    w, ww = gauss_legendre_panels(w_edges, domain.order)
    twice_area = np.linalg.norm(_twice_area_normal(domain))
    points = _triangle_point(domain, v[:, None], w[None, :]).reshape(-1, len(domain.a))
    weights = (twice_area * (v * wv)[:, None] * ww[None, :]).ravel()
    return points, weights, v, w


@quadrature.register
def _(domain: Triangle):
    edges = np.linspace(0.0, 1.0, domain.n_panels + 1)
    points, weights, _, _ = _triangle_rule(domain, edges, edges)
    return points, weights


@cells.register
def _(domain: Triangle, pilot, n_cells):
    # Quantiles of v² (equal-probability rings for uniform points) times equal steps of w.
    n_w = 4 if n_cells >= 32 else 2
    n_v = max(n_cells // n_w, 2)
    v_pilot, _ = _triangle_vw(domain, pilot)
    v_edges = np.sqrt(quantile_edges(np.clip(v_pilot, 0.0, 1.0) ** 2, n_v, 0.0, 1.0))
    w_edges = np.linspace(0.0, 1.0, n_w + 1)
    base = np.linspace(0.0, 1.0, domain.n_panels + 1)
    points, weights, v, w = _triangle_rule(domain, np.unique(np.concatenate([base, v_edges])),
                                           np.unique(np.concatenate([base, w_edges])))
    cell = (bin_index(v_edges, v)[:, None] * n_w + bin_index(w_edges, w)[None, :]).ravel()

    def assign(x):
        v, w = _triangle_vw(domain, x)
        return np.where(contains(domain, x), bin_index(v_edges, v) * n_w + bin_index(w_edges, w), -1)

    return Cells((len(v_edges) - 1) * n_w, points, weights, cell, assign)


@contains.register
def _(domain: Triangle, x, tolerance: float = 1e-5):
    a, b, c = _vertices(domain)
    size = max(np.max(np.abs(np.stack([a, b, c]))), np.max(np.abs(b - a)), np.max(np.abs(c - a)))
    bb, bc, plane = barycentric(domain, x)
    # Tolerances in distance units: a barycentric coordinate times 2·area / |edge| is a distance.
    twice_area = np.linalg.norm(_twice_area_normal(domain))
    slack = tolerance * size
    to_b = slack * np.linalg.norm(c - a) / twice_area
    to_c = slack * np.linalg.norm(b - a) / twice_area
    to_a = slack * np.linalg.norm(c - b) / twice_area
    return (bb >= -to_b) & (bc >= -to_c) & (bb + bc <= 1.0 + to_a) & (plane <= slack)


# ---------------------------------------------------------------------------------------------
# Finite sets: the quadrature is the sum over all outcomes; chi-square cells are runs of
# consecutive outcomes of roughly equal pilot probability (every outcome its own cell when
# size <= n_cells), so tables of 10^6 entries are tested in about n_cells pooled cells.
# ---------------------------------------------------------------------------------------------


@quadrature.register
def _(domain: DiscreteSet):
    return np.arange(domain.size, dtype=np.int64), np.ones(domain.size)


@cells.register
def _(domain: DiscreteSet, pilot, n_cells):
    if domain.size <= n_cells:
        starts = np.arange(domain.size)
    else:
        probs = np.arange(1, n_cells) / n_cells
        interior = np.quantile(np.asarray(pilot).ravel(), probs, method="inverted_cdf")
        starts = np.unique(np.concatenate([[0], np.clip(interior.astype(np.int64), 0, domain.size - 1)]))
    points = np.arange(domain.size, dtype=np.int64)
    cell = np.searchsorted(starts, points, side="right") - 1

    def assign(x):
        x = np.asarray(x)
        index = np.searchsorted(starts, np.clip(x, 0, domain.size - 1), side="right") - 1
        return np.where(contains(domain, x), index, -1)

    return Cells(len(starts), points, np.ones(domain.size), cell, assign)


@contains.register
def _(domain: DiscreteSet, x):
    x = np.asarray(x)
    return (x >= 0) & (x < domain.size) & (x == np.floor(x))


__all__ = [
    "Directions", "Interval", "Box", "Disk", "Triangle", "DiscreteSet", "quadrature", "cells", "contains",
    "Cells", "GAUSS_ORDER", "bin_index", "gauss_legendre_panels", "graded_edges", "quantile_edges",
    "panel_edges", "barycentric",
]
