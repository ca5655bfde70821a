"""An inverse problem: recover a Phong surface's exponent and albedo from the radiance it reflects.

A shading point at the origin (normal +z) is lit by a spherical light. The observations are the
outgoing radiance toward six views for Phong(exponent=40, albedo=0.6), by float64 quadrature
(`scene.reference_radiance`), so they carry no Monte Carlo noise. Starting from exponent 4 and
albedo 0.3, Adam descends the squared error, differentiating `scene.shade` (MIS, attached samples).

The gradient of a squared estimate is biased by its variance, E[(L̂ - L)²] = (E L̂ - L)² + Var L̂:
each step uses two independent estimates per view and differentiates stop_gradient(L̂_a - L) L̂_b,
whose gradient is unbiased for that of (E L̂ - L)². A small version of the report's
`jaxsample.report.inverse_problem`, which also fits the light's position and a GGX roughness.
"""

import jax
import jax.numpy as jnp
import matplotlib.pyplot as plt
import numpy as np

from jaxsample import scene

POINT, NORMAL = jnp.zeros(3), jnp.array([0.0, 0.0, 1.0])
LIGHT = scene.SphereLight(4.0 * jnp.array([-np.sin(0.5), 0.0, np.cos(0.5)]), 0.48, 20.0)
# Views whose mirror directions sweep away from the light: the falloff fixes n, the level the albedo.
angles = np.array([0.5, 0.58, 0.66, 0.75, 0.85, 0.4])
VIEWS = jnp.asarray(np.stack([np.sin(angles), np.zeros_like(angles), np.cos(angles)], axis=1), jnp.float32)
observed = np.array([scene.reference_radiance(POINT, NORMAL, wo, scene.Phong(40.0, 0.6), LIGHT, panels=64)
                     for wo in VIEWS])


def brdf(params):  # log n and logit albedo: unconstrained, so every step lands on valid parameters
    return scene.Phong(jnp.exp(params[0]), jax.nn.sigmoid(params[1]))


def radiance(params, key, n=256):
    keys = jax.random.split(key, VIEWS.shape[0])
    return jax.vmap(lambda wo, k: scene.shade(POINT, NORMAL, wo, brdf(params), LIGHT, k, n).mean)(VIEWS, keys)


def surrogate(params, key):
    key_a, key_b = jax.random.split(key)
    residual = jax.lax.stop_gradient(radiance(params, key_a) - observed)
    return 2.0 * jnp.sum(residual * radiance(params, key_b)), jnp.sum(residual ** 2)


@jax.jit
def adam_step(state, key, rate=0.1):
    params, m, v, t = state
    grad, loss = jax.grad(surrogate, has_aux=True)(params, key)
    t = t + 1
    m, v = 0.9 * m + 0.1 * grad, 0.999 * v + 0.001 * grad ** 2
    params = params - rate * (m / (1 - 0.9 ** t)) / (jnp.sqrt(v / (1 - 0.999 ** t)) + 1e-8)
    return (params, m, v, t), loss


state = (jnp.array([np.log(4.0), np.log(0.3 / 0.7)]), jnp.zeros(2), jnp.zeros(2), jnp.zeros(()))
history = []
for key in jax.random.split(jax.random.key(0), 300):
    exponent, albedo = float(jnp.exp(state[0][0])), float(jax.nn.sigmoid(state[0][1]))
    state, loss = adam_step(state, key)
    history.append((exponent, albedo, float(loss)))
history = np.array(history)
tail = history[-60:]  # the iterates jitter with the gradient's noise: average the last fifth of the run
exponent, albedo = float(np.exp(np.mean(np.log(tail[:, 0])))), float(np.mean(tail[:, 1]))
print(f"start:  exponent 4.0, albedo 0.30, loss {history[0, 2]:.3g}")
print(f"fitted: exponent {exponent:.1f} (true 40), albedo {albedo:.3f} (true 0.6), loss {np.mean(tail[:, 2]):.3g}")

fitted = np.asarray(radiance(jnp.array([np.log(exponent), np.log(albedo / (1 - albedo))]), jax.random.key(9), 1 << 14))
fig, (left, middle, right) = plt.subplots(1, 3, figsize=(12, 3.6))
left.plot(history[:, 0], label="exponent (true 40)")
left.plot(history[:, 1] * 100, label="albedo × 100 (true 60)")
left.set(xlabel="Adam step", title="Parameters")
left.legend(fontsize=8)
middle.semilogy(history[:, 2])
middle.set(xlabel="Adam step", ylabel="Σ (L̂ − L)²", title="Loss (one estimate per step)")
order = np.argsort(angles)
right.plot(angles[order], observed[order], "ko-", label="observed (quadrature)")
right.plot(angles[order], fitted[order], "s--", label="fitted surface (MC, 2^14 samples)")
right.set(xlabel="view angle from the normal (rad)", ylabel="radiance", title="Radiance per view")
right.legend(fontsize=8)
fig.tight_layout()
