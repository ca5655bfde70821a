"""Many spherical area lights as one batch: arrays with a leading light axis, one program whatever
their number.

`SphereLights(centers, radii, radiance)` is K `SphereLight`s whose parameters are arrays of K rows.
`shade` sees one light: its sample chooses light k with probability P_k (by `selection`) and then a
direction in k's cone, and its density is the mixture Σ_k P_k p_k(ω) (the one-sample MIS of the
lights, balance heuristic; Veach 1997, §9.2.4); the lights are transparent, so the radiance along
ω is the sum of those whose cones contain it. Every step is vectorized over the light axis, so the
program, and its compile time, do not grow with K (a Python list of lights is unrolled instead).
The selection (PBRT-v4's light samplers, without their BVH):
  "power" (default): P_k ∝ radiance · r² (the sphere's emitted power, 4π² r² L, independent of
    the point: PBRT's `PowerLightSampler`);
  "uniform": P_k = 1/K;
  "solid_angle": P_k ∝ radiance · Ω_k(p), the light's unshadowed contribution at the point to a
    constant BRDF without the cosine (a per-point importance, what PBRT's `LightBounds` bound).
The density and radiance cost O(K) per direction (a test against every cone), the selection
O(log K) (a search in the selection's cumulative table).

Gradients: the lights' silhouettes are not given to `shade` (their boundary terms are left out), so
a derivative that moves their edges is refused, as for any light without `silhouette`; derivatives
in the BRDF's parameters with light sampling, or with `mode="detached"`, are unbiased.
"""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from .._core.numerics import safe_sqrt
from .._core.params import check_choice, concrete_value
from .._core.pytree import Pytree, parameter, static_field
from ..samplers.frame import Frame

SELECTIONS = ("power", "uniform", "solid_angle")


class SphereLights(Pytree):
    """K sphere lights: `centers` (K, 3), `radii` (K,) > 0, `radiance` (K,) >= 0 or (K, C) for C
    channels (`jaxsample.scene.colour`); `selection` "power" (default), "uniform" or "solid_angle"
    (see the module docstring). A point inside or on any sphere is outside the range (refused by
    `shade` when concrete, NaN when traced), as for `SphereLight`."""

    centers: jax.Array = parameter(rank=2, doc="the spheres' centres, (K, 3)")
    radii: jax.Array = parameter(0.0, low_open=True, rank=1, doc="the spheres' radii, (K,)")
    radiance: jax.Array = parameter(0.0, rank=1, doc="each sphere's radiance, (K,) or (K, C)")
    selection: str = static_field(default="power")
    uniform_dims: ClassVar[int] = 3
    samples_follow_edges: ClassVar[bool] = False

    def __post_init__(self):
        check_choice("SphereLights", "selection", self.selection, SELECTIONS)
        centers, radii = concrete_value(self.centers), concrete_value(self.radii)
        if centers is not None and (np.ndim(centers) != 2 or np.shape(centers)[-1] != 3):
            raise ValueError(f"SphereLights: parameter 'centers' must have shape (K, 3); got {np.shape(centers)}")
        if centers is not None and radii is not None and np.shape(radii) != np.shape(centers)[:1]:
            raise ValueError(f"SphereLights: parameter 'radii' must have shape (K,) = {np.shape(centers)[:1]}; got "
                             f"{np.shape(radii)}")
        radiance = concrete_value(self.radiance)
        if centers is not None and radiance is not None and np.shape(radiance)[:1] != np.shape(centers)[:1]:
            raise ValueError(f"SphereLights: parameter 'radiance' must have K = {np.shape(centers)[0]} rows; got "
                             f"shape {np.shape(radiance)}")

    def _grey(self):
        """Each light's radiance for the selection: its channel mean where it has channels."""
        radiance = jnp.asarray(self.radiance)
        return jnp.mean(radiance, axis=-1) if radiance.ndim == 2 else radiance

    def _cones(self, point):
        """(unit axes (K, 3), h = 1 − cos θ_max (K,)): h = s/(1 + sqrt(1 − s)) from s = r²/d², exact for
        tiny cones (as `UniformCone.from_sin2`); NaN for a point inside a sphere."""
        offset = jnp.asarray(self.centers) - point
        distance2 = jnp.sum(offset * offset, axis=-1)
        s = self.radii * self.radii / distance2
        s = jnp.where(s < 1.0, s, jnp.nan)
        return offset / jnp.sqrt(distance2)[:, None], s / (1.0 + jnp.sqrt(1.0 - s))

    def contains(self, point):
        """Whether `point` lies inside or on any of the spheres."""
        offset = jnp.asarray(self.centers) - point
        return jnp.any(jnp.sum(offset * offset, axis=-1) <= self.radii * self.radii)

    def probabilities(self, point):
        """P_k, the chance that a light sample comes from light k, (K,)."""
        grey = self._grey()
        if self.selection == "uniform":
            weights = jnp.ones_like(grey)
        elif self.selection == "power":
            weights = grey * self.radii * self.radii
        else:
            weights = grey * self._cones(point)[1]  # Ω_k = 2π h_k
        return weights / jnp.sum(weights)

    def _inside(self, point, wi):
        """Whether each direction lies in each cone, (..., K): 1 − cos(ω, axis) = |ω − axis|²/2 <= h."""
        axes, h = self._cones(point)
        gap = wi[..., None, :] - axes
        return 0.5 * jnp.sum(gap * gap, axis=-1) <= h, h

    def pdf(self, point, wi):
        """Σ_k P_k [ω in cone k] / (2π h_k) over solid angle."""
        inside, h = self._inside(point, wi)
        return jnp.sum(jnp.where(inside, self.probabilities(point) / (2.0 * jnp.pi * h), 0.0), axis=-1)

    def radiance_from(self, point, wi):
        """Σ_k L_k over the cones that contain ω (the lights are transparent); NaN for a point inside."""
        inside, _ = self._inside(point, wi)
        radiance = jnp.asarray(self.radiance, jnp.result_type(wi, float))
        if radiance.ndim == 2:
            total = jnp.einsum("...k,kc->...c", inside.astype(radiance.dtype), radiance)
        else:
            total = jnp.sum(jnp.where(inside, radiance, 0.0), axis=-1)
        return jnp.where(self.contains(point), jnp.nan, total)

    def sample(self, point, u):
        """(ω, L, p) from uniforms u (..., 3): u₀ chooses the light (its cumulative table), u₁, u₂ a
        direction uniform in its cone; L and p are the sums over every cone containing ω, the chosen
        light's own term taken without re-testing its rim."""
        axes, h = self._cones(point)
        probabilities = self.probabilities(point)
        cdf = jnp.cumsum(probabilities)
        k = jnp.clip(jnp.searchsorted(cdf, u[..., 0] * cdf[-1], side="right"), 0, h.shape[0] - 1)
        h_k = h[k]
        one_minus_cos = u[..., 1] * h_k
        sin_theta = safe_sqrt(one_minus_cos * (2.0 - one_minus_cos))
        phi = 2.0 * jnp.pi * u[..., 2]
        local = jnp.stack([sin_theta * jnp.cos(phi), sin_theta * jnp.sin(phi), 1.0 - one_minus_cos], axis=-1)
        wi = Frame.from_normal(axes[k]).to_world(local)
        inside, _ = self._inside(point, wi)
        own = jax.nn.one_hot(k, h.shape[0], dtype=bool)
        inside = inside | own
        pdf = jnp.sum(jnp.where(inside, probabilities / (2.0 * jnp.pi * h), 0.0), axis=-1)
        radiance = jnp.asarray(self.radiance, wi.dtype)
        if radiance.ndim == 2:
            total = jnp.einsum("...k,kc->...c", inside.astype(radiance.dtype), radiance)
        else:
            total = jnp.sum(jnp.where(inside, radiance, 0.0), axis=-1)
        return wi, total, pdf
