"""The GGX (Trowbridge-Reitz) microfacet distribution and its visible normals (`jaxsample.samplers.microfacet`)."""

from __future__ import annotations

from typing import ClassVar

import jax.numpy as jnp
import numpy as np

from .microfacet import MicrofacetDistribution, _dot, _normalized, _stack
from .._core.numerics import azimuth_fraction, safe_div, safe_sqrt, sincos_2pi


class GGX(MicrofacetDistribution):
    """GGX / Trowbridge-Reitz: D(m) = 1 / (π α_x α_y (m_x²/α_x² + m_y²/α_y² + m_z²)²) for m_z > 0.

    (Trowbridge & Reitz 1975; Walter et al. 2007, eq. 33, written without tan θ: for unit m the
    denominator is cos⁴θ (1 + tan²θ (cos²φ/α_x² + sin²φ/α_y²))², and in this form no cos θ_m is
    rounded to 1 or divided by, which keeps D right in float32 at alpha = 1e-4.) As a sampler: m with
    density D(m) cos θ_m over solid angle; the unit-roughness slope radius² is u₀ / (1 - u₀), so
    m ∝ (alpha_x √u₀ cos 2πu₁, alpha_y √u₀ sin 2πu₁, √(1 - u₀)) (Walter et al. eqs. 35-36, scaled by
    √(1 - u₀) so that nothing overflows as u₀ -> 1).

    Smith's Λ(w) = (√(1 + a⁻²) - 1) / 2 with a⁻² = (α_x² w_x² + α_y² w_y²) / w_z² (Heitz 2014, eq. 72).
    Written with h = √(w_z² + α_x² w_x² + α_y² w_y²): Λ = s² / (2|w_z|(|w_z| + h)), G1 = 2|w_z| / (|w_z| + h)
    and G2 = 2 |w_z,o| |w_z,i| / (|w_z,i| h_o + |w_z,o| h_i), all free of the cancellation
    √(1 + a⁻²) - 1 at small roughness and finite at the horizon.

    Visible normals: the spherical-cap form (see `VisibleNormals`).
    """

    _visible_periodic_dims: ClassVar = (1,)

    def _log_D(self, m):
        ax, ay = self._alphas()
        mz = m[..., 2]
        upper = mz > 0
        q = (m[..., 0] / ax) ** 2 + (m[..., 1] / ay) ** 2 + mz * mz
        # q >= min(1, 1/alpha²) > 0 for unit m; the guard only keeps log finite off the support.
        q = jnp.where(upper & (q > 0), q, 1.0)
        return jnp.where(upper, -jnp.log(np.pi * ax * ay) - 2.0 * jnp.log(q), -jnp.inf)

    def _heights(self, w):
        """(|w_z|, h = √(w_z² + α_x² w_x² + α_y² w_y²), the squared slope part s²)."""
        ax, ay = self._alphas()
        z = jnp.abs(w[..., 2])
        s2 = (ax * w[..., 0]) ** 2 + (ay * w[..., 1]) ** 2
        return z, safe_sqrt(z * z + s2), s2

    def _g1_over_cos(self, w):
        z, h, _ = self._heights(w)
        return safe_div(2.0, z + h)

    def _lambda(self, w):
        z, h, s2 = self._heights(w)
        above = z > 0
        z_safe = jnp.where(above, z, 1.0)
        return jnp.where(above, s2 / (2.0 * z_safe * (z_safe + h)), jnp.inf)

    def _g2_unsided(self, wo, wi):
        zo, ho, _ = self._heights(wo)
        zi, hi, _ = self._heights(wi)
        return safe_div(2.0 * zo * zi, zi * ho + zo * hi)

    def _radial(self, u0):
        return safe_sqrt(u0), safe_sqrt(1.0 - u0)

    def _u0_from_slope(self, numerator, denominator):
        return safe_div(numerator, numerator + denominator)

    def _visible_warp(self, wh, u):
        ax, ay = self._alphas()
        u0 = u[..., 0]
        whx, why, whz = wh[..., 0], wh[..., 1], wh[..., 2]
        k = 1.0 + whz  # in [1, 2]: wh is in the upper hemisphere
        one_minus_whz = (whx * whx + why * why) / k
        # The cap point c: 1 - c_z = k u₀ and 1 + c_z = (1 - wh_z) + k (1 - u₀), each without cancellation.
        sin_c = safe_sqrt(k * u0 * (one_minus_whz + k * (1.0 - u0)))
        sin_phi, cos_phi = sincos_2pi(u[..., 1])
        hx = sin_c * cos_phi + whx
        hy = sin_c * sin_phi + why
        hz = k * (1.0 - u0)  # (c + wh)_z > 0 for u₀ < 1
        return _normalized(_stack(ax * hx, ay * hy, hz))

    def _visible_inverse(self, wh, m):
        ax, ay = self._alphas()
        n = _normalized(_stack(m[..., 0] / ax, m[..., 1] / ay, m[..., 2]))
        t = 2.0 * _dot(n, wh)  # c + wh = t n, |c| = 1
        k = 1.0 + wh[..., 2]
        u0 = jnp.clip(1.0 - t * n[..., 2] / k, 0.0, 1.0)
        u1 = azimuth_fraction(t * n[..., 1] - wh[..., 1], t * n[..., 0] - wh[..., 0])
        return jnp.stack([u0, u1], axis=-1)
