"""Mixtures of samplers on a common domain: one-sample multiple importance sampling."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from .base import Sampler, point_method, refuse_class
from .._core.pytree import parameter
from .discrete import as_array, cdf_from_weights, check_weights, select_with_remainder, valid_tables


def _merged_domain(domains):
    """One domain for all components: same-type domains with `breaks` get the union of them."""
    first = domains[0]
    if not all(type(d) is type(first) for d in domains) or not hasattr(first, "breaks"):
        return first
    breaks = np.unique(np.concatenate([np.ravel(np.asarray(d.breaks, np.float64)) for d in domains]))
    changes = {"breaks": tuple(breaks)}
    if getattr(first, "quadrature_high", None) is not None:
        changes["quadrature_high"] = max(d.quadrature_high for d in domains)
    if getattr(first, "quadrature_low", None) is not None:
        changes["quadrature_low"] = min(d.quadrature_low for d in domains)
    return dataclasses.replace(first, **changes)


class Mixture(Sampler):
    """p(x) = Σ_k w_k p_k(x) with w normalised: pick component k with probability w_k, sample it.

    Estimating ∫ f with x from the mixture and the weight f(x)/p(x) is one-sample MIS with the
    balance heuristic (Veach & Guibas 1995; Veach 1997, §9.2.2): the mixture density is exactly
    the balance heuristic's denominator, so no component's low density can blow the weight up.

    Warp: the component is chosen from u₀ by CDF search; the remainder of u₀ (uniform on [0, 1)
    and independent of the choice) replaces u₀, and the chosen component warps (remainder, u₁, ...)
    — so `uniform_dims` is the largest component's, and stratification of u₀ carries over. Every
    component is evaluated and one is selected (no branching under jit). Not a bijection: no
    inverse. Components must share an event shape and a domain; concrete weights must be finite,
    >= 0, not all zero and one per component (ValueError otherwise).
    """

    components: tuple
    weights: jax.Array = parameter(rank=1, doc="one per component, >= 0, not all 0")

    def __post_init__(self):
        self.weights = as_array(self.weights)
        if isinstance(self.components, (tuple, list)):
            for c in self.components:
                refuse_class("Mixture", "components", c)
        if not isinstance(self.components, (tuple, list)) or not all(isinstance(c, Sampler) for c in self.components):
            return  # rebuilt by JAX with placeholders
        self.components = tuple(self.components)
        if not self.components:
            raise ValueError("Mixture: parameter 'components' must hold at least one sampler")
        if len({tuple(c.event_shape) for c in self.components}) != 1:
            raise ValueError("Mixture: parameter 'components' must share one event shape")
        if len({c.measure for c in self.components}) != 1:
            raise ValueError("Mixture: parameter 'components' must have densities over one measure; got "
                             + ", ".join(f"{type(c).__name__}: {c.measure}" for c in self.components)
                             + " (a Transformed component states its measure with measure=...)")
        check_weights("Mixture", "weights", self.weights)
        if hasattr(self.weights, "shape") and jnp.shape(self.weights)[-1] != len(self.components):
            raise ValueError(f"Mixture: parameter 'weights' must have one entry per component "
                             f"({len(self.components)}); got shape {jnp.shape(self.weights)}")

    @property
    def uniform_dims(self) -> int:
        return max(c.uniform_dims for c in self.components)

    @property
    def event_shape(self):
        return self.components[0].event_shape

    @property
    def measure(self):
        return self.components[0].measure

    def _parameters_valid(self):
        return valid_tables(self._pmf())

    def _pmf(self):
        w = jnp.asarray(self.weights)
        return w / jnp.sum(w)

    @point_method
    def warp(self, u):
        index, remainder = select_with_remainder(cdf_from_weights(jnp.asarray(self.weights)), u[..., 0])
        u = jnp.concatenate([remainder[..., None], u[..., 1:]], axis=-1)
        outputs = [c.warp(u[..., : c.uniform_dims]) for c in self.components]
        if len(outputs) == 1:
            return outputs[0]
        # An elementwise select (not a gather from stacked outputs): it fuses with the warps.
        index = index.reshape(index.shape + (1,) * len(self.event_shape))
        return jax.lax.select_n(jnp.broadcast_to(index, outputs[0].shape), *outputs)

    @point_method
    def pdf(self, x):
        pmf = self._pmf()
        return sum(pmf[k] * c.pdf(x) for k, c in enumerate(self.components))

    def domain(self):
        return _merged_domain([c.domain() for c in self.components])
