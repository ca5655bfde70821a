"""The Lambertian (ideal diffuse) BRDF f_r = albedo / π, sampled cosine-weighted."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .._core.pytree import Pytree, parameter
from ..samplers.cosine import CosineHemisphere
from .._core.numerics import INV_PI
from .colour import lift


class Lambertian(Pytree):
    """f_r(ω_o, ω_i) = albedo / π for ω_o and ω_i both above the surface, 0 otherwise.

    Directions are in the local shading frame (the normal is +z), as in PBRT's BxDFs; `shade` turns
    world directions into that frame. Reciprocal (f_r does not depend on either direction) and
    energy-conserving for albedo <= 1: the directional albedo ∫ f_r cos θ_i dω_i = albedo exactly.

    Sampling: the cosine-weighted hemisphere (Malley's method), p(ω_i) = cos θ_i / π over solid
    angle, which makes f_r cos θ_i / p = albedo for every sample (zero variance under a constant sky).

    Parameter: `albedo` in [0, 1] (checked when concrete), a scalar or one per channel, shape (C,)
    (`jaxsample.scene.colour`); `eval` then returns (..., C).
    """

    albedo: jax.Array = parameter(0.0, 1.0)

    def eval(self, wo: jax.Array, wi: jax.Array) -> jax.Array:
        """f_r for local directions (..., 3), shape (...) or (..., C) for a colour albedo; 0 unless
        both are strictly above the surface."""
        above = (wo[..., 2] > 0) & (wi[..., 2] > 0)
        return jnp.where(lift(above, self.albedo), self.albedo * INV_PI, 0.0).astype(jnp.result_type(wi, float))

    def sampler(self, wo: jax.Array) -> CosineHemisphere:
        """The directional sampler of ω_i (local frame); it does not depend on ω_o."""
        del wo
        return CosineHemisphere()

    def sample(self, wo: jax.Array, u: jax.Array) -> tuple[jax.Array, jax.Array]:
        """(ω_i, p(ω_i)) from uniforms u of shape (..., 2); the density is over solid angle."""
        return self.sampler(wo).warp_with_pdf(u)

    def pdf(self, wo: jax.Array, wi: jax.Array) -> jax.Array:
        """Density over solid angle with which `sample` draws ω_i."""
        return self.sampler(wo).pdf(wi)
