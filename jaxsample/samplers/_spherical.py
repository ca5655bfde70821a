"""Geometry shared by the spherical triangle and rectangle samplers: solid angles, the inside test of
a spherical polygon, the bilinear warp of the cosine-aware variant, and the domain the checks
integrate over.

Everything here is written for vertices that are NOT unit vectors: the viewer is at the origin and a
vertex is a point in R³. A small triangle is known to the last bit through its own vertex
coordinates and edge vectors (b - a is exact when a and b are close); normalising the vertices
first would spend that precision: unit vectors 1e-4 apart carry their difference to only ~1e-3
relative in float32. So the edges are always formed from the points as given, and solid angles
come from Van Oosterom & Strackee's formula on them, never from angle sums (Girard's formula
cancels catastrophically for small triangles; docs/literature.md §5.8).
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np

from .._core.numerics import safe_div, safe_sqrt
from .domain import Cells, bin_index, gauss_legendre_panels, quantile_edges


# Vectors are tuples of their three components (arrays of one shape), split once where a method
# starts and stacked once where it returns: written on (..., 3) arrays, every `p[..., k]` is a slice
# and a squeeze of its own, which made these samplers' programs several times larger to compile.


def components(v):
    """(x, y, z) of an array (..., 3)."""
    v = jnp.asarray(v)
    return v[..., 0], v[..., 1], v[..., 2]


def stack(p):
    return jnp.stack(jnp.broadcast_arrays(*p), axis=-1)


def add(p, q):
    return tuple(pk + qk for pk, qk in zip(p, q))


def sub(p, q):
    return tuple(pk - qk for pk, qk in zip(p, q))


def scale(s, p):
    return tuple(s * pk for pk in p)


def where(condition, p, q):
    return tuple(jnp.where(condition, pk, qk) for pk, qk in zip(p, q))


def dot(p, q):
    return p[0] * q[0] + p[1] * q[1] + p[2] * q[2]


def cross(p, q):
    return (p[1] * q[2] - p[2] * q[1], p[2] * q[0] - p[0] * q[2], p[0] * q[1] - p[1] * q[0])


def length(p):
    """|p|, with a zero derivative (not NaN) at p = 0."""
    return safe_sqrt(dot(p, p))


def normalize(p):
    return scale(1.0 / length(p), p)


def safe_atan2(y, x):
    """atan2(y, x) with finite derivatives at (0, 0), where the value is taken as 0."""
    origin = (x == 0) & (y == 0)
    return jnp.where(origin, 0.0, jnp.arctan2(y, jnp.where(origin, 1.0, x)))


def triangle_solid_angle(a, e1, e2):
    """Solid angle of the triangle (a, a + e1, a + e2) seen from the origin (a need not be unit;
    vectors as component tuples): `van_oosterom_strackee` with the triple product a · (e1 × e2)
    formed from the edges (b × c of two nearly parallel vectors would cancel)."""
    b, c = add(a, e1), add(a, e2)
    return van_oosterom_strackee(jnp.abs(dot(a, cross(e1, e2))), length(a), length(b), length(c),
                                 dot(a, b), dot(a, c), dot(b, c))


def van_oosterom_strackee(triple, la, lb, lc, ab, ac, bc):
    """Solid angle of a triangle (a, b, c) seen from the origin, from triple = |det(a, b, c)| (formed
    by the caller from edges, never as a · (b × c)), the lengths |a|, |b|, |c| and the dot products
    a·b, a·c, b·c: the package's one Van Oosterom–Strackee formula (a caller that has some of these
    passes its own).

    Van Oosterom & Strackee (1983), for vectors of any length:

        tan(Ω/2) = |a · (b × c)| / (|a||b||c| + (a·b)|c| + (a·c)|b| + (b·c)|a|),

    taken as Ω = 2 atan2(numerator, denominator), which holds for Ω up to 2π (the denominator is
    negative beyond π). The denominator has no cancellation for small triangles (it is about
    4|a|³ there). A triangle whose plane holds the origin has Ω = 0 (the limit 2π of the formula
    from a viewer just off the plane inside the triangle is not taken: the directions that meet
    such a triangle form a great circle).
    """
    denominator = la * lb * lc + ab * lc + ac * lb + bc * la
    return jnp.where(triple > 0, 2.0 * safe_atan2(triple, denominator), 0.0)


def fan_solid_angle(apex, spokes):
    """Solid angle of the convex polygon (apex, apex + spokes[0], apex + spokes[1], ...) seen from
    the origin: its fan of triangles from the apex, each from the exact edges `spokes`."""
    total = triangle_solid_angle(apex, spokes[0], spokes[1])
    for e1, e2 in zip(spokes[1:-1], spokes[2:]):
        total = total + triangle_solid_angle(apex, e1, e2)
    return total


def polygon_inside(x, vertices, edges, tolerance, xp=jnp):
    """Whether unit directions x lie in the convex spherical polygon with `vertices` (points of R³,
    in order either way round) and `edges[k] = vertices[k+1] - vertices[k]` (passed in, so that a
    caller with exact edges uses them), to within `tolerance` radians of an edge's great circle
    (component tuples; the package's one inside test).

    Edge k's great circle has the normal n_k = v_k × e_k (= v_k × v_{k+1}, formed from the edge so
    that close vertices do not cancel); x is inside when σ x·n_k >= -tolerance |n_k| for every k,
    σ the orientation of the polygon (the sign of v_0 · (e_0 × e_1)); a degenerate polygon (σ = 0)
    holds nothing. `xp` is the array namespace: `numpy` for the checks' float64 domain.
    """
    size = length if xp is jnp else (lambda p: xp.sqrt(dot(p, p)))
    orientation = xp.sign(dot(vertices[0], cross(edges[0], edges[1])))
    inside = orientation != 0
    for v, e in zip(vertices, edges):
        normal = cross(v, e)
        inside = inside & (orientation * dot(x, normal) >= -tolerance * size(normal))
    return inside


def edge_tolerance(dtype) -> float:
    """Angular slack of the inside test: 8 ε of the working precision (1e-6 rad in float32).

    A sample computed on an edge lands up to a few ε to either side of its great circle (float32
    samples were measured within 5e-8 rad); the slack keeps a sampler's own samples inside."""
    return 8.0 * float(np.finfo(dtype).eps)


def same_sign_difference(p, q, r_p, r_q, scale2, p_minus_q):
    """p/r_p - q/r_q where r_k = sqrt(scale2 + k²), without cancellation.

    For p and q of one sign the two ratios are close when p and q are, and their difference is
    scale2 (p - q)(p + q) / (r_p r_q (p r_q + q r_p)), with p - q passed in exactly (an edge
    length); for opposite signs (or a zero) the plain difference has no cancellation."""
    same = p * q > 0
    denominator = r_p * r_q * (p * r_q + q * r_p)
    stable = safe_div(scale2 * p_minus_q * (p + q), jnp.where(same, denominator, 1.0))
    return jnp.where(same, stable, safe_div(p, r_p) - safe_div(q, r_q))


# ---------------------------------------------------------------------------------------------
# The bilinear warp of the cosine-aware variants (PBRT-v4 §A.5: a bilinear density on [0, 1]²
# sampled by its marginal in y and its conditional in x, both linear).
# ---------------------------------------------------------------------------------------------


def sample_linear(u, a, b):
    """t in [0, 1] with density ∝ (1 - t) a + t b (a, b > 0): the inverse CDF in the form
    t = u (a + b) / (a + sqrt((1 - u) a² + u b²)), which does not cancel as a -> b (where the
    quadratic formula's (sqrt(...) - a)/(b - a) would be 0/0)."""
    return u * (a + b) / (a + jnp.sqrt((1.0 - u) * a * a + u * b * b))


def invert_linear(t, a, b):
    """The CDF of `sample_linear`'s density: u = t (a (2 - t) + b t) / (a + b)."""
    return t * (a * (2.0 - t) + b * t) / (a + b)


def bilinear_warp(u0, u1, w00, w10, w01, w11):
    """(u₀, u₁) -> (x, y) with density `bilinear_pdf` (corner weights w_xy at (x, y) ∈ {0,1}²): y from
    its marginal, linear from w00 + w10 to w01 + w11, then x given y, linear from
    lerp(y, w00, w01) to lerp(y, w10, w11)."""
    y = sample_linear(u1, w00 + w10, w01 + w11)
    x = sample_linear(u0, (1.0 - y) * w00 + y * w01, (1.0 - y) * w10 + y * w11)
    return x, y


def bilinear_inverse(x, y, w00, w10, w01, w11):
    u1 = invert_linear(y, w00 + w10, w01 + w11)
    u0 = invert_linear(x, (1.0 - y) * w00 + y * w01, (1.0 - y) * w10 + y * w11)
    return u0, u1


def bilinear_pdf(x, y, w00, w10, w01, w11):
    """4 [(1-x)(1-y) w00 + x(1-y) w10 + (1-x) y w01 + x y w11] / (w00 + w10 + w01 + w11) on [0, 1]²."""
    value = (1.0 - x) * (1.0 - y) * w00 + x * (1.0 - y) * w10 + (1.0 - x) * y * w01 + x * y * w11
    return 4.0 * value / (w00 + w10 + w01 + w11)


# The smallest corner weight of the cosine-aware variants (PBRT-v4 uses the same 0.01): it keeps
# the density positive over the whole polygon, so the sampler covers the directions where the
# cosine is 0 too (an integrand that is not zero there still has an unbiased estimate).
MIN_CORNER_WEIGHT = 0.01


def cosine_weight(normal, direction):
    """max(|n̂ · ω̂|, 0.01) (component tuples): |cos|, not max(cos, 0), so that a surface lit from
    behind (a transmitting BSDF) is importance sampled too, as PBRT-v4 does. A zero normal,
    refused when concrete, gives NaN when traced."""
    cosine = dot(normal, direction) / (length(direction) * jnp.sqrt(dot(normal, normal)))
    return jnp.maximum(jnp.abs(cosine), MIN_CORNER_WEIGHT)


# ---------------------------------------------------------------------------------------------
# Checks on concrete parameters
# ---------------------------------------------------------------------------------------------


def check_vectors(owner: str, names: tuple, values) -> list | None:
    """The concrete values as float64 arrays broadcast together, after a ValueError unless they are
    finite with last axis 3; None when any is traced (then `_parameters_valid` rules)."""
    from .._core.params import concrete_value

    arrays = [concrete_value(v) for v in values]
    if any(v is None for v in arrays):
        return None
    for name, v in zip(names, arrays):
        if v.shape[-1:] != (3,):
            raise ValueError(f"{owner}: parameter '{name}' must have shape (3,) (leading dimensions are a batch); "
                             f"got {v.shape}")
        if not np.all(np.isfinite(v)):
            shown = v.tolist() if v.size <= 6 else v.shape
            raise ValueError(f"{owner}: parameter '{name}' must be finite; got {shown}")
    try:
        return list(np.broadcast_arrays(*arrays))
    except ValueError:
        shapes = ", ".join(f"{n} {v.shape}" for n, v in zip(names, arrays))
        raise ValueError(f"{owner}: the batch shapes of its parameters must broadcast; got {shapes}") from None


# ---------------------------------------------------------------------------------------------
# The domain: a convex spherical polygon, for the checks (quadrature, chi-square cells, contains)
# ---------------------------------------------------------------------------------------------


def _unit64(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


@dataclasses.dataclass(frozen=True, eq=False)
class SphericalPolygon:
    """The convex spherical polygon that a planar convex polygon with `vertices` (points of R³, in
    order; the viewer at the origin) subtends, with the solid-angle measure; event_shape (3,).

    The checks parametrise it independently of any sampler's warp: a fan of triangles from the
    centre g = normalize(Σ v̂_k), and in the triangle (g, v̂_k, v̂_{k+1}) the coordinates s ∈ [0, 1]
    (the fraction of the arc from v̂_k to v̂_{k+1}, of angle θ, at which the great circle from g
    through the point meets it: P̂(s) = slerp(v̂_k, v̂_{k+1}, s)) and t ∈ [0, 1]
    (1 - g·ω = t (1 - g·P̂(s))). The solid angle element is then

        dω = θ det(g, v̂_k, v̂_{k+1}) / (sin θ (1 + g · P̂(s))) ds dt,

    (polar coordinates about g: dω = d(1 - cos ρ) dψ, and dψ/ds = det(g, P̂, dP̂/ds) / (1 - (g·P̂)²)),
    smooth on the closed square for any polygon smaller than a hemisphere, tiny ones included, so
    Gauss–Legendre panels integrate it to ~1e-14. Cells are pilot quantiles of s per fan triangle
    times pilot quantiles of t.
    """

    vertices: tuple
    n_panels: int = 4
    order: int = 8
    event_shape = (3,)
    measure = "solid angle"

    def _fan(self):
        v = _unit64(np.asarray(self.vertices, np.float64))
        centre = _unit64(np.sum(v, axis=0))
        return centre, v

    def _orientation(self):
        v = np.asarray(self.vertices, np.float64)
        return np.sign(v[0] @ np.cross(v[1] - v[0], v[2] - v[0]))

    def _points(self, k, s, t):
        """Directions of fan triangle k at coordinates (s, t) (broadcast), and the weight dω/(ds dt)."""
        g, v = self._fan()
        start, end = v[k], v[(k + 1) % len(v)]
        s, t = np.broadcast_arrays(np.asarray(s, np.float64), np.asarray(t, np.float64))
        theta = np.arctan2(np.linalg.norm(np.cross(start, end)), start @ end)
        p_hat = _unit64((np.sin((1.0 - s) * theta)[..., None] * start + np.sin(s * theta)[..., None] * end)
                        / np.sin(theta))
        chord = p_hat - g
        half_chord = 0.5 * np.linalg.norm(chord, axis=-1)  # sin(ρ/2), ρ the angle from g to P̂
        tangent = chord - (chord @ g)[..., None] * g
        tangent = tangent / np.linalg.norm(tangent, axis=-1, keepdims=True)
        sigma = np.sqrt(t) * half_chord  # sin(ρ'/2) with 1 - cos ρ' = t (1 - cos ρ)
        x = (1.0 - 2.0 * sigma ** 2)[..., None] * g + (2.0 * sigma * np.sqrt(1.0 - sigma ** 2))[..., None] * tangent
        weight = theta * abs(np.linalg.det(np.stack([g, start, end]))) / (np.sin(theta) * (1.0 + p_hat @ g))
        return x, weight

    def _coordinates(self, x):
        """(fan triangle, s, t) of directions x."""
        g, v = self._fan()
        x = _unit64(x)
        count = len(v)
        sign = self._orientation()
        # det(g, v_k, x): which side of the half great circle from g through v_k.
        side = np.stack([sign * (x @ np.cross(g, v[k])) for k in range(count)], -1)
        k = np.full(x.shape[:-1], count - 1)
        for j in range(count - 1, -1, -1):
            k = np.where((side[..., j] >= 0) & (side[..., (j + 1) % count] < 0), j, k)
        start, end = v[k], v[(k + 1) % count]
        d_start = np.sum(x * np.cross(start, g), -1)
        d_end = np.sum(x * np.cross(end, g), -1)
        denominator = d_start - d_end
        ratio = np.where(denominator != 0, d_start / np.where(denominator != 0, denominator, 1.0), 0.0)
        chord = np.clip(ratio, 0.0, 1.0)
        p_hat = _unit64(start + chord[..., None] * (end - start))
        theta = np.arctan2(np.linalg.norm(np.cross(start, end), axis=-1), np.sum(start * end, -1))
        s = np.arctan2(np.linalg.norm(np.cross(start, p_hat), axis=-1), np.sum(start * p_hat, -1)) / theta
        t = np.sum((x - g) ** 2, -1) / np.sum((p_hat - g) ** 2, -1)
        return k, s, t

    def quadrature(self):
        edges = np.linspace(0.0, 1.0, self.n_panels + 1)
        s, ws = gauss_legendre_panels(edges, self.order)
        t, wt = gauss_legendre_panels(edges, self.order)
        points, weights = [], []
        for k in range(len(self.vertices)):
            x, jac = self._points(k, s[:, None], t[None, :])
            points.append(x.reshape(-1, 3))
            weights.append((jac * ws[:, None] * wt[None, :]).ravel())
        return np.concatenate(points), np.concatenate(weights)

    def cells(self, pilot, n_cells):
        count = len(self.vertices)
        per_triangle = max(n_cells // count, 4)
        n_t = max(2, int(round(np.sqrt(per_triangle / 2.0))))
        n_s = max(2, per_triangle // n_t)
        k_pilot, s_pilot, t_pilot = self._coordinates(np.asarray(pilot, np.float64))
        base = np.linspace(0.0, 1.0, self.n_panels + 1)
        s_edges, t_edges, offsets = [], [], [0]
        points, weights, ids = [], [], []
        for k in range(count):
            mine = k_pilot == k
            se = quantile_edges(s_pilot[mine], n_s, 0.0, 1.0)
            te = quantile_edges(np.clip(t_pilot[mine], 0.0, 1.0), n_t, 0.0, 1.0)
            s_edges.append(se)
            t_edges.append(te)
            s, ws = gauss_legendre_panels(np.unique(np.concatenate([base, se])), self.order)
            t, wt = gauss_legendre_panels(np.unique(np.concatenate([base, te])), self.order)
            x, jac = self._points(k, s[:, None], t[None, :])
            points.append(x.reshape(-1, 3))
            weights.append((jac * ws[:, None] * wt[None, :]).ravel())
            n_tk = len(te) - 1
            cell = bin_index(se, s)[:, None] * n_tk + bin_index(te, t)[None, :]
            ids.append((offsets[-1] + cell).ravel())
            offsets.append(offsets[-1] + (len(se) - 1) * n_tk)

        def assign(x):
            x = np.asarray(x, np.float64)
            k, s, t = self._coordinates(x)
            index = np.zeros(len(x), np.int64)
            for j in range(count):
                n_tj = len(t_edges[j]) - 1
                here = offsets[j] + bin_index(s_edges[j], s) * n_tj + bin_index(t_edges[j], t)
                index = np.where(k == j, here, index)
            return np.where(self.contains(x), index, -1)

        return Cells(offsets[-1], np.concatenate(points), np.concatenate(weights), np.concatenate(ids), assign)

    def contains(self, x, tolerance: float = 1e-6):
        """Unit length within 1e-5 and inside every edge's great circle within `tolerance` radians."""
        x = np.asarray(x, np.float64)
        v = np.asarray(self.vertices, np.float64)
        norm = np.linalg.norm(x, axis=-1)
        edges = [tuple(v[(k + 1) % len(v)] - v[k]) for k in range(len(v))]
        inside = polygon_inside(tuple(np.moveaxis(x, -1, 0)), [tuple(p) for p in v], edges, tolerance * norm, xp=np)
        return (np.abs(norm - 1.0) <= 1e-5) & inside
