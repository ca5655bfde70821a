"""A latitude–longitude environment map at infinity, importance-sampled by its texels."""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from ..samplers.base import Sampler, point_method
from .._core.params import concrete_value
from .._core.pytree import Pytree
from ..samplers.domain import Directions
from .._core.numerics import azimuth_fraction, safe_div, spherical_direction
from ..samplers.piecewise import PiecewiseConstant2D

_TWO_PI_SQUARED = 2.0 * np.pi * np.pi


def _texel(coordinate, count):
    """Texel index of a coordinate in [0, 1] for `count` equal texels (the last one closed)."""
    return jnp.clip(jnp.floor(coordinate * count), 0, count - 1).astype(jnp.int32)


def direction_from_uv(uv):
    """(s, t) in [0, 1]² -> the direction with φ = 2πs, θ = πt (θ from the world +z axis)."""
    theta = jnp.pi * uv[..., 1]
    return spherical_direction(jnp.sin(theta), jnp.cos(theta), uv[..., 0])


def uv_from_direction(wi):
    """The inverse of `direction_from_uv`, and sin θ (from x and y: exact near the poles)."""
    sin_theta = jnp.sqrt(wi[..., 0] ** 2 + wi[..., 1] ** 2)
    t = jnp.arctan2(sin_theta, wi[..., 2]) / jnp.pi
    return jnp.stack([azimuth_fraction(wi[..., 1], wi[..., 0]), t], axis=-1), sin_theta


class EnvironmentMap(Pytree):
    """Radiance L(ω) = values[row, column] of a lat–long map of shape (H, W): row j covers polar
    angles θ in [πj/H, π(j+1)/H] about the world +z axis, column i covers φ in [2πi/W, 2π(i+1)/W].

    The map is at infinity, so the shading point does not matter. Sampling: `PiecewiseConstant2D`
    over (s, t) = (φ/2π, θ/π) with texel weights
    values · sin θ_row (θ at the row's centre), so that texels are chosen in proportion to their
    power. The map (s, t) -> ω has dω = sin θ dθ dφ = 2π² sin θ ds dt, so the density over solid
    angle is p_ω = p_st / (2π² sin θ) (PBRT-v4 `ImageInfiniteLight`; Pharr et al., *PBR* 3rd ed.,
    §14.2.4). Where sin θ = 0 (the poles, measure zero) the density is reported as 0.

    `values` must be finite, >= 0 and not all zero, shape (H, W) (ValueError when concrete); they
    may be traced, and gradients reach them through the radiance and the sampling tables.

    Colour: `values` of shape (H, W, C) hold C channels per texel (`jaxsample.scene.colour`), and the
    radiance methods return (..., C). One table samples every channel: the texel weights use the
    channel average (as PBRT-v4's image lights do), defined for any number of channels, where
    luminance would be RGB's alone. A channel that is bright where the average is dim is sampled
    poorly, never with bias: the weight of a texel is > 0 wherever any channel is.
    """

    # Its radiance jumps at texel edges, which stay put in ω whatever its values: a gradient is
    # biased only where samples move across them (`shade` says which strategies those are).
    fixed_edges: ClassVar[bool] = True
    values: jax.Array
    distribution: PiecewiseConstant2D

    def __init__(self, values):
        values = jnp.asarray(values)
        if values.ndim not in (2, 3):
            raise ValueError(f"EnvironmentMap: parameter 'values' must have shape (H, W), or (H, W, C) for C "
                             f"channels; got {values.shape}")
        concrete = concrete_value(values)
        if concrete is not None and values.ndim == 3 and not np.all(np.isfinite(concrete) & (concrete >= 0)):
            raise ValueError("EnvironmentMap: parameter 'values' must be finite and >= 0 in every channel")
        rows = values.shape[0]
        centre_sin = np.sin(np.pi * (np.arange(rows) + 0.5) / rows).astype(values.dtype)
        self.values = values
        weights = values if values.ndim == 2 else jnp.mean(values, axis=-1)
        self.distribution = PiecewiseConstant2D(weights * centre_sin[:, None])

    def __repr__(self):
        return f"EnvironmentMap(shape={tuple(self.values.shape)})"

    # --- the light interface (the point is ignored: the map is at infinity) ---

    def sampler(self, point=None) -> "EnvironmentDirections":
        """The directional sampler of `sample`, for the checks in `jaxsample.testing`."""
        return EnvironmentDirections(self)

    def sample(self, point, u):
        """(ω, L(ω), p(ω)) from uniforms u (..., 2); L is the texel the sample was drawn from."""
        uv, pdf_uv = self.distribution.warp_with_pdf(u)
        wi = direction_from_uv(uv)
        pdf = safe_div(pdf_uv, _TWO_PI_SQUARED * jnp.sin(jnp.pi * uv[..., 1]))
        return wi, self._lookup(uv), pdf

    def pdf(self, point, wi):
        uv, sin_theta = uv_from_direction(wi)
        return safe_div(self.distribution.pdf(uv), _TWO_PI_SQUARED * sin_theta)

    def radiance_from(self, point, wi):
        return self._lookup(uv_from_direction(wi)[0])

    def _lookup(self, uv):
        rows, columns = self.values.shape[:2]
        return self.values[_texel(uv[..., 1], rows), _texel(uv[..., 0], columns)]


class EnvironmentDirections(Sampler):
    """An `EnvironmentMap`'s light sampler as a `Sampler` of directions (density over solid angle)."""

    light: EnvironmentMap
    uniform_dims: ClassVar[int] = 2
    event_shape: ClassVar = (3,)

    @point_method
    def warp(self, u):
        return direction_from_uv(self.light.distribution.warp(u))

    @point_method
    def warp_with_pdf(self, u):
        wi, _, pdf = self.light.sample(None, u)
        return wi, pdf

    @point_method
    def pdf(self, x):
        return self.light.pdf(None, x)

    def domain(self):
        rows = self.light.values.shape[0]
        # Row edges are where the density jumps: 1 - cos θ at θ = πj/H.
        breaks = tuple(float(1.0 - np.cos(np.pi * j / rows)) for j in range(1, rows))
        return Directions(breaks=breaks)
