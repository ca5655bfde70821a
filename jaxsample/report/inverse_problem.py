"""The inverse problem: recover a Phong surface's exponent and albedo, and the light's position,
from observed radiance; and a GGX conductor's roughness under a rectangular light.

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

Third experiment, the roughness fit, in colour: a GGX rough conductor (`scene.RoughConductor`, gold's
RGB complex index) lit by a rectangular light (`scene.QuadLight`, solid-angle sampling) seen from four
views about the light's mirror direction; the observations are float64 quadratures at α = 0.2, one
radiance per channel, and the loss sums the squared error over views and channels.
Gradient descent on log α starts from α = 0.05, where the highlight is a quarter as wide: Adam (its
first moment decaying by 0.5, not 0.9: see ROUGHNESS_BETA1) on the unbiased surrogate above, each
view's estimate and gradient from independent keys (`conductor_quad_program`). The attached MIS
gradient of α moves the BRDF samples (visible-normal reflection) across the light's edges: the
silhouette's boundary term is part of it. The fit differentiates log α alone (its program has one
tangent per point, not four); the gradient checks take log α and the quad's corner (`--quick`: log α,
with the fit's compiled program) against central differences of the quadrature, on four
configurations (`CONDUCTOR_QUAD_CASES`).
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
        # lax.map, not vmap, over the views: the same values, and a program that compiles in about
        # half the time (vmap batches the streaming loop itself; docs/xla-cpu-paths.md).
        def one(args):
            wo, k = args
            return scene.shade(POINT, NORMAL, wo, brdf, lamp, k, n, strategy=strategy, mode=mode).mean

        return jax.lax.map(one, (views, keys))

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


# The roughness fit (third experiment).
TRUE_ROUGHNESS = 0.2
START_ROUGHNESS = 0.05
ROUGHNESS_LEARNING_RATE = 0.1
# Adam's first-moment decay for the one-parameter fit: 0.9 (the Phong fit's) overshoots α by 13 % and
# takes 100 steps to come back; with 0.5 the iterates reach the truth within 1 % in 40 steps.
ROUGHNESS_BETA1 = 0.5
# Gold's RGB complex index (`scene.CONDUCTOR_RGB`): the observations, the estimates and their gradients
# have one value per channel, all channels from the same samples.
CONDUCTOR_METAL = "gold"
CONDUCTOR_ETA, CONDUCTOR_K = (np.asarray(v) for v in scene.CONDUCTOR_RGB[CONDUCTOR_METAL])
CHANNELS = ("R", "G", "B")
# A 1 x 0.8 rectangle 2 above the point, its centre 0.45 rad from the normal (toward -x), facing down.
QUAD_CORNER = np.array([-1.47, -0.4, 2.0])
QUAD_EDGE_U = np.array([0.0, 0.8, 0.0])
QUAD_EDGE_V = np.array([1.0, 0.0, 0.0])
QUAD_RADIANCE = 5.0
# Mirror directions of the views, as (polar, azimuth) offsets from the light's centre: on it, at its
# edges and beyond them, so that the highlight's width (α) and its level both show.
ROUGHNESS_VIEW_OFFSETS = [(0.0, 0.0), (0.15, 0.0), (0.5, 0.0), (0.0, 0.25)]


def quad_light():
    return scene.QuadLight(jnp.asarray(QUAD_CORNER, jnp.float32), jnp.asarray(QUAD_EDGE_U, jnp.float32),
                           jnp.asarray(QUAD_EDGE_V, jnp.float32), QUAD_RADIANCE)


def conductor(alpha):
    return scene.RoughConductor(alpha, CONDUCTOR_ETA, CONDUCTOR_K)


def roughness_views():
    """wo per view: the mirror (about +z) of the direction toward the quad's centre, turned by the offsets."""
    centre = QUAD_CORNER + 0.5 * (QUAD_EDGE_U + QUAD_EDGE_V)
    theta0 = np.arccos(centre[2] / np.linalg.norm(centre))
    phi0 = np.arctan2(centre[1], centre[0])
    views = []
    for d_theta, d_phi in ROUGHNESS_VIEW_OFFSETS:
        theta, phi = theta0 + d_theta, phi0 + d_phi
        toward = np.array([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])
        views.append(toward * np.array([-1.0, -1.0, 1.0]))
    return np.asarray(views, np.float32)


def roughness_observations(views, alpha=TRUE_ROUGHNESS):
    return np.array([scene.reference_radiance(POINT, NORMAL, wo, conductor(alpha), quad_light()) for wo in views])


def conductor_quad_scene(config, params):
    """(point, normal, wo, brdf, light) of one configuration: config = (point, normal, wo, edge_u,
    edge_v, radiance), params = {"log_alpha", "corner"} (what the gradients are taken in)."""
    point, normal, wo, edge_u, edge_v, radiance = config
    return (point, normal, wo, conductor(jnp.exp(params["log_alpha"])),
            scene.QuadLight(params["corner"], edge_u, edge_v, radiance))


_PROGRAMS = {}


def gradient_columns(wrt=("corner", "log_alpha")) -> tuple[str, ...]:
    """The names of the gradient's columns when differentiating the parameters `wrt` (ravel_pytree
    order: the dict's keys sorted)."""
    return tuple(name for name in CONDUCTOR_QUAD_PARAMETERS if name.split("[")[0] in wrt)


def conductor_quad_program(n, strategy="mis", mode="attached", wrt=("corner", "log_alpha")):
    """jit: (configs, params, keys) -> (value, value stderr, gradient, gradient stderr) per configuration,
    a leading axis of K of each (`lax.map`, one compiled program for any K configurations of that shape).

    The value is `shade`'s estimate of L_o, one per channel (shape (3,)); the gradient `shade_grad`'s in
    the parameters `wrt` ("corner", "log_alpha" or both) per channel (shape (3, P), columns
    `gradient_columns(wrt)`, the silhouette's boundary term inside), from an independent key: so value
    and gradient are independent, and 2 (value − L) · gradient is an unbiased gradient of (E value − L)².
    Each parameter differentiated is a tangent per point: log α alone is a quarter of the program."""
    wrt = tuple(sorted(wrt))
    if not wrt or not set(wrt) <= {"corner", "log_alpha"}:
        raise ValueError(f"conductor_quad_program: wrt must name 'corner' and/or 'log_alpha', got {wrt!r}")
    cache_key = (n, strategy, mode, wrt)
    if cache_key not in _PROGRAMS:
        from jax.flatten_util import ravel_pytree

        def flat(tree):  # per channel: {"corner": (3, 3), "log_alpha": (3,)} -> (3, 4)
            return jax.vmap(lambda t: ravel_pytree(t)[0])(tree)

        def one(args):
            config, params, key = args
            key_value, key_gradient = jax.random.split(key)
            value = scene.shade(*conductor_quad_scene(config, params), key_value, n, strategy=strategy, mode=mode)
            grad = scene.shade_grad(lambda q: conductor_quad_scene(config, {**params, **q}),
                                    {name: params[name] for name in wrt}, key_gradient, n,
                                    strategy=strategy, mode=mode)
            return value.mean, value.stderr, flat(grad.mean), flat(grad.stderr)

        _PROGRAMS[cache_key] = jax.jit(lambda configs, params, keys: jax.lax.map(one, (configs, params, keys)))
    return _PROGRAMS[cache_key]


def _unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


# Configurations of the conductor under a quad light for the gradient checks (point, normal, wo, α,
# corner, edge_u, edge_v, radiance); each quad's front face (edge_u × edge_v) looks at the point.
CONDUCTOR_QUAD_CASES = [
    # α = 0.05, the lobe's peak 0.015 rad inside the quad's edge: the rim crosses a sharp lobe
    ((0, 0, 0), (0, 0, 1), tuple(_unit((0.5, 0.0, 2.0))), 0.05, QUAD_CORNER, QUAD_EDGE_U, QUAD_EDGE_V, 3.0),
    # α = 0.5, grazing view (θ_o = 1.3), a vertical quad low toward the mirror direction
    ((0, 0, 0), (0, 0, 1), (np.sin(1.3), 0.0, np.cos(1.3)), 0.5, (-1.93, -0.5, 0.13), (0, 1.0, 0), (0, 0, 0.8), 2.0),
    # α = 0.25, tilted normal, the quad straddling the tangent plane (the cos⁺ kink inside the light)
    ((0, 0, 0), tuple(_unit((0.3, -0.2, 0.93))), tuple(_unit((0.7, 0.1, 0.7))), 0.25, (-1.6, -0.5, 0.3),
     (0, 1.0, 0), (1.2, 0, 0), 4.0),
    # α = 0.15, a point close to a large quad
    ((0.2, 0.1, 0), (0, 0, 1), tuple(_unit((0.3, -0.2, 1.0))), 0.15, (-1.0, -0.8, 0.6), (0, 1.6, 0), (2.0, 0, 0), 1.0),
]
CONDUCTOR_QUAD_PARAMETERS = ("corner[0]", "corner[1]", "corner[2]", "log_alpha")  # ravel_pytree order


def conductor_quad_inputs(cases=CONDUCTOR_QUAD_CASES):
    """(configs, params) of `conductor_quad_program` for the cases, float32, a leading axis each."""
    column = lambda i: jnp.asarray(np.array([np.asarray(c[i], float) for c in cases]), jnp.float32)  # noqa: E731
    configs = (column(0), column(1), column(2), column(5), column(6), column(7))
    params = {"corner": column(4), "log_alpha": jnp.asarray(np.log([c[3] for c in cases]), jnp.float32)}
    return configs, params


def conductor_quad_reference(case, step=1e-4, **quadrature):
    """(L_o, ∂L_o/∂(corner, log α)) per channel, shapes (3,) and (3, 4), by float64 quadrature
    (`reference_radiance`) and central differences."""
    point, normal, wo, alpha, corner, edge_u, edge_v, radiance = (np.asarray(v, float) for v in case)

    def value(corner, log_alpha):
        light = scene.QuadLight(corner, edge_u, edge_v, float(radiance))
        return scene.reference_radiance(point, normal, wo, conductor(float(np.exp(log_alpha))), light, **quadrature)

    base = value(corner, np.log(alpha))
    grad = [(value(corner + step * e, np.log(alpha)) - value(corner - step * e, np.log(alpha))) / (2 * step)
            for e in np.eye(3)]
    grad.append((value(corner, np.log(alpha) + step) - value(corner, np.log(alpha) - step)) / (2 * step))
    return base, np.asarray(grad).T


def conductor_quad_z_scores(n=4096, seed=24, cases=CONDUCTOR_QUAD_CASES, wrt=("corner", "log_alpha"), **quadrature):
    """z = (estimate − reference)/stderr of the value and of the gradient in the parameters `wrt`
    (columns "parameters"), per case: `shade`/`shade_grad`, default strategy ("mis") and mode
    ("attached"); the reference's own error (differencing, the quadrature at a horizon kink) is taken
    as 1e-4 relative, in quadrature."""
    configs, params = conductor_quad_inputs(cases)
    keys = jax.random.split(jax.random.key(seed), len(cases))
    program = conductor_quad_program(n, wrt=wrt)
    value, value_err, grad, grad_err = (np.asarray(a, float) for a in program(configs, params, keys))
    columns = gradient_columns(wrt)
    references = [conductor_quad_reference(case, **quadrature) for case in cases]
    ref_value = np.array([r[0] for r in references])
    ref_grad = np.stack([r[1] for r in references])[..., [CONDUCTOR_QUAD_PARAMETERS.index(c) for c in columns]]
    z_value = (value - ref_value) / np.sqrt(value_err ** 2 + (1e-4 * np.abs(ref_value)) ** 2)
    z_grad = (grad - ref_grad) / np.sqrt(grad_err ** 2 + (1e-4 * np.abs(ref_grad) + 1e-7) ** 2)
    return {"parameters": list(columns), "z_value": z_value, "z_gradient": z_grad, "value": value,
            "reference_value": ref_value,
            "gradient": grad, "gradient_stderr": grad_err, "reference_gradient": ref_grad}


def fit_roughness(iterations, n, key, mode="attached", strategy="mis", views=None, observed=None,
                  learning_rate=ROUGHNESS_LEARNING_RATE, beta1=ROUGHNESS_BETA1) -> dict:
    """Gradient descent (Adam with first-moment decay `beta1`) on log α from START_ROUGHNESS toward the observations
    (float64 references at TRUE_ROUGHNESS); one call of `conductor_quad_program` per step gives every
    view's estimate and its gradient from independent keys. α is the geometric mean of the last fifth
    of the iterates. The program differentiates log α alone (all the fit reads)."""
    views = roughness_views() if views is None else np.asarray(views, np.float32)
    observed = roughness_observations(views) if observed is None else np.asarray(observed)
    count = views.shape[0]
    program = conductor_quad_program(n, strategy, mode, wrt=("log_alpha",))
    tile = lambda v: jnp.tile(jnp.asarray(v, jnp.float32), (count, 1))  # noqa: E731
    configs = (tile(POINT), tile(NORMAL), jnp.asarray(views), tile(QUAD_EDGE_U), tile(QUAD_EDGE_V),
               jnp.full((count,), QUAD_RADIANCE, jnp.float32))
    corner = jnp.tile(jnp.asarray(QUAD_CORNER, jnp.float32), (count, 1))
    log_alpha, m, v = np.log(START_ROUGHNESS), 0.0, 0.0
    history = {"loss": [], "alpha": []}
    for t, k in enumerate(jax.random.split(key, iterations), start=1):
        history["alpha"].append(float(np.exp(log_alpha)))
        params = {"corner": corner, "log_alpha": jnp.full((count,), log_alpha, jnp.float32)}
        outputs = program(configs, params, jax.random.split(k, count))
        value, gradient = np.asarray(outputs[0], np.float64), np.asarray(outputs[2], np.float64)
        residual = value - observed                                  # (views, channels)
        # d/d log α of Σ (L̂ − L)² over views and channels, unbiased: the residual and the gradient
        # come from independent keys.
        grad = float(np.sum(2.0 * residual * gradient[..., 0]))
        history["loss"].append(float(np.sum(residual * residual)))
        m = beta1 * m + (1.0 - beta1) * grad
        v = 0.999 * v + 0.001 * grad * grad
        log_alpha -= learning_rate * (m / (1.0 - beta1 ** t)) / (np.sqrt(v / (1.0 - 0.999 ** t)) + 1e-8)
        log_alpha = float(np.clip(log_alpha, np.log(1e-4), 0.0))  # inside the BRDF's range [1e-4, 1]
    tail = max(iterations // 5, 1)
    alpha = float(np.exp(np.mean(np.log(history["alpha"][-tail:]))))
    return {"strategy": strategy, "mode": mode, "iterations": iterations, "samples_per_estimate": n,
            "alpha": alpha, "alpha_rel_error": abs(alpha - TRUE_ROUGHNESS) / TRUE_ROUGHNESS,
            "initial_loss": history["loss"][0], "final_loss": float(np.mean(history["loss"][-tail:])),
            "history": history}


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


def _plot(results, out_dir, roughness=None):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    fig, axes = plt.subplots(1, 5 if roughness else 4, figsize=(20 if roughness else 16, 3.6))
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
    if roughness:
        axes[4].semilogy(roughness["history"]["alpha"], label=f"{roughness['strategy']}, {roughness['mode']}")
        axes[4].axhline(TRUE_ROUGHNESS, color="k", ls="--", lw=0.8, label="truth")
    titles = ["squared error (one estimate)", "exponent n", "albedo", "light polar angle (rad)",
              "GGX roughness α (quad light)"]
    for ax, title in zip(axes, titles):
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
    gradient_key, roughness_key = jax.random.split(gradient_key)
    # --quick: the fit's 4 views and the 4 gradient configurations share one compiled program (same n,
    # log α alone); the full run checks the corner's gradient too.
    roughness_samples = 4096 if quick else 1 << 15
    roughness = fit_roughness(60 if quick else 200, roughness_samples, roughness_key)
    conductor_z = conductor_quad_z_scores(n=roughness_samples, wrt=("log_alpha",) if quick else ("corner", "log_alpha"))
    result = {
        "truth": {"exponent": TRUE_EXPONENT, "albedo": TRUE_ALBEDO, "light_angles": TRUE_LIGHT_ANGLES},
        "start": {"exponent": START_EXPONENT, "albedo": START_ALBEDO, "light_angles": START_LIGHT_ANGLES},
        "observed": observed.tolist(),
        "fits": fits,
        "light_position_gradient": gradient,
        "roughness_fit": roughness,
        "conductor_quad_z": {k: np.asarray(v).tolist() if k != "parameters" else v for k, v in conductor_z.items()},
        "plot": None,
        "quick": quick,
    }
    if out_dir is not None:
        os.makedirs(out_dir, exist_ok=True)
        result["plot"] = _plot(fits, out_dir, roughness)
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
                     f"{f['exponent_rel_error']:.2%}), albedo {f['albedo']:.4f} "
                     f"(rel. error {f['albedo_rel_error']:.2%}), "
                     f"light centre off by {f['light_position_error']:.4f} "
                     f"(from {f['initial_light_position_error']:.3f}), "
                     f"loss {f['initial_loss']:.3e} -> {f['final_loss']:.3e} in {f['iterations']} iterations")
    g = result["light_position_gradient"]
    lines.append(f"dL_o/d(light centre) at L_o = {g['radiance']:.5f}, {g['samples']} evaluations each (shade_grad):")
    lines.append(f"  {'reference (finite differences)':>30}: "
                 + ", ".join(f"{v:+.5f}" for v in g["finite_difference_reference"]))
    for name, row in g["estimates"].items():
        lines.append(f"  {name:>30}: "
                     + ", ".join(f"{v:+.5f} ± {e:.5f}" for v, e in zip(row["gradient"], row["stderr"]))
                     + "   z: " + ", ".join(f"{z:+.1f}" for z in row["z"]))
    r = result.get("roughness_fit")
    if r:
        lines.append(f"roughness fit (GGX gold conductor, RGB, under a quad light, {r['strategy']}, "
                     f"{r['mode']}): α {r['alpha']:.4f} "
                     f"(truth {TRUE_ROUGHNESS:g}, start {START_ROUGHNESS:g}, rel. error {r['alpha_rel_error']:.2%}), "
                     f"loss {r['initial_loss']:.3e} -> {r['final_loss']:.3e} in {r['iterations']} iterations of "
                     f"{r['samples_per_estimate']} evaluations per view")
    z = result.get("conductor_quad_z")
    if z:
        lines.append("GGX gold conductor (RGB) under a quad light, shade's default strategy (mis, attached) "
                     "against central differences of the float64 reference, z = (estimate − reference)/stderr "
                     "per configuration and channel:")
        lines.append(f"  {'configuration':>13}  {'value':>6}  "
                     + "  ".join(f"{name:>9}" for name in z.get("parameters", CONDUCTOR_QUAD_PARAMETERS)))
        for i, (zv, zg) in enumerate(zip(z["z_value"], z["z_gradient"])):
            for channel, v, g in zip(CHANNELS, zv, zg):
                lines.append(f"  {f'{i} {channel}':>13}  {v:+6.2f}  " + "  ".join(f"{x:+9.2f}" for x in g))
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
