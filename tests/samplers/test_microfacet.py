"""What is particular to the microfacet samplers (`GGX`, `Beckmann`, `VisibleNormals`,
`MicrofacetReflection`); the contract (normalization, chi-square, inverse, Jacobian, support, finite
values and gradients at the hard cases) is `test_contract.py` over their `registry.py` entries.

Exact references, in float64 quadrature written here (Cartesian in the unit-roughness slopes, with
the visible half plane's edge a grid line, independent of the polar chart the samplers' domain uses):
∫ D(m) cos θ_m dm = 1, the weak white furnace ∫ G1(wo, m) max(0, wo·m) D(m) dm = cos θ_o (Heitz
2014, eq. 38), Λ and G1 against their closed forms, and the roughness derivative of GGX's directional
albedo estimated pathwise over `MicrofacetReflection` samples against a finite difference of the
albedo's quadrature. Plus: wrong samplers the chi-square family rejects, wo's normalisation and its
side, isotropy as alpha_y = None, the Beckmann inversion's convergence, and derivatives in alpha.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.special as special

import jaxsample as js
from jaxsample import testing
from jaxsample.samplers import microfacet_beckmann

import registry

DISTRIBUTIONS = {"GGX": js.GGX, "Beckmann": js.Beckmann}
ALPHAS = [(1e-4, 1e-4), (1e-2, 1e-2), (0.3, 0.3), (1.0, 1.0), (1.0, 1e-3)]
GRAZING = registry.MICROFACET_GRAZING
WOS = [(0.0, 0.0, 1.0), registry.MICROFACET_SKEW, (float(np.sin(1.4)), 0.0, float(np.cos(1.4))), GRAZING]


# ---------------------------------------------------------------------------------------------
# A float64 quadrature over the unit-roughness slope plane
# ---------------------------------------------------------------------------------------------

def _panels(a, b, n_panels, order=16):
    x, w = np.polynomial.legendre.leggauss(order)
    edges = np.linspace(a, b, n_panels + 1)
    half = 0.5 * np.diff(edges)[:, None]
    return ((edges[:-1, None] + edges[1:, None]) * 0.5 + half * x).ravel(), (half * w).ravel()


def _line(n_panels=24):
    """Nodes and weights for ∫_R g(s) ds with s = tan(πt/2), t in (-1, 1)."""
    t, w = _panels(-1.0, 1.0, 2 * n_panels)
    return np.tan(0.5 * np.pi * t), w * 0.5 * np.pi / np.cos(0.5 * np.pi * t) ** 2


def _half_line(c, n_panels=24):
    """Nodes and weights for ∫_{-∞}^{c} g(a) da, split at 0 (the lobe's peak) when c > 0."""
    t, w = _panels(0.0, 1.0, n_panels)
    nodes, weights = [-np.tan(0.5 * np.pi * t)], [w * 0.5 * np.pi / np.cos(0.5 * np.pi * t) ** 2]
    if c > 0:  # [0, c] by a = tan(t atan c): graded toward 0 for any c
        top = np.arctan(c)
        nodes.append(np.tan(t * top))
        weights.append(w * top / np.cos(t * top) ** 2)
    return np.concatenate(nodes), np.concatenate(weights)


def slope_quadrature(alpha_x, alpha_y, wo=None):
    """(unit normals m, weights) with Σ w g(m) ≈ ∫ g dω_m over the normals visible from wo (all of
    the upper hemisphere for wo = None): coordinates (a, b) of the unit-roughness slopes along and
    across the visible half plane's normal, whose edge a = c is a grid line."""
    e1, c = np.array([1.0, 0.0]), np.inf
    if wo is not None:
        n = np.array([alpha_x * wo[0], alpha_y * wo[1]])
        if np.hypot(*n) > 0:
            e1, c = -n / np.hypot(*n), wo[2] / np.hypot(*n)
    e2 = np.array([-e1[1], e1[0]])
    a, wa = _line() if not np.isfinite(c) else _half_line(c)
    tau, w_tau = _line()
    # b = √(1 + a²) τ: GGX's 1/(1 + a² + b²)² is then (1 + a²)^-2 (1 + τ²)^-2, smooth in (a, τ) up to
    # the corners of the square (on a plain tensor grid it is not, and the error falls only as h²).
    scale = np.sqrt(1.0 + a * a)[:, None]
    b = scale * tau[None, :]
    s = a[:, None, None] * e1 + b[..., None] * e2
    slopes = np.stack([alpha_x * s[..., 0], alpha_y * s[..., 1], np.ones(s.shape[:2])], axis=-1)
    m = slopes / np.linalg.norm(slopes, axis=-1, keepdims=True)
    weights = wa[:, None] * w_tau[None, :] * scale * m[..., 2] ** 3 * alpha_x * alpha_y  # dω = cos³θ α_x α_y ds
    return m.reshape(-1, 3), weights.ravel()


def _float64(name, alpha_x, alpha_y):
    return DISTRIBUTIONS[name](jnp.float64(alpha_x), jnp.float64(alpha_y))


@pytest.mark.parametrize("name", DISTRIBUTIONS)
def test_projected_normal_distribution_integrates_to_one(name):
    with jax.enable_x64(True):
        for alphas in ALPHAS:
            m, w = slope_quadrature(*alphas)
            d = _float64(name, *alphas)
            total = float(np.sum(w * np.asarray(d.D(jnp.asarray(m))) * m[:, 2]))
            assert abs(total - 1.0) < 1e-9, (name, alphas, total)


@pytest.mark.parametrize("name", DISTRIBUTIONS)
def test_weak_white_furnace(name):
    """∫ G1(wo, m) max(0, wo·m) D(m) dm = cos θ_o (Heitz 2014, eq. 38): relative error below 1e-9,
    from normal incidence to cos θ_o = 1e-7, for every hard-case roughness."""
    with jax.enable_x64(True):
        for alphas in ALPHAS:
            d = _float64(name, *alphas)
            for wo in WOS:
                wo = np.asarray(wo) / np.linalg.norm(wo)
                m, w = slope_quadrature(*alphas, wo)
                mj = jnp.asarray(m)
                g1 = np.asarray(d.G1(jnp.asarray(wo), mj))
                total = float(np.sum(w * g1 * np.maximum(m @ wo, 0.0) * np.asarray(d.D(mj))))
                assert abs(total / wo[2] - 1.0) < 1e-9, (name, alphas, wo, total, wo[2])


# ---------------------------------------------------------------------------------------------
# Λ, G1 and G2 against their closed forms
# ---------------------------------------------------------------------------------------------

def _directions(n=400, seed=0):
    rng = np.random.default_rng(seed)
    w = rng.normal(size=(n, 3))
    w[:, 2] = np.abs(w[:, 2]) * 10.0 ** rng.uniform(-7, 0, n)
    return w / np.linalg.norm(w, axis=-1, keepdims=True)


def _textbook_lambda(name, alpha_x, alpha_y, w):
    """Λ as printed (Heitz 2014 eqs. 72 and 80 with α in w's azimuth), in float64."""
    tan2 = (w[:, 0] ** 2 + w[:, 1] ** 2) / w[:, 2] ** 2
    cos2_phi = w[:, 0] ** 2 / (w[:, 0] ** 2 + w[:, 1] ** 2)
    alpha2 = alpha_x ** 2 * cos2_phi + alpha_y ** 2 * (1.0 - cos2_phi)
    if name == "GGX":
        return (np.sqrt(1.0 + alpha2 * tan2) - 1.0) / 2.0
    a = 1.0 / np.sqrt(alpha2 * tan2)
    return (special.erf(a) - 1.0) / 2.0 + np.exp(-a * a) / (2.0 * a * np.sqrt(np.pi))


@pytest.mark.parametrize("name", DISTRIBUTIONS)
def test_lambda_g1_and_g2_match_their_closed_forms(name):
    w, v = _directions(seed=1), _directions(seed=2)
    with jax.enable_x64(True):
        for alphas in ALPHAS:
            d = _float64(name, *alphas)
            lam = np.asarray(d.smith_lambda(jnp.asarray(w)))
            ref = _textbook_lambda(name, *alphas, w)
            # The printed forms cancel where Λ is tiny; compare there in absolute terms.
            assert np.allclose(lam, ref, rtol=1e-9, atol=1e-12), (name, alphas)
            up = jnp.asarray([0.0, 0.0, 1.0])
            g1 = np.asarray(d.G1(jnp.asarray(w), up))
            assert np.allclose(g1, 1.0 / (1.0 + ref), rtol=1e-9, atol=1e-15), (name, alphas)
            g2 = np.asarray(d.G2(jnp.asarray(w), jnp.asarray(v), up))
            lam_v = _textbook_lambda(name, *alphas, v)
            assert np.allclose(g2, 1.0 / (1.0 + ref + lam_v), rtol=1e-9, atol=1e-15), (name, alphas)
            assert np.all(g2 <= np.minimum(g1, np.asarray(d.G1(jnp.asarray(v), up))) + 1e-15)
            # G2 with wi along the normal is G1(wo); both vanish at the horizon and on back faces.
            assert np.allclose(np.asarray(d.G2(jnp.asarray(w), up, up)), g1, rtol=1e-12)
            horizon = jnp.asarray([[1.0, 0.0, 0.0], [0.6, -0.8, 0.0]])
            assert np.all(np.asarray(d.G1(horizon, up)) == 0) and np.all(np.isinf(np.asarray(d.smith_lambda(horizon))))
            back = jnp.asarray([0.8, 0.0, -0.6])  # m facing away from w = (-0.6, 0, 0.8)
            assert float(d.G1(jnp.asarray([-0.6, 0.0, 0.8]), back)) == 0.0


def test_masking_derivatives_are_finite_at_the_horizon_and_right_in_alpha():
    """d/dα of log D, G1 and G2 against central differences (float64), and every derivative finite
    in float32 at cos θ = 1e-7 and at the horizon itself (mitsuba2#32 reported NaN there)."""
    w = jnp.asarray([0.6, 0.0, 0.8])
    v = jnp.asarray([-0.3, 0.5, float(np.sqrt(0.66))])
    m = jnp.asarray([0.1, -0.05, float(np.sqrt(1 - 0.0125))])
    for name, cls in DISTRIBUTIONS.items():
        with jax.enable_x64(True):
            @jax.jit
            def values(alpha):
                d = cls(alpha, 0.7 * alpha)
                return jnp.stack([jnp.log(d.D(m)), d.G1(w, m), d.G2(w, v, m)])

            for alpha in (1e-2, 0.3, 1.0):
                h = 1e-6 * alpha
                exact = np.asarray(jax.jacfwd(values)(jnp.float64(alpha)))
                fd = (np.asarray(values(jnp.float64(alpha + h))) - np.asarray(values(jnp.float64(alpha - h)))) / (2 * h)
                assert np.allclose(exact, fd, rtol=1e-6, atol=1e-8), (name, alpha, exact, fd)

        def everything(alpha, wo):
            d = cls(alpha, alpha)
            up = jnp.asarray([0.0, 0.0, 1.0], jnp.float32)
            return (d.G1(wo, up) + d.G2(wo, wo, up) + d.G2(wo, up, up) + d._g1_over_cos(wo)
                    + js.VisibleNormals(d, wo).pdf(up) + js.MicrofacetReflection(d, wo).pdf(up))

        value_and_grads = jax.jit(jax.value_and_grad(everything, argnums=(0, 1)))
        for wo in ([float(np.sqrt(1 - 1e-14)), 0.0, 1e-7], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]):
            for alpha in (1e-4, 1.0):
                value, grads = value_and_grads(jnp.float32(alpha), jnp.asarray(wo, jnp.float32))
                assert np.isfinite(float(value)), (name, wo, alpha)
                assert all(np.all(np.isfinite(np.asarray(g))) for g in grads), (name, wo, alpha, grads)


# ---------------------------------------------------------------------------------------------
# The roughness derivative of GGX's directional albedo (F = 1)
# ---------------------------------------------------------------------------------------------

def _albedo_make(params):
    """(f, sampler) for js.estimate_grad: f(wi) cos θ_i = D(m) G2(wo, wi, m) / (4 cos θ_o) on wi_z > 0,
    0 below (F = 1), over MicrofacetReflection(GGX(alpha), wo); params = (alpha, wo)."""
    alpha, wo = params
    d = js.GGX(alpha)

    def f(wi):
        half = wo + wi
        m = half / jnp.sqrt(jnp.sum(half * half))
        return jnp.where(wi[2] > 0, d.D(m) * d.G2(wo, wi, m) / (4.0 * wo[2]), 0.0)

    return f, js.MicrofacetReflection(d, wo)


def _albedo_quadrature(alpha, wo):
    """A(α) = ∫_{H²} D G2 / (4 cos θ_o) dω_i in float64: Gauss–Legendre in cos θ_i and φ_i."""
    mu, w_mu = _panels(0.0, 1.0, 12)
    phi, w_phi = _panels(0.0, 2 * np.pi, 16)
    sin = np.sqrt(1.0 - mu ** 2)
    wi = np.stack(np.broadcast_arrays(sin[:, None] * np.cos(phi), sin[:, None] * np.sin(phi), mu[:, None]), -1)
    wi = wi.reshape(-1, 3)
    weights = (w_mu[:, None] * w_phi[None, :]).ravel()
    with jax.enable_x64(True):
        d = js.GGX(jnp.float64(alpha))
        wo_, wi_ = jnp.asarray(wo), jnp.asarray(wi)
        m = (wo_ + wi_) / jnp.linalg.norm(wo_ + wi_, axis=-1, keepdims=True)
        f = np.asarray(d.D(m) * d.G2(wo_, wi_, m)) / (4.0 * wo[2])
    return float(np.sum(weights * f))


@pytest.mark.parametrize("alpha,cos_o", [(0.3, 0.5), (1.0, 0.1)])
def test_pathwise_roughness_derivative_of_the_ggx_albedo(alpha, cos_o):
    """js.estimate_grad (pathwise: attached MicrofacetReflection samples, f/p = G2/G1(wo)) against
    the central difference of the float64 quadrature (h = 1e-4: truncation ~1e-9, below the 3σ of
    ~1e-3). Within 3 standard errors: false-failure rate 0.27 % per case (0.54 % for the two, with the
    stderr from the same 2^16 samples; the keys are fixed, so the outcome is deterministic)."""
    wo = np.array([np.sqrt(1.0 - cos_o ** 2), 0.0, cos_o])
    h = 1e-4
    reference = (_albedo_quadrature(alpha + h, wo) - _albedo_quadrature(alpha - h, wo)) / (2 * h)
    gradient = js.estimate_grad(_albedo_make, (jnp.float32(alpha), jnp.asarray(wo, jnp.float32)),
                                jax.random.key(24), 1 << 16)
    mean, stderr = float(gradient.mean[0]), float(gradient.stderr[0])
    assert abs(mean - reference) < 3.0 * stderr, (mean, stderr, reference)
    assert stderr < 0.05 * abs(reference), (mean, stderr, reference)  # the test has power


# ---------------------------------------------------------------------------------------------
# Wrong samplers the chi-square family rejects (at the contract's settings)
# ---------------------------------------------------------------------------------------------

class _RoughnessOff(js.VisibleNormals):
    """Warps with a roughness 3 % too large while claiming the right density."""

    def warp(self, u):
        d = type(self.distribution)(self.distribution.alpha_x * 1.03, self.distribution.alpha_y * 1.03)
        return js.VisibleNormals(d, self.wo).warp(u)


class _FullD(js.VisibleNormals):
    """Samples D(m) cos θ_m, ignoring visibility, while claiming the visible-normal density."""

    def warp(self, u):
        return self.distribution.warp(u)


@pytest.mark.parametrize("name", DISTRIBUTIONS)
def test_chi_square_rejects_wrong_visible_normals(name):
    d = DISTRIBUTIONS[name](jnp.float32(0.3), jnp.float32(0.3))
    wo = jnp.asarray(registry.MICROFACET_OBLIQUE, jnp.float32)
    settings = registry.chi2_settings(f"VisibleNormals-{name}")
    # (The full-D impostor only for GGX: the Beckmann entry's own warp is the costlier one to compile.)
    # FFR not quantified: p < 1e-12 is asked of each impostor, and its p over other keys is not recorded.
    for wrong in (_RoughnessOff(d, wo),) + ((_FullD(d, wo),) if name == "GGX" else ()):
        result = testing.chi2_test(wrong, jax.random.key(11), **settings)
        assert not result.passed and result.p_value < 1e-12, (type(wrong).__name__, result)


# ---------------------------------------------------------------------------------------------
# Parameters: isotropy, wo's length and side, refusals
# ---------------------------------------------------------------------------------------------

@jax.jit
def _warp_and_pdf(sampler, u):
    x = sampler.warp(u)
    return x, sampler.pdf(x)


def test_alpha_y_none_is_isotropic_and_wo_is_normalised():
    u = jnp.asarray(np.random.default_rng(0).random((64, 2)), jnp.float32)
    wo = jnp.asarray([0.3, -0.4, 0.5], jnp.float32)
    for cls in DISTRIBUTIONS.values():
        iso, same = cls(jnp.float32(0.2)), cls(jnp.float32(0.2), jnp.float32(0.2))
        assert iso.alpha_y is None and iso.batch_shape == ()
        for lobe in (js.VisibleNormals, js.MicrofacetReflection):
            (xa, pa), (xb, pb) = _warp_and_pdf(lobe(iso, wo), u), _warp_and_pdf(lobe(same, 3.0 * wo), u)
            np.testing.assert_allclose(np.asarray(xa), np.asarray(xb), atol=1e-6)
            np.testing.assert_allclose(np.asarray(pa), np.asarray(pb), rtol=1e-5)
        assert np.asarray(cls(jnp.asarray([0.1, 0.5])).sample(jax.random.key(1), (3,))).shape == (3, 2, 3)


def test_wo_below_the_horizon_is_the_surface_seen_from_the_other_side():
    """Visible normals of wo (wo_z < 0) are those of -wo (upper hemisphere); the reflected lobe is the
    point reflection of -wo's, with the same density there."""
    u = jnp.asarray(np.random.default_rng(1).random((256, 2)), jnp.float32)
    below = jnp.asarray(registry.MICROFACET_BELOW, jnp.float32)
    for cls in DISTRIBUTIONS.values():
        d = cls(jnp.float32(0.3), jnp.float32(0.1))
        (m_below, p_below), (m_above, p_above) = (_warp_and_pdf(js.VisibleNormals(d, w), u) for w in (below, -below))
        np.testing.assert_allclose(np.asarray(m_below), np.asarray(m_above), atol=1e-6)
        np.testing.assert_allclose(np.asarray(p_below), np.asarray(p_above), rtol=1e-5)
        assert np.all(np.asarray(m_below)[:, 2] > 0)
        (wi, p_wi), (wi_above, p_wi_above) = (_warp_and_pdf(js.MicrofacetReflection(d, w), u) for w in (below, -below))
        np.testing.assert_allclose(np.asarray(wi), -np.asarray(wi_above), atol=1e-6)
        np.testing.assert_allclose(np.asarray(p_wi), np.asarray(p_wi_above), rtol=1e-5)
        assert np.mean(np.asarray(wi)[:, 2] < 0) > 0.9  # the lobe is below, about the mirror of wo


def test_zero_or_non_finite_wo_is_refused_and_nan_when_traced():
    d = js.GGX(0.3)
    for lobe in (js.VisibleNormals, js.MicrofacetReflection):
        for wo in ([0.0, 0.0, 0.0], [np.nan, 0.0, 1.0]):
            with pytest.raises(ValueError, match="parameter 'wo' must be a finite, non-zero direction"):
                lobe(d, jnp.asarray(wo))
        with pytest.raises(ValueError, match=r"parameter 'wo' must have shape \(\.\.\., 3\)"):
            lobe(d, jnp.ones(2))
        with pytest.raises(TypeError, match="microfacet distribution"):
            lobe(js.PhongLobe(2.0), jnp.asarray([0.0, 0.0, 1.0]))
        x = jax.jit(lambda w: lobe(d, w).warp(jnp.full((2,), 0.5)))(jnp.zeros(3))
        p = jax.jit(lambda a: lobe(js.GGX(a), jnp.asarray([0.0, 0.6, 0.8])).pdf(jnp.asarray([0.0, 0.0, 1.0])))(20.0)
        assert np.all(np.isnan(np.asarray(x))) and np.isnan(float(p))


# ---------------------------------------------------------------------------------------------
# The Beckmann visible-slope inversion
# ---------------------------------------------------------------------------------------------

def test_beckmann_visible_slope_inversion_reaches_its_floor():
    """F(x)/F(a) = u₀ to ~100 ulps (relative below u₀ = 1/2, absolute above), over cuts a from 1e-4
    (and 0, 1e-7: roughness 10 at grazing) to ∞ and u₀ from the clamp to
    1 - 1e-15 (float64) / 1 - 2^-24 (float32), by float64 SciPy."""
    rng = np.random.default_rng(3)
    cuts = np.concatenate([[0.0, 1e-7], np.geomspace(1e-4, 50.0, 40), [np.inf]])
    for dtype, tol in ((np.float64, 2e3), (np.float32, 2e2)):
        eps = float(np.finfo(dtype).eps)
        smallest = microfacet_beckmann._smallest_u(dtype)
        u0 = np.concatenate([rng.random(200), np.geomspace(smallest, 0.1, 30),
                             1.0 - np.geomspace(eps, 0.1, 30)]).astype(dtype)
        a = np.repeat(cuts, len(u0))
        u = np.tile(u0, len(cuts)).astype(np.float64)
        w1 = np.where(np.isinf(a), 1.0, np.sqrt(np.pi) * a / (np.sqrt(np.pi) * np.where(np.isinf(a), 1.0, a) + 1.0))
        w2 = np.where(np.isinf(a), 0.0, 1.0 / (np.sqrt(np.pi) * np.where(np.isinf(a), 1.0, a) + 1.0))
        cut = np.minimum(a, microfacet_beckmann._A_CUT)
        with jax.enable_x64(dtype == np.float64):
            x = np.asarray(jax.jit(microfacet_beckmann._visible_slope)(
                *(jnp.asarray(v, dtype) for v in (w1, w2, cut, u))), np.float64)
        w1, w2, cut, u = (np.asarray(v.astype(dtype), np.float64) for v in (w1, w2, cut, u))
        z = w1 * special.erfc(-cut) + w2 * np.exp(-cut ** 2)
        lower = (w1 * special.erfc(-x) + w2 * np.exp(-x * x)) / z
        upper = ((w1 * special.erfc(x) - w2 * np.exp(-x * x)) - (w1 * special.erfc(cut) - w2 * np.exp(-cut ** 2))) / z
        error = np.where(u <= 0.5, np.abs(lower / u - 1.0), np.abs(upper - (1.0 - u)))
        assert np.all(x <= cut) and np.max(error) < tol * eps, (dtype, np.max(error) / eps)


def test_the_erfcx_of_older_jax_versions_matches_scipy():
    """`scaled_erfc` stands in for jax.scipy.special.erfcx (new in JAX 0.10.1) on older versions:
    e^{x²} erfc(x) to 1e-14 in float64 and 2e-6 in float32 from -3 to 1e6, across its switch at 3,
    with the derivative 2x erfcx(x) - 2/√π."""
    from jaxsample.samplers.microfacet_beckmann import scaled_erfc

    x = np.concatenate([np.linspace(-3.0, 40.0, 801), [2.999999, 3.0, 3.000001, 1e3, 1e6]])
    exact = special.erfcx(x)
    with jax.enable_x64(True):
        value = np.asarray(scaled_erfc(jnp.asarray(x, jnp.float64)))
        slope = np.asarray(jax.vmap(jax.grad(scaled_erfc))(jnp.asarray(x, jnp.float64)))
    assert np.max(np.abs(value / exact - 1.0)) < 1e-14
    expected_slope = 2.0 * x * exact - 2.0 / np.sqrt(np.pi)
    big = np.abs(expected_slope) > 1e-12
    assert np.max(np.abs(slope[big] / expected_slope[big] - 1.0)) < 1e-9
    value32 = np.asarray(scaled_erfc(jnp.asarray(x, jnp.float32)), np.float64)
    assert np.max(np.abs(value32 / exact - 1.0)) < 2e-6
