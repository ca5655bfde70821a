"""Uniform points on the unit disk: p = 1/π over area."""

from __future__ import annotations

from typing import ClassVar

import jax.numpy as jnp
import numpy as np

from . import concentric
from .base import Sampler, point_method
from .._core.params import check_choice
from .._core.pytree import parameter, static_field
from .domain import Disk
from .._core.numerics import INV_PI, azimuth_fraction, safe_sqrt, sincos_2pi
from .rejection import select_first


def _polar(u):
    sin_phi, cos_phi = sincos_2pi(u[..., 1])
    r = safe_sqrt(u[..., 0])
    return jnp.stack([r * cos_phi, r * sin_phi], axis=-1)


class UniformDisk(Sampler):
    """Uniform on the unit disk {x² + y² <= 1}: p = 1/π over area, 0 outside.

    `method="concentric"` (default): the Shirley–Chiu map (`jaxsample.concentric`, PBRT-v4
    `SampleUniformDiskConcentric`), area preserving up to π/4 and low in distortion, so stratified
    and Sobol' points stay well spread. Its value and reverse-mode gradient are finite on the axes
    and at the centre; it is a bijection of the open square onto the disk, with inverse.

    `method="polar"`: the marginal of r has density 2r, CDF r², so r = sqrt(u₀), φ = 2πu₁ (PBRT-v4
    `SampleUniformDiskPolar`); inverse u₀ = x² + y², u₁ = φ/2π (periodic).

    `method="rejection"`: points uniform in [-1, 1]², the first one strictly inside the disk among
    `tries` (acceptance π/4 each), run without branching; 2 uniforms per try plus 2 more that feed
    a polar sample, used only if every try is rejected: it is independent of the rejected tries,
    so the output stays exactly uniform (as `UniformSphere(method="rejection")`). No inverse.
    """

    method: str = static_field(default="concentric")
    tries: int = parameter(1, 4096, static=True, default=8, doc="attempts of the rejection method")
    event_shape: ClassVar = (2,)
    measure: ClassVar = "area"

    def __post_init__(self):
        check_choice("UniformDisk", "method", self.method, ("concentric", "polar", "rejection"))

    @property
    def uniform_dims(self) -> int:
        return 2 * self.tries + 2 if self.method == "rejection" else 2

    @property
    def periodic_dims(self):
        return (1,) if self.method == "polar" else ()

    @property
    def has_inverse(self) -> bool:
        return self.method != "rejection"

    @point_method
    def warp(self, u):
        if self.method == "polar":
            return _polar(u)
        if self.method == "concentric":
            x, y, _ = concentric.square_to_disk(u)
            return jnp.stack([x, y], axis=-1)
        points = 2.0 * u[..., :-2].reshape(u.shape[:-1] + (self.tries, 2)) - 1.0
        accepted = jnp.sum(points * points, axis=-1) < 1.0
        return select_first(points, accepted, _polar(u[..., -2:]))

    @point_method
    def warp_with_pdf(self, u):
        x = self.warp(u)
        return x, jnp.full(x.shape[:-1], INV_PI, x.dtype)

    @point_method
    def pdf(self, x):
        # A point warped from u₀ -> 1 may land an ulp or two outside r = 1 (cos² + sin² rounds).
        slack = 8.0 * np.finfo(jnp.result_type(x, float)).eps
        inside = jnp.sum(x * x, axis=-1) <= 1.0 + slack
        return jnp.where(inside, INV_PI, 0.0).astype(jnp.result_type(x, float))

    @point_method
    def inverse(self, x):
        if self.method == "polar":
            r2 = jnp.clip(jnp.sum(x * x, axis=-1), 0.0, 1.0)
            return jnp.stack([r2, azimuth_fraction(x[..., 1], x[..., 0])], axis=-1)
        if self.method == "concentric":
            # disk_to_square takes sqrt(x² + y²) unguarded, whose reverse-mode gradient is NaN at the
            # centre; the centre is mapped to (½, ½) here with a zero gradient instead.
            at_centre = (x[..., 0] == 0) & (x[..., 1] == 0)
            x_safe = jnp.where(at_centre, 1.0, x[..., 0])
            u = concentric.disk_to_square(x_safe, x[..., 1])
            return jnp.where(at_centre[..., None], 0.5, u)
        return super().inverse(x)

    def domain(self):
        return Disk()
