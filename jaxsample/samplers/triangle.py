"""Uniform points on a triangle in R² or R³: p = 1/area over area."""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from .base import Sampler, point_method
from .._core.params import concrete_value
from .._core.pytree import parameter
from .domain import Triangle
from .._core.numerics import safe_div, safe_sqrt

# A triangle whose doubled area is below this many float64 epsilons times its longest squared edge
# is zero to within the rounding of the cross product itself: degenerate.
_DEGENERATE_ULPS = 64.0


def _cross(p, q):
    """p × q for 3-vectors; the scalar z-component for 2-vectors."""
    if p.shape[-1] == 2:
        return p[..., 0] * q[..., 1] - p[..., 1] * q[..., 0]
    return jnp.cross(p, q)


def _along(v, unit_normal, dim):
    """Component of a cross product along the unit normal (in 2D the normal is the sign ±1)."""
    return v * unit_normal if dim == 2 else jnp.sum(v * unit_normal, axis=-1)


class UniformTriangle(Sampler):
    """Uniform on the triangle (a, b, c) in R² or R³: p = 1/area over area, 0 off the triangle.

    Warp by marginal and conditional (Turk, *Graphics Gems* 1990; Pharr et al., *PBR* 3rd ed.
    §13.6.5): write x = a + v((1 - w)(b - a) + w(c - a)) with v in [0, 1] the distance from a toward
    the opposite edge and w in [0, 1] the position along it. The segment at v has length ∝ v, so the
    marginal of v is 2v with CDF v², giving v = sqrt(u₀); given v, w is uniform, w = u₁. In
    barycentrics, b_b = sqrt(u₀)(1 - u₁), b_c = sqrt(u₀) u₁. Inverse: u₀ = (b_b + b_c)²,
    u₁ = b_c/(b_b + b_c), with barycentrics from cross products (edge functions).

    Degenerate means zero area to within the rounding of the float64 cross product (doubled area
    below 64 ε |longest edge|², about 1.4e-14): such concrete vertices raise ValueError, as do
    non-finite vertices or shapes other than three equal (2,) or (3,). A thin triangle, area 1e-12
    of |edge|², is not degenerate and works in float64 (in float32 it is a segment to rounding,
    and only `warp_with_pdf`'s constant density is meaningful).

    `pdf(x)` accepts points within 64 ε (of the vertices' scale) of the triangle, measured as
    distances, not as barycentric coordinates, so that thin triangles' own samples are inside.
    """

    a: jax.Array = parameter(rank=1, doc="a vertex, (2,) or (3,)")
    b: jax.Array = parameter(rank=1, doc="a vertex")
    c: jax.Array = parameter(rank=1, doc="a vertex")
    uniform_dims: ClassVar[int] = 2
    measure: ClassVar = "area"

    def _parameters_valid(self):
        vertices = jnp.stack(jnp.broadcast_arrays(*(jnp.asarray(v) for v in (self.a, self.b, self.c))))
        return jnp.all(jnp.isfinite(vertices)) & (self._normal()[1] > 0)

    def __post_init__(self):
        values = [concrete_value(v) for v in (self.a, self.b, self.c)]
        if any(v is None for v in values):
            return
        a, b, c = values
        if not (a.shape[-1:] == b.shape[-1:] == c.shape[-1:] and a.shape[-1:] in ((2,), (3,))):
            raise ValueError(f"UniformTriangle: parameters 'a', 'b', 'c' must all have shape (2,) or (3,) "
                             f"(leading dimensions are a batch); got {a.shape}, {b.shape}, {c.shape}")
        if not all(np.all(np.isfinite(v)) for v in values):
            raise ValueError("UniformTriangle: parameters 'a', 'b', 'c' must be finite")
        a, b, c = np.broadcast_arrays(a, b, c)
        e1, e2 = b - a, c - a
        if a.shape[-1] == 2:
            twice_area = np.abs(e1[..., 0] * e2[..., 1] - e1[..., 1] * e2[..., 0])
        else:
            twice_area = np.linalg.norm(np.cross(e1, e2), axis=-1)
        longest = np.maximum(np.maximum(np.sum(e1 * e1, -1), np.sum(e2 * e2, -1)), np.sum((c - b) ** 2, -1))
        if not np.all(twice_area > _DEGENERATE_ULPS * np.finfo(np.float64).eps * longest):
            twice_area = np.min(twice_area)
            raise ValueError(f"UniformTriangle: vertices 'a', 'b', 'c' are degenerate: area {0.5 * twice_area:g} "
                             f"must be > {0.5 * _DEGENERATE_ULPS * np.finfo(np.float64).eps:g} × |longest edge|² "
                             f"(collinear or coincident points)")

    @property
    def event_shape(self):
        return jnp.shape(self.a)[-1:]

    def _normal(self):
        """(unit normal, |n| = 2·area) with n = (b - a) × (c - a); in 2D the unit normal is a sign."""
        n = _cross(jnp.asarray(self.b) - self.a, jnp.asarray(self.c) - self.a)
        if self._dim == 2:
            twice_area = jnp.abs(n)
            return jnp.where(n < 0, -1.0, 1.0).astype(twice_area.dtype), twice_area
        twice_area = jnp.sqrt(jnp.sum(n * n, axis=-1))
        return n / jnp.where(twice_area > 0, twice_area, 1.0), twice_area

    @property
    def _dim(self) -> int:
        return jnp.shape(self.a)[-1]

    @property
    def area(self):
        return 0.5 * self._normal()[1]

    @point_method
    def warp(self, u):
        v = safe_sqrt(u[..., 0])
        weight_b = (v * (1.0 - u[..., 1]))[..., None]
        weight_c = (v * u[..., 1])[..., None]
        return self.a + weight_b * (jnp.asarray(self.b) - self.a) + weight_c * (jnp.asarray(self.c) - self.a)

    @point_method
    def warp_with_pdf(self, u):
        x = self.warp(u)
        return x, jnp.broadcast_to(1.0 / self.area, x.shape[:-1]).astype(x.dtype)

    def _edge_functions(self, x):
        """(E_a, E_b, E_c, distance to the plane, unit normal data): E_k = b_k · 2·area."""
        a, b, c = (jnp.asarray(v) for v in (self.a, self.b, self.c))
        unit_normal, twice_area = self._normal()
        d = x - a
        dim = self._dim
        e_b = _along(_cross(d, c - a), unit_normal, dim)
        e_c = _along(_cross(b - a, d), unit_normal, dim)
        e_a = _along(_cross(c - b, x - b), unit_normal, dim)
        plane = jnp.abs(jnp.sum(d * unit_normal, axis=-1)) if dim == 3 else jnp.zeros(x.shape[:-1], x.dtype)
        return e_a, e_b, e_c, plane, twice_area

    @point_method
    def pdf(self, x):
        dtype = jnp.result_type(x, float)
        a, b, c = (jnp.asarray(v) for v in (self.a, self.b, self.c))
        e_a, e_b, e_c, plane, twice_area = self._edge_functions(x)
        length_a = jnp.linalg.norm(c - b, axis=-1)
        length_b = jnp.linalg.norm(c - a, axis=-1)
        length_c = jnp.linalg.norm(b - a, axis=-1)
        longest = jnp.maximum(jnp.maximum(length_a, length_b), length_c)
        scale = jnp.max(jnp.abs(jnp.stack([a, b, c])), axis=(-1, -2)) + longest
        tolerance = 64.0 * np.finfo(dtype).eps * scale
        # E_k / |edge k| is the signed distance to that edge's line; the normal of a thin triangle
        # is only known to ε |edge|²/(2·area), which widens the slab accepted around its plane.
        inside = ((e_a >= -tolerance * length_a) & (e_b >= -tolerance * length_b) & (e_c >= -tolerance * length_c)
                  & (plane <= tolerance * (1.0 + safe_div(longest * longest, twice_area))))
        return jnp.where(inside, 1.0 / (0.5 * twice_area), 0.0).astype(dtype)

    @point_method
    def inverse(self, x):
        _, e_b, e_c, _, twice_area = self._edge_functions(x)
        weight_b = jnp.clip(e_b / twice_area, 0.0, 1.0)
        weight_c = jnp.clip(e_c / twice_area, 0.0, 1.0)
        v = jnp.clip(weight_b + weight_c, 0.0, 1.0)
        return jnp.stack([v * v, jnp.clip(safe_div(weight_c, weight_b + weight_c), 0.0, 1.0)], axis=-1)

    def domain(self):
        vertices = [concrete_value(v) for v in (self.a, self.b, self.c)]
        if any(v is None for v in vertices):
            raise ValueError("UniformTriangle.domain: needs concrete vertices")
        return Triangle(*(tuple(float(t) for t in v) for v in vertices))
