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


def _log_cdf(z):
    """log F(z) = −softplus(−z), F the standard logistic CDF: finite for every finite z (log of the
    sigmoid underflows to −inf below z ≈ −88 in float32)."""
    return -jax.nn.softplus(-z)


class TrimmedLogistic(_OnInterval):
    """The logistic density of scale s restricted to [a, b] (length measure), 0 outside:

        p(x) = e^{−|x|/s} / (s (1 + e^{−|x|/s})²) / (F(b) − F(a)),  F(x) = 1/(1 + e^{−x/s}),

    s = `scale`, a = `low`, b = `high` (PBRT-v4 `TrimmedLogisticPDF`).

    Inversion (PBRT-v4 `SampleTrimmedLogistic`, rewritten for the tails): x = s · logit(v) with
    v = F(a) + u (F(b) − F(a)), computed in logarithms relative to the end nearer 0 so that an
    interval any number of scales into a tail neither underflows nor cancels. With z = x/s,
    ℓ = log F = −softplus(−z) and r = F(a)/F(b) = e^{ℓ(a) − ℓ(b)}: log v = ℓ(b) + log(r + u(1 − r)),
    z = log v − log1p(−v), the mass m = F(b)(1 − r) with 1 − r = −expm1(ℓ(a) − ℓ(b)), and the
    density e^{ℓ(z) + ℓ(−z) − log m}/s (the logistic density is F(z)(1 − F(z))/s). An interval whose
    centre lies right of 0 is drawn as the mirror image of (−b, −a) with 1 − u. Inverse:
    u = r expm1(ℓ(z) − ℓ(a)) / (1 − r), mirrored likewise.
    """

    scale: jax.Array = parameter(0.0, np.inf, low_open=True, high_open=True, doc="s")
    low: jax.Array = parameter(doc="a, finite")
    high: jax.Array = parameter(doc="b, finite, above a")

    def _ends(self):
        """(mirrored, z_a, z_b): the interval in units of s, mirrored (−b, −a) when its centre is
        right of 0, so that the formulas work from the end nearer 0 (`_left_*`)."""
        z_a, z_b = self.low / self.scale, self.high / self.scale
        mirrored = z_a + z_b > 0
        return mirrored, jnp.where(mirrored, -z_b, z_a), jnp.where(mirrored, -z_a, z_b)

    def _log_mass(self, z_a, z_b):
        return _log_cdf(z_b) + jnp.log(-jnp.expm1(_log_cdf(z_a) - _log_cdf(z_b)))

    def _log_density(self, x, log_mass):
        z = x / self.scale
        return _log_cdf(z) + _log_cdf(-z) - log_mass - jnp.log(self.scale)

    @point_method
    def warp(self, u):
        return self.warp_with_pdf(u)[0]

    @point_method
    def warp_with_pdf(self, u):
        mirrored, z_a, z_b = self._ends()
        u0 = jnp.where(mirrored, 1.0 - u[..., 0], u[..., 0])
        l_b = _log_cdf(z_b)
        ratio = jnp.exp(_log_cdf(z_a) - l_b)
        log_v = l_b + jnp.log(ratio + u0 * (1.0 - ratio))
        z = log_v - jnp.log1p(-jnp.exp(log_v))
        x = jnp.clip(self.scale * jnp.where(mirrored, -z, z), self.low, self.high)
        return x, jnp.exp(self._log_density(x, self._log_mass(z_a, z_b)))

    @point_method
    def pdf(self, x):
        inside = (x >= self.low) & (x <= self.high)
        _, z_a, z_b = self._ends()
        p = jnp.exp(self._log_density(x, self._log_mass(z_a, z_b)))
        return jnp.where(inside, p, 0.0).astype(jnp.result_type(x, float))

    @point_method
    def inverse(self, x):
        mirrored, z_a, z_b = self._ends()
        z = jnp.clip(x, self.low, self.high) / self.scale
        z = jnp.where(mirrored, -z, z)
        l_a, l_b = _log_cdf(z_a), _log_cdf(z_b)
        u = jnp.exp(l_a - l_b) * jnp.expm1(_log_cdf(z) - l_a) / -jnp.expm1(l_a - l_b)
        return jnp.clip(jnp.where(mirrored, 1.0 - u, u), 0.0, 1.0)[..., None]

    def domain(self):
        low, high = concrete_value(self.low), concrete_value(self.high)
        if low is None or high is None:
            raise ValueError("TrimmedLogistic.domain: needs concrete 'low' and 'high'")
        return Interval(float(low), float(high), breaks=(0.0,) if low < 0 < high else ())
