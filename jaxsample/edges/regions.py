"""Regions whose boundaries are known: the discontinuities of an integrand, sampled by arc length.

A parameter that moves an edge of the integrand changes the integral by the *boundary term*
(Reynolds transport; Li et al. 2018, "Differentiable Monte Carlo ray tracing through edge
sampling", eq. 6): for a region Ω(θ) and an integrand that jumps by Δf(y) = f_inside(y) −
f_outside(y) across its boundary,

    d/dθ ∫ f dμ = ∫ ∂f/∂θ dμ  +  ∫_{∂Ω} Δf(y) (v(y) · n(y)) dl(y),

with n the outward unit normal of the boundary (tangent to the sphere for regions of directions),
v = ∂y/∂θ the velocity of a boundary point that stays on the boundary, and dl the arc length
(on the unit sphere: the length of the curve on the sphere). Only the normal part of v matters,
so any parametrisation of the boundary that moves with θ gives the same term.

Each region here has:

- `indicator(x)`: 1 inside (boundary included), 0 outside, as a float;
- `boundary_dims`: uniforms per boundary sample (1 for every region here);
- `boundary_sample(t)`: (y, n, pdf) from t of shape (..., boundary_dims): a point y on the boundary
  as a differentiable function of the region's parameters, the outward unit normal at y, and the
  density of y over arc length. Every region samples its boundary uniformly by arc length, so an
  integrand whose jump is constant has a boundary term with zero variance.

Regions of directions (`Cap`, `SphericalTriangle`, `SphericalPolygon`) live on the unit sphere; `Disk`
in the plane.
"""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp

from .._core.numerics import INV_2PI, safe_div, safe_sqrt, sincos_2pi
import numpy as np

from .._core.params import check_parameter, concrete_value
from .._core.pytree import Pytree, parameter
from ..samplers._spherical import components, fan_solid_angle, polygon_inside, sub
from ..samplers.frame import Frame

__all__ = ["Cap", "SphericalTriangle", "SphericalPolygon", "Disk"]


def _unit(v):
    v = jnp.asarray(v)
    return v / jnp.linalg.norm(v, axis=-1, keepdims=True)


def _check_vector(owner: str, name: str, value, size: int, nonzero: bool = True) -> None:
    """ValueError unless a concrete `value` is a finite vector of `size` entries (non-zero if asked)."""
    v = concrete_value(value)
    if v is None:
        return
    v = np.asarray(v, float)
    if v.shape != (size,) or not np.all(np.isfinite(v)) or (nonzero and not np.any(v)):
        raise ValueError(f"{owner}: parameter '{name}' must be a finite{' non-zero' if nonzero else ''} vector of "
                         f"shape ({size},); got {v.tolist() if v.size <= 4 else v.shape}")


class Cap(Pytree):
    """The spherical cap {ω ∈ S²: ω·â ≥ cos α} about the axis â = axis/|axis|.

    Stored as h = 1 − cos α (0 < h ≤ 2), the stable form for small caps (`UniformCone` does the
    same); `Cap.from_angle(axis, alpha)` builds it from the half-angle. Its boundary is the circle
    of radius sin α = sqrt(h (2 − h)) at height 1 − h, of length 2π sin α; the outward normal at a
    boundary point is the direction in which α grows, ∂y/∂α. Solid angle 2π h.
    """

    axis: jax.Array
    one_minus_cos: jax.Array = parameter(0.0, 2.0, low_open=True)
    boundary_dims: ClassVar[int] = 1

    def __post_init__(self):
        _check_vector("Cap", "axis", self.axis, 3)

    @classmethod
    def from_angle(cls, axis, alpha) -> "Cap":
        """The cap of half-angle α in (0, π] (1 − cos α = 2 sin²(α/2), accurate for small α)."""
        check_parameter("Cap.from_angle", "alpha", alpha, 0.0, np.pi, low_open=True)
        return cls(axis, 2.0 * jnp.sin(0.5 * jnp.asarray(alpha)) ** 2)

    def solid_angle(self):
        return 2.0 * jnp.pi * self.one_minus_cos

    def indicator(self, x):
        dtype = jnp.result_type(x, float)
        return (jnp.sum(x * _unit(self.axis), axis=-1) >= 1.0 - self.one_minus_cos).astype(dtype)

    def boundary_sample(self, t):
        h = jnp.asarray(self.one_minus_cos)
        frame = Frame.from_normal(self.axis)
        sin_alpha = safe_sqrt(h * (2.0 - h))
        sin_phi, cos_phi = sincos_2pi(t[..., 0])
        around = cos_phi[..., None] * frame.x + sin_phi[..., None] * frame.y
        y = sin_alpha[..., None] * around + (1.0 - h)[..., None] * frame.z
        normal = (1.0 - h)[..., None] * around - sin_alpha[..., None] * frame.z
        pdf = safe_div(INV_2PI, sin_alpha) * jnp.ones_like(t[..., 0])
        return y, normal, pdf


def _norm(v):
    """|v| with a finite derivative at v = 0 (jnp.linalg.norm's is NaN there)."""
    return safe_sqrt(jnp.sum(v * v, axis=-1))


def _arc_angle(a, b):
    """The angle between unit vectors a and b, stable at 0 and π: atan2(|a × b|, a·b)."""
    return jnp.arctan2(_norm(jnp.cross(a, b)), jnp.sum(a * b, axis=-1))


def _polygon_vertices(vertices):
    """(K, 3) unit vertices."""
    return _unit(jnp.asarray(vertices))


def _polygon_indicator(points, x):
    """1 inside a convex spherical polygon (edges p_k → p_{k+1} all turning the same way; a
    degenerate, traced, polygon holds nothing), boundary included, else 0: the inside test of
    `samplers._spherical.polygon_inside` on the vertices as given and their exact edges."""
    edges = [sub(q, p) for p, q in zip(points, points[1:] + points[:1])]
    return polygon_inside(components(x), points, edges, 0.0).astype(jnp.result_type(x, float))


def _polygon_boundary(vertices, t):
    """(y, outward normal, arc-length density) on a convex spherical polygon's perimeter, uniformly by
    arc length: an edge in proportion to its length, then the point at arc length φ along it,
    y = cos φ · start + sin φ · w (w the unit tangent of the great circle at `start`, toward `end`).

    What depends on the point drawn is only the edge's choice and one sine and cosine: the edges'
    vertices, tangents, lengths and normals are shared by every point (they depend on the polygon
    alone), and (sin φ, cos φ) come from `sincos_2pi` (polynomials; XLA's CPU sine is several times
    the cost, and per edge it was the bulk of a boundary term's derivative).
    """
    count = vertices.shape[0]
    edges = []
    start_length = 0.0
    for k in range(count):
        start, end = vertices[k], vertices[(k + 1) % count]
        opposite = vertices[(k + 2) % count]
        angle = _arc_angle(start, end)
        # An arc of length 0 or π (the viewpoint on an edge's line) has no great-circle plane: its
        # normal and tangent are taken as 0, so it adds nothing (a measure-zero configuration)
        # instead of NaN.
        cross = jnp.cross(start, end)
        length = _norm(cross)[..., None]
        plane = cross / jnp.where(length > 0, length, 1.0)
        side = jnp.sign(jnp.sum(plane * opposite, axis=-1))
        tangent = jnp.cross(plane, start)
        edges.append((start, tangent, angle, -side[..., None] * plane, start_length))
        start_length = start_length + angle
    perimeter = start_length
    position = t[..., 0] * perimeter
    chosen = None
    for start, tangent, angle, normal, offset in edges:
        here = (position >= offset)[..., None]
        values = (start, tangent, angle[..., None], normal, jnp.asarray(offset)[..., None])
        values = [v * jnp.ones_like(position)[..., None] for v in values]
        chosen = values if chosen is None else [jnp.where(here, v, c) for v, c in zip(values, chosen)]
    start, tangent, angle, normal, offset = chosen
    arc = jnp.clip(position[..., None] - offset, 0.0, angle)
    sin_arc, cos_arc = sincos_2pi(arc * np.float32(1.0 / (2.0 * np.pi)))
    y = cos_arc * start + sin_arc * tangent
    pdf = safe_div(1.0, perimeter) * jnp.ones_like(t[..., 0])
    return y, normal, pdf


def _polygon_solid_angle(points):
    """Solid angle of a convex spherical polygon from its vertices as given (points of R³, not
    normalised): the fan of triangles from the first, by `samplers._spherical.fan_solid_angle`
    (Van Oosterom & Strackee on the points and their exact edges; unit vertices would lose a small
    polygon's edges to rounding, and b × c of close vertices cancels)."""
    apex = points[0]
    return fan_solid_angle(apex, [sub(p, apex) for p in points[1:]])


class _ConvexSpherical(Pytree):
    """What a convex spherical polygon does with its (K, 3) unit vertices (`_vertices()`, for the
    boundary's arcs) and its vertices as given (`_points()`, for the solid angle and the inside
    test)."""

    def _points(self):
        """The vertices as given, as component tuples."""
        return [components(v) for v in self.vertices]

    def solid_angle(self):
        return _polygon_solid_angle(self._points())

    def indicator(self, x):
        return _polygon_indicator(self._points(), x)

    def boundary_sample(self, t):
        return _polygon_boundary(self._vertices(), t)


class SphericalTriangle(_ConvexSpherical):
    """The spherical triangle of directions spanned by a, b, c (normalised here): the directions
    ω = (λ_a a + λ_b b + λ_c c)/|...| with λ ≥ 0, i.e. the directions in which a point sees the flat
    triangle with vertices at a, b, c relative to it. Its boundary is three great-circle arcs.

    Solid angle by Van Oosterom & Strackee (1983) on a, b, c as given (`samplers._spherical`).
    The boundary is sampled uniformly by arc length over the whole perimeter (an edge in proportion
    to its length, then a point along its great circle by slerp); the outward normal on an edge is
    the unit normal of its great-circle plane, signed away from the opposite vertex.
    """

    a: jax.Array
    b: jax.Array
    c: jax.Array
    boundary_dims: ClassVar[int] = 1

    def __post_init__(self):
        for name in ("a", "b", "c"):
            _check_vector("SphericalTriangle", name, getattr(self, name), 3)
        _check_not_degenerate("SphericalTriangle", "'a', 'b', 'c'", [self.a, self.b, self.c])

    def _vertices(self):
        return jnp.stack([_unit(self.a), _unit(self.b), _unit(self.c)])

    def _points(self):
        return [components(self.a), components(self.b), components(self.c)]


class SphericalPolygon(_ConvexSpherical):
    """A convex spherical polygon with K >= 3 vertices (a (K, 3) array, normalised here, in order
    around it, either way): the directions inside every edge's great circle. The boundary, the
    indicator and the sampling are the triangle's (`SphericalTriangle`) with K edges; the normal of
    an edge is signed away from the next vertex after it, which for a convex polygon is inside.
    Solid angle: the fan of triangles from the first vertex. A non-convex polygon is outside the
    documented range (its indicator would be the intersection of the edges' half-spheres).
    """

    vertices: jax.Array
    boundary_dims: ClassVar[int] = 1

    def __post_init__(self):
        v = concrete_value(self.vertices)
        if v is not None:
            v = np.asarray(v, float)
            if v.ndim != 2 or v.shape[0] < 3 or v.shape[1] != 3 or not np.all(np.isfinite(v)):
                raise ValueError(f"SphericalPolygon: parameter 'vertices' must be a finite (K, 3) array with K >= 3; "
                                 f"got shape {v.shape}")
            _check_not_degenerate("SphericalPolygon", "'vertices'", list(v[:3]))

    def _vertices(self):
        return _unit(self.vertices)


def _check_not_degenerate(owner, names, vertices):
    values = [concrete_value(v) for v in vertices]
    if all(v is not None for v in values):
        a, b, c = (np.asarray(v, float) / np.linalg.norm(v) for v in values)
        if abs(a @ np.cross(b, c)) < 1e-12:
            raise ValueError(f"{owner}: parameters {names} must not lie on one great circle "
                             "(a degenerate polygon of zero solid angle)")


class Disk(Pytree):
    """The disk {x ∈ R²: |x − center| ≤ radius}; boundary the circle of length 2π r, outward
    normal (cos φ, sin φ), sampled uniformly by arc length (density 1/(2π r)). Area π r²."""

    center: jax.Array
    radius: jax.Array = parameter(0.0, low_open=True)
    boundary_dims: ClassVar[int] = 1

    def __post_init__(self):
        _check_vector("Disk", "center", self.center, 2, nonzero=False)

    def area(self):
        return jnp.pi * jnp.asarray(self.radius) ** 2

    def indicator(self, x):
        offset = x - jnp.asarray(self.center)
        return (jnp.sum(offset * offset, axis=-1) <= jnp.asarray(self.radius) ** 2).astype(jnp.result_type(x, float))

    def boundary_sample(self, t):
        sin_phi, cos_phi = sincos_2pi(t[..., 0])
        normal = jnp.stack([cos_phi, sin_phi], axis=-1)
        radius = jnp.asarray(self.radius)
        y = jnp.asarray(self.center) + radius[..., None] * normal
        pdf = safe_div(INV_2PI, radius) * jnp.ones_like(t[..., 0])
        return y, normal, pdf
