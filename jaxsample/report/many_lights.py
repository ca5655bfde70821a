"""Many lights: how the choice among K sphere lights changes the error of a shading point.

Run alone: `python -m jaxsample.report.many_lights [--quick]`.

A Lambertian point under K sphere lights (`scene.SphereLights`, one batch) whose radiance spans four
orders of magnitude and whose distances run from 0.6 to 7.5, shaded with each selection rule ("uniform",
"power", "solid_angle") and each of "light" and "mis": estimate ± stderr against the closed form,
variance per evaluation, time per evaluation (interleaved medians) and variance × time against
uniform selection. The reference is exact: a sphere entirely above the horizon gives a Lambertian
point L (r/d)² cos θ times its albedo (the sphere's form factor, L π sin²α cos θ over π), and
transparent lights add.
"""

from __future__ import annotations

import argparse

import jax
import jax.numpy as jnp
import numpy as np

from .. import scene
from .timing import interleaved_medians

ALBEDO = 0.8
SELECTIONS = ("uniform", "power", "solid_angle")
STRATEGIES = ("light", "mis")


def lights_and_reference(count: int, seed: int = 0):
    """(SphereLights arrays, exact radiance): `count` spheres, radiance log-uniform on [1e-2, 1e2],
    radii on [0.05, 0.5], centres over [-4, 4]² x [0.6, 5]: each centre's height exceeds its radius,
    so every sphere lies wholly above the point's horizon (sin of its elevation z/d above sin α = r/d)."""
    rng = np.random.default_rng(seed)
    radii = rng.uniform(0.05, 0.5, count)
    centers = np.stack([rng.uniform(-4, 4, count), rng.uniform(-4, 4, count), rng.uniform(0.6, 5.0, count)], -1)
    distance = np.linalg.norm(centers, axis=-1)
    radiance = 10.0 ** rng.uniform(-2, 2, count)
    reference = ALBEDO * float(np.sum(radiance * (radii / distance) ** 2 * centers[:, 2] / distance))
    return (centers, radii, radiance), reference


def selection_table(quick: bool = True, progress=print) -> list[dict]:
    """One row per (selection, strategy) for K = 64 lights (`quick`, n = 2^14) or 1000 (n = 2^16)."""
    count, n = (64, 1 << 14) if quick else (1000, 1 << 16)
    (centers, radii, radiance), reference = lights_and_reference(count)
    point, normal, wo = jnp.zeros(3), jnp.array([0.0, 0.0, 1.0]), jnp.array([0.3, 0.1, 1.0])
    brdf = scene.Lambertian(ALBEDO)
    programs = {}
    for selection in SELECTIONS:
        lights = scene.SphereLights(jnp.asarray(centers, jnp.float32), jnp.asarray(radii, jnp.float32),
                                    jnp.asarray(radiance, jnp.float32), selection=selection)
        for strategy in STRATEGIES:
            programs[(selection, strategy)] = jax.jit(
                lambda k, lights=lights, strategy=strategy: scene.shade(point, normal, wo, brdf, lights, k, n,
                                                                        strategy=strategy))
    progress(f"[many lights] {count} sphere lights: {len(programs)} programs")
    estimates = {name: program(jax.random.key(23)) for name, program in programs.items()}
    seconds = interleaved_medians(programs, iter(jax.random.split(jax.random.key(24), 64)), repeats=3)
    rows = []
    for (selection, strategy), est in estimates.items():
        variance = float(est.variance)
        uniform = float(estimates[("uniform", strategy)].variance) * seconds[("uniform", strategy)]
        rows.append({"lights": count, "selection": selection, "strategy": strategy, "n": n, "mean": float(est.mean),
                     "stderr": float(est.stderr), "exact": reference,
                     "z": (float(est.mean) - reference) / float(est.stderr), "variance_per_evaluation": variance,
                     "ns_per_evaluation": 1e9 * seconds[(selection, strategy)] / n,
                     "variance_x_time_vs_uniform": variance * seconds[(selection, strategy)] / uniform})
    return rows


def markdown(rows: list[dict]) -> str:
    out = ["| lights | selection | strategy | estimate ± stderr | exact | z | variance per evaluation "
           "| ns per evaluation | variance × time, × uniform's |", "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        out.append(f"| {r['lights']} | {r['selection']} | {r['strategy']} | {r['mean']:.5g} ± {r['stderr']:.2g} | "
                   f"{r['exact']:.5g} | {r['z']:+.2f} | {r['variance_per_evaluation']:.3g} | "
                   f"{r['ns_per_evaluation']:.1f} | {r['variance_x_time_vs_uniform']:.3g} |")
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    print(markdown(selection_table(parser.parse_args().quick)))
