"""The Beckmann microfacet distribution and its visible normals (`jaxsample.samplers.microfacet`)."""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np
from jax.scipy.special import erf, erfc, ndtr, ndtri

from .microfacet import MicrofacetDistribution, _normalized, _stack
from .._core.numerics import safe_div, safe_sqrt

SQRT_PI = float(np.sqrt(np.pi))


def scaled_erfc(x):
    """erfcx(x) = e^{x²} erfc(x), for JAX versions before 0.10.1 (which added
    `jax.scipy.special.erfcx`). Below x = 3 the product itself (erfc(3) = 2.2e-5 keeps its relative
    precision in float32); from 3 on the continued fraction erfcx(x) = (1/√π) / (x + (1/2)/(x + 1/(x +
    (3/2)/(x + ...)))) (Abramowitz & Stegun 7.1.4), 40 levels deep, which converges there to float64
    rounding. Negative x by erfcx(-x) = 2 e^{x²} - erfcx(x). Each branch sees only its own x (double
    `where`), so no discarded inf reaches a gradient."""
    x = jnp.asarray(x)
    t = jnp.abs(x)
    near = t < 3.0
    t_near = jnp.where(near, t, 0.0)
    t_far = jnp.where(near, 3.0, t)
    fraction = t_far
    for k in range(40, 0, -1):
        fraction = t_far + (0.5 * k) / fraction
    value = jnp.where(near, jnp.exp(t_near * t_near) * erfc(t_near), 1.0 / (SQRT_PI * fraction))
    x_negative = jnp.where(x < 0, x, 0.0)
    return jnp.where(x < 0, 2.0 * jnp.exp(x_negative * x_negative) - value, value)


try:  # JAX >= 0.10.1
    from jax.scipy.special import erfcx
except ImportError:  # older JAX: the continued fraction above
    erfcx = scaled_erfc
# Beyond a = cot θ / alpha = 26, erfc(a) and e^{-a²} are below float64's resolution of 1: the
# masking terms that carry them are dropped there (a is capped, not divided out).
_A_MASKING = 26.0
# The visible slope's cut x <= a: beyond 30 its mass e^{-900} is zero in float64, so the cut is capped
# there (its density (a - x) e^{-x²} keeps the exact a).
_A_CUT = 30.0
# Newton steps of the visible-slope inversion after the start (converged by 5 in float32 and 6 in
# float64 over a ∈ {0} ∪ [1e-4, ∞), u₀ ∈ [2^-53, 1 - 1e-15]: tests/samplers/test_microfacet.py), then
# one more step that carries the derivatives.
_NEWTON_STEPS = 6


def _smallest_u(dtype) -> float:
    """u is clamped above this: u = 0 is the slope -∞. 2^-24 in float32 (the smallest uniform the
    library's sources give, `jaxsample.uniforms`), 2^-53 in float64: the sample there keeps a density
    whose square is a normal number, so f/p and its derivative stay finite (at 1e-30 they did not)."""
    return float(np.finfo(dtype).epsneg)


class Beckmann(MicrofacetDistribution):
    """Beckmann: D(m) = exp(-(m_x²/α_x² + m_y²/α_y²) / m_z²) / (π α_x α_y m_z⁴) for m_z > 0.

    (Beckmann & Spizzichino 1963; Walter et al. 2007, eq. 25, with tan²θ (cos²φ/α_x² + sin²φ/α_y²)
    written from the components of m, as for GGX.) As a sampler: m with density D(m) cos θ_m over
    solid angle; the unit-roughness slopes are Gaussian, slope radius² = -log(1 - u₀) (Walter et al.
    eqs. 28-29), m ∝ (alpha_x r cos 2πu₁, alpha_y r sin 2πu₁, 1).

    Smith: with a = |w_z| / √(α_x² w_x² + α_y² w_y²) (cot θ over the roughness in w's azimuth),
    Λ = (e^{-a²} / (a√π) - erfc(a)) / 2 (Walter et al. eq. 27 before its rational fit; Heitz 2014 eq. 80),
    and G1 = 2a√π / (a√π (1 + erf a) + e^{-a²}),
    G2 = 2√π a_o a_i / (√π a_o a_i (erf a_o + erf a_i) + a_i e^{-a_o²} + a_o e^{-a_i²}):
    sums of positive terms (no 1 + Λ formed), multiplied through by the components so that the
    horizon (a = 0) is finite. Λ itself cancels where it is tiny (a > 4, Λ < 1e-8: relative error
    ~ 2a² ulps there, which G1 and G2 do not inherit).

    Visible normals: the slope-space inversion (see `VisibleNormals` and `_visible_slope`).
    """

    _visible_periodic_dims: ClassVar = ()

    def _log_D(self, m):
        ax, ay = self._alphas()
        mz = m[..., 2]
        upper = mz > 0
        mz_safe = jnp.where(upper, mz, 1.0)
        exponent = ((m[..., 0] / ax) ** 2 + (m[..., 1] / ay) ** 2) / (mz_safe * mz_safe)
        # Beyond e^{-1000} the density is 0 in any precision; treating it as outside keeps the
        # derivative of exp(-x) from meeting the overflowing 1/m_z³ of the exponent's.
        inside = upper & (exponent <= 1e3)
        exponent = jnp.where(inside, exponent, 0.0)
        return jnp.where(inside, -exponent - jnp.log(np.pi * ax * ay) - 4.0 * jnp.log(mz_safe), -jnp.inf)

    def _masking_terms(self, w):
        """(|w_z|, s = √(α_x² w_x² + α_y² w_y²), a = |w_z| / s capped at 26)."""
        ax, ay = self._alphas()
        z = jnp.abs(w[..., 2])
        s = safe_sqrt((ax * w[..., 0]) ** 2 + (ay * w[..., 1]) ** 2)
        # a = z / max(s, z / 26): capped without a division by a vanishing s.
        floor = z / _A_MASKING
        a = safe_div(z, jnp.maximum(s, floor))
        return z, s, a

    def _g1_over_cos(self, w):
        z, s, a = self._masking_terms(w)
        return safe_div(2.0 * SQRT_PI, z * SQRT_PI * (1.0 + erf(a)) + s * jnp.exp(-a * a))

    def _lambda(self, w):
        z, _, a = self._masking_terms(w)
        above = (z > 0) & (a > 0)
        a_safe = jnp.where(above, a, 1.0)
        direct = 0.5 * jnp.exp(-a_safe * a_safe) * (1.0 / (a_safe * SQRT_PI) - erfcx(a_safe))
        return jnp.where(above, jnp.maximum(direct, 0.0), jnp.inf)

    def _g2_unsided(self, wo, wi):
        zo, so, ao = self._masking_terms(wo)
        zi, si, ai = self._masking_terms(wi)
        numerator = 2.0 * SQRT_PI * zo * zi
        denominator = (SQRT_PI * zo * zi * (erf(ao) + erf(ai)) + zi * so * jnp.exp(-ao * ao)
                       + zo * si * jnp.exp(-ai * ai))
        return safe_div(numerator, denominator)

    def _radial(self, u0):
        return safe_sqrt(-jnp.log1p(-u0)), 1.0

    def _u0_from_slope(self, numerator, denominator):
        upper = denominator > 0
        r2 = numerator / jnp.where(upper, denominator, 1.0)
        return jnp.where(upper, -jnp.expm1(-r2), 1.0)

    # ---- visible normals ------------------------------------------------------------------------
    def _standard_frame(self, wh):
        """(cos φ, sin φ) of wh's azimuth and the weights w₁ = √π cos θ / (√π cos θ + sin θ),
        w₂ = sin θ / (√π cos θ + sin θ) of the visible slope's CDF, and its cut a = cot θ (capped)."""
        whz = wh[..., 2]
        sin_theta = safe_sqrt(wh[..., 0] ** 2 + wh[..., 1] ** 2)
        tilted = sin_theta > 0
        sin_safe = jnp.where(tilted, sin_theta, 1.0)
        cos_phi = jnp.where(tilted, wh[..., 0] / sin_safe, 1.0)
        sin_phi = jnp.where(tilted, wh[..., 1] / sin_safe, 0.0)
        total = SQRT_PI * whz + sin_theta
        w1, w2 = SQRT_PI * whz / total, sin_theta / total
        cut = safe_div(whz, jnp.maximum(sin_theta, whz / _A_CUT))
        return cos_phi, sin_phi, w1, w2, cut

    def _visible_warp(self, wh, u):
        ax, ay = self._alphas()
        cos_phi, sin_phi, w1, w2, cut = self._standard_frame(wh)
        dtype = jnp.result_type(u)
        x = _visible_slope(w1, w2, cut, u[..., 0])
        low, high = _smallest_u(dtype), 1.0 - float(np.finfo(dtype).epsneg)
        u1 = u[..., 1]
        # Clamped (u₁ = 0 is the slope -∞) by a double where: 0 times ndtri's large derivative at
        # the clamp would not be 0 in every precision.
        clamped = (u1 < low) | (u1 > high)
        y = jnp.where(clamped, jax.lax.stop_gradient(ndtri(jnp.clip(u1, low, high))),
                      ndtri(jnp.where(clamped, 0.5, u1)))
        y = y / np.sqrt(2.0)  # the slope across wo: N(0, 1/2)
        sx = cos_phi * x - sin_phi * y
        sy = sin_phi * x + cos_phi * y
        return _normalized(_stack(-ax * sx, -ay * sy, jnp.ones_like(sx)))

    def _visible_inverse(self, wh, m):
        ax, ay = self._alphas()
        cos_phi, sin_phi, w1, w2, cut = self._standard_frame(wh)
        mz = m[..., 2]
        upper = mz > 0
        mz_safe = jnp.where(upper, mz, 1.0)
        sx = -m[..., 0] / (ax * mz_safe)
        sy = -m[..., 1] / (ay * mz_safe)
        x = jnp.minimum(cos_phi * sx + sin_phi * sy, cut)
        y = -sin_phi * sx + cos_phi * sy
        u0 = _slope_cdf(w1, w2, x) / _slope_cdf(w1, w2, cut)
        u1 = ndtr(np.sqrt(2.0) * y)
        return jnp.stack([jnp.where(upper, jnp.clip(u0, 0.0, 1.0), 0.0), jnp.where(upper, u1, 0.5)], axis=-1)


def _slope_cdf(w1, w2, x):
    """F(x) = w₁ erfc(-x) + w₂ e^{-x²}, the CDF of the visible slope up to its normaliser F(a):
    ∫_{-∞}^x (a - t) e^{-t²} dt ∝ a (√π/2) erfc(-t) + e^{-t²}/2. Both terms are positive for every x."""
    return w1 * erfc(-x) + w2 * jnp.exp(-x * x)


def _visible_slope(w1, w2, cut, u0):
    """The visible slope x <= a with F(x) = u₀ F(a), density ∝ (a - x) e^{-x²} = (w₁/√π - w₂ x) e^{-x²}/w₂.

    Newton's method, on log F(x) - log(u₀ F(a)) for u₀ <= 1/2 and on log G(x) - log((1 - u₀) F(a))
    above, G = F(a) - F(x) = H(x) - H(a) with H(x) = w₁ erfc(x) - w₂ e^{-x²} (the upper tail from
    erfc(x), not 2 - erfc(-x)). log F and log G are concave (the density is log-concave), so Newton
    from a bound on the correct side does not overshoot; each step is clipped to the bracket. The
    start is the better of two bounds of the root, [lo, hi]:
      lo = max(-√(-log t), a - δ) with t = u₀ F(a): F(x) <= e^{-x²} for x <= 0 (erfc(|x|) <= e^{-x²});
           and near the cut G(a - δ) >= w₂ e^{-a²} δ² (for a - δ >= -a), δ² = (1 - u₀) F(a) e^{a²} / w₂;
      hi = min(a, x_G) with erfc(-x_G) = t / w₁: F >= w₁ erfc(-x), computed from the upper tail
           1 - t/(2w₁) = ((1 - u₀) F(a) + H(a)) / (2 w₁) with H(a) = e^{-a²}(w₁ erfcx(a) - w₂).
    These are exact in the two limits (a = 0: -√(-log u₀); a = ∞: the Gaussian quantile) and
    close between. The iteration runs without derivatives; a last Newton step, whose residual and
    slope carry them, gives the implicit-function derivative dx = -(∂r/∂θ) / (∂r/∂x).
    """
    dtype = jnp.result_type(u0, w1)
    tiny = float(np.finfo(dtype).tiny)
    u = jnp.clip(u0, _smallest_u(dtype), 1.0)
    upper = u > 0.5

    def terms(x, w1, w2, cut, u):
        """(log of F (lower) or G (upper) at x, its derivative in x, log of the target)."""
        z = _slope_cdf(w1, w2, cut)
        h_cut = jnp.exp(-cut * cut) * (w1 * erfcx(cut) - w2)
        sign = jnp.where(upper, 1.0, -1.0)
        e = erfc(sign * x)
        gauss = jnp.exp(-x * x)
        mass = jnp.where(upper, w1 * e - w2 * gauss - h_cut, w1 * e + w2 * gauss)
        mass = jnp.maximum(mass, tiny)
        density = 2.0 * gauss * (w1 / SQRT_PI - w2 * x)
        slope = jnp.where(upper, -density, density) / mass
        target = jnp.where(upper, jnp.log1p(-u) + jnp.log(z), jnp.log(u) + jnp.log(z))
        return jnp.log(mass), slope, target

    w1_c, w2_c, cut_c = (jax.lax.stop_gradient(v) for v in (w1, w2, cut))
    u_c = jax.lax.stop_gradient(u)
    z = _slope_cdf(w1_c, w2_c, cut_c)
    log_t = jnp.log(u_c) + jnp.log(z)
    upper_target = (1.0 - u_c) * z
    lo = -jnp.sqrt(jnp.maximum(-log_t, 0.0))
    delta2 = upper_target * jnp.exp(jnp.minimum(cut_c * cut_c, 80.0)) / jnp.where(w2_c > 0, w2_c, 1.0)
    near_cut = cut_c - jnp.sqrt(delta2)
    lo = jnp.where((w2_c > 0) & (near_cut >= -cut_c), jnp.maximum(lo, near_cut), lo)
    h_cut = jnp.exp(-cut_c * cut_c) * (w1_c * erfcx(cut_c) - w2_c)
    q = (upper_target + h_cut) / jnp.where(w1_c > 0, 2.0 * w1_c, 1.0)
    gaussian = -ndtri(jnp.clip(q, tiny, 0.5)) / np.sqrt(2.0)
    hi = jnp.where((w1_c > 0) & (q > 0) & (q < 1), jnp.minimum(gaussian, cut_c), cut_c)
    lo = jnp.minimum(lo, hi)

    def residual(x):
        log_mass, slope, target = terms(x, w1_c, w2_c, cut_c, u_c)
        return log_mass - target, slope

    r_lo, _ = residual(lo)
    r_hi, _ = residual(hi)
    x = jnp.where(jnp.abs(r_hi) < jnp.abs(r_lo), hi, lo)
    def newton(_, x):
        r, slope = residual(x)
        return jnp.clip(x - safe_div(r, slope), lo, hi)

    x = jax.lax.fori_loop(0, _NEWTON_STEPS, newton, x)
    # The last step with derivatives: x is a constant, the residual carries d/d(w₁, w₂, a, u₀).
    log_mass, slope, target = terms(x, w1, w2, cut, u)
    step = safe_div(log_mass - target, jax.lax.stop_gradient(slope))
    return jnp.minimum(x - step, cut_c)
