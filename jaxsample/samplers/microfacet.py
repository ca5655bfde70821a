"""Microfacet normal distributions (GGX, Beckmann) and the lobes built on them, density over solid angle.

A microfacet distribution is a density D(m) of facet normals m about the macro normal +z, per unit
solid angle of m, normalised so that the projected facet area is one: ∫ D(m) cos θ_m dω_m = 1
(Walter et al. 2007, "Microfacet models for refraction through rough surfaces", eq. 4). Three
samplers come from it, each a warp of [0, 1)² with its density and inverse:

- the distribution itself (`GGX`, `Beckmann`): m with density D(m) cos θ_m ("sampling the full D");
- `VisibleNormals(distribution, wo)`: the normals seen from wo, density
  D_wo(m) = G1(wo, m) max(0, wo·m) D(m) / cos θ_o (Heitz 2014, "Understanding the masking-shadowing
  function in microfacet-based BRDFs", JCGT 3(2), eq. 38; Heitz & d'Eon 2014);
- `MicrofacetReflection(distribution, wo)`: wi = 2 (wo·m) m - wo with m ~ D_wo, density
  D_wo(m) / (4 |wo·m|) at m = normalize(wo + wi) (the reflection Jacobian, Walter et al. eq. 14).

Masking: Smith's Λ of each distribution (`smith_lambda`), G1 = χ⁺ / (1 + Λ) and the height-correlated
G2 = χ⁺ χ⁺ / (1 + Λ(wo) + Λ(wi)) (Heitz 2014, eqs. 43 and 99). Every one of them is computed in a form
with no cancellation and no division by cos θ (the "G1 / cos θ" factor of the visible-normal density
is finite at grazing angles: at cos θ_o = 1e-7, and at 0), so values and derivatives stay finite.

Conventions shared by the three samplers:

- Roughness: `alpha_x`, `alpha_y` in [1e-4, 10] (alpha_y = None: isotropic); the slopes of the
  microsurface are those of the unit-roughness one stretched by (alpha_x, alpha_y).
- wo (rank 1) is normalised here, so any non-zero length works; it is a parameter: derivatives flow
  to it, as to the roughness.
- wo below the horizon (wo_z < 0): the surface is seen from its other side. Visible normals are those
  of -wo (PBRT-v4's flip, `TrowbridgeReitzDistribution::Sample_wm`): m stays in the upper hemisphere,
  D_wo(m) = D_{-wo}(m), and the reflected direction is the point reflection of the one for -wo. At
  wo_z = 0 exactly the upper side is used. A concrete zero or non-finite wo raises `ValueError`; a
  traced one makes every output NaN (the invalid-parameter rule).
- `MicrofacetReflection` is a distribution on the whole sphere: a reflected direction below the
  horizon (a rough lobe, a grazing wo) is a sample like any other, with its density. It is not
  zeroed there: a BRDF is, so f / p = 0 for those samples, and estimates of ∫ f cos θ_i are the
  same as with PBRT's convention of a zero density below the horizon; the density integrates to 1.
"""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from .base import Sampler, point_method, refuse_class
from .domain import Directions
from .._core.params import check_number, concrete_value
from .._core.pytree import parameter
from .._core.numerics import azimuth_fraction, safe_log, sincos_2pi

# The roughness values the declarations are checked at (smooth to rough); the registry adds anisotropy
# of 1e3 (alpha_x = 1, alpha_y = 1e-3). Roughness above 1 is in range (an optimizer may step past it).
ROUGHNESS_HARD_CASES = (1e-4, 1e-2, 0.3, 1.0, 10.0)


def _dot(a, b):
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def _normalized(v):
    """v / |v|, and 0 where |v| = 0 (double where: the derivative of the norm at 0 is not finite)."""
    squared = _dot(v, v)
    nonzero = squared > 0
    inverse = jax.lax.rsqrt(jnp.where(nonzero, squared, 1.0))
    return v * jnp.where(nonzero, inverse, 0.0)[..., None]


def _stack(x, y, z):
    return jnp.stack([x, y, z], axis=-1)


class MicrofacetDistribution(Sampler):
    """Base class of `GGX` and `Beckmann`: a normal distribution D(m) about +z, as a sampler of the
    normals m with density D(m) cos θ_m over solid angle (z > 0), and its Smith masking functions.

    The sampler (polar inversion of the slope distribution, Walter et al. 2007, eqs. 35-36 and 28-29):
    the slope radius of the unit-roughness distribution comes from u₀ (its CDF inverted by the
    subclass), the azimuth of the slope is 2πu₁, and the slope is stretched by (alpha_x, alpha_y), so
    m = normalize(alpha_x r cos φ, alpha_y r sin φ, 1). Each coordinate carries its own scale (no
    1 - cos θ is formed), so float32 holds lobes of alpha = 1e-4, whose cos θ_m rounds to 1.
    """

    alpha_x: jax.Array = parameter(1e-4, 10.0, doc="roughness along x (slope scale)", hard_cases=ROUGHNESS_HARD_CASES)
    alpha_y: jax.Array = parameter(1e-4, 10.0, default=None, doc="roughness along y; None: alpha_x (isotropic)",
                                   hard_cases=ROUGHNESS_HARD_CASES)
    uniform_dims: ClassVar[int] = 2
    event_shape: ClassVar = (3,)
    periodic_dims: ClassVar = (1,)
    measure: ClassVar = "solid angle"

    def _alphas(self):
        ax = jnp.asarray(self.alpha_x)
        return ax, (ax if self.alpha_y is None else jnp.asarray(self.alpha_y))

    # ---- what a subclass defines (for one distribution, points (..., 3)) -----------------------
    def _log_D(self, m):  # log D(m) for unit m, -inf for m_z <= 0
        raise NotImplementedError

    def _g1_over_cos(self, w):  # 1 / ((1 + Λ(w)) |w_z|), finite for every w != 0
        raise NotImplementedError

    def _lambda(self, w):
        raise NotImplementedError

    def _g2_unsided(self, wo, wi):  # 1 / (1 + Λ(wo) + Λ(wi)), no χ⁺ factors
        raise NotImplementedError

    def _radial(self, u0):  # (ρ, ζ): the unit-roughness slope radius is ρ / ζ
        raise NotImplementedError

    def _u0_from_slope(self, r2_numerator, r2_denominator):  # the CDF of the slope radius² = num / den
        raise NotImplementedError

    def _visible_warp(self, wh, u):  # m from u for the stretched upper direction wh
        raise NotImplementedError

    def _visible_inverse(self, wh, m):
        raise NotImplementedError

    _visible_periodic_dims: ClassVar = ()

    # ---- the distribution's functions (broadcast over leading axes) ----------------------------
    @point_method(batched=False)
    def D(self, m):
        """D(m), per unit solid angle of the unit vector m (not multiplied by cos θ_m); 0 for m_z <= 0."""
        return jnp.exp(self._log_D(m))

    @point_method(batched=False)
    def smith_lambda(self, w):
        """Smith's Λ(w) (Heitz 2014, section 5); a function of |w_z| (the same for w and its mirror
        image below the surface); +inf at the horizon. w need not be unit."""
        return self._lambda(w)

    @point_method(batched=False)
    def G1(self, w, m):
        """Smith masking G1(w, m) = χ⁺((w·m) w_z) / (1 + Λ(w)) (Heitz 2014, eq. 43): the fraction of
        the facets of normal m visible from w. Finite for every w (0 at the horizon)."""
        sided = _dot(w, m) * w[..., 2] > 0
        return jnp.where(sided, self._g1_over_cos(w) * jnp.abs(w[..., 2]), 0.0)

    @point_method(batched=False)
    def G2(self, wo, wi, m):
        """Height-correlated Smith masking-shadowing G2(wo, wi, m) = χ⁺((wo·m) wo_z) χ⁺((wi·m) wi_z) /
        (1 + Λ(wo) + Λ(wi)) (Heitz 2014, eq. 99), in a form that is finite at the horizon."""
        sided = (_dot(wo, m) * wo[..., 2] > 0) & (_dot(wi, m) * wi[..., 2] > 0)
        return jnp.where(sided, self._g2_unsided(wo, wi), 0.0)

    def visible(self, wo) -> "VisibleNormals":
        """The distribution of normals visible from wo: `VisibleNormals(self, wo)`."""
        return VisibleNormals(self, wo)

    def reflection(self, wo) -> "MicrofacetReflection":
        """Directions reflected about visible normals: `MicrofacetReflection(self, wo)`."""
        return MicrofacetReflection(self, wo)

    # ---- the sampler of D(m) cos θ_m -----------------------------------------------------------
    def _stretched(self, w):
        """normalize(alpha_x w_x, alpha_y w_y, w_z): w in the unit-roughness configuration."""
        ax, ay = self._alphas()
        return _normalized(_stack(ax * w[..., 0], ay * w[..., 1], w[..., 2]))

    def _slope_coordinates(self, m):
        """(s_x, s_y) = unit-roughness slopes (numerators over m_z): (m_x / alpha_x, m_y / alpha_y)."""
        ax, ay = self._alphas()
        return m[..., 0] / ax, m[..., 1] / ay

    @point_method
    def warp(self, u):
        ax, ay = self._alphas()
        rho, zeta = self._radial(u[..., 0])
        sin_phi, cos_phi = sincos_2pi(u[..., 1])
        return _normalized(_stack(ax * rho * cos_phi, ay * rho * sin_phi, zeta * jnp.ones_like(rho)))

    @point_method
    def log_pdf(self, x):
        return self._log_D(x) + safe_log(x[..., 2])

    @point_method
    def pdf(self, x):
        return jnp.exp(self.log_pdf(x))

    @point_method
    def inverse(self, x):
        sx, sy = self._slope_coordinates(x)
        u0 = self._u0_from_slope(sx * sx + sy * sy, x[..., 2] * x[..., 2])
        return jnp.stack([jnp.clip(u0, 0.0, 1.0), azimuth_fraction(sy, sx)], axis=-1)

    def _concrete_alphas(self):
        ax = concrete_value(self.alpha_x)
        ay = ax if self.alpha_y is None else concrete_value(self.alpha_y)
        if ax is None or ay is None or ax.shape != () or ay.shape != ():
            return None
        return float(ax), float(ay)

    def domain(self):
        alphas = self._concrete_alphas()
        if alphas is None:
            return Directions(breaks=(1.0,))
        from .microfacet_domain import MicrofacetDirections
        return MicrofacetDirections(*alphas)


class _MicrofacetLobe(Sampler):
    """Shared fields and checks of `VisibleNormals` and `MicrofacetReflection`."""

    distribution: MicrofacetDistribution
    wo: jax.Array = parameter(rank=1, doc="the direction seen from (normalised here; below the horizon: "
                                          "the surface seen from its other side)")
    uniform_dims: ClassVar[int] = 2
    event_shape: ClassVar = (3,)
    measure: ClassVar = "solid angle"

    def __post_init__(self):
        name = type(self).__name__
        refuse_class(name, "distribution", self.distribution)
        if isinstance(self.distribution, Sampler) and not isinstance(self.distribution, MicrofacetDistribution):
            raise TypeError(f"{name}: parameter 'distribution' must be a microfacet distribution (GGX or "
                            f"Beckmann); got {type(self.distribution).__name__}")
        check_number(name, "wo", self.wo)
        value = concrete_value(self.wo)
        if value is not None:
            if value.shape[-1:] != (3,):
                raise ValueError(f"{name}: parameter 'wo' must have shape (..., 3); got {value.shape}")
            norms = np.linalg.norm(value, axis=-1)
            if not np.all(np.isfinite(norms)) or np.any(norms == 0):
                raise ValueError(f"{name}: parameter 'wo' must be a finite, non-zero direction; got {value}")

    def _parameters_valid(self):
        wo = jnp.asarray(self.wo)
        squared = _dot(wo, wo)
        valid = jnp.all(jnp.isfinite(wo)) & jnp.all(squared > 0)
        declared = super()._parameters_valid()
        return valid if declared is None else valid & declared

    @property
    def periodic_dims(self):
        return self.distribution._visible_periodic_dims

    def _upper(self):
        """(wo normalised and turned to the upper side, the side's sign σ = ±1)."""
        wo = _normalized(jnp.asarray(self.wo))
        sign = jnp.where(wo[..., 2] < 0, -1.0, 1.0).astype(wo.dtype)
        return wo * sign[..., None], sign

    def _visible_log_pdf(self, wo_up, m):
        """log D_wo(m) = log(G1(wo)/cos θ_o) + log(wo·m) + log D(m), -inf off the visible normals."""
        d = self.distribution
        cosine = _dot(wo_up, m)
        visible = (cosine > 0) & (m[..., 2] > 0)
        return jnp.where(visible, jnp.log(d._g1_over_cos(wo_up)) + safe_log(cosine) + d._log_D(m), -jnp.inf)

    def _domain(self, reflect: bool):
        alphas = self.distribution._concrete_alphas()
        wo = concrete_value(self.wo)
        if alphas is None or wo is None or wo.shape != (3,):
            return Directions()
        from .microfacet_domain import MicrofacetDirections
        wo = wo / np.linalg.norm(wo)
        sign = -1.0 if wo[2] < 0 else 1.0
        return MicrofacetDirections(*alphas, wo=tuple(float(c) for c in sign * wo), reflect=reflect,
                                    sign=sign if reflect else 1.0)


class VisibleNormals(_MicrofacetLobe):
    """Normals m visible from wo: D_wo(m) = G1(wo, m) max(0, wo·m) D(m) / cos θ_o over solid angle.

    (Heitz 2014, eq. 38; it integrates to 1 by the weak white furnace identity
    ∫ G1(wo, m) max(0, wo·m) D(m) dm = cos θ_o.) Both warps are exact and invertible, with the
    distribution's stretch: wo is taken to the unit-roughness configuration
    wh = normalize(alpha_x wo_x, alpha_y wo_y, wo_z), sampled there, and the normal stretched back.

    - GGX: the spherical-cap form of Dupuy & Benyoub 2023 ("Sound and robust sampling of the GGX
      distribution of visible normals", HPG; equivalent to Heitz 2018's disk, JCGT 7(4)): a point c
      uniform on the cap {c_z >= -wh_z} of the unit sphere, m ∝ stretch(c + wh). Written for float32:
      with k = 1 + wh_z, c_z = 1 - k u₀, sin²θ_c = k u₀ ((1 - wh_z) + k (1 - u₀)) and
      (c + wh)_z = k (1 - u₀), so neither sin θ_c nor the normal's height is a difference of nearly
      equal numbers (1 - c² and c_z + wh_z cancel near the cap's rim and its pole), and
      1 - wh_z = |wh_xy|² / (1 + wh_z). The rim, where the normals turn perpendicular to wo, stays
      in the support: (c + wh)_z > 0 for every u₀ < 1, where Heitz 2018 as printed clamps its
      lifted height at 0 (PBRT-v4: 1e-6). Inverse: c is the reflection of wh about the unstretched
      normal, c = 2 (n·wh) n - wh. The map is singular at one point, u = (1, (φ_wh + π)/2π) (c = -wh,
      where the normals perpendicular to wo meet): there float32 cannot place m (condition number
      1/(1 - u₀)), which costs nothing in probability but can break a round trip through `inverse`.
      The densities are D_wo(m) from m's components (no tan θ): in float32 the textbook density, through
      tan²θ = sin²θ / cos²θ with cos²θ rounded to 1, is off by more than 1e-3 for 86 % of the samples at
      alpha = 1e-4 and 0.4 % at 1e-2 (benchmarks/float32_microfacet.py; here: none).
    - Beckmann: the slope-space inversion of Heitz & d'Eon 2014 ("Importance sampling
      microfacet-based BSDFs using the distribution of visible normals", EGSR) in the form of
      Jakob 2014 ("An improved visible normal sampling routine for the Beckmann distribution"): the
      slope across wo is independent N(0, 1/2); the slope along it has density ∝ (a - x)⁺ e^{-x²},
      a = cot θ of wh. Its CDF is inverted by Newton's method on log F (lower half) or log(1 - F)
      (upper half) in x itself, with F = w₁ erfc(-x) + w₂ e^{-x²} a sum of positive terms at every x
      (erfc, not 1 + erf), started at proven bounds of the root; see `microfacet_beckmann`. Jakob's
      form works in b = erf(x), which rounds to -1 below x ≈ -3.9 in float32, so its left tail is
      lost (Mitsuba and PBRT-v3 clamp u ≥ 1e-6 for it); this one keeps relative accuracy in the
      tails down to u = 2^-24 (float32; 2^-53 in float64), below which u is clamped.

    wo: see the module docstring (normalised; below the horizon the visible normals are those of
    -wo). The density is 0 off the visible normals (wo·m <= 0) and below the horizon (m_z <= 0).
    """

    @point_method
    def warp(self, u):
        wo_up, _ = self._upper()
        return self.distribution._visible_warp(self.distribution._stretched(wo_up), u)

    @point_method
    def log_pdf(self, x):
        wo_up, _ = self._upper()
        return self._visible_log_pdf(wo_up, x)

    @point_method
    def pdf(self, x):
        return jnp.exp(self.log_pdf(x))

    @point_method
    def inverse(self, x):
        wo_up, _ = self._upper()
        return self.distribution._visible_inverse(self.distribution._stretched(wo_up), x)

    def domain(self):
        return self._domain(reflect=False)


class MicrofacetReflection(_MicrofacetLobe):
    """Directions wi = 2 (wo·m) m - wo reflected about visible normals m ~ `VisibleNormals(distribution, wo)`.

    Density over solid angle of wi: D_wo(m) / (4 |wo·m|) with m = normalize(wo + wi) (Walter et al.
    2007, eq. 14), which simplifies to G1(wo) D(m) / (4 |cos θ_o|): no division by wo·m, finite at
    grazing wo. It is 0 where that m is below the horizon (D(m) = 0), and at wi = -wo.

    Below the horizon of wi the density is NOT zero: the sampler is a distribution on the whole sphere
    (normalised to 1) and a reflected direction below the horizon is one of its samples. For a BRDF
    the integrand is 0 there, so f / p = 0 for those samples, exactly as PBRT's convention (a zero
    density below the horizon, the sample discarded) gives. For wo below the horizon the lobe is the
    point reflection of the one for -wo (module docstring). Inverse: m = normalize(wo + wi), then
    the visible-normal inverse.
    """

    @point_method
    def warp(self, u):
        wo_up, sign = self._upper()
        m = self.distribution._visible_warp(self.distribution._stretched(wo_up), u)
        reflected = 2.0 * _dot(wo_up, m)[..., None] * m - wo_up
        return sign[..., None] * reflected

    def _normal(self, wi):
        wo_up, sign = self._upper()
        return wo_up, _normalized(wo_up + sign[..., None] * wi)

    @point_method
    def log_pdf(self, x):
        wo_up, m = self._normal(x)
        d = self.distribution
        inside = m[..., 2] > 0
        return jnp.where(inside, jnp.log(0.25 * d._g1_over_cos(wo_up)) + d._log_D(m), -jnp.inf)

    @point_method
    def pdf(self, x):
        return jnp.exp(self.log_pdf(x))

    @point_method
    def inverse(self, x):
        wo_up, m = self._normal(x)
        return self.distribution._visible_inverse(self.distribution._stretched(wo_up), m)

    def domain(self):
        return self._domain(reflect=True)
