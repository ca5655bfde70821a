"""Uniform directions on the sphere and the hemisphere (density over solid angle)."""

from __future__ import annotations

from typing import ClassVar

import jax.numpy as jnp

from .base import Sampler, point_method
from .._core.params import check_choice
from .._core.pytree import parameter, static_field
from .domain import Directions
from .._core.numerics import (INV_2PI, INV_4PI, azimuth_fraction, one_minus_cos_theta, safe_sqrt,
    spherical_direction)
from .rejection import select_first


class UniformSphere(Sampler):
    """Uniform on the unit sphere S²: p(ω) = 1/(4π) over solid angle.

    `method="inversion"` (default, 2 uniforms): z = 1 - 2u₀, φ = 2πu₁ (Archimedes' hat-box theorem;
    the seed derivation and PBRT-v4 `SampleUniformSphere`). sin θ is computed as 2 sqrt(u₀(1 - u₀)),
    not sqrt(1 - z²), so that it keeps full precision at both poles.

    `method="rejection"`: points uniform in the cube [-1, 1]³, accepted inside the shell
    1e-4 <= |p|² <= 1 (acceptance ≈ π/6) and normalised; `tries` attempts, 3 uniforms each, run
    without branching. The last 2 uniforms feed an inversion sample used only if every try is
    rejected: being independent of the rejected tries, it keeps the output exactly uniform.
    This form has no inverse.
    """

    method: str = static_field(default="inversion")
    tries: int = parameter(1, 4096, static=True, default=16, doc="attempts of the rejection method")
    event_shape: ClassVar = (3,)
    measure: ClassVar = "solid angle"
    periodic_dims: ClassVar = (1,)

    def __post_init__(self):
        check_choice("UniformSphere", "method", self.method, ("inversion", "rejection"))

    @property
    def uniform_dims(self) -> int:
        return 2 if self.method == "inversion" else 3 * self.tries + 2

    def _inversion(self, u):
        u0, u1 = u[..., 0], u[..., 1]
        sin_theta = 2.0 * safe_sqrt(u0 * (1.0 - u0))
        return spherical_direction(sin_theta, 1.0 - 2.0 * u0, u1)

    @point_method
    def warp(self, u):
        if self.method == "inversion":
            return self._inversion(u)
        fallback = self._inversion(u[..., -2:])
        points = 2.0 * u[..., :-2].reshape(u.shape[:-1] + (self.tries, 3)) - 1.0
        r2 = jnp.sum(points * points, axis=-1)
        accepted = (r2 <= 1.0) & (r2 >= 1e-4)
        # The fallback (a unit vector) carries r² = 1, so one normalisation serves both outcomes.
        chosen, chosen_r2 = select_first((points, r2), accepted, (fallback, jnp.ones_like(r2[..., 0])))
        return chosen / jnp.sqrt(chosen_r2)[..., None]

    @point_method
    def pdf(self, x):
        return jnp.full(x.shape[:-1], INV_4PI, dtype=jnp.result_type(x, float))

    @point_method
    def inverse(self, x):
        if self.method != "inversion":
            return super().inverse(x)
        u0 = 0.5 * one_minus_cos_theta(x)
        return jnp.stack([u0, azimuth_fraction(x[..., 1], x[..., 0])], axis=-1)

    @property
    def has_inverse(self) -> bool:
        return self.method == "inversion"

    def domain(self):
        return Directions()


class UniformHemisphere(Sampler):
    """Uniform on the upper hemisphere z >= 0: p(ω) = 1/(2π) over solid angle, 0 below.

    Warp (PBRT-v4 `SampleUniformHemisphere`): cos θ = 1 - u₀ (so u₀ = 0 is the pole), φ = 2πu₁,
    sin θ = sqrt(u₀(2 - u₀)), which stays exact at the pole.
    """

    uniform_dims: ClassVar[int] = 2
    event_shape: ClassVar = (3,)
    measure: ClassVar = "solid angle"
    periodic_dims: ClassVar = (1,)

    @point_method
    def warp(self, u):
        u0 = u[..., 0]
        return spherical_direction(safe_sqrt(u0 * (2.0 - u0)), 1.0 - u0, u[..., 1])

    @point_method
    def pdf(self, x):
        return jnp.where(x[..., 2] >= 0, INV_2PI, 0.0).astype(jnp.result_type(x, float))

    @point_method
    def inverse(self, x):
        return jnp.stack([one_minus_cos_theta(x), azimuth_fraction(x[..., 1], x[..., 0])], axis=-1)

    def domain(self):
        return Directions(breaks=(1.0,))
