"""`shade`'s gradients where the light's silhouette lies in the Phong lobe's tail: a light far outside
the lobe, or a lobe far narrower than the light.

The attached "brdf" and "mis" gradients carry the silhouette's boundary term, in which the BRDF's
samples move through each rim point y by the sampler's flow (`Sampler.flow`: warp(inverse(y)) with
the uniforms held). `PhongLobe.inverse` returns u₀ = 1 - μ^{n+1}, which rounds to exactly 1 once
μ^{n+1} < 2^-25 (μ = cos α of y about the mirror direction). Through the round trip, the warp then
takes log1p(-1) = -inf, divides it by n + 1 (derivative in n: +inf) and passes it to expm1, whose
derivative exp(-inf) = 0 multiplies the inf: NaN in every such gradient (the far light below, at
exponents 10, 40 and 100; finite at 2, where no rim point has u₀ = 1). The horizon u₀ = 1 does not
move with n, so the warp's derivative there is 0; and since u₀ = 1 has lost how the tail moves,
`PhongLobe.flow` moves a direction by log ξ = (n + 1) log μ instead, without the round trip (through
u, the "brdf" gradient at exponent 40 below is exactly 0 against the reference's -4.6e-21).

Every program here is compiled once per (strategy, mode), with the exponent, the light's centre and
the key traced.
"""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import strategies as st

from jaxsample import scene
from jaxsample.samplers.phong import PhongLobe

POINT = jnp.zeros(3)
NORMAL = jnp.array([0.0, 0.0, 1.0])
WO = jnp.array([-0.56671204, -0.58350857, 0.58168309])
CENTRE = jnp.array([-1.5786448, -0.53701097, 3.635863])   # 4 from the point, cos α = 0.23 about the mirror
RADIUS, RADIANCE, ALBEDO = 0.4, 60.0, 0.8
N = 256
MODES = [(strategy, mode) for strategy in ("mis", "brdf", "light") for mode in ("attached", "detached")]


@functools.cache
def value_and_gradient(strategy, mode):
    """(L_o, (d/d exponent, d/d centre)) of `shade` at N evaluations, jitted once per strategy and mode."""
    def radiance(exponent, centre, key):
        light = scene.SphereLight(centre, RADIUS, RADIANCE)
        return scene.shade(POINT, NORMAL, WO, scene.Phong(exponent, ALBEDO), light, key, N,
                           strategy=strategy, mode=mode).mean

    return jax.jit(jax.value_and_grad(radiance, argnums=(0, 1)))


def reference_gradient(exponent, step=0.05):
    """d L_o / d exponent by a central difference of the float64 quadrature (step 0.05: the
    difference moves by 0.9 % from step 0.2, so its own error is about 0.06 %)."""
    def value(n):
        return scene.reference_radiance(POINT, NORMAL, WO, scene.Phong(n, ALBEDO),
                                        scene.SphereLight(CENTRE, RADIUS, RADIANCE))

    return (value(exponent + step) - value(exponent - step)) / (2.0 * step)


@pytest.mark.parametrize("strategy", ["mis", "brdf"])
def test_the_far_light_reproduction_is_finite_and_agrees_with_the_reference(strategy):
    """The far light (key 0 among the keys), attached, at exponents 10, 40 and 100, over 32
    keys: every gradient finite; at 10 and 40 their mean within 5 of its standard errors of the
    float64 reference (|t| with 31 dof: false failure 2e-5 per check); at 100, where the reference
    (-1.0e-50) lies below float32's smallest subnormal, every gradient exactly 0. Per key, at N = 256,
    the spread is 10-14 % of the reference ("mis" 38 % at 40: light samples of the lobe's far tail),
    so the bound 5 sd/sqrt(32) is 9-12 % of it (34 % for "mis" at 40); the means lie within 1.2 sd.
    Catches the NaN of the tail's round trip through u, and, with the derivative at u₀ = 1 zeroed
    but the tail still moved through u, the "brdf" gradient at 40: 0."""
    grad = value_and_gradient(strategy, "attached")
    for exponent in (10.0, 40.0, 100.0):
        gradients = []
        for k in range(32):
            value, (d_exponent, d_centre) = grad(jnp.float32(exponent), CENTRE, jax.random.key(k))
            assert np.isfinite(float(value)) and np.isfinite(float(d_exponent)), (strategy, exponent, k)
            assert np.all(np.isfinite(np.asarray(d_centre))), (strategy, exponent, k, d_centre)
            gradients.append(float(d_exponent))
        gradients = np.asarray(gradients, np.float64)
        reference = reference_gradient(exponent)
        if exponent == 100.0:
            assert abs(reference) < np.finfo(np.float32).smallest_subnormal, reference
            assert np.all(gradients == 0.0), (strategy, gradients)
            continue
        stderr = gradients.std(ddof=1) / np.sqrt(len(gradients))
        t = (gradients.mean() - reference) / stderr
        assert abs(t) < 5.0, (strategy, exponent, gradients.mean(), stderr, reference)


def _centre(cos_theta, azimuth, distance):
    sin_theta = np.sqrt(max(1.0 - cos_theta * cos_theta, 0.0))
    phi = 2.0 * np.pi * azimuth
    return jnp.asarray(distance * np.array([sin_theta * np.cos(phi), sin_theta * np.sin(phi), cos_theta]),
                       jnp.float32)


_WO_AZIMUTH = float(np.arctan2(WO[1], WO[0]) / (2.0 * np.pi)) % 1.0


@pytest.mark.parametrize("strategy,mode", MODES)
@given(cos_theta=st.floats(-1.0, 1.0), azimuth=st.floats(0.0, 1.0), distance=st.floats(2.0, 5.0),
       log10_exponent=st.floats(0.0, 4.0), seed=st.integers(0, 2 ** 31 - 1))
@example(cos_theta=0.909, azimuth=0.5523, distance=4.0, log10_exponent=1.0, seed=0)         # the reproduction
@example(cos_theta=0.5817, azimuth=(_WO_AZIMUTH + 0.5) % 1.0, distance=3.0, log10_exponent=4.0,
         seed=1)                                                                           # the mirror, n = 1e4
@example(cos_theta=0.0, azimuth=0.3, distance=2.0, log10_exponent=2.0, seed=2)              # at the horizon
@example(cos_theta=0.5817, azimuth=_WO_AZIMUTH, distance=2.5, log10_exponent=1.5, seed=3)   # behind the view
@example(cos_theta=-0.6, azimuth=0.7, distance=2.0, log10_exponent=0.5, seed=4)             # below the surface
def test_value_and_gradients_are_finite_wherever_the_light_sits(strategy, mode, cos_theta, azimuth, distance,
                                                                  log10_exponent, seed):
    """A light of radius 0.4 anywhere on a sphere of radius 2-5 about the point (inside the lobe,
    outside it, straddling the horizon, toward the viewer, below the surface), exponents 1 to 1e4
    log-uniformly, every strategy and mode: the value and the gradients in the exponent and the
    light's centre are finite. Catches a NaN from any density, weight or flow that underflows in
    the lobe's tail (such a NaN reaches the attached "brdf" and "mis" gradients wherever the
    silhouette reaches the tail, at the mirror direction too once n = 1e4 makes the lobe narrower
    than the light)."""
    value, (d_exponent, d_centre) = value_and_gradient(strategy, mode)(
        jnp.float32(10.0 ** log10_exponent), _centre(cos_theta, azimuth, distance), jax.random.key(seed))
    assert np.isfinite(float(value)), value
    assert np.isfinite(float(d_exponent)), d_exponent
    assert np.all(np.isfinite(np.asarray(d_centre))), d_centre


def _direction(cos_theta, azimuth=0.3):
    sin_theta = np.sqrt(max(1.0 - cos_theta * cos_theta, 0.0))
    phi = 2.0 * np.pi * azimuth
    return jnp.asarray([[sin_theta * np.cos(phi), sin_theta * np.sin(phi), cos_theta]], jnp.float32)


@pytest.mark.parametrize("exponent", [0.0, 1.0, 10.0, 1e3, 1e7])
def test_the_lobe_warp_at_u0_one_is_the_horizon_with_derivative_zero(exponent):
    """u₀ = 1, what `PhongLobe.inverse` returns for the tail, warps to the horizon for every n, so
    the derivative in n is 0, forward and reverse (the plain log1p(-u₀)/(n + 1) under expm1 gives
    0 · inf = NaN); a u₀ below 1 keeps its derivative."""
    u = jnp.array([[1.0, 0.3], [0.5, 0.3]])

    def warp(n):
        return PhongLobe(n).warp(u)

    n = jnp.float32(exponent)
    assert float(warp(n)[0, 2]) == 0.0
    forward = np.asarray(jax.jacfwd(warp)(n))
    reverse = np.asarray(jax.jacrev(warp)(n))
    np.testing.assert_array_equal(forward[0], 0.0)
    np.testing.assert_array_equal(reverse[0], 0.0)
    assert np.all(np.isfinite(forward[1])) and np.all(np.isfinite(reverse[1]))


@pytest.mark.parametrize("exponent", [0.0, 3.0, 10.0, 1e3])
def test_the_lobe_flow_moves_the_tail_as_the_closed_form_says(exponent):
    """`PhongLobe.flow`'s derivative in n: the round trip's where u₀ carries x (ξ = μ^{n+1} >= 1e-3,
    its rounding 6e-5 relative), and everywhere the closed form d cos θ/dn = -μ log μ/(n + 1) of
    the sample at fixed ξ, the tail where u₀ rounds to 1 included (the round trip gives 0 there);
    0 at and below the horizon. Near the horizon cos θ = 1 - (1 - μ) rounds to 2^-24 absolute, and
    so does its derivative, times |d log μ/dn| = |log μ|/(n + 1): that is the absolute tolerance."""
    n = jnp.float32(exponent)
    for mu in (0.999, 0.9, 0.5, 0.2, 0.01, 1e-6, 0.0, -0.3):
        x = _direction(mu)
        flow = np.asarray(jax.jacfwd(lambda m, x=x: PhongLobe(m).flow(x))(n))[0]
        assert np.all(np.isfinite(flow)), (exponent, mu, flow)
        if mu <= 0.0:
            np.testing.assert_array_equal(flow, 0.0)
            continue
        rounding = 2.0 ** -23 * abs(np.log(mu)) / (exponent + 1.0)
        np.testing.assert_allclose(flow[2], -mu * np.log(mu) / (exponent + 1.0), rtol=2e-3, atol=rounding,
                                   err_msg=str(mu))
        if mu ** (exponent + 1.0) >= 1e-3:
            def round_trip(m, x=x):
                lobe = PhongLobe(m)
                return lobe.warp(jax.lax.stop_gradient(lobe.inverse(x)))

            np.testing.assert_allclose(flow, np.asarray(jax.jacfwd(round_trip)(n))[0], rtol=2e-3, atol=1e-9,
                                       err_msg=str(mu))


# ---- a rough conductor under a quad light: roughness 1e-3 to 1, views from the normal to grazing ----

def _quad_facing_the_point(cos_theta, azimuth, distance, size):
    """A square of side `size` centred `distance` from the origin along (cos_theta, azimuth), its
    front face (edge_u × edge_v) toward the origin."""
    axis = np.asarray(_centre(cos_theta, azimuth, 1.0), np.float64)
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t1 = np.cross(axis, helper)
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(axis, t1)
    edge_u, edge_v = size * t2, size * t1                        # t2 × t1 = -axis: facing the origin
    corner = distance * axis - 0.5 * (edge_u + edge_v)
    return tuple(jnp.asarray(v, jnp.float32) for v in (corner, edge_u, edge_v))


@functools.cache
def conductor_value_and_gradient(strategy, mode):
    """(L_o, (d/d log α, d/d shift)) of `shade` for a gold-like conductor under a quad light moved by
    `shift` along its edge_u, at N evaluations, jitted once per strategy and mode (everything traced)."""
    def radiance(log_alpha, shift, wo, corner, edge_u, edge_v, key):
        light = scene.QuadLight(corner + shift * edge_u, edge_u, edge_v, 5.0)
        brdf = scene.RoughConductor(jnp.exp(log_alpha), 0.2, 3.0)
        return scene.shade(POINT, NORMAL, wo, brdf, light, key, N, strategy=strategy, mode=mode).mean

    return jax.jit(jax.value_and_grad(radiance, argnums=(0, 1)))


@pytest.mark.parametrize("strategy,mode", MODES)
@given(cos_theta=st.floats(-0.3, 1.0), azimuth=st.floats(0.0, 1.0), distance=st.floats(1.5, 5.0),
       size=st.floats(0.2, 2.0), log10_alpha=st.floats(-3.0, 0.0), view_cos=st.floats(1e-3, 1.0),
       view_azimuth=st.floats(0.0, 1.0), seed=st.integers(0, 2 ** 31 - 1))
@example(cos_theta=0.9, azimuth=0.5, distance=2.0, size=1.0, log10_alpha=-3.0, view_cos=0.9, view_azimuth=0.0,
         seed=0)                                                     # α = 1e-3, the light on the mirror direction
@example(cos_theta=0.05, azimuth=0.5, distance=2.0, size=1.0, log10_alpha=-1.0, view_cos=1e-3, view_azimuth=0.0,
         seed=1)                                                     # grazing view, the light at the horizon
@example(cos_theta=0.9, azimuth=0.0, distance=3.0, size=0.3, log10_alpha=-2.5, view_cos=0.95, view_azimuth=0.0,
         seed=2)                                                     # a sharp lobe far from a small light
@example(cos_theta=-0.2, azimuth=0.3, distance=2.0, size=1.5, log10_alpha=0.0, view_cos=0.5, view_azimuth=0.7,
         seed=3)                                                     # the light straddling the horizon, α = 1
def test_conductor_values_and_gradients_are_finite_wherever_the_quad_sits(strategy, mode, cos_theta, azimuth,
                                                                         distance, size, log10_alpha, view_cos,
                                                                         view_azimuth, seed):
    """A GGX conductor of roughness 1e-3 to 1 (log-uniform) seen from the normal down to 1e-3 of
    grazing, under a quad light of side 0.2-2 anywhere from just below the horizon to the zenith,
    every strategy and mode: the value and the gradients in log α and in the light's position are
    finite. Catches a NaN from a microfacet density, a visible-normal flow or a rim term that
    underflows at a sharp lobe or a grazing view (the boundary term moves BRDF samples through the
    sampler's inverse at every rim point of the quad)."""
    corner, edge_u, edge_v = _quad_facing_the_point(cos_theta, azimuth, distance, size)
    wo = _direction(view_cos, view_azimuth)[0]
    value, (d_alpha, d_shift) = conductor_value_and_gradient(strategy, mode)(
        jnp.float32(np.log(10.0 ** log10_alpha)), jnp.float32(0.0), wo, corner, edge_u, edge_v, jax.random.key(seed))
    assert np.isfinite(float(value)), value
    assert np.isfinite(float(d_alpha)), d_alpha
    assert np.isfinite(float(d_shift)), d_shift
