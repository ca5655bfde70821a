"""What is particular to HenyeyGreenstein, Normal, Normal2D, Tent, Linear and Bilinear; their
contract (normalization, chi-square, inverse, Jacobian, support, finite values and gradients at
the hard cases) is `test_contract.py`, over the entries of `registry.py`.

Here: exact references. The HG warp against exact rational arithmetic at the hard g's; its
normalization and Legendre moments E[P_l(cos θ)] = g^l by float64 quadrature; d/dg of
expectations, pathwise, against a float64 quadrature of ∂p/∂g (deterministic, float32 and
float64) and by Monte Carlo through `expectation_grad`; continuity of the warp and its derivative
through g = 0. Normal and Normal2D moments by quadrature and tails against SciPy's float64
quantile; closed-form CDFs of the tent, linear and bilinear densities against their warps and the
a -> b limit; a wrong g the chi-square test rejects; parameter errors.
"""

from __future__ import annotations

from fractions import Fraction

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.special

import registry
from helpers import WrongWarp
import jaxsample as js
from jaxsample.domains import gauss_legendre_panels, graded_edges
from jaxsample.testing.sampler_checks import chi2_test, pdf_float64

F32_LAST = 1.0 - 2.0 ** -24
HARD_G = (0.0, 1e-4, -1e-4, 0.5, -0.5, 0.99, -0.99, 1.0 - 1e-4, -(1.0 - 1e-4))


def _unit_rule(n_uniform=16, n_geometric=40):
    """Gauss–Legendre nodes and weights on [0, 1], graded toward both ends (float64)."""
    return gauss_legendre_panels(graded_edges(0.0, 1.0, n_uniform=n_uniform, n_geometric=n_geometric))


def _t_rule():
    """Nodes t = 1 - cos θ in [0, 2], graded toward both poles, and their weights."""
    t, w = gauss_legendre_panels(graded_edges(0.0, 2.0))
    return t, w


# ---------------------------------------------------------------------------------------------
# Henyey–Greenstein
# ---------------------------------------------------------------------------------------------


def _exact_one_minus_and_plus_cos(g: float, xi: float):
    """(1 - μ, 1 + μ) of the textbook inverse CDF in exact rational arithmetic."""
    g, xi = Fraction(g), Fraction(xi)
    if g == 0:
        mu = 2 * xi - 1
    else:
        s = (1 - g * g) / (1 - g + 2 * g * xi)
        mu = (1 + g * g - s * s) / (2 * g)
    return 1 - mu, 1 + mu


@jax.jit
def _warp_with_pdf(sampler, u):
    return sampler.warp_with_pdf(u)


def test_hg_warp_matches_exact_rational_arithmetic_at_the_hard_g():
    """At the float32 hard g's and u from 0 to 1 - 2^-24, both 1 - cos θ and 1 + cos θ of the
    sample, recomputed from its components, and its density agree with the exact values to a few
    float32 ulps, at both poles (the textbook form loses them all near the pole its g favours)."""
    xis = np.array([0.0, 1e-30, 1e-7, 0.01, 0.25, 0.5, 0.75, 0.99, 1.0 - 1e-6, F32_LAST], np.float32)
    u = jnp.asarray(np.stack([xis, np.full_like(xis, 0.3)], axis=-1))
    tiny = float(np.finfo(np.float32).tiny)
    for g in HARD_G:
        g32 = float(np.float32(g))
        sampler = js.HenyeyGreenstein(np.float32(g))
        x, p = (np.asarray(a, np.float64) for a in _warp_with_pdf(sampler, u))
        sin2 = x[:, 0] ** 2 + x[:, 1] ** 2
        one_minus = np.where(x[:, 2] > 0, sin2 / np.maximum(1.0 + x[:, 2], 1.0), 1.0 - x[:, 2])
        one_plus = np.where(x[:, 2] < 0, sin2 / np.maximum(1.0 - x[:, 2], 1.0), 1.0 + x[:, 2])
        for i, xi in enumerate(xis):
            exact_minus, exact_plus = _exact_one_minus_and_plus_cos(g32, float(xi))
            # The smaller of the two carries the information; below float32's normal range
            # (1 + μ = 1e-38 at g = -(1 - 1e-4), ξ = 1e-30) it cannot be held, only rounded to 0.
            got, exact = (one_minus[i], exact_minus) if exact_minus < 1 else (one_plus[i], exact_plus)
            if exact > 100 * tiny:
                assert abs(got - float(exact)) <= 1e-6 * float(exact), (g, xi, got, float(exact))
            w = 1 + Fraction(g32) ** 2 - 2 * Fraction(g32) * (1 - exact_minus)
            density = float((1 - Fraction(g32) ** 2) / (4 * Fraction(np.pi) * w)) / np.sqrt(float(w))
            assert abs(p[i] - density) <= 2e-6 * density, (g, xi, p[i], density)
        np.testing.assert_allclose(np.asarray(sampler.pdf(jnp.asarray(x, jnp.float32))), p, rtol=2e-6)


def test_hg_normalization_and_legendre_moments_by_float64_quadrature():
    """∫ p dω = 1 and E[P_l(cos θ)] = g^l for l = 1, 2, 3 (the mean cosine is g) at every hard g,
    by Gauss–Legendre panels in t = 1 - cos θ graded toward both poles (in 1 + cos θ for g < 0,
    so that the lobe sits at the rule's well-resolved end)."""
    t, w = _t_rule()
    sin_theta = np.sqrt(t * (2.0 - t))
    up = np.stack([sin_theta, np.zeros_like(t), 1.0 - t], axis=-1)
    for g in HARD_G:
        g64 = float(np.float32(g))
        sampler = js.HenyeyGreenstein(g64)  # a Python float: promoted to float64 with the points
        points = up if g64 >= 0 else up * np.array([1.0, 1.0, -1.0])
        mu = points[:, 2]
        mass = 2.0 * np.pi * w * pdf_float64(sampler, points)
        legendre = [np.ones_like(mu), mu, 1.5 * mu ** 2 - 0.5, 2.5 * mu ** 3 - 1.5 * mu]
        for order, values in enumerate(legendre):
            assert abs(np.sum(mass * values) - g64 ** order) < 1e-9, (g, order, np.sum(mass * values))


def _f_bar(mu):
    """E over the azimuth of f(ω) = exp(2 ω_z) + ω_x²: exp(2μ) + (1 - μ²)/2."""
    return np.exp(2.0 * mu) + 0.5 * (1.0 - mu * mu)


def _d_expectation_dg_reference(g: float, f_bar) -> float:
    """d/dg ∫ f̄(μ) p_g(μ) dμ in float64 NumPy, from the closed-form ∂p/∂g of the density of μ,
    p_g(μ) = (1 - g²)/(2 w^{3/2}), w = 1 + g² - 2gμ: ∂p/∂g = -g w^{-3/2} - (3/2)(1 - g²)(g - μ) w^{-5/2}.
    For g < 0 by the mirror symmetry p_g(μ) = p_{-g}(-μ), so the nodes stay graded toward the lobe."""
    if g < 0:
        return -_d_expectation_dg_reference(-g, lambda mu: f_bar(-mu))
    t, wt = _t_rule()
    mu = 1.0 - t
    w = (1.0 - g) ** 2 + 2.0 * g * t
    dp = -g * w ** -1.5 - 1.5 * (1.0 - g * g) * (g - mu) * w ** -2.5
    return float(np.sum(wt * f_bar(mu) * dp))


def _expectation_by_quadrature(g, xi, w_xi, n_phi: int):
    """E[(ω_z, exp(2 ω_z) + ω_x²)] under HG(g), as a quadrature of the warp over u: Gauss–Legendre
    in u₀ and the trapezoid rule in u₁ (exact for these integrands' cos² φ)."""
    phi = (jnp.arange(n_phi, dtype=xi.dtype) + 0.5) / n_phi
    u = jnp.stack(jnp.broadcast_arrays(xi[:, None], phi[None, :]), axis=-1).reshape(-1, 2)
    x = js.HenyeyGreenstein(g).warp(u)
    weights = jnp.repeat(w_xi, n_phi) / n_phi
    z = x[:, 2]
    return jnp.stack([jnp.sum(weights * z), jnp.sum(weights * (jnp.exp(2.0 * z) + x[:, 0] ** 2))])


_d_expectation_by_quadrature = jax.jit(jax.jacfwd(_expectation_by_quadrature), static_argnums=3)


@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_hg_pathwise_derivative_matches_a_float64_quadrature_derivative(dtype):
    """d/dg E[cos θ] = 1 and d/dg E[exp(2 ω_z) + ω_x²], from autodiff of the warp (the pathwise
    derivative, integrated over u by a fixed rule), against the float64 quadrature of f̄ ∂p/∂g:
    deterministic, at every hard g (near |g| = 1 the per-sample derivative reaches 1/(1 - |g|), so
    a Monte Carlo check there would have a huge variance; this one has none)."""
    xi, w_xi = _unit_rule()
    with jax.enable_x64(dtype == "float64"):
        dt = jnp.float64 if dtype == "float64" else jnp.float32
        xi, w_xi = jnp.asarray(xi, dt), jnp.asarray(w_xi, dt)
        for g in HARD_G:
            g_here = np.float32(g) if dtype == "float32" else float(np.float32(g))
            d_mean, d_f = np.asarray(_d_expectation_by_quadrature(jnp.asarray(g_here, dt), xi, w_xi, 8), np.float64)
            expected = _d_expectation_dg_reference(float(g_here), _f_bar)
            # float32 nodes near u₀ = 1 (where g -> -1 puts its lobe) are rounded to 6e-8,
            # which is 6e-4 of the lobe's width in u₀ at g = -(1 - 1e-4).
            tolerance = 1e-9 if dtype == "float64" else 1e-4
            assert abs(d_mean - 1.0) < tolerance, (g, dtype, d_mean)
            assert abs(d_f - expected) < tolerance * max(1.0, abs(expected)), (g, dtype, d_f, expected)


def _mean_cosine(g):
    return (lambda w: w[2]), js.HenyeyGreenstein(g)


@pytest.mark.parametrize("g", [0.0, -0.5, 0.99])
def test_hg_pathwise_estimate_of_d_mean_cosine_dg_is_one(g):
    """`expectation_grad` (pathwise, float32, 2^14 samples): d/dg E[cos θ] = 1 within 5 standard
    errors (false-failure rate 5.7e-7 per case, Gaussian limit: the per-sample derivative has a
    finite fourth moment at these g; its variance grows as 1/(1 - |g|), which is why the hard g's
    near ±1 are checked by quadrature above)."""
    estimate = js.expectation_grad(_mean_cosine, jnp.float32(g), jax.random.key(24), 1 << 14)
    z = (float(estimate.mean) - 1.0) / float(estimate.stderr)
    assert abs(z) < 5.0, (g, float(estimate.mean), float(estimate.stderr))


@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_hg_warp_and_its_derivative_are_continuous_through_g_zero(dtype):
    """At g = 0 the sample is isotropic (cos θ = 2ξ - 1) and dcos θ/dg = 6ξ(1 - ξ) (the
    first-order term of the inverse CDF): the same, to rounding, just either side of 0, where the
    textbook form is 0/0 and PBRT's and Mitsuba's branches switch formula."""
    xi = np.array([0.0, 1e-6, 0.1, 0.25, 0.5, 0.75, 0.9, F32_LAST])
    with jax.enable_x64(dtype == "float64"):
        dt = jnp.float64 if dtype == "float64" else jnp.float32
        u = jnp.asarray(np.stack([xi, np.full_like(xi, 0.2)], axis=-1), dt)
        cos_theta = jax.jit(lambda g: js.HenyeyGreenstein(g).warp(u)[:, 2])
        d_cos_theta = jax.jit(jax.jacfwd(lambda g: js.HenyeyGreenstein(g).warp(u)[:, 2]))
        for g in (-1e-7, -1e-30, 0.0, 1e-30, 1e-7):
            g = jnp.asarray(g, dt)
            np.testing.assert_allclose(np.asarray(cos_theta(g)), 2.0 * xi - 1.0,
                                       atol=4e-7 if dtype == "float32" else 3e-7)
            np.testing.assert_allclose(np.asarray(d_cos_theta(g)), 6.0 * xi * (1.0 - xi), atol=2e-6)


def test_chi2_rejects_a_wrong_g():
    # g = -0.48 sampled, -0.5 claimed: at the contract's settings for HenyeyGreenstein (400 000
    # samples) p < 1e-100 for every key tried, where the Šidák threshold is ~1e-8. FFR below 1e-26
    # (estimated: a noncentral chi-square(127) whose median p is 1e-100 reaches 1e-20 that rarely).
    wrong = WrongWarp(js.HenyeyGreenstein(-0.5), js.HenyeyGreenstein(-0.48))
    result = chi2_test(wrong, jax.random.key(7), **registry.chi2_settings("HenyeyGreenstein"))
    assert not result.passed and result.p_value < 1e-20, result


# ---------------------------------------------------------------------------------------------
# Gaussians
# ---------------------------------------------------------------------------------------------


def test_normal_moments_by_quadrature_and_through_the_warp():
    """Mean μ and variance σ² by the domain's float64 quadrature of the density, and by a
    quadrature of the warp over u (graded toward u = 0 and 1, where the quantile has its log
    singularities), the latter in float64 with the clamp at 2^-53 costing below 1e-13."""
    u, w = _unit_rule(n_geometric=60)
    with jax.enable_x64(True):
        for loc, scale in ((0.0, 1.0), (-3.0, 1e-6), (2.5, 1e6)):
            sampler = js.Normal(loc, scale)
            points, weights = js.domains.quadrature(sampler.domain())
            p = pdf_float64(sampler, points)
            # The panels' ends carry loc's rounding, 1e-9 of their width for σ = 1e-6 at loc = -3.
            assert abs(np.sum(weights * p) - 1.0) < 1e-9
            assert abs(np.sum(weights * p * points) - loc) < 1e-9 * max(1.0, scale)
            assert abs(np.sum(weights * p * (points - loc) ** 2) / scale ** 2 - 1.0) < 1e-9
            x = np.asarray(sampler.warp(jnp.asarray(u[:, None])), np.float64)
            assert abs(np.sum(w * x) - loc) < 1e-12 * max(1.0, abs(loc), scale)
            assert abs(np.sum(w * (x - loc) ** 2) / scale ** 2 - 1.0) < 1e-9


def test_normal_tails_are_finite_and_accurate_in_float32():
    """u = 0 maps to the mirror image of u = 1 - 2^-24 (±5.33σ); over [2^-24, 1 - 2^-24] the
    quantile matches SciPy's float64 one to 1e-6 relative, both tails included (erf⁻¹(2u - 1) is
    0.8 % off at u = 7e-8 in float32), and the inverse returns u to 1e-5 relative in the lower tail."""
    sampler = js.Normal(1.0, 2.0)
    edges = np.asarray(sampler.warp(jnp.array([[0.0], [2.0 ** -24], [0.5], [F32_LAST]], jnp.float32)), np.float64)
    assert np.all(np.isfinite(edges))
    assert edges[0] == edges[1] and abs((edges[0] - 1.0) + (edges[3] - 1.0)) < 1e-5 and edges[2] == 1.0
    assert abs((edges[0] - 1.0) / 2.0 - scipy.special.ndtri(2.0 ** -24)) < 1e-5
    low = np.geomspace(2.0 ** -24, 0.5, 2000).astype(np.float32)
    u = np.concatenate([low, (1.0 - np.geomspace(2.0 ** -24, 0.5, 2000)).astype(np.float32)])
    z = (np.asarray(sampler.warp(jnp.asarray(u[:, None])), np.float64) - 1.0) / 2.0
    exact = scipy.special.ndtri(u.astype(np.float64))
    assert np.max(np.abs(z - exact) / np.maximum(np.abs(exact), 1.0)) < 1e-6
    back = np.asarray(sampler.inverse(jnp.asarray(1.0 + 2.0 * exact[:2000], jnp.float32)), np.float64)[:, 0]
    assert np.max(np.abs(back - low) / low) < 1e-5


def test_normal_2d_moments_and_the_radial_law():
    """Mean and covariance diag(σ²) by the domain's float64 quadrature; |z|²/2 = -log(1 - u₀)
    exactly (the polar form: the squared radius is exponential); and the round trip of the
    anisotropic hard case, which the contract leaves out (its Jacobian check cancels there)."""
    with jax.enable_x64(True):
        sampler = js.Normal2D([1.0, -2.0], [0.5, 3.0])
        points, weights = js.domains.quadrature(sampler.domain())
        p = weights * pdf_float64(sampler, points)
        assert abs(np.sum(p) - 1.0) < 1e-12
        np.testing.assert_allclose(p @ points, [1.0, -2.0], atol=1e-12)
        centred = points - np.array([1.0, -2.0])
        np.testing.assert_allclose((centred * p[:, None]).T @ centred, np.diag([0.25, 9.0]), atol=1e-11)
        u = jnp.asarray(np.random.default_rng(1).random((512, 2)))
        z = (np.asarray(sampler.warp(u)) - [1.0, -2.0]) / [0.5, 3.0]
        np.testing.assert_allclose(0.5 * np.sum(z * z, axis=-1), -np.log1p(-np.asarray(u[:, 0])), rtol=1e-13)
    thin = js.Normal2D([0.0, 0.0], [1e-6, 1e6])
    u = jnp.asarray(1e-3 + (1.0 - 2e-3) * np.random.default_rng(2).random((2048, 2)), jnp.float32)
    error = np.asarray(js.testing.inverse_error(thin, u))
    assert np.max(error) < 2e-4, np.max(error)


# ---------------------------------------------------------------------------------------------
# Tent, linear, bilinear: closed-form CDFs against the warps
# ---------------------------------------------------------------------------------------------

_U = np.concatenate([[0.0, 1e-30, 1e-10, 1e-6, 0.5 - 2.0 ** -24, 0.5, 0.5 + 2.0 ** -24, 1.0 - 1e-6, F32_LAST],
                     np.linspace(0.0, 1.0, 257)[1:-1]])


def test_tent_cdf_in_closed_form():
    """F(x) = (1 + x/r)²/2 for x < 0 and 1 - (1 - x/r)²/2 for x >= 0, at the warped points, is u
    (float64: 1e-13; float32: 1e-7 absolute), and near the peak x keeps its relative precision."""
    def cdf(x, r):
        t = 1.0 - np.abs(x) / r
        return np.where(x < 0, 0.5 * t * t, 1.0 - 0.5 * t * t)

    for r in (1e-6, 1.0, 1e6):
        with jax.enable_x64(True):
            x = np.asarray(js.Tent(r).warp(jnp.asarray(_U[:, None])))
        np.testing.assert_allclose(cdf(x, r), _U, atol=1e-13)
        u32 = _U.astype(np.float32)
        x32 = np.asarray(js.Tent(np.float32(r)).warp(jnp.asarray(u32[:, None])), np.float64)
        np.testing.assert_allclose(cdf(x32, float(np.float32(r))), u32, atol=1e-7)
        # Just either side of the peak: x = r(2u - 1)/(1 + √(2w)), exact to a few ulps.
        near = np.array([0.5 - 2.0 ** -24, 0.5 + 2.0 ** -24, 0.5 + 2.0 ** -20], np.float32).astype(np.float64)
        w = np.minimum(near, 1.0 - near)
        exact = float(np.float32(r)) * (2.0 * near - 1.0) / (1.0 + np.sqrt(2.0 * w))
        got = np.asarray(js.Tent(np.float32(r)).warp(jnp.asarray(near[:, None], jnp.float32)), np.float64)
        np.testing.assert_allclose(got, exact, rtol=1e-6)


def _linear_cdf_textbook(x, a, b):
    """F(x) = (2a x + (b - a) x²)/(a + b), float64."""
    return (2.0 * a * x + (b - a) * x * x) / (a + b)


def _linear_quantile_by_bisection(u, a, b, steps=80):
    low, high = np.zeros_like(u), np.ones_like(u)
    for _ in range(steps):
        middle = 0.5 * (low + high)
        below = _linear_cdf_textbook(middle, a, b) < u
        low, high = np.where(below, middle, low), np.where(below, high, middle)
    return 0.5 * (low + high)


LINEAR_CASES = [(1.0, 3.0), (3.0, 1.0), (0.0, 1.0), (1.0, 0.0), (2.0, 2.0), (1.0, 1.0 + 2.0 ** -23), (1.0, 1.0001),
                (1e6, 1e-6), (1e-30, 1e30)]


def test_linear_quantile_against_bisection_of_the_closed_form_cdf():
    """The float32 warp against the float64 root of F(x) = u found by bisection, for weights equal
    (the textbook root's 0/0), one ulp apart, 1e-4 apart, with a zero at either end and 60 orders
    of magnitude apart: within 3e-7 absolute, and relative near x = 0 where it matters (x = √u for
    a = 0, u/2 for b = 0, u for a = b); the density from u is the closed form at the sample."""
    u32 = _U.astype(np.float32)
    for a, b in LINEAR_CASES:
        a32, b32 = np.float32(a), np.float32(b)
        x, p = (np.asarray(v, np.float64) for v in _warp_with_pdf(js.Linear(a32, b32), jnp.asarray(u32[:, None])))
        exact = _linear_quantile_by_bisection(u32.astype(np.float64), float(a32), float(b32))
        assert np.all(np.abs(x - exact) <= 3e-7 + 2e-6 * exact), (a, b, np.max(np.abs(x - exact)))
        density = 2.0 * ((1.0 - x) * float(a32) + x * float(b32)) / (float(a32) + float(b32))
        np.testing.assert_allclose(p, density, rtol=1e-5, atol=1e-6, err_msg=f"{a}, {b}")
    small = np.array([1e-30, 1e-20, 1e-10], np.float32)
    for (a, b), expected in (((0.0, 1.0), np.sqrt(small.astype(np.float64))), ((1.0, 0.0), 0.5 * small),
                             ((2.0, 2.0), small)):
        got = np.asarray(js.Linear(a, b).warp(jnp.asarray(small[:, None])), np.float64)
        np.testing.assert_allclose(got, expected, rtol=1e-6)


def test_linear_tends_to_the_uniform_as_a_tends_to_b():
    u = jnp.asarray(_U[:, None], jnp.float32)
    uniform = np.asarray(js.Linear(1.0, 1.0).warp(u))
    np.testing.assert_array_equal(uniform, np.asarray(u[:, 0]))
    for delta in (2.0 ** -23, 1e-6, 1e-4):
        x = np.asarray(js.Linear(1.0, 1.0 + delta).warp(u), np.float64)
        # To first order in δ = b - a (a = 1), x = u + (δ/2) u (1 - u), from F(x) = u; the next
        # term, -(δ²/2) u²(1 - u), is below 1e-8 here.
        expected = _U + 0.5 * float(np.float32(1.0 + delta) - 1.0) * _U * (1.0 - _U)
        assert np.max(np.abs(x - expected)) < 3e-7, (delta, np.max(np.abs(x - expected)))  # 5 ulps of 1/2


BILINEAR_CASES = [(1.0, 2.0, 3.0, 4.0), (0.0, 0.0, 1.0, 3.0), (0.0, 1.0, 1.0, 0.0), (1e6, 1.0, 0.0, 1e-6),
                  (5.0, 0.0, 0.0, 0.0)]


def test_bilinear_marginal_and_conditional_cdfs_in_closed_form():
    """The marginal CDF of y, F(y) = ∫₀^y ∫₀^1 p dx dy', and the conditional CDF of x given y,
    written from the bilinear form in float64, return u₁ and u₀ at the warped points; the
    density from u is the bilinear form at the sample."""
    grid = np.linspace(0.0, 1.0, 33)
    grid[-1] = F32_LAST
    u = np.stack(np.meshgrid(grid, grid, indexing="ij"), axis=-1).reshape(-1, 2).astype(np.float32)
    for w in BILINEAR_CASES:
        w00, w10, w01, w11 = (float(np.float32(v)) for v in w)
        total = w00 + w10 + w01 + w11
        point, p = (np.asarray(v, np.float64) for v in _warp_with_pdf(js.Bilinear(np.float32(w)), jnp.asarray(u)))
        x, y = point[:, 0], point[:, 1]
        marginal = ((w00 + w10) * (y - 0.5 * y * y) + (w01 + w11) * 0.5 * y * y) * 2.0 / total
        np.testing.assert_allclose(marginal, u[:, 1], atol=1e-6, err_msg=str(w))
        left, right = (1.0 - y) * w00 + y * w01, (1.0 - y) * w10 + y * w11
        row = left + right
        conditional = np.where(row > 0,
                               (left * (x - 0.5 * x * x) + right * 0.5 * x * x) * 2.0 / np.where(row > 0, row, 1.0),
                               x)  # a row of zero density is given uniform x
        np.testing.assert_allclose(conditional, u[:, 0], atol=1e-6, err_msg=str(w))
        bilerp = (1 - x) * (1 - y) * w00 + x * (1 - y) * w10 + (1 - x) * y * w01 + x * y * w11
        np.testing.assert_allclose(p, 4.0 * bilerp / total, rtol=1e-5, atol=1e-5, err_msg=str(w))


# ---------------------------------------------------------------------------------------------
# Parameters
# ---------------------------------------------------------------------------------------------


def test_invalid_parameters_raise_and_traced_ones_give_nan():
    for make, match in ((lambda: js.HenyeyGreenstein(1.0), r"HenyeyGreenstein: parameter 'g' must be in \(-1, 1\)"),
                        (lambda: js.HenyeyGreenstein(float("nan")), "'g'"),
                        (lambda: js.Normal(0.0, 0.0), r"Normal: parameter 'scale' must be in \(0, inf\)"),
                        (lambda: js.Normal(float("inf"), 1.0), "Normal: parameter 'loc'"),
                        (lambda: js.Normal2D([0.0, 0.0], [1.0, -1.0]), "Normal2D: parameter 'scale'"),
                        (lambda: js.Normal2D([0.0, 1.0, 2.0]), "Normal2D: parameter 'loc' must have shape"),
                        (lambda: js.Tent(0.0), "Tent: parameter 'radius'"),
                        (lambda: js.Linear(-1.0, 1.0), "Linear: parameter 'a'"),
                        (lambda: js.Linear(0.0, 0.0), "Linear: parameters 'a' and 'b' must not both be 0"),
                        (lambda: js.Bilinear([0.0, 0.0, 0.0, 0.0]), "Bilinear: parameter 'w' must not be all 0"),
                        (lambda: js.Bilinear([1.0, -1.0, 1.0, 1.0]),
                         r"Bilinear: parameter 'w' must have every entry in \[0"),
                        (lambda: js.Bilinear([1.0, 2.0, 3.0]),
                         r"Bilinear: parameter 'w' must have shape \(\.\.\., 4\)")):
        with pytest.raises(ValueError, match=match):
            make()
    u = jnp.full((3, 2), 0.3)
    assert np.all(np.isnan(jax.jit(lambda a, b: js.Linear(a, b).warp(u[:, :1]))(0.0, 0.0)))
    assert np.all(np.isnan(jax.jit(lambda w: js.Bilinear(w).warp(u))(jnp.zeros(4))))
    assert np.all(np.isnan(jax.jit(lambda m: js.Normal(m, 1.0).pdf(jnp.zeros(3)))(jnp.inf)))
    assert np.all(np.isnan(jax.jit(lambda g: js.HenyeyGreenstein(g).warp(u))(1.0)))


def test_batches_of_parameters():
    """Leading parameter dimensions are a batch; Normal2D's scalar scale is repeated on both axes."""
    batch = js.Normal2D(jnp.zeros((5, 2)), 2.0)
    assert batch.batch_shape == (5,) and batch.scale.shape == (2,)
    np.testing.assert_allclose(np.asarray(batch.prob(jnp.zeros((5, 2)))), np.full(5, 1.0 / (8.0 * np.pi)), rtol=1e-6)
    densities = js.Linear(jnp.array([0.0, 1.0]), jnp.array([1.0, 1.0])).prob(jnp.full((2,), 0.5))
    np.testing.assert_allclose(np.asarray(densities), [1.0, 1.0], rtol=1e-6)
    assert js.Bilinear(jnp.ones((3, 4))).batch_shape == (3,)
