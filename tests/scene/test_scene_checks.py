"""Scene mistakes are answered in the library's words, before anything is traced.

Each test names the mistake a user makes (a class for an instance, lights in a dict, a batch of
points, a zero normal, a view below the surface, a point inside a light or behind every light, an
integrand indexed as a batch) and reads the message: it must name the parameter and say what to do.
None of these tests is statistical.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxsample as js
from jaxsample import scene

POINT, NORMAL, WO = jnp.zeros(3), jnp.array([0.0, 0.0, 1.0]), jnp.array([0.3, 0.1, 0.9])
SPHERE = scene.SphereLight(jnp.array([0.5, 0.3, 3.0]), 0.5, 10.0)
BRDF = scene.Lambertian(0.8)


def shade(point=POINT, normal=NORMAL, wo=WO, brdf=BRDF, lights=SPHERE):
    return scene.shade(point, normal, wo, brdf, lights, jax.random.key(0), 64)


def test_a_class_for_an_instance():
    with pytest.raises(ValueError, match=r"parameter 'brdf' must be an instance; got the class Lambertian: call it"):
        shade(brdf=scene.Lambertian)
    with pytest.raises(ValueError, match=r"parameter 'lights' must be an instance; got the class SphereLight"):
        shade(lights=scene.SphereLight)
    with pytest.raises(TypeError, match=r"parameter 'brdf' must have eval, sample, pdf; dict lacks"):
        shade(brdf={"albedo": 0.8})


def test_lights_in_a_dict_or_an_empty_list():
    with pytest.raises(ValueError, match=r"parameter 'lights' must be one light or a list of lights; got a dict"):
        shade(lights={"key": SPHERE})
    with pytest.raises(ValueError, match=r"'lights' must hold at least one light"):
        shade(lights=[])
    with pytest.raises(TypeError, match=r"parameter 'lights\[1\]' must have sample, pdf, radiance_from"):
        shade(lights=[SPHERE, 3.0])


def test_vectors_of_the_wrong_shape_or_zero_length():
    with pytest.raises(ValueError,
                       match=r"parameter 'point' must be a 3-vector .* got shape \(4, 3\) \(one shading point"):
        shade(point=jnp.zeros((4, 3)))
    with pytest.raises(ValueError, match=r"parameter 'wo' must be a 3-vector \(shape \(3,\)\); got shape \(2,\)"):
        shade(wo=jnp.ones(2))
    with pytest.raises(ValueError, match=r"parameter 'normal' must be a non-zero vector"):
        shade(normal=jnp.zeros(3))
    with pytest.raises(ValueError, match=r"parameter 'wo' must be a non-zero vector"):
        shade(wo=[0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match=r"parameter 'normal' must be finite"):
        shade(normal=jnp.array([0.0, jnp.nan, 1.0]))


def test_a_view_below_the_surface_is_refused_with_its_likely_cause():
    with pytest.raises(ValueError, match=r"parameter 'wo' points below the surface .* flip the normal"):
        shade(wo=jnp.array([0.3, 0.1, -0.9]))
    # the same scene seen from the side the normal points to is shaded
    assert np.isfinite(float(shade(normal=-NORMAL, wo=jnp.array([0.3, 0.1, -0.9]),
                                   lights=scene.SphereLight(jnp.array([0.5, 0.3, -3.0]), 0.5, 10.0)).mean))


def test_a_point_inside_or_on_a_sphere_light():
    """Concrete: a ValueError (it returned 0.5048 ± 0.005, marked reliable). Traced: NaN."""
    inside = scene.SphereLight(jnp.array([0.1, 0.2, 0.5]), 2.0, 1.0)
    with pytest.raises(ValueError, match=r"parameter 'point' .* lies inside or on light 0 \(SphereLight\)"):
        shade(lights=inside)
    on = scene.SphereLight(jnp.array([0.0, 0.0, 2.0]), 2.0, 1.0)
    with pytest.raises(ValueError, match=r"inside or on light 1"):
        shade(lights=[SPHERE, on])
    with pytest.raises(ValueError, match=r"inside or on light 0"):
        scene.reference_radiance(POINT, NORMAL, WO, BRDF, inside)
    traced = jax.jit(lambda centre: shade(lights=scene.SphereLight(centre, 2.0, 1.0)).mean)
    assert np.isnan(float(traced(jnp.array([0.1, 0.2, 0.5]))))
    assert np.isfinite(float(traced(jnp.array([0.1, 0.2, 2.5]))))


def test_a_point_behind_every_one_sided_light():
    quad = scene.QuadLight(jnp.array([-0.5, -0.5, 2.0]), jnp.array([1.0, 0.0, 0.0]), jnp.array([0.0, 1.0, 0.0]), 5.0)
    # edge_u x edge_v = +z: the quad faces up, away from the point below it
    with pytest.raises(ValueError, match=r"is behind every light \(QuadLight\): each emits from its front face"):
        shade(lights=quad)
    triangle = scene.TriangleLight(jnp.array([0.0, 0.0, 2.0]), jnp.array([1.0, 0.0, 2.0]), jnp.array([0.0, 1.0, 2.0]),
                                   5.0)  # (b - a) x (c - a) = +z: facing up too
    with pytest.raises(ValueError, match=r"behind every light \(QuadLight, TriangleLight\)"):
        shade(lights=[quad, triangle])
    flipped = scene.QuadLight(quad.corner, quad.edge_v, quad.edge_u, 5.0)
    assert float(shade(lights=flipped).mean) > 0
    assert float(shade(lights=[quad, flipped]).mean) > 0  # one light in front: shaded


def test_shade_grad_checks_the_scene_that_make_builds():
    with pytest.raises(ValueError, match=r"shade_grad: parameter 'normal' must be a non-zero vector"):
        scene.shade_grad(lambda e: (POINT, jnp.zeros(3), WO, scene.Phong(e, 0.8), SPHERE), 10.0,
                         jax.random.key(0), 64)


def test_an_integrand_written_for_a_batch_is_told_it_receives_one_sample():
    with pytest.raises(IndexError, match=r"receives one sample x of shape \(3,\), not a batch .* not x\[:, k\]"):
        js.estimate(lambda w: w[:, 2], js.CosineHemisphere(), jax.random.key(0), 64)
