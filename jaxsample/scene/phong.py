"""The energy-normalized modified Phong BRDF about the mirror direction (Lafortune & Willems 1994)."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .._core.pytree import Pytree, parameter
from .._core.numerics import INV_2PI, safe_pow
from ..samplers.oriented import Oriented
from ..samplers.phong import PhongLobe
from .colour import lift


def reflect(wo: jax.Array) -> jax.Array:
    """Mirror direction of a local direction about the normal +z: (-x, -y, z)."""
    return wo * jnp.asarray([-1.0, -1.0, 1.0], dtype=jnp.result_type(wo, float))


class Phong(Pytree):
    """f_r(ω_o, ω_i) = albedo (n + 2)/(2π) max(cos α, 0)^n, α the angle between ω_i and the mirror
    direction r of ω_o; 0 unless both directions are above the surface (local frame, normal +z).

    Why (n + 2)/(2π) and not (n + 1)/(2π): the extra cosine of the rendering equation. At normal
    incidence r is the normal, α = θ_i, and ∫ cos^n θ cos θ dω = 2π/(n + 2), so with (n + 2) the
    directional albedo is exactly `albedo` there; at n = 0 the BRDF is the Lambertian albedo/π.
    With (n + 1) the albedo would top out at albedo (n + 1)/(n + 2), half of it at n = 0.
    For any other ω_o the albedo is smaller: ∫ max(r·ω, 0)^n max(n·ω, 0) dω is a spherical
    convolution of two kernels that are each symmetric and decreasing about their axes, which is
    largest when the axes coincide (Baernstein & Taylor 1976) — so albedo <= 1 conserves energy
    for every ω_o (checked by quadrature in the tests).
    Reciprocal: cos α = ω_i · reflect(ω_o) = reflect(ω_i) · ω_o is symmetric in the two directions.

    Sampling: the cos^n lobe about r, p(ω_i) = (n + 1)/(2π) max(cos α, 0)^n over the whole sphere
    (`PhongLobe` turned by `Oriented`); samples below the surface have f_r = 0 and are wasted, the
    usual price of lobe sampling (Lafortune & Willems 1994).

    Parameters: `exponent` n in [0, 1e7], `albedo` in [0, 1] (checked when concrete). The albedo may
    be one per channel, shape (C,) (`jaxsample.scene.colour`): `eval` then returns (..., C); the
    exponent, which shapes the sampled lobe, is one for every channel.
    """

    exponent: jax.Array = parameter(0.0, 1e7)
    albedo: jax.Array = parameter(0.0, 1.0)

    def eval(self, wo: jax.Array, wi: jax.Array) -> jax.Array:
        """f_r for local directions (..., 3), shape (...) or (..., C) for a colour albedo; 0 unless
        both are strictly above the surface."""
        n = self.exponent
        above = (wo[..., 2] > 0) & (wi[..., 2] > 0)
        cos_alpha = jnp.sum(wi * reflect(wo), axis=-1)
        lobe = safe_pow(jnp.maximum(cos_alpha, 0.0), n)
        albedo = self.albedo
        return jnp.where(lift(above, albedo), albedo * (n + 2.0) * INV_2PI * lift(lobe, albedo), 0.0)

    def sampler(self, wo: jax.Array) -> Oriented:
        """The cos^n lobe about the mirror direction of ω_o, as a directional sampler (local frame)."""
        return Oriented(PhongLobe(self.exponent), reflect(wo))

    def sample(self, wo: jax.Array, u: jax.Array) -> tuple[jax.Array, jax.Array]:
        """(ω_i, p(ω_i)) from uniforms u of shape (..., 2); the density is over solid angle."""
        return self.sampler(wo).warp_with_pdf(u)

    def pdf(self, wo: jax.Array, wi: jax.Array) -> jax.Array:
        """Density over solid angle with which `sample` draws ω_i (nonzero below the surface too)."""
        return self.sampler(wo).pdf(wi)
