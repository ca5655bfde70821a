"""The Phong (power-cosine) lobe p_n(ω) = (n + 1)/(2π) cos^n θ over solid angle, z >= 0."""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp

from .base import Sampler, point_method
from .._core.pytree import parameter
from .domain import Directions
from .._core.numerics import (INV_2PI, azimuth_fraction, direction_from_one_minus_cos,
    one_minus_cos_theta, one_minus_epsilon)


class PhongLobe(Sampler):
    """cos^n lobe about +z: p(ω) = (n + 1)/(2π) cos^n θ over solid angle on z >= 0, 0 below.

    Inversion (Chuang, *Monte Carlo Integration*; docs/reference.md): the marginal CDF of μ = cos θ is
    μ^{n+1}, so μ = ξ^{1/(n+1)} with ξ uniform; we use ξ = 1 - u₀, so that u₀ = 0 is the pole and
    u₀ -> 1 the horizon, and log ξ = log1p(-u₀) stays finite on [0, 1).

    Stability for n up to 1e7 in float32: μ itself rounds to 1 near the pole, so the warp carries
    1 - μ = -expm1(log ξ/(n+1)) and builds sin² θ = (1 - μ)(1 + μ) from it; the density uses
    log μ = log1p(-(1 - μ)) with 1 - μ taken from x and y (`one_minus_cos_theta`), never from z.

    The tail: `inverse` returns u₀ = 1 - μ^{n+1}, which rounds to exactly 1 once μ^{n+1} < 2^-25
    (a direction far outside the lobe, or at or below its horizon), and the warp maps u₀ = 1 to the
    horizon, μ = 0 for every n, with derivative 0 (`_one_minus_cos_from_u`). What u cannot carry is
    how a tail direction moves with n at fixed ξ = 1 - u₀; `flow` computes that from
    log ξ = (n+1) log μ, without the round trip through u.
    """

    exponent: jax.Array = parameter(0.0, 1e7, doc="the exponent n")
    uniform_dims: ClassVar[int] = 2
    event_shape: ClassVar = (3,)
    periodic_dims: ClassVar = (1,)

    measure: ClassVar = "solid angle"

    def _log_cos_from_u(self, u0):
        return jnp.log1p(-u0) / (self.exponent + 1.0)

    def _one_minus_cos_from_u(self, u0):
        """1 - μ = -expm1(log ξ/(n + 1)), and exactly 1 (the horizon, for every n) at u₀ = 1.

        u₀ = 1 is ξ = 0, which `inverse` returns for the tail; there log ξ = -inf, the quotient's
        derivative in n is -log ξ/(n + 1)² = +inf, and expm1's derivative exp(log μ) = 0 multiplies
        it (0 · inf = NaN, forward and reverse). The horizon does not move with n (μ = 0^{1/(n+1)}),
        so its derivative is 0: a double where keeps u₀ = 1 out of the logarithm.
        """
        horizon = u0 >= 1.0
        log_cos = self._log_cos_from_u(jnp.where(horizon, 0.0, u0))
        return jnp.where(horizon, 1.0, -jnp.expm1(log_cos))

    def _log_cos_of(self, x):
        """(z > 0, log μ) of directions x: log1p(-(1 - μ)) near the pole (z rounds to 1 there), log z
        toward the horizon (where a vector a few ulps off unit length could push 1 - μ past 1); log μ is a
        placeholder 0 where z <= 0."""
        upper = x[..., 2] > 0
        z_safe = jnp.where(upper, x[..., 2], 1.0)
        t = jnp.where(upper, one_minus_cos_theta(x), 0.5)
        return upper, jnp.where(t < 0.5, jnp.log1p(-jnp.minimum(t, 0.5)), jnp.log(z_safe))

    @point_method
    def warp(self, u):
        return direction_from_one_minus_cos(self._one_minus_cos_from_u(u[..., 0]), u[..., 1])

    @point_method
    def warp_with_pdf(self, u):
        log_cos = self._log_cos_from_u(u[..., 0])
        x = direction_from_one_minus_cos(-jnp.expm1(log_cos), u[..., 1])
        n = self.exponent
        return x, (n + 1.0) * INV_2PI * jnp.exp(n * log_cos)

    @point_method(batched=False)
    def measure_valued_pair(self, u):
        """(x, x', c) for the measure-valued derivative in the exponent, from u (..., 3).

        With μ = cos θ, the density of μ is m μ^n on [0, 1] (m = n + 1), and
        d/dn (m μ^n) = (1/m) (m μ^n - m² μ^n (-ln μ)); the second density is that of the product
        of two independent draws of μ (Mohamed et al. 2020, section 6; docs/reference.md). So
        d/dn E[g] = c (E[g(x)] - E[g(x')]) with c = 1/m, x ~ p_n and x' with cos θ' = μ₁ μ₂ and a
        uniform azimuth. x' reuses x's draw μ₁ = μ and azimuth (a coupling: the difference has
        far less variance than two independent terms) and takes μ₂ from u₂. log μ' = log μ₁ +
        log μ₂, so 1 - μ' = -expm1(log μ') keeps full precision near the pole.
        """
        log_cos = self._log_cos_from_u(u[..., 0])
        log_cos_product = log_cos + self._log_cos_from_u(u[..., 2])
        x = direction_from_one_minus_cos(-jnp.expm1(log_cos), u[..., 1])
        x_product = direction_from_one_minus_cos(-jnp.expm1(log_cos_product), u[..., 1])
        return x, x_product, 1.0 / (self.exponent + 1.0)

    def measure_valued_terms(self, u):
        """(n, x, x', 1/(n + 1)): the measure-valued decomposition in the exponent n
        (`measure_valued_pair`), for `gradient="measure_valued"`."""
        return (self.exponent, *self.measure_valued_pair(u))

    @point_method
    def log_pdf(self, x):
        n = self.exponent
        upper, log_cos = self._log_cos_of(x)
        inside = jnp.log1p(n) - jnp.log(2.0 * jnp.pi) + n * log_cos
        # At the horizon (z = 0) the density is (n+1)/2π for n = 0 and 0 for n > 0.
        horizon = jnp.where(n == 0, jnp.log1p(n) - jnp.log(2.0 * jnp.pi), -jnp.inf)
        return jnp.where(upper, inside, jnp.where(x[..., 2] == 0, horizon, -jnp.inf))

    @point_method
    def pdf(self, x):
        return jnp.exp(self.log_pdf(x))

    @point_method
    def inverse(self, x):
        # u₀ = 1 - μ^{n+1} = -expm1((n+1) log μ), with log μ from the accurate 1 - μ.
        t = jnp.clip(one_minus_cos_theta(x), 0.0, 1.0)
        # t = 1 (the horizon) maps to u₀ = 1; clamp one ulp short so log1p stays finite.
        log_cos = jnp.log1p(-jnp.minimum(t, one_minus_epsilon(t.dtype)))
        u0 = -jnp.expm1((self.exponent + 1.0) * log_cos)
        return jnp.stack([u0, azimuth_fraction(x[..., 1], x[..., 0])], axis=-1)

    @point_method
    def flow(self, x):
        """warp(inverse(x)) with the uniforms held, moving with n, computed without u: what is held
        is log ξ = log(1 - u₀) = (n + 1) log μ, and the azimuth.

        So the sample through x moves as log μ = log ξ/(n + 1), d log μ/dn = -log μ/(n + 1), wherever
        μ > 0, the tail included, where u₀ rounds to 1 and warp(inverse(x)) sits still at the
        horizon. Directions at or below the horizon (μ <= 0: ξ = 0, no samples) do not move.
        """
        x = jax.lax.stop_gradient(x)
        upper, log_cos = self._log_cos_of(x)
        log_xi = jax.lax.stop_gradient((self.exponent + 1.0) * log_cos)
        moved = direction_from_one_minus_cos(-jnp.expm1(log_xi / (self.exponent + 1.0)),
                                             azimuth_fraction(x[..., 1], x[..., 0]))
        return jnp.where(upper[..., None], moved, x)

    def domain(self):
        return Directions(breaks=(1.0,))
