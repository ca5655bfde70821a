"""Integrands that say where they jump: `mask(region, inside, outside)`.

An integrand written with a comparison, `jnp.where(x @ a >= cos_alpha, h(x), 0.0)`, has a derivative
in α of exactly 0 at every sample: the jump is invisible to pathwise, score and measure-valued
estimators alike, and the gradient of its estimate is 0 ± 0 while the truth is the boundary term
(`regions.py`). `mask(region, inside, outside)` is the same function, f(x) = inside(x) where x is
in the region and outside(x) (default 0) elsewhere, that also tells the estimators its
discontinuity: the region's boundary and the jump Δf(y) = inside(y) − outside(y) there. The
estimators (`estimate`, `estimate_grad`, `expectation`, `expectation_grad`) then add the boundary
term, sampled on the boundary alongside every interior sample (`estimators/boundary.py`).

Masks nest: `mask(cap, mask(triangle, h))` is h on the intersection; the inner boundary's jump
counts only where it lies inside the outer region (and an `outside` mask's only outside it). The
jumps of `inside` and `outside` themselves must be declared this way too: a comparison written in
them by hand is again invisible. `inside` and `outside` map one sample to one real array.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Callable

import jax.numpy as jnp

__all__ = ["Masked", "mask", "discontinuities", "boundary_dims"]


@dataclasses.dataclass(frozen=True)
class Masked:
    """f(x) = inside(x) for x in `region` (boundary included), outside(x) elsewhere."""

    region: Any
    inside: Callable
    outside: Callable | None = None

    def __call__(self, x):
        value_in = jnp.asarray(self.inside(x))
        value_out = jnp.zeros_like(value_in) if self.outside is None else jnp.asarray(self.outside(x))
        return jnp.where(self.region.indicator(x) > 0, value_in, value_out)

    def jump(self, y):
        """Δf(y) = inside(y) − outside(y) at a boundary point y."""
        value_in = jnp.asarray(self.inside(y))
        return value_in if self.outside is None else value_in - jnp.asarray(self.outside(y))

    def discontinuities(self) -> list:
        """[(region, jump)] for this mask's boundary and the nested masks' boundaries."""
        found = [(self.region, self.jump)]
        for part, keep in ((self.inside, lambda y: self.region.indicator(y)),
                           (self.outside, lambda y: 1.0 - self.region.indicator(y))):
            for region, jump in discontinuities(part):
                found.append((region, lambda y, jump=jump, keep=keep: keep(y) * jump(y)))
        return found


def mask(region, inside: Callable, outside: Callable | None = None) -> Masked:
    """The integrand inside(x) on `region` (a `Cap`, `SphericalTriangle`, `Disk` or any object with
    `indicator`, `boundary_dims` and `boundary_sample`), outside(x) (default 0) elsewhere, whose
    jump across the region's boundary the gradient estimators add (see the module docstring).

    Named `mask`, not `masked`, so that `jaxsample.edges.masked` is this module and nothing hides it."""
    for name in ("indicator", "boundary_sample", "boundary_dims"):
        if not hasattr(region, name):
            raise TypeError(f"mask: parameter 'region' must have '{name}' (a jaxsample.edges region); "
                            f"got {type(region).__name__}")
    if not callable(inside) or (outside is not None and not callable(outside)):
        raise TypeError("mask: parameters 'inside' and 'outside' must be functions of one sample")
    return Masked(region, inside, outside)


def discontinuities(f) -> list:
    """The declared discontinuities of an integrand: [] for a plain function."""
    found = getattr(f, "discontinuities", None)
    return list(found()) if callable(found) else []


def boundary_dims(f) -> int:
    """Uniforms per sample that the boundary terms of `f` use (0 for a plain function)."""
    return sum(int(region.boundary_dims) for region, _ in discontinuities(f))
