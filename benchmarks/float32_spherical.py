"""Float32 failure rates of solid-angle sampling of spherical triangles and rectangles, jaxsample's
beside the textbook formulas as PBRT-v4 writes them, at the same uniforms and shapes:
`python benchmarks/float32_spherical.py` (a few minutes on 2 cores; `--shapes 6 --points 1024` takes ~15 s).

Shapes. For each target solid angle Ω (1, 1e-2, 1e-4, 4e-6, 1e-6, 4e-8 and 1e-8 sr, and two near
the hemisphere, 2π - 0.1 and 2π - 0.01), `--shapes` random triangles (random vertices about a
random centre at distance 1 to 3, scaled about it to the target) and as many random rectangles
(random centre and orientation, aspect 1 to 3), built in float64 and then rounded to float32: the
float32 vertices are the shape, and Ω is their float64 Van Oosterom–Strackee solid angle. The
near-hemisphere shapes are seen from a point just off their plane, inside them. The same
`--points` uniforms (a NumPy float32 draw in [0, 1)²) serve every routine and shape.

Routines. jaxsample's `SphericalTriangle` and `SphericalRectangle` in float32, and, written here
in NumPy float32 from the formulas (our code, not PBRT's): Arvo's algorithm as PBRT-v4
`SampleSphericalTriangle` computes it (vertex angles from normalised edge-plane normals with
the half-angle `AngleBetween`, A = α + β + γ - π, the cos β' solve with FMA-exact difference and
sum of products, here emulated by forming the products in float64), and Ureña et al.'s as PBRT-v4
`SampleSphericalRectangle` (interior angles the same way, Ω = Σ g_i - 2π summed in float64 as
PBRT does, without its fall-back to area sampling below 1e-3 sr; PBRT's Triangle::Sample also
falls back, below 3e-4 sr, and then its density is not 1/Ω).

Counted invalid: a NaN or inf in the sample or its density, a density <= 0, a sample off the
unit sphere (| |ω| - 1 | > 1e-5), or outside the shape by more than 1e-6 rad (beyond an edge's
great circle; rounding alone puts a float32 sample within ~1e-7 of it). Misplaced (of the valid
samples with u in [1e-3, 1 - 1e-3]²): the exact inverse (jaxsample's map evaluated in float64 on
the float32 shape; it is Arvo's and Ureña's map, the one PBRT computes) of the float32 sample
differs from u by more than 10x the yardstick, the largest |Δu| that turning the exact sample by
2^-24 rad (half an ulp of 1: the most that rounding a unit vector to float32 can move it) in a
random direction causes for that shape. Density error: max |1/pdf - Ω| / Ω over the valid
samples. Round trip (jaxsample only): max |inverse(warp(u)) - u| in float32 over the same u, in
units of the yardstick (1 or below: as exact as float32 can hold the sample; near the hemisphere Arvo's map shears
and the triangle's float32 error grows past it, which is shown as is).
"""

from __future__ import annotations

import argparse

import jax
import jax.numpy as jnp
import numpy as np

import jaxsample as js

F32 = np.float32
TARGETS = (1.0, 1e-2, 1e-4, 4e-6, 1e-6, 4e-8, 1e-8)
NEAR_HEMISPHERE = (0.1, 0.01)  # 2π - Ω
OUTSIDE_TOLERANCE = 1e-6  # radians
MISPLACED = 10.0  # times what rounding the exact sample to float32 can cost in u


# ---------------------------------------------------------------------------------------------
# Float64 geometry of the shapes (the references)
# ---------------------------------------------------------------------------------------------


def solid_angle64(a, b, c):
    """Van Oosterom–Strackee in float64 on unit vectors (the reference Ω of a triangle)."""
    a, b, c = (np.asarray(v, np.float64) / np.linalg.norm(v, axis=-1, keepdims=True) for v in (a, b, c))
    triple = np.abs(np.sum(a * np.cross(b, c), -1))
    return 2.0 * np.arctan2(triple, 1.0 + np.sum(a * b, -1) + np.sum(b * c, -1) + np.sum(c * a, -1))


def outside_distance(vertices, w):
    """max over edges of the angular distance of w beyond the edge's great circle (<= 0 inside)."""
    v = [np.asarray(p, np.float64) for p in vertices]
    sign = np.sign(np.sum(v[0] * np.cross(v[1] - v[0], v[2] - v[0]), -1))[..., None]
    w = w / np.linalg.norm(w, axis=-1, keepdims=True)
    worst = np.full(w.shape[:-1], -np.inf)
    for k in range(len(v)):
        normal = np.cross(v[k], v[(k + 1) % len(v)] - v[k]) * sign
        worst = np.maximum(worst, -np.sum(w * normal, -1) / np.linalg.norm(normal, axis=-1))
    return worst


def _scaled_to(make, omega, rng):
    """make(scale) -> shape vertices; bisect the scale (log) until the solid angle is omega."""
    while True:
        build = make(rng)
        low, high = 1e-12, 1e4
        for _ in range(200):
            s = np.sqrt(low * high)
            got = build(s)[1]
            low, high = (s, high) if got < omega else (low, s)
        shape, got = build(s)
        if abs(got / omega - 1.0) < 1e-3:
            return shape


def random_triangle(rng):
    centre = rng.normal(size=3)
    centre *= rng.uniform(1.0, 3.0) / np.linalg.norm(centre)
    offsets = rng.normal(size=(3, 3))

    def build(s):
        a, b, c = (centre + s * o for o in offsets)
        return (a, b, c), solid_angle64(a, b, c)

    return build


def _frame(rng):
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q[:, 0], q[:, 1], q[:, 2]


def random_rectangle(rng):
    centre = rng.normal(size=3)
    centre *= rng.uniform(1.0, 3.0) / np.linalg.norm(centre)
    x, y, _ = _frame(rng)
    aspect = rng.uniform(1.0, 3.0)

    def build(s):
        eu, ev = s * aspect * x, s * y
        corner = centre - 0.5 * (eu + ev)
        return (corner, eu, ev), _rectangle_solid_angle(corner, eu, ev)

    return build


def _rectangle_solid_angle(corner, eu, ev):
    v = rectangle_vertices(corner, eu, ev)
    return solid_angle64(v[0], v[1], v[2]) + solid_angle64(v[0], v[2], v[3])


def rectangle_vertices(corner, eu, ev):
    return corner, corner + eu, corner + eu + ev, corner + ev


def near_hemisphere_triangle(gap, rng):
    """A triangle seen from just off its plane, inside it: Ω = 2π - gap."""
    x, y, z = _frame(rng)
    angles = rng.uniform(0, 2 * np.pi) + np.array([0.0, 2.1, 4.2]) + rng.uniform(-0.3, 0.3, 3)
    radius = rng.uniform(0.5, 2.0, 3)
    low, high = 1e-12, 10.0
    for _ in range(200):
        h = np.sqrt(low * high)
        verts = [r * (np.cos(t) * x + np.sin(t) * y) - h * z for r, t in zip(radius, angles)]
        got = solid_angle64(*verts)
        low, high = (low, h) if 2 * np.pi - got > gap else (h, high)
    return tuple(verts)


def near_hemisphere_rectangle(gap, rng):
    x, y, z = _frame(rng)
    w, hgt = rng.uniform(1.0, 3.0, 2)
    fx, fy = rng.uniform(0.2, 0.8, 2)
    low, high = 1e-12, 10.0
    for _ in range(200):
        h = np.sqrt(low * high)
        corner = -fx * w * x - fy * hgt * y - h * z
        got = _rectangle_solid_angle(corner, w * x, hgt * y)
        low, high = (low, h) if 2 * np.pi - got > gap else (h, high)
    return corner, w * x, hgt * y


# ---------------------------------------------------------------------------------------------
# The textbook routines, NumPy float32
# ---------------------------------------------------------------------------------------------


def _dot(p, q):
    return np.sum(p * q, axis=-1, dtype=p.dtype)


def _normalize(p):
    return p / np.sqrt(_dot(p, p))[..., None]


def _angle_between(v1, v2):
    """The half-angle form of the angle between unit vectors (PBRT-v4 `AngleBetween`)."""
    d = _dot(v1, v2)
    half_sum = np.arcsin(np.clip(np.sqrt(_dot(v1 + v2, v1 + v2)) / F32(2), -1, 1))
    half_diff = np.arcsin(np.clip(np.sqrt(_dot(v2 - v1, v2 - v1)) / F32(2), -1, 1))
    return np.where(d < 0, F32(np.pi) - F32(2) * half_sum, F32(2) * half_diff).astype(np.float32)


def _products(a, b, c, d, sign):
    """a b + sign c d rounded once (the FMA forms DifferenceOfProducts / SumOfProducts)."""
    return (a.astype(np.float64) * b + sign * (c.astype(np.float64) * d)).astype(np.float32)


def textbook_triangle(a, b, c, u):
    """(w, pdf) of Arvo's algorithm as PBRT-v4 computes it; a, b, c float32 (3,), u float32 (N, 2)."""
    with np.errstate(all="ignore"):
        a, b, c = _normalize(a), _normalize(b), _normalize(c)
        n_ab, n_bc, n_ca = _normalize(np.cross(a, b)), _normalize(np.cross(b, c)), _normalize(np.cross(c, a))
        alpha, beta, gamma = _angle_between(n_ab, -n_ca), _angle_between(n_bc, -n_ab), _angle_between(n_ca, -n_bc)
        a_pi = alpha + beta + gamma
        ap_pi = (F32(1) - u[:, 0]) * F32(np.pi) + u[:, 0] * a_pi
        area = a_pi - F32(np.pi)
        pdf = np.full(len(u), F32(0) if area <= 0 else F32(1) / area, np.float32)
        cos_a, sin_a = np.cos(alpha), np.sin(alpha)
        sin_phi = np.sin(ap_pi) * -cos_a + np.cos(ap_pi) * sin_a
        cos_phi = np.cos(ap_pi) * -cos_a - np.sin(ap_pi) * sin_a
        k1 = cos_phi - cos_a
        k2 = sin_phi + sin_a * _dot(a, b)
        cos_bp = ((_products(k2, cos_phi, k1, sin_phi, -1) * cos_a - k2)
                  / (_products(k2, sin_phi, k1, cos_phi, 1) * sin_a))
        cos_bp = np.clip(cos_bp, -1, 1)
        sin_bp = np.sqrt(np.maximum(F32(0), F32(1) - cos_bp * cos_bp))
        cp = cos_bp[:, None] * a + sin_bp[:, None] * _normalize(c - _dot(c, a) * a)
        cos_t = F32(1) - u[:, 1] * (F32(1) - _dot(cp, b))
        sin_t = np.sqrt(np.maximum(F32(0), F32(1) - cos_t * cos_t))
        w = cos_t[:, None] * b + sin_t[:, None] * _normalize(cp - _dot(cp, b)[:, None] * b)
    return w, pdf


def textbook_rectangle(corner, eu, ev, u):
    """(w, pdf) of Ureña et al.'s algorithm as PBRT-v4 computes it, without its area fall-back."""
    with np.errstate(all="ignore"):
        lu, lv = np.sqrt(_dot(eu, eu)), np.sqrt(_dot(ev, ev))
        x, y = eu / lu, ev / lv
        z = np.cross(x, y)
        x0, y0, z0 = _dot(corner, x), _dot(corner, y), _dot(corner, z)
        if z0 > 0:
            z, z0 = -z, -z0
        x1, y1 = x0 + lu, y0 + lv
        v00, v01 = np.array([x0, y0, z0], F32), np.array([x0, y1, z0], F32)
        v10, v11 = np.array([x1, y0, z0], F32), np.array([x1, y1, z0], F32)
        n0, n1 = _normalize(np.cross(v00, v10)), _normalize(np.cross(v10, v11))
        n2, n3 = _normalize(np.cross(v11, v01)), _normalize(np.cross(v01, v00))
        g0, g1 = _angle_between(-n0, n1), _angle_between(-n1, n2)
        g2, g3 = _angle_between(-n2, n3), _angle_between(-n3, n0)
        omega = F32(float(g0) + float(g1) + float(g2) + float(g3) - 2.0 * np.pi)
        pdf = np.full(len(u), max(F32(0), F32(1) / omega) if omega > 0 else F32(0), np.float32)
        b0, b1 = n0[2], n2[2]
        au = u[:, 0] * omega - g2 - g3
        fu = (np.cos(au) * b0 - b1) / np.sin(au)
        cu = np.copysign(F32(1) / np.sqrt(fu * fu + b0 * b0), fu)
        cu = np.clip(cu, -F32(1 - 2 ** -24), F32(1 - 2 ** -24))
        xu = np.clip(-(cu * z0) / np.sqrt(np.maximum(F32(0), F32(1) - cu * cu)), x0, x1)
        dd = np.sqrt(xu * xu + z0 * z0)
        h0 = y0 / np.sqrt(dd * dd + y0 * y0)
        h1 = y1 / np.sqrt(dd * dd + y1 * y1)
        hv = h0 + u[:, 1] * (h1 - h0)
        yv = np.where(hv * hv < F32(1 - 1e-6), hv * dd / np.sqrt(F32(1) - hv * hv), y1)
        w = _normalize(xu[:, None] * x + yv[:, None] * y + z0 * z)
    return w, pdf


# ---------------------------------------------------------------------------------------------
# jaxsample's, float32 (and float64 for the round trip's yardstick)
# ---------------------------------------------------------------------------------------------


@jax.jit
def _ours(sampler, u):
    x, p = sampler.warp_with_pdf(u)
    return x, p


@jax.jit
def _round_trip(sampler, u):
    return sampler.inverse(sampler.warp(u))


@jax.jit
def _inverse(sampler, x):
    return sampler.inverse(x)


@jax.jit
def _warp(sampler, u):
    return sampler.warp(u)


def _exact(make, params32, u):
    """(a float64 inverse, the yardstick): the exact map is the sampler evaluated in float64 on the
    float32 shape; the yardstick is max over the inner u of |u' - u|, u' the float64 inverse of the
    exact sample turned by 2^-24 rad (half an ulp of 1, the most that rounding a unit vector to
    float32 moves it) in a random direction: what float32's rounding of the sample can cost."""
    with jax.enable_x64(True):
        sampler = make(*(jnp.asarray(p, jnp.float64) for p in params32))
        exact = np.asarray(_warp(sampler, jnp.asarray(u, jnp.float64)))
        turn = np.random.default_rng(0).normal(size=exact.shape)
        turn -= np.sum(turn * exact, -1, keepdims=True) * exact
        turned = exact + 2.0 ** -24 * turn / np.linalg.norm(turn, axis=-1, keepdims=True)
        floor = np.abs(np.asarray(_inverse(sampler, jnp.asarray(turned))) - u)

        def inverse(w):
            w = np.where(np.isfinite(w), w, 1.0)
            return np.asarray(_inverse(sampler, jnp.asarray(np.asarray(w, np.float64))))

    inner = np.all((u >= 1e-3) & (u <= 1 - 1e-3), -1)
    return inverse, float(np.max(floor[inner]))


def _score(vertices, w, p, omega, u, inverse, floor):
    """(invalid count, misplaced count, density errors of the valid samples)."""
    w = np.asarray(w, np.float64)
    p = np.asarray(p, np.float64)
    bad = ~np.all(np.isfinite(w), -1) | ~np.isfinite(p) | (p <= 0)
    w = np.where(bad[:, None], 1.0, w)
    bad |= np.abs(np.linalg.norm(w, axis=-1) - 1.0) > 1e-5
    bad |= outside_distance(vertices, w) > OUTSIDE_TOLERANCE
    inner = np.all((u >= 1e-3) & (u <= 1 - 1e-3), -1)
    with jax.enable_x64(True):
        off = np.max(np.abs(inverse(w) - u), -1)
    misplaced = ~bad & inner & (off > MISPLACED * floor)
    with np.errstate(all="ignore"):
        error = np.abs(1.0 / p[~bad] - omega) / omega
    return int(bad.sum()), int(misplaced.sum()), int(inner.sum()), error


def measure(kind: str, shapes, u):
    """Rows: the Ω label, then for ours and the textbook (invalid %, misplaced %, max density
    error), then our float32 round trip over the rounding floor."""
    make = js.SphericalTriangle if kind == "triangle" else js.SphericalRectangle
    textbook = textbook_triangle if kind == "triangle" else textbook_rectangle
    inner = np.all((u >= 1e-3) & (u <= 1 - 1e-3), -1)
    rows = []
    for label, group in shapes:
        totals = {"ours": [0, 0, 0, []], "textbook": [0, 0, 0, []]}
        ratios = []
        for params in group:
            params32 = tuple(np.asarray(p, np.float32) for p in params)
            p64 = tuple(p.astype(np.float64) for p in params32)
            vertices = p64 if kind == "triangle" else rectangle_vertices(*p64)
            omega = solid_angle64(*p64) if kind == "triangle" else _rectangle_solid_angle(*p64)
            sampler = make(*(jnp.asarray(q) for q in params32))
            inverse, floor = _exact(make, params32, u.astype(np.float64))
            x, p = _ours(sampler, jnp.asarray(u))
            for name, (w, density) in (("ours", (x, p)), ("textbook", textbook(*params32, u))):
                bad, misplaced, count, error = _score(vertices, w, density, omega, u, inverse, floor)
                totals[name][0] += bad
                totals[name][1] += misplaced
                totals[name][2] += count
                totals[name][3].append(error)
            trip = np.asarray(_round_trip(sampler, jnp.asarray(u)))
            ratios.append(np.max(np.abs(trip - u)[inner]) / floor)
        cells = []
        for name in ("ours", "textbook"):
            bad, misplaced, count, errors = totals[name]
            errors = np.concatenate(errors)
            cells += [100.0 * bad / (len(group) * len(u)), 100.0 * misplaced / count,
                      float(np.max(errors)) if errors.size else float("nan")]
        rows.append((label, *cells, float(np.max(ratios))))
    return rows


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--shapes", type=int, default=32, help="random shapes per solid angle")
    parser.add_argument("--points", type=int, default=4096, help="uniforms per shape")
    parser.add_argument("--seed", type=int, default=20261201)
    args = parser.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    u = rng.random((args.points, 2)).astype(np.float32)
    for kind, random_shape, near in (("triangle", random_triangle, near_hemisphere_triangle),
                                      ("rectangle", random_rectangle, near_hemisphere_rectangle)):
        shapes = [(f"{omega:g}", [_scaled_to(random_shape, omega, rng) for _ in range(args.shapes)])
                  for omega in TARGETS]
        shapes += [(f"2π - {gap:g}", [near(gap, rng) for _ in range(args.shapes)]) for gap in NEAR_HEMISPHERE]
        rows = measure(kind, shapes, u)
        print(f"\n{kind}s: {args.shapes} shapes x {args.points} uniforms per row, float32")
        print("| Ω (sr) | jaxsample: invalid | misplaced | max \\|1/pdf - Ω\\|/Ω "
              "| PBRT-v4 formulas: invalid | misplaced | max \\|1/pdf - Ω\\|/Ω | jaxsample round trip / rounding |")
        print("|---|---|---|---|---|---|---|---|")
        for label, *cells, ratio in rows:
            a, b, c, d, e, f = cells
            print(f"| {label} | {a:.2f} % | {b:.2f} % | {c:.1e} | {d:.2f} % | {e:.2f} % | {f:.1e} | {ratio:.1f} |")

if __name__ == "__main__":
    main()
