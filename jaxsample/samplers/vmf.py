"""The von Mises–Fisher distribution on S², density over solid angle."""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from .base import Sampler, point_method
from .._core.pytree import parameter
from .domain import Directions
from .._core.numerics import azimuth_fraction, direction_from_one_minus_cos, one_minus_cos_theta


class VonMisesFisher(Sampler):
    """von Mises–Fisher about +z: p(ω) = κ e^{κ cos θ} / (4π sinh κ) over solid angle on S².

    Written in the stable form of Jakob 2012 ("Numerically stable sampling of the von Mises–Fisher
    distribution on S²"): with t = 1 - cos θ and s = 1 - e^{-2κ} = -expm1(-2κ),

        p = κ / (2π s) · e^{-κ t},       t = -log1p(-u₀ s) / κ,       u₀ = -expm1(-κ t) / s.

    The textbook inverse CDF, log(e^{-κ} + 2u sinh κ)/κ, overflows near κ = 89 in float32 and
    cancels for tiny κ; these forms do neither: at κ = 1e-6, s ≈ 2κ and t ≈ 2u₀ (uniform sphere);
    at κ = 1e7, s = 1 and t = -log1p(-u₀)/κ. u₀ = 0 is the mode (+z). Near the antipode, reachable
    for small κ, 1 + cos θ is computed directly as log1p((1 - u₀) expm1(2κ)) / κ.

    """

    kappa: jax.Array = parameter(1e-6, 1e7, doc="the concentration κ")
    uniform_dims: ClassVar[int] = 2
    event_shape: ClassVar = (3,)
    periodic_dims: ClassVar = (1,)
    measure: ClassVar = "solid angle"

    def _s(self):
        return -jnp.expm1(-2.0 * self.kappa)

    def _log_normalizer(self):
        return jnp.log(self.kappa) - jnp.log(2.0 * np.pi * self._s())

    def _one_minus_cos(self, u0):
        return jnp.clip(-jnp.log1p(-u0 * self._s()) / self.kappa, 0.0, 2.0)

    def _one_plus_cos(self, u0):
        # 1 + cos θ = 2 - t cancels near the antipode, which small κ reaches; written directly it
        # is log1p((1 - u₀) expm1(2κ)) / κ. Only used where t > 1, which needs κ < ~37 even in
        # float64, so 2κ is capped at 80 to keep expm1 finite on the lanes that discard it.
        two_kappa = jnp.minimum(2.0 * self.kappa, 80.0)
        direct = jnp.clip(jnp.log1p((1.0 - u0) * jnp.expm1(two_kappa)) / self.kappa, 0.0, 2.0)
        t = self._one_minus_cos(u0)
        # Where t > 1, t itself is taken from the direct 1 + cos θ: log1p(-u₀ s) rounds the
        # product u₀ s near 1 (an error of 8e-4 in t at κ = 10, cos θ = -1/4, in float32), and a
        # t that disagrees with 1 + cos θ gives a direction off the sphere and a density not its own.
        far = t > 1.0
        return jnp.where(far, direct, 2.0 - t), jnp.where(far, 2.0 - direct, t)

    @point_method
    def warp(self, u):
        one_plus_cos, t = self._one_plus_cos(u[..., 0])
        return direction_from_one_minus_cos(t, u[..., 1], one_plus_cos)

    @point_method
    def warp_with_pdf(self, u):
        one_plus_cos, t = self._one_plus_cos(u[..., 0])
        x = direction_from_one_minus_cos(t, u[..., 1], one_plus_cos)
        return x, jnp.exp(self._log_normalizer() - self.kappa * t)

    @point_method
    def log_pdf(self, x):
        return self._log_normalizer() - self.kappa * one_minus_cos_theta(x)

    @point_method
    def pdf(self, x):
        return jnp.exp(self.log_pdf(x))

    @point_method
    def inverse(self, x):
        u0 = -jnp.expm1(-self.kappa * one_minus_cos_theta(x)) / self._s()
        return jnp.stack([u0, azimuth_fraction(x[..., 1], x[..., 0])], axis=-1)

    def domain(self):
        return Directions()
