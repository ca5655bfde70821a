"""Two smooth 1-D densities of PBRT-v4's sampling library, over length: the smooth step and the
trimmed logistic.

`SmoothStep(low, high)` rises as Hermite's smoothstep 3t² − 2t³ over [low, high] (PBRT-v4
`SmoothStepPDF`/`SampleSmoothStep`, used to fade a light's falloff); `TrimmedLogistic(scale, low,
high)` is the logistic density restricted to [low, high] (PBRT-v4 `TrimmedLogisticPDF`/
`SampleTrimmedLogistic`, the azimuthal lobe of its hair BSDF). Both intervals need low < high.
"""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from .._core.params import concrete_value
from .._core.pytree import parameter
from .base import Sampler, point_method
from .domain import Interval

# Newton steps of the smooth step's inversion: each side's equation is convex or concave and
# monotone on its half, so the iterates approach the root from one side, quadratically from a
# start within 10 % (float64 is exact to rounding after 5).
_NEWTON_STEPS = 6


def _check_interval(owner: str, low, high) -> None:
    low, high = concrete_value(low), concrete_value(high)
    if low is None or high is None:
        return
    if not (np.all(np.isfinite(low)) and np.all(np.isfinite(high)) and np.all(low < high)):
        raise ValueError(f"{owner}: parameters 'low' and 'high' must be finite with low < high; got {low} and {high}")


def _interval_valid(declared, low, high):
    """The declared ranges (None: nothing declared) and the rule no range states: a finite low < high."""
    valid = jnp.isfinite(low) & jnp.isfinite(high) & (low < high)
    return valid if declared is None else declared & valid


class _OnInterval(Sampler):
    """What the two densities share: a finite interval [low, high] with low < high, checked when
    concrete and poisoning the outputs when traced, and the log-density from the density."""

    uniform_dims: ClassVar[int] = 1
    event_shape: ClassVar = ()
    measure: ClassVar = "length"

    def __post_init__(self):
        _check_interval(type(self).__name__, self.low, self.high)

    def _parameters_valid(self):
        return _interval_valid(super()._parameters_valid(), self.low, self.high)

    @point_method
    def log_pdf(self, x):
        p = self.pdf(x)
        return jnp.where(p > 0, jnp.log(jnp.where(p > 0, p, 1.0)), -jnp.inf)


@jax.custom_jvp
def _smooth_step_t(u):
    """(t, 1 − t) for t in [0, 1] with C(t) = 2t³ − t⁴ = u, the smooth step's CDF on [0, 1]. Below
    u = 1/2 by Newton on C(t) = u from t = (u/2)^(1/3); above, on 1 − C(1 − s) = 2s − 2s³ + s⁴ = 1 − u
    for s = 1 − t from s = (1 − u)/2, so that u -> 1 keeps s to full relative precision. The
    derivative of t is 1/C'(t) (implicit function), 0 at t = 0 where C' = 0 (as `safe_sqrt`'s at 0)."""
    low_side = u < 0.5
    w = 1.0 - u
    t = jnp.cbrt(0.5 * u)
    s = 0.5 * w
    for _ in range(_NEWTON_STEPS):
        t = t - (t * t * t * (2.0 - t) - u) / jnp.maximum(t * t * (6.0 - 4.0 * t), 1e-30)
        s = s - (s * (2.0 - s * s * (2.0 - s)) - w) / (2.0 - s * s * (6.0 - 4.0 * s))
    t, s = jnp.clip(t, 0.0, 1.0), jnp.clip(s, 0.0, 1.0)
    return jnp.where(low_side, t, 1.0 - s), jnp.where(low_side, 1.0 - t, s)


@_smooth_step_t.defjvp
def _smooth_step_t_jvp(primals, tangents):
    (u,), (du,) = primals, tangents
    t, s = _smooth_step_t(u)
    slope = t * t * (6.0 - 4.0 * t)
    positive = slope > 0
    dt = jnp.where(positive, du / jnp.where(positive, slope, 1.0), 0.0)
    return (t, s), (dt, -dt)


class SmoothStep(_OnInterval):
    """p(x) = 2/(b − a) · S(t), S(t) = 3t² − 2t³, t = (x − a)/(b − a), on [a, b] (length measure);
    0 outside; a = `low`, b = `high` (PBRT-v4 `SmoothStepPDF`; ∫₀¹ S = 1/2).

    Inversion: the CDF is C(t) = 2t³ − t⁴, inverted by Newton's method on whichever side of
    u = 1/2 the uniform falls (see `_smooth_step_t`), then x = a + (b − a) t below t = 1/2 and
    b − (b − a)(1 − t) above; t does not depend on the parameters, so the derivatives in a and b
    are exact. Inverse: u = t³(2 − t).
    """

    low: jax.Array = parameter(doc="a, the start of the rise, finite")
    high: jax.Array = parameter(doc="b, where the step reaches 1, finite, above a")

    def _density(self, t):
        return 2.0 * t * t * (3.0 - 2.0 * t) / (self.high - self.low)

    def _map(self, u0):
        t, s = _smooth_step_t(u0)
        # From the nearer end, so that x next to b is b − s(b − a) with s to full precision.
        width = self.high - self.low
        return jnp.where(t < 0.5, self.low + t * width, self.high - s * width), self._density(t)

    @point_method
    def warp(self, u):
        return self._map(u[..., 0])[0]

    @point_method
    def warp_with_pdf(self, u):
        return self._map(u[..., 0])

    @point_method
    def pdf(self, x):
        inside = (x >= self.low) & (x <= self.high)
        t = jnp.clip((x - self.low) / (self.high - self.low), 0.0, 1.0)
        return jnp.where(inside, self._density(t), 0.0).astype(jnp.result_type(x, float))

    @point_method
    def inverse(self, x):
        t = jnp.clip((x - self.low) / (self.high - self.low), 0.0, 1.0)
        return (t * t * t * (2.0 - t))[..., None]

    def domain(self):
        low, high = concrete_value(self.low), concrete_value(self.high)
        if low is None or high is None:
            raise ValueError("SmoothStep.domain: needs concrete 'low' and 'high'")
        return Interval(float(low), float(high))


def _logistic_density(x, s):
    """e^{−|x|/s} / (s (1 + e^{−|x|/s})²), the logistic density, in a form that never overflows."""
    e = jnp.exp(-jnp.abs(x) / s)
    return e / (s * (1.0 + e) ** 2)


class TrimmedLogistic(_OnInterval):
    """The logistic density of scale s restricted to [a, b] (length measure), 0 outside:

        p(x) = e^{−|x|/s} / (s (1 + e^{−|x|/s})²) / (F(b) − F(a)),  F(x) = 1/(1 + e^{−x/s}),

    s = `scale`, a = `low`, b = `high` (PBRT-v4 `TrimmedLogisticPDF`).

    Inversion (PBRT-v4 `SampleTrimmedLogistic`, rewritten for the tails): x = s · logit(v) with
    v = F(a) + u (F(b) − F(a)), as x = s (log v − log(1 − v)) where v and 1 − v = G(a) − u m
    (G = 1 − F, computed as F of −x) are each formed without cancelling; the mass m is G(a) − G(b)
    when the interval lies right of 0 and F(b) − F(a) otherwise, so that an interval deep in a tail
    keeps its relative precision. Inverse: u = (F(x) − F(a))/m, in the same form.
    """

    scale: jax.Array = parameter(0.0, np.inf, low_open=True, high_open=True, doc="s")
    low: jax.Array = parameter(doc="a, finite")
    high: jax.Array = parameter(doc="b, finite, above a")

    def _cdfs(self):
        """(F(a), G(a), m)."""
        s = self.scale
        f_a, g_a = jax.nn.sigmoid(self.low / s), jax.nn.sigmoid(-self.low / s)
        f_b, g_b = jax.nn.sigmoid(self.high / s), jax.nn.sigmoid(-self.high / s)
        return f_a, g_a, jnp.where(self.low >= 0, g_a - g_b, f_b - f_a)

    @point_method
    def warp(self, u):
        return self.warp_with_pdf(u)[0]

    @point_method
    def warp_with_pdf(self, u):
        f_a, g_a, mass = self._cdfs()
        v, one_minus_v = f_a + u[..., 0] * mass, g_a - u[..., 0] * mass
        x = jnp.clip(self.scale * (jnp.log(v) - jnp.log(one_minus_v)), self.low, self.high)
        return x, _logistic_density(x, self.scale) / mass

    @point_method
    def pdf(self, x):
        inside = (x >= self.low) & (x <= self.high)
        p = _logistic_density(x, self.scale) / self._cdfs()[2]
        return jnp.where(inside, p, 0.0).astype(jnp.result_type(x, float))

    @point_method
    def inverse(self, x):
        f_a, g_a, mass = self._cdfs()
        x = jnp.clip(x, self.low, self.high)
        right = self.low >= 0
        above = jnp.where(right, g_a - jax.nn.sigmoid(-x / self.scale), jax.nn.sigmoid(x / self.scale) - f_a)
        return jnp.clip(above / mass, 0.0, 1.0)[..., None]

    def domain(self):
        low, high = concrete_value(self.low), concrete_value(self.high)
        if low is None or high is None:
            raise ValueError("TrimmedLogistic.domain: needs concrete 'low' and 'high'")
        return Interval(float(low), float(high), breaks=(0.0,) if low < 0 < high else ())
