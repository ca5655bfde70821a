"""The power law p(x) = (n + 1) x^n on [0, 1] (length measure)."""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from .base import Sampler, point_method
from .._core.params import check_choice, concrete_value
from .._core.pytree import parameter, static_field
from .domain import Interval
from .._core.numerics import safe_log, safe_pow


class Power(Sampler):
    """p(x) = (n + 1) x^n on [0, 1] (length measure), 0 outside; n = `exponent`.

    `method="inversion"` (default, 1 uniform): the CDF is x^{n+1}, so x = ξ^{1/(n+1)} with
    ξ = 1 - u (Chuang, *Monte Carlo Integration*; the same step as the Phong lobe). It is computed
    as log x = log1p(-u)/(n + 1), x = exp(log x): finite on [0, 1), u = 0 gives the mode x = 1, and
    nothing is raised to a huge power. The density from u is (n + 1) exp(n log x), which keeps its
    full precision even where x itself rounds to 1; `exponent` n in [0, 1e6]. In float32 a sample
    near 1 is resolved only to 6e-8, so for n ≳ 1e5 prefer `warp_with_pdf` or float64 to `pdf(x)`.

    `method="max"`: x = max(u₀, ..., u_n), the largest of n + 1 uniforms (P(max <= x) = x^{n+1}).
    It needs an integer n, which is static (`uniform_dims` = n + 1 and changing n recompiles) and
    costs n + 1 uniforms per sample: it is a teaching device and a test of the inversion, not a
    fast method beyond n of a few dozen. Not a bijection: it has no inverse.

    A concrete exponent outside [0, 1e6] (or a non-integer one for "max") raises ValueError.
    """

    exponent: jax.Array = parameter(0.0, 1e6, doc="n")
    method: str = static_field()
    # "max" draws n + 1 uniforms: its n is a static int, which also sets `uniform_dims`.
    max_exponent: int | None = static_field()
    event_shape: ClassVar = ()
    measure: ClassVar = "length"

    def __init__(self, exponent, method: str = "inversion"):
        check_choice("Power", "method", method, ("inversion", "max"))
        self.method = method
        self.exponent = exponent
        self.max_exponent = None
        if method == "max":
            n = concrete_value(self.exponent)
            if n is None or n.ndim != 0 or n != np.floor(n):
                raise ValueError("Power: method 'max' needs a concrete integer 'exponent' in [0, 1e6]; "
                                 f"got {exponent!r}")
            self.max_exponent = int(n)

    def _n(self):
        return self.max_exponent if self.method == "max" else self.exponent

    def __repr__(self):
        return f"Power(exponent={self.exponent!r}, method={self.method!r})"

    @property
    def uniform_dims(self) -> int:
        return 1 if self.method == "inversion" else self.max_exponent + 1

    @property
    def has_inverse(self) -> bool:
        return self.method == "inversion"

    def _parameters_valid(self):
        return super()._parameters_valid() if self.method == "inversion" else None

    def _log_x(self, u0):
        return jnp.log1p(-u0) / (self.exponent + 1.0)

    @point_method
    def warp(self, u):
        if self.method == "max":
            return jnp.max(u, axis=-1)
        return jnp.exp(self._log_x(u[..., 0]))

    @point_method
    def warp_with_pdf(self, u):
        if self.method == "max":
            x = self.warp(u)
            return x, self.pdf(x)
        log_x = self._log_x(u[..., 0])
        n = self.exponent
        return jnp.exp(log_x), (n + 1.0) * jnp.exp(n * log_x)

    @point_method
    def pdf(self, x):
        n = self._n()
        inside = (x >= 0) & (x <= 1)
        density = (n + 1.0) * safe_pow(jnp.where(inside, x, 0.0), n)
        return jnp.where(inside, density, 0.0).astype(jnp.result_type(x, float))

    @point_method
    def log_pdf(self, x):
        n = self._n()
        inside = (x >= 0) & (x <= 1)
        # n log x with log 0 = -inf would give 0 * -inf = NaN at n = 0; safe_log of the pdf avoids it.
        log_x = safe_log(jnp.where(inside, x, 1.0))
        positive = inside & (x > 0)
        value = jnp.log1p(n) + n * jnp.where(positive, log_x, 0.0)
        at_zero = jnp.where(n == 0, 0.0, -jnp.inf)
        return jnp.where(positive, value, jnp.where(inside, at_zero, -jnp.inf))

    @point_method
    def inverse(self, x):
        if self.method == "max":
            return super().inverse(x)
        # u = 1 - x^{n+1} = -expm1((n + 1) log x): exact as x -> 1, where 1 - x^{n+1} cancels.
        log_x = safe_log(jnp.clip(x, 0.0, 1.0))
        positive = x > 0
        u = -jnp.expm1((self.exponent + 1.0) * jnp.where(positive, log_x, 0.0))
        return jnp.where(positive, u, 1.0)[..., None]

    def domain(self):
        return Interval(0.0, 1.0)
