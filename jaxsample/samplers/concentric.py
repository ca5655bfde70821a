"""Shirley–Chiu concentric map between the square [0,1)² and the unit disk, and its inverse.

Shirley & Chiu, "A Low Distortion Map Between Disk and Square", JGT 2(3), 1997 (PBRT-v4
`SampleUniformDiskConcentric`). With a = 2u₀ - 1, b = 2u₁ - 1: where |a| > |b|, r = a and
φ = (π/4)(b/a); otherwise r = b and φ = π/2 - (π/4)(a/b). The map is area preserving up to the
constant π/4, so uniform u gives uniform points on the disk.

Both wedges share one division, whose divisor is the larger of |a| and |b| (1 at the centre),
so that neither the value nor the reverse-mode gradient is NaN on the axes and at the centre.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from .._core.numerics import safe_sqrt, sincos_small

QUARTER_PI = 0.25 * np.pi


def square_to_disk(u):
    """(x, y, r) with (x, y) on the unit disk and r = sqrt(x² + y²) >= 0, computed without a sqrt."""
    a = 2.0 * u[..., 0] - 1.0
    b = 2.0 * u[..., 1] - 1.0
    a_wins = jnp.abs(a) > jnp.abs(b)
    radius = jnp.where(a_wins, a, b)
    # One division for both wedges (the divider is the slowest unit a sample uses): b/a where
    # |a| > |b|, else a/b, with b = 0 (then a = 0 too, the centre) divided by 1.
    other = jnp.where(a_wins, b, a)
    divisor = jnp.where(a_wins | (b != 0), radius, 1.0)
    ratio = other / divisor
    # The wedge's own angle ψ = (π/4) ratio lies in [-π/4, π/4], where `sincos_small` needs no
    # reduction: φ = ψ in the |a| > |b| wedges, so (cos φ, sin φ) = (cos ψ, sin ψ), and φ = π/2 - ψ
    # in the others, so (cos φ, sin φ) = (sin ψ, cos ψ).
    sin_psi, cos_psi = sincos_small(QUARTER_PI * ratio)
    cos_phi = jnp.where(a_wins, cos_psi, sin_psi)
    sin_phi = jnp.where(a_wins, sin_psi, cos_psi)
    # |radius| is max(|a|, |b|): written so, an integrand of r alone needs neither branch's select.
    return radius * cos_phi, radius * sin_phi, jnp.maximum(jnp.abs(a), jnp.abs(b))


def disk_to_square(x, y):
    """Inverse of `square_to_disk`: (u₀, u₁) in [0, 1]² for (x, y) on the unit disk."""
    # safe_sqrt: the reverse-mode derivative of sqrt at the centre is inf, and times the zero
    # derivative of x² + y² it would give NaN; safe_sqrt's is 0 there.
    r = safe_sqrt(x * x + y * y)
    x_wins = jnp.abs(x) >= jnp.abs(y)
    x_safe = jnp.where(x_wins & (x != 0), x, 1.0)
    y_safe = jnp.where(x_wins | (y == 0), 1.0, y)
    # In the |x| >= |y| wedges r = a (signed), b = a (4/π) atan(y/x); in the others symmetric.
    signed_r = jnp.where(x_wins, jnp.copysign(r, x), jnp.copysign(r, y))
    ratio = jnp.where(x_wins, y / x_safe, x / y_safe)
    other = signed_r * jnp.arctan(ratio) / QUARTER_PI
    a = jnp.where(x_wins, signed_r, other)
    b = jnp.where(x_wins, other, signed_r)
    return jnp.stack([0.5 * (a + 1.0), 0.5 * (b + 1.0)], axis=-1)
