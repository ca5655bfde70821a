"""The inverse problem: recover a Phong surface's exponent and albedo, and the light's position,
from observed radiance.

Run alone:  python -m jaxsample.report.inverse_problem [--quick] [--out DIR]
From the report:  run_inverse_problem(quick, out_dir) -> dict

Setup: a shading point at the origin with normal +z under one spherical light at a known distance
and radius. The "observations" are L_o for the true Phong(exponent=40, albedo=0.6) and the true
light direction (0.5 rad from the normal), seen from several view directions, computed by float64
quadrature (`jaxsample.scene.reference_radiance`), so they carry no Monte Carlo noise. Starting
10x off in exponent (4), at albedo 0.3 and with the light turned by (0.12, 0.1) rad, gradient
descent (Adam, written out below, on log n, logit albedo and the light's two angles) minimizes
the squared error Σ_v (L̂_v − L_v)², with `jax.grad` through `jaxsample.scene.shade` with its
default strategy (MIS, power heuristic), in attached and in detached mode, and with BRDF sampling
alone. Moving the light moves its silhouette: every one of these gradients carries the
silhouette's boundary term (`scene.direct`); without it the default MIS gradient of the light is
biased and BRDF sampling's is exactly 0 (`benchmarks/shade_gradients.py` compares the estimators with
and without the term).

The gradient of a squared Monte Carlo estimate is biased by its variance (E[(L̂ − L)²] =
(E L̂ − L)² + Var L̂). So each step draws two independent estimates per view and differentiates
stop_gradient(L̂_a − L) · L̂_b, whose gradient 2(L̂_a − L) ∂L̂_b/∂θ is unbiased for the gradient of
(E L̂ − L)²; the reported loss uses L̂_a.

Second experiment: ∂L_o/∂(light centre) for the true surface, by the default strategy attached and
detached, against central finite differences of the same estimator with common random numbers
(the same key, `jax.random.clone`) and of the quadrature reference.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

from jaxsample import scene

TRUE_EXPONENT = 40.0
TRUE_ALBEDO = 0.6
START_EXPONENT = 4.0
START_ALBEDO = 0.3
TRUE_LIGHT_ANGLES = (0.5, 0.0)       # polar angle from the normal, azimuth from -x
START_LIGHT_ANGLES = (0.62, 0.1)
# Adam's step per parameter: log n, logit albedo, and the light's two angles (radians).
LEARNING_RATES = (0.08, 0.08, 0.01, 0.01)
FITS = (("mis", "attached"), ("mis", "detached"), ("brdf", "attached"))
POINT = np.zeros(3)
NORMAL = np.array([0.0, 0.0, 1.0])
# The light's axis is 0.5 rad from the normal (toward -x); its half-angle is asin(0.12) ≈ 0.12 rad.
LIGHT_DIRECTION = np.array([-np.sin(0.5), 0.0, np.cos(0.5)])
LIGHT_DISTANCE = 4.0
LIGHT_RADIUS = 0.48
LIGHT_RADIANCE = 20.0
# View directions whose mirror directions sweep from the light's centre outward (in and out of
# the plane of incidence): the falloff of L_o across them fixes the exponent, its level the albedo.
VIEW_OFFSETS = [(0.0, 0.0), (0.08, 0.0), (0.16, 0.0), (0.25, 0.0), (0.35, 0.0), (0.0, 0.12), (0.1, 0.2),
                (-0.15, 0.0)]


def light(center=None):
    center = LIGHT_DISTANCE * LIGHT_DIRECTION if center is None else center
    return scene.SphereLight(jnp.asarray(center, jnp.float32), LIGHT_RADIUS, LIGHT_RADIANCE)


def light_center(theta, phi):
    """The light's centre at polar angle θ from the normal and azimuth φ (from −x), at the known distance."""
    return LIGHT_DISTANCE * jnp.stack([-jnp.sin(theta) * jnp.cos(phi), -jnp.sin(theta) * jnp.sin(phi), jnp.cos(theta)])


def view_directions():
    """wo for each view: the mirror direction is the light axis turned by (dθ, dφ-ish offsets)."""
    views = []
    for d_theta, d_side in VIEW_OFFSETS:
        theta = 0.5 + d_theta
        mirror = np.array([-np.sin(theta) * np.cos(d_side), np.sin(d_side), np.cos(theta) * np.cos(d_side)])
        mirror /= np.linalg.norm(mirror)
        views.append(mirror * np.array([-1.0, -1.0, 1.0]))  # wo = reflect(mirror) about +z
    return np.asarray(views, np.float32)


def observations(views):
    brdf = scene.Phong(TRUE_EXPONENT, TRUE_ALBEDO)
    return np.array([scene.reference_radiance(POINT, NORMAL, wo, brdf, light(), panels=96) for wo in views])


def _brdf(params):
    return scene.Phong(jnp.exp(params[0]), jax.nn.sigmoid(params[1]))


def make_step(views, observed, n, mode, learning_rate, strategy="mis"):
    views = jnp.asarray(views)
    observed = jnp.asarray(observed, jnp.float32)
    learning_rate = jnp.asarray(learning_rate, jnp.float32)

    def estimates(params, key):
        brdf = _brdf(params)
        lamp = light(light_center(params[2], params[3]))
        keys = jax.random.split(key, views.shape[0])
        return jax.vmap(lambda wo, k: scene.shade(POINT, NORMAL, wo, brdf, lamp, k, n, strategy=strategy,
                                                  mode=mode).mean)(views, keys)

    def surrogate(params, key):
        key_a, key_b = jax.random.split(key)
        residual = jax.lax.stop_gradient(estimates(params, key_a) - observed)
        # d/dθ of Σ residual·L̂_b is Σ residual ∂L̂_b/∂θ: half the gradient of the squared error.
        return 2.0 * jnp.sum(residual * estimates(params, key_b)), jnp.sum(residual * residual)

    @jax.jit
    def step(state, key):
        params, m, v, t = state
        grad, loss = jax.grad(surrogate, has_aux=True)(params, key)
        # Adam (Kingma & Ba 2015), β₁ = 0.9, β₂ = 0.999, bias-corrected moments.
        t = t + 1
        m = 0.9 * m + 0.1 * grad
        v = 0.999 * v + 0.001 * grad * grad
        m_hat = m / (1.0 - 0.9 ** t)
        v_hat = v / (1.0 - 0.999 ** t)
        params = params - learning_rate * m_hat / (jnp.sqrt(v_hat) + 1e-8)
        return (params, m, v, t), loss

    return step


def fit(views, observed, mode, iterations, n, key, learning_rate=LEARNING_RATES, strategy="mis"):
    step = make_step(views, observed, n, mode, learning_rate, strategy)
    params = jnp.array([np.log(START_EXPONENT), np.log(START_ALBEDO / (1 - START_ALBEDO)), *START_LIGHT_ANGLES],
                       jnp.float32)
    state = (params, jnp.zeros(4), jnp.zeros(4), jnp.zeros((), jnp.float32))
    history = {"loss": [], "exponent": [], "albedo": [], "light_theta": [], "light_phi": []}
    keys = jax.random.split(key, iterations)
    for i in range(iterations):
        values = np.asarray(state[0])
        history["exponent"].append(float(np.exp(values[0])))
        history["albedo"].append(float(1.0 / (1.0 + np.exp(-values[1]))))
        history["light_theta"].append(float(values[2]))
        history["light_phi"].append(float(values[3]))
        state, loss = step(state, keys[i])
        history["loss"].append(float(loss))
    # Average the parameters over the last fifth of the run: the iterates jitter with the noise
    # of the gradient (Polyak–Ruppert averaging).
    tail = max(iterations // 5, 1)
    exponent = float(np.exp(np.mean(np.log(history["exponent"][-tail:]))))
    albedo = float(np.mean(history["albedo"][-tail:]))
    theta, phi = (float(np.mean(history[name][-tail:])) for name in ("light_theta", "light_phi"))
    true_center = np.asarray(light_center(*TRUE_LIGHT_ANGLES))
    return {
        "strategy": strategy,
        "mode": mode,
        "iterations": iterations,
        "samples_per_estimate": n,
        "exponent": exponent,
        "albedo": albedo,
        "light_theta": theta,
        "light_phi": phi,
        "exponent_rel_error": abs(exponent - TRUE_EXPONENT) / TRUE_EXPONENT,
        "albedo_rel_error": abs(albedo - TRUE_ALBEDO) / TRUE_ALBEDO,
        "light_position_error": float(np.linalg.norm(np.asarray(light_center(theta, phi)) - true_center)),
        "initial_light_position_error": float(np.linalg.norm(np.asarray(light_center(*START_LIGHT_ANGLES))
                                                             - true_center)),
        "initial_loss": history["loss"][0],
        "final_loss": float(np.mean(history["loss"][-tail:])),
        "history": history,
    }


def light_position_gradient(n, key, step=1e-2):
    """∂L_o/∂centre for the true surface and the second view, by `shade_grad` for each strategy and
    mode (gradient ± stderr, the boundary term inside), against central differences of the
    quadrature reference; z = (gradient − reference)/stderr per component."""
    wo = jnp.asarray(view_directions()[1])
    brdf = scene.Phong(TRUE_EXPONENT, TRUE_ALBEDO)
    center = np.asarray(LIGHT_DISTANCE * LIGHT_DIRECTION, np.float64)
    reference = []
    for axis in range(3):
        offset = np.zeros(3)
        offset[axis] = step
        values = [scene.reference_radiance(POINT, NORMAL, wo, brdf, light(center + sign * offset), panels=96)
                  for sign in (1.0, -1.0)]
        reference.append((values[0] - values[1]) / (2 * step))
    reference = np.asarray(reference)
    rows = {}
    keys = jax.random.split(key, 4)
    for k, (strategy, mode) in zip(keys, (("mis", "attached"), ("mis", "detached"), ("brdf", "attached"),
                                          ("light", "attached"))):
        est = scene.shade_grad(lambda c: (POINT, NORMAL, wo, brdf, light(c)), jnp.asarray(center, jnp.float32), k, n,
                               strategy=strategy, mode=mode)
        mean, stderr = np.asarray(est.mean, float), np.asarray(est.stderr, float)
        rows[f"{strategy}, {mode}"] = {"gradient": mean.tolist(), "stderr": stderr.tolist(),
                                       "z": ((mean - reference) / np.maximum(stderr, 1e-12)).tolist()}
    return {
        "radiance": float(scene.reference_radiance(POINT, NORMAL, wo, brdf, light(center), panels=96)),
        "finite_difference_reference": reference.tolist(),
        "estimates": rows,
        "step": step,
        "samples": n,
    }


def _plot(results, out_dir):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    fig, axes = plt.subplots(1, 4, figsize=(16, 3.6))
    for run in results:
        h = run["history"]
        label = f"{run['strategy']}, {run['mode']}"
        axes[0].semilogy(h["loss"], label=label)
        axes[1].semilogy(h["exponent"], label=label)
        axes[2].plot(h["albedo"], label=label)
        axes[3].plot(h["light_theta"], label=label)
    axes[1].axhline(TRUE_EXPONENT, color="k", ls="--", lw=0.8, label="truth")
    axes[2].axhline(TRUE_ALBEDO, color="k", ls="--", lw=0.8, label="truth")
    axes[3].axhline(TRUE_LIGHT_ANGLES[0], color="k", ls="--", lw=0.8, label="truth")
    for ax, title in zip(axes, ["squared error (one estimate)", "exponent n", "albedo", "light polar angle (rad)"]):
        ax.set_title(title)
        ax.set_xlabel("iteration")
        ax.legend()
    fig.tight_layout()
    path = os.path.join(out_dir, "inverse_problem.png")
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def run_inverse_problem(quick: bool = True, out_dir=None, *, iterations: int | None = None,
                        samples: int | None = None, seed: int = 0) -> dict:
    """Both fits (attached, detached) and the light-position gradient check; returns a dict
    (histories included) and, when `out_dir` is given, writes inverse_problem.json and .png there."""
    start = time.perf_counter()
    iterations = iterations or (300 if quick else 600)
    samples = samples or (1024 if quick else 4096)
    key = jax.random.key(seed)
    fit_key, gradient_key = jax.random.split(key)
    views = view_directions()
    observed = observations(views)
    fits = [fit(views, observed, mode, iterations, samples, k, strategy=strategy)
            for (strategy, mode), k in zip(FITS, jax.random.split(fit_key, len(FITS)))]
    gradient = light_position_gradient(1 << 14 if quick else 1 << 17, gradient_key)
    result = {
        "truth": {"exponent": TRUE_EXPONENT, "albedo": TRUE_ALBEDO, "light_angles": TRUE_LIGHT_ANGLES},
        "start": {"exponent": START_EXPONENT, "albedo": START_ALBEDO, "light_angles": START_LIGHT_ANGLES},
        "observed": observed.tolist(),
        "fits": fits,
        "light_position_gradient": gradient,
        "plot": None,
        "quick": quick,
    }
    if out_dir is not None:
        os.makedirs(out_dir, exist_ok=True)
        result["plot"] = _plot(fits, out_dir)
        if result["plot"] is None:
            result["plot_skipped"] = "matplotlib is not importable"
        with open(os.path.join(out_dir, "inverse_problem.json"), "w") as fh:
            json.dump(result, fh, indent=1)
    result["seconds"] = time.perf_counter() - start
    return result


def markdown_summary(result) -> str:
    lines = [f"truth: exponent {TRUE_EXPONENT:g}, albedo {TRUE_ALBEDO:g}, light angles {TRUE_LIGHT_ANGLES}; "
             f"start: exponent {START_EXPONENT:g}, albedo {START_ALBEDO:g}, light angles {START_LIGHT_ANGLES}"]
    for f in result["fits"]:
        lines.append(f"{f['strategy']:>5}, {f['mode']:>8}: exponent {f['exponent']:.3f} (rel. error "
                     f"{f['exponent_rel_error']:.2%}), albedo {f['albedo']:.4f} (rel. error {f['albedo_rel_error']:.2%}), "
                     f"light centre off by {f['light_position_error']:.4f} (from {f['initial_light_position_error']:.3f}), "
                     f"loss {f['initial_loss']:.3e} -> {f['final_loss']:.3e} in {f['iterations']} iterations")
    g = result["light_position_gradient"]
    lines.append(f"dL_o/d(light centre) at L_o = {g['radiance']:.5f}, {g['samples']} evaluations each (shade_grad):")
    lines.append(f"  {'reference (finite differences)':>30}: " + ", ".join(f"{v:+.5f}" for v in g["finite_difference_reference"]))
    for name, row in g["estimates"].items():
        lines.append(f"  {name:>30}: " + ", ".join(f"{v:+.5f} ± {e:.5f}" for v, e in zip(row["gradient"], row["stderr"]))
                     + "   z: " + ", ".join(f"{z:+.1f}" for z in row["z"]))
    lines.append(f"plot: {result['plot'] or result.get('plot_skipped', 'not written (no --out)')}")
    lines.append(f"{result['seconds']:.1f} s")
    return "\n".join(lines)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer iterations and samples (< ~60 s on 2 cores)")
    parser.add_argument("--out", default="inverse_problem_out", help="directory for the JSON and the PNG")
    args = parser.parse_args(argv)
    result = run_inverse_problem(args.quick, args.out)
    print(markdown_summary(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
