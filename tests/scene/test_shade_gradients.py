"""`shade`'s gradients for every parameter of the BRDF and the light, against central
differences of the float64 `reference_radiance` (`jaxsample/report/shade_gradients.py`: 12 configurations per light).

Each configuration's gradient comes from `shade_grad` (per-evaluation gradients, the silhouette's
boundary term inside each, 4096 evaluations, a fixed key); z = (gradient - reference) / stderr per
parameter. Thresholds: the mean of z² over a light's 12 x (7 or 12) parameters below 2.5, and
every |z| below 5.5 (attached: all three strategies, both lights; detached: the default
"mis" on the sphere light, whose boundary term is the plain Δf v·n). With independent normal z the
first is the χ² statistic divided by its dof,
and 2.5 is more than 9 of its standard deviations above 1; the parameters are correlated (albedo
and radiance enter as a product), which widens its spread, at most by the factor of the two
duplicated columns, keeping the threshold above 6 sd (false failure below 1e-8 for a normal
tail); the second, over 12 x 7 x 4 + 12 x 12 x 3 = 768 values, fails by chance with probability 768 x 3.8e-8 < 3e-5. The
estimators' skew at exponent 1000 (a mean 2.9 sd low at 2^14 evaluations, unbiased at 2^21)
is what 5.5 leaves room for. Without the boundary term the light parameters' z reach hundreds
(the "brdf" strategy's light gradient is then exactly 0), and the default "mis" is 5-100 sd off.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.flatten_util import ravel_pytree

from jaxsample import scene
from jaxsample.report import shade_gradients as shade_grid

N = 4096


def z_scores(kind, strategy, mode):
    return shade_grid.z_scores(kind, strategy, mode, N, seed=23)


@pytest.mark.parametrize("kind,strategy,mode", [(kind, strategy, "attached") for kind in ("sphere", "triangle")
                                                for strategy in ("mis", "brdf", "light")]
                         + [("sphere", "mis", "detached")])
def test_every_gradient_agrees_with_the_reference(kind, strategy, mode):
    # FFR per case: 84 (sphere) or 144 (triangle) values at |z| < 5.5, 3.2e-6 or 5.5e-6; 3e-5 in all.
    z = z_scores(kind, strategy, mode)
    assert np.all(np.isfinite(z))
    assert float(np.mean(z ** 2)) < 2.5, (kind, strategy, mode, np.round(z, 1))
    assert float(np.max(np.abs(z))) < 5.5, (kind, strategy, mode, np.round(z, 1))


def test_shade_grad_is_the_gradient_of_shade():
    """The mean of `shade_grad` is `jax.grad` of `shade`'s mean on the same samples (BRDF sampling,
    where the gradient is the boundary term alone), and its stderr is positive."""
    point, normal, wo = jnp.zeros(3), jnp.array([0.0, 0.0, 1.0]), jnp.array([0.3, 0.1, 1.0])

    def make(centre):
        return point, normal, wo, scene.Lambertian(0.7), scene.SphereLight(centre, 0.5, 3.0)

    centre, key = jnp.array([0.4, 0.3, 2.0]), jax.random.key(5)
    est = scene.shade_grad(make, centre, jax.random.clone(key), 1024, strategy="brdf")
    direct = jax.grad(lambda c: scene.shade(*make(c), jax.random.clone(key), 1024, strategy="brdf").mean)(centre)
    np.testing.assert_allclose(est.mean, direct, rtol=2e-4, atol=1e-6)
    assert np.all(np.asarray(est.stderr) > 0)


def test_without_the_boundary_term_the_value_is_the_same_and_an_edge_gradient_is_lost():
    """`boundary_term=False` (for measuring the term): the value is bit for bit the default's (the term
    has value 0), and under BRDF sampling the light centre's gradient, which is the term alone, is
    exactly 0; with the term its z component is resolved: more than 5 stderr from 0 (138 at this key,
    so a fresh key's chance of falling below 5 is nil: FFR < 1e-20) Anything but True or False is refused by name."""
    point, normal, wo = jnp.zeros(3), jnp.array([0.0, 0.0, 1.0]), jnp.array([0.3, 0.1, 1.0])

    def make(centre):
        return point, normal, wo, scene.Lambertian(0.7), scene.SphereLight(centre, 1.0, 3.0)

    centre, key = jnp.array([0.4, 0.3, 2.0]), jax.random.key(8)
    k_value, k_with, k_without, k_direct = jax.random.split(key, 4)
    with_term = scene.shade(*make(centre), jax.random.clone(k_value), 1024, strategy="brdf")
    without = scene.shade(*make(centre), k_value, 1024, strategy="brdf", boundary_term=False)
    assert float(with_term.mean) == float(without.mean) and float(with_term.stderr) == float(without.stderr)
    grad_with = scene.shade_grad(make, centre, k_with, 1024, strategy="brdf")
    grad_without = scene.shade_grad(make, centre, k_without, 1024, strategy="brdf", boundary_term=False)
    assert np.all(np.asarray(grad_without.mean) == 0.0), grad_without.mean
    direct = jax.grad(lambda c: scene.shade(*make(c), k_direct, 1024, strategy="brdf", boundary_term=False).mean)
    assert np.all(np.asarray(direct(centre)) == 0.0)
    # Moving the sphere away (z) shrinks its solid angle: that derivative is the largest.
    assert abs(float(grad_with.mean[2])) > 5 * float(grad_with.stderr[2]), (grad_with.mean, grad_with.stderr)
    with pytest.raises(ValueError, match="'boundary_term' must be True or False"):
        scene.shade(*make(centre), jax.random.key(0), 1024, boundary_term="yes")


def test_gradients_that_cannot_be_unbiased_are_refused():
    """An environment map's texel edges are unknown to `shade`: attached BRDF samples cross them,
    so the exponent's gradient under attached "mis" is refused; detached is allowed, and so is
    the value."""
    env = scene.EnvironmentMap(jnp.ones((4, 8)).at[1, 2].set(5.0))

    def value(exponent, mode):
        return scene.shade(jnp.zeros(3), jnp.array([0.0, 0.0, 1.0]), jnp.array([0.3, 0.0, 1.0]),
                           scene.Phong(exponent, 0.8), env, jax.random.key(0), 256, mode=mode).mean

    assert np.isfinite(float(value(10.0, "attached")))
    with pytest.raises(ValueError, match="mode='detached'"):
        jax.grad(value)(10.0, "attached")
    assert np.isfinite(float(jax.grad(value)(10.0, "detached")))


def test_overlapping_lights_and_a_sky():
    """Two sphere lights that overlap as seen from the point, plus a sky: light sampling's pieces
    cross each other's rims (the mixture's samples of one light at the other's silhouette), the case
    the per-piece flows exist for (the triangle's rim code is held by the grid above). Every gradient
    (log-exponent, both centres) within 5 of its stderrs of central differences of the float64
    reference (7 values: false failure 4e-6)."""
    point, normal, wo = np.zeros(3), np.array([0.0, 0.0, 1.0]), np.array([0.3, 0.1, 1.0])

    def build(p, dtype=jnp.float32):
        brdf = scene.Phong(jnp.exp(p["log_n"]), 0.8)
        return point, normal, wo, brdf, [scene.SphereLight(p["c"], 0.5, 3.0), scene.SphereLight(p["a"], 0.4, 2.0),
                                         scene.ConstantSky(0.2)]

    start = {"log_n": np.log(10.0), "c": np.array([0.2, 0.2, 1.8]), "a": np.array([-0.3, 0.1, 1.6])}
    with jax.enable_x64(True):
        flat, unravel = ravel_pytree(jax.tree_util.tree_map(np.float64, start))
        flat = np.asarray(flat)

        def reference(theta):
            return scene.reference_radiance(*build(unravel(jnp.asarray(theta)), jnp.float64), **shade_grid.QUADRATURE)

        steps = np.eye(flat.size) * 1e-5
        expected = np.array([(reference(flat + h) - reference(flat - h)) / 2e-5 for h in steps])
    params = jax.tree_util.tree_map(jnp.float32, start)
    g = scene.shade_grad(build, params, jax.random.key(31), 1 << 14)  # "mis": BRDF and light pieces
    mean, stderr = np.asarray(ravel_pytree(g.mean)[0]), np.asarray(ravel_pytree(g.stderr)[0])
    assert np.all(np.abs(mean - expected) < 5.0 * stderr), (mean, stderr, expected)


def test_gradients_stay_finite_at_degenerate_geometry():
    """No NaN where a silhouette degenerates: a shading point just outside a sphere light (the cap
    nearly a hemisphere) and a viewpoint on the line of a triangle's edge (an arc of length π, whose
    great-circle plane does not exist). A traced point inside the sphere, outside the range, is NaN
    rather than a confident number (a concrete one is refused: tests/scene/test_scene_checks.py)."""
    point, normal, wo = jnp.zeros(3), jnp.array([0.0, 0.0, 1.0]), jnp.array([0.3, 0.1, 1.0])

    def sphere(centre):
        return scene.shade(point, normal, wo, scene.Lambertian(0.8), scene.SphereLight(centre, 2.0, 1.0),
                           jax.random.key(0), 256, strategy="brdf").mean

    def on_edge(a):
        light = scene.TriangleLight(a, jnp.array([1.0, 0.0, 0.0]), jnp.array([0.0, 0.5, 1.0]), 1.0)
        return scene.shade(point, normal, wo, scene.Lambertian(0.8), light, jax.random.key(1), 256,
                           strategy="brdf").mean

    just_outside = jnp.array([0.0, 0.0, 2.002])
    assert np.isfinite(float(jax.jit(sphere)(just_outside)))
    assert np.all(np.isfinite(np.asarray(jax.grad(sphere)(just_outside))))
    assert np.isnan(float(jax.jit(sphere)(jnp.array([0.1, 0.2, 0.5]))))
    assert np.all(np.isfinite(np.asarray(jax.grad(on_edge)(jnp.array([-1.0, 0.0, 0.0])))))


def _phong_under_a_sphere(theta):
    return (jnp.zeros(3), jnp.array([0.0, 0.0, 1.0]), jnp.array([0.3, 0.1, 1.0]), scene.Phong(jnp.exp(theta), 0.8),
            [scene.SphereLight(jnp.array([0.5, 0.2, 2.0]), 0.4, 5.0)])


def _log_exponent_reference(theta):
    """d L_o / d log n by the central difference of the float64 reference."""
    with jax.enable_x64(True):
        def reference(t):
            return scene.reference_radiance(*_phong_under_a_sphere(jnp.asarray(t, jnp.float64)),
                                            **shade_grid.QUADRATURE)

        return (reference(theta + 1e-5) - reference(theta - 1e-5)) / 2e-5


def test_rotated_pairs_lower_the_variance_of_a_glossy_gradient_without_bias():
    """d L_o / d log n (Phong 25, a sphere light, the boundary term inside) by BRDF sampling at 2^16
    evaluations: plain and antithetic="rotate" both within 4.5 stderrs of the central difference of the
    float64 reference (2 values: false failure 1.4e-5), and the rotated pairs have at most 0.8 of the
    plain estimator's variance per evaluation (measured 0.663 ± 0.004 over 12 keys: the bound is 29 of
    those standard deviations away; a partner equal to its sample doubles the variance instead)."""
    theta = np.log(25.0)
    expected = _log_exponent_reference(theta)
    plain = scene.shade_grad(_phong_under_a_sphere, jnp.float32(theta), jax.random.key(42), 1 << 16, strategy="brdf")
    rotated = scene.shade_grad(_phong_under_a_sphere, jnp.float32(theta), jax.random.key(43), 1 << 16,
                               strategy="brdf", antithetic="rotate")
    for g in (plain, rotated):
        assert abs(float(g.mean) - expected) < 4.5 * float(g.stderr), (float(g.mean), float(g.stderr), expected)
    assert float(rotated.variance) < 0.8 * float(plain.variance), (float(rotated.variance), float(plain.variance))


@pytest.mark.parametrize("strategy,antithetic", [("brdf", "reflect"), ("mis", "rotate"), ("mis", "reflect")])
def test_every_antithetic_pairing_is_unbiased(strategy, antithetic):
    """d L_o / d log n as above at 2^14 evaluations within 4.5 stderrs of the reference (false failure
    6.8e-6 per case): the pairings with "mis", whose light uniforms are reflected, and "reflect"."""
    theta = np.log(25.0)
    g = scene.shade_grad(_phong_under_a_sphere, jnp.float32(theta), jax.random.key(41), 1 << 14, strategy=strategy,
                         antithetic=antithetic)
    expected = _log_exponent_reference(theta)
    assert abs(float(g.mean) - expected) < 4.5 * float(g.stderr), (float(g.mean), float(g.stderr), expected)


def test_antithetic_shade_gradients_refuse_what_they_cannot_pair():
    """ValueError: "rotate" with light sampling alone (no BRDF sample to turn), n not a multiple of 4
    with "mis", an unknown pairing."""
    theta = jnp.float32(np.log(25.0))
    with pytest.raises(ValueError, match="strategy='light' draws no BRDF sample"):
        scene.shade_grad(_phong_under_a_sphere, theta, jax.random.key(0), 1024, strategy="light", antithetic="rotate")
    with pytest.raises(ValueError, match="multiple of 4"):
        scene.shade_grad(_phong_under_a_sphere, theta, jax.random.key(0), 1026, antithetic="reflect")
    with pytest.raises(ValueError, match="antithetic"):
        scene.shade_grad(_phong_under_a_sphere, theta, jax.random.key(0), 1024, antithetic="mirror")
