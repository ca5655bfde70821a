"""Exponential free-flight distances for participating media (length measure).

`Exponential(rate)` on [0, ∞) and `TruncatedExponential(rate, t_max)` on [0, t_max] (the distance
to the first interaction *given* one happens before t_max, e.g. before the medium ends). Both are
written with `log1p`/`expm1` so that they are exact at u -> 0, finite at u -> 1, and, for the
truncated one, keep the σ t_max -> 0 limit (a uniform distance) without cancellation.
"""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from .base import Sampler, point_method
from .._core.params import concrete_value
from .._core.pytree import parameter
from .domain import Interval


# Beyond 80 mean free paths the exponential has mass e^-80 < 1e-34: the quadrature stops there.
_TAIL_MEAN_FREE_PATHS = 80.0


def _expm1_ratio(z):
    """-expm1(-z)/z for z >= 0, = 1 at z = 0 (the truncated exponential's mass per unit σ t_max)."""
    tiny = z < 1e-30
    z_safe = jnp.where(tiny, 1.0, z)
    return jnp.where(tiny, 1.0, -jnp.expm1(-z_safe) / z_safe)


def _log1p_ratio(y):
    """log1p(y)/y for y > -1, = 1 at y = 0."""
    tiny = y == 0
    y_safe = jnp.where(tiny, 1.0, y)
    return jnp.where(tiny, 1.0, jnp.log1p(y_safe) / y_safe)


class Exponential(Sampler):
    """p(t) = σ e^{-σ t} on t >= 0 (length measure), 0 for t < 0; σ = `rate`.

    Inversion (PBRT-v4 `SampleExponential`, with log1p): the CDF is 1 - e^{-σt}, so
    t = -log1p(-u)/σ. log1p keeps full relative precision at u -> 0 (where log(1 - u) rounds 1 - u
    to 1 and returns 0 for every u below an ulp), and is finite for u < 1 (t <= 16.6/σ in float32).
    The density from u is σ(1 - u), exactly; the inverse is u = -expm1(-σt).

    In float32 a rate below about 1e-37 gives distances beyond float range.
    """

    rate: jax.Array = parameter(0.0, np.inf, low_open=True, high_open=True, doc="σ", hard_cases=(1e-6, 1e6))
    uniform_dims: ClassVar[int] = 1
    event_shape: ClassVar = ()
    measure: ClassVar = "length"

    @point_method
    def warp(self, u):
        return -jnp.log1p(-u[..., 0]) / self.rate

    @point_method
    def warp_with_pdf(self, u):
        u0 = u[..., 0]
        return -jnp.log1p(-u0) / self.rate, self.rate * (1.0 - u0)

    @point_method
    def log_pdf(self, t):
        inside = t >= 0
        return jnp.where(inside, jnp.log(self.rate) - self.rate * jnp.where(inside, t, 0.0), -jnp.inf)

    @point_method
    def pdf(self, t):
        return jnp.exp(self.log_pdf(t))

    @point_method
    def inverse(self, t):
        return (-jnp.expm1(-self.rate * jnp.maximum(t, 0.0)))[..., None]

    def domain(self):
        rate = concrete_value(self.rate)
        if rate is None:
            raise ValueError("Exponential.domain: needs a concrete 'rate'")
        return Interval(0.0, np.inf, quadrature_high=_TAIL_MEAN_FREE_PATHS / float(rate))


class TruncatedExponential(Sampler):
    """p(t) = σ e^{-σ t} / (1 - e^{-σ T}) on [0, T] (length measure), 0 outside; T = `t_max`.

    Inversion (PBRT-v4 `SampleTrimmedExponential`, rewritten): with z = σT and the mass
    m = 1 - e^{-z} = -expm1(-z), t = -log1p(-u m)/σ. Written as t = T · u · g(z) · L(-u z g(z)) with
    g(z) = -expm1(-z)/z and L(y) = log1p(y)/y, every factor is O(1) and exact for any z: at z -> 0
    (thin media, small σ) g and L tend to 1 and t -> uT (uniform), where the textbook form divides
    two vanishing numbers, 1 - e^{-σT} cancelling first. The density is e^{-σt} / (T g(z)) and the
    inverse u = (t/T) g(σt)/g(σT).

    σ is tested from 1e-6 to 1e6. The formulas tend to the uniform density on [0, T] as σ -> 0; σ = 0 itself is
    outside the range (traced, it makes every value NaN, as any invalid parameter does).
    """

    rate: jax.Array = parameter(0.0, np.inf, low_open=True, high_open=True, doc="σ", hard_cases=(1e-6, 1e6))
    t_max: jax.Array = parameter(0.0, np.inf, low_open=True, high_open=True, doc="T")
    uniform_dims: ClassVar[int] = 1
    event_shape: ClassVar = ()
    measure: ClassVar = "length"

    def _mass_ratio(self):
        return _expm1_ratio(self.rate * self.t_max)

    @point_method
    def warp(self, u):
        u0 = u[..., 0]
        g = self._mass_ratio()
        t = self.t_max * u0 * g * _log1p_ratio(-u0 * (self.rate * self.t_max) * g)
        return jnp.clip(t, 0.0, self.t_max)

    @point_method
    def warp_with_pdf(self, u):
        t = self.warp(u)
        return t, self.pdf(t)

    @point_method
    def log_pdf(self, t):
        inside = (t >= 0) & (t <= self.t_max)
        t_safe = jnp.where(inside, t, 0.0)
        return jnp.where(inside, -self.rate * t_safe - jnp.log(self.t_max * self._mass_ratio()), -jnp.inf)

    @point_method
    def pdf(self, t):
        return jnp.exp(self.log_pdf(t))

    @point_method
    def inverse(self, t):
        t = jnp.clip(t, 0.0, self.t_max)
        u = (t / self.t_max) * _expm1_ratio(self.rate * t) / self._mass_ratio()
        return jnp.clip(u, 0.0, 1.0)[..., None]

    def domain(self):
        t_max = concrete_value(self.t_max)
        if t_max is None:
            raise ValueError("TruncatedExponential.domain: needs a concrete 't_max'")
        return Interval(0.0, float(t_max))
