"""The domain of the microfacet samplers: directions with the solid-angle measure, described by a chart
of the sphere in which their densities are smooth, for the checks' quadrature and chi-square cells.

The plain `Directions` rule (polar about one axis, 64 azimuths) cannot integrate these lobes: an
anisotropic one (alpha_x / alpha_y = 1e3) is a sheet 1e-3 wide in azimuth, and the visible normals
of a grazing wo are cut off by the plane wo·m = 0, a kink through the lobe's peak. In the chart the
stretch is undone and the cut is a coordinate line:

- s = (s_x, s_y): the unit-roughness slopes, m = normalize(alpha_x s_x, alpha_y s_y, 1), over
  the plane; dω_m = cos³θ_m alpha_x alpha_y ds. Every density here is a smooth function of s times
  the unit-roughness slope density.
- polar coordinates of s about the origin (the lobe's peak), ρ = tan(πq/2) with q in [0, 1): the
  heavy GGX tail becomes a bounded integrand in q, and q -> 1 is the horizon.
- visible normals: wo·m > 0 is the half plane s·e₁ < c with e₁ = -(alpha_x wo_x, alpha_y wo_y)/ν
  and c = wo_z / ν, ν = |(alpha_x wo_x, alpha_y wo_y)|; along the ray at angle ψ from e₁ it ends at
  ρ* = c / cos ψ (|ψ| < π/2), and v = q / q*(ψ) in [0, 1] makes the cut the edge v = 1. The panels in
  ψ are graded toward ψ = ±π/2, where ρ* runs off to infinity (over an angle ~c: 1e-7 at grazing).
- reflected directions: the same chart pushed forward by wi = 2 (wo·m) m - wo, dω_i = 4 (wo·m) dω_m.

Imported on first use of the checks (`quadrature`, `cells`), never by the samplers' import; it
builds its rules from the panels and `Cells` of `jaxsample.samplers.domain`.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .domain import Cells, bin_index, gauss_legendre_panels, graded_edges, quantile_edges

_ORDER = 8  # Gauss–Legendre nodes per panel
_V_TOLERANCE = 1e-3  # a sample this far past the cut (v > 1) in float32 rounding still counts inside


@dataclasses.dataclass(frozen=True)
class MicrofacetDirections:
    """The unit sphere (solid angle) for a microfacet lobe: normals of D cos θ (`wo` None), visible
    normals of `wo` (unit, wo_z >= 0), or their reflections (`reflect`; the points are `sign` · wi,
    sign = -1 for a wo given below the horizon). `axis`: the macro normal (an `Oriented` lobe)."""

    alpha_x: float
    alpha_y: float
    wo: tuple | None = None
    reflect: bool = False
    sign: float = 1.0
    axis: tuple = (0.0, 0.0, 1.0)
    n_uniform_psi: int = 8
    n_graded_psi: int = 30
    n_uniform_v: int = 24
    event_shape = (3,)
    measure = "solid angle"

    # ---- the chart ------------------------------------------------------------------------------
    def _cut(self):
        """(e₁, e₂, c): the frame of the slope plane and the cut's distance (inf: no cut)."""
        if self.wo is None:
            return np.array([1.0, 0.0]), np.array([0.0, 1.0]), np.inf
        wo = np.asarray(self.wo, np.float64)
        n = np.array([self.alpha_x * wo[0], self.alpha_y * wo[1]])
        nu = float(np.hypot(*n))
        if nu == 0.0:
            return np.array([1.0, 0.0]), np.array([0.0, 1.0]), np.inf
        e1 = -n / nu
        return e1, np.array([-e1[1], e1[0]]), float(wo[2]) / nu

    def _q_star(self, psi, c):
        cos_psi = np.cos(psi)
        with np.errstate(divide="ignore", invalid="ignore"):
            rho_star = np.where(cos_psi > 0, c / np.where(cos_psi > 0, cos_psi, 1.0), np.inf)
        return np.arctan(rho_star) * (2.0 / np.pi)

    def _frame(self):
        axis = np.asarray(self.axis, np.float64)
        axis = axis / np.linalg.norm(axis)
        x, y, z = axis
        s = np.copysign(1.0, z)
        a = -1.0 / (s + z)
        b = x * y * a
        return np.array([1.0 + s * x * x * a, s * b, -s * x]), np.array([b, s + y * y * a, -y]), axis

    def _to_world(self, local):
        if tuple(self.axis) == (0.0, 0.0, 1.0):
            return local
        t, b, n = self._frame()
        return local[..., 0:1] * t + local[..., 1:2] * b + local[..., 2:3] * n

    def _to_local(self, x):
        if tuple(self.axis) == (0.0, 0.0, 1.0):
            return x
        t, b, n = self._frame()
        return np.stack([x @ t, x @ b, x @ n], axis=-1)

    def _chart(self, psi, v):
        """(points, dω / (dψ dv)) at chart coordinates (broadcast)."""
        e1, e2, c = self._cut()
        psi, v = np.broadcast_arrays(np.asarray(psi, np.float64), np.asarray(v, np.float64))
        q_star = self._q_star(psi, c)
        q = v * q_star
        rho = np.tan(0.5 * np.pi * q)
        s = rho[..., None] * (np.cos(psi)[..., None] * e1 + np.sin(psi)[..., None] * e2)
        slopes = np.stack([self.alpha_x * s[..., 0], self.alpha_y * s[..., 1], np.ones_like(rho)], axis=-1)
        m = slopes / np.linalg.norm(slopes, axis=-1, keepdims=True)
        jacobian = m[..., 2] ** 3 * self.alpha_x * self.alpha_y * rho * (0.5 * np.pi) * (1.0 + rho * rho) * q_star
        if self.reflect:
            wo = np.asarray(self.wo, np.float64)
            cosine = m @ wo
            points = self.sign * (2.0 * cosine[..., None] * m - wo)
            jacobian = jacobian * 4.0 * cosine
        else:
            points = m
        return self._to_world(points), jacobian

    def _coordinates(self, x):
        """(ψ, v, inside) of points: the chart's inverse; inside False off the support."""
        x = self._to_local(np.asarray(x, np.float64))
        if self.reflect:
            wo = np.asarray(self.wo, np.float64)
            half = wo + self.sign * x
            norm = np.linalg.norm(half, axis=-1, keepdims=True)
            m = half / np.where(norm > 0, norm, 1.0)
            inside = norm[..., 0] > 0
        else:
            m = x
            inside = np.ones(x.shape[:-1], bool)
        inside = inside & (m[..., 2] > 0)
        mz = np.where(inside, m[..., 2], 1.0)
        s = np.stack([m[..., 0] / (self.alpha_x * mz), m[..., 1] / (self.alpha_y * mz)], axis=-1)
        e1, e2, c = self._cut()
        along, across = s @ e1, s @ e2
        psi = np.arctan2(across, along)
        q = np.arctan(np.hypot(along, across)) * (2.0 / np.pi)
        q_star = self._q_star(psi, c)
        v = q / np.where(q_star > 0, q_star, 1.0)
        inside = inside & (v <= 1.0 + _V_TOLERANCE)
        return psi, np.clip(v, 0.0, 1.0), inside

    # ---- panels ---------------------------------------------------------------------------------
    def _psi_edges(self):
        _, _, c = self._cut()
        if not np.isfinite(c):
            return np.linspace(-np.pi, np.pi, 2 * self.n_uniform_psi + 1)
        pieces = [(-np.pi, -0.5 * np.pi), (-0.5 * np.pi, 0.5 * np.pi), (0.5 * np.pi, np.pi)]
        return np.unique(np.concatenate([graded_edges(a, b, "both", self.n_graded_psi, self.n_uniform_psi, 1e-15)
                                         for a, b in pieces]))

    def _v_edges(self):
        return np.linspace(0.0, 1.0, self.n_uniform_v + 1)

    @staticmethod
    def _nodes(global_edges, cell_edges):
        """Gauss–Legendre nodes of every cell [cell_edges[i], cell_edges[i+1]], each split at the
        global panel edges inside it: (nodes, weights, cell index)."""
        nodes, weights, cells = [], [], []
        for i, (a, b) in enumerate(zip(cell_edges[:-1], cell_edges[1:])):
            inner = global_edges[(global_edges > a) & (global_edges < b)]
            x, w = gauss_legendre_panels(np.concatenate([[a], inner, [b]]), _ORDER)
            nodes.append(x)
            weights.append(w)
            cells.append(np.full(len(x), i))
        return np.concatenate(nodes), np.concatenate(weights), np.concatenate(cells)

    # ---- what the checks call -------------------------------------------------------------------
    def quadrature(self):
        psi_edges, v_edges = self._psi_edges(), self._v_edges()
        psi, w_psi, _ = self._nodes(psi_edges, psi_edges[[0, -1]])
        v, w_v, _ = self._nodes(v_edges, v_edges[[0, -1]])
        points, jacobian = self._chart(psi[:, None], v[None, :])
        return points.reshape(-1, 3), (w_psi[:, None] * w_v[None, :] * jacobian).ravel()

    def cells(self, pilot, n_cells):
        psi_p, v_p, inside = self._coordinates(pilot)
        psi_p, v_p = psi_p[inside], v_p[inside]
        n_psi = 8 if n_cells >= 32 else 2
        n_v = max(n_cells // n_psi, 2)
        _, _, c = self._cut()
        breaks = [-0.5 * np.pi, 0.5 * np.pi] if np.isfinite(c) else []
        psi_cells = np.unique(np.concatenate([quantile_edges(psi_p, n_psi, -np.pi, np.pi), breaks]))
        v_cells = quantile_edges(v_p, n_v, 0.0, 1.0)
        psi, w_psi, i_psi = self._nodes(self._psi_edges(), psi_cells)
        v, w_v, i_v = self._nodes(self._v_edges(), v_cells)
        points, jacobian = self._chart(psi[:, None], v[None, :])
        weights = w_psi[:, None] * w_v[None, :] * jacobian
        count_v = len(v_cells) - 1
        ids = i_psi[:, None] * count_v + i_v[None, :]

        def assign(x):
            psi_x, v_x, inside_x = self._coordinates(x)
            index = bin_index(psi_cells, psi_x) * count_v + bin_index(v_cells, v_x)
            return np.where(inside_x, index, -1)

        return Cells((len(psi_cells) - 1) * count_v, points.reshape(-1, 3), weights.ravel(), ids.ravel(), assign)

    def contains(self, x, tolerance: float = 1e-5):
        return np.abs(np.linalg.norm(np.asarray(x, np.float64), axis=-1) - 1.0) <= tolerance
