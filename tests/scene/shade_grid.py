"""The configurations on which `shade`'s gradients are held to finite differences of the float64
reference (issue 23): grazing views, lights at the horizon, a shading point close to the light,
exponents from 1 to 1000, tilted normals, small and large lights. Shared by the tests and the report.

Each configuration is (point, normal, wo, exponent, albedo, light); the differentiated parameters
are the BRDF's log-exponent and albedo and every parameter of the light (a sphere's centre, radius
and radiance; a triangle's three vertices and radiance).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from jaxsample import scene

_UP = (0.0, 0.0, 1.0)


def _mirror_target(wo, normal, distance, offset):
    """A point at `distance` along the mirror direction of wo about normal, moved by `offset`
    (so that a small light's rim crosses a sharp lobe)."""
    wo, normal = np.asarray(wo, float), np.asarray(normal, float)
    wo, normal = wo / np.linalg.norm(wo), normal / np.linalg.norm(normal)
    mirror = 2.0 * (wo @ normal) * normal - wo
    return distance * mirror + np.asarray(offset, float)


# (point, normal, wo, exponent, albedo, sphere centre, radius, radiance)
SPHERES = [
    ((0, 0, 0), _UP, (0.3, 0.1, 1.0), 25.0, 0.8, (0.4, 0.3, 2.0), 0.5, 3.0),             # baseline
    ((0, 0, 0), _UP, (1.0, 0.0, 0.05), 25.0, 0.7, (-2.0, 0.1, 0.35), 0.4, 2.0),         # grazing view
    ((0, 0, 0), _UP, (-0.6, 0.0, 0.8), 5.0, 0.9, (2.0, 0.5, 0.15), 0.4, 4.0),           # light at the horizon
    ((0, 0, 0), _UP, (0.2, 0.0, 1.0), 10.0, 0.6, (0.1, 0.0, 0.75), 0.5, 1.0),           # point close to the light
    ((0, 0, 0), _UP, (0.0, 0.4, 1.0), 1.0, 0.5, (0.5, -0.5, 1.5), 0.3, 5.0),            # exponent 1
    ((0, 0, 0), _UP, (0.3, 0.1, 1.0), 1000.0, 0.8,
     tuple(_mirror_target((0.3, 0.1, 1.0), _UP, 3.0, (0.0, 0.15, 0.0))), 0.15, 2.0),    # exponent 1000, rim on the lobe
    ((0, 0, 0), _UP, (0.5, -0.2, 1.0), 100.0, 0.9,
     tuple(_mirror_target((0.5, -0.2, 1.0), _UP, 2.0, (0.2, 0.0, 0.0))), 0.25, 2.0),    # exponent 100, rim on the lobe
    ((0, 0, 0), (0.3, -0.2, 0.93), (0.1, 0.3, 1.0), 20.0, 0.8,
     tuple(_mirror_target((0.1, 0.3, 1.0), (0.3, -0.2, 0.93), 1.8, (0.3, 0.0, 0.0))), 0.4, 2.0),  # tilted normal
    ((0, 0, 0), _UP, (0.2, 0.2, 1.0), 50.0, 0.8,
     tuple(_mirror_target((0.2, 0.2, 1.0), _UP, 2.0, (0.05, 0.0, 0.0))), 0.05, 50.0),   # small light
    ((0.5, -0.3, 0.0), _UP, (0.0, 0.0, 1.0), 3.0, 0.7, (0.5, -0.3, 3.0), 1.5, 1.0),     # large light overhead
    ((0, 0, 0), _UP, (0.9, 0.3, 0.2), 300.0, 0.8,
     tuple(_mirror_target((0.9, 0.3, 0.2), _UP, 2.5, (0.0, 0.0, 0.06))), 0.2, 3.0),     # exponent 300, low view
    ((0, 0, 0), (-0.4, 0.0, 0.92), (0.0, 0.0, 1.0), 8.0, 0.9, (-1.8, 0.0, 0.5), 0.5, 2.0),  # tilted, light low
]

# (point, normal, wo, exponent, albedo, a, b, c, radiance); vertices ordered so that the front
# face, (b - a) x (c - a), faces the shading point.
TRIANGLES = [
    ((0, 0, 0), _UP, (0.3, 0.1, 1.0), 25.0, 0.8, (-0.5, 0.2, 1.5), (0.1, 0.8, 1.2), (0.6, -0.3, 1.7), 3.0),
    ((0, 0, 0), _UP, (1.0, 0.0, 0.05), 25.0, 0.7, (-2.0, -0.5, 0.1), (-2.0, 0.5, 0.1), (-2.2, 0.0, 0.9), 2.0),
    ((0, 0, 0), _UP, (-0.6, 0.0, 0.8), 5.0, 0.9, (2.0, -0.6, -0.2), (2.0, 0.6, -0.2), (2.0, 0.0, 0.5), 4.0),
    ((0, 0, 0), _UP, (0.2, 0.0, 1.0), 10.0, 0.6, (-0.4, -0.4, 0.5), (0.5, -0.3, 0.6), (0.0, 0.5, 0.55), 1.0),
    ((0, 0, 0), _UP, (0.0, 0.4, 1.0), 1.0, 0.5, (0.3, -0.8, 1.4), (0.9, -0.2, 1.6), (0.4, -0.2, 1.3), 5.0),
    ((0, 0, 0), _UP, (0.3, 0.1, 1.0), 1000.0, 0.8, None, None, None, 2.0),   # filled in below: rim on the lobe
    ((0, 0, 0), _UP, (0.5, -0.2, 1.0), 100.0, 0.9, None, None, None, 2.0),
    ((0, 0, 0), (0.3, -0.2, 0.93), (0.1, 0.3, 1.0), 20.0, 0.8, None, None, None, 2.0),
    ((0, 0, 0), _UP, (0.2, 0.2, 1.0), 50.0, 0.8, None, None, None, 50.0),
    ((0.5, -0.3, 0.0), _UP, (0.0, 0.0, 1.0), 3.0, 0.7, (-1.0, -1.5, 2.0), (2.0, -1.5, 2.0), (0.5, 1.5, 2.0), 1.0),
    ((0, 0, 0), _UP, (0.9, 0.3, 0.2), 300.0, 0.8, None, None, None, 3.0),
    ((0, 0, 0), (-0.4, 0.0, 0.92), (0.0, 0.0, 1.0), 8.0, 0.9, (-1.8, -0.5, 0.2), (-1.8, 0.5, 0.2), (-1.9, 0.0, 1.0), 2.0),
]


def _facing(a, b, c, point):
    """(a, b, c) or (a, c, b): the order whose front face looks at `point`."""
    a, b, c, point = (np.asarray(v, float) for v in (a, b, c, point))
    normal = np.cross(b - a, c - a)
    return (a, b, c) if normal @ (point - a) > 0 else (a, c, b)


def _triangle_on_lobe(point, normal, wo, distance, size, offset):
    centre = _mirror_target(wo, normal, distance, offset) + np.asarray(point, float)
    axis = centre - np.asarray(point, float)
    axis /= np.linalg.norm(axis)
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(axis, helper); e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    angles = np.array([0.3, 2.4, 4.3])
    return [centre + size * (np.cos(t) * e1 + np.sin(t) * e2) for t in angles]


_LOBE_TRIANGLES = {5: (3.0, 0.15, (0.0, 0.12, 0.0)), 6: (2.0, 0.25, (0.18, 0.0, 0.0)),
                   7: (1.8, 0.4, (0.25, 0.0, 0.0)), 8: (2.0, 0.06, (0.04, 0.0, 0.0)),
                   10: (2.5, 0.2, (0.0, 0.0, 0.05))}
for _index, (_distance, _size, _offset) in _LOBE_TRIANGLES.items():
    _row = list(TRIANGLES[_index])
    _row[5:8] = _triangle_on_lobe(_row[0], _row[1], _row[2], _distance, _size, _offset)
    TRIANGLES[_index] = tuple(_row)
TRIANGLES = [tuple(row[:5]) + _facing(row[5], row[6], row[7], row[0]) + (row[8],) for row in TRIANGLES]


def sphere_params(row):
    _, _, _, exponent, albedo, centre, radius, radiance = row
    return {"log_exponent": np.log(exponent), "albedo": albedo, "centre": np.asarray(centre, float),
            "radius": radius, "radiance": radiance}


def triangle_params(row):
    _, _, _, exponent, albedo, a, b, c, radiance = row
    return {"log_exponent": np.log(exponent), "albedo": albedo, "a": np.asarray(a, float),
            "b": np.asarray(b, float), "c": np.asarray(c, float), "radiance": radiance}


def sphere_scene(geometry, params):
    point, normal, wo = geometry
    brdf = scene.Phong(jnp.exp(params["log_exponent"]), params["albedo"])
    return point, normal, wo, brdf, scene.SphereLight(params["centre"], params["radius"], params["radiance"])


def triangle_scene(geometry, params):
    point, normal, wo = geometry
    brdf = scene.Phong(jnp.exp(params["log_exponent"]), params["albedo"])
    return point, normal, wo, brdf, scene.TriangleLight(params["a"], params["b"], params["c"], params["radiance"])


CASES = {"sphere": (SPHERES, sphere_params, sphere_scene), "triangle": (TRIANGLES, triangle_params, triangle_scene)}


def reference_gradient(kind, row, step=1e-5, **quadrature):
    """Central differences of the float64 `reference_radiance` in every parameter, as a flat vector
    in `ravel_pytree` order (dict keys sorted), with the reference value."""
    from jax.flatten_util import ravel_pytree
    import jax

    rows, to_params, to_scene = CASES[kind]
    geometry = tuple(np.asarray(v, float) for v in row[:3])
    with jax.enable_x64(True):
        flat, unravel = ravel_pytree(jax.tree_util.tree_map(np.float64, to_params(row)))
        flat = np.asarray(flat, float)

        def value(theta):
            return scene.reference_radiance(*to_scene(geometry, unravel(jnp.asarray(theta))), **quadrature)

        grad = np.empty_like(flat)
        for i in range(flat.size):
            h = step * max(1.0, abs(flat[i]))
            up, down = flat.copy(), flat.copy()
            up[i] += h
            down[i] -= h
            grad[i] = (value(up) - value(down)) / (2.0 * h)
        return value(flat), grad
