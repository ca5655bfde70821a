"""Exact references for SphericalTriangle, CosineSphericalTriangle and SphericalRectangle (the
contract suite, tests/samplers/test_contract.py, runs their chi-square, normalization, inverse and
gradient checks from registry.py):

- solid angles against Van Oosterom–Strackee in float64, closed forms (the octant π/2, a square of
  side 2 at distance 1: 2π/3) and the domain's own quadrature (an independent parametrisation);
- in float32 at 1e-6 and 1e-8 sr: 1/pdf = Ω to 1e-6, every sample inside, and the round trip
  inverse(warp(u)) = u within a few times what rounding the sample to float32 can cost;
- the cosine-aware density is the bilinear density of the corner weights max(|n·ω̂|, 0.01) over Ω;
- degenerate and edge-on shapes, traced invalid parameters, derivatives against finite
  differences, batches.

No test here is statistical (every check is deterministic, false-failure rate 0).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxsample as js
from jaxsample.samplers._spherical import SphericalPolygon

import registry

OCTANT = registry.SPHERICAL_OCTANT
SQUARE = registry.SPHERICAL_RECTANGLE_SQUARE


def vos64(a, b, c):
    """Van Oosterom & Strackee in float64 on unit vectors: the reference solid angle."""
    a, b, c = (np.asarray(v, np.float64) / np.linalg.norm(v) for v in (a, b, c))
    return 2.0 * np.arctan2(abs(a @ np.cross(b, c)), 1.0 + a @ b + b @ c + c @ a)


def rectangle_vos64(corner, eu, ev):
    corner, eu, ev = (np.asarray(v, np.float64) for v in (corner, eu, ev))
    return vos64(corner, corner + eu, corner + eu + ev) + vos64(corner, corner + eu + ev, corner + ev)


def triangle_of(omega_scale, centre=(0.3, -0.2, 1.0)):
    """A skew triangle about `centre`, scaled by s (Ω ≈ 0.29 s² sr)."""
    a = np.asarray(centre, np.float64)
    return a, a + omega_scale * np.array([1.0, 0.1, 0.2]), a + omega_scale * np.array([0.2, 0.9, -0.3])


# Float32 shapes of 1e-6 and 1e-8 sr: triangles, and rectangles off the perpendicular's foot (where
# the strips' solid angles cancel), far off it in y (where h ≈ 1) and seen at grazing incidence.
SMALL_TRIANGLES = {1e-6: triangle_of(1.79e-3), 1e-8: triangle_of(1.79e-4)}
SMALL_RECTANGLES = {1e-6: ((0.4, -0.3, 1.0), (1.18e-3, 2.36e-4, 1.18e-4), (-2.36e-4, 1.18e-3, 0.0)),
                    1e-8: registry.SPHERICAL_RECTANGLE_TINY,
                    "far in y": ((-0.4, 1.977, 0.445), (0.0015, 0.0, 0.0), (0.0, 0.0012, -0.0027)),
                    # 4e-8 sr seen at 89° from the plane's normal, far off the foot: E(x₀) ≈ δ and δ - E_t
                    # cancels (the warp's Newton step repairs it; without, samples 40 % of the way off).
                    "grazing": ((-0.43342063, 0.9673481, -0.06335076), (-0.00087914855, 0.002047909, -0.00012634952),
                                (-0.00033881646, -7.001721e-05, 0.0012226492))}


def _f32(shape):
    return tuple(jnp.asarray(np.asarray(v, np.float32)) for v in shape)


def _f64_of_f32(shape):
    return tuple(jnp.asarray(np.asarray(v, np.float32), jnp.float64) for v in shape)


# ---------------------------------------------------------------------------------------------
# Solid angles
# ---------------------------------------------------------------------------------------------


def test_solid_angles_match_their_closed_forms_in_float32_and_float64():
    with jax.enable_x64(True):
        octant64 = float(js.SphericalTriangle(*(jnp.asarray(v, jnp.float64) for v in OCTANT)).solid_angle)
        square64 = float(js.SphericalRectangle(*(jnp.asarray(v, jnp.float64) for v in SQUARE)).solid_angle)
    assert abs(octant64 - np.pi / 2) < 1e-15 and abs(square64 - 2 * np.pi / 3) < 1e-15
    octant32 = float(js.SphericalTriangle(*_f32(OCTANT)).solid_angle)
    square32 = float(js.SphericalRectangle(*_f32(SQUARE)).solid_angle)
    assert abs(octant32 / (np.pi / 2) - 1) < 2e-7 and abs(square32 / (2 * np.pi / 3) - 1) < 2e-7


def test_solid_angles_match_van_oosterom_strackee_and_an_independent_quadrature():
    """Random triangles and rectangles from 1e-6 sr to near the hemisphere, in float64: against the
    unit-vector form of Van Oosterom–Strackee, and against the domain's quadrature (a fan of
    triangles from the centre, no shared code with the sampler); 1/pdf of the samples is Ω."""
    rng = np.random.default_rng(7)
    u = jnp.asarray(rng.random((64, 2)))
    with jax.enable_x64(True):
        for _ in range(12):
            centre = rng.normal(size=3)
            scale = 10.0 ** rng.uniform(-3, 0.5)
            a, b, c = (centre + scale * rng.normal(size=3) for _ in range(3))
            tri = js.SphericalTriangle(*(jnp.asarray(v) for v in (a, b, c)))
            reference = vos64(a, b, c)
            assert abs(float(tri.solid_angle) / reference - 1) < 1e-10, (a, b, c)
            _, weights = SphericalPolygon((tuple(a), tuple(b), tuple(c))).quadrature()
            assert abs(np.sum(weights) / reference - 1) < 1e-9
            _, p = tri.warp_with_pdf(u)
            np.testing.assert_allclose(1.0 / np.asarray(p), reference, rtol=1e-10)

            x_axis, y_axis = np.linalg.qr(rng.normal(size=(3, 3)))[0][:, :2].T
            corner = centre - scale * (x_axis + y_axis)
            eu, ev = 2 * scale * rng.uniform(0.5, 1.5) * x_axis, 2 * scale * y_axis
            rect = js.SphericalRectangle(*(jnp.asarray(v) for v in (corner, eu, ev)))
            reference = rectangle_vos64(corner, eu, ev)
            assert abs(float(rect.solid_angle) / reference - 1) < 1e-10
            vertices = (corner, corner + eu, corner + eu + ev, corner + ev)
            _, weights = SphericalPolygon(tuple(tuple(v) for v in vertices)).quadrature()
            assert abs(np.sum(weights) / reference - 1) < 1e-9
            _, p = rect.warp_with_pdf(u)
            np.testing.assert_allclose(1.0 / np.asarray(p), reference, rtol=1e-10)


# A rectangle 0.005 below the viewer, who sees it nearly as a hemisphere (Ω = 2π - 0.0125): most
# samples lie near the foot of the perpendicular, far nearer than the corner.
NEAR_HEMISPHERE_RECTANGLE = ((-1.3, -0.7, -0.005), (2.0, 0.0, 0.0), (0.0, 1.6, 0.0))

# The solid angle and the inside test have one implementation each (samplers/_spherical.py), which
# the samplers, the regions of jaxsample.edges and the checks' domain all call.


def fan64(points):
    """Van Oosterom & Strackee in float64 on the points as given and their edges from the first: the
    reference solid angle of a polygon (exact to ~1e-15 for the shapes below)."""
    p = [np.asarray(v, np.float64) for v in points]
    total, a = 0.0, p[0]
    for b, c in zip(p[1:-1], p[2:]):
        la, lb, lc = (np.linalg.norm(v) for v in (a, b, c))
        total += 2.0 * np.arctan2(abs(a @ np.cross(b - a, c - a)),
                                  la * lb * lc + (a @ b) * lc + (a @ c) * lb + (b @ c) * la)
    return total


# Float32 shapes (the viewer at the origin): 1e-6 and 1e-8 sr triangles (a, b, c), a 1e-8 sr
# rectangle (corner, edge_u, edge_v), and a triangle and a rectangle seen as nearly a hemisphere
# (Ω > 6 sr).
HARD_POLYGONS = {"triangle 1e-6 sr": SMALL_TRIANGLES[1e-6], "triangle 1e-8 sr": SMALL_TRIANGLES[1e-8],
                 "rectangle 1e-8 sr": registry.SPHERICAL_RECTANGLE_TINY,
                 "triangle near a hemisphere": ((1.0, 0.0, 0.01), (-0.5, 0.866, 0.01), (-0.5, -0.866, 0.01)),
                 "rectangle near a hemisphere": NEAR_HEMISPHERE_RECTANGLE}


def _polygon32(name):
    """(the sampler, the polygon's float32 vertices) of a shape of HARD_POLYGONS."""
    shape = _f32(HARD_POLYGONS[name])
    if name.startswith("triangle"):
        return js.SphericalTriangle(*shape), [np.asarray(v) for v in shape]
    corner, eu, ev = (np.asarray(v, np.float64) for v in shape)
    points = [corner, corner + eu, corner + eu + ev, corner + ev]
    return js.SphericalRectangle(*shape), [np.asarray(v, np.float32) for v in points]


def _region(points32):
    if len(points32) == 3:
        return js.edges.SphericalTriangle(*(jnp.asarray(v) for v in points32))
    return js.edges.SphericalPolygon(jnp.asarray(np.stack(points32)))


@pytest.mark.parametrize("name", list(HARD_POLYGONS))
def test_a_region_solid_angle_is_exact_to_rounding_at_the_hard_cases(name):
    """`jaxsample.edges` regions in float32 take Ω from the samplers' Van Oosterom–Strackee (the
    points as given, the triple product from exact edges): within 1e-6 of the float64 reference.
    Catches the cancelling form the regions had, a·(b×c) of unit vectors: 1.4e-3, 5.7e-2 and 0.31
    off at the 1e-6 sr triangle, the 1e-8 sr triangle and the 1e-8 sr rectangle."""
    _, points32 = _polygon32(name)
    reference = fan64(points32)
    assert abs(float(_region(points32).solid_angle()) / reference - 1) < 1e-6, (float(_region(points32).solid_angle()),
                                                                              reference)


def _probes(points, fraction):
    """Unit directions just inside and just outside each edge of a convex polygon (float64): off the
    edge's midpoint along its great circle's normal by `fraction` of the edge's angle."""
    p = [np.asarray(v, np.float64) / np.linalg.norm(v) for v in points]
    centre = np.sum(p, axis=0)
    inside, outside = [], []
    for k in range(len(p)):
        start, end = p[k], p[(k + 1) % len(p)]
        normal = np.cross(start, end)
        normal *= np.sign(normal @ centre) / np.linalg.norm(normal)  # toward the polygon
        middle = (start + end) / np.linalg.norm(start + end)
        step = fraction * np.arctan2(np.linalg.norm(np.cross(start, end)), start @ end)
        for sign, found in ((1.0, inside), (-1.0, outside)):
            x = middle + sign * step * normal
            found.append(x / np.linalg.norm(x))
    return np.array(inside), np.array(outside)


@pytest.mark.parametrize("name", list(HARD_POLYGONS))
def test_the_inside_test_agrees_with_float64_for_the_samplers_the_regions_and_the_checks(name):
    """Directions 5 % of an edge's angle inside and outside each edge (both orientations of the
    polygon): the sampler's density is > 0 exactly inside, the region's indicator is 1 exactly
    inside, and the checks' `contains` agrees, as the float64 geometry says. Catches an inside test
    that skips an edge (the directions beyond it are counted inside) in any of the three users."""
    sampler, vertices = _polygon32(name)
    for points32 in (vertices, vertices[::-1]):
        inside, outside = _probes(points32, 0.05)
        region = _region(points32)
        domain = SphericalPolygon(tuple(tuple(float(t) for t in v) for v in points32))
        for probes, expected in ((inside, True), (outside, False)):
            x = jnp.asarray(probes, jnp.float32)
            assert np.all((np.asarray(sampler.pdf(x)) > 0) == expected), (name, expected)
            assert np.all((np.asarray(jax.vmap(region.indicator)(x)) == 1) == expected), (name, expected)
            assert np.all(domain.contains(probes) == expected), (name, expected)


# ---------------------------------------------------------------------------------------------
# Float32 at the smallest solid angles
# ---------------------------------------------------------------------------------------------


@jax.jit
def _warp_pdf_inverse(sampler, u):
    x, p = sampler.warp_with_pdf(u)
    return x, p, sampler.pdf(x), sampler.inverse(x)


@jax.jit
def _warp(sampler, u):
    return sampler.warp(u)


@jax.jit
def _inverse(sampler, x):
    return sampler.inverse(x)


def _yardstick(make, shape32, u):
    """max |u' - u| with u' the float64 inverse of the exact (float64) sample turned by 2^-24 rad in
    a random direction: the most that rounding a unit vector to float32 can cost in u."""
    with jax.enable_x64(True):
        sampler = make(*_f64_of_f32(shape32))
        exact = np.asarray(_warp(sampler, jnp.asarray(u, jnp.float64)))
        turn = np.random.default_rng(1).normal(size=exact.shape)
        turn -= np.sum(turn * exact, -1, keepdims=True) * exact
        turned = exact + 2.0 ** -24 * turn / np.linalg.norm(turn, axis=-1, keepdims=True)
        return float(np.max(np.abs(np.asarray(_inverse(sampler, jnp.asarray(turned))) - u)))


CASES_32 = ([("SphericalTriangle", js.SphericalTriangle, shape) for shape in SMALL_TRIANGLES.values()]
            + [("CosineSphericalTriangle",
                lambda a, b, c: js.CosineSphericalTriangle(a, b, c, jnp.array([0.3, 0.2, -1.0])),
                SMALL_TRIANGLES[1e-8])]
            + [("SphericalRectangle", js.SphericalRectangle, shape)
               for shape in (*SMALL_RECTANGLES.values(), NEAR_HEMISPHERE_RECTANGLE)])


@pytest.mark.parametrize("name,make,shape", CASES_32, ids=[f"{n}-{i}" for i, (n, _, _) in enumerate(CASES_32)])
def test_float32_is_exact_to_rounding_at_the_hard_solid_angles(name, make, shape):
    """At 1e-6 and 1e-8 sr (and a rectangle seen as nearly a hemisphere): 1/pdf = Ω to 1e-6 (the
    textbook formulas: 28 % and 2300 % off at 1e-6 and 1e-8 sr), every
    sample inside and of unit length, and the round trip within 4x what rounding the sample to
    float32 can cost (measured: 0.2x to 1.9x)."""
    u = np.random.default_rng(3).random((4096, 2)) * (1 - 2e-3) + 1e-3
    u32 = jnp.asarray(u, jnp.float32)
    u = np.asarray(u32, np.float64)
    sampler = make(*_f32(shape))
    x, p, pdf, back = (np.asarray(t, np.float64) for t in _warp_pdf_inverse(sampler, u32))
    shape64 = [np.asarray(np.asarray(v, np.float32), np.float64) for v in shape]
    if name == "SphericalRectangle":
        corner, eu, ev = shape64
        omega = rectangle_vos64(corner, eu, ev)
        domain = SphericalPolygon(tuple(tuple(v) for v in (corner, corner + eu, corner + eu + ev, corner + ev)))
    else:
        omega = vos64(*shape64)
        domain = SphericalPolygon(tuple(tuple(v) for v in shape64))
    assert omega < 1.1e-6 or shape is NEAR_HEMISPHERE_RECTANGLE
    if name != "CosineSphericalTriangle":
        assert np.max(np.abs(1.0 / p - omega)) / omega < 1e-6
    assert np.all(pdf > 0) and np.all(np.isfinite(x))
    assert np.all(domain.contains(x, tolerance=1e-6))
    assert np.max(np.abs(np.linalg.norm(x, axis=-1) - 1.0)) < 1e-6
    worst = float(np.max(np.abs(back - u)))
    yardstick = _yardstick(make, shape, u)
    assert worst < 4.0 * yardstick, (worst, yardstick)


def test_sampling_at_1e_8_sr_stays_inside():
    """`sample` (the estimators' compiled path, on coordinate lanes) at 1e-8 sr."""
    for make, shape in ((js.SphericalTriangle, SMALL_TRIANGLES[1e-8]), (js.SphericalRectangle, SMALL_RECTANGLES[1e-8])):
        sampler = make(*_f32(shape))
        x = np.asarray(sampler.sample(jax.random.key(4), (1 << 14,)), np.float64)
        assert np.all(sampler.domain().contains(x, tolerance=1e-6))


# ---------------------------------------------------------------------------------------------
# The cosine-aware variant
# ---------------------------------------------------------------------------------------------


def _bilinear64(v, w00, w10, w01, w11):
    x, y = v[:, 0], v[:, 1]
    return 4 * ((1 - x) * (1 - y) * w00 + x * (1 - y) * w10 + (1 - x) * y * w01 + x * y * w11) / (w00 + w10 + w01 + w11)


@pytest.mark.parametrize("normal", [(0.3, -0.2, 0.9), (1.0, -1.0, 0.0), (0.0, 0.0, -1.0)])
def test_cosine_density_is_the_bilinear_cosine_weight_over_the_solid_angle(normal):
    """pdf(Arvo(v)) Ω = bilinear density of v with corner weights max(|n̂·ω̂|, 0.01) at b, b, a, c
    ((1, -1, 0) is perpendicular to c = e_z: that weight is at its floor 0.01; (0, 0, -1) faces
    away), and the density integrates to 1 by the domain's quadrature."""
    with jax.enable_x64(True):
        a, b, c = (np.asarray(v, np.float64) for v in OCTANT)
        n = np.asarray(normal, np.float64) / np.linalg.norm(normal)
        weight = {k: max(abs(n @ (v / np.linalg.norm(v))), 0.01) for k, v in zip("abc", (a, b, c))}
        cosine = js.CosineSphericalTriangle(*(jnp.asarray(t) for t in (a, b, c, np.asarray(normal, np.float64))))
        uniform = js.SphericalTriangle(*(jnp.asarray(t) for t in (a, b, c)))
        grid = (np.stack(np.meshgrid(np.linspace(0.02, 0.98, 17), np.linspace(0.02, 0.98, 17)), -1).reshape(-1, 2))
        x = uniform.warp(jnp.asarray(grid))
        expected = _bilinear64(grid, weight["b"], weight["b"], weight["a"], weight["c"]) / (np.pi / 2)
        np.testing.assert_allclose(np.asarray(cosine.pdf(x)), expected, rtol=1e-9)
        points, weights = cosine.domain().quadrature()
        assert abs(float(np.sum(weights * np.asarray(cosine.pdf(jnp.asarray(points))))) - 1.0) < 1e-9
        # The sampler's own samples carry the same density, and map back to their u.
        u = jnp.asarray(np.random.default_rng(2).random((256, 2)) * 0.98 + 0.01)
        y, p = cosine.warp_with_pdf(u)
        v = np.asarray(uniform.inverse(y))
        np.testing.assert_allclose(np.asarray(p), _bilinear64(v, weight["b"], weight["b"], weight["a"], weight["c"])
                                   / (np.pi / 2), rtol=1e-9)
        np.testing.assert_allclose(np.asarray(cosine.inverse(y)), np.asarray(u), atol=1e-10)


# ---------------------------------------------------------------------------------------------
# Degenerate and edge-on shapes, invalid parameters
# ---------------------------------------------------------------------------------------------


def test_degenerate_shapes_are_refused_naming_their_parameters():
    with pytest.raises(ValueError, match=r"parameters 'a', 'b', 'c' are degenerate"):
        js.SphericalTriangle(jnp.array([0.0, 0.0, 1.0]), jnp.array([1.0, 1.0, 1.0]), jnp.array([2.0, 2.0, 1.0]))
    with pytest.raises(ValueError, match=r"parameters 'a', 'b', 'c' are degenerate"):
        js.CosineSphericalTriangle(jnp.ones(3), jnp.ones(3), jnp.array([0.0, 1.0, 1.0]), jnp.ones(3))
    with pytest.raises(ValueError, match=r"parameter 'normal'"):
        js.CosineSphericalTriangle(*(jnp.asarray(v) for v in OCTANT), jnp.zeros(3))
    with pytest.raises(ValueError, match=r"parameter 'b' must be finite"):
        js.SphericalTriangle(jnp.ones(3), jnp.array([np.nan, 0.0, 1.0]), jnp.zeros(3))
    with pytest.raises(ValueError, match=r"parameter 'edge_u' must be a non-zero vector"):
        js.SphericalRectangle(jnp.ones(3), jnp.zeros(3), jnp.array([0.0, 1.0, 0.0]))
    with pytest.raises(ValueError, match=r"'edge_u' and 'edge_v' must be perpendicular"):
        js.SphericalRectangle(jnp.ones(3), jnp.array([1.0, 0.0, 0.0]), jnp.array([0.1, 1.0, 0.0]))
    with pytest.raises(ValueError, match=r"parameter 'corner' must have shape \(3,\)"):
        js.SphericalRectangle(jnp.ones(2), jnp.array([1.0, 0.0, 0.0]), jnp.array([0.0, 1.0, 0.0]))


def test_traced_invalid_parameters_give_nan():
    u = jnp.full((3, 2), 0.5)
    collinear = (jnp.array([0.0, 0.0, 1.0]), jnp.array([1.0, 1.0, 1.0]), jnp.array([2.0, 2.0, 1.0]))
    x = jax.jit(lambda a, b, c: js.SphericalTriangle(a, b, c).warp(u))(*collinear)
    skew = (jnp.ones(3), jnp.array([1.0, 0.0, 0.0]), jnp.array([0.1, 1.0, 0.0]))
    y, p = jax.jit(lambda *r: js.SphericalRectangle(*r).warp_with_pdf(u))(*skew)
    assert np.all(np.isnan(np.asarray(x))) and np.all(np.isnan(np.asarray(y))) and np.all(np.isnan(np.asarray(p)))


EDGE_ON = {
    "triangle, viewer in its plane outside it": (js.SphericalTriangle,
                                                 ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (1.0, 1.0, 0.0))),
    "triangle, viewer in its plane inside it": (js.SphericalTriangle,
                                                ((1.0, 0.0, 0.0), (-1.0, 1.0, 0.0), (-1.0, -1.0, 0.0))),
    "triangle, a vertex at the viewer": (js.SphericalTriangle, ((0.0, 0.0, 0.0), (0.0, 1.0, 0.0), (1.0, 1.0, 0.0))),
    "cosine triangle, edge-on": (lambda a, b, c: js.CosineSphericalTriangle(a, b, c, jnp.array([0.0, 0.0, 1.0])),
                                 ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (1.0, 1.0, 0.0))),
    "rectangle, viewer in its plane": (js.SphericalRectangle, ((-1.0, -1.0, 0.0), (2.0, 0.0, 0.0), (0.0, 2.0, 0.0))),
}


@pytest.mark.parametrize("name", list(EDGE_ON))
def test_a_shape_seen_edge_on_has_density_zero_and_finite_samples_and_gradients(name):
    """Ω = 0 (the viewer in the shape's plane): density 0 everywhere, samples finite unit vectors,
    and the derivatives of samples and densities in the vertices finite (float32)."""
    make, shape = EDGE_ON[name]
    u = registry.edge_uniforms(2, jnp.float32)
    sampler = make(*_f32(shape))
    x, p = sampler.warp_with_pdf(u)
    assert float(sampler.solid_angle) == 0.0
    assert np.all(np.asarray(p) == 0) and np.all(np.asarray(sampler.pdf(x)) == 0)
    assert np.all(np.isfinite(np.asarray(x))) and np.allclose(np.linalg.norm(np.asarray(x), axis=-1), 1.0, atol=1e-6)
    assert np.all(np.isfinite(np.asarray(sampler.inverse(x))))

    def total(params):
        s = make(*params)
        y, q = s.warp_with_pdf(u)
        return jnp.sum(y) + jnp.sum(q) + jnp.sum(s.pdf(jnp.asarray(registry.SPHERICAL_POINTS, jnp.float32)))

    gradient = jax.grad(total)(_f32(shape))
    assert all(np.all(np.isfinite(np.asarray(g))) for g in gradient)


# ---------------------------------------------------------------------------------------------
# Derivatives in the vertices, batches
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("make,shape", [(js.SphericalTriangle, registry.SPHERICAL_MEDIUM),
                                        (js.SphericalRectangle, registry.SPHERICAL_RECTANGLE_SQUARE)],
                         ids=["triangle", "rectangle"])
def test_derivatives_in_the_vertices_match_finite_differences(make, shape):
    """d warp(u)/d vertex and d Ω/d vertex (float64, forward mode) against central differences."""
    u = jnp.asarray([[0.3, 0.7], [0.8, 0.2], [0.5, 0.5]])
    with jax.enable_x64(True):
        params = tuple(jnp.asarray(v, jnp.float64) for v in shape)
        tangent = tuple(jnp.asarray(np.random.default_rng(k).normal(size=3)) for k in range(len(params)))

        def outputs(p):
            s = make(*p)
            return s.warp(u), s.solid_angle

        _, derivative = jax.jvp(outputs, (params,), (tangent,))
        h = 1e-6
        plus = outputs(tuple(p + h * t for p, t in zip(params, tangent)))
        minus = outputs(tuple(p - h * t for p, t in zip(params, tangent)))
        for d, hi, lo in zip(derivative, plus, minus):
            np.testing.assert_allclose(np.asarray(d), (np.asarray(hi) - np.asarray(lo)) / (2 * h), rtol=1e-6, atol=1e-8)


def test_a_batch_of_shapes_samples_each_member():
    a, b, c = (np.stack([np.asarray(v0), np.asarray(v1)]) for v0, v1 in zip(OCTANT, registry.SPHERICAL_MEDIUM))
    batch = js.SphericalTriangle(*(jnp.asarray(v, jnp.float32) for v in (a, b, c)))
    assert batch.batch_shape == (2,)
    u = jnp.asarray(np.random.default_rng(5).random((4, 1, 2)), jnp.float32)
    x = np.asarray(batch.warp(u))
    assert x.shape == (4, 2, 3)
    for k in range(2):
        member = js.SphericalTriangle(*(jnp.asarray(v[k], jnp.float32) for v in (a, b, c)))
        np.testing.assert_allclose(x[:, k], np.asarray(member.warp(u[:, 0])), atol=1e-6)
    assert batch.sample(jax.random.key(0), (5,)).shape == (5, 2, 3)


def test_the_difference_of_two_close_ratios_keeps_full_precision():
    """same_sign_difference (h₁ - h₀ of a short, far edge): within 4 ε of the float64 value, where
    the plain difference of the rounded ratios loses ~ε |y| / (y₁ - y₀) (1e-3 here)."""
    from jaxsample.samplers._spherical import same_sign_difference

    y0 = np.float32(1.7)
    for height in (np.float32(1e-4), np.float32(3e-3)):
        y1 = np.float32(y0 + height)
        scale2 = np.float32(0.37)
        r0, r1 = np.sqrt(scale2 + y0 * y0), np.sqrt(scale2 + y1 * y1)
        got = float(same_sign_difference(jnp.float32(y1), jnp.float32(y0), jnp.float32(r1), jnp.float32(r0),
                                         jnp.float32(scale2), jnp.float32(height)))
        y0_64, y1_64 = float(y0), float(y0) + float(height)
        exact = y1_64 / np.sqrt(0.37 + y1_64 ** 2) - y0_64 / np.sqrt(0.37 + y0_64 ** 2)
        assert abs(got / exact - 1) < 4 * np.finfo(np.float32).eps, (height, got, exact)
