"""A constant sky: the same radiance from every direction, at infinity."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .._core.pytree import Pytree, parameter
from .._core.numerics import INV_4PI
from ..samplers.sphere import UniformSphere


class ConstantSky(Pytree):
    """L_i(ω) = radiance for every direction ω (the white furnace when radiance = 1).

    Light sampling draws ω uniformly on the sphere, p = 1/(4π) over solid angle. It does not know
    the surface normal, so half of its samples fall below the surface; a cosine-weighted BRDF
    sampler is the better strategy here, and MIS finds that out by itself.

    `radiance` >= 0, a scalar or one per channel, shape (C,) (`jaxsample.scene.colour`): the radiance
    methods then return (..., C).
    """

    radiance: jax.Array = parameter(0.0)

    def sampler(self, point: jax.Array) -> UniformSphere:
        """The directional sampler of `sample` as seen from `point` (world frame)."""
        del point
        return UniformSphere()

    def silhouette(self, point):
        """None: the sky's radiance is the same from every direction, so it has no edge."""
        return None

    def sample(self, point, u):
        """(ω, L_i(ω), p(ω)) from uniforms u (..., 2); p over solid angle at `point`."""
        wi, pdf = self.sampler(point).warp_with_pdf(u)
        return wi, jnp.broadcast_to(jnp.asarray(self.radiance, pdf.dtype), pdf.shape + jnp.shape(self.radiance)), pdf

    def pdf(self, point, wi):
        return jnp.full(wi.shape[:-1], INV_4PI, jnp.result_type(wi, float))

    def radiance_from(self, point, wi):
        """L_i arriving at `point` from direction `wi` (world frame)."""
        return jnp.broadcast_to(jnp.asarray(self.radiance, jnp.result_type(wi, float)),
                                wi.shape[:-1] + jnp.shape(self.radiance))
