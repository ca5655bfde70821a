"""Foundation checks for every directional sampler: normalization, chi-square, inverse, Jacobian,
domain, finiteness at the hard cases in float32 and float64, parameter errors, jit and vmap.

Statistical false-failure rate: the chi-square tests below form one family of at most
`N_CHI2_TESTS` tests run at a family-wise significance of 1e-6 (Šidák-corrected per test), so the
whole file fails by chance with probability below 1e-6.

Power: the demonstrations that a wrong sampler is rejected run at the sample size the suite uses
for that family (`CHI2_SAMPLES`), and require a p-value far below the threshold, so that the
rejection is not one lucky key. At 400k samples a 2 % Phong exponent error was rejected for only
some keys, so the Phong families use 2M samples: there a 2 % error gives p < 1e-50 for every key
tried (a 1 % error is at the edge: rejected for 3 keys of 4 at n = 5). Cones 1 % too narrow give
p < 1e-150 at 400k.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import jaxsample as js
from jaxsample import domains as js_domains
from jaxsample.checks import sampler_checks as testing

F32_LAST = 1.0 - 2.0**-24
N_CHI2_TESTS = 40
FAMILY_SIGNIFICANCE = 1e-6

# (name, constructor from one float parameter, parameter values spanning the documented range)
FAMILIES = {
    "UniformSphere": (lambda p: js.UniformSphere(), [0.0]),
    "UniformSphere-rejection": (lambda p: js.UniformSphere(method="rejection"), [0.0]),
    "UniformHemisphere": (lambda p: js.UniformHemisphere(), [0.0]),
    "CosineHemisphere-malley": (lambda p: js.CosineHemisphere(), [0.0]),
    "CosineHemisphere-inversion": (lambda p: js.CosineHemisphere(method="inversion"), [0.0]),
    "PhongLobe": (lambda n: js.PhongLobe(n), [0.0, 1.0, 20.0, 100.0, 1e4, 1e7]),
    "UniformCone": (lambda h: js.UniformCone(one_minus_cos_theta_max=h),
                    [1e-8 / (2 * np.pi), 1e-6, 1e-3, 0.5, 1.0, 2.0]),
    "VonMisesFisher": (lambda k: js.VonMisesFisher(k), [1e-6, 1e-2, 1.0, 89.0, 1e3, 1e7]),
    "Oriented-Phong": (lambda n: js.Oriented(js.PhongLobe(n), jnp.array([0.3, -0.5, -0.8])),
                       [0.0, 10.0, 1e3]),
    "Oriented-Cone-down": (lambda h: js.Oriented(js.UniformCone(one_minus_cos_theta_max=h),
                                                 jnp.array([0.0, 0.0, -1.0])), [1e-3, 0.3]),
}
CASES = [(name, p) for name, (_, values) in FAMILIES.items() for p in values]
PARAMETRIC = {"PhongLobe": (0.0, 1e7), "UniformCone": (1e-9, 2.0), "VonMisesFisher": (1e-6, 1e7)}


def make(name, p):
    return FAMILIES[name][0](jnp.float32(p))


def hard_uniforms(dtype=jnp.float32, dims=2):
    """Every combination of u in {0, 0.5, 1 - 2^-24} in the first two coordinates (0.5 elsewhere),
    plus all-0 and all-(1 - 2^-24) rows for samplers that use more than two uniforms."""
    edges = jnp.array([0.0, 0.5, 1.0 - 2.0**-24], dtype)
    a, b = jnp.meshgrid(edges, edges, indexing="ij")
    rows = jnp.full((9, dims), 0.5, dtype).at[:, 0].set(a.ravel()).at[:, 1].set(b.ravel())
    if dims > 2:
        rows = jnp.concatenate([rows, jnp.full((2, dims), 0.0, dtype).at[1].set(edges[2])])
    return rows


@pytest.mark.parametrize("name,p", CASES)
def test_normalization_within_1e_6(name, p):
    assert abs(testing.normalization(make(name, p)) - 1.0) < 1e-6


@given(log_n=st.floats(0.0, 7.0), log_h=st.floats(-9.0, np.log10(2.0)), log_k=st.floats(-6.0, 7.0))
def test_normalization_across_the_documented_ranges(log_n, log_h, log_k):
    for sampler in (js.PhongLobe(jnp.float32(10**log_n - 1.0)),
                    js.UniformCone(one_minus_cos_theta_max=jnp.float32(10**log_h)),
                    js.VonMisesFisher(jnp.float32(10**log_k))):
        assert abs(testing.normalization(sampler) - 1.0) < 1e-6, sampler


CHI2_CASES = [c for c in CASES if c[1] not in (1e4,)]
# Samples per chi-square test, by family (default 400k): enough to reject a 2 % exponent error.
CHI2_SAMPLES = {"PhongLobe": 2_000_000, "Oriented-Phong": 2_000_000}


def chi2_samples(name):
    return CHI2_SAMPLES.get(name, 400_000)


@pytest.mark.parametrize("name,p", CHI2_CASES)
def test_chi_square_goodness_of_fit(name, p):
    assert len(CHI2_CASES) <= N_CHI2_TESTS
    key = jax.random.fold_in(jax.random.key(20261121), CASES.index((name, p)))
    result = testing.chi2_test(make(name, p), key, n_samples=chi2_samples(name),
                               significance=FAMILY_SIGNIFICANCE, n_tests=N_CHI2_TESTS)
    assert result.passed, result


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
    # At the suite's own sample size for the family, and by a wide margin: p below 1e-20 where
    # the threshold is 2.5e-8 (the margin seen over keys is tens of decades).
    result = testing.chi2_test(wrong, jax.random.key(7), n_samples=chi2_samples(family),
                               significance=FAMILY_SIGNIFICANCE, n_tests=N_CHI2_TESTS)
    assert not result.passed and result.p_value < 1e-20, result


@pytest.mark.parametrize("name,p", [c for c in CASES if make(*c).has_inverse])
def test_inverse_round_trip(name, p):
    sampler = make(name, p)
    u = jax.random.uniform(jax.random.key(3), (4096, 2))
    u = jnp.concatenate([u, hard_uniforms()])
    # At the pole (sin θ = 0) the azimuth is not recoverable: the warp is a bijection only off
    # that measure-zero set, so there only the polar coordinate is compared.
    x = sampler.warp(u)
    at_pole = np.asarray(u[:, 0] == 0) & bool(sampler.periodic_dims)  # u₀ = 0 is the pole
    # float32: 2e-6 on u. A rotated lobe loses ~1e-7 absolute per component in the rotation,
    # which n = 1000 amplifies in u₀ = 1 - cos^{n+1}: Oriented gets 5e-5 (documented there).
    tolerance = 5e-5 if isinstance(sampler, js.Oriented) else 2e-6
    assert float(jnp.max(testing.inverse_error(sampler, u[~at_pole]))) < tolerance
    polar = np.abs(np.asarray(sampler.inverse(x[at_pole])[:, 0] - u[at_pole][:, 0]))
    assert np.all(polar < tolerance)


@pytest.mark.parametrize("name,p", [c for c in CASES if make(*c).has_inverse])
def test_density_matches_the_autodiff_jacobian_of_the_warp(name, p):
    # In float64 the Jacobian of the warp is accurate even for lobes 1e-7 wide.
    with jax.enable_x64(True):
        sampler = FAMILIES[name][0](jnp.float64(p))
        u = jax.random.uniform(jax.random.key(4), (512, 2), dtype=jnp.float64)
        u = 1e-3 + (1 - 2e-3) * u  # away from the horizon, where pdf -> 0 and J -> inf
        assert float(jnp.max(testing.jacobian_error(sampler, u))) < 1e-6


@pytest.mark.parametrize("name,p", CASES)
def test_samples_are_unit_vectors_inside_the_support(name, p):
    sampler = make(name, p)
    x, pdf = sampler.sample_with_pdf(jax.random.key(5), (20_000,))
    assert x.shape == (20_000, 3) and x.dtype == jnp.float32
    assert np.all(js_domains.contains(sampler.domain(), np.asarray(x)))
    assert np.all(np.asarray(pdf) > 0)
    np.testing.assert_allclose(sampler.pdf(x), pdf, rtol=2e-5)
    np.testing.assert_allclose(sampler.log_pdf(x), jnp.log(pdf), atol=2e-5)


def _probe(name, dtype):
    """A scalar function of (parameter, u) touching warp, pdf, log_pdf and warp_with_pdf."""

    def probe(p, u):
        sampler = FAMILIES[name][0](p)
        x, pdf = sampler.warp_with_pdf(u)
        log_pdf = sampler.log_pdf(x)  # -inf where the density is 0 (Malley's corners: the horizon)
        return (jnp.sum(x * jnp.array([0.3, 0.5, 0.7], dtype)) + pdf * 1e-3
                + jnp.where(jnp.isfinite(log_pdf), log_pdf, 0.0) * 1e-3)

    return probe


@pytest.mark.parametrize("dtype", ["float32", "float64"])
@pytest.mark.parametrize("name,p", CASES)
def test_no_nan_or_inf_in_values_and_gradients_at_the_hard_cases(name, p, dtype):
    with jax.enable_x64(dtype == "float64"):
        dt = jnp.dtype(dtype)
        probe = _probe(name, dt)
        param = jnp.asarray(p, dt)
        sampler = FAMILIES[name][0](param)
        u = hard_uniforms(dt, sampler.uniform_dims)
        x, pdf = sampler.warp_with_pdf(u)
        assert np.all(np.isfinite(x)) and np.all(np.isfinite(pdf)) and np.all(pdf >= 0), (u, x, pdf)
        assert np.all(np.isfinite(sampler.pdf(x))) and not np.any(np.isnan(sampler.log_pdf(x)))
        assert np.all(np.isfinite(jax.vmap(probe, (None, 0))(param, u)))
        for transform in (jax.jacfwd, jax.jacrev):  # forward and reverse mode (grad is jacrev here)
            grads = jax.jit(jax.vmap(transform(probe, argnums=(0, 1)), (None, 0)))(param, u)
            for g in grads:
                assert np.all(np.isfinite(np.asarray(g))), (u, grads)


def test_float32_matches_float64_at_the_hard_cases():
    # The worst float32 error of directions and densities against a float64 reference.
    worst_direction, worst_pdf = 0.0, 0.0
    for name, p in CASES:
        u32 = hard_uniforms(jnp.float32, make(name, p).uniform_dims)
        x32, p32 = make(name, p).warp_with_pdf(u32)
        with jax.enable_x64(True):
            x64, p64 = FAMILIES[name][0](jnp.float64(np.float32(p))).warp_with_pdf(u32.astype(jnp.float64))
            x64, p64 = np.asarray(x64), np.asarray(p64)
        worst_direction = max(worst_direction, float(np.max(np.abs(np.asarray(x32) - x64))))
        positive = p64 > 0
        assert np.all(np.asarray(p32)[~positive] == 0)
        worst_pdf = max(worst_pdf, float(np.max(np.abs(np.asarray(p32)[positive] / p64[positive] - 1))))
    assert worst_direction < 1e-6 and worst_pdf < 1e-5, (worst_direction, worst_pdf)


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
        values = jnp.array(FAMILIES[name][1][:3], jnp.float32)
        out = jax.jit(jax.vmap(lambda p: FAMILIES[name][0](p).sample(jax.random.key(0), (8,))))(values)
        assert out.shape == (3, 8, 3) and np.all(np.isfinite(out))


def test_sampler_is_a_pytree_with_parameters_as_leaves():
    leaves = jax.tree_util.tree_leaves(js.Oriented(js.PhongLobe(2.0), jnp.array([0.0, 1.0, 0.0])))
    assert any(np.ndim(l) == 0 and float(l) == 2.0 for l in leaves)
    assert len(jax.tree_util.tree_leaves(js.UniformCone(0.5))) == 1
