"""Directions uniform in solid angle over a spherical triangle (Arvo 1995), and its cosine-aware
variant (PBRT-v4): the directions in which the viewer at the origin sees a triangle of R³."""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from .base import Sampler, point_method
from .._core.numerics import safe_div, safe_sqrt
from .._core.pytree import parameter
from ._spherical import (SphericalPolygon, add, bilinear_inverse, bilinear_pdf, bilinear_warp, check_vectors,
                         components, cosine_weight, cross, dot, edge_tolerance, length, normalize, polygon_inside,
                         safe_atan2, scale, stack, sub, triangle_solid_angle,
                         van_oosterom_strackee, where)

# Vertices whose planar triangle has doubled area below this many float64 epsilons times its
# longest squared edge are collinear to rounding: degenerate (as for UniformTriangle).
_DEGENERATE_ULPS = 64.0
# The stand-in triangle (the octant) on which the map is evaluated where the real one is seen
# edge-on, so that the discarded branch stays finite in value and derivative.
_OCTANT = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


def _triple(a, b, c):
    """|a · ((b - a) × (c - a))| = |det(a, b, c)|, from the edges (b × c would cancel): 0 edge-on."""
    return jnp.abs(dot(a, cross(sub(b, a), sub(c, a))))


def _geometry(a, b, c):
    """The per-triangle quantities of the warp and its inverse (`_edge_fraction`); Ω by
    `van_oosterom_strackee` from the lengths and the triple product shared with them."""
    e = sub(c, a)
    la, lb, lc = length(a), length(b), length(c)
    triple = _triple(a, b, c)
    ab = dot(a, b)
    return dict(a=a, b=b, c=c, e=e, la=la, lb=lb, triple=triple,
                omega=van_oosterom_strackee(triple, la, lb, lc, ab, dot(a, c), dot(b, c)),
                k=la * lb + ab,
                y=lb * dot(a, e) + la * dot(b, e),
                # (a × b) · (c × a), from the edges: a × b = a × (b - a), c × a = e × a.
                x=dot(cross(a, sub(b, a)), cross(e, a)))


def _arc_chord(g, p):
    """(P̂ - b̂, b̂) for the apex b and a point p = P of the opposite edge. The difference of two close
    unit vectors carries only their absolute rounding, ε, which moves the sample by ~ε whatever
    the triangle's size (a cancellation-free form of P̂ - b̂ was measured to change nothing)."""
    b_hat = scale(1.0 / g["lb"], g["b"])
    return sub(normalize(p), b_hat), b_hat


def _edge_fraction(g, u0):
    """λ in [0, 1] with the sub-triangle (a, b, P), P = a + λ (c - a), of solid angle u₀ Ω.

    Van Oosterom–Strackee for the sub-triangle: det(a, b, P) = λ det(a, b, c) = λ T (T = |a·((b-a)×(c-a))|),
    and its denominator is K (|P| + |a|) + λ Y with K = |a||b| + a·b, Y = |b| a·(c-a) + |a| b·(c-a).
    With S, C = sin, cos of u₀Ω/2 the condition λ T C = S (K (|P| + |a|) + λ Y) has one square
    root, |P|; squared, it is a quadratic in λ whose constant term cancels exactly (λ = 0 is the
    root of the other sign), so the root sought is rational, with X = (a × b)·(c × a):

        λ = 2 S K (|a| T C + S X) / ((T C - S Y)² - (S K |c - a|)²).

    No angle sum, no arccos: everything is formed from the vertices and edges as given, and stays
    accurate in float32 down to solid angles of 1e-11 sr (benchmarks/float32_spherical.py).
    """
    half = 0.5 * u0 * g["omega"]
    s, c = jnp.sin(half), jnp.cos(half)
    t, k = g["triple"], g["k"]
    alpha = t * c - s * g["y"]
    reach = s * k * length(g["e"])
    lam = 2.0 * s * k * (g["la"] * t * c + s * g["x"]) / ((alpha - reach) * (alpha + reach))
    return jnp.clip(lam, 0.0, 1.0)


def _arvo_warp(g, u0, u1):
    """Arvo's map: u₀ chooses P on the edge from a to c (the sub-triangle (a, b, P) has solid angle
    u₀ Ω), u₁ the point on the great arc from b to P̂ with 1 - cos ρ = u₁ (1 - cos ρ_P), ρ the angle
    from b. In half-angle form: sin(ρ/2) = sqrt(u₁) |P̂ - b̂|/2, ω = b̂ - 2 sin²(ρ/2) b̂ + sin ρ t̂,
    t̂ the unit tangent at b̂ toward P̂."""
    lam = _edge_fraction(g, u0)
    p = add(g["a"], scale(lam, g["e"]))
    chord, b_hat = _arc_chord(g, p)
    tangent = normalize(sub(chord, scale(dot(chord, b_hat), b_hat)))
    # safe_sqrt: at u₁ = 0 (the apex) d sqrt(u₁)/du₁ is infinite; the convention is 0 there.
    sigma = safe_sqrt(u1) * (0.5 * length(chord))
    w = add(scale(1.0 - 2.0 * sigma * sigma, b_hat), scale(2.0 * sigma * safe_sqrt(1.0 - sigma * sigma), tangent))
    return normalize(w)


def _arvo_inverse(g, x):
    """P is where the great circle through b and ω meets the edge a-c: λ = ω·(a×b) / ω·(a×b + b×c);
    u₀ = Ω(a, b, P)/Ω by the same Van Oosterom–Strackee form as the warp, u₁ = |ω - b̂|² / |P̂ - b̂|²."""
    a, b, c = g["a"], g["b"], g["c"]
    x = normalize(x)
    to_a = dot(x, cross(a, sub(b, a)))
    to_c = dot(x, cross(b, sub(c, b)))
    lam = jnp.clip(safe_div(to_a, to_a + to_c), 0.0, 1.0)
    p = add(a, scale(lam, g["e"]))
    sub_angle = 2.0 * safe_atan2(lam * g["triple"], g["k"] * (length(p) + g["la"]) + lam * g["y"])
    chord, b_hat = _arc_chord(g, p)
    rest = sub(x, b_hat)
    u0 = safe_div(sub_angle, g["omega"])
    u1 = safe_div(dot(rest, rest), dot(chord, chord))
    return jnp.clip(u0, 0.0, 1.0), jnp.clip(u1, 0.0, 1.0)


class _Triangle(Sampler):
    """What both triangle samplers share: the vertices, their checks, the solid angle, the edge-on
    rule and the domain."""

    a: jax.Array = parameter(rank=1, doc="a vertex, (3,): a point of R³, the viewer at the origin")
    b: jax.Array = parameter(rank=1, doc="a vertex (the apex of Arvo's sweep)")
    c: jax.Array = parameter(rank=1, doc="a vertex")
    uniform_dims: ClassVar[int] = 2
    event_shape: ClassVar = (3,)
    measure: ClassVar = "solid angle"

    def _vertices(self):
        """a, b, c as component tuples."""
        return tuple(components(v) for v in (self.a, self.b, self.c))

    def _parameters_valid(self):
        vertices = jnp.stack(jnp.broadcast_arrays(*(jnp.asarray(v) for v in (self.a, self.b, self.c))))
        a, b, c = self._vertices()
        twice_area = length(cross(sub(b, a), sub(c, a)))
        return jnp.all(jnp.isfinite(vertices)) & jnp.all(twice_area > 0)

    def __post_init__(self):
        owner = type(self).__name__
        values = check_vectors(owner, ("a", "b", "c"), (self.a, self.b, self.c))
        if values is None:
            return
        a, b, c = values
        twice_area = np.linalg.norm(np.cross(b - a, c - a), axis=-1)
        longest = np.maximum(np.maximum(np.sum((b - a) ** 2, -1), np.sum((c - a) ** 2, -1)), np.sum((c - b) ** 2, -1))
        if not np.all(twice_area > _DEGENERATE_ULPS * np.finfo(np.float64).eps * longest):
            raise ValueError(f"{owner}: parameters 'a', 'b', 'c' are degenerate: the triangle's area "
                             f"{0.5 * float(np.min(twice_area)):g} must be > "
                             f"{0.5 * _DEGENERATE_ULPS * np.finfo(np.float64).eps:g} × |longest edge|² "
                             "(collinear or coincident vertices)")

    @property
    def solid_angle(self):
        """Ω in [0, 2π) by Van Oosterom & Strackee (1983) on the vertices and edges as given; 0 for a
        triangle seen edge-on (its plane through the viewer)."""
        a, b, c = self._vertices()
        return triangle_solid_angle(a, sub(b, a), sub(c, a))

    def _safe_geometry(self):
        """(geometry, edge_on): the triangle's, or the octant's where it is seen edge-on (Ω = 0),
        so that the branch the `where`s discard has finite values and derivatives."""
        a, b, c = self._vertices()
        edge_on = _triple(a, b, c) == 0
        dtype = jnp.result_type(a[0])
        stand_in = [where(edge_on, tuple(jnp.asarray(t, dtype) for t in o), v) for o, v in zip(_OCTANT, (a, b, c))]
        return _geometry(*stand_in), edge_on

    def _edge_on_direction(self, u0, u1):
        """Where Ω = 0 (the viewer in the triangle's plane) the samples are the directions of the
        triangle's uniformly chosen points (UniformTriangle's map), finite and of density 0."""
        a, b, c = self._vertices()
        v = safe_sqrt(u0)
        p = add(a, add(scale(v * (1.0 - u1), sub(b, a)), scale(v * u1, sub(c, a))))
        size = length(p)
        return where(size > 0, scale(1.0 / jnp.where(size > 0, size, 1.0), p), normalize(sub(b, a)))

    def _uniform_warp(self, u0, u1):
        """(Arvo's map of (u₀, u₁) as components, 1/Ω: 0 edge-on)."""
        g, edge_on = self._safe_geometry()
        density = jnp.where(edge_on, 0.0, 1.0 / g["omega"])
        return where(edge_on, self._edge_on_direction(u0, u1), _arvo_warp(g, u0, u1)), density

    def _uniform_inverse(self, x):
        """(u₀, u₁) of Arvo's map at x, and 1/Ω (0 edge-on)."""
        g, edge_on = self._safe_geometry()
        return _arvo_inverse(g, components(x)), jnp.where(edge_on, 0.0, 1.0 / g["omega"])

    def _inside(self, x):
        a, b, c = self._vertices()
        return polygon_inside(components(x), (a, b, c), (sub(b, a), sub(c, b), sub(a, c)),
                              edge_tolerance(jnp.result_type(x, float)))

    def domain(self):
        from .._core.params import concrete_value

        vertices = [concrete_value(v) for v in (self.a, self.b, self.c)]
        if any(v is None for v in vertices):
            raise ValueError(f"{type(self).__name__}.domain: needs concrete vertices")
        return SphericalPolygon(tuple(tuple(float(t) for t in v) for v in vertices))


class SphericalTriangle(_Triangle):
    """Directions uniform in solid angle over the spherical triangle that the triangle with vertices
    a, b, c (points of R³, not necessarily unit; the viewer at the origin) subtends:
    p(ω) = 1/Ω over solid angle inside it, 0 outside.

    Warp: Arvo's (1995, "Stratified sampling of spherical triangles"; PBRT-v4 §6.5.4): u₀ picks the
    point P on the edge from a to c such that the sub-triangle (a, b, P) has solid angle u₀ Ω, and
    u₁ the point on the arc from b to P with 1 - cos ρ = u₁ (1 - cos ρ_P) (ρ the angle from b);
    (0, ·) -> b, (0, 1) -> a, (1, 1) -> c. Same map as PBRT's `SampleSphericalTriangle`, written
    differently: P comes from a closed form in λ (`_edge_fraction`: Van Oosterom–Strackee for the
    sub-triangle, solved exactly) instead of Arvo's angle formula, the arc in half-angle form,
    and Ω from Van Oosterom & Strackee (1983), never from the angle sum
    α + β + γ - π. Measured in float32 (`benchmarks/float32_spherical.py`, 32 random triangles x
    4096 u per solid angle): the textbook form gives invalid samples (NaN, off the sphere,
    outside) for 0.1 % of u at 1e-4 sr, 3 % at 4e-6, 19 % at 1e-6, 82 % at 4e-8 and 90 % at 1e-8 sr,
    with 1/pdf off by up to 23x; this one none, no sample off the exact map by more than 10x what
    rounding a unit vector to float32 can cost, from 1 sr down to 1e-8 sr, and 1/pdf = Ω to
    2.5e-6 (3.5e-5 for a sliver seen at grazing incidence, where the triple product of its edges
    rounds as ε/(sin · cos)). No fall-back to area sampling is needed.

    Precision: inverse(warp(u)) = u in float32 to within 2x what rounding the sample can cost
    (~ε/θ, θ the triangle's angular size: ~1e-3 at 1e-8 sr; 12x for a large triangle seen at
    grazing incidence). Near the hemisphere (the viewer close to the plane, inside the triangle)
    Arvo's map itself shears without bound (the arcs from b sweep through the pole within a
    sliver of u₀, so a float32 rounding of P moves the sample by ~ε/(2π - Ω)): at 2π - 0.1 and
    2π - 0.01 the samples stay inside with density exactly 1/Ω, but 17 % and 77 % of them are off
    the exact map by more than that 10x (the textbook form: 48 % and 83 %, and 15 % invalid at
    2π - 0.01). `inverse` is exact for points of the triangle other than b, where u₀ is not defined.

    Edge-on (the viewer in the triangle's plane, a vertex at the origin included): Ω = 0, the
    density is 0 everywhere, and the samples are the (finite) directions of uniformly chosen points
    of the triangle; `inverse` is then finite but meaningless. Concrete collinear or coincident
    vertices raise ValueError; traced ones give NaN.
    """

    @point_method
    def warp(self, u):
        return stack(self._uniform_warp(u[..., 0], u[..., 1])[0])

    @point_method
    def warp_with_pdf(self, u):
        x, density = self._uniform_warp(u[..., 0], u[..., 1])
        x = stack(x)
        return x, jnp.broadcast_to(density, x.shape[:-1]).astype(x.dtype)

    @point_method
    def pdf(self, x):
        dtype = jnp.result_type(x, float)
        return jnp.where(self._inside(x), safe_div(1.0, self.solid_angle), 0.0).astype(dtype)

    @point_method
    def inverse(self, x):
        return jnp.stack(self._uniform_inverse(x)[0], axis=-1)


class CosineSphericalTriangle(_Triangle):
    """The spherical triangle of a, b, c (as `SphericalTriangle`) sampled in proportion to a bilinear
    approximation of the cosine to the shading normal: p(ω) = q(v(ω))/Ω over solid angle inside the
    triangle, 0 outside, where v = Arvo's inverse map (`SphericalTriangle.inverse`) and q the
    bilinear density on [0, 1]² with corner weights w_k = max(|n·ω̂_k|, 0.01) at the directions the
    corners map to: (0, 0) and (1, 0) -> b, (0, 1) -> a, (1, 1) -> c.

    Warp (PBRT-v4 §6.5.4, Triangle::Sample with a shading normal): u -> v by the bilinear density
    (its marginal in v₁, then v₀ given v₁, both linear), then Arvo's map of v; Arvo's map carries
    uniform v to uniform ω with the constant Jacobian 1/Ω, so the density is q(v)/Ω. The weights
    use |cos| (a surface lit from behind is sampled too) and are at least 0.01, so the density is
    positive over the whole triangle. `normal` is normalised.

    Precision and the edge-on rule are `SphericalTriangle`'s.
    """

    normal: jax.Array = parameter(rank=1, doc="the shading normal, (3,), normalised here")

    def _parameters_valid(self):
        n = jnp.asarray(self.normal)
        return super()._parameters_valid() & jnp.all(jnp.isfinite(n)) & (dot(n, n) > 0)

    def __post_init__(self):
        super().__post_init__()
        from .._core.params import concrete_value

        n = concrete_value(self.normal)
        if n is not None and (n.shape[-1:] != (3,) or not np.all(np.isfinite(n)) or np.any(np.sum(n * n, -1) == 0)):
            raise ValueError(f"CosineSphericalTriangle: parameter 'normal' must be a finite non-zero vector of shape "
                             f"(3,); got {n.tolist() if n.size <= 6 else n.shape}")

    def _weights(self):
        """(w00, w10, w01, w11): the cosine weights at b, b, a, c (the corners' directions)."""
        a, b, c = self._vertices()
        n = components(self.normal)
        w_a, w_b, w_c = (cosine_weight(n, v) for v in (a, b, c))
        return w_b, w_b, w_a, w_c

    @point_method
    def warp(self, u):
        return stack(self._uniform_warp(*bilinear_warp(u[..., 0], u[..., 1], *self._weights()))[0])

    @point_method
    def warp_with_pdf(self, u):
        weights = self._weights()
        v = bilinear_warp(u[..., 0], u[..., 1], *weights)
        x, density = self._uniform_warp(*v)
        x = stack(x)
        return x, (density * bilinear_pdf(*v, *weights)).astype(x.dtype)

    @point_method
    def pdf(self, x):
        dtype = jnp.result_type(x, float)
        v, density = self._uniform_inverse(x)
        return jnp.where(self._inside(x), density * bilinear_pdf(*v, *self._weights()), 0.0).astype(dtype)

    @point_method
    def inverse(self, x):
        return jnp.stack(bilinear_inverse(*self._uniform_inverse(x)[0], *self._weights()), axis=-1)
