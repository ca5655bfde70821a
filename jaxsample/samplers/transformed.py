"""A sampler pushed through a smooth bijection, with the change-of-variables density by autodiff."""

from __future__ import annotations

import math
from typing import Any, Callable

import jax
import jax.numpy as jnp

from .base import Sampler, WrapsSampler, point_method, refuse_class
from .._core.pytree import static_field


def _map_points(fn, x, event_ndim):
    """Apply a one-point function over all leading (batch) axes of x."""
    batch = x.shape[: x.ndim - event_ndim]
    flat = x.reshape((math.prod(batch),) + x.shape[x.ndim - event_ndim:])
    out = jax.vmap(fn)(flat)
    return out.reshape(batch + out.shape[1:])


class Transformed(WrapsSampler):
    """y = T(x) with x from `base`: p_y(y) = p_x(T⁻¹(y)) / |det J_T(T⁻¹(y))|.

    The change-of-variables formula (Chuang, *Monte Carlo Integration*, "transformation method";
    *PBR* §2.4.1). J_T is computed by `jax.jacfwd`, so only T and T⁻¹ are written by hand. When T
    maps R^d into R^m with m > d (a parametrised surface: spherical coordinates onto the sphere)
    the density is over the surface measure and |det J| becomes sqrt(det(JᵀJ)).

    `forward` and `inverse` take and return ONE point (shapes `base.event_shape` and the output
    event shape); they are vmapped over batch axes. They are static (part of the tree structure),
    so the object is still a pytree whose leaves are the base's parameters; use module-level
    functions, since a new function object recompiles. `domain` (optional, static) is the output
    domain for the checks. Where det J is 0 or not finite (T's singular points, a set of measure
    zero such as the centre of polar coordinates) the density is reported as 0.

    `measure` (optional, static) names the output density's measure ("solid angle", "area", ...);
    by default it is the base's when T keeps the dimension, unknown (None) when it maps onto a
    surface. `estimate_mis` needs it known.
    """

    base: Sampler
    forward: Callable = static_field()
    backward: Callable = static_field()
    support: Any = static_field()
    output_measure: str | None = static_field()

    def __init__(self, base: Sampler, forward: Callable, inverse: Callable, domain=None, measure=None):
        refuse_class("Transformed", "base", base)
        if not isinstance(base, Sampler):
            raise ValueError("Transformed: parameter 'base' must be a Sampler")
        self.base = base
        self.forward = forward
        self.backward = inverse
        self.support = domain
        self.output_measure = measure

    @property
    def measure(self):
        if self.output_measure is not None:
            return self.output_measure
        same_dimension = math.prod(self.event_shape) == math.prod(self.base.event_shape)
        return self.base.measure if same_dimension else None

    @property
    def event_shape(self):
        point = jax.ShapeDtypeStruct(tuple(self.base.event_shape), jnp.float32)
        return tuple(jax.eval_shape(self.forward, point).shape)

    def _log_abs_det(self, x):
        """log |det J_T(x)| (or ½ log det JᵀJ), batched; NaN where the Jacobian is not finite."""
        in_size = math.prod(self.base.event_shape)

        def one(point):
            jac = jax.jacfwd(self.forward)(point).reshape(-1, in_size)
            if jac.shape[0] == jac.shape[1]:
                return jnp.linalg.slogdet(jac)[1]
            return 0.5 * jnp.linalg.slogdet(jac.T @ jac)[1]

        return _map_points(one, x, len(self.base.event_shape))

    def _density(self, base_density, log_det):
        ok = jnp.isfinite(log_det)
        return jnp.where(ok, base_density * jnp.exp(-jnp.where(ok, log_det, 0.0)), 0.0)

    @point_method
    def warp(self, u):
        return _map_points(self.forward, self.base.warp(u), len(self.base.event_shape))

    @point_method
    def warp_with_pdf(self, u):
        x, base_density = self.base.warp_with_pdf(u)
        y = _map_points(self.forward, x, len(self.base.event_shape))
        return y, self._density(base_density, self._log_abs_det(x))

    def _preimage(self, y):
        return _map_points(self.backward, y, len(self.event_shape))

    @point_method
    def pdf(self, y):
        x = self._preimage(y)
        return self._density(self.base.pdf(x), self._log_abs_det(x))

    @point_method
    def log_pdf(self, y):
        x = self._preimage(y)
        log_det = self._log_abs_det(x)
        ok = jnp.isfinite(log_det)
        return jnp.where(ok, self.base.log_pdf(x) - jnp.where(ok, log_det, 0.0), -jnp.inf)

    @point_method
    def inverse(self, y):
        return self.base.inverse(self._preimage(y))

    def domain(self):
        if self.support is None:
            raise ValueError("Transformed.domain: pass domain=... (the output domain) to run the checks")
        return self.support
