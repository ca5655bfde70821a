"""Directions uniform in solid angle over a spherical rectangle (Ureña, Fajardo & King 2013): the
directions in which the viewer at the origin sees a rectangle of R³."""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from .base import Sampler, point_method
from .._core.numerics import safe_div, safe_sqrt
from .._core.pytree import parameter
from ._spherical import (SphericalPolygon, add, check_vectors, components, cross, dot, edge_tolerance, fan_solid_angle,
                         length, normalize, polygon_inside, safe_atan2, same_sign_difference, scale, stack, sub, where)

# |edge_u · edge_v| must be at most this fraction of |edge_u| |edge_v|: perpendicular to float32
# rounding (edges rotated by a float32 matrix are perpendicular to ~1e-7).
_PERPENDICULAR_TOLERANCE = 1e-5


def _strip(x, y0, y1, height, d):
    """The signed solid angle of the rectangle [0, x] × [y0, y1] in the plane at distance d:
    E(x) = asin(k₁ sin ψ) - asin(k₀ sin ψ) (k_i = y_i / sqrt(y_i² + d²), sin ψ = x / sqrt(x² + d²),
    Ureña et al. 2013 §3), written without the cancellation of the two arcsines as

        E = atan2(x d (y₁ r₀ - y₀ r₁), d² r₀ r₁ + x² y₀ y₁),   r_i = sqrt(x² + y_i² + d²).

    y₁ r₀ - y₀ r₁ cancels for a short edge far off the perpendicular (relative error ~ε |y|/(y₁ - y₀));
    that costs the sample ~ε |y|, what rounding it costs anyway, where the perpendicular's foot
    lies in [x₀, x₁], and the warp's Newton step removes it where the foot does not (a
    cancellation-free form, (x² + d²)(y₁ - y₀)(y₁ + y₀)/(y₁ r₀ + y₀ r₁), was measured to change
    nothing)."""
    r0 = jnp.sqrt(x * x + y0 * y0 + d * d)
    r1 = jnp.sqrt(x * x + y1 * y1 + d * d)
    return safe_atan2(x * d * (y1 * r0 - y0 * r1), d * d * r0 * r1 + x * x * y0 * y1)


def _sub_solid_angle(x0, y0, z0, width, height):
    """Solid angle of the rectangle [x₀, x₀ + width] × [y₀, y₀ + height] at z = z₀ (local frame):
    its two triangles by Van Oosterom–Strackee, from the corner and the exact edge lengths."""
    zero = jnp.zeros_like(width)
    corner = (x0 + zero, y0 + zero, z0 + zero)
    along_x, diagonal, along_y = (width, zero, zero), (width, zero + height, zero), (zero, zero + height, zero)
    return fan_solid_angle(corner, (along_x, diagonal, along_y))


class SphericalRectangle(Sampler):
    """Directions uniform in solid angle over the spherical rectangle that the rectangle
    {corner + s edge_u + t edge_v : s, t ∈ [0, 1]} (edge_u ⟂ edge_v; the viewer at the origin)
    subtends: p(ω) = 1/Ω over solid angle inside it, 0 outside.

    Warp: Ureña, Fajardo & King (2013), "An area-preserving parametrization for spherical
    rectangles" (PBRT-v4 §6.5.4, `SampleSphericalRectangle`). In the frame x ∥ edge_u, y ∥ edge_v,
    the rectangle is [x₀, x₁] × [y₀, y₁] at distance d. u₀ chooses x_u such that the sub-rectangle
    [x₀, x_u] × [y₀, y₁] has solid angle u₀ Ω; given x_u, the sine of the elevation toward y,
    h = y / sqrt(x_u² + d² + y²), is uniform between its values h₀, h₁ at the edges
    (dω = dh dψ), so h = h₀ + u₁ (h₁ - h₀). (0, 0) -> the corner, (1, 0) -> corner + edge_u.

    Stable form. The paper solves for x_u with angles measured from the rectangle's corner, which
    a small solid angle (1e-3 sr and below, where PBRT falls back to area sampling) loses to
    cancellation. Here the angle is measured from the foot of the perpendicular (x = 0): with
    E(x) the solid angle of [0, x] × [y₀, y₁] (`_strip`, free of the arcsines' cancellation), the target
    E_t = E(x₀) + u₀ (E(x₁) - E(x₀)) gives x_u in closed form (from asin(k₁ sin ψ) = E_t + asin(k₀ sin ψ),
    k_i = cos φ_i, with the cosine differences written as products of sines of accurate angles):

        x_u = d sin E_t / (2 sqrt(sin((δ-E_t)/2) sin((δ+E_t)/2) sin((σ-E_t)/2) sin((σ+E_t)/2))),

    φ_i = atan2(d, y_i), δ = φ₀ - φ₁ (from one atan2), σ = φ₀ + φ₁. Where the foot lies outside
    [x₀, x₁], E(x₀) can be far larger than Ω, and toward grazing (x ≫ d) δ - E_t cancels; one
    Newton step on the sub-rectangle's own solid angle (two Van Oosterom–Strackee triangles,
    accurate at any size; dΩ/dx = d (h₁ - h₀)/(x² + d²)) removes what they cost (without it, a
    rectangle 1e-4 rad across seen at 89° from its plane's normal had samples 40 % of the way
    off). y_v comes from h without cancellation (`_height_sample`),
    and the direction from the point corner + s edge_u + t edge_v, or from the local coordinates
    where the point is much nearer the viewer than the corner. Ω (the density) is the two
    triangles' Van Oosterom–Strackee sum from the parameters as given. Measured in float32
    (`benchmarks/float32_spherical.py`, 32 random rectangles x 4096 u per solid angle): no invalid
    sample, no sample off the exact map by more than 10x what rounding a unit vector to float32
    can cost, and 1/pdf = Ω to 1e-6 (4.6e-6 for a rectangle seen at grazing incidence, ~ε/cos of
    the view), from 2π - 0.01 down to 1e-8 sr; the textbook form puts 48 % of the samples off the
    map at 1e-2 sr and 99.5 % at 1e-6 sr, gives 6 % and 16 % invalid ones at 4e-8 and 1e-8 sr, and
    1/pdf off by up to 64x. The float32 round trip inverse(warp(u)) = u is within 5.4x what
    rounding the sample can cost.

    Edge-on (the viewer in the rectangle's plane): Ω = 0, density 0, samples the directions of
    corner + u₀ edge_u + u₁ edge_v (finite). Concrete edges of length 0, or not perpendicular to
    within 1e-5 relative, raise ValueError; traced ones give NaN.
    """

    corner: jax.Array = parameter(rank=1, doc="a corner of the rectangle, (3,), the viewer at the origin")
    edge_u: jax.Array = parameter(rank=1, doc="the edge from the corner that u₀ sweeps, (3,)")
    edge_v: jax.Array = parameter(rank=1, doc="the edge from the corner that u₁ sweeps, (3,), perpendicular to edge_u")
    uniform_dims: ClassVar[int] = 2
    event_shape: ClassVar = (3,)
    measure: ClassVar = "solid angle"

    def _vectors(self):
        """corner, edge_u, edge_v as component tuples."""
        return tuple(components(v) for v in (self.corner, self.edge_u, self.edge_v))

    def _parameters_valid(self):
        arrays = (jnp.asarray(v) for v in (self.corner, self.edge_u, self.edge_v))
        finite = jnp.all(jnp.isfinite(jnp.stack(jnp.broadcast_arrays(*arrays))))
        corner, eu, ev = self._vectors()
        lu, lv = dot(eu, eu), dot(ev, ev)
        perpendicular = jnp.abs(dot(eu, ev)) <= _PERPENDICULAR_TOLERANCE * jnp.sqrt(lu * lv)
        return finite & jnp.all((lu > 0) & (lv > 0) & perpendicular)

    def __post_init__(self):
        values = check_vectors("SphericalRectangle", ("corner", "edge_u", "edge_v"),
                               (self.corner, self.edge_u, self.edge_v))
        if values is None:
            return
        _, eu, ev = values
        for name, e in (("edge_u", eu), ("edge_v", ev)):
            if np.any(np.sum(e * e, -1) == 0):
                raise ValueError(f"SphericalRectangle: parameter '{name}' must be a non-zero vector (a rectangle of "
                                 "zero area is degenerate)")
        cosine = np.abs(np.sum(eu * ev, -1)) / (np.linalg.norm(eu, axis=-1) * np.linalg.norm(ev, axis=-1))
        if np.any(cosine > _PERPENDICULAR_TOLERANCE):
            raise ValueError(f"SphericalRectangle: parameters 'edge_u' and 'edge_v' must be perpendicular "
                             f"(|cos| <= {_PERPENDICULAR_TOLERANCE:g}); got |cos| = {float(np.max(cosine)):.3g}")

    @property
    def solid_angle(self):
        """Ω in [0, 2π): the rectangle's two triangles by Van Oosterom & Strackee; 0 edge-on."""
        corner, eu, ev = self._vectors()
        return fan_solid_angle(corner, (eu, add(eu, ev), ev))

    def _local(self):
        """The frame (x̂ ∥ edge_u, ŷ ∥ edge_v, ẑ = x̂ × ŷ) and the rectangle in it: x₀, y₀, z₀, d = |z₀|,
        W = |edge_u|, H = |edge_v|. Seen edge-on (d = 0) a unit square at distance 1 stands in, so
        that the branch the `where`s discard stays finite."""
        corner, eu, ev = self._vectors()
        width, height = length(eu), length(ev)
        x_axis = scale(1.0 / width, eu)
        y_axis = normalize(sub(ev, scale(dot(ev, x_axis), x_axis)))
        z_axis = cross(x_axis, y_axis)
        x0, y0, z0 = dot(corner, x_axis), dot(corner, y_axis), dot(corner, z_axis)
        edge_on = z0 == 0
        z0 = jnp.where(edge_on, -1.0, z0)
        return dict(x=x_axis, y=y_axis, z=z_axis, x0=x0, y0=y0, z0=z0, d=jnp.abs(z0), width=width, height=height,
                    edge_on=edge_on)

    def _heights(self, f, xu):
        """(h₀, h₁ - h₀, x_u² + d²) at x = x_u."""
        dd2 = xu * xu + f["d"] * f["d"]
        y0, y1 = f["y0"], f["y0"] + f["height"]
        r0, r1 = jnp.sqrt(dd2 + y0 * y0), jnp.sqrt(dd2 + y1 * y1)
        return y0 / r0, same_sign_difference(y1, y0, r1, r0, dd2, f["height"]), dd2

    def _warp(self, u):
        """(the sample, 1/Ω: 0 edge-on)."""
        f = self._local()
        x0, y0, z0, d, width, height = (f[k] for k in ("x0", "y0", "z0", "d", "width", "height"))
        x1, y1 = x0 + width, y0 + height
        # u₀ -> x_u: the closed form in the angle from the perpendicular (x = 0).
        e0, e1 = _strip(x0, y0, y1, height, d), _strip(x1, y0, y1, height, d)
        target = e0 + u[..., 0] * (e1 - e0)
        # δ = φ₀ - φ₁ and σ = φ₀ + φ₁, φ_i = atan2(d, y_i) the angle of edge i seen along x; δ from
        # one atan2 (φ₀ - φ₁ would cancel for a short edge).
        delta = jnp.arctan2(d * height, d * d + y0 * y1)
        sigma = jnp.arctan2(d, y0) + jnp.arctan2(d, y1)
        product = (jnp.sin(0.5 * (delta - target)) * jnp.sin(0.5 * (delta + target))
                   * jnp.sin(0.5 * (sigma - target)) * jnp.sin(0.5 * (sigma + target)))
        sin_t = jnp.sin(target)
        # Where x_u would pass the rectangle's far side (the product rounds to 0 toward the horizon)
        # the sample is that side. The guard (and the product at least 2^-100, a division rather
        # than rsqrt, whose derivative -rsqrt(p)/2p overflows first) keeps the derivative finite.
        reach = 2.0 * (jnp.maximum(jnp.abs(x0), jnp.abs(x1)) + d)
        resolved = (4.0 * product * reach * reach > d * d * sin_t * sin_t) & (product > 2.0 ** -100)
        far = jnp.where(sin_t >= 0, x1, x0)
        xu = jnp.where(resolved, 0.5 * d * sin_t / jnp.sqrt(jnp.where(resolved, product, 1.0)), far)
        xu = jnp.clip(xu, x0, x1)
        # With the perpendicular's foot outside [x₀, x₁], E(x₀) can be far larger than Ω (and near
        # grazing, δ - E_t cancels): one Newton step on the sub-rectangle's own solid angle, which
        # has neither problem, removes what they cost. (With the foot inside, x_u is kept: the step
        # forms x_u - x₀ and would lose the absolute precision of samples near the foot.)
        h0, dh, dd2 = self._heights(f, xu)
        residual = _sub_solid_angle(x0, y0, z0, xu - x0, height) - u[..., 0] * self.solid_angle
        stepped = jnp.clip(xu - safe_div(residual * dd2, d * dh), x0, x1)
        xu = jnp.where(x0 * x1 > 0, stepped, xu)
        yv = self._height_sample(f, xu, u[..., 1])
        # The sample as a point: corner + s edge_u + t edge_v (s = (x_u - x₀)/|edge_u|, t likewise)
        # lies on the rectangle as given to rounding, whatever the rounding of the frame, but carries
        # an error of ε |corner| (the sum's scale): where the point is much nearer the viewer than the
        # corner (near the foot of the perpendicular, a viewer close to a large rectangle), the
        # local coordinates (x_u, y_v, z₀), small and exact there, give the direction instead.
        corner, eu, ev = self._vectors()
        s, t = (xu - x0) / width, (yv - y0) / height
        s = jnp.where(f["edge_on"], u[..., 0], s)  # edge-on: the points of the plane, uniformly
        t = jnp.where(f["edge_on"], u[..., 1], t)
        on_rectangle = add(corner, add(scale(s, eu), scale(t, ev)))
        local = add(add(scale(xu, f["x"]), scale(yv, f["y"])), scale(z0, f["z"]))
        near = 4.0 * jnp.sqrt(xu * xu + yv * yv + z0 * z0) < length(corner) + width + height
        x = where(near & ~f["edge_on"], local, on_rectangle)
        size = length(x)
        x = where(size > 0, scale(1.0 / jnp.where(size > 0, size, 1.0), x), f["x"])
        return stack(x), safe_div(1.0, self.solid_angle)

    def _height_sample(self, f, xu, u1):
        """y_v with h(y_v) = h₀ + u₁ (h₁ - h₀) at x = x_u, h(y) = y / sqrt(x_u² + d² + y²).

        Three exact forms, with r² = x_u² + d², c = sqrt(1 - h²) (c₀ = r/r₀ exact): y = h r / c, whose
        error is ~ε |h|/c² in units of the sample's own size |p| = r/c (it cancels at low elevation,
        h ≈ 1, a far-off rectangle); and from either end, with a = h_v - h₀ = u₁ (h₁ - h₀) exact,
        c_v² = c₀² - a (h_v + h₀) and y_v = y₀ + r a (h_v + h₀) / ((h_v c₀ + h₀ c_v) c_v c₀) (h_v, h₀
        of one sign; likewise from y₁), error ~ε |y₀| c_v / r. The form with the smallest error
        bound is taken (near the perpendicular the direct one: there y_v is small and an end far)."""
        y0, height, d = f["y0"], f["height"], f["d"]
        y1 = y0 + height
        dd2 = xu * xu + d * d
        r = jnp.sqrt(dd2)
        r0, r1 = jnp.sqrt(dd2 + y0 * y0), jnp.sqrt(dd2 + y1 * y1)
        h0, h1 = y0 / r0, y1 / r1
        c0, c1 = r / r0, r / r1
        dh = same_sign_difference(y1, y0, r1, r0, dd2, height)
        rise, fall = u1 * dh, (1.0 - u1) * dh
        near_low = u1 <= 0.5
        hv = jnp.where(near_low, h0 + rise, h1 - fall)
        cv = safe_sqrt(jnp.where(near_low, c0 * c0 - rise * (hv + h0), c1 * c1 + fall * (h1 + hv)))

        def from_end(end_y, end_h, end_c, step):  # step = h_v - h_end
            same = hv * end_h > 0
            denominator = jnp.where(same, (hv * end_c + end_h * cv) * cv * end_c, 1.0)
            return end_y + safe_div(r * step * (hv + end_h), denominator), jnp.where(same, jnp.abs(end_y) * cv, jnp.inf)

        low, low_error = from_end(y0, h0, c0, rise)
        high, high_error = from_end(y1, h1, c1, -fall)
        direct = jnp.where(cv > 0, hv * r / jnp.where(cv > 0, cv, 1.0), jnp.where(hv > 0, y1, y0))
        direct_error = r * jnp.abs(hv) / jnp.maximum(cv * cv, jnp.finfo(cv.dtype).tiny)  # both bounds times r
        yv = jnp.where(low_error <= high_error, low, high)
        yv = jnp.where(direct_error <= jnp.minimum(low_error, high_error), direct, yv)
        return jnp.clip(yv, y0, y1)

    @point_method
    def warp(self, u):
        return self._warp(u)[0]

    @point_method
    def warp_with_pdf(self, u):
        x, density = self._warp(u)
        return x, jnp.broadcast_to(density, x.shape[:-1]).astype(x.dtype)

    @point_method
    def pdf(self, x):
        corner, eu, ev = self._vectors()
        vertices = (corner, add(corner, eu), add(add(corner, eu), ev), add(corner, ev))
        inside = polygon_inside(components(x), vertices, (eu, ev, scale(-1.0, eu), scale(-1.0, ev)),
                                edge_tolerance(jnp.result_type(x, float)))
        return jnp.where(inside, safe_div(1.0, self.solid_angle), 0.0).astype(jnp.result_type(x, float))

    @point_method
    def inverse(self, x):
        """The ray along x meets the plane at (x_u, y_v); u₀ = (E(x_u) - E(x₀)) / (E(x₁) - E(x₀)) where
        the foot of the perpendicular lies in [x₀, x₁], and Ω([x₀, x_u] × [y₀, y₁]) / Ω (the
        sub-rectangle's two Van Oosterom–Strackee triangles, free of E(x₀)'s rounding; from E it
        was measured 2-4x less exact) where it does not; u₁ = (h(y_v) - h₀)/(h₁ - h₀) without
        cancellation."""
        f = self._local()
        x = normalize(components(x))
        to_plane = safe_div(f["z0"], dot(x, f["z"]))
        xu = jnp.clip(dot(x, f["x"]) * to_plane, f["x0"], f["x0"] + f["width"])
        yv = jnp.clip(dot(x, f["y"]) * to_plane, f["y0"], f["y0"] + f["height"])
        x0, y0, d, height = f["x0"], f["y0"], f["d"], f["height"]
        x1, y1 = x0 + f["width"], y0 + height
        total = _sub_solid_angle(x0, y0, f["z0"], f["width"], height)
        from_corner = safe_div(_sub_solid_angle(x0, y0, f["z0"], xu - x0, height), total)
        e0 = _strip(x0, y0, y1, height, d)
        from_foot = safe_div(_strip(xu, y0, y1, height, d) - e0, _strip(x1, y0, y1, height, d) - e0)
        u0 = jnp.where(x0 * x1 > 0, from_corner, from_foot)
        h0, dh, dd2 = self._heights(f, xu)
        rise = same_sign_difference(yv, y0, jnp.sqrt(dd2 + yv * yv), jnp.sqrt(dd2 + y0 * y0), dd2, yv - y0)
        u1 = safe_div(rise, dh)
        return jnp.stack([jnp.clip(u0, 0.0, 1.0), jnp.clip(u1, 0.0, 1.0)], axis=-1)

    def domain(self):
        from .._core.params import concrete_value

        corner, eu, ev = (concrete_value(v) for v in (self.corner, self.edge_u, self.edge_v))
        if corner is None or eu is None or ev is None:
            raise ValueError("SphericalRectangle.domain: needs concrete parameters")
        vertices = (corner, corner + eu, corner + eu + ev, corner + ev)
        return SphericalPolygon(tuple(tuple(float(t) for t in v) for v in vertices))
