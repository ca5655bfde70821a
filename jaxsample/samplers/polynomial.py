"""Low-order polynomial densities, each by inversion: `Tent` on [-r, r], `Linear` on [0, 1] and
`Bilinear` on [0, 1]² (lengths and area); PBRT-v4 `util/sampling.h` (`SampleTent`,
`SampleLinear`, `SampleBilinear`) has the same three."""

from __future__ import annotations

import functools
from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from .base import Sampler, point_method
from .._core.params import concrete_value
from .._core.pytree import parameter
from .domain import Box, Interval
from .._core.numerics import safe_log, safe_sqrt


# ---------------------------------------------------------------------------------------------
# The linear density on [0, 1], shared by Linear and Bilinear. With weights a (at 0) and b (at 1),
# p(x) = 2((1 - x) a + x b)/(a + b) and F(x) = x((2 - x) a + x b)/(a + b).
# ---------------------------------------------------------------------------------------------


def _normalised(a, b):
    """(a, b) divided by max(a, b), so that squares neither overflow nor underflow; (1, 1) (the
    uniform density) where both are 0, a row of zero density that is never sampled (Bilinear).
    Every formula below is homogeneous of degree 0 in (a, b), so the scale drops out exactly."""
    m = jnp.maximum(a, b)
    positive = m > 0
    m_safe = jnp.where(positive, m, 1.0)
    return jnp.where(positive, a / m_safe, 1.0), jnp.where(positive, b / m_safe, 1.0)


def linear_quantile(u, a, b):
    """x with F(x) = u for the density ∝ (1 - x) a + x b on [0, 1], and p(x) (from u).

    F(x) = u is the quadratic (b - a) x² + 2a x - (a + b) u = 0. Its textbook root
    x = (√(a² + (b² - a²) u) - a)/(b - a) is 0/0 at a = b and cancels as a -> b; multiplied
    through by the conjugate it is x = (a + b) u / (a + √((1 - u) a² + u b²)) (the form of
    PBRT-v4 `SampleLinear`), in which every operation adds same-signed terms: exact at a = b
    (x = u), at a = 0 (x = √u) and at b = 0 (x = u/(1 + √(1 - u)), where 1 - √(1 - u) would
    cancel). The square root is the density's own weight at x, (1 - x) a + x b, so the density
    from u is 2√(...)/(a + b). The one 0/0, a = 0 and u = 0, is x = 0.
    """
    a, b = _normalised(a, b)
    weight = safe_sqrt((1.0 - u) * a * a + u * b * b)
    denominator = a + weight
    nonzero = denominator > 0
    x = jnp.where(nonzero, (a + b) * u / jnp.where(nonzero, denominator, 1.0), 0.0)
    return jnp.clip(x, 0.0, 1.0), 2.0 * weight / (a + b)


def linear_density(x, a, b):
    """p(x) = 2((1 - x) a + x b)/(a + b) on [0, 1] (x is taken inside; the caller masks outside)."""
    a, b = _normalised(a, b)
    return 2.0 * ((1.0 - x) * a + x * b) / (a + b)


def linear_cdf(x, a, b):
    """F(x) = x((2 - x) a + x b)/(a + b) for x in [0, 1]: a sum of same-signed terms."""
    a, b = _normalised(a, b)
    x = jnp.clip(x, 0.0, 1.0)
    return jnp.clip(x * ((2.0 - x) * a + x * b) / (a + b), 0.0, 1.0)


def _in_unit(x):
    return (x >= 0) & (x <= 1)


def _all_of(*checks):
    """The conjunction of validity checks: a NumPy bool when all are concrete, a JAX one otherwise."""
    if all(isinstance(c, (bool, np.bool_)) for c in checks):
        return np.bool_(all(bool(c) for c in checks))
    return functools.reduce(jnp.logical_and, [jnp.asarray(c) for c in checks])


# ---------------------------------------------------------------------------------------------


class Tent(Sampler):
    """The tent (triangle) density p(x) = (1 - |x|/r)/r on [-r, r], over length; 0 outside;
    r = `radius`. The sum of two independent uniforms on [-r/2, r/2] has it; here it is sampled
    by inversion, one uniform per sample (PBRT-v4 `SampleTent` draws the side from u and a
    `SampleLinear` within it; the same map, in closed form).

    With w = min(u, 1 - u) (the mass beyond x on its side, exact: 1 - u is exact for u >= 1/2),
    |x| = r(1 - √(2w)), written x = r(2u - 1)/(1 + √(2w)) so that it does not cancel near the
    peak (u -> 1/2, where 2u - 1 is exact); u = 0 gives -r, u -> 1 gives r(1 - 2^-11.5). The
    density from u is exactly √(2w)/r (0 at u = 0, where x = -r is the support's closed end).
    Inverse: with t = 1 - |x|/r, u = t²/2 for x < 0 and 1 - t²/2 for x >= 0.
    """

    radius: jax.Array = parameter(0.0, np.inf, low_open=True, high_open=True, doc="the half-width r",
                                  hard_cases=(1e-6, 1.0, 1e6))
    uniform_dims: ClassVar[int] = 1
    event_shape: ClassVar = ()
    measure: ClassVar = "length"

    def _map(self, u0):
        w = safe_sqrt(2.0 * jnp.minimum(u0, 1.0 - u0))
        return self.radius * (2.0 * u0 - 1.0) / (1.0 + w), w / self.radius

    @point_method
    def warp(self, u):
        return self._map(u[..., 0])[0]

    @point_method
    def warp_with_pdf(self, u):
        return self._map(u[..., 0])

    @point_method
    def pdf(self, x):
        # r - |x| is exact near the ends (Sterbenz), where 1 - |x|/r would round first.
        t = (self.radius - jnp.abs(x)) / self.radius
        return jnp.where(t >= 0, t / self.radius, 0.0).astype(jnp.result_type(x, float))

    @point_method
    def log_pdf(self, x):
        return safe_log(self.pdf(x))

    @point_method
    def inverse(self, x):
        t = jnp.clip((self.radius - jnp.abs(x)) / self.radius, 0.0, 1.0)
        half_square = 0.5 * t * t
        return jnp.where(x < 0, half_square, 1.0 - half_square)[..., None]

    def domain(self):
        r = concrete_value(self.radius)
        if r is None:
            raise ValueError("Tent.domain: needs a concrete 'radius'")
        return Interval(-float(r), float(r), breaks=(0.0,))


class Linear(Sampler):
    """The linear density on [0, 1]: p(x) = 2((1 - x) a + x b)/(a + b), over length; 0 outside.
    a is the (unnormalised) weight at x = 0, b at x = 1; a, b >= 0, not both 0.

    Inversion in the stable form of the quadratic's root (`linear_quantile`; PBRT-v4
    `SampleLinear`): x = (a + b) u / (a + √((1 - u) a² + u b²)), exact as a -> b (x -> u) and
    when either weight is 0; the density from u is 2√((1 - u) a² + u b²)/(a + b). The weights
    are divided by max(a, b) first (the density depends only on their ratio), so any finite
    weights work. Inverse: u = x((2 - x) a + x b)/(a + b). Where a weight is 0 the density is 0
    at that end (u = 0 gives x = 0 when a = 0).
    """

    a: jax.Array = parameter(0.0, np.inf, high_open=True, doc="the weight at x = 0 (a and b not both 0)",
                             hard_cases=(0.0, 1e-6, 1.0, 1e6))
    b: jax.Array = parameter(0.0, np.inf, high_open=True, doc="the weight at x = 1 (a and b not both 0)",
                             hard_cases=(0.0, 1e-6, 1.0, 1e6))
    uniform_dims: ClassVar[int] = 1
    event_shape: ClassVar = ()
    measure: ClassVar = "length"

    def __post_init__(self):
        a, b = concrete_value(self.a), concrete_value(self.b)
        if (a is not None and b is not None
                and np.any(np.broadcast_to(a + b, np.broadcast_shapes(a.shape, b.shape)) <= 0)):
            raise ValueError("Linear: parameters 'a' and 'b' must not both be 0 (the density would be 0 everywhere)")

    def _parameters_valid(self):
        a, b = concrete_value(self.a), concrete_value(self.b)
        positive = np.all(a + b > 0) if a is not None and b is not None else jnp.all(
            jnp.asarray(self.a) + jnp.asarray(self.b) > 0)
        return _all_of(super()._parameters_valid(), positive)

    @point_method
    def warp(self, u):
        return linear_quantile(u[..., 0], self.a, self.b)[0]

    @point_method
    def warp_with_pdf(self, u):
        return linear_quantile(u[..., 0], self.a, self.b)

    @point_method
    def pdf(self, x):
        inside = _in_unit(x)
        density = linear_density(jnp.where(inside, x, 0.5), self.a, self.b)
        return jnp.where(inside, density, 0.0).astype(jnp.result_type(x, float))

    @point_method
    def log_pdf(self, x):
        return safe_log(self.pdf(x))

    @point_method
    def inverse(self, x):
        return linear_cdf(x, self.a, self.b)[..., None]

    def domain(self):
        return Interval(0.0, 1.0)


class Bilinear(Sampler):
    """The bilinear density on [0, 1]², over area; 0 outside:

        p(x, y) = 4 ((1-x)(1-y) w₀₀ + x(1-y) w₁₀ + (1-x) y w₀₁ + x y w₁₁) / (w₀₀ + w₁₀ + w₀₁ + w₁₁),

    w = (w₀₀, w₁₀, w₀₁, w₁₁) the corner weights, w_ij at (x, y) = (i, j) (PBRT-v4's order): every
    entry >= 0, not all 0.

    Marginal, then conditional (PBRT-v4 `SampleBilinear`): integrating out x leaves the linear
    density in y with end weights w₀₀ + w₁₀ and w₀₁ + w₁₁, sampled from u₁; given y, x has the
    linear density with end weights (1-y) w₀₀ + y w₀₁ and (1-y) w₁₀ + y w₁₁, sampled from u₀.
    Each step is `Linear`'s stable inversion, and the density is the product of the two steps'
    densities from u. Inverse: u₁ = F_y(y), u₀ = F_x(x | y). Where an edge's weights are both 0
    the density is 0 along it; a row of zero density at y = 0 (u₁ = 0) is given uniform x.
    """

    w: jax.Array = parameter(rank=1, doc="the corner weights (w00, w10, w01, w11), each >= 0, not all 0")
    uniform_dims: ClassVar[int] = 2
    event_shape: ClassVar = (2,)
    measure: ClassVar = "area"

    def __post_init__(self):
        w = concrete_value(self.w)
        if w is None:
            return
        if w.ndim < 1 or w.shape[-1] != 4:
            raise ValueError(f"Bilinear: parameter 'w' must have shape (..., 4) (w00, w10, w01, w11); got {w.shape}")
        if not np.all(np.isfinite(w)) or np.any(w < 0):
            raise ValueError("Bilinear: parameter 'w' must have every entry in [0, inf) (finite, no NaN)")
        if np.any(np.sum(w, axis=-1) <= 0):
            raise ValueError("Bilinear: parameter 'w' must not be all 0 (the density would be 0 everywhere)")

    def _parameters_valid(self):
        w = concrete_value(self.w)
        if w is not None:
            return np.bool_(np.all(np.isfinite(w) & (w >= 0)) and np.all(np.sum(w, axis=-1) > 0))
        w = jnp.asarray(self.w)
        return jnp.all(jnp.isfinite(w) & (w >= 0)) & jnp.all(jnp.sum(w, axis=-1) > 0)

    def _corners(self):
        w = jnp.asarray(self.w)
        return w[..., 0], w[..., 1], w[..., 2], w[..., 3]

    def _conditional(self, y):
        w00, w10, w01, w11 = self._corners()
        return (1.0 - y) * w00 + y * w01, (1.0 - y) * w10 + y * w11

    @point_method
    def warp(self, u):
        return self.warp_with_pdf(u)[0]

    @point_method
    def warp_with_pdf(self, u):
        w00, w10, w01, w11 = self._corners()
        y, p_y = linear_quantile(u[..., 1], w00 + w10, w01 + w11)
        x, p_x = linear_quantile(u[..., 0], *self._conditional(y))
        return jnp.stack([x, y], axis=-1), p_x * p_y

    @point_method
    def pdf(self, x):
        inside = _in_unit(x[..., 0]) & _in_unit(x[..., 1])
        s, t = x[..., 0], x[..., 1]
        w00, w10, w01, w11 = self._corners()
        # Each weight over the total: the density has no overflow for any finite weights.
        total = w00 + w10 + w01 + w11
        bilerp = ((1.0 - s) * (1.0 - t) * (w00 / total) + s * (1.0 - t) * (w10 / total)
                  + (1.0 - s) * t * (w01 / total) + s * t * (w11 / total))
        return jnp.where(inside, 4.0 * bilerp, 0.0).astype(jnp.result_type(x, float))

    @point_method
    def log_pdf(self, x):
        return safe_log(self.pdf(x))

    @point_method
    def inverse(self, x):
        w00, w10, w01, w11 = self._corners()
        y = jnp.clip(x[..., 1], 0.0, 1.0)
        u1 = linear_cdf(y, w00 + w10, w01 + w11)
        u0 = linear_cdf(x[..., 0], *self._conditional(y))
        return jnp.stack([u0, u1], axis=-1)

    def domain(self):
        return Box.from_bounds([0.0, 0.0], [1.0, 1.0])
