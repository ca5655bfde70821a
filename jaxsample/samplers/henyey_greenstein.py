"""The Henyey–Greenstein phase function as a sampler of scattered directions (solid angle)."""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from .base import Sampler, point_method
from .._core.params import concrete_value
from .._core.pytree import parameter
from .domain import Directions
from .._core.numerics import azimuth_fraction, direction_from_one_minus_cos, one_minus_cos_theta

_LOG_4PI = float(np.log(4.0 * np.pi))
_ONE_MINUS_TINY = 1.0 - 1e-4  # the float32 hard case nearest to |g| = 1


class HenyeyGreenstein(Sampler):
    """Henyey–Greenstein phase function about +z: over solid angle on S²,

        p(ω) = (1 - g²) / (4π (1 + g² - 2g cos θ)^{3/2}),

    θ the angle between ω and +z. Convention: +z is the direction the light travels in before it
    scatters and ω the direction it travels in after, so g > 0 is forward scattering (mass toward
    +z), g < 0 backward, g = 0 isotropic (1/4π), and g = E[cos θ] is the mean cosine. (PBRT-v4
    and Mitsuba 3 measure their angle against the reversed direction, so their cos θ is minus this
    one.) Henyey & Greenstein 1941, "Diffuse radiation in the galaxy", ApJ 93, eq. (3); the
    Legendre moments are E[P_l(cos θ)] = g^l.

    Inversion: with μ = cos θ and ξ = u₀, the CDF of μ is
    F(μ) = (1 - g)(1 + μ) / (√w ((1 + g) + √w)), w = 1 + g² - 2gμ, and its inverse, written with
    D = 1 - g + 2gξ, is

        1 + μ = 2ξ (1 + g)² (1 - g + gξ) / D²,       1 - μ = 2(1 - ξ)(1 - g)² (1 + gξ) / D².

    These come from the textbook form μ = (1 + g² - ((1 - g²)/D)²)/(2g) (PBRT-v4
    `SampleHenyeyGreenstein`, Mitsuba 3 `hg.cpp`) by dividing out the common factor 2g by hand:
    the textbook form is 0/0 at g = 0, and branching to 1 - 2ξ below a threshold leaves a jump
    in the value and the derivative at the threshold; these are exact at g = 0 (μ = 2ξ - 1,
    dμ/dg = 6ξ(1 - ξ)) and smooth through it. As |g| -> 1 the textbook form subtracts two
    numbers near (1 + g)² (pbrt-v4#333: NaN at g = ±1; PBRT clamps g to ±0.99); here both 1 ± μ
    are products of factors that are each a sum of same-signed terms (for g < 0 the three
    factors 1 - g + 2gξ, 1 + gξ, 1 - g + gξ are formed from 1 + g and 1 - ξ instead), so each is
    exact to a few ulps at any g in (-1, 1) and any ξ, and sin²θ = (1 - μ)(1 + μ) keeps full
    precision at both poles. ξ = 0 is the backward pole (μ = -1), ξ -> 1 the forward one.

    The density from u is exact too: p = D³ / (4π (1 - g²)²). From a direction, w is formed as
    (1 - g)² + 2g(1 - μ) for g >= 0 and (1 + g)² - 2g(1 + μ) for g < 0, with 1 ∓ μ from the
    vector's x and y near the poles (`one_minus_cos_theta`): again sums of same-signed terms.
    φ = 2πu₁. Tested at g = 0, ±1e-4, ±0.5, ±0.99 and ±(1 - 1e-4), the last the float32 value
    nearest ±1 worth testing (the lobe is then 1e-4 rad wide).
    """

    g: jax.Array = parameter(-1.0, 1.0, low_open=True, high_open=True,
                             doc="the asymmetry parameter (mean cosine); > 0 scatters forward (toward +z)",
                             hard_cases=(0.0, 1e-4, -1e-4, 0.5, -0.5, 0.99, -0.99, _ONE_MINUS_TINY,
                                         -_ONE_MINUS_TINY))
    uniform_dims: ClassVar[int] = 2
    event_shape: ClassVar = (3,)
    periodic_dims: ClassVar = (1,)
    measure: ClassVar = "solid angle"

    def _polar(self, u0):
        """(1 - μ, 1 + μ, D) at ξ = u₀, each from same-signed terms (class docstring)."""
        g = self.g
        xi, rest = u0, 1.0 - u0
        forward = g >= 0
        one_minus_g, one_plus_g = 1.0 - g, 1.0 + g
        # For g < 0 each factor below would subtract nearly equal numbers as g -> -1 and ξ -> 1;
        # rewritten with 1 - ξ they add. Both branches are the same polynomial in (g, ξ), so the
        # select changes neither the value nor the derivative at g = 0.
        d = jnp.where(forward, one_minus_g + 2.0 * g * xi, one_plus_g - 2.0 * g * rest)
        a = jnp.where(forward, one_minus_g + g * xi, 1.0 - g * rest)     # 1 - g + gξ
        b = jnp.where(forward, 1.0 + g * xi, one_plus_g - g * rest)      # 1 + gξ
        d2 = d * d
        one_plus_cos = 2.0 * xi * (one_plus_g * one_plus_g) * a / d2
        one_minus_cos = 2.0 * rest * (one_minus_g * one_minus_g) * b / d2
        return jnp.clip(one_minus_cos, 0.0, 2.0), jnp.clip(one_plus_cos, 0.0, 2.0), d

    def _one_minus_g2(self):
        return (1.0 - self.g) * (1.0 + self.g)

    @point_method
    def warp(self, u):
        one_minus_cos, one_plus_cos, _ = self._polar(u[..., 0])
        return direction_from_one_minus_cos(one_minus_cos, u[..., 1], one_plus_cos)

    @point_method
    def warp_with_pdf(self, u):
        one_minus_cos, one_plus_cos, d = self._polar(u[..., 0])
        x = direction_from_one_minus_cos(one_minus_cos, u[..., 1], one_plus_cos)
        s = self._one_minus_g2()
        return x, d * d * d / (4.0 * np.pi * s * s)

    def _w(self, x):
        """w = 1 + g² - 2g cos θ and 1 + cos θ of unit vectors x, accurate at both poles."""
        g = self.g
        one_minus_cos = one_minus_cos_theta(x)
        one_plus_cos = one_minus_cos_theta(-x)  # 1 + z, from x and y near z = -1
        w = jnp.where(g >= 0, (1.0 - g) ** 2 + 2.0 * g * one_minus_cos, (1.0 + g) ** 2 - 2.0 * g * one_plus_cos)
        return w, one_plus_cos

    @point_method
    def log_pdf(self, x):
        w, _ = self._w(x)
        return jnp.log(self._one_minus_g2()) - _LOG_4PI - 1.5 * jnp.log(w)

    @point_method
    def pdf(self, x):
        w, _ = self._w(x)
        return self._one_minus_g2() / (4.0 * np.pi * w * jnp.sqrt(w))

    @point_method
    def inverse(self, x):
        # u₀ = F(μ) = (1 - g)(1 + μ) / (√w ((1 + g) + √w)): F's 1/(2g) divided out, as in the warp.
        w, one_plus_cos = self._w(x)
        root = jnp.sqrt(w)
        u0 = (1.0 - self.g) * jnp.clip(one_plus_cos, 0.0, 2.0) / (root * ((1.0 + self.g) + root))
        return jnp.stack([jnp.clip(u0, 0.0, 1.0), azimuth_fraction(x[..., 1], x[..., 0])], axis=-1)

    def domain(self):
        # The checks' rules are graded toward the axis, where the lobe peaks: +z, or -z for g < 0.
        g = concrete_value(self.g)
        return Directions(axis=(0.0, 0.0, -1.0)) if g is not None and g.ndim == 0 and g < 0 else Directions()
