"""Uniform points in an axis-aligned box of R^d: p = 1/volume over volume (Lebesgue measure).

Not in the contract's table, but the natural proposal for `Rejection` (the disk in the square, the
ball in the cube) and the natural base for `Transformed` (polar or spherical coordinates).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from .base import Sampler, point_method
from .._core.params import concrete_value
from .._core.pytree import parameter
from .domain import Box


class UniformBox(Sampler):
    """Uniform on prod_k [low_k, high_k]: p = 1/prod_k (high_k - low_k), 0 outside.

    Warp x_k = (1 - u_k) low_k + u_k high_k, the lerp form that is exact at both ends (PBRT-v4
    `Lerp`); inverse u_k = (x_k - low_k)/(high_k - low_k). Concrete bounds must be finite, of equal
    shape (d,), with low < high (ValueError otherwise).
    """

    low: jax.Array = parameter(rank=1, doc="the lower corner, finite")
    high: jax.Array = parameter(rank=1, doc="the upper corner, finite, above low")

    def __post_init__(self):
        low, high = concrete_value(self.low), concrete_value(self.high)
        if low is None or high is None:
            return
        if low.ndim < 1 or low.shape[-1:] != high.shape[-1:] or low.size == 0:
            raise ValueError(f"UniformBox: parameters 'low' and 'high' must have shapes (..., d) with one d "
                             f"(leading dimensions are a batch); got {low.shape} and {high.shape}")
        if not (np.all(np.isfinite(low)) and np.all(np.isfinite(high)) and np.all(low < high)):
            raise ValueError("UniformBox: parameters 'low' and 'high' must be finite with low < high")

    @property
    def uniform_dims(self) -> int:
        return jnp.shape(self.low)[-1]

    @property
    def event_shape(self):
        return (self.uniform_dims,)

    @property
    def measure(self) -> str:
        """Lebesgue measure on R^d: length, area, volume, or "d-volume"."""
        d = self.uniform_dims
        return {1: "length", 2: "area", 3: "volume"}.get(d, f"{d}-volume")

    def _parameters_valid(self):
        low, high = jnp.asarray(self.low), jnp.asarray(self.high)
        return jnp.all(jnp.isfinite(low) & jnp.isfinite(high) & (low < high))  # no range states low < high

    def _volume(self):
        return jnp.prod(jnp.asarray(self.high) - jnp.asarray(self.low), axis=-1)

    @point_method
    def warp(self, u):
        return (1.0 - u) * self.low + u * self.high

    @point_method
    def warp_with_pdf(self, u):
        x = self.warp(u)
        return x, jnp.broadcast_to(1.0 / self._volume(), x.shape[:-1]).astype(x.dtype)

    @point_method
    def pdf(self, x):
        inside = jnp.all((x >= self.low) & (x <= self.high), axis=-1)
        return jnp.where(inside, 1.0 / self._volume(), 0.0).astype(jnp.result_type(x, float))

    @point_method
    def inverse(self, x):
        return jnp.clip((x - self.low) / (jnp.asarray(self.high) - self.low), 0.0, 1.0)

    def domain(self):
        return Box.from_bounds(concrete_value(self.low), concrete_value(self.high))
