"""Many sphere lights as one batch (`scene.SphereLights`) against the sum of single-light references.

False-failure rates (fresh keys) are stated per test; `tests/false_failures.md` sums them.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxsample import scene
from keyring import next_key

POINT, NORMAL, WO = np.zeros(3), np.array([0.0, 0.0, 1.0]), np.array([0.3, 0.1, 1.0])
_rng = np.random.default_rng(0)
CENTERS = np.stack([_rng.uniform(-3, 3, 6), _rng.uniform(-3, 3, 6), _rng.uniform(1.0, 4.0, 6)], -1)
CENTERS[5] = 1.6 * CENTERS[4]  # behind light 4, seen through it: transparent lights add
RADII = _rng.uniform(0.2, 0.6, 6)
RADIANCE = _rng.uniform(0.5, 5.0, 6)


def _batch(selection="power", centers=CENTERS):
    return scene.SphereLights(jnp.asarray(centers, jnp.float32), jnp.asarray(RADII, jnp.float32),
                              jnp.asarray(RADIANCE, jnp.float32), selection=selection)


def _reference(exponent=20.0):
    """The sum of the float64 references of the lights one at a time (they are transparent)."""
    brdf = scene.Phong(exponent, 0.8)
    return sum(float(scene.reference_radiance(POINT, NORMAL, WO, brdf, [scene.SphereLight(c, r, L)]))
               for c, r, L in zip(CENTERS, RADII, RADIANCE))


@pytest.mark.parametrize("selection", ["power", "uniform", "solid_angle"])
def test_a_batch_of_lights_is_the_sum_of_its_lights(selection):
    """`shade` with light sampling and with MIS (2^16 evaluations) within 4.5 standard errors of the
    sum of single-light float64 references, for each selection rule; two of the six lights overlap
    (one seen through the other). FFR 2 x 6.8e-6 per case, 4.1e-5 in all."""
    reference = _reference()
    for strategy in ("light", "mis"):
        est = scene.shade(POINT, NORMAL, WO, scene.Phong(20.0, 0.8), _batch(selection), next_key(), 1 << 16,
                          strategy=strategy)
        assert abs(float(est.mean) - reference) < 4.5 * float(est.stderr), (strategy, float(est.mean), reference)


def test_density_and_radiance_are_the_mixture_and_the_sum_of_the_single_lights():
    """Deterministic: at directions drawn inside every cone (and at random ones), the batch's density
    is Σ_k P_k p_k(ω) and its radiance Σ_k L_k(ω) over the single `SphereLight`s, to float32 rounding;
    the overlapping pair makes the sum differ from any one light's."""
    singles = [scene.SphereLight(jnp.asarray(c, jnp.float32), float(r), float(L))
               for c, r, L in zip(CENTERS, RADII, RADIANCE)]
    rng = np.random.default_rng(1)
    inside = [np.asarray(light.sampler(jnp.zeros(3)).warp(jnp.asarray(rng.random((64, 2)), jnp.float32)))
              for light in singles]
    random = rng.normal(size=(256, 3))
    directions = jnp.asarray(np.concatenate(inside + [random / np.linalg.norm(random, axis=-1, keepdims=True)]),
                             jnp.float32)
    for selection in ("power", "solid_angle"):
        batch = _batch(selection)
        weights = np.asarray(batch.probabilities(jnp.zeros(3)))
        pdf = sum(w * np.asarray(light.pdf(jnp.zeros(3), directions)) for w, light in zip(weights, singles))
        radiance = sum(np.asarray(light.radiance_from(jnp.zeros(3), directions)) for light in singles)
        np.testing.assert_allclose(np.asarray(batch.pdf(jnp.zeros(3), directions)), pdf, rtol=1e-4)
        np.testing.assert_allclose(np.asarray(batch.radiance_from(jnp.zeros(3), directions)), radiance, rtol=1e-5)
        assert np.any(radiance > RADIANCE.max())  # some directions see two lights at once


def test_the_selection_rules_are_their_closed_forms():
    """P_k ∝ L r² ("power"), 1/K ("uniform") and L Ω_k(p) ("solid_angle", Ω = 2π(1 − sqrt(1 − r²/d²)))."""
    distance2 = np.sum(CENTERS ** 2, axis=-1)
    cone = 1.0 - np.sqrt(1.0 - RADII ** 2 / distance2)
    expected = {"power": RADIANCE * RADII ** 2, "uniform": np.ones(6), "solid_angle": RADIANCE * cone}
    for selection, weights in expected.items():
        np.testing.assert_allclose(np.asarray(_batch(selection).probabilities(jnp.zeros(3))),
                                   weights / weights.sum(), rtol=2e-5)


def test_the_program_does_not_grow_with_the_number_of_lights():
    """The jaxpr of `shade` over 100 lights and over 3000 has the same equations: the lights are one
    batch of arrays, not a list unrolled into the program (whose size, and compile time, grew with
    every light). (Up to 64 values per point the per-coordinate fast path, `_core/lanes.py`, unrolls
    the light axis into lanes: below about 21 lights the program grows with K up to that bound.)"""
    def equations(count):
        centers = np.tile(CENTERS, (count // 6 + 1, 1))[:count]
        lights = scene.SphereLights(jnp.asarray(centers), jnp.full(count, 0.3), jnp.ones(count))
        program = jax.make_jaxpr(lambda k: scene.shade(jnp.zeros(3), jnp.array([0.0, 0.0, 1.0]), jnp.asarray(WO),
                                                       scene.Phong(20.0, 0.8), lights, k, 4096).mean)
        return str(program(jax.random.key(0))).count(" = ")

    assert equations(100) == equations(3000)


def test_the_brdf_gradient_with_light_sampling_matches_differences_of_the_reference():
    """d/dn of L_o in the Phong exponent n (light sampling, attached: the lights hold still) from 2^16
    evaluations, within 4.5 standard errors (from 16 keys) of the central difference of the summed
    float64 references at n ± 0.05. FFR: Student t with 15 degrees of freedom beyond 4.5, 4e-4."""
    step = 0.05
    exact = (_reference(20.0 + step) - _reference(20.0 - step)) / (2 * step)
    lights = _batch()

    def radiance(exponent, key):
        return scene.shade(POINT, NORMAL, WO, scene.Phong(exponent, 0.8), lights, key, 1 << 14, strategy="light").mean

    grads = np.asarray(jax.jit(jax.vmap(jax.grad(radiance), (None, 0)))(20.0, jax.random.split(next_key(), 16)))
    assert abs(grads.mean() - exact) < 4.5 * grads.std(ddof=1) / 4, (grads.mean(), exact)


def test_moving_lights_and_points_inside_them_are_refused():
    def radiance(shift):
        lights = _batch(centers=jnp.asarray(CENTERS) + shift)
        return scene.shade(POINT, NORMAL, WO, scene.Phong(20.0, 0.8), lights, jax.random.key(3), 1024,
                           strategy="light").mean

    with pytest.raises(ValueError, match="no 'silhouette'"):
        jax.grad(radiance)(0.0)
    with pytest.raises(ValueError, match="inside"):
        scene.shade(CENTERS[0], NORMAL, WO, scene.Phong(20.0, 0.8), _batch(), jax.random.key(4), 1024)
    with pytest.raises(ValueError, match="selection"):
        _batch("nearest")
