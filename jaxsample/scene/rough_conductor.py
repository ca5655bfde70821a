"""A rough conductor: the GGX microfacet BRDF with the exact conductor Fresnel term, or Schlick's.

f_r(ω_o, ω_i) = D(h) G2(ω_o, ω_i, h) F(ω_o·h) / (4 cos θ_o cos θ_i),   h = (ω_o + ω_i)/|ω_o + ω_i|

(Cook & Torrance 1982; Walter et al. 2007, "Microfacet models for refraction through rough
surfaces", eq. 20), with the GGX distribution D and the height-correlated Smith masking-shadowing G2
of `jaxsample.samplers.microfacet` (Heitz 2014, "Understanding the masking-shadowing function in
microfacet-based BRDFs", eq. 99). Local shading frame, normal +z; 0 unless both directions are
above the surface.
"""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from .._core.params import check_choice, check_parameter, concrete_value
from .._core.pytree import Pytree, parameter, static_field
from .._core.numerics import safe_div, safe_log, safe_sqrt
from ..samplers.base import Sampler, point_method, refuse_class
from ..samplers.domain import Directions
from ..samplers.microfacet import MicrofacetDistribution, MicrofacetReflection
from ..samplers.microfacet_ggx import GGX
from .colour import lift

__all__ = ["RoughConductor", "FullNormalsReflection", "fresnel_conductor", "fresnel_schlick",
           "normal_incidence_reflectance", "FRESNEL_FORMS", "BRDF_SAMPLING", "CONDUCTOR_RGB"]

FRESNEL_FORMS = ("conductor", "schlick")
BRDF_SAMPLING = ("visible", "full")

# The complex index η + i k of four metals in linear sRGB, (η_RGB, k_RGB): measured spectra integrated
# against the sRGB primaries, as tabulated by the Tungsten renderer (`ComplexIorData`) and reused by
# several renderers since; a three-channel stand-in for a spectral conductor.
CONDUCTOR_RGB = {
    "gold": ((0.1431189557, 0.3749570432, 1.4424785571), (3.9831604247, 2.3857207478, 1.6032152899)),
    "copper": ((0.2004376970, 0.9240334304, 1.1022119527), (3.9129485033, 2.4528477015, 2.1421879552)),
    "silver": ((0.1552646489, 0.1167232965, 0.1383806959), (4.8283433224, 3.1222459278, 2.1469504455)),
    "aluminium": ((1.6574599595, 0.8803689579, 0.5212287346), (9.2238691996, 6.2695232477, 4.8370012281)),
}


def _dot(a, b):
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def _normalized(v):
    """v / |v|, and 0 where |v| = 0 (double where: the norm's derivative at 0 is not finite)."""
    squared = _dot(v, v)
    nonzero = squared > 0
    return v * jnp.where(nonzero, jax.lax.rsqrt(jnp.where(nonzero, squared, 1.0)), 0.0)[..., None]


def normal_incidence_reflectance(eta, k):
    """F(0) = ((n − 1)² + k²) / ((n + 1)² + k²) for the complex index η = n + i k (Born & Wolf,
    *Principles of Optics*, §14.2): the reflectance at normal incidence, Schlick's F0."""
    eta, k = jnp.asarray(eta), jnp.asarray(k)
    return ((eta - 1.0) ** 2 + k * k) / ((eta + 1.0) ** 2 + k * k)


def fresnel_conductor(cos_theta, eta, k):
    """Unpolarized Fresnel reflectance F = (R_s + R_p)/2 of a conductor of complex relative index
    η = n + i k, light arriving at cos θ = `cos_theta` (clamped to [0, 1]) from a medium of index 1.

    The amplitude coefficients (Born & Wolf, *Principles of Optics*, §1.5.2 and §14.2, the
    complex index in Snell's law) are r_s = (c − z)/(c + z) and r_p = (η² c − z)/(η² c + z) with
    c = cos θ and z = η cos θ_t = √(η² − sin²θ), the root with Re z >= 0. With η² = e_r + i e_i
    (e_r = n² − k², e_i = 2nk) and z = a + i b everything is real arithmetic:

        R_s = ((c − a)² + b²) / ((c + a)² + b²),
        R_p = ((e_r c − a)² + (e_i c − b)²) / ((e_r c + a)² + (e_i c + b)²).

    Written so: no tan θ (the textbook "a, b" form of R_p divides by cos θ, 0/0 at grazing
    incidence, where here F = 1 exactly), and the complex root taken without cancellation: of
    a² = (|w| + Re w)/2 and b² = (|w| − Re w)/2 (w = η² − sin²θ) only the one that adds is formed
    and the other is e_i / (2·root) (for a metal, n < k, Re w < 0 and |w| + Re w would lose every
    digit of a). At normal incidence F = ((n − 1)² + k²)/((n + 1)² + k²); k = 0 is the dielectric
    Fresnel term, total internal reflection (F = 1) included for n < 1.
    """
    c = jnp.clip(jnp.asarray(cos_theta), 0.0, 1.0)
    eta, k = jnp.asarray(eta), jnp.asarray(k)
    sin2 = (1.0 - c) * (1.0 + c)
    e_r = (eta - k) * (eta + k)
    e_i = 2.0 * eta * k
    w_r = e_r - sin2
    modulus = safe_sqrt(w_r * w_r + e_i * e_i)
    big = safe_sqrt(0.5 * (modulus + jnp.abs(w_r)))   # the root whose square has no cancellation
    small = safe_div(e_i, 2.0 * big)
    a = jnp.where(w_r >= 0, big, small)
    b = jnp.where(w_r >= 0, small, big)
    r_s = safe_div((c - a) ** 2 + b * b, (c + a) ** 2 + b * b)
    r_p = safe_div((e_r * c - a) ** 2 + (e_i * c - b) ** 2, (e_r * c + a) ** 2 + (e_i * c + b) ** 2)
    # c = 0 and z = 0 together (k = 0, n = 0) is outside the range; elsewhere a denominator is > 0.
    return 0.5 * (r_s + r_p)


def fresnel_schlick(cos_theta, f0):
    """Schlick's approximation F = F0 + (1 − F0)(1 − cos θ)^5 (Schlick 1994, "An inexpensive BRDF
    model for physically-based rendering", eq. 15): F0 at normal incidence, 1 at grazing."""
    c = jnp.clip(jnp.asarray(cos_theta), 0.0, 1.0)
    one_minus = 1.0 - c
    squared = one_minus * one_minus
    return f0 + (1.0 - f0) * squared * squared * one_minus


class FullNormalsReflection(Sampler):
    """Directions ω_i = 2 (ω_o·m) m − ω_o reflected about normals m drawn from the whole
    distribution, density D(m) cos θ_m (`GGX`, `Beckmann` as samplers): "sampling the full D"
    (Walter et al. 2007, §5.3), the strategy visible normals replaced.

    Density over solid angle of ω_i, by the reflection Jacobian dω_h/dω_i = 1/(4 |ω_o·h|)
    (Walter et al. 2007, eq. 14): p(ω_i) = D(m) cos θ_m / (4 |ω_o·m|), with m the upper of ±h,
    h = normalize(ω_o + ω_i). The normals facing away from ω_o (ω_o·m < 0) are drawn too; their
    reflections have h = −m, a half vector below the surface, where a BRDF is 0: those samples are
    wasted (the reason visible-normal sampling exists). m ↦ ω_i is one to one on the upper
    hemisphere (h = ±m fixes m), so the warp is a bijection with `inverse` u = D.inverse(m).
    The density is unbounded toward ω_i = −ω_o (ω_o·m -> 0), an integrable singularity.

    wo (local frame, normalised here; a parameter: derivatives flow to it) and `distribution` are
    as in `MicrofacetReflection`; wo below the horizon is not special-cased (its lobe is the
    reflection about the same normals, mostly below the surface).
    """

    distribution: MicrofacetDistribution
    wo: jax.Array = parameter(rank=1, doc="the direction seen from (normalised here)")
    uniform_dims: ClassVar[int] = 2
    event_shape: ClassVar = (3,)
    measure: ClassVar = "solid angle"

    def __post_init__(self):
        refuse_class("FullNormalsReflection", "distribution", self.distribution)
        value = concrete_value(self.wo)
        if value is not None and (value.shape[-1:] != (3,) or not np.all(np.isfinite(value))
                                  or np.any(np.linalg.norm(value, axis=-1) == 0)):
            raise ValueError(f"FullNormalsReflection: parameter 'wo' must be a finite, non-zero direction of "
                             f"shape (..., 3); got {value}")

    def _wo(self):
        return _normalized(jnp.asarray(self.wo))

    def _reflect(self, m):
        wo = self._wo()
        cosine = _dot(wo, m)
        return 2.0 * cosine[..., None] * m - wo, cosine

    def _log_jacobian(self, cosine):
        # log 1/(4 |ω_o·m|). Where ω_o·m = 0 (ω_i = −ω_o, a single direction) the density would be
        # infinite; it is reported as 0 there, a measure-zero choice that keeps every value finite.
        return jnp.where(cosine != 0, -safe_log(4.0 * jnp.abs(cosine)), -jnp.inf)

    @point_method
    def warp(self, u):
        return self._reflect(self.distribution.warp(u))[0]

    @point_method
    def warp_with_pdf(self, u):
        m, pdf_m = self.distribution.warp_with_pdf(u)
        wi, cosine = self._reflect(m)
        return wi, safe_div(pdf_m, 4.0 * jnp.abs(cosine))

    def _normal(self, x):
        h = _normalized(self._wo() + x)
        return h * jnp.where(h[..., 2] < 0, -1.0, 1.0).astype(h.dtype)[..., None]

    @point_method
    def log_pdf(self, x):
        m = self._normal(x)
        cosine = _dot(self._wo(), m)
        inside = (m[..., 2] > 0) & (cosine != 0)
        return jnp.where(inside, self.distribution.log_pdf(m) + self._log_jacobian(cosine), -jnp.inf)

    @point_method
    def pdf(self, x):
        return jnp.exp(self.log_pdf(x))

    @point_method
    def inverse(self, x):
        return self.distribution.inverse(self._normal(x))

    def domain(self):
        return Directions()


class RoughConductor(Pytree):
    """The GGX rough-conductor BRDF f_r = D(h) G2(ω_o, ω_i, h) F(ω_o·h) / (4 cos θ_o cos θ_i).

    D: GGX (Trowbridge–Reitz) of roughness `alpha`, isotropic (Walter et al. 2007, eq. 33). G2: the
    height-correlated Smith term (Heitz 2014, eq. 99); for reflection ω_o·h > 0 and ω_i·h > 0
    always, and with GGX's Λ (Heitz 2014, eq. 72) the quotient is written without dividing by a
    cosine: G2 / (4 cos θ_o cos θ_i) = 1 / (2 (cos θ_i H_o + cos θ_o H_i)), H = √(cos²θ + α² sin²θ),
    finite and nonzero down to grazing directions. F: `fresnel="conductor"` (default), the exact
    unpolarized reflectance of the complex index η + i k (`fresnel_conductor`); `"schlick"`,
    Schlick's approximation with F0 the same conductor's normal-incidence reflectance
    (`normal_incidence_reflectance`); `RoughConductor.schlick(alpha, f0)` builds one from F0 itself.
    Reciprocal (h, F and the symmetric G2 do not change when the directions swap). A single
    scattering model: energy lost to multiple bounces is not returned (white furnace < 1 at large α).

    Sampling (`sampling`): "visible" (default), the reflection of visible normals
    (`MicrofacetReflection`: density D_ωo(m) / (4 ω_o·m), Heitz 2014/2018), for which f cos θ_i / p =
    F G2 / G1(ω_o) <= 1; "full", the reflection of normals from the whole D (`FullNormalsReflection`),
    the textbook strategy the report compares it with. Either's density is nonzero below the surface,
    where f_r = 0, so those samples contribute 0 (`MicrofacetReflection`'s docstring).

    Colour: η and k may be one per channel, shape (C,) (`jaxsample.scene.colour`; `from_table` gives
    the RGB index of gold, copper, silver or aluminium), and `eval` then returns (..., C). α, which
    shapes the sampled lobe, is one for every channel.

    Gradients: every parameter (α above all: roughness is what inverse rendering fits) is a leaf;
    attached samples move with α and ω_o through the sampler's warp, and `shade` accounts for them
    crossing a light's silhouette through the sampler's `inverse`. The lobe itself has no edge, so it
    adds no boundary term of its own.
    """

    alpha: jax.Array = parameter(1e-4, 1.0, doc="GGX roughness (slope scale)")
    eta: jax.Array = parameter(0.0, low_open=True, doc="real part n of the complex index of refraction")
    k: jax.Array = parameter(0.0, doc="extinction coefficient (imaginary part of the index)")
    fresnel: str = static_field(default="conductor")
    sampling: str = static_field(default="visible")

    def __post_init__(self):
        check_choice("RoughConductor", "fresnel", self.fresnel, FRESNEL_FORMS)
        check_choice("RoughConductor", "sampling", self.sampling, BRDF_SAMPLING)

    @classmethod
    def from_table(cls, metal: str, alpha, fresnel: str = "conductor", sampling: str = "visible") -> "RoughConductor":
        """A rough conductor with the RGB complex index of a metal in `CONDUCTOR_RGB` ("gold", "copper",
        "silver", "aluminium")."""
        check_choice("RoughConductor.from_table", "metal", metal, tuple(CONDUCTOR_RGB))
        eta, k = CONDUCTOR_RGB[metal]
        return cls(alpha, jnp.asarray(eta, jnp.float32), jnp.asarray(k, jnp.float32), fresnel=fresnel,
                   sampling=sampling)

    @classmethod
    def schlick(cls, alpha, f0, sampling: str = "visible") -> "RoughConductor":
        """The GGX lobe with Schlick's Fresnel term of normal-incidence reflectance F0 in [0, 1):
        stored as the real index η = (1 + √F0)/(1 − √F0), k = 0, whose F(0) is F0."""
        check_parameter("RoughConductor.schlick", "f0", f0, 0.0, 1.0, high_open=True)
        root = safe_sqrt(jnp.asarray(f0))
        return cls(alpha, (1.0 + root) / (1.0 - root), jnp.zeros_like(root), fresnel="schlick", sampling=sampling)

    @property
    def distribution(self) -> GGX:
        return GGX(self.alpha)

    @property
    def f0(self):
        """Reflectance at normal incidence, ((n − 1)² + k²)/((n + 1)² + k²)."""
        return normal_incidence_reflectance(self.eta, self.k)

    def reflectance(self, cos_theta):
        """F at cos θ between the direction and the microfacet normal (the selected form)."""
        if self.fresnel == "schlick":
            return fresnel_schlick(cos_theta, self.f0)
        return fresnel_conductor(cos_theta, self.eta, self.k)

    def eval(self, wo: jax.Array, wi: jax.Array) -> jax.Array:
        """f_r for local directions (..., 3), shape (...) or (..., C) for a colour η or k; 0 unless
        both are strictly above the surface."""
        above = (wo[..., 2] > 0) & (wi[..., 2] > 0)
        h = _normalized(wo + wi)
        alpha2 = jnp.asarray(self.alpha) ** 2

        def height(w):
            z = w[..., 2]
            return safe_sqrt(z * z + alpha2 * (w[..., 0] ** 2 + w[..., 1] ** 2))

        zo, zi = wo[..., 2], wi[..., 2]
        masking = safe_div(0.5, zi * height(wo) + zo * height(wi))  # G2 / (4 cos θ_o cos θ_i)
        index = jnp.zeros(jnp.broadcast_shapes(jnp.shape(self.eta), jnp.shape(self.k)))  # () or (C,)
        fresnel = self.reflectance(lift(_dot(wo, h), index))
        value = lift(self.distribution.D(h) * masking, index) * fresnel
        return jnp.where(lift(above, index), value, 0.0)

    def sampler(self, wo: jax.Array) -> Sampler:
        """The directional sampler of ω_i for this ω_o (local frame): `sampling`'s reflection lobe."""
        if self.sampling == "full":
            return FullNormalsReflection(self.distribution, wo)
        return MicrofacetReflection(self.distribution, wo)

    def sample(self, wo: jax.Array, u: jax.Array) -> tuple[jax.Array, jax.Array]:
        """(ω_i, p(ω_i)) from uniforms u of shape (..., 2); the density is over solid angle."""
        return self.sampler(wo).warp_with_pdf(u)

    def pdf(self, wo: jax.Array, wi: jax.Array) -> jax.Array:
        """Density over solid angle with which `sample` draws ω_i (nonzero below the surface too)."""
        return self.sampler(wo).pdf(wi)
