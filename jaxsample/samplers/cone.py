"""Uniform directions in a cone (spherical cap) about +z, density over solid angle."""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from .base import Sampler, point_method
from .._core.params import as_parameter, check_parameter, concrete_value
from .._core.pytree import parameter
from .domain import Directions
from .._core.numerics import (INV_2PI, safe_sqrt, azimuth_fraction, direction_from_one_minus_cos,
    one_minus_cos_theta)

# Relative slack on the cap's edge in `pdf`: a sample warped from u₀ = 1 - 2^-24 must not be
# declared outside the cap because recomputing 1 - cos θ from the vector rounds up by an ulp.
_EDGE_SLACK = 4 * np.finfo(np.float32).eps


class UniformCone(Sampler):
    """Uniform on the cap {ω : cos θ >= cos θ_max}: p(ω) = 1/(2π(1 - cos θ_max)) over solid angle.

    Warp (PBRT-v4 `SampleUniformCone`, lerp form): 1 - cos θ = u₀ (1 - cos θ_max), φ = 2πu₁.

    The sampler stores h = 1 - cos θ_max, not cos θ_max: for a distant light of 1e-8 sr,
    h = 1.6e-9 and cos θ_max rounds to exactly 1 in float32, while h is represented to full
    precision. Build tiny caps with `from_angle`, `from_solid_angle` or `from_sin2` (the small-cap
    form h = sin²θ_max / (1 + cos θ_max) of PBRT's sphere light); `UniformCone(cos_theta_max)` is
    exact only while 1 - cos θ_max is well above float epsilon.

    `cos_theta_max` must be in [-1, 1).
    """

    one_minus_cos_theta_max: jax.Array = parameter(0.0, 2.0, low_open=True, doc="h = 1 - cos θ_max")
    uniform_dims: ClassVar[int] = 2
    event_shape: ClassVar = (3,)
    periodic_dims: ClassVar = (1,)
    measure: ClassVar = "solid angle"

    def __init__(self, cos_theta_max=None, *, one_minus_cos_theta_max=None):
        if (cos_theta_max is None) == (one_minus_cos_theta_max is None):
            raise ValueError("UniformCone: give exactly one of 'cos_theta_max' and 'one_minus_cos_theta_max'")
        cos_theta_max, one_minus_cos_theta_max = as_parameter(cos_theta_max), as_parameter(one_minus_cos_theta_max)
        if cos_theta_max is not None:
            check_parameter("UniformCone", "cos_theta_max", cos_theta_max, -1.0, 1.0, high_open=True)
            one_minus_cos_theta_max = 1.0 - cos_theta_max
        self.one_minus_cos_theta_max = one_minus_cos_theta_max

    @classmethod
    def from_angle(cls, theta_max):
        """Cap of half-angle θ_max in (0, π]: h = 2 sin²(θ_max/2), exact for tiny angles."""
        check_parameter("UniformCone.from_angle", "theta_max", theta_max, 0.0, np.pi, low_open=True)
        return cls(one_minus_cos_theta_max=2.0 * jnp.sin(0.5 * jnp.asarray(theta_max)) ** 2)

    @classmethod
    def from_solid_angle(cls, solid_angle):
        """Cap of the given solid angle in (0, 4π]: h = Ω / (2π)."""
        check_parameter("UniformCone.from_solid_angle", "solid_angle", solid_angle, 0.0, 4 * np.pi,
                        low_open=True)
        # 4π rounded to float32 and divided by 2π can land an ulp above 2: clamp to the sphere.
        return cls(one_minus_cos_theta_max=jnp.minimum(jnp.asarray(solid_angle) * INV_2PI, 2.0))

    @classmethod
    def from_sin2(cls, sin2_theta_max):
        """Cap no wider than a hemisphere, from sin² θ_max in (0, 1]: h = s / (1 + sqrt(1 - s))."""
        check_parameter("UniformCone.from_sin2", "sin2_theta_max", sin2_theta_max, 0.0, 1.0, low_open=True)
        s = jnp.asarray(sin2_theta_max)
        # safe_sqrt: at s = 1 (a hemisphere; a sphere light whose clamp has reached it) the derivative of
        # sqrt(1 - s) is infinite, and inf times a zero tangent would make the gradient NaN.
        return cls(one_minus_cos_theta_max=s / (1.0 + safe_sqrt(1.0 - s)))

    @property
    def cos_theta_max(self):
        return 1.0 - self.one_minus_cos_theta_max

    @property
    def solid_angle(self):
        return 2.0 * jnp.pi * self.one_minus_cos_theta_max

    def __repr__(self):
        return f"UniformCone(one_minus_cos_theta_max={self.one_minus_cos_theta_max!r})"

    @point_method
    def warp(self, u):
        return direction_from_one_minus_cos(u[..., 0] * self.one_minus_cos_theta_max, u[..., 1])

    @point_method
    def warp_with_pdf(self, u):
        x = self.warp(u)
        return x, jnp.broadcast_to(INV_2PI / self.one_minus_cos_theta_max, x.shape[:-1]).astype(x.dtype)

    @point_method
    def pdf(self, x):
        h = self.one_minus_cos_theta_max
        inside = one_minus_cos_theta(x) <= h * (1.0 + _EDGE_SLACK)
        return jnp.where(inside, INV_2PI / h, 0.0).astype(jnp.result_type(x, float))

    @point_method
    def inverse(self, x):
        u0 = one_minus_cos_theta(x) / self.one_minus_cos_theta_max
        return jnp.stack([u0, azimuth_fraction(x[..., 1], x[..., 0])], axis=-1)

    def domain(self):
        h = concrete_value(self.one_minus_cos_theta_max)
        return Directions(breaks=() if h is None else (float(h),))
