"""Orthonormal frames built from one unit vector (Duff et al. 2017, "Building an Orthonormal Basis,
Revisited", JCGT 6(1)).

Duff et al. fix the singularity of Frisvad's 2012 basis at n = -z with a branchless sign: with
s = copysign(1, n_z), a = -1 / (s + n_z) and b = n_x n_y a, the tangents are
t = (1 + s n_x² a, s b, -s n_x) and b' = (b, s + n_y² a, -n_y). `copysign` (not `sign`) matters:
sign(-0.0) is 0 and would divide by zero.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .._core.params import as_parameter, check_number, concrete_value
from .._core.pytree import Pytree, parameter

import numpy as np


class Frame(Pytree):
    """A right-handed orthonormal frame (x, y, z), each a (..., 3) array; `z` is the normal."""

    x: jax.Array = parameter(rank=1)
    y: jax.Array = parameter(rank=1)
    z: jax.Array = parameter(rank=1, doc="the normal")

    @classmethod
    def from_normal(cls, normal: jax.Array) -> "Frame":
        """Frame whose z axis is `normal` (normalised here).

        A concrete normal that is zero, non-finite, or too short or too long to normalise in its
        dtype raises: n / |n| is computed from n·n, which underflows to 0 below about 1e-19
        (float32; 1e-154 in float64) and overflows above about 1e19 (1e154), and gives NaN or a
        zero axis there. A traced normal cannot be checked (a zero one gives a NaN frame).
        """
        check_number("Frame.from_normal", "normal", normal)
        normal = jnp.asarray(as_parameter(normal))
        v = concrete_value(normal)
        if v is not None:
            if v.shape[-1:] != (3,):
                raise ValueError(f"Frame.from_normal: parameter 'normal' must have shape (..., 3); got {v.shape}")
            norms = np.linalg.norm(v, axis=-1)
            if not np.all(np.isfinite(norms)) or np.any(norms == 0):
                raise ValueError("Frame.from_normal: parameter 'normal' must be finite and non-zero")
            dtype = normal.dtype if jnp.issubdtype(normal.dtype, jnp.floating) else jnp.zeros(()).dtype
            info = np.finfo(dtype)
            squares = np.sum(np.square(v), axis=-1)
            bad = (squares < info.tiny) | (squares > info.max)
            if np.any(bad):
                shortest, longest = np.sqrt(info.tiny), np.sqrt(info.max)
                raise ValueError(f"Frame.from_normal: parameter 'normal' must have a length in "
                                 f"[{shortest:.3g}, {longest:.3g}] to be normalised in {dtype}; got length "
                                 f"{np.ravel(norms[bad] if norms.ndim else norms)[0]:.3g} (scale it first)")
        normal = normal / jnp.linalg.norm(normal, axis=-1, keepdims=True)
        nx, ny, nz = normal[..., 0], normal[..., 1], normal[..., 2]
        s = jnp.copysign(jnp.ones_like(nz), nz)
        a = -1.0 / (s + nz)
        b = nx * ny * a
        tangent = jnp.stack([1.0 + s * nx * nx * a, s * b, -s * nx], axis=-1)
        bitangent = jnp.stack([b, s + ny * ny * a, -ny], axis=-1)
        return cls(tangent, bitangent, normal)

    def to_world(self, v: jax.Array) -> jax.Array:
        """Local coordinates (about +z) to world: v_x x + v_y y + v_z z."""
        return v[..., 0:1] * self.x + v[..., 1:2] * self.y + v[..., 2:3] * self.z

    def to_local(self, v: jax.Array) -> jax.Array:
        """World vector to local coordinates: (v·x, v·y, v·z).

        Each dot product is written out, v_0 a_0 + v_1 a_1 + v_2 a_2 (the order of a sum over the
        last axis), not `jnp.sum(v * a, -1)`: XLA's CPU backend makes a reduction over an axis of 3 a
        loop of its own that ends the fusion, and in reverse mode through `shade`'s boundary term
        such loops multiply and slow down its gradient in a Phong exponent. The written-out sum
        gives the same values bit for bit as the reduction on the programs checked."""
        def dot(a):
            return v[..., 0] * a[..., 0] + v[..., 1] * a[..., 1] + v[..., 2] * a[..., 2]
        return jnp.stack([dot(self.x), dot(self.y), dot(self.z)], axis=-1)
