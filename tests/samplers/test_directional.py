"""What is particular to the directional samplers; the contract every sampler meets
(normalization, chi-square, inverse, Jacobian, support, finite values and gradients at the hard
cases) is `test_contract.py`, over the entries of `registry.py`.

Here: the wrong-sampler demonstrations for the chi-square family (at the sample size the contract
uses for the family: a 2 % Phong exponent error was rejected at 400k samples for only some keys, so
the Phong entries use 2M, where it gives p < 1e-50 for every key tried; a 1 % error is at the edge,
rejected for 3 keys of 4 at n = 5; cones 1 % too narrow give p < 1e-150 at 400k), normalization
over the documented parameter ranges, the cone's constructors, float32 against float64, parameter
errors, and jit/vmap over parameters.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import jaxsample as js
from jaxsample import testing

import registry

@given(log_n=st.floats(0.0, 7.0), log_h=st.floats(-9.0, np.log10(2.0)), log_k=st.floats(-6.0, 7.0))
def test_normalization_across_the_documented_ranges(log_n, log_h, log_k):
    for sampler in (js.PhongLobe(jnp.float32(10**log_n - 1.0)),
                    js.UniformCone(one_minus_cos_theta_max=jnp.float32(10**log_h)),
                    js.VonMisesFisher(jnp.float32(10**log_k))):
        assert abs(testing.normalization(sampler) - 1.0) < 1e-6, sampler


class _PhongOff(js.PhongLobe):
    """Warps with an exponent 2 % too large while claiming the right density."""

    def warp(self, u):
        return js.PhongLobe(self.exponent * 1.02).warp(u)


class _ConeOff(js.UniformCone):
    """Warps into a cap 2 % too narrow (in 1 - cos θ_max) while claiming the right density."""

    def warp(self, u):
        return js.UniformCone(one_minus_cos_theta_max=self.one_minus_cos_theta_max * 0.98).warp(u)



@pytest.mark.parametrize("family,wrong", [("PhongLobe", _PhongOff(jnp.float32(5.0))),
                                          ("PhongLobe", _PhongOff(jnp.float32(100.0))),
                                          ("PhongLobe", _PhongOff(jnp.float32(1e6))),
                                          ("UniformCone", _ConeOff(one_minus_cos_theta_max=jnp.float32(0.5))),
                                          ("UniformCone", _ConeOff(one_minus_cos_theta_max=jnp.float32(1e-6)))])
def test_chi_square_rejects_a_sampler_off_by_two_percent(family, wrong):
    # At the contract's sample size and threshold for the family (1.1e-8 per test), and by a wide
    # margin: p below 1e-20 (the margin seen over keys is tens of decades). FFR below 2e-7 per
    # Phong case (estimated: a noncentral chi-square(127) whose median p is 1e-50 reaches 1e-20 that
    # rarely), negligible for the cones.
    result = testing.chi2_test(wrong, jax.random.key(7), **registry.chi2_settings(family))
    assert not result.passed and result.p_value < 1e-20, result


DIRECTIONAL = ["UniformSphere", "UniformSphere-rejection", "UniformSphere-equal-area", "UniformHemisphere",
               "CosineHemisphere-malley", "CosineHemisphere-inversion", "PhongLobe", "UniformCone", "VonMisesFisher",
               "Oriented-Phong", "Oriented-UniformCone"]
_warp_with_pdf = jax.jit(lambda sampler, u: sampler.warp_with_pdf(u))


def test_float32_matches_float64_at_the_hard_cases():
    # The worst float32 error of directions and densities, at the hard u, against float64 with
    # the same (float32-rounded) parameters.
    worst_direction, worst_pdf = 0.0, 0.0
    for entry in map(registry.BY_NAME.get, DIRECTIONAL):
        for case in entry.cases:
            params = registry.cast_params(case.params, jnp.float32)
            sampler = entry.make(*params)
            u32 = registry.edge_uniforms(sampler.uniform_dims, jnp.float32)
            x32, p32 = _warp_with_pdf(sampler, u32)
            with jax.enable_x64(True):
                x64, p64 = _warp_with_pdf(entry.make(*registry.cast_params(params, jnp.float64)),
                                          u32.astype(jnp.float64))
                x64, p64 = np.asarray(x64), np.asarray(p64)
            worst_direction = max(worst_direction, float(np.max(np.abs(np.asarray(x32) - x64))))
            positive = p64 > 0
            assert np.all(np.asarray(p32)[~positive] == 0), (entry.name, case)
            worst_pdf = max(worst_pdf, float(np.max(np.abs(np.asarray(p32)[positive] / p64[positive] - 1))))
    assert worst_direction < 1e-6 and worst_pdf < 1e-5, (worst_direction, worst_pdf)


def _clarberg_square_to_sphere(u):
    """PBRT-v4 EqualAreaSquareToSphere, transcribed to float64 NumPy."""
    a, b = 2 * u[:, 0] - 1, 2 * u[:, 1] - 1
    signed = 1 - (np.abs(a) + np.abs(b))
    r = 1 - np.abs(signed)
    with np.errstate(divide="ignore", invalid="ignore"):
        phi = np.where(r == 0, 1.0, (np.abs(b) - np.abs(a)) / r + 1) * np.pi / 4
    z = np.copysign(1 - r * r, signed)
    scale = r * np.sqrt(np.maximum(2 - r * r, 0))
    return np.stack([np.copysign(np.cos(phi), a) * scale, np.copysign(np.sin(phi), b) * scale, z], -1)


def test_equal_area_map_is_pbrts_in_float64_and_inverts_at_the_poles_in_float32():
    """Deterministic: 4096 points of a grid and the square's centre, corners and edge midpoints
    against PBRT-v4's formula in float64; then, in float32, the round trip next to both poles
    (u = centre + 1e-4 and a corner − 1e-4), where r = sqrt(1 − |z|) written plainly loses half its
    digits (an error of 6e-8/(2r) ≈ 4e-4 in u there)."""
    grid = (np.stack(np.meshgrid(np.arange(64), np.arange(64)), -1).reshape(-1, 2) + 0.5) / 64
    special = np.array([[0.5, 0.5], [0.0, 0.0], [1.0, 1.0], [0.0, 1.0], [1.0, 0.0], [0.5, 0.0], [0.0, 0.5],
                        [0.75, 0.75], [0.25, 0.6]])
    u = np.concatenate([grid, special])
    sampler = js.UniformSphere(method="equal_area")
    with jax.enable_x64(True):
        x = np.asarray(sampler.warp(jnp.asarray(u)))
        back = np.asarray(sampler.inverse(jnp.asarray(x)))
    np.testing.assert_allclose(x, _clarberg_square_to_sphere(u), rtol=0, atol=1e-14)
    np.testing.assert_allclose(back[:len(grid)], grid, rtol=0, atol=1e-13)
    near_poles = np.array([[0.5 + 1e-4, 0.5 + 3e-5], [0.5 - 2e-4, 0.5], [1e-4, 2e-4], [1 - 1e-4, 1 - 3e-4]], np.float32)
    x32 = sampler.warp(jnp.asarray(near_poles))
    np.testing.assert_allclose(np.asarray(sampler.inverse(x32)), near_poles, rtol=0, atol=3e-7)


@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_cone_constructors_match_their_closed_forms(dtype):
    """Each UniformCone constructor against its float64 formula (deterministic, no FFR), and the
    cap it builds against the angle or solid angle it was given: h = 1 - cos θ_max = 2 sin²(θ/2)
    from the angle, h = Ω/(2π) from the solid angle, h = 1 - sqrt(1 - s) from s = sin² θ_max.
    A cap of half the size (sin²(θ/2), Ω/4π) fails every line by a factor 2."""
    with jax.enable_x64(dtype == "float64"):
        dt = jnp.dtype(dtype)
        rtol = 1e-12 if dtype == "float64" else 4e-7
        theta = np.array([1e-6, 1e-3, 0.05, 0.4, 1.0, np.pi / 2, 2.5, 3.0, np.pi])
        cone = js.UniformCone.from_angle(jnp.asarray(theta, dt))
        np.testing.assert_allclose(cone.one_minus_cos_theta_max, 2 * np.sin(theta / 2) ** 2, rtol=rtol)
        np.testing.assert_allclose(cone.solid_angle, 2 * np.pi * (1 - np.cos(theta)), rtol=rtol, atol=1e-15)
        # The derivative of the cap's size follows the angle: dΩ/dθ = 2π sin θ.
        d_solid = jax.vmap(jax.grad(lambda t: js.UniformCone.from_angle(t).solid_angle))(jnp.asarray(theta, dt))
        np.testing.assert_allclose(d_solid, 2 * np.pi * np.sin(theta), rtol=10 * rtol, atol=1e-6)
        # The warp's last sample sits on the rim: its angle from +z is θ_max.
        rim = cone.warp(jnp.stack([jnp.full(theta.shape, 1 - 2.0 ** -24, dt), jnp.zeros(theta.shape, dt)], -1))
        rim_angle = np.arctan2(np.hypot(np.asarray(rim[:, 0], np.float64), np.asarray(rim[:, 1], np.float64)),
                               np.asarray(rim[:, 2], np.float64))
        np.testing.assert_allclose(rim_angle, theta, rtol=1e-3)

        omega = np.array([1e-8, 1e-3, 0.5, np.pi, 2 * np.pi, 10.0, 4 * np.pi])
        cone = js.UniformCone.from_solid_angle(jnp.asarray(omega, dt))
        np.testing.assert_allclose(cone.one_minus_cos_theta_max, omega / (2 * np.pi), rtol=rtol)
        np.testing.assert_allclose(cone.solid_angle, omega, rtol=rtol)

        sin2 = np.array([1e-8, 1e-4, 0.09, 0.5, 0.99, 1.0])
        cone = js.UniformCone.from_sin2(jnp.asarray(sin2, dt))
        np.testing.assert_allclose(cone.one_minus_cos_theta_max, sin2 / (1 + np.sqrt(1 - sin2)), rtol=rtol)
        np.testing.assert_allclose(cone.cos_theta_max, np.sqrt(1 - sin2), rtol=rtol, atol=1e-7)


@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_cone_constructors_have_finite_derivatives_at_the_hard_cases(dtype):
    """d(1 - cos θ_max)/d(parameter) of each constructor, forward and reverse, at the caps the
    contract's hard cases name (1e-8 sr to the whole sphere); with the contract's check of the
    cone's derivatives in 1 - cos θ_max at those caps, every constructor's derivatives are finite."""
    constructors = {
        "from_solid_angle": (js.UniformCone.from_solid_angle, [1e-8, 1e-3, 2 * np.pi, 4 * np.pi]),
        "from_sin2": (js.UniformCone.from_sin2, [1e-8 / np.pi, 0.5, 1.0]),  # 1: the hemisphere
        "from_angle": (js.UniformCone.from_angle, [1e-4, 0.5, np.pi / 2, np.pi]),
        "cos_theta_max": (js.UniformCone, [-1.0, 0.0, 0.999]),
    }
    with jax.enable_x64(dtype == "float64"):
        for name, (build, values) in constructors.items():
            values = jnp.asarray(values, jnp.dtype(dtype))
            h = lambda v: build(v).one_minus_cos_theta_max  # noqa: E731
            for transform in (jax.jacfwd, jax.jacrev):
                derivative = np.asarray(jax.jit(jax.vmap(transform(h)))(values))
                assert np.all(np.isfinite(derivative)), (name, transform.__name__, derivative)


def test_densities_vanish_outside_the_support_without_nan():
    below = jnp.array([[0.0, 0.6, -0.8], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    for sampler in (js.UniformHemisphere(), js.CosineHemisphere(), js.PhongLobe(3.0),
                    js.UniformCone(0.9)):
        pdf = sampler.pdf(below[:1])
        assert float(pdf[0]) == 0.0 and float(sampler.log_pdf(below[:1])[0]) == -np.inf
    np.testing.assert_allclose(js.PhongLobe(0.0).pdf(below[1:2]), 1 / (2 * np.pi), rtol=1e-6)
    assert float(js.UniformCone(0.9).pdf(below[1:2])[0]) == 0.0


@pytest.mark.parametrize("build,message", [
    (lambda: js.PhongLobe(-1.0), r"'exponent' must be in \[0, 1e\+07\]"),
    (lambda: js.PhongLobe(float("nan")), "'exponent'"),
    (lambda: js.PhongLobe(2e7), "'exponent'"),
    (lambda: js.PhongLobe(jnp.array([1.0, -2.0])), "'exponent'"),
    (lambda: js.UniformCone(1.0), r"'cos_theta_max' must be in \[-1, 1\)"),
    (lambda: js.UniformCone(-1.5), "'cos_theta_max'"),
    (lambda: js.UniformCone(float("nan")), "'cos_theta_max'"),
    (lambda: js.UniformCone(one_minus_cos_theta_max=0.0), "'one_minus_cos_theta_max'"),
    (lambda: js.UniformCone.from_angle(0.0), "'theta_max'"),
    (lambda: js.UniformCone.from_solid_angle(-1.0), "'solid_angle'"),
    (lambda: js.VonMisesFisher(0.0), r"'kappa' must be in \[1e-06, 1e\+07\]"),
    (lambda: js.VonMisesFisher(float("inf")), "'kappa'"),
    (lambda: js.CosineHemisphere(method="cosine"), "'method'"),
    (lambda: js.UniformSphere(method="nope"), "'method'"),
    (lambda: js.Oriented(js.PhongLobe(1.0), jnp.zeros(3)), "'normal'"),
    (lambda: js.Frame.from_normal(jnp.array([np.nan, 0.0, 1.0])), "'normal'"),
    (lambda: js.Frame.from_normal(jnp.ones(2)), "'normal'"),
])
def test_invalid_concrete_parameters_raise_value_error(build, message):
    with pytest.raises(ValueError, match=message):
        build()


def test_jit_and_vmap_over_parameters_compile_once():
    traces = []

    @jax.jit
    def warp_batch(exponents, u):
        traces.append(1)
        return jax.vmap(lambda n: js.PhongLobe(n).warp_with_pdf(u))(exponents)

    u = jax.random.uniform(jax.random.key(8), (64, 2))
    for exponents in (jnp.array([0.0, 10.0, 1e7]), jnp.array([3.0, 4.0, 5.0])):
        x, pdf = warp_batch(exponents, u)
        for i, n in enumerate(exponents):
            x_ref, pdf_ref = js.PhongLobe(n).warp_with_pdf(u)
            np.testing.assert_allclose(x[i], x_ref, atol=1e-6)
            np.testing.assert_allclose(pdf[i], pdf_ref, rtol=1e-5)
    assert len(traces) == 1
    # Samplers built inside vmap from traced parameters, for every parametric family.
    for name in ("UniformCone", "VonMisesFisher"):
        entry = registry.BY_NAME[name]
        values = jnp.array([case.params[0] for case in entry.cases[:3]], jnp.float32)
        out = jax.jit(jax.vmap(lambda p: entry.make(p).sample(jax.random.key(0), (8,))))(values)
        assert out.shape == (3, 8, 3) and np.all(np.isfinite(out))


def test_sampler_is_a_pytree_with_parameters_as_leaves():
    leaves = jax.tree_util.tree_leaves(js.Oriented(js.PhongLobe(2.0), jnp.array([0.0, 1.0, 0.0])))
    assert any(np.ndim(l) == 0 and float(l) == 2.0 for l in leaves)
    assert len(jax.tree_util.tree_leaves(js.UniformCone(0.5))) == 1


@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_phong_gradients_at_1e7_and_u_next_to_one(dtype):
    # The sharpest lobe at the last representable u: the derivative in n of the sample and of its
    # density are finite, and match the closed forms d(1 - μ)/dn and d log p/dn.
    with jax.enable_x64(dtype == "float64"):
        dt = jnp.dtype(dtype)
        u = jnp.asarray([1.0 - 2.0 ** -24, 0.25], dt)
        n = jnp.asarray(1e7, dt)

        def one_minus_mu_and_log_pdf(n):
            x, p = js.PhongLobe(n).warp_with_pdf(u)
            return 1.0 - x[2], jnp.log(p)

        for transform in (jax.jacfwd, jax.jacrev):
            d_t, d_log_p = jax.jit(transform(one_minus_mu_and_log_pdf))(n)
            log_xi = np.log1p(-(1.0 - 2.0 ** -24))
            n64 = 1e7
            # 1 - μ = -expm1(L/(n+1)), L = log ξ: d/dn = expm1'(·) L/(n+1)² = e^{L/(n+1)} L/(n+1)².
            expected_t = np.exp(log_xi / (n64 + 1)) * log_xi / (n64 + 1) ** 2
            # log p = log(n+1) - log 2π + n L/(n+1): d/dn = 1/(n+1) + L/(n+1)².
            expected_log_p = 1.0 / (n64 + 1) + log_xi / (n64 + 1) ** 2
            np.testing.assert_allclose(float(d_log_p), expected_log_p, rtol=1e-4)
            if dtype == "float64":
                np.testing.assert_allclose(float(d_t), expected_t, rtol=1e-6)
            else:
                assert np.isfinite(float(d_t))


def test_vmf_far_hemisphere_direction_and_density_agree():
    """VonMisesFisher(10) beyond the equator (t = 1 - cos θ > 1): the direction is a unit vector and
    the returned density is the density of that direction, so f/p for f = e^{10 cos θ} is constant
    to float32 rounding (1e-5 relative; t from log1p(-u₀ s) there is off by 8e-4)."""
    kappa, t = 10.0, np.linspace(1.05, 1.6, 64)
    u0 = -np.expm1(-kappa * t) / -np.expm1(-2 * kappa)    # the uniforms that reach those t
    u = jnp.asarray(np.stack([u0, np.full_like(u0, 0.3)], axis=-1), jnp.float32)
    x, p = js.VonMisesFisher(kappa).warp_with_pdf(u)
    assert np.all(np.asarray(x[:, 2]) < -0.04)
    ratio = np.asarray(jnp.exp(kappa * x[:, 2]) / p)
    np.testing.assert_allclose(ratio, 4 * np.pi * np.sinh(kappa) / kappa, rtol=1e-5)
    np.testing.assert_allclose(np.linalg.norm(np.asarray(x, np.float64), axis=-1), 1.0, atol=1e-6)
