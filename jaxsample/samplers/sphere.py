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


def equal_area_square_to_sphere(u):
    """Clarberg's equal-area map of [0, 1]² onto S² (see `UniformSphere`, method "equal_area")."""
    a, b = 2.0 * u[..., 0] - 1.0, 2.0 * u[..., 1] - 1.0
    abs_a, abs_b = jnp.abs(a), jnp.abs(b)
    signed = 1.0 - (abs_a + abs_b)  # > 0 inside the diamond: the northern hemisphere
    r = 1.0 - jnp.abs(signed)
    r_safe = jnp.where(r > 0, r, 1.0)
    phi = jnp.where(r > 0, (abs_b - abs_a) / r_safe + 1.0, 1.0) * (jnp.pi / 4)
    # 1 − |z| = r², so sin θ = r sqrt(2 − r²) and |z| = 1 − r² each without cancelling.
    sin_theta = r * jnp.sqrt(2.0 - r * r)
    z = jnp.where(signed >= 0, 1.0, -1.0) * (1.0 - r * r)
    return jnp.stack([jnp.copysign(jnp.cos(phi), a) * sin_theta, jnp.copysign(jnp.sin(phi), b) * sin_theta, z],
                     axis=-1)


def equal_area_sphere_to_square(x):
    """The inverse of `equal_area_square_to_sphere` (PBRT-v4 `EqualAreaSphereToSquare`)."""
    ax, ay, az = jnp.abs(x[..., 0]), jnp.abs(x[..., 1]), jnp.abs(x[..., 2])
    # r² = 1 − |z| = (x² + y²)/(1 + |z|), exact near the poles where 1 − |z| cancels.
    r = jnp.sqrt((ax * ax + ay * ay) / (1.0 + az))
    big, small = jnp.maximum(ax, ay), jnp.minimum(ax, ay)
    angle = jnp.arctan(small / jnp.where(big > 0, big, 1.0)) * (2.0 / jnp.pi)
    angle = jnp.where(ax < ay, 1.0 - angle, angle)
    v = angle * r
    u = r - v
    south = x[..., 2] < 0
    u, v = jnp.where(south, 1.0 - v, u), jnp.where(south, 1.0 - u, v)
    u, v = jnp.copysign(u, x[..., 0]), jnp.copysign(v, x[..., 1])
    return jnp.stack([0.5 * (u + 1.0), 0.5 * (v + 1.0)], axis=-1)


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

    `method="equal_area"` (2 uniforms): Clarberg's equal-area map of the square onto the sphere
    (Clarberg 2008, "Fast equal-area mapping of the (hemi)sphere using SIMD"; PBRT-v4
    `EqualAreaSquareToSphere`): the square, folded into an octahedron, maps the diamond
    |u'| + |v'| <= 1 (u' = 2u₀ − 1, v' = 2u₁ − 1) onto the northern hemisphere and its four corners
    onto the southern one, with r = 1 − |1 − |u'| − |v'||, |z| = 1 − r², φ = π/4 (1 + (|v'| − |u'|)/r)
    in the quadrant of (u', v'). Continuous over the whole square (its edges meet in pairs on the
    sphere), with the inverse `EqualAreaSphereToSquare`; neighbouring points stay neighbours, so
    stratified and QMC points keep their structure across the sphere, and an image stored on the
    square (an environment map) is sampled with equal solid angle per texel.
    """

    method: str = static_field(default="inversion")
    tries: int = parameter(1, 4096, static=True, default=16, doc="attempts of the rejection method")
    event_shape: ClassVar = (3,)
    measure: ClassVar = "solid angle"

    def __post_init__(self):
        check_choice("UniformSphere", "method", self.method, ("inversion", "rejection", "equal_area"))

    @property
    def uniform_dims(self) -> int:
        return 3 * self.tries + 2 if self.method == "rejection" else 2

    @property
    def periodic_dims(self):
        return (1,) if self.method == "inversion" else ()

    def _inversion(self, u):
        u0, u1 = u[..., 0], u[..., 1]
        sin_theta = 2.0 * safe_sqrt(u0 * (1.0 - u0))
        return spherical_direction(sin_theta, 1.0 - 2.0 * u0, u1)

    @point_method
    def warp(self, u):
        if self.method == "inversion":
            return self._inversion(u)
        if self.method == "equal_area":
            return equal_area_square_to_sphere(u)
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
        if self.method == "equal_area":
            return equal_area_sphere_to_square(x)
        if self.method != "inversion":
            return super().inverse(x)
        u0 = 0.5 * one_minus_cos_theta(x)
        return jnp.stack([u0, azimuth_fraction(x[..., 1], x[..., 0])], axis=-1)

    @property
    def has_inverse(self) -> bool:
        return self.method != "rejection"

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
