"""A spherical area light, seen from a shading point as a cone of directions."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .._core.pytree import Pytree, parameter
from ..samplers.cone import UniformCone
from ..samplers.oriented import Oriented
from .colour import lift


class SphereLight(Pytree):
    """A sphere of radius r about `center` whose surface emits `radiance` L uniformly.

    From a point p at distance d > r the sphere covers the cone of directions about
    (center - p)/d with sin² θ_max = r²/d², and every direction in that cone sees radiance L. So
    L_i(ω) = L inside the cone and 0 outside, and the light is sampled uniformly over the cone
    (PBRT-v4 `Sphere::Sample(ctx)`, which samples the cone rather than the area for points
    outside): p(ω) = 1/(2π(1 - cos θ_max)) over solid angle.

    Stability for tiny or distant lights: the cone is built with `UniformCone.from_sin2`, which
    stores h = 1 - cos θ_max = s/(1 + sqrt(1 - s)) from s = sin² θ_max; that is accurate when
    cos θ_max itself rounds to 1 (sin θ_max = 1e-4 gives h = 5e-9, and 1 - cos θ_max in float32
    would be 0). The same cone decides membership in `pdf` and `radiance_from`, so the light
    sampling density and the radiance seen by other strategies agree on one support.

    The light is transparent (no occlusion anywhere in this scene layer). A point inside or on the
    sphere is outside the range: `shade` refuses a concrete one, and a traced one gives NaN.
    Parameters: `radius` > 0, `radiance` >= 0 (checked when concrete);
    `center` a 3-vector; `radiance` a scalar or one per channel, shape (C,) (`jaxsample.scene.colour`),
    and the radiance methods then return (..., C). All three may be traced and differentiated:
    attached light samples move
    with the sphere.
    """

    center: jax.Array
    radius: jax.Array = parameter(0.0, low_open=True)
    radiance: jax.Array = parameter(0.0)

    def contains(self, point):
        """Whether `point` lies inside or on the sphere, d <= r (outside the shading range)."""
        offset = jnp.asarray(self.center) - point
        return jnp.sum(offset * offset, axis=-1) <= self.radius * self.radius

    def sin2_theta_max(self, point):
        """sin² of the cone's half-angle from `point`: r²/d², and NaN for a point inside or on the
        sphere (d <= r), where the light covers no cone; a concrete such point is refused by `shade`."""
        offset = jnp.asarray(self.center) - point
        ratio = self.radius * self.radius / jnp.sum(offset * offset, axis=-1)
        return jnp.where(ratio < 1.0, ratio, jnp.nan)

    def sampler(self, point: jax.Array) -> Oriented:
        """The cone of directions the sphere covers from `point`, as a directional sampler."""
        axis = jnp.asarray(self.center) - point
        return Oriented(UniformCone.from_sin2(self.sin2_theta_max(point)), axis)

    def silhouette(self, point):
        """The cap of directions the sphere covers from `point` (`jaxsample.edges.Cap`): its rim is the
        silhouette, where L_i jumps from L to 0, moving with the centre, the radius and the point."""
        from ..edges.regions import Cap
        return Cap(jnp.asarray(self.center) - point, self.sampler(point).base.one_minus_cos_theta_max)

    def inside_values(self, point, wi):
        """(L_i, p(ω)) just inside the silhouette at rim directions `wi`: L and 1/(2π(1 - cos θ_max))."""
        pdf = 1.0 / (2.0 * jnp.pi * self.sampler(point).base.one_minus_cos_theta_max)
        shape = jnp.shape(wi)[:-1]
        dtype = jnp.result_type(wi, float)
        return (jnp.broadcast_to(jnp.asarray(self.radiance, dtype), shape + jnp.shape(self.radiance)),
                jnp.broadcast_to(jnp.asarray(pdf, dtype), shape))

    def sample(self, point, u):
        """(ω, L, p(ω)) from uniforms u (..., 2): every cone direction sees the sphere, so the
        radiance is L without re-testing membership (which rounding at the rim could flip)."""
        wi, pdf = self.sampler(point).warp_with_pdf(u)
        return wi, jnp.broadcast_to(jnp.asarray(self.radiance, pdf.dtype), pdf.shape + jnp.shape(self.radiance)), pdf

    def pdf(self, point, wi):
        return self.sampler(point).pdf(wi)

    def radiance_from(self, point, wi):
        """L where `wi` lies in the cone (the ray hits the sphere), 0 elsewhere; NaN for a point inside
        or on the sphere (outside the range: no cone)."""
        radiance = jnp.where(lift(self.sampler(point).pdf(wi) > 0, self.radiance), self.radiance, 0.0)
        return jnp.where(self.contains(point), jnp.nan, radiance).astype(jnp.result_type(wi, float))
