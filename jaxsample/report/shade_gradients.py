"""`shade`'s gradients against finite differences of the float64 reference, per strategy and mode,
and what the silhouettes' boundary term costs. Shared by the tests and the report; run alone:
`python -m jaxsample.report.shade_gradients [--quick] [--out DIR]`.

The configurations: grazing views, lights at the horizon, a shading point close to the light,
exponents from 1 to 1000, tilted normals, small and large lights, each under a sphere light and a
triangle light.

Each configuration is (point, normal, wo, exponent, albedo, light); the differentiated parameters
are the BRDF's log-exponent and albedo and every parameter of the light (a sphere's centre, radius
and radiance; a triangle's three vertices and radiance).
"""

from __future__ import annotations

import functools

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
    ((0, 0, 0), (-0.4, 0.0, 0.92), (0.0, 0.0, 1.0), 8.0, 0.9,
     (-1.8, -0.5, 0.2), (-1.8, 0.5, 0.2), (-1.9, 0.0, 1.0), 2.0),
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
    e1 = np.cross(axis, helper)
    e1 /= np.linalg.norm(e1)
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


QUADRATURE = dict(panels=16, order=8, azimuth=128)
STRATEGY_MODES = [(strategy, mode) for mode in ("attached", "detached") for strategy in ("mis", "brdf", "light")]
_REFERENCES = {}


def references(kind):
    """(configurations, parameters) reference gradients, computed once per process."""
    if kind not in _REFERENCES:
        rows = CASES[kind][0]
        _REFERENCES[kind] = np.stack([reference_gradient(kind, row, **QUADRATURE)[1] for row in rows])
    return _REFERENCES[kind]


def parameter_names(kind):
    """Names of the flat parameter vector's entries (`ravel_pytree` order: sorted keys)."""
    params = CASES[kind][1](CASES[kind][0][0])
    names = []
    for key in sorted(params):
        size = np.size(params[key])
        names += [key] if size == 1 else [f"{key}[{i}]" for i in range(size)]
    return names


@functools.lru_cache(maxsize=None)
def _program(kind, strategy, mode, n, boundary):
    """jit: (geometry, params, keys) -> flat (means, stderrs) per configuration; one per process for
    each (kind, strategy, mode, n, boundary), so the cost table reuses the z-table's compiled programs
    at the same n."""
    import jax
    from jax.flatten_util import ravel_pytree

    rows, to_params, to_scene = CASES[kind]

    def one(geometry, params, key):
        return scene.shade_grad(lambda q: to_scene(geometry, q), params, key, n, strategy=strategy, mode=mode,
                                boundary_term=boundary)

    def run(geometry, params, keys):
        # lax.map, not vmap, over configurations: the same values, and a smaller program to compile.
        def each(args):
            est = one(*args)
            return ravel_pytree(est.mean)[0], ravel_pytree(est.stderr)[0]
        return jax.lax.map(each, (geometry, params, keys))

    return jax.jit(run)


def _inputs(kind, seed):
    import jax

    rows, to_params, _ = CASES[kind]
    geometry = tuple(jnp.asarray(np.array([row[i] for row in rows], float), jnp.float32) for i in range(3))
    params = jax.tree_util.tree_map(lambda *xs: jnp.asarray(np.stack(xs), jnp.float32),
                                    *[to_params(row) for row in rows])
    return geometry, params, jax.random.split(jax.random.key(seed), len(rows))


def gradients(kind, strategy, mode, n=4096, seed=23, boundary=True):
    """(means, stderrs): (configurations, parameters) arrays from one vmapped `shade_grad` call."""
    means, stderrs = _program(kind, strategy, mode, n, boundary)(*_inputs(kind, seed))
    return np.asarray(means), np.asarray(stderrs)


def z_scores(kind, strategy, mode, n=4096, seed=23, boundary=True):
    """(gradient − reference) / stderr per configuration and parameter; the reference's own error
    (quadrature at a horizon kink, differencing) is below 1e-4 relative and is added in quadrature."""
    means, stderrs = gradients(kind, strategy, mode, n, seed, boundary)
    reference = references(kind)
    return (means - reference) / np.sqrt(stderrs ** 2 + (1e-4 * np.abs(reference) + 1e-7) ** 2)


def z_table(n=4096, seed=23, progress=print, quick=False):
    """One row per light, strategy and mode, with and without the boundary term: the mean of z²
    (about 1 when unbiased with honest error bars), the largest |z| and where it is. `quick`: every
    strategy attached and "mis" detached with the term, the estimators without the term for
    attached "mis" and "brdf" only."""
    rows = []
    for kind in CASES:
        names = parameter_names(kind)
        for strategy, mode in STRATEGY_MODES:
            for boundary in (True, False):
                if quick and mode == "detached" and (strategy != "mis" or not boundary):
                    continue
                if quick and not boundary and strategy == "light":
                    continue
                progress(f"  shade gradients: {kind} light, {strategy}, {mode}, "
                         f"boundary term {'on' if boundary else 'off'}")
                z = z_scores(kind, strategy, mode, n, seed, boundary)
                worst = np.unravel_index(int(np.argmax(np.abs(z))), z.shape)
                rows.append({"light": kind, "strategy": strategy, "mode": mode,
                             "boundary_term": "yes" if boundary else "no", "configurations": z.shape[0],
                             "parameters": z.shape[1], "mean_z2": float(np.mean(z ** 2)),
                             "max_abs_z": float(np.max(np.abs(z))),
                             "within_3_sigma": float(np.mean(np.abs(z) < 3.0)),
                             "worst": f"configuration {worst[0]}, {names[worst[1]]}"})
    return rows


def cost_table(n=1 << 14, seed=29, repeats=3, progress=print, strategies=("mis", "brdf")):
    """Time per gradient sample and gradient variance x time, with and without the boundary term,
    per light and strategy (attached), medians of `repeats` timed runs after a compile. (Light
    sampling of one light, attached, adds no term: its samples follow the rim.)"""
    import time

    rows = []
    for kind in CASES:
        for strategy in strategies:
            measured = {}
            for boundary in (True, False):
                progress(f"  boundary-term cost: {kind} light, {strategy}, term {'on' if boundary else 'off'}")
                program = _program(kind, strategy, "attached", n, boundary)
                inputs = _inputs(kind, seed)
                means, stderrs = program(*inputs)
                np.asarray(means)
                times = []
                for _ in range(repeats):
                    start = time.perf_counter()
                    np.asarray(program(*inputs)[0])
                    times.append(time.perf_counter() - start)
                per_sample = float(np.median(times)) / (n * len(CASES[kind][0]))
                variance = np.asarray(stderrs) ** 2 * n
                measured[boundary] = (per_sample, variance)
            (with_time, with_var), (without_time, without_var) = measured[True], measured[False]
            ratio = with_var / np.where(without_var > 0, without_var, np.nan)
            rows.append({"light": kind, "strategy": strategy, "ns_per_gradient_sample": 1e9 * with_time,
                         "ns_without_term": 1e9 * without_time, "time_ratio": with_time / without_time,
                         "median_variance_ratio": float(np.nanmedian(ratio)),
                         "median_variance_x_time_ratio": float(np.nanmedian(ratio)) * with_time / without_time})
    return rows


def value_cost_table(n=1 << 22, repeats=5, progress=print):
    """ns per radiance evaluation of `shade`'s value (no gradient) with and without the boundary
    term in the program, the first configuration of each light: the term is a custom JVP whose
    value is never computed, so the two should match (medians of `repeats` runs)."""
    import time

    import jax

    rows = []
    for kind in CASES:
        rows_of_kind, to_params, to_scene = CASES[kind]
        row = rows_of_kind[0]
        geometry = tuple(jnp.asarray(v, jnp.float32) for v in row[:3])
        params = {k: jnp.asarray(v, jnp.float32) for k, v in to_params(row).items()}
        for strategy in ("mis", "brdf"):
            measured = {}
            for boundary in (True, False):
                progress(f"  value cost: {kind} light, {strategy}, term {'in' if boundary else 'out'}")

                def run(key, boundary=boundary):
                    return scene.shade(*to_scene(geometry, params), key, n, strategy=strategy,
                                       boundary_term=boundary).mean

                program = jax.jit(run)
                program(jax.random.key(0)).block_until_ready()
                times = []
                for i in range(repeats):
                    start = time.perf_counter()
                    program(jax.random.key(i + 1)).block_until_ready()
                    times.append(time.perf_counter() - start)
                measured[boundary] = 1e9 * float(np.median(times)) / n
            rows.append({"light": kind, "strategy": strategy, "ns_with_term": measured[True],
                         "ns_without_term": measured[False], "ratio": measured[True] / measured[False]})
    return rows


def markdown(z_rows, cost_rows, value_rows=()) -> str:
    lines = ["z = (gradient − reference)/stderr for every parameter of 12 configurations per light (a gradient "
             "that is exactly 0 ± 0 gets the reference's own error, 1e-4 relative, as its stderr).", "",
             "| light | strategy | mode | boundary term | mean z² | max abs z | within 3σ | worst |",
             "|---|---|---|---|---|---|---|---|"]
    for r in z_rows:
        lines.append(f"| {r['light']} | {r['strategy']} | {r['mode']} | {r['boundary_term']} | {r['mean_z2']:.2f} | "
                     f"{r['max_abs_z']:.1f} | {r['within_3_sigma']:.1%} | {r['worst']} |")
    lines += ["", "| light | strategy (attached) | ns / gradient sample | without the term | time ratio | "
              "variance ratio (median) | variance x time ratio |", "|---|---|---|---|---|---|---|"]
    for r in cost_rows:
        lines.append(f"| {r['light']} | {r['strategy']} | {r['ns_per_gradient_sample']:.0f} "
                     f"| {r['ns_without_term']:.0f} | {r['time_ratio']:.2f} | {r['median_variance_ratio']:.2f} "
                     f"| {r['median_variance_x_time_ratio']:.2f} |")
    if value_rows:
        lines += ["",
                  "| light | strategy (value only) | ns / evaluation, term in the program | term left out | ratio |",
                  "|---|---|---|---|---|"]
        for r in value_rows:
            lines.append(f"| {r['light']} | {r['strategy']} | {r['ns_with_term']:.1f} | {r['ns_without_term']:.1f} | "
                         f"{r['ratio']:.2f} |")
    return "\n".join(lines) + "\n"


def main(argv=None):
    import argparse
    import json
    import os

    parser = argparse.ArgumentParser(
        description="shade's gradients against the reference, and the boundary term's cost")
    parser.add_argument("--quick", action="store_true", help="without the boundary term: attached mis and brdf only")
    parser.add_argument("--out", default=None, help="directory for shade_gradients.json")
    args = parser.parse_args(argv)
    z_rows = z_table(quick=args.quick)
    cost_rows = cost_table(strategies=("mis", "brdf") if args.quick else ("mis", "brdf", "light"))
    value_rows = value_cost_table()
    print(markdown(z_rows, cost_rows, value_rows))
    if args.out:
        os.makedirs(args.out, exist_ok=True)
        with open(os.path.join(args.out, "shade_gradients.json"), "w") as fh:
            json.dump({"z": z_rows, "cost": cost_rows, "value_cost": value_rows}, fh, indent=1)
    return 0


if __name__ == "__main__":
    import sys
    sys.exit(main())
