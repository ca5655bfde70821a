"""Gaussians: `Normal` on the real line (length measure) and `Normal2D` on the plane (area measure)."""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np
from jax.scipy.special import ndtr, ndtri

from .base import Sampler, point_method
from .._core.params import as_parameter, check_number, check_parameter, concrete_value, in_range
from .._core.pytree import parameter
from .domain import Box, Interval
from .._core.numerics import azimuth_fraction, one_minus_epsilon, safe_sqrt, sincos_2pi

_LOG_SQRT_2PI = float(0.5 * np.log(2.0 * np.pi))
_LOG_2PI = float(np.log(2.0 * np.pi))
# The checks' quadrature covers loc ± 12σ (the mass beyond is 2e-33 on each side) in panels of σ/2.
_QUADRATURE_SIGMAS = 12.0
_PANELS_PER_SIGMA = 2


def _axis(loc: float, scale: float) -> Interval:
    """The real line with the checks' rule for a Gaussian of this location and scale."""
    breaks = loc + scale * np.arange(-_QUADRATURE_SIGMAS, _QUADRATURE_SIGMAS + 1e-9, 1.0 / _PANELS_PER_SIGMA)
    return Interval(-np.inf, np.inf, breaks=tuple(float(b) for b in breaks), graded=False,
                    quadrature_low=float(breaks[0]), quadrature_high=float(breaks[-1]))


class Normal(Sampler):
    """The normal distribution on the real line: p(x) = exp(-z²/2) / (σ √(2π)), z = (x - μ)/σ,
    over length; μ = `loc`, σ = `scale`.

    Inversion: x = μ + σ Φ⁻¹(u), Φ the standard normal CDF (the map of PBRT-v4's `SampleNormal`,
    μ + σ√2 erf⁻¹(2u - 1)). Φ⁻¹ is `jax.scipy.special.ndtri` (Cephes' rational approximations,
    in √(-2 log u) in the tails), not erf⁻¹(2u - 1): forming 2u - 1 rounds away the lower tail
    (in float32 its error is 2^-25 absolute, 0.8 % of the quantile at u = 7e-8, and every u below
    2^-25 gives -inf), while ndtri takes u itself, and 1 - u (exact for u >= 1/2) at the top:
    3e-7 relative over [2^-24, 1 - 2^-24] in float32 (the tests check 1e-6).

    u is clamped to [ε, 1 - ε], 1 - ε the largest float below 1 (ε = 2^-24 in float32, 2^-53
    in float64): u = 0, whose quantile is -inf, maps to μ - 5.33σ in float32 (μ - 8.21σ in
    float64), the mirror image of u = 1 - ε. The library's uniform sources never go below ε in
    float32 (their smallest point is 2^-24) nor in float64 (2^-33), so this changes no sample
    they produce; it keeps 1/p and its derivatives inside float32's range (at 2^-100, -11.5σ,
    the estimator's f/p is 1e30 and its derivative overflows). The inverse is u = Φ(z) (`ndtr`,
    through erfc in the lower tail); the density from u is the one from x.
    """

    loc: jax.Array = parameter(doc="the mean μ, finite", default=0.0)
    scale: jax.Array = parameter(0.0, np.inf, low_open=True, high_open=True, doc="the standard deviation σ",
                                 hard_cases=(1e-6, 1.0, 1e6), default=1.0)
    uniform_dims: ClassVar[int] = 1
    event_shape: ClassVar = ()
    measure: ClassVar = "length"

    def __post_init__(self):
        _check_finite("Normal", "loc", self.loc)

    def _parameters_valid(self):
        return _both(super()._parameters_valid(), _finite(self.loc))

    def _z(self, u0):
        top = one_minus_epsilon(jnp.result_type(u0))
        u0 = jnp.clip(u0, 1.0 - top, top)
        return ndtri(u0)

    @point_method
    def warp(self, u):
        return self.loc + self.scale * self._z(u[..., 0])

    @point_method
    def warp_with_pdf(self, u):
        z = self._z(u[..., 0])
        return self.loc + self.scale * z, jnp.exp(-0.5 * z * z - _LOG_SQRT_2PI) / self.scale

    @point_method
    def log_pdf(self, x):
        z = (x - self.loc) / self.scale
        return -0.5 * z * z - _LOG_SQRT_2PI - jnp.log(self.scale)

    @point_method
    def pdf(self, x):
        return jnp.exp(self.log_pdf(x))

    @point_method
    def inverse(self, x):
        u = ndtr((x - self.loc) / self.scale)
        return jnp.clip(u, 0.0, one_minus_epsilon(u.dtype))[..., None]

    def domain(self):
        loc, scale = concrete_value(self.loc), concrete_value(self.scale)
        if loc is None or scale is None:
            raise ValueError("Normal.domain: needs a concrete 'loc' and 'scale'")
        return _axis(float(loc), float(scale))


class Normal2D(Sampler):
    """The axis-aligned Gaussian on the plane: p(x) = exp(-|z|²/2) / (2π σ₀ σ₁) over area,
    z = ((x₀ - μ₀)/σ₀, (x₁ - μ₁)/σ₁); μ = `loc`, σ = `scale`, each of shape (..., 2).

    Polar inversion (the Box–Muller transform, Box & Muller 1958, "A note on the generation of
    random normal deviates", Ann. Math. Statist. 29(2), written as one bijection): |z|²/2 is
    exponential with rate 1 and the angle uniform, so r = √(-2 log(1 - u₀)), φ = 2πu₁ and
    z = r (cos φ, sin φ). log(1 - u₀) is `log1p(-u₀)`, exact as u₀ -> 0 (the centre) and finite
    up to u₀ = 1 - 2^-24 (r = 5.77 in float32). The density from u is exactly (1 - u₀)/(2π σ₀ σ₁);
    the inverse is u₀ = -expm1(-|z|²/2), u₁ = φ/2π (periodic). u₀ = 0 is the mean, where the
    angle is not recoverable (the map's one singular point, of measure 0).

    `loc` and `scale` may be given as scalars (the same on both axes); they are stored as 2-vectors.
    """

    loc: jax.Array = parameter(rank=1, doc="the mean (μ₀, μ₁), finite")
    scale: jax.Array = parameter(0.0, np.inf, low_open=True, high_open=True, rank=1,
                                 doc="the standard deviations (σ₀, σ₁) along the axes",
                                 hard_cases=(1e-6, 1.0, 1e6))
    uniform_dims: ClassVar[int] = 2
    event_shape: ClassVar = (2,)
    periodic_dims: ClassVar = (1,)
    measure: ClassVar = "area"

    def __init__(self, loc=(0.0, 0.0), scale=(1.0, 1.0)):
        self.loc = _as_pair("loc", loc)
        self.scale = _as_pair("scale", scale)
        _check_finite("Normal2D", "loc", self.loc)

    def _parameters_valid(self):
        return _both(super()._parameters_valid(), _finite(self.loc))

    def _standard(self, u):
        r = safe_sqrt(-2.0 * jnp.log1p(-u[..., 0]))
        sin_phi, cos_phi = sincos_2pi(u[..., 1])
        return jnp.stack([r * cos_phi, r * sin_phi], axis=-1)

    def _log_normalizer(self):
        return -_LOG_2PI - jnp.sum(jnp.log(self.scale), axis=-1)

    @point_method
    def warp(self, u):
        return self.loc + self.scale * self._standard(u)

    @point_method
    def warp_with_pdf(self, u):
        x = self.loc + self.scale * self._standard(u)
        return x, (1.0 - u[..., 0]) * jnp.exp(self._log_normalizer())

    @point_method
    def log_pdf(self, x):
        z = (x - self.loc) / self.scale
        return self._log_normalizer() - 0.5 * jnp.sum(z * z, axis=-1)

    @point_method
    def pdf(self, x):
        return jnp.exp(self.log_pdf(x))

    @point_method
    def inverse(self, x):
        z = (x - self.loc) / self.scale
        u0 = -jnp.expm1(-0.5 * jnp.sum(z * z, axis=-1))
        return jnp.stack([jnp.minimum(u0, one_minus_epsilon(u0.dtype)), azimuth_fraction(z[..., 1], z[..., 0])],
                         axis=-1)

    def domain(self):
        loc, scale = concrete_value(self.loc), concrete_value(self.scale)
        if loc is None or scale is None or loc.shape != (2,) or scale.shape != (2,):
            raise ValueError("Normal2D.domain: needs one concrete distribution (loc and scale of shape (2,))")
        return Box(tuple(_axis(float(m), float(s)) for m, s in zip(loc, scale)))


def _finite(value):
    """Whether every entry is finite: a NumPy bool when concrete, a JAX one when traced (`in_range`)."""
    return in_range(value, -np.inf, np.inf, low_open=True, high_open=True)


def _check_finite(owner: str, name: str, value) -> None:
    """ValueError naming the parameter for a concrete value that is inf or NaN (no declared range
    states it: the range of a mean is the whole line)."""
    check_parameter(owner, name, value, -np.inf, np.inf, low_open=True, high_open=True)


def _both(a, b):
    if isinstance(a, (bool, np.bool_)) and isinstance(b, (bool, np.bool_)):
        return np.bool_(a and b)
    return jnp.logical_and(a, b)


def _as_pair(name: str, value):
    """`value` with a last axis of 2: a scalar is repeated on both axes; ValueError for another length."""
    value = as_parameter(value)
    check_number("Normal2D", name, value)
    if jnp.ndim(value) == 0:
        return jnp.stack([jnp.asarray(value)] * 2)
    if jnp.shape(value)[-1] != 2:
        raise ValueError(f"Normal2D: parameter '{name}' must have shape (..., 2) (or be a scalar); "
                         f"got {jnp.shape(value)}")
    return value
